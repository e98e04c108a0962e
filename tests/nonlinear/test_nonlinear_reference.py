"""The NumPy reference of the nonlinear filters (kfast.reference.nonlinear), the oracle for the
Rust ones, checked three ways: on linear models against the reference Kalman filter and RTS
smoother, against filterpy's EKF and UKF on a nonlinear tracking model, and against Söderström
section 9.2.4 / Table 9.1 and Example 9.1 (tests/data/textbook_cases.json, cases G1 and G2)."""

import json
from pathlib import Path

import numpy as np
import pytest
from modelgen import random_case
from tracking import DT, ct, ct_one, ct_problem, range_bearing, range_bearing_jac

from kfast.reference import kalman_filter, rts_smoother
from kfast.reference import nonlinear as ref

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())
FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "S", "K", "loglik_t")


def linear_functions(F, H):
    """f, h and their Jacobians of a constant linear model, batched."""

    def f(X, t, u):
        return X @ F.T

    def h(X, t, u):
        return X @ H.T

    def jac_f(X, t, u):
        return np.broadcast_to(F, (len(X),) + F.shape)

    def jac_h(X, t, u):
        return np.broadcast_to(H, (len(X),) + H.shape)

    return f, h, jac_f, jac_h


def assert_same_filter(got, want, fields=FIELDS, rtol=1e-10, atol=1e-10):
    for k in fields:
        np.testing.assert_allclose(got[k], want[k], rtol=rtol, atol=atol, err_msg=k)
    assert got["loglik"] == pytest.approx(want["loglik"], rel=1e-10)


@pytest.mark.parametrize("seed, n, m, missing", [(1, 2, 1, "none"), (2, 4, 2, "partial"), (3, 5, 3, "rows")])
def test_on_a_linear_model_every_filter_is_the_kalman_filter(seed, n, m, missing):
    c = random_case(seed, n, m, T=25, missing=missing)
    F, H, Q, R = (c.model[k] for k in "FHQR")
    f, h, jac_f, jac_h = linear_functions(F, H)
    want = kalman_filter(F, H, Q, R, c.y, c.x0, c.P0, form="joseph")
    for kw in ({}, {"iterations": 3}, {"iterations": 3, "iteration": "gauss-newton"}):
        assert_same_filter(ref.ekf(f, h, Q, R, c.y, c.x0, c.P0, jac_f, jac_h, **kw), want)
    # Jacobians by differences are exact for a linear map up to rounding
    assert_same_filter(ref.ekf(f, h, Q, R, c.y, c.x0, c.P0), want, rtol=1e-7, atol=1e-7)
    want_std = kalman_filter(F, H, Q, R, c.y, c.x0, c.P0, form="standard")
    for points in (ref.merwe(), ref.merwe(alpha=0.5), ref.julier(kappa=1.0), ref.cubature()):
        got = ref.ukf(f, h, Q, R, c.y, c.x0, c.P0, points=points)
        assert_same_filter(got, want_std, rtol=1e-9, atol=1e-9)


def test_on_a_linear_model_both_smoothers_are_rts():
    c = random_case(4, 4, 2, T=30, missing="partial")
    F, H, Q, R = (c.model[k] for k in "FHQR")
    f, h, jac_f, jac_h = linear_functions(F, H)
    xs, Ps, _, _ = rts_smoother(F, H, Q, R, c.y, c.x0, c.P0)
    x_e, P_e, _ = ref.extended_rts(f, h, Q, R, c.y, c.x0, c.P0, jac_f, jac_h)
    x_u, P_u, _ = ref.unscented_rts(f, h, Q, R, c.y, c.x0, c.P0, points=ref.merwe(alpha=0.5))
    for x, P in ((x_e, P_e), (x_u, P_u)):
        np.testing.assert_allclose(x, xs, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(P, Ps, rtol=1e-9, atol=1e-9)


def test_ukf_equals_filterpy_with_the_same_points_and_prior_timing():
    filterpy = pytest.importorskip("filterpy.kalman")
    Q, R, y, x0, P0 = ct_problem()
    points = filterpy.MerweScaledSigmaPoints(5, alpha=0.5, beta=2.0, kappa=0.0)
    kf = filterpy.UnscentedKalmanFilter(
        dim_x=5, dim_z=2, dt=DT, fx=lambda x, dt: ct_one(x), hx=lambda x: range_bearing(x[None], 0, None)[0],
        points=points,
    )
    kf.x, kf.P, kf.Q, kf.R = x0.copy(), P0.copy(), Q, R
    # filterpy predicts first (its prior is x(-1|-1)); kfast's prior is x(0|-1), so filterpy's
    # first update is given the points of that prior. filterpy 2.0 redraws the points from the
    # predicted moments before each update, as kfast does.
    kf.sigmas_f = points.sigma_points(x0, P0)
    x_filt, P_filt = [], []
    for t in range(len(y)):
        if t:
            kf.predict()
        kf.update(y[t])
        x_filt.append(kf.x.copy())
        P_filt.append(kf.P.copy())
    got = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5, 2.0, 0.0), angles=[1])
    np.testing.assert_allclose(got["x_filt"], x_filt, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got["P_filt"], P_filt, rtol=1e-8, atol=1e-10)


def test_ekf_equals_a_filterpy_extended_kalman_filter_loop():
    filterpy = pytest.importorskip("filterpy.kalman")
    Q, R, y, x0, P0 = ct_problem()

    class CT(filterpy.ExtendedKalmanFilter):
        def predict_x(self, u=0):
            self.x = ct_one(self.x)

    kf = CT(dim_x=5, dim_z=2)
    kf.x, kf.P, kf.Q, kf.R = x0.copy(), P0.copy(), Q, R
    x_filt, P_filt = [], []
    for t in range(len(y)):
        kf.update(y[t], lambda x: range_bearing_jac(x[None], 0, None)[0], lambda x: range_bearing(x[None], 0, None)[0])
        x_filt.append(kf.x.copy())
        P_filt.append(kf.P.copy())
        kf.F = np.array(jacobian_ct(kf.x))
        kf.predict()
    got = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, jac_f=lambda X, t, u: np.array([jacobian_ct(x) for x in X]),
                  jac_h=range_bearing_jac, angles=[1])
    # filterpy multiplies by an explicit S^-1 (S's condition number is ~1e4 here): 1e-8
    np.testing.assert_allclose(got["x_filt"], x_filt, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(got["P_filt"], P_filt, rtol=1e-8, atol=1e-8)


def jacobian_ct(x):
    """The coordinated turn's Jacobian by central differences at a fine step (what matters here
    is that filterpy and the reference use the same one)."""
    return ref.jacobian_by_differences(ct, np.asarray(x, float), 0, None)


def test_gauss_newton_iterations_reach_the_map_estimate():
    """Iterated to convergence, the Gauss-Newton update minimizes V(x) = 1/2 |y - h(x)|^2_R^-1 +
    1/2 |x - x(t|t-1)|^2_P^-1 (Bell & Cathey 1993): its gradient vanishes there; the book's form
    (only the gain moves) does not, and with zero iterations both are the EKF."""
    Q, R, y, x0, P0 = ct_problem(T=1)
    P0 = np.diag([400.0, 400.0, 4.0, 4.0, 0.01])  # a wide prior: h is far from linear over it
    y = np.array([[90.0, 0.6]])
    kw = dict(jac_h=range_bearing_jac, angles=[1])
    ekf = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, **kw)
    book = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, iterations=30, **kw)
    gn = ref.ekf(ct, range_bearing, Q, R, y, x0, P0, iterations=30, iteration="gauss-newton", **kw)

    def gradient(x):
        J = range_bearing_jac(x[None], 0, None)[0]
        r = y[0] - range_bearing(x[None], 0, None)[0]
        return -J.T @ np.linalg.solve(R, r) + np.linalg.solve(P0, x - x0)

    scale = np.linalg.norm(gradient(ekf["x_filt"][0]))
    assert np.linalg.norm(gradient(gn["x_filt"][0])) < 1e-8 * scale
    assert np.linalg.norm(gradient(book["x_filt"][0])) > 1e-3 * scale
    assert not np.allclose(book["x_filt"], ekf["x_filt"])


# ----------------------------------------------------------------------------------------------
# Textbook: Söderström section 9.2.4 (Table 9.1) and Example 9.1
# ----------------------------------------------------------------------------------------------


def square(X, t, u):
    return X**2


def identity(X, t, u):
    return X


def test_g1_ekf_and_second_order_ekf_closed_forms():
    """(9.28)-(9.31): x(0|0) = K y, P(0|0) = a^2 b^2 / 3(a^2 + b^2), z = x(0|0)^2 (+ P(0|0))."""
    c = CASES["G1"]
    a = c["a"]
    for b in c["b"]:
        for y0 in (-1.3, 0.2, 0.9):
            args = (square, identity, [[0.0]], [[b**2 / 3]], [[y0]], [0.0], [[a**2 / 3]])
            K = a**2 / (a**2 + b**2)
            P00 = a**2 * b**2 / (3 * (a**2 + b**2))
            first = ref.ekf(*args)
            second = ref.ekf(*args, order=2)
            hess = ref.ekf(*args, order=2, hess_f=lambda X, t, u: np.full((len(X), 1, 1, 1), 2.0))
            assert first["x_filt"][0, 0] == pytest.approx(K * y0, rel=1e-12)
            assert first["P_filt"][0, 0, 0] == pytest.approx(P00, rel=1e-12)
            assert first["x_next"][0] == pytest.approx((K * y0) ** 2, rel=1e-9)
            assert hess["x_next"][0] == pytest.approx((K * y0) ** 2 + P00, rel=1e-12)
            assert second["x_next"][0] == pytest.approx((K * y0) ** 2 + P00, rel=1e-6)


def test_g1_table_9_1_by_monte_carlo():
    """Table 9.1 (a = 1, 10,000 trials): the MSEs of x(0|0) and of z = E x(1) for the EKF, the
    second-order EKF and the optimal (conditional-mean) estimator, within Monte-Carlo error
    (four standard errors, or half a unit of the last printed digit). The closed forms are the
    reference filter's, checked against it on the first trials."""
    c = CASES["G1"]
    a, N = c["a"], c["trials"]
    table = c["table_9_1"]
    rng = np.random.default_rng(20021)
    for j, b in enumerate(c["b"]):
        x = rng.uniform(-a, a, N)
        y = x + rng.uniform(-b, b, N)
        K = a**2 / (a**2 + b**2)
        P00 = a**2 * b**2 / (3 * (a**2 + b**2))
        x_ekf = K * y
        z_ekf, z_second = x_ekf**2, x_ekf**2 + P00
        lo, hi = np.maximum(-a, y - b), np.minimum(a, y + b)
        x_opt, z_opt = (lo + hi) / 2, (hi**2 + hi * lo + lo**2) / 3
        for i in range(5):  # the closed forms are the reference filter's
            args = (square, identity, [[0.0]], [[b**2 / 3]], [[y[i]]], [0.0], [[a**2 / 3]])
            assert ref.ekf(*args)["x_next"][0] == pytest.approx(z_ekf[i], rel=1e-8, abs=1e-12)
            assert ref.ekf(*args, order=2)["x_next"][0] == pytest.approx(z_second[i], rel=1e-6)
        rows = {
            "EKF MSE(x)": (x_ekf - x) ** 2,
            "EKF MSE(z)": (z_ekf - x**2) ** 2,
            "second-order EKF MSE(z)": (z_second - x**2) ** 2,
            "optimal MSE(x)": (x_opt - x) ** 2,
            "optimal MSE(z)": (z_opt - x**2) ** 2,
        }
        for name, sq in rows.items():
            printed = table[name][j]
            digits = len(str(printed).split(".")[1])
            allowed = max(4 * sq.std() / np.sqrt(N), 0.5 * 10.0**-digits)
            assert abs(sq.mean() - printed) <= allowed, (name, b, sq.mean(), printed)


def test_g2_example_9_1_second_order_corrections():
    """f(x) = (x1^2 + x2, x1 exp(-x2)): f_bar = (P11, 1/2 exp(-x2) (x1 P22 - 2 P12)) with
    P = P(t|t), from given Hessians and from differences."""

    def f(X, t, u):
        return np.stack([X[:, 0] ** 2 + X[:, 1], X[:, 0] * np.exp(-X[:, 1])], axis=1)

    def hess_f(X, t, u):
        Hs = np.zeros((len(X), 2, 2, 2))
        Hs[:, 0, 0, 0] = 2.0
        e = np.exp(-X[:, 1])
        Hs[:, 1, 0, 1] = Hs[:, 1, 1, 0] = -e
        Hs[:, 1, 1, 1] = X[:, 0] * e
        return Hs

    H = np.array([[1.0, 0.5]])
    Q, R = 0.1 * np.eye(2), np.array([[0.5]])
    x0, P0 = np.array([0.7, -0.3]), np.array([[0.4, 0.1], [0.1, 0.3]])
    y = np.array([[1.1]])
    for hess in (hess_f, None):
        res = ref.ekf(f, lambda X, t, u: X @ H.T, Q, R, y, x0, P0, order=2, hess_f=hess)
        x, P = res["x_filt"][0], res["P_filt"][0]
        f_bar = np.array([P[0, 0], 0.5 * np.exp(-x[1]) * (x[0] * P[1, 1] - 2 * P[0, 1])])
        tol = 1e-12 if hess is not None else 1e-6
        np.testing.assert_allclose(res["x_next"], f(x[None], 0, None)[0] + f_bar, rtol=tol, atol=tol)
