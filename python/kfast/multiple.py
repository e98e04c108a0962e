"""Multiple-model estimation (Söderström section 9.5): r filters -- the *modes* -- run side by
side on the same measurements, with the Bayes probabilities of the modes.

- :func:`imm_filter` and the streaming :class:`IMMFilter`: the interacting multiple-model filter
  (Söderström (9.64)-(9.86)), for a system that switches between models as a Markov chain;
- :func:`model_bank`: the fixed bank (9.56)-(9.63), for a system that is one of r models;
- :func:`gaussian_sum`: the Gaussian-sum filter (9.43)-(9.55), one nonlinear model filtered from
  the components of a Gaussian-mixture prior.

A mode is a :class:`kfast.LinearGaussian` (filtered by the Kalman filter) or a
:class:`kfast.NonlinearModel` (by the EKF or the UKF, ``method=``). Conventions as everywhere in
kfast: the prior (x0, P0) is x(0|-1), P(0|-1), and ``mode_probs`` the prior mode probabilities
of step 0, mu(0|-1); each step is the update with y(t), then the time update.
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from typing import Any, Literal, Mapping, Optional, Sequence, Union, cast

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice
from kfast._arrays import as_float64
from kfast.linear.model import LinearGaussian
from kfast.nonlinear.model import NonlinearModel
from kfast.nonlinear.streaming import ExtendedKalmanFilter, UnscentedKalmanFilter
from kfast.sigma import SigmaPoints

__all__ = ["IMMResult", "IMMFilter", "IMM", "ModelBank", "imm_filter", "model_bank", "gaussian_sum"]

Model = Union[LinearGaussian, NonlinearModel]
Method = Literal["ekf", "ukf"]
StateMap = Union[ArrayLike, tuple]
_FIELDS = ("x_filt", "P_filt", "x_pred", "P_pred", "mode_probs", "mode_probs_pred", "loglik_t")


@dataclass(frozen=True, repr=False)
class IMMResult:
    """What a multiple-model filter computed over T steps with r modes.

    The combined estimates are the moments of the mixture of the modes' Gaussians (Söderström
    (9.85)-(9.86): the mean first, then the positive semidefinite sum), in the state space of
    model 0 (n0 states); they are None for a bank of models of different sizes without maps.
    For :func:`gaussian_sum` the modes are the mixture's components: ``mode_probs`` are their
    weights and ``x_filt_modes`` their means.
    """

    mode_probs: np.ndarray
    """mu_j(t) = P(mode j at t | y(0..t)), shape (T, r); zero for a pruned component."""
    mode_probs_pred: np.ndarray
    """cbar_j(t) = P(mode j at t | y(0..t-1)) (Söderström (9.71)), shape (T, r)."""
    loglik: float
    """log p(y(0..T-1)), the sum of ``loglik_t``."""
    loglik_t: np.ndarray
    """log p(y(t) | y(0..t-1)) = log sum_j cbar_j(t) l_j(t) (9.84), shape (T,)."""
    x_filt: Optional[np.ndarray] = None
    """x(t|t) = sum_j mu_j x_j(t|t), shape (T, n0)."""
    P_filt: Optional[np.ndarray] = None
    """P(t|t), shape (T, n0, n0)."""
    x_pred: Optional[np.ndarray] = None
    """x(t|t-1) = sum_j cbar_j x_j(t|t-1), shape (T, n0)."""
    P_pred: Optional[np.ndarray] = None
    """P(t|t-1), shape (T, n0, n0)."""
    x_filt_modes: Optional[tuple[np.ndarray, ...]] = None
    """x_j(t|t) of each mode j, shapes (T, n_j) (NaN where a component was pruned)."""
    P_filt_modes: Optional[tuple[np.ndarray, ...]] = None
    """P_j(t|t) of each mode j, shapes (T, n_j, n_j)."""

    def __repr__(self) -> str:
        steps, r = self.mode_probs.shape
        return f"IMMResult(T={steps}, r={r}, loglik={self.loglik:.6g})"


def _models(models: Sequence[Model]) -> list[Model]:
    if isinstance(models, (LinearGaussian, NonlinearModel)) or not isinstance(models, Sequence):
        raise _kfast.KfastError("models: expected a list of LinearGaussian or NonlinearModel objects")
    out = list(models)
    if not out:
        raise _kfast.KfastError("models: expected at least one model")
    for j, model in enumerate(out):
        if not isinstance(model, (LinearGaussian, NonlinearModel)):
            raise _kfast.KfastError(f"models: model {j} is a {type(model).__name__}, not a LinearGaussian or NonlinearModel")
    return out


def _maps(state_maps: Optional[Mapping[tuple[int, int], StateMap]]) -> list[tuple]:
    """``{(i, j): A | (A, b) | (A, b, Sigma)}`` as (i, j, A, b, Sigma) rows."""
    if state_maps is None:
        return []
    if not isinstance(state_maps, Mapping):
        raise _kfast.KfastError("state_maps: expected a dict {(i, j): A or (A, b) or (A, b, Sigma)}")
    rows = []
    for key, value in state_maps.items():
        if not (isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, (int, np.integer)) for k in key)):
            raise _kfast.KfastError(f"state_maps: the key {key!r} is not a pair of model indices (i, j)")
        parts = value if isinstance(value, tuple) else (value,)
        if not 1 <= len(parts) <= 3:
            raise _kfast.KfastError(f"state_maps: the map {key} is not A, (A, b) or (A, b, Sigma)")
        A, b, Sigma = (list(parts) + [None, None])[:3]
        A = np.atleast_2d(as_float64("state_maps", A))
        b = None if b is None else np.atleast_1d(as_float64("state_maps", b))
        Sigma = None if Sigma is None else np.atleast_2d(as_float64("state_maps", Sigma))
        rows.append((int(key[0]), int(key[1]), A, b, Sigma))
    return rows


def _map_prior(x0: np.ndarray, P0: np.ndarray, row: tuple) -> tuple[np.ndarray, np.ndarray]:
    _, _, A, b, Sigma = row
    x = A @ x0 + (0.0 if b is None else b)
    P = A @ P0 @ A.T + (0.0 if Sigma is None else Sigma)
    return x, (P + P.T) / 2


def _priors(models: list[Model], x0: Any, P0: Any, maps: list[tuple], per_model: bool) -> list[tuple[Any, Any]]:
    """Each model's prior: from lists of r priors (always for ``per_model``; for r > 1 when
    x0 and P0 are lists of r), or one prior of model 0's size mapped by
    ``state_maps[(0, j)]`` into the models of other sizes."""
    r = len(models)
    listed = isinstance(x0, (list, tuple)) and isinstance(P0, (list, tuple)) and len(x0) == r and len(P0) == r
    if per_model or (listed and r > 1 and np.ndim(x0[0]) == 1):
        return list(zip(x0, P0))
    sizes = [m.n_states for m in models]
    priors: list[tuple[Any, Any]] = []
    for j in range(r):
        if sizes[j] == sizes[0]:
            priors.append((x0, P0))
            continue
        row = next((row for row in maps if row[:2] == (0, j)), None)
        if row is None:
            raise _kfast.KfastError(
                f"x0: model {j} has {sizes[j]} states, model 0 has {sizes[0]}: give a list of {r} priors, or state_maps[(0, {j})]"
            )
        x = np.atleast_1d(as_float64("x0", x0))
        P = np.atleast_2d(as_float64("P0", P0))
        priors.append(_map_prior(x, P, row))
    return priors


def _inputs(u: Any, r: int) -> list[Optional[np.ndarray]]:
    """One input (or None) per model: a list of r items each None or a NumPy array is one per
    model; anything else is the input of every model."""
    if isinstance(u, (list, tuple)) and len(u) == r and all(v is None or isinstance(v, np.ndarray) for v in u):
        return [None if v is None else as_float64("u", v) for v in u]
    return [None if u is None else as_float64("u", u)] * r


def _mode_filter(model: Model, x0: Any, P0: Any, method: str, options: dict[str, Any]) -> Any:
    """The streaming filter of one mode at its prior (its compiled core)."""
    if isinstance(model, LinearGaussian):
        return _kfast.KalmanFilter(model, x0, P0, form=options.get("form") or "joseph")
    if method == "ukf":
        ukf_form = cast(Literal["standard", "sqrt"], options.get("form") or "standard")
        return UnscentedKalmanFilter(model, x0, P0, points=options.get("points"), form=ukf_form)._core
    ekf_options = {k: v for k, v in options.items() if k in ("iterations", "iteration", "order") and v is not None}
    return ExtendedKalmanFilter(model, x0, P0, form=options.get("form") or "joseph", **ekf_options)._core


def _core(
    models: Sequence[Model],
    x0: Any,
    P0: Any,
    mode_probs: Optional[ArrayLike],
    transition: Optional[ArrayLike],
    state_maps: Optional[Mapping[tuple[int, int], StateMap]],
    method: str,
    options: dict[str, Any],
    prune: float = 0.0,
    merge: float = 0.0,
    per_model: bool = False,
) -> Any:
    mods = _models(models)
    method = choice("method", method, ("ekf", "ukf"))
    maps = _maps(state_maps)
    filters = [_mode_filter(m, x, P, method, options) for m, (x, P) in zip(mods, _priors(mods, x0, P0, maps, per_model))]
    r = len(mods)
    probs = np.full(r, 1.0 / r) if mode_probs is None else np.atleast_1d(as_float64("mode_probs", mode_probs))
    if probs.ndim != 1:
        raise _kfast.KfastError(f"mode_probs: expected {r} values, got shape {probs.shape}")
    trans = None if transition is None else np.atleast_2d(as_float64("transition", transition))
    return _kfast.MultipleModelFilter(filters, [float(p) for p in probs], trans, maps, float(prune), float(merge))


def _series(y: ArrayLike, m: int) -> np.ndarray:
    arr = as_float64("y", y)
    if arr.ndim == 1 and m == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] != m:
        raise _kfast.KfastError(f"y: expected shape (T, {m}) (m = {m} outputs), got {arr.shape}")
    return arr


def _run(core: Any, models: list[Model], y: ArrayLike, u: Any, outputs: Optional[Sequence[str]], modes: bool) -> IMMResult:
    y_arr = _series(y, models[0].n_obs)
    inputs = [None if v is None else (v[:, None] if v.ndim == 1 else v) for v in _inputs(u, len(models))]
    wanted = list(_FIELDS) if outputs is None else list(outputs)
    for name in wanted:
        choice("outputs", name, _FIELDS)
    fields = set(wanted) | {"mode_probs", "mode_probs_pred", "loglik_t"}
    out = core.filter(y_arr, inputs, sorted(fields) + (["modes"] if modes else []))
    if "x_filt_modes" in out:
        out["x_filt_modes"] = tuple(out["x_filt_modes"])
        out["P_filt_modes"] = tuple(out["P_filt_modes"])
    return IMMResult(**out)


_OPTIONS_DOC = """
    method : "ekf" or "ukf"
        The filter of the nonlinear models (linear models always get the Kalman filter).
    form : str, optional
        The covariance update of each filter: "joseph" (default) or "standard"; for the UKF
        "standard" (default) or "sqrt".
    points : kfast.sigma.SigmaPoints, optional
        The UKF's sigma points (kfast.sigma.merwe() by default).
    iterations, iteration, order
        The EKF's options, as in :meth:`NonlinearModel.ekf`.
"""


def imm_filter(
    models: Sequence[Model],
    transition: ArrayLike,
    y: ArrayLike,
    x0: Any,
    P0: Any,
    mode_probs: Optional[ArrayLike] = None,
    u: Any = None,
    *,
    state_maps: Optional[Mapping[tuple[int, int], StateMap]] = None,
    method: Method = "ekf",
    form: Optional[str] = None,
    points: Optional[SigmaPoints] = None,
    iterations: Optional[int] = None,
    iteration: Optional[str] = None,
    order: Optional[int] = None,
    outputs: Optional[Sequence[str]] = None,
    modes: bool = True,
) -> IMMResult:
    """The interacting multiple-model (IMM) filter, Söderström (9.64)-(9.86), over y (T, m).

    The system is in one of r modes, each a model (``models[j]``), and switches between them as
    a Markov chain: ``transition[i, j]`` = P(mode j at t+1 | mode i at t), rows summing to 1.
    Every step each mode's filter updates with y(t) (log-likelihood log l_j), the mode
    probabilities become mu_j = l_j cbar_j / c (9.82)-(9.84) (in logarithms), and before the time
    update each mode's estimate is replaced by the mixture of all modes' estimates weighted by
    mu_{i|j} = p_ij mu_i / cbar_j (9.70)-(9.73); then each mode predicts by its own model (its
    own input gain B_j: the book's (9.74) prints one G for all modes, its Example 9.2 has two).
    A mode that no mode can reach (cbar_j = 0) keeps its own state.

    Parameters
    ----------
    models : list of LinearGaussian or NonlinearModel
        The modes, with the same number of outputs m. Models of different state sizes need
        ``state_maps``. Linear models with a cross-covariance N cannot be mixed (refused).
    transition : array_like, shape (r, r)
        The mode transition matrix p_ij (row-stochastic; rows within 1e-8 of 1 are renormalised).
    y : array_like, shape (T, m)
        The measurements; NaN marks a missing component (a step with nothing observed leaves
        the probabilities at cbar).
    x0, P0 : array_like
        The prior x(0|-1), P(0|-1) of model 0 (and of every model of its size; mapped by
        ``state_maps[(0, j)]`` into the others), or lists of r per-model priors.
    mode_probs : array_like, shape (r,), optional
        mu(0|-1), the prior mode probabilities at step 0 (equal by default). filterpy's
        ``IMMEstimator(mu=mu0)`` uses mu0 @ transition at its first update.
    u : array_like or list, optional
        The input: one (T, k) array for every model, or a list of r NumPy arrays (or None), one
        per model (per-mode inputs).
    state_maps : dict, optional
        ``{(i, j): A | (A, b) | (A, b, Sigma)}``: model i's state read in model j's space as
        x_j = A x_i + b, covariance A P A' + Sigma (Sigma: the uncertainty of the states model i
        does not carry). Needed for every pair (i, j) of different sizes with p_ij > 0 and for
        (j, 0), since the combined estimates are in model 0's space (as MATLAB's switchimm;
        filterpy and Stone Soup have no such modes).
    outputs : sequence of str, optional
        The combined fields to compute ("x_filt", "P_filt", "x_pred", "P_pred"; all by default);
        the mode probabilities and log-likelihoods always are.
    modes : bool
        Whether to return the per-mode estimates ``x_filt_modes``, ``P_filt_modes``.
    """ + _OPTIONS_DOC + """
    Returns
    -------
    IMMResult

    Examples
    --------
    Söderström's Example 9.2, two first-order modes with different input gains:

    >>> slow = kfast.LinearGaussian(F=0.95, B=0.05, H=1.0, Q=0.01, R=0.25)
    >>> fast = kfast.LinearGaussian(F=0.5, B=2.0, H=1.0, Q=0.09, R=0.25)
    >>> u = np.where(np.arange(6) % 80 < 40, 1.0, -1.0)
    >>> res = kfast.imm_filter([slow, fast], [[0.98, 0.02], [0.02, 0.98]], [4.9, 4.7, 4.6, 4.4, 4.3, 4.1],
    ...                        x0=5.0, P0=1.0, mode_probs=[0.5, 0.5], u=u)
    >>> res.mode_probs.shape, bool(res.mode_probs[-1, 0] > 0.5)
    ((6, 2), True)
    """
    if transition is None:
        raise _kfast.KfastError("transition: required (the fixed bank without switching is kfast.model_bank)")
    options = dict(form=form, points=points, iterations=iterations, iteration=iteration, order=order)
    core = _core(models, x0, P0, mode_probs, transition, state_maps, method, options)
    return _run(core, _models(models), y, u, outputs, modes)


def model_bank(
    models: Sequence[Model],
    y: ArrayLike,
    x0: Any,
    P0: Any,
    mode_probs: Optional[ArrayLike] = None,
    u: Any = None,
    *,
    state_maps: Optional[Mapping[tuple[int, int], StateMap]] = None,
    method: Method = "ekf",
    form: Optional[str] = None,
    points: Optional[SigmaPoints] = None,
    iterations: Optional[int] = None,
    iteration: Optional[str] = None,
    order: Optional[int] = None,
    outputs: Optional[Sequence[str]] = None,
    modes: bool = True,
) -> IMMResult:
    """The fixed multiple-model bank, Söderström (9.56)-(9.63): the system is one of the r
    models and never switches; each model's filter runs on its own and the probabilities of the
    models are mu_j(t) = l_j(t) mu_j(t-1) / sum_i l_i(t) mu_i(t-1) (9.59)-(9.61). If the true
    model is in the bank its probability tends to 1; a wrong model's decays geometrically and
    cannot recover once it underflows to 0.

    The models may differ in state size (then give per-model priors x0, P0 as lists); the
    combined estimates are computed only when all have model 0's size or ``state_maps`` carry
    them into model 0's space ({(j, 0): ...}), else they are None. Parameters as
    :func:`imm_filter`, without ``transition``.
    """
    options = dict(form=form, points=points, iterations=iterations, iteration=iteration, order=order)
    core = _core(models, x0, P0, mode_probs, None, state_maps, method, options)
    combined = ("x_filt", "P_filt", "x_pred", "P_pred")
    if core.combined() is None:
        outputs = [name for name in (outputs or _FIELDS) if name not in combined]
    return _run(core, _models(models), y, u, outputs, modes)


def gaussian_sum(
    model: NonlinearModel,
    y: ArrayLike,
    means: ArrayLike,
    covs: ArrayLike,
    weights: Optional[ArrayLike] = None,
    u: Optional[ArrayLike] = None,
    *,
    method: Method = "ekf",
    prune: float = 0.0,
    merge: float = 0.0,
    form: Optional[str] = None,
    points: Optional[SigmaPoints] = None,
    iterations: Optional[int] = None,
    iteration: Optional[str] = None,
    order: Optional[int] = None,
    modes: bool = True,
) -> IMMResult:
    """The Gaussian-sum filter, Söderström (9.43)-(9.55): the prior of x(0) is the mixture
    sum_i weights[i] N(means[i], covs[i]), and each component runs its own EKF (or UKF) of the
    one model; after each update the weights become alpha_i(t) ~ alpha_i(t-1) gamma(y; yhat_i,
    S_i) (9.52), the time update leaves them as they are, and the estimates are the mixture's
    moments. With Gaussian noise the number of components stays r.

    Söderström has no mixture reduction; kfast offers two, both off by default: ``prune`` drops
    the components whose weight falls below it after an update (the largest always stays), and
    ``merge`` joins two components into their moment-matched Gaussian when Salmond's distance
    alpha_a alpha_b / (alpha_a + alpha_b) (m_a - m_b)' P^-1 (m_a - m_b) (P the merged
    covariance) is below it. Both only save time: they make the sum an approximation of the
    unreduced one.

    Parameters
    ----------
    model : NonlinearModel or LinearGaussian
    y : array_like, shape (T, m)
    means : array_like, shape (r, n)
        The components' means (priors x_i(0|-1)).
    covs : array_like, shape (r, n, n)
        Their covariances.
    weights : array_like, shape (r,), optional
        Their weights (equal by default), summing to 1.
    u : array_like, shape (T, k), optional
    """ + _OPTIONS_DOC + """
    Returns
    -------
    IMMResult
        ``mode_probs`` are the weights (T, r), ``x_filt_modes`` the components' means.
    """
    if not isinstance(model, (LinearGaussian, NonlinearModel)):
        raise _kfast.KfastError(f"model: expected a NonlinearModel or LinearGaussian, got {type(model).__name__}")
    m_arr = np.atleast_2d(as_float64("means", means))
    c_arr = as_float64("covs", covs)
    n = model.n_states
    if m_arr.ndim != 2 or m_arr.shape[1] != n:
        raise _kfast.KfastError(f"means: expected shape (r, {n}), got {np.shape(means)}")
    if c_arr.shape != (m_arr.shape[0], n, n):
        raise _kfast.KfastError(f"covs: expected shape ({m_arr.shape[0]}, {n}, {n}), got {c_arr.shape}")
    r = m_arr.shape[0]
    options = dict(form=form, points=points, iterations=iterations, iteration=iteration, order=order)
    core = _core([model] * r, list(m_arr), list(c_arr), weights, None, None, method, options, prune, merge, True)
    return _run(core, [model] * r, y, None if u is None else [u] * r, None, modes)


class IMMFilter:
    """The IMM filter (or, with ``transition=None``, the fixed bank) one measurement at a time:
    ``update(y)`` then ``predict()`` per step, as :class:`kfast.KalmanFilter`. The same steps
    give the numbers of :func:`imm_filter`. Arguments as there.

    >>> slow = kfast.LinearGaussian(F=0.95, H=1.0, Q=0.01, R=0.25)
    >>> fast = kfast.LinearGaussian(F=0.5, H=1.0, Q=0.09, R=0.25)
    >>> imm = kfast.IMMFilter([slow, fast], [[0.98, 0.02], [0.02, 0.98]], x0=5.0, P0=1.0)
    >>> imm.update(4.8); imm.predict()
    >>> imm.t, imm.mode_probs.shape
    (1, (2,))
    """

    def __init__(
        self,
        models: Sequence[Model],
        transition: Optional[ArrayLike],
        x0: Any,
        P0: Any,
        mode_probs: Optional[ArrayLike] = None,
        *,
        state_maps: Optional[Mapping[tuple[int, int], StateMap]] = None,
        method: Method = "ekf",
        form: Optional[str] = None,
        points: Optional[SigmaPoints] = None,
        iterations: Optional[int] = None,
        iteration: Optional[str] = None,
        order: Optional[int] = None,
    ) -> None:
        self._models = _models(models)
        options = dict(form=form, points=points, iterations=iterations, iteration=iteration, order=order)
        self._core = _core(self._models, x0, P0, mode_probs, transition, state_maps, method, options)

    def _rows(self, u: Any) -> list[Optional[np.ndarray]]:
        return [None if v is None else np.atleast_1d(v) for v in _inputs(u, len(self._models))]

    def update(self, y: ArrayLike, u: Any = None) -> None:
        """The update of every mode with y(t) (NaN: missing) and the mode probabilities; ``u``
        one input for all models or a list of r (or None)."""
        self._core.update(np.atleast_1d(as_float64("y", y)), self._rows(u))

    def predict(self, u: Any = None) -> None:
        """The time update to t + 1: the mixing, then each mode's prediction."""
        self._core.predict(self._rows(u))

    @property
    def x(self) -> Optional[np.ndarray]:
        """The combined estimate x(t|t) after an update, x(t|t-1) before it (model 0's space;
        None for a bank of different sizes without maps)."""
        combined = self._core.combined()
        return None if combined is None else cast(np.ndarray, combined[0])

    @property
    def P(self) -> Optional[np.ndarray]:
        """Its covariance."""
        combined = self._core.combined()
        return None if combined is None else cast(np.ndarray, combined[1])

    @property
    def mode_probs(self) -> np.ndarray:
        """mu(t) after an update, cbar(t) before it, shape (r,)."""
        return cast(np.ndarray, self._core.mode_probs)

    def mode_estimate(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Model j's own estimate (x, P)."""
        return cast(tuple, self._core.mode_estimate(int(j)))

    @property
    def t(self) -> int:
        """The current step."""
        return int(self._core.t)

    @property
    def loglik(self) -> float:
        """The sum of the log-likelihood terms so far."""
        return float(self._core.loglik)

    def __repr__(self) -> str:
        return f"IMMFilter(t={self.t}, r={len(self._models)})"


@dataclass(frozen=True, repr=False)
class _Bank:
    """The models and options of a multiple-model filter, run by ``filter``."""

    models: Sequence[Model]
    _: KW_ONLY
    mode_probs: Optional[ArrayLike] = None
    state_maps: Optional[Mapping[tuple[int, int], StateMap]] = None
    method: Method = "ekf"
    form: Optional[str] = None
    points: Optional[SigmaPoints] = None
    iterations: Optional[int] = None
    iteration: Optional[str] = None
    order: Optional[int] = None

    def _options(self) -> dict[str, Any]:
        return dict(mode_probs=self.mode_probs, state_maps=self.state_maps, method=self.method, form=self.form,
                    points=self.points, iterations=self.iterations, iteration=self.iteration, order=self.order)

    def _transition(self) -> Optional[ArrayLike]:
        """The mode transition matrix (None: a fixed bank)."""
        return None

    def stream(self, x0: Any, P0: Any) -> IMMFilter:
        """The same filter one measurement at a time, from the prior x0, P0."""
        options = self._options()
        return IMMFilter(self.models, self._transition(), x0, P0, options.pop("mode_probs"), **options)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(r={len(self.models)}, method={self.method!r})"


@dataclass(frozen=True, repr=False)
class IMM(_Bank):
    """The interacting multiple-model filter as an object: ``kfast.IMM(models, transition=Pi,
    mode_probs=mu0).filter(y, x0, P0)`` is :func:`imm_filter` (Söderström (9.64)-(9.86));
    ``.stream(x0, P0)`` its :class:`IMMFilter`. ``mode_probs`` is the prior of the modes at
    y(0): cbar(0) = mu0, no transition applied before the first update. A one-mode IMM is the
    mode's own filter. The other arguments as :func:`imm_filter`.

    >>> slow = kfast.LinearGaussian(F=0.95, H=1.0, Q=0.01, R=0.25)
    >>> fast = kfast.LinearGaussian(F=0.5, H=1.0, Q=0.09, R=0.25)
    >>> imm = kfast.IMM([slow, fast], transition=[[0.98, 0.02], [0.02, 0.98]])
    >>> imm.filter([4.9, 4.7, 4.6], x0=5.0, P0=1.0).mode_probs.shape
    (3, 2)
    """

    transition: Optional[ArrayLike] = None

    def _transition(self) -> Optional[ArrayLike]:
        return self.transition

    def filter(self, y: ArrayLike, x0: Any, P0: Any, u: Any = None, *, outputs: Optional[Sequence[str]] = None,
               modes: bool = True) -> IMMResult:
        """The IMM over y (T, m) from the prior x0, P0 (as :func:`imm_filter`)."""
        if self.transition is None:
            raise _kfast.KfastError("transition: required (the fixed bank without switching is kfast.ModelBank)")
        return imm_filter(self.models, self.transition, y, x0, P0, u=u, outputs=outputs, modes=modes, **self._options())



@dataclass(frozen=True, repr=False)
class ModelBank(_Bank):
    """The fixed multiple-model bank as an object: ``kfast.ModelBank(models,
    mode_probs=mu0).filter(y, x0, P0)`` is :func:`model_bank` (Söderström (9.56)-(9.63)): the
    system is one of the models and never switches. Arguments as :func:`model_bank`."""

    def filter(self, y: ArrayLike, x0: Any, P0: Any, u: Any = None, *, outputs: Optional[Sequence[str]] = None,
               modes: bool = True) -> IMMResult:
        """The bank over y (T, m) from the prior x0, P0 (as :func:`model_bank`)."""
        return model_bank(self.models, y, x0, P0, u=u, outputs=outputs, modes=modes, **self._options())

