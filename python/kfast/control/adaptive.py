"""One-step controllers for an ARX model with uncertain parameters (Söderström Sec. 10.2,
(10.63)-(10.74)):

    y(t) = φ(t)' θ + e(t),   φ(t) = (-y(t-1), .., -y(t-n), u(t-1), .., u(t-n))',
    θ = (a_1, .., a_n, b_1, .., b_n)'

with θ estimated by a Kalman filter with H(t) = φ(t)' (e.g. ``kfast.KalmanFilter`` with
``update_with``), mean θ̂ and covariance P. Both laws aim y(t+1) at the reference r; the
certainty-equivalence law (10.70)-(10.71) treats θ̂ as exact, the cautious law (10.74) minimises
E[(y(t+1) - r)² | data] = λ² + (φ(t+1)' θ̂ - r)² + φ(t+1)' P φ(t+1) (10.69) and shrinks the input
when the gain b_1 is uncertain. Neither guarantees closed-loop stability (Söderström).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from kfast._arrays import finite_vector
from kfast._kfast import KfastError
from kfast._numbers import real_scalar

__all__ = ["certainty_equivalence_control", "cautious_control"]


def _regressor(theta: ArrayLike, y_past: ArrayLike, u_past: ArrayLike) -> tuple[np.ndarray, np.ndarray, int]:
    """θ̂ and φ̃(t+1) = (-y(t), .., -y(t-n+1), 0, u(t-1), .., u(t-n+1)) (u(t) set to zero, (10.72))."""
    th = finite_vector("theta", theta, "(a_1 .. a_n, b_1 .. b_n)")
    if th.size % 2:
        raise KfastError(f"theta: expected 2n entries (a_1 .. a_n, b_1 .. b_n), got {th.size}")
    n = th.size // 2
    y = finite_vector("y_past", y_past, "(y(t), .., y(t-n+1))")
    if y.size != n:
        raise KfastError(f"y_past: expected n = {n} values (y(t), .., y(t-n+1)), got {y.size}")
    u = np.zeros(0) if np.size(u_past) == 0 else finite_vector("u_past", u_past, "(u(t-1), .., u(t-n+1))")
    if u.size != n - 1:
        raise KfastError(f"u_past: expected n - 1 = {n - 1} values (u(t-1), .., u(t-n+1)), got {u.size}")
    return th, np.r_[-y, 0.0, u], n


def certainty_equivalence_control(theta: ArrayLike, y_past: ArrayLike, u_past: ArrayLike, r: float = 0.0) -> float:
    """u(t) with φ(t+1)' θ̂ = r (Söderström (10.70)-(10.71)):
    u = [r + â_1 y(t) + .. + â_n y(t-n+1) - b̂_2 u(t-1) - .. - b̂_n u(t-n+1)] / b̂_1.

    ``y_past`` = (y(t), .., y(t-n+1)), ``u_past`` = (u(t-1), .., u(t-n+1)) (empty for n = 1).

    Examples
    --------
    >>> round(kfast.control.certainty_equivalence_control([-0.9, 0.5], [2.0], [], r=1.0), 12)
    -1.6
    """
    th, phi, n = _regressor(theta, y_past, u_past)
    ref = real_scalar("r", r, "a number")
    b1 = th[n]
    if abs(b1) <= 1e-12 * max(1.0, float(np.abs(th).max())):
        raise KfastError("theta: the estimated gain b_1 is zero: the certainty-equivalence law is undefined")
    return float((ref - phi @ th) / b1)


def cautious_control(theta: ArrayLike, P: ArrayLike, y_past: ArrayLike, u_past: ArrayLike, r: float = 0.0) -> float:
    """The cautious law (Söderström (10.74)):
    u(t) = -[ε'θ̂ (φ̃'θ̂ - r) + ε' P φ̃] / [(ε'θ̂)² + ε' P ε], ε the unit vector of b_1,
    φ̃ = φ(t+1) with u(t) = 0. With P = 0 it is the certainty-equivalence law (ex. 10.3);
    with only b_1 uncertain and n = 1 it is -a β/(β² + p) x of (10.37).

    Examples
    --------
    >>> round(kfast.control.cautious_control([-0.9, 0.5], [[0.0, 0.0], [0.0, 0.25]], [2.0], [], r=1.0), 12)
    -0.8
    """
    th, phi, n = _regressor(theta, y_past, u_past)
    ref = real_scalar("r", r, "a number")
    Pm = np.asarray(P, dtype=float)
    if Pm.shape != (2 * n, 2 * n) or not np.all(np.isfinite(Pm)):
        raise KfastError(f"P: expected a finite ({2 * n}, {2 * n}) covariance of theta, got shape {Pm.shape}")
    if np.linalg.eigvalsh((Pm + Pm.T) / 2)[0] < -1e-10 * max(1.0, float(np.abs(Pm).max())):
        raise KfastError("P: must be positive semidefinite")
    b1, var_b1 = th[n], Pm[n, n]
    denominator = b1**2 + var_b1
    if denominator <= 1e-300:
        raise KfastError("theta, P: b_1 is estimated as exactly zero with no uncertainty: no input moves y(t+1)")
    return float(-(b1 * (phi @ th - ref) + Pm[n] @ phi) / denominator)
