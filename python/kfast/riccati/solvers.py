"""Riccati and Lyapunov solvers with SciPy's argument conventions (drop-in replacements for
``scipy.linalg.solve_discrete_are``, ``solve_continuous_are``, ``solve_discrete_lyapunov``
and ``solve_continuous_lyapunov``), computed in Rust.

Complex input (Hermitian q, r for the Riccati equations) is solved through the real embedding
M -> [[Re M, -Im M], [Im M, Re M]] (docs/algorithms.md, "Complex and generalized equations"):
it maps products, inverses and conjugate transposes to their real counterparts, so the real
equation of twice the size has the embedded solution. The Lyapunov solvers also take a
nonsingular e (generalized equations), reduced to the standard ones by e^-1.
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


def _is_complex(*values: Optional[ArrayLike]) -> bool:
    """Whether any of the given values has a complex dtype (values that are not arrays at all
    are left to the real path's checks, which name them)."""
    for v in values:
        try:
            if v is not None and np.iscomplexobj(np.asarray(v)):
                return True
        except (ValueError, TypeError):
            continue
    return False


def _complex_matrix(name: str, value: ArrayLike) -> np.ndarray:
    """A 2-D complex128 array with finite entries (a scalar is 1 x 1)."""
    a = np.asarray(value)
    if a.dtype.kind not in "fiuc":
        raise _kfast.KfastError(f"{name}: expected numbers, got dtype {a.dtype}")
    a = np.asarray(a, dtype=np.complex128)
    if a.ndim == 0:
        a = a.reshape(1, 1)
    if a.ndim != 2:
        raise _kfast.KfastError(f"{name}: expected a 2-D array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise _kfast.KfastError(f"{name}: contains a non-finite value")
    return a


def _realify(m: Optional[np.ndarray]) -> Optional[np.ndarray]:
    """The real embedding [[Re m, -Im m], [Im m, Re m]]."""
    if m is None:
        return None
    return np.block([[m.real, -m.imag], [m.imag, m.real]])


def _complexify(x: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """The complex matrix whose embedding is (nearest to) x, of shape (rows, cols)."""
    real = (x[:rows, :cols] + x[rows:, cols:]) / 2
    imag = (x[rows:, :cols] - x[:rows, cols:]) / 2
    return real + 1j * imag


def _reduce_by_e(name: str, e: Optional[ArrayLike], a: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(e^-1 a, e^-1 q e^-H) for a nonsingular e (a and q unchanged without e)."""
    if e is None:
        return a, q
    em = _complex_matrix("e", e) if np.iscomplexobj(np.asarray(e)) or np.iscomplexobj(a) else _matrix("e", e)
    n = a.shape[0]
    if em.shape != (n, n):
        raise _kfast.KfastError(f"e: expected shape ({n}, {n}) like a, got {em.shape}")
    if not np.all(np.isfinite(em)):
        raise _kfast.KfastError("e: contains a non-finite value")
    condition = np.linalg.cond(em)
    if condition > 1e12:
        raise _kfast.KfastError(f"e: must be nonsingular for {name} (condition number {condition:.3g})")
    ea = np.linalg.solve(em, a)
    eq = np.linalg.solve(em, np.linalg.solve(em, q.conj().T).conj().T)
    return ea, eq


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
    if _is_complex(a, b, q, r, e, s):
        return _complex_riccati(a, b, q, r, e, s, cast(DareMethod, method), eigenvalues)
    args = (_matrix("a", a), _matrix("b", b), _matrix("q", q), _matrix("r", r), _optional("e", e), _optional("s", s))
    return _kfast.dare(*args, cast(DareMethod, method), eigenvalues)


def _complex_riccati(a, b, q, r, e, s, method: Optional[DareMethod], eigenvalues: bool = True) -> dict:
    """A complex DARE (``method`` given) or CARE (``method=None``) through its real embedding;
    x Hermitian, gain complex, the closed-loop eigenvalues those of the complex closed loop."""
    am, bm, qm, rm = (_complex_matrix(k, v) for k, v in zip("abqr", (a, b, q, r)))
    em = None if e is None else _complex_matrix("e", e)
    sm = None if s is None else _complex_matrix("s", s)
    n, k = am.shape[0], bm.shape[1]
    for name, m in (("q", qm), ("r", rm)):
        if m.shape[0] == m.shape[1] and not np.allclose(m, m.conj().T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(m).max())):
            raise _kfast.KfastError(f"{name}: must be Hermitian (equal to its conjugate transpose)")
    real = [_realify(m) for m in (am, bm, qm, rm, em, sm)]
    discrete = method is not None
    solver: Any = _kfast.dare if discrete else _kfast.care
    out = dict(solver(*real, method, False) if discrete else solver(*real))
    x = _complexify(out["x"], n, n)
    out["x"] = (x + x.conj().T) / 2
    out["gain"] = _complexify(out["gain"], k, n)
    if eigenvalues:
        closed = am - bm @ out["gain"]
        if em is not None:
            closed = closed @ np.linalg.inv(em) if discrete else np.linalg.solve(em, closed)
        out["closed_loop_eigenvalues"] = np.linalg.eigvals(closed)
    return out


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
    if _is_complex(a, b, q, r, e, s):
        return _complex_riccati(a, b, q, r, e, s, None)
    return _kfast.care(_matrix("a", a), _matrix("b", b), _matrix("q", q), _matrix("r", r), _optional("e", e), _optional("s", s))


def solve_discrete_lyapunov(a: ArrayLike, q: ArrayLike, e: Optional[ArrayLike] = None) -> np.ndarray:
    """X with X = a X a' + q (SciPy's convention a X a^H - X + q = 0); with e, the generalized
    a X a^H - e X e^H + q = 0 (python-control's ``dlyap(A, Q, E=E)``).

    Parameters
    ----------
    a : array_like, shape (n, n)
        Real or complex.
    q : array_like, shape (n, n)
        Real or complex.
    e : array_like, shape (n, n), optional
        Nonsingular; the equation is reduced to the standard one with e^-1 a and e^-1 q e^-H.

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
    the stationary state covariance Pi = F Pi F' + Q (Söderström (4.22)). Complex input is
    solved through the real embedding, which needs lambda_i lambda_j != 1 for all eigenvalues of
    a and their conjugates (true for a stable a).

    Examples
    --------
    >>> print(kfast.solve_discrete_lyapunov(0.8, 0.68).round(6))  # 0.68 / (1 - 0.8^2)
    [[1.888889]]
    """
    return _lyapunov(_kfast.solve_discrete_lyapunov, "the discrete Lyapunov equation", a, q, e)


def _lyapunov(solver: Any, name: str, a: ArrayLike, q: ArrayLike, e: Optional[ArrayLike]) -> np.ndarray:
    """A (generalized, complex) Lyapunov equation by the real solver ``solver``."""
    if not _is_complex(a, q, e):
        am, qm = _matrix("a", a), _matrix("q", q)
        if e is not None:
            am, qm = _reduce_by_e(name, e, am, qm)
            am, qm = np.ascontiguousarray(am), np.ascontiguousarray(qm)
        return solver(am, qm)
    am, qm = _complex_matrix("a", a), _complex_matrix("q", q)
    am, qm = _reduce_by_e(name, e, am, qm)
    n = am.shape[0]
    if am.shape != (n, n) or qm.shape != (n, n):
        raise _kfast.KfastError(f"q: expected shape {am.shape} like a, got {qm.shape}")
    return _complexify(solver(_realify(am), _realify(qm)), n, n)


def solve_continuous_lyapunov(a: ArrayLike, q: ArrayLike, e: Optional[ArrayLike] = None) -> np.ndarray:
    """X with a X + X a' = q (SciPy's convention); with e, the generalized
    a X e^H + e X a^H = q (python-control's ``lyap(A, -q, E=E)``).

    Parameters
    ----------
    a : array_like, shape (n, n)
        Real or complex.
    q : array_like, shape (n, n)
        For a state covariance, q = -Qc. Real or complex.
    e : array_like, shape (n, n), optional
        Nonsingular; the equation is reduced to the standard one with e^-1 a and e^-1 q e^-H.

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
    is the stationary covariance of dx = A x dt + dbeta (Söderström (4.90)-(4.92)). Complex
    input is solved through the real embedding, which needs lambda_i + lambda_j != 0 for all
    eigenvalues of a and their conjugates (true for a Hurwitz a).

    Examples
    --------
    A damped resonator (Grewal & Andrews ex. 4.9: omega_r = 2, omega_d = 1/3): the stationary
    covariance is diag(q / (4 omega_d (omega_r^2 + omega_d^2)), q / (4 omega_d)).

    >>> A = np.array([[0.0, 1.0], [-(4 + 1 / 9), -2 / 3]])
    >>> X = kfast.solve_continuous_lyapunov(A, -np.diag([0.0, 1.0]))
    >>> print(np.diag(X).round(6))
    [0.182432 0.75    ]
    """
    return _lyapunov(_kfast.solve_continuous_lyapunov, "the continuous Lyapunov equation", a, q, e)
