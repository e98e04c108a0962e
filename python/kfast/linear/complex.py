"""Complex-valued linear Gaussian models (Söderström Sec. 2.5 and Lemma 6.1;
Picinbono & Chevalier (1995); Schreier & Scharf (2010)), filtered and smoothed through the real
composite form:

    x[t+1] = F x[t] + B u[t] + w[t],   y[t] = H x[t] + D u[t] + v[t]

with complex F, H, B, D, Hermitian covariances Q = E w w^H, R = E v v^H (and N = E w v^H), and
optional complementary covariances Qc = E w w^T, Rc = E v v^T for improper (non-circular) noise.
The state [Re x; Im x] (2n real components) follows the real model with M -> [[Re M, -Im M],
[Im M, Re M]] and the covariance blocks

    E z_R u_R' = ½ Re(Γ + Γ̃),  E z_R u_I' = ½ Im(Γ̃ - Γ),  E z_I u_R' = ½ Im(Γ + Γ̃),  E z_I u_I' = ½ Re(Γ - Γ̃)

(Γ = E z u^H, Γ̃ = E z u^T). With proper noise this is the complex Kalman filter with Hermitian
transposes (Lemma 6.1 read with ' as ^H); with improper noise it is the widely linear filter, the
conditional mean for Gaussian noise. Results come back complex: estimates, the Hermitian
covariance P = E x̃ x̃^H and the complementary P̃ = E x̃ x̃^T; the log-likelihood is the real
2m-dimensional one, which for proper noise is -[m log π + log det S + e^H S^-1 e] per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._kfast import KfastError

__all__ = ["ComplexLinearGaussian", "ComplexFilterResult", "ComplexSmootherResult", "is_complex_model"]


def is_complex_model(values: tuple, Qc: Any, Rc: Any) -> bool:
    """Whether LinearGaussian's arguments describe a complex model."""
    if Qc is not None or Rc is not None:
        return True
    for v in values:
        try:
            if v is not None and np.iscomplexobj(np.asarray(v)):
                return True
        except (TypeError, ValueError):
            continue
    return False


def _complex(name: str, value: Any, ndim_min: int = 2) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype.kind not in "fiuc":
        raise KfastError(f"{name}: expected numbers, got dtype {a.dtype}")
    a = np.array(a, dtype=np.complex128)
    while a.ndim < ndim_min:
        a = a.reshape((1,) * (ndim_min - a.ndim) + a.shape)
    if not np.all(np.isfinite(a)):
        raise KfastError(f"{name}: must be finite")
    return a


def _block(rr: np.ndarray, ri: np.ndarray, ir: np.ndarray, ii: np.ndarray) -> np.ndarray:
    """[[rr, ri], [ir, ii]] over the last two axes (per-step stacks allowed)."""
    return np.concatenate([np.concatenate([rr, ri], axis=-1), np.concatenate([ir, ii], axis=-1)], axis=-2)


def realify(M: np.ndarray) -> np.ndarray:
    """The real form [[Re M, -Im M], [Im M, Re M]] of a strictly linear map."""
    return _block(M.real, -M.imag, M.imag, M.real)


def real_covariance(gamma: np.ndarray, comp: Optional[np.ndarray]) -> np.ndarray:
    """The covariance of ([Re z; Im z], [Re u; Im u]) from Γ = E z u^H and Γ̃ = E z u^T."""
    g = gamma
    c = np.zeros_like(g) if comp is None else comp
    return 0.5 * _block((g + c).real, (c - g).imag, (g + c).imag, (g - c).real)


def complex_covariance(C: np.ndarray, n: int, complementary: bool = False, proper: bool = False) -> np.ndarray:
    """Γ = C_RR + C_II + i (C_IR - C_RI) of a real covariance C of [Re z; Im z] (z of n
    components), or with ``complementary`` Γ̃ = C_RR - C_II + i (C_IR + C_RI).

    ``proper``: z is known to be proper (C_RR = C_II, C_IR = -C_RI, Γ̃ = 0 in exact
    arithmetic), so Γ = 2 (C_RR + i C_IR) reads half of C and Γ̃ is exactly zero. The filter of
    a proper model keeps this structure to rounding; the shortcut halves the conversion's
    memory traffic, which is most of what a complex run costs beyond the real one."""
    rr, ri, ir, ii = C[..., :n, :n], C[..., :n, n:], C[..., n:, :n], C[..., n:, n:]
    if proper and complementary:
        return np.zeros(rr.shape, dtype=np.complex128)
    out = np.empty(rr.shape, dtype=np.complex128)
    # (written part by part into the output: no temporaries)
    if proper:
        np.multiply(rr, 2.0, out=out.real)
        np.multiply(ir, 2.0, out=out.imag)
    elif complementary:
        np.subtract(rr, ii, out=out.real)
        np.add(ir, ri, out=out.imag)
    else:
        np.add(rr, ii, out=out.real)
        np.subtract(ir, ri, out=out.imag)
    return out


def complex_vector(a: np.ndarray, k: int) -> np.ndarray:
    """z = a[..., :k] + i a[..., k:] of the composite [Re z; Im z], written into its output
    part by part (no temporaries)."""
    out = np.empty(a.shape[:-1] + (k,), dtype=np.complex128)
    out.real = a[..., :k]
    out.imag = a[..., k:]
    return out


def _check_hermitian(name: str, a: np.ndarray) -> None:
    scale = max(1.0, float(np.abs(a).max(initial=0.0)))
    if not np.allclose(a, np.conj(np.swapaxes(a, -1, -2)), rtol=1e-10, atol=1e-12 * scale):
        raise KfastError(f"{name}: must be Hermitian (equal to its conjugate transpose)")


def _check_symmetric(name: str, a: np.ndarray) -> None:
    scale = max(1.0, float(np.abs(a).max(initial=0.0)))
    if not np.allclose(a, np.swapaxes(a, -1, -2), rtol=1e-10, atol=1e-12 * scale):
        raise KfastError(f"{name}: a complementary covariance E z z^T must be symmetric (equal to its transpose)")


class ComplexFilterResult:
    """The filter's outputs in complex form (T steps, n states, m outputs), each converted from
    the real composite run on first access (``real``, the composite FilterResult):

    - x_pred, x_filt, x_next: x̂(t|t-1), x̂(t|t), x̂(T|T-1), complex;
    - P_pred, P_filt, P_next: E x̃ x̃^H (Hermitian); P_pred_c, P_filt_c, P_next_c: the
      complementary E x̃ x̃^T (zero for proper noise);
    - innov: e(t) = y(t) - H x̂(t|t-1) - D u(t), (T, m), NaN where y is missing; S = E e e^H, S_c;
    - loglik, loglik_t: the real 2m-dimensional log-likelihood (for proper noise
      Σ -[m log π + log det S + e^H S^-1 e]).
    """

    def __init__(self, real: Any, n: int, m: int, proper: bool) -> None:
        self.real = real
        self._n, self._m, self._proper = n, m, proper
        self.loglik: float = real.loglik
        self.loglik_t: np.ndarray = real.loglik_t

    def _vector(self, name: str, k: int) -> np.ndarray:
        return complex_vector(getattr(self.real, name), k)

    def _covariance(self, name: str, k: int, complementary: bool) -> np.ndarray:
        return complex_covariance(getattr(self.real, name), k, complementary, self._proper)

    x_pred = cached_property(lambda self: self._vector("x_pred", self._n))
    x_filt = cached_property(lambda self: self._vector("x_filt", self._n))
    x_next = cached_property(lambda self: self._vector("x_next", self._n))
    innov = cached_property(lambda self: self._vector("innov", self._m))
    P_pred = cached_property(lambda self: self._covariance("P_pred", self._n, False))
    P_pred_c = cached_property(lambda self: self._covariance("P_pred", self._n, True))
    P_filt = cached_property(lambda self: self._covariance("P_filt", self._n, False))
    P_filt_c = cached_property(lambda self: self._covariance("P_filt", self._n, True))
    P_next = cached_property(lambda self: self._covariance("P_next", self._n, False))
    P_next_c = cached_property(lambda self: self._covariance("P_next", self._n, True))
    S = cached_property(lambda self: self._covariance("S", self._m, False))
    S_c = cached_property(lambda self: self._covariance("S", self._m, True))

    def __repr__(self) -> str:
        return f"ComplexFilterResult(T={len(self.loglik_t)}, n={self._n}, loglik={self.loglik:.6g})"


@dataclass(frozen=True, repr=False)
class ComplexSmootherResult:
    """The RTS smoother's outputs in complex form."""

    x_smooth: np.ndarray
    P_smooth: np.ndarray
    P_smooth_c: np.ndarray
    filter: ComplexFilterResult
    real: Any
    """The real composite SmootherResult."""

    def __repr__(self) -> str:
        T, n = self.x_smooth.shape
        return f"ComplexSmootherResult(T={T}, n={n})"


class ComplexLinearGaussian:
    """A complex-valued linear Gaussian model (module docstring); made by
    ``kfast.LinearGaussian(...)`` when a matrix is complex or ``Qc``/``Rc`` is given.

    Attributes F, H, Q, R, B, D, N, Qc, Rc are the complex matrices as given; ``real`` is the real
    composite LinearGaussian (2n states, 2m outputs) that does the work.
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
        Qc: Optional[ArrayLike] = None,
        Rc: Optional[ArrayLike] = None,
    ) -> None:
        from kfast.linear.model import LinearGaussian

        self.F, self.H, self.Q, self.R = (_complex(k, v) for k, v in (("F", F), ("H", H), ("Q", Q), ("R", R)))
        self.B = None if B is None else _complex("B", B)
        self.D = None if D is None else _complex("D", D)
        self.N = None if N is None else _complex("N", N)
        self.Qc = None if Qc is None else _complex("Qc", Qc)
        self.Rc = None if Rc is None else _complex("Rc", Rc)
        _check_hermitian("Q", self.Q)
        _check_hermitian("R", self.R)
        for name, c in (("Qc", self.Qc), ("Rc", self.Rc)):
            if c is not None:
                _check_symmetric(name, c)
        self.real = LinearGaussian(
            realify(self.F),
            realify(self.H),
            real_covariance(self.Q, self.Qc),
            real_covariance(self.R, self.Rc),
            B=None if self.B is None else realify(self.B),
            D=None if self.D is None else realify(self.D),
            N=None if self.N is None else real_covariance(self.N, None),
        )

    @property
    def n_states(self) -> int:
        return self.real.n_states // 2

    @property
    def n_obs(self) -> int:
        return self.real.n_obs // 2

    def __repr__(self) -> str:
        proper = "proper" if self.Qc is None and self.Rc is None else "improper"
        return f"ComplexLinearGaussian(n_states={self.n_states}, n_obs={self.n_obs}, {proper} noise)"

    def _data(self, y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike], P0c: Optional[ArrayLike]):
        n, m = self.n_states, self.n_obs
        yc = np.asarray(y)
        if yc.dtype.kind not in "fiuc":
            raise KfastError(f"y: expected numbers, got dtype {yc.dtype}")
        if yc.ndim == 1 and m == 1:
            yc = yc[:, None]
        if yc.ndim != 2 or yc.shape[1] != m:
            raise KfastError(f"y: expected shape (T, {m}), got {yc.shape}")
        yr = np.empty((len(yc), 2 * m))
        yr[:, :m] = yc.real
        yr[:, m:] = yc.imag if np.iscomplexobj(yc) else 0.0
        if np.isnan(yr).any():  # a component is missing when either part is
            missing = np.isnan(yr[:, :m]) | np.isnan(yr[:, m:])
            yr[:, :m][missing] = np.nan
            yr[:, m:][missing] = np.nan
        x0c = _complex("x0", x0, ndim_min=1).reshape(-1)
        if x0c.shape != (n,):
            raise KfastError(f"x0: expected {n} entries, got {x0c.shape}")
        P0_ = _complex("P0", P0)
        _check_hermitian("P0", P0_)
        P0c_ = None if P0c is None else _complex("P0c", P0c)
        if P0c_ is not None:
            _check_symmetric("P0c", P0c_)
        ur = None
        if u is not None:
            uc = _complex("u", u, ndim_min=1)
            uc = uc[:, None] if uc.ndim == 1 else uc
            ur = np.concatenate([uc.real, uc.imag], axis=1)
        return yr, np.r_[x0c.real, x0c.imag], real_covariance(P0_, P0c_), ur

    def _proper(self, P0c: Optional[ArrayLike]) -> bool:
        """Proper noise and prior: every covariance the filter makes is proper too (strictly
        linear maps and the removal of whole complex components preserve it)."""
        return self.Qc is None and self.Rc is None and P0c is None

    def _result(self, res: Any, proper: bool) -> ComplexFilterResult:
        return ComplexFilterResult(res, self.n_states, self.n_obs, proper)

    def filter(
        self, y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike] = None, P0c: Optional[ArrayLike] = None
    ) -> ComplexFilterResult:
        """The Kalman filter (the widely linear one for improper noise) over the complex data
        ``y`` (T, m) from the prior x(0|-1) ~ (x0, P0, P0c); see the module docstring."""
        yr, x0r, P0r, ur = self._data(y, x0, P0, u, P0c)
        return self._result(self.real.filter(yr, x0r, P0r, u=ur), self._proper(P0c))

    def loglik(
        self, y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike] = None, P0c: Optional[ArrayLike] = None
    ) -> float:
        """The exact log-likelihood (the real 2m-dimensional one)."""
        yr, x0r, P0r, ur = self._data(y, x0, P0, u, P0c)
        return self.real.loglik(yr, x0r, P0r, u=ur)

    def smooth(
        self, y: ArrayLike, x0: ArrayLike, P0: ArrayLike, u: Optional[ArrayLike] = None, P0c: Optional[ArrayLike] = None
    ) -> ComplexSmootherResult:
        """The RTS smoother in complex form."""
        yr, x0r, P0r, ur = self._data(y, x0, P0, u, P0c)
        res = self.real.smooth(yr, x0r, P0r, u=ur)
        assert res.x_smooth is not None and res.P_smooth is not None
        n, proper = self.n_states, self._proper(P0c)
        return ComplexSmootherResult(
            x_smooth=complex_vector(res.x_smooth, n),
            P_smooth=complex_covariance(res.P_smooth, n, proper=proper),
            P_smooth_c=complex_covariance(res.P_smooth, n, complementary=True, proper=proper),
            filter=self._result(res.filter, proper),
            real=res,
        )
