"""Linear-quadratic control: the stationary regulator (``lqr``) and the finite-horizon one
(``lq_finite``), Söderström ch. 11. Sign convention: u = -L x.

Both run on the filter's Riccati code through duality (Söderström (11.19)-(11.31)): the control
problem (F, G, Q1, Q2, Q12, Q0) is the filter problem (F', G', Q1, Q2, Q12, P0 = Q0) in reversed
time, with S(t) = P(t̄|t̄-1) and L(t) = K_pred(t̄)'. So the stationary S is the DARE solution of
:func:`kfast.solve_discrete_are` (with SciPy's a = F, b = G, s = Q12) and the backward recursion
is the compiled Kalman filter run backwards over the horizon.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, index
from kfast._arrays import as_float64
from kfast._kfast import KfastError
from kfast._typing import DareMethod
from kfast.control._checks import matrix, symmetric_psd

__all__ = ["LQResult", "LQFiniteResult", "lqr", "lq_finite"]


@dataclass(frozen=True, repr=False)
class LQResult:
    """The stationary LQ regulator u = -L x (Söderström (11.47)-(11.48))."""

    L: np.ndarray
    """Feedback gain (k, n): L = (G' S G + Q2)^-1 (G' S F + Q12'); u = -L x."""
    S: np.ndarray
    """The stabilizing solution (n, n) of S = F' S F + Q1 - (F' S G + Q12)(G' S G + Q2)^-1 (G' S F + Q12')."""
    closed_loop: np.ndarray
    """F - G L (n, n)."""
    residual: float
    """Relative residual of the Riccati equation."""

    @cached_property
    def closed_loop_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of F - G L (inside the unit circle), computed on first access."""
        return _kfast.eigenvalues(self.closed_loop)

    def __repr__(self) -> str:
        rho = float(np.abs(self.closed_loop_eigenvalues).max())
        return f"LQResult(n={self.S.shape[0]}, k={self.L.shape[0]}, closed-loop radius={rho:.4g})"


@dataclass(frozen=True, repr=False)
class LQFiniteResult:
    """The finite-horizon LQ regulator u(t) = -L(t) x(t), t = 0..N-1 (Söderström (11.6)-(11.7))."""

    L: np.ndarray
    """Gains (N, k, n); u(t) = -L[t] x(t)."""
    S: np.ndarray
    """Riccati matrices (N + 1, n, n), S[N] = Q0: the cost to go from x(t) is x' S[t] x + sigma[t]."""
    sigma: np.ndarray
    """(N + 1,): the noise's share of the cost to go, sigma[t] = sum_{s >= t} tr S[s+1] Q(s)
    (zero without ``Q``); Söderström (11.14) and the Bellman form (11.122)."""
    expected_cost: Optional[float]
    """E ℓ = x0' S[0] x0 + tr S[0] P0 + sigma[0] under the optimal law with the state known
    (Söderström Thm 11.2, (11.14)); None when ``x0`` was not given."""

    def __repr__(self) -> str:
        cost = "" if self.expected_cost is None else f", expected_cost={self.expected_cost:.6g}"
        return f"LQFiniteResult(N={self.L.shape[0]}, n={self.S.shape[1]}, k={self.L.shape[1]}{cost})"


def lqr(
    F: ArrayLike,
    G: ArrayLike,
    Q1: ArrayLike,
    Q2: ArrayLike,
    Q12: Optional[ArrayLike] = None,
    method: DareMethod = "doubling",
) -> LQResult:
    """The stationary discrete-time LQ regulator u = -L x minimising
    sum_t [x' Q1 x + 2 x' Q12 u + u' Q2 u] for x(t+1) = F x(t) + G u(t) (Söderström (11.47)-(11.48)).

    Parameters
    ----------
    F : array_like, shape (n, n)
    G : array_like, shape (n, k)
        Input matrix (a vector is one column).
    Q1, Q2, Q12 : array_like, shapes (n, n), (k, k), (n, k)
        State, input and cross weights; [[Q1, Q12], [Q12', Q2]] must be symmetric positive
        semidefinite and G' S G + Q2 positive definite.
    method : {"doubling", "newton", "iteration", "eigen"}
        The DARE method of :func:`kfast.solve_discrete_are`.

    Returns
    -------
    LQResult
        L (u = -L x, the sign of python-control's ``dlqr``), S, the closed-loop eigenvalues of
        F - G L and the residual. python-control's ``dlqr(F, G, Q1, Q2, Q12)`` returns the same
        (K, S, E).

    Raises
    ------
    NoStabilizingSolutionError
        When (F, G) is not stabilizable or (F - G Q2^-1 Q12', Q1 - Q12 Q2^-1 Q12') has an
        unobservable mode on the unit circle: no stabilizing solution exists.

    Examples
    --------
    Söderström ex. 11.4 (a): the sampled double integrator, h = 0.5, Q1 = I, Q2 = 0.1.

    >>> h = 0.5
    >>> res = kfast.control.lqr([[1, h], [0, 1]], [h**2 / 2, h], np.eye(2), 0.1)
    >>> print(np.sort(res.closed_loop_eigenvalues.real).round(2))
    [0.27 0.58]
    """
    out = _kfast.lqr(
        _as_matrix("F", F),
        _as_matrix("G", G),
        _as_matrix("Q1", Q1),
        _as_matrix("Q2", Q2),
        None if Q12 is None else _as_matrix("Q12", Q12),
        choice("method", method, _METHODS),
    )
    return LQResult(L=out["L"], S=out["S"], closed_loop=out["closed_loop"], residual=float(out["residual"]))


_METHODS = ("doubling", "newton", "iteration", "eigen")


def _as_matrix(name: str, value: ArrayLike, stack: bool = False) -> np.ndarray:
    """float64, a scalar as 1 x 1 and a vector as a column (the core checks shapes and values)."""
    a = as_float64(name, value)
    if a.ndim < 2:
        return a.reshape(-1, 1)
    if a.ndim == 3 and not stack:
        raise KfastError(f"{name}: expected a 2-D array, got shape {a.shape}")
    return a


def _per_step(name: str, a: np.ndarray, N: int) -> np.ndarray:
    """``a`` as an (N, ...) stack: a constant matrix repeated, a stack checked for length N."""
    if a.ndim == 3:
        if a.shape[0] != N:
            raise KfastError(f"{name}: a per-step stack must have N = {N} matrices, got {a.shape[0]}")
        return a
    return np.broadcast_to(a, (N,) + a.shape)


def lq_finite(
    F: ArrayLike,
    G: ArrayLike,
    Q0: ArrayLike,
    Q1: ArrayLike,
    Q2: ArrayLike,
    N: int,
    Q12: Optional[ArrayLike] = None,
    x0: Optional[ArrayLike] = None,
    P0: Optional[ArrayLike] = None,
    Q: Optional[ArrayLike] = None,
) -> LQFiniteResult:
    """The finite-horizon LQ regulator u(t) = -L(t) x(t), t = 0..N-1, minimising
    E[x(N)' Q0 x(N) + sum_{t<N} (x' Q1 x + 2 x' Q12 u + u' Q2 u)] for
    x(t+1) = F x(t) + G u(t) + w(t) (Söderström (11.3), (11.6)-(11.7)):

    ::

        S(N) = Q0,  L(t) = (G' S(t+1) G + Q2)^-1 (G' S(t+1) F + Q12'),
        S(t) = F' S(t+1) F + Q1 - (F' S(t+1) G + Q12) L(t)

    Computed in Rust by the Kalman filter (Joseph form) on the dual problem in reversed time
    (Söderström (11.19)-(11.31)).

    Parameters
    ----------
    F, G, Q1, Q2, Q12 : array_like
        Matrices as in :func:`lqr`, each constant or a per-step stack of N (F[t] is the step from
        t to t + 1); the joint weight must be positive semidefinite at every step.
    Q0 : array_like, shape (n, n)
        Terminal weight (positive semidefinite).
    N : int
        Horizon (>= 1).
    x0, P0 : array_like, optional
        Mean and covariance of x(0), for the expected cost (P0 defaults to zero).
    Q : array_like, optional
        Covariance of w(t) (constant or a stack), for sigma and the expected cost (zero if omitted).

    Returns
    -------
    LQFiniteResult
        L (N, k, n), S (N + 1, n, n) with S[N] = Q0, sigma and the expected cost.

    Examples
    --------
    The horizon's gains converge to the stationary ones:

    >>> h = 0.5
    >>> F, G = [[1, h], [0, 1]], [h**2 / 2, h]
    >>> fin = kfast.control.lq_finite(F, G, np.zeros((2, 2)), np.eye(2), 0.1, N=60)
    >>> bool(np.allclose(fin.L[0], kfast.control.lqr(F, G, np.eye(2), 0.1).L))
    True
    """
    steps = index("N", N)
    if steps < 1:
        raise KfastError(f"N: the horizon must be at least 1, got {steps}")
    out = _kfast.lq_finite(
        _as_matrix("F", F, stack=True),
        _as_matrix("G", G, stack=True),
        _as_matrix("Q0", Q0),
        _as_matrix("Q1", Q1, stack=True),
        _as_matrix("Q2", Q2, stack=True),
        steps,
        None if Q12 is None else _as_matrix("Q12", Q12, stack=True),
    )
    S, L = out["S"], out["L"]
    n = S.shape[-1]
    sigma = np.zeros(steps + 1)
    if Q is not None:
        Q_ = matrix("Q", Q, n, n, stack=True)
        symmetric_psd("Q", Q_)
        terms = np.einsum("tij,tji->t", S[1:], _per_step("Q", Q_, steps))
        sigma[:-1] = np.cumsum(terms[::-1])[::-1]
    cost = None
    if x0 is not None:
        m = matrix("x0", x0, rows=n, cols=1)[:, 0]
        R0 = np.zeros((n, n)) if P0 is None else matrix("P0", P0, n, n)
        symmetric_psd("P0", R0)
        cost = float(m @ S[0] @ m + np.trace(S[0] @ R0) + sigma[0])
    return LQFiniteResult(L=L, S=S, sigma=sigma, expected_cost=cost)
