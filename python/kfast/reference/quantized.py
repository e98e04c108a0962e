"""Quantized measurements in plain NumPy (Söderström section 9.6): the quantizer (9.101), the
moments of a quantized variable summed directly over the cells, the characteristic-function
series (9.121)-(9.131) as the book writes it (complex, over k != 0, truncated at |k| <= K), and
the log-likelihood of a quantized Gaussian measurement by the plain difference of normal
distribution functions (accurate away from the far tails only)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["quantize", "moments_over_cells", "moments_by_series", "quantized_loglik"]


def quantize(x, delta):
    """delta * floor(x / delta + 1/2): (9.101), half up."""
    return delta * np.floor(np.asarray(x, dtype=float) / delta + 0.5)


def _cdf(x, mean, std, distribution):
    if distribution == "gaussian":
        return 0.5 * (1.0 + math.erf((x - mean) / (std * math.sqrt(2.0))))
    half = math.sqrt(3.0) * std
    return min(1.0, max(0.0, (x - mean + half) / (2.0 * half)))


def moments_over_cells(delta, mean, std, distribution="gaussian"):
    """(E x_Q, E x_Q^2, var x_Q) = sums over the cells j of (j delta)^p P(x in cell j), the
    cell probabilities from differences of the distribution function (the oracle)."""
    reach = 12.0 * std if distribution == "gaussian" else math.sqrt(3.0) * std
    levels = np.arange(math.floor((mean - reach) / delta) - 1, math.ceil((mean + reach) / delta) + 2)
    p = np.array([_cdf((j + 0.5) * delta, mean, std, distribution) - _cdf((j - 0.5) * delta, mean, std, distribution) for j in levels])
    first = float(np.sum(levels * delta * p))
    second = float(np.sum((levels * delta) ** 2 * p))
    return first, second, float(np.sum((levels * delta - first) ** 2 * p))


def _phi(w, mean, std, distribution):
    """The characteristic function phi(w) = E exp(i w x) and its derivative phi'(w)."""
    if distribution == "gaussian":
        phi = np.exp(1j * w * mean - 0.5 * std**2 * w**2)
        return phi, (1j * mean - std**2 * w) * phi
    a = math.sqrt(3.0) * std
    s = np.sin(a * w) / (a * w)
    ds = np.cos(a * w) / w - np.sin(a * w) / (a * w**2)
    rot = np.exp(1j * w * mean)
    return rot * s, 1j * mean * rot * s + rot * ds


def moments_by_series(delta, mean, std, distribution="gaussian", K=1000, positive_k_only=False):
    """(E x_Q, E x_Q^2) by the series of (9.121)-(9.131), term by term over 0 < |k| <= K:

        f_k'(0) = (-1)^k delta/(2 pi k),  f_k''(0) = (-1)^(k+1) delta^2/(2 pi^2 k^2)
        E x_Q   = E x - i sum_k f_k'(0) phi(w_k)
        E x_Q^2 = E x^2 + delta^2/12 - sum_k [f_k''(0) phi(w_k) + 2 f_k'(0) phi'(w_k)]

    with w_k = 2 pi k/delta. ``positive_k_only`` sums k > 0 only, as (9.131) is printed (wrong)."""
    k = np.arange(1, K + 1, dtype=float)
    k = k if positive_k_only else np.concatenate([-k[::-1], k])
    w = 2.0 * np.pi * k / delta
    sign = np.where(np.abs(k) % 2 == 1, -1.0, 1.0)
    d1 = sign * delta / (2.0 * np.pi * k)
    d2 = -sign * delta**2 / (2.0 * np.pi**2 * k**2)
    phi, dphi = _phi(w, mean, std, distribution)
    first = mean + (-1j * np.sum(d1 * phi)).real
    second = mean**2 + std**2 + delta**2 / 12.0 - np.sum(d2 * phi + 2.0 * d1 * dphi).real
    return float(first), float(second)


def quantized_loglik(y, y_hat, std, delta):
    """sum_i log(Phi((y_i + delta_i/2 - y_hat_i)/std_i) - Phi((y_i - delta_i/2 - y_hat_i)/std_i)) for
    each row of y_hat (M, m); NaN in y skipped."""
    y_hat = np.atleast_2d(np.asarray(y_hat, dtype=float))
    out = np.zeros(len(y_hat))
    for r, row in enumerate(y_hat):
        for i, (v, s, d) in enumerate(zip(np.atleast_1d(y), np.atleast_1d(std), np.atleast_1d(delta))):
            if np.isnan(v):
                continue
            hi = 0.5 * (1.0 + math.erf((v + d / 2 - row[i]) / (s * math.sqrt(2.0))))
            lo = 0.5 * (1.0 + math.erf((v - d / 2 - row[i]) / (s * math.sqrt(2.0))))
            out[r] += math.log(hi - lo) if hi > lo else -math.inf
    return out
