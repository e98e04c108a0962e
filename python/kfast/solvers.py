"""Riccati and Lyapunov solvers with SciPy's argument conventions (drop-in replacements for
``scipy.linalg.solve_discrete_are``, ``solve_continuous_are``, ``solve_discrete_lyapunov``
and ``solve_continuous_lyapunov``), computed in Rust. Real input only.
"""

from __future__ import annotations

from typing import Any, Optional, cast

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._arrays import as_float64
from kfast._typing import DareMethod

__all__ = ["solve_discrete_are", "solve_continuous_are", "solve_discrete_lyapunov", "solve_continuous_lyapunov"]

DARE_METHODS = ("doubling", "newton", "iteration", "eigen")


def _matrix(name: str, value: ArrayLike) -> np.ndarray:
    a = as_float64(name, value)
    if a.ndim == 0:
        return a.reshape(1, 1)
    if a.ndim != 2:
        raise _kfast.KfastError(f"{name}: expected a 2-D array, got shape {a.shape}")
    return a


def _optional(name: str, value: Optional[ArrayLike]) -> Optional[np.ndarray]:
    return None if value is None else _matrix(name, value)


def solve_discrete_are(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    e: Optional[ArrayLike] = None,
    s: Optional[ArrayLike] = None,
    method: DareMethod = "doubling",
    balanced: Any = None,
) -> np.ndarray:
    """The stabilizing X of a'Xa - e'Xe - (a'Xb + s)(b'Xb + r)^-1 (b'Xa + s') + q = 0.

    methods: "doubling" (structure-preserving doubling, default, refined by Newton steps
    when its relative residual exceeds 1e-12; needs r invertible and falls back to
    "iteration" refined by Newton when r is singular), "newton" (Newton-Hewer,
    Söderström ex. 6.23), "iteration" (Riccati iteration (6.90); singular r allowed),
    "eigen" (eigenvectors of the symplectic matrix, Söderström 6.8; the extended pencil
    (6.125)-(6.129) when a - b r^-1 s' is singular).

    When the method finds no stabilizing solution (doubling from zero can stop at a
    non-stabilizing fixed point when q - s r^-1 s' is singular, or diverge when it is
    indefinite), the solver falls back to Newton-Hewer from a stabilizing gain, then to the
    eigenvectors of the extended pencil of size 2n + m (no inverse of r or a needed), and
    raises ``kfast.NoStabilizingSolutionError`` only when these find none either (a fallback's
    closed loop must stay 1e-8 inside the unit circle); it never returns another fixed point.
    The fallbacks cost nothing when the method succeeds. For the Kalman filter's P(t|t-1):
    a = F', b = H', q = Q, r = R, s = N. ``balanced`` is accepted for SciPy compatibility and
    ignored.
    """
    return dare(a, b, q, r, e=e, s=s, method=method)["x"]


def dare(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    e: Optional[ArrayLike] = None,
    s: Optional[ArrayLike] = None,
    method: DareMethod = "doubling",
) -> dict:
    """``solve_discrete_are`` with the details: a dict with x, gain K = (b'Xb + r)^-1 (b'Xa + s'),
    closed_loop_eigenvalues of a - bK, residual (relative) and iterations."""
    if method not in DARE_METHODS:
        raise _kfast.KfastError(f"method: expected one of {DARE_METHODS}, got {method!r}")
    return _kfast.dare(
        _matrix("a", a), _matrix("b", b), _matrix("q", q), _matrix("r", r), _optional("e", e), _optional("s", s), cast(DareMethod, method)
    )


def solve_continuous_are(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    e: Optional[ArrayLike] = None,
    s: Optional[ArrayLike] = None,
    balanced: Any = None,
) -> np.ndarray:
    """The stabilizing X of a'Xe + e'Xa - (e'Xb + s) r^-1 (b'Xe + s') + q = 0 (Hamiltonian
    eigenvectors refined by Newton-Kleinman). Raises ``kfast.NoStabilizingSolutionError``."""
    return care(a, b, q, r, e=e, s=s)["x"]


def care(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    e: Optional[ArrayLike] = None,
    s: Optional[ArrayLike] = None,
) -> dict:
    """``solve_continuous_are`` with the details (x, gain r^-1 (b'Xe + s'), closed-loop
    eigenvalues, residual, iterations)."""
    return _kfast.care(_matrix("a", a), _matrix("b", b), _matrix("q", q), _matrix("r", r), _optional("e", e), _optional("s", s))


def solve_discrete_lyapunov(a: ArrayLike, q: ArrayLike) -> np.ndarray:
    """X with X = a X a' + q (SciPy's convention a X a^H - X + q = 0), Bartels-Stewart on the
    real Schur form. Raises ``kfast.KfastError`` when the solution is not unique
    (lambda_i lambda_j = 1)."""
    return _kfast.solve_discrete_lyapunov(_matrix("a", a), _matrix("q", q))


def solve_continuous_lyapunov(a: ArrayLike, q: ArrayLike) -> np.ndarray:
    """X with a X + X a' = q (SciPy's convention; a state covariance needs q = -Qc).
    Raises ``kfast.KfastError`` when the solution is not unique (lambda_i + lambda_j = 0)."""
    return _kfast.solve_continuous_lyapunov(_matrix("a", a), _matrix("q", q))
