"""Steady-state filter and stationary analysis: textbook cases B1-B4 and D2, convergence of
the filter to steady_state(), converge_tol, autocovariance and spectral density against each
other and simulation. Continuous time (D1, D3, Van Loan, Kalman-Bucy) is in
tests/sampling/test_continuous_time.py."""

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl

import kfast
from modelgen import random_case

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


def test_b1_steady_state():
    c = CASES["B1"]
    ss = kfast.LinearGaussian(**c["model"]).steady_state()
    for name, key in [("P_pred", "P_pred"), ("K_pred", "K_pred"), ("K", "K"), ("S", "S"), ("P_filt", "P_filt")]:
        assert getattr(ss, name).item() == pytest.approx(c[key], abs=c["tol"])
    assert ss.closed_loop_eigenvalues.item() == pytest.approx(c["closed_loop"], abs=c["tol"])


@pytest.mark.parametrize("r", ["0.1", "1", "10"])
def test_b2_ar2_in_noise(r):
    c = CASES["B2"]
    want = c["cases"][r]
    model = kfast.LinearGaussian(c["F"], c["H"], np.diag([float(r), 0.0]), c["R"])
    ss = model.steady_state()
    np.testing.assert_allclose(ss.P_pred, want["P_pred"], atol=c["tol"] * 10, rtol=c["tol"])
    np.testing.assert_allclose(ss.K.ravel(), want["K"], atol=c["tol"], rtol=c["tol"])
    np.testing.assert_allclose(ss.K_pred.ravel(), want["K_pred"], atol=c["tol"], rtol=c["tol"])


@pytest.mark.parametrize("case", range(2))
@pytest.mark.parametrize("method", ["doubling", "newton", "iteration"])
def test_b3_singular_r_returns_the_stabilizing_solution(case, method):
    c = CASES["B3"]["cases"][case]
    a, cc = c["a"], c["c"]
    model = kfast.LinearGaussian([[-a, 1.0], [0.0, 0.0]], [[1.0, 0.0]], [[1.0, cc], [cc, cc * cc]], [[0.0]])
    ss = model.steady_state(method=method)
    tol = CASES["B3"]["tol"]
    np.testing.assert_allclose(ss.P_pred, c["P"], atol=tol)
    np.testing.assert_allclose(ss.K_pred.ravel(), c["K_pred"], atol=tol)
    np.testing.assert_allclose(np.sort(ss.closed_loop_eigenvalues.real), np.sort(c["eig"]), atol=tol)


def test_b4_no_steady_state_raises():
    c = CASES["B4"]
    with pytest.raises(kfast.KfastError, match=r"^A: is not stable .*no stationary covariance"):
        kfast.stationary_cov_continuous([[c["continuous"]["F"]]], [[c["continuous"]["Q"]]])
    # The Lyapunov equation itself has the solution -1/2, which is not a covariance.
    assert kfast.solve_continuous_lyapunov([[1.0]], [[-1.0]]).item() == pytest.approx(c["continuous"]["lyapunov_solution"])
    walk = kfast.LinearGaussian(c["discrete"]["F"], 1.0, c["discrete"]["Q"], 1.0)
    with pytest.raises(kfast.KfastError, match=r"^F: is not stable \(spectral radius 1.000000e0\)"):
        walk.stationary_cov()
    with pytest.raises(kfast.KfastError, match="no stationary covariance"):
        walk.autocovariance([0, 1])
    with pytest.raises(kfast.KfastError, match="no stationary covariance"):
        walk.spectral_density([0.1])
    walk.steady_state()  # the filter still has a steady state (q > 0, r > 0)


def test_d2_partial_convergence():
    c = CASES["D2"]
    e1 = np.exp(-1)
    G = np.array([[0.0], [np.sqrt(1 - np.exp(-2))]])
    model = kfast.LinearGaussian([[-1.0, 1.0], [0.0, e1]], np.eye(2), G @ G.T, np.eye(2))
    fc = model.forecast(np.zeros(2), np.zeros((2, 2)), 400)
    assert fc.P[-1, 1, 1] == pytest.approx(c["P22_limit"], abs=1e-10)
    assert abs(fc.P[-1, 0, 1]) == pytest.approx(c["P12_limit"], abs=1e-10)
    # P11 has no limit; its two-step increments alternate around tanh(1/2).
    incr = np.diff(fc.P[-4:, 0, 0])
    assert np.mean(incr[-2:]) == pytest.approx(c["P11_increment_limit"], abs=1e-9)
    with pytest.raises(kfast.KfastError, match="no stationary covariance"):
        model.stationary_cov()


@pytest.mark.parametrize("seed", range(20))
def test_time_varying_recursion_converges_to_steady_state(seed):
    case = random_case(700 + seed, n=1 + seed % 5, m=1 + seed % 3, T=5, correlated=bool(seed % 2))
    model = kfast.LinearGaussian(**case.model)
    ss = model.steady_state()
    y = np.zeros((400, model.n_obs))
    res = model.filter(y, np.zeros(model.n_states), 10 * np.eye(model.n_states))
    scale = np.abs(ss.P_pred).max()
    np.testing.assert_allclose(res.P_pred[-1], ss.P_pred, atol=1e-9 * scale)
    np.testing.assert_allclose(res.P_filt[-1], ss.P_filt, atol=1e-9 * scale)
    np.testing.assert_allclose(res.K_pred[-1], ss.K_pred, atol=1e-8 * max(1, np.abs(ss.K_pred).max()))
    np.testing.assert_allclose(res.K[-1], ss.K, atol=1e-8 * max(1, np.abs(ss.K).max()))
    np.testing.assert_allclose(res.S[-1], ss.S, atol=1e-9 * np.abs(ss.S).max())
    assert ss.residual <= 1e-10 and np.abs(ss.closed_loop_eigenvalues).max() < 1


@pytest.mark.parametrize("seed", range(12))
def test_steady_state_filter_equals_the_filter_once_converged(seed):
    case = random_case(800 + seed, n=1 + seed % 4, m=1 + seed % 2, T=300, correlated=bool(seed % 2), inputs=bool(seed % 3 == 0))
    model = kfast.LinearGaussian(**case.model)
    ss = model.steady_state()
    exact = model.filter(case.y, case.x0, ss.P_pred, u=case.u)  # started at the stationary P: the same gains
    steady = model.filter(case.y, case.x0, None, u=case.u, steady_state=True)
    for name in ("x_pred", "x_filt", "innov", "loglik_t", "P_pred", "K"):
        np.testing.assert_allclose(getattr(steady, name), getattr(exact, name), rtol=1e-9, atol=1e-10)
    # From another prior the ordinary filter converges to the same estimates.
    other = model.filter(case.y, case.x0, 5 * np.eye(model.n_states), u=case.u)
    np.testing.assert_allclose(steady.x_filt[-50:], other.x_filt[-50:], rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("seed", range(8))
def test_converge_tol_changes_results_by_about_the_tolerance(seed):
    case = random_case(900 + seed, n=1 + seed % 4, m=1 + seed % 2, T=400, missing="rows" if seed % 2 else "none")
    model = kfast.LinearGaussian(**case.model)
    exact = model.filter(case.y, case.x0, case.P0)
    for tol in (1e-8, 1e-12):
        fast = model.filter(case.y, case.x0, case.P0, converge_tol=tol)
        scale = np.abs(exact.P_pred).max()
        assert np.abs(fast.P_pred - exact.P_pred).max() <= 100 * tol * scale
        assert np.abs(fast.x_filt - exact.x_filt).max() <= 1e3 * tol * max(1, np.abs(exact.x_filt).max())
        assert fast.loglik == pytest.approx(exact.loglik, rel=1e3 * tol)
    assert model.loglik(case.y, case.x0, case.P0, converge_tol=1e-12) == pytest.approx(exact.loglik, rel=1e-9)
    with pytest.raises(kfast.KfastError, match="^converge_tol: must be >= 0"):
        model.filter(case.y, case.x0, case.P0, converge_tol=-1)


def test_converge_tol_needs_a_constant_model():
    case = random_case(1, n=2, m=1, T=10, time_varying=True)
    with pytest.raises(kfast.KfastError, match="^converge_tol: needs constant model matrices"):
        kfast.LinearGaussian(**case.model).filter(case.y, case.x0, case.P0, converge_tol=1e-9)


@pytest.mark.parametrize("seed", range(10))
def test_autocovariance_and_spectral_density(seed):
    case = random_case(1000 + seed, n=1 + seed % 4, m=1 + seed % 3, T=5, correlated=bool(seed % 2))
    model = kfast.LinearGaussian(**case.model)
    lags = np.arange(-6, 7)
    r = model.autocovariance(lags)
    np.testing.assert_allclose(r[lags == 0][0], r[lags == 0][0].T, rtol=1e-12)
    np.testing.assert_allclose(r[lags == -3][0], r[lags == 3][0].T, rtol=1e-12)
    # Direct: Pi from scipy, r(k) = H F^(k-1) (F Pi H' + N).
    F, H, N = model.F, model.H, model.N if model.N is not None else np.zeros((model.n_states, model.n_obs))
    Pi = sl.solve_discrete_lyapunov(F, model.Q)
    np.testing.assert_allclose(model.stationary_cov(), Pi, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(r[lags == 2][0], H @ F @ (F @ Pi @ H.T + N), rtol=1e-9, atol=1e-12)
    # The spectrum integrates back to the autocovariance: r(k) = (1/2pi) int phi e^{iwk} dw.
    w = np.linspace(-np.pi, np.pi, 4096, endpoint=False)
    phi = model.spectral_density(w)
    np.testing.assert_allclose(phi, np.conj(np.swapaxes(phi, 1, 2)), atol=1e-12)
    for k in (0, 1, 4):
        rk = (phi * np.exp(1j * w * k)[:, None, None]).mean(axis=0)
        np.testing.assert_allclose(rk.real, r[lags == k][0], atol=1e-8 * np.abs(r).max())
    # With a sampling interval h the density scales by h and the frequency by 1/h.
    np.testing.assert_allclose(model.spectral_density(w[:5] / 0.1, h=0.1), 0.1 * phi[:5], rtol=1e-12)


def test_innovations_form_reproduces_the_output_statistics():
    """The innovations model (F, K_pred, H, S) has the same output autocovariance."""
    case = random_case(5, n=3, m=2, T=5, correlated=True)
    model = kfast.LinearGaussian(**case.model)
    inn = model.innovations_form()
    K, S = inn.K_pred, inn.S
    twin = kfast.LinearGaussian(inn.F, inn.H, K @ S @ K.T, S, N=K @ S)
    np.testing.assert_allclose(twin.autocovariance(range(5)), model.autocovariance(range(5)), rtol=1e-8, atol=1e-10)
    # Its own steady state is P = 0 (a sanity test of singular joint noise; docs/algorithms.md, "Correlated noise").
    np.testing.assert_allclose(twin.steady_state().P_pred, 0, atol=1e-10)
