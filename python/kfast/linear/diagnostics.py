"""Diagnostics of a filter run: is the model consistent with the data?

Under the true model the innovations e(t) are zero-mean and white with covariance S(t)
(Söderström ex. 6.16), and in a simulation the error x(t) - x(t|t) has covariance P(t|t).
:meth:`FilterResult.diagnostics <kfast.FilterResult.diagnostics>` tests both; the tests and
their conventions are in docs/algorithms.md, "Filter diagnostics".
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from kfast import _kfast
from kfast._args import index
from kfast._arrays import as_float64
from kfast._numbers import real_scalar

if TYPE_CHECKING:
    from kfast.linear.model import FilterResult

__all__ = ["Diagnostics", "diagnostics", "plot_diagnostics", "chi_square_sf", "chi_square_quantile"]


@dataclass(frozen=True, repr=False)
class Diagnostics:
    """The consistency tests of a filter run of T steps, n states, m outputs.

    NIS and NEES follow Bar-Shalom, Li & Kirubarajan (2001) Sec. 5.4; the standardized innovations,
    Ljung–Box and Jarque–Bera tests are statsmodels' (``standardized_forecasts_error``,
    ``test_serial_correlation``, ``test_normality``). Every bound is two-sided and holds with
    probability ``1 - alpha`` under the model.
    """

    standardized_innov: np.ndarray
    """L(t)^-1 e(t) with S(t) = L L' (Cholesky) over the observed components, shape (T, m);
    N(0, I) and white under the model. NaN where y is missing."""
    nis: np.ndarray
    """Normalized innovation squared e' S^-1 e over the observed components, shape (T,);
    ~ chi2(m_t). NaN where nothing is observed."""
    nis_dof: np.ndarray
    """m_t, the number of components observed at each step (the degrees of freedom), (T,)."""
    nis_bounds: np.ndarray
    """The chi2(m_t) quantiles alpha/2 and 1 - alpha/2, shape (T, 2); NaN where nothing is
    observed."""
    nis_mean: float
    """The average NIS over the observed steps after ``burn`` (expected value: the average m_t)."""
    nis_mean_bounds: np.ndarray
    """Its bounds, shape (2,): K * nis_mean ~ chi2(sum of m_t) over the K steps averaged."""
    acf: np.ndarray
    """Sample autocorrelations r_0 .. r_lags of each standardized component after ``burn``,
    shape (lags + 1, m) (r_0 = 1); missing steps are left out of the sums
    (statsmodels' ``acf(..., missing="conservative")``)."""
    acf_bound: np.ndarray
    """The white-noise bound z_(1-alpha/2) / sqrt(N) of each component's r_k, shape (m,),
    N = the number of observed steps tested."""
    ljung_box: np.ndarray
    """Ljung–Box Q(h) = N (N + 2) sum_(k<=h) r_k^2 / (N - k), h = 1..lags, shape (lags, m)."""
    ljung_box_pvalue: np.ndarray
    """P(chi2(h) > Q(h)), shape (lags, m): small values reject whiteness."""
    jarque_bera: np.ndarray
    """Jarque–Bera JB = N/6 (skew^2 + (kurtosis - 3)^2 / 4) per component, shape (m,)."""
    jarque_bera_pvalue: np.ndarray
    """P(chi2(2) > JB), shape (m,): small values reject normality."""
    skew: np.ndarray
    """Sample skewness of each standardized component (biased moments, as scipy.stats.skew)."""
    kurtosis: np.ndarray
    """Sample kurtosis (3 for a normal sample; biased moments)."""
    nees: Optional[np.ndarray] = None
    """Normalized estimation error squared (x - x(t|t))' P(t|t)^-1 (x - x(t|t)), shape (T,);
    ~ chi2(n). Only with ``x_true``."""
    nees_bounds: Optional[np.ndarray] = None
    """The chi2(n) quantiles alpha/2 and 1 - alpha/2, shape (2,)."""
    nees_mean: Optional[float] = None
    """The average NEES over the steps after ``burn`` (expected value: n)."""
    nees_mean_bounds: Optional[np.ndarray] = None
    """Its bounds: K * nees_mean ~ chi2(K n) over the K steps averaged."""
    lags: int = 10
    burn: int = 0
    alpha: float = 0.05

    @property
    def nis_fraction_inside(self) -> float:
        """The fraction of observed steps whose NIS lies inside its bounds (about 1 - alpha
        under the model)."""
        seen = self.nis_dof > 0
        inside = (self.nis >= self.nis_bounds[:, 0]) & (self.nis <= self.nis_bounds[:, 1])
        return float(inside[seen].mean())

    def __repr__(self) -> str:
        lb = np.array2string(self.ljung_box_pvalue[-1], precision=3)
        jb = np.array2string(self.jarque_bera_pvalue, precision=3)
        text = (
            f"Diagnostics(nis_mean={self.nis_mean:.4g} in [{self.nis_mean_bounds[0]:.4g}, "
            f"{self.nis_mean_bounds[1]:.4g}], ljung_box_pvalue(lag {self.lags})={lb}, jarque_bera_pvalue={jb}"
        )
        if self.nees_mean is not None and self.nees_mean_bounds is not None:
            text += f", nees_mean={self.nees_mean:.4g} in [{self.nees_mean_bounds[0]:.4g}, {self.nees_mean_bounds[1]:.4g}]"
        return text + ")"


def diagnostics(result: "FilterResult", lags: int = 10, x_true: Any = None, burn: int = 0, alpha: float = 0.05) -> Diagnostics:
    """The body of :meth:`kfast.FilterResult.diagnostics` (see there)."""
    lags, burn = index("lags", lags), index("burn", burn)
    alpha = _probability("alpha", alpha)
    if result.innov is None or result.S is None:
        raise _kfast.KfastError("diagnostics: this FilterResult has no innov or S (left out with outputs=)")
    out: dict = _kfast.innovation_diagnostics(result.innov, result.S, lags, burn, alpha)
    if x_true is not None:
        if result.x_filt is None or result.P_filt is None:
            raise _kfast.KfastError("x_true: this FilterResult has no x_filt or P_filt (left out with outputs=)")
        truth = as_float64("x_true", x_true)
        if truth.ndim == 1 and result.x_filt.shape[1] == 1:
            truth = truth[:, None]
        out.update(_kfast.state_diagnostics(truth, result.x_filt, result.P_filt, burn, alpha))
    return Diagnostics(**out, lags=lags, burn=burn, alpha=alpha)


def plot_diagnostics(result: "FilterResult", component: int = 0, lags: int = 10, fig: Any = None, figsize: Any = None) -> Any:
    """The body of :meth:`kfast.FilterResult.plot_diagnostics` (see there)."""
    try:
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - exercised only without matplotlib
        raise ImportError("plot_diagnostics needs matplotlib: pip install kfast[plot]") from None
    d = diagnostics(result, lags=lags)
    m = d.standardized_innov.shape[1]
    component = index("component", component)
    if component >= m:
        raise _kfast.KfastError(f"component: must be below m = {m}, got {component}")
    z = d.standardized_innov[:, component]
    seen = z[~np.isnan(z)]
    if fig is None:
        fig = plt.figure(figsize=figsize or (10, 7))
    top_left, top_right, bottom_left, bottom_right = (fig.add_subplot(2, 2, k) for k in range(1, 5))

    top_left.plot(z, lw=0.8)
    top_left.axhline(0.0, color="k", lw=0.5)
    top_left.set_title(f"Standardized innovation {component}")

    grid = np.linspace(min(seen.min(), -3.0), max(seen.max(), 3.0), 200)
    top_right.hist(seen, bins="auto", density=True, alpha=0.5, label="Hist")
    top_right.plot(grid, np.exp(-0.5 * grid**2) / np.sqrt(2 * np.pi), label="N(0,1)")
    top_right.legend()
    top_right.set_title("Histogram")

    ordered = np.sort(seen)
    probabilities = (np.arange(1, len(ordered) + 1) - 0.5) / len(ordered)
    theoretical = np.array([_STANDARD_NORMAL.inv_cdf(p) for p in probabilities])
    bottom_left.plot(theoretical, ordered, ".", ms=3)
    bottom_left.plot(theoretical, theoretical, color="r", lw=0.8)
    bottom_left.set_title("Normal Q-Q")

    r = d.acf[1:, component]
    bottom_right.vlines(np.arange(1, lags + 1), 0.0, r)
    bottom_right.plot(np.arange(1, lags + 1), r, "o", ms=4)
    bound = d.acf_bound[component]
    bottom_right.axhspan(-bound, bound, alpha=0.2)
    bottom_right.axhline(0.0, color="k", lw=0.5)
    bottom_right.set_title("Correlogram")
    return fig


# The Q-Q plot's quantiles (a plot, not a test: the standard library's inverse is enough).
_STANDARD_NORMAL = NormalDist()


def chi_square_sf(x: float, k: float) -> float:
    """P(X > x) for X ~ chi2(k): the regularized upper incomplete gamma function Q(k/2, x/2),
    by its series or continued fraction (the p-values of the tests above; no scipy needed)."""
    return float(_kfast.chi_square(float(x), float(k), False))


def chi_square_quantile(p: float, k: float) -> float:
    """The p-quantile of chi2(k), 0 < p < 1 (the NIS and NEES bounds)."""
    return float(_kfast.chi_square(_probability("p", p), float(k), True))


def _probability(name: str, value: object) -> float:
    p = real_scalar(name, value, "a number in (0, 1)")
    if not 0.0 < p < 1.0:
        raise _kfast.KfastError(f"{name}: must be in (0, 1), got {value!r}")
    return p
