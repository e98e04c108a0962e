"""The linear Gaussian state-space model and its filter results (conventions: docs/conventions.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Iterator, NamedTuple, Optional, Sequence, Union, cast

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._arrays import as_float64, frozen_copy
from kfast._typing import DareMethod, EMParameter, FilterOutputs, Form, SmoothOutputs

if TYPE_CHECKING:
    from kfast.estimation import EMResult
    from kfast.stationary import InnovationsForm, SteadyState

__all__ = [
    "LinearGaussian",
    "FilterResult",
    "SmootherResult",
    "FixedLagResult",
    "FixedPointResult",
    "Forecast",
    "Simulation",
]

_FORMS = ("joseph", "standard")
_MATRICES = ("F", "H", "Q", "R", "B", "D", "N")


@dataclass(frozen=True, repr=False)
class FilterResult:
    """What the Kalman filter computed over T steps (n states, m outputs).

    Conventions: the prior (x0, P0) is x(0|-1), P(0|-1); row t of ``x_pred`` is x(t|t-1)
    and of ``x_filt`` is x(t|t). Söderström Lemma 6.1, (6.22)-(6.27). Fields left out with
    ``filter(..., outputs=...)`` are None.
    """

    x_pred: Optional[np.ndarray] = None
    """x(t|t-1), shape (T, n)."""
    P_pred: Optional[np.ndarray] = None
    """P(t|t-1), shape (T, n, n)."""
    x_filt: Optional[np.ndarray] = None
    """x(t|t), shape (T, n)."""
    P_filt: Optional[np.ndarray] = None
    """P(t|t), shape (T, n, n)."""
    innov: Optional[np.ndarray] = None
    """Innovations e(t) = y(t) - H x(t|t-1) - D u(t), shape (T, m); NaN where y is missing."""
    S: Optional[np.ndarray] = None
    """Innovation (one-step forecast error) covariance H P(t|t-1) H' + R of all m components,
    shape (T, m, m), also where y is missing."""
    K: Optional[np.ndarray] = None
    """Filter gain P(t|t-1) H' S^-1, shape (T, n, m): x(t|t) = x(t|t-1) + K e(t).
    Columns of missing components are zero."""
    K_pred: Optional[np.ndarray] = None
    """Predictor gain (F P(t|t-1) H' + N) S^-1, shape (T, n, m):
    x(t+1|t) = F x(t|t-1) + B u(t) + K_pred e(t). (statsmodels' ``kalman_gain``.)"""
    loglik: float = float("nan")
    """Total log-likelihood sum_t log p(y(t) | y(0..t-1)) (Söderström (6.142))."""
    loglik_t: Optional[np.ndarray] = None
    """Per-step log-likelihood terms, shape (T,); 0 where nothing is observed."""
    x_next: Optional[np.ndarray] = None
    """x(T|T-1): the prediction one step past the data, shape (n,)."""
    P_next: Optional[np.ndarray] = None
    """P(T|T-1), shape (n, n)."""
    model: Optional["LinearGaussian"] = field(default=None, repr=False, compare=False)
    """The model that was filtered."""

    def __repr__(self) -> str:
        stored = [k for k in _FILTER_FIELDS if getattr(self, k) is not None]
        return f"FilterResult(loglik={self.loglik:.6g}, fields={stored})"

    def forecast(self, steps: int, u: Optional[ArrayLike] = None) -> "Forecast":
        """Forecast the `steps` steps after the data, T..T+steps-1, from x(T|T-1), P(T|T-1)
        (u, shape (steps, k), holds the future inputs u(T), ...)."""
        if self.model is None or self.x_next is None or self.P_next is None:
            raise _kfast.KfastError("forecast: this FilterResult has no model or no x_next, P_next")
        return self.model.forecast(self.x_next, self.P_next, steps, u=u)


_FILTER_FIELDS = tuple(k for k in FilterResult.__dataclass_fields__ if k not in ("model", "loglik"))


@dataclass(frozen=True, repr=False)
class Forecast:
    """k-step forecasts (Söderström (6.38)-(6.42)). Row j forecasts step t+j from data up to
    t-1. Unpacks as ``mean, cov = model.forecast(...)`` (the state's)."""

    x: np.ndarray
    """State means x(t+j|t-1), shape (steps, n)."""
    P: np.ndarray
    """State covariances P(t+j|t-1), shape (steps, n, n)."""
    y: np.ndarray
    """Output means H x + D u, shape (steps, m)."""
    y_cov: np.ndarray
    """Output covariances H P H' + R, shape (steps, m, m)."""

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter((self.x, self.P))

    def __repr__(self) -> str:
        return f"Forecast(steps={len(self.x)})"


class Simulation(NamedTuple):
    """A sample path: ``x, y = model.simulate(...)``."""

    x: np.ndarray
    """States x[0..T-1], shape (T, n)."""
    y: np.ndarray
    """Outputs y[0..T-1], shape (T, m)."""


@dataclass(frozen=True, repr=False)
class SmootherResult:
    """Fixed-interval (RTS) smoother results: every state given all T measurements. Fields
    left out with ``smooth(..., outputs=...)`` are None (in ``filter`` too)."""

    filter: FilterResult
    """The forward pass."""
    x_smooth: Optional[np.ndarray] = None
    """x(t|T-1), shape (T, n)."""
    P_smooth: Optional[np.ndarray] = None
    """P(t|T-1), shape (T, n, n)."""
    P_lag1: Optional[np.ndarray] = None
    """Cov(x[t], x[t-1] | y(0..T-1)), shape (T, n, n); row 0 is zero (there is no x[-1])."""

    def __repr__(self) -> str:
        stored = [k for k in ("x_smooth", "P_smooth", "P_lag1") if getattr(self, k) is not None]
        return f"SmootherResult(loglik={self.filter.loglik:.6g}, fields={stored})"


@dataclass(frozen=True, repr=False)
class FixedLagResult:
    """Fixed-lag smoother results: x[s] given y(0..s+lag) (fewer near the end of the data)."""

    x_smooth: np.ndarray
    """Row s is x(s | min(s+lag, T-1)), shape (T, n)."""
    P_smooth: np.ndarray
    """Row s is P(s | min(s+lag, T-1)), shape (T, n, n)."""
    lag: int

    def __repr__(self) -> str:
        T, n = self.x_smooth.shape
        return f"FixedLagResult(T={T}, n={n}, lag={self.lag})"


@dataclass(frozen=True, repr=False)
class FixedPointResult:
    """Fixed-point smoother results: one state x[t_point] given more and more data."""

    x: np.ndarray
    """Row j is x(t_point | t_point + j), shape (T - t_point, n)."""
    P: np.ndarray
    """Row j is P(t_point | t_point + j), shape (T - t_point, n, n)."""
    t_point: int

    def __repr__(self) -> str:
        return f"FixedPointResult(t_point={self.t_point}, rows={len(self.x)})"


class LinearGaussian:
    """Linear Gaussian state-space model, validated once::

        x[t+1] = F x[t] + B u[t] + w[t]      w ~ N(0, Q)   (Q: discrete-time covariance)
        y[t]   = H x[t] + D u[t] + v[t]      v ~ N(0, R),  E[w[t] v[t]'] = N

    Each matrix is constant, e.g. F of shape (n, n), or given per step with a leading axis T,
    e.g. (T, n, n). Per-step matrices are indexed by the step they leave: F[t], B[t], Q[t],
    N[t] take x[t] to x[t+1]; H[t], D[t], R[t] produce y[t]. A scalar is a 1 x 1 matrix.

    Validation: all entries finite; Q and R symmetric positive semidefinite; the joint
    covariance [[Q, N], [N', R]] positive semidefinite; shapes consistent. A failure raises
    ``kfast.KfastError`` (a ValueError) naming the argument, the step and the problem.
    The arguments are copied; the model's matrices are read-only attributes.
    """

    def __init__(
        self,
        F: ArrayLike,
        H: ArrayLike,
        Q: ArrayLike,
        R: ArrayLike,
        B: Optional[ArrayLike] = None,
        D: Optional[ArrayLike] = None,
        N: Optional[ArrayLike] = None,
    ) -> None:
        given = {"F": F, "H": H, "Q": Q, "R": R, "B": B, "D": D, "N": N}
        for name in ("F", "H", "Q", "R"):
            if given[name] is None:
                raise _kfast.KfastError(f"{name}: required (got None)")
        arrays: dict = {k: (None if v is None else frozen_copy(k, v, scalar_shape=(1, 1))) for k, v in given.items()}
        self._core = _kfast.LinearGaussian(**arrays)
        self.F: np.ndarray = arrays["F"]
        self.H: np.ndarray = arrays["H"]
        self.Q: np.ndarray = arrays["Q"]
        self.R: np.ndarray = arrays["R"]
        self.B: Optional[np.ndarray] = arrays["B"]
        self.D: Optional[np.ndarray] = arrays["D"]
        self.N: Optional[np.ndarray] = arrays["N"]

    def __getstate__(self) -> dict:
        """Pickling and copying keep the matrices (and any attributes a subclass adds); the
        compiled core is rebuilt from them, validating them again."""
        state = self.__dict__.copy()
        del state["_core"]
        return state

    def __setstate__(self, state: dict) -> None:
        arrays: dict = {k: (None if state[k] is None else frozen_copy(k, state[k], scalar_shape=(1, 1))) for k in _MATRICES}
        self.__dict__.update(state)
        self.__dict__.update(arrays)
        self._core = _kfast.LinearGaussian(**arrays)

    @classmethod
    def from_continuous(
        cls,
        A: ArrayLike,
        Qc: ArrayLike,
        H: ArrayLike,
        R: ArrayLike,
        dt: Optional[ArrayLike] = None,
        B: Optional[ArrayLike] = None,
        D: Optional[ArrayLike] = None,
        times: Optional[ArrayLike] = None,
    ) -> "LinearGaussian":
        """The exact discrete model of dx = A x dt + B u dt + dbeta (E[dbeta dbeta'] = Qc dt, a
        continuous intensity), sampled as y[t] = H x[t] + D u[t] + v[t], cov v = R (a
        discrete covariance: white noise of intensity Rc averaged over h has R = Rc / h).

        ``dt`` a scalar gives a constant model; an array of T intervals (dt[t] from step t to
        t+1; the last one only moves x(T|T-1) past the data) or T sample ``times``
        (irregular; the last step reuses the last interval) give per-step F[t] = e^{A dt[t]},
        Qd[t], Bd[t] (Van Loan, computed in Rust).
        """
        from kfast.sampling import discretize, intervals

        if times is None and dt is not None and np.ndim(dt) == 0:
            F, Qd, Bd = discretize(A, Qc, dt, B=B)
        else:
            F, Qd, Bd = discretize(A, Qc, intervals(dt=dt, times=times), B=B)
        return cls(F, H, Qd, R, B=Bd, D=D)

    @property
    def n_states(self) -> int:
        """State dimension n."""
        return self._core.n_states

    @property
    def n_obs(self) -> int:
        """Output dimension m."""
        return self._core.n_obs

    @property
    def n_inputs(self) -> int:
        """Input dimension k (0 without B and D)."""
        return self._core.n_inputs

    @property
    def steps(self) -> Optional[int]:
        """T when some matrix is given per step (data must then have T steps), else None."""
        return self._core.steps

    def __repr__(self) -> str:
        tv = "" if self.steps is None else f", steps={self.steps}"
        return f"LinearGaussian(n_states={self.n_states}, n_obs={self.n_obs}, n_inputs={self.n_inputs}{tv})"

    def filter(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: Optional[ArrayLike] = None,
        u: Optional[ArrayLike] = None,
        form: Form = "joseph",
        steady_state: bool = False,
        converge_tol: Optional[float] = None,
        outputs: FilterOutputs = None,
    ) -> FilterResult:
        """Kalman filter over y, shape (T, m) (or (T,) when m = 1); NaN marks a missing value.

        (x0, P0) is the prior x(0|-1), P(0|-1): the first operation is the update with y[0].
        A whole missing row skips the update; a partly missing row updates with the observed
        components only (their rows of H, D, R and columns of N). u, shape (T, k), is required
        when the model has B or D; u[t] enters x[t+1] via B and y[t] via D.

        form: "joseph" (default; (I-KH)P(I-KH)' + KRK', stays PSD) or "standard"
        (P - K S K', symmetrized). Söderström Lemma 6.1 / (6.24).

        steady_state=True: the constant-gain filter with the stationary gains of
        ``steady_state()`` from the first step, O(n^2) per step (P0 is not used; constant
        models only). A missing value runs the exact recursion through the gap (the
        covariance grows while nothing is observed) and after it, until P(t+1|t) has
        converged back to the stationary one (change below 1e-10 relative); then the gains
        are constant again. So with gaps the estimates and the log-likelihood are those of the
        exact filter started from the stationary covariance, to about that tolerance.
        converge_tol: switch to constant gains once max|P(t+1|t) - P(t|t-1)| <= converge_tol
        * max(1, max|P|) at a fully observed step, like statsmodels' steady-state shortcut;
        results then differ from the exact filter by about that tolerance. Off by default.
        outputs: the names of the fields to store (e.g. ("x_filt", "P_filt")); the others
        are None, which saves their memory and time. All by default.
        """
        if steady_state:
            if converge_tol is not None:
                raise _kfast.KfastError("converge_tol: not used with steady_state=True (the gains are constant from the start)")
            P0 = self.steady_state().P_pred
            converge_tol = _STEADY_STATE_TOL
        elif P0 is None:
            raise _kfast.KfastError("P0: required unless steady_state=True")
        args = self._data(y, x0, P0, u)
        names = _output_names(outputs)
        out = self._core.filter(*args, form=_form(form), converge_tol=_tolerance(converge_tol), outputs=names)
        return FilterResult(**out, model=self)

    def loglik(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        form: Form = "joseph",
        converge_tol: Optional[float] = None,
    ) -> float:
        """The log-likelihood sum_t log N(y(t); H x(t|t-1) + D u(t), S(t)) alone (Söderström
        (6.142)), computed without storing any per-step covariance. Same arguments as filter."""
        return self._core.loglik(*self._data(y, x0, P0, u), form=_form(form), converge_tol=_tolerance(converge_tol))

    def steady_state(self, method: DareMethod = "doubling") -> "SteadyState":
        """The stationary filter: P_pred (the stabilizing DARE solution, with SciPy's
        solve_discrete_are(F', H', Q, R, s=N)), P_filt, K, K_pred, S, the closed-loop
        eigenvalues of F - K_pred H and the residual (Söderström (6.91)). Raises
        ``kfast.NoStabilizingSolutionError`` when (F, H) is not detectable or the noise does not
        excite the unstable modes. Constant models only."""
        from kfast.stationary import steady_state

        return steady_state(self, method=method)

    def innovations_form(self) -> "InnovationsForm":
        """(F, K_pred, H, S) of the steady-state innovations model (Söderström Thm 4.2)."""
        from kfast.stationary import innovations_form

        return innovations_form(self)

    def stationary_cov(self) -> np.ndarray:
        """The stationary state covariance Pi = F Pi F' + Q (Söderström (4.22)); raises
        ``kfast.KfastError`` unless F is stable (a random walk has none)."""
        from kfast.stationary import stationary_cov

        return stationary_cov(self)

    def autocovariance(self, lags: ArrayLike) -> np.ndarray:
        """r_y(tau) = E[y(t+tau) y(t)'] of the stationary output for each lag, shape
        (len(lags), m, m); r_y(-tau) = r_y(tau)'. Inputs are ignored (zero mean)."""
        from kfast.stationary import autocovariance

        return autocovariance(self, lags)

    def spectral_density(self, omega: ArrayLike, h: float = 1.0) -> np.ndarray:
        """Output spectral density phi_y(e^{i omega h}), shape (len(omega), m, m), complex
        Hermitian, with Söderström's normalization (no 1/2pi): r_y(k) = (1/2pi) times the
        integral of phi_y e^{i omega k h} over |omega| <= pi/h. h is the sampling interval."""
        from kfast.stationary import spectral_density

        return spectral_density(self, omega, h=h)

    def smooth(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        form: Form = "joseph",
        outputs: SmoothOutputs = None,
    ) -> SmootherResult:
        """Rauch-Tung-Striebel fixed-interval smoother: x(t|T-1), P(t|T-1) and the lag-one
        covariances Cov(x[t], x[t-1] | all data), with the filter's results. Same arguments
        and missing-data rules as ``filter``. outputs: the names of the fields to store, among
        "x_smooth", "P_smooth", "P_lag1" and the filter's (e.g. ("x_smooth", "P_smooth")); the
        others are None, which saves their memory and time. All by default.

        Backward pass (docs/algorithms.md, "RTS"): J(t) = (P(t|t) F' - K(t) N') P(t+1|t)^-1,
        x(t|T-1) = x(t|t) + J (x(t+1|T-1) - x(t+1|t)), P(t|T-1) = P(t|t) + J (P(t+1|T-1) -
        P(t+1|t)) J'. With N != 0 this is the N = 0 smoother of the decorrelated model of
        Söderström Lemma 6.4 (F - N R^-1 H in place of F), written without R^-1.
        A singular P(t+1|t) is handled with its pseudo-inverse.
        """
        out = self._core.smooth(*self._data(y, x0, P0, u), form=_form(form), outputs=_output_names(outputs))
        filt = FilterResult(**{k: out.pop(k, None) for k in _FILTER_FIELDS}, loglik=out.pop("loglik"), model=self)
        return SmootherResult(filter=filt, **out)

    def smooth_fixed_lag(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        lag: int,
        u: Optional[ArrayLike] = None,
        form: Form = "joseph",
    ) -> FixedLagResult:
        """Fixed-lag smoother: the estimate of x[s] from y up to s + lag, for every s (near the
        end, from all the data). lag = 0 is the filter, lag >= T-1 the RTS smoother.

        Structured recursion of Söderström (6.70)-(6.75): O(lag n^3) per step, never the
        filter on the (lag+1) n augmented state. For online use see ``kfast.FixedLagSmoother``.
        """
        y, x0, P0, u = self._data(y, x0, P0, u)
        out = self._core.smooth_fixed_lag(y, x0, P0, _index("lag", lag), u=u, form=_form(form))
        return FixedLagResult(lag=int(lag), **out)

    def smooth_fixed_point(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        t_point: int,
        u: Optional[ArrayLike] = None,
        form: Form = "joseph",
    ) -> FixedPointResult:
        """Fixed-point smoother: the estimate of x[t_point] from y up to each t >= t_point, with
        its covariance (Söderström (6.45)-(6.54)). Row 0 is the filtered x(t_point|t_point);
        the last row equals the RTS smoother at t_point."""
        t_point = _index("t_point", t_point)
        y, x0, P0, u = self._data(y, x0, P0, u)
        out = self._core.smooth_fixed_point(y, x0, P0, t_point, u=u, form=_form(form))
        return FixedPointResult(t_point=t_point, **out)

    def forecast(self, x: ArrayLike, P: ArrayLike, steps: int, u: Optional[ArrayLike] = None) -> Forecast:
        """Forecast `steps` steps from a one-step prediction (x, P) = x(t|t-1), P(t|t-1), such
        as ``FilterResult.x_next`` or ``KalmanFilter.x`` after ``predict()``. Row j is the
        forecast of step t+j (row 0 is (x, P) itself); u, shape (steps, k), holds u(t+j).

        x(t+j+1|t-1) = F x(t+j|t-1) + B u(t+j), P(t+j+1|t-1) = F P F' + Q (Söderström
        (6.38)-(6.42)); y forecasts H x + D u with covariance H P H' + R. Constant models only.
        Unpacks as ``mean, cov = model.forecast(...)``.
        """
        steps = _index("steps", steps)
        x, P = self._prior(x, P, names=("x", "P"))
        if u is not None:
            u = _column_if_1d(as_float64("u", u), self.n_inputs)
        return Forecast(**self._core.forecast(x, P, steps, u=u))

    def simulate(
        self,
        T: int,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        seed: Union[int, np.random.Generator, None] = None,
    ) -> Simulation:
        """Draw a sample path of T steps: x[0] ~ N(x0, P0), (w[t], v[t]) ~ N(0, [[Q, N],
        [N', R]]) jointly (so N is honoured), y[t] = H x[t] + D u[t] + v[t],
        x[t+1] = F x[t] + B u[t] + w[t]. ``seed`` (an int or a numpy Generator) makes the
        draw reproducible. Returns ``Simulation(x, y)``, shapes (T, n) and (T, m).
        """
        T = _index("T", T)
        if T == 0:
            raise _kfast.KfastError("T: must be >= 1, got 0")
        if self.steps is not None and T != self.steps:
            raise _kfast.KfastError(f"T: is {T} but the model's per-step matrices have {self.steps} steps")
        y_dummy, x0, P0, u = self._data(np.zeros((T, self.n_obs)), x0, P0, u)
        rng = np.random.default_rng(seed)
        n, m = self.n_states, self.n_obs
        x_init = _psd_sqrt(P0) @ rng.standard_normal(n) + x0
        z = rng.standard_normal((T, n + m))
        wv = np.einsum("...ij,...j->...i", _psd_sqrt(self._joint_noise_cov()), z)
        w, v = np.ascontiguousarray(wv[:, :n]), np.ascontiguousarray(wv[:, n:])
        x, y = self._core.propagate(x_init, w, v, u=u)
        return Simulation(x, y)

    def em(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        n_iter: int = 10,
        fit: Sequence[EMParameter] = ("F", "H", "Q", "R", "x0", "P0"),
        u: Optional[ArrayLike] = None,
        tol: Optional[float] = None,
        progress: bool = False,
    ) -> "EMResult":
        """Expectation-maximization (Shumway & Stoffer) of the parameters named in ``fit``
        (any of "F", "H", "Q", "R", "x0", "P0"), starting from this model and (x0, P0).

        E-step: the RTS smoother with lag-one covariances (in Rust). M-step: closed forms, in
        pykalman's order H, R, F, Q, x0, P0. B and D stay fixed; N is not supported. Missing
        data: rows with nothing observed drop out of the H and R updates; partly observed rows
        use the conditional moments of their missing components (Shumway & Stoffer 2000).
        The log-likelihood never decreases. ``tol`` stops early when its relative change is
        below tol; ``progress`` prints the iterations to stderr. Returns ``EMResult``.
        """
        from kfast.estimation import em

        return em(self, y, x0, P0, n_iter=n_iter, fit=fit, u=u, tol=tol, progress=progress)

    def _joint_noise_cov(self) -> np.ndarray:
        """[[Q, N], [N', R]], shape (n+m, n+m) or (T, n+m, n+m) for per-step models."""
        n, m = self.n_states, self.n_obs
        N = self.N if self.N is not None else np.zeros((n, m))
        lead = () if self.steps is None else (self.steps,)
        Q, R, N = (np.broadcast_to(a, lead + a.shape[-2:]) for a in (self.Q, self.R, N))
        top = np.concatenate([Q, N], axis=-1)
        bottom = np.concatenate([np.swapaxes(N, -1, -2), R], axis=-1)
        return np.concatenate([top, bottom], axis=-2)

    def _data(
        self, y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Optional[np.ndarray]]:
        y_arr = _column_if_1d(as_float64("y", y), self.n_obs)
        x0_arr, P0_arr = self._prior(x0, P0)
        u_arr = None if u is None else _column_if_1d(as_float64("u", u), self.n_inputs)
        return y_arr, x0_arr, P0_arr, u_arr

    def _prior(self, x: ArrayLike, P: ArrayLike, names: tuple[str, str] = ("x0", "P0")) -> tuple[np.ndarray, np.ndarray]:
        """A mean and covariance as float64; scalars (size 1) for a scalar state."""
        x, P = as_float64(names[0], x), as_float64(names[1], P)
        if self.n_states == 1:
            x = x.reshape(1) if x.size == 1 else x
            P = P.reshape(1, 1) if P.size == 1 else P
        return x, P


# steady_state=True freezes the gains when P(t+1|t) changes by less than this (relative): at
# once from the stationary P0 (the DARE's solution is accurate to ~1e-14), and again once the
# recursion has returned to it after a gap.
_STEADY_STATE_TOL = 1e-10


def _psd_sqrt(C: np.ndarray) -> np.ndarray:
    """A square root L with L L' = C for symmetric PSD C (or a stack), via the eigenvalues so
    that singular covariances (e.g. Q = 0, or a singular joint [[Q, N], [N', R]]) work."""
    lam, V = np.linalg.eigh(C)
    return V * np.sqrt(np.clip(lam, 0.0, None))[..., None, :]


def _column_if_1d(a: np.ndarray, width: int) -> np.ndarray:
    """A 1-D series of a scalar quantity as a (T, 1) column."""
    return a[:, None] if a.ndim == 1 and width == 1 else a


def _tolerance(value) -> Optional[float]:
    if value is None:
        return None
    tol = float(value)
    if not tol >= 0:
        raise _kfast.KfastError(f"converge_tol: must be >= 0, got {value!r}")
    return tol


def _output_names(outputs) -> Optional[list[str]]:
    """``outputs=``: None (everything), one name, or an iterable of names."""
    if outputs is None:
        return None
    names = [outputs] if isinstance(outputs, str) else list(outputs)
    bad = [name for name in names if not isinstance(name, str)]
    if bad:
        raise _kfast.KfastError(f"outputs: expected field names (str), got {bad[0]!r}")
    return names


def _index(name: str, value) -> int:
    """An integer argument (lag, t_point, steps): Python or NumPy integers only."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise _kfast.KfastError(f"{name}: expected an integer, got {value!r}")
    if value < 0:
        raise _kfast.KfastError(f"{name}: must be >= 0, got {value}")
    return int(value)


def _form(form: str) -> Form:
    if form not in _FORMS:
        raise _kfast.KfastError(f"form: expected one of {_FORMS}, got {form!r}")
    return cast(Form, form)
