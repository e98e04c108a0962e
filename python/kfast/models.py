"""Catalogue of stochastic-process models as ready-made ``kfast.LinearGaussian`` models
(docs/algorithms.md, "Model catalogue"; Grewal & Andrews ch. 4; Söderström Sec. 4.4; Gimel'farb; Mortensen).

Conventions used throughout (docs/conventions.md; docs/algorithms.md, "Model catalogue"):

* ``q`` is a continuous white-noise *intensity* (covariance q δ(τ)), ``sigma2`` a variance,
  ``dt`` = h the sampling interval. Continuous models dx = A x dt + dβ, E[dβ dβ'] = Qc dt are
  sampled *exactly*: F = e^{Ah}, Qd = ∫_0^h e^{As} Qc e^{A's} ds (closed forms where they are
  short, otherwise ``kfast.discretize``, Van Loan in Rust). Never Qd ≈ Qc h.
* ``r`` is the *discrete* measurement-noise variance (a scalar gives R = r I, a matrix is used
  as R). R = 0 is accepted: kfast filters as long as H P H' + R > 0.
* Autocovariance: ψ(τ) = E[y(t+τ) y(t)] of the noise-free output H x (lag on the first
  factor). The sampled output y[k] = H x[k] + v[k] has r_y(k) = ψ(k h) + r δ_k; the
  ``*_autocovariance`` functions return ψ(lag) + r·[lag == 0] (r defaults to 0) with ``lag``
  in the same time unit as dt (pass k * dt for sample lags).
* PSDs are two-sided in rad/s: Φ(ω) = ∫ ψ(τ) e^{−iωτ} dτ, ψ(τ) = (1/2π) ∫ Φ(ω) e^{iωτ} dω.
  Discrete-time (AR) spectra: φ(e^{iω}) = Σ_k r(k) e^{−iωk}, no 1/2π, inverse with 1/2π.
* Multi-axis models (``dim`` > 1) order the state *derivative-major*:
  [positions (axis 0..dim−1), velocities (...), accelerations (...)], i.e. state index
  ``order * dim + axis``. Per-axis matrices M give the full ones as kron(M, I_dim).
  ``observe`` selects the measured derivative orders (0 = position, 1 = velocity,
  2 = acceleration; an int or a sequence), each for every axis, in that order.

Errors: a bad parameter raises ``kfast.KfastError`` (a ValueError) naming the argument.

For coloured process or measurement noise, append a shaping filter with ``augment`` (discrete
models) or, better for continuous models, ``augment_continuous`` on the continuous forms from
``continuous(...)`` followed by ``Continuous.discretize`` (joint Van Loan discretization keeps
the plant/shaping cross terms of Qd that discretizing the pieces separately loses).
"""

from __future__ import annotations

import math
from typing import Callable, Dict, NamedTuple, Optional, Sequence, Union

import numpy as np

from kfast import _kfast
from kfast._args import index
from kfast._arrays import as_float64, finite_vector
from kfast._numbers import integer_lags, powers_applied
from kfast.linear.model import LinearGaussian
from kfast.nonlinear.model import BuiltinFunction
from kfast.sampling import discretize
from kfast.structural import arma, combine, cycle, local_level, local_linear_trend, seasonal, smooth_trend

__all__ = [
    "coordinated_turn",
    "range_bearing",
    "bearings_only",
    "range_bearing_elevation",
    "ungm",
    "random_constant",
    "random_walk",
    "random_ramp",
    "constant_velocity",
    "constant_acceleration",
    "gauss_markov_1",
    "gauss_markov_2",
    "damped_resonator",
    "singer",
    "ar",
    "local_level",
    "local_linear_trend",
    "smooth_trend",
    "seasonal",
    "cycle",
    "arma",
    "combine",
    "augment",
    "Continuous",
    "continuous",
    "augment_continuous",
    "gauss_markov_1_autocovariance",
    "gauss_markov_2_autocovariance",
    "damped_resonator_autocovariance",
    "singer_autocovariance",
    "ar_autocovariance",
]

KfastError = _kfast.KfastError
Observe = Union[int, Sequence[int]]


# --------------------------------------------------------------------------------------------
# argument checks


def _real(name: str, value) -> float:
    if isinstance(value, (bool, np.bool_)):
        raise KfastError(f"{name}: expected a real number, got {value!r}")
    arr = as_float64(name, value)
    if arr.ndim != 0 and arr.size != 1:
        raise KfastError(f"{name}: expected a scalar, got shape {arr.shape}")
    x = float(arr.reshape(()))
    if not math.isfinite(x):
        raise KfastError(f"{name}: must be finite, got {x}")
    return x


def _positive(name: str, value) -> float:
    x = _real(name, value)
    if not x > 0:
        raise KfastError(f"{name}: must be > 0, got {x}")
    return x


def _nonneg(name: str, value) -> float:
    x = _real(name, value)
    if x < 0:
        raise KfastError(f"{name}: must be >= 0 (a variance or intensity), got {x}")
    return x


def _dim(dim, orders: int) -> int:
    """The number of axes: an integer >= 1 such that the model's matrices (``orders * dim``
    states) fit in memory."""
    d = index("dim", dim)
    if d < 1:
        raise KfastError(f"dim: expected an integer >= 1, got {dim!r}")
    n = orders * d
    if n >= 2**32:  # n * n elements would overflow 64 bits
        raise KfastError(f"dim: is too large ({d}): the model's {n} x {n} matrices would not fit in memory")
    # F, Q, H, R (n x n at most) with their working copies (kron, the rows of H selected from
    # I_n, LinearGaussian's and the core's copies), and I_dim
    _kfast.check_alloc("dim", [[n, n]] * 12 + [[d, d]] * 2)
    return d


def _require_finite(names: str, what: str, *values) -> None:
    """Refuse a model quantity that overflowed (inf or NaN computed from finite parameters),
    naming the parameters it comes from (not F or Q, which the user did not pass)."""
    if not all(np.all(np.isfinite(v)) for v in values):
        raise KfastError(f"{names}: {what} is out of the range of double precision (overflow)")


def _evaluate(names: str, what: str, compute: Callable[[], tuple]) -> tuple:
    """``compute()`` (a tuple of numbers or arrays), refused naming ``names`` when it
    overflows: Python floats raise OverflowError (x ** 3) or ZeroDivisionError (1 / 1e-300**2)
    where NumPy gives inf."""
    try:
        values = compute()
    except (OverflowError, ZeroDivisionError):
        raise KfastError(f"{names}: {what} is out of the range of double precision (overflow)") from None
    _require_finite(names, what, *values)
    return values


def _discretize_checked(A: np.ndarray, Qc: np.ndarray, h, names: str):
    """``discretize(A, Qc, h)`` (F, Qd); when the interval is too long for the rates (the
    sampled model overflows or cannot be resolved), the error names the model's parameters
    ``names`` instead of A, Qc and dt, which the user did not pass."""
    try:
        F, Qd, _ = discretize(A, Qc, h)
    except KfastError as exc:
        raise KfastError(f"{names}: {str(exc).split(': ', 1)[-1]}") from None
    return F, Qd


def _per_axis(name: str, value, dim: int) -> np.ndarray:
    """A nonnegative scalar or one value per axis, as an array of length dim."""
    arr = as_float64(name, value)
    if arr.ndim == 0:
        arr = np.full(dim, float(arr))
    if arr.shape != (dim,):
        raise KfastError(f"{name}: expected a scalar or {dim} values (one per axis), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise KfastError(f"{name}: must be finite, got {arr}")
    if np.any(arr < 0):
        raise KfastError(f"{name}: must be >= 0 (a variance or intensity), got {arr}")
    return arr


def _observe(observe: Observe, orders: int) -> tuple:
    items: tuple
    try:
        if isinstance(observe, (int, np.integer)) and not isinstance(observe, bool):
            items = (observe,)
        else:
            items = tuple(observe)  # type: ignore[arg-type]
    except TypeError:
        raise KfastError(f"observe: expected an int or a sequence of ints, got {observe!r}") from None
    if not items:
        raise KfastError("observe: selects no component")
    for o in items:
        if isinstance(o, (bool, np.bool_)) or not isinstance(o, (int, np.integer)) or not 0 <= o < orders:
            raise KfastError(f"observe: components are derivative orders 0..{orders - 1}, got {observe!r}")
    if len(set(items)) != len(items):
        raise KfastError(f"observe: repeated component in {observe!r}")
    return tuple(int(o) for o in items)


def _H(observe: tuple, orders: int, dim: int) -> np.ndarray:
    rows = [order * dim + axis for order in observe for axis in range(dim)]
    return np.eye(orders * dim)[rows]


def _R(r, m: int) -> np.ndarray:
    arr = as_float64("r", r)
    if arr.ndim == 0 or arr.size == 1 and m == 1:
        return np.eye(m) * _nonneg("r", arr)
    if arr.shape != (m, m):
        raise KfastError(f"r: expected a variance or an ({m}, {m}) covariance matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise KfastError("r: must be finite")
    return arr  # LinearGaussian checks symmetry and positive semidefiniteness


def _kron_axes(M: np.ndarray, dim: int, scale: Optional[np.ndarray] = None) -> np.ndarray:
    return np.kron(M, np.eye(dim) if scale is None else np.diag(scale))


# --------------------------------------------------------------------------------------------
# continuous forms


class Continuous(NamedTuple):
    """A continuous-time model dx = A x dt + dβ, E[dβ dβ'] = Qc dt (Qc an intensity), output
    H x sampled with white discrete noise added at ``discretize``."""

    A: np.ndarray
    Qc: np.ndarray
    H: np.ndarray

    def discretize(self, dt, r=1.0) -> LinearGaussian:
        """The exact discrete model (Van Loan): F = e^{A dt}, Qd = ∫_0^dt e^{As} Qc e^{A's} ds,
        with R = r I (or the matrix r). ``dt`` may be an array of intervals (per-step model)."""
        if np.ndim(dt) == 0:
            dt = _positive("dt", dt)
        F, Qd, _ = discretize(self.A, self.Qc, dt)  # refuses, naming dt, what would overflow
        return LinearGaussian(F, self.H, Qd, _R(r, self.H.shape[0]))


def _cont_random_constant() -> Continuous:
    return Continuous(np.zeros((1, 1)), np.zeros((1, 1)), np.ones((1, 1)))


def _cont_random_walk(q) -> Continuous:
    return Continuous(np.zeros((1, 1)), np.full((1, 1), _nonneg("q", q)), np.ones((1, 1)))


def _cont_random_ramp(observe=0) -> Continuous:
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    return Continuous(A, np.zeros((2, 2)), _H(_observe(observe, 2), 2, 1))


def _cont_polynomial(order: int, dim, q, observe) -> Continuous:
    dim = _dim(dim, order)
    qa = _per_axis("q", q, dim)
    obs = _observe(observe, order)
    A1 = np.eye(order, k=1)
    G = np.zeros((order, order))
    G[-1, -1] = 1.0
    return Continuous(_kron_axes(A1, dim), _kron_axes(G, dim, qa), _H(obs, order, dim))


def _cont_gauss_markov_1(sigma2, beta) -> Continuous:
    s2, b = _nonneg("sigma2", sigma2), _positive("beta", beta)
    _require_finite("sigma2, beta", f"the intensity 2 sigma2 beta = 2 * {s2:g} * {b:g}", 2 * s2 * b)
    return Continuous(np.full((1, 1), -b), np.full((1, 1), 2 * s2 * b), np.ones((1, 1)))


def _cont_gauss_markov_2(omega_n, zeta, q, observe=0) -> Continuous:
    wn, z, qq = _positive("omega_n", omega_n), _positive("zeta", zeta), _nonneg("q", q)
    _require_finite("omega_n", f"omega_n^2 = {wn:g}^2", wn * wn)
    _require_finite("zeta, omega_n", f"2 zeta omega_n = 2 * {z:g} * {wn:g}", 2 * z * wn)
    A = np.array([[0.0, 1.0], [-wn * wn, -2 * z * wn]])
    return Continuous(A, np.diag([0.0, qq]), _H(_observe(observe, 2), 2, 1))


def _cont_damped_resonator(omega, tau, q, observe=0) -> Continuous:
    w, t, qq = _positive("omega", omega), _positive("tau", tau), _nonneg("q", q)
    return Continuous(_resonator_A(w, t), np.diag([0.0, qq]), _H(_observe(observe, 2), 2, 1))


def _resonator_A(w: float, t: float) -> np.ndarray:
    """A = [[0, 1], [-(ω² + 1/τ²), -2/τ]], refused naming omega or tau when it overflows."""
    _require_finite("omega", f"omega^2 = {w:g}^2", w * w)
    _evaluate("tau", f"1/tau^2 = 1/{t:g}^2", lambda: (1 / (t * t),))
    _require_finite("omega, tau", f"omega^2 + 1/tau^2 (omega = {w:g}, tau = {t:g})", w * w + 1 / (t * t))
    return np.array([[0.0, 1.0], [-(w * w + 1 / (t * t)), -2 / t]])


def _singer_axis(alpha, sigma_m2):
    a, s2 = _positive("alpha", alpha), _nonneg("sigma_m2", sigma_m2)
    _require_finite("sigma_m2, alpha", f"the intensity 2 alpha sigma_m2 = 2 * {a:g} * {s2:g}", 2 * a * s2)
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -a]])
    return A, np.diag([0.0, 0.0, 2 * a * s2])


def _cont_singer(alpha, sigma_m2, dim=1, observe=0) -> Continuous:
    dim = _dim(dim, 3)
    A, Qc = _singer_axis(alpha, sigma_m2)
    return Continuous(_kron_axes(A, dim), _kron_axes(Qc, dim), _H(_observe(observe, 3), 3, dim))


_CONTINUOUS: Dict[str, Callable[..., Continuous]] = {
    "random_constant": _cont_random_constant,
    "random_walk": _cont_random_walk,
    "random_ramp": _cont_random_ramp,
    "constant_velocity": lambda dim=1, q=1.0, observe=0: _cont_polynomial(2, dim, q, observe),
    "constant_acceleration": lambda dim=1, q=1.0, observe=0: _cont_polynomial(3, dim, q, observe),
    "gauss_markov_1": _cont_gauss_markov_1,
    "gauss_markov_2": _cont_gauss_markov_2,
    "damped_resonator": _cont_damped_resonator,
    "singer": _cont_singer,
}


def continuous(kind: str, **params) -> Continuous:
    """The continuous form (A, Qc, H) of a catalogue model, with the builder's parameters
    except ``dt`` and ``r``: e.g. ``continuous("gauss_markov_1", sigma2=1.0, beta=0.5)``,
    ``continuous("constant_velocity", dim=2, q=1.0)``. Kinds: random_constant, random_walk,
    random_ramp, constant_velocity, constant_acceleration, gauss_markov_1, gauss_markov_2,
    damped_resonator, singer. ``continuous(kind, **p).discretize(dt, r)`` equals the builder's
    model (which may use a closed form instead of Van Loan)."""
    if kind not in _CONTINUOUS:
        raise KfastError(f"kind: expected one of {sorted(_CONTINUOUS)}, got {kind!r}")
    try:
        return _CONTINUOUS[kind](**params)
    except TypeError as exc:
        raise KfastError(f"params: {exc}") from None


def augment_continuous(plant: Continuous, shaping: Continuous, where: str, gamma=None) -> Continuous:
    """Append a continuous shaping filter dx_s = A_s x_s dt + dβ_s (output H_s x_s) for coloured
    noise (G&A Sec. 4.5, (4.77); docs/algorithms.md, "Shaping filters"):

    * ``where="process"``: the shaping output drives the plant through ``gamma`` (n × m_s;
      default I when n = m_s): A_a = [[A, Γ H_s], [0, A_s]], Qc_a = blockdiag(Qc, Qc_s),
      H_a = [H, 0]. Qc is the plant's remaining *white* intensity (build the plant with q = 0
      when the coloured noise replaces it).
    * ``where="measurement"``: the shaping output adds to the measurement: A_a = blockdiag(A, A_s),
      Qc_a = blockdiag(Qc, Qc_s), H_a = [H, H_s]; the white part R is given to ``discretize``
      (R = 0 is allowed).

    Call ``.discretize(dt, r)`` on the result: the *joint* exact discretization. For coloured
    process noise its Qd has plant/shaping cross terms that discretizing the plant and the
    shaping filter separately (then ``augment``) loses.
    """
    A, Qc, H = (np.asarray(m, dtype=float) for m in plant)
    As, Qcs, Hs = (np.asarray(m, dtype=float) for m in shaping)
    n, ns, m = A.shape[0], As.shape[0], H.shape[0]
    if where == "process":
        G = _gamma(gamma, n, Hs.shape[0])
        Aa = np.block([[A, G @ Hs], [np.zeros((ns, n)), As]])
        Ha = np.hstack([H, np.zeros((m, ns))])
    elif where == "measurement":
        if Hs.shape[0] != m:
            raise KfastError(f"shaping: its output has {Hs.shape[0]} components, the plant's {m}")
        Aa = _blockdiag(A, As)
        Ha = np.hstack([H, Hs])
    else:
        raise KfastError(f"where: expected 'process' or 'measurement', got {where!r}")
    return Continuous(Aa, _blockdiag(Qc, Qcs), Ha)


def _blockdiag(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros((a.shape[0] + b.shape[0], a.shape[1] + b.shape[1]))
    out[: a.shape[0], : a.shape[1]] = a
    out[a.shape[0] :, a.shape[1] :] = b
    return out


def _gamma(gamma, n: int, ms: int) -> np.ndarray:
    if gamma is None:
        if n != ms:
            raise KfastError(f"gamma: required (an {n} x {ms} matrix) when the state ({n}) and the shaping output ({ms}) differ in size")
        return np.eye(n)
    G = as_float64("gamma", gamma)
    if G.ndim == 1 and ms == 1:
        G = G[:, None]
    if G.ndim == 0 and n == ms == 1:
        G = G.reshape(1, 1)
    if G.shape != (n, ms):
        raise KfastError(f"gamma: expected shape ({n}, {ms}), got {G.shape}")
    if not np.all(np.isfinite(G)):
        raise KfastError("gamma: must be finite")
    return G


# --------------------------------------------------------------------------------------------
# builders


def random_constant(r=1.0) -> LinearGaussian:
    """Random constant (Gimel'farb ex. 1; Mortensen's resistor; docs/algorithms.md, "Random constant").

    State x (scalar). Continuous ẋ = 0; discrete x[k+1] = x[k]: F = 1, Q = 0. y = x + v,
    var v = r. With x(0) ~ (m0, P0): Cov(x[k], x[l]) = P0 for all k, l, so
    Cov(y[k], y[l]) = P0 + r δ_kl. Viewed as "stationary" its PSD is 2π P0 δ(ω).
    The filter "falls asleep" (P, K → 0); use ``random_walk`` with small q if it may drift.
    """
    return LinearGaussian(1.0, 1.0, 0.0, _R(r, 1))


def random_walk(dt, q=1.0, r=1.0) -> LinearGaussian:
    """Random walk / Wiener process (G&A (4.79)-(4.84); Mortensen ch. 1; docs/algorithms.md, "Random walk").

    State x (scalar). Continuous ẋ = w, w white with intensity q. Exact discrete: F = 1,
    Qd = q dt. y = x + v, var v = r.
    Covariance (x(0) ~ (0, P0)): Cov(x[k], x[l]) = P0 + q dt min(k, l) (continuous:
    P0 + q min(t, s)). Nonstationary: no stationary covariance and no PSD (q/ω² is only
    heuristic).
    """
    h = _positive("dt", dt)
    qq = _nonneg("q", q)
    _require_finite("q, dt", f"the process noise variance q dt = {qq:g} * {h:g}", qq * h)
    return LinearGaussian(1.0, 1.0, qq * h, _R(r, 1))


def random_ramp(dt, r=1.0, observe: Observe = 0) -> LinearGaussian:
    """Random ramp [standard] (docs/algorithms.md, "Random ramp").

    State [x1, x2] = [value, slope]. Continuous ẋ1 = x2, ẋ2 = 0, no noise. Exact discrete:
    F = [[1, dt], [0, 1]], Q = 0. ``observe`` 0 measures the value (default), 1 the slope,
    (0, 1) both; R = r I.
    Covariance with x(0) ~ (0, [[p11, p12], [p12, p22]]): P(t) = Φ(t) P0 Φ(t)' and
    Cov(x1(t), x1(s)) = p11 + p12 (t + s) + p22 t s (t = k dt, s = l dt). Nonstationary.
    """
    h = _positive("dt", dt)
    obs = _observe(observe, 2)
    F = np.array([[1.0, h], [0.0, 1.0]])
    H = _H(obs, 2, 1)
    return LinearGaussian(F, H, np.zeros((2, 2)), _R(r, len(obs)))


def constant_velocity(dim, dt, q=1.0, r=1.0, observe: Observe = 0) -> LinearGaussian:
    """Constant velocity = white-noise acceleration = integrated random walk, per axis
    [standard] (docs/algorithms.md, "Constant velocity").

    State (derivative-major): [p_0..p_{dim-1}, v_0..v_{dim-1}]; for dim = 2, (px, py, vx, vy).
    Per axis, continuous ṗ = v, v̇ = w, w white with intensity q (a scalar or one per axis):
    A = [[0, 1], [0, 0]], Qc = diag(0, q). Exact discrete (closed form), h = dt:
    F = [[1, h], [0, 1]], Qd = q [[h³/3, h²/2], [h²/2, h]], i.e. F = kron(F_axis, I),
    Q = kron(Qd_axis/q, diag(q)). Measurement: ``observe`` 0 = positions (default), 1 =
    velocities, (0, 1) both; R = r I. With dim = 2, dt = 0.1, q = 1, r = 1 this is the
    demo/benchmark "CV" model.

    Covariance per axis with x(0) ~ (0, P0), t = k h ≥ s = l h, Φ(t) = [[1, t], [0, 1]]:
    Cov(x(t), x(s)) = Φ(t) P0 Φ(s)' + q [[t s²/2 − s³/6, t s − s²/2], [s²/2, s]]
    (rows: p(t), v(t); columns p(s), v(s)). Nonstationary (the position grows like q t³/3).
    """
    dim = _dim(dim, 2)
    h = _positive("dt", dt)
    qa = _per_axis("q", q, dim)
    obs = _observe(observe, 2)
    F1 = np.array([[1.0, h], [0.0, 1.0]])
    (Q1,) = _evaluate("dt", f"the exact discrete model (dt^3/3 in Q, dt = {h:g})", lambda: (np.array([[h**3 / 3, h**2 / 2], [h**2 / 2, h]]),))
    H = _H(obs, 2, dim)
    with np.errstate(over="ignore"):  # refused just below, naming q
        Q = _kron_axes(Q1, dim, qa)
    _require_finite("q, dt", f"the process noise q dt^3/3 (q up to {qa.max():g}, dt = {h:g})", Q)
    return LinearGaussian(_kron_axes(F1, dim), H, Q, _R(r, H.shape[0]))


def constant_acceleration(dim, dt, q=1.0, r=1.0, observe: Observe = 0) -> LinearGaussian:
    """Constant acceleration = white-noise jerk, per axis (Gimel'farb ex. 2; docs/algorithms.md, "Constant acceleration").

    State (derivative-major): [positions..., velocities..., accelerations...]. Per axis,
    continuous ṗ = v, v̇ = a, ȧ = w, w white with intensity q (scalar or per axis):
    A = [[0,1,0],[0,0,1],[0,0,0]], Qc = diag(0, 0, q). Exact discrete (closed form), h = dt:
    F = [[1, h, h²/2], [0, 1, h], [0, 0, 1]],
    Qd = q [[h⁵/20, h⁴/8, h³/6], [h⁴/8, h³/3, h²/2], [h³/6, h²/2, h]].
    ``observe`` 0/1/2 or a sequence (positions default); R = r I.
    Covariance: P(k) = F^k P0 F'^k + Σ_{j<k} F^j Qd F'^j, Cov(x[k], x[l]) = F^{k−l} P(l),
    k ≥ l. Nonstationary.
    """
    dim = _dim(dim, 3)
    h = _positive("dt", dt)
    qa = _per_axis("q", q, dim)
    obs = _observe(observe, 3)
    F1, Q1 = _evaluate(
        "dt",
        f"the exact discrete model (dt^5/20 in Q, dt = {h:g})",
        lambda: (
            np.array([[1.0, h, h * h / 2], [0.0, 1.0, h], [0.0, 0.0, 1.0]]),
            np.array(
                [
                    [h**5 / 20, h**4 / 8, h**3 / 6],
                    [h**4 / 8, h**3 / 3, h**2 / 2],
                    [h**3 / 6, h**2 / 2, h],
                ]
            ),
        ),
    )
    H = _H(obs, 3, dim)
    with np.errstate(over="ignore"):  # refused just below, naming q
        Q = _kron_axes(Q1, dim, qa)
    _require_finite("q, dt", f"the process noise q dt^5/20 (q up to {qa.max():g}, dt = {h:g})", Q)
    return LinearGaussian(_kron_axes(F1, dim), H, Q, _R(r, H.shape[0]))


def gauss_markov_1(sigma2, beta, dt, r=1.0) -> LinearGaussian:
    """First-order Gauss-Markov (exponentially correlated) process (G&A Table 4.1,
    Prob. 4.30-4.31; Söderström Sec. 4.5; docs/algorithms.md, "First-order Gauss–Markov").

    State x (scalar), variance ``sigma2`` = σ², ``beta`` = β = 1/τ_c (τ_c the correlation time).
    Continuous ẋ = −β x + w, w white with intensity q = 2σ²β. Exact discrete, a = e^{−β dt}:
    F = a, Qd = σ²(1 − e^{−2β dt}). y = x + v, var v = r.
    ψ(τ) = σ² e^{−β|τ|} (``gauss_markov_1_autocovariance``), so r_y(k) = σ² a^|k| + r δ_k.
    PSD (two-sided, rad/s) Φ(ω) = 2σ²β / (ω² + β²); per-sample density (h = 1, no 1/2π)
    σ²(1 − a²) / (1 − 2a cos ω + a²). Stationary covariance σ²: start with P0 = σ².
    """
    s2 = _nonneg("sigma2", sigma2)
    b = _positive("beta", beta)
    h = _positive("dt", dt)
    a = math.exp(-b * h)
    return LinearGaussian(a, 1.0, -s2 * math.expm1(-2 * b * h), _R(r, 1))


def gauss_markov_2(omega_n, zeta, q, dt, r=1.0, observe: Observe = 0) -> LinearGaussian:
    """Second-order Gauss-Markov process (G&A Sec. 4.3; docs/algorithms.md, "Second-order Gauss–Markov").

    State [x, ẋ] (position, velocity). Continuous ẍ + 2ζω_n ẋ + ω_n² x = w, w white with
    intensity q: A = [[0, 1], [−ω_n², −2ζω_n]], Qc = diag(0, q) (ζ > 0, ω_n > 0). Exact
    discrete F = e^{A dt}, Qd by Van Loan (``kfast.discretize``). ``observe`` 0 = position
    (default), 1 = velocity; R = r I.
    Stationary: var x = σ² = q / (4ζω_n³), var ẋ = q / (4ζω_n), Cov(x, ẋ) = 0.
    Position ψ(τ) (``gauss_markov_2_autocovariance``), ω_d = ω_n √(1−ζ²):
    ζ < 1: σ² e^{−ζω_n|τ|} [cos ω_d|τ| + (ζω_n/ω_d) sin ω_d|τ|];
    ζ = 1: σ² e^{−ω_n|τ|} (1 + ω_n|τ|);  ζ > 1: the same with cos, sin → cosh, sinh and
    ω_d → ω_n √(ζ²−1). PSD (two-sided, rad/s) of the position:
    Φ(ω) = q / (ω⁴ + 2ω_n²(2ζ² − 1) ω² + ω_n⁴), peaked at ω_n √(1 − 2ζ²) when ζ < 1/√2.
    G&A's general form (a²ω² + b²)/(...) is the output [b, a] with unit intensity.
    """
    h = _positive("dt", dt)
    cm = _cont_gauss_markov_2(omega_n, zeta, q, observe)
    F, Qd = _discretize_checked(cm.A, cm.Qc, h, "dt, omega_n, zeta")
    return LinearGaussian(F, cm.H, Qd, _R(r, cm.H.shape[0]))


def _resonator_discrete(omega: float, tau: float, q: float, h: float):
    """Closed forms of G&A ex. 4.9 (docs/algorithms.md, "Damped resonator")."""
    S, C = math.sin(omega * h), math.cos(omega * h)
    E = math.exp(-2 * h / tau)
    one_minus_E = -math.expm1(-2 * h / tau)
    wt = omega * tau
    F = math.exp(-h / tau) * np.array(
        [[C + S / wt, S / omega], [-S * (1 + wt * wt) / (omega * tau * tau), C - S / wt]]
    )
    q11 = q * tau * (wt * wt * one_minus_E - 2 * S * E * (S + wt * C)) / (4 * omega**2 * (1 + wt * wt))
    q12 = q * E * S * S / (2 * omega**2)
    q22 = q * (wt * wt * one_minus_E - 2 * S * E * (S - wt * C)) / (4 * omega**2 * tau)
    return F, np.array([[q11, q12], [q12, q22]])


def damped_resonator(omega, tau, q, dt, r=1.0, observe: Observe = 0) -> LinearGaussian:
    """Damped harmonic resonator driven by white acceleration (G&A Example 4.9;
    docs/algorithms.md, "Damped resonator").

    State [x, ẋ]. ``omega`` = ω is the *damped* frequency (rad/s), 1/``tau`` the damping rate:
    A = [[0, 1], [−(ω² + 1/τ²), −2/τ]], Qc = diag(0, q) (q the intensity of the white
    acceleration). This is ``gauss_markov_2`` with ω_n² = ω² + 1/τ², ζω_n = 1/τ (G&A's
    ω_r = ω, ω_d = 1/τ). Exact discrete, closed form with S = sin ωh, C = cos ωh,
    E = e^{−2h/τ}, h = dt:
    F = e^{−h/τ} [[C + S/(ωτ), S/ω], [−S (1 + ω²τ²)/(ωτ²), C − S/(ωτ)]],
    q11 = q τ [ω²τ²(1 − E) − 2 S E (S + ωτ C)] / (4ω²(1 + ω²τ²)),
    q12 = q21 = q E S² / (2ω²),
    q22 = q [ω²τ²(1 − E) − 2 S E (S − ωτ C)] / (4ω²τ)
    (Qd is full though Qc is sparse; q11 is a difference of O(h) terms, so its relative
    accuracy degrades like ε/(h/τ)² for h ≪ τ, 1/ω — use ``gauss_markov_2`` (Van Loan) there;
    where the closed form over- or underflows, e.g. ω → 0 or τ → ∞, F and Qd are computed by
    Van Loan instead).
    Stationary P∞ = diag(qτ / (4(ω² + 1/τ²)), qτ/4). Position ψ(τ') = P∞[0,0] e^{−|τ'|/τ}
    [cos ω|τ'| + sin(ω|τ'|)/(ωτ)] (``damped_resonator_autocovariance``); PSD (two-sided,
    rad/s) Φ(ω') = q / ((ω_n² − ω'²)² + 4ω'²/τ²). ``observe`` 0 = position (default),
    1 = velocity; R = r I.
    """
    w, t, qq = _positive("omega", omega), _positive("tau", tau), _nonneg("q", q)
    h = _positive("dt", dt)
    obs = _observe(observe, 2)
    A = _resonator_A(w, t)
    try:
        F, Qd = _resonator_discrete(w, t, qq, h)
        closed_form = bool(np.all(np.isfinite(F)) and np.all(np.isfinite(Qd)))
    except (OverflowError, ZeroDivisionError):
        closed_form = False
    if not closed_form:  # e.g. omega -> 0 or tau -> inf: the exact discretization by Van Loan
        F, Qd = _discretize_checked(A, np.diag([0.0, qq]), h, "omega, tau, dt")
        Qd = (Qd + Qd.T) / 2
    H = _H(obs, 2, 1)
    return LinearGaussian(F, H, Qd, _R(r, H.shape[0]))


def singer(dt, alpha, sigma_m2, r=1.0, dim=1, observe: Observe = 0) -> LinearGaussian:
    """Singer manoeuvring-target model (Singer 1970; G&A ch. 4 style Gauss-Markov acceleration).

    State (derivative-major) [positions..., velocities..., accelerations...]; per axis
    ṗ = v, v̇ = a, ȧ = −α a + w, w white with intensity q = 2α σ_m² (``alpha`` = α = 1/τ_m,
    τ_m the manoeuvre time constant; ``sigma_m2`` = σ_m² the acceleration variance):
    A = [[0,1,0],[0,0,1],[0,0,−α]], Qc = diag(0, 0, 2ασ_m²). Exact discrete F = e^{A dt},
    Qd by Van Loan (``kfast.discretize``, per axis, then kron(·, I_dim)); its acceleration
    entry is σ_m² (1 − e^{−2α dt}). ``observe`` 0 = positions (default), 1, 2 or a
    sequence; R = r I.
    The acceleration is a stationary first-order Gauss-Markov process:
    ψ_a(τ) = σ_m² e^{−α|τ|} (``singer_autocovariance``), PSD 2σ_m²α/(ω² + α²). Position and
    velocity are nonstationary (integrals of it): no stationary covariance.
    """
    h = _positive("dt", dt)
    dim = _dim(dim, 3)
    A, Qc = _singer_axis(alpha, sigma_m2)
    obs = _observe(observe, 3)
    F1, Q1 = _discretize_checked(A, Qc, h, "dt, alpha")
    Q1 = (Q1 + Q1.T) / 2
    H = _H(obs, 3, dim)
    return LinearGaussian(_kron_axes(F1, dim), H, _kron_axes(Q1, dim), _R(r, H.shape[0]))


def _ar_coeffs(coeffs) -> np.ndarray:
    return finite_vector("coeffs", coeffs, "[a1, ..., ap]")


def ar(coeffs, noise_var, r=0.0) -> LinearGaussian:
    """AR(p) process in companion form (Söderström Example 3.1 / Sec. 4.2.3; G&A (4.75)-(4.76);
    docs/algorithms.md, "AR(p)").

    Sign convention (Söderström, statsmodels' ``ArmaProcess([1, a1, ..., ap], [1])``):
        y(t) + a1 y(t−1) + … + ap y(t−p) = e(t),   var e = ``noise_var`` = λ²,
    ``coeffs`` = [a1, ..., ap]. G&A write y_k = Σ φ_i y_{k−i} + w_k: pass coeffs = −φ.
    State x(t) = [y(t), y(t−1), …, y(t−p+1)]:
    F = [[−a1, …, −ap], [1, 0, …, 0], …, [0, …, 1, 0]], Q = diag(λ², 0, …, 0),
    H = [1, 0, …, 0], R = r (default 0: y is observed exactly; kfast accepts R = 0 when
    H P H' > 0). Q is singular.
    Stationary when the zeros of z^p + a1 z^{p−1} + … + ap lie inside the unit circle; then the
    stationary state covariance is the Toeplitz matrix of r(0..p−1) and r(k) solves the
    Yule-Walker equations Σ_i a_i r(k−i) = λ² δ_k (``ar_autocovariance``).
    Spectrum (discrete, no 1/2π): φ(e^{iω}) = λ² / |1 + Σ a_i e^{−iωi}|²,
    r(k) = (1/2π) ∫_{−π}^{π} φ(e^{iω}) e^{iωk} dω. Nonstationary coefficients are accepted
    (e.g. coeffs = [−1] is a random walk).
    """
    a = _ar_coeffs(coeffs)
    lam2 = _nonneg("noise_var", noise_var)
    p = a.size
    F = np.zeros((p, p))
    F[0] = -a
    F[1:, :-1] = np.eye(p - 1)
    Q = np.zeros((p, p))
    Q[0, 0] = lam2
    H = np.zeros((1, p))
    H[0, 0] = 1.0
    return LinearGaussian(F, H, Q, _R(r, 1))


# --------------------------------------------------------------------------------------------
# coloured noise: discrete augmentation


def augment(model: LinearGaussian, shaping: LinearGaussian, where: str, *, gamma=None, Q=None, R=None) -> LinearGaussian:
    """Append a discrete shaping filter for coloured noise (G&A Sec. 4.5, (4.77);
    docs/algorithms.md, "Shaping filters"). The coloured noise is the shaping model's *output*
    y_s[k] = H_s x_s[k] + v_s[k], x_s[k+1] = F_s x_s[k] + w_s[k] (cov w_s = Q_s, cov v_s = R_s,
    E[w_s v_s'] = N_s): build it with r = 0 for purely coloured noise (e.g.
    ``gauss_markov_1(sigma2, beta, dt, r=0)``). The augmented state is [x; x_s].

    * ``where="process"``: x[k+1] = F x[k] + Γ y_s[k] + w[k], with ``gamma`` = Γ (n × m_s;
      default I when n = m_s) and w the remaining white noise, cov ``Q`` (default model.Q;
      pass Q=0 when the coloured noise replaces it):
      F_a = [[F, Γ H_s], [0, F_s]], Q_a = [[Q + Γ R_s Γ', Γ N_s'], [N_s Γ', Q_s]]
      (= blockdiag(Q, Q_s) when R_s = 0, N_s = 0), H_a = [H, 0], R_a = model.R,
      N_a = [N; 0].
    * ``where="measurement"``: y[k] = H x[k] + y_s[k] + v[k], with v white, cov ``R``
      (default model.R; 0 allowed — kfast filters while H P H' + R > 0):
      F_a = blockdiag(F, F_s), Q_a = blockdiag(Q, Q_s), H_a = [H, H_s], R_a = R + R_s,
      N_a = [N; N_s].

    B and D of ``model`` are kept (B_a = [B; 0]); the shaping model must have no inputs, and
    both must be constant (no per-step matrices). For a continuous plant and shaping filter,
    prefer ``augment_continuous(...).discretize(dt, r)``: this function combines *discrete*
    models, which for coloured process noise drops the cross terms that the joint exact
    discretization has.
    Output autocovariance (stationary, measurement case): r_y(k) = r_model(k) + r_shaping(k),
    the sum of the two models' output autocovariances (the white R counted once).
    """
    for name, mdl in (("model", model), ("shaping", shaping)):
        if not isinstance(mdl, LinearGaussian):
            raise KfastError(f"{name}: expected a kfast.LinearGaussian, got {type(mdl).__name__}")
        if mdl.steps is not None:
            raise KfastError(f"{name}: per-step (time-varying) models are not supported")
    if shaping.B is not None or shaping.D is not None:
        raise KfastError("shaping: must have no inputs (B, D)")
    n, m, ns, ms = model.n_states, model.n_obs, shaping.n_states, shaping.n_obs
    F, H = model.F, model.H
    Fs, Qs, Hs, Rs = shaping.F, shaping.Q, shaping.H, shaping.R
    Ns = np.zeros((ns, ms)) if shaping.N is None else shaping.N
    N = np.zeros((n, m)) if model.N is None else model.N
    B = None if model.B is None else np.vstack([model.B, np.zeros((ns, model.B.shape[1]))])
    if where == "process":
        G = _gamma(gamma, n, ms)
        if R is not None:
            raise KfastError("R: only for where='measurement' (the process case keeps model.R)")
        Qw = model.Q if Q is None else _matrix_or_scalar("Q", Q, n)
        Fa = np.block([[F, G @ Hs], [np.zeros((ns, n)), Fs]])
        cross = G @ Ns.T
        Qa = np.block([[Qw + G @ Rs @ G.T, cross], [cross.T, Qs]])
        Ha = np.hstack([H, np.zeros((m, ns))])
        Ra = model.R
        Na = np.vstack([N, np.zeros((ns, m))])
    elif where == "measurement":
        if gamma is not None:
            raise KfastError("gamma: only for where='process'")
        if Q is not None:
            raise KfastError("Q: only for where='process' (the measurement case keeps model.Q)")
        if ms != m:
            raise KfastError(f"shaping: its output has {ms} components, the model's {m}")
        Rw = model.R if R is None else _matrix_or_scalar("R", R, m)
        Fa = _blockdiag(F, Fs)
        Qa = _blockdiag(model.Q, Qs)
        Ha = np.hstack([H, Hs])
        Ra = Rw + Rs
        Na = np.vstack([N, Ns])
    else:
        raise KfastError(f"where: expected 'process' or 'measurement', got {where!r}")
    return LinearGaussian(Fa, Ha, Qa, Ra, B=B, D=model.D, N=Na if np.any(Na) else None)


def _matrix_or_scalar(name: str, value, size: int) -> np.ndarray:
    arr = as_float64(name, value)
    if arr.ndim == 0:
        return np.eye(size) * _nonneg(name, arr)
    if arr.shape != (size, size):
        raise KfastError(f"{name}: expected a scalar or shape ({size}, {size}), got {arr.shape}")
    return arr


# --------------------------------------------------------------------------------------------
# autocovariance functions of the stationary models


def _lags(lag) -> np.ndarray:
    t = as_float64("lag", lag)
    if not np.all(np.isfinite(t)):
        raise KfastError("lag: must be finite")
    return t


def _plus_white(psi: np.ndarray, t: np.ndarray, r) -> Union[np.ndarray, float]:
    rr = _nonneg("r", r)
    out = psi + rr * (t == 0)
    return out if out.ndim else float(out)


def gauss_markov_1_autocovariance(lag, sigma2, beta, r=0.0):
    """ψ(τ) = σ² e^{−β|τ|} of ``gauss_markov_1`` at ``lag`` = τ (time units of dt; array-like),
    plus ``r`` at τ = 0 (the sampled output's r_y(k) = ψ(k dt) + r δ_k)."""
    t = np.abs(_lags(lag))
    s2, b = _nonneg("sigma2", sigma2), _positive("beta", beta)
    return _plus_white(s2 * np.exp(-b * t), t, r)


def _second_order_acov(t: np.ndarray, var: float, a: float, wn: float) -> np.ndarray:
    """var e^{−a t}[cos ω_d t + (a/ω_d) sin ω_d t] for the damping rate a = ζω_n (t ≥ 0),
    continued to ζ ≥ 1."""
    disc = wn * wn - a * a
    if disc > 0:
        wd = math.sqrt(disc)
        return var * np.exp(-a * t) * (np.cos(wd * t) + a * np.sin(wd * t) / wd)
    if disc == 0:
        return var * np.exp(-a * t) * (1 + a * t)
    wh = math.sqrt(-disc)  # < a
    slow = np.exp((wh - a) * t)
    fast = np.exp(-(wh + a) * t)
    # e^{-at} cosh(wh t) + a e^{-at} sinh(wh t) / wh, without overflow or cancellation
    return var * (0.5 * (slow + fast) + a * slow * (-np.expm1(-2 * wh * t)) / (2 * wh))


def gauss_markov_2_autocovariance(lag, omega_n, zeta, q, r=0.0):
    """Position ψ(τ) of ``gauss_markov_2`` (formulas in its docstring; σ² = q/(4ζω_n³)) at
    ``lag`` = τ, plus ``r`` at τ = 0."""
    t = np.abs(_lags(lag))
    wn, z, qq = _positive("omega_n", omega_n), _positive("zeta", zeta), _nonneg("q", q)
    (var,) = _evaluate("omega_n, zeta, q", f"the variance q/(4 zeta omega_n^3) = {qq:g}/(4 * {z:g} * {wn:g}^3)", lambda: (qq / (4 * z * wn**3),))
    _require_finite("omega_n, zeta", f"omega_n^2 and (zeta omega_n)^2 (omega_n = {wn:g}, zeta = {z:g})", wn * wn, (z * wn) * (z * wn))
    if z == 1.0:
        psi = var * np.exp(-wn * t) * (1 + wn * t)
    else:
        psi = _second_order_acov(t, var, z * wn, wn)
    _require_finite("omega_n, zeta", "the autocovariance", psi)
    return _plus_white(psi, t, r)


def damped_resonator_autocovariance(lag, omega, tau, q, r=0.0):
    """Position ψ(τ') = qτ/(4(ω² + 1/τ²)) e^{−|τ'|/τ} [cos ω|τ'| + sin(ω|τ'|)/(ωτ)] of
    ``damped_resonator`` at ``lag`` = τ', plus ``r`` at τ' = 0."""
    t = np.abs(_lags(lag))
    w, tt, qq = _positive("omega", omega), _positive("tau", tau), _nonneg("q", q)
    _resonator_A(w, tt)
    (var,) = _evaluate("q, tau", f"the variance q tau/(4(omega^2 + 1/tau^2)) (q = {qq:g}, tau = {tt:g})", lambda: (qq * tt / (4 * (w * w + 1 / (tt * tt))),))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        psi = var * np.exp(-t / tt) * (np.cos(w * t) + np.sin(w * t) / (w * tt))
    _require_finite("omega, tau", f"the autocovariance (omega tau = {w * tt:g})", psi)
    return _plus_white(psi, t, r)


def singer_autocovariance(lag, alpha, sigma_m2):
    """Acceleration autocovariance ψ_a(τ) = σ_m² e^{−α|τ|} of ``singer`` (the only stationary
    component of its state) at ``lag`` = τ."""
    t = np.abs(_lags(lag))
    a, s2 = _positive("alpha", alpha), _nonneg("sigma_m2", sigma_m2)
    out = s2 * np.exp(-a * t)
    return out if out.ndim else float(out)


def ar_autocovariance(lags, coeffs, noise_var, r=0.0):
    """r(k) = E[y(t+k) y(t)] of the stationary AR(p) process of ``ar`` at integer ``lags``
    (array-like), plus ``r`` at k = 0. Yule-Walker (Söderström (4.29)-(4.35);
    docs/algorithms.md, "ARMA covariances"): for k = 0..p, Σ_i a_i r(k−i) = λ² δ_k with r(−k) = r(k), then
    r(k) = −Σ_i a_i r(k−i) for k > p. Raises KfastError when the process is not stationary."""
    a = _ar_coeffs(coeffs)
    lam2 = _nonneg("noise_var", noise_var)
    k = np.abs(integer_lags("lags", lags))
    roots = np.roots(np.concatenate([[1.0], a]))
    if roots.size and np.max(np.abs(roots)) >= 1:
        raise KfastError(f"coeffs: not stationary (a zero of z^p + a1 z^(p-1) + ... has modulus {np.max(np.abs(roots)):.6g} >= 1)")
    p = a.size
    a0 = np.concatenate([[1.0], a])
    M = np.zeros((p + 1, p + 1))
    for tau in range(p + 1):
        for j in range(p + 1):
            if 0 <= tau - j <= p:
                M[tau, j] += a0[tau - j]
            if j >= 1 and tau + j <= p:
                M[tau, j] += a0[tau + j]
    rhs = np.zeros(p + 1)
    rhs[0] = lam2
    rr = np.linalg.solve(M, rhs)
    rv = _nonneg("r", r)
    far = k > _AR_RECURSION_LIMIT
    near = k[~far]
    kmax = int(near.max()) if near.size else 0
    if kmax > p:
        rr = np.concatenate([rr, np.zeros(kmax - p)])
        for j in range(p + 1, kmax + 1):
            rr[j] = -np.dot(a, rr[j - p : j][::-1])
    out = np.empty(k.shape)
    out[~far] = rr[near]
    if far.any():
        # [r(p+j), ..., r(j+1)] = C^j [r(p), ..., r(1)], C the companion matrix of the
        # recursion: any lag < 2**63 in O(log lag) products
        C = np.zeros((p, p))
        C[0] = -a
        C[1:, :-1] = np.eye(p - 1)
        powers = powers_applied(C, rr[p:0:-1], k[far] - p)
        out[far] = [powers[j][0] for j in (k[far] - p).tolist()]
    out = out + rv * (k == 0)
    return out if out.ndim else float(out)


# Lags up to this are computed by the recursion r(k) = -sum_i a_i r(k-i) (an array of that
# length), beyond it by powers of the companion matrix.
_AR_RECURSION_LIMIT = 100_000


# ----------------------------------------------------------------------------------------------
# Built-in nonlinear models (Rust): f and h for kfast.NonlinearModel
# ----------------------------------------------------------------------------------------------


def coordinated_turn(dt, q=1.0, sigma_omega=0.0, omega=None) -> BuiltinFunction:
    """The coordinated turn with unknown turn rate, state (px, py, vx, vy, omega), as the
    transition f of a :class:`kfast.NonlinearModel` (n = 5), computed in Rust -- or, with a
    known turn rate ``omega`` (rad per unit time), the 4-state turn (px, py, vx, vy), a linear
    map x' = F(omega) x with the same F entries (n = 4; ``sigma_omega`` does not apply).

    The exact discretization for a constant turn rate omega over ``dt`` (Bar-Shalom, Li &
    Kirubarajan 2001; Li & Jilkov 2003)::

        px' = px + s vx - c vy      vx' = C vx - S vy      omega' = omega
        py' = py + c vx + s vy      vy' = S vx + C vy
        s = sin(omega dt)/omega,  c = (1 - cos(omega dt))/omega,  C = cos(omega dt),  S = sin(omega dt)

    evaluated from one sine and cosine with 1 - cos = sin^2 / (1 + cos) for |omega dt| <= pi/2,
    so that omega -> 0 has no cancellation and omega = 0 is the constant-velocity model exactly
    (the known-omega map through sinc), with its Jacobian in closed form (a Taylor series for
    |omega dt| < 0.02). ``.Q`` is the process
    noise that goes with it: white-noise acceleration of intensity ``q`` per axis,
    q [[dt^3/3, dt^2/2], [dt^2/2, dt]] on (p, v), and sigma_omega^2 dt on omega (the rotation
    of the noise by the turn is ignored, a standard approximation).

    >>> ct = kfast.models.coordinated_turn(dt=0.1, q=1.0, sigma_omega=0.05)
    >>> ct.Q.shape
    (5, 5)
    >>> known = kfast.models.coordinated_turn(dt=0.1, q=1.0, omega=0.2)
    >>> known.params.shape, known.Q.shape
    ((4, 4), (4, 4))
    """
    h = _positive("dt", dt)
    q = _nonneg("q", q)
    s2 = _nonneg("sigma_omega", sigma_omega) ** 2
    n = 5 if omega is None else 4
    Q = np.zeros((n, n))
    per_axis = q * np.array([[h**3 / 3, h**2 / 2], [h**2 / 2, h]])
    for axis in (0, 1):
        Q[np.ix_([axis, axis + 2], [axis, axis + 2])] = per_axis
    if omega is None:
        Q[4, 4] = s2 * h
        Q.setflags(write=False)
        return BuiltinFunction("coordinated_turn", (h,), Q=Q)
    Q.setflags(write=False)
    return BuiltinFunction("linear", _known_turn(h, _real("omega", omega)), Q=Q)


def _known_turn(dt: float, omega: float) -> np.ndarray:
    """F of the turn by a known omega over dt, through sinc (no cancellation as omega -> 0):
    s = dt sinc(omega dt), c = (omega dt^2 / 2) sinc^2(omega dt / 2)."""
    a = omega * dt
    s = dt * np.sinc(a / np.pi)  # NumPy's sinc is sin(pi x) / (pi x)
    c = omega * dt * dt / 2 * np.sinc(a / 2 / np.pi) ** 2
    C, S = np.cos(a), np.sin(a)
    F = np.array([[1.0, 0.0, s, -c], [0.0, 1.0, c, s], [0.0, 0.0, C, -S], [0.0, 0.0, S, C]])
    F.setflags(write=False)
    return F


def range_bearing(sensor=(0.0, 0.0)) -> BuiltinFunction:
    """A range-bearing sensor at ``sensor`` = (sx, sy) as the measurement h of a
    :class:`kfast.NonlinearModel`, computed in Rust: the state's first two components are the
    position p, and y = (|p - s|, atan2(py - sy, px - sx)) -- the bearing is the mathematical
    angle from the x axis, counter-clockwise, in (-pi, pi]. It declares the bearing an angle
    (``angles=(1,)``), so innovations are wrapped. Its Jacobian is undefined at the sensor
    (range 0): the filters then raise naming the step.

    >>> kfast.models.range_bearing(sensor=(1.0, -2.0)).params
    (1.0, -2.0)
    """
    s = finite_vector("sensor", sensor, "(the sensor position)")
    if s.shape != (2,):
        raise KfastError(f"sensor: expected two coordinates (sx, sy), got shape {s.shape}")
    return BuiltinFunction("range_bearing", (float(s[0]), float(s[1])), angles=(1,))


def bearings_only(sensor=(0.0, 0.0)) -> BuiltinFunction:
    """A bearings-only sensor at ``sensor`` = (sx, sy): y = atan2(py - sy, px - sx) of the
    state's position (its first two components), m = 1, declared an angle (wrapped). The
    bearing row of :func:`range_bearing`; undefined at the sensor (the filters raise, naming
    the step).

    >>> kfast.models.bearings_only((0.0, 0.0)).angles
    (0,)
    """
    s = finite_vector("sensor", sensor, "(the sensor position)")
    if s.shape != (2,):
        raise KfastError(f"sensor: expected two coordinates (sx, sy), got shape {s.shape}")
    return BuiltinFunction("bearing", (float(s[0]), float(s[1])), angles=(0,))


def range_bearing_elevation(sensor=(0.0, 0.0, 0.0)) -> BuiltinFunction:
    """A 3-D radar at ``sensor`` = (sx, sy, sz) seeing the state's position (its first three
    components): y = (range r, azimuth atan2(dy, dx), elevation atan2(dz, rho)) with d = p - s,
    rho = sqrt(dx^2 + dy^2); the azimuth is declared an angle (wrapped). Undefined straight above
    or below the sensor (rho = 0): the filters raise, naming the step.

    >>> kfast.models.range_bearing_elevation((0.0, 0.0, 10.0)).params
    (0.0, 0.0, 10.0)
    """
    s = finite_vector("sensor", sensor, "(the sensor position)")
    if s.shape != (3,):
        raise KfastError(f"sensor: expected three coordinates (sx, sy, sz), got shape {s.shape}")
    return BuiltinFunction("range_bearing_elevation", tuple(float(v) for v in s), angles=(1,))


def ungm(q=10.0, r=1.0):
    """The univariate nonstationary growth model (Kitagawa 1996; Gordon, Salmond & Smith 1993),
    in Rust, as a :class:`kfast.NonlinearModel` (n = m = 1)::

        x[t+1] = x/2 + 25 x/(1 + x^2) + 8 cos(1.2 t) + w,   w ~ N(0, q)
        y[t]   = x^2/20 + v,                               v ~ N(0, r)

    with t the step of the transition t -> t+1 (papers differ between cos(1.2 t) and
    cos(1.2 (t+1))). The standard benchmark of nonlinear filters (the EKF does badly on it).

    >>> model = kfast.models.ungm()
    >>> model.ekf([[0.5], [1.0]], x0=[0.0], P0=[[5.0]]).x_filt.shape
    (2, 1)
    """
    from kfast.nonlinear.model import NonlinearModel

    q, r = _nonneg("q", q), _positive("r", r)
    return NonlinearModel(BuiltinFunction("ungm", ()), BuiltinFunction("ungm_measurement", ()), [[q]], [[r]], n=1)
