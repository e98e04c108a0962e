"""The analytic score (kfast.loglik_score, the filter's tangent recursion) against central
differences of model.loglik on random models with every option and parameters in every
matrix and the prior, against statsmodels' analytic score (Harvey's method), and fit with
gradient="analytic" against fit with numerical derivatives."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import kfast
from modelgen import random_case

OPTIONS = list(itertools.product([False, True], [False, True], [False, True], ["none", "rows", "partial"]))


def parametrized(case):
    """build(theta) moving every matrix present and the prior smoothly with 5 parameters."""
    M = case.model

    def build(theta):
        a, b, c, d, e = theta
        mats = {
            "F": np.asarray(M["F"]) * np.exp(0.1 * a),
            "H": np.asarray(M["H"]) + 0.1 * d,
            "Q": np.asarray(M["Q"]) * np.exp(b),
            "R": np.asarray(M["R"]) * np.exp(c),
        }
        if "N" in M:
            mats["N"] = np.asarray(M["N"]) * np.exp(0.5 * (b + c)) * np.tanh(1 - e) / np.tanh(1)
        if "B" in M:
            mats["B"] = np.asarray(M["B"]) * (1 + e)
            mats["D"] = np.asarray(M["D"]) + d
        return kfast.LinearGaussian(**mats), case.x0 + a - e, case.P0 * np.exp(0.3 * b)

    return build


def numerical_score(build, theta, y, u, h=1e-5):
    grad = np.zeros(len(theta))
    for i in range(len(theta)):
        step = np.zeros(len(theta))
        step[i] = h
        lls = []
        for sign in (1, -1):
            model, x0, P0 = build(theta + sign * step)
            lls.append(model.loglik(y, x0, P0, u=u))
        grad[i] = (lls[0] - lls[1]) / (2 * h)
    return grad


@pytest.mark.parametrize("seed", range(24))
def test_score_equals_central_differences(seed):
    inputs, correlated, time_varying, missing = OPTIONS[seed % len(OPTIONS)]
    rng = np.random.default_rng(700 + seed)
    n, m = int(rng.integers(1, 6)), int(rng.integers(1, 4))
    case = random_case(seed, n, m, T=25, inputs=inputs, correlated=correlated, time_varying=time_varying, missing=missing)
    build = parametrized(case)
    theta = np.array([0.1, -0.2, 0.3, 0.05, 0.1])
    ll, score = kfast.loglik_score(build, theta, case.y, case.u)
    model, x0, P0 = build(theta)
    assert ll == model.loglik(case.y, x0, P0, u=case.u)
    want = numerical_score(build, theta, case.y, case.u)
    np.testing.assert_allclose(score, want, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(want).max()), err_msg=str(case.info))


def test_score_with_singular_q_and_exact_measurements():
    """A local linear trend with no level noise (singular Q) and R = 0 at some steps."""
    T = 30
    R = np.where(np.arange(T) % 7 == 3, 0.0, 1.0)[:, None, None]

    def build(theta):
        Q = np.diag([0.0, np.exp(theta[0])])
        model = kfast.LinearGaussian(F=[[1.0, 1.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=Q, R=R * np.exp(theta[1]))
        return model, np.array([0.0, theta[2]]), np.eye(2)

    y = np.cumsum(np.cumsum(np.random.default_rng(2).standard_normal(T)))[:, None]
    theta = np.array([-1.0, 0.2, 0.5])
    ll, score = kfast.loglik_score(build, theta, y)
    np.testing.assert_allclose(score, numerical_score(build, theta, y, None), rtol=1e-6)


def test_score_equals_statsmodels_harvey():
    """statsmodels' analytic score (method="harvey") of a local level model, known prior."""
    sm = pytest.importorskip("statsmodels.api")
    y = np.cumsum(np.random.default_rng(5).standard_normal(60)) + np.random.default_rng(6).standard_normal(60)
    mod = sm.tsa.UnobservedComponents(y, "llevel")
    mod.ssm.initialize_known(np.array([0.5]), np.array([[2.0]]))
    mod.loglikelihood_burn = mod.ssm.loglikelihood_burn = 0  # its default skips y[0]
    params = np.array([1.3, 0.7])  # sigma2.irregular, sigma2.level

    def build(theta):
        return kfast.models.local_level(theta[1], irregular=theta[0]), 0.5, 2.0

    ll, score = kfast.loglik_score(build, params, y)
    assert ll == pytest.approx(mod.loglike(params), rel=1e-10)
    np.testing.assert_allclose(score, mod.score(params, method="harvey"), rtol=1e-8)


def ar1_build(theta):
    phi, log_q, log_r = theta
    return kfast.LinearGaussian(F=np.tanh(phi), H=1.0, Q=np.exp(log_q), R=np.exp(log_r)), 0.0, 1.0


def test_fit_with_the_analytic_score_finds_the_same_optimum():
    model, _, _ = ar1_build(np.array([0.8, -0.5, 0.0]))
    _, y = model.simulate(400, x0=0.0, P0=1.0, seed=11)
    analytic = kfast.fit(ar1_build, [0.0, 0.0, 0.0], y, gradient="analytic")
    numerical = kfast.fit(ar1_build, [0.0, 0.0, 0.0], y)
    assert analytic.success
    np.testing.assert_allclose(analytic.theta, numerical.theta, atol=1e-3)
    assert analytic.loglik >= numerical.loglik - 1e-8
    # At the optimum the score vanishes, and the standard errors agree.
    _, score = kfast.loglik_score(ar1_build, analytic.theta, y)
    assert np.abs(score).max() < 1e-3
    np.testing.assert_allclose(analytic.se, numerical.se, rtol=1e-2)


def test_score_refusals():
    y = np.ones(5)
    with pytest.raises(ValueError, match="gradient"):
        kfast.fit(ar1_build, [0.0, 0.0, 0.0], y, gradient="complex")
    with pytest.raises(ValueError, match="gradient.*P0_inf"):
        kfast.fit(ar1_build, [0.0, 0.0, 0.0], y, gradient="analytic", P0_inf=1.0)

    def changing(theta):
        B = None if theta[0] > 0 else 1.0
        return kfast.LinearGaussian(F=0.5, H=1.0, Q=1.0, R=1.0, B=B), 0.0, 1.0

    with pytest.raises(ValueError, match="build: B"):
        kfast.loglik_score(changing, [0.0], y, u=np.ones(5))
    with pytest.raises(ValueError, match="build"):
        kfast.loglik_score(42, [0.0], y)
