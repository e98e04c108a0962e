"""Polynomial methods (kfast.poly) against their state-space counterparts and the textbook:
the spectral factor by zeros equals the one by the Riccati equation on random ARMA spectra;
the ARMA k-step predictor equals the stationary Kalman k-step predictor of the same model;
ARMA <-> state space round-trips; the Diophantine solution satisfies its identity; the worked
cases E1, E2 (spectral factorization, Mortensen) and F (Söderström Example 7.1) from
tests/data/textbook_cases.json; bad input is refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import kfast
from modelgen import stable_monic
from kfast.poly import laurent

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


@pytest.mark.parametrize("seed", range(12))
def test_roots_and_riccati_routes_agree(seed):
    rng = np.random.default_rng(seed)
    d = int(rng.integers(1, 9))
    C = stable_monic(rng, d, radius=0.95)
    lam2 = rng.uniform(0.2, 3.0)
    r = lam2 * laurent(C, C)
    by_roots = kfast.poly.spectral_factor(r)
    by_riccati = kfast.poly.spectral_factor(r, method="riccati")
    np.testing.assert_allclose(by_roots.B, C, atol=1e-8)
    np.testing.assert_allclose(by_riccati.B, C, atol=1e-8)
    assert by_roots.lam2 == pytest.approx(lam2, rel=1e-8) and by_riccati.lam2 == pytest.approx(lam2, rel=1e-8)
    assert not by_roots.on_circle


@pytest.mark.parametrize("seed", range(6))
def test_a_spectrum_with_a_non_minimum_phase_factor_gets_the_minimum_phase_one(seed):
    """The factor of a spectrum built from a polynomial with zeros outside the circle is the
    reflected (minimum-phase) one, with the same spectrum."""
    rng = np.random.default_rng(100 + seed)
    d = int(rng.integers(1, 6))
    C = stable_monic(rng, d)
    outside = np.real(np.poly(1.0 / np.roots(C))) if d else C  # zeros reflected outside
    r = laurent(outside, outside)
    f = kfast.poly.spectral_factor(r)
    assert np.all(np.abs(np.roots(f.B)) < 1)
    omega = np.linspace(0, np.pi, 50)
    np.testing.assert_allclose(f.lam2 * np.abs(np.polyval(f.B, np.exp(1j * omega))) ** 2,
                               kfast.poly.evaluate_spectrum(r, omega), rtol=1e-8, atol=1e-12)


def test_e1_fir_factor():
    case = CASES["E1"]
    for method in ("roots", "riccati"):
        f = kfast.poly.spectral_factor(case["laurent"], method=method)
        np.testing.assert_allclose(f.B, case["factor"], atol=1e-12)
        assert f.lam2 == pytest.approx(1.0, rel=1e-12)


def test_e2_rational_factor_with_zeros_on_the_circle():
    """φ = (1 + cos ω)/(2.125 - cos 2ω): B = z + 1 (a zero on the circle, Lemma 4.6), A = z² - 1/4;
    H = sqrt(lam2) B / A has impulse response 0, 1/2, 1/2, 1/8, 1/8, ... and the model's
    autocovariance is (9 - (-1)^τ)/15 2^-τ."""
    case = CASES["E2"]
    f = kfast.poly.spectral_factor(num=case["num"], den=case["den"])
    assert f.on_circle
    np.testing.assert_allclose(f.B, [1.0, 1.0], atol=1e-7)
    np.testing.assert_allclose(f.A, [1.0, 0.0, -0.25], atol=1e-12)
    # Impulse response of sqrt(lam2) B(z)/A(z) in powers of z^-1.
    h = np.zeros(len(case["impulse_response"]))
    num = np.sqrt(f.lam2) * np.r_[0.0, f.B]  # B / A = z^-1 (1 + z^-1) / (1 - z^-2/4)
    a = f.A
    for t in range(len(h)):
        h[t] = (num[t] if t < len(num) else 0.0) - sum(a[i] * h[t - i] for i in range(1, len(a)) if t - i >= 0)
    np.testing.assert_allclose(h, case["impulse_response"], atol=1e-7)
    by_riccati = kfast.poly.spectral_factor(num=case["num"], den=case["den"], method="riccati")
    assert by_riccati.on_circle
    np.testing.assert_allclose(by_riccati.B, f.B, atol=1e-6)
    assert by_riccati.lam2 == pytest.approx(f.lam2, rel=1e-6)
    # The autocovariance c(τ) = Σ_j h_j h_(j+τ) of the factor's impulse response.
    long = np.zeros(200)
    for t in range(200):
        long[t] = (num[t] if t < len(num) else 0.0) - sum(a[i] * long[t - i] for i in range(1, len(a)) if t - i >= 0)
    c = [float(long[: 200 - tau] @ long[tau:]) for tau in range(len(case["autocovariance"]))]
    np.testing.assert_allclose(c, case["autocovariance"], atol=1e-7)


def test_f_example_7_1_predictors():
    case = CASES["F"]
    for k, want in case["predictors"].items():
        p = kfast.poly.arma_predictor(case["A"], case["C"], int(k), lam2=case["lam2"])
        np.testing.assert_allclose(p.den, case["C_invertible"], atol=1e-12)
        assert p.lam2 == pytest.approx(case["lam2_invertible"], rel=1e-12)
        np.testing.assert_allclose(p.num, want["num"], atol=1e-12)
        assert p.error_variance == pytest.approx(want["error_variance"], rel=1e-12)


def predictor_response(model, k, z):
    """The stationary Kalman k-step predictor y(t) -> ŷ(t+k|t) = H F^(k-1) x̂(t+1|t) as a transfer
    function at the point z (x̂(t+1|t) = z (zI - F + K_pred H)^-1 K_pred y(t))."""
    ss = model.steady_state()
    F, H, Kp = model.F, model.H, ss.K_pred
    n = len(F)
    x_next = z * np.linalg.solve(z * np.eye(n) - F + Kp @ H, Kp)
    return (H @ np.linalg.matrix_power(F, k - 1) @ x_next)[0, 0]


@pytest.mark.parametrize("seed", range(10))
def test_arma_predictor_is_the_kalman_k_step_predictor(seed):
    rng = np.random.default_rng(200 + seed)
    n = int(rng.integers(1, 5))
    A = stable_monic(rng, n, radius=0.95)
    C = np.r_[stable_monic(rng, int(rng.integers(0, n + 1))), np.zeros(n)][: n + 1]  # deg C = deg A
    lam2, k = rng.uniform(0.5, 2.0), int(rng.integers(1, 5))
    model = kfast.poly.arma_to_ss(A, C, lam2)
    p = kfast.poly.arma_predictor(A, C, k, lam2=lam2)
    for z in np.exp(1j * rng.uniform(0, np.pi, 3)) * rng.uniform(0.98, 1.5, 3):
        want = predictor_response(model, k, z)
        got = np.polyval(p.num, z) / np.polyval(p.den, z)
        assert got == pytest.approx(want, rel=1e-8, abs=1e-10)
    # The error variance is the k-step prediction error variance of the Kalman filter.
    ss = model.steady_state()
    P = ss.P_pred
    for _ in range(k - 1):
        P = model.F @ P @ model.F.T + model.Q
    assert p.error_variance == pytest.approx((model.H @ P @ model.H.T + model.R)[0, 0], rel=1e-8)


@pytest.mark.parametrize("seed", range(6))
def test_arma_state_space_round_trip(seed):
    rng = np.random.default_rng(300 + seed)
    n = int(rng.integers(1, 6))
    A = stable_monic(rng, n)
    C = stable_monic(rng, n)
    lam2 = rng.uniform(0.5, 2.0)
    A2, C2, lam2_2 = kfast.poly.ss_to_arma(kfast.poly.arma_to_ss(A, C, lam2))
    np.testing.assert_allclose(A2, A, atol=1e-9)
    np.testing.assert_allclose(C2, C, atol=1e-7)
    assert lam2_2 == pytest.approx(lam2, rel=1e-8)
    # Its spectrum is λ² C C* / (A A*).
    omega = rng.uniform(0, np.pi, 4)
    z = np.exp(1j * omega)
    want = lam2 * np.abs(np.polyval(C, z)) ** 2 / np.abs(np.polyval(A, z)) ** 2
    got = kfast.poly.arma_to_ss(A, C, lam2).spectral_density(omega)[:, 0, 0].real
    np.testing.assert_allclose(got, want, rtol=1e-9)


@pytest.mark.parametrize("seed", range(10))
def test_diophantine_identity(seed):
    rng = np.random.default_rng(400 + seed)
    A = np.r_[1.0, rng.standard_normal(int(rng.integers(0, 5)))]
    B = rng.standard_normal(int(rng.integers(1, 5)))
    C = rng.standard_normal(int(rng.integers(1, 9)))
    d = kfast.poly.diophantine(A, B, C)
    assert len(d.X) == max(len(B) - 1, 1)
    lhs = np.polyadd(np.polymul(A, d.X), np.polymul(B, d.Y))
    np.testing.assert_allclose(np.trim_zeros(lhs, "f") if np.any(lhs) else lhs, np.trim_zeros(C, "f"), atol=1e-9 * d.condition)


def test_predictor_identity_is_the_impulse_response():
    """(7.23): F's coefficients are the first k impulse-response coefficients of C/A."""
    A, C, k = [1.0, -1.5, 0.7], [1.0, 0.4, 0.2], 4
    F, L = kfast.poly.predictor_identity(A, C, k)
    h = np.zeros(k)
    for t in range(k):
        h[t] = (C[t] if t < len(C) else 0.0) - sum(A[i] * h[t - i] for i in range(1, len(A)) if t - i >= 0)
    np.testing.assert_allclose(F, h, atol=1e-12)
    lhs = np.polyadd(np.polymul(A, F), L)
    np.testing.assert_allclose(lhs, np.r_[C, np.zeros(k - 1)], atol=1e-12)


def test_bad_input():
    with pytest.raises(ValueError, match="A: must be monic"):
        kfast.poly.arma_predictor([2.0, -0.8], [1.0, 0.5], 1)
    with pytest.raises(ValueError, match="C: has a zero on the unit circle"):
        kfast.poly.arma_predictor([1.0, -0.8], [1.0, 1.0], 1)
    with pytest.raises(ValueError, match="r: the spectrum is negative on the unit circle"):
        kfast.poly.spectral_factor([1.0, 0.0, 1.0])  # 1 + 2 cos 2ω
    with pytest.raises(ValueError, match="r: must be symmetric"):
        kfast.poly.spectral_factor([1.0, 3.0, 2.0])
    with pytest.raises(ValueError, match="r: a symmetric Laurent polynomial has an odd number"):
        kfast.poly.spectral_factor([1.0, 3.0])
    with pytest.raises(ValueError, match="A, B: have a common factor"):
        kfast.poly.diophantine(np.polymul([1, -0.5], [1, 0.3]), np.polymul([1, -0.5], [1, 2.0]), [1.0, 0, 0, 0])
    with pytest.raises(ValueError, match="k: the prediction horizon must be at least 1"):
        kfast.poly.predictor_identity([1, -0.5], [1, 0.2], 0)
    with pytest.raises(ValueError, match="method: expected one of"):
        kfast.poly.spectral_factor([1.0], method="qz")
    with pytest.raises(ValueError, match="r: give either r"):
        kfast.poly.spectral_factor([1.0], num=[1.0])
