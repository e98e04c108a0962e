"""kfast.ExtendedKalmanFilter and kfast.UnscentedKalmanFilter: the batch filters one step at a
time, sequential updates by a second sensor, and their errors."""

import numpy as np
import pytest
from tracking import DT, ct, ct_jac, ct_problem, range_bearing, range_bearing_jac

import kfast


def models():
    Q, R, y, x0, P0 = ct_problem(T=30)
    y = y.copy()
    y[4, 1] = np.nan
    y[9] = np.nan
    builtin = kfast.NonlinearModel(kfast.models.coordinated_turn(DT, 1.0, 0.05), kfast.models.range_bearing(), Q, R, n=5)
    python = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, jac_f=ct_jac, jac_h=range_bearing_jac, angles=[1])
    return builtin, python, y, x0, P0


@pytest.mark.parametrize("which", ["ekf", "iterated", "second-order", "ukf", "cubature"])
def test_streaming_equals_the_batch_filter(which):
    builtin, python, y, x0, P0 = models()
    for model in (builtin, python):
        if which == "ukf":
            batch, stream = model.ukf(y, x0, P0), kfast.UnscentedKalmanFilter(model, x0, P0)
        elif which == "cubature":
            pts = kfast.sigma.cubature()
            batch, stream = model.ukf(y, x0, P0, points=pts), kfast.UnscentedKalmanFilter(model, x0, P0, points=pts)
        else:
            kw = {"ekf": {}, "iterated": {"iterations": 2, "iteration": "gauss-newton"}, "second-order": {"order": 2}}[which]
            batch, stream = model.ekf(y, x0, P0, **kw), kfast.ExtendedKalmanFilter(model, x0, P0, **kw)
        for t in range(len(y)):
            np.testing.assert_allclose(stream.x, batch.x_pred[t], rtol=1e-13, atol=1e-13)
            stream.update(y[t])
            np.testing.assert_allclose(stream.x, batch.x_filt[t], rtol=1e-13, atol=1e-13)
            np.testing.assert_allclose(stream.P, batch.P_filt[t], rtol=1e-13, atol=1e-13)
            assert stream.t == t
            stream.predict()
        np.testing.assert_allclose(stream.P, batch.P_next, rtol=1e-13, atol=1e-13)
        assert stream.loglik == pytest.approx(batch.loglik, rel=1e-12)


def test_a_second_sensor_updates_in_sequence():
    """On a linear model, an update by the model's sensor (m = 2) and then by a second one (one
    velocity, m = 1, its own R) equals one update by both stacked (H = [H1; H2],
    R = blockdiag(R1, R2))."""
    cv = kfast.models.constant_velocity(2, DT, q=1.0, r=1.0)
    H2 = np.array([[0, 0, 1.0, 0]])
    R2 = np.array([[0.5]])
    both = kfast.LinearGaussian(cv.F, np.vstack([cv.H, H2]), cv.Q, np.block([[cv.R, np.zeros((2, 1))], [np.zeros((1, 2)), R2]]))
    x0, P0 = np.array([1.0, -1.0, 0.5, 0.2]), np.diag([10, 10, 1, 1.0])
    y1, y2 = np.array([1.2, -0.7]), np.array([0.4])
    want = both.filter(np.concatenate([y1, y2])[None], x0, P0)
    for stream in (kfast.ExtendedKalmanFilter(kfast.NonlinearModel.from_linear(cv), x0, P0),
                   kfast.UnscentedKalmanFilter(kfast.NonlinearModel.from_linear(cv), x0, P0)):
        stream.update(y1)
        stream.update(y2, h=lambda X, t, u: X @ H2.T, R=R2)
        np.testing.assert_allclose(stream.x, want.x_filt[0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(stream.P, want.P_filt[0], rtol=1e-9, atol=1e-9)
        assert stream.loglik == pytest.approx(want.loglik, rel=1e-9)
        stream.predict()
        np.testing.assert_allclose(stream.x, want.x_next, rtol=1e-9, atol=1e-9)
        stream.update(y1)  # back to the model's sensor (m = 2)
        assert np.all(np.isfinite(stream.x))


def test_the_functions_see_the_step_and_the_input():
    seen = []

    def f(X, t, u):
        seen.append(("f", t, None if u is None else float(u[0])))
        return X

    def h(X, t, u):
        seen.append(("h", t, None if u is None else float(u[0])))
        return X

    model = kfast.NonlinearModel(f, h, [[0.1]], [[1.0]], n=1, jac_f=lambda X, t, u: np.ones((len(X), 1, 1)),
                                 jac_h=lambda X, t, u: np.ones((len(X), 1, 1)))
    ekf = kfast.ExtendedKalmanFilter(model, [0.0], [[1.0]])
    ekf.update([0.5], u=[7.0])
    ekf.predict(u=[7.0])
    ekf.step([0.1], u=[8.0])
    assert seen == [("h", 0, 7.0), ("f", 0, 7.0), ("h", 1, 8.0), ("f", 1, 8.0)]
    assert ekf.t == 2


def test_streaming_errors():
    builtin, _, y, x0, P0 = models()
    ekf = kfast.ExtendedKalmanFilter(builtin, x0, P0)
    with pytest.raises(kfast.KfastError, match=r"y at step 0: expected 2 values"):
        ekf.update([1.0, 2.0, 3.0])
    with pytest.raises(kfast.KfastError, match="h, R"):
        ekf.update(y[0], h=range_bearing)
    with pytest.raises(kfast.KfastError, match="angles"):
        ekf.update(y[0], angles=[1])
    with pytest.raises(kfast.KfastError, match="R: not positive semidefinite"):
        ekf.update(y[0], h=range_bearing, R=-np.eye(2))
    with pytest.raises(kfast.KfastError, match="model"):
        kfast.UnscentedKalmanFilter(kfast.models.constant_velocity(1, 0.1), [0, 0], np.eye(2))
    with pytest.raises(kfast.KfastError, match="x0"):
        kfast.UnscentedKalmanFilter(builtin, x0[:3], P0)
    with pytest.raises(kfast.KfastError, match="y at step 0: .*inf"):
        ekf.update([np.inf, 0.0])
    ekf.update(y[0])  # the state is usable after the errors
    assert np.all(np.isfinite(ekf.x))
