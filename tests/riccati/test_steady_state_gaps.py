"""filter(steady_state=True) with missing data: exact through a gap, then back to the
stationary gains (the README's example)."""

import numpy as np
import pytest

import kfast
from kfast.reference import kalman_filter as reference_filter


def _readme_model():
    dt = 0.1
    F = np.array([[1, dt], [0, 1]])
    H = np.array([[1.0, 0.0]])
    Q = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    R = np.array([[0.5]])
    return kfast.LinearGaussian(F, H, Q, R)


def _readme_data():
    y = np.cumsum(np.random.default_rng(0).standard_normal(200)) * 0.1
    y[50:60] = np.nan
    return y


def test_gap_returns_to_the_stationary_gain():
    model = _readme_model()
    ss = model.steady_state()
    res = model.filter(_readme_data(), [0, 0], None, steady_state=True)
    np.testing.assert_allclose(res.K[-1], ss.K, rtol=1e-8)
    np.testing.assert_allclose(res.P_pred[-1], ss.P_pred, rtol=1e-8)
    # Before the gap the gains are the stationary ones exactly where frozen.
    np.testing.assert_allclose(res.K[10], ss.K, rtol=1e-12)


def test_gap_matches_the_exact_filter_from_the_stationary_covariance():
    model = _readme_model()
    y = _readme_data()
    P_stat = model.steady_state().P_pred
    fast = model.filter(y, [0, 0], None, steady_state=True)
    exact = model.filter(y, [0, 0], P_stat)
    ref = reference_filter(model.F, model.H, model.Q, model.R, y[:, None], np.zeros(2), P_stat)
    assert fast.loglik == pytest.approx(exact.loglik, rel=1e-9)
    assert fast.loglik == pytest.approx(ref["loglik"], rel=1e-9)
    # Inside and right after the gap the covariance grows and shrinks back exactly.
    np.testing.assert_allclose(fast.P_pred[50:80], exact.P_pred[50:80], rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(fast.x_filt, exact.x_filt, rtol=1e-8, atol=1e-10)
    assert fast.P_pred[60, 0, 0] > 2 * P_stat[0, 0]


def test_finite_converge_tol_reconverges_after_a_gap():
    model = _readme_model()
    y = _readme_data()
    res = model.filter(y, [0, 0], np.eye(2), converge_tol=1e-12)
    exact = model.filter(y, [0, 0], np.eye(2))
    assert res.loglik == pytest.approx(exact.loglik, rel=1e-9)
    np.testing.assert_allclose(res.K[-1], exact.K[-1], rtol=1e-9)
