"""Parameter estimation: EM against pykalman and the NumPy reference, monotone with missing
data; maximum likelihood recovers known parameters; errors name `build`."""

import numpy as np
import pytest
from pykalman import KalmanFilter as PKKalmanFilter

import kfast
from kfast.reference import em_step
from modelgen import random_case

PK_VARS = {
    "F": "transition_matrices",
    "H": "observation_matrices",
    "Q": "transition_covariance",
    "R": "observation_covariance",
    "x0": "initial_state_mean",
    "P0": "initial_state_covariance",
}


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("missing", ["none", "rows"])
@pytest.mark.parametrize("fit", [("F", "H", "Q", "R", "x0", "P0"), ("Q", "R"), ("F", "Q", "x0")])
def test_em_matches_pykalman(seed, missing, fit):
    case = random_case(400 + seed, n=1 + seed % 3, m=1 + seed % 2, T=60, missing=missing)
    model = kfast.LinearGaussian(**case.model)
    res = model.em(case.y, case.x0, case.P0, n_iter=4, fit=fit)
    pk = PKKalmanFilter(
        transition_matrices=model.F, observation_matrices=model.H, transition_covariance=model.Q,
        observation_covariance=model.R, initial_state_mean=case.x0, initial_state_covariance=case.P0,
        em_vars=[PK_VARS[k] for k in fit],
    ).em(np.ma.masked_invalid(case.y), n_iter=4)
    for name, got in (("F", res.model.F), ("H", res.model.H), ("Q", res.model.Q), ("R", res.model.R), ("x0", res.x0), ("P0", res.P0)):
        np.testing.assert_allclose(got, getattr(pk, PK_VARS[name]), rtol=1e-8, atol=1e-10, err_msg=name)
    assert res.loglik[-1] == pytest.approx(pk.loglikelihood(np.ma.masked_invalid(case.y)), rel=1e-9)


@pytest.mark.parametrize("seed", range(8))
def test_em_matches_reference_with_partial_missing_data_and_inputs(seed):
    case = random_case(500 + seed, n=2 + seed % 2, m=2 + seed % 2, T=40, missing="partial", inputs=bool(seed % 2))
    model = kfast.LinearGaussian(**case.model)
    res = model.em(case.y, case.x0, case.P0, n_iter=3, u=case.u)
    F, H, Q, R = (case.model[k] for k in "FHQR")
    x0, P0 = case.x0, case.P0
    B, D = case.model.get("B"), case.model.get("D")
    for i in range(3):
        (F, H, Q, R, x0, P0), ll = em_step(F, H, Q, R, x0, P0, case.y, B=B, D=D, u=case.u)
        assert res.loglik[i] == pytest.approx(ll, rel=1e-10)
    for got, want in ((res.model.F, F), (res.model.H, H), (res.model.Q, Q), (res.model.R, R), (res.x0, x0), (res.P0, P0)):
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("missing", ["none", "rows", "partial"])
def test_em_never_decreases_the_loglik(seed, missing):
    case = random_case(600 + seed, n=2, m=3, T=120, missing=missing)
    model = kfast.LinearGaussian(**case.model)
    res = model.em(case.y, case.x0, case.P0, n_iter=25)
    steps = np.diff(res.loglik)
    assert (steps >= -1e-8 * np.abs(res.loglik[1:])).all(), steps
    assert res.loglik[-1] > res.loglik[0]
    assert res.n_iter == 25 and len(res.loglik) == 26


def test_em_tolerance_stops_early_and_progress_prints(capsys):
    case = random_case(7, n=2, m=2, T=80)
    model = kfast.LinearGaussian(**case.model)
    res = model.em(case.y, case.x0, case.P0, n_iter=500, fit=("R",), tol=1e-7, progress=True)
    assert res.converged and res.n_iter < 500
    assert "EM" in capsys.readouterr().err


def _ar1_plus_noise(theta):
    phi, log_q, log_r = theta
    return kfast.LinearGaussian(F=phi, H=1.0, Q=np.exp(log_q), R=np.exp(log_r)), 0.0, np.exp(log_q) / (1 - phi**2)


def test_mle_recovers_known_parameters():
    truth = np.array([0.8, np.log(0.5), np.log(1.0)])
    model, x0, P0 = _ar1_plus_noise(truth)
    _, y = model.simulate(3000, x0, P0, seed=42)
    res = kfast.fit(_ar1_plus_noise, [0.3, 0.0, 0.0], y, bounds=[(-0.99, 0.99), (-5, 5), (-5, 5)])
    assert res.success
    assert np.all(np.abs(res.theta - truth) < 4 * res.se), (res.theta, res.se)
    assert np.all(res.se < 0.2) and np.all(res.se > 0)
    # It is the maximum: the truth and nearby points score no higher.
    assert res.loglik >= res.model.loglik(y, res.x0, res.P0) - 1e-9
    assert res.loglik >= _ar1_plus_noise(truth)[0].loglik(y, x0, P0)


def test_mle_standard_errors_match_the_scalar_closed_form():
    """A random constant x ~ N(mu, 0) seen with noise of known variance r: the MLE of mu is
    the sample mean and its standard error sqrt(r / T) (with a vague prior)."""
    rng = np.random.default_rng(3)
    y = 2.0 + rng.standard_normal(400)

    def build(theta):
        return kfast.LinearGaussian(F=1.0, H=1.0, Q=0.0, R=1.0), theta, 1e-12

    res = kfast.fit(build, [0.0], y)
    assert res.theta[0] == pytest.approx(y.mean(), abs=1e-5)
    assert res.se[0] == pytest.approx(np.sqrt(1 / 400), rel=1e-3)


def test_fit_errors_name_build():
    y = np.zeros(10)
    with pytest.raises(kfast.KfastError, match=r"^build: must return \(kfast.LinearGaussian, x0, P0\)"):
        kfast.fit(lambda th: (1, 2), [0.0], y)
    with pytest.raises(kfast.KfastError, match=r"^build: theta0 gave an invalid model: Q: not positive semidefinite"):
        kfast.fit(lambda th: (kfast.LinearGaussian(1.0, 1.0, th[0], 1.0), 0.0, 1.0), [-1.0], y)


def test_em_bad_arguments():
    case = random_case(1, n=2, m=1, T=10, correlated=True)
    with pytest.raises(kfast.KfastError, match="^model: EM does not support correlated noise N"):
        kfast.LinearGaussian(**case.model).em(case.y, case.x0, case.P0)
    plain = {k: v for k, v in case.model.items() if k != "N"}
    with pytest.raises(kfast.KfastError, match=r"^fit: unknown parameters \['G'\]"):
        kfast.LinearGaussian(**plain).em(case.y, case.x0, case.P0, fit=("F", "G"))
    with pytest.raises(kfast.KfastError, match="^n_iter: expected an integer >= 0"):
        kfast.LinearGaussian(**plain).em(case.y, case.x0, case.P0, n_iter=-1)
    tv = random_case(1, n=2, m=1, T=10, time_varying=True)
    with pytest.raises(kfast.KfastError, match="^model: EM needs constant matrices"):
        kfast.LinearGaussian(**tv.model).em(tv.y, tv.x0, tv.P0)
