"""The exact diffuse smoother: E[x(t) | y] and its covariances when part of the initial state
is unknown (P(0|-1) = P0 + kappa P0_inf, kappa -> inf), by de Jong's (1991) augmentation
(docs/algorithms.md, "Exact diffuse initialization").

Write x(0) = x0 + A delta + eta with P0_inf = A A' (A of full column rank q), eta ~ N(0, P0) and
delta with a flat prior. The filter and smoother are linear in the data and the prior mean, so
with the ordinary smoother of y from (x0, P0) (innovations e(t), covariances S(t), smoothed
states x_0(t)) and of zero data from each column A_j (innovations E_j(t), smoothed states
X_j(t)), delta given y is N(-M^-1 s, M^-1), M = sum E' S^-1 E, s = sum E' S^-1 e, and

    x(t|T-1) = x_0(t) - X(t) M^-1 s,      P(t|T-1) = P_0(t|T-1) + X(t) M^-1 X(t)'

(and the lag-one covariances likewise). This is the exact diffuse smoother of Durbin & Koopman
(2012) Sec. 5.3 by another route; the diffuse log-likelihood -1/2 log det M + 1/2 s' M^-1 s
plus the ordinary one is the filter's (Koopman's) value, which the tests check.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from kfast import _kfast
from kfast._typing import UpdateForm

if TYPE_CHECKING:
    from kfast.linear.model import LinearGaussian, SmootherResult


def diffuse_directions(P_inf: np.ndarray) -> np.ndarray:
    """A (n, q) with A A' = P_inf, q its numerical rank."""
    lam, V = np.linalg.eigh((P_inf + P_inf.T) / 2)
    keep = lam > 1e-12 * max(lam.max(), 0.0)
    return V[:, keep] * np.sqrt(lam[keep])


def smooth(model: "LinearGaussian", y: Any, x0: Any, P0: Any, P0_inf: Any, u: Any, form: UpdateForm, outputs: Optional[tuple]) -> "SmootherResult":
    """The body of :meth:`LinearGaussian.smooth` with ``P0_inf`` (see there)."""
    from kfast.linear.model import SmootherResult

    y_arr, x0_arr, P0_arr, u_arr = model._data(y, x0, P0, u)
    P_inf = model._prior(x0, P0_inf, ("x0", "P0_inf"))[1]
    exact_filter = model.filter(y_arr, x0_arr, P0_arr, u=u_arr, form=form, P0_inf=P_inf)
    A = diffuse_directions(P_inf)
    base = model.smooth(y_arr, x0_arr, P0_arr, u=u_arr, form=form)
    if A.shape[1] == 0:
        return SmootherResult(filter=exact_filter, x_smooth=base.x_smooth, P_smooth=base.P_smooth, P_lag1=base.P_lag1)
    zeros = np.where(np.isnan(y_arr), np.nan, 0.0)
    zero_u = None if u_arr is None else np.zeros_like(u_arr)
    columns = [_moments(model.smooth(zeros, A[:, j], P0_arr, u=zero_u, form=form)) for j in range(A.shape[1])]
    E = np.stack([c[0] for c in columns], axis=-1)  # innovations, (T, m, q)
    X = np.stack([c[2] for c in columns], axis=-1)  # smoothed states, (T, n, q)
    e, S_full, x_base, P_base, lag_base = _moments(base)
    seen = ~np.isnan(e)
    # S(t)^-1 on the observed block, as one stacked solve: missing rows and columns replaced by
    # the identity, with zero right-hand sides there.
    S = np.where(seen[:, :, None] & seen[:, None, :], S_full, 0.0) + np.eye(e.shape[1]) * ~seen[:, :, None]
    E0 = np.where(seen[:, :, None], E, 0.0)
    e0 = np.where(seen, e, 0.0)
    S_inv_E = np.linalg.solve(S, E0)
    M = np.einsum("tiq,tir->qr", E0, S_inv_E)
    s = np.einsum("tiq,ti->q", S_inv_E, e0)
    lam = np.linalg.eigvalsh((M + M.T) / 2)
    if not lam[0] > 1e-10 * lam[-1]:
        raise _kfast.KfastError(
            "P0_inf: the data do not determine every diffuse direction of the initial state (too few "
            "observations, or a state the outputs never see), so the exact diffuse smoother is not defined"
        )
    M_inv = np.linalg.inv(M)
    delta = -M_inv @ s
    x_smooth = x_base + X @ delta
    P_smooth = P_base + X @ M_inv @ np.swapaxes(X, -1, -2)
    P_lag1 = lag_base.copy()
    P_lag1[1:] += X[1:] @ M_inv @ np.swapaxes(X[:-1], -1, -2)
    out = dict(x_smooth=x_smooth, P_smooth=(P_smooth + np.swapaxes(P_smooth, -1, -2)) / 2, P_lag1=P_lag1)
    if outputs is not None:
        out = {k: (v if k in outputs else None) for k, v in out.items()}
    return SmootherResult(filter=exact_filter, **out)


def _moments(sm: "SmootherResult") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """innov, S, x_smooth, P_smooth, P_lag1 of a smoother run that stored them all."""
    arrays = (sm.filter.innov, sm.filter.S, sm.x_smooth, sm.P_smooth, sm.P_lag1)
    assert all(a is not None for a in arrays)
    return arrays  # type: ignore[return-value]
