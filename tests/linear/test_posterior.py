"""The disturbance smoother and the simulation smoother (Durbin & Koopman 2002): against KFAS's
results shipped with statsmodels (transcribed in tests/data), against the state smoother they
must agree with, and as samplers (seeded moment tests that can fail)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import kfast

from tests.modelgen import random_case

DATA = Path(__file__).resolve().parents[1] / "data"


def _macro():
    return pd.read_csv(DATA / "macrodata_gdp_cons_inv.csv", comment="#").to_numpy()


# -- KFAS ------------------------------------------------------------------------------------


def test_disturbance_smoother_equals_kfas_with_missing_data():
    y = np.diff(_macro(), axis=0)
    for rows, cols in [(slice(0, 50), [0]), (slice(19, 70), [1]), (slice(39, 90), [2]), (slice(119, 130), [0, 2])]:
        for c in cols:
            y[rows, c] = np.nan
    kfas = pd.read_csv(DATA / "kfas_disturbance_smoothing.csv", comment="#")
    eye = np.eye(3)
    ds = kfast.LinearGaussian(eye, eye, eye, eye).disturbance_smooth(y, np.zeros(3), 1e6 * eye)
    np.testing.assert_allclose(ds.smoother.x_smooth, kfas[["alphahat1", "alphahat2", "alphahat3"]], rtol=1e-7)
    np.testing.assert_allclose(ds.w_smooth, kfas[["etahat1", "etahat2", "etahat3"]], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(ds.w_cov), kfas["detVeta"], rtol=1e-7)
    np.testing.assert_allclose(ds.v_smooth, kfas[["epshat1", "epshat2", "epshat3"]], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(np.diagonal(ds.v_cov, axis1=1, axis2=2), kfas[["Veps1", "Veps2", "Veps3"]], rtol=1e-7)


_VAR_F = [[-0.1119908792, 0.8441841604, 0.0238725303], [0.2629347724, 0.4996718412, -0.0173023305], [-3.2192369082, 4.1536028244, 0.4514379215]]
_VAR_Q = [[0.0000640649, 0.0000388496, 0.0002148769], [0.0000388496, 0.0000572802, 0.000001555], [0.0002148769, 0.000001555, 0.0017088585]]
_VAR_R = np.diag([0.0000640649, 0.0000572802, 0.0017088585])


def test_simulation_smoother_equals_kfas_given_the_same_variates():
    y = np.diff(np.log(_macro()), axis=0)
    T = len(y)
    z = pd.read_csv(DATA / "kfas_simulation_variates.csv", comment="#").to_numpy()[:, 0]
    variates = {"measurement": z[: 3 * T], "state": z[3 * T : 6 * T], "initial": z[6 * T :]}
    model = kfast.LinearGaussian(_VAR_F, np.eye(3), _VAR_Q, _VAR_R)
    post = model.simulation_smoother(y, np.zeros(3), 1e6 * np.eye(3), variates=variates)
    kfas = pd.read_csv(DATA / "kfas_simulation_smoothing.csv", comment="#")
    assert model.loglik(y, np.zeros(3), 1e6 * np.eye(3)) == pytest.approx(1695.34872, rel=1e-9)
    np.testing.assert_allclose(post.x[0], kfas[["state1", "state2", "state3"]], atol=1e-7)
    np.testing.assert_allclose(post.w[0], kfas[["eta1", "eta2", "eta3"]], atol=1e-7)
    np.testing.assert_allclose(post.v[0], kfas[["eps1", "eps2", "eps3"]], atol=1e-7)


# -- agreement with the state smoother ---------------------------------------------------------


@pytest.mark.parametrize("correlated, missing, inputs", [(False, "none", False), (True, "partial", True), (False, "rows", True)])
def test_disturbances_are_the_smoothed_residuals(correlated, missing, inputs):
    case = random_case(11, 3, 2, T=40, correlated=correlated, missing=missing, inputs=inputs)
    model = kfast.LinearGaussian(**case.model)
    ds = model.disturbance_smooth(case.y, case.x0, case.P0, u=case.u)
    sm = model.smooth(case.y, case.x0, case.P0, u=case.u)
    F, H = case.model["F"], case.model["H"]
    B = case.model.get("B", np.zeros((3, 2)))
    D = case.model.get("D", np.zeros((2, 2)))
    u = case.u if case.u is not None else np.zeros((40, 2))
    w = sm.x_smooth[1:] - sm.x_smooth[:-1] @ F.T - u[:-1] @ B.T
    np.testing.assert_allclose(ds.w_smooth[:-1], w, rtol=1e-9, atol=1e-10)
    seen = ~np.isnan(case.y)
    v = case.y - sm.x_smooth @ H.T - u @ D.T
    np.testing.assert_allclose(ds.v_smooth[seen], v[seen], rtol=1e-9, atol=1e-10)
    # Var(v_i | y) = H_i P(t|T-1) H_i' where observed.
    HPH = H @ sm.P_smooth @ H.T
    for t in range(40):
        o = seen[t]
        np.testing.assert_allclose(ds.v_cov[t][np.ix_(o, o)], HPH[t][np.ix_(o, o)], rtol=1e-8, atol=1e-10)
    assert np.all(np.linalg.eigvalsh(ds.w_cov) > -1e-10) and np.all(np.linalg.eigvalsh(ds.v_cov) > -1e-10)


def test_the_noise_after_the_data_keeps_its_prior_unless_correlated():
    case = random_case(12, 2, 2, T=20)
    ds = kfast.LinearGaussian(**case.model).disturbance_smooth(case.y, case.x0, case.P0)
    assert np.all(ds.w_smooth[-1] == 0.0)
    np.testing.assert_allclose(ds.w_cov[-1], case.model["Q"], rtol=1e-12)
    # Missing components with a diagonal R: prior mean and variance.
    y = case.y.copy()
    y[5, 1] = np.nan
    model = kfast.LinearGaussian(**{**case.model, "R": np.diag(np.diag(case.model["R"]))})
    ds = model.disturbance_smooth(y, case.x0, case.P0)
    assert ds.v_smooth[5, 1] == pytest.approx(0.0, abs=1e-14)
    assert ds.v_cov[5, 1, 1] == pytest.approx(case.model["R"][1, 1], rel=1e-12)


def test_disturbance_covariances_equal_brute_force_conditioning():
    """Against the dense Gaussian conditioning of (w, v) on the stacked data."""
    case = random_case(13, 2, 2, T=6, correlated=True, missing="partial")
    model = kfast.LinearGaussian(**case.model)
    ds = model.disturbance_smooth(case.y, case.x0, case.P0)
    F, H, Q, R, N = (case.model[k] for k in "FHQRN")
    n, m, T = 2, 2, 6
    # Latent vector: x0 and xi(t) = (w(t), v(t)), t < T. y(t) = H x(t) + v(t).
    size = n + T * (n + m)
    mean = np.zeros(size)
    mean[:n] = case.x0
    cov = np.zeros((size, size))
    cov[:n, :n] = case.P0
    J = np.block([[Q, N], [N.T, R]])
    for t in range(T):
        s = n + t * (n + m)
        cov[s:s + n + m, s:s + n + m] = J
    # x(t) = M_t @ latent
    M = np.zeros((n, size))
    M[:, :n] = np.eye(n)
    rows = []
    for t in range(T):
        s = n + t * (n + m)
        obs = np.zeros((m, size))
        obs[:, :] = H @ M
        obs[:, s + n:s + n + m] += np.eye(m)
        rows.append(obs)
        M = F @ M
        M[:, s:s + n] += np.eye(n)
    G = np.vstack(rows)
    seen = ~np.isnan(case.y).ravel()
    G, yv = G[seen], case.y.ravel()[seen]
    gain = cov @ G.T @ np.linalg.inv(G @ cov @ G.T)
    post_mean = mean + gain @ (yv - G @ mean)
    post_cov = cov - gain @ G @ cov
    for t in range(T):
        s = n + t * (n + m)
        np.testing.assert_allclose(ds.w_smooth[t], post_mean[s:s + n], rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(ds.v_smooth[t], post_mean[s + n:s + n + m], rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(ds.w_cov[t], post_cov[s:s + n, s:s + n], rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(ds.v_cov[t], post_cov[s + n:s + n + m, s + n:s + n + m], rtol=1e-8, atol=1e-10)


# -- the sampler -----------------------------------------------------------------------------


def test_draws_have_the_smoothed_moments():
    case = random_case(14, 2, 2, T=15, correlated=True, missing="partial", inputs=True)
    model = kfast.LinearGaussian(**case.model)
    draws = 4000
    post = model.simulation_smoother(case.y, case.x0, case.P0, u=case.u, draws=draws, seed=3)
    sm = model.smooth(case.y, case.x0, case.P0, u=case.u)
    ds = model.disturbance_smooth(case.y, case.x0, case.P0, u=case.u)
    for draws_of, mean, cov in [(post.x, sm.x_smooth, sm.P_smooth), (post.w, ds.w_smooth, ds.w_cov), (post.v, ds.v_smooth, ds.v_cov)]:
        sd = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
        # The sample mean within 4.5 standard errors of the smoothed mean, everywhere.
        err = np.abs(draws_of.mean(axis=0) - mean)
        assert np.all(err <= 4.5 * sd / np.sqrt(draws) + 1e-12)
        # The sample covariance within 10% (4000 draws: SE of a variance about 2.2%).
        sample = np.einsum("dti,dtj->tij", draws_of - mean, draws_of - mean) / draws
        scale = np.sqrt(np.einsum("ti,tj->tij", sd**2, sd**2))
        assert np.all(np.abs(sample - cov) <= 0.1 * scale + 1e-12)
    # The draws are consistent paths: x(t+1) = F x(t) + B u(t) + w(t), y = H x + D u + v where seen.
    F, H, B, D = (case.model[k] for k in "FHBD")
    x, w, v = post.x[7], post.w[7], post.v[7]
    np.testing.assert_allclose(x[1:], x[:-1] @ F.T + case.u[:-1] @ B.T + w[:-1], atol=1e-9)
    seen = ~np.isnan(case.y)
    np.testing.assert_allclose((x @ H.T + case.u @ D.T + v)[seen], case.y[seen], atol=1e-9)


def test_exact_diffuse_disturbances_are_the_limit_of_a_vague_prior():
    """P0_inf: the disturbance smoother's moments are the kappa -> infinity limits of those with
    P0 + kappa P0_inf."""
    trend = kfast.models.local_linear_trend(0.5, 0.1, irregular=1.0)
    y = np.sin(np.arange(25) / 4.0) + 0.2 * np.arange(25)
    y[[4, 11]] = np.nan
    exact = trend.disturbance_smooth(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))
    vague = trend.disturbance_smooth(y, np.zeros(2), 1e7 * np.eye(2))
    for name in ["w_smooth", "w_cov", "v_smooth", "v_cov"]:
        np.testing.assert_allclose(getattr(exact, name), getattr(vague, name), rtol=1e-5, atol=1e-5, err_msg=name)
    assert exact.smoother.filter.n_diffuse == 2


def test_exact_diffuse_draws_have_the_exact_diffuse_smoothed_moments():
    trend = kfast.models.local_linear_trend(0.5, 0.1, irregular=1.0)
    y = np.sin(np.arange(12) / 3.0) + 0.3 * np.arange(12)
    y[5] = np.nan
    draws = 4000
    post = trend.simulation_smoother(y, np.zeros(2), np.zeros((2, 2)), draws=draws, seed=8, P0_inf=np.eye(2))
    sm = trend.smooth(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))
    sd = np.sqrt(np.diagonal(sm.P_smooth, axis1=1, axis2=2))
    assert np.all(np.abs(post.x.mean(axis=0) - sm.x_smooth) <= 4.5 * sd / np.sqrt(draws))
    sample = np.einsum("dti,dtj->tij", post.x - sm.x_smooth, post.x - sm.x_smooth) / draws
    assert np.all(np.abs(sample - sm.P_smooth) <= 0.1 * np.sqrt(np.einsum("ti,tj->tij", sd**2, sd**2)))
    with pytest.raises(ValueError, match="P0_inf"):
        trend.simulation_smoother(y, np.zeros(2), np.zeros((2, 2)), P0_inf=-np.eye(2))


def test_the_same_seed_gives_the_same_draws_and_singular_noise_works():
    model = kfast.LinearGaussian(F=[[1.0, 1.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=np.diag([0.0, 0.1]), R=1.0)
    y = np.cumsum(np.cumsum(np.random.default_rng(0).standard_normal(30))) * 0.1
    a = model.simulation_smoother(y, [0.0, 0.0], 10 * np.eye(2), draws=3, seed=5)
    b = model.simulation_smoother(y, [0.0, 0.0], 10 * np.eye(2), draws=3, seed=5)
    assert np.array_equal(a.x, b.x)
    # The level's disturbance has variance 0: every draw has w_0 = 0 (up to rounding).
    assert np.abs(a.w[:, :, 0]).max() < 1e-9


def test_bad_arguments_are_named():
    case = random_case(15, 2, 2, T=10)
    model = kfast.LinearGaussian(**case.model)
    for kwargs, message in [
        (dict(draws=0), "draws: must be >= 1"),
        (dict(draws=-2), "draws: must be >= 0"),
        (dict(draws=10**15), "draws: "),
        (dict(variates=[1, 2]), "variates: expected a dict"),
        (dict(variates={"initial": np.zeros(2), "state": np.zeros(20), "measurement": np.zeros(19)}), r"variates\['measurement'\]: expected 20 values"),
        (dict(variates={"initial": np.zeros(2), "state": np.full(20, np.nan), "measurement": np.zeros(20)}), r"variates\['state'\]: must be finite"),
    ]:
        with pytest.raises(ValueError, match=message):
            model.simulation_smoother(case.y, case.x0, case.P0, **kwargs)
    with pytest.raises(ValueError, match="P0"):
        model.simulation_smoother(case.y, case.x0, -np.eye(2))
    with pytest.raises(ValueError, match="y"):
        model.disturbance_smooth(case.y[:, :1], case.x0, case.P0)
