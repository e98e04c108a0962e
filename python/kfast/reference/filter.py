"""The Kalman filter in plain NumPy, as Söderström writes it (Lemma 6.1, (6.22)-(6.27)).

Model (kfast notation; Söderström's R1, R2, R12 are our Q, R, N)::

    x[t+1] = F x[t] + B u[t] + w[t]        cov w = Q
    y[t]   = H x[t] + D u[t] + v[t]        cov v = R,   E[w[t] v[t]'] = N

The prior (x0, P0) is x(0|-1), P(0|-1), so each step is: measurement update, then time update.
Missing values (NaN) in y: the update uses the observed components only.
"""

from __future__ import annotations

import numpy as np


def _at(M, t):
    """The matrix in force at step t: M itself, or M[t] for a per-step stack."""
    if M is None:
        return None
    M = np.asarray(M, dtype=float)
    return M[t] if M.ndim == 3 else M


def kalman_filter(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None, form="joseph"):
    """Run the filter; returns a dict with the fields of ``kfast.FilterResult``."""
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n = len(x0)
    out = {
        "x_pred": np.zeros((T, n)),
        "P_pred": np.zeros((T, n, n)),
        "x_filt": np.zeros((T, n)),
        "P_filt": np.zeros((T, n, n)),
        "innov": np.full((T, m), np.nan),
        "S": np.zeros((T, m, m)),
        "K": np.zeros((T, n, m)),
        "K_pred": np.zeros((T, n, m)),
        "loglik_t": np.zeros(T),
    }
    x = np.asarray(x0, dtype=float).copy()  # x(t|t-1)
    P = np.asarray(P0, dtype=float).copy()  # P(t|t-1)
    for t in range(T):
        Ft, Ht, Qt, Rt = _at(F, t), _at(H, t), _at(Q, t), _at(R, t)
        Nt = _at(N, t) if N is not None else np.zeros((n, m))
        Bu = _at(B, t) @ u[t] if B is not None else np.zeros(n)
        Du = _at(D, t) @ u[t] if D is not None else np.zeros(m)
        out["x_pred"][t], out["P_pred"][t] = x, P

        # Innovation e(t) = y(t) - H x(t|t-1) - D u(t) and S(t) = H P H' + R  (6.24)
        e = y[t] - Ht @ x - Du
        out["innov"][t] = e
        out["S"][t] = Ht @ P @ Ht.T + Rt
        o = ~np.isnan(y[t])  # observed components
        if o.any():
            Ho, Ro, No, eo = Ht[o], Rt[np.ix_(o, o)], Nt[:, o], e[o]
            S = Ho @ P @ Ho.T + Ro
            K = P @ Ho.T @ np.linalg.inv(S)  # filter gain
            x_filt = x + K @ eo
            if form == "joseph":
                A = np.eye(n) - K @ Ho
                P_filt = A @ P @ A.T + K @ Ro @ K.T
            else:
                P_filt = P - K @ S @ K.T
            # predictor gain K_pred = (F P H' + N) S^-1   (6.25)
            K_pred = (Ft @ P @ Ho.T + No) @ np.linalg.inv(S)
            _, logdet = np.linalg.slogdet(S)
            out["loglik_t"][t] = -0.5 * (o.sum() * np.log(2 * np.pi) + logdet + eo @ np.linalg.solve(S, eo))
            out["K"][t][:, o] = K
            out["K_pred"][t][:, o] = K_pred
            # x(t+1|t) = F x(t|t-1) + B u(t) + K_pred e(t)                  (6.23)
            # P(t+1|t) = F P F' + Q - K_pred S K_pred'                        (6.26), (6.18)
            x_next = Ft @ x + Bu + K_pred @ eo
            P_next = Ft @ P @ Ft.T + Qt - K_pred @ S @ K_pred.T
        else:
            x_filt, P_filt = x, P
            x_next = Ft @ x + Bu
            P_next = Ft @ P @ Ft.T + Qt
        out["x_filt"][t], out["P_filt"][t] = x_filt, (P_filt + P_filt.T) / 2
        x, P = x_next, (P_next + P_next.T) / 2
    out["loglik"] = float(out["loglik_t"].sum())
    out["x_next"], out["P_next"] = x, P
    return out
