"""Optimal control (Söderström ch. 10-11). Sign convention everywhere: u = -L x.

- :func:`lqr` — the stationary LQ regulator (the DARE through duality, (11.47)-(11.48));
- :func:`lq_finite` — the finite-horizon regulator, time-varying data allowed ((11.6)-(11.7));
- :func:`lqg` — stationary LQG by separation (Thm 11.3): regulator realisation, closed loop,
  variances and cost, k = 0 or 1;
- :func:`return_difference` ((11.49)), :func:`reference_gain` ((11.89)),
  :func:`lqr_integral` ((11.90)-(11.91)), :func:`ltr_gain` ((11.105)-(11.108));
- :func:`minimum_variance` ((11.51)-(11.69), Ex. 11.5) and :func:`lqg_polynomial`
  ((11.74)-(11.88)): polynomial regulators R u = -S y for ARMAX models;
- :func:`dynamic_programming` — stochastic dynamic programming on finite grids (Lemma 10.4);
  :func:`certainty_equivalence_control` and :func:`cautious_control` — the one-step laws of
  Sec. 10.2 for an ARX model with estimated parameters ((10.70), (10.74)).
"""

from kfast.control.adaptive import cautious_control, certainty_equivalence_control
from kfast.control.dp import DPResult, dynamic_programming
from kfast.control.lq import LQFiniteResult, LQResult, lq_finite, lqr
from kfast.control.polynomial import PolynomialRegulator, closed_loop_variance, lqg_polynomial, minimum_variance
from kfast.control.lqg import IntegralLQResult, LQGResult, lqg, lqr_integral, ltr_gain, reference_gain, return_difference

__all__ = [
    "lqr",
    "lq_finite",
    "lqg",
    "return_difference",
    "reference_gain",
    "lqr_integral",
    "ltr_gain",
    "dynamic_programming",
    "certainty_equivalence_control",
    "cautious_control",
    "minimum_variance",
    "lqg_polynomial",
    "closed_loop_variance",
    "PolynomialRegulator",
    "LQResult",
    "LQFiniteResult",
    "LQGResult",
    "IntegralLQResult",
    "DPResult",
]
