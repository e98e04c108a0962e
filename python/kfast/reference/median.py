"""Median and mean filters (Söderström section 9.7, (9.105)-(9.106)) by brute force: the oracle
for ``kfast.median_filter`` and ``kfast.mean_filter``."""

from __future__ import annotations

import numpy as np

__all__ = ["median_filter", "mean_filter"]


def _windows(u, n, mode, statistic):
    u = np.asarray(u, dtype=float)
    column = u.ndim == 1
    u2 = u[:, None] if column else u
    out = np.full(u2.shape, np.nan)
    for t in range(len(u2)):
        start = t - n + 1
        if start < 0 and mode == "valid":
            continue
        window = u2[max(start, 0): t + 1]
        out[t] = statistic(window, axis=0)
    return out[:, 0] if column else out


def median_filter(u, n, mode="valid"):
    """y(t) = median{u(t-n+1), ..., u(t)} (9.105); "grow": the median of the samples so far
    until the window is full (the mean of the two middle ones for an even count)."""
    return _windows(u, n, mode, np.median)


def mean_filter(u, n, mode="valid"):
    """y(t) = (u(t-n+1) + ... + u(t)) / n (9.106); "grow": the mean of the samples so far."""
    return _windows(u, n, mode, np.mean)
