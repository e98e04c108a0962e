"""Multiple-model filters in plain NumPy, as Söderström writes them (sections 9.4-9.5): the
Gaussian-sum filter (9.43)-(9.55), the fixed model bank (9.56)-(9.63) and the interacting
multiple-model (IMM) filter (9.64)-(9.86).

Linear Gaussian modes are dicts with "F", "H", "Q", "R" and optional "B", "D"::

    x[t+1] = F_j x[t] + B_j u_j[t] + w[t]     cov w = Q_j
    y[t]   = H_j x[t] + D_j u_j[t] + v[t]     cov v = R_j

Conventions as ``kalman_filter``: the prior (x0, P0) is x(0|-1), P(0|-1); each step is the
measurement update with y(t), then the time update; NaN in y is a missing component (the update
uses the observed ones; with none observed the likelihood term is 0); P(t|t) in Joseph form;
log-likelihood terms are -1/2 (m_o log 2 pi + log det S + e' S^-1 e). ``mode_probs`` is the prior
mu(0|-1) of the modes at step 0, so step 0 has no mixing: c_bar(0) = mode_probs.

Mixture moments are always formed as the mean first, then P = sum w [P_i + (x_i - x)(x_i - x)']
(never E[xx'] - x x', which cancels).
"""

from __future__ import annotations

import numpy as np

__all__ = ["imm_filter", "model_bank", "gaussian_sum_filter"]


def _log_gauss(e, S):
    """log N(e; 0, S)."""
    _, logdet = np.linalg.slogdet(S)
    return float(-0.5 * (len(e) * np.log(2 * np.pi) + logdet + e @ np.linalg.solve(S, e)))


def _update(x, P, y, y_hat, H, R):
    """The Kalman update with the observed components of y (prediction y_hat, Jacobian H):
    x(t|t), P(t|t) (Joseph form) and the log-likelihood term (Lemma 6.1)."""
    o = ~np.isnan(y)
    if not o.any():
        return x.copy(), P.copy(), 0.0
    Ho, Ro = H[o], R[np.ix_(o, o)]
    e = y[o] - y_hat[o]
    S = Ho @ P @ Ho.T + Ro
    K = P @ Ho.T @ np.linalg.inv(S)
    A = np.eye(len(x)) - K @ Ho
    P_filt = A @ P @ A.T + K @ Ro @ K.T
    return x + K @ e, (P_filt + P_filt.T) / 2, _log_gauss(e, S)


def _moments(weights, xs, Ps):
    """The mixture's mean x = sum w x_i, then P = sum w [P_i + (x_i - x)(x_i - x)']."""
    x = sum(w * xi for w, xi in zip(weights, xs))
    P = sum(w * (Pi + np.outer(xi - x, xi - x)) for w, xi, Pi in zip(weights, xs, Ps))
    return x, P


def _normalize_logs(log_terms, fallback):
    """(log c, w) with c = sum exp(log_terms) and w = exp(log_terms) / c, by log-sum-exp. When
    every term is -inf (no component can explain y) the weights stay at ``fallback``."""
    top = np.max(log_terms)
    if top == -np.inf:
        return -np.inf, np.asarray(fallback, dtype=float).copy()
    log_c = top + np.log(np.sum(np.exp(log_terms - top)))
    return float(log_c), np.exp(log_terms - log_c)


def _log(p):
    with np.errstate(divide="ignore"):
        return np.log(p)


def _state_map(maps, sizes, i, j):
    """(A, b, Sigma) of x_j = A x_i + b, covariance A P A' + Sigma; the identity for a pair of
    equal size without a map; None when the sizes differ and no map is given."""
    if (i, j) not in maps:
        if sizes[i] != sizes[j]:
            return None
        return np.eye(sizes[j]), np.zeros(sizes[j]), np.zeros((sizes[j], sizes[j]))
    m = maps[(i, j)]
    A, b, Sigma = (tuple(m) + (None, None))[:3] if isinstance(m, tuple) else (m, None, None)
    A = np.asarray(A, dtype=float).reshape(sizes[j], sizes[i])
    b = np.zeros(sizes[j]) if b is None else np.asarray(b, dtype=float).reshape(sizes[j])
    Sigma = np.zeros((sizes[j], sizes[j])) if Sigma is None else np.asarray(Sigma, dtype=float)
    return A, b, Sigma.reshape(sizes[j], sizes[j])


def _apply(map_, x, P):
    A, b, Sigma = map_
    return A @ x + b, A @ P @ A.T + Sigma


def _mode(model):
    mats = {k: np.atleast_2d(np.asarray(v, dtype=float)) for k, v in model.items() if v is not None}
    n, m = mats["F"].shape[0], mats["H"].shape[0]
    for k, shape in (("F", (n, n)), ("H", (m, n)), ("Q", (n, n)), ("R", (m, m)), ("B", (n, -1)), ("D", (m, -1))):
        if k in mats:
            mats[k] = mats[k].reshape(shape)
    return mats


def _inputs(u, r, T):
    """Per-mode inputs: u None, one (T, k) array for every mode, or a list of r arrays/None."""
    us = list(u) if isinstance(u, (list, tuple)) else [u] * r
    if len(us) != r:
        raise ValueError(f"u: a list of {r} per-mode inputs, got {len(us)}")
    return [None if v is None else np.asarray(v, dtype=float).reshape(T, -1) for v in us]


def _per_mode(v):
    """Whether a prior is given per mode (a list or tuple of arrays)."""
    return isinstance(v, (list, tuple)) and np.ndim(v[0]) >= 1


def imm_filter(models, transition, y, x0, P0, mode_probs, u=None, state_maps=None):
    """The IMM filter, Söderström (9.64)-(9.86).

    ``transition[i, j]`` = P(mode j at t+1 | mode i at t) (row-stochastic). ``x0``, ``P0``: one
    prior in mode 0's space (mapped to each mode by ``state_maps[(0, j)]``, the identity for modes
    of mode 0's size), or lists of r per-mode priors. ``mode_probs`` mu(0|-1) (None: uniform).
    ``u``: None, one (T, k) array, or a list of r per-mode arrays/None. ``state_maps``
    {(i, j): A | (A, b) | (A, b, Sigma)}: mode i's state in mode j's space is A x_i + b with
    covariance A P A' + Sigma (Sigma for the states mode i does not carry); pairs of equal size
    default to the identity.

    Returns a dict: x_filt, P_filt, x_pred, P_pred (combined, in mode 0's space; None when some
    mode cannot be mapped to mode 0), mode_probs mu(t|t) (T, r), mode_probs_pred c_bar(t) (T, r),
    x_filt_modes, P_filt_modes (lists of r), loglik_t (T,), loglik.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    T, r = len(y), len(models)
    maps = dict(state_maps or {})
    modes = [_mode(m) for m in models]
    sizes = [m["F"].shape[0] for m in modes]
    p = np.asarray(transition, dtype=float).reshape(r, r)
    us = _inputs(u, r, T)

    def mapping(i, j):
        map_ = _state_map(maps, sizes, i, j)
        if map_ is None:
            raise ValueError(f"state_maps: modes {i} and {j} differ in size and ({i}, {j}) has no map")
        return map_

    # every map the mixing (p_ij > 0) will need, checked before the run
    links = {(i, j): mapping(i, j) for i in range(r) for j in range(r) if i != j and p[i, j] > 0}
    to_0 = [_state_map(maps, sizes, j, 0) for j in range(r)]
    combined = all(mp is not None for mp in to_0)

    # the priors x_j(0|-1), P_j(0|-1)
    if _per_mode(x0):
        xs = [np.atleast_1d(np.asarray(v, dtype=float)) for v in x0]
        Ps = [np.asarray(v, dtype=float).reshape(len(x), len(x)) for v, x in zip(P0, xs)]
    else:
        x0 = np.atleast_1d(np.asarray(x0, dtype=float))
        P0 = np.asarray(P0, dtype=float).reshape(len(x0), len(x0))
        xs, Ps = [], []
        for j in range(r):
            x, P = _apply(mapping(0, j), x0, P0)
            xs.append(x)
            Ps.append(P)
    c_bar = np.full(r, 1.0 / r) if mode_probs is None else np.asarray(mode_probs, dtype=float)

    n0 = sizes[0]
    out = {
        "x_filt": np.zeros((T, n0)) if combined else None,
        "P_filt": np.zeros((T, n0, n0)) if combined else None,
        "x_pred": np.zeros((T, n0)) if combined else None,
        "P_pred": np.zeros((T, n0, n0)) if combined else None,
        "mode_probs": np.zeros((T, r)),
        "mode_probs_pred": np.zeros((T, r)),
        "x_filt_modes": [np.zeros((T, n)) for n in sizes],
        "P_filt_modes": [np.zeros((T, n, n)) for n in sizes],
        "loglik_t": np.zeros(T),
    }

    def combine(weights):
        return _moments(weights, *zip(*[_apply(to_0[j], xs[j], Ps[j]) for j in range(r)]))

    for t in range(T):
        # the combined prediction x(t|t-1) = sum_j c_bar_j x_j(t|t-1)
        out["mode_probs_pred"][t] = c_bar
        if combined:
            out["x_pred"][t], out["P_pred"][t] = combine(c_bar)

        # mode-matched Kalman updates and likelihoods l_j = gamma(e_j; 0, S_j)  (9.80)-(9.81)
        log_l = np.zeros(r)
        for j, m in enumerate(modes):
            y_hat = m["H"] @ xs[j]
            if "D" in m and us[j] is not None:
                y_hat = y_hat + m["D"] @ us[j][t]
            xs[j], Ps[j], log_l[j] = _update(xs[j], Ps[j], y[t], y_hat, m["H"], m["R"])
            out["x_filt_modes"][j][t], out["P_filt_modes"][j][t] = xs[j], Ps[j]

        # mu_j(t) = l_j c_bar_j / c, c = sum_j l_j c_bar_j = p(y(t) | Y(t-1)), in logs  (9.82)-(9.84)
        out["loglik_t"][t], mu = _normalize_logs(_log(c_bar) + log_l, c_bar)
        out["mode_probs"][t] = mu
        # the combined estimate x(t|t), P(t|t)  (9.85), (9.86)
        if combined:
            out["x_filt"][t], out["P_filt"][t] = combine(mu)
        if t == T - 1:
            break

        # mixing: c_bar_j = sum_i p_ij mu_i (9.71), mu_{i|j} = p_ij mu_i / c_bar_j (9.70),
        # x0_j = sum_i mu_{i|j} x_ij (9.72), P0_j = sum_i mu_{i|j} [P_ij + (x_ij - x0_j)(...)'] (9.73)
        # (x_ij, P_ij: mode i's filtered estimate in mode j's space)
        c_bar = p.T @ mu
        mixed = []
        for j in range(r):
            if c_bar[j] == 0:  # mode j cannot be reached: it keeps its own estimate
                mixed.append((xs[j], Ps[j]))
                continue
            w = p[:, j] * mu / c_bar[j]
            src = [i for i in range(r) if w[i] > 0]
            in_j = [(xs[i], Ps[i]) if i == j else _apply(links[i, j], xs[i], Ps[i]) for i in src]
            mixed.append(_moments(w[src], *zip(*in_j)))

        # mode-matched time update x_j(t+1|t) = F_j x0_j + B_j u_j(t), P_j = F_j P0_j F_j' + Q_j  (9.74), (9.76)
        for j, m in enumerate(modes):
            x, P = mixed[j]
            xs[j] = m["F"] @ x
            if "B" in m and us[j] is not None:
                xs[j] = xs[j] + m["B"] @ us[j][t]
            P = m["F"] @ P @ m["F"].T + m["Q"]
            Ps[j] = (P + P.T) / 2
    out["loglik"] = float(out["loglik_t"].sum())
    return out


def model_bank(models, y, x0, P0, mode_probs, u=None, state_maps=None):
    """The fixed model bank (9.56)-(9.63): r Kalman filters that never switch, weighted by
    mu_j(t) proportional to l_j mu_j(t-1). It is the IMM with the identity transition matrix (no
    mixing), so modes may differ in size (per-mode priors as lists); the combined fields are None
    unless every mode maps to mode 0 (same size, or ``state_maps[(j, 0)]``)."""
    return imm_filter(models, np.eye(len(models)), y, x0, P0, mode_probs, u=u, state_maps=state_maps)


def gaussian_sum_filter(f, h, F_jac, H_jac, Q, R, y, means, covs, weights=None):
    """The Gaussian-sum filter (9.43)-(9.55) of r EKF components for x[t+1] = f(x) + w,
    y = h(x) + v; f, h, F_jac, H_jac take one 1-D state. ``means`` (r, n), ``covs`` (r, n, n),
    ``weights`` (r,) (None: equal) are the components of the prior at t = 0, before its update.

    Per step: each component's EKF update, H at its prior mean; weights alpha_i(t) proportional
    to alpha_i(t-1) gamma(y(t); h(m_i), S_i) (9.52), in logs, and loglik_t = log sum_i
    alpha_i(t-1) gamma_i; each component's EKF time update, F at its filtered mean, the weights
    unchanged. No pruning or merging.

    Returns a dict: x_filt, P_filt, x_pred, P_pred (mixture moments), weights (T, r) after the
    update, means (T, r, n) filtered, loglik_t, loglik.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    T, m = y.shape
    ms = [np.atleast_1d(np.asarray(v, dtype=float)) for v in means]
    r, n = len(ms), len(ms[0])
    Ps = [np.asarray(v, dtype=float).reshape(n, n) for v in covs]
    Q, R = np.asarray(Q, dtype=float).reshape(n, n), np.asarray(R, dtype=float).reshape(m, m)
    alpha = np.full(r, 1.0 / r) if weights is None else np.asarray(weights, dtype=float) / np.sum(weights)
    out = {
        "x_filt": np.zeros((T, n)),
        "P_filt": np.zeros((T, n, n)),
        "x_pred": np.zeros((T, n)),
        "P_pred": np.zeros((T, n, n)),
        "weights": np.zeros((T, r)),
        "means": np.zeros((T, r, n)),
        "loglik_t": np.zeros(T),
    }
    for t in range(T):
        out["x_pred"][t], out["P_pred"][t] = _moments(alpha, ms, Ps)
        # EKF measurement update of each component, H at its prior mean m_i(t|t-1)
        log_gamma = np.zeros(r)
        for i in range(r):
            H = np.asarray(H_jac(ms[i]), dtype=float).reshape(m, n)
            y_hat = np.atleast_1d(np.asarray(h(ms[i]), dtype=float))
            ms[i], Ps[i], log_gamma[i] = _update(ms[i], Ps[i], y[t], y_hat, H, R)
        # alpha_i(t) = alpha_i(t-1) gamma_i / sum_k alpha_k(t-1) gamma_k  (9.52)
        out["loglik_t"][t], alpha = _normalize_logs(_log(alpha) + log_gamma, alpha)
        out["weights"][t], out["means"][t] = alpha, np.array(ms)
        out["x_filt"][t], out["P_filt"][t] = _moments(alpha, ms, Ps)
        # EKF time update of each component, F at its filtered mean; the weights unchanged
        for i in range(r):
            F = np.asarray(F_jac(ms[i]), dtype=float).reshape(n, n)
            P = F @ Ps[i] @ F.T + Q
            ms[i], Ps[i] = np.atleast_1d(np.asarray(f(ms[i]), dtype=float)), (P + P.T) / 2
    out["loglik"] = float(out["loglik_t"].sum())
    return out
