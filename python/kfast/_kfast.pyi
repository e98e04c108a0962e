"""Type stubs for the compiled module kfast._kfast (rust/src/python)."""

from typing import Any, Optional, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kfast.linear.model import LinearGaussian as _Model
from kfast._typing import DareMethod, Form, Iteration, Keep, Resample, UkfForm, UpdateForm

# The functions and the compiled model's methods take C-contiguous float64 arrays (the
# package converts array-likes first); the streaming objects take array-likes themselves.

__version__: str
# The filter's outputs: (name, shape in "T", "n", "m"), in FilterResult's order.
FILTER_FIELDS: list[tuple[str, list[str]]]
"""Cargo.toml's version, compiled in."""

class KfastError(ValueError):
    """Invalid input to kfast (a ValueError): the message names the argument, step and problem."""

class InnovationCovarianceError(KfastError):
    """The innovation covariance S = H P H' + R at some step cannot be factorized."""

class NoStabilizingSolutionError(KfastError):
    """A Riccati equation has no stabilizing solution."""


# a quantizing sensor: (delta, low, high)
Quantizer = tuple[NDArray[np.float64], Optional[NDArray[np.float64]], Optional[NDArray[np.float64]]]
# the particle filter's likelihood: (kind, nu, quantizer or the user's function)
LikelihoodSpec = tuple[str, float, Optional[Any]]
PointsSpec = tuple[str, float, float, float, Optional[NDArray[np.float64]], Optional[NDArray[np.float64]], Optional[NDArray[np.float64]]]
"""kfast.sigma.SigmaPoints._spec(): kind, alpha, beta, kappa and a custom set's unit points, Wm, Wc."""

def solve_discrete_lyapunov(a: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]: ...
def solve_continuous_lyapunov(a: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]: ...
def stationary_covariance(F: NDArray[np.float64], Q: NDArray[np.float64]) -> NDArray[np.float64]: ...
def dare(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    q: NDArray[np.float64],
    r: NDArray[np.float64],
    e: Optional[NDArray[np.float64]] = None,
    s: Optional[NDArray[np.float64]] = None,
    method: DareMethod = "doubling",
    eigenvalues: bool = True,
) -> dict[str, Any]: ...
def care(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    q: NDArray[np.float64],
    r: NDArray[np.float64],
    e: Optional[NDArray[np.float64]] = None,
    s: Optional[NDArray[np.float64]] = None,
) -> dict[str, Any]: ...
def lqr(
    F: NDArray[np.float64],
    G: NDArray[np.float64],
    Q1: NDArray[np.float64],
    Q2: NDArray[np.float64],
    Q12: Optional[NDArray[np.float64]] = None,
    method: str = "doubling",
    eigenvalues: bool = False,
) -> dict[str, Any]: ...
def lq_finite(
    F: NDArray[np.float64],
    G: NDArray[np.float64],
    Q0: NDArray[np.float64],
    Q1: NDArray[np.float64],
    Q2: NDArray[np.float64],
    N: int,
    Q12: Optional[NDArray[np.float64]] = None,
) -> dict[str, NDArray[np.float64]]: ...
def eigenvalues(a: NDArray[np.float64]) -> NDArray[np.complex128]: ...
def poly_roots(p: NDArray[np.float64]) -> NDArray[np.complex128]: ...
def spectral_factor_roots(r: NDArray[np.float64]) -> tuple[list[float], float, bool]: ...
def diophantine(A: NDArray[np.float64], B: NDArray[np.float64], C: NDArray[np.float64]) -> tuple[list[float], list[float], float]: ...
def predictor_identity(A: NDArray[np.float64], C: NDArray[np.float64], k: int) -> tuple[list[float], list[float]]: ...
def levinson(r: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[list[float], list[float]]: ...

def expm(a: NDArray[np.float64]) -> NDArray[np.float64]: ...
def innovation_diagnostics(
    innov: NDArray[np.float64], S: NDArray[np.float64], lags: int, burn: int, alpha: float
) -> dict[str, Any]: ...
def state_diagnostics(
    x_true: NDArray[np.float64], x_filt: NDArray[np.float64], P_filt: NDArray[np.float64], burn: int, alpha: float
) -> dict[str, Any]: ...
def chi_square(value: float, k: float, quantile: bool) -> float: ...
def check_alloc(arg: str, shapes: list[list[int]]) -> None: ...
def kernel_info() -> dict[str, str | bool]: ...
def set_deterministic(on: bool) -> bool: ...
def deterministic() -> bool: ...
def _force_kernel(name: Optional[str]) -> None: ...
def filter_batch(
    model: LinearGaussian,
    Y: NDArray[np.float64],
    x0: NDArray[np.float64],
    P0: NDArray[np.float64],
    u: Optional[NDArray[np.float64]] = None,
    return_covs: bool = True,
    threads: Optional[int] = None,
    form: UpdateForm = "joseph",
) -> dict[str, Any]: ...
def discretize(
    A: NDArray[np.float64], Qc: NDArray[np.float64], dt: NDArray[np.float64], B: Optional[NDArray[np.float64]] = None
) -> dict[str, NDArray[np.float64]]: ...

class LinearGaussian:
    """The compiled model; use kfast.LinearGaussian, which converts and keeps the arrays."""

    def __init__(
        self,
        F: NDArray[np.float64],
        H: NDArray[np.float64],
        Q: NDArray[np.float64],
        R: NDArray[np.float64],
        B: Optional[NDArray[np.float64]] = None,
        D: Optional[NDArray[np.float64]] = None,
        N: Optional[NDArray[np.float64]] = None,
    ) -> None: ...
    @property
    def n_states(self) -> int: ...
    @property
    def n_obs(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def steps(self) -> Optional[int]: ...
    def filter(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        u: Optional[NDArray[np.float64]] = None,
        form: UpdateForm = "joseph",
        converge_tol: Optional[float] = None,
        outputs: Optional[Sequence[str]] = None,
    ) -> dict[str, Any]: ...
    def filter_diffuse(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        P0_inf: NDArray[np.float64],
        u: Optional[NDArray[np.float64]] = None,
        form: UpdateForm = "joseph",
        converge_tol: Optional[float] = None,
        outputs: Optional[Sequence[str]] = None,
    ) -> dict[str, Any]: ...
    def loglik(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        u: Optional[NDArray[np.float64]] = None,
        form: UpdateForm = "joseph",
        converge_tol: Optional[float] = None,
    ) -> float: ...

    def smooth(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        u: Optional[NDArray[np.float64]] = None,
        form: UpdateForm = "joseph",
        outputs: Optional[Sequence[str]] = None,
    ) -> dict[str, Any]: ...
    def smooth_fixed_lag(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        lag: int,
        u: Optional[NDArray[np.float64]] = None,
        form: Form = "joseph",
    ) -> dict[str, NDArray[np.float64]]: ...
    def smooth_fixed_point(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        t_point: int,
        u: Optional[NDArray[np.float64]] = None,
        form: Form = "joseph",
    ) -> dict[str, NDArray[np.float64]]: ...
    def forecast(
        self,
        x: NDArray[np.float64],
        P: NDArray[np.float64],
        steps: int,
        u: Optional[NDArray[np.float64]] = None,
    ) -> dict[str, NDArray[np.float64]]: ...
    def check_prior(self, x0: NDArray[np.float64], P0: NDArray[np.float64]) -> None: ...
    def propagate(
        self,
        x_init: NDArray[np.float64],
        w: NDArray[np.float64],
        v: NDArray[np.float64],
        u: Optional[NDArray[np.float64]] = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...

class NonlinearModel:
    """The compiled nonlinear model: f and h as Python callables f(X, t, u) over a batch X of
    shape (k, n), or built-ins given as (kind, params); kfast.NonlinearModel wraps it."""

    def __init__(
        self,
        f: Any,
        h: Any,
        Q: NDArray[np.float64],
        R: NDArray[np.float64],
        n: int,
        m: int,
        angles: list[int],
        jac_f: Optional[Any] = None,
        jac_h: Optional[Any] = None,
        hess_f: Optional[Any] = None,
        hess_h: Optional[Any] = None,
        g: Optional[Any] = None,
        noise_input: bool = False,
    ) -> None: ...
    def ekf(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        outputs: list[str],
        u: Optional[NDArray[np.float64]] = None,
        form: Form = "joseph",
        iterations: int = 0,
        iteration: Iteration = "book",
        order: int = 1,
    ) -> dict[str, Any]: ...
    def particle_filter(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        n_particles: int,
        resample: Resample = "multinomial",
        ess_threshold: Optional[float] = None,
        seed: int = 0,
        keep: Optional[Keep] = None,
        u: Optional[NDArray[np.float64]] = None,
        threads: Optional[int] = None,
        likelihood: Optional[LikelihoodSpec] = None,
        regularize: Optional[float] = None,
        copies: int = 1,
        rejuvenate: Optional[Any] = None,
    ) -> dict[str, Any]: ...
    def ukf(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        outputs: list[str],
        points: PointsSpec,
        u: Optional[NDArray[np.float64]] = None,
        form: UkfForm = "standard",
    ) -> dict[str, Any]: ...
    def smooth(
        self,
        y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        method: str,
        points: PointsSpec,
        u: Optional[NDArray[np.float64]] = None,
        form: Union[Form, UkfForm] = "joseph",
        iterations: int = 0,
        iteration: Iteration = "book",
        order: int = 1,
    ) -> dict[str, Any]: ...
    def batch(
        self,
        Y: NDArray[np.float64],
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        method: str,
        points: PointsSpec,
        u: Optional[NDArray[np.float64]] = None,
        return_covs: bool = True,
        threads: Optional[int] = None,
        form: Union[Form, UkfForm] = "joseph",
        iterations: int = 0,
        iteration: Iteration = "book",
        order: int = 1,
    ) -> dict[str, Any]: ...

class NonlinearKalmanFilter:
    """The streaming EKF (method "ekf") or UKF ("ukf") of a compiled NonlinearModel;
    kfast.ExtendedKalmanFilter and kfast.UnscentedKalmanFilter wrap it."""

    def __init__(
        self,
        model: NonlinearModel,
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        method: str,
        points: PointsSpec,
        form: Union[Form, UkfForm] = "joseph",
        iterations: int = 0,
        iteration: Iteration = "book",
        order: int = 1,
    ) -> None: ...
    def update(
        self,
        y: NDArray[np.float64],
        u: Optional[NDArray[np.float64]] = None,
        h: Any = None,
        R: Optional[NDArray[np.float64]] = None,
        angles: Optional[list[int]] = None,
    ) -> None: ...
    def predict(self, u: Optional[NDArray[np.float64]] = None) -> None: ...
    @property
    def x(self) -> NDArray[np.float64]: ...
    @property
    def P(self) -> NDArray[np.float64]: ...
    @property
    def t(self) -> int: ...
    @property
    def loglik(self) -> float: ...

class KalmanFilter:
    """Streaming Kalman filter from the prior (x0, P0) = x(0|-1), P(0|-1).

    After update at step t, x and P are x(t|t), P(t|t); after predict they are x(t+1|t),
    P(t+1|t). A predict without an update treats the step as missing.
    """

    def __init__(self, model: Union[_Model, LinearGaussian], x0: ArrayLike, P0: ArrayLike, form: UpdateForm = "joseph") -> None: ...
    def update(
        self, y: ArrayLike, u: Optional[ArrayLike] = None, *, H: Optional[ArrayLike] = None, R: Optional[ArrayLike] = None
    ) -> None: ...
    def predict(self, u: Optional[ArrayLike] = None) -> None: ...
    def step(
        self, y: ArrayLike, u: Optional[ArrayLike] = None, *, H: Optional[ArrayLike] = None, R: Optional[ArrayLike] = None
    ) -> None: ...
    @property
    def x(self) -> NDArray[np.float64]: ...
    @property
    def P(self) -> NDArray[np.float64]: ...
    @property
    def t(self) -> int: ...
    @property
    def loglik(self) -> float: ...

class FixedLagSmoother:
    """Online fixed-lag smoother from the prior (x0, P0) = x(0|-1), P(0|-1).

    After update at step t: x_lagged, P_lagged are x(t-lag|t), P(t-lag|t) (None while
    t < lag); x_window, P_window hold x(t-i|t) for i = 0..min(t, lag).
    """

    def __init__(
        self, model: Union[_Model, LinearGaussian], x0: ArrayLike, P0: ArrayLike, lag: int, form: Form = "joseph"
    ) -> None: ...
    def update(self, y: ArrayLike, u: Optional[ArrayLike] = None) -> None: ...
    def predict(self, u: Optional[ArrayLike] = None) -> None: ...
    def step(self, y: ArrayLike, u: Optional[ArrayLike] = None) -> None: ...
    @property
    def lag(self) -> int: ...
    @property
    def t(self) -> int: ...
    @property
    def x_lagged(self) -> Optional[NDArray[np.float64]]: ...
    @property
    def P_lagged(self) -> Optional[NDArray[np.float64]]: ...
    @property
    def x_window(self) -> NDArray[np.float64]: ...
    @property
    def P_window(self) -> NDArray[np.float64]: ...

class ParticleFilter:
    """The streaming particle filter; kfast.ParticleFilter wraps it."""

    def __init__(
        self,
        model: NonlinearModel,
        x0: NDArray[np.float64],
        P0: NDArray[np.float64],
        n_particles: int,
        resample: Resample = "multinomial",
        ess_threshold: Optional[float] = None,
        seed: int = 0,
        threads: Optional[int] = None,
        likelihood: Optional[LikelihoodSpec] = None,
        regularize: Optional[float] = None,
        copies: int = 1,
        rejuvenate: Optional[Any] = None,
    ) -> None: ...
    def update(self, y: NDArray[np.float64], u: Optional[NDArray[np.float64]] = None) -> float: ...
    def predict(self, u: Optional[NDArray[np.float64]] = None) -> bool: ...
    @property
    def x(self) -> NDArray[np.float64]: ...
    @property
    def P(self) -> NDArray[np.float64]: ...
    @property
    def particles(self) -> NDArray[np.float64]: ...
    @property
    def log_weights(self) -> NDArray[np.float64]: ...
    @property
    def ess(self) -> float: ...
    @property
    def t(self) -> int: ...
    @property
    def loglik(self) -> float: ...

class MultipleModelFilter:
    """The IMM filter, the fixed bank and the Gaussian-sum filter over streaming mode filters;
    kfast.IMMFilter, imm_filter, model_bank and gaussian_sum wrap it."""

    def __init__(
        self,
        filters: list[Any],
        mode_probs: list[float],
        transition: Optional[NDArray[np.float64]] = None,
        state_maps: list[tuple[int, int, NDArray[np.float64], Optional[NDArray[np.float64]], Optional[NDArray[np.float64]]]] = ...,
        prune: float = 0.0,
        merge: float = 0.0,
    ) -> None: ...
    def update(self, y: NDArray[np.float64], u: list[Optional[NDArray[np.float64]]]) -> None: ...
    def predict(self, u: list[Optional[NDArray[np.float64]]]) -> None: ...
    def combined(self) -> Optional[tuple[NDArray[np.float64], NDArray[np.float64]]]: ...
    def mode_estimate(self, j: int) -> Optional[tuple[NDArray[np.float64], NDArray[np.float64]]]: ...
    def filter(
        self, y: NDArray[np.float64], u: list[Optional[NDArray[np.float64]]], outputs: list[str]
    ) -> dict[str, Any]: ...
    @property
    def mode_probs(self) -> NDArray[np.float64]: ...
    @property
    def t(self) -> int: ...
    @property
    def loglik(self) -> float: ...
    @property
    def n_modes(self) -> int: ...

def median_filter(u: NDArray[np.float64], n: int, mode: str) -> NDArray[np.float64]: ...
def mean_filter(u: NDArray[np.float64], n: int, mode: str) -> NDArray[np.float64]: ...
def quantize(x: NDArray[np.float64], delta: NDArray[np.float64]) -> NDArray[np.float64]: ...
def quantized_loglik(
    y: NDArray[np.float64],
    y_hat: NDArray[np.float64],
    std: NDArray[np.float64],
    delta: NDArray[np.float64],
    low: Optional[NDArray[np.float64]] = None,
    high: Optional[NDArray[np.float64]] = None,
) -> NDArray[np.float64]: ...
def quantized_moments(delta: float, mean: float, std: float, distribution: str) -> tuple[float, float, float]: ...
