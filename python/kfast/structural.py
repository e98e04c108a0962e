"""Structural time-series components (Harvey 1989; Durbin & Koopman (2012) ch. 3; statsmodels'
``UnobservedComponents`` and ``SARIMAX``) as ``LinearGaussian`` models, and their sums
(docs/algorithms.md, "Structural time-series models"). Re-exported by ``kfast.models``.

Every component is a univariate signal H x(t) with its own state; ``combine`` adds components
(block-diagonal F and Q, H side by side) and an irregular term: y(t) = sum of signals + e(t),
var e = ``irregular``. Variances are discrete (per step); the states are in the order
statsmodels uses (level, trend; seasonal; cycle; ARMA), so that ``combine`` of the same pieces in
that order has statsmodels' matrices. The state of a nonstationary component (level, trend,
seasonal) has an unknown start: filter with a vague P0, or exactly with ``P0_inf`` when the
exact diffuse filter is available.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from kfast import _kfast
from kfast._args import index
from kfast._arrays import finite_vector
from kfast._numbers import real_scalar
from kfast.linear.model import LinearGaussian

__all__ = ["local_level", "local_linear_trend", "smooth_trend", "seasonal", "cycle", "arma", "combine"]

KfastError = _kfast.KfastError


def _variance(name: str, value: object) -> float:
    x = real_scalar(name, value, "a variance (a number >= 0)")
    if not (math.isfinite(x) and x >= 0):
        raise KfastError(f"{name}: must be a finite variance >= 0, got {value!r}")
    return x


def _component(F: np.ndarray, Q: np.ndarray, irregular: float) -> LinearGaussian:
    H = np.zeros((1, F.shape[0]))
    H[0, 0] = 1.0
    return LinearGaussian(F, H, Q, [[_variance("irregular", irregular)]])


def local_level(level_var: float, irregular: float = 0.0) -> LinearGaussian:
    """The random walk plus noise: mu(t+1) = mu(t) + eta(t), y(t) = mu(t) + e(t).

    ``level_var`` = var eta, ``irregular`` = var e (statsmodels' ``sigma2.level``,
    ``sigma2.irregular``; Durbin & Koopman (2012) (2.3)). State [mu]."""
    return _component(np.ones((1, 1)), np.array([[_variance("level_var", level_var)]]), irregular)


def local_linear_trend(level_var: float, slope_var: float, irregular: float = 0.0) -> LinearGaussian:
    """mu(t+1) = mu(t) + nu(t) + eta(t), nu(t+1) = nu(t) + zeta(t), y(t) = mu(t) + e(t).

    State [mu, nu] (level, slope); F = [[1, 1], [0, 1]], Q = diag(``level_var``,
    ``slope_var``) (statsmodels' ``level="local linear trend"``; Durbin & Koopman (2012) (3.2))."""
    Q = np.diag([_variance("level_var", level_var), _variance("slope_var", slope_var)])
    return _component(np.array([[1.0, 1.0], [0.0, 1.0]]), Q, irregular)


def smooth_trend(slope_var: float, irregular: float = 0.0) -> LinearGaussian:
    """The local linear trend without level noise (an integrated random walk): Q =
    diag(0, ``slope_var``) (statsmodels' ``level="smooth trend"``)."""
    return local_linear_trend(0.0, slope_var, irregular)


def seasonal(period: int, var: float, form: str = "dummy", harmonics: Optional[int] = None, irregular: float = 0.0) -> LinearGaussian:
    """A seasonal component of ``period`` s.

    ``form="dummy"`` (statsmodels' ``seasonal=s``; Durbin & Koopman (2012) (3.3)): the s seasonal
    effects sum to a noise, gamma(t+1) = -gamma(t) - ... - gamma(t-s+2) + omega(t), var omega =
    ``var``; state [gamma(t), ..., gamma(t-s+2)] (s - 1 states).

    ``form="trigonometric"`` (statsmodels' ``freq_seasonal=[{"period": s, "harmonics": h}]``;
    Durbin & Koopman (2012) (3.6)): h harmonics (default floor(s/2)), each a pair
    [gamma_j, gamma*_j] rotated by lambda_j = 2 pi j / s with noise of variance ``var`` in both,
    the signal the sum of the gamma_j (2 h states; statsmodels keeps both states of j = s/2 too).
    """
    s = index("period", period)
    if s < 2:
        raise KfastError(f"period: must be >= 2, got {period!r}")
    v = _variance("var", var)
    if form == "dummy":
        F = np.zeros((s - 1, s - 1))
        F[0] = -1.0
        F[1:, :-1] = np.eye(s - 2)
        Q = np.zeros((s - 1, s - 1))
        Q[0, 0] = v
        return _component(F, Q, irregular)
    if form != "trigonometric":
        raise KfastError(f"form: expected 'dummy' or 'trigonometric', got {form!r}")
    h = s // 2 if harmonics is None else index("harmonics", harmonics)
    if not 1 <= h <= s // 2:
        raise KfastError(f"harmonics: must be in 1..{s // 2} for period {s}, got {harmonics!r}")
    blocks = [_rotation(2 * math.pi * j / s, 1.0) for j in range(1, h + 1)]
    F = _block_diag(blocks)
    H = np.tile([1.0, 0.0], h)[None, :]
    return LinearGaussian(F, H, v * np.eye(2 * h), [[_variance("irregular", irregular)]])


def cycle(frequency: float, var: float, damping: float = 1.0, irregular: float = 0.0) -> LinearGaussian:
    """The stochastic cycle ``[c, c*](t+1) = rho [[cos l, sin l], [-sin l, cos l]] [c, c*](t) +
    noise``, both noises of variance ``var``, signal c (statsmodels' ``cycle=True,
    stochastic_cycle=True, damped_cycle=True`` with ``frequency.cycle`` = l in radians per step,
    ``damping.cycle`` = rho; Durbin & Koopman (2012) (3.13)). Period 2 pi / l."""
    lam = _finite("frequency", frequency)
    if not 0.0 <= lam <= math.pi:
        raise KfastError(f"frequency: must be in [0, pi] radians per step, got {frequency!r}")
    rho = _finite("damping", damping)
    if not 0.0 <= rho <= 1.0:
        raise KfastError(f"damping: must be in [0, 1], got {damping!r}")
    return _component(_rotation(lam, rho), _variance("var", var) * np.eye(2), irregular)


def arma(ar: Sequence[float] = (), ma: Sequence[float] = (), var: float = 1.0, irregular: float = 0.0) -> LinearGaussian:
    """ARMA(p, q) in statsmodels' sign convention (``SARIMAX(order=(p, 0, q))``):

        y(t) = phi_1 y(t-1) + ... + phi_p y(t-p) + e(t) + theta_1 e(t-1) + ... + theta_q e(t-q),

    ``ar`` = [phi_1..phi_p], ``ma`` = [theta_1..theta_q], var e = ``var``. NOTE: the opposite
    sign of ``kfast.models.ar``, which follows Söderström (y(t) + a_1 y(t-1) + ... = e(t)):
    ``models.ar(a, ...)`` is ``arma(ar=-a, ...)``.

    State-space form of Harvey (as SARIMAX): r = max(p, q + 1) states, F = [phi | I; 0] (phi
    padded with zeros in the first column, the identity above the diagonal), Q = var g g' with
    g = [1, theta_1, ..., theta_{r-1}] (rank one), H = [1, 0, ..., 0].
    """
    phi = _coefficients("ar", ar)
    theta = _coefficients("ma", ma)
    r = max(phi.size, theta.size + 1)
    F = np.zeros((r, r))
    F[: phi.size, 0] = phi
    F[:-1, 1:] = np.eye(r - 1)
    g = np.zeros(r)
    g[0] = 1.0
    g[1 : theta.size + 1] = theta
    return _component(F, _variance("var", var) * np.outer(g, g), irregular)


def combine(*components: LinearGaussian, irregular: float = 0.0) -> LinearGaussian:
    """The sum of components: y(t) = H_1 x_1(t) + H_2 x_2(t) + ... + e(t), the states stacked.

    F and Q block-diagonal, H side by side, R = the components' own R summed plus
    ``irregular`` (var e). Components must be constant models with no inputs and no N and the
    same number of outputs."""
    if not components:
        raise KfastError("components: give at least one model to combine")
    m = components[0].n_obs
    for i, c in enumerate(components):
        if not isinstance(c, LinearGaussian):
            raise KfastError(f"components[{i}]: expected a kfast.LinearGaussian, got {type(c).__name__}")
        if c.steps is not None or c.B is not None or c.D is not None or c.N is not None:
            raise KfastError(f"components[{i}]: must be a constant model without B, D or N")
        if c.n_obs != m:
            raise KfastError(f"components[{i}]: has {c.n_obs} outputs, the first has {m}")
    F = _block_diag([c.F for c in components])
    Q = _block_diag([c.Q for c in components])
    H = np.concatenate([c.H for c in components], axis=1)
    R = sum(c.R for c in components) + _variance("irregular", irregular) * np.eye(m)
    return LinearGaussian(F, H, Q, R)


def _rotation(lam: float, rho: float) -> np.ndarray:
    c, s = math.cos(lam), math.sin(lam)
    return rho * np.array([[c, s], [-s, c]])


def _block_diag(blocks: Sequence[np.ndarray]) -> np.ndarray:
    n = sum(b.shape[0] for b in blocks)
    out = np.zeros((n, n))
    k = 0
    for b in blocks:
        out[k : k + b.shape[0], k : k + b.shape[0]] = b
        k += b.shape[0]
    return out


def _finite(name: str, value: object) -> float:
    x = real_scalar(name, value, "a real number")
    if not math.isfinite(x):
        raise KfastError(f"{name}: must be finite, got {value!r}")
    return x


def _coefficients(name: str, value: object) -> np.ndarray:
    a = np.asarray(value, dtype=object)
    if a.size == 0:
        return np.zeros(0)
    return finite_vector(name, value, f"[{name}_1, ..., {name}_k]")
