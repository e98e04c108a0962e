"""Stationary LQG (kfast.control.lqg): the realisation is the book's (11.34), (11.38); the closed
loop's variances equal the NumPy reference in the book's coordinates (x, x̃) ((11.42)-(11.43)) and
a long simulation; its poles are eig(F - GL) ∪ eig(F - K_pred H); the cost equals
tr(S Q) + tr(P L' Γ L); the regulator realisation reproduces the law u = -L x̂(t|t-k) - L_w e
step by step, with N != 0 and D != 0; L_w minimises the cost; the pre-gain, integral action and
loop transfer recovery do what (11.89)-(11.91) and Lemma 11.9 say."""

from __future__ import annotations

import numpy as np
import pytest

import kfast
from kfast.control.lqg import _closed_loop
from kfast.reference.control import lqg_closed_loop


def random_plant(seed, cross=False, direct=False, m=None):
    rng = np.random.default_rng(300 + seed)
    n, ku = int(rng.integers(1, 6)), int(rng.integers(1, 3))
    m = int(rng.integers(1, 3)) if m is None else m
    F = rng.standard_normal((n, n)) * 0.8
    B = rng.standard_normal((n, ku))
    H = rng.standard_normal((m, n))
    C = rng.standard_normal((n + m, n + m))
    W = C @ C.T / (n + m) + 0.1 * np.eye(n + m)
    model = kfast.LinearGaussian(
        F, H, W[:n, :n], W[n:, n:], B=B, D=0.3 * rng.standard_normal((m, ku)) if direct else None, N=W[:n, n:] if cross else None
    )
    V = rng.standard_normal((n + ku, n + ku))
    weight = V @ V.T / (n + ku) + 0.1 * np.eye(n + ku)
    return model, weight[:n, :n], weight[n:, n:], weight[:n, n:] if seed % 2 else None


@pytest.mark.parametrize("k", [0, 1])
@pytest.mark.parametrize("seed", range(8))
def test_closed_loop_equals_the_books_coordinates(seed, k):
    model, Q1, Q2, Q12 = random_plant(seed)
    reg = kfast.control.lqg(model, Q1, Q2, Q12, k=k)
    F, H, B = model.F, model.H, model.B
    L, K, Kp = reg.L, reg.filter.K, reg.filter.K_pred
    n = len(F)
    # The realisations (11.34) and (11.38) (N = 0, D = 0).
    if k == 1:
        want = (F - Kp @ H - B @ L, Kp, L, np.zeros_like(reg.J_r))
    else:
        I = np.eye(n)
        want = ((F - B @ L) @ (I - K @ H), (F - B @ L) @ K, L @ (I - K @ H), L @ K)
    for got, w, name in zip((reg.F_r, reg.G_r, reg.H_r, reg.J_r), want, ("F_r", "G_r", "H_r", "J_r")):
        np.testing.assert_allclose(got, w, rtol=1e-9, atol=1e-10, err_msg=name)
    Pi, var_y, var_u = lqg_closed_loop(F, B, H, model.Q, model.R, L, K, Kp, k)
    np.testing.assert_allclose(reg.var_y, var_y, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(reg.var_u, var_u, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(reg.var_x, Pi[:n, :n], rtol=1e-8, atol=1e-10)
    poles = np.r_[reg.lq.closed_loop_eigenvalues, reg.filter.closed_loop_eigenvalues]
    np.testing.assert_allclose(np.sort_complex(reg.closed_loop_poles), np.sort_complex(poles), atol=1e-7)
    # The stationary cost: tr(S Q) + tr(P_k L' Γ L), P_k = P(t|t-1) (k = 1) or P(t|t) (k = 0).
    Q2_ = np.atleast_2d(Q2)
    gamma = B.T @ reg.lq.S @ B + Q2_
    P = reg.filter.P_pred if k == 1 else reg.filter.P_filt
    assert reg.cost == pytest.approx(np.trace(reg.lq.S @ model.Q) + np.trace(P @ L.T @ gamma @ L), rel=1e-9)


@pytest.mark.parametrize("k", [0, 1])
@pytest.mark.parametrize("seed, cross, direct", [(0, True, False), (1, False, True), (2, True, True), (3, True, True)])
def test_realisation_reproduces_the_law_and_its_variances(seed, cross, direct, k):
    """Plant, stationary filter and u = -L x̂(t|t-k) - L_w e simulated directly; the realisation
    (F_r, G_r, H_r, J_r) driven by the same y gives the same u, and the sample variances of y
    and u approach var_y, var_u."""
    model, Q1, Q2, Q12 = random_plant(seed, cross=cross, direct=direct)
    reg = kfast.control.lqg(model, Q1, Q2, Q12, k=k)
    F, H, B = model.F, model.H, model.B
    D = model.D if model.D is not None else np.zeros((len(H), B.shape[1]))
    n, m = len(F), len(H)
    Nw = model.N if model.N is not None else np.zeros((n, m))
    W = np.block([[model.Q, Nw], [Nw.T, model.R]])
    rng = np.random.default_rng(seed)
    T = 40000
    noise = rng.multivariate_normal(np.zeros(n + m), W, size=T)
    M = reg.L @ reg.filter.K + reg.L_w if k == 0 else np.zeros((B.shape[1], m))
    x, z, zeta = np.zeros(n), np.zeros(n), np.zeros(n)
    us, ys = np.empty((T, B.shape[1])), np.empty((T, m))
    for t in range(T):
        w, v = noise[t, :n], noise[t, n:]
        e = H @ (x - z) + v  # the innovation does not depend on u
        u = -reg.L @ z - M @ e
        y = H @ x + D @ u + v
        if t < 6:
            # (Only at the start: the regulator alone may be unstable, so its state drifts from
            # the filter's by rounding at that rate; the closed loop is stable.)
            u_r = -reg.H_r @ zeta - reg.J_r @ y
            np.testing.assert_allclose(u_r, u, rtol=1e-8, atol=1e-9 * max(1.0, np.abs(u).max()))
            zeta = reg.F_r @ zeta + reg.G_r @ y
        us[t], ys[t] = u, y
        z = F @ z + B @ u + reg.filter.K_pred @ e
        x = F @ x + B @ u + w
    np.testing.assert_allclose(np.cov(us[1000:].T).reshape(reg.var_u.shape), reg.var_u, rtol=0.08, atol=0.02 * np.abs(reg.var_u).max())
    np.testing.assert_allclose(np.cov(ys[1000:].T).reshape(reg.var_y.shape), reg.var_y, rtol=0.08, atol=0.02 * np.abs(reg.var_y).max())


@pytest.mark.parametrize("seed", range(4))
def test_the_innovation_feedback_L_w_minimises_the_cost_with_correlated_noise(seed):
    model, Q1, Q2, Q12 = random_plant(seed, cross=True)
    reg = kfast.control.lqg(model, Q1, Q2, Q12, k=0)
    assert np.abs(reg.L_w).max() > 0
    F, H, B = model.F, model.H, model.B
    D = np.zeros((len(H), B.shape[1]))
    n = len(F)
    W = np.block([[model.Q, model.N], [model.N.T, model.R]])
    weight = np.block([[Q1, np.zeros((n, B.shape[1])) if Q12 is None else Q12], [np.zeros((B.shape[1], n)) if Q12 is None else Q12.T, np.atleast_2d(Q2)]])

    def cost(L_w):
        M = reg.L @ reg.filter.K + L_w
        H_r, J_r = reg.L - M @ H, M
        F_r = F - B @ H_r - reg.filter.K_pred @ H
        G_r = reg.filter.K_pred - B @ J_r
        A, Bn, _, _, C_u, D_u = _closed_loop(F, H, B, D, F_r, G_r, H_r, J_r)
        Pi = kfast.solve_discrete_lyapunov(A, Bn @ W @ Bn.T)
        X = np.vstack([np.eye(n, 2 * n), C_u])
        cov = X @ Pi @ X.T
        cov[n:, n:] += D_u @ model.R @ D_u.T
        return float(np.sum(weight * cov))

    best = cost(reg.L_w)
    assert best == pytest.approx(reg.cost, rel=1e-10)
    rng = np.random.default_rng(seed)
    for _ in range(5):
        assert cost(reg.L_w + 1e-3 * rng.standard_normal(reg.L_w.shape)) > best
    assert cost(np.zeros_like(reg.L_w)) > best


def test_reference_gain_and_integral_action():
    h = 0.5
    F, G, H = np.array([[1, h], [0, 1]]), np.array([[h**2 / 2], [h]]), np.array([[1.0, 0.0]])
    lq = kfast.control.lqr(F, G, np.eye(2), 0.1)
    M = kfast.control.reference_gain(F, G, H, lq.L)
    static = H @ np.linalg.solve(np.eye(2) - F + G @ lq.L, G) @ M
    np.testing.assert_allclose(static, [[1.0]], rtol=1e-12)
    # Integral action removes a constant load disturbance: y -> r.
    integ = kfast.control.lqr_integral(F, G, H, np.eye(2), 0.1, Q3=0.5)
    assert np.abs(integ.augmented.closed_loop_eigenvalues).max() < 1
    x, z, r, load = np.zeros(2), np.zeros(1), 2.0, np.array([0.05, -0.1])
    for _ in range(400):
        u = -integ.L1 @ x - integ.L2 @ z
        z = z + H @ x - r
        x = F @ x + G @ u + load
    assert (H @ x)[0] == pytest.approx(r, abs=1e-9)
    # Without it the load leaves an offset.
    x = np.zeros(2)
    for _ in range(400):
        x = F @ x + G @ (-lq.L @ x + M @ [r]) + load
    assert abs((H @ x)[0] - r) > 1e-3


def test_loop_transfer_recovery_lemma_11_9():
    rng = np.random.default_rng(5)
    # A square, minimum-phase plant: two inputs, two outputs, zeros inside the circle.
    F = np.diag([0.9, 0.5, -0.3]) + 0.1 * rng.standard_normal((3, 3))
    G = rng.standard_normal((3, 2))
    H = rng.standard_normal((2, 3))
    lq = kfast.control.lqr(F, G, np.eye(3), np.eye(2))
    K = kfast.control.ltr_gain(G, H)
    L = lq.L
    eye = np.eye(3)
    for z in [0.7 + 0.4j, np.exp(0.3j), -1.2 + 0.1j]:
        G_R = z * L @ np.linalg.solve(z * eye - (eye - K @ H) @ (F - G @ L), K)
        G_S = H @ np.linalg.solve(z * eye - F, G)
        G_0 = L @ np.linalg.solve(z * eye - F, G)
        np.testing.assert_allclose(G_R @ G_S, G_0, atol=1e-10)
    with pytest.raises(ValueError, match="H: loop transfer recovery needs H G square"):
        kfast.control.ltr_gain(G, H[:1])


def test_bad_input():
    model, Q1, Q2, Q12 = random_plant(0)
    with pytest.raises(ValueError, match="k: expected 0 or 1"):
        kfast.control.lqg(model, Q1, Q2, k=2)
    with pytest.raises(ValueError, match="model: lqg needs the input matrix B"):
        kfast.control.lqg(kfast.LinearGaussian(0.5, 1.0, 1.0, 1.0), 1.0, 1.0)
    stack = kfast.LinearGaussian(np.full((3, 1, 1), 0.5), 1.0, 1.0, 1.0, B=1.0)
    with pytest.raises(ValueError, match="model: lqg needs constant matrices"):
        kfast.control.lqg(stack, 1.0, 1.0)
    with pytest.raises(ValueError, match="H: the pre-gain needs as many outputs as inputs"):
        kfast.control.reference_gain(np.eye(2) * 0.5, [[1.0], [0.0]], np.eye(2), [[0.1, 0.1]])
    with pytest.raises(ValueError, match="L: F - G L has an eigenvalue at 1"):
        kfast.control.reference_gain(np.eye(1), [[1.0]], [[1.0]], [[0.0]])
