"""``python -m kfast bench``: a few of the benchmark workloads (benches/ and BENCHMARKS.md have
them all) against whichever peers are installed, with the ratio table.

The model is the 2-D constant-velocity target (n = 4, m = 2) of BENCHMARKS.md's "CV"
workloads; each contender computes the same outputs from the same data and prior:

- W1 filter: x(t|t) and P(t|t) for every step (kfast, filterpy's batch_filter, pykalman);
- W3 log-likelihood: the total (kfast, statsmodels' KalmanFilter.loglike, filterpy's loop);
- W7 streaming: one update + predict per Python call (kfast.KalmanFilter, filterpy).

Times are the fastest of several interleaved rounds, in ns per time step; "kfast / peer" below
1 means kfast is faster. The outputs are compared (max relative difference) before timing.
"""

from __future__ import annotations

import importlib
import time
from typing import Any, Callable, Optional

import numpy as np

import kfast


def _import(name: str) -> Optional[Any]:
    try:
        return importlib.import_module(name)
    except Exception:  # noqa: BLE001 - a peer that is missing or broken is skipped
        return None


def _problem(T: int, seed: int = 1):
    model = kfast.models.constant_velocity(2, 0.1, q=1.0, r=1.0)
    x0 = np.array([1.0, -1.0, 0.5, 0.2])
    P0 = np.diag([10.0, 10.0, 1.0, 1.0])
    _, y = model.simulate(T, x0, P0, seed=seed)
    return model, x0, P0, np.ascontiguousarray(y)


def _filterpy(model, x0, P0):
    fp = _import("filterpy.kalman")
    if fp is None:
        return None
    kf = fp.KalmanFilter(dim_x=4, dim_z=2)
    kf.F, kf.H, kf.Q, kf.R = model.F.copy(), model.H.copy(), model.Q.copy(), model.R.copy()

    def reset():
        kf.x, kf.P = x0.copy(), P0.copy()
        return kf

    return reset


def _contenders(T: int) -> dict[str, dict[str, Callable[[], Any]]]:
    """{workload: {contender: run}}; every run returns the workload's output."""
    model, x0, P0, y = _problem(T)
    rows = list(y)
    work: dict[str, dict[str, Callable[[], Any]]] = {"W1 filter": {}, "W3 log-likelihood": {}, "W7 streaming": {}}
    work["W1 filter"]["kfast"] = lambda: model.filter(y, x0, P0, outputs=("x_filt", "P_filt")).x_filt
    work["W3 log-likelihood"]["kfast"] = lambda: model.loglik(y, x0, P0)

    def kfast_stream():
        f = kfast.KalmanFilter(model, x0, P0)
        for r in rows:
            f.update(r)
            f.predict()
        return f.x

    work["W7 streaming"]["kfast"] = kfast_stream
    reset = _filterpy(model, x0, P0)
    if reset is not None:
        def fp_filter():
            return reset().batch_filter(y, update_first=True)[0]

        def fp_loglik():
            kf, ll = reset(), 0.0
            for r in rows:
                kf.update(r)
                ll += kf.log_likelihood
                kf.predict()
            return ll

        def fp_stream():
            kf = reset()
            for r in rows:
                kf.update(r)
                kf.predict()
            return kf.x

        work["W1 filter"]["filterpy"] = fp_filter
        work["W3 log-likelihood"]["filterpy"] = fp_loglik
        work["W7 streaming"]["filterpy"] = fp_stream
    pk = _import("pykalman")
    if pk is not None:
        pkf = pk.KalmanFilter(transition_matrices=model.F, observation_matrices=model.H,
                              transition_covariance=model.Q, observation_covariance=model.R,
                              initial_state_mean=x0, initial_state_covariance=P0)
        work["W1 filter"]["pykalman"] = lambda: pkf.filter(y)[0]
    sm = _import("statsmodels.tsa.statespace.kalman_filter")
    if sm is not None:
        skf = sm.KalmanFilter(k_endog=2, k_states=4, k_posdef=4)
        skf.bind(y.copy())
        for name, value in (("design", model.H), ("obs_cov", model.R), ("transition", model.F),
                            ("selection", np.eye(4)), ("state_cov", model.Q)):
            skf[name] = value
        skf.initialize_known(x0, P0)  # statsmodels' a(1), P(1) are kfast's x(0|-1), P(0|-1)
        work["W3 log-likelihood"]["statsmodels"] = skf.loglike
    return work


def _best_time(run: Callable[[], Any], budget: float) -> float:
    best = float("inf")
    spent = 0.0
    while spent < budget or best == float("inf"):
        t0 = time.perf_counter()
        run()
        dt = time.perf_counter() - t0
        best, spent = min(best, dt), spent + dt
    return best


def _difference(a: Any, b: Any) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def run(quick: bool = False, out: Callable[[str], None] = print) -> list[tuple[str, str, float, float]]:
    """Runs the workloads; prints and returns (workload, contender, ns per step, kfast / it)."""
    T = 2_000 if quick else 20_000
    rounds, budget = (2, 0.05) if quick else (5, 0.2)
    info = kfast.kernel_info()
    out(f"kfast {kfast.__version__}: instruction set {info['instruction_set']}, "
        f"deterministic {info['deterministic']}, build {info['build']}; T = {T}, CV model n = 4, m = 2")
    table = []
    out("| workload | contender | ns / step | kfast / this | max rel. diff vs kfast |")
    out("|---|---|---:|---:|---:|")
    for workload, runs in _contenders(T).items():
        # The streaming workload is T Python calls: shorter, so quick runs stay quick.
        reference = runs["kfast"]()
        diffs = {name: _difference(fn(), reference) for name, fn in runs.items()}
        best = {name: float("inf") for name in runs}
        for _ in range(rounds):  # interleaved: load changes hit every contender alike
            for name, fn in runs.items():
                best[name] = min(best[name], _best_time(fn, budget / rounds))
        for name in runs:
            ns = best[name] / T * 1e9
            ratio = best["kfast"] / best[name]
            table.append((workload, name, ns, ratio))
            out(f"| {workload} | {name} | {ns:,.1f} | {ratio:.3g} | {diffs[name]:.1e} |")
    missing = [p for p in ("filterpy", "pykalman", "statsmodels") if _import(p) is None]
    if missing:
        out(f"(not installed, skipped: {', '.join(missing)}; pip install \"kfast[bench]\" adds them)")
    return table
