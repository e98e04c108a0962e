"""Many tracks through one nonlinear model, on all cores: ``kfast.ekf_batch``, ``kfast.ukf_batch``."""

from __future__ import annotations

from typing import Optional, Union, cast

from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, flag, index
from kfast._typing import Form, Iteration, UkfForm
from kfast.linear.batch import BatchResult, batch_arguments
from kfast.nonlinear.model import NonlinearModel
from kfast.sigma import SigmaPoints

__all__ = ["ekf_batch", "ukf_batch"]


def ekf_batch(
    model: NonlinearModel,
    Y: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike] = None,
    return_covs: bool = True,
    threads: Optional[int] = None,
    form: Form = "joseph",
    iterations: int = 0,
    iteration: Iteration = "book",
    order: int = 1,
) -> BatchResult:
    """The extended Kalman filter of many independent series (tracks) through one model, in parallel.

    Each series is filtered exactly as ``model.ekf(Y[b], x0[b], P0[b], u[b], ...)`` would filter
    it alone (bit for bit, whatever ``threads``), with one release of the GIL for the whole batch.

    Parameters
    ----------
    model : NonlinearModel
        The model, shared by all series.
    Y : array_like, shape (B, T, m), or (B, T) when m = 1
        B series of T steps; NaN marks a missing value (per component).
    x0 : array_like, shape (n,) or (B, n)
        Prior mean x(0|-1), shared or one per series.
    P0 : array_like, shape (n, n) or (B, n, n)
        Prior covariance P(0|-1), shared or one per series.
    u : array_like, shape (T, k) or (B, T, k), optional
        Inputs passed to f and h as u[t], shared or one set per series.
    return_covs : bool
        Whether to return P(t|t).
    threads : int, optional
        Number of threads (default: all cores); never more than the series or the cores. A
        model whose f or h is a Python callable runs its series one after another: the
        callable holds the GIL (built-in models and compiled functions run in parallel).
    form, iterations, iteration, order
        As for :meth:`NonlinearModel.ekf`.

    Returns
    -------
    BatchResult
        x_filt (B, T, n), P_filt (B, T, n, n) or None, loglik (B,) (each series' EKF
        log-likelihood); ``shared_covariance`` is False (a nonlinear filter's covariances
        depend on the data).

    Raises
    ------
    KfastError
        As for :meth:`NonlinearModel.ekf`; the message names the series (the lowest-numbered
        one that failed) and the step.

    Examples
    --------
    >>> ct = kfast.models.coordinated_turn(dt=0.1, q=1.0, sigma_omega=0.05)
    >>> model = kfast.NonlinearModel(ct, kfast.models.range_bearing(sensor=(0.0, 0.0)), ct.Q,
    ...                              np.diag([1.0, 1e-4]), n=5)
    >>> Y = np.array([[[111.8, 0.464], [112.2, 0.451]], [[80.1, -0.2], [80.6, -0.21]]])  # (B, T, m)
    >>> res = kfast.ekf_batch(model, Y, [100, 50, 5, -2, 0.1], np.diag([100, 100, 4, 4, 0.01]))
    >>> res.x_filt.shape, res.P_filt.shape, res.loglik.shape
    ((2, 2, 5), (2, 2, 5, 5), (2,))
    >>> one = model.ekf(Y[1], [100, 50, 5, -2, 0.1], np.diag([100, 100, 4, 4, 0.01]))
    >>> bool((res.x_filt[1] == one.x_filt).all() and res.loglik[1] == one.loglik)
    True
    """
    iteration = cast(Iteration, choice("iteration", iteration, ("book", "gauss-newton")))
    form = cast(Form, choice("form", form, ("joseph", "standard")))
    return _run(
        model, Y, x0, P0, u, return_covs, threads, "ekf", None,
        form, index("iterations", iterations), iteration, index("order", order),
    )


def ukf_batch(
    model: NonlinearModel,
    Y: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike] = None,
    points: Optional[SigmaPoints] = None,
    return_covs: bool = True,
    threads: Optional[int] = None,
    form: UkfForm = "standard",
) -> BatchResult:
    """The unscented Kalman filter of many independent series through one model, in parallel.

    Each series is filtered exactly as ``model.ukf(Y[b], x0[b], P0[b], u[b], points, form=form)``
    would filter it alone; arguments, results and errors as for :func:`ekf_batch`.

    Parameters
    ----------
    points, form : optional
        As for :meth:`NonlinearModel.ukf` (``kfast.sigma.merwe()`` and "standard" by default).
    model, Y, x0, P0, u, return_covs, threads
        As for :func:`ekf_batch`.
    """
    form = cast(UkfForm, choice("form", form, ("standard", "sqrt")))
    return _run(model, Y, x0, P0, u, return_covs, threads, "ukf", points, form)


def _run(
    model: NonlinearModel,
    Y: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    u: Optional[ArrayLike],
    return_covs: bool,
    threads: Optional[int],
    method: str,
    points: Optional[SigmaPoints],
    form: Union[Form, UkfForm] = "joseph",
    iterations: int = 0,
    iteration: Iteration = "book",
    order: int = 1,
) -> BatchResult:
    if not isinstance(model, NonlinearModel):
        raise _kfast.KfastError(f"model: expected a kfast.NonlinearModel, got {type(model).__name__}")
    Y_arr, x, P, u_arr, threads = batch_arguments(model.n_states, model.n_obs, Y, x0, P0, u, threads)
    spec = model._points(points)._spec()
    out = model._core.batch(
        Y_arr, x, P, method, spec, u=u_arr, return_covs=flag("return_covs", return_covs), threads=threads,
        form=form, iterations=iterations, iteration=iteration, order=order,
    )
    return BatchResult(x_filt=out["x_filt"], P_filt=out.get("P_filt"), loglik=out["loglik"], shared_covariance=False)
