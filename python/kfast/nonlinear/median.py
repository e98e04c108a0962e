"""Median and mean filters (Söderström section 9.7): causal running statistics of a window of
n = 2m + 1 samples."""

from __future__ import annotations

from typing import Any, Callable, Literal

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, index
from kfast._arrays import as_float64

__all__ = ["median_filter", "mean_filter"]

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


def _filter(core: Callable[..., Any], u: ArrayLike, n: int, mode: str) -> np.ndarray:
    arr = as_float64("u", u)
    if arr.ndim not in (1, 2):
        raise _kfast.KfastError(f"u: expected shape (T,) or (T, k), got {arr.shape}")
    window = index("n", n)
    choice("mode", mode, ("valid", "grow"))
    columns = arr.reshape(arr.shape[0], arr.shape[1] if arr.ndim == 2 else 1)
    out = core(np.ascontiguousarray(columns), window, mode)
    return np.asarray(out).reshape(arr.shape)
