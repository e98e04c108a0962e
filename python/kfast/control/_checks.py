"""Validation of the control problems' matrices: a ``KfastError`` (a ValueError) that names the
argument, the step (for per-step stacks) and the problem."""

from __future__ import annotations

from typing import Optional

import numpy as np

from kfast._arrays import as_float64
from kfast._kfast import KfastError


def matrix(name: str, value: object, rows: Optional[int] = None, cols: Optional[int] = None, stack: bool = False) -> np.ndarray:
    """A finite 2-D float64 matrix (a scalar is 1 x 1, a vector a column), or with ``stack`` a
    3-D per-step stack too. ``rows``/``cols`` are checked when given."""
    a = as_float64(name, value)
    if a.ndim < 2:
        a = a.reshape(-1, 1)
    if a.ndim != 2 and not (stack and a.ndim == 3):
        want = "a 2-D array or a 3-D per-step stack" if stack else "a 2-D array"
        raise KfastError(f"{name}: expected {want}, got shape {a.shape}")
    if (rows is not None and a.shape[-2] != rows) or (cols is not None and a.shape[-1] != cols):
        want = f"({rows if rows is not None else '.'}, {cols if cols is not None else '.'})"
        raise KfastError(f"{name}: expected shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        where = f" at step {bad[0]}" if a.ndim == 3 else ""
        raise KfastError(f"{name}{where}: must be finite, got {a[tuple(bad)]}")
    return a


def symmetric_psd(name: str, value: np.ndarray, what: str = "", definite: bool = False) -> None:
    """``value`` (a matrix or a per-step stack) is symmetric and positive semidefinite (definite)."""
    stack = value if value.ndim == 3 else value[None]
    for t, m in enumerate(stack):
        where = f" at step {t}" if value.ndim == 3 else ""
        scale = max(1.0, float(np.abs(m).max(initial=0.0)))
        if not np.allclose(m, m.T, rtol=1e-10, atol=1e-12 * scale):
            raise KfastError(f"{name}{where}: {what or name} must be symmetric")
        if m.size == 0:
            continue
        smallest = float(np.linalg.eigvalsh((m + m.T) / 2)[0])
        tol = 1e-12 * scale * len(m)
        if smallest < -tol or (definite and smallest <= tol):
            kind = "positive definite" if definite else "positive semidefinite"
            raise KfastError(f"{name}{where}: {what or name} must be {kind} (smallest eigenvalue {smallest:.6e})")
