"""W6: the stationary Kalman filter's DARE, kfast against SciPy, python-control and slycot.

    python benches/bench_riccati.py [--quick] [--write]

"kfast doubling" is `solve_discrete_are` (X, checked stabilizing; the gain is computed for the
check and dropped), "kfast dare(eigenvalues=False)" returns the gain and the residual too, and
"kfast dare()" adds the closed-loop eigenvalues, as control.dare returns them.
n = 4 is the CV model (a = F', b = H', q = Q, r = R, as the Kalman DARE); n = 20 and 100 are
seeded random stable systems with m = n/2. Contenders run interleaved (A B C A B C ...) and
the median time per solve is reported, with every result checked against kfast's (max
relative difference) so the comparison is honest. A benchmark never fails; it prints.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.linalg as sl  # noqa: E402

import kfast  # noqa: E402
from kfast.riccati.solvers import dare  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
BEGIN = "<!-- BEGIN W6 RESULTS (benches/bench_riccati.py --write) -->"
END = "<!-- END W6 RESULTS -->"


def problems():
    cv = kfast.models.constant_velocity(2, 0.1)
    yield 4, (cv.F.T, cv.H.T, cv.Q, cv.R)
    rng = np.random.default_rng(6)
    for n in (20, 100):
        m = n // 2
        a = rng.standard_normal((n, n))
        a *= 0.95 / max(abs(np.linalg.eigvals(a)))
        b = rng.standard_normal((n, m))
        c = rng.standard_normal((n, n))
        yield n, (a, b, c @ c.T / n + 0.1 * np.eye(n), np.eye(m))


def contenders():
    out = {
        "kfast doubling": lambda a, b, q, r: kfast.solve_discrete_are(a, b, q, r),
        # X with the gain and the residual, then with the closed-loop eigenvalues too (what
        # control.dare returns): the eigenvalues cost an eigenvalue solve that X does not.
        "kfast dare(eigenvalues=False)": lambda a, b, q, r: dare(a, b, q, r, eigenvalues=False)["x"],
        "kfast dare()": lambda a, b, q, r: dare(a, b, q, r)["x"],
        "kfast newton": lambda a, b, q, r: kfast.solve_discrete_are(a, b, q, r, method="newton"),
        "kfast eigen": lambda a, b, q, r: kfast.solve_discrete_are(a, b, q, r, method="eigen"),
        "scipy": lambda a, b, q, r: sl.solve_discrete_are(a, b, q, r),
    }
    try:
        import control

        out["control.dare (scipy)"] = lambda a, b, q, r: control.dare(a, b, q, r, method="scipy")[0]
        try:
            import slycot  # noqa: F401

            out["control.dare (slycot)"] = lambda a, b, q, r: control.dare(a, b, q, r, method="slycot")[0]
        except ImportError:
            print("slycot: not installed")
    except ImportError:
        print("python-control: not installed")
    return out


def measure(fn, args, reps):
    t0 = time.perf_counter()
    for _ in range(reps):
        fn(*args)
    return (time.perf_counter() - t0) / reps


def run(quick: bool):
    rows = []
    for n, args in problems():
        funcs = contenders()
        ref = kfast.solve_discrete_are(*args)
        diffs = {}
        for name, fn in funcs.items():
            try:
                X = fn(*args)
                diffs[name] = float(np.abs(X - ref).max() / np.abs(ref).max())
            except Exception as exc:  # a peer that fails is reported, not fatal
                diffs[name] = f"failed: {exc}"
        live = {k: f for k, f in funcs.items() if not isinstance(diffs[k], str)}
        one = {k: measure(f, args, 1) for k, f in live.items()}
        reps = {k: max(1, int((0.02 if quick else 0.1) / max(t, 1e-7))) for k, t in one.items()}
        samples = {k: [] for k in live}
        for _ in range(5 if quick else 15):
            for k, f in live.items():
                samples[k].append(measure(f, args, reps[k]))
        med = {k: statistics.median(v) for k, v in samples.items()}
        rows.append((n, med, diffs))
    return rows


def table(rows):
    lines = ["| n | contender | µs / solve | kfast doubling / this | max rel. diff vs kfast |", "|---|---|---:|---:|---:|"]
    for n, med, diffs in rows:
        base = med.get("kfast doubling")
        for name, d in diffs.items():
            if isinstance(d, str):
                lines.append(f"| {n} | {name} | {d} | | |")
                continue
            t = med[name]
            lines.append(f"| {n} | {name} | {t * 1e6:,.1f} | {base / t:.3f} | {d:.1e} |")
    return "\n".join(lines)


def machine():
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, NumPy {np.__version__}, kfast {kfast.__version__}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--write", action="store_true", help="update the W6 block of BENCHMARKS.md")
    args = p.parse_args(argv)
    rows = run(args.quick)
    text = table(rows)
    print(text)
    if args.write:
        write_block(rows)
    return 0


def write_block(rows):
    """Rewrite the W6 block of BENCHMARKS.md (also called from bench_filter.py --write)."""
    text = table(rows)
    stamp = datetime.date.today().isoformat()
    block = f"{BEGIN}\n\nMeasured {stamp} on {machine()}; load {os.getloadavg()[0]:.2f}.\n\n{text}\n\n{END}"
    path = ROOT / "BENCHMARKS.md"
    doc = path.read_text()
    if BEGIN in doc:
        doc = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), block, doc, flags=re.S)
    else:
        doc += "\n## W6: the DARE\n\n`python benches/bench_riccati.py --write`\n\n" + block + "\n"
    path.write_text(doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
