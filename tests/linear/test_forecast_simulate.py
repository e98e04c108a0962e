"""Forecasting (vs the reference and vs filtering with missing future data) and simulation
(reproducible; sample covariances match the model, the joint noise covariance honoured)."""

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

import kfast
from kfast.reference import forecast as ref_forecast
from kfast.reference import propagate as ref_propagate
from modelgen import random_case


@pytest.mark.parametrize("seed", range(12))
def test_forecast_matches_reference_and_missing_data_filtering(seed):
    inputs, correlated = bool(seed % 2), bool(seed % 3 == 0)
    case = random_case(seed, n=1 + seed % 5, m=1 + seed % 3, T=20, inputs=inputs, correlated=correlated)
    model = kfast.LinearGaussian(**case.model)
    steps = 6
    u_future = None if case.u is None else np.random.default_rng(seed).standard_normal((steps, 2))
    res = model.filter(case.y, case.x0, case.P0, u=case.u)
    fc = res.forecast(steps, u=u_future)
    want = ref_forecast(**{k: v for k, v in case.model.items() if k != "N"}, x=res.x_next, P=res.P_next, steps=steps, u=u_future)
    for got, exp, name in zip((fc.x, fc.P, fc.y, fc.y_cov), want, ("x", "P", "y", "y_cov")):
        np.testing.assert_allclose(got, exp, rtol=1e-12, atol=1e-12, err_msg=name)
    # Forecasting = filtering with the future observations missing.
    y_ext = np.vstack([case.y, np.full((steps, model.n_obs), np.nan)])
    u_ext = None if case.u is None else np.vstack([case.u, u_future])
    ext = model.filter(y_ext, case.x0, case.P0, u=u_ext)
    np.testing.assert_allclose(fc.x, ext.x_pred[-steps:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(fc.P, ext.P_pred[-steps:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(fc.y_cov, ext.S[-steps:], rtol=1e-12, atol=1e-12)
    mean, cov = fc  # the DESIGN contract: mean, cov = m.forecast(...)
    assert mean is fc.x and cov is fc.P


def test_forecast_tends_to_the_stationary_covariance():
    """P(t+k|t) -> Pi, the solution of Pi = F Pi F' + Q, for stable F (docs/algorithms.md, "Forecasting")."""
    case = random_case(4, n=3, m=1, T=5)
    model = kfast.LinearGaussian(**case.model)
    fc = model.forecast(np.zeros(3), np.eye(3), 400)
    Pi = solve_discrete_lyapunov(model.F, model.Q)
    np.testing.assert_allclose(fc.P[-1], Pi, rtol=1e-8)


@pytest.mark.parametrize("seed", range(6))
def test_simulate_is_the_model_recursion_and_reproducible(seed):
    case = random_case(seed, n=3, m=2, T=30, inputs=True, correlated=True, time_varying=bool(seed % 2))
    model = kfast.LinearGaussian(**case.model)
    x, y = model.simulate(30, case.x0, case.P0, u=case.u, seed=seed)
    again = model.simulate(30, case.x0, case.P0, u=case.u, seed=seed)
    np.testing.assert_array_equal(x, again.x)
    np.testing.assert_array_equal(y, again.y)
    assert not np.allclose(y, model.simulate(30, case.x0, case.P0, u=case.u, seed=seed + 1).y)
    # Recover the noise from the path and re-run the recursion in NumPy.
    at = lambda M, t: M[t] if M.ndim == 3 else M  # noqa: E731
    w = np.array([x[t + 1] - at(model.F, t) @ x[t] - at(model.B, t) @ case.u[t] for t in range(29)] + [np.zeros(3)])
    v = np.array([y[t] - at(model.H, t) @ x[t] - at(model.D, t) @ case.u[t] for t in range(30)])
    xr, yr = ref_propagate(model.F, model.H, x[0], w, v, B=model.B, D=model.D, u=case.u)
    np.testing.assert_allclose(xr, x, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(yr, y, rtol=1e-10, atol=1e-10)


def test_simulated_noise_and_outputs_have_the_model_covariances():
    """Monte Carlo: sample covariance of (w, v) matches [[Q, N], [N', R]] and that of y the
    stationary H Pi H' + R, within sampling tolerance (T = 40,000)."""
    case = random_case(9, n=2, m=2, T=5, correlated=True)
    model = kfast.LinearGaussian(**case.model)
    Pi = solve_discrete_lyapunov(model.F, model.Q)
    T = 40_000
    x, y = model.simulate(T, np.zeros(2), Pi, seed=123)
    w = x[1:] - x[:-1] @ model.F.T
    v = y - x @ model.H.T
    wv = np.hstack([w, v[:-1]])
    J = np.block([[model.Q, model.N], [model.N.T, model.R]])
    scale = np.sqrt(np.outer(np.diag(J), np.diag(J)))
    assert np.abs(np.cov(wv.T) - J).max() / scale.max() < 0.05
    Sy = model.H @ Pi @ model.H.T + model.R
    assert np.abs(np.cov(y.T) - Sy).max() / np.abs(Sy).max() < 0.08
    assert np.abs(y.mean(axis=0)).max() < 0.1 * np.sqrt(np.diag(Sy)).max()


def test_simulate_with_singular_noise():
    """Q = 0 (a random constant): the state never moves, and x[0] ~ N(x0, P0)."""
    model = kfast.LinearGaussian(F=1.0, H=1.0, Q=0.0, R=1.0)
    x, y = model.simulate(50, 3.0, 0.0, seed=0)
    np.testing.assert_array_equal(x, 3.0)
    assert np.std(y) > 0.5


def test_forecast_and_simulate_arguments_are_checked():
    model = kfast.LinearGaussian(F=0.5, H=1.0, Q=1.0, R=1.0)
    with pytest.raises(kfast.KfastError, match="^steps: must be >= 0, got -1"):
        model.forecast(0.0, 1.0, -1)
    with pytest.raises(kfast.KfastError, match="^P: not positive semidefinite"):
        model.forecast(0.0, -1.0, 3)
    with pytest.raises(kfast.KfastError, match="^T: must be >= 0, got -5"):
        model.simulate(-5, 0.0, 1.0)
    tv = kfast.LinearGaussian(F=np.full((4, 1, 1), 0.5), H=1.0, Q=1.0, R=1.0)
    with pytest.raises(kfast.KfastError, match="^model: forecasting needs constant matrices"):
        tv.forecast(0.0, 1.0, 3)
    with pytest.raises(kfast.KfastError, match="^T: is 5 but the model's per-step matrices have 4 steps"):
        tv.simulate(5, 0.0, 1.0)
    assert model.forecast(0.0, 1.0, 0).x.shape == (0, 1)
