"""Polynomial regulators (kfast.control.minimum_variance, lqg_polynomial) for ARMAX models:
the minimum-variance closed loop is y = F(q) e(t-k+1) (Söderström (11.64)-(11.66)); the
non-minimum-phase law is the ρ -> 0 limit of polynomial LQG; generalized minimum variance has the
closed loop of Ex. 11.5; polynomial LQG equals the state-space LQG of the same model (the
(n+1)-state realisation of Söderström Example 7.2, k = 0) transfer function for transfer function,
cost for cost; bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest

import kfast
from modelgen import stable_monic
from kfast.poly import polyadd, polymul


def armax(seed, minimum_phase=True):
    rng = np.random.default_rng(700 + seed)
    n = int(rng.integers(1 if minimum_phase else 2, 5))
    m = int(rng.integers(0 if minimum_phase else 1, n))  # a zero to move outside needs m >= 1
    A = stable_monic(rng, n, radius=1.2)  # open loop may be unstable
    A[-1] = A[-1] if abs(A[-1]) > 1e-3 else 0.05
    C = stable_monic(rng, n)
    B = rng.uniform(0.5, 2.0) * stable_monic(rng, m, radius=0.9 if minimum_phase else 0.5)
    if not minimum_phase:
        zeros = np.roots(B)
        zeros[0] = 1.0 / zeros[0] if abs(zeros[0]) > 0.1 else 2.5
        B = B[0] * np.real(np.poly(zeros))
    return A, B, C, n - m, rng


def response(num, den, z):
    return np.polyval(num, z) / np.polyval(den, z)


@pytest.mark.parametrize("seed", range(10))
def test_minimum_variance_closed_loop_is_F_of_the_predictor_identity(seed):
    A, B, C, k, rng = armax(seed)
    lam2 = rng.uniform(0.5, 2.0)
    delay = int(seed % 3 == 0)
    reg = kfast.control.minimum_variance(A, B, C, lam2=lam2, delay=delay)
    F, L = kfast.poly.predictor_identity(A, C, k + delay)
    # (A R + B S) y = C R e with A R + B S = B z^(k+delay-1) C: y = F(q) e(t - k - delay + 1).
    np.testing.assert_allclose(reg.closed_loop * B[0], polymul(B, np.r_[C, np.zeros(k + delay - 1)]), atol=1e-9)
    assert reg.output_variance == pytest.approx(lam2 * np.sum(F**2), rel=1e-9)
    for z in rng.uniform(0.5, 2.0, 3) * np.exp(1j * rng.uniform(0, np.pi, 3)):
        closed = response(polymul(C, reg.R), polyadd(polymul(A, reg.R), polymul(B, reg.S)), z)
        assert closed == pytest.approx(np.polyval(F, z) / z ** (k + delay - 1), rel=1e-8)


@pytest.mark.parametrize("seed", range(6))
def test_minimum_variance_is_minimal(seed):
    """Any perturbation of a stable law raises the output variance."""
    A, B, C, k, rng = armax(seed)
    reg = kfast.control.minimum_variance(A, B, C)
    for _ in range(4):
        S = reg.S + 0.02 * rng.standard_normal(reg.S.shape)
        closed = polyadd(polymul(A, reg.R), polymul(B, S))
        closed = closed / closed[0]
        if np.abs(np.roots(closed)).max() < 0.999:
            assert kfast.control.closed_loop_variance(polymul(C, reg.R) / polyadd(polymul(A, reg.R), polymul(B, S))[0], closed) > reg.output_variance


@pytest.mark.parametrize("seed", range(6))
def test_non_minimum_phase_law_is_the_limit_of_polynomial_lqg(seed):
    A, B, C, k, rng = armax(seed, minimum_phase=False)
    mv = kfast.control.minimum_variance(A, B, C)
    assert mv.kind == "minimum variance (non-minimum-phase B)"
    assert np.abs(np.roots(mv.closed_loop)).max() < 1
    lqg = kfast.control.lqg_polynomial(A, B, C, rho=1e-9)
    for z in np.exp(1j * rng.uniform(0, np.pi, 3)):
        assert response(mv.S, mv.R, z) == pytest.approx(response(lqg.S, lqg.R, z), rel=1e-4)
    assert mv.output_variance == pytest.approx(lqg.output_variance, rel=1e-5)


@pytest.mark.parametrize("seed", range(6))
def test_generalized_minimum_variance_closed_loop(seed):
    A, B, C, k, rng = armax(seed)
    rho = rng.uniform(0.05, 2.0)
    reg = kfast.control.minimum_variance(A, B, C, rho=rho)
    # A R + B S = C (b0 q^k B + ρ A)  (Söderström Ex. 11.5)
    want = polymul(C, polyadd(B[0] * np.r_[B, np.zeros(k)], rho * A))
    np.testing.assert_allclose(reg.closed_loop, want / want[0], atol=1e-9)


def realisation(A, B, C, lam2):
    """Söderström Example 7.2's (n+1)-state model: N = 0, R = 0, P = λ² c̄ c̄', K = c̄."""
    n, m = len(A) - 1, len(B) - 1
    k = n - m
    F = np.eye(n + 1, k=1)
    F[:n, 0] = -A[1:]
    c = np.r_[C].reshape(-1, 1)
    G = np.zeros((n + 1, 1))
    G[k - 1 : k + m, 0] = B  # (0_(k-1), b0 .. bm, 0)'
    return kfast.LinearGaussian(F, np.eye(1, n + 1), lam2 * c @ c.T, [[0.0]], B=G)


@pytest.mark.parametrize("seed", range(8))
def test_polynomial_lqg_equals_state_space_lqg(seed):
    A, B, C, k, rng = armax(seed, minimum_phase=seed % 2 == 0)
    rho, lam2 = rng.uniform(0.05, 2.0), rng.uniform(0.5, 2.0)
    poly_reg = kfast.control.lqg_polynomial(A, B, C, rho=rho, lam2=lam2)
    model = realisation(A, B, C, lam2)
    n1 = model.n_states
    H = model.H
    ss_reg = kfast.control.lqg(model, H.T @ H, rho, k=0)
    for z in rng.uniform(0.8, 1.5, 3) * np.exp(1j * rng.uniform(0, np.pi, 3)):
        assert ss_reg.regulator_response(z)[0, 0, 0] == pytest.approx(response(poly_reg.S, poly_reg.R, z), rel=1e-6, abs=1e-9)
    # The closed loop's poles are the zeros of C and P (11.84), and the costs agree.
    P = np.roots(poly_reg.closed_loop)
    assert np.all(np.abs(P) < 1) and n1 == len(A)
    assert poly_reg.output_variance + rho * poly_reg.input_variance == pytest.approx(ss_reg.cost, rel=1e-6)


def test_bad_input():
    A, B, C = [1.0, -1.5, 0.7], [1.0, 0.5], [1.0, -0.2, 0.1]
    with pytest.raises(ValueError, match="A: must be monic"):
        kfast.control.minimum_variance([2.0, -1.5, 0.7], B, C)
    with pytest.raises(ValueError, match="C: must have its zeros strictly inside"):
        kfast.control.minimum_variance(A, B, [1.0, 0.0, -4.0])
    with pytest.raises(ValueError, match="B: degree 2 must be below deg A"):
        kfast.control.minimum_variance(A, [1.0, 0.0, 0.0], C)
    with pytest.raises(ValueError, match="B: has a zero on the unit circle"):
        kfast.control.minimum_variance(A, [1.0, 1.0], C)
    with pytest.raises(ValueError, match="A: A\\(0\\) = 0"):
        kfast.control.lqg_polynomial([1.0, -1.5, 0.0], B, C, rho=0.1)
    with pytest.raises(ValueError, match="A, B: have a common factor"):
        kfast.control.lqg_polynomial(np.polymul([1.0, -0.5], [1.0, 0.2]), [1.0, -0.5], C, rho=0.1)
    with pytest.raises(ValueError, match="rho: must be a finite number >= 0"):
        kfast.control.minimum_variance(A, B, C, rho=-1.0)
    with pytest.raises(ValueError, match="delay: a computation delay is supported for minimum-phase B only"):
        kfast.control.minimum_variance(A, [1.0, 2.0], C, delay=1)
