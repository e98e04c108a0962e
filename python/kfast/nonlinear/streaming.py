"""Streaming nonlinear filters: the EKF, the UKF and the particle filter one measurement at a
time."""

from __future__ import annotations

from typing import Any, Optional, Sequence, Union, cast

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, index
from kfast._arrays import as_float64
from kfast._typing import Form, Iteration, Resample, UkfForm
from kfast.nonlinear.model import BuiltinFunction, NonlinearModel, _angles, _particle_options, _spec
from kfast.nonlinear.likelihood import Likelihood, ParticleMove
from kfast.sigma import SigmaPoints, merwe

__all__ = ["ExtendedKalmanFilter", "UnscentedKalmanFilter", "ParticleFilter"]


class _State:
    """The state every streaming nonlinear filter shows."""

    _core: Any
    _model: NonlinearModel

    @property
    def x(self) -> np.ndarray:
        """x(t|t) after an update, x(t|t-1) otherwise, shape (n,) (a particle filter's: the
        weighted mean of its particles)."""
        return cast(np.ndarray, self._core.x)

    @property
    def P(self) -> np.ndarray:
        """Its covariance, shape (n, n)."""
        return cast(np.ndarray, self._core.P)

    @property
    def t(self) -> int:
        """The current step (0 at the start; ``predict`` advances it)."""
        return int(self._core.t)

    @property
    def loglik(self) -> float:
        """The sum of the updates' log-likelihood terms so far."""
        return float(self._core.loglik)


class _Streaming(_State):
    """What the EKF and the UKF share: update / predict / step."""

    def update(
        self,
        y: ArrayLike,
        u: Optional[ArrayLike] = None,
        *,
        h: Any = None,
        R: Optional[ArrayLike] = None,
        angles: Optional[Sequence[int]] = None,
    ) -> None:
        """The measurement update with y(t) (NaN marks a missing component): x, P become
        x(t|t), P(t|t). Several updates at one step chain (each starts from the last).

        ``h`` and ``R`` (both) update by another sensor instead of the model's: a callable
        ``h(X, t, u)``, a compiled function or a built-in, with its own m (R is m x m) and its
        own angular outputs (``angles``; a built-in brings its own).
        """
        y_arr = as_float64("y", y)
        y_arr = y_arr.reshape(1) if y_arr.ndim == 0 else y_arr
        u_arr = None if u is None else _vector("u", u)
        if h is None and R is None:
            if angles is not None:
                raise _kfast.KfastError("angles: only with a second sensor's h and R")
            self._core.update(y_arr, u_arr)
            return
        if h is None or R is None:
            raise _kfast.KfastError("h, R: a second sensor needs both its h and its R")
        R_arr = as_float64("R", R)
        R_arr = R_arr.reshape(1, 1) if R_arr.size == 1 and R_arr.ndim < 2 else R_arr
        if R_arr.ndim != 2:
            raise _kfast.KfastError(f"R: expected an (m, m) matrix, got shape {R_arr.shape}")
        declared = tuple(angles) if angles is not None else (h.angles if isinstance(h, BuiltinFunction) else ())
        self._core.update(y_arr, u_arr, _spec("h", h), R_arr, list(_angles(declared, R_arr.shape[0])))

    def predict(self, u: Optional[ArrayLike] = None) -> None:
        """The time update to t + 1: x, P become x(t+1|t), P(t+1|t) (from x(t|t), or from
        x(t|t-1) when there was no update at step t)."""
        self._core.predict(None if u is None else _vector("u", u))

    def step(self, y: ArrayLike, u: Optional[ArrayLike] = None) -> None:
        """``update(y, u)`` then ``predict(u)``."""
        self.update(y, u)
        self.predict(u)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(t={self.t}, n={self._model.n_states})"


class ExtendedKalmanFilter(_Streaming):
    """The EKF of a :class:`kfast.NonlinearModel` one measurement at a time, from the prior
    (x0, P0) = x(0|-1), P(0|-1): ``update(y)`` then ``predict()`` per step, as
    :class:`kfast.KalmanFilter`. The same steps give the numbers of :meth:`NonlinearModel.ekf`.
    Options as there (``iterations``, ``iteration``, ``form``, ``order``).

    >>> ct = kfast.models.coordinated_turn(dt=0.1, q=1.0, sigma_omega=0.05)
    >>> model = kfast.NonlinearModel(ct, kfast.models.range_bearing(), ct.Q, np.diag([1.0, 1e-4]), n=5)
    >>> ekf = kfast.ExtendedKalmanFilter(model, [100, 50, 5, -2, 0.1], np.diag([100, 100, 4, 4, 0.01]))
    >>> ekf.update([111.8, 0.4636]); ekf.predict()
    >>> ekf.t, ekf.x.shape
    (1, (5,))
    """

    def __init__(
        self,
        model: NonlinearModel,
        x0: ArrayLike,
        P0: ArrayLike,
        iterations: int = 0,
        iteration: Iteration = "book",
        form: Form = "joseph",
        order: int = 1,
    ) -> None:
        self._model = _model(model)
        choice("iteration", iteration, ("book", "gauss-newton"))
        choice("form", form, ("joseph", "standard"))
        x, P = model._prior(x0, P0)
        self._core = _kfast.NonlinearKalmanFilter(
            model._core, x, P, "ekf", merwe()._spec(), form=form, iterations=index("iterations", iterations),
            iteration=iteration, order=index("order", order),
        )


class UnscentedKalmanFilter(_Streaming):
    """The UKF of a :class:`kfast.NonlinearModel` one measurement at a time, from the prior
    (x0, P0) = x(0|-1), P(0|-1), with the sigma points ``points`` (``kfast.sigma.merwe()`` by
    default) and the covariance ``form`` ("standard", or "sqrt": the square-root UKF). The same
    steps give the numbers of :meth:`NonlinearModel.ukf`."""

    def __init__(
        self,
        model: NonlinearModel,
        x0: ArrayLike,
        P0: ArrayLike,
        points: Optional[SigmaPoints] = None,
        form: UkfForm = "standard",
    ) -> None:
        self._model = _model(model)
        points = model._points(points)
        x, P = model._prior(x0, P0)
        form = cast(UkfForm, choice("form", form, ("standard", "sqrt")))
        self._core = _kfast.NonlinearKalmanFilter(model._core, x, P, "ukf", points._spec(), form=form)


class ParticleFilter(_State):
    """The particle filter of a :class:`kfast.NonlinearModel` one measurement at a time: M =
    ``n_particles`` particles drawn from the prior N(x0, P0) at t = 0, then ``update(y)`` and
    ``predict()`` per step. The same steps with the same options and seed give the numbers of
    :meth:`NonlinearModel.particle_filter`, bit for bit; the options are those.

    >>> pf = kfast.ParticleFilter(kfast.models.ungm(), [0.0], [[5.0]], n_particles=1000, seed=1)
    >>> loglik_0 = pf.update([0.4]); resampled = pf.predict()
    >>> pf.t, pf.x.shape, pf.particles.shape
    (1, (1,), (1000, 1))
    """

    def __init__(
        self,
        model: NonlinearModel,
        x0: ArrayLike,
        P0: ArrayLike,
        n_particles: int,
        resample: Resample = "multinomial",
        ess_threshold: Optional[float] = None,
        seed: int = 0,
        threads: Optional[int] = None,
        likelihood: Optional[Likelihood] = None,
        regularize: Union[bool, float] = False,
        copies: int = 1,
        move: Optional[ParticleMove] = None,
    ) -> None:
        self._model = _model(model)
        options = _particle_options(
            n_particles, resample, ess_threshold, seed, threads, likelihood, self._model.n_obs, regularize, copies, move
        )
        self._n_particles: int = options["n_particles"]
        x, P = model._prior(x0, P0)
        self._core = _kfast.ParticleFilter(model._core, x, P, **options)

    def update(self, y: ArrayLike, u: Optional[ArrayLike] = None) -> float:
        """The measurement update with y(t) (NaN marks a missing component): the weights
        times p(y(t) | x_i). Returns the estimate of log p(y(t) | y(0..t-1)). After an error
        the particles and weights are unchanged."""
        return float(self._core.update(_vector("y", y), None if u is None else _vector("u", u)))

    def predict(self, u: Optional[ArrayLike] = None) -> bool:
        """Resampling (every step, or when the ESS is below the threshold) and the time update
        to t + 1. Returns whether the particles were resampled."""
        return bool(self._core.predict(None if u is None else _vector("u", u)))

    def step(self, y: ArrayLike, u: Optional[ArrayLike] = None) -> float:
        """``update(y, u)`` then ``predict(u)``; returns the update's log-likelihood term."""
        loglik_t = self.update(y, u)
        self.predict(u)
        return loglik_t

    @property
    def particles(self) -> np.ndarray:
        """The particles, shape (M, n) (a copy)."""
        return cast(np.ndarray, self._core.particles)

    @property
    def log_weights(self) -> np.ndarray:
        """Their normalized log-weights, shape (M,)."""
        return cast(np.ndarray, self._core.log_weights)

    @property
    def ess(self) -> float:
        """The effective sample size 1 / sum W_i^2 of the particles now."""
        return float(self._core.ess)

    def __repr__(self) -> str:
        return f"ParticleFilter(t={self.t}, n={self._model.n_states}, particles={self._n_particles})"


def _model(model: Any) -> NonlinearModel:
    if not isinstance(model, NonlinearModel):
        raise _kfast.KfastError(f"model: expected a kfast.NonlinearModel, got {type(model).__name__}")
    return model


def _vector(name: str, value: ArrayLike) -> np.ndarray:
    arr = as_float64(name, value)
    return arr.reshape(1) if arr.ndim == 0 else arr
