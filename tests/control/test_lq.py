"""LQ control (kfast.control.lqr, lq_finite): equal to python-control's dlqr, to the NumPy
backward Riccati recursion (python/kfast/reference/control.py) on time-varying data, to the
Kalman predictor gain on the dual data (Söderström (11.28)-(11.31)); the finite horizon converges
to the stationary law; the expected cost (11.14) equals the closed loop's propagated cost; the
return-difference identity (11.49) holds; Söderström ex. 11.4 (a); bad input is refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import kfast
from kfast.reference.control import closed_loop_cost, lq_backward
from modelgen import random_spd

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


def random_problem(seed, cross=False, stable=False):
    rng = np.random.default_rng(900 + seed)
    n, k = int(rng.integers(1, 9)), int(rng.integers(1, 4))
    F = rng.standard_normal((n, n)) * (0.5 if stable else 1.0)
    G = rng.standard_normal((n, k))
    C = rng.standard_normal((n + k, n + k))
    W = C @ C.T / (n + k) + 0.05 * np.eye(n + k)
    Q1, Q2, Q12 = W[:n, :n], W[n:, n:], W[:n, n:]
    return F, G, Q1, Q2, (Q12 if cross else None)


@pytest.mark.parametrize("seed", range(16))
def test_lqr_equals_python_control_dlqr(seed):
    control = pytest.importorskip("control")
    F, G, Q1, Q2, Q12 = random_problem(seed, cross=seed % 2 == 1)
    res = kfast.control.lqr(F, G, Q1, Q2, Q12)
    if Q12 is None:
        K, S, E = control.dlqr(F, G, Q1, Q2)
    else:
        K, S, E = control.dlqr(F, G, Q1, Q2, Q12)
    scale = max(1.0, np.abs(S).max())
    np.testing.assert_allclose(res.S, S, rtol=1e-8, atol=1e-9 * scale)
    np.testing.assert_allclose(res.L, K, rtol=1e-8, atol=1e-9 * max(1.0, np.abs(K).max()))
    np.testing.assert_allclose(np.sort_complex(res.closed_loop_eigenvalues), np.sort_complex(E), atol=1e-8)
    assert np.abs(res.closed_loop_eigenvalues).max() < 1


@pytest.mark.parametrize("seed", range(8))
def test_the_lq_gain_on_the_dual_data_is_the_transposed_predictor_gain(seed):
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 7)), int(rng.integers(1, 4))
    F = rng.standard_normal((n, n))
    H = rng.standard_normal((m, n))
    C = rng.standard_normal((n + m, n + m))
    W = C @ C.T / (n + m) + 0.1 * np.eye(n + m)
    model = kfast.LinearGaussian(F, H, W[:n, :n], W[n:, n:], N=W[:n, n:])
    dual = kfast.control.lqr(F.T, H.T, W[:n, :n], W[n:, n:], W[:n, n:])
    ss = model.steady_state()
    np.testing.assert_allclose(dual.L.T, ss.K_pred, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(dual.S, ss.P_pred, rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("seed", range(10))
def test_lq_finite_equals_the_backward_recursion_with_time_varying_data(seed):
    rng = np.random.default_rng(40 + seed)
    n, k, N = int(rng.integers(1, 8)), int(rng.integers(1, 4)), int(rng.integers(1, 25))
    F = rng.standard_normal((N, n, n))
    G = rng.standard_normal((N, n, k))
    Ws = [random_spd(rng, n + k) for _ in range(N)]
    Q1 = np.array([w[:n, :n] for w in Ws])
    Q2 = np.array([w[n:, n:] for w in Ws])
    Q12 = np.array([w[:n, n:] for w in Ws]) if seed % 2 else None
    Q0 = random_spd(rng, n)
    res = kfast.control.lq_finite(F, G, Q0, Q1, Q2, N, Q12=Q12)
    S, L = lq_backward(F, G, Q0, Q1, Q2, N, Q12)
    assert res.S.shape == (N + 1, n, n) and res.L.shape == (N, k, n)
    np.testing.assert_array_equal(res.S[N], Q0)
    scale = max(1.0, np.abs(S).max())
    np.testing.assert_allclose(res.S, S, rtol=1e-9, atol=1e-10 * scale)
    np.testing.assert_allclose(res.L, L, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(L).max()))


@pytest.mark.parametrize("seed", range(6))
def test_lq_finite_converges_to_lqr_and_scales(seed):
    F, G, Q1, Q2, Q12 = random_problem(seed, cross=seed % 2 == 0)
    stat = kfast.control.lqr(F, G, Q1, Q2, Q12)
    fin = kfast.control.lq_finite(F, G, np.zeros_like(Q1), Q1, Q2, 400, Q12=Q12)
    np.testing.assert_allclose(fin.L[0], stat.L, rtol=1e-7, atol=1e-8 * max(1.0, np.abs(stat.L).max()))
    np.testing.assert_allclose(fin.S[0], stat.S, rtol=1e-7, atol=1e-8 * max(1.0, np.abs(stat.S).max()))
    # (a Q0, a Q1, a Q12, a Q2) gives a S and the same L (Söderström Sec. 11.6.1).
    scaled = kfast.control.lq_finite(F, G, np.zeros_like(Q1), 3 * Q1, 3 * Q2, 20, Q12=None if Q12 is None else 3 * Q12)
    base = kfast.control.lq_finite(F, G, np.zeros_like(Q1), Q1, Q2, 20, Q12=Q12)
    np.testing.assert_allclose(scaled.S, 3 * base.S, rtol=1e-9, atol=1e-9 * np.abs(base.S).max())
    np.testing.assert_allclose(scaled.L, base.L, rtol=1e-8, atol=1e-9 * max(1.0, np.abs(base.L).max()))


@pytest.mark.parametrize("seed", range(6))
def test_expected_cost_is_the_closed_loops_cost(seed):
    """Söderström Thm 11.2, (11.14): m' S(0) m + tr S(0) P0 + sum tr S(t+1) Q equals the cost of the
    optimal law computed by propagating the closed loop's mean and covariance."""
    rng = np.random.default_rng(70 + seed)
    F, G, Q1, Q2, Q12 = random_problem(seed, cross=seed % 2 == 1)
    n = len(F)
    N = 12
    Q0, P0, Q = random_spd(rng, n), random_spd(rng, n), random_spd(rng, n)
    x0 = rng.standard_normal(n)
    res = kfast.control.lq_finite(F, G, Q0, Q1, Q2, N, Q12=Q12, x0=x0, P0=P0, Q=Q)
    want = closed_loop_cost(F, G, Q0, Q1, Q2, res.L, x0, P0, Q, Q12)
    assert res.expected_cost == pytest.approx(want, rel=1e-10)
    # Any other law costs more.
    worse = closed_loop_cost(F, G, Q0, Q1, Q2, res.L + 1e-3 * rng.standard_normal(res.L.shape), x0, P0, Q, Q12)
    assert worse > want
    assert res.sigma[N] == 0.0 and res.sigma[0] == pytest.approx(sum(np.trace(res.S[t + 1] @ Q) for t in range(N)), rel=1e-12)


@pytest.mark.parametrize("seed", range(8))
def test_return_difference_identity(seed):
    rng = np.random.default_rng(seed)
    F, G, Q1, Q2, Q12 = random_problem(seed, cross=seed % 2 == 1)
    on = np.exp(1j * rng.uniform(-np.pi, np.pi, 3))
    off = rng.uniform(0.3, 3.0, 3) * np.exp(1j * rng.uniform(-np.pi, np.pi, 3))
    left, right = kfast.control.return_difference(F, G, Q1, Q2, np.r_[on, off], Q12=Q12)
    scale = max(1.0, np.abs(right).max())
    np.testing.assert_allclose(left, right, atol=1e-9 * scale)


def test_soderstrom_example_11_4a():
    case = CASES["I2"]
    h, q2, r = case["h"], case["Q2"], case["noise_scale"]
    F, G = np.array([[1, h], [0, 1]]), np.array([[h**2 / 2], [h]])
    res = kfast.control.lqr(F, G, np.eye(2), q2)
    np.testing.assert_allclose(np.sort(res.closed_loop_eigenvalues.real).round(case["digits"]), case["controller_poles"])
    plant = kfast.LinearGaussian(F, [[1.0, 0.0]], r * np.array([[h**3 / 3, h**2 / 2], [h**2 / 2, h]]), r, B=G)
    reg = kfast.control.lqg(plant, np.eye(2), q2)
    est = np.sort_complex(np.linalg.eigvals(F - reg.filter.K_pred @ plant.H))
    want = np.sort_complex(np.array([complex(*p) for p in case["estimator_poles"]]))
    np.testing.assert_allclose(est.round(case["digits"]), want, atol=1e-12)
    # The closed loop's poles are the two sets together (Söderström Lemma 11.4).
    np.testing.assert_allclose(np.sort_complex(reg.closed_loop_poles), np.sort_complex(np.r_[res.closed_loop_eigenvalues, est]), atol=1e-8)


def test_bad_input():
    F, G = np.array([[1.0, 1.0], [0.0, 1.0]]), np.array([[0.0], [1.0]])
    with pytest.raises(kfast.NoStabilizingSolutionError, match="lqr: no stabilizing feedback"):
        kfast.control.lqr(np.diag([1.5, 0.5]), [[0.0], [1.0]], np.eye(2), 1.0)  # unstable mode not controllable
    with pytest.raises(ValueError, match="Q1: .*positive semidefinite"):
        kfast.control.lqr(F, G, -np.eye(2), 1.0)
    with pytest.raises(ValueError, match="Q1: .*symmetric"):
        kfast.control.lqr(F, G, [[1.0, 0.5], [0.0, 1.0]], 1.0)
    with pytest.raises(ValueError, match="Q12: the joint weight"):
        kfast.control.lqr(F, G, np.eye(2), 1.0, Q12=[[3.0], [0.0]])
    with pytest.raises(ValueError, match=r"G: expected 2 rows like F"):
        kfast.control.lqr(F, np.ones((3, 1)), np.eye(2), 1.0)
    with pytest.raises(ValueError, match="F: contains a non-finite value"):
        kfast.control.lqr([[np.nan, 1.0], [0.0, 1.0]], G, np.eye(2), 1.0)
    with pytest.raises(ValueError, match="N: the horizon must be at least 1"):
        kfast.control.lq_finite(F, G, np.eye(2), np.eye(2), 1.0, 0)
    with pytest.raises(ValueError, match="N: expected an integer"):
        kfast.control.lq_finite(F, G, np.eye(2), np.eye(2), 1.0, 2.5)
    with pytest.raises(ValueError, match="F: a per-step stack must have N = 3"):
        kfast.control.lq_finite(np.stack([F, F]), G, np.eye(2), np.eye(2), 1.0, 3)
    with pytest.raises(ValueError, match="Q2 at step 1: .*positive semidefinite"):
        kfast.control.lq_finite(F, G, np.eye(2), np.eye(2), np.array([[[1.0]], [[-1.0]], [[1.0]]]), 3)
    with pytest.raises(ValueError, match="Q2 at step 2: G' S\\(t\\+1\\) G \\+ Q2 is not positive definite"):
        kfast.control.lq_finite(F, G, np.zeros((2, 2)), np.zeros((2, 2)), 0.0, 3)
    with pytest.raises(ValueError, match="Q0: .*positive semidefinite"):
        kfast.control.lq_finite(F, G, -np.eye(2), np.eye(2), 1.0, 3)
    with pytest.raises(ValueError, match="Q1 at step 1: not symmetric"):
        kfast.control.lq_finite(F, G, np.eye(2), np.array([np.eye(2), [[1.0, 0.5], [0.0, 1.0]], np.eye(2)]), 1.0, 3)
    with pytest.raises(ValueError, match="Q12 at step 2: .*the joint weight"):
        kfast.control.lq_finite(F, G, np.eye(2), np.eye(2), 1.0, 3, Q12=np.array([[[0.0], [0.0]], [[0.0], [0.0]], [[3.0], [0.0]]]))
    with pytest.raises(ValueError, match="N: .*too large|N: .*memory"):
        kfast.control.lq_finite(F, G, np.eye(2), np.eye(2), 1.0, 2**62)
    with pytest.raises(ValueError, match="method: expected one of"):
        kfast.control.lqr(F, G, np.eye(2), 1.0, method="qz")
    # Nothing passed in is modified.
    Q1 = np.eye(2)
    kfast.control.lq_finite(F, G, Q1, Q1, 1.0, 3, x0=[1.0, 2.0], Q=Q1)
    np.testing.assert_array_equal(Q1, np.eye(2))
