"""The general k-step predictor of a multivariable model y = G(q) u + H(q) e (Söderström
(7.24)-(7.31)), with G and H given as a left matrix fraction (a VARMAX model):

    A(q) y(t) = B(q) u(t) + C(q) e(t),   cov e = Λ,   H = A⁻¹ C,   G = A⁻¹ B

A, C, B are matrix polynomials in descending powers of q: arrays of shape (d + 1, p, p) (B:
(d_B + 1, p, nu)) with A[0] = C[0] = I and deg C = deg A (so H(∞) = I and e is the innovation);
deg B < deg A (a pole excess: u(t) first affects y(t+1)). For p = 1 this is
:func:`kfast.poly.arma_predictor`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._args import index
from kfast._arrays import as_float64
from kfast._kfast import KfastError

__all__ = ["VarmaxPredictor", "varmax_predictor"]


@dataclass(frozen=True, repr=False)
class VarmaxPredictor:
    """ŷ(t+k|t) = G(q) u(t+k) + H1(q) e(t), e = H⁻¹ (y − G u), which is (7.29)
    ŷ(t+k|t) = H1 H⁻¹ y(t) + q H0 H⁻¹ G u(t) rearranged (q^k H = q H0 + H1)."""

    k: int
    F: np.ndarray
    """(k, p, p): h_0 = I, h_1, .., h_(k-1), the first k impulse-response (Markov) matrices of
    H = A⁻¹ C: the coefficients of H0 (7.26), F of q^(k-1) C = A F + L."""
    L: np.ndarray
    """(deg A, p, p): L of the matrix predictor identity q^(k-1) C = A F + L (deg L < deg A);
    H1 = q A⁻¹ L."""
    error_cov: np.ndarray
    """(p, p): cov ỹ(t+k) = Σ_{j<k} h_j Λ h_j' (7.30); E ỹ' P ỹ = tr(P error_cov) (7.31)."""
    A: np.ndarray
    C: np.ndarray
    B: Optional[np.ndarray]

    def predict(self, y: ArrayLike, u: Optional[ArrayLike] = None) -> np.ndarray:
        """ŷ(t|t−k) for t = 0..T−1 from the data y (T, p) (and u (T, nu)), with the model's
        signals zero before t = 0; rows t < k are NaN. Runs the difference equations
        C e = A y − B u and A w = L̃ e, L̃(q⁻¹) = l_0 + l_1 q⁻¹ + .. (w(t) = H1 e(t)), in NumPy."""
        A, C, B, L, k = self.A, self.C, self.B, self.L, self.k
        p = A.shape[1]
        Y = _data("y", y, p)
        T = len(Y)
        U = None
        if B is not None:
            if u is None:
                raise KfastError("u: the model has an input (B); pass u of shape (T, nu)")
            U = _data("u", u, B.shape[2])
            if len(U) != T:
                raise KfastError(f"u: has {len(U)} rows, y has {T}")
        elif u is not None:
            raise KfastError("u: the model has no input (B is None)")
        na = len(A) - 1
        e = np.zeros((T, p))
        w = np.zeros((T, p))
        d = np.zeros((T, p))
        for t in range(T):
            lags = range(1, min(t, na) + 1)
            drive = Y[t] + sum(A[i] @ Y[t - i] for i in lags)
            if U is not None and B is not None:
                forced = sum((B[i] @ U[t - i] for i in lags), np.zeros(p))
                d[t] = forced - sum((A[i] @ d[t - i] for i in lags), np.zeros(p))
                drive = drive - forced
            e[t] = drive - sum((C[i] @ e[t - i] for i in lags), np.zeros(p))
            w[t] = sum(L[i] @ e[t - i] for i in range(min(t, na - 1) + 1)) - sum(
                (A[i] @ w[t - i] for i in lags), np.zeros(p)
            )
        out = np.full((T, p), np.nan)
        # ŷ(t+k|t) = d(t+k) + w(t): u up to t+k−1 enters d(t+k) (pole excess ≥ 1).
        out[k:] = w[: T - k] + d[k:]
        return out

    def __repr__(self) -> str:
        return f"VarmaxPredictor(k={self.k}, p={self.A.shape[1]})"


def varmax_predictor(
    A: ArrayLike, C: ArrayLike, k: int, Lambda: Optional[ArrayLike] = None, B: Optional[ArrayLike] = None
) -> VarmaxPredictor:
    """The optimal k-step predictor of A(q) y = B(q) u + C(q) e, cov e = Λ (Söderström
    (7.24)-(7.31)): H0 from the Markov matrices h_j of A⁻¹ C (h_j = C_j − Σ_i A_i h_(j−i)),
    L from q^(k−1) C = A F + L (the triangular system (7.21) with matrix coefficients, A on the
    left), the error covariance Σ_{j<k} h_j Λ h_j'. det C(z) must have its zeros strictly
    inside the unit circle (H⁻¹ stable; a multivariable C is not reflected — an error);
    A may be unstable (Söderström Sec. 7.2.4: exact only for an exact model).

    Examples
    --------
    Two outputs, A = I + A1 q⁻¹, C = I + C1 q⁻¹, two steps ahead:

    >>> A = [np.eye(2), [[-0.5, 0.1], [0.0, -0.3]]]
    >>> C = [np.eye(2), [[0.4, 0.0], [0.2, 0.1]]]
    >>> pred = kfast.poly.varmax_predictor(A, C, k=2)
    >>> pred.F[1]                      # h_1 = C1 - A1
    array([[ 0.9, -0.1],
           [ 0.2,  0.4]])
    >>> pred.error_cov                 # Λ = I: h_0 h_0' + h_1 h_1'
    array([[1.82, 0.14],
           [0.14, 1.2 ]])
    """
    A_ = _matrix_poly("A", A)
    C_ = _matrix_poly("C", C)
    p = A_.shape[1]
    for name, M in (("A", A_), ("C", C_)):
        if not np.array_equal(M[0], np.eye(p)):
            raise KfastError(f"{name}: the leading coefficient {name}[0] must be the identity (monic)")
    if C_.shape != A_.shape:
        raise KfastError(
            f"C: must have the degree and size of A, shape {A_.shape} in descending powers of q, got {C_.shape}"
        )
    na = len(A_) - 1
    if na == 0:
        raise KfastError("A: must have degree at least 1")
    kk = index("k", k)
    if kk < 1:
        raise KfastError("k: the prediction horizon must be at least 1")
    if _companion_radius(C_) >= 1.0 - 1e-10:
        raise KfastError(
            "C: det C(z) has a zero on or outside the unit circle: H⁻¹ is unstable and e is not the "
            "innovation (a multivariable C is not reflected; spectral-factorize the noise model first)"
        )
    Lam = np.eye(p) if Lambda is None else as_float64("Lambda", Lambda)
    if Lam.shape != (p, p) or not np.all(np.isfinite(Lam)):
        raise KfastError(f"Lambda: expected a finite ({p}, {p}) covariance, got shape {Lam.shape}")
    if not np.allclose(Lam, Lam.T, rtol=1e-12, atol=0) or np.linalg.eigvalsh(Lam).min() < -1e-12 * max(
        1.0, np.abs(Lam).max()
    ):
        raise KfastError("Lambda: must be symmetric positive semidefinite")
    B_ = None
    if B is not None:
        B_ = _input_poly(B, na, p)
    # Markov matrices of A⁻¹ C up to lag k + na − 1 (the triangular system (7.21)).
    h = np.zeros((kk + na, p, p))
    for j in range(kk + na):
        h[j] = (C_[j] if j <= na else 0.0) - sum(A_[i] @ h[j - i] for i in range(1, min(j, na) + 1))
    F = h[:kk].copy()
    # l_(j−k) = Σ_{i = j−k+1}^{min(j, na)} A_i h_(j−i) subtracted from C_j: the tail of A F.
    L = np.zeros((na, p, p))
    for j in range(kk, kk + na):
        L[j - kk] = (C_[j] if j <= na else 0.0) - sum(A_[i] @ h[j - i] for i in range(j - kk + 1, min(j, na) + 1))
    error_cov = sum(hj @ Lam @ hj.T for hj in F)
    return VarmaxPredictor(k=kk, F=F, L=L, error_cov=0.5 * (error_cov + error_cov.T), A=A_, C=C_, B=B_)


def _matrix_poly(name: str, value: ArrayLike) -> np.ndarray:
    a = as_float64(name, value)
    if a.ndim == 1:  # a scalar polynomial
        a = a.reshape(-1, 1, 1)
    if a.ndim != 3 or a.shape[1] != a.shape[2] or a.shape[0] == 0 or a.shape[1] == 0:
        raise KfastError(f"{name}: expected a matrix polynomial of shape (degree + 1, p, p), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise KfastError(f"{name}: coefficients must be finite")
    return a


def _input_poly(B: ArrayLike, na: int, p: int) -> np.ndarray:
    """B as na + 1 coefficient matrices aligned with A (leading zeros prepended); B[0] = 0."""
    b = as_float64("B", B)
    if b.ndim == 1:
        b = b.reshape(-1, 1, 1)
    if b.ndim != 3 or b.shape[1] != p or b.shape[0] == 0 or b.shape[2] == 0:
        raise KfastError(f"B: expected a matrix polynomial of shape (degree + 1, {p}, nu), got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise KfastError("B: coefficients must be finite")
    first = next((i for i in range(len(b)) if np.any(b[i])), len(b) - 1)
    b = b[first:]
    if len(b) > na:
        raise KfastError(f"B: degree {len(b) - 1} must be below deg A = {na} (a pole excess of at least one)")
    out = np.zeros((na + 1, p, b.shape[2]))
    out[na + 1 - len(b):] = b
    return out


def _companion_radius(C: np.ndarray) -> float:
    """The largest |z| with det C(z) = 0 (C monic): the spectral radius of the block companion."""
    nc, p = len(C) - 1, C.shape[1]
    comp = np.zeros((nc * p, nc * p))
    comp[:p, :] = -np.concatenate(C[1:], axis=1)
    comp[p:, :-p] = np.eye((nc - 1) * p)
    return float(np.max(np.abs(np.linalg.eigvals(comp)))) if comp.size else 0.0


def _data(name: str, value: ArrayLike, width: int) -> np.ndarray:
    a = as_float64(name, value)
    if a.ndim == 1 and width == 1:
        a = a.reshape(-1, 1)
    if a.ndim != 2 or a.shape[1] != width:
        raise KfastError(f"{name}: expected shape (T, {width}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = int(np.argwhere(~np.isfinite(a))[0, 0])
        raise KfastError(f"{name}: non-finite value at time step {bad} (the polynomial predictor needs complete data)")
    return a
