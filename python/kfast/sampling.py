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

    Raises
    ------
    KfastError
        For input that is not a finite real square matrix.

    Notes
    -----
    Scaling and squaring with the degree-13 Padé approximant (Higham 2005).

    Examples
    --------
    >>> print(kfast.expm([[0.0, 1.0], [0.0, 0.0]]))
    [[1. 1.]
     [0. 1.]]
    >>> print(round(float(kfast.expm(1.0)[0, 0]), 12))
    2.718281828459
    """
    return _kfast.expm(_matrix("a", a))


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
        The interval, or T intervals (then every output is a per-step stack), all > 0.
    B : array_like, shape (n, k), optional

    Returns
    -------
    Discretized
        ``F, Qd, Bd``: e^{A dt}, the discrete process noise covariance and the input matrix
        (None without B); (n, n) for a scalar dt, (T, n, n) for an array.

    Raises
    ------
    KfastError
        For invalid matrices or intervals.

    Notes
    -----
    Söderström (4.99)-(4.103)::

        F = e^{A h},   Qd = integral over [0, h] of e^{A s} Qc e^{A' s} ds,   Bd = (integral of e^{A s} ds) B

    from Van Loan's (1978) block exponential in its inverse-free form,
    exp(h [[-A, Qc], [0, A']]) = [[., E12], [0, E22]], F = E22', Qd = F E12. Qd is full even when
    Qc is sparse.

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
    dt_arr = as_float64("dt", dt)
    if dt_arr.ndim > 1:
        raise _kfast.KfastError(f"dt: expected a scalar or a 1-D array, got shape {dt_arr.shape}")
    out = _kfast.discretize(_matrix("A", A), _matrix("Qc", Qc), np.atleast_1d(dt_arr), None if B is None else _matrix("B", B))
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
        if d.ndim != 1:
            raise _kfast.KfastError(f"dt: expected a scalar or a 1-D array, got shape {d.shape}")
    bad = np.flatnonzero(~(d > 0) | ~np.isfinite(d))
    if len(bad):
        raise _kfast.KfastError(f"dt at step {bad[0]}: must be positive and finite, got {d[bad[0]]}")
    return d


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
        is not a covariance (Grewal & Andrews problem 4.27).

    Examples
    --------
    Grewal & Andrews ex. 4.7: dx/dt = -x + w with unit intensity has P(inf) = 1/2.

    >>> print(kfast.stationary_cov_continuous(-1.0, 1.0))
    [[0.5]]
    """
    from kfast.riccati.solvers import solve_continuous_lyapunov

    A, Qc = _matrix("A", A), _matrix("Qc", Qc)
    top = float(np.linalg.eigvals(A).real.max())
    if top >= 0:
        raise _kfast.KfastError(
            f"A: is not stable (largest real part of an eigenvalue {top:.6g}): the state has no stationary covariance"
        )
    return solve_continuous_lyapunov(A, -Qc)


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
    A, H = _matrix("A", A), _matrix("H", H)
    sol = care(A.T, H.T, Qc, Rc)
    return KalmanBucy(P=sol["x"], K=sol["gain"].T, closed_loop_eigenvalues=sol["closed_loop_eigenvalues"])
