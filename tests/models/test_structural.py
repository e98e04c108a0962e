"""The structural time-series builders (kfast.models.local_level, ..., combine) against
statsmodels' UnobservedComponents and SARIMAX: the same matrices for the same parameters, and
the same log-likelihood from the same known prior."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from statsmodels.tsa.arima_process import ArmaProcess
from statsmodels.tsa.statespace.sarimax import SARIMAX
from statsmodels.tsa.statespace.structural import UnobservedComponents

import kfast
from kfast import models

Y = np.cumsum(np.random.default_rng(0).standard_normal(60)) + np.sin(np.arange(60))


def _system(sm_model):
    ssm = sm_model.ssm
    select = ssm["selection"]
    return ssm["transition"], ssm["design"], select @ ssm["state_cov"] @ select.T, ssm["obs_cov"]


def _same(kf_model, sm_model, seed=1):
    F, H, Q, R = _system(sm_model)
    np.testing.assert_allclose(kf_model.F, F, atol=1e-15)
    np.testing.assert_allclose(kf_model.H, H, atol=1e-15)
    np.testing.assert_allclose(kf_model.Q, Q, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(kf_model.R, R, atol=1e-15)
    n = F.shape[0]
    rng = np.random.default_rng(seed)
    x0 = rng.standard_normal(n)
    A = rng.standard_normal((n, n))
    P0 = A @ A.T + np.eye(n)
    sm_model.ssm.initialize_known(x0, P0)
    sm_model.ssm.loglikelihood_burn = 0  # (UnobservedComponents leaves out the first d steps)
    expected = sm_model.ssm.loglike()
    assert kf_model.loglik(Y, x0, P0) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize(
    "level, build",
    [
        ("local level", lambda: models.local_level(1.3, irregular=0.7)),
        ("local linear trend", lambda: models.local_linear_trend(1.3, 0.2, irregular=0.7)),
        ("smooth trend", lambda: models.smooth_trend(0.2, irregular=0.7)),
    ],
)
def test_trends_equal_unobserved_components(level, build):
    uc = UnobservedComponents(Y, level=level)
    params = {"sigma2.irregular": 0.7, "sigma2.level": 1.3, "sigma2.trend": 0.2}
    uc.update([params[name] for name in uc.param_names])
    _same(build(), uc)


def test_a_sum_of_every_component_equals_unobserved_components():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        uc = UnobservedComponents(
            Y,
            level="local linear trend",
            seasonal=4,
            freq_seasonal=[{"period": 5, "harmonics": 2}, {"period": 12}],
            cycle=True,
            stochastic_cycle=True,
            damped_cycle=True,
        )
    uc.update([2.0, 1.0, 0.1, 0.5, 0.3, 0.25, 0.2, 0.7, 0.9])
    ours = models.combine(
        models.local_linear_trend(1.0, 0.1),
        models.seasonal(4, 0.5),
        models.seasonal(5, 0.3, form="trigonometric", harmonics=2),
        models.seasonal(12, 0.25, form="trigonometric"),
        models.cycle(frequency=0.7, var=0.2, damping=0.9),
        irregular=2.0,
    )
    assert ours.n_states == 2 + 3 + 4 + 12 + 2
    _same(ours, uc)


@pytest.mark.parametrize("order, params", [((1, 0, 0), [0.6]), ((2, 0, 1), [0.5, 0.2, 0.3]), ((1, 0, 3), [-0.4, 0.3, 0.2, -0.1]), ((0, 0, 2), [0.5, 0.25])])
def test_arma_equals_sarimax(order, params):
    p, _, q = order
    sarimax = SARIMAX(Y, order=order, trend="n")
    sarimax.update(params + [1.7])
    _same(models.arma(ar=params[:p], ma=params[p:], var=1.7), sarimax)


def test_arma_sign_convention_and_the_opposite_one_of_models_ar():
    # statsmodels' ArmaProcess takes the lag polynomials [1, -phi] and [1, theta]; the stationary
    # variance of our ARMA(1, 1) equals its theoretical one.
    phi, theta = 0.6, 0.4
    model = models.arma(ar=[phi], ma=[theta], var=2.0)
    acov = ArmaProcess([1, -phi], [1, theta]).acovf(1)[0] * 2.0
    assert (model.H @ model.stationary_cov() @ model.H.T)[0, 0] == pytest.approx(acov, rel=1e-12)
    # models.ar([a1]) is y(t) + a1 y(t-1) = e(t): arma(ar=[-a1]).
    a = models.ar([-phi], 2.0)
    b = models.arma(ar=[phi], var=2.0)
    np.testing.assert_allclose(a.F, b.F)
    np.testing.assert_allclose(a.Q, b.Q)


def test_combined_components_filter_like_statsmodels_with_missing_data():
    y = Y.copy()
    y[[3, 17, 18, 40]] = np.nan
    uc = UnobservedComponents(y, level="local level", seasonal=3)
    uc.update([0.5, 1.1, 0.2])
    ours = models.combine(models.local_level(1.1), models.seasonal(3, 0.2), irregular=0.5)
    x0, P0 = np.zeros(3), 10 * np.eye(3)
    uc.ssm.initialize_known(x0, P0)
    uc.ssm.loglikelihood_burn = 0
    res = uc.ssm.filter()
    ours_res = ours.filter(y, x0, P0)
    np.testing.assert_allclose(ours_res.x_filt, res.filtered_state.T, rtol=1e-10, atol=1e-12)
    assert ours_res.loglik == pytest.approx(res.llf, rel=1e-10)


def test_bad_parameters_are_named():
    for call, message in [
        (lambda: models.local_level(-1.0), "level_var: must be a finite variance >= 0"),
        (lambda: models.local_linear_trend(1.0, float("nan")), "slope_var: must be a finite variance"),
        (lambda: models.seasonal(1, 1.0), "period: must be >= 2"),
        (lambda: models.seasonal(4, 1.0, form="fourier"), "form: expected 'dummy' or 'trigonometric'"),
        (lambda: models.seasonal(4, 1.0, form="trigonometric", harmonics=3), r"harmonics: must be in 1..2"),
        (lambda: models.cycle(4.0, 1.0), r"frequency: must be in \[0, pi\]"),
        (lambda: models.cycle(0.5, 1.0, damping=1.5), r"damping: must be in \[0, 1\]"),
        (lambda: models.arma(ar=[np.inf]), "ar: must be finite"),
        (lambda: models.arma(ma="x"), "ma: "),
        (lambda: models.combine(), "components: give at least one model"),
        (lambda: models.combine(models.local_level(1.0), "x"), r"components\[1\]: expected a kfast.LinearGaussian"),
        (lambda: models.combine(models.local_level(1.0), kfast.LinearGaussian(1.0, [[1.0], [1.0]], 1.0, np.eye(2))), r"components\[1\]: has 2 outputs"),
        (lambda: models.local_level(1.0, irregular="big"), "irregular: expected a variance"),
    ]:
        with pytest.raises(ValueError, match=message):
            call()
