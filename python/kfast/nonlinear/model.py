"""The nonlinear state-space model with additive noise and its Gaussian filters (EKF, UKF)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Optional, Sequence, Union, cast

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice, index
from kfast._numbers import positive_real, real_scalar
from kfast._arrays import as_float64, frozen_copy
from kfast._typing import FilterOutputs, Form, Iteration, Keep, Resample, UkfForm
from kfast.linear.model import FilterResult, SmootherResult, _column_if_1d, _output_names
from kfast.nonlinear.particle import ParticleResult
from kfast.nonlinear.likelihood import Likelihood, ParticleMove, _spec as _likelihood_spec
from kfast.sigma import SigmaPoints, merwe

if TYPE_CHECKING:
    from kfast.linear.model import LinearGaussian
    from kfast.multiple import IMMResult

__all__ = ["NonlinearModel", "BuiltinFunction"]

PointFunction = Callable[[np.ndarray, int, Optional[np.ndarray]], ArrayLike]
"""``f(X, t, u)``: X of shape (k, n), one row per point; returns (k, n) for f, (k, m) for h."""

# The fields the nonlinear filters compute (all of FilterResult's but the predictor gain).
_FIELDS = tuple(name for name, _ in _kfast.FILTER_FIELDS if name != "K_pred")


@dataclass(frozen=True)
class BuiltinFunction:
    """A transition f or measurement h written in Rust, with its Jacobian in closed form
    (``kfast.models.coordinated_turn``, ``kfast.models.range_bearing``). Pass it as ``f`` or
    ``h`` of :class:`NonlinearModel`; the filter then never calls back into Python."""

    kind: str
    params: Any
    """The model's parameters: a tuple of numbers, or the matrix of a linear map."""
    Q: Optional[np.ndarray] = field(default=None, repr=False)
    """The process noise covariance that goes with a transition model, if it has one."""
    angles: tuple = ()
    """The outputs that are angles (for a measurement model)."""


class NonlinearModel:
    """A nonlinear state-space model with additive Gaussian noise, validated once::

        x[t+1] = f(x[t], t, u[t]) + w[t]      w ~ N(0, Q)
        y[t]   = h(x[t], t, u[t]) + v[t]      v ~ N(0, R)
        prior  x[0] ~ N(x0, P0)               (x0, P0) is x(0|-1): the first step is an update

    Parameters
    ----------
    f, h : callable, BuiltinFunction or LinearGaussian
        Either a Python function vectorized over a batch of points, ``f(X, t, u)`` with X of
        shape (k, n) (one point per row), t the integer step and u the input row u[t] (None
        without inputs), returning shape (k, n) for f and (k, m) for h -- the filter calls it
        once per step for all its points (one sigma-point set, or the 2n points of a difference
        Jacobian) -- or a built-in model from :mod:`kfast.models`, which runs in Rust (a
        ``LinearGaussian`` from the catalogue gives its F as f or its H as h, so that e.g.
        ``constant_velocity`` dynamics compose with a ``range_bearing`` sensor) -- or a
        compiled function of the C signature ``C_SIGNATURE`` (a numba ``@cfunc``, a
        ``scipy.LowLevelCallable`` or a ctypes function pointer), which the Rust loop calls
        directly without the GIL: ``void f(const double *X, intptr_t k, intptr_t n, int64_t t,
        const double *u, double *out)`` with X the k points (k x n, row-major), u the input row
        (NULL without inputs) and out the k results (k x n for f, k x m for h). A signature that
        does not match is refused; the function itself is trusted (it must not write past out).
    Q : array_like, shape (n, n) or (T, n, n); (r, r) or (T, r, r) with ``g``
        Process noise covariance (Q[t] takes x[t] to x[t+1]); may be singular, even 0.
    R : array_like, shape (m, m) or (T, m, m)
        Measurement noise covariance; m is taken from it.
    n : int
        The state size.
    jac_f, jac_h : callable, optional
        Jacobians, batched like f and h: ``jac_f(X, t, u)`` -> (k, n, n), ``jac_h`` -> (k, m, n)
        (Python functions or compiled ones of ``C_SIGNATURE`` writing k x n x n or k x m x n
        numbers, with f and h of either kind).
        Without them the EKF uses central differences, column j with step
        eps^(1/3) max(|x_j|, 1), all 2n points in one call of f or h.
    hess_f, hess_h : callable, optional
        Hessians for the second-order EKF (``ekf(order=2)``), one n x n matrix per output:
        ``hess_f(X, t, u)`` -> (k, n, n, n), ``hess_h`` -> (k, m, n, n). Without them, second
        central differences with step eps^(1/4) max(|x_j|, 1), all 1 + 2n^2 points in one call.
    angles : sequence of int, optional
        The components of y that are angles (radians): their innovations, differences and
        sigma-point deviations are wrapped to [-pi, pi), so a bearing crossing +-pi does not
        jump by 2 pi. A built-in h brings its own (e.g. the bearing of ``range_bearing``).
    g : callable or array_like, shape (n, r), optional
        A noise gain: x[t+1] = f(x[t], t, u[t]) + g(x[t], t, u[t]) w[t] with w ~ N(0, Q), Q of
        shape (r, r). A constant G (an array), a Python function batched like f returning
        (k, n, r), or a compiled function of ``C_SIGNATURE`` writing k x n*r numbers. The filters
        add G Q G' with G = g(x(t|t), t, u[t]), the gain at the estimate where f is linearized.
    noise_input : bool, default False
        The process noise is an input of f: x[t+1] = f(x[t], w[t], t, u[t]) with w ~ N(0, Q), Q
        of shape (r, r) (non-additive noise, e.g. a multiplicative disturbance). A Python f is
        then called as ``f(X, W, t, u)`` with W of shape (k, r), one noise vector per point;
        ``jac_f(X, W, t, u)`` returns (k, n, n + r), the Jacobian in x then w, and ``hess_f``
        (k, n, n + r, n + r); a compiled f gets the rows (x, w) of n + r numbers (its n
        argument is n + r). The EKF linearizes f at (x(t|t), 0) and adds L Q L' with
        L = df/dw; the UKF places its time-update points on the augmented (x, w) ~
        N((x(t|t), 0), diag(P(t|t), Q)) -- 2(n + r) + 1 Merwe or Julier points, with the weights
        of dimension n + r -- and adds no Q (Wan & van der Merwe 2000). Not with ``g``, a
        built-in f or a custom sigma-point set.

    Examples
    --------
    A target in a coordinated turn seen by a range-bearing radar at the origin:

    >>> ct = kfast.models.coordinated_turn(dt=0.1, q=1.0, sigma_omega=0.05)
    >>> radar = kfast.models.range_bearing(sensor=(0.0, 0.0))
    >>> model = kfast.NonlinearModel(ct, radar, ct.Q, np.diag([1.0, np.deg2rad(0.5) ** 2]), n=5)
    >>> y = np.array([[111.8, 0.4636], [112.3, 0.4513]])
    >>> res = model.ukf(y, x0=[100, 50, 5, -2, 0.1], P0=np.diag([100, 100, 4, 4, 0.01]))
    >>> res.x_filt.shape, res.P_filt.shape
    ((2, 5), (2, 5, 5))
    """

    def __init__(
        self,
        f: Union[PointFunction, BuiltinFunction, "LinearGaussian"],
        h: Union[PointFunction, BuiltinFunction, "LinearGaussian"],
        Q: ArrayLike,
        R: ArrayLike,
        n: int,
        jac_f: Optional[Callable[..., ArrayLike]] = None,
        jac_h: Optional[Callable[..., ArrayLike]] = None,
        angles: Sequence[int] = (),
        hess_f: Optional[Callable[..., ArrayLike]] = None,
        hess_h: Optional[Callable[..., ArrayLike]] = None,
        g: Union[PointFunction, ArrayLike, None] = None,
        noise_input: bool = False,
    ) -> None:
        self.n_states: int = index("n", n)
        if self.n_states == 0:
            raise _kfast.KfastError("n: must be at least 1")
        self.Q: np.ndarray = frozen_copy("Q", Q, scalar_shape=(1, 1))
        if self.Q.ndim not in (2, 3):
            raise _kfast.KfastError(f"Q: expected shape (r, r) or (T, r, r), got {self.Q.shape}")
        self.R: np.ndarray = frozen_copy("R", R, scalar_shape=(1, 1))
        if self.R.ndim not in (2, 3):
            raise _kfast.KfastError(f"R: expected shape (m, m) or (T, m, m), got {self.R.shape}")
        self.n_obs: int = self.R.shape[-1]
        declared = tuple(angles) if not isinstance(h, BuiltinFunction) or angles else h.angles
        self.angles: tuple[int, ...] = _angles(declared, self.n_obs)
        derivatives = {}
        for name, fn, what, given in (
            ("jac_f", f, "Jacobian", jac_f), ("jac_h", h, "Jacobian", jac_h),
            ("hess_f", f, "Hessians", hess_f), ("hess_h", h, "Hessians", hess_h),
        ):
            if given is not None and isinstance(fn, BuiltinFunction):
                raise _kfast.KfastError(f"{name}: the built-in {name[-1]} has its own {what}")
            derivatives[name] = _derivative(name, given)
        jac_f, jac_h, hess_f, hess_h = (derivatives[k] for k in ("jac_f", "jac_h", "hess_f", "hess_h"))
        self.f, self.h = f, h
        self.noise_input: bool = bool(noise_input)
        f_spec = _spec("f", f)
        if self.noise_input:
            f_spec, jac_f, hess_f = _noise_as_input(f, f_spec, jac_f, hess_f, self.n_states, g)
        self.g: Union[PointFunction, np.ndarray, None] = _noise_gain(g, self.n_states, self.Q.shape[-1])
        self._core = _kfast.NonlinearModel(
            f_spec, _spec("h", h), self.Q, self.R, self.n_states, self.n_obs, list(self.angles),
            jac_f=jac_f, jac_h=jac_h, hess_f=hess_f, hess_h=hess_h,
            g=None if self.g is None else ("constant", self.g) if isinstance(self.g, np.ndarray) else _spec("g", self.g),
            noise_input=self.noise_input,
        )

    @classmethod
    def from_linear(cls, model: "LinearGaussian") -> "NonlinearModel":
        """The linear model x[t+1] = F x + w, y = H x + v as a nonlinear one, run by the built-in
        matrix path (constant F and H, no B, D or N)."""
        if model.steps is not None and (model.F.ndim == 3 or model.H.ndim == 3):
            raise _kfast.KfastError("model: F and H must be constant to run as a nonlinear model")
        if model.B is not None or model.D is not None or model.N is not None:
            raise _kfast.KfastError("model: a model with B, D or N has no nonlinear form here")
        return cls(
            BuiltinFunction("linear", model.F),
            BuiltinFunction("linear", model.H),
            model.Q,
            model.R,
            n=model.n_states,
        )

    def __repr__(self) -> str:
        extra = ", noise_input=True" if self.noise_input else ""
        return f"NonlinearModel(n={self.n_states}, m={self.n_obs}, angles={list(self.angles)}{extra})"

    def ekf(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        iterations: int = 0,
        iteration: Iteration = "book",
        form: Form = "joseph",
        outputs: FilterOutputs = None,
        order: int = 1,
    ) -> FilterResult:
        """The extended Kalman filter (Söderström (9.2)-(9.11)).

        h is linearized at x(t|t-1) and f at x(t|t)::

            H(t) = dh/dx at x(t|t-1)       e(t) = y(t) - h(x(t|t-1))      S = H P H' + R
            K    = P H' S^-1               x(t|t) = x(t|t-1) + K e         P(t|t): Joseph form
            F(t) = df/dx at x(t|t)         x(t+1|t) = f(x(t|t))            P(t+1|t) = F P(t|t) F' + Q

        Parameters
        ----------
        y : array_like, shape (T, m), or (T,) when m = 1
            Observations; NaN marks a missing value (the update uses the observed components).
        x0, P0 : array_like
            The prior x(0|-1), P(0|-1).
        u : array_like, shape (T, k), optional
            Inputs, passed to f and h as u[t].
        iterations : int
            Relinearizations of the update per step (0: the EKF).
        iteration : {"book", "gauss-newton"}
            "book" (Söderström (9.12)-(9.17)): the gain is recomputed with H at the last
            estimate, the innovation stays y - h(x(t|t-1)). "gauss-newton" (Bell & Cathey 1993):
            x_(i+1) = x(t|t-1) + K_i (y - h(x_i) - H_i (x(t|t-1) - x_i)), Gauss-Newton steps on
            the MAP criterion; P(t|t) relinearized at the result. S, K and P(t|t) come from the
            last linearization; the innovation and log-likelihood use y - h(x(t|t-1)).
        form : {"joseph", "standard"}
            The covariance update (as the linear filter's).
        outputs : str or iterable of str, optional
            The fields to store (default: all but K_pred, which a nonlinear filter does not have).
        order : {1, 2}
            2: the second-order EKF (Söderström (9.21)-(9.26)): the predicted means get the
            expected quadratic terms, y_hat_k = h_k(x(t|t-1)) + 1/2 tr(P(t|t-1) hess h_k) and
            x(t+1|t)_k = f_k(x(t|t)) + 1/2 tr(P(t|t) hess f_k); the covariances stay the EKF's
            (the book corrects the means only). Not with ``iterations``.

        Returns
        -------
        FilterResult
            With ``model`` None; ``loglik`` is that of the EKF's Gaussian approximation.
        """
        iteration = cast(Iteration, choice("iteration", iteration, ("book", "gauss-newton")))
        form = cast(Form, choice("form", form, ("joseph", "standard")))
        args = self._data(y, x0, P0, u)
        out = self._core.ekf(
            *args[:3], self._outputs(outputs), u=args[3], form=form, iterations=index("iterations", iterations),
            iteration=iteration, order=index("order", order),
        )
        return FilterResult(**out)

    def ukf(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        u: Optional[ArrayLike] = None,
        points: Optional[SigmaPoints] = None,
        outputs: FilterOutputs = None,
        form: UkfForm = "standard",
    ) -> FilterResult:
        """The unscented Kalman filter (Julier & Uhlmann 1997; Wan & van der Merwe 2000).

        At step t the sigma points of (x(t|t-1), P(t|t-1)) go through h::

            y_hat = sum Wm_i h(X_i)        S = sum Wc_i (h(X_i) - y_hat)(.)' + R
            C = sum Wc_i (X_i - x)(h(X_i) - y_hat)'      K = C S^-1
            x(t|t) = x(t|t-1) + K (y - y_hat)            P(t|t) = P(t|t-1) - K S K'

        and the points of (x(t|t), P(t|t)) through f give x(t+1|t) and P(t+1|t) (plus Q). The
        points are drawn afresh at each update (as filterpy 2.0 and Särkkä 2013 do).

        Parameters
        ----------
        points : SigmaPoints, optional
            ``kfast.sigma.merwe(alpha=1e-3, beta=2, kappa=0)`` by default; or ``julier(kappa)``,
            ``cubature()``, ``custom(...)``.
        form : {"standard", "sqrt"}
            ``"standard"``: P(t|t) = P - K S K' (mirrored, exactly symmetric), each covariance
            Cholesky-factored for its points. ``"sqrt"``: the square-root UKF (van der Merwe &
            Wan 2001), which carries the lower factors L of P(t|t-1) and P(t|t) instead and
            never factors a covariance: the time update takes L from a QR decomposition of the
            weighted deviations sqrt(W_i) (f(X_i) - X_0) and Q's factor (a Cholesky downdate for a
            negative weight), the update downdates L by the columns of K S^(1/2). The covariances
            stay positive semidefinite by construction and a singular P0 is accepted; the
            numbers equal the standard form's to rounding. (The Joseph form needs an H; the UKF
            has none, and "sqrt" is its remedy for lost definiteness.)
        y, x0, P0, u, outputs
            As :meth:`ekf`.

        Raises
        ------
        KfastError
            Also when P(t|t-1) or P(t|t) stops being positive definite (the message names the
            step): there are then no sigma points -- use ``form="sqrt"``.
        """
        points = self._points(points)
        args = self._data(y, x0, P0, u)
        form = cast(UkfForm, choice("form", form, ("standard", "sqrt")))
        out = self._core.ukf(*args[:3], self._outputs(outputs), points._spec(), u=args[3], form=form)
        return FilterResult(**out)

    def smooth(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        method: str = "ekf",
        u: Optional[ArrayLike] = None,
        points: Optional[SigmaPoints] = None,
        iterations: int = 0,
        iteration: Iteration = "book",
        form: Optional[Union[Form, UkfForm]] = None,
        order: int = 1,
    ) -> SmootherResult:
        """The extended (``method="ekf"``) or unscented (``"ukf"``) RTS smoother.

        The forward pass is :meth:`ekf` (with ``iterations``, ``iteration``, ``order`` and its
        ``form``, "joseph" by default) or :meth:`ukf` (with ``points`` and its ``form``,
        "standard" by default, or "sqrt"), which also keeps C(t) = Cov(x(t), x(t+1) | y(0..t)):
        P(t|t) F(t)' for the EKF (F at x(t|t)), the sigma points' cross-covariance for the UKF
        (Särkkä 2008). Then, for t = T-2 .. 0::

            J(t)     = C(t) P(t+1|t)^-1
            x(t|T-1) = x(t|t) + J (x(t+1|T-1) - x(t+1|t))
            P(t|T-1) = P(t|t) + J (P(t+1|T-1) - P(t+1|t)) J'

        Returns
        -------
        SmootherResult
            x_smooth, P_smooth, P_lag1 (Cov(x[t], x[t-1] | all data) = P(t|T-1) J(t-1)', zero at
            t = 0) and the forward ``filter`` (all FilterResult fields but K_pred).

        Raises
        ------
        KfastError
            Also when P(t+1|t) is singular (the gain J is then undefined), naming the step.
        """
        method = cast(str, choice("method", method, ("ekf", "ukf")))
        iteration = cast(Iteration, choice("iteration", iteration, ("book", "gauss-newton")))
        chosen = _form(method, form)
        points = self._points(points)
        args = self._data(y, x0, P0, u)
        out = self._core.smooth(
            *args[:3], method, points._spec(), u=args[3], form=chosen, iterations=index("iterations", iterations),
            iteration=iteration, order=index("order", order),
        )
        smoothed = {k: out.pop(k) for k in ("x_smooth", "P_smooth", "P_lag1")}
        return SmootherResult(filter=FilterResult(**out), **smoothed)

    def particle_filter(
        self,
        y: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        n_particles: int,
        resample: Resample = "multinomial",
        ess_threshold: Optional[float] = None,
        seed: int = 0,
        u: Optional[ArrayLike] = None,
        keep: Optional[Keep] = None,
        threads: Optional[int] = None,
        likelihood: Optional[Likelihood] = None,
        regularize: Union[bool, float] = False,
        copies: int = 1,
        move: Optional[ParticleMove] = None,
    ) -> ParticleResult:
        """The particle filter: sequential importance resampling with the model as proposal
        (the bootstrap filter of Söderström (9.89)-(9.100)).

        M = ``n_particles`` particles are drawn from the prior N(x0, P0). At each step t::

            l_i      = log p(y(t) | x_i) = log N(y(t); h(x_i), R)     (observed components)
            loglik_t = log sum_i W_i exp(l_i)                         (W: the carried weights)
            W_i      <- W_i exp(l_i) / exp(loglik_t)                  (9.94), in logs
            x(t|t)   = sum_i W_i x_i,  P(t|t) = sum_i W_i (x_i - x(t|t))(.)'    (9.99)-(9.100)

        then the particles are resampled (every step, or when the effective sample size
        1 / sum W_i^2 falls below ``ess_threshold`` * M; N = M / ``copies`` ancestors, each
        taken by ``copies`` particles), optionally moved by ``regularize`` and ``move``, and
        moved by the model,
        x_i <- f(x_i, t, u) + w_i with w_i ~ N(0, Q) (or g(x_i) w_i, or f(x_i, w_i) with
        ``noise_input``). Angles among the outputs have their residuals wrapped. f and h are
        called once per step for all M particles.

        Parameters
        ----------
        y : array_like, shape (T, m), or (T,) when m = 1
            Observations; NaN marks a missing value (the weights use the observed components; a
            step with nothing observed keeps its weights).
        x0, P0 : array_like
            The prior x(0|-1) ~ N(x0, P0) the particles are drawn from (P0 may be singular).
        n_particles : int
            M, at least 1. Memory: a few arrays of M x n numbers.
        resample : {"multinomial", "systematic", "stratified", "residual"}
            How the ancestors are drawn; every scheme copies particle i M W_i times in
            expectation. "multinomial" is the book's ((9.95)-(9.97)); "systematic" usually has
            the least variance.
        ess_threshold : float in (0, 1], optional
            None (the book): resample after every update. A fraction tau: resample when
            ESS < tau M (0.5 is common).
        seed : int
            The seed of kfast's own generator, 0 <= seed < 2**64: a draw depends only on the
            seed, the step and the particle, so the same seed gives the same numbers.
        u : array_like, shape (T, k), optional
            Inputs, passed to f and h as u[t].
        keep : {None, "last", "all"}
            Also return the particles and their log-weights of the last step or of every step.
        threads : int, optional
            Threads for the particle loops (all cores by default; Python callables, which hold
            the GIL, are called once per step for all particles while the rest of the step runs on
            the threads). The particles are processed in blocks of a fixed size and the blocks'
            sums added in order, so the result is the same bits for any thread count.
        likelihood : kfast.StudentT, kfast.UniformNoise, kfast.Quantized or a function, optional
            None: l_i = log N(y(t); h(x_i), R). ``kfast.StudentT(nu)``: multivariate Student-t
            noise of scale R (heavy tails, robust to outliers). ``kfast.UniformNoise()``: noise
            uniform on +-sqrt(3 R_ii) (R diagonal). ``kfast.Quantized(delta, bounds=None)``: y is
            quantized, y = Q_delta(h(x) + v) (Söderström section 9.6), and l_i is the log
            probability of y's cell (R diagonal; see :func:`kfast.quantized_loglik`).
            A function ``likelihood(X, y, t, u)`` of all the particles X (M, n), y(t) (m,; NaN
            where missing; not called when nothing is observed), the step and the input row,
            returning the M log-likelihoods log p(y(t) | x_i) (-inf for an impossible particle;
            h and R are not used), or a compiled one of ``PARTICLE_C_SIGNATURE`` (numba
            ``@cfunc``, ``scipy.LowLevelCallable``, ctypes), which runs on all threads.
        regularize : bool or float
            False (the book): resampled copies of a particle stay identical until the process
            noise moves them. True, or a factor c > 0: after each resampling every particle moves
            by h L z, z ~ N(0, I), L L' = P(t|t) and Silverman's bandwidth
            h = c (4 / (M (n + 2)))^(1/(n + 4)) (c = 1 for True): the regularized particle filter,
            for small process noise where the copies would otherwise collapse. It widens the
            filtered density by h^2 P(t|t) at each resampling.
        copies : int
            r of the book's filter (Söderström (9.98)): resampling draws N = M / r ancestors and
            each is propagated r times (r particles with independent process noise); M must be
            a multiple of r. 1 (the default) is the standard bootstrap filter.
        move : function, optional
            A move after each resampling (after ``regularize``): ``move(X, y, t, u)`` returns the
            moved particles (M, n), given y(t) of the update just made (all NaN if none). The
            resample-move filter (Gilks & Berzuini 2001): a Metropolis-Hastings step whose
            target is p(x(t) | y(0..t)) -- e.g. proposing x_i + s z_i, accepting by the ratio of
            p(y(t) | x) p(x) -- keeps the filter exact and restores the particles' diversity. Its
            own random numbers are the user's to seed. A compiled one (``PARTICLE_C_SIGNATURE``,
            out the k x n moved particles) is called per block of particles on all threads.

        Returns
        -------
        ParticleResult
            ``x_filt``, ``P_filt``, ``ess``, ``resampled``, ``loglik`` (whose exponential is an
            unbiased estimate of p(y), with adaptive resampling too), ``loglik_t``.

        Raises
        ------
        KfastError
            Bad arguments; f, h or g returning a non-finite value (naming it and the step); no
            particle explaining y(t) (every likelihood 0: more particles or a wider R).
        """
        options = _particle_options(
            n_particles, resample, ess_threshold, seed, threads, likelihood, self.n_obs, regularize, copies, move
        )
        if keep is not None:
            keep = cast(Keep, choice("keep", keep, ("last", "all")))
        args = self._data(y, x0, P0, u)
        out = self._core.particle_filter(*args[:3], keep=keep, u=args[3], **options)
        return ParticleResult(**out)

    def gaussian_sum(self, y: ArrayLike, means: ArrayLike, covs: ArrayLike, weights: Optional[ArrayLike] = None,
                     u: Optional[ArrayLike] = None, **options: Any) -> "IMMResult":
        """The Gaussian-sum filter of this model (Söderström (9.43)-(9.55)) from the prior
        mixture sum_i weights[i] N(means[i], covs[i]): :func:`kfast.gaussian_sum` with this
        model (options ``method``, ``prune``, ``merge``, ... as there; pruning and merging off
        by default)."""
        from kfast.multiple import gaussian_sum

        return gaussian_sum(self, y, means, covs, weights, u, **options)

    def _points(self, points: Optional[SigmaPoints]) -> SigmaPoints:
        points = merwe() if points is None else points
        if not isinstance(points, SigmaPoints):
            raise _kfast.KfastError(f"points: expected a kfast.sigma.SigmaPoints, got {type(points).__name__}")
        return points

    def _outputs(self, outputs: Any) -> list[str]:
        names = _output_names(outputs)
        return list(_FIELDS) if names is None else names

    def _prior(self, x0: ArrayLike, P0: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The prior as float64; scalars (size 1) for a scalar state."""
        x, P = as_float64("x0", x0), as_float64("P0", P0)
        if self.n_states == 1:
            x = x.reshape(1) if x.size == 1 else x
            P = P.reshape(1, 1) if P.size == 1 else P
        return x, P

    def _data(
        self, y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Optional[np.ndarray]]:
        y_arr = _column_if_1d(as_float64("y", y), self.n_obs)
        x, P = self._prior(x0, P0)
        u_arr = None if u is None else as_float64("u", u)
        if u_arr is not None and u_arr.ndim == 1:
            u_arr = u_arr[:, None]
        return y_arr, x, P, u_arr


C_SIGNATURE = "void (const double *X, intptr_t k, intptr_t n, int64_t t, const double *u, double *out)"
"""The C signature of a compiled f or h: the k points X (k x n, row-major), the step t, the input
row u (NULL without inputs, else the model's input width) and the k x m results in out."""

PARTICLE_C_SIGNATURE = (
    "void (const double *X, intptr_t k, intptr_t n, const double *y, intptr_t m, int64_t t, const double *u, double *out)"
)
"""The C signature of a compiled likelihood or move of the particle filter: C_SIGNATURE with
y(t) (m numbers, NaN where missing) after the particles X; out holds k log-likelihoods, or the
k x n moved particles."""

# the argument kinds of the two signatures: "p" a double pointer, "i" a 64-bit integer
_ARG_KINDS = {C_SIGNATURE: "piiipp", PARTICLE_C_SIGNATURE: "piipiipp"}


def _particle_options(
    n_particles: object,
    resample: object,
    ess_threshold: object,
    seed: object,
    threads: object,
    likelihood: object,
    m: int,
    regularize: object,
    copies: object,
    move: object,
) -> dict[str, Any]:
    """The particle filters' options, checked (as keyword arguments of the compiled calls)."""
    n_particles = index("n_particles", n_particles)
    copies = index("copies", copies)
    if copies < 1 or n_particles % copies:
        raise _kfast.KfastError(f"copies: must be at least 1 and divide n_particles = {n_particles}, got {copies}")
    return {
        "regularize": _bandwidth(regularize),
        "likelihood": _user_likelihood(likelihood, m),
        "rejuvenate": None if move is None else _callable("move", move, "a callable move(X, y, t, u)", PARTICLE_C_SIGNATURE),
        "copies": copies,
        "n_particles": n_particles,
        "resample": choice("resample", resample, ("multinomial", "systematic", "stratified", "residual")),
        "ess_threshold": None if ess_threshold is None else _fraction("ess_threshold", ess_threshold),
        "seed": _seed(seed),
        "threads": None if threads is None else index("threads", threads),
    }


def _user_likelihood(likelihood: Any, m: int) -> Optional[tuple]:
    """``likelihood`` as the compiled calls take it: a ready one's spec, or ("user", 0, the
    callable or ("cfunc", address)) for the user's log p(y | x)."""
    if callable(likelihood) or _is_compiled(likelihood):
        return ("user", 0.0, _callable("likelihood", likelihood, "a callable", PARTICLE_C_SIGNATURE))
    return _likelihood_spec(likelihood, m)


def _bandwidth(value: object) -> Optional[float]:
    """``regularize``: False -> None, True -> 1.0, or a factor > 0."""
    if value is False or value is None:
        return None
    if value is True:
        return 1.0
    return positive_real("regularize", value)


def _fraction(name: str, value: object) -> float:
    """A number in (0, 1]."""
    number = real_scalar(name, value, "a number in (0, 1]")
    if not 0 < number <= 1:
        raise _kfast.KfastError(f"{name}: must be in (0, 1], got {value!r}")
    return number


def _seed(seed: object) -> int:
    """An integer 0 <= seed < 2**64."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise _kfast.KfastError(f"seed: expected an integer, got {seed!r}")
    if not 0 <= seed < 2**64:
        raise _kfast.KfastError(f"seed: must be in [0, 2**64), got {seed}")
    return int(seed)


def _spec(name: str, fn: Any) -> Any:
    """What the compiled model takes for f or h: the callable, a built-in's (kind, params), or
    ("cfunc", address) for a compiled function."""
    if isinstance(fn, BuiltinFunction):
        return (fn.kind, fn.params)
    from kfast.linear.model import LinearGaussian

    if isinstance(fn, LinearGaussian):  # its F as f, its H as h: a linear part of a nonlinear model
        part = fn.F if name == "f" else fn.H
        if part.ndim != 2 or fn.B is not None or fn.D is not None:
            raise _kfast.KfastError(f"{name}: a LinearGaussian used as {name} needs a constant {'F' if name == 'f' else 'H'} and no B or D")
        return ("linear", part)
    return _callable(name, fn, f"a callable {name}(X, t, u) or a kfast.models built-in")


def _callable(name: str, fn: Any, expected: str, signature: str = C_SIGNATURE) -> Any:
    """A compiled function as ("cfunc", address) (its signature checked against
    ``signature``), a Python callable as it is."""
    address = _compiled_address(name, fn, signature)
    if address is not None:
        return ("cfunc", address)
    if not callable(fn):
        raise _kfast.KfastError(f"{name}: expected {expected}, got {type(fn).__name__}")
    return fn


def _noise_as_input(f: Any, f_spec: Any, jac_f: Any, hess_f: Any, n: int, g: Any) -> tuple[Any, Any, Any]:
    """f, jac_f and hess_f of ``f(X, W, t, u)`` as functions of the augmented points (x, w),
    which the compiled model passes as one (k, n + r) array; a compiled f takes those rows
    as they are."""
    if g is not None:
        raise _kfast.KfastError("noise_input: a noise gain g and the noise as an input of f exclude each other")
    if isinstance(f_spec, tuple):
        if f_spec[0] == "cfunc":
            return f_spec, jac_f, hess_f
        raise _kfast.KfastError("noise_input: a built-in f has additive noise; write f(X, W, t, u) as a function")

    def split(fn: Any) -> Any:
        if fn is None or isinstance(fn, tuple):  # a compiled derivative takes the rows (x, w)
            return fn
        return lambda Z, t, u: fn(Z[:, :n], Z[:, n:], t, u)

    return split(f), split(jac_f), split(hess_f)


def _form(method: str, form: Optional[str]) -> Any:
    """The covariance form of the filter ``method``: the EKF's "joseph" (default) or "standard",
    the UKF's "standard" (default) or "sqrt"."""
    forms = ("joseph", "standard") if method == "ekf" else ("standard", "sqrt")
    return forms[0] if form is None else cast(str, choice("form", form, forms))


def _derivative(name: str, given: Any) -> Any:
    """A Jacobian or Hessians as the compiled model takes them: a Python callable, or
    ("cfunc", address) for a compiled function of ``C_SIGNATURE`` (its out holding k x m x n,
    or k x m x n x n, numbers)."""
    return None if given is None else _callable(name, given, "a callable or a compiled function")


def _noise_gain(g: Any, n: int, r: int) -> Any:
    """A callable or compiled g as given; a constant G as a read-only (n, r) array."""
    if g is None or callable(g) or _is_compiled(g):
        return g
    G = frozen_copy("g", g)
    if G.shape != (n, r):
        raise _kfast.KfastError(f"g: a constant noise gain must have shape (n, r) = ({n}, {r}) for Q of shape ({r}, {r}), got {G.shape}")
    return G


def _is_compiled(fn: Any) -> bool:
    return type(fn).__name__ == "LowLevelCallable" or hasattr(fn, "address")


def _angles(angles: Sequence[int], m: int) -> tuple[int, ...]:
    out = []
    for a in angles:
        if isinstance(a, bool) or not isinstance(a, (int, np.integer)) or not 0 <= a < m:
            raise _kfast.KfastError(f"angles: expected indices of outputs in [0, {m}), got {a!r}")
        out.append(int(a))
    return tuple(out)


def _compiled_address(name: str, fn: Any, signature: str = C_SIGNATURE) -> Optional[int]:
    """The address of a compiled function -- a numba ``@cfunc``, a ``scipy.LowLevelCallable`` or
    a ctypes function pointer -- after checking its declared signature against ``signature``
    (C_SIGNATURE or PARTICLE_C_SIGNATURE); None for anything else (a Python callable)."""
    import ctypes

    kinds = _ARG_KINDS[signature]
    if type(fn).__name__ == "LowLevelCallable" and hasattr(fn, "signature"):
        sig = " ".join(str(fn.signature).replace("const ", "").split())
        pattern = ", ".join(r"double \*" if k == "p" else _INT64 for k in kinds)
        if not re.fullmatch(rf"void \({pattern}\)", sig):
            raise _kfast.KfastError(f"{name}: the LowLevelCallable's signature {fn.signature!r} is not {signature!r}")
        get_name = ctypes.pythonapi.PyCapsule_GetName
        get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
        get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
        get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
        capsule = tuple.__getitem__(fn, 0)  # a LowLevelCallable is (capsule, function, user_data)
        return int(get_pointer(capsule, get_name(capsule)))
    cfn = getattr(fn, "ctypes", None) if hasattr(fn, "address") else fn  # numba's cfunc, or ctypes
    if not isinstance(cfn, ctypes._CFuncPtr):  # type: ignore[attr-defined]
        return None
    double_p = ctypes.POINTER(ctypes.c_double)
    args = list(getattr(cfn, "argtypes", None) or [])

    def int64(t: Any) -> bool:
        return isinstance(t, type) and issubclass(t, ctypes._SimpleCData) and ctypes.sizeof(t) == 8 and t._type_ in "lq"  # type: ignore[attr-defined]

    ok = (
        cfn.restype is None
        and len(args) == len(kinds)
        and all(arg is double_p if kind == "p" else int64(arg) for arg, kind in zip(args, kinds))
    )
    if not ok:
        got = ", ".join(getattr(a, "__name__", str(a)) for a in args)
        raise _kfast.KfastError(f"{name}: the compiled function's signature ({got}) -> {cfn.restype} is not {signature!r}")
    return int(ctypes.cast(cfn, ctypes.c_void_p).value or 0)


_INT64 = "(?:long|long long|int64_t|intptr_t|ssize_t|Py_ssize_t)"
