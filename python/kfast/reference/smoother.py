"""Smoothers in plain NumPy: the oracles for kfast's Rust smoothers.

- ``rts_smoother``: Rauch-Tung-Striebel over the reference filter (docs/algorithms.md, "RTS").
- ``map_smoother``: the MAP criterion of Söderström (6.80)-(6.83) solved as one linear system;
  its solution is x(t|T-1), and the inverse of its matrix (the posterior precision) holds
  P(t|T-1) on the diagonal blocks and the lag-one covariances next to them. An independent
  oracle: it shares no recursion with the filter.
- ``fixed_lag_augmented``: the filter on the augmented state [x(t); x(t-1); ...; x(t-L)]
  (Söderström (6.58)-(6.65)), the textbook fixed-lag smoother.

Conventions as in ``kfast.reference.filter``: prior (x0, P0) = x(0|-1), y includes y(0).
"""

from __future__ import annotations

import numpy as np

from kfast.reference.filter import _at, kalman_filter


def rts_smoother(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None, form="joseph"):
    """RTS smoother; returns (x_smooth, P_smooth, P_lag1, filter dict). P_lag1[t] is
    Cov(x[t], x[t-1] | all data), zero at t = 0."""
    f = kalman_filter(F, H, Q, R, y, x0, P0, B=B, D=D, N=N, u=u, form=form)
    T, n = f["x_filt"].shape
    xs, Ps, Pl = f["x_filt"].copy(), f["P_filt"].copy(), np.zeros((T, n, n))
    for t in range(T - 2, -1, -1):
        Ft = _at(F, t)
        Nt = _at(N, t) if N is not None else np.zeros((n, y.shape[1]))
        # J = (P(t|t) F' - K N') P(t+1|t)^-1: Cov(x~(t|t), x~(t+1|t)) P(t+1|t)^-1
        C = f["P_filt"][t] @ Ft.T - f["K"][t] @ Nt.T
        J = C @ np.linalg.pinv(f["P_pred"][t + 1])
        xs[t] = f["x_filt"][t] + J @ (xs[t + 1] - f["x_pred"][t + 1])
        Ps[t] = f["P_filt"][t] + J @ (Ps[t + 1] - f["P_pred"][t + 1]) @ J.T
        Pl[t + 1] = Ps[t + 1] @ J.T
    return xs, Ps, Pl, f


def map_smoother(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None):
    """Minimize V of Söderström (6.80) over the stacked x(0..T-1) (Söderström (6.81)-(6.83),
    docs/algorithms.md, "MAP smoother"), with y(0) included. Correlated noise is first removed by Lemma 6.4:
    x(t+1) = F̄ x(t) + B̄ u(t) + N R^-1 y(t) + w̄, F̄ = F - N R^-1 H, Q̄ = Q - N R^-1 N'
    (over the observed components). Needs P0, Q̄, R invertible. Returns (x, P, P_lag1)."""
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n = len(x0)
    dim = T * n
    A = np.zeros((dim, dim))  # posterior precision (block tridiagonal)
    b = np.zeros(dim)

    def add(rows_of_x, c, W):
        """Add the quadratic 1/2 (M x - c)' W (M x - c) with M given by blocks {t: block}."""
        M = np.zeros((len(c), dim))
        for t, block in rows_of_x.items():
            M[:, t * n : (t + 1) * n] += block
        A[:] += M.T @ W @ M
        b[:] += M.T @ W @ c

    add({0: np.eye(n)}, np.asarray(x0, float), np.linalg.inv(P0))
    for t in range(T):
        Ht, Rt, Ft, Qt = _at(H, t), _at(R, t), _at(F, t), _at(Q, t)
        Nt = _at(N, t) if N is not None else np.zeros((n, m))
        Bu = _at(B, t) @ u[t] if B is not None else np.zeros(n)
        Du = _at(D, t) @ u[t] if D is not None else np.zeros(m)
        o = ~np.isnan(y[t])
        Ho, Ro, No, yo = Ht[o], Rt[np.ix_(o, o)], Nt[:, o], y[t, o] - Du[o]
        if o.any():
            add({t: Ho}, yo, np.linalg.inv(Ro))
        if t + 1 < T:
            G = No @ np.linalg.inv(Ro) if o.any() else np.zeros((n, 0))
            Fbar, Qbar = Ft - G @ Ho, Qt - G @ No.T
            add({t + 1: np.eye(n), t: -Fbar}, Bu + G @ yo, np.linalg.inv(Qbar))
    x = np.linalg.solve(A, b).reshape(T, n)
    cov = np.linalg.inv(A)
    P = np.array([cov[t * n : (t + 1) * n, t * n : (t + 1) * n] for t in range(T)])
    P_lag1 = np.zeros((T, n, n))
    for t in range(1, T):
        P_lag1[t] = cov[t * n : (t + 1) * n, (t - 1) * n : t * n]
    return x, P, P_lag1


def fixed_lag_augmented(F, H, Q, R, y, x0, P0, lag, B=None, D=None, N=None, u=None):
    """x(s | min(s+lag, T-1)) and its covariance for every s, from the filter on the augmented
    state z(t) = [x(t); x(t-1); ...; x(t-lag)] (Söderström (6.58)-(6.65)). Pre-sample blocks
    start at zero with zero covariance ((6.76)-(6.79)); they are never read."""
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n, L = len(x0), lag
    na = (L + 1) * n

    def aug(t):
        Fa = np.zeros((na, na))
        Fa[:n, :n] = _at(F, t)
        Fa[n:, :-n] = np.eye(L * n)
        Qa = np.zeros((na, na))
        Qa[:n, :n] = _at(Q, t)
        Ha = np.zeros((m, na))
        Ha[:, :n] = _at(H, t)
        Na = np.zeros((na, m))
        if N is not None:
            Na[:n] = _at(N, t)
        Ba = None
        if B is not None:
            Ba = np.zeros((na, _at(B, t).shape[1]))
            Ba[:n] = _at(B, t)
        return Fa, Ha, Qa, Na, Ba

    mats = [aug(t) for t in range(T)]
    Fa, Ha, Qa, Na, Ba = (np.stack([mt[i] for mt in mats]) if mats[0][i] is not None else None for i in range(5))
    za0 = np.zeros(na)
    za0[:n] = x0
    Pa0 = np.zeros((na, na))
    Pa0[:n, :n] = P0
    Ra = np.stack([_at(R, t) for t in range(T)])
    Da = None if D is None else np.stack([_at(D, t) for t in range(T)])
    f = kalman_filter(Fa, Ha, Qa, Ra, y, za0, Pa0, B=Ba, D=Da, N=Na, u=u)
    xs, Ps = np.zeros((T, n)), np.zeros((T, n, n))
    for s in range(T):
        t = min(s + L, T - 1)
        i = t - s
        xs[s] = f["x_filt"][t][i * n : (i + 1) * n]
        Ps[s] = f["P_filt"][t][i * n : (i + 1) * n, i * n : (i + 1) * n]
    return xs, Ps


def fixed_point_augmented(F, H, Q, R, y, x0, P0, t_point, B=None, D=None, N=None, u=None):
    """x(s | t) and P(s | t) for s = t_point and t = s..T-1, from the filter on the augmented
    state z = [x(t); x_s] with x_s(t+1) = x_s(t) = x(s) (Söderström (6.45)): run the plain
    filter up to s, then augment with x_s equal to x(s) (prior covariance [[P, P], [P, P]])."""
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n, s = len(x0), t_point
    head = kalman_filter(
        F, H, Q, R, y[:s] if s else y[:1], x0, P0, B=B, D=D, N=N, u=None if u is None else u[: max(s, 1)]
    )
    x_s, P_s = (head["x_next"], head["P_next"]) if s else (np.asarray(x0, float), np.asarray(P0, float))

    Fa = np.stack([np.block([[_at(F, t), np.zeros((n, n))], [np.zeros((n, n)), np.eye(n)]]) for t in range(s, T)])
    Qa = np.stack([np.block([[_at(Q, t), np.zeros((n, n))], [np.zeros((n, n)), np.zeros((n, n))]]) for t in range(s, T)])
    Ha = np.stack([np.hstack([_at(H, t), np.zeros((m, n))]) for t in range(s, T)])
    Ra = np.stack([_at(R, t) for t in range(s, T)])
    Na = None if N is None else np.stack([np.vstack([_at(N, t), np.zeros((n, m))]) for t in range(s, T)])
    Ba = None if B is None else np.stack([np.vstack([_at(B, t), np.zeros((n, _at(B, t).shape[1]))]) for t in range(s, T)])
    Da = None if D is None else np.stack([_at(D, t) for t in range(s, T)])
    za = np.concatenate([x_s, x_s])
    Pa = np.block([[P_s, P_s], [P_s, P_s]])
    f = kalman_filter(Fa, Ha, Qa, Ra, y[s:], za, Pa, B=Ba, D=Da, N=Na, u=None if u is None else u[s:])
    return f["x_filt"][:, n:], f["P_filt"][:, n:, n:]
