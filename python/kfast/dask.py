"""Many series beyond one machine: kfast's batch functions over Dask collections (the optional
``dask`` extra: ``pip install "kfast[dask]"``).

Each function takes the series as a Dask array of shape (B, T, m) (or (B, T) when m = 1),
chunked along the series only (other axes are made one chunk), or as a Dask bag of (T, m)
arrays for :func:`fit`, and returns Dask collections: nothing runs until ``.compute()``. Each
chunk of series is one task running the ordinary in-process function (:func:`kfast.filter_batch`,
:meth:`LinearGaussian.smooth`, :func:`kfast.fit`) on a worker; the model and the arguments travel
by pickling. Results are bit for bit those of the in-process call on the whole array (the
filter's arithmetic does not depend on which series share a call).

Run on a cluster by connecting a client first — the same code runs locally or remotely::

    from dask.distributed import Client
    client = Client("tcp://scheduler:8786")        # or Client(LocalCluster(n_workers=8))
    res = kfast.dask.filter_batch(model, Y, x0, P0).compute()

``threads``: the threads of each task's kfast call (default 1: Dask's workers already run one
task per core; raise it for workers with one task slot and many cores).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional

import numpy as np
from numpy.typing import ArrayLike

import kfast
from kfast._kfast import KfastError
from kfast._typing import UpdateForm
from kfast.linear.batch import BatchResult

__all__ = ["filter_batch", "loglik", "smooth", "fit", "DaskBatchResult", "DaskSmootherResult"]


def _dask() -> tuple[Any, Any]:
    try:
        import dask
        import dask.array as da
    except ImportError as exc:  # pragma: no cover - exercised only without dask
        raise ImportError('kfast.dask needs dask: pip install "kfast[dask]"') from exc
    return dask, da


@dataclass(frozen=True, repr=False)
class DaskBatchResult:
    """:func:`filter_batch`'s lazy outputs: Dask arrays chunked by series like Y."""

    x_filt: Any
    """x(t|t), (B, T, n)."""
    P_filt: Optional[Any]
    """P(t|t), (B, T, n, n); None with ``return_covs=False``."""
    loglik: Any
    """Log-likelihood of each series, (B,)."""

    def compute(self, **kwargs: Any) -> BatchResult:
        """Computes all outputs in one pass (keyword arguments go to ``dask.compute``)."""
        dask, _ = _dask()
        x, P, ll = dask.compute(self.x_filt, self.P_filt, self.loglik, **kwargs)
        return BatchResult(x_filt=x, P_filt=P, loglik=ll, shared_covariance=False)

    def __repr__(self) -> str:
        B, T, n = self.x_filt.shape
        return f"DaskBatchResult(B={B}, T={T}, n={n}, chunks={len(self.x_filt.chunks[0])})"


@dataclass(frozen=True, repr=False)
class DaskSmootherResult:
    """:func:`smooth`'s lazy outputs: Dask arrays chunked by series like Y."""

    x_smooth: Any
    """x(t|T), (B, T, n)."""
    P_smooth: Any
    """P(t|T), (B, T, n, n)."""

    def compute(self, **kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
        """(x_smooth, P_smooth) as NumPy arrays, in one pass."""
        dask, _ = _dask()
        x, P = dask.compute(self.x_smooth, self.P_smooth, **kwargs)
        return x, P

    def __repr__(self) -> str:
        B, T, n = self.x_smooth.shape
        return f"DaskSmootherResult(B={B}, T={T}, n={n}, chunks={len(self.x_smooth.chunks[0])})"


def _series_array(Y: Any, m: int) -> Any:
    """Y as a Dask array (B, T, m) with one chunk along T and m."""
    _, da = _dask()
    if not isinstance(Y, da.Array):
        raise KfastError(f"Y: expected a Dask array of shape (B, T, m), got {type(Y).__name__} (use kfast.filter_batch "
                         "for NumPy arrays, or dask.array.from_array)")
    if Y.ndim == 2 and m == 1:
        Y = Y[:, :, None]
    if Y.ndim != 3 or Y.shape[2] != m:
        raise KfastError(f"Y: expected shape (B, T, {m}), got {Y.shape}")
    if any(np.isnan(s) for s in Y.shape):
        raise KfastError("Y: the array's shape must be known (call compute_chunk_sizes() first)")
    return Y.rechunk({1: -1, 2: -1})


def _per_series(name: str, value: Any, B: int, trailing: int) -> tuple[Optional[np.ndarray], Any]:
    """(per-series NumPy array, shared value): x0, P0 or u given once or one per series."""
    if value is None:
        return None, None
    arr = np.asarray(value, dtype=float) if not hasattr(value, "compute") else value
    if arr.ndim == trailing + 1:
        if arr.shape[0] != B:
            raise KfastError(f"{name}: one per series expected {B} rows, got {arr.shape[0]}")
        return arr, None
    return None, arr


def _map_chunks(Ys: Any, x0: Any, P0: Any, u: Any, run: Callable[..., tuple], shapes: list[tuple]) -> list[Any]:
    """One task per chunk of series: ``run(block, x0, P0, u)`` with the per-series arguments
    sliced like the chunk, returning one array per entry of ``shapes`` (each output's shape
    after its series axis); the outputs concatenated along the series as Dask arrays."""
    dask, da = _dask()
    B = Ys.shape[0]
    args = [_per_series(name, v, B, trailing) for name, v, trailing in (("x0", x0, 1), ("P0", P0, 2), ("u", u, 2))]
    offsets = np.cumsum((0,) + Ys.chunks[0])
    outs: list[list[Any]] = [[] for _ in shapes]
    for a, b, block in zip(offsets[:-1], offsets[1:], Ys.to_delayed().ravel()):
        sliced = [per[a:b] if per is not None else shared for per, shared in args]
        task = dask.delayed(run, nout=len(shapes), pure=True)(block, *sliced)
        for k, shape in enumerate(shapes):
            outs[k].append(da.from_delayed(task[k], shape=(int(b - a),) + shape, dtype=float))
    return [da.concatenate(o, axis=0) for o in outs]


def filter_batch(
    model: kfast.LinearGaussian,
    Y: Any,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike] = None,
    return_covs: bool = True,
    threads: Optional[int] = 1,
    form: UpdateForm = "joseph",
) -> DaskBatchResult:
    """:func:`kfast.filter_batch` over a Dask array of series, one task per chunk of series.
    x0 (n,) or (B, n), P0 (n, n) or (B, n, n), u (T, k) or (B, T, k) as in-process (NumPy or
    Dask, per-series ones are split like Y). The covariances are per series: (B, T, n, n)."""
    Ys = _series_array(Y, model.n_obs)
    T, n = Ys.shape[1], model.n_states

    def run(block: np.ndarray, x0b: Any, P0b: Any, ub: Any) -> tuple[np.ndarray, ...]:
        res = kfast.filter_batch(model, block, x0b, P0b, u=ub, return_covs=return_covs, threads=threads, form=form)
        if res.P_filt is None:
            return res.x_filt, res.loglik
        return res.x_filt, np.ascontiguousarray(res.P_filt), res.loglik  # a shared view materialized

    shapes = [(T, n), (T, n, n), ()] if return_covs else [(T, n), ()]
    outs = _map_chunks(Ys, x0, P0, u, run, shapes)
    return DaskBatchResult(x_filt=outs[0], P_filt=outs[1] if return_covs else None, loglik=outs[-1])


def loglik(
    model: kfast.LinearGaussian,
    Y: Any,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike] = None,
    threads: Optional[int] = 1,
) -> Any:
    """The log-likelihood of each series, a Dask array (B,) (:func:`filter_batch` without
    covariances)."""
    return filter_batch(model, Y, x0, P0, u=u, return_covs=False, threads=threads).loglik


def smooth(
    model: kfast.LinearGaussian,
    Y: Any,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike] = None,
) -> DaskSmootherResult:
    """The RTS smoother (:meth:`LinearGaussian.smooth`) of each series, one task per chunk of
    series: x_smooth (B, T, n) and P_smooth (B, T, n, n) as Dask arrays."""
    Ys = _series_array(Y, model.n_obs)
    T, n = Ys.shape[1], model.n_states

    def run(block: np.ndarray, x0b: Any, P0b: Any, ub: Any) -> tuple[np.ndarray, np.ndarray]:
        xs, Ps = [], []
        for i in range(len(block)):
            # Per-series arguments have one more axis than shared ones.
            res = model.smooth(block[i], x0b[i] if np.ndim(x0b) == 2 else x0b, P0b[i] if np.ndim(P0b) == 3 else P0b,
                               u=ub[i] if ub is not None and np.ndim(ub) == 3 else ub, outputs=("x_smooth", "P_smooth"))
            assert res.x_smooth is not None and res.P_smooth is not None
            xs.append(res.x_smooth)
            Ps.append(res.P_smooth)
        return np.stack(xs), np.stack(Ps)

    x, P = _map_chunks(Ys, x0, P0, u, run, [(T, n), (T, n, n)])
    return DaskSmootherResult(x_smooth=x, P_smooth=P)


def fit(build: Callable[[np.ndarray], tuple], theta0: ArrayLike, series: Any, **fit_kwargs: Any) -> Any:
    """:func:`kfast.fit` of one independent model per series: ``series`` is a Dask bag of (T, m)
    arrays (or a Dask array (B, T, m), one series per row); returns a Dask bag of FitResult in
    the same order. ``build`` must pickle (a module-level function, or one cloudpickle can
    send); ``fit_kwargs`` go to every fit."""
    dask, da = _dask()
    import dask.bag as db

    if isinstance(series, da.Array):
        if series.ndim not in (2, 3):
            raise KfastError(f"series: expected a Dask array (B, T, m) or (B, T), got shape {series.shape}")
        rows = series.rechunk({i: -1 for i in range(1, series.ndim)})
        series = db.from_delayed([dask.delayed(list)(block) for block in rows.to_delayed().ravel()])
    if not isinstance(series, db.Bag):
        raise KfastError(f"series: expected a Dask bag of (T, m) arrays or a Dask array (B, T, m), got {type(series).__name__}")
    theta = np.asarray(theta0, dtype=float)
    return series.map(lambda y: kfast.fit(build, theta, np.asarray(y), **fit_kwargs))
