"""Textbook cases A1, A2, A3 and B1 (tests/data/textbook_cases.json names each source)."""

import json
from pathlib import Path

import numpy as np
import pytest

import kfast

CASES = json.loads((Path(__file__).parent / "data" / "textbook_cases.json").read_text())


def model_of(case):
    return kfast.LinearGaussian(**case["model"])


def test_a1_scalar_filter_from_a_known_start():
    """Mortensen ch. 11: P_pred, P_filt = K for five steps, and the steady filter."""
    c = CASES["A1"]
    y = np.random.default_rng(1).standard_normal(60)
    res = model_of(c).filter(y, c["x0"], c["P0"])
    k = len(c["P_pred"])
    np.testing.assert_allclose(res.P_pred[:k, 0, 0], c["P_pred"], atol=c["tol"])
    np.testing.assert_allclose(res.P_filt[:k, 0, 0], c["P_filt"], atol=c["tol"])
    np.testing.assert_allclose(res.K[:k, 0, 0], c["P_filt"], atol=c["tol"])  # H = R = 1: K = P_filt
    assert res.P_pred[-1, 0, 0] == pytest.approx(c["P_pred_inf"], abs=c["tol"])
    assert res.K[-1, 0, 0] == pytest.approx(c["K_inf"], abs=c["tol"])
    assert c["K_inf"] == pytest.approx((np.sqrt(65) - 7) / 2, abs=c["tol"])
    # Steady filter: x(t|t) = 0.2344355629 x(t-1|t-1) + 0.5311288741 y(t)
    steady = c["steady_filter_coefficient"] * res.x_filt[-2, 0] + c["K_inf"] * y[-1]
    assert res.x_filt[-1, 0] == pytest.approx(steady, abs=1e-9)


def test_a2_constant_in_noise_closed_form():
    """Söderström ex. 6.1: the filter is a weighted running mean of prior and data."""
    c = CASES["A2"]
    y = 100 + np.random.default_rng(2).standard_normal(50)
    res = model_of(c).filter(y, c["x0"], c["P0"])
    t = np.arange(len(y))
    P0, r, x0 = c["P0"], c["r"], c["x0"]
    x_closed = (P0 * np.cumsum(y) + r * x0) / ((t + 1) * P0 + r)
    p_closed = 1 / (1 / P0 + (t + 1) / r)
    np.testing.assert_allclose(res.x_filt[:, 0], x_closed, rtol=c["rtol"])
    np.testing.assert_allclose(res.P_filt[:, 0, 0], p_closed, rtol=c["rtol"])


@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_a3_decay_without_process_noise(form):
    """Söderström ex. 6.2: P_pred and the predictor gain F P / (P + R) for t = 0..7."""
    c = CASES["A3"]
    k = len(c["P_pred"])
    res = model_of(c).filter(np.zeros(k), c["x0"], c["P0"], form=form)
    np.testing.assert_allclose(res.P_pred[:, 0, 0], c["P_pred"], rtol=c["rtol"])
    np.testing.assert_allclose(res.K_pred[:, 0, 0], c["K_pred"], rtol=c["rtol"])


def test_b1_ar1_in_noise_is_stationary_from_p_equal_1():
    """Söderström ex. 6.17: P_pred = 1 solves the Riccati equation, so it stays there."""
    c = CASES["B1"]
    y = np.random.default_rng(3).standard_normal(20)
    res = model_of(c).filter(y, 0.0, c["P_pred"])
    tol = c["tol"]
    np.testing.assert_allclose(res.P_pred[:, 0, 0], c["P_pred"], atol=tol)
    np.testing.assert_allclose(res.K_pred[:, 0, 0], c["K_pred"], atol=tol)
    np.testing.assert_allclose(res.K[:, 0, 0], c["K"], atol=tol)
    np.testing.assert_allclose(res.S[:, 0, 0], c["S"], atol=tol)
    np.testing.assert_allclose(res.P_filt[:, 0, 0], c["P_filt"], atol=tol)
    F, H = c["model"]["F"], c["model"]["H"]
    assert F - res.K_pred[-1, 0, 0] * H == pytest.approx(c["closed_loop"], abs=tol)
    # Signal-to-noise: stationary E x^2 = Q / (1 - F^2), over E v^2 = R.
    assert c["model"]["Q"] / (1 - F**2) / c["model"]["R"] == pytest.approx(c["signal_to_noise"], abs=tol)


def test_b1_converges_to_the_stationary_values_from_any_prior():
    c = CASES["B1"]
    res = model_of(c).filter(np.zeros(80), 0.0, 25.0)
    assert res.P_pred[-1, 0, 0] == pytest.approx(c["P_pred"], abs=1e-12)
    assert res.K_pred[-1, 0, 0] == pytest.approx(c["K_pred"], abs=1e-12)
