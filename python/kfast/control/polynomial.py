"""Polynomial (input-output) controllers for the ARMAX model A(q) y = B(q) u + C(q) e, var e = λ²
(Söderström Sec. 11.5-11.6; descending powers of q, A and C monic of degree n, B of degree
m < n, pole excess k = n - m): minimum-variance control (11.51)-(11.66), its non-minimum-phase
variant (11.67)-(11.69), generalized minimum variance (Ex. 11.5), and LQG by the polynomial
route (11.74)-(11.88). Every regulator is R(q) u(t) = -S(q) y(t), i.e. u = -S/R y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kfast._args import index
from kfast._kfast import KfastError
from kfast._numbers import real_scalar
from kfast.poly._poly import laurent, monic, poly, polyadd, polymul, require_stable, roots
from kfast.poly.equations import diophantine, predictor_identity
from kfast.poly.spectral import spectral_factor

__all__ = ["PolynomialRegulator", "minimum_variance", "lqg_polynomial", "closed_loop_variance"]

_CIRCLE_TOL = 1e-8


@dataclass(frozen=True, repr=False)
class PolynomialRegulator:
    """R(q) u(t) = -S(q) y(t) (descending powers of q), with its nominal closed loop."""

    R: np.ndarray
    S: np.ndarray
    kind: str
    """"minimum variance", "minimum variance (non-minimum-phase B)", "generalized minimum variance"
    or "lqg"."""
    closed_loop: np.ndarray
    """A R + B S: the closed-loop characteristic polynomial, (A R + B S) y = C R e."""
    output_variance: float
    """E y² of the nominal closed loop."""
    input_variance: float
    """E u² of the nominal closed loop."""

    def __repr__(self) -> str:
        return f"PolynomialRegulator({self.kind}, deg R={len(self.R) - 1}, deg S={len(self.S) - 1}, var y={self.output_variance:.6g})"


def closed_loop_variance(num: ArrayLike, den: ArrayLike, lam2: float = 1.0) -> float:
    """E x² for x = [num(q)/den(q)] e, var e = λ², den monic with its zeros inside the unit circle:
    the stationary variance of an observer-form realisation (a discrete Lyapunov equation)."""
    from kfast.riccati.solvers import solve_discrete_lyapunov

    d = monic("den", den)
    b = np.atleast_1d(np.asarray(num, float))
    n = len(d) - 1
    if len(b) - 1 > n:
        raise KfastError(f"num: degree {len(b) - 1} exceeds that of den ({n}): not proper")
    if n == 0:
        return float(lam2 * b[-1] ** 2)
    if np.any(np.abs(roots(d)) >= 1.0 - _CIRCLE_TOL):
        raise KfastError("den: has zeros on or outside the unit circle: the closed loop is not stable")
    b = np.pad(b, (n + 1 - len(b), 0))
    # x = b0 e + (b1 - b0 d1 ...)/(...): observer form with direct term b0.
    F = np.eye(n, k=1)
    F[:, 0] = -d[1:]
    g = (b[1:] - b[0] * d[1:]).reshape(n, 1)
    P = solve_discrete_lyapunov(F, lam2 * g @ g.T)
    return float(P[0, 0] + lam2 * b[0] ** 2)


def _armax(A: ArrayLike, B: ArrayLike, C: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    A_, C_ = monic("A", A), monic("C", C)
    B_ = poly("B", B)
    n, m = len(A_) - 1, len(B_) - 1
    if len(C_) != len(A_):
        raise KfastError(f"C: must have the degree of A ({n}), got {len(C_) - 1}")
    if m >= n:
        raise KfastError(f"B: degree {m} must be below deg A = {n} (a pole excess k = n - m of at least one)")
    require_stable("C", C_, _CIRCLE_TOL)
    return A_, B_, C_, n - m


def _finish(kind: str, A, B, C, R, S, lam2) -> PolynomialRegulator:
    closed = polyadd(polymul(A, R), polymul(B, S))
    lead = closed[np.flatnonzero(np.abs(closed) > 1e-12 * np.abs(closed).max())[0]]
    closed = np.trim_zeros(closed / lead, "f") if lead else closed
    # y = C R / (A R + B S) e, u = -C S / (A R + B S) e (normalised to a monic denominator).
    var_y = closed_loop_variance(polymul(C, R) / lead, closed, lam2)
    var_u = closed_loop_variance(polymul(C, S) / lead, closed, lam2)
    return PolynomialRegulator(R=R, S=S, kind=kind, closed_loop=closed, output_variance=var_y, input_variance=var_u)


def minimum_variance(
    A: ArrayLike, B: ArrayLike, C: ArrayLike, lam2: float = 1.0, rho: float = 0.0, delay: int = 0
) -> PolynomialRegulator:
    """The minimum-variance regulator for A(q) y = B(q) u + C(q) e (Söderström (11.51)-(11.69),
    Ex. 11.3, 11.5), u = -S/R y.

    - rho = 0, B minimum phase: z^(k+delay-1) C = A F + L, R = B F, S = L (11.58)-(11.62); the
      output is y = F(q) e(t-k+1) with variance λ² (1 + f_1² + ...) (11.65)-(11.66); ``delay``
      is a computation delay (u(t) may use y up to t - delay; Ex. 11.3).
    - rho = 0, B with zeros outside the unit circle: B = B₊ B₋ (B₋ the outside zeros, degree r),
      A R' + B₋ P = C z^(k-1) z^r B₋(z^-1), R = R' B₊, S = P (11.67)-(11.69).
    - rho > 0: generalized minimum variance (Ex. 11.5), minimising E[y²(t+k) + ρ u²(t)]:
      R = b_0 q B F + ρ C, S = b_0 q L.

    Examples
    --------
    >>> reg = kfast.control.minimum_variance([1, -1.5, 0.7], [1, 0.5], [1, -0.2, 0.1])
    >>> print(round(reg.output_variance, 12))
    1.0
    """
    A_, B_, C_, k = _armax(A, B, C)
    lam = real_scalar("lam2", lam2, "a positive number")
    rho_ = real_scalar("rho", rho, "a number >= 0")
    if not (lam > 0 and np.isfinite(lam)):
        raise KfastError(f"lam2: must be a finite number > 0, got {lam2!r}")
    if not (rho_ >= 0 and np.isfinite(rho_)):
        raise KfastError(f"rho: must be a finite number >= 0, got {rho!r}")
    lag = index("delay", delay)
    zeros = roots(B_) if len(B_) > 1 else np.zeros(0)
    if rho_ > 0:
        F, L = predictor_identity(A_, C_, k + lag)
        b0 = B_[0]
        R = polyadd(b0 * polymul(np.r_[B_, 0.0], F), rho_ * C_)
        S = b0 * np.r_[L, 0.0]
        return _finish("generalized minimum variance", A_, B_, C_, R, S, lam)
    if np.any(np.abs(np.abs(zeros) - 1.0) < _CIRCLE_TOL):
        raise KfastError("B: has a zero on the unit circle: no stable minimum-variance law exists (use rho > 0)")
    outside = np.abs(zeros) > 1.0
    if not outside.any():
        F, L = predictor_identity(A_, C_, k + lag)
        return _finish("minimum variance", A_, B_, C_, polymul(B_, F), L, lam)
    if lag:
        raise KfastError("delay: a computation delay is supported for minimum-phase B only")
    # B = B₊ B₋ with B₋ monic (its zeros outside); the scale stays in B₊.
    B_minus = np.real(np.poly(zeros[outside]))
    B_plus = B_[0] * np.real(np.poly(zeros[~outside])) if (~outside).any() else np.array([B_[0]])
    rhs = polymul(polymul(C_, np.r_[1.0, np.zeros(k - 1)]), B_minus[::-1])  # C z^(k-1) z^r B₋(z^-1)
    sol = diophantine(B_minus, A_, rhs)  # B₋ P + A R' = rhs, deg P < deg A
    P, R_prime = sol.X, sol.Y
    return _finish("minimum variance (non-minimum-phase B)", A_, B_, C_, polymul(R_prime, B_plus), P, lam)


def lqg_polynomial(A: ArrayLike, B: ArrayLike, C: ArrayLike, rho: float, lam2: float = 1.0) -> PolynomialRegulator:
    """Stationary LQG by the polynomial route (Söderström (11.74)-(11.88)), minimising
    lim E[y² + ρ u²]: the spectral factor r P(z) P(z^-1) = ρ A A* + B B* (11.81), P monic of
    degree n with its zeros inside; then A R + B S = C P with R monic of degree n and
    S = s_0 q^n + .. + s_(n-1) q (s_n = 0, Lemma 11.8) (11.85); u = -S/R y (11.77). The closed
    loop's poles are the zeros of C and P (11.84). Needs A(0) != 0 (11.82) and A, B coprime.

    Examples
    --------
    >>> reg = kfast.control.lqg_polynomial([1, -1.5, 0.7], [1, 0.5], [1, -0.2, 0.1], rho=0.1)
    >>> bool(np.abs(np.roots(reg.closed_loop)).max() < 1)
    True
    """
    A_, B_, C_, k = _armax(A, B, C)
    rho_ = real_scalar("rho", rho, "a number >= 0")
    lam = real_scalar("lam2", lam2, "a positive number")
    if not (rho_ >= 0 and np.isfinite(rho_)):
        raise KfastError(f"rho: must be a finite number >= 0, got {rho!r}")
    n = len(A_) - 1
    if abs(A_[-1]) <= 1e-12:
        raise KfastError("A: A(0) = 0 (a_n = 0): the polynomial route needs a_n != 0 (11.82); use the state-space lqg")
    spectrum = polyadd(rho_ * laurent(A_, A_), np.pad(laurent(B_, B_), (k, k)))
    factor = spectral_factor(spectrum)
    P = np.r_[factor.B, np.zeros(n - (len(factor.B) - 1))]  # rho = 0: n - m zeros at the origin
    sol = diophantine(np.r_[B_, 0.0], A_, polymul(C_, P))  # q B S~ + A R = C P, deg S~ < n
    S = np.r_[sol.X, 0.0] if len(sol.X) == n else np.r_[np.pad(sol.X, (n - len(sol.X), 0)), 0.0]
    R = sol.Y
    return _finish("lqg", A_, B_, C_, R, S, lam)
