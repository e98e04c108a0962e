"""Exact diffuse initialization (P0_inf): Koopman's (1997) closed forms, statsmodels' exact
diffuse filter (the same univariate method) on random models with mixed known and diffuse
states, missing data and correlated measurement noise, and the limit of a growing vague prior."""

from __future__ import annotations

import numpy as np
import pytest
from statsmodels.tsa.statespace.initialization import Initialization

import kfast
from kfast import models

# -- Koopman (1997), section 5: closed forms ------------------------------------------------

Y1, Y2, Y3 = 10.2394, 4.2039, 6.123123


def test_local_level_koopman_1997():
    sigma2_y, sigma2_mu = 1.993, 8.253
    y = np.r_[Y1, [1.0] * 9]
    res = models.local_level(sigma2_mu, irregular=sigma2_y).filter(y, [0.0], [[0.0]], P0_inf=[[1.0]])
    assert res.n_diffuse == 1
    assert (res.innov[0, 0], res.S[0, 0, 0], res.K[0, 0, 0]) == pytest.approx((Y1, sigma2_y, 1.0), rel=1e-14)
    assert res.P_pred_inf[0, 0, 0] == 1.0 and res.P_pred_inf[1, 0, 0] == 0.0
    assert res.x_pred[1, 0] == pytest.approx(Y1, rel=1e-14)
    assert res.P_pred[1, 0, 0] == pytest.approx(sigma2_y + sigma2_mu, rel=1e-14)
    # The diffuse log-likelihood term: -(log 2 pi + log F_inf) / 2 with F_inf = 1.
    assert res.loglik_t[0] == pytest.approx(-0.5 * np.log(2 * np.pi), rel=1e-14)


@pytest.mark.parametrize("missing", [False, True])
def test_local_linear_trend_koopman_1997(missing):
    sigma2_y, sigma2_mu, sigma2_beta = 1.993, 8.253, 2.334
    q_mu, q_beta = sigma2_mu / sigma2_y, sigma2_beta / sigma2_y
    y = np.r_[Y1, np.nan if missing else Y2, Y3, [1.0] * 7]
    res = models.local_linear_trend(sigma2_mu, sigma2_beta, irregular=sigma2_y).filter(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))
    np.testing.assert_allclose(res.K[0, :, 0], [1, 0], atol=1e-15)
    np.testing.assert_allclose(res.x_pred[1], [Y1, 0], atol=1e-14)
    np.testing.assert_allclose(res.P_pred[1], sigma2_y * np.array([[1 + q_mu, 0], [0, q_beta]]), rtol=1e-14)
    np.testing.assert_allclose(res.P_pred_inf[1], np.ones((2, 2)), rtol=1e-14)
    if not missing:
        assert res.n_diffuse == 2
        np.testing.assert_allclose(res.x_pred[2], [2 * Y2 - Y1, Y2 - Y1], rtol=1e-13)
        P3 = sigma2_y * np.array([[5 + 2 * q_mu + q_beta, 3 + q_mu + q_beta], [3 + q_mu + q_beta, 2 + q_mu + 2 * q_beta]])
        np.testing.assert_allclose(res.P_pred[2], P3, rtol=1e-13)
        np.testing.assert_allclose(res.P_pred_inf[2], 0.0)
    else:
        assert res.n_diffuse == 3
        np.testing.assert_allclose(res.x_pred[3], [1.5 * Y3 - 0.5 * Y1, 0.5 * Y3 - 0.5 * Y1], rtol=1e-13)
        P4 = sigma2_y * np.array(
            [[2.5 + 1.5 * q_mu + 1.25 * q_beta, 1 + 0.5 * q_mu + 1.25 * q_beta], [1 + 0.5 * q_mu + 1.25 * q_beta, 0.5 + 0.5 * q_mu + 2.25 * q_beta]]
        )
        np.testing.assert_allclose(res.P_pred[3], P4, rtol=1e-13)


def test_common_level_koopman_1997():
    theta, sigma2_mu = 0.1111, 3.2324
    y11, y21 = 10.2394, 8.2304
    y = np.column_stack([np.r_[y11, [1.0] * 9], np.r_[y21, [1.0] * 9]])
    model = kfast.LinearGaussian(np.eye(2), [[1.0, 0.0], [theta, 1.0]], np.diag([sigma2_mu, 0.0]), np.eye(2))
    res = model.filter(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))
    assert res.n_diffuse == 1
    np.testing.assert_allclose(res.x_pred[1], [y11, y21 - theta * y11], rtol=1e-13)
    np.testing.assert_allclose(res.P_pred[1], [[1 + sigma2_mu, -theta], [-theta, 1 + theta**2]], rtol=1e-13)
    # Restricted (mu_bar = 0): one state seen through both outputs.
    restricted = kfast.LinearGaussian(1.0, [[1.0], [theta]], sigma2_mu, np.eye(2))
    res = restricted.filter(y, [0.0], [[0.0]], P0_inf=[[1.0]])
    phi = 1 / (1 + theta**2)
    assert res.x_pred[1, 0] == pytest.approx(phi * (y11 + theta * y21), rel=1e-13)
    assert res.P_pred[1, 0, 0] == pytest.approx(phi + sigma2_mu, rel=1e-13)


# -- statsmodels' exact diffuse filter ---------------------------------------------------------


def _mixed_model(seed, m=2, correlated_R=False):
    """States: a random walk and a local linear trend (diffuse), then a stationary AR(2)."""
    rng = np.random.default_rng(seed)
    n = 5
    F = np.zeros((n, n))
    F[0, 0] = 1.0
    F[1:3, 1:3] = [[1.0, 1.0], [0.0, 1.0]]
    F[3:5, 3:5] = [[0.5, 0.3], [1.0, 0.0]]
    H = rng.standard_normal((m, n))
    Q = np.diag(rng.uniform(0.1, 1.0, n))
    Q[4, 4] = 0.0
    A = rng.standard_normal((m, m))
    R = A @ A.T + 0.5 * np.eye(m) if correlated_R else np.diag(rng.uniform(0.2, 1.0, m))
    x0 = np.r_[0.0, 0.0, 0.0, rng.standard_normal(2)]
    P0 = np.zeros((n, n))
    P0[3:, 3:] = kfast.solve_discrete_lyapunov(F[3:, 3:], Q[3:, 3:])
    P_inf = np.diag([1.0, 1.0, 1.0, 0.0, 0.0])
    model = kfast.LinearGaussian(F, H, Q, R)
    x, y = model.simulate(40, x0, P0 + 10 * P_inf, seed=seed)
    return model, y, x0, P0, P_inf


def _statsmodels(model, y, x0, P0):
    """statsmodels' smoother (its filter's output too) with the first three states diffuse."""
    from statsmodels.tsa.statespace.kalman_smoother import KalmanSmoother

    T, m = y.shape
    n = model.n_states
    ssm = KalmanSmoother(k_endog=m, k_states=n, k_posdef=n)
    ssm.bind(np.ascontiguousarray(y))
    ssm["design"], ssm["obs_cov"], ssm["transition"], ssm["state_cov"] = model.H, model.R, model.F, model.Q
    ssm["selection"] = np.eye(n)
    init = Initialization(n)
    init.set((0, 3), "diffuse")
    init.set((3, 5), "known", constant=x0[3:], stationary_cov=P0[3:, 3:])
    ssm.initialize(init)
    return ssm.smooth()


@pytest.mark.parametrize("seed, missing, correlated_R", [(0, False, False), (1, True, False), (2, True, True), (3, False, True)])
def test_equals_statsmodels(seed, missing, correlated_R):
    model, y, x0, P0, P_inf = _mixed_model(seed, correlated_R=correlated_R)
    if missing:
        y[0, 1] = y[2] = y[7, 0] = np.nan
    res = model.filter(y, x0, P0, P0_inf=P_inf)
    sm = _statsmodels(model, y, x0, P0)
    assert res.n_diffuse == sm.nobs_diffuse
    assert res.loglik == pytest.approx(sm.llf_obs.sum(), rel=1e-10)
    np.testing.assert_allclose(res.loglik_t, sm.llf_obs, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.x_pred, sm.predicted_state[:, :-1].T, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(res.P_pred, np.moveaxis(sm.predicted_state_cov[..., :-1], -1, 0), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(res.P_pred_inf, np.moveaxis(sm.predicted_diffuse_state_cov[..., :-1], -1, 0), atol=1e-12)
    np.testing.assert_allclose(res.x_filt, sm.filtered_state.T, rtol=1e-9, atol=1e-9)
    d = res.n_diffuse
    np.testing.assert_allclose(res.K_pred[d:], np.moveaxis(sm.kalman_gain, -1, 0)[d:], rtol=1e-8, atol=1e-10)
    assert model.loglik(y, x0, P0, P0_inf=P_inf) == res.loglik


def test_the_limit_of_a_growing_vague_prior():
    """The diffuse log-likelihood is lim (loglik with P0 + kappa P_inf) + (q/2) log kappa, and
    the estimates after the diffuse steps are the limits of the vague prior's."""
    model, y, x0, P0, P_inf = _mixed_model(4)
    exact = model.filter(y, x0, P0, P0_inf=P_inf)
    q = np.linalg.matrix_rank(P_inf)
    for kappa in [1e5, 1e6]:
        vague = model.filter(y, x0, P0 + kappa * P_inf)
        assert vague.loglik + 0.5 * q * np.log(kappa) == pytest.approx(exact.loglik, abs=30 / kappa**0.5)
        d = exact.n_diffuse
        np.testing.assert_allclose(vague.x_filt[d:], exact.x_filt[d:], rtol=1e-3, atol=100 / kappa)


def test_every_step_diffuse_and_bad_input():
    walk = models.local_level(1.0, irregular=1.0)
    res = walk.filter([np.nan, np.nan], [0.0], [[0.0]], P0_inf=[[1.0]])
    assert res.n_diffuse == 2 and res.loglik == 0.0
    np.testing.assert_allclose(res.P_next, [[2.0]])
    with pytest.raises(ValueError, match="P0_inf: "):
        walk.filter([1.0], [0.0], [[0.0]], P0_inf=[[-1.0]])
    with pytest.raises(ValueError, match="P0_inf: "):
        walk.filter([1.0], [0.0], [[0.0]], P0_inf=np.eye(2))
    with pytest.raises(ValueError, match="P0_inf: .*N = 0"):
        kfast.LinearGaussian(1.0, 1.0, 1.0, 1.0, N=0.5).filter([1.0], [0.0], [[0.0]], P0_inf=[[1.0]])
    singular_R = kfast.LinearGaussian(np.eye(2), np.eye(2), np.eye(2), [[1.0, 1.0], [1.0, 1.0]])
    with pytest.raises(ValueError, match="R at step 0: .*positive definite"):
        singular_R.filter(np.ones((3, 2)), np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))


# -- the exact diffuse smoother ------------------------------------------------------------------


@pytest.mark.parametrize("seed, missing, correlated_R", [(0, False, False), (1, True, False), (2, True, True)])
def test_smoother_equals_statsmodels(seed, missing, correlated_R):
    model, y, x0, P0, P_inf = _mixed_model(seed, correlated_R=correlated_R)
    if missing:
        y[0, 1] = y[2] = y[7, 0] = np.nan
    sm = model.smooth(y, x0, P0, P0_inf=P_inf)
    ref = _statsmodels(model, y, x0, P0)
    np.testing.assert_allclose(sm.x_smooth, ref.smoothed_state.T, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(sm.P_smooth, np.moveaxis(ref.smoothed_state_cov, -1, 0), rtol=1e-8, atol=1e-8)
    # statsmodels' smoothed_state_autocov[t] is Cov(x(t+1), x(t) | y); in the diffuse steps it is
    # not the kappa -> inf limit (its own tests skip them), so compare after them and check the
    # limit below.
    d = sm.filter.n_diffuse
    assert d == ref.nobs_diffuse
    lag = np.moveaxis(ref.smoothed_state_autocov, -1, 0)
    np.testing.assert_allclose(sm.P_lag1[d + 1 :], lag[d:-1], rtol=1e-7, atol=1e-8)
    vague = model.smooth(y, x0, P0 + 1e7 * P_inf)
    np.testing.assert_allclose(sm.P_lag1, vague.P_lag1, atol=1e-4)
    np.testing.assert_allclose(sm.P_smooth, vague.P_smooth, atol=1e-4)


def test_smoother_koopman_local_level_and_refusals():
    # One observation of a diffuse random walk: x(0|T) = y(0) and P(0|T) = R.
    walk = models.local_level(2.0, irregular=0.5)
    sm = walk.smooth([3.0], [0.0], [[0.0]], P0_inf=[[1.0]])
    assert sm.x_smooth[0, 0] == pytest.approx(3.0, rel=1e-13)
    assert sm.P_smooth[0, 0, 0] == pytest.approx(0.5, rel=1e-12)
    with pytest.raises(ValueError, match="P0_inf: the data do not determine every diffuse direction"):
        walk.smooth([np.nan, np.nan], [0.0], [[0.0]], P0_inf=[[1.0]])


def test_fit_with_an_exact_diffuse_start_equals_statsmodels():
    import warnings

    from statsmodels.tsa.statespace.structural import UnobservedComponents

    rng = np.random.default_rng(8)
    y = np.cumsum(0.7 * rng.standard_normal(120)) + rng.standard_normal(120)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = UnobservedComponents(y, "llevel", use_exact_diffuse=True).fit(disp=False)

    def build(theta):
        return models.local_level(np.exp(theta[1]), irregular=np.exp(theta[0])), [0.0], [[0.0]]

    res = kfast.fit(build, [0.0, 0.0], y, P0_inf=[[1.0]])
    assert res.loglik == pytest.approx(ref.llf, abs=1e-6)
    np.testing.assert_allclose(np.exp(res.theta), ref.params, rtol=1e-3)


def test_local_linear_trend_with_a_missing_value_equals_kfas():
    from pathlib import Path

    import pandas as pd

    kfas = pd.read_csv(Path(__file__).resolve().parents[1] / "data" / "kfas_exact_diffuse_local_linear_trend.csv", comment="#")
    model = models.local_linear_trend(8.253, 2.334, irregular=1.993)
    y = np.r_[Y1, np.nan, Y3, [1.0] * 7]
    sm = model.smooth(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))
    res = sm.filter
    np.testing.assert_allclose(res.x_pred, kfas[["a_1", "a_2"]][:10], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.x_next, kfas[["a_1", "a_2"]].iloc[10], rtol=1e-9)
    np.testing.assert_allclose(res.P_pred.sum(axis=(1, 2)), kfas["sumP"][:10], rtol=1e-9)
    d = res.n_diffuse
    np.testing.assert_allclose(res.P_pred_inf[:d].sum(axis=(1, 2)), kfas["sumPinf"][:d], rtol=1e-12)
    assert np.isnan(kfas["sumPinf"][d])
    np.testing.assert_allclose(sm.x_smooth, kfas[["alphahat_1", "alphahat_2"]][:10], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(sm.P_smooth.sum(axis=(1, 2)), kfas["sumV"][:10], rtol=1e-9)
    # KFAS leaves out log(2 pi) / 2 for each of the two diffuse terms (y(0) and y(2)).
    assert res.loglik == pytest.approx(-18.3036127435546 - np.log(2 * np.pi), rel=1e-12)
