"""The analytic score: the gradient of the Gaussian log-likelihood in the parameters of a model,
by the Kalman filter's tangent (sensitivity) recursion (docs/algorithms.md, "Analytic score").

The filter (Söderström Lemma 6.1, (6.22)-(6.27), the log-likelihood (6.142)) is differentiated
step by step for all parameters at once: the derivatives of x(t|t-1) and P(t|t-1) are carried
along, so the score is exact for any model the filter runs (singular Q or R, N, missing values,
inputs, per-step matrices). The derivatives of the matrices themselves, dF/dtheta_i and so on,
come from central differences of ``build`` (matrices only: no filtering), which is exact to
about 1e-10 for smooth parametrizations.
"""

from __future__ import annotations

from typing import Any, Callable, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._arrays import as_float64, finite_vector
from kfast._kfast import KfastError

__all__ = ["loglik_score"]

_MATRICES = ("F", "H", "Q", "R", "B", "D", "N")
_LOG_2PI = float(np.log(2 * np.pi))


def loglik_score(
    build: Callable[[np.ndarray], tuple], theta: ArrayLike, y: ArrayLike, u: Optional[ArrayLike] = None
) -> tuple[float, np.ndarray]:
    """The log-likelihood of a parametrized model and its gradient (the score) in theta.

    Parameters
    ----------
    build : callable
        ``build(theta) -> (model, x0, P0)``, as for :func:`kfast.fit`; it must give the same
        structure (which of B, D, N, per-step or constant matrices) near theta.
    theta : array_like, shape (p,)
        The parameters.
    y : array_like, shape (T, m), or (T,) when m = 1
        Observations (NaN = missing).
    u : array_like, shape (T, k), optional
        Inputs.

    Returns
    -------
    (float, ndarray of shape (p,))
        log p(y | theta) (Söderström (6.142), prior x(0|-1) ~ N(x0, P0), equal to
        ``model.loglik``) and its gradient.

    Raises
    ------
    KfastError
        When build fails or changes the model's structure near theta, or as ``model.loglik``.

    Notes
    -----
    For each step, with e = y - H x - D u, S = H P H' + R and the predictor gain
    K = (F P H' + N) S^-1 (observed components only), the derivatives follow the recursion::

        dl  = -1/2 tr(S^-1 dS) - e' S^-1 de + 1/2 e' S^-1 dS S^-1 e
        dS  = dH P H' + H dP H' + H P dH' + dR,      de = -dH x - H dx - dD u
        dK  = (dF P H' + F dP H' + F P dH' + dN - K dS) S^-1
        dx+ = dF x + F dx + dB u + dK e + K de
        dP+ = dF P F' + F dP F' + F P dF' + dQ - dK S K' - K dS K' - K S dK'

    from dx(0|-1) = dx0 and dP(0|-1) = dP0. Cost: about 3p filters' worth of O(n^3) work, in a
    NumPy loop over time (vectorized over the p parameters).

    Examples
    --------
    >>> def build(theta):
    ...     return kfast.LinearGaussian(F=0.8, H=1.0, Q=np.exp(theta[0]), R=1.0), 0.0, 1.0
    >>> ll, grad = kfast.loglik_score(build, [0.0], [0.3, -0.1, 0.7])
    >>> bool(np.isclose(ll, build([0.0])[0].loglik([0.3, -0.1, 0.7], 0.0, 1.0)))
    True
    """
    from kfast.linear.estimation import _build

    if not callable(build):
        raise KfastError(f"build: expected a callable build(theta) -> (model, x0, P0), got {type(build).__name__}")
    theta = finite_vector("theta", theta, "of parameters")
    model, x0, P0 = _build(build, theta, "theta")
    y_arr, x0_arr, P0_arr, u_arr = model._data(y, x0, P0, u)
    # The value from the filter itself (which also validates the data against the model).
    loglik = model.loglik(y_arr, x0_arr, P0_arr, u=u_arr)
    base = _arrays(model, x0_arr, P0_arr)
    deriv = _derivatives(build, theta, base)
    _, score = _tangent_filter(base, deriv, y_arr, u_arr)
    return float(loglik), score


def _arrays(model, x0, P0) -> dict[str, Any]:
    """The model's matrices and the prior as float arrays (None for absent B, D, N)."""
    out: dict[str, Any] = {k: (None if getattr(model, k) is None else np.asarray(getattr(model, k), dtype=float)) for k in _MATRICES}
    out["x0"] = np.asarray(x0, dtype=float).reshape(-1)
    out["P0"] = np.asarray(P0, dtype=float).reshape(len(out["x0"]), len(out["x0"]))
    return out


def _derivatives(build: Callable, theta: np.ndarray, base: dict[str, Any]) -> dict[str, Any]:
    """d(matrix)/d(theta_i) for every matrix and the prior, shape (p,) + the matrix's, by
    central differences of build with steps 1e-6 max(1, |theta_i|)."""
    from kfast.linear.estimation import _build

    p = len(theta)
    deriv = {k: np.zeros((p,) + v.shape) for k, v in base.items() if v is not None}
    for i in range(p):
        h = 1e-6 * max(1.0, abs(theta[i]))
        sides = []
        for sign in (1.0, -1.0):
            t = theta.copy()
            t[i] += sign * h
            model, x0, P0 = _build(build, t, f"theta{'+' if sign > 0 else '-'}{h:.1e} e_{i}")
            sides.append(_arrays(model, x0, P0))
        for k in deriv:
            plus, minus = sides[0][k], sides[1][k]
            if plus is None or minus is None or plus.shape != base[k].shape or minus.shape != base[k].shape:
                raise KfastError(f"build: {k} changes its structure near theta (entry {i}); the score needs the same matrices on both sides")
            deriv[k][i] = (plus - minus) / (2 * h)
        for k, v in base.items():
            if v is None and (sides[0][k] is not None or sides[1][k] is not None):
                raise KfastError(f"build: {k} appears near theta (entry {i}) but not at theta")
    return deriv


def _at(M: Any, t: int, per_step_ndim: int) -> Any:
    """The matrix in force at step t (M[t] for a per-step stack; the derivative arrays carry a
    leading parameter axis, so their per-step form has one more dimension)."""
    if M.ndim == per_step_ndim:
        return M[t] if per_step_ndim == 3 else M[:, t]
    return M


def _tangent_filter(base: dict[str, Any], deriv: dict[str, Any], y: np.ndarray, u: Optional[np.ndarray]) -> tuple[float, np.ndarray]:
    T, m = y.shape
    n = len(base["x0"])
    p = deriv["x0"].shape[0]
    x, P = base["x0"].copy(), base["P0"].copy()
    dx, dP = deriv["x0"].copy(), deriv["P0"].copy()
    loglik, score = 0.0, np.zeros(p)
    zeros_nm, dzeros_nm = np.zeros((n, m)), np.zeros((p, n, m))
    for t in range(T):
        F, H, Q, R = (_at(base[k], t, 3) for k in "FHQR")
        dF, dH, dQ, dR = (_at(deriv[k], t, 4) for k in "FHQR")
        N = _at(base["N"], t, 3) if base["N"] is not None else zeros_nm
        dN = _at(deriv["N"], t, 4) if base["N"] is not None else dzeros_nm
        Bu, dBu = np.zeros(n), np.zeros((p, n))
        Du, dDu = np.zeros(m), np.zeros((p, m))
        if u is not None:
            if base["B"] is not None:
                Bu, dBu = _at(base["B"], t, 3) @ u[t], _at(deriv["B"], t, 4) @ u[t]
            if base["D"] is not None:
                Du, dDu = _at(base["D"], t, 3) @ u[t], _at(deriv["D"], t, 4) @ u[t]
        FP, dFP = F @ P, dF @ P + F @ dP  # (n, n), (p, n, n): d(F P)
        x_next = F @ x + Bu
        dx_next = dF @ x + dx @ F.T + dBu
        # d(F P F') = dF P F' + F dP F' + F P dF'
        P_next = FP @ F.T + Q
        dP_next = dFP @ F.T + FP @ np.swapaxes(dF, 1, 2) + dQ
        o = ~np.isnan(y[t])
        if o.any():
            Ho, dHo, Ro = H[o], dH[:, o], R[np.ix_(o, o)]
            dRo = dR[:, o][:, :, o]
            No, dNo = N[:, o], dN[:, :, o]
            e = y[t][o] - Ho @ x - Du[o]
            de = -(dHo @ x) - dx @ Ho.T - dDu[:, o]
            PH = P @ Ho.T
            S = Ho @ PH + Ro
            A = dHo @ PH  # dH P H'
            dS = A + np.swapaxes(A, 1, 2) + Ho @ dP @ Ho.T + dRo
            L = np.linalg.cholesky((S + S.T) / 2)
            S_inv = np.linalg.inv(S)
            S_inv_e = S_inv @ e
            loglik -= 0.5 * (o.sum() * _LOG_2PI + 2 * np.sum(np.log(np.diag(L))) + e @ S_inv_e)
            score += -0.5 * np.einsum("ij,pji->p", S_inv, dS) - de @ S_inv_e + 0.5 * np.einsum("i,pij,j->p", S_inv_e, dS, S_inv_e)
            M = F @ PH + No
            K = M @ S_inv
            dM = dF @ PH + F @ dP @ Ho.T + F @ P @ np.swapaxes(dHo, 1, 2) + dNo
            dK = (dM - K @ dS) @ S_inv
            x_next = x_next + K @ e
            dx_next = dx_next + dK @ e + de @ K.T
            KSK = K @ S @ K.T
            dKSK = dK @ S @ K.T
            P_next = P_next - KSK
            dP_next = dP_next - dKSK - np.swapaxes(dKSK, 1, 2) - K @ dS @ K.T
        x, dx = x_next, dx_next
        P, dP = (P_next + P_next.T) / 2, (dP_next + np.swapaxes(dP_next, 1, 2)) / 2
    return float(loglik), score
