"""Stationary analysis of a constant model (Söderström ch. 4, Sec. 6.7; docs/algorithms.md, "Stationary analysis"):
the steady-state filter, the innovations form, the stationary covariance, the output
autocovariance and spectral density.

Conventions (docs/conventions.md): r_y(tau) = E[y(t+tau) y(t)'] (lag on the first factor), r_y(-tau) =
r_y(tau)'. The spectral density has no 1/2pi: phi(w) = h sum_k r_y(k) e^{-i w k h}, so that
r_y(k) = (1/2pi) int_{-pi/h}^{pi/h} phi(w) e^{i w k h} dw (Söderström (3.22)-(3.25)); with
h = 1 the frequency w is in radians per sample. (statsmodels and Brockwell-Davis divide by
2pi; one-sided Hz spectra are 2 phi.)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._arrays import as_float64
from kfast._numbers import integer_lags, positive_real, powers_applied
from kfast._typing import DareMethod
from kfast.riccati.solvers import dare

if TYPE_CHECKING:
    from kfast.linear.model import LinearGaussian

__all__ = ["SteadyState", "InnovationsForm"]


@dataclass(frozen=True, repr=False)
class SteadyState:
    """The stationary Kalman filter (Söderström (6.91)): the stabilizing solution P of
    P = F P F' + Q - (F P H' + N) S^-1 (F P H' + N)', S = H P H' + R."""

    P_pred: np.ndarray
    """Stationary P(t|t-1)."""
    P_filt: np.ndarray
    """Stationary P(t|t) = P_pred - K S K'."""
    K: np.ndarray
    """Filter gain P_pred H' S^-1."""
    K_pred: np.ndarray
    """Predictor gain (F P_pred H' + N) S^-1."""
    S: np.ndarray
    """Innovation covariance H P_pred H' + R."""
    closed_loop_eigenvalues: np.ndarray
    """Eigenvalues of F - K_pred H (inside the unit circle: the filter is stable)."""
    residual: float
    """Relative residual of the Riccati equation."""

    def __repr__(self) -> str:
        rho = float(np.abs(self.closed_loop_eigenvalues).max())
        return f"SteadyState(n={len(self.P_pred)}, closed-loop radius={rho:.4g}, residual={self.residual:.2e})"


@dataclass(frozen=True, repr=False)
class InnovationsForm:
    """x(t+1) = F x(t) + B u(t) + K_pred e(t), y(t) = H x(t) + D u(t) + e(t), cov e = S
    (Söderström Thm 4.2): the same output statistics as the model, driven by its innovations."""

    F: np.ndarray
    K_pred: np.ndarray
    H: np.ndarray
    S: np.ndarray

    def __repr__(self) -> str:
        return f"InnovationsForm(n={len(self.F)}, m={len(self.S)})"


def _require_constant(model: "LinearGaussian", what: str) -> None:
    if model.steps is not None:
        raise _kfast.KfastError(f"model: {what} needs constant matrices (this model has per-step ones)")


def steady_state(model: "LinearGaussian", method: DareMethod = "doubling") -> SteadyState:
    _require_constant(model, "steady_state()")
    F, H, Q, R = model.F, model.H, model.Q, model.R
    sol = dare(F.T, H.T, Q, R, s=model.N, method=method)
    P = sol["x"]
    S = H @ P @ H.T + R
    S = (S + S.T) / 2
    K = np.linalg.solve(S, H @ P).T  # S symmetric: (S^-1 H P)' = P H' S^-1
    P_filt = P - K @ S @ K.T
    return SteadyState(
        P_pred=P,
        P_filt=(P_filt + P_filt.T) / 2,
        K=K,
        K_pred=sol["gain"].T,
        S=S,
        closed_loop_eigenvalues=sol["closed_loop_eigenvalues"],
        residual=float(sol["residual"]),
    )


def innovations_form(model: "LinearGaussian") -> InnovationsForm:
    ss = steady_state(model)
    return InnovationsForm(F=model.F, K_pred=ss.K_pred, H=model.H, S=ss.S)


def stationary_cov(model: "LinearGaussian") -> np.ndarray:
    _require_constant(model, "stationary_cov()")
    return _kfast.stationary_covariance(np.ascontiguousarray(model.F), np.ascontiguousarray(model.Q))


def autocovariance(model: "LinearGaussian", lags: ArrayLike) -> np.ndarray:
    """r_y(tau) for each tau in lags, shape (len(lags), m, m) (Söderström Lemma 4.2; with N,
    r_y(tau) = H F^(tau-1) (F Pi H' + N) for tau >= 1, r_y(0) = H Pi H' + R). ``lags`` are
    integers with |tau| < 2**63 (floats with integer values are accepted); F^(tau-1) is
    reached by repeated squaring, so a huge lag costs O(log tau) products."""
    lags = integer_lags("lags", lags)
    if lags.ndim > 1:
        raise _kfast.KfastError("lags: expected integers (a scalar or a 1-D array)")
    lags = np.atleast_1d(lags)
    Pi = stationary_cov(model)
    F, H = model.F, model.H
    N = model.N if model.N is not None else np.zeros((model.n_states, model.n_obs))
    out = np.empty((len(lags), model.n_obs, model.n_obs))
    G = F @ Pi @ H.T + N  # F Pi H' + N
    by_lag = {0: H @ Pi @ H.T + model.R}
    magnitudes = np.abs(lags)
    for k, FkG in powers_applied(F, G, magnitudes[magnitudes >= 1] - 1).items():
        by_lag[k + 1] = H @ FkG  # H F^k G = r_y(k + 1)
    for i, tau in enumerate(lags.tolist()):
        out[i] = by_lag[abs(tau)] if tau >= 0 else by_lag[-tau].T
    return out


def spectral_density(model: "LinearGaussian", omega: ArrayLike, h: float = 1.0) -> np.ndarray:
    """phi_y(e^{i w h}) = h G(z) [[Q, N], [N', R]] G(1/z)', G(z) = [H (zI - F)^-1, I]
    (Söderström (4.25)), shape (len(omega), m, m), complex Hermitian; see the module doc for
    the normalization."""
    stationary_cov(model)  # raises unless F is stable
    omega = np.atleast_1d(as_float64("omega", omega))
    if omega.ndim != 1:
        raise _kfast.KfastError(f"omega: expected a scalar or a 1-D array, got shape {omega.shape}")
    if not np.all(np.isfinite(omega)):
        raise _kfast.KfastError(f"omega: must be finite, got {omega[~np.isfinite(omega)][0]}")
    h = positive_real("h", h)
    with np.errstate(over="ignore"):
        largest_angle = np.abs(omega).max(initial=0.0) * h
    if not np.isfinite(largest_angle):
        raise _kfast.KfastError(f"omega: omega * h overflows (max |omega| = {np.abs(omega).max():.3g}, h = {h:.3g})")
    n, m = model.n_states, model.n_obs
    N = model.N if model.N is not None else np.zeros((n, m))
    J = np.block([[model.Q, N], [N.T, model.R]])
    z = np.exp(1j * omega * h)
    resolvent = np.linalg.solve(z[:, None, None] * np.eye(n) - model.F, np.broadcast_to(np.eye(n), (len(z), n, n)))
    G = np.concatenate([model.H @ resolvent, np.broadcast_to(np.eye(m), (len(z), m, m))], axis=2)
    # G(1/z)' = conj(G(z))' on |z| = 1 for real matrices
    return h * G @ J @ np.conj(np.swapaxes(G, 1, 2))
