"""Polynomial equations: the Diophantine equation A X + B Y = C (Söderström (11.84)-(11.85), the
Sylvester system) and the predictor identity z^(k-1) C = A F + L ((7.13)-(7.22))."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kfast._args import index
from kfast._arrays import as_float64
from kfast import _kfast
from kfast._kfast import KfastError
from kfast.poly._poly import monic, poly, require_stable, trim

__all__ = ["Diophantine", "diophantine", "predictor_identity", "two_sided", "causal_part"]


@dataclass(frozen=True, repr=False)
class Diophantine:
    """The solution of A X + B Y = C with the minimal degree of X (deg X < deg B)."""

    X: np.ndarray
    Y: np.ndarray
    condition: float
    """Condition number of the Sylvester system (large: A and B nearly share a factor)."""

    def __repr__(self) -> str:
        return f"Diophantine(deg X={len(self.X) - 1}, deg Y={len(self.Y) - 1}, condition={self.condition:.3g})"


def diophantine(A: ArrayLike, B: ArrayLike, C: ArrayLike) -> Diophantine:
    """Solve A(z) X(z) + B(z) Y(z) = C(z) for the solution with deg X < deg B (unique when A and
    B are coprime), by the Sylvester system of the coefficients (Söderström (11.84)-(11.85),
    (7.64)-(7.70)), in Rust (kfast::poly::diophantine).

    Parameters
    ----------
    A, B, C : array_like
        Coefficients in descending powers of z.

    Returns
    -------
    Diophantine
        X (degree deg B - 1), Y (degree max(deg C, deg A + deg B - 1) - deg B) and the
        condition number of the system.

    Raises
    ------
    KfastError
        When A and B have a common factor (the Sylvester matrix is singular): then the equation
        has no solution unless the factor divides C, and never a unique one.

    Examples
    --------
    >>> d = kfast.poly.diophantine([1, -1.5, 0.7], [1, 0.5], [1, 0, 0, 0])
    >>> bool(np.allclose(np.polyadd(np.polymul([1, -1.5, 0.7], d.X), np.polymul([1, 0.5], d.Y)), [1, 0, 0, 0]))
    True
    """
    A_, B_, C_ = poly("A", A), poly("B", B), poly("C", C, allow_zero=True)
    X, Y, cond = _kfast.diophantine(A_, B_, C_)
    return Diophantine(X=np.asarray(X), Y=np.asarray(Y), condition=float(cond))


def predictor_identity(A: ArrayLike, C: ArrayLike, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The predictor identity z^(k-1) C(z) = A(z) F(z) + L(z) (Söderström (7.13)-(7.22)): F monic of
    degree k - 1 (the first k impulse-response coefficients of C/A) and L of degree < deg A,
    by long division. A and C monic, deg C <= deg A; k >= 1.

    Returns (F, L), L padded to deg A coefficients (ℓ_0 z^(n-1) + ... + ℓ_(n-1))."""
    A_, C_ = monic("A", A), monic("C", C)
    steps = index("k", k)
    if steps < 1:
        raise KfastError(f"k: the prediction horizon must be at least 1, got {steps}")
    coefficients = _kfast.predictor_identity(A_, C_, steps)
    return np.asarray(coefficients[0]), np.asarray(coefficients[1])


def two_sided(lhs: np.ndarray, lhs_top: int, Bstar: np.ndarray, alpha: int, deg_R: int, A_: np.ndarray, beta: int, deg_L: int) -> tuple[np.ndarray, np.ndarray]:
    """Solve lhs(z) = z^alpha B*(z) R(z) + z^beta A(z) L*(z) for R (a polynomial in z of degree
    deg_R) and L* (a polynomial in z^-1 of degree deg_L) by matching Laurent coefficients
    (Söderström (7.64)-(7.70)); Bstar = B(z^-1) as coefficients of z^0 .. z^-(deg B).
    Returns R (descending powers of z) and L* (coefficients of z^0 .. z^-deg_L)."""
    columns = []
    for j in range(deg_R + 1):  # z^j R-term: z^(alpha + j) B*(z)
        columns.append((alpha + j, Bstar))
    for j in range(deg_L + 1):  # z^-j L*-term: z^(beta - j) A(z)
        columns.append((beta - j + len(A_) - 1, A_))
    tops = [top for top, _ in columns] + [lhs_top]
    bottoms = [top - (len(c) - 1) for top, c in columns] + [lhs_top - (len(lhs) - 1)]
    hi, lo = max(tops), min(bottoms)
    rows = hi - lo + 1
    M = np.zeros((rows, len(columns)))
    for k, (top, c) in enumerate(columns):
        M[hi - top: hi - top + len(c), k] = c
    rhs = np.zeros(rows)
    rhs[hi - lhs_top: hi - lhs_top + len(lhs)] = lhs
    sol, *_ = np.linalg.lstsq(M, rhs, rcond=None)
    scale = max(1.0, float(np.abs(rhs).max()))
    if np.abs(M @ sol - rhs).max() > 1e-8 * scale:
        raise KfastError("the two-sided Diophantine equation (7.84) has no solution: are B and A coprime?")
    R = sol[: deg_R + 1][::-1]  # coefficients of z^deg_R .. z^0
    L_star = sol[deg_R + 1:]  # coefficients of z^0 .. z^-deg_L
    return R, L_star


def causal_part(G: ArrayLike, top: int, D: ArrayLike, P: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The causal part [G(z, z^-1) / (D(z) P(z^-1))]_+ (Söderström (7.64)-(7.70)): the terms in
    z^0, z^-1, ... (g_0 included) of the expansion, which is z^α R(z) / D(z) with R from the
    two-sided Diophantine equation G = z^α P* R + z^β D L* (7.65), α = min(0, μ - p),
    β = max(0, ℓ - ν) (7.67). The partial-fraction split that keeps D's (stable) poles.

    Parameters
    ----------
    G : array_like
        Laurent coefficients from z^top down to z^-(len(G) - 1 - top).
    top : int
        The power of z of G[0].
    D : array_like
        Monic, zeros strictly inside the unit circle (degree ν).
    P : array_like
        Monic, zeros strictly inside (degree μ): the denominator factor is P(z^-1), whose zeros
        1/z̄ are outside.

    Returns
    -------
    (num, den)
        The causal part as num(q)/den(q) in descending powers (den = D q^-α).

    Examples
    --------
    Söderström Example 7.7: [z^k C / A]_+ with k = 2 is z L / A of the predictor identity.

    >>> num, den = kfast.poly.causal_part([1, 0.5, 0, 0], 3, [1, -0.8], [1])  # z^2 (z + 0.5) / (z - 0.8)
    >>> print(num.round(12), den)
    [1.04 0.  ] [ 1.  -0.8]
    """
    D_, P_ = monic("D", D), monic("P", P)
    G_ = np.atleast_1d(as_float64("G", G)).ravel()
    if not np.all(np.isfinite(G_)) or G_.size == 0:
        raise KfastError("G: expected a non-empty array of finite Laurent coefficients")
    require_stable("D", D_)
    require_stable("P", P_)
    if isinstance(top, (bool, np.bool_)) or not isinstance(top, (int, np.integer)):
        raise KfastError(f"top: expected an integer power of z, got {top!r}")
    top_ = int(top)
    nu, mu = len(D_) - 1, len(P_) - 1
    ell, p = max(top_, 0), max(len(G_) - 1 - top_, 0)
    alpha, beta = min(0, mu - p), max(0, ell - nu)
    R, _ = two_sided(G_, top_, P_[::-1], alpha, nu - alpha, D_, beta, mu + beta - 1)
    return trim(R), np.r_[D_, np.zeros(-alpha)]
