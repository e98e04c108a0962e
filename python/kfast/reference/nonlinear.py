"""Nonlinear Gaussian filters and smoothers in plain NumPy: the oracles for kfast's nonlinear family.

Model (kfast notation; Söderström ch. 9 writes R1, R2 for Q, R)::

    x[t+1] = f(x[t], t, u[t]) + g(x[t], t, u[t]) w[t]   cov w = Q  (g defaults to I)
    y[t]   = h(x[t], t, u[t]) + v[t]              cov v = R

The prior (x0, P0) is x(0|-1), P(0|-1): each step is a measurement update, then a time update.
``f`` and ``h`` are *batched* callables, as kfast takes them: ``f(X, t, u)`` maps the points X of
shape (k, n) to (k, n), ``h(X, t, u)`` to (k, m); ``u`` is u[t] or None. Jacobians are batched the
same way: ``jac_f(X, t, u)`` -> (k, n, n), ``jac_h`` -> (k, m, n); Hessians ``hess_f`` ->
(k, n, n, n) (one n x n Hessian per output component), ``hess_h`` -> (k, m, n, n). ``g(X, t, u)``
-> (k, n, r) for Q of size r x r, evaluated at x(t|t). With ``noise_input=True`` the noise is an
input of f instead, x[t+1] = f(x[t], w[t], t, u[t]): ``f(X, W, t, u)`` with W (k, r), ``jac_f``
-> (k, n, n + r) (in x, then w), ``hess_f`` -> (k, n, n + r, n + r). Missing values (NaN) in y: the update uses
the observed components only; a step with nothing observed skips it. ``angles`` lists the components of y
that are angles: their innovations (and sigma-point deviations) are wrapped to [-pi, pi).

Every function returns a dict with the fields of ``kfast.FilterResult`` (x_pred, P_pred, x_filt,
P_filt, innov, S, K, loglik_t, loglik, x_next, P_next); the UKF adds ``D`` (the cross-covariance
of x(t|t) and x(t+1|t), for the unscented smoother).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SigmaPoints",
    "merwe",
    "julier",
    "cubature",
    "jacobian_by_differences",
    "hessian_by_differences",
    "psd_cholesky",
    "ekf",
    "ukf",
    "extended_rts",
    "unscented_rts",
    "wrap",
]


def wrap(a):
    """a - 2 pi floor((a + pi) / 2 pi), in [-pi, pi)."""
    return a - 2 * np.pi * np.floor((a + np.pi) / (2 * np.pi))


def _at(M, t):
    M = np.asarray(M, dtype=float)
    return M[t] if M.ndim == 3 else M


def _one(fn, x, t, u):
    """fn at one point, through the batched interface."""
    return np.asarray(fn(x[None, :], t, u), dtype=float)[0]


def _noise_cov(g, Q, x, n, t, u):
    """G Q G' with G = g(x, t, u) (I without g), the gain at x(t|t)."""
    if g is None:
        return Q
    G = np.asarray(g(x[None, :], t, u), dtype=float)[0].reshape(n, -1)
    return G @ Q @ G.T


def _augmented(f, n):
    """f(X, W, t, u) as a function of the augmented points Z = (X, W), shape (k, n + r)."""
    return None if f is None else (lambda Z, t, u: f(Z[:, :n], Z[:, n:], t, u))


def _block_diag(P, Q):
    n, r = len(P), len(Q)
    A = np.zeros((n + r, n + r))
    A[:n, :n], A[n:, n:] = P, Q
    return A


def psd_cholesky(A):
    """The lower factor L (L L' = A) of a positive semidefinite A; a pivot at rounding level
    (<= n eps max A_ii) leaves its column zero, so a singular A (even 0) has one."""
    A = np.asarray(A, dtype=float)
    n = len(A)
    tol = n * np.finfo(float).eps * max(np.max(np.diag(A)), 0.0)
    L = np.zeros_like(A)
    for j in range(n):
        d = A[j, j] - L[j, :j] @ L[j, :j]
        if d <= tol:
            continue
        L[j, j] = np.sqrt(d)
        L[j + 1 :, j] = (A[j + 1 :, j] - L[j + 1 :, :j] @ L[j, :j]) / L[j, j]
    return L


# ----------------------------------------------------------------------------------------------
# Differences (central; the steps of the algorithm notes: eps^(1/3) and eps^(1/4) times max(|x_j|, 1))
# ----------------------------------------------------------------------------------------------


def jacobian_by_differences(fn, x, t, u, wrapped=()):
    """d fn / dx at x by central differences, all 2n points in one batched call. Components in
    ``wrapped`` are angles: their differences are wrapped."""
    n = len(x)
    step = np.cbrt(np.finfo(float).eps) * np.maximum(np.abs(x), 1.0)
    X = np.concatenate([x + np.diag(step), x - np.diag(step)])
    Z = np.asarray(fn(X, t, u), dtype=float)
    diff = Z[:n] - Z[n:]
    for k in wrapped:
        diff[:, k] = wrap(diff[:, k])
    taken = np.diag(X[:n]) - np.diag(X[n:])  # the steps actually taken (x +- step rounds)
    return (diff / taken[:, None]).T


def hessian_by_differences(fn, x, t, u):
    """The Hessian of every component of fn at x, shape (out, n, n), by second central
    differences (one batched call)."""
    n = len(x)
    step = np.finfo(float).eps ** 0.25 * np.maximum(np.abs(x), 1.0)
    E = np.diag(step)
    points = [x]
    for i in range(n):
        points += [x + E[i], x - E[i]]
    for i in range(n):
        for j in range(i + 1, n):
            points += [x + E[i] + E[j], x + E[i] - E[j], x - E[i] + E[j], x - E[i] - E[j]]
    Z = np.asarray(fn(np.array(points), t, u), dtype=float)
    z0, k = Z[0], 1
    Hs = np.zeros((Z.shape[1], n, n))
    for i in range(n):
        Hs[:, i, i] = (Z[k] - 2 * z0 + Z[k + 1]) / step[i] ** 2
        k += 2
    for i in range(n):
        for j in range(i + 1, n):
            Hs[:, i, j] = Hs[:, j, i] = (Z[k] - Z[k + 1] - Z[k + 2] + Z[k + 3]) / (4 * step[i] * step[j])
            k += 4
    return Hs


# ----------------------------------------------------------------------------------------------
# The measurement update shared by every Gaussian filter (Söderström Lemma 6.1)
# ----------------------------------------------------------------------------------------------


def _update(x, P, e, C, S, joseph_HR=None):
    """x(t|t), P(t|t), K and the log-likelihood term from the innovation e, C = Cov(x, y) and
    S = Cov(y). ``joseph_HR = (H, R)`` gives the Joseph form (I-KH) P (I-KH)' + K R K'."""
    K = np.linalg.solve(S, C.T).T
    x_filt = x + K @ e
    if joseph_HR is None:
        P_filt = P - K @ S @ K.T
    else:
        H, R = joseph_HR
        A = np.eye(len(x)) - K @ H
        P_filt = A @ P @ A.T + K @ R @ K.T
    _, logdet = np.linalg.slogdet(S)
    loglik = -0.5 * (len(e) * np.log(2 * np.pi) + logdet + e @ np.linalg.solve(S, e))
    return x_filt, (P_filt + P_filt.T) / 2, K, loglik


def _outputs(T, n, m):
    return {
        "x_pred": np.zeros((T, n)),
        "P_pred": np.zeros((T, n, n)),
        "x_filt": np.zeros((T, n)),
        "P_filt": np.zeros((T, n, n)),
        "innov": np.full((T, m), np.nan),
        "S": np.zeros((T, m, m)),
        "K": np.zeros((T, n, m)),
        "loglik_t": np.zeros(T),
    }


def _wrap_components(e, angles, observed=None):
    e = e.copy()
    for k in angles:
        if observed is None or observed[k]:
            idx = k if observed is None else int(np.sum(observed[:k]))
            e[..., idx] = wrap(e[..., idx])
    return e


# ----------------------------------------------------------------------------------------------
# Extended Kalman filter: EKF, iterated (book and Gauss-Newton), second order
# ----------------------------------------------------------------------------------------------


def ekf(
    f,
    h,
    Q,
    R,
    y,
    x0,
    P0,
    jac_f=None,
    jac_h=None,
    u=None,
    g=None,
    iterations=0,
    iteration="book",
    order=1,
    hess_f=None,
    hess_h=None,
    angles=(),
    form="joseph",
    noise_input=False,
):
    """The extended Kalman filter (Söderström (9.2)-(9.11)): h linearised at x(t|t-1), f at x(t|t).

    With ``noise_input``, f(x, w) is linearised in both at (x(t|t), 0): P(t+1|t) = J diag(P, Q) J'
    with J = [df/dx, df/dw] (= F P F' + L Q L'); the second-order correction takes the trace
    over diag(P, Q).

    ``iterations=k`` relinearises the update k times: ``iteration="book"`` moves only the gain,
    the innovation staying y - h(x(t|t-1)) ((9.12)-(9.17)); ``"gauss-newton"`` is Gauss-Newton
    on the MAP criterion (Bell & Cathey 1993), its innovation y - h(x_i) - H_i (x(t|t-1) - x_i).
    ``order=2`` adds the second-order mean corrections h_bar_k = 1/2 tr(P(t|t-1) hess h_k) and
    f_bar_k = 1/2 tr(P(t|t) hess f_k) ((9.21)-(9.26)); the covariances stay the EKF's.
    Jacobians and Hessians not given are central differences.
    """
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n = len(x0)
    out = _outputs(T, n, m)
    x = np.asarray(x0, dtype=float).copy()
    P = np.asarray(P0, dtype=float).copy()

    def jac(fn, J, xp, t, ut, wrapped=()):
        return _one(J, xp, t, ut) if J is not None else jacobian_by_differences(fn, xp, t, ut, wrapped)

    def hess(fn, Hs, xp, t, ut):
        return _one(Hs, xp, t, ut) if Hs is not None else hessian_by_differences(fn, xp, t, ut)

    for t in range(T):
        ut = None if u is None else np.asarray(u[t], dtype=float)
        Rt = _at(R, t)
        out["x_pred"][t], out["P_pred"][t] = x, P
        H = jac(h, jac_h, x, t, ut, angles)
        y_hat = _one(h, x, t, ut)
        if order == 2:
            # h_bar_k = 1/2 tr(P(t|t-1) hess h_k)                                   (9.23)
            y_hat = y_hat + 0.5 * np.einsum("ij,kji->k", P, hess(h, hess_h, x, t, ut))
        e_full = _wrap_components(y[t] - y_hat, angles)
        out["innov"][t] = e_full
        out["S"][t] = H @ P @ H.T + Rt
        o = ~np.isnan(y[t])
        if o.any():
            Ho, Ro, eo = H[o], Rt[np.ix_(o, o)], e_full[o]
            joseph = form == "joseph"
            S = Ho @ P @ Ho.T + Ro
            x_filt, P_filt, K, ll = _update(x, P, eo, P @ Ho.T, S, (Ho, Ro) if joseph else None)
            if iterations:
                x_i = x_filt
                for _ in range(iterations):
                    # relinearise h at the last estimate x_i
                    H = jac(h, jac_h, x_i, t, ut, angles)
                    Ho = H[o]
                    if iteration == "book":
                        r = eo  # (9.13): the innovation stays at the prediction
                    elif iteration == "gauss-newton":
                        r = _wrap_components((y[t] - _one(h, x_i, t, ut))[o], angles, o) - Ho @ (x - x_i)
                    else:
                        raise ValueError(f"iteration: {iteration!r}")
                    x_i = x + P @ Ho.T @ np.linalg.solve(Ho @ P @ Ho.T + Ro, r)  # (9.12)-(9.13)
                if iteration == "gauss-newton":
                    H = jac(h, jac_h, x_i, t, ut, angles)  # the covariance at the estimate
                    Ho = H[o]
                # (9.16)-(9.17): P(t|t) from the last linearisation; S, K reported from it too
                S = Ho @ P @ Ho.T + Ro
                _, P_filt, K, ll = _update(x, P, eo, P @ Ho.T, S, (Ho, Ro) if joseph else None)
                x_filt = x_i
                out["S"][t] = H @ P @ H.T + Rt  # all components, from the last linearisation
            out["S"][t][np.ix_(o, o)] = S
            out["K"][t][:, o] = K
            out["loglik_t"][t] = ll
        else:
            x_filt, P_filt = x, P
        out["x_filt"][t], out["P_filt"][t] = x_filt, P_filt
        # time update (9.10): f and G at x(t|t)
        if noise_input:  # f(x, w) at (x(t|t), 0) with diag(P(t|t), Q)
            Qt = _at(Q, t)
            fa, point, cov = _augmented(f, n), np.concatenate([x_filt, np.zeros(len(Qt))]), _block_diag(P_filt, Qt)
            J = jac(fa, _augmented(jac_f, n), point, t, ut)
            x = _one(fa, point, t, ut)
            if order == 2:
                x = x + 0.5 * np.einsum("ij,kji->k", cov, hess(fa, _augmented(hess_f, n), point, t, ut))
            P = J @ cov @ J.T
        else:
            F = jac(f, jac_f, x_filt, t, ut)
            x = _one(f, x_filt, t, ut)
            if order == 2:
                # f_bar_k = 1/2 tr(P(t|t) hess f_k), with P(t|t) already computed          (9.22)
                x = x + 0.5 * np.einsum("ij,kji->k", P_filt, hess(f, hess_f, x_filt, t, ut))
            P = F @ P_filt @ F.T + _noise_cov(g, _at(Q, t), x_filt, n, t, ut)
        P = (P + P.T) / 2
    out["loglik"] = float(out["loglik_t"].sum())
    out["x_next"], out["P_next"] = x, P
    return out


# ----------------------------------------------------------------------------------------------
# Sigma points and the unscented Kalman filter
# ----------------------------------------------------------------------------------------------


class SigmaPoints:
    """A sigma-point set for dimension-free use: ``scale`` c and weights as functions of n.

    Points of (x, P): [x, x + c a_1, ..., x + c a_n, x - c a_1, ..., x - c a_n] with a_i the
    columns of the lower Cholesky factor of P (without the first point when ``centre`` is False).
    """

    def __init__(self, kind, alpha=1.0, beta=0.0, kappa=0.0):
        self.kind, self.alpha, self.beta, self.kappa = kind, alpha, beta, kappa

    def weights(self, n):
        """(c, Wm, Wc) for state dimension n."""
        if self.kind == "merwe":
            lam = self.alpha**2 * (n + self.kappa) - n
            Wm = np.full(2 * n + 1, 1 / (2 * (n + lam)))
            Wc = Wm.copy()
            Wm[0] = lam / (n + lam)
            Wc[0] = Wm[0] + 1 - self.alpha**2 + self.beta
            return np.sqrt(n + lam), Wm, Wc
        if self.kind == "julier":
            W = np.full(2 * n + 1, 1 / (2 * (n + self.kappa)))
            W[0] = self.kappa / (n + self.kappa)
            return np.sqrt(n + self.kappa), W, W.copy()
        W = np.full(2 * n, 1 / (2 * n))  # cubature: no centre point
        return np.sqrt(n), W, W.copy()

    def points(self, x, P):
        return self.points_of_factor(x, np.linalg.cholesky(P))

    def points_of_factor(self, x, L):
        """The points of (x, L L') for a lower factor L."""
        c, Wm, _ = self.weights(len(x))
        A = c * L.T  # rows: the scaled columns of the lower factor
        spread = np.concatenate([x + A, x - A])
        return spread if len(Wm) == 2 * len(x) else np.concatenate([x[None, :], spread])


def merwe(alpha=1e-3, beta=2.0, kappa=0.0):
    """Scaled sigma points (Julier 2002; Wan & van der Merwe 2000): lambda = alpha^2 (n + kappa) - n."""
    return SigmaPoints("merwe", alpha, beta, kappa)


def julier(kappa=0.0):
    """Julier & Uhlmann (1997): c = sqrt(n + kappa), W_0 = kappa / (n + kappa)."""
    return SigmaPoints("julier", kappa=kappa)


def cubature():
    """Third-degree spherical-radial cubature (Arasaratnam & Haykin 2009): 2n points, weights 1/2n."""
    return SigmaPoints("cubature")


class CustomPoints:
    """A user's set: unit points xi (k x n) placed at x + L xi_i, weights Wm, Wc; no centre."""

    centred = False

    def __init__(self, unit, Wm, Wc=None):
        self.unit, self.Wm = np.asarray(unit, dtype=float), np.asarray(Wm, dtype=float)
        self.Wc = self.Wm if Wc is None else np.asarray(Wc, dtype=float)

    def weights(self, n):
        return 1.0, self.Wm, self.Wc

    def points(self, x, P):
        return self.points_of_factor(x, np.linalg.cholesky(P))

    def points_of_factor(self, x, L):
        return x + self.unit @ L.T


def _unscented_moments(X, Z, Wm, Wc, angles=(), centred=None):
    """The unscented transform of the points X -> Z: the mean of Z, Cov(Z) and Cov(X, Z).

    Sets with a centre point (len(Wm) odd) use the centred form: with D_i = Z_i - Z_0,
    E_i = X_i - X_0 (i >= 1), d = sum W_i D_i, e = sum W_i E_i and delta = Wc_0 - Wm_0,
    mean = Z_0 + d, Cov(Z) = sum W_i D_i D_i' + (delta - 1) d d',
    Cov(X, Z) = sum W_i E_i D_i' + (delta - 1) e d' -- the plain sums rearranged exactly, but
    every weight left is positive, so a small alpha (W_0 ~ -1e6) does not cancel digits away.
    Angular components of Z are differenced to the centre (wrapped), so their mean is the
    circular mean about it. Without a centre, the plain sums (angles relative to the first point).
    """
    if centred is None:
        centred = len(Wm) % 2 == 1
    if not centred:  # no centre point (or a custom set): the plain sums
        Z = Z.copy()
        for k in angles:
            Z[:, k] = Z[0, k] + wrap(Z[:, k] - Z[0, k])
        z = Wm @ Z
        dZ = _wrap_components(Z - z, angles)
        dX = X - Wm @ X
        return z, (Wc * dZ.T) @ dZ, (Wc * dX.T) @ dZ
    W = Wm[1:]
    D = _wrap_components(Z[1:] - Z[0], angles)
    E = X[1:] - X[0]
    d, e = W @ D, W @ E
    delta = Wc[0] - Wm[0]
    cov = (W * D.T) @ D + (delta - 1) * np.outer(d, d)
    cross = (W * E.T) @ D + (delta - 1) * np.outer(e, d)
    return Z[0] + d, cov, cross


def tria(A):
    """The lower-triangular L with non-negative diagonal and L L' = A A' (A of shape (n, c),
    c >= n), from the QR decomposition of A'."""
    L = np.linalg.qr(A.T, mode="r").T[:, : len(A)]
    return L * np.where(np.diag(L) < 0, -1.0, 1.0)


def cholesky_downdate(L, x):
    """The lower factor of L L' - x x' (a hyperbolic rotation per pivot); raises if the
    difference is not positive definite."""
    L, x = L.copy(), np.asarray(x, dtype=float).copy()
    for j in range(len(x)):
        if x[j] == 0:
            continue
        r2 = L[j, j] ** 2 - x[j] ** 2
        if not r2 > 0:
            raise np.linalg.LinAlgError(f"downdate: pivot {j} lost")
        r = np.sqrt(r2)
        c, s = r / L[j, j], x[j] / L[j, j]
        L[j, j] = r
        L[j + 1 :, j] = (L[j + 1 :, j] - s * x[j + 1 :]) / c
        x[j + 1 :] = c * x[j + 1 :] - s * L[j + 1 :, j]
    return L


def _sqrt_covariance(Z, Wm, Wc, centred, extra=None):
    """The lower factor of the unscented covariance of the points Z (plus extra @ extra'): QR of
    the positively weighted deviations of _unscented_moments' sums, a downdate for each
    negative weight."""
    if centred:
        W = Wm[1:]
        D = Z[1:] - Z[0]
        d = W @ D
        terms = list(zip(W, D)) + [(Wc[0] - Wm[0] - 1, d)]
    else:
        terms = list(zip(Wc, Z - Wm @ Z))
    cols = [np.sqrt(w) * v for w, v in terms if w > 0]
    if extra is not None:
        cols += list(extra.T)
    L = tria(np.array(cols).T)
    for w, v in terms:
        if w < 0:
            L = cholesky_downdate(L, np.sqrt(-w) * v)
    return L


def ukf(f, h, Q, R, y, x0, P0, points=None, u=None, g=None, angles=(), noise_input=False, form="standard"):
    """The unscented Kalman filter (Julier & Uhlmann 1997; Wan & van der Merwe 2000).

    Update at t from points of (x(t|t-1), P(t|t-1)) (redrawn after the time update, as filterpy
    2.0 and Särkkä 2013 do); time update from points of (x(t|t), P(t|t)). P(t|t) = P - K S K'.
    With ``noise_input`` the time update's points are those of the augmented (x(t|t), 0),
    diag(P(t|t), Q) -- factor diag(chol P, psd_cholesky Q), weights of dimension n + r -- through
    f(x, w), and no Q is added.

    ``form="sqrt"``: the square-root UKF (van der Merwe & Wan 2001). The lower factors L of
    P(t|t-1) and P(t|t) are carried (L(0|-1) = psd_cholesky(P0)) and the points placed from
    them; P(t+1|t)'s factor is tria of the weighted deviations (and Q's factor), with downdates
    for negative weights; P(t|t)'s is L(t|t-1) downdated by the columns of C chol(S)'^-1.
    """
    points = points or merwe()
    y = np.asarray(y, dtype=float)
    T, m = y.shape
    n = len(x0)
    _, Wm, Wc = points.weights(n)
    out = _outputs(T, n, m)
    out["D"] = np.zeros((T, n, n))
    x = np.asarray(x0, dtype=float).copy()
    P = np.asarray(P0, dtype=float).copy()
    sqrt = form == "sqrt"
    L = psd_cholesky(P) if sqrt else None
    centred = getattr(points, "centred", None)
    centred = len(Wm) % 2 == 1 if centred is None else centred
    for t in range(T):
        ut = None if u is None else np.asarray(u[t], dtype=float)
        Rt = _at(R, t)
        out["x_pred"][t], out["P_pred"][t] = x, P
        X = points.points_of_factor(x, L) if sqrt else points.points(x, P)
        Y = np.asarray(h(X, t, ut), dtype=float)
        y_hat, S_full, C_full = _unscented_moments(X, Y, Wm, Wc, angles, getattr(points, "centred", None))
        S_full = S_full + Rt
        e_full = _wrap_components(y[t] - y_hat, angles)
        out["innov"][t], out["S"][t] = e_full, S_full
        o = ~np.isnan(y[t])
        if o.any():
            S = S_full[np.ix_(o, o)]
            x_filt, P_filt, K, ll = _update(x, P, e_full[o], C_full[:, o], S)
            out["K"][t][:, o] = K
            out["loglik_t"][t] = ll
            if sqrt:
                U = np.linalg.solve(np.linalg.cholesky(S), C_full[:, o].T).T  # K S^(1/2)
                L_filt = L
                for col in U.T:
                    L_filt = cholesky_downdate(L_filt, col)
                P_filt = L_filt @ L_filt.T
        else:
            x_filt, P_filt, L_filt = x, P, L
        out["x_filt"][t], out["P_filt"][t] = x_filt, P_filt
        L_now = L_filt if sqrt else np.linalg.cholesky(P_filt)
        if noise_input:
            Qt = _at(Q, t)
            r = len(Qt)
            Xa = points.points_of_factor(np.concatenate([x_filt, np.zeros(r)]), _block_diag(L_now, psd_cholesky(Qt)))
            _, Wm_a, Wc_a = points.weights(n + r)
            propagated = np.asarray(f(Xa[:, :n], Xa[:, n:], t, ut), dtype=float)
            x, P, D = _unscented_moments(Xa, propagated, Wm_a, Wc_a)
            out["D"][t] = D[:n]  # the state rows of Cov((x, w), x(t+1))
            if sqrt:
                L = _sqrt_covariance(propagated, Wm_a, Wc_a, centred)
        else:
            Xf = points.points_of_factor(x_filt, L_now)
            propagated = np.asarray(f(Xf, t, ut), dtype=float)
            x, P, D = _unscented_moments(Xf, propagated, Wm, Wc, centred=getattr(points, "centred", None))
            # D = Cov(x(t), x(t+1)): the unscented smoother's cross-covariance (Särkkä 2008)
            out["D"][t] = D
            noise = _noise_cov(g, _at(Q, t), x_filt, n, t, ut)
            P = P + noise
            if sqrt:
                L = _sqrt_covariance(propagated, Wm, Wc, centred, psd_cholesky(noise))
        P = L @ L.T if sqrt else (P + P.T) / 2
    out["loglik"] = float(out["loglik_t"].sum())
    out["x_next"], out["P_next"] = x, P
    return out


# ----------------------------------------------------------------------------------------------
# Smoothers: extended and unscented RTS
# ----------------------------------------------------------------------------------------------


def _rts(filt, cross):
    """The RTS backward pass with J(t) = cross(t) P(t+1|t)^-1; returns (x_smooth, P_smooth)."""
    xs, Ps = filt["x_filt"].copy(), filt["P_filt"].copy()
    for t in range(len(xs) - 2, -1, -1):
        J = cross(t) @ np.linalg.pinv(filt["P_pred"][t + 1])
        xs[t] = filt["x_filt"][t] + J @ (xs[t + 1] - filt["x_pred"][t + 1])
        Pt = filt["P_filt"][t] + J @ (Ps[t + 1] - filt["P_pred"][t + 1]) @ J.T
        Ps[t] = (Pt + Pt.T) / 2
    return xs, Ps


def extended_rts(
    f, h, Q, R, y, x0, P0, jac_f=None, jac_h=None, u=None, g=None, angles=(), form="joseph", noise_input=False
):
    """Extended RTS smoother (Särkkä 2013): J(t) = P(t|t) F(t)' P(t+1|t)^-1, F at x(t|t)
    (with ``noise_input``, the x columns of f's Jacobian at (x(t|t), 0)).
    Returns (x_smooth, P_smooth, filter dict)."""
    filt = ekf(f, h, Q, R, y, x0, P0, jac_f=jac_f, jac_h=jac_h, u=u, g=g, angles=angles, form=form, noise_input=noise_input)
    n = len(x0)

    def cross(t):
        ut = None if u is None else np.asarray(u[t], dtype=float)
        xf = filt["x_filt"][t]
        if noise_input:
            fn, J, xf = _augmented(f, n), _augmented(jac_f, n), np.concatenate([xf, np.zeros(len(_at(Q, t)))])
        else:
            fn, J = f, jac_f
        F = (_one(J, xf, t, ut) if J is not None else jacobian_by_differences(fn, xf, t, ut))[:, :n]
        return filt["P_filt"][t] @ F.T

    xs, Ps = _rts(filt, cross)
    return xs, Ps, filt


def unscented_rts(f, h, Q, R, y, x0, P0, points=None, u=None, g=None, angles=(), noise_input=False, form="standard"):
    """Unscented RTS smoother (Särkkä 2008): J(t) = D(t) P(t+1|t)^-1 with the forward pass's
    cross-covariance D(t) of x(t|t) and x(t+1|t). Returns (x_smooth, P_smooth, filter dict)."""
    filt = ukf(f, h, Q, R, y, x0, P0, points=points, u=u, g=g, angles=angles, noise_input=noise_input, form=form)
    xs, Ps = _rts(filt, lambda t: filt["D"][t])
    return xs, Ps, filt
