"""Process noise as an input of f: x[t+1] = f(x[t], w[t], t, u[t]), w ~ N(0, Q) with Q r x r
(``NonlinearModel(..., noise_input=True)``). The EKF linearizes f in x and w at (x(t|t), 0); the
UKF draws its time-update points from the augmented (x, w). Shown: f(x, w) = f(x) + G w is the
noise-gain model (EKF exactly); a linear f(x, w) = F x + G w is the Kalman filter (EKF and UKF);
a genuinely non-additive f equals the NumPy reference for every filter and smoother, through
the streaming and batch filters too; a singular Q is accepted; bad combinations are named."""

import numpy as np
import pytest
from test_noise_gain import G_CT, Q_W
from tracking import DT, ct, ct_jac, ct_jac_one, ct_one, ct_problem, range_bearing, range_bearing_jac

import kfast
from kfast.reference import nonlinear as ref

FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "S", "K", "loglik_t", "x_next", "P_next")


def data(T=30):
    _, R, y, x0, P0 = ct_problem(T=T)
    y = y.copy()
    y[5, 1] = np.nan
    return R, y, x0, P0


def gained(X, W, t, u):
    """CT plus G w: the noise-gain model written with the noise as an input."""
    return ct(X, t, u) + W @ G_CT.T


def gained_jac(X, W, t, u):
    return np.concatenate([ct_jac(X, t, u), np.broadcast_to(G_CT, (len(X), 5, 3))], axis=2)


def turn_noise(X, W, t, u):
    """A turn-rate disturbance inside the rotation and accelerations scaled by the speed:
    non-additive in w."""
    Xw = X.copy()
    Xw[:, 4] = X[:, 4] + W[:, 2]
    speed = np.hypot(X[:, 2], X[:, 3])[:, None]
    accel = (W[:, :2] * (1 + 0.1 * speed)) @ G_CT[:, :2].T
    return np.array([ct_one(x) for x in Xw]) + accel


def turn_noise_jac(X, W, t, u):
    """[d/dx, d/dw] of turn_noise, (k, 5, 8)."""
    J = np.zeros((len(X), 5, 8))
    for i, (x, w) in enumerate(zip(X, W)):
        xw = x.copy()
        xw[4] += w[2]
        F = ct_jac_one(xw)
        speed = np.hypot(x[2], x[3])
        J[i, :, :5] = F + 0.1 * np.outer(G_CT[:, :2] @ w[:2], [0, 0, x[2] / speed, x[3] / speed, 0])
        J[i, :, 5:7] = G_CT[:, :2] * (1 + 0.1 * speed)
        J[i, :, 7] = F[:, 4]
    return J


def test_f_plus_g_w_is_the_noise_gain_model():
    R, y, x0, P0 = data()
    as_input = kfast.NonlinearModel(gained, range_bearing, Q_W, R, n=5, jac_f=gained_jac, jac_h=range_bearing_jac, angles=[1], noise_input=True)
    as_gain = kfast.NonlinearModel(ct, range_bearing, Q_W, R, n=5, jac_f=ct_jac, jac_h=range_bearing_jac, angles=[1], g=G_CT)
    for run in (lambda m: m.ekf(y, x0, P0), lambda m: m.ekf(y, x0, P0, iterations=2, iteration="gauss-newton")):
        a, b = run(as_input), run(as_gain)
        for k in FIELDS:
            np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=1e-12, atol=1e-12, err_msg=k)
    # differenced Jacobians: f is linear in w, so its w columns are G to rounding
    by_differences = kfast.NonlinearModel(gained, range_bearing, Q_W, R, n=5, angles=[1], noise_input=True)
    np.testing.assert_allclose(by_differences.ekf(y, x0, P0).P_filt, as_gain.ekf(y, x0, P0).P_filt, rtol=1e-6, atol=1e-8)
    # the UKF spreads points in w too: close to the gain model, not the same numbers
    u_in, u_gain = as_input.ukf(y, x0, P0), as_gain.ukf(y, x0, P0)
    assert 0 < np.max(np.abs(u_in.x_filt - u_gain.x_filt)) < 1.0


@pytest.mark.parametrize("points", ["merwe", "julier", "cubature"])
def test_a_linear_transition_with_noise_input_is_the_kalman_filter(points):
    rng = np.random.default_rng(11)
    n, r, m, T = 3, 2, 2, 25
    F = 0.9 * np.linalg.qr(rng.standard_normal((n, n)))[0]
    G, H = rng.standard_normal((n, r)), rng.standard_normal((m, n))
    Q, R = np.diag([0.5, 0.2]), np.diag([0.3, 0.1])
    lin = kfast.LinearGaussian(F, H, G @ Q @ G.T, R)
    y = lin.simulate(T, np.zeros(n), np.eye(n), seed=3).y
    want = lin.filter(y, np.zeros(n), np.eye(n), outputs=("x_filt", "P_filt", "loglik_t"))
    model = kfast.NonlinearModel(lambda X, W, t, u: X @ F.T + W @ G.T, lambda X, t, u: X @ H.T, Q, R, n=n, noise_input=True)
    sets = {"merwe": kfast.sigma.merwe(0.5), "julier": kfast.sigma.julier(1.0), "cubature": kfast.sigma.cubature()}
    for got in (model.ukf(y, np.zeros(n), np.eye(n), points=sets[points]), model.ekf(y, np.zeros(n), np.eye(n))):
        for k in ("x_filt", "P_filt", "loglik_t"):
            np.testing.assert_allclose(getattr(got, k), getattr(want, k), rtol=1e-9, atol=1e-10, err_msg=k)


def reference_runs(R, y, x0, P0, Q):
    common = dict(angles=[1], noise_input=True)
    jacobians = dict(jac_f=turn_noise_jac, jac_h=range_bearing_jac)
    return {
        "ekf": ref.ekf(turn_noise, range_bearing, Q, R, y, x0, P0, **jacobians, **common),
        "iekf": ref.ekf(turn_noise, range_bearing, Q, R, y, x0, P0, iterations=2, iteration="book", **jacobians, **common),
        "merwe": ref.ukf(turn_noise, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), **common),
        "julier": ref.ukf(turn_noise, range_bearing, Q, R, y, x0, P0, points=ref.julier(1.0), **common),
        "cubature": ref.ukf(turn_noise, range_bearing, Q, R, y, x0, P0, points=ref.cubature(), **common),
    }


def kfast_runs(model, y, x0, P0):
    return {
        "ekf": model.ekf(y, x0, P0),
        "iekf": model.ekf(y, x0, P0, iterations=2, iteration="book"),
        "merwe": model.ukf(y, x0, P0, points=kfast.sigma.merwe(0.5)),
        "julier": model.ukf(y, x0, P0, points=kfast.sigma.julier(1.0)),
        "cubature": model.ukf(y, x0, P0, points=kfast.sigma.cubature()),
    }


@pytest.mark.parametrize("Q", [Q_W, np.diag([1.0, 0.0, 0.05**2 / DT]), np.zeros((3, 3))], ids=["full", "singular", "zero"])
def test_non_additive_noise_equals_the_reference(Q):
    R, y, x0, P0 = data()
    model = kfast.NonlinearModel(
        turn_noise, range_bearing, Q, R, n=5, jac_f=turn_noise_jac, jac_h=range_bearing_jac, angles=[1], noise_input=True
    )
    got, want = kfast_runs(model, y, x0, P0), reference_runs(R, y, x0, P0, Q)
    for name in want:
        for k in FIELDS:
            np.testing.assert_allclose(getattr(got[name], k), want[name][k], rtol=1e-9, atol=1e-9, err_msg=(name, k))
        assert got[name].loglik == pytest.approx(want[name]["loglik"], rel=1e-10)
    # the noise matters: the EKF differs from the model without it unless Q = 0 (L Q L' = 0)
    still = kfast.NonlinearModel(ct, range_bearing, np.zeros((5, 5)), R, n=5, jac_h=range_bearing_jac, angles=[1])
    differs = np.max(np.abs(still.ekf(y, x0, P0).P_filt - got["ekf"].P_filt))
    assert (differs > 1e-3) == bool(Q.any()), differs


def test_differenced_jacobians_and_hessians_in_x_and_w():
    """Central differences over the n + r numbers agree with turn_noise_jac (to the
    differences' accuracy), and the second-order EKF's trace runs over diag(P, Q) as the
    reference's does."""
    R, y, x0, P0 = data()
    exact = kfast.NonlinearModel(turn_noise, range_bearing, Q_W, R, n=5, jac_f=turn_noise_jac, angles=[1], noise_input=True)
    differenced = kfast.NonlinearModel(turn_noise, range_bearing, Q_W, R, n=5, angles=[1], noise_input=True)
    np.testing.assert_allclose(differenced.ekf(y, x0, P0).x_filt, exact.ekf(y, x0, P0).x_filt, rtol=1e-7, atol=1e-7)
    got = differenced.ekf(y, x0, P0, order=2)
    want = ref.ekf(turn_noise, range_bearing, Q_W, R, y, x0, P0, order=2, angles=[1], noise_input=True)
    np.testing.assert_allclose(got.x_filt, want["x_filt"], rtol=1e-6, atol=1e-6)
    # the w part of the trace: the ω noise bends the predicted position
    assert np.max(np.abs(got.x_pred - differenced.ekf(y, x0, P0).x_pred)) > 1e-4


def test_smoothers_with_noise_input_equal_the_reference():
    R, y, x0, P0 = data()
    model = kfast.NonlinearModel(
        turn_noise, range_bearing, Q_W, R, n=5, jac_f=turn_noise_jac, jac_h=range_bearing_jac, angles=[1], noise_input=True
    )
    common = dict(angles=[1], noise_input=True)
    xs, Ps, _ = ref.extended_rts(turn_noise, range_bearing, Q_W, R, y, x0, P0, jac_f=turn_noise_jac, jac_h=range_bearing_jac, **common)
    got = model.smooth(y, x0, P0, method="ekf")
    np.testing.assert_allclose(got.x_smooth, xs, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.P_smooth, Ps, rtol=1e-9, atol=1e-9)
    xs, Ps, _ = ref.unscented_rts(turn_noise, range_bearing, Q_W, R, y, x0, P0, points=ref.merwe(0.5), **common)
    got = model.smooth(y, x0, P0, method="ukf", points=kfast.sigma.merwe(0.5))
    np.testing.assert_allclose(got.x_smooth, xs, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.P_smooth, Ps, rtol=1e-9, atol=1e-9)


def test_streaming_and_batch_filters_take_the_noise_input():
    R, y, x0, P0 = data(T=12)
    model = kfast.NonlinearModel(turn_noise, range_bearing, Q_W, R, n=5, angles=[1], noise_input=True)
    for whole, stream in (
        (model.ukf(y, x0, P0), kfast.UnscentedKalmanFilter(model, x0, P0)),
        (model.ekf(y, x0, P0), kfast.ExtendedKalmanFilter(model, x0, P0)),
    ):
        for t in range(len(y)):
            stream.update(y[t])
            np.testing.assert_array_equal(stream.P, whole.P_filt[t])
            stream.predict()
        np.testing.assert_array_equal(stream.P, whole.P_next)
    bank = kfast.ukf_batch(model, np.stack([y, y[::-1]]), x0, P0)
    np.testing.assert_array_equal(bank.P_filt[0], model.ukf(y, x0, P0).P_filt)
    np.testing.assert_array_equal(bank.x_filt[1], model.ukf(y[::-1], x0, P0).x_filt)
    assert "noise_input=True" in repr(model)


def test_bad_noise_inputs_are_named():
    R, y, x0, P0 = data(T=6)
    ct_builtin, radar = kfast.models.coordinated_turn(DT), kfast.models.range_bearing()
    with pytest.raises(kfast.KfastError, match="noise_input: a built-in f has additive noise"):
        kfast.NonlinearModel(ct_builtin, radar, Q_W, R, n=5, noise_input=True)
    with pytest.raises(kfast.KfastError, match="noise_input: a noise gain g and the noise as an input of f exclude each other"):
        kfast.NonlinearModel(gained, radar, Q_W, R, n=5, g=G_CT, noise_input=True)
    model = kfast.NonlinearModel(gained, radar, Q_W, R, n=5, noise_input=True)
    unit = np.vstack([np.eye(5), -np.eye(5)]) * np.sqrt(5)
    with pytest.raises(kfast.KfastError, match=r"points: a custom set has one size.*n \+ r = 8"):
        model.ukf(y, x0, P0, points=kfast.sigma.custom(unit, np.full(10, 0.1)))
    wrong = kfast.NonlinearModel(lambda X, W, t, u: X[:, :4], radar, Q_W, R, n=5, noise_input=True)
    with pytest.raises(kfast.KfastError, match=r"f at step 0: .*shape \(\d+, 4\).*expected \(\d+, 5\)"):
        wrong.ukf(y, x0, P0)
    bad_jac = kfast.NonlinearModel(gained, radar, Q_W, R, n=5, jac_f=lambda X, W, t, u: ct_jac(X, t, u), noise_input=True)
    with pytest.raises(kfast.KfastError, match=r"f at step 0: its Jacobian returned shape \(1, 5, 5\).*expected \(1, 5, 8\)"):
        bad_jac.ekf(y, x0, P0)

    def nan_at_2(X, W, t, u):
        out = gained(X, W, t, u)
        if t == 2:
            out[0, 0] = np.nan
        return out

    with pytest.raises(kfast.KfastError, match=r"f at step 2: returned a non-finite value"):
        kfast.NonlinearModel(nan_at_2, radar, Q_W, R, n=5, noise_input=True).ukf(y, x0, P0)
