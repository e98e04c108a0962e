"""Conversion of user input to the float64 arrays the compiled core reads.

The one place where array-likes (lists, ints, float32, Fortran-ordered or strided arrays)
become C-contiguous float64. Complex and non-numeric input is refused with a message naming
the argument. The result may share memory with the input, which the core never writes to.
"""

from __future__ import annotations

import numpy as np

from kfast._kfast import KfastError


def as_float64(name: str, value: object) -> np.ndarray:
    """``value`` as a C-contiguous float64 array; ``KfastError`` (a ValueError) otherwise."""
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


def frozen_copy(name: str, value: object, scalar_shape: tuple = ()) -> np.ndarray:
    """A read-only float64 copy of ``value`` (for model attributes); a scalar gets
    ``scalar_shape`` (e.g. (1, 1) for a 1 x 1 matrix)."""
    arr = np.array(as_float64(name, value), copy=True)
    if arr.ndim == 0:
        arr = arr.reshape(scalar_shape)
    arr.setflags(write=False)
    return arr
