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
    """The stabilizing solution X of the discrete algebraic Riccati equation (SciPy's convention).

    ::

        a' X a - e' X e - (a' X b + s) (b' X b + r)^-1 (b' X a + s') + q = 0

    A drop-in replacement for ``scipy.linalg.solve_discrete_are``, computed in Rust.

    Parameters
    ----------
    a : array_like, shape (n, n)
    b : array_like, shape (n, k)
    q : array_like, shape (n, n)
        Symmetric.
    r : array_like, shape (k, k)
        Symmetric.
    e : array_like, shape (n, n), optional
        Nonsingular (identity when omitted).
    s : array_like, shape (n, k), optional
        Cross term (zero when omitted).
    method : {"doubling", "newton", "iteration", "eigen"}
        "doubling" (structure-preserving doubling, default, refined by Newton steps when its
        relative residual exceeds 1e-12; needs r invertible and falls back to "iteration"
        refined by Newton when r is singular), "newton" (Newton-Hewer), "iteration" (the
        Riccati iteration; singular r allowed), "eigen" (eigenvectors of the symplectic
        matrix; the extended pencil when a - b r^-1 s' is singular).
    balanced : ignored
        Accepted for SciPy compatibility.

    Returns
    -------
    ndarray, shape (n, n)
        The stabilizing X: a - b K is stable with K = (b' X b + r)^-1 (b' X a + s').

    Raises
    ------
    NoStabilizingSolutionError
        When neither the method nor the fallbacks (see Notes) find a stabilizing solution; it
        never returns another fixed point instead.
    KfastError
        For invalid input or an unknown method.

    Notes
    -----
    For the Kalman filter's stationary P(t|t-1) (Söderström (6.91)) call it with a = F',
    b = H', q = Q, r = R, s = N. The methods: Newton-Hewer is Söderström ex. 6.23, the
    iteration is (6.90), the eigenvector method is Söderström sec. 6.8 (Lemmas 6.5-6.6), the
    extended pencil (6.125)-(6.129).

    When the method finds no stabilizing solution (doubling from zero can stop at a
    non-stabilizing fixed point when q - s r^-1 s' is singular, or diverge when it is
    indefinite), the solver falls back to Newton-Hewer from a stabilizing gain, then to the
    eigenvectors of the extended pencil of size 2n + m (no inverse of r or a needed), and
    raises only when these find none either (a fallback's closed loop must stay 1e-8 inside
    the unit circle). The fallbacks cost nothing when the method succeeds.
    :func:`kfast.riccati.solvers.dare` also returns the gain, the closed-loop eigenvalues, the residual
    and the iterations.

    Examples
    --------
    Söderström ex. 6.3 (AR(2) in noise, r = 1):

    >>> F = np.array([[1.5, 1.0], [-0.7, 0.0]])
    >>> H = np.array([[1.0, 0.0]])
    >>> P = kfast.solve_discrete_are(F.T, H.T, np.diag([1.0, 0.0]), 1.0)
    >>> print(P.round(4))
    [[ 2.2277 -0.5955]
     [-0.5955  0.3382]]
    >>> bool(np.allclose(P, kfast.solve_discrete_are(F.T, H.T, np.diag([1.0, 0.0]), 1.0, method="eigen")))
    True
    """
    return dare(a, b, q, r, e=e, s=s, method=method, eigenvalues=False)["x"]


def dare(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    e: Optional[ArrayLike] = None,
    s: Optional[ArrayLike] = None,
    method: DareMethod = "doubling",
    eigenvalues: bool = True,
) -> dict:
    """``solve_discrete_are`` with the details: a dict with x, gain K = (b'Xb + r)^-1 (b'Xa + s'),
    closed_loop_eigenvalues of a - bK (with e: of (a - bK) e^-1; left out with
    ``eigenvalues=False``, which saves an eigenvalue solve, about 40% of the time at n = 20-100),
    residual (relative), iterations and method (the method that produced x: the one asked for,
    or a fallback, "newton" or "pencil")."""
    if method not in DARE_METHODS:
        raise _kfast.KfastError(f"method: expected one of {DARE_METHODS}, got {method!r}")
    args = (_matrix("a", a), _matrix("b", b), _matrix("q", q), _matrix("r", r), _optional("e", e), _optional("s", s))
    return _kfast.dare(*args, cast(DareMethod, method), eigenvalues)


def solve_continuous_are(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    e: Optional[ArrayLike] = None,
    s: Optional[ArrayLike] = None,
    balanced: Any = None,
) -> np.ndarray:
    """The stabilizing solution X of the continuous algebraic Riccati equation (SciPy's convention).

    ::

        a' X e + e' X a - (e' X b + s) r^-1 (b' X e + s') + q = 0

    A drop-in replacement for ``scipy.linalg.solve_continuous_are``, computed in Rust.

    Parameters
    ----------
    a : array_like, shape (n, n)
    b : array_like, shape (n, k)
    q : array_like, shape (n, n)
        Symmetric.
    r : array_like, shape (k, k)
        Symmetric positive definite.
    e : array_like, shape (n, n), optional
        Nonsingular (identity when omitted).
    s : array_like, shape (n, k), optional
        Cross term (zero when omitted).
    balanced : ignored
        Accepted for SciPy compatibility.

    Returns
    -------
    ndarray, shape (n, n)
        The stabilizing X: a - b K is Hurwitz with K = r^-1 (b' X e + s').

    Raises
    ------
    NoStabilizingSolutionError
        When there is no stabilizing solution.
    KfastError
        For invalid input.

    Notes
    -----
    Eigenvectors of the Hamiltonian matrix, refined by Newton-Kleinman steps. The Kalman-Bucy
    filter's stationary covariance solves it with a = A', b = H', q = Qc, r = Rc
    (Söderström (4.99)-(4.103) for the model; see :func:`kfast.kalman_bucy`).

    Examples
    --------
    dx = -x dt + dbeta, dy = x dt + dv with unit intensities: -2 X - X^2 + 1 = 0, X = sqrt(2) - 1.

    >>> print(kfast.solve_continuous_are(-1.0, 1.0, 1.0, 1.0).round(6))
    [[0.414214]]
    """
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
    """X with X = a X a' + q (SciPy's convention a X a^H - X + q = 0).

    Parameters
    ----------
    a : array_like, shape (n, n)
    q : array_like, shape (n, n)

    Returns
    -------
    ndarray, shape (n, n)

    Raises
    ------
    KfastError
        When the solution is not unique (lambda_i lambda_j = 1 for eigenvalues of a), or for
        invalid input.

    Notes
    -----
    Bartels-Stewart on the real Schur form of a. With a = F stable and q = Q the solution is
    the stationary state covariance Pi = F Pi F' + Q (Söderström (4.22)).

    Examples
    --------
    >>> print(kfast.solve_discrete_lyapunov(0.8, 0.68).round(6))  # 0.68 / (1 - 0.8^2)
    [[1.888889]]
    """
    return _kfast.solve_discrete_lyapunov(_matrix("a", a), _matrix("q", q))


def solve_continuous_lyapunov(a: ArrayLike, q: ArrayLike) -> np.ndarray:
    """X with a X + X a' = q (SciPy's convention).

    Parameters
    ----------
    a : array_like, shape (n, n)
    q : array_like, shape (n, n)
        For a state covariance, q = -Qc.

    Returns
    -------
    ndarray, shape (n, n)

    Raises
    ------
    KfastError
        When the solution is not unique (lambda_i + lambda_j = 0 for eigenvalues of a), or for
        invalid input.

    Notes
    -----
    Bartels-Stewart on the real Schur form of a. With a = A Hurwitz and q = -Qc the solution
    is the stationary covariance of dx = A x dt + dbeta (Söderström (4.90)-(4.92)).

    Examples
    --------
    A damped resonator (Grewal & Andrews ex. 4.9: omega_r = 2, omega_d = 1/3): the stationary
    covariance is diag(q / (4 omega_d (omega_r^2 + omega_d^2)), q / (4 omega_d)).

    >>> A = np.array([[0.0, 1.0], [-(4 + 1 / 9), -2 / 3]])
    >>> X = kfast.solve_continuous_lyapunov(A, -np.diag([0.0, 1.0]))
    >>> print(np.diag(X).round(6))
    [0.182432 0.75    ]
    """
    return _kfast.solve_continuous_lyapunov(_matrix("a", a), _matrix("q", q))
