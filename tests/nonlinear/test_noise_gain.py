"""A noise gain g: x[t+1] = f(x) + g(x) w, w ~ N(0, Q) with Q r x r. The filters add G Q G' with
G = g(x(t|t), t, u[t]); a constant G equals the model with Q replaced by G Q G'; a
state-dependent g equals the NumPy reference; bad gains are named."""

import numpy as np
import pytest
from tracking import DT, ct, ct_jac, ct_problem, range_bearing, range_bearing_jac

import kfast
from kfast.reference import nonlinear as ref

FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "S", "K", "loglik_t", "x_next", "P_next")

# CT with white acceleration on x and y and a turn-rate noise: r = 3 noise inputs
G_CT = np.array([[DT**2 / 2, 0, 0], [0, DT**2 / 2, 0], [DT, 0, 0], [0, DT, 0], [0, 0, DT]])
Q_W = np.diag([1.0, 1.0, 0.05**2 / DT])
# along-track acceleration noise 10x the cross-track's: G Q G' then turns with the heading
Q_ALONG = np.diag([1.0, 0.1, 0.05**2 / DT])


def speed_gain(X, t, u):
    """A state-dependent gain: acceleration noise along and across the velocity (unit vectors
    of (vx, vy)), plus the turn rate's."""
    v = np.hypot(X[:, 2], X[:, 3])
    c, s = X[:, 2] / v, X[:, 3] / v
    G = np.zeros((len(X), 5, 3))
    G[:, 0, 0], G[:, 1, 0], G[:, 2, 0], G[:, 3, 0] = DT**2 / 2 * c, DT**2 / 2 * s, DT * c, DT * s
    G[:, 0, 1], G[:, 1, 1], G[:, 2, 1], G[:, 3, 1] = -DT**2 / 2 * s, DT**2 / 2 * c, -DT * s, DT * c
    G[:, 4, 2] = DT
    return G


def data(T=40):
    _, R, y, x0, P0 = ct_problem(T=T)
    y = y.copy()
    y[6, 0] = np.nan
    return R, y, x0, P0


def runs(model, y, x0, P0):
    pts = kfast.sigma.merwe(alpha=0.5)
    return {
        "ekf": model.ekf(y, x0, P0),
        "iterated": model.ekf(y, x0, P0, iterations=2, iteration="gauss-newton"),
        "ukf": model.ukf(y, x0, P0, points=pts),
        "eks": model.smooth(y, x0, P0, method="ekf"),
        "urts": model.smooth(y, x0, P0, method="ukf", points=pts),
    }


def test_a_constant_gain_is_the_model_with_g_q_g_transposed():
    R, y, x0, P0 = data()
    ct_builtin = kfast.models.coordinated_turn(DT)
    radar = kfast.models.range_bearing((0.0, 0.0))
    with_gain = kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5, g=G_CT)
    folded = kfast.NonlinearModel(ct_builtin, radar, G_CT @ Q_W @ G_CT.T, R, n=5)
    as_callable = kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5, g=lambda X, t, u: np.broadcast_to(G_CT, (len(X), 5, 3)))
    a, b, c = runs(with_gain, y, x0, P0), runs(folded, y, x0, P0), runs(as_callable, y, x0, P0)
    for name in a:
        for k in ("x_smooth", "P_smooth") if name in ("eks", "urts") else FIELDS:
            for other in (b, c):
                np.testing.assert_allclose(getattr(a[name], k), getattr(other[name], k), rtol=1e-12, atol=1e-12, err_msg=(name, k))
    assert with_gain.g.shape == (5, 3) and not with_gain.g.flags.writeable


def test_a_state_dependent_gain_equals_the_reference():
    R, y, x0, P0 = data()
    model = kfast.NonlinearModel(ct, range_bearing, Q_ALONG, R, n=5, jac_f=ct_jac, jac_h=range_bearing_jac, angles=[1], g=speed_gain)
    refs = dict(u=None, g=speed_gain, angles=[1])
    want_ekf = ref.ekf(ct, range_bearing, Q_ALONG, R, y, x0, P0, jac_f=ct_jac, jac_h=range_bearing_jac, **refs)
    want_ukf = ref.ukf(ct, range_bearing, Q_ALONG, R, y, x0, P0, points=ref.merwe(0.5), **refs)
    got_ekf, got_ukf = model.ekf(y, x0, P0), model.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5))
    for got, want in ((got_ekf, want_ekf), (got_ukf, want_ukf)):
        for k in FIELDS:
            np.testing.assert_allclose(getattr(got, k), want[k], rtol=1e-10, atol=1e-10, err_msg=k)
        assert got.loglik == pytest.approx(want["loglik"], rel=1e-10)
    # the gain matters: without it (Q folded at the prior's heading) the filter differs
    G0 = speed_gain(x0[None], 0, None)[0]
    fixed = kfast.NonlinearModel(ct, range_bearing, G0 @ Q_ALONG @ G0.T, R, n=5, jac_f=ct_jac, jac_h=range_bearing_jac, angles=[1])
    other = fixed.ekf(y, x0, P0)
    assert np.abs(other.P_next - got_ekf.P_next).max() > 1e-3 * np.abs(got_ekf.P_next).max()


def test_streaming_and_batch_filters_use_the_gain():
    R, y, x0, P0 = data(T=12)
    model = kfast.NonlinearModel(kfast.models.coordinated_turn(DT), kfast.models.range_bearing(), Q_W, R, n=5, g=speed_gain)
    whole = model.ukf(y, x0, P0)
    stream = kfast.UnscentedKalmanFilter(model, x0, P0)
    for t in range(len(y)):
        stream.update(y[t])
        np.testing.assert_allclose(stream.P, whole.P_filt[t], rtol=1e-13, atol=1e-13)
        stream.predict()
    np.testing.assert_allclose(stream.P, whole.P_next, rtol=1e-13, atol=1e-13)
    bank = kfast.ukf_batch(model, np.stack([y, y]), x0, P0)
    np.testing.assert_array_equal(bank.P_filt[1], whole.P_filt)


def test_bad_gains_are_named():
    R, y, x0, P0 = data(T=8)
    ct_builtin, radar = kfast.models.coordinated_turn(DT), kfast.models.range_bearing()
    with pytest.raises(kfast.KfastError, match=r"g: a constant noise gain must have shape \(n, r\) = \(5, 3\)"):
        kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5, g=G_CT[:, :2])
    with pytest.raises(kfast.KfastError, match=r"Q: expected \(5, 5\), got \(3, 3\)"):
        kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5)
    wrong = kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5, g=lambda X, t, u: np.zeros((len(X), 5, 2)))
    with pytest.raises(kfast.KfastError, match=r"g at step 0: .*shape \(1, 5, 2\).*expected \(1, 5, 3\)"):
        wrong.ekf(y, x0, P0)

    def nan_later(X, t, u):
        G = np.broadcast_to(G_CT, (len(X), 5, 3)).copy()
        if t == 3:
            G[:, 0, 0] = np.nan
        return G

    model = kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5, g=nan_later)
    with pytest.raises(kfast.KfastError, match=r"g at step 3: returned a non-finite value"):
        model.ukf(y, x0, P0)
    stream = kfast.ExtendedKalmanFilter(model, x0, P0)
    for t in range(3):
        stream.update(y[t])
        stream.predict()
    stream.update(y[3])
    with pytest.raises(kfast.KfastError, match=r"g at step 3"):
        stream.predict()
