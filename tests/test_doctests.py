"""The Examples in the docstrings of the installed kfast run and print what they show.

Every module of the package (and the compiled kfast._kfast, whose docstrings come from the
Rust doc comments) goes through doctest with NORMALIZE_WHITESPACE and ELLIPSIS; ``np`` and
``kfast`` are available to every example, as in numpy's own docs. The public API must keep
its numpydoc sections and examples, so they cannot silently vanish.
"""

from __future__ import annotations

import doctest
import importlib
import inspect

import numpy as np
import pytest

import kfast

MODULES = [
    "kfast",
    "kfast.linear.model",
    "kfast._kfast",
    "kfast.linear.batch",
    "kfast.nonlinear.batch",
    "kfast.sigma",
    "kfast.linear.estimation",
    "kfast.sampling",
    "kfast.riccati.solvers",
    "kfast.riccati.stationary",
    "kfast.models",
    "kfast.control.lq",
    "kfast.control.lqg",
    "kfast.control.dp",
    "kfast.control.polynomial",
    "kfast.control.adaptive",
    "kfast.poly.spectral",
    "kfast.poly.equations",
    "kfast.poly.arma",
    "kfast.poly.wiener",
    "kfast.poly.varmax",
]

FLAGS = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS

# At least this many examples in all (there were 99 when this was written).
MIN_EXAMPLES = 90

LG = kfast.LinearGaussian
# The public API and the numpydoc sections its docstrings must have (all but the streaming
# objects' methods, which the classes' examples show, also "Examples").
DOCUMENTED = {
    "LinearGaussian": (LG, ("Parameters", "Raises", "Notes")),
    "LinearGaussian.from_continuous": (LG.from_continuous, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.filter": (LG.filter, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.loglik": (LG.loglik, ("Parameters", "Returns", "Raises")),
    "LinearGaussian.smooth": (LG.smooth, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.smooth_fixed_lag": (LG.smooth_fixed_lag, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.smooth_fixed_point": (LG.smooth_fixed_point, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.forecast": (LG.forecast, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.simulate": (LG.simulate, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.em": (LG.em, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.steady_state": (LG.steady_state, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.innovations_form": (LG.innovations_form, ("Returns", "Raises")),
    "LinearGaussian.stationary_cov": (LG.stationary_cov, ("Returns", "Raises")),
    "LinearGaussian.autocovariance": (LG.autocovariance, ("Parameters", "Returns", "Raises", "Notes")),
    "LinearGaussian.spectral_density": (LG.spectral_density, ("Parameters", "Returns", "Raises", "Notes")),
    "FilterResult.forecast": (kfast.FilterResult.forecast, ("Parameters", "Returns", "Raises")),
    "KalmanFilter": (kfast.KalmanFilter, ("Parameters", "Raises", "Notes")),
    "FixedLagSmoother": (kfast.FixedLagSmoother, ("Parameters", "Raises", "Notes")),
    "filter_batch": (kfast.filter_batch, ("Parameters", "Returns", "Raises", "Notes")),
    "ekf_batch": (kfast.ekf_batch, ("Parameters", "Returns", "Raises")),
    "fit": (kfast.fit, ("Parameters", "Returns", "Raises", "Notes")),
    "solve_discrete_are": (kfast.solve_discrete_are, ("Parameters", "Returns", "Raises", "Notes")),
    "solve_continuous_are": (kfast.solve_continuous_are, ("Parameters", "Returns", "Raises", "Notes")),
    "solve_discrete_lyapunov": (kfast.solve_discrete_lyapunov, ("Parameters", "Returns", "Raises", "Notes")),
    "solve_continuous_lyapunov": (kfast.solve_continuous_lyapunov, ("Parameters", "Returns", "Raises", "Notes")),
    "discretize": (kfast.discretize, ("Parameters", "Returns", "Raises", "Notes")),
    "expm": (kfast.expm, ("Parameters", "Returns", "Raises", "Notes")),
    "kalman_bucy": (kfast.kalman_bucy, ("Parameters", "Returns", "Raises", "Notes")),
    "stationary_cov_continuous": (kfast.stationary_cov_continuous, ("Parameters", "Returns", "Raises")),
    "control.lqr": (kfast.control.lqr, ("Parameters", "Returns", "Raises")),
    "control.lq_finite": (kfast.control.lq_finite, ("Parameters", "Returns")),
    "control.lqg": (kfast.control.lqg, ("Parameters", "Returns")),
    "control.dynamic_programming": (kfast.control.dynamic_programming, ("Parameters", "Returns")),
}
# Methods of the streaming objects: parameters and errors.
for cls in (kfast.KalmanFilter, kfast.FixedLagSmoother):
    for method in ("update", "predict"):
        DOCUMENTED[f"{cls.__name__}.{method}"] = (getattr(cls, method), ("Parameters", "Raises"))
WITHOUT_EXAMPLES = {name for name in DOCUMENTED if name.endswith((".update", ".predict"))}


def run_module(name: str) -> doctest.TestResults:
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in finder.find(module, extraglobs={"np": np, "kfast": kfast}):
        runner.run(test)
    return runner.summarize(verbose=False)


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name, capsys):
    failed, attempted = run_module(name)
    report = capsys.readouterr().out
    assert failed == 0, report


def test_examples_are_many():
    attempted = sum(run_module(name).attempted for name in MODULES)
    assert attempted >= MIN_EXAMPLES


@pytest.mark.parametrize("name", DOCUMENTED)
def test_public_api_has_numpydoc_sections_and_examples(name):
    obj, sections = DOCUMENTED[name]
    doc = inspect.cleandoc(obj.__doc__ or "")
    if name not in WITHOUT_EXAMPLES:
        sections += ("Examples",)
        assert "\n>>> " in doc, f"{name}: no example"
    for section in sections:
        assert f"\n{section}\n{'-' * len(section)}\n" in doc, f"{name}: no {section} section"
