"""FilterResult.diagnostics(): standardized innovations, NIS/NEES with chi-square bounds,
autocorrelation, Ljung–Box and Jarque–Bera — against statsmodels and scipy, against their
definitions written out in NumPy, and as statistical tests that accept the true model and
reject wrong ones (seeded)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from scipy import stats
from statsmodels.stats.diagnostic import acorr_ljungbox
from statsmodels.stats.stattools import jarque_bera
from statsmodels.tsa.statespace import kalman_filter as sm_kf
from statsmodels.tsa.stattools import acf as sm_acf

import kfast
from kfast.linear.diagnostics import chi_square_quantile, chi_square_sf

from tests.modelgen import random_case


def _filtered(seed, n=3, m=2, T=200, missing="none"):
    case = random_case(seed, n, m, T=T, missing=missing)
    model = kfast.LinearGaussian(**case.model)
    return case, model.filter(case.y, case.x0, case.P0)


# -- the chi-square distribution ------------------------------------------------------------


@pytest.mark.parametrize("k", [0.5, 1, 2, 3, 7, 10, 40, 250, 1e4, 1e6])
def test_chi_square_tail_and_quantile_equal_scipy(k):
    for p in [1e-10, 1e-3, 0.025, 0.3, 0.5, 0.975, 0.999, 1 - 1e-9]:
        x = stats.chi2.ppf(p, k)
        assert chi_square_quantile(p, k) == pytest.approx(x, rel=1e-10)
        assert chi_square_sf(x, k) == pytest.approx(stats.chi2.sf(x, k), rel=1e-11)


def test_chi_square_refuses_what_is_not_a_probability_or_dof():
    for bad in [0.0, 1.0, -0.1, float("nan"), "0.5", True]:
        with pytest.raises(ValueError, match="p: "):
            chi_square_quantile(bad, 2.0)
    with pytest.raises(ValueError, match="k: "):
        chi_square_sf(1.0, 0.0)


# -- each statistic against its definition and the peers ------------------------------------


@pytest.mark.parametrize("missing", ["none", "partial"])
def test_standardized_innovations_equal_statsmodels(missing):
    case, res = _filtered(1, n=3, m=3, T=80, missing=missing)
    ssm = sm_kf.KalmanFilter(k_endog=3, k_states=3, k_posdef=3, tolerance=0)
    ssm.bind(np.ascontiguousarray(case.y))
    ssm.set_filter_method(filter_method=sm_kf.FILTER_CONVENTIONAL)
    for name, key in [("design", "H"), ("obs_cov", "R"), ("transition", "F"), ("state_cov", "Q")]:
        ssm[name] = case.model[key]
    ssm["selection"] = np.eye(3)
    ssm.initialize_known(case.x0, case.P0)
    expected = ssm.filter().standardized_forecasts_error.T
    d = res.diagnostics()
    # (statsmodels fills missing components with 0 or NaN, depending on its version; kfast NaN.)
    seen = ~np.isnan(case.y)
    np.testing.assert_allclose(d.standardized_innov[seen], expected[seen], rtol=1e-9, atol=1e-10)
    assert np.array_equal(np.isnan(d.standardized_innov), ~seen)


def test_nis_and_its_bounds_by_definition():
    case, res = _filtered(2, missing="partial")
    d = res.diagnostics(alpha=0.1)
    for t in range(len(case.y)):
        seen = ~np.isnan(case.y[t])
        assert d.nis_dof[t] == seen.sum()
        if not seen.any():
            assert np.isnan(d.nis[t]) and np.isnan(d.nis_bounds[t]).all()
            continue
        e, S = res.innov[t, seen], res.S[t][np.ix_(seen, seen)]
        assert d.nis[t] == pytest.approx(e @ np.linalg.solve(S, e), rel=1e-10)
        np.testing.assert_allclose(d.nis_bounds[t], stats.chi2.ppf([0.05, 0.95], seen.sum()), rtol=1e-10)
    observed = d.nis_dof > 0
    K, dof = observed.sum(), d.nis_dof.sum()
    assert d.nis_mean == pytest.approx(d.nis[observed].mean(), rel=1e-12)
    np.testing.assert_allclose(d.nis_mean_bounds, stats.chi2.ppf([0.05, 0.95], dof) / K, rtol=1e-10)


def test_ljung_box_and_jarque_bera_equal_statsmodels():
    _, res = _filtered(3, T=300)
    d = res.diagnostics(lags=12, burn=5)
    for i in range(2):
        z = d.standardized_innov[5:, i]
        lb = acorr_ljungbox(z, lags=12)
        np.testing.assert_allclose(d.ljung_box[:, i], lb["lb_stat"], rtol=1e-10)
        np.testing.assert_allclose(d.ljung_box_pvalue[:, i], lb["lb_pvalue"], rtol=1e-9)
        np.testing.assert_allclose(d.acf[:, i], sm_acf(z, nlags=12, fft=False), rtol=1e-10, atol=1e-14)
        jb, pvalue, skew, kurtosis = jarque_bera(z)
        assert (d.jarque_bera[i], d.jarque_bera_pvalue[i]) == pytest.approx((jb, pvalue), rel=1e-10)
        assert (d.skew[i], d.kurtosis[i]) == pytest.approx((skew, kurtosis), rel=1e-10)
        assert d.acf_bound[i] == pytest.approx(stats.norm.ppf(0.975) / np.sqrt(295), rel=1e-10)


def test_missing_values_use_the_conservative_autocorrelation():
    _, res = _filtered(4, T=300, missing="partial")
    d = res.diagnostics(lags=6)
    for i in range(2):
        z = d.standardized_innov[:, i]
        N = int((~np.isnan(z)).sum())
        r = sm_acf(z, nlags=6, fft=False, missing="conservative")
        np.testing.assert_allclose(d.acf[:, i], r, rtol=1e-10, atol=1e-14)
        Q = N * (N + 2) * np.cumsum(r[1:] ** 2 / (N - np.arange(1, 7)))
        np.testing.assert_allclose(d.ljung_box[:, i], Q, rtol=1e-10)
        np.testing.assert_allclose(d.ljung_box_pvalue[:, i], stats.chi2.sf(Q, np.arange(1, 7)), rtol=1e-9)
        jb, pvalue, _, _ = jarque_bera(z[~np.isnan(z)])
        assert d.jarque_bera[i] == pytest.approx(jb, rel=1e-10)


def test_nees_by_definition():
    model = kfast.models.constant_velocity(1, dt=0.5, q=0.3, r=1.0)
    x, y = model.simulate(150, x0=np.zeros(2), P0=np.eye(2), seed=7)
    res = model.filter(y, np.zeros(2), np.eye(2))
    d = res.diagnostics(x_true=x, burn=10, alpha=0.01)
    err = x - res.x_filt
    expected = np.einsum("ti,ti->t", err, np.linalg.solve(res.P_filt, err[..., None])[..., 0])
    np.testing.assert_allclose(d.nees, expected, rtol=1e-10)
    np.testing.assert_allclose(d.nees_bounds, stats.chi2.ppf([0.005, 0.995], 2), rtol=1e-10)
    assert d.nees_mean == pytest.approx(expected[10:].mean(), rel=1e-12)
    np.testing.assert_allclose(d.nees_mean_bounds, stats.chi2.ppf([0.005, 0.995], 140 * 2) / 140, rtol=1e-10)


def test_one_state_takes_one_dimensional_true_states():
    model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
    x, y = model.simulate(50, x0=0.0, P0=1.0, seed=3)
    res = model.filter(y, 0.0, 1.0)
    assert np.array_equal(res.diagnostics(x_true=x[:, 0]).nees, res.diagnostics(x_true=x).nees)


# -- as tests: the true model passes, wrong ones fail (seeded) ------------------------------

_TRUE = dict(F=[[0.9, 0.2], [0.0, 0.7]], H=[[1.0, 0.0], [0.5, 1.0]], Q=np.diag([0.5, 0.2]), R=np.diag([1.0, 0.5]))


def _runs(filter_model, seeds=range(100), T=300):
    truth = kfast.LinearGaussian(**_TRUE)
    out = []
    for seed in seeds:
        x, y = truth.simulate(T, x0=np.zeros(2), P0=np.eye(2), seed=seed)
        out.append(filter_model.filter(y, np.zeros(2), np.eye(2)).diagnostics(lags=10, x_true=x))
    return out


def test_the_true_model_passes_at_the_nominal_rate():
    runs = _runs(kfast.LinearGaussian(**_TRUE))
    # Each test's rejection rate at alpha = 0.05 is 5%, within 4 binomial SE (2 components
    # x 100 runs for the per-component tests, 100 runs for the averages).
    for name, reject in [
        ("Ljung-Box", [p < 0.05 for r in runs for p in r.ljung_box_pvalue[-1]]),
        ("Jarque-Bera", [p < 0.05 for r in runs for p in r.jarque_bera_pvalue]),
        ("NIS mean", [not r.nis_mean_bounds[0] <= r.nis_mean <= r.nis_mean_bounds[1] for r in runs]),
        ("NEES mean", [not r.nees_mean_bounds[0] <= r.nees_mean <= r.nees_mean_bounds[1] for r in runs]),
    ]:
        assert abs(np.mean(reject) - 0.05) < 4 * np.sqrt(0.05 * 0.95 / len(reject)), name
    inside = np.mean([r.nis_fraction_inside for r in runs])
    assert inside == pytest.approx(0.95, abs=0.005)


def test_wrong_models_are_rejected():
    # The wrong dynamics leave correlated innovations: Ljung-Box rejects.
    slow = kfast.LinearGaussian(**{**_TRUE, "F": [[0.3, 0.0], [0.0, 0.3]]})
    assert np.mean([r.ljung_box_pvalue[-1].min() < 0.05 for r in _runs(slow, range(20))]) >= 0.95
    # A measurement noise taken 4 times too small: the NIS and NEES averages exceed their bounds.
    confident = kfast.LinearGaussian(**{**_TRUE, "R": np.diag([0.25, 0.125])})
    runs = _runs(confident, range(20))
    assert all(r.nis_mean > r.nis_mean_bounds[1] for r in runs)
    assert all(r.nees_mean > r.nees_mean_bounds[1] for r in runs)


def test_innovations_factor_the_covariance_of_the_data():
    """Söderström ex. 6.18: Y = L E + O x0 with L unit block lower triangular (blocks
    H F^(i-j-1) K_pred(j) below the diagonal), so cov(Y) = L blockdiag(S(t)) L' — the filter is
    the block L D L' factorization of the data's covariance, and its innovations are white."""
    F, H, Q, R = (np.asarray(_TRUE[k], float) for k in "FHQR")
    x0, P0, T, n, m = np.array([0.3, -0.2]), np.diag([2.0, 1.0]), 6, 2, 2
    res = kfast.LinearGaussian(F, H, Q, R).filter(np.zeros((T, m)), x0, P0)
    powers = [np.linalg.matrix_power(F, k) for k in range(T)]
    L = np.eye(T * m)
    for i in range(T):
        for j in range(i):
            L[i * m:(i + 1) * m, j * m:(j + 1) * m] = H @ powers[i - j - 1] @ res.K_pred[j]
    D = np.zeros((T * m, T * m))
    for t in range(T):
        D[t * m:(t + 1) * m, t * m:(t + 1) * m] = res.S[t]
    # The data's covariance, built directly from the model: x(t) = F^t x(0) + sum F^(t-1-s) w(s).
    X = np.zeros((T * n, T * n))
    for i in range(T):
        for j in range(T):
            c = powers[i] @ P0 @ powers[j].T
            for s in range(min(i, j)):
                c = c + powers[i - 1 - s] @ Q @ powers[j - 1 - s].T
            X[i * n:(i + 1) * n, j * n:(j + 1) * n] = c
    Hb = np.kron(np.eye(T), H)
    cov_Y = Hb @ X @ Hb.T + np.kron(np.eye(T), R)
    np.testing.assert_allclose(L @ D @ L.T, cov_Y, rtol=1e-10, atol=1e-12)
    # And Y - O x0 = L E for any data: E from the filter.
    y = np.random.default_rng(0).standard_normal((T, m))
    e = kfast.LinearGaussian(F, H, Q, R).filter(y, x0, P0).innov
    O = np.vstack([H @ powers[t] for t in range(T)])
    np.testing.assert_allclose(L @ e.ravel(), y.ravel() - O @ x0, rtol=1e-10, atol=1e-12)


# -- the plot --------------------------------------------------------------------------------


def test_plot_diagnostics_draws_four_panels():
    _, res = _filtered(5, missing="partial")
    fig = res.plot_diagnostics(component=1, lags=8)
    assert len(fig.axes) == 4
    assert fig.axes[0].get_title() == "Standardized innovation 1"
    assert len(fig.axes[3].collections[0].get_segments()) == 8
    with pytest.raises(ValueError, match="component: must be below m = 2"):
        res.plot_diagnostics(component=2)
    import matplotlib.pyplot as plt

    plt.close("all")


# -- bad input -------------------------------------------------------------------------------


def test_bad_arguments_are_named():
    case, res = _filtered(6, T=30)
    for kwargs, message in [
        (dict(lags=0), "lags: must be at least 1"),
        (dict(lags=30), "lags: 30 needs more observed steps"),
        (dict(lags=-1), "lags: must be >= 0"),
        (dict(burn=30), "burn: 30 leaves none of the 30 steps"),
        (dict(alpha=0.0), "alpha: must be in"),
        (dict(alpha=float("nan")), "alpha: must be in"),
        (dict(x_true=np.zeros((29, 3))), r"x_true: expected shape \(30, 3\)"),
        (dict(x_true=np.full((30, 3), np.inf)), "x_true at step 0: component 0 is inf"),
    ]:
        with pytest.raises(ValueError, match=message):
            res.diagnostics(**kwargs)
    model = kfast.LinearGaussian(**case.model)
    with pytest.raises(ValueError, match="no innov or S"):
        model.filter(case.y, case.x0, case.P0, outputs="x_filt").diagnostics()
    with pytest.raises(ValueError, match="no x_filt or P_filt"):
        model.filter(case.y, case.x0, case.P0, outputs=("innov", "S")).diagnostics(x_true=np.zeros((30, 3)))


def test_a_covariance_that_is_not_positive_definite_is_named_with_its_step():
    _, res = _filtered(7, T=30)
    S = res.S.copy()
    S[4] = -np.eye(2)
    bad = kfast.FilterResult(innov=res.innov, S=S)
    with pytest.raises(ValueError, match="S at step 4: the block of the observed components is not positive definite"):
        bad.diagnostics()
    P = res.P_filt.copy()
    P[9, 0, 0] = np.nan
    with pytest.raises(ValueError, match="P_filt at step 9: not positive definite"):
        kfast.FilterResult(innov=res.innov, S=res.S, x_filt=res.x_filt, P_filt=P).diagnostics(x_true=np.zeros((30, 3)))


def test_a_component_never_observed_is_refused_and_inputs_are_not_modified():
    case, res = _filtered(8, T=40, missing="none")
    innov = res.innov.copy()
    innov[:, 1] = np.nan
    before = innov.copy()
    with pytest.raises(ValueError, match="component 1 is observed at 0 of the steps tested"):
        kfast.FilterResult(innov=innov, S=res.S).diagnostics()
    assert np.array_equal(innov, before, equal_nan=True)
    all_missing = np.full_like(innov, np.nan)
    with pytest.raises(ValueError, match="nothing is observed after burn = 0"):
        kfast.FilterResult(innov=all_missing, S=res.S).diagnostics()
