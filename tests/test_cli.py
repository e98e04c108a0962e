"""The demo of `python -m kfast demo` runs and the filter beats the raw measurements."""

import re
import subprocess
import sys

import numpy as np

from kfast.cli import constant_velocity_2d


def test_demo_prints_rmse_and_loglik():
    out = subprocess.run(
        [sys.executable, "-m", "kfast", "demo", "--steps", "300", "--seed", "4"],
        capture_output=True, text=True, check=True,
    ).stdout
    numbers = dict(re.findall(r"^\s*(.+?)\s*:\s*(-?[\d.]+)$", out, flags=re.M))
    raw = float(numbers["position RMSE of the raw measurements"])
    filtered = float(numbers["position RMSE of the filtered estimate"])
    assert filtered < 0.8 * raw, out
    assert np.isfinite(float(numbers["log-likelihood of the measurements"]))


def test_demo_model_is_the_cv_workload_model():
    m = constant_velocity_2d(dt=0.1)
    assert m.F[0, 2] == 0.1 and m.F[1, 3] == 0.1
    assert m.Q[0, 0] == 0.1**3 / 3 and m.Q[0, 2] == 0.1**2 / 2 and m.Q[2, 2] == 0.1


def test_demo_plot_info_and_bench(tmp_path):
    path = tmp_path / "demo.png"
    out = subprocess.run(
        [sys.executable, "-m", "kfast", "demo", "--steps", "200", "--plot", str(path)],
        capture_output=True, text=True, check=True,
    ).stdout
    assert f"plot written to {path}" in out
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    info = subprocess.run([sys.executable, "-m", "kfast", "info"], capture_output=True, text=True, check=True).stdout
    import kfast

    details = kfast.kernel_info()
    assert f"kfast {kfast.__version__} ({details['build']} build" in info
    assert f"instruction set: {details['instruction_set']}" in info
    assert f"threads (batch functions, threads=None): {details['threads']}" in info
    assert details["threads"] >= 1 and details["build"] in ("release", "debug")

    bench = subprocess.run([sys.executable, "-m", "kfast", "bench", "--quick"], capture_output=True, text=True,
                           check=True).stdout
    rows = [line.split("|")[1:-1] for line in bench.splitlines() if line.startswith("| W")]
    got = {(w.strip(), c.strip()) for w, c, *_ in rows}
    # The test extras install filterpy, pykalman and statsmodels: every peer row is there.
    for workload, peers in (("W1 filter", ("kfast", "filterpy", "pykalman")),
                            ("W3 log-likelihood", ("kfast", "filterpy", "statsmodels")),
                            ("W7 streaming", ("kfast", "filterpy"))):
        for peer in peers:
            assert (workload, peer) in got, bench
    for w, c, ns, ratio, diff in rows:
        assert float(ns.replace(",", "")) > 0 and float(ratio) > 0
        assert float(diff) < 1e-8, (w, c, diff)  # the same outputs before timing
