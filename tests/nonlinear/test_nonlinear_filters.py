"""kfast.NonlinearModel's EKF and UKF (Rust) against the NumPy reference, the linear Kalman
filter and filterpy, with f and h as Python callables and as built-in Rust models."""

import numpy as np
import pytest
from modelgen import random_case
from tracking import DT, ct, ct_jac, ct_one, ct_problem, range_bearing, range_bearing_jac

import kfast
from kfast.reference import nonlinear as ref

FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "loglik_t", "x_next", "P_next")


def assert_close(res, want, rtol=1e-10, atol=1e-10, fields=FIELDS):
    for k in fields:
        got = getattr(res, k)
        np.testing.assert_allclose(got, want[k], rtol=rtol, atol=atol, err_msg=k)
    assert res.loglik == pytest.approx(want["loglik"], rel=rtol, abs=atol)


def linear_callables(F, H):
    return (lambda X, t, u: X @ F.T), (lambda X, t, u: X @ H.T)


@pytest.mark.parametrize("seed, n, m, missing", [(11, 1, 1, "none"), (12, 4, 2, "partial"), (13, 6, 3, "rows")])
def test_on_a_linear_model_every_filter_is_the_kalman_filter(seed, n, m, missing):
    c = random_case(seed, n, m, T=40, missing=missing)
    lg = kfast.LinearGaussian(**c.model)
    F, H, Q, R = (c.model[k] for k in "FHQR")
    f, h = linear_callables(F, H)
    models = [kfast.NonlinearModel.from_linear(lg), kfast.NonlinearModel(f, h, Q, R, n=n)]
    joseph = lg.filter(c.y, c.x0, c.P0)
    standard = lg.filter(c.y, c.x0, c.P0, form="standard")
    fields = [k for k in FIELDS if k not in ("innov",)]
    for nm, tol in zip(models, (1e-10, 1e-7)):  # the callables' Jacobians are differenced
        for kw in ({}, {"iterations": 2}, {"iterations": 2, "iteration": "gauss-newton"}):
            res = nm.ekf(c.y, c.x0, c.P0, **kw)
            for k in fields:
                np.testing.assert_allclose(getattr(res, k), getattr(joseph, k), rtol=tol, atol=tol, err_msg=(k, kw))
        for points in (kfast.sigma.merwe(), kfast.sigma.julier(kappa=1.0), kfast.sigma.cubature()):
            res = nm.ukf(c.y, c.x0, c.P0, points=points)
            for k in fields:
                np.testing.assert_allclose(getattr(res, k), getattr(standard, k), rtol=1e-9, atol=1e-9, err_msg=(k, points))
            assert res.loglik == pytest.approx(standard.loglik, rel=1e-10)
    np.testing.assert_array_equal(np.isnan(res.innov), np.isnan(standard.innov))


@pytest.mark.parametrize("missing", ["none", "partial"])
def test_on_a_linear_model_both_smoothers_are_rts(missing):
    c = random_case(21, 4, 2, T=35, missing=missing)
    lg = kfast.LinearGaussian(**c.model)
    want = lg.smooth(c.y, c.x0, c.P0)
    for nm in (kfast.NonlinearModel.from_linear(lg), kfast.NonlinearModel(*linear_callables(c.model["F"], c.model["H"]), c.model["Q"], c.model["R"], n=4)):
        for method in ("ekf", "ukf"):
            got = nm.smooth(c.y, c.x0, c.P0, method=method)
            for k in ("x_smooth", "P_smooth", "P_lag1"):
                np.testing.assert_allclose(getattr(got, k), getattr(want, k), rtol=1e-7, atol=1e-7, err_msg=(k, method))
            np.testing.assert_allclose(got.filter.x_filt, want.filter.x_filt, rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("method", ["ekf", "ukf"])
def test_smoothers_equal_the_reference(method):
    _, python, Q, R, y, x0, P0 = ct_models()
    y = y.copy()
    y[4] = np.nan
    if method == "ekf":
        xs, Ps, _ = ref.extended_rts(ct, range_bearing, Q, R, y, x0, P0, ct_jac, range_bearing_jac, angles=[1])
        got = python.smooth(y, x0, P0, method="ekf")
    else:
        xs, Ps, _ = ref.unscented_rts(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), angles=[1])
        got = python.smooth(y, x0, P0, method="ukf", points=kfast.sigma.merwe(0.5))
    np.testing.assert_allclose(got.x_smooth, xs, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.P_smooth, Ps, rtol=1e-9, atol=1e-9)
    assert np.all(np.diagonal(got.P_smooth, axis1=1, axis2=2) <= np.diagonal(got.filter.P_filt, axis1=1, axis2=2) + 1e-12)


def ct_models():
    Q, R, y, x0, P0 = ct_problem(T=60)
    builtin = kfast.NonlinearModel(
        kfast.models.coordinated_turn(DT, q=1.0, sigma_omega=0.05), kfast.models.range_bearing((0.0, 0.0)), Q, R, n=5
    )
    python = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, jac_f=ct_jac, jac_h=range_bearing_jac, angles=[1])
    return builtin, python, Q, R, y, x0, P0


def test_builtin_coordinated_turn_and_radar_equal_the_same_model_as_python_callables():
    builtin, python, Q, R, y, x0, P0 = ct_models()
    np.testing.assert_allclose(builtin.Q, Q, rtol=1e-15)
    differenced = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    for run in (lambda m: m.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5)), lambda m: m.ekf(y, x0, P0)):
        a, b, c = run(builtin), run(python), run(differenced)
        for k in FIELDS:
            # the NumPy model computes 1 - cos(w dt) with cancellation (~1e-12 relative here)
            np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=1e-8, atol=1e-8, err_msg=k)
            # Jacobians by differences (about 1e-10 relative) against the closed form
            np.testing.assert_allclose(getattr(c, k), getattr(b, k), rtol=1e-6, atol=1e-7, err_msg=k)


@pytest.mark.parametrize(
    "kw",
    [{}, {"iterations": 2}, {"iterations": 3, "iteration": "gauss-newton"}, {"form": "standard"}],
)
def test_ekf_equals_the_reference(kw):
    _, python, Q, R, y, x0, P0 = ct_models()
    y = y.copy()
    y[5, 0] = np.nan
    y[9] = np.nan
    form = kw.pop("form", "joseph")
    want = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, ct_jac, range_bearing_jac, angles=[1], form=form, **kw)
    assert_close(python.ekf(y, x0, P0, form=form, **kw), want, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("points", ["merwe", "merwe-small-alpha", "julier", "cubature"])
def test_ukf_equals_the_reference(points):
    _, python, Q, R, y, x0, P0 = ct_models()
    y = y.copy()
    y[7, 1] = np.nan
    mine, theirs = {
        "merwe": (kfast.sigma.merwe(0.5, 2.0, 0.0), ref.merwe(0.5, 2.0, 0.0)),
        "merwe-small-alpha": (kfast.sigma.merwe(), ref.merwe()),
        "julier": (kfast.sigma.julier(kappa=1.0), ref.julier(kappa=1.0)),
        "cubature": (kfast.sigma.cubature(), ref.cubature()),
    }[points]
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=theirs, angles=[1])
    # alpha = 1e-3 puts the points 1e-3 standard deviations apart: the mean's second-order term
    # d = sum W_i (h(X_i) - h(X_0)) is then a second difference with that step, which rounding
    # alone moves by ~1e-7 relative (the same in any implementation); the others agree to 1e-9
    tol = 1e-4 if points == "merwe-small-alpha" else 1e-9
    assert_close(python.ukf(y, x0, P0, points=mine), want, rtol=tol, atol=tol)


def test_ukf_equals_filterpy():
    filterpy = pytest.importorskip("filterpy.kalman")
    builtin, _, Q, R, y, x0, P0 = ct_models()
    points = filterpy.MerweScaledSigmaPoints(5, alpha=0.5, beta=2.0, kappa=0.0)
    kf = filterpy.UnscentedKalmanFilter(
        dim_x=5, dim_z=2, dt=DT, fx=lambda x, dt: ct_one(x), hx=lambda x: range_bearing(x[None], 0, None)[0], points=points
    )
    kf.x, kf.P, kf.Q, kf.R = x0.copy(), P0.copy(), Q, R
    kf.sigmas_f = points.sigma_points(x0, P0)  # filterpy predicts first: give it the prior's points
    x_filt = []
    for t in range(len(y)):
        if t:
            kf.predict()
        kf.update(y[t])
        x_filt.append(kf.x.copy())
    res = builtin.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5, 2.0, 0.0))
    np.testing.assert_allclose(res.x_filt, x_filt, rtol=1e-8, atol=1e-8)


def test_bearings_across_the_negative_x_axis_are_wrapped():
    """A target passing behind the sensor along y = 0, x < 0: the bearing jumps from pi to -pi.
    With the bearing declared an angle the innovations stay small; the filter tracks."""
    T = 40
    truth = np.stack([np.full(T, -50.0), np.linspace(3, -3, T), np.zeros(T), np.full(T, -1.5), np.zeros(T)], axis=1)
    y = np.stack([np.hypot(truth[:, 0], truth[:, 1]), np.arctan2(truth[:, 1], truth[:, 0])], axis=1)
    R = np.diag([0.1, 1e-4])
    Q = np.diag([1e-4, 1e-4, 1e-2, 1e-2, 1e-8])
    model = kfast.NonlinearModel(kfast.models.coordinated_turn(1.0), kfast.models.range_bearing(), Q, R, n=5)
    P0 = np.diag([1.0, 1.0, 1.0, 1.0, 1e-6])
    for res in (model.ekf(y, truth[0], P0), model.ukf(y, truth[0], P0, points=kfast.sigma.merwe(0.5))):
        assert np.all(np.abs(res.innov[:, 1]) < 0.05)
        np.testing.assert_allclose(res.x_filt[:, :2], truth[:, :2], atol=0.5)


def test_the_prior_and_the_data_are_not_modified():
    builtin, _, Q, R, y, x0, P0 = ct_models()
    copies = [a.copy() for a in (y, x0, P0)]
    builtin.ukf(y, x0, P0)
    builtin.ekf(y, x0, P0, iterations=1)
    for a, b in zip((y, x0, P0), copies):
        np.testing.assert_array_equal(a, b)


def test_ekf_outputs_and_k_pred():
    builtin, _, Q, R, y, x0, P0 = ct_models()
    res = builtin.ekf(y, x0, P0, outputs=("x_filt",))
    assert res.P_filt is None and res.x_filt.shape == (len(y), 5)
    with pytest.raises(kfast.KfastError, match="K_pred"):
        builtin.ekf(y, x0, P0, outputs="K_pred")


# ----------------------------------------------------------------------------------------------
# Bad input: clear errors naming the function or argument and the step
# ----------------------------------------------------------------------------------------------


def test_callables_that_misbehave_are_named_with_the_step():
    Q, R, y, x0, P0 = ct_problem(T=10)

    def nan_at_step_3(X, t, u):
        out = range_bearing(X, t, u)
        return out * np.nan if t == 3 else out

    cases = [
        (lambda X, t, u: X[:, :4], range_bearing, r"f at step 0: it returned shape \(\d+, 4\) for points X of shape \(\d+, 5\), expected \(\d+, 5\)"),
        (ct, lambda X, t, u: range_bearing(X, t, u)[:, :1], r"h at step 0: .*shape"),
        (ct, nan_at_step_3, r"h at step 3: returned a non-finite value"),
        (ct, lambda X, t, u: 1 / 0, r"h at step 0: it raised ZeroDivisionError"),
        (ct, lambda X, t, u: "text", r"h at step 0: it did not return an array of numbers"),
    ]
    for f, h, match in cases:
        model = kfast.NonlinearModel(f, h, Q, R, n=5, angles=[1])
        for run in (model.ekf, model.ukf):
            with pytest.raises(kfast.KfastError, match=match):
                run(y, x0, P0)


def test_bad_model_arguments():
    Q, R, y, x0, P0 = ct_problem(T=5)
    ct_builtin = kfast.models.coordinated_turn(DT)
    with pytest.raises(kfast.KfastError, match="angles"):
        kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[2])
    with pytest.raises(kfast.KfastError, match="angles"):
        kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[-1])
    with pytest.raises(kfast.KfastError, match="Q: not positive semidefinite"):
        kfast.NonlinearModel(ct, range_bearing, -Q, R, n=5)
    with pytest.raises(kfast.KfastError, match="f: the built-in model maps 5 states"):
        kfast.NonlinearModel(ct_builtin, range_bearing, np.eye(4), R, n=4)
    with pytest.raises(kfast.KfastError, match="jac_f: the built-in f has its own Jacobian"):
        kfast.NonlinearModel(ct_builtin, range_bearing, Q, R, n=5, jac_f=lambda X, t, u: X)
    with pytest.raises(kfast.KfastError, match="h: expected a callable"):
        kfast.NonlinearModel(ct, 3.0, Q, R, n=5)
    with pytest.raises(kfast.KfastError, match="dt"):
        kfast.models.coordinated_turn(0.0)
    with pytest.raises(kfast.KfastError, match="sensor"):
        kfast.models.range_bearing((0.0, np.inf))
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    with pytest.raises(kfast.KfastError, match="iteration"):
        model.ekf(y, x0, P0, iterations=1, iteration="newton")
    with pytest.raises(kfast.KfastError, match="P0"):
        model.ekf(y, x0, -P0)
    with pytest.raises(kfast.KfastError, match="y"):
        model.ukf(y[:, :1], x0, P0)
    with pytest.raises(kfast.KfastError, match="points"):
        model.ukf(y, x0, P0, points=kfast.sigma.merwe(alpha=0.0))
    with pytest.raises(kfast.KfastError, match=r"y at step 2: .*inf"):
        bad = y.copy()
        bad[2, 0] = np.inf
        model.ukf(bad, x0, P0)


def test_a_covariance_that_is_not_positive_definite_names_the_step():
    """A singular prior has no sigma points: the UKF says which covariance and which step."""
    Q, R, y, x0, P0 = ct_problem(T=5)
    P0 = P0.copy()
    P0[4, 4] = 0.0
    model = kfast.NonlinearModel(kfast.models.coordinated_turn(DT), kfast.models.range_bearing(), Q, R, n=5)
    with pytest.raises(kfast.KfastError, match=r"P\(t\|t-1\) at step 0 is not positive definite"):
        model.ukf(y, x0, P0)
    model.ekf(y, x0, P0)  # the EKF needs no square root


def test_the_radar_at_the_target_is_refused():
    Q, R, y, x0, P0 = ct_problem(T=5)
    model = kfast.NonlinearModel(kfast.models.coordinated_turn(DT), kfast.models.range_bearing((100.0, 50.0)), Q, R, n=5)
    with pytest.raises(kfast.KfastError, match="h at step 0: the range-bearing Jacobian is undefined"):
        model.ekf(y, x0, P0)


# ----------------------------------------------------------------------------------------------
# Second-order EKF: Söderström section 9.2.4 and Example 9.1 (tests/data/textbook_cases.json)
# ----------------------------------------------------------------------------------------------


def test_g1_second_order_ekf_closed_form():
    """(9.28)-(9.31) through the Rust filter: x(0|0) = K y, z = x(1|0) = x(0|0)^2 (EKF) and
    x(0|0)^2 + P(0|0) (second order), with the Hessian given and differenced."""
    a = 1.0
    for b in (0.3, 2.0):
        K, P00 = a**2 / (a**2 + b**2), a**2 * b**2 / (3 * (a**2 + b**2))
        y = np.array([[0.4], [0.0]])  # the second step only carries x(1|0) forward
        kw = dict(Q=[[0.0]], R=[[b**2 / 3]], n=1)
        square = kfast.NonlinearModel(lambda X, t, u: X**2, lambda X, t, u: X, **kw)
        given = kfast.NonlinearModel(
            lambda X, t, u: X**2, lambda X, t, u: X, hess_f=lambda X, t, u: np.full((len(X), 1, 1, 1), 2.0), **kw
        )
        first = square.ekf(y, [0.0], [[a**2 / 3]])
        assert first.x_filt[0, 0] == pytest.approx(K * 0.4, rel=1e-12)
        assert first.P_filt[0, 0, 0] == pytest.approx(P00, rel=1e-12)
        assert first.x_pred[1, 0] == pytest.approx((K * 0.4) ** 2, rel=1e-12)
        assert given.ekf(y, [0.0], [[a**2 / 3]], order=2).x_pred[1, 0] == pytest.approx((K * 0.4) ** 2 + P00, rel=1e-12)
        assert square.ekf(y, [0.0], [[a**2 / 3]], order=2).x_pred[1, 0] == pytest.approx((K * 0.4) ** 2 + P00, rel=1e-7)


def test_g2_example_9_1_corrections_through_rust():
    def f(X, t, u):
        return np.stack([X[:, 0] ** 2 + X[:, 1], X[:, 0] * np.exp(-X[:, 1])], axis=1)

    H = np.array([[1.0, 0.5]])
    model = kfast.NonlinearModel(f, lambda X, t, u: X @ H.T, 0.1 * np.eye(2), [[0.5]], n=2)
    res = model.ekf([[1.1]], [0.7, -0.3], [[0.4, 0.1], [0.1, 0.3]], order=2)
    x, P = res.x_filt[0], res.P_filt[0]
    f_bar = np.array([P[0, 0], 0.5 * np.exp(-x[1]) * (x[0] * P[1, 1] - 2 * P[0, 1])])
    np.testing.assert_allclose(res.x_next, f(x[None], 0, None)[0] + f_bar, rtol=1e-7, atol=1e-9)


def test_second_order_ekf_equals_the_reference():
    """With the Hessians given, to rounding; differenced, loosely: a second difference with the
    step eps^(1/4) moves by ~1e-8 relative for a 1-ulp change of its point, so the two
    implementations, bitwise equal for the first steps, drift apart by ~1e-6 later."""
    _, python, Q, R, y, x0, P0 = ct_models()

    def hess_h(X, t, u):  # range and bearing: closed-form Hessians in (px, py)
        Hs = np.zeros((len(X), 2, 5, 5))
        px, py = X[:, 0], X[:, 1]
        r2 = px**2 + py**2
        r3 = r2 ** 1.5
        Hs[:, 0, 0, 0], Hs[:, 0, 1, 1], Hs[:, 0, 0, 1] = py**2 / r3, px**2 / r3, -px * py / r3
        Hs[:, 1, 0, 0], Hs[:, 1, 1, 1], Hs[:, 1, 0, 1] = 2 * px * py / r2**2, -2 * px * py / r2**2, (py**2 - px**2) / r2**2
        Hs[:, :, 1, 0] = Hs[:, :, 0, 1]
        return Hs

    def hess_f(X, t, u):  # a Hessian that is not the model's: what matters is that both use it
        return np.broadcast_to(np.eye(5) * 1e-3, (len(X), 5, 5, 5)).copy()

    given = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, jac_f=ct_jac, jac_h=range_bearing_jac, hess_f=hess_f, hess_h=hess_h, angles=[1])
    want = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, ct_jac, range_bearing_jac, angles=[1], order=2, hess_f=hess_f, hess_h=hess_h)
    assert_close(given.ekf(y, x0, P0, order=2), want, rtol=1e-9, atol=1e-9)
    want = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, ct_jac, range_bearing_jac, angles=[1], order=2)
    assert_close(python.ekf(y, x0, P0, order=2), want, rtol=1e-4, atol=1e-4)
    with pytest.raises(kfast.KfastError, match="order"):
        python.ekf(y, x0, P0, order=2, iterations=1)
    with pytest.raises(kfast.KfastError, match="order"):
        python.ekf(y, x0, P0, order=3)


# ----------------------------------------------------------------------------------------------
# Compiled callables: C functions of the documented signature, through ctypes and scipy
# ----------------------------------------------------------------------------------------------

C_MODEL = r"""
#include <math.h>
#include <stdint.h>
void ct(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    const double dt = 0.1;
    for (intptr_t i = 0; i < k; i++) {
        const double *x = X + i * n; double *o = out + i * n;
        double w = x[4], S = sin(w * dt), C = cos(w * dt);
        double s = fabs(w) < 1e-9 ? dt : S / w, c = fabs(w) < 1e-9 ? 0.0 : (1 - C) / w;
        o[0] = x[0] + s * x[2] - c * x[3]; o[1] = x[1] + c * x[2] + s * x[3];
        o[2] = C * x[2] - S * x[3]; o[3] = S * x[2] + C * x[3]; o[4] = w;
    }
}
void radar(const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out) {
    for (intptr_t i = 0; i < k; i++) {
        out[2 * i] = hypot(X[i * n], X[i * n + 1]);
        out[2 * i + 1] = atan2(X[i * n + 1], X[i * n]);
    }
}
"""


@pytest.fixture(scope="module")
def c_library(tmp_path_factory):
    import ctypes
    import shutil
    import subprocess

    compiler = shutil.which("gcc") or shutil.which("cc")
    if compiler is None:
        pytest.fail("a C compiler is needed to build the compiled-callable test model")
    d = tmp_path_factory.mktemp("cmodel")
    (d / "model.c").write_text(C_MODEL)
    subprocess.run([compiler, "-O2", "-shared", "-fPIC", "-o", str(d / "model.so"), str(d / "model.c"), "-lm"], check=True)
    lib = ctypes.CDLL(str(d / "model.so"))
    proto = ctypes.CFUNCTYPE(
        None, ctypes.POINTER(ctypes.c_double), ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_int64,
        ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
    )
    return lib, proto


def test_compiled_callables_equal_python_callables_and_the_reference(c_library):
    import scipy

    lib, proto = c_library
    _, python, Q, R, y, x0, P0 = ct_models()
    f_c, h_c = proto(("ct", lib)), proto(("radar", lib))
    variants = [(f_c, h_c), (scipy.LowLevelCallable(f_c), scipy.LowLevelCallable(h_c))]
    for f, h in variants:
        compiled = kfast.NonlinearModel(f, h, Q, R, n=5, angles=[1])
        plain = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
        for run in (lambda m: m.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5)), lambda m: m.ekf(y, x0, P0)):
            a, b = run(compiled), run(plain)
            # C's sin and cos (libm) and NumPy's differ by an ulp now and then; the weakly
            # observed turn rate amplifies that to ~1e-9 absolute over 60 steps
            for k in FIELDS:
                np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=1e-7, atol=1e-8, err_msg=k)
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), angles=[1])
    compiled = kfast.NonlinearModel(f_c, h_c, Q, R, n=5, angles=[1])
    assert_close(compiled.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5)), want, rtol=1e-7, atol=1e-8)


def test_a_compiled_callable_with_another_signature_is_refused(c_library):
    import ctypes

    import scipy

    lib, _ = c_library
    Q, R, y, x0, P0 = ct_problem(T=5)
    wrong = ctypes.CFUNCTYPE(None, ctypes.POINTER(ctypes.c_double), ctypes.c_int, ctypes.c_int, ctypes.c_int64,
                             ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double))(("ct", lib))
    returns = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_double), ctypes.c_ssize_t, ctypes.c_ssize_t,
                               ctypes.c_int64, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double))(("ct", lib))
    for bad in (wrong, returns, scipy.LowLevelCallable(wrong)):
        with pytest.raises(kfast.KfastError, match="f: the .*signature .* is not"):
            kfast.NonlinearModel(bad, range_bearing, Q, R, n=5)


# ----------------------------------------------------------------------------------------------
# Custom sigma-point sets (kfast.sigma.custom)
# ----------------------------------------------------------------------------------------------


def merwe_written_out(n, alpha, beta=2.0, kappa=0.0):
    lam = alpha**2 * (n + kappa) - n
    c = np.sqrt(n + lam)
    unit = np.concatenate([np.zeros((1, n)), c * np.eye(n), -c * np.eye(n)])
    Wm = np.full(2 * n + 1, 1 / (2 * (n + lam)))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = Wm[0] + 1 - alpha**2 + beta
    return unit, Wm, Wc


def test_custom_points_written_as_merwe_and_cubature_equal_the_built_in_sets():
    builtin, python, Q, R, y, x0, P0 = ct_models()
    unit, Wm, Wc = merwe_written_out(5, 0.5)
    cub = np.sqrt(5) * np.concatenate([np.eye(5), -np.eye(5)])
    for model in (builtin, python):
        for mine, theirs in (
            (kfast.sigma.custom(unit, Wm, Wc), kfast.sigma.merwe(0.5)),
            (kfast.sigma.custom(cub, np.full(10, 0.1)), kfast.sigma.cubature()),
        ):
            a, b = model.ukf(y, x0, P0, points=mine), model.ukf(y, x0, P0, points=theirs)
            # the built-in centred sums and the plain sums differ by rounding only
            assert_close(a, {k: getattr(b, k) for k in FIELDS + ("loglik",)}, rtol=1e-9, atol=1e-9)
            s_mine = model.smooth(y, x0, P0, method="ukf", points=mine)
            s_theirs = model.smooth(y, x0, P0, method="ukf", points=theirs)
            np.testing.assert_allclose(s_mine.P_smooth, s_theirs.P_smooth, rtol=1e-9, atol=1e-9)


def test_a_custom_set_with_its_own_weights_equals_the_reference():
    """A set unlike the built-ins: Merwe's points along randomly rotated axes (so L xi_i mixes
    every column of L), with its unequal centre weights, in the filter, the streaming filter and
    ukf_batch."""
    _, _, Q, R, y, x0, P0 = ct_models()
    rotation, _ = np.linalg.qr(np.random.default_rng(4).normal(size=(5, 5)))
    unit, Wm, Wc = merwe_written_out(5, 0.7)
    unit = unit @ rotation.T
    points = kfast.sigma.custom(unit, Wm, Wc)
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    got = model.ukf(y, x0, P0, points=points)
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref.CustomPoints(unit, Wm, Wc), angles=[1])
    assert_close(got, want, rtol=1e-10, atol=1e-10)
    stream = kfast.UnscentedKalmanFilter(model, x0, P0, points=points)
    stream.update(y[0])
    np.testing.assert_allclose(stream.P, got.P_filt[0], rtol=1e-13, atol=1e-13)
    bank = kfast.ukf_batch(model, np.stack([y, y]), x0, P0, points=points)
    np.testing.assert_array_equal(bank.x_filt[1], got.x_filt)


def test_bad_custom_sets_are_named():
    builtin, _, Q, R, y, x0, P0 = ct_models()
    with pytest.raises(kfast.KfastError, match=r"Wm: expected one weight per point, shape \(3,\)"):
        kfast.sigma.custom(np.eye(3), [0.5, 0.5])
    with pytest.raises(kfast.KfastError, match=r"points: expected unit points of shape \(k, n\)"):
        kfast.sigma.custom([1.0, 2.0], [0.5, 0.5])
    with pytest.raises(kfast.KfastError, match=r"points: the mean weights must sum to 1"):
        builtin.ukf(y, x0, P0, points=kfast.sigma.custom(np.eye(5), np.full(5, 0.3)))
    with pytest.raises(kfast.KfastError, match=r"points: the set is for n = 3 states, the model has n = 5"):
        builtin.ukf(y, x0, P0, points=kfast.sigma.custom(np.eye(3), np.full(3, 1 / 3)))
    with pytest.raises(kfast.KfastError, match=r"points: points and weights must be finite"):
        builtin.ukf(y, x0, P0, points=kfast.sigma.custom(np.full((2, 5), np.nan), [0.5, 0.5]))
    with pytest.raises(kfast.KfastError, match=r"unit points go with kind 'custom' only"):
        kfast.sigma.SigmaPoints("merwe", unit=np.eye(2))
