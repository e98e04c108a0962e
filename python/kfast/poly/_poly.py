"""Polynomials as 1-D coefficient arrays in descending powers of q (or z), NumPy's ``poly1d``
order (DESIGN: A, C and spectral factors monic). Laurent polynomials (products such as
C(z) C(z^-1)) are symmetric coefficient arrays, highest power first, centred on z^0."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from kfast._arrays import as_float64
from kfast import _kfast
from kfast._kfast import KfastError

__all__ = ["poly", "monic", "polymul", "polyadd", "polysub", "reciprocal", "laurent", "trim", "roots", "require_stable"]


def poly(name: str, value: ArrayLike, allow_zero: bool = False) -> np.ndarray:
    """A finite 1-D coefficient array (a scalar is degree 0), leading zeros removed."""
    a = as_float64(name, value)
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1 or a.size == 0:
        raise KfastError(f"{name}: expected a 1-D array of polynomial coefficients, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise KfastError(f"{name}: coefficients must be finite, got {a}")
    a = trim(a)
    if not allow_zero and not np.any(a):
        raise KfastError(f"{name}: is the zero polynomial")
    return a


def monic(name: str, value: ArrayLike) -> np.ndarray:
    """A monic polynomial (leading coefficient 1, as Söderström's A and C), else a clear error."""
    a = poly(name, value)
    if a[0] != 1.0:
        raise KfastError(f"{name}: must be monic (leading coefficient 1), got leading coefficient {a[0]:g}")
    return a


def trim(a: np.ndarray) -> np.ndarray:
    """``a`` without leading zeros (the zero polynomial stays [0])."""
    nz = np.flatnonzero(a)
    return a[nz[0]:] if nz.size else a[-1:] * 0.0


def polymul(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """The product A(z) B(z) (descending coefficients)."""
    return np.convolve(np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float)))


def polyadd(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """A(z) + B(z), the shorter padded on the left (descending coefficients)."""
    a, b = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float))
    n = max(len(a), len(b))
    return np.pad(a, (n - len(a), 0)) + np.pad(b, (n - len(b), 0))


def polysub(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """A(z) - B(z)."""
    return polyadd(a, -np.atleast_1d(np.asarray(b, float)))


def reciprocal(a: ArrayLike) -> np.ndarray:
    """The reciprocal polynomial z^deg A · A(z^-1): the coefficients reversed (its zeros are the
    inverses of A's)."""
    return np.atleast_1d(np.asarray(a, float))[::-1].copy()


def laurent(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """The Laurent polynomial A(z) B(z^-1) as its coefficients from z^(deg A) down to z^-(deg B)
    (so ``laurent(c, c)`` is the symmetric C C* of a spectrum, centred on z^0)."""
    return polymul(a, reciprocal(b))


def roots(p: ArrayLike) -> np.ndarray:
    """The zeros of p (complex), by the compiled companion-matrix eigenvalue solve."""
    return _kfast.poly_roots(np.ascontiguousarray(np.atleast_1d(np.asarray(p, dtype=float))))


def require_stable(name: str, p: np.ndarray, margin: float = 0.0) -> None:
    """A clear error unless every zero of p is strictly inside the unit circle (|z| < 1 - margin)."""
    if len(p) > 1 and np.abs(roots(p)).max() >= 1.0 - margin:
        raise KfastError(f"{name}: must have its zeros strictly inside the unit circle")
