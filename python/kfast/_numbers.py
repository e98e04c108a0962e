"""Checks of real and integer-valued arguments that ``_args.py`` does not cover: integer lags
given as an array, and a positive real scalar. Each raises ``KfastError`` (a ValueError) naming
the argument; and the power of a matrix for one or many (possibly huge) lags, in O(log lag)
products, so that no lag makes a computation hang or allocate without bound.
"""

from __future__ import annotations

import math

import numpy as np

from kfast._arrays import as_float64
from kfast._kfast import KfastError

# Lags are 64-bit integers: |lag| < 2**63 (so that |lag| is one too).
_LAG_BOUND = 2**63

# Consecutive lags closer than this are reached by repeated multiplication (as a loop over
# the lags would do), farther ones by repeated squaring (numpy.linalg.matrix_power).
_STEP_LIMIT = 1000


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def integer_lags(name: str, value: object) -> np.ndarray:
    """``value`` (a scalar or an array of any shape) as int64 lags: integers, or floats with
    integer values, each with |lag| < 2**63; NaN, inf, fractions, bools and complex are refused."""
    if not isinstance(value, np.ma.MaskedArray):
        try:
            raw = np.asarray(value)
        except Exception:
            raw = None
        if raw is not None and raw.dtype.kind in "iu":
            if raw.size and (int(raw.max()) >= _LAG_BOUND or int(raw.min()) <= -_LAG_BOUND):
                raise KfastError(f"{name}: must be integers with |lag| < 2**63, got {_short(value)}")
            return raw.astype(np.int64)
    lags = as_float64(name, value)
    if not np.all(np.isfinite(lags)):
        raise KfastError(f"{name}: expected integers, got a non-finite value in {_short(value)}")
    if np.any(lags != np.round(lags)):
        raise KfastError(f"{name}: expected integers, got {_short(value)}")
    if np.any(np.abs(lags) >= _LAG_BOUND):
        raise KfastError(f"{name}: must be integers with |lag| < 2**63, got {_short(value)}")
    return lags.astype(np.int64)


def real_scalar(name: str, value: object, what: str) -> float:
    """A real number (possibly inf or NaN: the caller checks its range): a Python or NumPy int
    or float, or a 0-d array (not a bool, str, None, list or complex). ``what`` says in the
    error what was expected, e.g. "a positive real number"."""
    if value is None or isinstance(value, (bool, np.bool_, str, bytes)):
        raise KfastError(f"{name}: expected {what}, got {_short(value)}")
    if isinstance(value, int):  # a Python int of any size: 10**400 is not a double
        return float(value) if abs(value) < 2**1000 else (math.inf if value > 0 else -math.inf)
    try:
        arr = np.asarray(value)
    except Exception:
        raise KfastError(f"{name}: expected {what}, got {_short(value)}") from None
    if arr.ndim != 0 or arr.dtype.kind not in "fiu":
        raise KfastError(f"{name}: expected {what}, got {_short(value)}")
    return float(arr)


def positive_real(name: str, value: object) -> float:
    """A finite real number > 0 (see :func:`real_scalar`)."""
    x = real_scalar(name, value, "a positive real number")
    if not (math.isfinite(x) and x > 0):
        raise KfastError(f"{name}: must be a finite number > 0, got {_short(value)}")
    return x


def powers_applied(F: np.ndarray, G: np.ndarray, exponents: np.ndarray) -> dict:
    """{k: F^k G} for each distinct k >= 0 of ``exponents`` (ascending walk: a product per
    step between close exponents, repeated squaring across large gaps, so any k < 2**63 costs
    O(log k) products)."""
    out: dict = {}
    current, at = G, 0
    for k in np.unique(exponents).tolist():
        gap = k - at
        if gap <= _STEP_LIMIT:
            for _ in range(gap):
                current = F @ current
        else:
            current = np.linalg.matrix_power(F, gap) @ current
        out[k], at = current, k
    return out
