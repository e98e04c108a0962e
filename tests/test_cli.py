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
