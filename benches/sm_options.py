#!/usr/bin/env python
"""Which statsmodels KalmanFilter options matter for speed on the CV model?

    python benches/sm_options.py [--T 100000] [--rounds 5] [--no-smoother]

Times KalmanFilter.loglike(conserve_memory=MEMORY_CONSERVE) (W3) and
KalmanFilter._filter(conserve_memory=<keep filtered only>) (W1) for a grid of
filter_method / inversion_method / stability_method / tolerance settings,
interleaved, medians.  Then (W2) KalmanSmoother: smooth() with defaults and
_filter() + _smooth(SMOOTHER_STATE | SMOOTHER_STATE_COV) over filter and
smoothing-method options.  Used to pick the "statsmodels tuned" settings in
bench_filter.py.  Prints; never fails.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_filter as b  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--T", type=int, default=100_000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--no-smoother", action="store_true", help="skip the W2 smoother grid")
    a = ap.parse_args()
    try:
        import statsmodels
        import statsmodels.tsa.statespace.kalman_filter as K
    except ImportError:
        print("statsmodels not installed")
        return
    y = b.simulate(a.T)
    mem = b._sm_filter_memory(K)
    U, nosym = K.FILTER_UNIVARIATE, dict(stability_method=0)
    grid = {
        "defaults (conventional, solve_cholesky, force symmetry)": {},
        "inversion_method=INVERT_CHOLESKY": dict(inversion_method=K.INVERT_CHOLESKY),
        "inversion_method=SOLVE_LU": dict(inversion_method=K.SOLVE_LU),
        "stability_method=0": nosym,
        "filter_method=UNIVARIATE": dict(filter_method=U),
        "filter_method=UNIVARIATE, stability_method=0": dict(filter_method=U, **nosym),
        "tolerance=0 (no steady state)": dict(tolerance=0.0),
        "UNIVARIATE, stability_method=0, tolerance=0": dict(filter_method=U, tolerance=0.0, **nosym),
    }
    fns = {}
    for name, kw in grid.items():
        try:
            _, kf = b._sm_kf(y, **kw)
            fns[(name, "W3 loglike")] = lambda kf=kf: kf.loglike(conserve_memory=K.MEMORY_CONSERVE)
            fns[(name, "W1 _filter")] = lambda kf=kf: kf._filter(conserve_memory=mem)
        except Exception as e:  # noqa: BLE001
            print(f"{name}: setup failed: {e}")
    ts = {k: [] for k in fns}
    for f in fns.values():
        f()
    for _ in range(a.rounds):
        for k, f in fns.items():
            ts[k].append(b.time_once(f))
    print(f"statsmodels {statsmodels.__version__}, CV model, T={a.T:,}, {a.rounds} interleaved rounds, median ns/step")
    print(f"{'options':56s} {'W3 loglike':>11s} {'W1 _filter':>11s}")
    for name in grid:
        r = [ts.get((name, w)) for w in ("W3 loglike", "W1 _filter")]
        cells = [f"{statistics.median(v) / a.T * 1e9:11.0f}" if v else f"{'-':>11s}" for v in r]
        print(f"{name:56s} {cells[0]} {cells[1]}")
    if not a.no_smoother:
        smoother_grid(y, a.T, a.rounds)


def smoother_grid(y, T, rounds):
    import statsmodels.tsa.statespace.kalman_filter as K
    import statsmodels.tsa.statespace.kalman_smoother as S
    U, nosym = K.FILTER_UNIVARIATE, dict(stability_method=0)
    out = S.SMOOTHER_STATE | S.SMOOTHER_STATE_COV
    mem = K.MEMORY_NO_LIKELIHOOD | K.MEMORY_NO_STD_FORECAST
    # (label, constructor kwargs, smooth_method or None, plain smooth() API?)
    grid = [
        ("defaults, smooth() (SMOOTHER_ALL, SmootherResults)", {}, None, True),
        ("defaults", {}, None, False),
        ("stability_method=0", nosym, None, False),
        ("stability_method=0, SMOOTH_CLASSICAL", nosym, S.SMOOTH_CLASSICAL, False),
        ("stability_method=0, SMOOTH_ALTERNATIVE", nosym, S.SMOOTH_ALTERNATIVE, False),
        ("UNIVARIATE, stability_method=0", dict(filter_method=U, **nosym), None, False),
        ("UNIVARIATE, stability_method=0, conserve_memory (tuned)",
         dict(filter_method=U, conserve_memory=mem, **nosym), None, False),
        ("tolerance=0 (no steady state)", dict(tolerance=0.0), None, False),
        ("UNIVARIATE, stability_method=0, tolerance=0", dict(filter_method=U, tolerance=0.0, **nosym),
         None, False),
    ]
    fns = {}
    for label, kw, meth, plain in grid:
        try:
            _, ks = b._sm_ks(y, **kw)
            if plain:
                fns[label] = lambda ks=ks: ks.smooth()
            else:
                def f(ks=ks, meth=meth):
                    ks._filter()
                    return ks._smooth(out, smooth_method=meth)
                fns[label] = f
            fns[label]()
        except Exception as e:  # noqa: BLE001
            print(f"{label}: setup failed: {e}")
            fns.pop(label, None)
    ts = {k: [] for k in fns}
    for _ in range(rounds):
        for k, f in fns.items():
            ts[k].append(b.time_once(f))
    print(f"\nKalmanSmoother (W2: smoothed states + covariances), T={T:,}, median ns/step")
    print("(all but the first row: _filter() + _smooth(SMOOTHER_STATE | SMOOTHER_STATE_COV))")
    for label, *_ in grid:
        v = ts.get(label)
        cell = f"{statistics.median(v) / T * 1e9:11.0f}" if v else f"{'-':>11s}"
        print(f"{label:56s} {cell}")


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # noqa: BLE001
        print(f"sm_options: {type(e).__name__}: {e}")
