"""The built-in nonlinear models (Rust) against the same models written as NumPy callables:
bearings-only, the 3-D radar with constant-velocity dynamics from the linear catalogue, UNGM,
and the coordinated turn with a known turn rate."""

import numpy as np
import pytest
from tracking import DT, ct_one, ct_problem

import kfast

FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "loglik_t")


def assert_same(a, b, tol):
    for k in FIELDS:
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=tol, atol=tol, err_msg=k)


def runs(model, y, x0, P0):
    return [model.ekf(y, x0, P0), model.ekf(y, x0, P0, iterations=2), model.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5))]


def test_bearings_only_equals_numpy():
    cv = kfast.models.constant_velocity(2, 0.5, q=0.1)
    rng = np.random.default_rng(3)
    T = 40
    truth = np.array([20.0, 5.0]) + np.outer(np.arange(T), [-1.0, 0.3])
    y = np.arctan2(truth[:, 1] - 1.0, truth[:, 0] - 2.0)[:, None] + 0.01 * rng.standard_normal((T, 1))
    x0, P0 = np.array([20.0, 5.0, -1.0, 0.3]), np.diag([4.0, 4.0, 0.5, 0.5])
    builtin = kfast.NonlinearModel(cv, kfast.models.bearings_only((2.0, 1.0)), cv.Q, [[1e-4]], n=4)
    numpy = kfast.NonlinearModel(
        lambda X, t, u: X @ cv.F.T, lambda X, t, u: np.arctan2(X[:, 1:2] - 1.0, X[:, 0:1] - 2.0), cv.Q, [[1e-4]], n=4, angles=[0]
    )
    for a, b in zip(runs(builtin, y, x0, P0), runs(numpy, y, x0, P0)):
        assert_same(a, b, 1e-6)  # the NumPy model's Jacobians are differenced


def test_range_bearing_elevation_with_catalogue_dynamics_equals_numpy():
    cv3 = kfast.models.constant_velocity(3, 0.1, q=1.0)  # state (px, py, pz, vx, vy, vz)
    sensor = np.array([1.0, -2.0, 0.5])

    def rbe(X, t, u):
        d = X[:, :3] - sensor
        rho = np.hypot(d[:, 0], d[:, 1])
        return np.stack([np.hypot(rho, d[:, 2]), np.arctan2(d[:, 1], d[:, 0]), np.arctan2(d[:, 2], rho)], axis=1)

    def rbe_jac(X, t, u):
        d = X[:, :3] - sensor
        rho2 = d[:, 0] ** 2 + d[:, 1] ** 2
        r2 = rho2 + d[:, 2] ** 2
        rho, r = np.sqrt(rho2), np.sqrt(r2)
        J = np.zeros((len(X), 3, 6))
        J[:, 0, :3] = d / r[:, None]
        J[:, 1, 0], J[:, 1, 1] = -d[:, 1] / rho2, d[:, 0] / rho2
        J[:, 2, 0], J[:, 2, 1], J[:, 2, 2] = -d[:, 0] * d[:, 2] / (r2 * rho), -d[:, 1] * d[:, 2] / (r2 * rho), rho / r2
        return J

    R = np.diag([0.5, 1e-4, 1e-4])
    x0 = np.array([30.0, 20.0, 10.0, -2.0, 1.0, 0.5])
    P0 = np.diag([4.0, 4.0, 4.0, 1.0, 1.0, 1.0])
    truth = x0 + np.outer(np.arange(30) * 0.1, np.r_[x0[3:], 0, 0, 0])
    y = rbe(truth, 0, None) + np.random.default_rng(4).standard_normal((30, 3)) * np.sqrt(np.diag(R))
    builtin = kfast.NonlinearModel(cv3, kfast.models.range_bearing_elevation(tuple(sensor)), cv3.Q, R, n=6)
    numpy = kfast.NonlinearModel(lambda X, t, u: X @ cv3.F.T, rbe, cv3.Q, R, n=6, jac_f=lambda X, t, u: np.broadcast_to(cv3.F, (len(X), 6, 6)),
                                 jac_h=rbe_jac, angles=[1])
    for a, b in zip(runs(builtin, y, x0, P0), runs(numpy, y, x0, P0)):
        assert_same(a, b, 1e-9)
    with pytest.raises(kfast.KfastError, match="straight above or below"):
        builtin.ekf(y, np.r_[sensor, 0, 0, 0], P0)


def test_ungm_equals_numpy():
    def f(X, t, u):
        return X / 2 + 25 * X / (1 + X**2) + 8 * np.cos(1.2 * t)

    def h(X, t, u):
        return X**2 / 20

    def jac_f(X, t, u):
        return (0.5 + 25 * (1 - X**2) / (1 + X**2) ** 2)[:, :, None]

    def jac_h(X, t, u):
        return (X / 10)[:, :, None]

    rng = np.random.default_rng(5)
    x, y = 0.1, np.zeros((50, 1))
    for t in range(50):
        y[t] = x**2 / 20 + rng.standard_normal()
        x = x / 2 + 25 * x / (1 + x**2) + 8 * np.cos(1.2 * t) + np.sqrt(10) * rng.standard_normal()
    builtin = kfast.models.ungm()
    numpy = kfast.NonlinearModel(f, h, [[10.0]], [[1.0]], n=1, jac_f=jac_f, jac_h=jac_h)
    for a, b in zip(runs(builtin, y, [0.0], [[5.0]]), runs(numpy, y, [0.0], [[5.0]])):
        assert_same(a, b, 1e-10)
    with pytest.raises(kfast.KfastError, match="r"):
        kfast.models.ungm(r=0.0)


def test_a_linear_model_with_inputs_is_refused_as_f():
    m = kfast.LinearGaussian(np.eye(2), np.eye(2), np.eye(2), np.eye(2), B=np.ones((2, 1)))
    with pytest.raises(kfast.KfastError, match="f: a LinearGaussian used as f"):
        kfast.NonlinearModel(m, kfast.models.range_bearing(), np.eye(2), np.eye(2), n=2)


# ----------------------------------------------------------------------------------------------
# Coordinated turn with a known turn rate (a linear map of the 4-state (px, py, vx, vy))
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("omega", [0.7, -0.3, 1e-3, 1e-9, 0.0])
def test_known_turn_rate_is_the_turn_of_the_five_state_model(omega):
    known = kfast.models.coordinated_turn(DT, q=2.0, omega=omega)
    F = known.params
    assert known.kind == "linear" and F.shape == (4, 4) and not F.flags.writeable
    x = np.array([3.0, -1.0, 5.0, -2.0])
    if omega == 0.0:
        cv = np.array([[1, 0, DT, 0], [0, 1, 0, DT], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        np.testing.assert_array_equal(F, cv)
    else:
        # the NumPy form sin(w dt)/w, (1 - cos(w dt))/w cancels for tiny w: compare loosely there
        tol = 1e-13 if abs(omega) > 1e-2 else 1e-6
        np.testing.assert_allclose(F @ x, ct_one(np.append(x, omega))[:4], rtol=tol, atol=tol)
    np.testing.assert_allclose(known.Q, kfast.models.coordinated_turn(DT, q=2.0).Q[:4, :4], rtol=0, atol=0)


def test_known_turn_rate_filters_as_the_five_state_model_with_omega_fixed():
    """The EKF of the 5-state CT with omega known exactly (no variance, no noise on it) is the
    Kalman filter of the 4-state known-omega turn."""
    _, R, y, x0, P0 = ct_problem(T=30)
    omega = x0[4]
    radar = kfast.models.range_bearing((0.0, 0.0))
    P5 = P0.copy()
    P5[4, 4] = 0.0
    five = kfast.NonlinearModel(kfast.models.coordinated_turn(DT, q=1.0), radar, kfast.models.coordinated_turn(DT, q=1.0).Q, R, n=5)
    known = kfast.models.coordinated_turn(DT, q=1.0, omega=omega)
    four = kfast.NonlinearModel(known, radar, known.Q, R, n=4)
    a, b = five.ekf(y, x0, P5), four.ekf(y, x0[:4], P0[:4, :4])
    np.testing.assert_allclose(a.x_filt[:, :4], b.x_filt, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(a.P_filt[:, :4, :4], b.P_filt, rtol=1e-10, atol=1e-9)
    assert a.loglik == pytest.approx(b.loglik, rel=1e-11)
    with pytest.raises(kfast.KfastError, match="omega: must be finite"):
        kfast.models.coordinated_turn(DT, omega=np.inf)
