"""kfast.NonlinearModel with f, h and g written as numba ``@cfunc`` of the documented C signature
``void f(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out)``.

Each compiled model is checked two ways: against the same model written in NumPy (and the
NumPy reference filters, kfast.reference.nonlinear), which shows the cfunc computes the model;
and against the very same cfunc called from Python through ctypes (``via_python``), which runs
the Python-callable path of the Rust core: bit-for-bit equality there shows the direct C call
gets the same X (k x n, row-major), k, n, t, u and out layout. Then the streaming and batch
filters, the signature check (wrong signatures refused before any call, naming f, h or g), and
non-finite outputs (named with the step)."""

import ctypes
import re

import numba
import numpy as np
import pytest
import scipy
from numba import types
from test_noise_gain import speed_gain  # speed_gain_c in NumPy
from tracking import DT, ct, ct_jac, ct_problem, range_bearing, range_bearing_jac

import kfast
from kfast.reference import nonlinear as ref

FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "loglik_t", "x_next", "P_next")

double_p = types.CPointer(types.double)
SIGNATURE = types.void(double_p, types.intp, types.intp, types.int64, double_p, double_p)
"""kfast.nonlinear.model.C_SIGNATURE in numba's types."""

# ----------------------------------------------------------------------------------------------
# The compiled models (compiled once, at import: about a second for all of them)
# ----------------------------------------------------------------------------------------------


@numba.cfunc(SIGNATURE)
def ct_c(X, k, n, t, u, out):
    """The coordinated turn of tracking.py (n = 5)."""
    x, o = numba.carray(X, (k, n)), numba.carray(out, (k, n))
    for i in range(k):
        px, py, vx, vy, w = x[i, 0], x[i, 1], x[i, 2], x[i, 3], x[i, 4]
        s, c = np.sin(w * DT), np.cos(w * DT)
        if abs(w) < 1e-9:
            o[i, 0], o[i, 1], o[i, 2], o[i, 3] = px + DT * vx, py + DT * vy, vx, vy
        else:
            o[i, 0] = px + s / w * vx - (1 - c) / w * vy
            o[i, 1] = py + (1 - c) / w * vx + s / w * vy
            o[i, 2] = c * vx - s * vy
            o[i, 3] = s * vx + c * vy
        o[i, 4] = w


@numba.cfunc(SIGNATURE)
def radar_c(X, k, n, t, u, out):
    """Range and bearing from the origin (m = 2)."""
    x, o = numba.carray(X, (k, n)), numba.carray(out, (k, 2))
    for i in range(k):
        o[i, 0] = np.hypot(x[i, 0], x[i, 1])
        o[i, 1] = np.arctan2(x[i, 1], x[i, 0])


def ct_jacobian(scale):
    """The coordinated turn's Jacobian (tracking.ct_jac_one) times scale, k x n x n."""

    @numba.cfunc(SIGNATURE)
    def jac(X, k, n, t, u, out):
        x, J = numba.carray(X, (k, n)), numba.carray(out, (k, n, n))
        for i in range(k):
            vx, vy, w = x[i, 2], x[i, 3], x[i, 4]
            S, C = np.sin(w * DT), np.cos(w * DT)
            s, c = S / w, (1 - C) / w
            ds, dc = (w * DT * C - S) / w**2, (w * DT * S - (1 - C)) / w**2
            J[i, :, :] = 0.0
            J[i, 0, 0], J[i, 0, 2], J[i, 0, 3], J[i, 0, 4] = 1.0, s, -c, ds * vx - dc * vy
            J[i, 1, 1], J[i, 1, 2], J[i, 1, 3], J[i, 1, 4] = 1.0, c, s, dc * vx + ds * vy
            J[i, 2, 2], J[i, 2, 3], J[i, 2, 4] = C, -S, -DT * (S * vx + C * vy)
            J[i, 3, 2], J[i, 3, 3], J[i, 3, 4] = S, C, DT * (C * vx - S * vy)
            J[i, 4, 4] = 1.0
            J[i] *= scale

    return jac


ct_jac_c = ct_jacobian(1.0)
ct_jac_scaled_c = ct_jacobian(1.01)


@numba.cfunc(SIGNATURE)
def radar_jac_c(X, k, n, t, u, out):
    """Range and bearing's Jacobian, k x m x n."""
    x, J = numba.carray(X, (k, n)), numba.carray(out, (k, 2, n))
    for i in range(k):
        px, py = x[i, 0], x[i, 1]
        r2 = px * px + py * py
        r = np.sqrt(r2)
        J[i, :, :] = 0.0
        J[i, 0, 0], J[i, 0, 1] = px / r, py / r
        J[i, 1, 0], J[i, 1, 1] = -py / r2, px / r2


@numba.cfunc(SIGNATURE)
def speed_gain_c(X, k, n, t, u, out):
    """A state-dependent noise gain, k x n x r (r = 3): acceleration noise along and across the
    velocity, and the turn rate's (tests/nonlinear/test_noise_gain.py's speed_gain)."""
    x, G = numba.carray(X, (k, n)), numba.carray(out, (k, n, 3))
    for i in range(k):
        v = np.hypot(x[i, 2], x[i, 3])
        c, s = x[i, 2] / v, x[i, 3] / v
        G[i, :, :] = 0.0
        G[i, 0, 0], G[i, 1, 0], G[i, 2, 0], G[i, 3, 0] = DT**2 / 2 * c, DT**2 / 2 * s, DT * c, DT * s
        G[i, 0, 1], G[i, 1, 1], G[i, 2, 1], G[i, 3, 1] = -DT**2 / 2 * s, DT**2 / 2 * c, -DT * s, DT * c
        G[i, 4, 2] = DT


# A seeded random model whose f and h depend on the step t and the inputs u (n = 3, m = 2, two
# inputs): x+ = A x + c * sin(x rolled) + cos(0.3 t) B u,  y = H x + d * cos(x) + (1 + 0.1 t) D u.
# Sums are written out in the same order in both versions, and NumPy's sin and cos are the
# ones numba calls: the two agree bit for bit, so the reference comparison is tight.
_rng = np.random.default_rng(20260101)
A_U = _rng.normal(size=(3, 3))
A_U *= 0.95 / np.abs(np.linalg.eigvals(A_U)).max()
C_U = 0.5 * _rng.normal(size=3)
B_U = _rng.normal(size=(3, 2))
H_U = _rng.normal(size=(2, 3))
D_U = 0.5 * _rng.normal(size=2)
E_U = _rng.normal(size=(2, 2))


@numba.cfunc(SIGNATURE)
def f_u_c(X, k, n, t, u, out):
    x, o, uu = numba.carray(X, (k, n)), numba.carray(out, (k, n)), numba.carray(u, (2,))
    for i in range(k):
        for j in range(3):
            lin = A_U[j, 0] * x[i, 0] + A_U[j, 1] * x[i, 1] + A_U[j, 2] * x[i, 2]
            o[i, j] = lin + C_U[j] * np.sin(x[i, (j + 1) % 3]) + np.cos(0.3 * t) * (B_U[j, 0] * uu[0] + B_U[j, 1] * uu[1])


@numba.cfunc(SIGNATURE)
def h_u_c(X, k, n, t, u, out):
    x, o, uu = numba.carray(X, (k, n)), numba.carray(out, (k, 2)), numba.carray(u, (2,))
    for i in range(k):
        for j in range(2):
            lin = H_U[j, 0] * x[i, 0] + H_U[j, 1] * x[i, 1] + H_U[j, 2] * x[i, 2]
            o[i, j] = lin + D_U[j] * np.cos(x[i, j]) + (1 + 0.1 * t) * (E_U[j, 0] * uu[0] + E_U[j, 1] * uu[1])


def f_u(X, t, u):
    lin = [A_U[j, 0] * X[:, 0] + A_U[j, 1] * X[:, 1] + A_U[j, 2] * X[:, 2] for j in range(3)]
    return np.stack(
        [lin[j] + C_U[j] * np.sin(X[:, (j + 1) % 3]) + np.cos(0.3 * t) * (B_U[j, 0] * u[0] + B_U[j, 1] * u[1]) for j in range(3)],
        axis=1,
    )


def h_u(X, t, u):
    lin = [H_U[j, 0] * X[:, 0] + H_U[j, 1] * X[:, 1] + H_U[j, 2] * X[:, 2] for j in range(2)]
    return np.stack(
        [lin[j] + D_U[j] * np.cos(X[:, j]) + (1 + 0.1 * t) * (E_U[j, 0] * u[0] + E_U[j, 1] * u[1]) for j in range(2)],
        axis=1,
    )


Q_U = np.diag([0.02, 0.01, 0.03])
Q3 = np.diag([1.0, 0.1, 0.05**2 / DT])
"""Q of the noise w (r = 3) that speed_gain_c maps into the state."""
R_U = np.array([[0.1, 0.02], [0.02, 0.05]])
X0_U, P0_U = np.array([0.5, -0.3, 0.2]), np.diag([0.5, 0.5, 0.5])


def input_problem(T=40, seed=8):
    """Data simulated from the input model, with inputs u (T, 2); some values missing."""
    rng = np.random.default_rng(seed)
    U = rng.normal(size=(T, 2))
    x0, P0 = X0_U, P0_U
    x = rng.multivariate_normal(x0, P0)
    y = np.zeros((T, 2))
    for t in range(T):
        y[t] = h_u(x[None], t, U[t])[0] + rng.multivariate_normal(np.zeros(2), R_U)
        x = f_u(x[None], t, U[t])[0] + rng.multivariate_normal(np.zeros(3), Q_U)
    y[6 % T, 1] = np.nan
    y[11 % T] = np.nan
    return y, U, x0, P0


def via_python(cfunc, *shape):
    """The cfunc as a Python callable f(X, t, u) returning (k, *shape) (called through ctypes),
    so that the Rust core takes its Python-callable path with the very same arithmetic."""
    dp = ctypes.POINTER(ctypes.c_double)

    def fn(X, t, u):
        X = np.ascontiguousarray(X, dtype=np.float64)
        out = np.empty((len(X),) + shape)
        u_p = ctypes.cast(None, dp) if u is None else np.ascontiguousarray(u, dtype=np.float64).ctypes.data_as(dp)
        cfunc.ctypes(X.ctypes.data_as(dp), len(X), X.shape[1], t, u_p, out.ctypes.data_as(dp))
        return out

    return fn


def ct_data(T=60):
    Q, R, y, x0, P0 = ct_problem(T=T)
    y = y.copy()
    y[4 % T] = np.nan
    y[9 % T, 1] = np.nan
    return Q, R, y, x0, P0


def assert_fields(a, b, rtol, atol, fields=FIELDS):
    for k in fields:
        np.testing.assert_allclose(getattr(a, k), getattr(b, k) if not isinstance(b, dict) else b[k], rtol=rtol, atol=atol, err_msg=k)
    want = b["loglik"] if isinstance(b, dict) else b.loglik
    assert a.loglik == pytest.approx(want, rel=max(rtol, 1e-10), abs=atol)


def assert_identical(a, b, fields=FIELDS):
    for k in fields:
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
    assert a.loglik == b.loglik


def runs(model, y, x0, P0, u=None):
    """Every nonlinear filter and smoother of kfast on one series."""
    pts = kfast.sigma.merwe(0.5)
    return {
        "ekf": model.ekf(y, x0, P0, u=u),
        "iterated": model.ekf(y, x0, P0, u=u, iterations=2, iteration="gauss-newton"),
        "ukf": model.ukf(y, x0, P0, u=u, points=pts),
        "cubature": model.ukf(y, x0, P0, u=u, points=kfast.sigma.cubature()),
        "eks": model.smooth(y, x0, P0, u=u, method="ekf"),
        "urts": model.smooth(y, x0, P0, u=u, method="ukf", points=pts),
    }


def assert_runs_identical(a, b):
    for name in a:
        if name in ("eks", "urts"):
            for k in ("x_smooth", "P_smooth", "P_lag1"):
                np.testing.assert_array_equal(getattr(a[name], k), getattr(b[name], k), err_msg=(name, k))
            assert_identical(a[name].filter, b[name].filter)
        else:
            assert_identical(a[name], b[name])


def assert_runs_close(a, b, tol):
    for name in a:
        if name in ("eks", "urts"):
            for k in ("x_smooth", "P_smooth", "P_lag1"):
                np.testing.assert_allclose(getattr(a[name], k), getattr(b[name], k), rtol=tol, atol=tol, err_msg=(name, k))
            assert_fields(a[name].filter, b[name].filter, rtol=tol, atol=tol)
        else:
            assert_fields(a[name], b[name], rtol=tol, atol=tol)


# ----------------------------------------------------------------------------------------------
# f and h compiled: the same numbers as the Python callables and the reference
# ----------------------------------------------------------------------------------------------


def test_compiled_coordinated_turn_and_radar_are_the_same_model_as_python_callables():
    Q, R, y, x0, P0 = ct_data()
    compiled = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1])
    # the same functions through the Python-callable path: the same numbers, bit for bit
    same = kfast.NonlinearModel(via_python(ct_c, 5), via_python(radar_c, 2), Q, R, n=5, angles=[1])
    assert_runs_identical(runs(compiled, y, x0, P0), runs(same, y, x0, P0))
    # a scipy.LowLevelCallable of the cfunc is the same function
    low_level = kfast.NonlinearModel(scipy.LowLevelCallable(ct_c.ctypes), scipy.LowLevelCallable(radar_c.ctypes), Q, R, n=5, angles=[1])
    assert_identical(low_level.ukf(y, x0, P0), compiled.ukf(y, x0, P0))
    # the NumPy model: NumPy's arctan2 (SIMD) and libm's, which numba calls, differ by an ulp
    # now and then; the UKF keeps that at rounding level, the EKF's differenced Jacobian of the
    # weakly observed turn rate amplifies it (as for the C model in test_nonlinear_filters.py)
    numpy_model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    a, b = compiled.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5)), numpy_model.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5))
    assert_fields(a, b, rtol=1e-9, atol=1e-10)
    assert_fields(compiled.ekf(y, x0, P0), numpy_model.ekf(y, x0, P0), rtol=1e-7, atol=1e-8)


def test_compiled_coordinated_turn_and_radar_equal_the_reference():
    Q, R, y, x0, P0 = ct_data()
    compiled = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1])
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), angles=[1])
    assert_fields(compiled.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5)), want, rtol=1e-9, atol=1e-10)
    want = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, angles=[1])
    assert_fields(compiled.ekf(y, x0, P0), want, rtol=1e-7, atol=1e-8)
    for method, (xs, Ps, _) in (
        ("ukf", ref.unscented_rts(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), angles=[1])),
        ("ekf", ref.extended_rts(ct, range_bearing, Q, R, y, x0, P0, angles=[1])),
    ):
        got = compiled.smooth(y, x0, P0, method=method, points=kfast.sigma.merwe(0.5))
        tol = 1e-9 if method == "ukf" else 1e-7
        np.testing.assert_allclose(got.x_smooth, xs, rtol=tol, atol=tol, err_msg=method)
        np.testing.assert_allclose(got.P_smooth, Ps, rtol=tol, atol=tol, err_msg=method)


def test_t_and_u_reach_compiled_functions():
    """f and h depending on the step and the inputs: every filter and smoother equals the
    Python-callable path bit for bit, the NumPy model to 1e-10, and the NumPy reference as closely as
    the Python callables do (test_nonlinear_filters.py, test_noise_gain.py): 1e-10 for the UKF,
    1e-9 for the EKF (whose Jacobians by differences round differently there)."""
    y, U, x0, P0 = input_problem()
    compiled = kfast.NonlinearModel(f_u_c, h_u_c, Q_U, R_U, n=3)
    same = kfast.NonlinearModel(via_python(f_u_c, 3), via_python(h_u_c, 2), Q_U, R_U, n=3)
    numpy_model = kfast.NonlinearModel(f_u, h_u, Q_U, R_U, n=3)
    got = runs(compiled, y, x0, P0, u=U)
    assert_runs_identical(got, runs(same, y, x0, P0, u=U))
    # (bit for bit here, where NumPy's sin and cos are libm's; 1e-10 allows for an ulp elsewhere)
    assert_runs_close(got, runs(numpy_model, y, x0, P0, u=U), 1e-10)
    assert_fields(got["ekf"], ref.ekf(f_u, h_u, Q_U, R_U, y, x0, P0, u=U), rtol=1e-9, atol=1e-9)
    assert_fields(got["iterated"], ref.ekf(f_u, h_u, Q_U, R_U, y, x0, P0, u=U, iterations=2, iteration="gauss-newton"), rtol=1e-9, atol=1e-9)
    assert_fields(got["ukf"], ref.ukf(f_u, h_u, Q_U, R_U, y, x0, P0, points=ref.merwe(0.5), u=U), rtol=1e-10, atol=1e-10)
    for name, (xs, Ps, _), tol in (
        ("eks", ref.extended_rts(f_u, h_u, Q_U, R_U, y, x0, P0, u=U), 1e-9),
        ("urts", ref.unscented_rts(f_u, h_u, Q_U, R_U, y, x0, P0, points=ref.merwe(0.5), u=U), 1e-10),
    ):
        np.testing.assert_allclose(got[name].x_smooth, xs, rtol=tol, atol=tol, err_msg=name)
        np.testing.assert_allclose(got[name].P_smooth, Ps, rtol=tol, atol=tol, err_msg=name)
    # t and u matter: another step numbering (u shifted by one) or no inputs give other numbers
    for other in (np.roll(U, 1, axis=0), np.zeros_like(U)):
        assert np.abs(compiled.ekf(y, x0, P0, u=other).x_filt - got["ekf"].x_filt).max() > 1e-2


# ----------------------------------------------------------------------------------------------
# Jacobians and the noise gain compiled
# ----------------------------------------------------------------------------------------------


def test_a_compiled_noise_gain_is_used():
    """g compiled (k x n x r out, r = 3, Q of shape (r, r)): the Python g's numbers and the reference's."""
    _, R, y, x0, P0 = ct_data(T=40)
    compiled = kfast.NonlinearModel(ct_c, radar_c, Q3, R, n=5, angles=[1], g=speed_gain_c)
    # the same f and h with g a NumPy function (the same arithmetic: hypot and divisions)
    numpy_gain = kfast.NonlinearModel(ct_c, radar_c, Q3, R, n=5, angles=[1], g=speed_gain)
    same = kfast.NonlinearModel(ct_c, radar_c, Q3, R, n=5, angles=[1], g=via_python(speed_gain_c, 5, 3))
    got = runs(compiled, y, x0, P0)
    assert_runs_identical(got, runs(same, y, x0, P0))
    assert_runs_close(got, runs(numpy_gain, y, x0, P0), 1e-10)
    want = ref.ukf(ct, range_bearing, Q3, R, y, x0, P0, points=ref.merwe(0.5), g=speed_gain, angles=[1])
    assert_fields(got["ukf"], want, rtol=1e-9, atol=1e-10)
    want = ref.ekf(ct, range_bearing, Q3, R, y, x0, P0, g=speed_gain, angles=[1])
    assert_fields(got["ekf"], want, rtol=1e-7, atol=1e-8)
    # the gain matters: Q folded with the prior's gain gives another filter
    G0 = speed_gain(x0[None], 0, None)[0]
    fixed = kfast.NonlinearModel(ct_c, radar_c, G0 @ Q3 @ G0.T, R, n=5, angles=[1]).ekf(y, x0, P0)
    assert np.abs(fixed.P_next - got["ekf"].P_next).max() > 1e-3 * np.abs(got["ekf"].P_next).max()


@pytest.mark.parametrize("f, h", [(ct_c, radar_c), (ct, range_bearing)], ids=["compiled f and h", "python f and h"])
def test_compiled_jacobians_are_used(f, h):
    Q, R, y, x0, P0 = ct_data()
    # a Jacobian of f that is not the model's (the true one times 1.01), so that using it shows
    scaled = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1], jac_f=lambda X, t, u: 1.01 * ct_jac(X, t, u), jac_h=range_bearing_jac)
    want = scaled.ekf(y, x0, P0)
    model = kfast.NonlinearModel(f, h, Q, R, n=5, angles=[1], jac_f=ct_jac_scaled_c, jac_h=radar_jac_c)
    assert_fields(model.ekf(y, x0, P0), want, rtol=1e-7, atol=1e-8)


def test_python_jacobians_of_compiled_functions_are_used():
    Q, R, y, x0, P0 = ct_data()
    jac_f = lambda X, t, u: 1.01 * ct_jac(X, t, u)  # noqa: E731  (not the model's: using it shows)
    want = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1], jac_f=jac_f, jac_h=range_bearing_jac).ekf(y, x0, P0)
    model = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1], jac_f=jac_f, jac_h=range_bearing_jac)
    assert_fields(model.ekf(y, x0, P0), want, rtol=1e-7, atol=1e-8)


def test_a_python_hessian_of_a_compiled_f_is_used():
    Q, R, y, x0, P0 = ct_data(T=30)
    hess_f = lambda X, t, u: np.full((len(X), 5, 5, 5), 1e-3)  # noqa: E731  (not the model's: using it shows)
    want = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1], hess_f=hess_f).ekf(y, x0, P0, order=2)
    got = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1], hess_f=hess_f).ekf(y, x0, P0, order=2)
    assert_fields(got, want, rtol=1e-7, atol=1e-8)


def test_the_compiled_jacobians_are_right():
    """The cfuncs of the expected failures above are the Jacobians they claim to be (called
    directly): those tests fail for kfast's reason, not theirs; and the scaled Jacobian makes a
    difference when it is used."""
    rng = np.random.default_rng(3)
    X = np.array([100.0, 50.0, 5.0, -2.0, 0.1]) + rng.normal(size=(7, 5))
    for cfunc, scale in ((ct_jac_c, 1.0), (ct_jac_scaled_c, 1.01)):
        got = via_python(cfunc, 25)(X, 0, None).reshape(7, 5, 5)
        np.testing.assert_allclose(got, scale * ct_jac(X, 0, None), rtol=1e-12, atol=1e-14)
    got = via_python(radar_jac_c, 10)(X, 0, None).reshape(7, 2, 5)
    np.testing.assert_allclose(got, range_bearing_jac(X, 0, None), rtol=1e-12, atol=1e-16)
    Q, R, y, x0, P0 = ct_data()
    scaled = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1], jac_f=lambda X, t, u: 1.01 * ct_jac(X, t, u), jac_h=range_bearing_jac)
    differenced = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1])
    assert np.abs(scaled.ekf(y, x0, P0).P_next - differenced.ekf(y, x0, P0).P_next).max() > 1e-3


# ----------------------------------------------------------------------------------------------
# Streaming and batch filters
# ----------------------------------------------------------------------------------------------


def test_streaming_filters_run_compiled_models():
    Q, R, y, x0, P0 = ct_data(T=20)
    model = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1])
    for stream, whole in (
        (kfast.ExtendedKalmanFilter(model, x0, P0), model.ekf(y, x0, P0)),
        (kfast.UnscentedKalmanFilter(model, x0, P0, points=kfast.sigma.merwe(0.5)), model.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5))),
    ):
        for t in range(len(y)):
            stream.update(y[t])
            np.testing.assert_allclose(stream.x, whole.x_filt[t], rtol=1e-13, atol=1e-13)
            np.testing.assert_allclose(stream.P, whole.P_filt[t], rtol=1e-13, atol=1e-13)
            stream.predict()
        np.testing.assert_allclose(stream.P, whole.P_next, rtol=1e-13, atol=1e-13)
        assert stream.loglik == pytest.approx(whole.loglik, rel=1e-12)
    # with inputs, t and u given step by step
    yu, U, xu, Pu = input_problem(T=15)
    model_u = kfast.NonlinearModel(f_u_c, h_u_c, Q_U, R_U, n=3)
    whole = model_u.ukf(yu, xu, Pu, u=U)
    stream = kfast.UnscentedKalmanFilter(model_u, xu, Pu)
    for t in range(len(yu)):
        stream.update(yu[t], U[t])
        np.testing.assert_allclose(stream.x, whole.x_filt[t], rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(stream.P, whole.P_filt[t], rtol=1e-13, atol=1e-13)
        stream.predict(U[t])
    np.testing.assert_allclose(stream.x, whole.x_next, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(stream.P, whole.P_next, rtol=1e-13, atol=1e-13)


def test_a_second_sensor_given_as_a_compiled_function():
    """update(y, h=cfunc, R=...) uses the compiled h: the same as its Python-callable path."""
    Q, R, y, x0, P0 = ct_data(T=10)
    model = kfast.NonlinearModel(kfast.models.coordinated_turn(DT), kfast.models.range_bearing((50.0, 0.0)), Q, R, n=5)
    a, b = kfast.UnscentedKalmanFilter(model, x0, P0), kfast.UnscentedKalmanFilter(model, x0, P0)
    e = kfast.ExtendedKalmanFilter(model, x0, P0)
    for t in range(len(y)):
        a.update(y[t], h=radar_c, R=R, angles=[1])
        b.update(y[t], h=via_python(radar_c, 2), R=R, angles=[1])
        e.update(y[t], h=radar_c, R=R, angles=[1])
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.P, b.P)
        for s in (a, b, e):
            s.predict()
    assert a.loglik == b.loglik
    # the second sensor (at the origin) is not the model's (at (50, 0)): it was used
    own = model.ukf(y, x0, P0)
    assert np.abs(own.x_next - a.x).max() > 1.0
    # the EKF through the second sensor is the EKF of the model whose own h is that sensor
    origin = kfast.NonlinearModel(kfast.models.coordinated_turn(DT), radar_c, Q, R, n=5, angles=[1])
    np.testing.assert_allclose(e.x, origin.ekf(y, x0, P0).x_next, rtol=1e-12, atol=1e-12)


def batch_tracks(B=6, T=30):
    Q, R, _, x0, P0 = ct_problem(T=T)
    Y = np.stack([ct_problem(T=T, seed=200 + b)[2] for b in range(B)])
    Y[1, 5, 0] = np.nan
    Y[2, 7:9, :] = np.nan
    rng = np.random.default_rng(6)
    X0 = x0 + rng.normal(0.0, 1.0, (B, 5)) * [3, 3, 0.5, 0.5, 0.01]
    P0s = np.stack([P0 * s for s in rng.uniform(0.5, 2.0, B)])
    return Q, R, Y, X0, P0s


@pytest.mark.parametrize("threads", [1, 2, None])
def test_batch_filters_run_compiled_models_as_each_series_alone(threads):
    Q, R, Y, X0, P0s = batch_tracks()
    model = kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1], g=None)
    pts = kfast.sigma.merwe(0.5)
    for batch, single in (
        (lambda: kfast.ekf_batch(model, Y, X0, P0s, threads=threads), lambda b: model.ekf(Y[b], X0[b], P0s[b])),
        (
            lambda: kfast.ekf_batch(model, Y, X0, P0s, threads=threads, iterations=2, iteration="gauss-newton"),
            lambda b: model.ekf(Y[b], X0[b], P0s[b], iterations=2, iteration="gauss-newton"),
        ),
        (lambda: kfast.ukf_batch(model, Y, X0, P0s, points=pts, threads=threads), lambda b: model.ukf(Y[b], X0[b], P0s[b], points=pts)),
    ):
        res = batch()
        for b in range(len(Y)):
            one = single(b)
            np.testing.assert_array_equal(res.x_filt[b], one.x_filt)
            np.testing.assert_array_equal(res.P_filt[b], one.P_filt)
            assert res.loglik[b] == one.loglik
    # per-series inputs, and a compiled noise gain, reach the compiled functions on each thread
    rng = np.random.default_rng(9)
    Yu = np.stack([input_problem(T=20, seed=300 + b)[0] for b in range(5)])
    U = rng.normal(size=(5, 20, 2))
    model_u = kfast.NonlinearModel(f_u_c, h_u_c, Q_U, R_U, n=3)
    x0u, P0u = X0_U, P0_U
    for res, single in (
        (kfast.ukf_batch(model_u, Yu, x0u, P0u, u=U, threads=threads), lambda b: model_u.ukf(Yu[b], x0u, P0u, u=U[b])),
        (kfast.ekf_batch(model_u, Yu, x0u, P0u, u=U, threads=threads), lambda b: model_u.ekf(Yu[b], x0u, P0u, u=U[b])),
    ):
        for b in range(len(Yu)):
            one = single(b)
            np.testing.assert_array_equal(res.x_filt[b], one.x_filt)
            assert res.loglik[b] == one.loglik
    gained = kfast.NonlinearModel(ct_c, radar_c, Q3, R, n=5, angles=[1], g=speed_gain_c)
    res = kfast.ukf_batch(gained, Y, X0, P0s, points=pts, threads=threads)
    for b in range(len(Y)):
        np.testing.assert_array_equal(res.P_filt[b], gained.ukf(Y[b], X0[b], P0s[b], points=pts).P_filt)


# ----------------------------------------------------------------------------------------------
# Wrong signatures: refused when the model is made, naming the argument
# ----------------------------------------------------------------------------------------------

# numba's ctypes names for intp and int64 (c_long on Linux), as the error message shows them
SZ, I64 = ctypes.c_ssize_t.__name__, ctypes.c_int64.__name__
F32, VOID, INTP = types.CPointer(types.float32), types.voidptr, types.intp
WRONG = {  # a signature, and what the message shows of it
    "int32 sizes": (types.void(double_p, types.int32, types.int32, types.int64, double_p, double_p), rf"\(LP_c_double, c_int, c_int, {I64}, "),
    "int32 step": (types.void(double_p, INTP, INTP, types.int32, double_p, double_p), rf"\(LP_c_double, {SZ}, {SZ}, c_int, "),
    "unsigned sizes": (types.void(double_p, types.uintp, types.uintp, types.int64, double_p, double_p), rf"\(LP_c_double, c_ulong, c_ulong, {I64}, "),
    "float32 pointers": (types.void(F32, INTP, INTP, types.int64, F32, F32), rf"\(LP_c_float, {SZ}, {SZ}, {I64}, LP_c_float, LP_c_float\) -> None"),
    "void pointers": (types.void(VOID, INTP, INTP, types.int64, VOID, VOID), r"\(c_void_p, .*, c_void_p\) -> None"),
    "returns int64": (types.int64(double_p, INTP, INTP, types.int64, double_p, double_p), rf"LP_c_double\) -> <class 'ctypes.{I64}'>"),
    "returns double": (types.double(double_p, INTP, INTP, types.int64, double_p, double_p), r"LP_c_double\) -> <class 'ctypes.c_double'>"),
    "5 arguments": (types.void(double_p, INTP, INTP, types.int64, double_p), rf"\(LP_c_double, {SZ}, {SZ}, {I64}, LP_c_double\) -> None"),
    "7 arguments": (types.void(double_p, INTP, INTP, types.int64, double_p, double_p, INTP), rf"LP_c_double, LP_c_double, {SZ}\) -> None"),
}


def _stub(sig):
    """A cfunc of the signature sig doing nothing."""
    args = ", ".join(f"a{i}" for i in range(len(sig.args)))
    body = "    return 0\n" if sig.return_type != types.void else "    pass\n"
    namespace = {}
    exec(f"def fn({args}):\n{body}", namespace)
    return numba.cfunc(sig)(namespace["fn"])


@pytest.fixture(scope="module")
def wrong_cfuncs():
    return {name: (_stub(sig), shown) for name, (sig, shown) in WRONG.items()}


def test_numbas_own_signature_is_the_documented_one():
    assert ct_c.ctypes.restype is None
    assert [t.__name__ for t in ct_c.ctypes.argtypes] == ["LP_c_double", SZ, SZ, I64, "LP_c_double", "LP_c_double"]
    assert ct_c.ctypes.argtypes[0] is ctypes.POINTER(ctypes.c_double)
    assert kfast.nonlinear.model._compiled_address("f", ct_c) == ct_c.address


@pytest.mark.parametrize("name", list(WRONG))
def test_a_cfunc_of_another_signature_is_refused_naming_the_argument(name, wrong_cfuncs):
    """Refused when the model (or the second sensor) is given, before any filter calls it."""
    bad, shown = wrong_cfuncs[name]
    Q, R, y, x0, P0 = ct_data(T=5)
    sig = r"the compiled function's signature \(.*\) -> .* is not 'void \(const double \*X, intptr_t k, intptr_t n, int64_t t, const double \*u, double \*out\)'"
    for arg, make in (
        ("f", lambda: kfast.NonlinearModel(bad, radar_c, Q, R, n=5)),
        ("h", lambda: kfast.NonlinearModel(ct_c, bad, Q, R, n=5)),
        ("g", lambda: kfast.NonlinearModel(ct_c, radar_c, Q3, R, n=5, g=bad)),
    ):
        with pytest.raises(kfast.KfastError, match=rf"^{arg}: {sig}$") as err:
            make()
        assert re.search(shown, str(err.value)), (shown, str(err.value))
    with pytest.raises(kfast.KfastError, match=r"^f: the LowLevelCallable's signature '.*' is not 'void \(const double"):
        kfast.NonlinearModel(scipy.LowLevelCallable(bad.ctypes), radar_c, Q, R, n=5)
    # a second sensor of a streaming filter is checked the same way
    stream = kfast.ExtendedKalmanFilter(kfast.NonlinearModel(ct_c, radar_c, Q, R, n=5, angles=[1]), x0, P0)
    with pytest.raises(kfast.KfastError, match=rf"^h: {sig}$"):
        stream.update(y[0], h=bad, R=R)
    assert stream.t == 0
    np.testing.assert_array_equal(stream.x, x0)


# ----------------------------------------------------------------------------------------------
# Non-finite results: named with the function and the step
# ----------------------------------------------------------------------------------------------


def nan_at(step, cfunc_like, width):
    """A cfunc computing what ``cfunc_like`` computes, but NaN in its first output at ``step``."""
    inner = cfunc_like.ctypes

    @numba.cfunc(SIGNATURE)
    def fn(X, k, n, t, u, out):
        inner(X, k, n, t, u, out)
        if t == step:
            o = numba.carray(out, (k, width))
            for i in range(k):
                o[i, 0] = np.nan

    return fn


@pytest.fixture(scope="module")
def nan_cfuncs():
    return {"f": nan_at(5, ct_c, 5), "h": nan_at(3, radar_c, 2), "g": nan_at(4, speed_gain_c, 15)}


@pytest.mark.parametrize("arg, step", [("f", 5), ("h", 3), ("g", 4)])
def test_a_compiled_function_writing_nan_is_named_with_the_step(arg, step, nan_cfuncs):
    Q, R, y, x0, P0 = ct_data(T=10)
    fns = {"f": ct_c, "h": radar_c, "g": speed_gain_c, arg: nan_cfuncs[arg]}
    model = kfast.NonlinearModel(fns["f"], fns["h"], Q3, R, n=5, angles=[1], g=fns["g"])
    message = rf"^{arg} at step {step}: returned a non-finite value \(NaN\)"
    for run in (
        lambda: model.ekf(y, x0, P0),
        lambda: model.ukf(y, x0, P0),
        lambda: model.smooth(y, x0, P0, method="ekf"),
        lambda: model.smooth(y, x0, P0, method="ukf"),
    ):
        with pytest.raises(kfast.KfastError, match=message):
            run()
    stream = kfast.UnscentedKalmanFilter(model, x0, P0)
    with pytest.raises(kfast.KfastError, match=message):
        for t in range(len(y)):
            stream.step(y[t])
    assert stream.t == step
    with pytest.raises(kfast.KfastError, match=rf"^{arg} at step {step}: \(series 0\) returned a non-finite value \(NaN\)"):
        kfast.ekf_batch(model, np.stack([y, y]), x0, P0)
