"""The linear Gaussian state-space model and its filter results (conventions: docs/conventions.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterator, NamedTuple, Optional, Sequence, Union, cast

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, flag, index, tolerance
from kfast._arrays import as_float64, frozen_copy
from kfast._typing import DareMethod, EMParameter, FilterOutputs, Form, SmoothOutputs, UpdateForm

if TYPE_CHECKING:
    from kfast.linear.posterior import DisturbanceSmootherResult, PosteriorDraws
    from kfast.linear.diagnostics import Diagnostics
    from kfast.linear.estimation import EMResult
    from kfast.riccati.stationary import InnovationsForm, SteadyState

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
# The forms of filter, loglik and smooth (docs/algorithms.md, "Update forms").
_UPDATE_FORMS = _FORMS + ("sqrt", "ud", "information", "sequential")
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
    P_pred_inf: Optional[np.ndarray] = None
    """With an exact diffuse start (``P0_inf``): the diffuse part P_inf(t|t-1) of P(t|t-1) =
    P_pred + kappa P_pred_inf, kappa -> inf, shape (T, n, n); zero from step ``n_diffuse`` on.
    None otherwise."""
    n_diffuse: int = 0
    """The number d of diffuse steps of an exact diffuse start (P_inf(d|d-1) = 0): in steps
    t < d, P_pred and P_filt are the finite parts P_* and the log-likelihood term is the
    diffuse one. 0 without ``P0_inf``."""
    model: Optional["LinearGaussian"] = field(default=None, repr=False, compare=False)
    """The model that was filtered."""

    def __repr__(self) -> str:
        stored = [k for k in _FILTER_FIELDS if getattr(self, k) is not None]
        return f"FilterResult(loglik={self.loglik:.6g}, fields={stored})"

    def forecast(self, steps: int, u: Optional[ArrayLike] = None) -> "Forecast":
        """Forecast the ``steps`` steps after the data, T..T+steps-1, from x(T|T-1), P(T|T-1).

        Parameters
        ----------
        steps : int
            Number of steps to forecast.
        u : array_like, shape (steps, k), optional
            The future inputs u(T), ..., u(T+steps-1); required when the model has B or D.

        Returns
        -------
        Forecast
            See :meth:`LinearGaussian.forecast`.

        Raises
        ------
        KfastError
            When this result has no model or no x_next, P_next (left out with ``outputs=``).

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> fc = model.filter([0.3, -0.1, 0.7], x0=0.0, P0=1.0).forecast(2)
        >>> print(fc.x[:, 0].round(4), fc.P[:, 0, 0].round(4))
        [0.2832 0.2266] [1.   1.32]
        """
        if self.model is None or self.x_next is None or self.P_next is None:
            raise _kfast.KfastError("forecast: this FilterResult has no model or no x_next, P_next")
        return self.model.forecast(self.x_next, self.P_next, steps, u=u)

    def diagnostics(self, lags: int = 10, x_true: Optional[ArrayLike] = None, burn: int = 0, alpha: float = 0.05) -> "Diagnostics":
        """Tests of the model's consistency with the data: standardized innovations, NIS (and
        NEES given the true states) with chi-square bounds, autocorrelation, Ljung–Box and
        Jarque–Bera.

        Under the true model the innovations are zero-mean and white with covariance S(t)
        (Söderström ex. 6.16), so their standardized values L(t)^-1 e(t) (S = L L') are
        N(0, I) and uncorrelated in time, and e' S^-1 e ~ chi2(m_t) (NIS). In a simulation the
        error x - x(t|t) has covariance P(t|t), so its NEES ~ chi2(n).

        Parameters
        ----------
        lags : int
            Largest lag of the autocorrelations and Ljung–Box statistics (1..lags).
        x_true : array_like, shape (T, n), optional
            The true states of a simulation, for the NEES.
        burn : int
            Steps at the start left out of the tests over the run (the averages, the
            autocorrelation, Ljung–Box, Jarque–Bera), e.g. while a vague prior is forgotten, as
            statsmodels' ``loglikelihood_burn``. The per-step values cover every step.
        alpha : float
            The bounds are two-sided and hold 1 - alpha under the model.

        Returns
        -------
        Diagnostics
            standardized_innov, nis (+ dof, bounds, mean and its bounds), acf, acf_bound,
            ljung_box (+ p-values), jarque_bera (+ p-values, skew, kurtosis) and, given
            x_true, nees (+ bounds, mean and its bounds).

        Raises
        ------
        KfastError
            When innov or S (or x_filt, P_filt with x_true) were left out with ``outputs=``,
            when S(t) of the observed components is not positive definite, or when a
            component has no more observed steps than ``lags``.

        Notes
        -----
        The standardized innovations are statsmodels' ``standardized_forecasts_error`` and the
        Ljung–Box statistics and p-values are ``statsmodels.stats.diagnostic.acorr_ljungbox``
        of each component (model_df = 0), Jarque–Bera is ``statsmodels.stats.stattools
        .jarque_bera``, all after ``burn``. Missing values are left out: a step's NIS uses its
        observed components, and the autocorrelations sum the pairs observed at both ends over
        the N observed steps (statsmodels' ``acf(..., missing="conservative")``; statsmodels'
        own Ljung–Box gives NaN there). Averaged NIS and NEES: Bar-Shalom, Li & Kirubarajan
        (2001) Sec. 5.4.

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> x, y = model.simulate(500, x0=0.0, P0=1.0, seed=1)
        >>> d = model.filter(y, 0.0, 1.0).diagnostics(lags=5, x_true=x)
        >>> bool(d.nis_mean_bounds[0] <= d.nis_mean <= d.nis_mean_bounds[1])
        True
        >>> bool(d.ljung_box_pvalue[-1, 0] > 0.05)
        True
        """
        from kfast.linear.diagnostics import diagnostics

        return diagnostics(self, lags=lags, x_true=x_true, burn=burn, alpha=alpha)

    def plot_diagnostics(self, component: int = 0, lags: int = 10, fig: Any = None, figsize: Any = None) -> Any:
        """Four panels on one output component, like statsmodels' ``plot_diagnostics``: the
        standardized innovations over time, their histogram with the N(0, 1) density, a normal
        Q-Q plot, and the correlogram with its white-noise band (see :meth:`diagnostics`).
        Needs matplotlib (``pip install kfast[plot]``). Returns the matplotlib Figure (``fig``
        if given)."""
        from kfast.linear.diagnostics import plot_diagnostics

        return plot_diagnostics(self, component=component, lags=lags, fig=fig, figsize=figsize)


_FILTER_FIELDS = tuple(k for k in FilterResult.__dataclass_fields__ if k not in ("model", "loglik", "P_pred_inf", "n_diffuse"))


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
    """Linear Gaussian state-space model, validated once.

    ::

        x[t+1] = F x[t] + B u[t] + w[t]      w ~ N(0, Q)   (Q: discrete-time covariance)
        y[t]   = H x[t] + D u[t] + v[t]      v ~ N(0, R),  E[w[t] v[t]'] = N

    Each matrix is constant, e.g. F of shape (n, n), or given per step with a leading axis T,
    e.g. (T, n, n). Per-step matrices are indexed by the step they leave: F[t], B[t], Q[t],
    N[t] take x[t] to x[t+1]; H[t], D[t], R[t] produce y[t]. A scalar is a 1 x 1 matrix.
    The arguments are copied; the model's matrices are read-only attributes. Models pickle
    and copy (for multiprocessing and Dask); unpickling validates the matrices again.

    Parameters
    ----------
    F : array_like, shape (n, n) or (T, n, n)
        State transition.
    H : array_like, shape (m, n) or (T, m, n)
        Observation matrix.
    Q : array_like, shape (n, n) or (T, n, n)
        Covariance of the process noise w[t].
    R : array_like, shape (m, m) or (T, m, m)
        Covariance of the measurement noise v[t].
    B : array_like, shape (n, k) or (T, n, k), optional
        Input matrix of the state; data then need inputs u of shape (T, k).
    D : array_like, shape (m, k) or (T, m, k), optional
        Input matrix of the output.
    N : array_like, shape (n, m) or (T, n, m), optional
        Cross covariance E[w[t] v[t]'] of the noises at the same step (zero when omitted).
    Qc, Rc : array_like, optional
        Complementary covariances E[w w^T], E[v v^T] of improper complex noise. A complex
        matrix or either of these makes a complex-valued model instead
        (:class:`kfast.linear.complex.ComplexLinearGaussian`: filter, smooth and loglik
        through the real composite form, results complex).

    Raises
    ------
    KfastError
        A ValueError naming the argument, the step and the problem, unless all entries are
        finite, Q and R are symmetric positive semidefinite, the joint covariance
        [[Q, N], [N', R]] is positive semidefinite and the shapes agree (per-step stacks all
        with the same T).

    Notes
    -----
    The notation is that of Söderström, *Discrete-time Stochastic Systems* (2002), ch. 6, with
    his G, R1, R2, R12 written B, Q, R, N. The prior (x0, P0) that the methods take is
    x(0|-1), P(0|-1): the first operation on data is the measurement update with y[0].

    Examples
    --------
    >>> import numpy as np
    >>> import kfast
    >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)  # Söderström ex. 6.17
    >>> model
    LinearGaussian(n_states=1, n_obs=1, n_inputs=0)
    >>> cv = kfast.LinearGaussian(F=[[1.0, 1.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=0.01 * np.eye(2), R=0.25)
    >>> cv.H.shape, cv.R.shape
    ((1, 2), (1, 1))
    >>> kfast.LinearGaussian(F=0.8, H=1.0, Q=-1.0, R=1.0)
    Traceback (most recent call last):
        ...
    kfast.KfastError: Q: not positive semidefinite ...
    """

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        # A complex matrix (or a complementary covariance Qc, Rc) makes a complex model, filtered
        # through its real composite form (kfast.linear.complex; docs/algorithms.md "Complex-valued models").
        from kfast.linear.complex import ComplexLinearGaussian, is_complex_model

        names = ("F", "H", "Q", "R", "B", "D", "N")
        values = tuple(args[: len(names)]) + tuple(kwargs.get(k) for k in names[len(args):])
        if cls is LinearGaussian and is_complex_model(values, kwargs.get("Qc"), kwargs.get("Rc")):
            return ComplexLinearGaussian(*args, **kwargs)
        return super().__new__(cls)

    def __init__(
        self,
        F: ArrayLike,
        H: ArrayLike,
        Q: ArrayLike,
        R: ArrayLike,
        B: Optional[ArrayLike] = None,
        D: Optional[ArrayLike] = None,
        N: Optional[ArrayLike] = None,
        Qc: Optional[ArrayLike] = None,
        Rc: Optional[ArrayLike] = None,
    ) -> None:
        if Qc is not None or Rc is not None:  # (a complex model is made by __new__)
            raise _kfast.KfastError("Qc: complementary covariances belong to complex models")
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
        """The exact discrete model of a continuous-time one sampled at intervals ``dt``.

        The state follows dx = A x dt + B u dt + dbeta with E[dbeta dbeta'] = Qc dt (Qc a
        continuous white-noise intensity; u held over each interval), and is sampled as
        y[t] = H x[t] + D u[t] + v[t] with cov v = R, a discrete covariance (white noise of
        intensity Rc averaged over h has R = Rc / h).

        Parameters
        ----------
        A : array_like, shape (n, n)
            Continuous system matrix.
        Qc : array_like, shape (n, n)
            Intensity of the process noise.
        H, R : array_like
            Observation matrix (m, n) and discrete measurement noise covariance (m, m).
        dt : float or array_like, shape (T,), optional
            A scalar interval gives a constant model; an array of T intervals (dt[t] from step t to
            t+1; the last one only moves x(T|T-1) past the data) gives per-step matrices.
        B, D : array_like, optional
            Continuous input matrix (n, k) and output input matrix (m, k).
        times : array_like, shape (T,), optional
            Sample times instead of ``dt`` (irregular; the last step reuses the last interval).

        Returns
        -------
        LinearGaussian
            F = e^{A dt}, Q = Qd(dt), B = Bd(dt), constant or per step.

        Raises
        ------
        KfastError
            For invalid matrices, both or neither of ``dt`` and ``times``, or intervals that are not
            positive.

        Notes
        -----
        Söderström (4.99)-(4.103)::

            F = e^{A h},   Qd = integral over [0, h] of e^{A s} Qc e^{A' s} ds,   Bd = (integral of e^{A s} ds) B

        computed with Van Loan's (1978) block matrix exponential (in its inverse-free form).

        Examples
        --------
        An Ornstein-Uhlenbeck process of unit variance: Qd = 1 - e^{-2 dt}.

        >>> ou = kfast.LinearGaussian.from_continuous(A=-1.0, Qc=2.0, H=1.0, R=0.1, dt=0.1)
        >>> print(round(float(ou.F[0, 0]), 6), round(float(ou.Q[0, 0]), 6))
        0.904837 0.181269
        >>> kfast.LinearGaussian.from_continuous(A=-1.0, Qc=2.0, H=1.0, R=0.1, times=[0.0, 0.1, 0.3]).steps
        3
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
        form: UpdateForm = "joseph",
        steady_state: bool = False,
        converge_tol: Optional[float] = None,
        outputs: FilterOutputs = None,
        P0_inf: Optional[ArrayLike] = None,
    ) -> FilterResult:
        """Kalman filter over the observations y.

        Parameters
        ----------
        y : array_like, shape (T, m), or (T,) when m = 1
            Observations; NaN marks a missing value. A whole missing row skips the update; a partly
            missing row updates with the observed components only (their rows of H, D, R and
            columns of N).
        x0 : array_like, shape (n,)
            Prior mean x(0|-1) (a scalar when n = 1).
        P0 : array_like, shape (n, n), optional
            Prior covariance P(0|-1); required unless ``steady_state=True``.
        u : array_like, shape (T, k), optional
            Inputs, required when the model has B or D: u[t] enters x[t+1] via B and y[t] via D.
        form : {"joseph", "standard", "sqrt", "ud", "information", "sequential"}
            The update form; all compute the same filter (docs/algorithms.md, "Update forms").
            "joseph" (default), (I-KH)P(I-KH)' + KRK', stays positive semidefinite under
            rounding; "standard", P - KSK' symmetrized, is cheaper. The robust forms take the
            observed components one scalar at a time (decorrelated by the Cholesky factor of
            their R when R is not diagonal) and remove N before the time update (Söderström
            Lemma 6.4): "sqrt" moves a Cholesky factor of P by Givens and Householder
            transformations and never forms P (Söderström Sec. 6.8.1); "ud" keeps
            P = U D U' (Bierman's measurement update, Thornton's time update); "information"
            keeps Y = P^-1 and Y x (needs R and F invertible, and P0 unless ``P0_inf``
            gives the diffuse case P0^-1 = 0: the exact diffuse steps supply the outputs
            while Y is singular); "sequential" updates P one
            scalar at a time, inverting no matrix. They form P, S and the gains only for the
            outputs asked for; ``converge_tol`` and ``steady_state`` need a covariance form.
        steady_state : bool
            Run the constant-gain filter with the stationary gains of :meth:`steady_state` from
            the first step, O(n^2) per step (P0 is not used; constant models only). A missing value
            runs the exact recursion through the gap (the covariance grows while nothing is
            observed) and after it, until P(t+1|t) has converged back to the stationary one
            (change below 1e-10 relative); then the gains are constant again. So with gaps the
            estimates and the log-likelihood are those of the exact filter started from the
            stationary covariance, to about that tolerance.
        converge_tol : float, optional
            Switch to constant gains once max|P(t+1|t) - P(t|t-1)| <= converge_tol * max(1, max|P|)
            at a fully observed step, like statsmodels' steady-state shortcut; results then differ
            from the exact filter by about that tolerance. Off by default.
        outputs : str or iterable of str, optional
            The names of the fields to store (e.g. ``("x_filt", "P_filt")``); the others are None,
            which saves their memory and time. All by default.
        P0_inf : array_like, shape (n, n), optional
            The diffuse part of the prior, for states whose initial value is unknown (random
            walks, trends, seasonals, nonstationary ARMA parts): P(0|-1) = P0 + kappa P0_inf with
            kappa -> inf, handled exactly (KFAS's ``P1inf``; P0 is then the finite part P_*,
            e.g. zero in the diffuse directions). See Notes.

        Returns
        -------
        FilterResult
            x_pred, P_pred, x_filt, P_filt, innov, S, K, K_pred, loglik, loglik_t, x_next, P_next
            (and with ``P0_inf``: P_pred_inf, n_diffuse).

        Raises
        ------
        KfastError
            For data that do not fit the model (shapes, inf, missing inputs) or an invalid prior.
        InnovationCovarianceError
            When S(t) of the observed components is not positive definite at some step.

        Notes
        -----
        Söderström Lemma 6.1, (6.22)-(6.27), at each step t::

            e(t)     = y(t) - H x(t|t-1) - D u(t)            S(t) = H P(t|t-1) H' + R
            K(t)     = P(t|t-1) H' S^-1                       x(t|t) = x(t|t-1) + K e(t)
            P(t|t)   = (I - K H) P(t|t-1) (I - K H)' + K R K'        (Joseph form)
            K_pred   = (F P(t|t-1) H' + N) S^-1               x(t+1|t) = F x(t|t-1) + B u(t) + K_pred e(t)
            P(t+1|t) = F P(t|t-1) F' + Q - K_pred S K_pred'

        and the log-likelihood is the sum over t of log N(e(t); 0, S(t)) (Söderström (6.142)).

        With ``P0_inf`` the first d = ``n_diffuse`` steps run the exact diffuse recursion of
        Koopman (1997) in the univariate form of Durbin & Koopman (2012) Sec. 6.4 (the observed
        components one at a time, decorrelated first when R is not diagonal; N must be 0), until
        the diffuse part of P is zero; then the ordinary filter continues. P_pred and P_filt of
        those steps are the finite parts P_*, S is H P_* H' + R, K the limit gain. The
        log-likelihood is the diffuse one, Durbin & Koopman (2012) Sec. 7.2.2: a component whose
        diffuse variance F_inf = h P_inf h' is positive adds -(log 2 pi + log F_inf) / 2 (its
        innovation carries no information about the parameters), the others the usual term.
        This is statsmodels' value; KFAS leaves out the log 2 pi of the F_inf > 0 terms, so its
        logLik is larger by (log 2 pi) / 2 per such term. A large P0 instead ("approximate
        diffuse") gives a log-likelihood that depends on its size.

        Examples
        --------
        Söderström ex. 6.17: P0 = 1 is the stationary P(t|t-1), so P(t|t) = 0.5 at every step.

        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> res = model.filter([0.3, -0.1, 0.7], x0=0.0, P0=1.0)
        >>> print(res.x_filt[:, 0].round(4))
        [0.15  0.01  0.354]
        >>> print(res.P_filt[:, 0, 0].round(6), res.K[:, 0, 0].round(6))
        [0.5 0.5 0.5] [0.5 0.5 0.5]
        >>> print(round(res.loglik, 4))
        -3.9509
        >>> model.filter([0.3, np.nan, 0.7], 0.0, 1.0, outputs="x_filt").P_filt is None
        True
        """
        if flag("steady_state", steady_state):
            if converge_tol is not None:
                raise _kfast.KfastError("converge_tol: not used with steady_state=True (the gains are constant from the start)")
            P0 = self.steady_state().P_pred
            converge_tol = _STEADY_STATE_TOL
        elif P0 is None:
            raise _kfast.KfastError("P0: required unless steady_state=True")
        args = self._data(y, x0, P0, u)
        names = _output_names(outputs)
        tol = tolerance("converge_tol", converge_tol)
        if P0_inf is not None:
            y_, x0_, P0_, u_ = args
            P_inf = self._prior(x0, P0_inf, ("x0", "P0_inf"))[1]
            out = self._core.filter_diffuse(y_, x0_, P0_, P_inf, u=u_, form=_update_form(form), converge_tol=tol, outputs=names)
            return FilterResult(**out, model=self)
        out = self._core.filter(*args, form=_update_form(form), converge_tol=tol, outputs=names)
        return FilterResult(**out, model=self)

    def loglik(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        form: UpdateForm = "joseph",
        converge_tol: Optional[float] = None,
        P0_inf: Optional[ArrayLike] = None,
    ) -> float:
        """The log-likelihood of y alone, without storing any per-step output.

        Parameters
        ----------
        y, x0, P0, u, form, converge_tol, P0_inf
            As for :meth:`filter` (with ``P0_inf``, the exact diffuse log-likelihood).

        Returns
        -------
        float
            The sum over t of log N(y(t); H x(t|t-1) + D u(t), S(t)) (Söderström (6.142)): the
            exact Gaussian log-likelihood given the prior x(0) ~ N(x0, P0).

        Raises
        ------
        KfastError, InnovationCovarianceError
            As for :meth:`filter`.

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> print(round(model.loglik([0.3, -0.1, 0.7], x0=0.0, P0=1.0), 4))
        -3.9509
        """
        if P0_inf is not None:
            return self.filter(y, x0, P0, u=u, form=form, converge_tol=converge_tol, outputs=(), P0_inf=P0_inf).loglik
        return self._core.loglik(*self._data(y, x0, P0, u), form=_update_form(form), converge_tol=tolerance("converge_tol", converge_tol))

    def steady_state(self, method: DareMethod = "doubling") -> "SteadyState":
        """The stationary Kalman filter of a constant model.

        Parameters
        ----------
        method : {"doubling", "newton", "iteration", "eigen"}
            The DARE algorithm (see :func:`kfast.solve_discrete_are`).

        Returns
        -------
        SteadyState
            P_pred (the stabilizing solution of the DARE), P_filt, K, K_pred, S, the closed-loop
            eigenvalues of F - K_pred H and the relative residual.

        Raises
        ------
        NoStabilizingSolutionError
            When (F, H) is not detectable or the noise does not excite the unstable modes.
        KfastError
            For a model with per-step matrices.

        Notes
        -----
        P solves Söderström (6.91)::

            P = F P F' + Q - (F P H' + N) (H P H' + R)^-1 (F P H' + N)'

        i.e. SciPy's ``solve_discrete_are(F', H', Q, R, s=N)``; S = H P H' + R,
        K = P H' S^-1, K_pred = (F P H' + N) S^-1, P_filt = P - K S K'.

        Examples
        --------
        Söderström ex. 6.17:

        >>> ss = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0).steady_state()
        >>> print(ss.P_pred.round(8), ss.K.round(8), ss.K_pred.round(8), ss.S.round(8))
        [[1.]] [[0.5]] [[0.4]] [[2.]]
        >>> print(ss.closed_loop_eigenvalues.real.round(8))
        [0.4]
        """
        from kfast.riccati.stationary import steady_state

        return steady_state(self, method=method)

    def innovations_form(self) -> "InnovationsForm":
        """The steady-state innovations model of a constant model.

        Returns
        -------
        InnovationsForm
            (F, K_pred, H, S) of x(t+1) = F x(t) + B u(t) + K_pred e(t), y(t) = H x(t) + D u(t) + e(t),
            cov e = S: the same output statistics as the model, driven by its innovations
            (Söderström Thm 4.2).

        Raises
        ------
        NoStabilizingSolutionError, KfastError
            As for :meth:`steady_state`.

        Examples
        --------
        >>> inn = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0).innovations_form()
        >>> print(inn.K_pred.round(8), inn.S.round(8))
        [[0.4]] [[2.]]
        """
        from kfast.riccati.stationary import innovations_form

        return innovations_form(self)

    def stationary_cov(self) -> np.ndarray:
        """The stationary state covariance Pi of a stable constant model.

        Returns
        -------
        ndarray, shape (n, n)
            Pi = F Pi F' + Q (Söderström (4.22)).

        Raises
        ------
        KfastError
            Unless F is stable (a random walk has no stationary covariance) and constant.

        Examples
        --------
        An AR(1) state: Pi = Q / (1 - F^2) = 0.68 / 0.36.

        >>> print(kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0).stationary_cov().round(6))
        [[1.888889]]
        """
        from kfast.riccati.stationary import stationary_cov

        return stationary_cov(self)

    def autocovariance(self, lags: ArrayLike) -> np.ndarray:
        """The autocovariance of the stationary output.

        Parameters
        ----------
        lags : int or array_like of int
            The lags tau.

        Returns
        -------
        ndarray, shape (len(lags), m, m)
            r_y(tau) = E[y(t+tau) y(t)'] (the lag on the first factor); r_y(-tau) = r_y(tau)'.
            Inputs are ignored (zero mean).

        Raises
        ------
        KfastError
            Unless F is stable and constant, or for lags that are not integers.

        Notes
        -----
        Söderström Lemma 4.2: r_y(0) = H Pi H' + R and r_y(tau) = H F^(tau-1) (F Pi H' + N) for
        tau >= 1, with Pi the stationary state covariance.

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> print(model.autocovariance([0, 1, 2])[:, 0, 0].round(6))
        [2.888889 1.511111 1.208889]
        """
        from kfast.riccati.stationary import autocovariance

        return autocovariance(self, lags)

    def spectral_density(self, omega: ArrayLike, h: float = 1.0) -> np.ndarray:
        """The spectral density of the stationary output.

        Parameters
        ----------
        omega : float or array_like
            Angular frequencies (radians per time unit).
        h : float
            The sampling interval (1: omega in radians per sample).

        Returns
        -------
        ndarray, shape (len(omega), m, m), complex
            phi_y(e^{i omega h}), Hermitian.

        Raises
        ------
        KfastError
            Unless F is stable and constant, or for h <= 0.

        Notes
        -----
        phi_y(z) = h G(z) [[Q, N], [N', R]] G(1/z)' with G(z) = [H (zI - F)^-1, I] (Söderström
        (4.25)), normalized without 1/2pi as in Söderström (3.22)-(3.25): r_y(k) is 1/2pi times the
        integral of phi_y e^{i omega k h} over |omega| <= pi/h. (statsmodels divides by 2pi.)

        Examples
        --------
        AR(1) in white noise: phi_y = Q / |e^{i omega} - F|^2 + R.

        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> print(model.spectral_density([0.0, np.pi])[:, 0, 0].real.round(6))
        [18.        1.209877]
        """
        from kfast.riccati.stationary import spectral_density

        return spectral_density(self, omega, h=h)

    def smooth(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        form: UpdateForm = "joseph",
        outputs: SmoothOutputs = None,
        P0_inf: Optional[ArrayLike] = None,
    ) -> SmootherResult:
        """Rauch-Tung-Striebel fixed-interval smoother: every state given all the data.

        Parameters
        ----------
        y, x0, P0, u, form, P0_inf
            As for :meth:`filter` (the same missing-data rules; with ``P0_inf`` the exact
            diffuse smoother, see Notes).
        outputs : str or iterable of str, optional
            The names of the fields to store, among "x_smooth", "P_smooth", "P_lag1" and the
            filter's (e.g. ``("x_smooth", "P_smooth")``); the others are None. All by default.

        Returns
        -------
        SmootherResult
            x(t|T-1), P(t|T-1), the lag-one covariances Cov(x[t], x[t-1] | all data) and the
            forward pass (``.filter``).

        Raises
        ------
        KfastError, InnovationCovarianceError
            As for :meth:`filter`.

        Notes
        -----
        The backward pass of Rauch, Tung & Striebel (1965) (docs/algorithms.md, "RTS"), for
        t = T-2, ..., 0::

            J(t)     = (P(t|t) F' - K(t) N') P(t+1|t)^-1
            x(t|T-1) = x(t|t) + J(t) (x(t+1|T-1) - x(t+1|t))
            P(t|T-1) = P(t|t) + J(t) (P(t+1|T-1) - P(t+1|t)) J(t)'

        With N != 0 this is the N = 0 smoother of the decorrelated model of Söderström Lemma 6.4
        (F - N R^-1 H in place of F), written without R^-1. A singular P(t+1|t) is handled with
        its pseudo-inverse. The lag-one covariance is P(t+1|T-1) J(t)'.

        With ``P0_inf`` (exact diffuse initialization) the result is the exact diffuse smoother
        (Durbin & Koopman (2012) Sec. 5.3), computed by de Jong's (1991) augmentation: the
        ordinary smoother from (x0, P0) corrected by the generalized least-squares estimate of
        the diffuse part of x(0), with its uncertainty added to P(t|T-1)
        (docs/algorithms.md, "Exact diffuse initialization"); ``.filter`` is the exact diffuse
        filter. The data must determine every diffuse direction.

        Examples
        --------
        The random walk of Söderström ch. 8 with beta = 1 (Q = 1, R = beta (beta + 1) = 2): the
        filter variance is beta, the smoother's tends to beta (beta + 1) / (2 beta + 1) = 2/3 away
        from the ends.

        >>> walk = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=2.0)
        >>> sm = walk.smooth(np.zeros(41), x0=0.0, P0=2.0)
        >>> print(round(sm.filter.P_filt[20, 0, 0], 6), round(sm.P_smooth[20, 0, 0], 6))
        1.0 0.666667
        """
        if P0_inf is not None:
            from kfast.linear.diffuse import smooth

            names = _output_names(outputs)
            return smooth(self, y, x0, P0, P0_inf, u, _update_form(form), None if names is None else tuple(names))
        out = self._core.smooth(*self._data(y, x0, P0, u), form=_update_form(form), outputs=_output_names(outputs))
        filt = FilterResult(**{k: out.pop(k, None) for k in _FILTER_FIELDS}, loglik=out.pop("loglik"), model=self)
        return SmootherResult(filter=filt, **out)

    def disturbance_smooth(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        P0_inf: Optional[ArrayLike] = None,
    ) -> "DisturbanceSmootherResult":
        """The disturbance smoother: the mean and covariance of each w(t) and v(t) given all the
        data (Durbin & Koopman (2012) Sec. 4.5; KFAS's ``etahat``, ``V_eta``, ``epshat``,
        ``V_eps``; statsmodels' ``smoothed_state_disturbance``).

        Parameters
        ----------
        y, x0, P0, u, P0_inf
            As in :meth:`filter` (missing values NaN; with ``P0_inf`` the exact diffuse
            smoother's moments, so the limits kappa -> infinity of the disturbances' moments).

        Returns
        -------
        DisturbanceSmootherResult
            w_smooth (T, n), w_cov (T, n, n), v_smooth (T, m), v_cov (T, m, m) and the state
            smoother they come from.

        Notes
        -----
        Given all states and the data, the noise xi(t) = (w(t), v(t)) ~ N(0, [[Q, N], [N', R]]) is
        known where it is "seen": w(t) = x(t+1) - F x(t) - B u(t) for t < T-1 and each observed
        v_i(t) = y_i(t) - H_i x(t) - D_i u(t). The rest (w(T-1), which moves the state past the
        data, and missing components of v) is Gaussian given the seen part o(t) alone. So with
        A = J (Pi J Pi)^+ Pi (Pi the mask of o):

            E[xi | y] = A E[o | y],    Var(xi | y) = J - A J + A Var(o | y) A'

        where E[o | y] and Var(o | y) follow from x(t|T-1), P(t|T-1) and the lag-one covariance
        of the RTS smoother. With N = 0 and nothing missing this is w(t|T-1) = x(t+1|T-1) -
        F x(t|T-1) - B u(t) and v(t|T-1) = y(t) - H x(t|T-1) - D u(t), Var = H P(t|T-1) H'.

        Examples
        --------
        >>> walk = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=2.0)
        >>> ds = walk.disturbance_smooth([1.0, 0.5, 2.0], x0=0.0, P0=1.0)
        >>> print(ds.w_smooth[:, 0].round(4), ds.v_cov[:, 0, 0].round(4))
        [0.2674 0.407  0.    ] [0.5116 0.6977 0.9767]
        """
        from kfast.linear.posterior import disturbance_smooth

        return disturbance_smooth(self, y, x0, P0, u=u, P0_inf=P0_inf)

    def simulation_smoother(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        draws: int = 1,
        seed: Union[int, np.random.Generator, None] = None,
        variates: Optional[dict] = None,
        P0_inf: Optional[ArrayLike] = None,
    ) -> "PosteriorDraws":
        """Draws of the states and disturbances from their joint posterior p(x, w, v | y): the
        simulation smoother of Durbin & Koopman (2002), for Gibbs samplers and other Bayesian
        uses of state-space models.

        Parameters
        ----------
        y, x0, P0, u
            As in :meth:`filter` (missing values NaN).
        draws : int
            Number of independent draws.
        seed : int or numpy.random.Generator, optional
            Makes the draws reproducible.
        variates : dict, optional
            The standard normal variates to use instead of drawing them:
            ``{"initial": (draws, n), "state": (draws, T, n), "measurement": (draws, T, m)}``
            (statsmodels' ``initial_state_variates``, ``state_disturbance_variates``,
            ``measurement_disturbance_variates``; KFAS's ``u``), mapped to x(0) = x0 + L0 z0 and
            (w, v) = L (z_w, z_v) with L0, L the lower Cholesky factors of P0 and
            [[Q, N], [N', R]] (the symmetric square root when singular).
        P0_inf : array_like, shape (n, n), optional
            The diffuse part of the prior (as in :meth:`filter`): the draws are then from the
            posterior under the exact diffuse prior (x+ starts from x0 + L0 z0 with L0 the factor
            of the finite part P0, and the mean correction uses the exact diffuse smoother, which
            does not depend on the diffuse part of x+; Durbin & Koopman (2012) Sec. 4.9).

        Returns
        -------
        PosteriorDraws
            x (draws, T, n), w (draws, T, n), v (draws, T, m).

        Notes
        -----
        The mean correction of Durbin & Koopman (2002): draw (x+, y+) from the model, then
        x~ = x+ + E[x | y] - E[x+ | y+] = x+ + E0[x | y - y+], where E0 is the smoother with a
        zero prior mean and no inputs (the smoother is linear in the data); the disturbances
        likewise with :meth:`disturbance_smooth`'s means. Each draw costs one smoother pass.
        The draws have the smoothed means and covariances; given the same variates they equal
        KFAS's ``simulateSSM`` (tests/data/kfas_simulation_smoothing.csv).

        Examples
        --------
        >>> walk = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=2.0)
        >>> post = walk.simulation_smoother([1.0, 0.5, 2.0], x0=0.0, P0=1.0, draws=4000, seed=1)
        >>> post.x.shape
        (4000, 3, 1)
        >>> print(post.x.mean(axis=0)[:, 0].round(1), walk.smooth([1.0, 0.5, 2.0], 0.0, 1.0).x_smooth[:, 0].round(1))
        [0.5 0.8 1.2] [0.5 0.8 1.2]
        """
        from kfast.linear.posterior import simulation_smoother

        return simulation_smoother(self, y, x0, P0, u=u, draws=draws, seed=seed, variates=variates, P0_inf=P0_inf)

    def smooth_fixed_lag(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        lag: int,
        u: Optional[ArrayLike] = None,
        form: Form = "joseph",
    ) -> FixedLagResult:
        """Fixed-lag smoother: the estimate of each x[s] from y up to s + lag.

        Parameters
        ----------
        y, x0, P0, u, form
            As for :meth:`filter`.
        lag : int
            The lag L >= 0. L = 0 is the filter, L >= T-1 the RTS smoother.

        Returns
        -------
        FixedLagResult
            Row s of x_smooth, P_smooth is x(s | min(s + L, T-1)), P(s | min(s + L, T-1)).

        Raises
        ------
        KfastError, InnovationCovarianceError
            As for :meth:`filter`, and for a negative or non-integer lag.

        Notes
        -----
        The structured recursion of Söderström (6.70)-(6.75): O(lag n^3) per step, never the filter
        on the (lag+1) n augmented state of (6.58)-(6.65). For online use see
        :class:`kfast.FixedLagSmoother`.

        Examples
        --------
        The random walk of Söderström ch. 8 (beta = 1): the variance with lag 2 is 0.6875.

        >>> walk = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=2.0)
        >>> res = walk.smooth_fixed_lag(np.zeros(20), x0=0.0, P0=2.0, lag=2)
        >>> print(round(res.P_smooth[10, 0, 0], 6))
        0.6875
        """
        y, x0, P0, u = self._data(y, x0, P0, u)
        out = self._core.smooth_fixed_lag(y, x0, P0, index("lag", lag), u=u, form=_form(form))
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
        """Fixed-point smoother: the estimate of x[t_point] from more and more data.

        Parameters
        ----------
        y, x0, P0, u, form
            As for :meth:`filter`.
        t_point : int
            The step s whose state is estimated, 0 <= s < T.

        Returns
        -------
        FixedPointResult
            Row j of x, P is x(s | s + j), P(s | s + j): row 0 is the filtered estimate, the last
            row equals the RTS smoother at s.

        Raises
        ------
        KfastError, InnovationCovarianceError
            As for :meth:`filter`, and for t_point outside the data.

        Notes
        -----
        Söderström (6.45)-(6.54): with C = Cov(x(s) - x(s|t-1), x(t) - x(t|t-1)),
        x(s|t) = x(s|t-1) + C H' S^-1 e(t), P(s|t) = P(s|t-1) - C H' S^-1 H C' and
        C <- C (F - K_pred H)'.

        Examples
        --------
        The random walk of Söderström ch. 8 (beta = 1): the variances V_0, ..., V_3.

        >>> walk = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=2.0)
        >>> res = walk.smooth_fixed_point(np.zeros(20), x0=0.0, P0=2.0, t_point=5)
        >>> print(res.P[:4, 0, 0].round(6))
        [1.       0.75     0.6875   0.671875]
        """
        t_point = index("t_point", t_point)
        y, x0, P0, u = self._data(y, x0, P0, u)
        out = self._core.smooth_fixed_point(y, x0, P0, t_point, u=u, form=_form(form))
        return FixedPointResult(t_point=t_point, **out)

    def forecast(self, x: ArrayLike, P: ArrayLike, steps: int, u: Optional[ArrayLike] = None) -> Forecast:
        """Forecast ``steps`` steps from a one-step prediction.

        Parameters
        ----------
        x, P : array_like, shapes (n,) and (n, n)
            x(t|t-1), P(t|t-1), such as ``FilterResult.x_next``, ``P_next`` or ``KalmanFilter.x``,
            ``P`` after ``predict()``.
        steps : int
            Number of steps; row j forecasts step t + j (row 0 is (x, P) itself).
        u : array_like, shape (steps, k), optional
            The inputs u(t + j); required when the model has B or D.

        Returns
        -------
        Forecast
            x, P (state means and covariances), y, y_cov (output means H x + D u and covariances
            H P H' + R); unpacks as ``mean, cov = model.forecast(...)``.

        Raises
        ------
        KfastError
            For a model with per-step matrices, or invalid x, P or u.

        Notes
        -----
        Söderström (6.38)-(6.42): x(t+j+1|t-1) = F x(t+j|t-1) + B u(t+j),
        P(t+j+1|t-1) = F P(t+j|t-1) F' + Q. For a stable F, P tends to the stationary covariance.

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> fc = model.forecast(x=1.0, P=1.0, steps=4)
        >>> print(fc.x[:, 0].round(4), fc.P[:, 0, 0].round(4))
        [1.    0.8   0.64  0.512] [1.     1.32   1.5248 1.6559]
        >>> print(fc.y_cov[:, 0, 0].round(4))
        [2.     2.32   2.5248 2.6559]
        """
        steps = index("steps", steps)
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
        """Draw a sample path of the model.

        Parameters
        ----------
        T : int
            Number of steps (the model's T for per-step matrices).
        x0, P0 : array_like
            x[0] ~ N(x0, P0).
        u : array_like, shape (T, k), optional
            Inputs; required when the model has B or D.
        seed : int or numpy.random.Generator, optional
            Makes the draw reproducible.

        Returns
        -------
        Simulation
            ``x, y``, shapes (T, n) and (T, m).

        Raises
        ------
        KfastError
            For T < 1, a T that does not match per-step matrices, or invalid x0, P0, u.

        Notes
        -----
        (w[t], v[t]) ~ N(0, [[Q, N], [N', R]]) jointly (so N is honoured), y[t] = H x[t] + D u[t]
        + v[t], x[t+1] = F x[t] + B u[t] + w[t]. Singular covariances are allowed.

        Examples
        --------
        >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> x, y = model.simulate(100, x0=0.0, P0=1.0, seed=1)
        >>> x.shape, y.shape
        ((100, 1), (100, 1))
        >>> bool(np.array_equal(y, model.simulate(100, x0=0.0, P0=1.0, seed=1).y))
        True
        """
        T = index("T", T)
        if T == 0:
            raise _kfast.KfastError("T: must be >= 1, got 0")
        if self.steps is not None and T != self.steps:
            raise _kfast.KfastError(f"T: is {T} but the model's per-step matrices have {self.steps} steps")
        n, m = self.n_states, self.n_obs
        _kfast.check_alloc("T", [[T, n + m], [T, n + m], [T, n], [T, m], [T, n], [T, m]])
        x0, P0 = self._prior(x0, P0)
        self._core.check_prior(x0, P0)
        u = None if u is None else _column_if_1d(as_float64("u", u), self.n_inputs)
        rng = _generator(seed)
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
        """Expectation-maximization estimates of the parameters named in ``fit``.

        Parameters
        ----------
        y, x0, P0, u
            As for :meth:`filter`; (x0, P0) is the starting prior.
        n_iter : int
            The maximum number of iterations.
        fit : sequence of {"F", "H", "Q", "R", "x0", "P0"}
            The parameters to estimate; the others stay fixed.
        tol : float, optional
            Stop early when the relative change of the log-likelihood is below tol.
        progress : bool
            Report each iteration and its log-likelihood on stderr (a tqdm bar when tqdm is
            installed).

        Returns
        -------
        EMResult
            The estimated model, x0, P0 and the log-likelihood before each iteration and at the
            result (non-decreasing).

        Raises
        ------
        KfastError
            For models with per-step matrices or N, unknown parameter names, or invalid data.

        Notes
        -----
        Shumway & Stoffer (1982). E-step: the RTS smoother with lag-one covariances (in Rust).
        M-step: closed forms, in pykalman's order H, R, F, Q, x0, P0; B and D stay fixed. Missing
        data: rows with nothing observed drop out of the H and R updates; partly observed rows use
        the conditional moments of their missing components (Shumway & Stoffer 2000).

        Examples
        --------
        >>> true = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
        >>> _, y = true.simulate(200, x0=0.0, P0=1.0, seed=7)
        >>> start = kfast.LinearGaussian(F=0.5, H=1.0, Q=1.0, R=1.0)
        >>> res = start.em(y, x0=0.0, P0=1.0, n_iter=20, fit=("F", "Q", "R"))
        >>> res.n_iter, bool(np.all(np.diff(res.loglik) >= -1e-9))
        (20, True)
        """
        from kfast.linear.estimation import em

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


def _generator(seed) -> np.random.Generator:
    """``seed`` as NumPy's ``default_rng`` reads it; a clear error naming ``seed`` otherwise."""
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError) as exc:
        raise _kfast.KfastError(f"seed: expected None, a non-negative integer or a numpy.random.Generator ({exc})") from None


def _psd_sqrt(C: np.ndarray) -> np.ndarray:
    """A square root L with L L' = C for symmetric PSD C (or a stack), via the eigenvalues so
    that singular covariances (e.g. Q = 0, or a singular joint [[Q, N], [N', R]]) work."""
    lam, V = np.linalg.eigh(C)
    return V * np.sqrt(np.clip(lam, 0.0, None))[..., None, :]


def _column_if_1d(a: np.ndarray, width: int) -> np.ndarray:
    """A 1-D series of a scalar quantity as a (T, 1) column."""
    return a[:, None] if a.ndim == 1 and width == 1 else a


def _output_names(outputs) -> Optional[list[str]]:
    """``outputs=``: None (everything), one name, or an iterable of names."""
    if outputs is None:
        return None
    try:
        names = [outputs] if isinstance(outputs, str) else list(outputs)
    except TypeError:
        raise _kfast.KfastError(f"outputs: expected a field name or an iterable of names, got {outputs!r}") from None
    bad = [name for name in names if not isinstance(name, str)]
    if bad:
        raise _kfast.KfastError(f"outputs: expected field names (str), got {bad[0]!r}")
    return names


def _form(form: str) -> Form:
    return cast(Form, choice("form", form, _FORMS))


def _update_form(form: str) -> UpdateForm:
    return cast(UpdateForm, choice("form", form, _UPDATE_FORMS))
