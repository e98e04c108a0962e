"""N1, N1b and N2: the nonlinear Gaussian filters, kfast against filterpy, dynamax and Stone Soup
(and kfast's linear filter).

    python benches/bench_nonlinear.py [--quick]

- N1: UKF (Merwe points alpha = 0.5, beta = 2, kappa = 0) on the CT model -- coordinated turn
  with unknown turn rate, state (px, py, vx, vy, omega), dt = 0.1, seen by a range-bearing
  sensor at the origin; q = 1 per axis, sigma_omega = 0.05, R = diag(1, (0.5 deg)^2), prior
  x(0|-1) = (100, 50, 5, -2, 0.1), P0 = diag(100, 100, 4, 4, 0.01) -- filtered means and
  covariances.
- N1b: the same UKF on the 4-state CV model of W1 (``NonlinearModel.from_linear``).
- N2: EKF with analytic Jacobians on CT; kfast's linear filter at n = 5, m = 2 beside it.

kfast runs each with the built-in Rust model, with the model compiled from C
(benches/c/ct_radar.c, gcc -O3, passed as ctypes function pointers), with the same C written as
numba @cfunc's (numba 0.68; "not installed" without it) and with the model as a vectorized
Python callable (one call per step for all points). The C and numba models pass the built-in's
closed-form Jacobians, compiled too (jac_f, jac_h), so that N2 compares like with like; one more
numba row leaves them out, and kfast differences f and h instead (2n more points per call).
filterpy's UKF and EKF run the same model with its per-point Python functions (a short series:
it is slow); its UKF is given the prior's sigma points for its first update, since it predicts
first.

dynamax (jax.jit, CPU, float64; EKF Jacobians by jacfwd: derivatives, not differences) and
Stone Soup's UnscentedKalmanPredictor/Updater (a short series, like filterpy) run in their own
venv through benches/peers_nonlinear.py, which times them itself (a warm-up call first, so no
jit compile; the same number of rounds; not interleaved with the rest). Create that venv with
``python3 -m venv /work/venv-peers && /work/venv-peers/bin/pip install numpy scipy jax dynamax
stonesoup`` (or point KFAST_PEER_PYTHON at another python that has them). Both take the prior as
x(0|-1), like kfast (dynamax's initial_mean is the prior of emissions[0]).

Conventions found: the simulated bearing crosses +-pi (first at step 2,285; 19 times in 100,000)
and kfast wraps its innovation; dynamax does not wrap, so its h gets the observed bearing as
input and returns the bearing within pi of it (filterpy and Stone Soup run 2,000 steps, before
the first crossing). dynamax's psd_solve adds 1e-9 I to the innovation covariance S; against the
bearing variance (7.6e-5) that moves x_filt by ~1e-5 early and ~1e-3 late (ranges up to 6 km);
with it patched to 0, dynamax's UKF matches to ~1e-9 over all 100,000 steps, its EKF to ~3e-6
(jacfwd through sin(w dt)/w loses digits where omega passes near 0). Stone Soup's kappa defaults
to 3 - n (given as 0 here); its Merwe weights and its update P - K S K' are kfast's; its own
models order the state (x, vx, y, vy, w) (ConstantTurn) and the radar (bearing, range) with
Bearing objects (CartesianToBearingRange), so custom models in kfast's order are used.

Every contender's x_filt is checked against kfast's built-in run on the same steps. Contenders
run interleaved (the peer venv's apart); medians.
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(__file__))
from bench_filter import Contender, run_interleaved  # noqa: E402

import kfast  # noqa: E402

DT = 0.1
X0 = np.array([100.0, 50.0, 5.0, -2.0, 0.1])
P0 = np.diag([100.0, 100.0, 4.0, 4.0, 0.01])
R = np.diag([1.0, np.deg2rad(0.5) ** 2])


def ct_one(x):
    px, py, vx, vy, w = x
    S, C = np.sin(w * DT), np.cos(w * DT)
    s, c = (S / w, (1 - C) / w) if abs(w) > 1e-9 else (DT, 0.0)
    return np.array([px + s * vx - c * vy, py + c * vx + s * vy, C * vx - S * vy, S * vx + C * vy, w])


def ct_batch(X, t, u):
    px, py, vx, vy, w = X.T
    S, C = np.sin(w * DT), np.cos(w * DT)
    small = np.abs(w) < 1e-9
    ws = np.where(small, 1.0, w)
    s = np.where(small, DT, S / ws)
    c = np.where(small, 0.0, (1 - C) / ws)
    return np.stack([px + s * vx - c * vy, py + c * vx + s * vy, C * vx - S * vy, S * vx + C * vy, w], axis=1)


def ct_jac_one(x):
    _, _, vx, vy, w = x
    S, C = np.sin(w * DT), np.cos(w * DT)
    s, c = S / w, (1 - C) / w
    ds, dc = (w * DT * C - S) / w**2, (w * DT * S - (1 - C)) / w**2
    return np.array(
        [
            [1, 0, s, -c, ds * vx - dc * vy],
            [0, 1, c, s, dc * vx + ds * vy],
            [0, 0, C, -S, -DT * (S * vx + C * vy)],
            [0, 0, S, C, DT * (C * vx - S * vy)],
            [0, 0, 0, 0, 1.0],
        ]
    )


def rb_batch(X, t, u):
    return np.stack([np.hypot(X[:, 0], X[:, 1]), np.arctan2(X[:, 1], X[:, 0])], axis=1)


def rb_jac_one(x):
    r2 = x[0] ** 2 + x[1] ** 2
    r = np.sqrt(r2)
    J = np.zeros((2, 5))
    J[0, :2] = x[0] / r, x[1] / r
    J[1, :2] = -x[1] / r2, x[0] / r2
    return J


def simulate(T, seed=20240601):
    ct = kfast.models.coordinated_turn(DT, q=1.0, sigma_omega=0.05)
    rng = np.random.default_rng(seed)
    x = X0.copy()
    y = np.zeros((T, 2))
    for t in range(T):
        y[t] = rb_batch(x[None], t, None)[0] + rng.multivariate_normal(np.zeros(2), R)
        x = ct_one(x) + rng.multivariate_normal(np.zeros(5), ct.Q)
    return ct, y


def filterpy_ukf(ct, y):
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    points = MerweScaledSigmaPoints(5, alpha=0.5, beta=2.0, kappa=0.0)

    def run():
        kf = UnscentedKalmanFilter(5, 2, DT, hx=lambda x: rb_batch(x[None], 0, None)[0], fx=lambda x, dt: ct_one(x), points=points)
        kf.x, kf.P, kf.Q, kf.R = X0.copy(), P0.copy(), ct.Q, R
        kf.sigmas_f = points.sigma_points(X0, P0)
        out = np.zeros((len(y), 5))
        for t in range(len(y)):
            if t:
                kf.predict()
            kf.update(y[t])
            out[t] = kf.x
        return out

    return run


def filterpy_ekf(ct, y):
    from filterpy.kalman import ExtendedKalmanFilter

    class CT(ExtendedKalmanFilter):
        def predict_x(self, u=0):
            self.x = ct_one(self.x)

    def run():
        kf = CT(5, 2)
        kf.x, kf.P, kf.Q, kf.R = X0.copy(), P0.copy(), ct.Q, R
        out = np.zeros((len(y), 5))
        for t in range(len(y)):
            kf.update(y[t], rb_jac_one, lambda x: rb_batch(x[None], 0, None)[0])
            out[t] = kf.x
            kf.F = ct_jac_one(kf.x)
            kf.predict()
        return out

    return run


def compiled_model(ct):
    """CT and the radar compiled from benches/c/ct_radar.c, or None without a C compiler."""
    import ctypes
    import shutil
    import subprocess
    import tempfile

    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        return None
    so = os.path.join(tempfile.mkdtemp(), "ct_radar.so")
    src = os.path.join(os.path.dirname(__file__), "c", "ct_radar.c")
    subprocess.run([cc, "-O3", "-shared", "-fPIC", "-o", so, src, "-lm"], check=True)
    lib = ctypes.CDLL(so)
    double_p = ctypes.POINTER(ctypes.c_double)
    proto = ctypes.CFUNCTYPE(None, double_p, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_int64, double_p, double_p)
    f, h, jac_f, jac_h = (proto((name, lib)) for name in ("ct", "radar", "ct_jac", "radar_jac"))
    # the function pointers keep the library loaded
    return kfast.NonlinearModel(f, h, ct.Q, R, n=5, angles=[1], jac_f=jac_f, jac_h=jac_h)


def numba_model(ct):
    """CT and the radar with their Jacobians as numba @cfunc's, statement for statement
    benches/c/ct_radar.c (so x_filt matches the C and built-in runs): (the model, the model
    without its Jacobians, which kfast then differences), or None without numba."""
    try:
        import math

        import numba
        from numba import types
    except ImportError:
        return None
    double_p = types.CPointer(types.double)
    sig = types.void(double_p, types.intp, types.intp, types.int64, double_p, double_p)

    # error_model="numpy": C's float semantics, no zero-division checks (w is tested first anyway)
    @numba.njit(error_model="numpy")
    def turn(w, dt):
        if w == 0.0:
            return dt, 0.0, 1.0, 0.0
        S, C = math.sin(w * dt), math.cos(w * dt)
        one_minus_cos = S * S / (1.0 + C) if C >= 0.0 else 1.0 - C  # no cancellation as w -> 0
        return S / w, one_minus_cos / w, C, S

    @numba.cfunc(sig, error_model="numpy")
    def f(X, k, n, t, u, out):
        for i in range(k):
            x, o = i * n, i * n  # row offsets of point i in X and out
            s, c, C, S = turn(X[x + 4], 0.1)
            out[o] = X[x] + s * X[x + 2] - c * X[x + 3]
            out[o + 1] = X[x + 1] + c * X[x + 2] + s * X[x + 3]
            out[o + 2] = C * X[x + 2] - S * X[x + 3]
            out[o + 3] = S * X[x + 2] + C * X[x + 3]
            out[o + 4] = X[x + 4]

    @numba.cfunc(sig, error_model="numpy")
    def jac_f(X, k, n, t, u, out):
        dt = 0.1
        for i in range(k):
            x, J = i * n, i * n * n
            vx, vy, w = X[x + 2], X[x + 3], X[x + 4]
            a = w * dt
            s, c, C, S = turn(w, dt)
            if abs(a) < 0.02:  # ds/dw, dc/dw by Taylor series: the closed forms are 0/0 at w = 0
                t2, w2 = dt * dt, w * w
                ds = -w * dt * t2 / 3.0 + w * w2 * t2 * t2 * dt / 30.0 - w * w2 * w2 * t2 * t2 * t2 * dt / 840.0
                dc = t2 / 2.0 - w2 * t2 * t2 / 8.0 + w2 * w2 * t2 * t2 * t2 / 144.0
            else:
                ds = (a * C - S) / (w * w)
                dc = (a * S - c * w) / (w * w)
            for e in range(25):
                out[J + e] = 0.0
            out[J], out[J + 2], out[J + 3], out[J + 4] = 1.0, s, -c, ds * vx - dc * vy
            out[J + 6], out[J + 7], out[J + 8], out[J + 9] = 1.0, c, s, dc * vx + ds * vy
            out[J + 12], out[J + 13], out[J + 14] = C, -S, -dt * (S * vx + C * vy)
            out[J + 17], out[J + 18], out[J + 19] = S, C, dt * (C * vx - S * vy)
            out[J + 24] = 1.0

    @numba.cfunc(sig, error_model="numpy")
    def h(X, k, n, t, u, out):
        for i in range(k):
            out[2 * i] = math.hypot(X[i * n], X[i * n + 1])
            out[2 * i + 1] = math.atan2(X[i * n + 1], X[i * n])

    @numba.cfunc(sig, error_model="numpy")
    def jac_h(X, k, n, t, u, out):
        for i in range(k):
            x, J = i * n, i * 2 * n
            r2 = X[x] * X[x] + X[x + 1] * X[x + 1]
            r = math.sqrt(r2)
            for e in range(2 * n):
                out[J + e] = 0.0
            out[J], out[J + 1] = X[x] / r, X[x + 1] / r
            out[J + n], out[J + n + 1] = -X[x + 1] / r2, X[x] / r2

    return (
        kfast.NonlinearModel(f, h, ct.Q, R, n=5, angles=[1], jac_f=jac_f, jac_h=jac_h),
        kfast.NonlinearModel(f, h, ct.Q, R, n=5, angles=[1]),
    )


PEER_VENV = "/work/venv-peers"
PEER_HOWTO = f"python3 -m venv {PEER_VENV} && {PEER_VENV}/bin/pip install numpy scipy jax dynamax stonesoup"


def run_peers(ct, y, rounds, runs):
    """Times the peers of ``runs`` ({name: steps}) in the peer venv (benches/peers_nonlinear.py):
    {name: (seconds per call, x_filt) or error}, and the peers' versions."""
    import json
    import subprocess
    import tempfile

    python = os.environ.get("KFAST_PEER_PYTHON") or f"{PEER_VENV}/bin/python"
    if not os.path.exists(python):
        return {name: f"peer venv missing: {PEER_HOWTO} (or set KFAST_PEER_PYTHON)" for name in runs}, {}
    with tempfile.TemporaryDirectory() as d:
        for name, a in {"y": y, "Q": ct.Q, "R": R, "x0": X0, "P0": P0}.items():
            np.save(os.path.join(d, name + ".npy"), np.asarray(a, dtype=float))
        with open(os.path.join(d, "job.json"), "w") as f:
            json.dump({"rounds": rounds, "runs": runs}, f)
        script = os.path.join(os.path.dirname(__file__), "peers_nonlinear.py")
        done = subprocess.run([python, script, d], capture_output=True, text=True)
        if done.returncode:
            error = "peer script failed: " + (done.stderr.strip().splitlines() or ["?"])[-1][:100]
            return {name: error for name in runs}, {}
        with open(os.path.join(d, "timings.json")) as f:
            job = json.load(f)
        out = {}
        for name, r in job["runs"].items():
            out[name] = r["error"] if "error" in r else (r["samples"], np.load(os.path.join(d, name + ".x_filt.npy")))
        return out, job["versions"]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    rounds = 3 if args.quick else 7
    T, T_py, T_peer = (20_000, 2_000, 300) if args.quick else (100_000, 10_000, 2_000)
    ct, y = simulate(T)
    radar = kfast.models.range_bearing((0.0, 0.0))
    builtin = kfast.NonlinearModel(ct, radar, ct.Q, R, n=5)
    python = kfast.NonlinearModel(
        ct_batch, rb_batch, ct.Q, R, n=5, jac_f=lambda X, t, u: np.array([ct_jac_one(x) for x in X]),
        jac_h=lambda X, t, u: np.array([rb_jac_one(x) for x in X]), angles=[1],
    )
    # kfast's own cost per step with a Python model: the same filter on a model that does
    # nothing, beside the bench's NumPy model alone (f and h at the 11 points of a step)
    identity = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X[:, :2], ct.Q, R, n=5, angles=[1])
    points11 = np.tile(X0, (11, 1))

    def model_alone():
        for t in range(T_py):
            rb_batch(ct_batch(points11, t, None), t, None)

    compiled = compiled_model(ct)
    jitted, differenced = numba_model(ct) or (None, None)
    merwe = kfast.sigma.merwe(0.5, 2.0, 0.0)
    out = ("x_filt", "P_filt")
    cv = kfast.models.constant_velocity(2, DT, q=1.0, r=1.0)
    cv_nl = kfast.NonlinearModel.from_linear(cv)
    y_cv = cv.simulate(T, [1, -1, 0.5, 0.2], np.diag([10, 10, 1, 1.0]), seed=1).y
    lin5 = kfast.LinearGaussian(ct_jac_one(X0), rb_jac_one(X0), ct.Q, R)
    workloads = {
        "N1: UKF on CT (Merwe 0.5, 2, 0)": [
            Contender("kfast built-in", lambda: builtin.ukf(y, X0, P0, points=merwe, outputs=out), T),
            Contender("kfast compiled C (cfunc path)", lambda: compiled.ukf(y, X0, P0, points=merwe, outputs=out), T),
            Contender("kfast numba cfunc", lambda: jitted.ukf(y, X0, P0, points=merwe, outputs=out), T),
            Contender("kfast Python callable", lambda: python.ukf(y[:T_py], X0, P0, points=merwe, outputs=out), T_py),
            Contender("  of which the NumPy model alone (f, h at 11 points)", model_alone, T_py),
            Contender("  kfast Python callable, a model doing nothing", lambda: identity.ukf(y[:T_py], X0, P0, points=merwe, outputs=out), T_py),
            Contender("filterpy UKF", filterpy_ukf(ct, y[:T_peer]), T_peer),
            Contender("dynamax UKF", None, T),  # these run in the peer venv (run_peers)
            Contender("Stone Soup UKF", None, T_peer),
        ],
        "N1b: UKF on the CV model (n = 4, m = 2)": [
            Contender("kfast built-in", lambda: cv_nl.ukf(y_cv, [1, -1, 0.5, 0.2], np.diag([10, 10, 1, 1.0]), points=merwe, outputs=out), T),
            Contender("kfast linear filter (same model)", lambda: cv.filter(y_cv, [1, -1, 0.5, 0.2], np.diag([10, 10, 1, 1.0]), outputs=out), T),
        ],
        "N2: EKF on CT (analytic Jacobians)": [
            Contender("kfast built-in", lambda: builtin.ekf(y, X0, P0, outputs=out), T),
            Contender("kfast compiled C (cfunc path; compiled Jacobians)", lambda: compiled.ekf(y, X0, P0, outputs=out), T),
            Contender("kfast numba cfunc (compiled Jacobians)", lambda: jitted.ekf(y, X0, P0, outputs=out), T),
            Contender("kfast numba cfunc (differenced Jacobians)", lambda: differenced.ekf(y, X0, P0, outputs=out), T),
            Contender("kfast Python callable", lambda: python.ekf(y[:T_py], X0, P0, outputs=out), T_py),
            Contender("filterpy EKF", filterpy_ekf(ct, y[:T_peer]), T_peer),
            Contender("dynamax EKF", None, T),
            Contender("kfast linear filter, n = 5, m = 2", lambda: lin5.filter(y, X0, P0, outputs=out), T),
        ],
    }
    peers = [c for contenders in workloads.values() for c in contenders if c.fn is None]
    timed, versions = run_peers(ct, y, rounds, {c.name: c.steps for c in peers})
    print(
        f"kfast {kfast.__version__}; T = {T:,} (Python callables {T_py:,}, filterpy and Stone Soup {T_peer:,}); "
        f"{rounds} rounds, medians"
    )
    numba_version = __import__("numba").__version__ if jitted is not None else "not installed"
    print("peers: " + ", ".join(f"{k} {v}" for k, v in {**versions, "numba": numba_version}.items()))
    reference = {
        "N1": builtin.ukf(y, X0, P0, points=merwe).x_filt,
        "N2": builtin.ekf(y, X0, P0).x_filt,
    }
    checks = {
        "N1": [("kfast Python callable", python.ukf(y[:T_py], X0, P0, points=merwe).x_filt), ("filterpy UKF", filterpy_ukf(ct, y[:T_peer])())],
        "N2": [("kfast Python callable", python.ekf(y[:T_py], X0, P0).x_filt), ("filterpy EKF", filterpy_ekf(ct, y[:T_peer])())],
    }
    for c in peers:
        if isinstance(timed[c.name], str):
            c.error = timed[c.name]
        else:
            c.samples, x = timed[c.name]
            note = " (S + 1e-9 I: see the docstring)" if "dynamax" in c.name else ""
            checks["N1" if "UKF" in c.name else "N2"].append((c.name + note, x))
    for i, (model, what, error) in enumerate(((compiled, "compiled", "no C compiler"), (jitted, "numba", "not installed"))):
        if model is None:
            for contenders in workloads.values():
                for c in contenders:
                    if what in c.name:
                        c.error = error
        else:
            checks["N1"].insert(i, (f"kfast {what}", model.ukf(y, X0, P0, points=merwe).x_filt))
            checks["N2"].insert(i, (f"kfast {what}", model.ekf(y, X0, P0).x_filt))
    if differenced is not None:
        after = [who for who, _ in checks["N2"]].index("kfast numba") + 1
        checks["N2"].insert(after, ("kfast numba (differenced Jacobians)", differenced.ekf(y, X0, P0).x_filt))
    for name, contenders in workloads.items():
        run_interleaved([c for c in contenders if c.fn is not None], rounds)
        base = contenders[0]
        print(f"\n{name}\n| contender | T | ns/step | IQR | /kfast built-in |\n|---|---:|---:|---:|---:|")
        for c in contenders:
            if not c.ok:
                print(f"| {c.name} | {c.steps:,} | - | - | {c.error} |")
                continue
            lo, hi = c.spread()
            print(f"| {c.name} | {c.steps:,} | {c.ns_per_step():,.0f} | {lo:,.0f}-{hi:,.0f} | {c.ns_per_step() / base.ns_per_step():.3g} |")
        key = name.split(":")[0]
        for who, x in checks.get(key, []):
            print(f"  check {who}: max|dx_filt| = {np.max(np.abs(x - reference[key][: len(x)])):.1e}")


if __name__ == "__main__":
    main()
