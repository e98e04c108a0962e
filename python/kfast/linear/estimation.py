"""Parameter estimation: maximum likelihood (``fit``) and expectation-maximization (``em``).

Both evaluate the likelihood with the Rust filter/smoother; the optimizer loop (scipy) and the
EM's closed-form M-step run in Python/NumPy, vectorized over time.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Optional, Sequence

import numpy as np
from numpy.typing import ArrayLike

from kfast._args import flag, tolerance
from kfast._progress import Progress
from kfast._arrays import as_float64, finite_vector
from kfast._kfast import KfastError
from kfast.linear.model import LinearGaussian
from kfast._typing import EMParameter

__all__ = ["fit", "FitResult", "em", "EMResult"]


@dataclass(frozen=True, repr=False)
class FitResult:
    """Maximum-likelihood estimates from ``kfast.fit``."""

    theta: np.ndarray
    """The estimates."""
    se: np.ndarray
    """Standard errors: sqrt(diag(cov)); NaN where the Hessian gives no information."""
    cov: np.ndarray
    """Asymptotic covariance of theta: the inverse of minus the numerical Hessian of the
    log-likelihood at theta."""
    loglik: float
    """Log-likelihood at theta."""
    model: LinearGaussian
    """build(theta)'s model ..."""
    x0: np.ndarray
    """... prior mean ..."""
    P0: np.ndarray
    """... and prior covariance."""
    optimizer: Any
    """The scipy.optimize.OptimizeResult."""

    @property
    def success(self) -> bool:
        return bool(self.optimizer.success)

    def __repr__(self) -> str:
        return f"FitResult(theta={np.array2string(self.theta, precision=4)}, loglik={self.loglik:.6g}, success={self.success})"


def _build(build: Callable, theta: np.ndarray, where: str):
    """build(theta) -> (model, x0, P0), with errors that say they came from `build`."""
    try:
        out = build(theta)
    except KfastError as exc:
        raise KfastError(f"build: {where} gave an invalid model: {exc}") from exc
    if not (isinstance(out, tuple) and len(out) == 3 and isinstance(out[0], LinearGaussian)):
        got = type(out).__name__ if not isinstance(out, tuple) else f"a tuple of {len(out)}"
        raise KfastError(f"build: must return (kfast.LinearGaussian, x0, P0), got {got} at {where}")
    return out


def fit(
    build: Callable[[np.ndarray], tuple],
    theta0: ArrayLike,
    y: ArrayLike,
    u: Optional[ArrayLike] = None,
    *,
    method: str = "L-BFGS-B",
    bounds: Optional[Sequence] = None,
    options: Optional[dict] = None,
    P0_inf: Optional[ArrayLike] = None,
    gradient: str = "numerical",
    progress: bool = False,
) -> FitResult:
    """Maximum-likelihood estimates of the parameters theta of a model.

    Parameters
    ----------
    build : callable
        ``build(theta) -> (model, x0, P0)``: the model and prior for the parameters theta (a
        1-D array). Parameters where it raises a kfast error (e.g. a negative variance) score
        -inf; prefer transformations (exp, tanh) that keep every theta valid.
    theta0 : array_like, shape (p,)
        The starting point.
    y : array_like, shape (T, m), or (T,) when m = 1
        Observations (NaN = missing).
    u : array_like, shape (T, k), optional
        Inputs.
    method : str
        The ``scipy.optimize.minimize`` method.
    bounds : sequence, optional
        Bounds on theta, for the methods that take them.
    options : dict, optional
        Options of the optimizer.
    P0_inf : array_like, shape (n, n), optional
        The diffuse part of the prior (exact diffuse initialization, see
        :meth:`LinearGaussian.filter`): then the diffuse log-likelihood is maximized and build's
        P0 is the finite part.
    gradient : {"numerical", "analytic"}
        How the optimizer gets the gradient: "numerical" (scipy's finite differences of the
        log-likelihood, the default) or "analytic", the exact score of :func:`kfast.loglik_score`
        (the filter's tangent recursion), which also gives the Hessian for the standard errors
        as central differences of the score. "analytic" needs an ordinary prior (no P0_inf).
    progress : bool
        Report each optimizer iteration and the best log-likelihood so far on stderr (a tqdm
        bar when tqdm is installed).

    Returns
    -------
    FitResult
        theta, its standard errors and covariance, the log-likelihood at theta, the model and
        prior built from it, and scipy's OptimizeResult.

    Raises
    ------
    KfastError
        When ``build`` is not callable or does not return (LinearGaussian, x0, P0) with a
        valid prior at theta0; when theta0 is not a non-empty finite 1-D array (a scalar is
        one parameter); when the log-likelihood at theta0 is not finite (naming ``y`` when its
        entries are too large for double precision, |y| > 1e154, else ``build``); or when the
        optimizer leaves the finite numbers (rescale y or give ``bounds``).

    Notes
    -----
    Maximizes ``model.loglik(y, x0, P0, u)``, the exact Gaussian log-likelihood of the prior
    x(0|-1) ~ N(x0, P0) (Söderström (6.142)), with ``scipy.optimize.minimize``. The covariance
    of theta is the inverse of minus the Hessian of the log-likelihood (central differences)
    at the optimum; a RuntimeWarning says when it is not positive definite.

    Examples
    --------
    White noise y = v with variance R = e^theta: the estimate is the mean of y^2, with standard
    error sqrt(2 / T) on the log scale.

    >>> def build(theta):
    ...     return kfast.LinearGaussian(F=0.0, H=1.0, Q=0.0, R=np.exp(theta[0])), 0.0, 0.0
    >>> res = kfast.fit(build, [0.0], [1.0, -2.0, 3.0, 0.5])
    >>> print(round(float(np.exp(res.theta[0])), 2), round(float(res.se[0]), 2))
    3.56 0.71
    """
    from scipy.optimize import minimize

    from kfast._args import choice

    gradient = choice("gradient", gradient, ("numerical", "analytic"))
    if gradient == "analytic" and P0_inf is not None:
        raise KfastError('gradient: the analytic score is for an ordinary prior; with P0_inf use gradient="numerical"')
    if not callable(build):
        raise KfastError(f"build: expected a callable build(theta) -> (model, x0, P0), got {type(build).__name__}")
    theta0 = _fit_theta0(theta0)
    y = as_float64("y", y)
    u = None if u is None else as_float64("u", u)
    model0, x00, P00 = _build(build, theta0, "theta0")
    ll0 = _fit_loglik0(model0, x00, P00, y, u, P0_inf)

    def loglik(theta):
        try:
            model, x0, P0 = _build(build, theta, "theta")
            return model.loglik(y, x0, P0, u=u, P0_inf=P0_inf)
        except KfastError:
            return -np.inf

    best = [ll0]

    def objective(theta):
        ll = loglik(theta)
        best[0] = max(best[0], ll) if np.isfinite(ll) else best[0]
        return -ll if np.isfinite(ll) else np.inf

    with Progress(flag("progress", progress), None, "fit") as bar:
        # One report per optimizer iteration, with the best log-likelihood seen so far.
        def report(*_: Any) -> None:
            bar.update(1, loglik=best[0])

        if gradient == "analytic":
            score = _negative_score(build, y, u)

            def traced(theta):
                value, grad = score(theta)
                best[0] = max(best[0], -value) if np.isfinite(value) else best[0]
                return value, grad

            opt = minimize(traced, theta0, jac=True, method=method, bounds=bounds, options=options, callback=report)
        else:
            opt = minimize(objective, theta0, method=method, bounds=bounds, options=options, callback=report)
    theta = np.asarray(opt.x, dtype=float)
    if not np.all(np.isfinite(theta)):
        raise KfastError(
            f"build: the optimizer left the finite numbers (theta = {theta}) from theta0 = {theta0}, where the "
            f"log-likelihood is {ll0:.6g}: rescale y, reparametrize build or give bounds"
        )
    hess = _hessian_of_score(build, y, u, theta) if gradient == "analytic" else _hessian(loglik, theta)
    cov, se = _covariance(hess)
    model, x0, P0 = _build(build, theta, "the optimum")
    return FitResult(theta=theta, se=se, cov=cov, loglik=float(-opt.fun), model=model, x0=x0, P0=P0, optimizer=opt)


def _fit_theta0(theta0: ArrayLike) -> np.ndarray:
    """fit's starting point: a non-empty finite 1-D array (a scalar is one parameter)."""
    return finite_vector("theta0", theta0, "of parameters")


# Above this, y^2 is not a double: the log-likelihood of any model of moderate scale overflows.
_Y_SQUARE_LIMIT = 1e154


def _fit_loglik0(model: LinearGaussian, x0, P0, y: np.ndarray, u: Optional[np.ndarray], P0_inf=None) -> float:
    """The log-likelihood at theta0, with errors that say whether y or build is at fault."""
    try:
        ll0 = model.loglik(y, x0, P0, u=u, P0_inf=P0_inf)
    except KfastError as exc:
        if str(exc).startswith(("x0:", "P0:")):  # the prior comes from build
            raise KfastError(f"build: theta0 gave an invalid prior: {exc}") from exc
        raise
    if not np.isfinite(ll0):
        finite = np.abs(y[np.isfinite(y)])
        largest = float(finite.max()) if finite.size else 0.0
        if largest > _Y_SQUARE_LIMIT:
            raise KfastError(
                f"y: entries as large as {largest:.3g} make the log-likelihood at theta0 overflow ({ll0}): rescale y"
            )
        raise KfastError(f"build: the log-likelihood at theta0 is not finite ({ll0})")
    return float(ll0)


def _negative_score(build: Callable, y: np.ndarray, u: Optional[np.ndarray]) -> Callable:
    """theta -> (-loglik, -score) for scipy (jac=True); +inf where build or the filter fail."""
    from kfast.linear.score import loglik_score

    def objective(theta):
        try:
            ll, score = loglik_score(build, theta, y, u)
        except KfastError:
            return np.inf, np.zeros(len(theta))
        if not (np.isfinite(ll) and np.all(np.isfinite(score))):
            return np.inf, np.zeros(len(theta))
        return -ll, -score

    return objective


def _hessian_of_score(build: Callable, y: np.ndarray, u: Optional[np.ndarray], theta: np.ndarray) -> np.ndarray:
    """Central differences of the analytic score, step 1e-4 max(1, |theta_i|), symmetrized."""
    from kfast.linear.score import loglik_score

    k = len(theta)
    H = np.zeros((k, k))
    for i in range(k):
        h = 1e-4 * max(1.0, abs(theta[i]))
        step = np.zeros(k)
        step[i] = h
        try:
            plus, minus = loglik_score(build, theta + step, y, u)[1], loglik_score(build, theta - step, y, u)[1]
        except KfastError:
            H[:, i] = np.nan
            continue
        H[:, i] = (plus - minus) / (2 * h)
    return (H + H.T) / 2


def _hessian(f: Callable, theta: np.ndarray) -> np.ndarray:
    """Central-difference Hessian of f at theta, step 1e-4 max(1, |theta_i|)."""
    k = len(theta)
    h = 1e-4 * np.maximum(1.0, np.abs(theta))
    H = np.zeros((k, k))
    f0 = f(theta)
    for i in range(k):
        ei = np.zeros(k)
        ei[i] = h[i]
        H[i, i] = (f(theta + ei) - 2 * f0 + f(theta - ei)) / h[i] ** 2
        for j in range(i):
            ej = np.zeros(k)
            ej[j] = h[j]
            H[i, j] = H[j, i] = (
                f(theta + ei + ej) - f(theta + ei - ej) - f(theta - ei + ej) + f(theta - ei - ej)
            ) / (4 * h[i] * h[j])
    return H


def _covariance(hess: np.ndarray):
    info = -hess
    if not np.isfinite(info).all():
        warnings.warn("fit: the Hessian is not finite at the optimum (on a boundary?); no standard errors", RuntimeWarning, stacklevel=3)
        nan = np.full(info.shape, np.nan)
        return nan, np.full(len(info), np.nan)
    eig = np.linalg.eigvalsh((info + info.T) / 2)
    if eig[0] <= 0:
        warnings.warn(
            "fit: minus the Hessian is not positive definite at the optimum; standard errors of "
            "unidentified directions are NaN",
            RuntimeWarning,
            stacklevel=3,
        )
    cov = np.linalg.pinv(info)
    diag = np.diag(cov)
    se = np.where(diag > 0, np.sqrt(np.abs(diag)), np.nan)
    return cov, se


@dataclass(frozen=True, repr=False)
class EMResult:
    """The model estimated by ``LinearGaussian.em``."""

    model: LinearGaussian
    x0: np.ndarray
    P0: np.ndarray
    loglik: np.ndarray
    """Log-likelihood before each iteration and, last, at the result: non-decreasing."""
    n_iter: int
    """Iterations made."""
    converged: bool
    """Whether the change of the log-likelihood fell below ``tol``."""
    fitted: tuple = ()
    """The names of the estimated parameters (``fit=``)."""
    # (y, u) of the run, for standard_errors(); not a field (the results' fields are its outputs).
    _data: ClassVar[tuple] = (None, None)

    def __repr__(self) -> str:
        return f"EMResult(n_iter={self.n_iter}, loglik={self.loglik[-1]:.6g}, converged={self.converged})"

    def standard_errors(self) -> dict:
        """Standard errors of the estimates from the observed information at the result.

        EM gives no standard errors of its own. These are the square roots of the diagonal of
        the inverse of minus the Hessian of the exact log-likelihood (central differences, as
        in :func:`fit`) with respect to the free entries of the estimated parameters: every
        entry of F, H and x0, the lower triangle of the symmetric Q, R and P0. At a maximum of
        the likelihood this is the asymptotic standard error of maximum likelihood (EM
        converges to the same point). A RuntimeWarning says when the information is not
        positive definite (e.g. a variance at zero); the standard errors of unidentified
        directions are then NaN.

        Returns
        -------
        dict
            {name: array of the parameter's shape}, for each name in ``fitted`` (symmetric
            matrices have symmetric arrays).

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.5, R=1.0)
        >>> x, y = model.simulate(400, x0=0.0, P0=1.0, seed=2)
        >>> res = model.em(y, x0=0.0, P0=1.0, n_iter=200, fit=("F", "Q", "R"), tol=1e-10)
        >>> se = res.standard_errors()
        >>> sorted(se), bool(0.0 < se["F"][0, 0] < 0.1)
        (['F', 'Q', 'R'], True)
        """
        y, u = self._data
        if y is None:
            raise KfastError("standard_errors: this EMResult does not carry its data")
        values = {"F": self.model.F, "H": self.model.H, "Q": self.model.Q, "R": self.model.R, "x0": self.x0, "P0": self.P0}
        layout = [(name, np.asarray(values[name], dtype=float)) for name in self.fitted]
        theta = np.concatenate([_free(name, a) for name, a in layout]) if layout else np.zeros(0)
        if theta.size == 0:
            return {}

        def loglik(t: np.ndarray) -> float:
            current = dict(values)
            k = 0
            for name, a in layout:
                size = _free(name, a).size
                current[name] = _unfree(name, a, t[k : k + size])
                k += size
            try:
                m = LinearGaussian(current["F"], current["H"], current["Q"], current["R"], B=self.model.B, D=self.model.D)
                return m.loglik(y, current["x0"], current["P0"], u=u)
            except KfastError:
                return -np.inf

        _, se = _covariance(_hessian(loglik, theta))
        out = {}
        k = 0
        for name, a in layout:
            size = _free(name, a).size
            out[name] = _unfree(name, a, se[k : k + size])
            k += size
        return out


_SYMMETRIC = ("Q", "R", "P0")


def _free(name: str, a: np.ndarray) -> np.ndarray:
    """The free entries of a parameter: its lower triangle if symmetric, else all."""
    return a[np.tril_indices(a.shape[0])] if name in _SYMMETRIC else a.ravel()


def _unfree(name: str, like: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The parameter of ``like``'s shape with the free entries ``values`` (mirrored if symmetric)."""
    if name not in _SYMMETRIC:
        return values.reshape(like.shape)
    out = np.zeros(like.shape)
    out[np.tril_indices(like.shape[0])] = values
    return out + np.tril(out, -1).T


EM_PARAMETERS: tuple[EMParameter, ...] = ("F", "H", "Q", "R", "x0", "P0")


def _em_parameters(fit) -> tuple:
    """``fit=`` as a tuple of parameter names (one name may be given alone)."""
    names = (fit,) if isinstance(fit, str) else fit
    try:
        names = tuple(names)
    except TypeError:
        raise KfastError(f"fit: expected a sequence of parameter names from {EM_PARAMETERS}, got {fit!r}") from None
    unknown = [name for name in names if name not in EM_PARAMETERS]
    if unknown:
        raise KfastError(f"fit: unknown parameters {unknown}; choose from {EM_PARAMETERS}")
    return names


def em(
    model: LinearGaussian,
    y: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    n_iter: int = 10,
    fit: Sequence[EMParameter] = EM_PARAMETERS,
    u: Optional[ArrayLike] = None,
    tol: Optional[float] = None,
    progress: bool = False,
) -> EMResult:
    """Expectation-maximization for a constant model: see :meth:`LinearGaussian.em`.

    Examples
    --------
    >>> model = kfast.LinearGaussian(F=0.5, H=1.0, Q=1.0, R=1.0)
    >>> res = kfast.linear.estimation.em(model, [0.3, -0.1, 0.7, 1.2], x0=0.0, P0=1.0, n_iter=3)
    >>> res.n_iter, len(res.loglik)
    (3, 4)
    """
    fit = _em_parameters(fit)
    if model.steps is not None:
        raise KfastError("model: EM needs constant matrices (this model has per-step ones)")
    if model.N is not None:
        raise KfastError("model: EM does not support correlated noise N")
    if isinstance(n_iter, bool) or not isinstance(n_iter, (int, np.integer)) or n_iter < 0:
        raise KfastError(f"n_iter: expected an integer >= 0, got {n_iter!r}")
    tol = tolerance("tol", tol)
    progress = flag("progress", progress)
    y, x0, P0, u = model._data(y, x0, P0, u)
    F, H, Q, R = (np.array(a) for a in (model.F, model.H, model.Q, model.R))
    B, D = model.B, model.D

    def e_step(F, H, Q, R, x0, P0):
        return LinearGaussian(F, H, Q, R, B=B, D=D).smooth(y, x0, P0, u=u, outputs=("x_smooth", "P_smooth", "P_lag1"))

    sm = e_step(F, H, Q, R, x0, P0)  # first, so that the core validates y, x0, P0 and u
    _check_em_scale("y", y)
    _check_em_scale("x0", np.asarray(x0))
    x0 = np.array(x0, dtype=float).reshape(model.n_states)  # copies: EM updates them
    P0 = np.array(P0, dtype=float).reshape(model.n_states, model.n_states)
    T = len(y)
    a = np.zeros((T, model.n_states)) if B is None else u @ B.T  # transition offsets B u(t)
    d = np.zeros((T, model.n_obs)) if D is None else u @ D.T  # observation offsets D u(t)

    history = [sm.filter.loglik]  # log-likelihood of the parameters entering each iteration
    converged = False
    iterations = 0
    with Progress(progress, n_iter, "EM") as bar:
        while iterations < n_iter:
            F, H, Q, R, x0, P0 = _m_step(sm, y, a, d, F, H, Q, R, x0, P0, fit)
            iterations += 1
            sm = e_step(F, H, Q, R, x0, P0)
            history.append(sm.filter.loglik)
            bar.update(1, loglik=history[-1])
            if tol is not None and abs(history[-1] - history[-2]) <= tol * max(1.0, abs(history[-1])):
                converged = True
                break
    final = LinearGaussian(F, H, Q, R, B=B, D=D)
    result = EMResult(
        model=final,
        x0=np.asarray(x0),
        P0=np.asarray(P0),
        loglik=np.array(history),
        n_iter=iterations,
        converged=converged,
        fitted=tuple(fit),
    )
    object.__setattr__(result, "_data", (y, u))
    return result


def _m_step(sm, y, a, d, F, H, Q, R, x0, P0, fit):
    """One M-step: closed-form maximizers of the expected complete-data log-likelihood, in
    pykalman's order (H, R, F, Q, x0, P0), each using the ones updated before it."""
    xs, Ps, Pl = sm.x_smooth, sm.P_smooth, sm.P_lag1
    Exx = Ps + xs[:, :, None] * xs[:, None, :]  # E[x x' | Y]
    M, c, Rc, used = _observation_moments(y, d, H, R)
    Eyx = M @ Exx + c[:, :, None] * xs[:, None, :]  # E[y x' | Y]
    if "H" in fit:
        lhs = (Eyx - d[:, :, None] * xs[:, None, :])[used].sum(axis=0)
        H = lhs @ np.linalg.pinv(Exx[used].sum(axis=0))
    if "R" in fit:
        A = M - H  # y - H x - d = A x + e (+ noise of the missing part)
        e = c - d
        Ax = np.einsum("tij,tj->ti", A, xs)
        terms = A @ Exx @ np.swapaxes(A, 1, 2) + Ax[:, :, None] * e[:, None, :] + e[:, :, None] * Ax[:, None, :]
        terms += e[:, :, None] * e[:, None, :] + Rc
        R = _covariance_estimate(terms[used].mean(axis=0))
    if "F" in fit:
        lhs = (Pl[1:] + xs[1:, :, None] * xs[:-1, None, :] - a[:-1, :, None] * xs[:-1, None, :]).sum(axis=0)
        F = lhs @ np.linalg.pinv(Exx[:-1].sum(axis=0))
    if "Q" in fit and len(xs) > 1:
        err = xs[1:] - xs[:-1] @ F.T - a[:-1]
        PlF = Pl[1:] @ F.T
        terms = err[:, :, None] * err[:, None, :] + F @ Ps[:-1] @ F.T + Ps[1:] - PlF - np.swapaxes(PlF, 1, 2)
        Q = _covariance_estimate(terms.mean(axis=0))
    if "x0" in fit:
        x0 = xs[0].copy()
    if "P0" in fit:
        dx = xs[0] - x0
        P0 = _covariance_estimate(Ps[0] + np.outer(dx, dx))
    return F, H, Q, R, x0, P0


def _observation_moments(y, d, H, R):
    """y[t] given Y and x[t] under the current (H, R) is M x + c + noise of covariance Rc:
    observed components are known (M = 0, c = y), missing ones are regressed on the observed
    residual, y_q = H_q x + d_q + G (y_o - H_o x - d_o) + eta with G = R_qo R_oo^-1 (Shumway &
    Stoffer's missing-data EM). Rows with nothing observed are left out (``used`` is False)."""
    T, m = y.shape
    n = H.shape[1]
    M = np.zeros((T, m, n))
    c = np.where(np.isnan(y), 0.0, y)
    Rc = np.zeros((T, m, m))
    observed = ~np.isnan(y)
    used = observed.any(axis=1)
    partial = used & ~observed.all(axis=1)
    if partial.any():
        patterns, which = np.unique(observed[partial], axis=0, return_inverse=True)
        rows = np.flatnonzero(partial)
        for p, o in enumerate(patterns):
            t = rows[which.ravel() == p]
            q = ~o
            G = R[np.ix_(q, o)] @ np.linalg.inv(R[np.ix_(o, o)])
            M[np.ix_(t, np.flatnonzero(q), np.arange(n))] = H[q] - G @ H[o]
            resid = y[np.ix_(t, np.flatnonzero(o))] - d[np.ix_(t, np.flatnonzero(o))]
            c[np.ix_(t, np.flatnonzero(q))] = d[np.ix_(t, np.flatnonzero(q))] + resid @ G.T
            Rc[np.ix_(t, np.flatnonzero(q), np.flatnonzero(q))] = R[np.ix_(q, q)] - G @ R[np.ix_(o, q)]
    return M, c, Rc, used


def _covariance_estimate(A: np.ndarray) -> np.ndarray:
    """The symmetric part of a covariance estimate, with eigenvalues that rounding pushed below
    zero set to zero (over thousands of iterations an R or Q shrinking towards a singular limit
    otherwise turns indefinite by about 1e-15 and stops EM with a confusing error)."""
    S = (A + A.T) / 2
    lam, V = np.linalg.eigh(S)
    if lam.min() >= 0:
        return S
    C = (V * np.clip(lam, 0.0, None)) @ V.T
    return (C + C.T) / 2


# EM sums squares of the data and of the states: entries beyond this would overflow.
_EM_MAX_ENTRY = 1e150


def _check_em_scale(name: str, a: np.ndarray) -> None:
    finite = np.abs(a[np.isfinite(a)])
    if finite.size and finite.max() > _EM_MAX_ENTRY:
        raise KfastError(
            f"{name}: has entries up to {finite.max():.3g}, too large for EM's second moments "
            f"(which square them); rescale so that |{name}| < {_EM_MAX_ENTRY:g}"
        )
