"""The square-root UKF (``form="sqrt"``, van der Merwe & Wan 2001): the factors of P(t|t-1) and
P(t|t) carried by QR and Cholesky downdates. It equals the standard UKF to rounding (every point
set: positive weights, a negative centre term (Julier), no centre (cubature), a custom set), the
NumPy reference's square-root filter, and the Kalman filter on a linear model; it runs through
the smoother, the streaming and the batch filters and with noise inputs; it accepts the singular
P0 on which the standard form stops."""

import numpy as np
import pytest
from test_noise_input import turn_noise
from test_noise_gain import Q_W
from tracking import ct, ct_problem, range_bearing

import kfast
from kfast.reference import nonlinear as ref

FIELDS = ("x_pred", "P_pred", "x_filt", "P_filt", "S", "K", "loglik_t", "x_next", "P_next")
# alpha = 1e-3 is ill-conditioned in any form (the mean's second-order term is a second
# difference with a step of alpha sigma): correct implementations agree to ~1e-6 there
SETS = {
    "merwe": (kfast.sigma.merwe(0.5), ref.merwe(0.5)),
    "merwe-small-alpha": (kfast.sigma.merwe(1e-3), ref.merwe(1e-3)),
    "julier": (kfast.sigma.julier(1.0), ref.julier(1.0)),
    "cubature": (kfast.sigma.cubature(), ref.cubature()),
}


def data(T=40):
    Q, R, y, x0, P0 = ct_problem(T=T)
    y = y.copy()
    if T > 9:
        y[4, 0] = np.nan
        y[9] = np.nan
    return Q, R, y, x0, P0


def assert_fields(got, want, tol, fields=FIELDS):
    for k in fields:
        w = want[k] if isinstance(want, dict) else getattr(want, k)
        np.testing.assert_allclose(getattr(got, k), w, rtol=tol, atol=tol, err_msg=k)


@pytest.mark.parametrize("name", SETS)
def test_the_square_root_form_is_the_standard_form_and_the_reference(name):
    Q, R, y, x0, P0 = data()
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    points, ref_points = SETS[name]
    tol = 1e-5 if name == "merwe-small-alpha" else 1e-9
    got = model.ukf(y, x0, P0, points=points, form="sqrt")
    assert_fields(got, model.ukf(y, x0, P0, points=points), tol)
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref_points, angles=[1], form="sqrt")
    assert_fields(got, want, tol / 10)
    assert got.loglik == pytest.approx(want["loglik"], rel=tol / 10)


def test_a_custom_set_with_a_negative_weight():
    """Julier's set written out by hand with kappa = -1 (n = 5): the centre weight is negative,
    so the factor takes a downdate for that point."""
    Q, R, y, x0, P0 = data()
    n, kappa = 5, -1.0
    unit = np.vstack([np.zeros(n), np.eye(n) * np.sqrt(n + kappa), -np.eye(n) * np.sqrt(n + kappa)])
    W = np.r_[kappa / (n + kappa), np.full(2 * n, 0.5 / (n + kappa))]
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    got = model.ukf(y, x0, P0, points=kfast.sigma.custom(unit, W), form="sqrt")
    assert_fields(got, model.ukf(y, x0, P0, points=kfast.sigma.custom(unit, W)), 1e-9)
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref.CustomPoints(unit, W), angles=[1], form="sqrt")
    assert_fields(got, want, 1e-10)


def test_on_a_linear_model_the_square_root_ukf_is_the_kalman_filter():
    rng = np.random.default_rng(5)
    n, m, T = 4, 2, 30
    F = 0.95 * np.linalg.qr(rng.standard_normal((n, n)))[0]
    H = rng.standard_normal((m, n))
    A = rng.standard_normal((n, n))
    lin = kfast.LinearGaussian(F, H, A @ A.T / n, np.diag([0.5, 0.2]))
    y = lin.simulate(T, np.zeros(n), np.eye(n), seed=2).y
    y[3, 1] = np.nan
    want = lin.filter(y, np.zeros(n), np.eye(n))
    got = kfast.NonlinearModel.from_linear(lin).ukf(y, np.zeros(n), np.eye(n), points=kfast.sigma.merwe(0.7), form="sqrt")
    assert_fields(got, want, 1e-9, ("x_filt", "P_filt", "x_pred", "P_pred", "loglik_t"))


def test_smoother_streaming_batch_and_noise_inputs_take_the_square_root_form():
    Q, R, y, x0, P0 = data(T=25)
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    pts = kfast.sigma.merwe(0.5)
    got = model.smooth(y, x0, P0, method="ukf", points=pts, form="sqrt")
    xs, Ps, _ = ref.unscented_rts(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), angles=[1], form="sqrt")
    np.testing.assert_allclose(got.x_smooth, xs, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(got.P_smooth, Ps, rtol=1e-10, atol=1e-10)
    whole = model.ukf(y, x0, P0, points=pts, form="sqrt")
    stream = kfast.UnscentedKalmanFilter(model, x0, P0, points=pts, form="sqrt")
    for t in range(len(y)):
        stream.update(y[t])
        np.testing.assert_array_equal(stream.P, whole.P_filt[t])
        stream.predict()
    np.testing.assert_array_equal(stream.x, whole.x_next)
    bank = kfast.ukf_batch(model, np.stack([y, y]), x0, P0, points=pts, form="sqrt")
    np.testing.assert_array_equal(bank.P_filt[1], whole.P_filt)
    # the noise as an input of f
    noisy = kfast.NonlinearModel(turn_noise, range_bearing, Q_W, R, n=5, angles=[1], noise_input=True)
    want = ref.ukf(turn_noise, range_bearing, Q_W, R, y, x0, P0, points=ref.merwe(0.5), angles=[1], noise_input=True, form="sqrt")
    assert_fields(noisy.ukf(y, x0, P0, points=pts, form="sqrt"), want, 1e-10)


def test_a_singular_prior_stops_the_standard_form_but_not_the_square_root_form():
    """A known turn rate: P0 has a zero variance. The standard UKF cannot factor P(0|-1); the
    square-root form starts from its semidefinite factor, and equals the standard form started
    from a vanishing variance instead."""
    Q, R, y, x0, P0 = data()
    P0 = P0.copy()
    P0[4, 4] = 0.0
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    with pytest.raises(kfast.KfastError, match=r"P\(t\|t-1\).*step 0|step 0.*P\(t\|t-1\)"):
        model.ukf(y, x0, P0)
    pts = kfast.sigma.merwe(0.5)
    got = model.ukf(y, x0, P0, points=pts, form="sqrt")
    assert np.all(np.isfinite(got.P_filt)) and np.all(np.linalg.eigvalsh(got.P_filt) > -1e-12)
    nearly = P0.copy()
    nearly[4, 4] = 1e-24
    np.testing.assert_allclose(got.x_filt, model.ukf(y, x0, nearly, points=pts).x_filt, rtol=1e-7, atol=1e-7)
    want = ref.ukf(ct, range_bearing, Q, R, y, x0, P0, points=ref.merwe(0.5), angles=[1], form="sqrt")
    assert_fields(got, want, 1e-9, ("x_filt", "P_filt", "x_next", "P_next"))


def test_a_bad_form_is_named():
    Q, R, y, x0, P0 = data(T=3)
    model = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    with pytest.raises(kfast.KfastError, match="form"):
        model.ukf(y, x0, P0, form="joseph")
    with pytest.raises(kfast.KfastError, match="form"):
        model.smooth(y, x0, P0, method="ukf", form="joseph")
    with pytest.raises(kfast.KfastError, match="form"):
        model.smooth(y, x0, P0, method="ekf", form="sqrt")
    with pytest.raises(kfast.KfastError, match="form"):
        kfast.UnscentedKalmanFilter(model, x0, P0, form="square-root")
