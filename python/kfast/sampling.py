"""Continuous-time models: matrix exponential, exact (Van Loan) discretization, irregular
sampling, and the stationary Kalman-Bucy filter (Söderström (4.99)-(4.103); docs/algorithms.md, "Sampling").

Conventions: dx = A x dt + B u dt + dbeta with E[dbeta dbeta'] = Qc dt, so Qc is a continuous
white-noise *intensity* (its discrete covariance over an interval h is Qd(h), about Qc h for
small h, never Qc itself). Inputs are held constant over each interval (zero-order hold).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._arrays import as_float64
from kfast.riccati.solvers import _matrix, care

__all__ = ["expm", "discretize", "Discretized", "kalman_bucy", "KalmanBucy", "intervals", "stationary_cov_continuous"]


def expm(a: ArrayLike) -> np.ndarray:
    """The matrix exponential e^a.

    Parameters
    ----------
    a : array_like, shape (n, n)

    Returns
    -------
    ndarray, shape (n, n)
        Every entry finite.

    Raises
    ------
    KfastError
        Naming ``a``: for input that is not a finite real square matrix (masked entries
        included), and when e^a overflows double precision (an entry beyond ±1.8e308, e.g.
        ``expm(diag(1e5, -1e5))``), where ``scipy.linalg.expm`` returns inf entries.

    Notes
    -----
    Scaling and squaring, e^a = r_m(a / 2^s)^(2^s) with the Padé approximant r_m of degree m
    in {3, 5, 7, 9, 13}, m and s chosen from ||a^k||^(1/k) rather than ||a|| (Al-Mohy & Higham
    2009), so that a non-normal or nilpotent ``a`` of large norm is not over-scaled (each
    squaring doubles the rounding error). For a triangular ``a`` the diagonal and first
    superdiagonal are recomputed exactly after each squaring: ``expm([[0, 1e20], [0, 0]])`` is
    exactly [[1, 1e20], [0, 1]]. docs/algorithms.md, "Matrix exponential".

    Examples
    --------
    >>> print(kfast.expm([[0.0, 1.0], [0.0, 0.0]]))
    [[1. 1.]
     [0. 1.]]
    >>> print(round(float(kfast.expm(1.0)[0, 0]), 12))
    2.718281828459
    """
    return _kfast.expm(_matrix("a", a))


def _square(name: str, value: ArrayLike) -> np.ndarray:
    a = _matrix(name, value)
    if a.shape[0] != a.shape[1]:
        raise _kfast.KfastError(f"{name}: expected a square matrix, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise _kfast.KfastError(f"{name}: contains a non-finite value")
    return a


def _covariance(name: str, value: ArrayLike, n: int, definite: bool = False, size_from: str = "A") -> np.ndarray:
    """An (n, n) symmetric positive semidefinite (``definite``: positive definite) matrix, with
    the relative tolerance 1e-10 of the core's checks; an error naming ``name`` otherwise
    (``size_from``: the argument n comes from, named in the shape error)."""
    c = _square(name, value)
    if c.shape != (n, n):
        raise _kfast.KfastError(f"{name}: expected shape ({n}, {n}) as {size_from} has size {n}, got {c.shape}")
    scale = np.abs(c).max() if n else 0.0
    if np.abs(c - c.T).max(initial=0.0) > 1e-10 * scale:
        raise _kfast.KfastError(f"{name}: not symmetric")
    if n:
        eig = np.linalg.eigvalsh(c)
        tol = 1e-10 * np.abs(eig).max()
        if (eig[0] <= tol) if definite else (eig[0] < -tol):
            kind = "definite" if definite else "semidefinite"
            raise _kfast.KfastError(f"{name}: not positive {kind} (smallest eigenvalue {eig[0]:.6e})")
    return c


class Discretized(NamedTuple):
    """The exact discrete model: ``F, Qd, Bd = kfast.discretize(...)``."""

    F: np.ndarray
    """e^{A dt}: (n, n), or (T, n, n) for an array of dt."""
    Qd: np.ndarray
    """The integral of e^{As} Qc e^{A's} over [0, dt]: the discrete process noise covariance."""
    Bd: Optional[np.ndarray]
    """The integral of e^{As} ds times B (zero-order hold), or None without B."""


def discretize(A: ArrayLike, Qc: ArrayLike, dt: ArrayLike, B: Optional[ArrayLike] = None) -> Discretized:
    """Exact discretization of a continuous-time linear model.

    The model is dx = A x dt + B u dt + dbeta with E[dbeta dbeta'] = Qc dt (Qc a white-noise
    intensity), the input held constant over each interval (zero-order hold).

    Parameters
    ----------
    A : array_like, shape (n, n)
    Qc : array_like, shape (n, n)
        Symmetric positive semidefinite intensity.
    dt : float or array_like, shape (T,)
        The interval, or T >= 1 intervals (then every output is a per-step stack), all
        positive and finite.
    B : array_like, shape (n, k), optional

    Returns
    -------
    Discretized
        ``F, Qd, Bd``: e^{A dt}, the discrete process noise covariance and the input matrix
        (None without B); (n, n) for a scalar dt, (T, n, n) for an array.

    Raises
    ------
    KfastError
        Naming the argument (a ValueError): ``A``, ``Qc`` or ``B`` of the wrong shape, not
        real (complex, bool, object), not finite or with masked entries; ``Qc`` not symmetric
        positive semidefinite (an indefinite intensity would give an indefinite Qd); ``dt``
        not a scalar or a non-empty 1-D array, or not positive and finite (``dt at step t``
        for an array); and ``dt`` when the sampled model overflows double precision (F, Qd or
        Bd would have an entry beyond ±1.8e308: e.g. A = 1, dt = 1000).

    Notes
    -----
    Söderström (4.99)-(4.103)::

        F = e^{A h},   Qd = integral over [0, h] of e^{A s} Qc e^{A' s} ds,   Bd = (integral of e^{A s} ds) B

    from Van Loan's (1978) block exponential in its inverse-free form,
    exp(h [[-A, Qc], [0, A']]) = [[., E12], [0, E22]], F = E22', Qd = F E12, evaluated at
    h = dt / 2^s (s chosen as in :func:`expm`) and then doubled s times with
    Qd(2h) = Qd(h) + F(h) Qd(h) F(h)', Bd(2h) = Bd(h) + F(h) Bd(h), F(2h) = F(h)^2. So a long
    interval of a stable model is exact too (A = -1, Qc = 2, dt = 1e300 gives F = 0, Qd = 1:
    the stationary variance), and Qd stays positive semidefinite. Qd is full even when Qc is
    sparse. docs/algorithms.md, "Van Loan".

    Examples
    --------
    The damped resonator of Grewal & Andrews ex. 4.9 (omega_r = 2, omega_d = 1/3, q = 1,
    dt = 0.1):

    >>> A = np.array([[0.0, 1.0], [-(4 + 1 / 9), -2 / 3]])
    >>> F, Qd, Bd = kfast.discretize(A, np.diag([0.0, 1.0]), 0.1)
    >>> print((Qd * 1e3).round(5))
    [[ 0.31459  4.6155 ]
     [ 4.6155  92.36921]]
    >>> Bd is None
    True
    """
    A_arr, Qc_arr = _matrix("A", A), _matrix("Qc", Qc)
    B_arr = None if B is None else _matrix("B", B)
    dt_arr = as_float64("dt", dt)
    if dt_arr.ndim > 1 or dt_arr.size == 0:
        raise _kfast.KfastError(f"dt: expected a scalar or a non-empty 1-D array, got shape {dt_arr.shape}")
    try:
        out = _kfast.discretize(A_arr, Qc_arr, np.atleast_1d(dt_arr), B_arr)
    except _kfast.KfastError as exc:
        if dt_arr.ndim == 0 and str(exc).startswith("dt at step 0: "):
            # the core always sees a stack; a scalar dt has no step
            raise _kfast.KfastError("dt: " + str(exc)[len("dt at step 0: ") :]) from None
        raise
    if dt_arr.ndim == 0:
        return Discretized(out["F"][0], out["Qd"][0], out["Bd"][0] if "Bd" in out else None)
    return Discretized(out["F"], out["Qd"], out.get("Bd"))


def intervals(dt: Optional[ArrayLike] = None, times: Optional[ArrayLike] = None) -> np.ndarray:
    """The per-step intervals of an irregularly sampled series.

    Parameters
    ----------
    dt : array_like, shape (T,), optional
        One interval per step: dt[t] is the interval from step t to t+1 (the last one only
        moves x(T|T-1) past the data).
    times : array_like, shape (T,), optional
        Strictly increasing sample times; the last step reuses the last interval.

    Returns
    -------
    ndarray, shape (T,)

    Raises
    ------
    KfastError
        Unless exactly one of dt and times is given, and all intervals are positive and finite.

    Examples
    --------
    >>> print(kfast.sampling.intervals(times=[0.0, 0.5, 2.0]))
    [0.5 1.5 1.5]
    """
    if (dt is None) == (times is None):
        raise _kfast.KfastError("dt, times: give exactly one of them")
    if times is not None:
        t = as_float64("times", times)
        if t.ndim != 1 or len(t) < 2:
            raise _kfast.KfastError(f"times: expected a 1-D array of at least 2 sample times, got shape {t.shape}")
        d = np.diff(t)
        bad = np.flatnonzero(~(d > 0))
        if len(bad):
            raise _kfast.KfastError(f"times at step {bad[0] + 1}: not strictly increasing ({t[bad[0]]} then {t[bad[0] + 1]})")
        d = np.append(d, d[-1])
    else:
        d = np.atleast_1d(as_float64("dt", dt))
        if d.ndim != 1 or len(d) == 0:
            raise _kfast.KfastError(f"dt: expected a scalar or a non-empty 1-D array, got shape {d.shape}")
    bad = np.flatnonzero(~(d > 0) | ~np.isfinite(d))
    if len(bad):
        raise _kfast.KfastError(f"dt at step {bad[0]}: must be positive and finite, got {d[bad[0]]}")
    return d


def _renamed(exc: Exception, names: dict) -> Exception:
    """``exc`` (of the same type) with the solver's argument name at its head replaced by the
    name the caller passed (a solver called as a building block names its own arguments)."""
    head, sep, rest = str(exc).partition(":")
    first, _, step = head.partition(" at step ")
    if not sep or first not in names:
        return exc
    return type(exc)(names[first] + (f" at step {step}" if step else "") + sep + rest)


def stationary_cov_continuous(A: ArrayLike, Qc: ArrayLike) -> np.ndarray:
    """The stationary covariance of dx = A x dt + dbeta with intensity Qc.

    Parameters
    ----------
    A : array_like, shape (n, n)
    Qc : array_like, shape (n, n)

    Returns
    -------
    ndarray, shape (n, n)
        Pi with A Pi + Pi A' + Qc = 0 (Söderström (4.90)-(4.92)).

    Raises
    ------
    KfastError
        Unless A is Hurwitz: the Lyapunov equation may still have a (negative) solution, which
        is not a covariance (Grewal & Andrews problem 4.27). Also naming ``A`` or ``Qc`` when
        they are not finite square matrices of one size, and ``Qc`` when it is not symmetric
        positive semidefinite.

    Examples
    --------
    Grewal & Andrews ex. 4.7: dx/dt = -x + w with unit intensity has P(inf) = 1/2.

    >>> print(kfast.stationary_cov_continuous(-1.0, 1.0))
    [[0.5]]
    """
    from kfast.riccati.solvers import solve_continuous_lyapunov

    A = _square("A", A)
    Qc = _covariance("Qc", Qc, len(A))
    top = float(np.linalg.eigvals(A).real.max()) if len(A) else -np.inf
    if top >= 0:
        raise _kfast.KfastError(
            f"A: is not stable (largest real part of an eigenvalue {top:.6g}): the state has no stationary covariance"
        )
    try:
        return solve_continuous_lyapunov(A, -Qc)
    except _kfast.KfastError as exc:
        raise _renamed(exc, {"a": "A", "q": "Qc"}) from None


@dataclass(frozen=True, repr=False)
class KalmanBucy:
    """The stationary continuous-time (Kalman-Bucy) filter of dx = A x dt + dbeta,
    dy = H x dt + dv with intensities Qc and Rc: A P + P A' - P H' Rc^-1 H P + Qc = 0."""

    P: np.ndarray
    """Stationary error covariance."""
    K: np.ndarray
    """Gain P H' Rc^-1: dx^ = A x^ dt + K (dy - H x^ dt)."""
    closed_loop_eigenvalues: np.ndarray
    """Eigenvalues of A - K H (all in the open left half-plane)."""

    def __repr__(self) -> str:
        return f"KalmanBucy(n={len(self.P)})"


def kalman_bucy(A: ArrayLike, Qc: ArrayLike, H: ArrayLike, Rc: ArrayLike) -> KalmanBucy:
    """The stationary continuous-time (Kalman-Bucy) filter.

    For dx = A x dt + dbeta, dy = H x dt + dv with intensities Qc and Rc.

    Parameters
    ----------
    A : array_like, shape (n, n)
    Qc : array_like, shape (n, n)
    H : array_like, shape (m, n)
    Rc : array_like, shape (m, m)
        Positive definite.

    Returns
    -------
    KalmanBucy
        P (stationary error covariance), K = P H' Rc^-1 and the eigenvalues of A - K H.

    Raises
    ------
    NoStabilizingSolutionError
        When (A, H) is not detectable or the noise does not excite the unstable modes.
    KfastError
        Naming the argument: shapes that do not fit, non-finite or masked entries, ``Qc`` not
        symmetric positive semidefinite, ``Rc`` not symmetric positive definite.

    Notes
    -----
    P solves A P + P A' - P H' Rc^-1 H P + Qc = 0, i.e. ``solve_continuous_are(A', H', Qc, Rc)``;
    the filter is dx^ = A x^ dt + K (dy - H x^ dt).

    Examples
    --------
    >>> kb = kfast.kalman_bucy(A=-1.0, Qc=1.0, H=1.0, Rc=1.0)
    >>> print(kb.P.round(6), kb.K.round(6), kb.closed_loop_eigenvalues.real.round(6))
    [[0.414214]] [[0.414214]] [-1.414214]
    """
    A = _square("A", A)
    H = _matrix("H", H)
    if H.shape[1] != len(A):
        raise _kfast.KfastError(f"H: expected {len(A)} columns like A, got shape {H.shape}")
    if H.shape[0] == 0:
        raise _kfast.KfastError("H: has no rows: the output needs at least one component")
    Qc = _covariance("Qc", Qc, len(A))
    Rc = _covariance("Rc", Rc, len(H), definite=True, size_from="H")
    try:
        sol = care(A.T, H.T, Qc, Rc)
    except _kfast.KfastError as exc:  # the dual CARE: a = A', b = H', q = Qc, r = Rc
        raise _renamed(exc, {"a": "A", "b": "H", "q": "Qc", "r": "Rc"}) from None
    return KalmanBucy(P=sol["x"], K=sol["gain"].T, closed_loop_eigenvalues=sol["closed_loop_eigenvalues"])
