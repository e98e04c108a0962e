"""Plots of kfast results (matplotlib, the optional ``plot`` extra: ``pip install "kfast[plot]"``).

Each function draws into the ``ax`` it is given (or a new figure's axes) and returns the axes,
so plots compose the matplotlib way:

- :func:`plot_estimates` — estimates over time with confidence bands (a filter, smoother,
  particle or multiple-model result), the truth and the measurements beside them;
- :func:`plot_track` — a 2-D track with covariance ellipses;
- :func:`plot_innovations` — the standardized innovations with ±z bands and their NIS
  (``FilterResult.plot_diagnostics`` draws statsmodels' four panels);
- :func:`plot_mode_probabilities` — the mode probabilities of an IMM, a model bank or a
  Gaussian sum, stacked;
- :func:`plot_particles` — a particle cloud with point sizes by weight.

Bands and ellipses are Gaussian: x ± z σ with z the two-sided standard normal quantile of
``level``, ellipses the ``level`` region of the 2 × 2 marginal covariance (radius
sqrt(χ²₂ quantile) = sqrt(−2 log(1 − level))).
"""

from __future__ import annotations

from statistics import NormalDist
from typing import Any, Optional, Sequence

import numpy as np
from numpy.typing import ArrayLike

from kfast._kfast import KfastError

__all__ = ["plot_estimates", "plot_track", "plot_innovations", "plot_mode_probabilities", "plot_particles"]


def _pyplot() -> Any:
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - exercised only without matplotlib
        raise ImportError('kfast.plot needs matplotlib: pip install "kfast[plot]"') from exc
    return plt


def _level(level: float) -> float:
    if not isinstance(level, (int, float)) or not 0.0 < float(level) < 1.0:
        raise KfastError(f"level: expected a probability in (0, 1), got {level!r}")
    return float(level)


def _moments(result: Any) -> tuple[np.ndarray, Optional[np.ndarray], str]:
    """(mean (T, n), covariance (T, n, n) or None, label) of a result: the smoothed moments if
    it has them, else the filtered ones."""
    for mean, cov, label in (("x_smooth", "P_smooth", "smoothed"), ("x_filt", "P_filt", "filtered")):
        x = getattr(result, mean, None)
        if x is not None:
            return np.asarray(x), getattr(result, cov, None), label
    raise KfastError(
        f"result: expected a result with x_filt or x_smooth (a filter, smoother, particle or multiple-model "
        f"result), got {type(result).__name__}"
    )


def _axes(ax: Any, nrows: int = 1, figsize: Any = None) -> Any:
    if ax is not None:
        return ax
    plt = _pyplot()
    _, axes = plt.subplots(nrows, 1, sharex=True, squeeze=False, figsize=figsize or (8, 2.2 * nrows + 0.6))
    return axes[:, 0]


def plot_estimates(
    result: Any,
    components: Optional[Sequence[int]] = None,
    truth: Optional[ArrayLike] = None,
    y: Optional[ArrayLike] = None,
    observed: Optional[Sequence[int]] = None,
    level: float = 0.95,
    time: Optional[ArrayLike] = None,
    names: Optional[Sequence[str]] = None,
    ax: Any = None,
) -> Any:
    """Each state component over time: the estimate, its ``level`` band x ± z sqrt(P_ii), the
    true state (``truth``, (T, n)) and the measurements ``y`` ((T, m), drawn on the state
    components ``observed[j]`` ← y[:, j]; NaN gaps stay gaps).

    Parameters
    ----------
    result : a FilterResult, SmootherResult, ParticleResult or IMMResult (smoothed moments are
        used when present).
    components : the state components to draw (default all), one axes each.
    truth, y, observed : optional overlays (see above).
    level : the band's probability (default 0.95).
    time : the x axis values (default 0 .. T-1).
    names : a label per drawn component.
    ax : a sequence of axes, one per component (default: a new figure).

    Returns
    -------
    The axes (a NumPy array of them).
    """
    x, P, label = _moments(result)
    T, n = x.shape
    comps = list(range(n)) if components is None else [int(c) for c in components]
    for c in comps:
        if not 0 <= c < n:
            raise KfastError(f"components: {c} is not a state component (n = {n})")
    t = np.arange(T) if time is None else np.asarray(time, float)
    if t.shape != (T,):
        raise KfastError(f"time: expected {T} values, got shape {t.shape}")
    z = NormalDist().inv_cdf(0.5 + _level(level) / 2)
    axes = np.atleast_1d(_axes(ax, len(comps)))
    if len(axes) != len(comps):
        raise KfastError(f"ax: expected {len(comps)} axes (one per component), got {len(axes)}")
    truth_arr = None if truth is None else _series("truth", truth, T, n)
    y_arr = None
    if y is not None:
        y_arr = _series("y", y, T, None)
        obs = list(range(y_arr.shape[1])) if observed is None else [int(c) for c in observed]
        if len(obs) != y_arr.shape[1]:
            raise KfastError(f"observed: expected one state component per column of y ({y_arr.shape[1]}), got {len(obs)}")
    for a, c, i in zip(axes, comps, range(len(comps))):
        a.plot(t, x[:, c], color="C0", lw=1.2, label=f"{label} estimate")
        if P is not None:
            sd = np.sqrt(np.clip(np.asarray(P)[:, c, c], 0.0, None))
            a.fill_between(t, x[:, c] - z * sd, x[:, c] + z * sd, color="C0", alpha=0.2, lw=0,
                           label=f"{level:.0%} band")
        if truth_arr is not None:
            a.plot(t, truth_arr[:, c], color="k", lw=0.8, ls="--", label="truth")
        if y_arr is not None:
            for j, s in enumerate(obs):
                if s == c:
                    a.plot(t, y_arr[:, j], ".", color="C3", ms=2.5, label="measurements")
        a.set_ylabel(names[i] if names is not None else f"x[{c}]")
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("t")
    return axes


def plot_track(
    result: Any,
    dims: Sequence[int] = (0, 1),
    truth: Optional[ArrayLike] = None,
    y: Optional[ArrayLike] = None,
    every: int = 10,
    level: float = 0.95,
    window: Optional[tuple[int, int]] = None,
    ax: Any = None,
) -> Any:
    """A 2-D track: the estimated path of the state components ``dims``, a ``level`` ellipse of
    their 2 × 2 covariance every ``every`` steps, the true path (``truth``, (T, n)) and the
    measured positions (``y``, (T, 2), in the same coordinates); ``window=(start, stop)`` draws
    only those steps (long tracks hide their ellipses). Returns the axes."""
    x, P, label = _moments(result)
    T, n = x.shape
    start, stop = (0, T) if window is None else (int(window[0]), int(window[1]))
    if not 0 <= start < stop <= T:
        raise KfastError(f"window: expected 0 <= start < stop <= {T}, got {window}")
    i, j = (int(d) for d in dims)
    if not (0 <= i < n and 0 <= j < n and i != j):
        raise KfastError(f"dims: expected two different state components below n = {n}, got {tuple(dims)}")
    if not isinstance(every, (int, np.integer)) or every < 1:
        raise KfastError(f"every: expected a positive integer, got {every!r}")
    radius = np.sqrt(-2.0 * np.log1p(-_level(level)))
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    from matplotlib.patches import Ellipse

    part = slice(start, stop)
    if y is not None:
        y_arr = _series("y", y, T, 2)[part]
        ax.plot(y_arr[:, 0], y_arr[:, 1], ".", color="C3", ms=2.5, label="measurements")
    if truth is not None:
        tr = _series("truth", truth, T, n)[part]
        ax.plot(tr[:, i], tr[:, j], color="k", lw=0.8, ls="--", label="truth")
    ax.plot(x[part, i], x[part, j], color="C0", lw=1.2, label=f"{label} estimate")
    if P is not None:
        P = np.asarray(P)
        for t in range(start, stop, every):
            C = P[t][np.ix_([i, j], [i, j])]
            vals, vecs = np.linalg.eigh(0.5 * (C + C.T))
            vals = np.clip(vals, 0.0, None)
            angle = float(np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1])))
            ax.add_patch(Ellipse((x[t, i], x[t, j]), 2 * radius * np.sqrt(vals[1]), 2 * radius * np.sqrt(vals[0]),
                                 angle=angle, fill=False, color="C0", alpha=0.6, lw=0.8))
    ax.set_xlabel(f"x[{i}]")
    ax.set_ylabel(f"x[{j}]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    return ax


def plot_innovations(result: Any, level: float = 0.95, ax: Any = None) -> Any:
    """The standardized innovations S^(-1/2) e(t) of each measurement component with the ±z band
    of ``level``, and the NIS per step with its χ²(m_t) bounds (``result.diagnostics()``; NaN
    where nothing was observed). ``ax``: two axes. Returns them."""
    if not hasattr(result, "diagnostics"):
        raise KfastError(f"result: expected a FilterResult (with diagnostics()), got {type(result).__name__}")
    d = result.diagnostics(alpha=1.0 - _level(level))
    axes = np.atleast_1d(_axes(ax, 2))
    z = NormalDist().inv_cdf(0.5 + level / 2)
    e = np.asarray(d.standardized_innov)
    t = np.arange(len(e))
    for k in range(e.shape[1]):
        axes[0].plot(t, e[:, k], lw=0.7, label=f"component {k}")
    for s in (-z, z):
        axes[0].axhline(s, color="k", ls=":", lw=0.8)
    axes[0].set_ylabel("standardized innovation")
    axes[0].legend(loc="upper right", fontsize="small")
    axes[1].plot(t, d.nis, lw=0.7, color="C2", label="NIS")
    axes[1].plot(t, d.nis_bounds[:, 0], color="k", ls=":", lw=0.8)
    axes[1].plot(t, d.nis_bounds[:, 1], color="k", ls=":", lw=0.8, label=f"{level:.0%} χ² bounds")
    axes[1].set_ylabel("NIS")
    axes[1].set_xlabel("t")
    axes[1].legend(loc="upper right", fontsize="small")
    return axes


def plot_mode_probabilities(result: Any, labels: Optional[Sequence[str]] = None, ax: Any = None) -> Any:
    """P(mode j at t | y(0..t)) of an IMM, model-bank or Gaussian-sum result (``mode_probs``,
    (T, r)) or of an array, stacked to 1. Returns the axes."""
    probs = np.asarray(getattr(result, "mode_probs", result), dtype=float)
    if probs.ndim != 2:
        raise KfastError(f"result: expected an IMMResult or a (T, r) array of mode probabilities, got shape {probs.shape}")
    T, r = probs.shape
    if labels is not None and len(labels) != r:
        raise KfastError(f"labels: expected {r} labels (one per mode), got {len(labels)}")
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 2.6))
    ax.stackplot(np.arange(T), probs.T, labels=list(labels) if labels is not None else [f"mode {j}" for j in range(r)],
                 alpha=0.8)
    ax.set_ylim(0.0, 1.0)
    ax.set_xlim(0, max(T - 1, 1))
    ax.set_ylabel("mode probability")
    ax.set_xlabel("t")
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_particles(
    particles: Any,
    weights: Optional[ArrayLike] = None,
    dims: Sequence[int] = (0, 1),
    step: int = -1,
    truth: Optional[ArrayLike] = None,
    ax: Any = None,
) -> Any:
    """A particle cloud in the state components ``dims`` (one component: a weighted histogram).
    ``particles`` is a ParticleResult run with ``keep="last"`` or ``keep="all"`` (then ``step``
    picks the step) or an (M, n) array with optional normalized ``weights`` (M,). Point areas
    are proportional to the weights; ``truth`` is the true state (n,) at that step. Returns
    the axes."""
    X, W = _cloud(particles, weights, step)
    M, n = X.shape
    d = [int(k) for k in dims]
    if not d or len(d) > 2 or any(not 0 <= k < n for k in d):
        raise KfastError(f"dims: expected one or two state components below n = {n}, got {tuple(dims)}")
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 5 if len(d) == 2 else 3))
    if len(d) == 1:
        ax.hist(X[:, d[0]], bins=min(60, max(10, M // 20)), weights=W, density=True, color="C0", alpha=0.6)
        if truth is not None:
            ax.axvline(float(np.asarray(truth, float).reshape(-1)[d[0]]), color="k", ls="--", label="truth")
            ax.legend(loc="upper right", fontsize="small")
        ax.set_xlabel(f"x[{d[0]}]")
        return ax
    ax.scatter(X[:, d[0]], X[:, d[1]], s=np.maximum(W * M * 6.0, 0.5), alpha=0.4, color="C0", lw=0, label=f"{M} particles")
    mean = W @ X
    ax.plot(mean[d[0]], mean[d[1]], "o", color="C1", label="weighted mean")
    if truth is not None:
        tv = np.asarray(truth, float).reshape(-1)
        ax.plot(tv[d[0]], tv[d[1]], "x", color="k", ms=9, label="truth")
    ax.set_xlabel(f"x[{d[0]}]")
    ax.set_ylabel(f"x[{d[1]}]")
    ax.legend(loc="best", fontsize="small")
    return ax


def _cloud(particles: Any, weights: Optional[ArrayLike], step: int) -> tuple[np.ndarray, np.ndarray]:
    if hasattr(particles, "particles"):
        X = particles.particles
        if X is None:
            raise KfastError('particles: the ParticleResult kept no particles; run the filter with keep="last" or "all"')
        lw = particles.log_weights
        X = np.asarray(X, float)
        lw = np.asarray(lw, float)
        if X.ndim == 3:
            if not -X.shape[0] <= step < X.shape[0]:
                raise KfastError(f"step: {step} is outside the {X.shape[0]} kept steps")
            X, lw = X[step], lw[step]
        return X, np.exp(lw)
    X = np.asarray(particles, float)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise KfastError(f"particles: expected a ParticleResult or an (M, n) array, got shape {X.shape}")
    if weights is None:
        return X, np.full(len(X), 1.0 / len(X))
    W = np.asarray(weights, float)
    if W.shape != (len(X),) or not np.all(np.isfinite(W)) or np.any(W < 0):
        raise KfastError(f"weights: expected {len(X)} finite nonnegative weights, got shape {W.shape}")
    return X, W / W.sum()


def _series(name: str, value: ArrayLike, T: int, width: Optional[int]) -> np.ndarray:
    a = np.asarray(value, float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or len(a) != T or (width is not None and a.shape[1] != width):
        want = f"({T}, {width})" if width is not None else f"({T}, m)"
        raise KfastError(f"{name}: expected shape {want}, got {a.shape}")
    return a
