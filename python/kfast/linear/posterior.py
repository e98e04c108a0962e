"""The noise given the data: the disturbance smoother (moments of w(t), v(t) given y) and the
simulation smoother (draws of x, w, v from their joint posterior), Durbin & Koopman (2002).

Both stand on the RTS smoother's x(t|T-1), P(t|T-1) and lag-one covariances; the formulas and
their conventions are in docs/algorithms.md, "Disturbance and simulation smoothers".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from kfast import _kfast
from kfast._args import index
from kfast._arrays import as_float64

if TYPE_CHECKING:
    from kfast.linear.model import LinearGaussian, SmootherResult

__all__ = ["DisturbanceSmootherResult", "PosteriorDraws"]


@dataclass(frozen=True, repr=False)
class DisturbanceSmootherResult:
    """The smoothed disturbances of x[t+1] = F x[t] + B u[t] + w[t], y[t] = H x[t] + D u[t] + v[t]
    given all T observations (Durbin & Koopman (2012) Sec. 4.5; KFAS's ``etahat``/``epshat``)."""

    w_smooth: np.ndarray
    """E[w(t) | y(0..T-1)], shape (T, n). Row T-1 is w(T-1), which moves x past the data (0
    unless N correlates it with v(T-1))."""
    w_cov: np.ndarray
    """Var(w(t) | y), shape (T, n, n)."""
    v_smooth: np.ndarray
    """E[v(t) | y], shape (T, m); for an observed component y - H x(t|T-1) - D u."""
    v_cov: np.ndarray
    """Var(v(t) | y), shape (T, m, m)."""
    smoother: "SmootherResult"
    """The state smoother they come from (x_smooth, P_smooth, P_lag1, filter)."""

    def __repr__(self) -> str:
        T, n = self.w_smooth.shape
        return f"DisturbanceSmootherResult(T={T}, n={n}, m={self.v_smooth.shape[1]})"


@dataclass(frozen=True, repr=False)
class PosteriorDraws:
    """Joint draws of the states and disturbances from p(x, w, v | y) (Durbin & Koopman 2002)."""

    x: np.ndarray
    """States x(t), shape (draws, T, n)."""
    w: np.ndarray
    """State disturbances w(t), shape (draws, T, n)."""
    v: np.ndarray
    """Measurement disturbances v(t), shape (draws, T, m)."""

    def __repr__(self) -> str:
        return f"PosteriorDraws(draws={self.x.shape[0]}, T={self.x.shape[1]}, n={self.x.shape[2]})"


class _Conditioning:
    """The per-step maps of the disturbance smoother, which depend on the model and on which
    components are observed, not on the data.

    At step t the noise xi = (w, v) ~ N(0, J), J = [[Q, N], [N', R]]. Given all states and the
    data, its "seen" part o is known: w(t) = x(t+1) - F x(t) - B u(t) for t < T-1 and the observed
    components of v(t) = y(t) - H x(t) - D u(t); the rest (w(T-1), missing components of v) is
    Gaussian given o alone, as the xi(t) are independent. So
        E[xi | y] = A E[o | y],  Var(xi | y) = J - A J + A Var(o | y) A',  A = J (Pi J Pi)^+ Pi
    with Pi the diagonal 0/1 mask of o (the pseudo-inverse serves singular J: Q of lower rank).
    """

    def __init__(self, model: "LinearGaussian", observed: np.ndarray):
        T, m = observed.shape
        n = model.n_states
        J = np.broadcast_to(model._joint_noise_cov(), (T, n + m, n + m))
        seen = np.concatenate([np.ones((T, n), bool), observed], axis=1)
        seen[-1, :n] = False
        mask = seen[:, :, None] & seen[:, None, :]
        self.J = J
        self.A = J @ np.linalg.pinv(np.where(mask, J, 0.0), hermitian=True) * seen[:, None, :]
        self.n, self.m, self.T = n, m, T
        self.seen = seen
        lead = (T,)
        self.F = np.broadcast_to(model.F, lead + (n, n))
        self.H = np.broadcast_to(model.H, lead + (m, n))

    def seen_noise(self, model: "LinearGaussian", y: np.ndarray, x: np.ndarray, u: Optional[np.ndarray]) -> np.ndarray:
        """o(t) = (x(t+1) - F x(t) - B u(t), y(t) - H x(t) - D u(t)) at the states x, shape (T, n + m);
        0 where not seen."""
        n, T = self.n, self.T
        w = np.zeros((T, n))
        w[:-1] = x[1:] - np.einsum("tij,tj->ti", self.F[:-1], x[:-1])
        v = np.where(np.isnan(y), 0.0, y) - np.einsum("tij,tj->ti", self.H, x)
        if u is not None:
            if model.B is not None:
                w[:-1] -= np.einsum("tij,tj->ti", np.broadcast_to(model.B, (T,) + model.B.shape[-2:])[:-1], u[:-1])
            if model.D is not None:
                v -= np.einsum("tij,tj->ti", np.broadcast_to(model.D, (T,) + model.D.shape[-2:]), u)
        return np.where(self.seen, np.concatenate([w, v], axis=1), 0.0)

    def seen_noise_cov(self, smoother: "SmootherResult") -> np.ndarray:
        """Var(o(t) | y) from the smoothed covariances of z = (x(t), x(t+1)): o = G z + data,
        G = [[-F, I], [-H, 0]], shape (T, n + m, n + m); 0 where not seen."""
        n, m, T = self.n, self.m, self.T
        P, lag = smoother.P_smooth, smoother.P_lag1
        assert P is not None and lag is not None
        Z = np.zeros((T, 2 * n, 2 * n))
        Z[:, :n, :n] = P
        Z[:-1, n:, n:] = P[1:]
        Z[:-1, n:, :n] = lag[1:]
        Z[:-1, :n, n:] = np.swapaxes(lag[1:], -1, -2)
        G = np.zeros((T, n + m, 2 * n))
        G[:, :n, :n] = -self.F
        G[:, :n, n:] = np.eye(n)
        G[:, n:, :n] = -self.H
        V = G @ Z @ np.swapaxes(G, -1, -2)
        both = self.seen[:, :, None] & self.seen[:, None, :]
        return np.where(both, V, 0.0)


def disturbance_smooth(
    model: "LinearGaussian", y: Any, x0: Any, P0: Any, u: Any = None, P0_inf: Any = None
) -> DisturbanceSmootherResult:
    """The body of :meth:`LinearGaussian.disturbance_smooth` (see there)."""
    smoother = model.smooth(y, x0, P0, u=u, P0_inf=P0_inf)
    y_arr, _, _, u_arr = model._data(y, x0, P0, u)
    cond = _Conditioning(model, ~np.isnan(y_arr))
    assert smoother.x_smooth is not None
    mean = np.einsum("tij,tj->ti", cond.A, cond.seen_noise(model, y_arr, smoother.x_smooth, u_arr))
    At = np.swapaxes(cond.A, -1, -2)
    cov = cond.J - cond.A @ cond.J + cond.A @ cond.seen_noise_cov(smoother) @ At
    cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    n = model.n_states
    return DisturbanceSmootherResult(
        w_smooth=np.ascontiguousarray(mean[:, :n]),
        w_cov=np.ascontiguousarray(cov[:, :n, :n]),
        v_smooth=np.ascontiguousarray(mean[:, n:]),
        v_cov=np.ascontiguousarray(cov[:, n:, n:]),
        smoother=smoother,
    )


def simulation_smoother(
    model: "LinearGaussian",
    y: Any,
    x0: Any,
    P0: Any,
    u: Any = None,
    draws: int = 1,
    seed: Any = None,
    variates: Any = None,
    P0_inf: Any = None,
) -> PosteriorDraws:
    """The body of :meth:`LinearGaussian.simulation_smoother` (see there)."""
    from kfast.linear.model import _generator

    draws = index("draws", draws)
    if draws == 0:
        raise _kfast.KfastError("draws: must be >= 1, got 0")
    y_arr, x0_arr, P0_arr, u_arr = model._data(y, x0, P0, u)
    T, n, m = y_arr.shape[0], model.n_states, model.n_obs
    _kfast.check_alloc("draws", [[draws, T, n], [draws, T, n], [draws, T, m], [draws, T, n + m]])
    model._core.check_prior(x0_arr, P0_arr)
    # (Checked by the first smoother call, which names it.)
    P_inf = None if P0_inf is None else model._prior(x0, P0_inf, ("x0", "P0_inf"))[1]
    z0, z = _variates(variates, draws, T, n, m, _generator(seed))

    # One draw (x+, y+) from the model per variate set, through the lower Cholesky factors.
    x_start = x0_arr + z0 @ _lower_factor(P0_arr).T
    noise = np.einsum("tij,dtj->dti", np.broadcast_to(_lower_factor(model._joint_noise_cov()), (T, n + m, n + m)), z)
    # The data's smoother, and the same smoother (zero prior mean, no inputs) of y - y+ per draw:
    # x~ = x+ + E0[x | y - y+] (Durbin & Koopman 2002, the mean correction).
    zero_u = None if u_arr is None else np.zeros_like(u_arr)
    cond = _Conditioning(model, ~np.isnan(y_arr))
    x_out = np.empty((draws, T, n))
    xi_out = np.empty((draws, T, n + m))
    zero = np.zeros(n)
    for d in range(draws):
        w_plus, v_plus = np.ascontiguousarray(noise[d, :, :n]), np.ascontiguousarray(noise[d, :, n:])
        x_plus, y_plus = model._core.propagate(x_start[d], w_plus, v_plus, u=u_arr)
        gap = y_arr - y_plus
        sm = model.smooth(gap, zero, P0_arr, u=zero_u, outputs=("x_smooth",), P0_inf=P_inf)
        assert sm.x_smooth is not None
        x_out[d] = x_plus + sm.x_smooth
        xi_out[d] = noise[d] + np.einsum("tij,tj->ti", cond.A, cond.seen_noise(model, gap, sm.x_smooth, zero_u))
    return PosteriorDraws(x=x_out, w=np.ascontiguousarray(xi_out[..., :n]), v=np.ascontiguousarray(xi_out[..., n:]))


def _variates(variates: Any, draws: int, T: int, n: int, m: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The N(0, 1) variates: (initial (draws, n), noise (draws, T, n + m)), w's before v's."""
    if variates is None:
        return rng.standard_normal((draws, n)), rng.standard_normal((draws, T, n + m))
    if not isinstance(variates, dict) or set(variates) != {"initial", "state", "measurement"}:
        raise _kfast.KfastError("variates: expected a dict with keys 'initial', 'state' and 'measurement'")
    shapes = {"initial": (draws, n), "state": (draws, T, n), "measurement": (draws, T, m)}
    arrays = {}
    for key, shape in shapes.items():
        a = as_float64(f"variates['{key}']", variates[key])
        if a.size != int(np.prod(shape)):
            raise _kfast.KfastError(f"variates['{key}']: expected {int(np.prod(shape))} values (shape {shape}), got shape {a.shape}")
        if not np.isfinite(a).all():
            raise _kfast.KfastError(f"variates['{key}']: must be finite")
        arrays[key] = a.reshape(shape)
    return arrays["initial"], np.concatenate([arrays["state"], arrays["measurement"]], axis=-1)


def _lower_factor(C: np.ndarray) -> np.ndarray:
    """L with L L' = C: the lower Cholesky factor (KFAS's and statsmodels' choice, so that the same
    variates give their draws) when C is positive definite, else the symmetric square root from
    the eigenvalues (singular covariances: Q of lower rank, R = 0)."""
    try:
        return np.linalg.cholesky(C)
    except np.linalg.LinAlgError:
        from kfast.linear.model import _psd_sqrt

        return _psd_sqrt(C)
