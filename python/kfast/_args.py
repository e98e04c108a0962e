"""Checks of the scalar arguments (counts, tolerances, flags, choices): a ``KfastError`` (a
ValueError) naming the argument, never a bare TypeError or OverflowError from deeper down."""

from __future__ import annotations

from typing import Optional

import numpy as np

from kfast._kfast import KfastError

# Counts and indices reach the core as 64-bit integers.
_INDEX_MAX = 2**63 - 1


def index(name: str, value: object) -> int:
    """A count or index: a Python or NumPy integer (not a bool), 0 <= value < 2**63."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise KfastError(f"{name}: expected an integer, got {value!r}")
    if value < 0:
        raise KfastError(f"{name}: must be >= 0, got {value}")
    if value > _INDEX_MAX:
        raise KfastError(f"{name}: is too large ({value})")
    return int(value)


def tolerance(name: str, value: object) -> Optional[float]:
    """None, or a number >= 0 (inf included: e.g. gains frozen at once)."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise KfastError(f"{name}: expected a number, got {value!r}")
    try:
        tol = float(value)  # type: ignore[arg-type]
    except OverflowError:  # an integer beyond float's range, e.g. 10**400
        raise KfastError(f"{name}: is too large ({value!r})") from None
    except (TypeError, ValueError):
        raise KfastError(f"{name}: expected a number, got {value!r}") from None
    if not tol >= 0:
        raise KfastError(f"{name}: must be >= 0, got {value!r}")
    return tol


def flag(name: str, value: object) -> bool:
    """A bool (Python or NumPy); strings such as 'no' are refused rather than read as True."""
    if not isinstance(value, (bool, np.bool_)):
        raise KfastError(f"{name}: expected True or False, got {value!r}")
    return bool(value)


def choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    """One of ``choices`` (exactly, as a str)."""
    if not isinstance(value, str) or value not in choices:
        raise KfastError(f"{name}: expected one of {choices}, got {value!r}")
    return value
