"""The particle filter in plain NumPy (Söderström (9.89)-(9.100); sequential importance
resampling with adaptive resampling): the oracle for ``NonlinearModel.particle_filter``.

It draws the same random numbers as kfast (the generator below is the Rust one, written with
NumPy's wrapping uint64 arithmetic), so on the same seed both filters follow the same
particles and agree to rounding.
"""

from __future__ import annotations

import math

import numpy as np

from kfast.reference.nonlinear import psd_cholesky, wrap
from kfast.reference.quantized import quantized_loglik

__all__ = ["Stream", "normal_quantile", "resample", "particle_filter", "PRIOR", "PROCESS_NOISE", "RESAMPLING", "REGULARIZATION"]

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
PRIOR, PROCESS_NOISE, RESAMPLING, REGULARIZATION = 1, 2, 3, 4
"""The purposes of the streams: the prior's particles, a step's process noise, its resampling,
the regularization's kernel jitter."""


def _mix(z):
    """SplitMix64's finalizer, on uint64 arrays (wrapping)."""
    z = np.asarray(z, dtype=np.uint64)
    with np.errstate(over="ignore"):
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


class Stream:
    """The draws of one (seed, step, purpose): draw i is mix(key + (i + 1) gamma)."""

    def __init__(self, seed, step, purpose):
        with np.errstate(over="ignore"):
            seed_key = _mix(np.uint64(seed) + _GAMMA)
            step_key = _mix(seed_key + np.uint64(step + 1) * _GAMMA)
            self.key = _mix(step_key + np.uint64(purpose) * _GAMMA)

    def bits(self, i):
        i = np.asarray(i, dtype=np.uint64)
        with np.errstate(over="ignore"):
            return _mix(self.key + (i + np.uint64(1)) * _GAMMA)

    def uniform(self, i):
        """Uniforms in (0, 1): the top 52 bits, centred in their cell."""
        return ((self.bits(i) >> np.uint64(12)).astype(float) + 0.5) * 2.0**-52

    def normal(self, i):
        return normal_quantile(self.uniform(i))


# Wichura (1988), AS 241 (PPND16): numerator and denominator coefficients, constant term first
_CENTRE = (
    [3.387132872796366608, 133.14166789178437745, 1971.5909503065514427, 13731.693765509461125,
     45921.953931549871457, 67265.770927008700853, 33430.575583588128105, 2509.0809287301226727],
    [1.0, 42.313330701600911252, 687.1870074920579083, 5394.1960214247511077, 21213.794301586595867,
     39307.89580009271061, 28729.085735721942674, 5226.495278852854561],
)
_NEAR = (
    [1.42343711074968357734, 4.6303378461565452959, 5.7694972214606914055, 3.64784832476320460504,
     1.27045825245236838258, 0.24178072517745061177, 0.0227238449892691845833, 7.7454501427834140764e-4],
    [1.0, 2.05319162663775882187, 1.6763848301838038494, 0.68976733498510000455, 0.14810397642748007459,
     0.0151986665636164571966, 5.475938084995344946e-4, 1.05075007164441684324e-9],
)
_FAR = (
    [6.6579046435011037772, 5.4637849111641143699, 1.7848265399172913358, 0.29656057182850489123,
     0.026532189526576123093, 0.0012426609473880784386, 2.71155556874348757815e-5, 2.01033439929228813265e-7],
    [1.0, 0.59983220655588793769, 0.13692988092273580531, 0.0148753612908506148525, 7.868691311456132591e-4,
     1.8463183175100546818e-5, 1.4215117583164458887e-7, 2.04426310338993978564e-15],
)


def _ratio(coefs, r):
    num, den = coefs
    top, bottom = np.full_like(r, num[-1]), np.full_like(r, den[-1])
    for c in num[-2::-1]:
        top = top * r + c
    for c in den[-2::-1]:
        bottom = bottom * r + c
    return top / bottom


def normal_quantile(p):
    """The standard normal quantile by AS 241 (relative error about 1e-16), p in (0, 1)."""
    p = np.asarray(p, dtype=float)
    q = p - 0.5
    out = np.empty_like(p)
    centre = np.abs(q) <= 0.425
    out[centre] = q[centre] * _ratio(_CENTRE, 0.180625 - q[centre] ** 2)
    tail = ~centre
    r = np.sqrt(-np.log(np.where(q[tail] < 0, p[tail], 1.0 - p[tail])))
    value = np.where(r <= 5.0, _ratio(_NEAR, r - 1.6), _ratio(_FAR, r - 5.0))
    out[tail] = np.where(q[tail] < 0, -value, value)
    return out


def _inverse_cdf(w, u):
    """The first j with w_0 + ... + w_j >= u_k * sum(w), for increasing u in (0, 1)."""
    cumulative = np.cumsum(w)
    return np.minimum(np.searchsorted(cumulative, u * cumulative[-1], side="left"), len(w) - 1)


def _ordered_uniforms(stream, m):
    """M sorted uniforms: partial sums of M + 1 exponentials over their total."""
    s = np.cumsum(-np.log(stream.uniform(np.arange(m + 1))))
    return s[:-1] / s[-1]


def resample(scheme, w, stream, draws=None):
    """``draws`` (N; M by default) ancestor indices, particle i chosen N w_i / sum(w) times in
    expectation (Söderström (9.95)-(9.97) for "multinomial"; Kitagawa 1996; Liu & Chen 1998 for
    "residual")."""
    w = np.asarray(w, dtype=float)
    m = len(w) if draws is None else draws
    if scheme == "multinomial":
        return _inverse_cdf(w, _ordered_uniforms(stream, m))
    if scheme == "systematic":
        return _inverse_cdf(w, (np.arange(m) + stream.uniform(0)) / m)
    if scheme == "stratified":
        return _inverse_cdf(w, (np.arange(m) + stream.uniform(np.arange(m))) / m)
    if scheme == "residual":
        scaled = w * (m / w.sum())
        copies = np.floor(scaled).astype(int)
        sure = np.repeat(np.arange(len(w)), copies)[:m]
        rest = m - len(sure)
        if rest == 0:
            return sure
        remainders = scaled - np.floor(scaled)
        if not np.any(remainders > 0):
            remainders = w
        return np.concatenate([sure, _inverse_cdf(remainders, _ordered_uniforms(stream, rest))])
    raise ValueError(f"resample: unknown scheme {scheme!r}")


def particle_filter(f, h, Q, R, y, x0, P0, n_particles, resample_scheme="multinomial", ess_threshold=None,
                    seed=0, u=None, angles=(), g=None, noise_input=False, quantized=None, student_t=None,
                    uniform=False, regularize=None, likelihood=None, copies=1, move=None):
    """The SIR particle filter with the model as proposal; x(0|-1) ~ N(x0, P0).

    f, h batched as kfast's (``f(X, t, u)``, or ``f(X, W, t, u)`` with ``noise_input``; ``g``
    a batched noise gain giving (k, n, r)). ``quantized``: the steps delta (m,) of a quantized
    measurement y = Q_delta(h(x) + v), whose likelihood is the probability of y's cell (R
    diagonal). ``student_t``: the degrees of freedom nu of multivariate Student-t noise of scale
    R. ``uniform``: noise uniform on +-sqrt(3 R_ii). Returns a dict of x_filt, P_filt, ess,
    resampled, loglik_t and loglik. ``regularize`` c: after each resampling x_i += h L z_i,
    L L' = P(t|t), h = c (4 / (M (n + 2)))^(1/(n + 4)). ``likelihood(X, y, t, u)``: the user's
    log p(y(t) | x) of all particles. ``copies`` r: resampling draws M / r ancestors, each taken
    by r particles in a row (Söderström (9.98)). ``move(X, y, t, u)``: the user's move after
    each resampling (and regularization), y the last update's (NaN if none).
    """
    y = np.asarray(y, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    T, m = y.shape
    n, M = len(x0), n_particles
    Qs = np.asarray(Q, dtype=float)
    # the prior's particles
    L0 = psd_cholesky(P0)
    Z = Stream(seed, 0, PRIOR).normal(np.arange(M * n)).reshape(M, n)
    X = np.asarray(x0, dtype=float) + Z @ L0.T
    log_w = np.full(M, -np.log(M))
    out = {k: [] for k in ("x_filt", "P_filt", "ess", "resampled", "loglik_t")}
    for t in range(T):
        u_t = None if u is None else np.asarray(u, dtype=float)[t]
        # the update: log-weights by the likelihood of the observed components (9.94)
        obs = ~np.isnan(y[t])
        increment = 0.0
        if obs.any():
            loglik_i = (_log_likelihoods(h, R, y[t], X, t, u_t, angles, quantized, student_t, uniform) if likelihood is None
                        else np.asarray(likelihood(X, y[t], t, u_t), dtype=float))
            a = log_w + loglik_i
            top = a.max()
            increment = top + np.log(np.sum(np.exp(a - top)))
            log_w = a - increment
        W = np.exp(log_w)
        # the weighted moments (9.99)-(9.100), two-pass
        mean = W @ X / W.sum()
        D = X - mean
        out["x_filt"].append(mean)
        out["P_filt"].append((W[:, None] * D).T @ D / W.sum())
        ess = W.sum() ** 2 / np.sum(W**2)
        out["ess"].append(ess)
        out["loglik_t"].append(increment)
        if t + 1 == T:
            out["resampled"].append(False)
            break
        # resampling, every step or when the effective sample size is low
        due = ess_threshold is None or ess < ess_threshold * M
        out["resampled"].append(due)
        if due:
            ancestors = resample(resample_scheme, W, Stream(seed, t, RESAMPLING), M // copies)
            X = X[np.repeat(ancestors, copies)]
            log_w = np.full(M, -np.log(M))
            if regularize is not None:
                h_bw = regularize * (4.0 / (M * (n + 2))) ** (1.0 / (n + 4))
                Z = Stream(seed, t, REGULARIZATION).normal(np.arange(M * n)).reshape(M, n)
                X = X + h_bw * Z @ psd_cholesky(out["P_filt"][-1]).T
            if move is not None:
                X = np.asarray(move(X, y[t], t, u_t), dtype=float)
        # the time update (9.98): x <- f(x) + w, w ~ N(0, Q(t))
        Q_t = Qs[t] if Qs.ndim == 3 else Qs
        r = len(Q_t)
        Wn = Stream(seed, t, PROCESS_NOISE).normal(np.arange(M * r)).reshape(M, r) @ psd_cholesky(Q_t).T
        if noise_input:
            X = np.asarray(f(X, Wn, t, u_t), dtype=float)
        elif g is not None:
            G = np.asarray(g(X, t, u_t), dtype=float).reshape(M, n, r)
            X = np.asarray(f(X, t, u_t), dtype=float) + np.einsum("ijk,ik->ij", G, Wn)
        else:
            X = np.asarray(f(X, t, u_t), dtype=float) + Wn
    res = {k: np.array(v) for k, v in out.items()}
    res["loglik"] = float(np.sum(res["loglik_t"]))
    return res


def _log_likelihoods(h, R, y_t, X, t, u_t, angles, quantized, student_t, uniform):
    """log p(y(t) | x_i) of the particles X on y's observed components: Gaussian, quantized,
    Student-t or uniform noise."""
    obs = ~np.isnan(y_t)
    m = len(y_t)
    Rs = np.asarray(R, dtype=float)
    R_t = Rs[t] if Rs.ndim == 3 else Rs
    Ro = R_t[np.ix_(obs, obs)]
    Y_hat = np.asarray(h(X, t, u_t), dtype=float)
    E = y_t[obs] - Y_hat[:, obs]
    for j, i in enumerate(np.flatnonzero(obs)):
        if i in angles:
            E[:, j] = wrap(E[:, j])
    maha = np.einsum("ij,ij->i", E, np.linalg.solve(Ro, E.T).T)
    mo, logdet = obs.sum(), np.linalg.slogdet(Ro)[1]
    if quantized is not None:
        loglik_i = quantized_loglik(y_t, Y_hat, np.sqrt(np.diag(R_t)), np.broadcast_to(quantized, (m,)))
    elif student_t is not None:
        nu = student_t
        loglik_i = (math.lgamma((nu + mo) / 2) - math.lgamma(nu / 2) - mo / 2 * np.log(nu * np.pi) - logdet / 2
                    - (nu + mo) / 2 * np.log1p(maha / nu))
    elif uniform:
        half = np.sqrt(3 * np.diag(Ro))
        loglik_i = np.where(np.all(np.abs(E) <= half, axis=1), -np.sum(np.log(2 * half)), -np.inf)
    else:
        loglik_i = -0.5 * (mo * np.log(2 * np.pi) + logdet + maha)
    return loglik_i
