"""Many independent series through one model, on all cores: ``kfast.filter_batch``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import flag, index
from kfast._arrays import as_float64
from kfast._progress import Progress
from kfast.linear.model import LinearGaussian, _update_form
from kfast._typing import UpdateForm

__all__ = ["filter_batch", "BatchResult"]


@dataclass(frozen=True, repr=False)
class BatchResult:
    """Filtered states of B series of T steps."""

    x_filt: np.ndarray
    """x(t|t) of every series, shape (B, T, n)."""
    P_filt: Optional[np.ndarray]
    """P(t|t), shape (B, T, n, n) (a read-only broadcast view of one (T, n, n) array when
    ``shared_covariance``); None with ``return_covs=False``."""
    loglik: np.ndarray
    """Log-likelihood of each series, shape (B,)."""
    shared_covariance: bool
    """True when the covariance recursion was computed once for all series (no missing value
    and one prior covariance): it does not depend on the data."""

    def __repr__(self) -> str:
        B, T, n = self.x_filt.shape
        return f"BatchResult(B={B}, T={T}, n={n}, shared_covariance={self.shared_covariance})"


def filter_batch(
    model: LinearGaussian,
    Y: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike] = None,
    return_covs: bool = True,
    threads: Optional[int] = None,
    form: UpdateForm = "joseph",
    progress: bool = False,
) -> BatchResult:
    """Kalman-filter many independent series through one model, in parallel.

    Parameters
    ----------
    model : LinearGaussian
        The model, shared by all series.
    Y : array_like, shape (B, T, m), or (B, T) when m = 1
        B series of T steps; NaN marks a missing value (per component).
    x0 : array_like, shape (n,) or (B, n)
        Prior mean x(0|-1), shared or one per series.
    P0 : array_like, shape (n, n) or (B, n, n)
        Prior covariance P(0|-1), shared or one per series.
    u : array_like, shape (T, k) or (B, T, k), optional
        Inputs, shared or one set per series; required when the model has B or D.
    return_covs : bool
        Whether to return P(t|t).
    threads : int, optional
        Number of threads (default: all cores); never more than the series or the cores.
    form : {"joseph", "standard", "sqrt", "ud", "information", "sequential"}
        The update form, as in :meth:`LinearGaussian.filter` (the robust forms filter each
        series alone: no shared covariance recursion).
    progress : bool
        Report progress on stderr (a tqdm bar when tqdm is installed): the series then go to
        the core in 20 chunks, one report each; the results are the same bits.

    Returns
    -------
    BatchResult
        x_filt (B, T, n), P_filt (B, T, n, n) or None, loglik (B,), shared_covariance.

    Raises
    ------
    KfastError, InnovationCovarianceError
        As for :meth:`LinearGaussian.filter` (the message names the series).

    Notes
    -----
    The series are filtered in parallel with one release of the GIL. When nothing is missing
    and P0 is shared, the covariance recursion (which does not depend on the data) is computed
    once and each series only moves its state: P_filt is then a read-only broadcast view.
    Results are those of ``model.filter`` on each series alone, bit for bit. A pure function
    of its arguments: it maps unchanged over chunks of series (e.g. blocks of a Dask array).

    Examples
    --------
    >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
    >>> Y = np.array([[0.3, -0.1, 0.7], [1.0, 0.5, -0.2]])
    >>> res = kfast.filter_batch(model, Y, x0=0.0, P0=1.0)
    >>> res
    BatchResult(B=2, T=3, n=1, shared_covariance=True)
    >>> bool(res.loglik[0] == model.loglik(Y[0], 0.0, 1.0))
    True
    >>> print(res.x_filt[0, :, 0].round(4))
    [0.15  0.01  0.354]
    """
    if not isinstance(model, LinearGaussian):
        raise _kfast.KfastError(f"model: expected a kfast.LinearGaussian, got {type(model).__name__}")
    Y, x0, P0, u, threads = batch_arguments(model.n_states, model.n_obs, Y, x0, P0, u, threads)
    return_covs = flag("return_covs", return_covs)
    B = Y.shape[0]

    def run(a: int, b: int) -> dict:
        def part(v: np.ndarray, per_series_ndim: int) -> np.ndarray:
            return v[a:b] if v.ndim == per_series_ndim else v

        return _kfast.filter_batch(model._core, Y[a:b], part(x0, 2), part(P0, 3), u=None if u is None else part(u, 3),
                                   return_covs=return_covs, threads=threads, form=_update_form(form))

    # With progress, the series go to the core in up to 20 chunks, one report each.
    on = flag("progress", progress) and B >= 2
    edges = np.linspace(0, B, (min(20, B) if on else 1) + 1).astype(int)
    parts = []
    with Progress(on, B, "filter_batch") as bar:
        for a, b in zip(edges[:-1], edges[1:]):
            parts.append(run(int(a), int(b)))
            bar.update(int(b - a))

    def join(arrays: list) -> np.ndarray:
        return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)

    def per_series(p: dict) -> np.ndarray:
        P = p["P_filt"]
        return np.broadcast_to(P, (len(p["x_filt"]),) + P.shape) if p["shared"] else P

    shared = all(p["shared"] for p in parts)
    P = None
    if return_covs:
        P = np.broadcast_to(parts[0]["P_filt"], (B,) + parts[0]["P_filt"].shape) if shared else join(
            [per_series(p) for p in parts])
    return BatchResult(x_filt=join([p["x_filt"] for p in parts]), P_filt=P, loglik=join([p["loglik"] for p in parts]),
                       shared_covariance=shared)


def batch_arguments(
    n: int, m: int, Y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike], threads: Optional[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Optional[np.ndarray], Optional[int]]:
    """The arguments of a batch filter as float64 arrays: Y as (B, T, m) (also (B, T) when
    m = 1), scalars x0 and P0 for a scalar state, and ``threads`` checked (>= 1) and capped at
    the number of series; the shapes of x0, P0 and u are checked by the core."""
    Y_arr = as_float64("Y", Y)
    if Y_arr.ndim == 2 and m == 1:
        Y_arr = Y_arr[:, :, None]
    if Y_arr.ndim != 3:
        raise _kfast.KfastError(f"Y: expected a 3-D array (B, T, m), got shape {Y_arr.shape}")
    x, P = as_float64("x0", x0), as_float64("P0", P0)
    if n == 1:  # scalars for a scalar state, as in the single-series filters
        x = x.reshape(1) if x.ndim == 0 else x
        P = P.reshape(1, 1) if P.ndim == 0 else P
    u_arr = None if u is None else as_float64("u", u)
    if threads is not None:
        if index("threads", threads) < 1:
            raise _kfast.KfastError(f"threads: must be >= 1, got {threads!r}")
        threads = min(int(threads), max(Y_arr.shape[0], 1))  # never more threads than series (nor cores)
    return Y_arr, x, P, u_arr, threads
