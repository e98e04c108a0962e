"""Quantized measurements (Söderström section 9.6): the quantizer, Sheppard's correction for a
Kalman filter, the exact likelihood of a quantized Gaussian measurement (for particle filters)
and the exact moments of a quantized Gaussian or uniform variable.

The quantizer of (9.101) rounds half **up**: x_Q = j delta when j delta - delta/2 <= x <
j delta + delta/2, i.e. delta * floor(x / delta + 1/2). ``np.round`` rounds half to even and
differs on every tie.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice
from kfast._arrays import as_float64
from kfast.sampling import _covariance, _square

__all__ = ["quantize", "sheppard", "quantized_loglik", "quantized_moments", "quantized_second_moment", "QuantizedMoments", "Quantized"]


def _steps(delta: ArrayLike, m: int, allow_zero: bool = False) -> np.ndarray:
    """``delta`` as m steps (a scalar is the step of every component)."""
    steps = as_float64("delta", delta)
    if steps.ndim == 0:
        steps = np.full(m, float(steps))
    if steps.shape != (m,):
        raise _kfast.KfastError(f"delta: expected a scalar or {m} steps (one per component), got shape {steps.shape}")
    floor_ok = steps >= 0 if allow_zero else steps > 0
    if not np.all(np.isfinite(steps) & floor_ok):
        raise _kfast.KfastError(f"delta: the steps must be finite and {'>= 0' if allow_zero else '> 0'}, got {steps}")
    return steps


def quantize(x: ArrayLike, delta: ArrayLike) -> np.ndarray:
    """The quantizer of Söderström (9.101): ``delta * floor(x / delta + 1/2)``, half **up**.

    Parameters
    ----------
    x : array_like
        Any shape; NaN stays NaN.
    delta : float or array_like, shape (m,)
        The step (> 0): one for every entry, or one per component of the last axis of x (a
        sensor whose outputs have different resolutions).

    Returns
    -------
    ndarray, the shape of x
        A new array (x is not modified). A finite x whose quantized value overflows (x / delta
        beyond the float range) is a ValueError.
    """
    values = as_float64("x", x)
    given = as_float64("delta", delta)
    if given.ndim > 1:
        raise _kfast.KfastError(f"delta: expected a scalar or shape (m,), got shape {given.shape}")
    m = 1 if given.ndim == 0 else given.size
    steps = _steps(given, m)
    if given.ndim == 1 and (values.ndim == 0 or values.shape[-1] != m):
        raise _kfast.KfastError(f"x: the last axis must have {m} components (one per step of delta), got shape {values.shape}")
    return np.asarray(_kfast.quantize(np.ascontiguousarray(values).reshape(-1, m), steps)).reshape(values.shape)


def sheppard(R: ArrayLike, delta: ArrayLike) -> np.ndarray:
    """Sheppard's correction (Söderström (9.102)-(9.103)): the measurement noise covariance of a
    Kalman filter fed quantized measurements, ``R + diag(delta**2 / 12)``.

    The quantization error of a component with step delta is treated as uniform on
    +-delta/2, independent of the signal and of the other components (variance delta^2/12).
    That holds when the density of h(x) + v is smooth on the scale of delta (std of the
    unquantized measurement above about delta/2; see :func:`quantized_moments` for the exact
    value); for coarser quantization use a particle filter with :func:`quantized_loglik`.

    Parameters
    ----------
    R : float or array_like, shape (m, m)
        The noise covariance of the unquantized measurement.
    delta : float or array_like, shape (m,)
        Each component's step (>= 0; 0 for a component that is not quantized).

    Returns
    -------
    ndarray, shape (m, m)
        A new matrix (R is not modified); use it as the model's R.
    """
    square = _square("R", R)
    if square.size == 0:
        raise _kfast.KfastError("R: expected a scalar or a non-empty (m, m) matrix, got shape (0, 0)")
    cov = _covariance("R", square, len(square), size_from="R")
    steps = _steps(delta, cov.shape[0], allow_zero=True)
    corrected = cov + np.diag(steps**2 / 12.0)
    if not np.all(np.isfinite(corrected)):
        raise _kfast.KfastError("delta: too large (delta**2 / 12 overflows)")
    return corrected


def quantized_loglik(
    y: ArrayLike, y_hat: ArrayLike, R: ArrayLike, delta: ArrayLike, bounds: Optional[tuple[ArrayLike, ArrayLike]] = None
) -> np.ndarray:
    """The exact log-likelihood of a quantized Gaussian measurement, for each of M predictions
    (the particles of a particle filter):

        log p(y_Q | x_r) = sum_i log P(y_i - delta_i/2 <= h_i(x_r) + v_i < y_i + delta_i/2),
        v ~ N(0, R), R diagonal (the components' cells are independent)

    each term log(Phi(b) - Phi(a)) computed without cancellation: in a tail as log Phi(-a) +
    log1p(-Phi(-b)/Phi(-a)), with log Phi accurate to x = -1e154 (asymptotic below -20); a cell
    narrow against the noise by the midpoint rule with its curvature terms. Not in Söderström,
    whose section 9.6 treats the Gaussian approximation; with R -> 0 the likelihood becomes the
    indicator of the cell and a particle filter degenerates (his section 9.7).

    Parameters
    ----------
    y : float or array_like, shape (m,)
        The quantized measurement: each component a multiple of its delta (a ValueError
        otherwise); NaN marks a missing component (it adds 0).
    y_hat : array_like, shape (M, m), or (M,) when m = 1
        h(x) of each particle.
    R : float or array_like, shape (m, m)
        The noise covariance before quantization; diagonal (>= 0; a zero variance makes the
        term 0 inside the cell and -inf outside).
    delta : float or array_like, shape (m,)
        The steps (> 0).
    bounds : (low, high), optional
        The lowest and highest levels of a saturating quantizer (scalars or (m,)): a
        measurement at ``low`` stands for everything below ``low + delta/2``, one at ``high``
        for everything from ``high - delta/2`` up.

    Returns
    -------
    ndarray, shape (M,)
        The log-likelihoods (-inf where a particle cannot have produced y).
    """
    obs = as_float64("y", y)
    obs = obs.reshape(1) if obs.ndim == 0 else obs
    if obs.ndim != 1 or obs.size == 0:
        raise _kfast.KfastError(f"y: expected a scalar or shape (m,), got shape {obs.shape}")
    m = obs.size
    pred = as_float64("y_hat", y_hat)
    if pred.ndim == 1 and m == 1:
        pred = pred.reshape(-1, 1)
    if pred.ndim != 2 or pred.shape[1] != m:
        raise _kfast.KfastError(f"y_hat: expected shape (M, {m}), got {pred.shape}")
    cov = as_float64("R", R)
    cov = cov.reshape(1, 1) if cov.ndim == 0 else cov
    if cov.shape != (m, m):
        raise _kfast.KfastError(f"R: expected a scalar or shape ({m}, {m}), got {cov.shape}")
    if np.any(cov != np.diag(np.diag(cov))):
        raise _kfast.KfastError("R: must be diagonal (correlated noise makes the cells of the components dependent)")
    var = np.diag(cov)
    if not np.all(np.isfinite(var) & (var >= 0)):
        raise _kfast.KfastError(f"R: the variances must be finite and >= 0, got {var}")
    steps, low, high = Quantized(delta, bounds)._spec(m)
    return np.asarray(_kfast.quantized_loglik(obs, pred, np.sqrt(var), steps, low, high))


@dataclass(frozen=True)
class Quantized:
    """The likelihood of a quantized measurement, for the particle filters
    (``NonlinearModel.particle_filter(..., likelihood=kfast.Quantized(delta))``,
    ``kfast.ParticleFilter``): y = Q_delta(h(x) + v), v ~ N(0, R) with the model's R diagonal,
    so that p(y | x) is the probability of y's cell (:func:`quantized_loglik`) instead of the
    Gaussian density N(y; h(x), R). Each observed y must be a level (a multiple of its delta).
    An angular output's h(x) is first moved by whole turns to within pi of y's cell.

    Attributes
    ----------
    delta : float or array_like, shape (m,)
        The steps (> 0), one for all outputs or one per output.
    bounds : (low, high), optional
        The lowest and highest levels of a saturating quantizer (scalars or (m,)).
    """

    delta: ArrayLike
    bounds: Optional[tuple[ArrayLike, ArrayLike]] = None

    def _spec(self, m: int) -> tuple[np.ndarray, Optional[np.ndarray], Optional[np.ndarray]]:
        """(delta, low, high) as float64 arrays of m values, for the compiled calls."""
        steps = _steps(self.delta, m)
        if self.bounds is None:
            return steps, None, None
        if not (isinstance(self.bounds, tuple) and len(self.bounds) == 2):
            raise _kfast.KfastError("bounds: expected a pair (low, high)")
        try:
            low, high = (np.broadcast_to(as_float64("bounds", b), (m,)).copy() for b in self.bounds)
        except ValueError as exc:
            raise _kfast.KfastError(f"bounds: expected scalars or {m} values each ({exc})") from None
        return steps, low, high


@dataclass(frozen=True)
class QuantizedMoments:
    """The exact moments of x_Q = Q_delta(x) (:func:`quantized_moments`)."""

    mean: float
    """E x_Q."""
    second_moment: float
    """E x_Q^2."""
    var: float
    """var x_Q = E x_Q^2 - (E x_Q)^2."""
    sheppard_var: float
    """Sheppard's approximation var x + delta^2/12 (9.103), for comparison."""


def quantized_moments(
    delta: float, mean: float = 0.0, std: float = 1.0, distribution: Literal["gaussian", "uniform"] = "gaussian"
) -> QuantizedMoments:
    """The exact mean, second moment and variance of Q_delta(x), x Gaussian N(mean, std^2) or
    uniform on mean +- sqrt(3) std, by the characteristic-function series of Söderström
    (9.115)-(9.131):

        E x_Q^2 = E x^2 + delta^2/12 - sum_{k != 0} [f_k''(0) phi(2 pi k/delta)
                                                     + 2 f_k'(0) phi'(2 pi k/delta)]

    with f_k(w) = (-1)^k sin(delta w/2) / (delta w/2 + k pi). The book prints the sum over
    k > 0; it runs over all k != 0 (pairing k with -k doubles the real parts for real x). The
    sum vanishes, and Sheppard's delta^2/12 is exact, when phi is zero beyond 2 pi/delta
    (9.132); for a Gaussian its terms scale as exp(-2 pi^2 std^2/delta^2): 7e-3 at std =
    delta/2, 3e-9 at std = delta, below rounding from std = 1.4 delta.

    Gaussian: the series, whose terms fall as exp(-2 pi^2 k^2 std^2/delta^2), summed until
    they are negligible (below std = 1.5e-5 delta, which would take over 1e5 terms, the sum over
    the few cells that hold the mass). Uniform: the terms fall only as 1/k^2, so the series is
    summed in closed form (Bernoulli polynomials: sum cos(2 pi k x)/k^2 = pi^2 B2(x), sum
    sin(2 pi k x)/k^3 = (2 pi^3/3) B3(x)). Exact to rounding either way; the test suite checks
    both against the direct sum over cells.

    Parameters
    ----------
    delta : float
        The quantization step (> 0).
    mean, std : float
        The mean and standard deviation (>= 0) of x.
    distribution : {"gaussian", "uniform"}

    Returns
    -------
    QuantizedMoments
    """
    choice("distribution", distribution, ("gaussian", "uniform"))
    values = {}
    for name, value in (("delta", delta), ("mean", mean), ("std", std)):
        arr = as_float64(name, value)
        if arr.ndim != 0:
            raise _kfast.KfastError(f"{name}: expected a scalar, got shape {arr.shape}")
        values[name] = float(arr)
    first, second, var = _kfast.quantized_moments(values["delta"], values["mean"], values["std"], distribution)
    return QuantizedMoments(first, second, var, values["std"] ** 2 + values["delta"] ** 2 / 12.0)


def quantized_second_moment(
    delta: float,
    dist: Literal["normal", "uniform"] = "normal",
    std: Optional[float] = None,
    mean: float = 0.0,
    low: Optional[float] = None,
    high: Optional[float] = None,
) -> float:
    """E x_Q^2, the exact second moment of the quantized variable Q_delta(x) (Söderström
    (9.131), the sum over all k != 0): x ~ N(mean, std^2) (``dist="normal"``) or uniform on
    [low, high] (``dist="uniform"``). :func:`quantized_moments` gives the mean and variance too.

    >>> round(kfast.quantized_second_moment(1.0, "uniform", low=-0.5, high=0.5), 12)
    0.0
    """
    choice("dist", dist, ("normal", "uniform"))
    if dist == "normal":
        if std is None or low is not None or high is not None:
            raise _kfast.KfastError("std: dist='normal' takes mean and std (not low, high)")
        return quantized_moments(delta, mean, std, "gaussian").second_moment
    if low is None or high is None or std is not None:
        raise _kfast.KfastError("low: dist='uniform' takes low and high (not std)")
    lo, hi = (float(as_float64(name, v)) for name, v in (("low", low), ("high", high)))
    if not lo < hi:
        raise _kfast.KfastError(f"low: must be below high, got low = {lo}, high = {hi}")
    return quantized_moments(delta, 0.5 * (lo + hi), (hi - lo) / np.sqrt(12.0), "uniform").second_moment
