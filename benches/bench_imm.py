"""Workload N4: an IMM of 3 modes -- constant velocity and coordinated turns at +-0.1 rad/s, state
(px, py, vx, vy, omega), n = 5, position measured -> combined means, covariances and mode
probabilities; T = 100,000.

    python benches/bench_imm.py [--quick]

Contenders, timed in one run (rounds interleaved, medians; ns per step):

- kfast.imm_filter with the modes as LinearGaussians (the Kalman filter per mode), with and
  without the per-mode estimates (filterpy keeps none);
- the same modes as NonlinearModels with f a vectorized Python callable (EKF per mode);
- three runs of kfast's linear filter, one per mode (what the IMM costs beyond its filters);
- filterpy's IMMEstimator over three filterpy KalmanFilters (the loop of its docs: update, then
  predict; on the first 5,000 steps, per step).

The run checks that kfast and filterpy give the same combined means (they take the same steps).
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, os.path.dirname(__file__))

import numpy as np  # noqa: E402

from bench_filter import Contender, run_interleaved  # noqa: E402

import kfast  # noqa: E402

DT, RATES = 1.0, (0.0, 0.1, -0.1)
TRANS = np.full((3, 3), 0.025) + np.eye(3) * 0.925
MU0 = np.array([0.8, 0.1, 0.1])


def turn(w):
    """F of the turn at the known rate w (w = 0: constant velocity), omega carried along."""
    F = np.eye(5)
    F[:4, :4] = kfast.models.coordinated_turn(dt=DT, q=1.0, omega=w).params
    F[4, 4] = 1.0
    return F


def modes():
    Q = np.zeros((5, 5))
    Q[:4, :4] = kfast.models.coordinated_turn(dt=DT, q=0.5, omega=0.1).Q
    Q[4, 4] = 1e-6
    H, R = np.eye(2, 5), np.eye(2) * 25.0
    return [dict(F=turn(w), H=H, Q=Q, R=R) for w in RATES]


def simulate(T, seed=7):
    rng = np.random.default_rng(seed)
    Fs = [m["F"] for m in modes()]
    x, mode, y = np.array([0.0, 0.0, 20.0, 0.0, 0.0]), 0, np.zeros((T, 2))
    for t in range(T):
        y[t] = x[:2] + 5.0 * rng.standard_normal(2)
        if rng.random() < 0.02:
            mode = int(rng.integers(3))
        x = Fs[mode] @ x + np.r_[0.0, 0.0, 0.5 * rng.standard_normal(2), 0.0]
    return y


def python_model(m):
    """The mode as a NonlinearModel of vectorized Python callables with their Jacobians."""
    F, H = m["F"], m["H"]

    def f(X, t, u):
        return X @ F.T

    def h(X, t, u):
        return X[:, :2]

    def jac_f(X, t, u):
        return np.broadcast_to(F, (len(X), 5, 5))

    def jac_h(X, t, u):
        return np.broadcast_to(H, (len(X), 2, 5))

    return kfast.NonlinearModel(f, h, m["Q"], m["R"], n=5, jac_f=jac_f, jac_h=jac_h)


def filterpy_imm(y, x0, P0):
    from filterpy.kalman import IMMEstimator, KalmanFilter

    filters = []
    for m in modes():
        kf = KalmanFilter(dim_x=5, dim_z=2)
        kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = m["F"], m["H"], m["Q"], m["R"], x0.copy(), P0.copy()
        filters.append(kf)
    imm = IMMEstimator(filters, MU0, TRANS)
    xs, mus = np.zeros((len(y), 5)), np.zeros((len(y), 3))
    for t, z in enumerate(y):
        imm.update(z)
        xs[t], mus[t] = imm.x, imm.mu
        imm.predict()
    return xs, mus


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    rounds = 3 if args.quick else 5
    T = 10_000 if args.quick else 100_000
    T_peer = 1_000 if args.quick else 5_000
    y = simulate(T)
    x0, P0 = np.array([0.0, 0.0, 20.0, 0.0, 0.0]), np.diag([100.0, 100.0, 25.0, 25.0, 1e-4])
    linear = [kfast.LinearGaussian(**m) for m in modes()]
    nonlinear = [python_model(m) for m in modes()]
    mu = MU0 @ TRANS  # filterpy's first update weighs the modes by mu0 @ M
    combined = ("x_filt", "P_filt")
    contenders = [
        Contender("kfast IMM, linear modes", lambda: kfast.imm_filter(linear, TRANS, y, x0, P0, mu, outputs=combined, modes=False), T),
        Contender("kfast IMM, linear modes, + per-mode estimates", lambda: kfast.imm_filter(linear, TRANS, y, x0, P0, mu, outputs=combined), T),
        Contender("kfast IMM, EKF modes, Python f/h", lambda: kfast.imm_filter(nonlinear, TRANS, y[:T_peer], x0, P0, mu, outputs=combined, modes=False), T_peer),
        Contender("3 x kfast linear filter (x_filt, P_filt)", lambda: [m.filter(y, x0, P0, outputs=combined) for m in linear], T),
        Contender("filterpy IMMEstimator", lambda: filterpy_imm(y[:T_peer], x0, P0), T_peer),
    ]
    run_interleaved(contenders, rounds)
    print(f"kfast {kfast.__version__}; N4 IMM, r = 3, n = 5, m = 2, T = {T:,} (filterpy, Python f: {T_peer:,}); "
          f"{rounds} rounds, medians; instruction set {kfast.kernel_info()}")
    base = contenders[0]
    print("\n| contender | ns/step | IQR | /kfast IMM |\n|---|---:|---:|---:|")
    for c in contenders:
        if not c.ok:
            print(f"| {c.name} | - | - | {c.error} |")
            continue
        lo, hi = c.spread()
        print(f"| {c.name} | {c.ns_per_step():.0f} | {lo:.0f}-{hi:.0f} | {c.ns_per_step() / base.ns_per_step():.3g} |")
    res = kfast.imm_filter(linear, TRANS, y[:T_peer], x0, P0, mu)
    try:
        xs, mus = filterpy_imm(y[:T_peer], x0, P0)
        print(f"  check filterpy: max|dx| = {np.max(np.abs(res.x_filt - xs)):.1e}, max|dmu| = {np.max(np.abs(res.mode_probs - mus)):.1e}")
    except ImportError:
        print("  filterpy not installed")


if __name__ == "__main__":
    main()
