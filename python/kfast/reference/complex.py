"""Complex-valued Kalman filtering in plain NumPy, independent of kfast's real composite form:
the strictly linear filter with Hermitian transposes for proper noise (Söderström Lemma 6.1 read
with ' as ^H) and the augmented (widely linear) filter for improper noise, on x_a = [x; x̄]
(Picinbono & Chevalier 1995; Schreier & Scharf 2010)."""

from __future__ import annotations

import numpy as np

__all__ = ["complex_kalman_filter", "augmented_kalman_filter", "complex_rts"]


def complex_kalman_filter(F, H, Q, R, y, x0, P0):
    """Proper noise: K = P H^H S^-1, P(t|t) = P - K S K^H, P(t+1|t) = F P F^H + Q; missing
    components (NaN) are left out; loglik_t = -[m_t log π + log det S + e^H S^-1 e]."""
    T = len(y)
    x, P = np.array(x0, complex), np.array(P0, complex)
    out = {k: [] for k in ("x_pred", "P_pred", "x_filt", "P_filt", "loglik_t")}
    for t in range(T):
        out["x_pred"].append(x.copy())
        out["P_pred"].append(P.copy())
        o = ~np.isnan(y[t])
        ll = 0.0
        if o.any():
            Ho, Ro = H[o], R[np.ix_(o, o)]
            e = y[t][o] - Ho @ x
            S = Ho @ P @ Ho.conj().T + Ro
            K = P @ Ho.conj().T @ np.linalg.inv(S)
            ll = -(o.sum() * np.log(np.pi) + np.log(np.linalg.det(S).real) + (e.conj() @ np.linalg.solve(S, e)).real)
            x, P = x + K @ e, P - K @ S @ K.conj().T
        out["x_filt"].append(x.copy())
        out["P_filt"].append(P.copy())
        out["loglik_t"].append(ll)
        x, P = F @ x, F @ P @ F.conj().T + Q
    res = {k: np.array(v) for k, v in out.items()}
    res["loglik"] = float(res["loglik_t"].sum())
    return res


def augmented_kalman_filter(F, H, Q, R, Qc, Rc, y, x0, P0, P0c):
    """Improper noise: the Kalman filter (with ^H) of x_a = [x; x̄] with F_a = diag(F, F̄),
    H_a = diag(H, H̄), Q_a = [[Q, Qc], [Q̄c, Q̄]], R_a likewise; x̂ = x̂_a[:n], P = P_a[:n, :n],
    P̃ = P_a[:n, n:]. loglik_t = -[m log π + ½ log det S_a + ½ e_a^H S_a^-1 e_a]: the real
    2m-dimensional density (det of the map [Re; Im] -> [z; z̄] is (2i)^m)."""
    n, m = len(x0), H.shape[0]

    def aug(M, C):
        return np.block([[M, C], [C.conj(), M.conj()]])

    Fa = np.block([[F, np.zeros((n, n))], [np.zeros((n, n)), F.conj()]])
    Ha = np.block([[H, np.zeros((m, n))], [np.zeros((m, n)), H.conj()]])
    Qa, Ra = aug(Q, Qc), aug(R, Rc)
    x, P = np.r_[x0, np.conj(x0)].astype(complex), aug(P0, P0c)
    out = {k: [] for k in ("x_filt", "P_filt", "P_filt_c", "loglik_t")}
    for t in range(len(y)):
        ya = np.r_[y[t], np.conj(y[t])]
        e = ya - Ha @ x
        S = Ha @ P @ Ha.conj().T + Ra
        K = P @ Ha.conj().T @ np.linalg.inv(S)
        out["loglik_t"].append(-(m * np.log(np.pi) + 0.5 * np.log(np.linalg.det(S).real) + 0.5 * (e.conj() @ np.linalg.solve(S, e)).real))
        x, P = x + K @ e, P - K @ S @ K.conj().T
        out["x_filt"].append(x[:n].copy())
        out["P_filt"].append(P[:n, :n].copy())
        out["P_filt_c"].append(P[:n, n:].copy())
        x, P = Fa @ x, Fa @ P @ Fa.conj().T + Qa
    res = {k: np.array(v) for k, v in out.items()}
    res["loglik"] = float(res["loglik_t"].sum())
    return res


def complex_rts(F, H, Q, R, y, x0, P0):
    """The RTS smoother with Hermitian transposes (proper noise)."""
    f = complex_kalman_filter(F, H, Q, R, y, x0, P0)
    T = len(y)
    xs, Ps = f["x_filt"].copy(), f["P_filt"].copy()
    for t in range(T - 2, -1, -1):
        P_next = F @ f["P_filt"][t] @ F.conj().T + Q
        J = f["P_filt"][t] @ F.conj().T @ np.linalg.inv(P_next)
        xs[t] = f["x_filt"][t] + J @ (xs[t + 1] - F @ f["x_filt"][t])
        Ps[t] = f["P_filt"][t] + J @ (Ps[t + 1] - P_next) @ J.conj().T
    return {"x_smooth": xs, "P_smooth": Ps}
