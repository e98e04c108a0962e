"""Conversion of user input to the float64 arrays the compiled core reads.

The one place where array-likes (lists, ints, float32, Fortran-ordered or strided arrays,
pandas objects) become C-contiguous float64. Complex and non-numeric input is refused with a
message naming the argument. NumPy masked arrays: a masked observation (``y``, ``Y``) is a
missing value, as in statsmodels, and becomes NaN; masked entries anywhere else are refused
(a matrix, prior or input has no "missing" meaning). The result may share memory with the
input, which the core never writes to.
"""

from __future__ import annotations

import numpy as np

from kfast._kfast import KfastError


# The arguments whose masked entries mean "missing" (NaN).
_OBSERVATIONS = ("y", "Y")


def as_float64(name: str, value: object) -> np.ndarray:
    """``value`` as a C-contiguous float64 array; ``KfastError`` (a ValueError) otherwise."""
    if isinstance(value, np.ma.MaskedArray):
        value = _unmask(name, value)
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise KfastError(f"{name}: cannot be read as an array ({exc})") from None
    if arr.dtype.kind == "c":
        raise KfastError(f"{name}: complex input is not supported (got dtype {arr.dtype})")
    if arr.dtype.kind not in "fiu":
        raise KfastError(f"{name}: expected real numbers, got dtype {arr.dtype}")
    # (not np.ascontiguousarray, which turns 0-d into 1-d)
    return np.asarray(arr, dtype=np.float64, order="C")


def finite_vector(name: str, value: object, what: str) -> np.ndarray:
    """``value`` as a non-empty, finite 1-D float64 array (a scalar is a vector of one);
    ``what`` says in the error what the entries are."""
    arr = as_float64(name, value)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or arr.size == 0:
        raise KfastError(f"{name}: expected a non-empty 1-D array {what}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise KfastError(f"{name}: must be finite, got {arr}")
    return arr


def frozen_copy(name: str, value: object, scalar_shape: tuple = ()) -> np.ndarray:
    """A read-only float64 copy of ``value`` (for model attributes); a scalar gets
    ``scalar_shape`` (e.g. (1, 1) for a 1 x 1 matrix)."""
    arr = np.array(as_float64(name, value), copy=True)
    if arr.ndim == 0:
        arr = arr.reshape(scalar_shape)
    arr.setflags(write=False)
    return arr


def _unmask(name: str, value: np.ma.MaskedArray) -> np.ndarray:
    """The data of a masked array with masked observations as NaN (a new array)."""
    mask = np.ma.getmaskarray(value)
    if not mask.any():
        return np.ma.getdata(value)
    if name not in _OBSERVATIONS:
        raise KfastError(
            f"{name}: has masked entries ({int(mask.sum())}); only observations (y) may be masked (missing "
            "values): a matrix, prior, input or interval cannot be missing"
        )
    data = np.ma.getdata(value)
    if data.dtype.kind not in "fiu":
        raise KfastError(f"{name}: expected real numbers, got dtype {data.dtype}")
    return np.where(mask, np.nan, data.astype(np.float64))
