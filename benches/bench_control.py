"""Control (issue 15): the stationary LQ regulator, kfast.control.lqr against python-control's
dlqr (slycot's SB02OD and SciPy's solver), and the finite-horizon regulator against a NumPy loop.

    python benches/bench_control.py [--quick] [--write]

Like for like: dlqr returns (K, S, E); kfast's lqr returns L and S and computes the closed-loop
eigenvalues on first access, so it is shown both without and with them. Both validate their input. n = 4 is two sampled double integrators (k = 2); n = 20 and 100 are
seeded random systems with k = n/2. Contenders run interleaved and the median time per call is
reported, each result checked against kfast's (max relative difference of S). A benchmark
never fails; it prints.
"""

from __future__ import annotations

import argparse
import datetime
import os
import re
import statistics
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import kfast  # noqa: E402
from bench_riccati import machine, measure  # noqa: E402
from kfast.reference.control import lq_backward  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
BEGIN = "<!-- BEGIN CONTROL RESULTS (benches/bench_control.py --write) -->"
END = "<!-- END CONTROL RESULTS -->"


def problems():
    h = 0.1
    di = np.array([[1, h], [0, 1]])
    F = np.kron(np.eye(2), di)
    G = np.kron(np.eye(2), np.array([[h**2 / 2], [h]]))
    yield 4, (F, G, np.eye(4), 0.1 * np.eye(2))
    rng = np.random.default_rng(15)
    for n in (20, 100):
        k = n // 2
        F = rng.standard_normal((n, n)) / np.sqrt(n)
        G = rng.standard_normal((n, k))
        C = rng.standard_normal((n, n))
        yield n, (F, G, C @ C.T / n + 0.1 * np.eye(n), np.eye(k))


def contenders():
    def with_eigenvalues(F, G, Q1, Q2):
        res = kfast.control.lqr(F, G, Q1, Q2)
        res.closed_loop_eigenvalues  # computed on first access: what dlqr's E costs
        return res.S

    out = {
        "kfast lqr": lambda F, G, Q1, Q2: kfast.control.lqr(F, G, Q1, Q2).S,
        "kfast lqr + eigenvalues": with_eigenvalues,
    }
    try:
        import control

        out["control.dlqr (scipy)"] = lambda F, G, Q1, Q2: control.dlqr(F, G, Q1, Q2, method="scipy")[1]
        try:
            import slycot  # noqa: F401

            out["control.dlqr (slycot)"] = lambda F, G, Q1, Q2: control.dlqr(F, G, Q1, Q2, method="slycot")[1]
        except ImportError:
            print("slycot: not installed")
    except ImportError:
        print("python-control: not installed")
    return out


def timed(funcs, args, quick, base):
    ref = base(*args)
    diffs = {}
    for name, fn in funcs.items():
        try:
            diffs[name] = float(np.abs(fn(*args) - ref).max() / np.abs(ref).max())
        except Exception as exc:  # a peer that fails is reported, not fatal
            diffs[name] = f"failed: {exc}"
    live = {k: f for k, f in funcs.items() if not isinstance(diffs[k], str)}
    one = {k: measure(f, args, 1) for k, f in live.items()}
    reps = {k: max(1, int((0.02 if quick else 0.1) / max(t, 1e-7))) for k, t in one.items()}
    samples: dict = {k: [] for k in live}
    for _ in range(5 if quick else 15):
        for k, f in live.items():
            samples[k].append(measure(f, args, reps[k]))
    return {k: statistics.median(v) for k, v in samples.items()}, diffs


def run(quick):
    rows = []
    for n, args in problems():
        med, diffs = timed(contenders(), args, quick, lambda *a: kfast.control.lqr(*a).S)
        rows.append((f"lqr n = {n}", "kfast lqr", med, diffs))
    # The finite horizon, N = 200 steps: the compiled dual filter against the NumPy recursion.
    for n, (F, G, Q1, Q2) in problems():
        if n > 20:
            continue
        fin = {
            "kfast lq_finite": lambda F, G, Q1, Q2: kfast.control.lq_finite(F, G, Q1, Q1, Q2, 200).S,
            "NumPy loop (reference)": lambda F, G, Q1, Q2: lq_backward(F, G, Q1, Q1, Q2, 200)[0],
        }
        med, diffs = timed(fin, (F, G, Q1, Q2), quick, fin["kfast lq_finite"])
        rows.append((f"lq_finite n = {n}, N = 200", "kfast lq_finite", med, diffs))
    # Spectral factorization, degree d: the zeros of z^d φ against the Riccati route (Thm 4.2);
    # the accuracy column is each route's max |λ² B B* - r| / max |r| (against r, not kfast).
    rng = np.random.default_rng(4)
    for d in (2, 10, 50):
        zeros = 0.9 * rng.uniform(0.1, 1.0, d) * np.exp(1j * rng.uniform(0, np.pi, d))
        C = np.real(np.poly(np.r_[zeros[: d // 2], np.conj(zeros[: d // 2]), 0.9 * rng.uniform(-1, 1, d % 2)]))
        r = kfast.poly.laurent(C, C)
        routes = {
            "kfast roots": lambda r: kfast.poly.spectral_factor(r),
            "kfast riccati": lambda r: kfast.poly.spectral_factor(r, method="riccati"),
        }
        med, _ = timed({k: (lambda f: lambda r: f(r).B)(f) for k, f in routes.items()}, (r,), quick, lambda r: kfast.poly.spectral_factor(r).B)
        errors = {}
        for k, f in routes.items():
            try:
                res = f(r)
                errors[k] = float(np.abs(res.lam2 * kfast.poly.laurent(res.B, res.B) - r).max() / np.abs(r).max())
            except Exception as exc:  # a route that fails is reported
                errors[k] = f"failed: {exc}"
        rows.append((f"spectral factor d = {d}", "kfast roots", med, errors))
    # A complex model against the real filter of the same composite size (2n): like for like,
    # x_filt and P_filt of the composite run; the complex one also maps them back.
    rng = np.random.default_rng(9)
    n, m, T = 4, 2, 20000
    F = (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))) * 0.3
    H = rng.standard_normal((m, n)) + 1j * rng.standard_normal((m, n))
    cmodel = kfast.LinearGaussian(F, H, np.eye(n) + 0j, np.eye(m) + 0j)
    y = rng.standard_normal((T, m)) + 1j * rng.standard_normal((T, m))
    yr = np.concatenate([y.real, y.imag], axis=1)
    x0, P0 = np.zeros(n, complex), np.eye(n) + 0j
    def complex_run():
        res = cmodel.filter(y, x0, P0)
        res.P_filt  # converted on access
        return res.x_filt.real

    def real_run():
        res = cmodel.real.filter(yr, np.zeros(2 * n), 0.5 * np.eye(2 * n))
        return res.x_filt[:, :n]

    runs = {"kfast complex filter (x_filt, P_filt)": complex_run, "kfast real filter, 2n states": real_run}
    med, diffs = timed(runs, (), quick, complex_run)
    rows.append((f"complex filter n = {n}, m = {m}, T = {T}", "kfast complex filter (x_filt, P_filt)", med, diffs))
    return rows


def table(rows):
    lines = ["| problem | contender | µs / call | kfast / this | max rel. diff (S vs kfast; spectra vs r) |", "|---|---|---:|---:|---:|"]
    for problem, base_name, med, diffs in rows:
        base = med.get(base_name)
        for name, d in diffs.items():
            if isinstance(d, str):
                lines.append(f"| {problem} | {name} | {d} | | |")
                continue
            t = med[name]
            lines.append(f"| {problem} | {name} | {t * 1e6:,.1f} | {base / t:.3f} | {d:.1e} |")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--write", action="store_true", help="update the control block of BENCHMARKS.md")
    args = p.parse_args(argv)
    rows = run(args.quick)
    text = table(rows)
    print(text)
    if args.write:
        stamp = datetime.date.today().isoformat()
        block = f"{BEGIN}\n\nMeasured {stamp} on {machine()}; load {os.getloadavg()[0]:.2f}.\n\n{text}\n\n{END}"
        path = ROOT / "BENCHMARKS.md"
        doc = path.read_text()
        if BEGIN in doc:
            doc = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), block, doc, flags=re.S)
        else:
            doc += "\n## Control: LQ regulators (issue 15)\n\n`python benches/bench_control.py --write`\n\n" + block + "\n"
        path.write_text(doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
