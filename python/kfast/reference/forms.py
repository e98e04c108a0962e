"""The filter's robust update forms in plain NumPy: square-root (array), U-D, information and
sequential, each written from its textbook formulas and independent of the others.

Model and conventions as in :mod:`kfast.reference.filter`. A cross-covariance N is removed first
(Söderström Lemma 6.4): with G = N_o R_oo^-1 over the observed components,

    x(t+1|t) = (F - G H_o) x(t|t) + B u + G (y_o - D_o u),   Q - G N_o'

is the same filter with uncorrelated noises. Every function returns the dict of
``kalman_filter``; P, S and the gains are formed from the form's own quantities for the
comparison.
"""

from __future__ import annotations

import numpy as np

from kfast.reference.filter import _at

__all__ = [
    "square_root_filter",
    "ud_filter",
    "information_filter",
    "information_filter_diffuse",
    "sequential_filter",
    "ud_factor",
]


def _sqrt_psd(A):
    """A square root G with G G' = A for a symmetric positive semidefinite A (eigenvalues)."""
    w, V = np.linalg.eigh((A + A.T) / 2)
    return V * np.sqrt(np.clip(w, 0.0, None))


def _lower_sqrt(A):
    """A lower triangular square root of a PSD A: the LQ factor of any square root."""
    return np.linalg.qr(_sqrt_psd(A).T, mode="r").T


def _whiten(Ho, Ro, eo):
    """Rows, innovations and variances of independent scalar components, and -log det L: as
    given for a diagonal R, else L^-1 H, L^-1 e and ones (R = L L')."""
    if not np.count_nonzero(Ro - np.diag(np.diag(Ro))):
        return Ho, eo, np.diag(Ro), 0.0
    L = np.linalg.cholesky(Ro)
    return np.linalg.solve(L, Ho), np.linalg.solve(L, eo), np.ones(len(eo)), -np.sum(np.log(np.diag(L)))


def ud_factor(P):
    """P = U diag(d) U' with U unit upper triangular (Bierman (1977)), for P PSD."""
    n = len(P)
    U, d = np.eye(n), np.zeros(n)
    for j in range(n - 1, -1, -1):
        d[j] = P[j, j] - np.sum(d[j + 1:] * U[j, j + 1:] ** 2)
        if d[j] > 1e-14 * max(1.0, np.abs(np.diag(P)).max()):
            for i in range(j):
                U[i, j] = (P[i, j] - np.sum(d[j + 1:] * U[i, j + 1:] * U[j, j + 1:])) / d[j]
        else:
            d[j] = 0.0
    return U, d


def _run(F, H, Q, R, y, x0, P0, B, D, N, u, state):
    """The time loop shared by the forms: ``state`` has ``x()``, ``P()``, ``update(H, R, e, t)``
    (the observed rows; returns log-likelihood term) and ``predict(F, Q, shift)``."""
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n = len(x0)
    out = {k: np.zeros(s) for k, s in [("x_pred", (T, n)), ("P_pred", (T, n, n)), ("x_filt", (T, n)),
                                       ("P_filt", (T, n, n)), ("S", (T, m, m)), ("K", (T, n, m)),
                                       ("K_pred", (T, n, m)), ("loglik_t", (T,))]}
    out["innov"] = np.full((T, m), np.nan)
    for t in range(T):
        Ft, Ht, Qt, Rt = _at(F, t), _at(H, t), _at(Q, t), _at(R, t)
        Nt = _at(N, t) if N is not None else None
        Bu = _at(B, t) @ u[t] if B is not None else np.zeros(n)
        Du = _at(D, t) @ u[t] if D is not None else np.zeros(m)
        x, P = state.x(), state.P()
        out["x_pred"][t], out["P_pred"][t] = x, P
        e = y[t] - Ht @ x - Du
        out["innov"][t] = e
        out["S"][t] = Ht @ P @ Ht.T + Rt
        o = ~np.isnan(y[t])
        if o.any():
            Ho, Ro, eo = Ht[o], Rt[np.ix_(o, o)], e[o]
            S = Ho @ P @ Ho.T + Ro
            out["K"][t][:, o] = np.linalg.solve(S, Ho @ P).T
            No = Nt[:, o] if Nt is not None else np.zeros((n, o.sum()))
            out["K_pred"][t][:, o] = np.linalg.solve(S, (Ft @ P @ Ho.T + No).T).T
            out["loglik_t"][t] = state.update(Ho, Ro, eo, t)
        out["x_filt"][t], out["P_filt"][t] = state.x(), state.P()
        shift = Bu.copy()
        Fd, Qd = Ft, Qt
        if Nt is not None and o.any():
            G = np.linalg.solve(Rt[np.ix_(o, o)], Nt[:, o].T).T
            Fd, Qd = Ft - G @ Ht[o], Qt - G @ Nt[:, o].T
            shift = shift + G @ (y[t][o] - Du[o])
        state.predict(Fd, (Qd + Qd.T) / 2, shift)
    out["loglik"] = float(out["loglik_t"].sum())
    out["x_next"], out["P_next"] = state.x(), state.P()
    return out


class _SquareRoot:
    """P = S S', S lower triangular; updates by QR of the pre-arrays (Söderström Sec. 6.8.1)."""

    def __init__(self, x0, P0):
        self.xv, self.S = np.array(x0, float), _lower_sqrt(P0)

    def x(self):
        return self.xv.copy()

    def P(self):
        return self.S @ self.S.T

    def update(self, Ho, Ro, eo, t):
        n, mo = len(self.xv), len(eo)
        # [[R^1/2, H S], [0, S]] Θ = [[S_e^1/2, 0], [K̄, S+]]: the LQ of the pre-array.
        pre = np.zeros((mo + n, mo + n))
        pre[:mo, :mo] = _lower_sqrt(Ro)
        pre[:mo, mo:] = Ho @ self.S
        pre[mo:, mo:] = self.S
        post = np.linalg.qr(pre.T, mode="r").T  # lower triangular, pre = post Θ'
        Se, Kbar, self.S = post[:mo, :mo], post[mo:, :mo], post[mo:, mo:]
        w = np.linalg.solve(Se, eo)  # S_e^-1/2 e
        self.xv = self.xv + Kbar @ w
        return -0.5 * (mo * np.log(2 * np.pi) + 2 * np.sum(np.log(np.abs(np.diag(Se)))) + w @ w)

    def predict(self, F, Q, shift):
        self.xv = F @ self.xv + shift
        # [F S, Q^1/2] Θ = [S+, 0].
        self.S = np.linalg.qr(np.hstack([F @ self.S, _sqrt_psd(Q)]).T, mode="r").T


class _UD:
    """P = U D U'; Bierman's scalar measurement update, Thornton's MWGS time update."""

    def __init__(self, x0, P0):
        self.xv = np.array(x0, float)
        self.U, self.d = ud_factor(np.asarray(P0, float))

    def x(self):
        return self.xv.copy()

    def P(self):
        return self.U @ np.diag(self.d) @ self.U.T

    def update(self, Ho, Ro, eo, t):
        Z, E, var, ll = _whiten(Ho, Ro, eo)
        x0 = self.xv.copy()
        for z, e, r in zip(Z, E, var):
            v = e - z @ (self.xv - x0)
            f = self.U.T @ z
            g = self.d * f
            alpha = r
            for j in range(len(f)):
                beta = alpha
                alpha = alpha + f[j] * g[j]
                lam = -f[j] / beta if beta > 0 else 0.0
                self.d[j] = self.d[j] * beta / alpha if alpha > 0 else self.d[j]
                for i in range(j):
                    u_ij = self.U[i, j]
                    self.U[i, j] = u_ij + g[i] * lam
                    g[i] = g[i] + g[j] * u_ij
            self.xv = self.xv + g / alpha * v
            ll -= 0.5 * (np.log(2 * np.pi) + np.log(alpha) + v * v / alpha)
        return ll

    def predict(self, F, Q, shift):
        self.xv = F @ self.xv + shift
        Uq, dq = ud_factor(Q)
        W = np.hstack([F @ self.U, Uq])
        Dw = np.concatenate([self.d, dq])
        n = len(self.xv)
        U, d = np.eye(n), np.zeros(n)
        for k in range(n - 1, -1, -1):
            c = Dw * W[k]
            d[k] = W[k] @ c
            if d[k] > 0:
                for i in range(k):
                    U[i, k] = W[i] @ c / d[k]
                    W[i] = W[i] - U[i, k] * W[k]
        self.U, self.d = U, np.clip(d, 0.0, None)


class _Information:
    """Y = P^-1 and yv = Y x (Söderström Sec. 6.8.1; Anderson & Moore (1979) Sec. 6.3)."""

    def __init__(self, x0, P0):
        self.Y = np.linalg.inv(P0)
        self.yv = self.Y @ np.asarray(x0, float)

    def x(self):
        return np.linalg.solve(self.Y, self.yv)

    def P(self):
        return np.linalg.inv(self.Y)

    def update(self, Ho, Ro, eo, t):
        x_pred, Y_pred = self.x(), self.Y
        Ri = np.linalg.inv(Ro)
        self.Y = Y_pred + Ho.T @ Ri @ Ho
        self.yv = self.yv + Ho.T @ Ri @ (eo + Ho @ x_pred)  # H' R^-1 (y - D u)
        S = Ho @ np.linalg.inv(Y_pred) @ Ho.T + Ro
        return -0.5 * (len(eo) * np.log(2 * np.pi) + np.linalg.slogdet(S)[1] + eo @ np.linalg.solve(S, eo))

    def predict(self, F, Q, shift):
        # By the definition Y(t+1|t) = P(t+1|t)^-1 = (F Y^-1 F' + Q)^-1: the oracle for kfast's
        # recursion through F^-1 (whose M - M G C^-1 G' M cancels when Q dominates F P F').
        x = np.linalg.solve(self.Y, self.yv)
        P = F @ np.linalg.inv(self.Y) @ F.T + Q
        self.Y = np.linalg.inv((P + P.T) / 2)
        self.Y = (self.Y + self.Y.T) / 2
        self.yv = self.Y @ (F @ x + shift)


class _Sequential:
    """P updated one whitened scalar component at a time (Söderström Sec. 6.8.1)."""

    def __init__(self, x0, P0):
        self.xv, self.Pm = np.array(x0, float), np.array(P0, float)

    def x(self):
        return self.xv.copy()

    def P(self):
        return self.Pm.copy()

    def update(self, Ho, Ro, eo, t):
        Z, E, var, ll = _whiten(Ho, Ro, eo)
        x0 = self.xv.copy()
        for z, e, r in zip(Z, E, var):
            v = e - z @ (self.xv - x0)
            c = self.Pm @ z
            f = z @ c + r
            self.xv = self.xv + c * v / f
            self.Pm = self.Pm - np.outer(c, c) / f
            ll -= 0.5 * (np.log(2 * np.pi) + np.log(f) + v * v / f)
        return ll

    def predict(self, F, Q, shift):
        self.xv = F @ self.xv + shift
        P = F @ self.Pm @ F.T + Q
        self.Pm = (P + P.T) / 2


def _filter(cls, F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None):
    return _run(F, H, Q, R, y, x0, P0, B, D, N, u, cls(x0, np.asarray(P0, float)))


def square_root_filter(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None):
    """The square-root (array) filter by QR of the pre-arrays; returns ``kalman_filter``'s dict."""
    return _filter(_SquareRoot, F, H, Q, R, y, x0, P0, B, D, N, u)


def ud_filter(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None):
    """The U-D filter (Bierman's update, Thornton's time update); ``kalman_filter``'s dict."""
    return _filter(_UD, F, H, Q, R, y, x0, P0, B, D, N, u)


def information_filter(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None):
    """The information filter (needs P0, R and F invertible); ``kalman_filter``'s dict."""
    return _filter(_Information, F, H, Q, R, y, x0, P0, B, D, N, u)


def sequential_filter(F, H, Q, R, y, x0, P0, B=None, D=None, N=None, u=None):
    """Scalar processing of independent (or whitened) components; ``kalman_filter``'s dict."""
    return _filter(_Sequential, F, H, Q, R, y, x0, P0, B, D, N, u)


def _pinv_quad(Y, v):
    """v' Y^+ v for a symmetric PSD Y and v in its range."""
    return float(v @ np.linalg.lstsq(Y, v, rcond=1e-12)[0])


def information_filter_diffuse(F, H, Q, R, y, x0, P0, P0_inf, B=None, D=None, u=None, tol=1e-9):
    """The information filter started at Y0 = lim (P0 + k P0_inf)^-1, k -> oo: Y0 = Z (Z' P0 Z)^-1 Z'
    with Z a basis of the null space of P0_inf (Y0 = 0 when P0_inf is nonsingular: P0^-1 = 0), and
    yv0 = Y0 x0. Both recursions are continuous in Y, so they run unchanged from the singular Y0:
    the measurement adds H' R^-1 H and H' R^-1 (y - D u), the time update is

        M = A' Y A,  C = G' M G + I,  Y+ = M - M G C^-1 G' M,  yv+ = (I - M G C^-1 G') A' yv + Y+ B u

    with A = F^-1 and G G' = Q (Anderson & Moore (1979) Sec. 6.3). No N.

    Returns x_filt, P_filt, x_pred, P_pred (NaN at the steps where Y is singular: the state is not
    yet identified), ``identified`` (Y(t|t) positive definite) and the diffuse log-likelihood of
    Durbin & Koopman (2012) Sec. 7.2.2, lim (log L + (q/2) log k), from information quantities:
    the terms of e' S^-1 e by y' R^-1 y + yv_pred' Y_pred^+ yv_pred - yv_filt' Y_filt^+ yv_filt (each
    a limit: yv stays in the range of Y), and the log det S terms telescoped,

        sum log det S = sum log det R + log det Y(T-1|T-1) - log det Y0(k) + sum (2 log|det F| + log det C),

    where -log det Y0(k) = q log k + log pdet(P0_inf) + log det(Z' P0 Z) + o(1). Needs Y(T-1|T-1)
    nonsingular (every diffuse direction identified by the end), F invertible and R positive definite.
    """
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n = len(x0)
    P0, P_inf = np.asarray(P0, float), np.asarray(P0_inf, float)
    w, V = np.linalg.eigh(P_inf)
    diffuse = w > tol * max(1.0, w.max(initial=0.0))
    Z = V[:, ~diffuse]
    Y = Z @ np.linalg.inv(Z.T @ P0 @ Z) @ Z.T if Z.shape[1] else np.zeros((n, n))
    yv = Y @ np.asarray(x0, float)
    log_det_terms = np.sum(np.log(w[diffuse])) + np.linalg.slogdet(Z.T @ P0 @ Z)[1]
    quad_and_const = 0.0
    nan = np.full((T, n), np.nan)
    out = {"x_pred": nan.copy(), "x_filt": nan.copy(), "P_pred": np.full((T, n, n), np.nan),
           "P_filt": np.full((T, n, n), np.nan), "identified": np.zeros(T, bool)}

    def definite(Y):
        ev = np.linalg.eigvalsh(Y)
        return ev[0] > tol * max(1.0, ev[-1])

    for t in range(T):
        Ft, Ht, Qt, Rt = _at(F, t), _at(H, t), _at(Q, t), _at(R, t)
        Bu = _at(B, t) @ u[t] if B is not None else np.zeros(n)
        Du = _at(D, t) @ u[t] if D is not None else np.zeros(m)
        if definite(Y):
            out["P_pred"][t] = np.linalg.inv(Y)
            out["x_pred"][t] = out["P_pred"][t] @ yv
        o = ~np.isnan(y[t])
        if o.any():
            Ho, Ro, yo = Ht[o], Rt[np.ix_(o, o)], (y[t] - Du)[o]
            Ri = np.linalg.inv(Ro)
            before = _pinv_quad(Y, yv)
            Y = Y + Ho.T @ Ri @ Ho
            yv = yv + Ho.T @ Ri @ yo
            quad = yo @ Ri @ yo + before - _pinv_quad(Y, yv)
            quad_and_const += o.sum() * np.log(2 * np.pi) + np.linalg.slogdet(Ro)[1] + quad
        if definite(Y):
            out["identified"][t] = True
            out["P_filt"][t] = np.linalg.inv(Y)
            out["x_filt"][t] = out["P_filt"][t] @ yv
        if t == T - 1:
            break
        A = np.linalg.inv(Ft)
        G = _sqrt_psd(Qt)
        M = A.T @ Y @ A
        C = G.T @ M @ G + np.eye(G.shape[1])
        MGC = np.linalg.solve(C, G.T @ M).T
        Y = M - MGC @ G.T @ M
        Y = (Y + Y.T) / 2
        yv = A.T @ yv - MGC @ (G.T @ (A.T @ yv)) + Y @ Bu
        log_det_terms += 2 * np.log(abs(np.linalg.det(Ft))) + np.linalg.slogdet(C)[1]
    if not definite(Y):
        raise ValueError("a diffuse direction is still unidentified at the last step")
    log_det_terms += np.linalg.slogdet(Y)[1]
    out["loglik"] = -0.5 * (quad_and_const + log_det_terms)
    return out
