"""ARMA(X) models A(q) y = B(q) u + C(q) e, var e = λ² (Söderström ch. 7; DESIGN: descending
powers of q, A and C monic): the k-step predictor (7.18)-(7.23), (11.61), and the conversions to
and from state space (Söderström Example 7.2 and Sec. 4.3's observer form), so every polynomial
result can be checked against the Kalman filter."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._kfast import KfastError
from kfast._numbers import positive_real
from kfast.poly._poly import monic, poly, polymul, roots
from kfast.poly.equations import predictor_identity

if TYPE_CHECKING:
    from kfast.linear.model import LinearGaussian

__all__ = ["ArmaPredictor", "invertible", "arma_predictor", "arma_to_ss", "ss_to_arma"]

_CIRCLE_TOL = 1e-8


def invertible(C: ArrayLike, lam2: float = 1.0) -> tuple[np.ndarray, float]:
    """The invertible form of the noise polynomial (Söderström Example 7.1): each zero c of C
    outside the unit circle is replaced by 1/c̄ and λ² multiplied by |c|², which leaves the
    spectrum λ² C C* unchanged. Zeros on the circle have no invertible form (an error)."""
    C_ = monic("C", C)
    lam = positive_real("lam2", lam2)
    zeros = roots(C_)
    radius = np.abs(zeros)
    if np.any(np.abs(radius - 1.0) < _CIRCLE_TOL):
        raise KfastError("C: has a zero on the unit circle: the noise model has no invertible (innovations) form")
    outside = radius > 1.0
    lam *= float(np.prod(radius[outside] ** 2))
    zeros[outside] = 1.0 / np.conj(zeros[outside])
    return np.real(np.poly(zeros)) if zeros.size else np.ones(1), lam


@dataclass(frozen=True, repr=False)
class ArmaPredictor:
    """ŷ(t+k|t) = [num(q) / den(q)] y(t) + [num_u(q) / den(q)] u(t) (Söderström (7.18), (11.61))."""

    k: int
    num: np.ndarray
    """q L(q) (descending powers of q)."""
    den: np.ndarray
    """C(q), in its invertible form."""
    num_u: Optional[np.ndarray]
    """q B(q) F(q), with an input; None without."""
    F: np.ndarray
    """F of the predictor identity: the first k impulse-response coefficients of C/A."""
    L: np.ndarray
    error_variance: float
    """λ² (1 + f_1² + ... + f_(k-1)²) (7.20)."""
    lam2: float
    """The innovation variance of the invertible form."""

    def __repr__(self) -> str:
        return f"ArmaPredictor(k={self.k}, error_variance={self.error_variance:.6g})"


def arma_predictor(A: ArrayLike, C: ArrayLike, k: int, lam2: float = 1.0, B: Optional[ArrayLike] = None) -> ArmaPredictor:
    """The optimal k-step predictor of the ARMA(X) model A(q) y = B(q) u + C(q) e
    (Söderström (7.12)-(7.23), (11.58)-(11.61)): z^(k-1) C = A F + L and
    ŷ(t+k|t) = q L(q)/C(q) y(t) + q B(q) F(q)/C(q) u(t), error variance λ² (1 + Σ f_i²).
    Zeros of C outside the unit circle are reflected first (:func:`invertible`, Example 7.1).

    Examples
    --------
    Söderström Example 7.1: y(t) - 0.8 y(t-1) = e(t) + 2 e(t-1), var e = 1.

    >>> p = kfast.poly.arma_predictor([1, -0.8], [1, 2], k=2)
    >>> print(p.num.round(12), p.den, round(p.error_variance, 12))
    [1.04 0.  ] [1.  0.5] 10.76
    """
    A_ = monic("A", A)
    C_, lam = invertible(C, lam2)
    _same_degree(A_, C_)
    F, L = predictor_identity(A_, C_, k)
    num = np.append(L, 0.0)
    num_u = None
    if B is not None:
        B_ = poly("B", B)
        if len(B_) >= len(A_):
            raise KfastError(f"B: degree {len(B_) - 1} must be below deg A = {len(A_) - 1} (a pole excess of at least one)")
        num_u = np.append(polymul(B_, F), 0.0)
    return ArmaPredictor(
        k=int(k), num=num, den=C_, num_u=num_u, F=F, L=L, error_variance=lam * float(np.sum(F**2)), lam2=lam
    )


def _same_degree(A: np.ndarray, C: np.ndarray) -> None:
    """C/A must be proper with leading term 1 (e(t) is the innovation): deg C = deg A in q."""
    if len(C) != len(A):
        raise KfastError(
            f"C: must have the degree of A ({len(A) - 1}) in powers of q, got {len(C) - 1} "
            "(an AR part without MA terms is C = q^n, i.e. [1, 0, ..., 0])"
        )


def arma_to_ss(A: ArrayLike, C: ArrayLike, lam2: float = 1.0, B: Optional[ArrayLike] = None) -> "LinearGaussian":
    """The innovations state-space form of A(q) y = B(q) u + C(q) e (observer form, n = deg A
    states): F the companion matrix with first column -(a_1 .. a_n), ones above the diagonal,
    H = (1, 0, .., 0), x(t+1) = F x + G u + g e, y = H x + e with g = c - a, so Q = λ² g g',
    N = λ² g, R = λ²; G = (0, .., 0, b_0, .., b_m)' (pole excess n - m >= 1)."""
    from kfast.linear.model import LinearGaussian

    A_ = monic("A", A)
    C_ = monic("C", C)
    lam = positive_real("lam2", lam2)
    n = len(A_) - 1
    if n == 0:
        raise KfastError("A: must have degree at least 1 (a state)")
    _same_degree(A_, C_)
    a, c = A_[1:], C_[1:]
    F = np.eye(n, k=1)
    F[:, 0] = -a
    g = (c - a).reshape(n, 1)
    H = np.eye(1, n)
    G = None
    if B is not None:
        B_ = poly("B", B)
        if len(B_) - 1 >= n:
            raise KfastError(f"B: degree {len(B_) - 1} must be below deg A = {n} (a pole excess of at least one)")
        G = np.zeros((n, 1))
        G[n - len(B_):, 0] = B_
    return LinearGaussian(F, H, lam * g @ g.T, [[lam]], B=G, N=lam * g)


def ss_to_arma(model: "LinearGaussian") -> tuple[np.ndarray, np.ndarray, float]:
    """(A, C, λ²) of a constant single-output model without inputs (Söderström Sec. 4.3, Thm 4.2):
    A(z) = det(zI - F), C(z) = det(zI - F + K_pred H) from the stationary filter, λ² = S."""
    if model.n_obs != 1:
        raise KfastError(f"model: ss_to_arma needs a single output (m = 1), got m = {model.n_obs}")
    ss = model.steady_state()
    A = np.real(np.poly(model.F))
    C = np.real(np.poly(model.F - ss.K_pred @ model.H))
    return A, C, float(ss.S[0, 0])
