"""Median and mean filters (Söderström section 9.7): causal running statistics of a window of
n = 2m + 1 samples."""

from __future__ import annotations

import math
from typing import Any, Callable, Literal

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, index
from kfast._arrays import as_float64

__all__ = ["median_filter", "mean_filter", "order_statistic_pdf"]

Mode = Literal["valid", "grow"]


def median_filter(u: ArrayLike, n: int, mode: Mode = "valid") -> np.ndarray:
    """The causal median filter (Söderström (9.105)): y(t) = median{u(t-n+1), ..., u(t)}.

    Nonlinear: it keeps steps and edges (delayed by m = (n - 1)/2 samples, (9.107)) and removes
    impulsive noise, where the mean filter smears both. O(log n) per sample (the window in two
    ordered halves).

    Parameters
    ----------
    u : array_like, shape (T,) or (T, k)
        The signal; each column is filtered on its own. NaN marks a missing sample: a window
        holding one gives NaN.
    n : int
        The window, odd (n = 2m + 1).
    mode : {"valid", "grow"}
        Before the window is full: NaN ("valid"), or the median of the samples so far ("grow";
        for an even count the mean of the two middle ones, as ``np.median``).

    Returns
    -------
    ndarray, the shape of u
        Causal: y(t) uses u up to t. ``scipy.signal.medfilt`` is centred and zero-padded; away
        from the edges it equals this output m samples later.
    """
    return _filter(_kfast.median_filter, u, n, mode)


def mean_filter(u: ArrayLike, n: int, mode: Mode = "valid") -> np.ndarray:
    """The causal mean (moving-average) filter (Söderström (9.106)): y(t) = (u(t-n+1) + ... +
    u(t)) / n, H(q) = (1 + q^-1 + ... + q^-(n-1)) / n, gain |sin(wn/2) / (n sin(w/2))| and a
    delay of m samples (9.111)-(9.112). A running sum with Neumaier's compensation: O(1) per
    sample, rounding that does not grow with T. Parameters as :func:`median_filter` ("grow":
    the mean of the samples so far)."""
    return _filter(_kfast.mean_filter, u, n, mode)


def order_statistic_pdf(
    z: ArrayLike,
    pdf: Callable[[np.ndarray], ArrayLike],
    cdf: Callable[[np.ndarray], ArrayLike],
    n: int,
    which: Literal["min", "max", "median"] = "median",
) -> np.ndarray:
    """The density of the smallest, the largest or the median of 2n + 1 independent samples of
    the density ``pdf`` with distribution function ``cdf`` (Söderström Lemma 9.1)::

        f_min(z)    = (2n+1) f(z) (1 - F(z))^(2n)                          (9.134)
        f_max(z)    = (2n+1) f(z) F(z)^(2n)                                (9.135)
        f_median(z) = (2n+1)! / (n! n!) f(z) F(z)^n (1 - F(z))^n           (9.136)

    evaluated in logs (log F and log(1 - F), the factorials by ``lgamma``), so that the tails
    underflow to 0 rather than to NaN. With n = 0 each is f itself.

    Parameters
    ----------
    z : array_like
        Where to evaluate.
    pdf, cdf : callable
        f and F of the samples, vectorized over an array of z.
    n : int
        2n + 1 samples (the median filter's window n = 2m + 1 has m here).
    which : {"min", "max", "median"}

    Returns
    -------
    ndarray, the shape of z
    """
    zs = as_float64("z", z)
    half = index("n", n)
    choice("which", which, ("min", "max", "median"))
    f = np.asarray(pdf(zs), dtype=float)
    F = np.asarray(cdf(zs), dtype=float)
    for name, values in (("pdf", f), ("cdf", F)):
        if values.shape != zs.shape:
            raise _kfast.KfastError(f"{name}: returned shape {values.shape} for z of shape {zs.shape}")
        if not np.all(np.isfinite(values)):
            raise _kfast.KfastError(f"{name}: returned a non-finite value")
    if np.any(f < 0) or np.any((F < 0) | (F > 1)):
        raise _kfast.KfastError("pdf, cdf: a density must be >= 0 and a distribution function in [0, 1]")
    with np.errstate(divide="ignore"):
        log_f, log_F, log_S = np.log(f), np.log(F), np.log1p(-F)
    count = 2 * half + 1
    if which == "min":
        log_density = math.log(count) + log_f + _times(2 * half, log_S)
    elif which == "max":
        log_density = math.log(count) + log_f + _times(2 * half, log_F)
    else:
        log_choose = math.lgamma(count + 1) - 2 * math.lgamma(half + 1)
        log_density = log_choose + log_f + _times(half, log_F) + _times(half, log_S)
    return np.exp(log_density)


def _times(k: int, log_values: np.ndarray) -> np.ndarray:
    """k log v, with 0 log 0 = 0 (v^0 = 1 even where v = 0)."""
    return np.zeros_like(log_values) if k == 0 else k * log_values


def _filter(core: Callable[..., Any], u: ArrayLike, n: int, mode: str) -> np.ndarray:
    arr = as_float64("u", u)
    if arr.ndim not in (1, 2):
        raise _kfast.KfastError(f"u: expected shape (T,) or (T, k), got {arr.shape}")
    window = index("n", n)
    choice("mode", mode, ("valid", "grow"))
    columns = arr.reshape(arr.shape[0], arr.shape[1] if arr.ndim == 2 else 1)
    out = core(np.ascontiguousarray(columns), window, mode)
    return np.asarray(out).reshape(arr.shape)
