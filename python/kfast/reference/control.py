"""LQ and LQG control in plain NumPy, written from Söderström ch. 11 and independent of the fast
path (which runs the Kalman filter on the dual problem). Sign convention u = -L x.
"""

from __future__ import annotations

import numpy as np

from kfast.reference.filter import _at

__all__ = ["lq_backward", "closed_loop_cost", "lqg_closed_loop"]


def lq_backward(F, G, Q0, Q1, Q2, N, Q12=None):
    """The backward Riccati recursion (11.6)-(11.7): S (N + 1, n, n) with S[N] = Q0 and the gains
    L (N, k, n); F, G and the weights constant or per-step stacks."""
    n = np.shape(Q0)[0]
    S = np.zeros((N + 1, n, n))
    S[N] = Q0
    L = []
    for t in range(N - 1, -1, -1):
        Ft, Gt, Q1t, Q2t = _at(F, t), _at(G, t), _at(Q1, t), _at(Q2, t)
        Q12t = _at(Q12, t) if Q12 is not None else np.zeros(Gt.shape)
        gamma = Gt.T @ S[t + 1] @ Gt + Q2t
        Lt = np.linalg.solve(gamma, Gt.T @ S[t + 1] @ Ft + Q12t.T)
        St = Ft.T @ S[t + 1] @ Ft + Q1t - (Ft.T @ S[t + 1] @ Gt + Q12t) @ Lt
        S[t] = (St + St.T) / 2
        L.append(Lt)
    return S, np.array(L[::-1])


def closed_loop_cost(F, G, Q0, Q1, Q2, L, x0, P0, Q, Q12=None):
    """E[x(N)' Q0 x(N) + sum_t (x' Q1 x + 2 x' Q12 u + u' Q2 u)] under u(t) = -L[t] x(t) by
    propagating the mean and covariance of x exactly (no Riccati equation)."""
    m, P = np.asarray(x0, float), np.asarray(P0, float)
    cost = 0.0
    for t in range(len(L)):
        Ft, Gt, Q1t, Q2t, Qt = _at(F, t), _at(G, t), _at(Q1, t), _at(Q2, t), _at(Q, t)
        Q12t = _at(Q12, t) if Q12 is not None else np.zeros(Gt.shape)
        W = np.block([[Q1t, Q12t], [Q12t.T, Q2t]])
        T = np.vstack([np.eye(len(m)), -L[t]])  # (x, u) = T x
        second = T @ (P + np.outer(m, m)) @ T.T
        cost += np.sum(W * second)
        A = Ft - Gt @ L[t]
        m, P = A @ m, A @ P @ A.T + Qt
    return cost + np.sum(Q0 * (P + np.outer(m, m)))


def lqg_closed_loop(F, G, H, Q, R, L, K, K_pred, k):
    """The closed loop in the coordinates xi = (x, x̃), x̃ = x - x̂(t|t-1), N = 0, no D
    (Söderström (11.42)-(11.43)); returns the stationary covariance Pi of xi (by iterating the
    Lyapunov recursion to convergence), var y and var u (Söderström Sec. 11.4, Example 11.5)."""
    n = len(F)
    Z = np.zeros((n, n))
    if k == 1:
        A = np.block([[F - G @ L, G @ L], [Z, F - K_pred @ H]])
        Bn = np.block([[np.eye(n), np.zeros((n, len(R)))], [np.eye(n), -K_pred]])
        Cu, Du = np.hstack([-L, L]), np.zeros((len(L), len(R)))
    else:
        I = np.eye(n)
        A = np.block([[F - G @ L, G @ L @ (I - K @ H)], [Z, F - K_pred @ H]])
        Bn = np.block([[I, -G @ L @ K], [I, -K_pred]])
        Cu, Du = np.hstack([-L, L @ (I - K @ H)]), -L @ K
    W = np.block([[Q, np.zeros((n, len(R)))], [np.zeros((len(R), n)), R]])
    Pi = np.zeros((2 * n, 2 * n))
    for _ in range(20000):
        new = A @ Pi @ A.T + Bn @ W @ Bn.T
        if np.max(np.abs(new - Pi)) <= 1e-15 * max(1.0, np.abs(new).max()):
            Pi = new
            break
        Pi = new
    Cy = np.hstack([H, np.zeros((len(H), n))])
    var_y = Cy @ Pi @ Cy.T + R
    var_u = Cu @ Pi @ Cu.T + Du @ R @ Du.T
    return Pi, var_y, var_u
