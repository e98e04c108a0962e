"""The fuzz campaign's cases and their classification (issue #10; docs/reliability.md).

A *case* is one call of a public entry point with one argument perturbed. Every argument is
written as a Python expression over a small fixture namespace (``M`` the model, ``Y``, ``X0``,
``P0``, ``U`` its data, ...), so a case pickles to the isolated worker (isolation.py) as plain
strings and prints as a one-line reproducer that anyone can paste into ``python -c``.

Each case is classified as exactly one of

* ``error``   a clear error: a ``ValueError`` or ``TypeError`` (``kfast.KfastError`` subclasses
  ``ValueError``) whose message names the offending argument (in its head, before the first
  ": ", or quoted);
* ``valid``   a result that passes the sanity checks (no NaN or inf that the inputs do not
  explain, covariances symmetric positive semidefinite, P(t|t) <= P(t|t-1), P(t|T) <= P(t|t))
  and, when the case has a reference (the same call on the clean float64 input; a masked entry
  is NaN there), equals it;
* a failure, by kind: ``crash`` (the worker died), ``hang`` (timeout), ``panic`` (a
  ``BaseException`` such as ``pyo3_runtime.PanicException``), ``memory`` (MemoryError),
  ``unclear-error`` (another exception type, or a message that does not name the argument),
  ``refused`` (a documented equivalent form, e.g. float32 or a pandas DataFrame, was refused),
  ``accepted-invalid`` (invalid input gave a result), ``mismatch`` (a result different from the
  reference), ``silent-nan`` / ``silent-inf`` (non-finite output from finite input),
  ``garbage`` (a covariance that is not symmetric positive semidefinite, or violates the
  ordering above), ``mutated`` (an input was modified), ``threads`` (more OS threads than
  cores or series).

This module is imported both by the tests (to build cases) and by the worker (to run them).
"""

from __future__ import annotations

import copy
import dataclasses
import os
import re
import threading
import time
from typing import Any, Optional

# Kinds of failure (the order is the report's).
FAILURE_KINDS = (
    "crash",
    "hang",
    "panic",
    "memory",
    "unclear-error",
    "refused",
    "accepted-invalid",
    "mismatch",
    "silent-nan",
    "silent-inf",
    "garbage",
    "mutated",
    "threads",
)


@dataclasses.dataclass(frozen=True)
class Case:
    """One call of one entry point with one perturbation.

    ``expect``: "error" (the input is invalid: a clear error is the only good outcome),
    "equal" (an equivalent form of valid input: the result must equal the reference, and
    refusing it is a failure when ``must_accept``), "either" (a clear error or a sane result,
    equal to the reference when there is one).
    ``reference``: None, or "canonical" (the perturbed arguments converted to clean float64
    arrays, masked entries as NaN), or a dict of replacement argument expressions.
    ``validator``: an optional sibling call (entry name, argument expressions) whose clear
    error means the input is invalid (e.g. ``simulate``'s prior must be one ``filter`` accepts).
    """

    entry: str
    fixture: str
    args: tuple  # ((name, expression), ...)
    perturbed: str
    names: tuple  # argument names an error message may name
    family: str
    variant: str
    expect: str = "either"
    must_accept: bool = False
    reference: Any = None
    validator: Any = None
    rtol: float = 1e-12  # of the comparison with the reference

    def key(self) -> str:
        return f"{self.entry}|{self.fixture}|{self.args}"

    def call_expr(self) -> str:
        return ENTRIES[self.entry].render(dict(self.args))

    def repro(self) -> str:
        """A one-line reproducer: ``python -c "<this>"``."""
        text = self.call_expr()
        used = set()
        for k, v in reversed(FIXTURES[self.fixture]):  # later definitions may use earlier ones
            if re.search(rf"\b{k}\b", text):
                used.add(k)
                text += " " + v
        defs = [f"{k} = {v}" for k, v in FIXTURES[self.fixture] if k in used]
        return "; ".join(["import numpy as np, pandas as pd, kfast", "from numpy import nan, inf", *defs, self.call_expr()])


# --------------------------------------------------------------------------------------------
# fixtures: small valid problems, as (name, expression) definitions evaluated in order

_IO_MODEL = (
    "kfast.LinearGaussian(F=0.9 * np.eye(3), H=np.eye(2, 3) + 0.5, Q=np.eye(3), R=np.eye(2), "
    "B=np.ones((3, 2)), D=np.ones((2, 2)), N=0.1 * np.eye(3, 2))"
)

FIXTURES: dict[str, list[tuple[str, str]]] = {
    # n = 3 states, m = 2 outputs, k = 2 inputs, with B, D and N; T = 6 steps; B = 5 series
    "io": [
        ("M", _IO_MODEL),
        ("Y", "np.sin(np.arange(12.0)).reshape(6, 2)"),
        ("X0", "np.linspace(-1.0, 1.0, 3)"),
        ("P0", "np.eye(3) + 0.5"),
        ("U", "np.cos(np.arange(12.0)).reshape(6, 2)"),
        ("YB", "np.sin(np.arange(60.0)).reshape(5, 6, 2)"),
        ("XB", "np.linspace(-1.0, 1.0, 15).reshape(5, 3)"),
        ("PB", "np.stack([np.eye(3) + 0.5] * 5)"),
        ("UB", "np.cos(np.arange(60.0)).reshape(5, 6, 2)"),
    ],
    # the constant-velocity model: n = 4, m = 2, no inputs
    "cv": [
        ("M", "kfast.models.constant_velocity(2, dt=0.1)"),
        ("Y", "np.sin(np.arange(12.0)).reshape(6, 2)"),
        ("X0", "np.zeros(4)"),
        ("P0", "np.eye(4)"),
        ("YB", "np.sin(np.arange(60.0)).reshape(5, 6, 2)"),
    ],
    # Söderström ex. 6.17: n = m = 1 (scalars allowed)
    "scalar": [
        ("M", "kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)"),
        ("Y", "np.sin(np.arange(6.0))"),
        ("X0", "0.0"),
        ("P0", "1.0"),
    ],
    # Riccati / Lyapunov / sampling problems (n = 2, one input, one output)
    "ric": [
        ("A", "np.array([[1.0, 0.1], [0.0, 1.0]])"),
        ("Bm", "np.array([[0.0], [0.1]])"),
        ("Q2", "np.eye(2)"),
        ("R1", "np.eye(1)"),
        ("AC", "np.array([[0.0, 1.0], [0.0, 0.0]])"),
        ("BC", "np.array([[0.0], [1.0]])"),
        ("AS", "np.array([[0.5, 0.2], [0.0, 0.3]])"),
        ("AH", "np.array([[-1.0, 0.5], [0.0, -2.0]])"),
        ("H2", "np.array([[1.0, 0.0]])"),
    ],
}

FIXTURE_DIMS = {"io": dict(n=3, m=2, k=2, T=6, B=5), "cv": dict(n=4, m=2, k=0, T=6, B=5), "scalar": dict(n=1, m=1, k=0, T=6)}


# --------------------------------------------------------------------------------------------
# entry points: how to call them, and their arguments


@dataclasses.dataclass(frozen=True)
class Arg:
    """An argument: its good expression, kind ("array", "int", "float", "str", "bool",
    "object"), the shape of the good array, other documented valid shapes, whether it is a
    covariance (symmetric PSD) and whether NaN in it means "missing" (data)."""

    name: str
    good: str
    kind: str = "array"
    shape: tuple = ()
    alt_shapes: tuple = ()
    cov: bool = False
    data: bool = False
    names: tuple = ()
    huge_reference: Optional[str] = None  # for ints: the equivalent of a huge value, if any
    stackable: bool = False  # a model matrix: a leading axis of any length is a per-step stack
    free_length: bool = False  # the length of the first axis is free (data steps, lags, ...)
    none_ok: bool = False  # None is a valid value (e.g. "use the model's")
    optional: bool = False

    @property
    def error_names(self) -> tuple:
        return self.names or (self.name,)


@dataclasses.dataclass(frozen=True)
class Entry:
    """A public entry point: ``template`` is the call with ``{name}`` holes (``{kw}`` for the
    keyword arguments not placed in the template)."""

    name: str
    fixture: str
    template: str
    args: tuple
    watch_threads: bool = False
    result_name: str = "result"  # the name of a bare (non-record) result, for the sanity checks
    inf_ok: bool = False  # an overflowing exact result (e.g. expm) may be inf
    raw: bool = False  # a compiled method that takes C-contiguous float64 arrays only: fuzzed for shapes
    validator: Optional[tuple] = None  # (entry name, {arg: arg}) mapping of the sibling call
    complex_ok: bool = False  # complex arrays are valid input (the Riccati and Lyapunov solvers)
    complex_model: bool = False  # complex arrays make a complex-valued model (another result type)

    def render(self, args: dict) -> str:
        placed = set(re.findall(r"\{(\w+)\}", self.template)) - {"kw"}
        kw = ", ".join(f"{k}={v}" for k, v in args.items() if k not in placed and v is not None)
        filled = {k: args.get(k) for k in placed}
        return self.template.format(kw=kw, **filled)

    def good_args(self) -> dict:
        return {a.name: a.good for a in self.args if not a.optional}

    def arg(self, name: str) -> Arg:
        return next(a for a in self.args if a.name == name)


def _data_args(n, m, k, T=6, u=True, scalar=False):
    y = Arg("y", "Y", shape=(T,) if scalar else (T, m), data=True, free_length=not u)
    x0 = Arg("x0", "X0", shape=() if scalar else (n,), alt_shapes=((1,),) if scalar else ())
    P0 = Arg("P0", "P0", shape=() if scalar else (n, n), cov=True, alt_shapes=((1,), (1, 1)) if scalar else ())
    out = [y, x0, P0]
    if u:
        out.append(Arg("u", "U", shape=(T, k), names=("u",)))
    return out


_MODEL_NAMES = ("model", "x0", "P0", "y", "Y", "u")  # another model may not fit the data
_IO = _data_args(3, 2, 2)
_CV = _data_args(4, 2, 0, u=False)
_SC = _data_args(1, 1, 0, u=False, scalar=True)
_FORM = Arg("form", "'joseph'", kind="str", optional=True)

_ENTRY_LIST = [
    Entry(
        "LinearGaussian",
        "io",
        "kfast.LinearGaussian({kw})",
        (
            Arg("F", "0.9 * np.eye(3)", shape=(3, 3), stackable=True),
            Arg("H", "np.eye(2, 3) + 0.5", shape=(2, 3), stackable=True),
            Arg("Q", "np.eye(3)", shape=(3, 3), cov=True, stackable=True, names=("Q", "N")),
            Arg("R", "np.eye(2)", shape=(2, 2), cov=True, stackable=True, names=("R", "N")),
            # B, D, N default to None (no inputs, no cross-covariance): None is valid
            Arg("B", "np.ones((3, 2))", shape=(3, 2), stackable=True, none_ok=True),
            Arg("D", "np.ones((2, 2))", shape=(2, 2), stackable=True, none_ok=True),
            Arg("N", "0.1 * np.eye(3, 2)", shape=(3, 2), stackable=True, none_ok=True),
        ),
        complex_model=True,
    ),
    Entry("filter", "io", "M.filter({kw})", (*_IO, _FORM, Arg("converge_tol", "None", kind="float", optional=True),
                                             Arg("outputs", "None", kind="outputs", optional=True)), validator=None),
    Entry("filter_scalar", "scalar", "M.filter({kw})", (*_SC, Arg("steady_state", "False", kind="bool", optional=True))),
    Entry("loglik", "io", "M.loglik({kw})", (*_IO, _FORM, Arg("converge_tol", "None", kind="float", optional=True)), result_name="loglik"),
    Entry("smooth", "io", "M.smooth({kw})", (*_IO, _FORM, Arg("outputs", "None", kind="outputs", optional=True))),
    Entry("smooth_cv", "cv", "M.smooth({kw})", (*_CV,)),
    Entry(
        "smooth_fixed_lag",
        "io",
        "M.smooth_fixed_lag({kw})",
        (*_IO, Arg("lag", "2", kind="int", huge_reference="5"), _FORM),
    ),
    Entry("smooth_fixed_point", "io", "M.smooth_fixed_point({kw})", (*_IO, Arg("t_point", "2", kind="int"), _FORM)),
    Entry(
        "forecast",
        "io",
        "M.forecast({kw})",
        (
            Arg("x", "X0", shape=(3,)),
            Arg("P", "P0", shape=(3, 3), cov=True),
            Arg("steps", "6", kind="int", names=("steps", "u")),
            Arg("u", "U", shape=(6, 2), names=("u", "steps")),
        ),
        validator=("filter", {"x0": "x", "P0": "P"}),
    ),
    Entry("forecast_cv", "cv", "M.forecast({kw})", (Arg("x", "X0", shape=(4,)), Arg("P", "P0", shape=(4, 4), cov=True),
                                                     Arg("steps", "6", kind="int")), validator=("smooth_cv", {"x0": "x", "P0": "P"})),
    Entry(
        "simulate",
        "io",
        "M.simulate({kw})",
        (
            Arg("T", "6", kind="int", names=("T", "u")),
            Arg("x0", "X0", shape=(3,)),
            Arg("P0", "P0", shape=(3, 3), cov=True),
            Arg("u", "U", shape=(6, 2), names=("u", "T")),
            Arg("seed", "0", kind="seed"),
        ),
        validator=("filter", {"x0": "x0", "P0": "P0", "u": "u"}),
    ),
    Entry(
        "em",
        "cv",
        "M.em({kw})",
        (*_CV, Arg("n_iter", "2", kind="int"), Arg("fit", "('F', 'Q', 'R')", kind="fit", optional=True),
         Arg("tol", "None", kind="float", optional=True)),
        validator=("smooth_cv", {"y": "y", "x0": "x0", "P0": "P0"}),
    ),
    Entry(
        "filter_batch",
        "io",
        "kfast.filter_batch({kw})",
        (
            Arg("model", "M", kind="object", names=_MODEL_NAMES),
            Arg("Y", "YB", shape=(5, 6, 2), data=True),
            Arg("x0", "XB", shape=(5, 3), alt_shapes=((3,),)),
            Arg("P0", "PB", shape=(5, 3, 3), alt_shapes=((3, 3),), cov=True),
            Arg("u", "UB", shape=(5, 6, 2), alt_shapes=((6, 2),)),
            Arg("return_covs", "True", kind="bool", optional=True),
            Arg("threads", "2", kind="int", huge_reference="None", optional=True),
            _FORM,
        ),
        watch_threads=True,
    ),
    Entry(
        "KalmanFilter",
        "io",
        "(kf := kfast.KalmanFilter({model}, {x0}, {P0}, form={form}), [kf.step({y2} if t == 2 else Y[t], {u2} if t == 2 else U[t]) "
        "for t in range(6)], dict(x=kf.x, P=kf.P, t=kf.t, loglik=kf.loglik))[-1]",
        (
            Arg("model", "M", kind="object", names=_MODEL_NAMES),
            Arg("x0", "X0", shape=(3,)),
            Arg("P0", "P0", shape=(3, 3), cov=True),
            Arg("y2", "Y[2]", shape=(2,), data=True, names=("y",)),
            Arg("u2", "U[2]", shape=(2,), names=("u",)),
            Arg("form", "'joseph'", kind="str"),
        ),
        validator=("filter", {"x0": "x0", "P0": "P0"}),
    ),
    Entry(
        "KalmanFilter_HR",
        "io",
        "(kf := kfast.KalmanFilter(M, X0, P0), kf.update(Y[0], U[0], H={H}, R={R}), dict(x=kf.x, P=kf.P, loglik=kf.loglik))[-1]",
        (
            Arg("H", "np.eye(2, 3)", shape=(2, 3), none_ok=True),
            Arg("R", "2.0 * np.eye(2)", shape=(2, 2), cov=True, none_ok=True),
        ),
    ),
    Entry(
        "FixedLagSmoother",
        "io",
        "(fl := kfast.FixedLagSmoother({model}, {x0}, {P0}, {lag}), [fl.step({y2} if t == 2 else Y[t], U[t]) for t in range(6)], "
        "dict(x_lagged=fl.x_lagged, P_lagged=fl.P_lagged, x_window=fl.x_window, P_window=fl.P_window))[-1]",
        (
            Arg("model", "M", kind="object", names=_MODEL_NAMES),
            Arg("x0", "X0", shape=(3,)),
            Arg("P0", "P0", shape=(3, 3), cov=True),
            Arg("lag", "2", kind="int", huge_reference="6"),
            Arg("y2", "Y[2]", shape=(2,), data=True, names=("y",)),
        ),
        validator=("filter", {"x0": "x0", "P0": "P0"}),
    ),
    Entry("steady_state", "cv", "M.steady_state({kw})", (Arg("method", "'doubling'", kind="str"),)),
    Entry("autocovariance", "io", "M.autocovariance({kw})", (Arg("lags", "[0, 1, 2]", shape=(3,), alt_shapes=((),), free_length=True),)),
    Entry("spectral_density", "io", "M.spectral_density({kw})", (Arg("omega", "np.linspace(0.0, 3.0, 4)", shape=(4,), alt_shapes=((),),
                                                                      free_length=True),
                                                                  Arg("h", "1.0", kind="float"))),
    Entry(
        "fit",
        "scalar",
        "kfast.fit({kw})",
        (Arg("build", "lambda th: (kfast.LinearGaussian(F=0.8, H=1.0, Q=np.exp(np.sum(th)), R=1.0), 0.0, 1.0)", kind="object"),
         Arg("theta0", "[0.0]", shape=(1,), names=("theta0", "build"), free_length=True), Arg("y", "Y", shape=(6,), data=True, free_length=True)),
    ),
    Entry(
        "solve_discrete_are",
        "ric",
        "kfast.solve_discrete_are({kw})",
        (
            Arg("a", "A", shape=(2, 2)),
            Arg("b", "Bm", shape=(2, 1)),
            Arg("q", "Q2", shape=(2, 2)),
            Arg("r", "R1", shape=(1, 1), alt_shapes=((),)),
            Arg("method", "'doubling'", kind="str", optional=True),
        ),
        complex_ok=True,
    ),
    Entry(
        "solve_continuous_are",
        "ric",
        "kfast.solve_continuous_are({kw})",
        (Arg("a", "AC", shape=(2, 2)), Arg("b", "BC", shape=(2, 1)), Arg("q", "Q2", shape=(2, 2)),
         Arg("r", "R1", shape=(1, 1), alt_shapes=((),))),
        complex_ok=True,
    ),
    Entry("solve_discrete_lyapunov", "ric", "kfast.solve_discrete_lyapunov({kw})",
          (Arg("a", "AS", shape=(2, 2)), Arg("q", "Q2", shape=(2, 2))), complex_ok=True),
    Entry("solve_continuous_lyapunov", "ric", "kfast.solve_continuous_lyapunov({kw})",
          (Arg("a", "AH", shape=(2, 2)), Arg("q", "Q2", shape=(2, 2))), complex_ok=True),
    Entry("expm", "ric", "kfast.expm({kw})", (Arg("a", "AH", shape=(2, 2)),), inf_ok=True),
    Entry(
        "discretize",
        "ric",
        "kfast.discretize({kw})",
        (Arg("A", "AH", shape=(2, 2)), Arg("Qc", "Q2", shape=(2, 2), cov=True), Arg("dt", "0.1", kind="float"),
         # B may have any number k >= 1 of columns (inputs)
         Arg("B", "BC", shape=(2, 1), optional=True, alt_shapes=((2, 2), (2, 3), (2, 4)))),
    ),
    Entry(
        "from_continuous",
        "ric",
        "kfast.LinearGaussian.from_continuous({kw})",
        (Arg("A", "AH", shape=(2, 2)), Arg("Qc", "Q2", shape=(2, 2), cov=True), Arg("H", "H2", shape=(1, 2), stackable=True, names=("H", "R")),
         Arg("R", "R1", shape=(1, 1), alt_shapes=((),), cov=True, stackable=True), Arg("dt", "0.1", kind="float")),
        complex_model=True,
    ),
    Entry("kalman_bucy", "ric", "kfast.kalman_bucy({kw})",
          (Arg("A", "AC", shape=(2, 2)), Arg("Qc", "Q2", shape=(2, 2), cov=True), Arg("H", "H2", shape=(1, 2)),
           Arg("Rc", "R1", shape=(1, 1), alt_shapes=((),), cov=True))),
    Entry("stationary_cov_continuous", "ric", "kfast.stationary_cov_continuous({kw})",
          (Arg("A", "AH", shape=(2, 2)), Arg("Qc", "Q2", shape=(2, 2), cov=True))),
    Entry("constant_velocity", "ric", "kfast.models.constant_velocity({kw})",
          (Arg("dim", "2", kind="int"), Arg("dt", "0.1", kind="float"), Arg("q", "1.0", kind="float"), Arg("r", "1.0", kind="float"))),
    Entry("singer", "ric", "kfast.models.singer({kw})",
          (Arg("dt", "0.1", kind="float"), Arg("alpha", "0.5", kind="float"), Arg("sigma_m2", "1.0", kind="float"),
           Arg("dim", "1", kind="int", optional=True))),
    Entry("damped_resonator", "ric", "kfast.models.damped_resonator({kw})",
          (Arg("omega", "2.0", kind="float"), Arg("tau", "3.0", kind="float"), Arg("q", "1.0", kind="float"), Arg("dt", "0.1", kind="float"))),
    Entry("ar", "ric", "kfast.models.ar({kw})",
          (Arg("coeffs", "[0.5, -0.2]", shape=(2,), alt_shapes=((),), free_length=True), Arg("noise_var", "1.0", kind="float"), Arg("r", "0.5", kind="float"))),
]
_MODE_PROBS = Arg("mode_probs", "np.array([0.5, 0.5])", shape=(2,), optional=True)
_ENTRY_LIST += [
    # the multiple-model filters over two copies of the CV model
    Entry("imm_filter", "cv", "kfast.imm_filter([M, M], {kw})",
          (Arg("transition", "np.array([[0.9, 0.1], [0.2, 0.8]])", shape=(2, 2)), *_CV, _MODE_PROBS)),
    Entry("model_bank", "cv", "kfast.model_bank([M, M], {kw})", (*_CV, _MODE_PROBS)),
]
_ENTRY_LIST += [
    # quantized measurements
    Entry("quantize", "ric", "kfast.quantize({kw})",
          (Arg("x", "np.array([[0.3, -1.5], [2.5, 0.49], [0.0, 7.0]])", shape=(3, 2), data=True, free_length=True,
               alt_shapes=((2,), (2, 3, 2), (3, 2, 2), (1, 3, 2)), names=("x", "delta")),  # any leading axes
           Arg("delta", "np.array([0.5, 1.0])", shape=(2,), alt_shapes=((),), names=("delta", "x"))), result_name="quantized"),
    Entry("sheppard", "ric", "kfast.sheppard({kw})",
          (Arg("R", "R1", shape=(1, 1), alt_shapes=((),), cov=True), Arg("delta", "0.5", kind="float")), result_name="R"),
    Entry("quantized_loglik", "ric", "kfast.quantized_loglik({kw})",
          (Arg("y", "np.array([1.0, -0.5])", shape=(2,), data=True, names=("y", "y_hat")),
           Arg("y_hat", "np.array([[0.9, -0.4], [1.2, 0.1], [0.0, 0.0]])", shape=(3, 2), free_length=True),
           Arg("R", "np.diag([0.1, 0.2])", shape=(2, 2)), Arg("delta", "np.array([0.5, 0.5])", shape=(2,), alt_shapes=((),))),
          result_name="loglik", inf_ok=True),
    Entry("quantized_moments", "ric", "kfast.quantized_moments({kw})",
          (Arg("delta", "1.0", kind="float"), Arg("mean", "0.3", kind="float"), Arg("std", "0.4", kind="float"),
           Arg("distribution", "'gaussian'", kind="str", optional=True))),
]
_ENTRY_LIST += [
    # the compiled model's simulation kernel (reachable as model._core.propagate)
    Entry("propagate", "io", "M._core.propagate({kw})",
          (Arg("x_init", "X0", shape=(3,)), Arg("w", "np.zeros((6, 3))", shape=(6, 3)), Arg("v", "np.zeros((6, 2))", shape=(6, 2)),
           Arg("u", "U", shape=(6, 2))), raw=True),
    # any expression (the reproducers; its reference may be another expression)
    Entry("expression", "io", "{e}", (Arg("e", "None", kind="expression"),)),
    Entry("expression_cv", "cv", "{e}", (Arg("e", "None", kind="expression"),)),
    Entry("expression_ric", "ric", "{e}", (Arg("e", "None", kind="expression"),), inf_ok=True),
]
ENTRIES = {e.name: e for e in _ENTRY_LIST}


# --------------------------------------------------------------------------------------------
# the worker side: evaluate, call, classify

_NAMESPACES: dict = {}


def _namespace(fixture: str) -> dict:
    """The fixture's definitions, evaluated once per worker (they are never handed out
    mutable: each case evaluates its argument expressions afresh)."""
    if fixture not in _NAMESPACES:
        import numpy as np
        import pandas as pd

        import kfast

        ns = {"np": np, "pd": pd, "kfast": kfast, "nan": float("nan"), "inf": float("inf")}
        for k, v in FIXTURES[fixture]:
            ns[k] = eval(v, ns)
        _NAMESPACES[fixture] = ns
    return _NAMESPACES[fixture]


def _fresh_ns(fixture: str) -> dict:
    """A namespace with fresh copies of the fixture's arrays, so that a mutation by one case
    cannot leak into another (and is detected on the copies)."""
    import numpy as np

    ns = dict(_namespace(fixture))
    for k, v in list(ns.items()):
        if isinstance(v, np.ndarray):
            ns[k] = v.copy()
    return ns


def canonical(value):
    """The clean float64 equivalent of an array-like: masked entries become NaN, pandas
    objects their values, everything else ``np.array(value, dtype=float)``."""
    import numpy as np

    if isinstance(value, np.ma.MaskedArray):
        return np.ma.filled(value.astype(np.float64), np.nan)
    if hasattr(value, "to_numpy"):
        return value.to_numpy(dtype=np.float64)
    if isinstance(value, (bool, np.bool_)):
        return np.float64(value)
    arr = np.asarray(value)
    if arr.dtype.kind == "c":
        arr = arr.real
    return np.array(arr, dtype=np.float64)


def _snapshot(value):
    import numpy as np

    if isinstance(value, np.ndarray):
        return (value.copy(), value.flags.writeable, np.ma.getmaskarray(value).copy() if isinstance(value, np.ma.MaskedArray) else None)
    try:
        return copy.deepcopy(value)
    except Exception:
        return None


def _unchanged(before, value) -> bool:
    import numpy as np

    if isinstance(value, np.ndarray):
        data, writeable, mask = before
        same = data.shape == value.shape and np.array_equal(np.asarray(data), np.asarray(value), equal_nan=data.dtype.kind in "fc")
        if mask is not None:
            same = same and np.array_equal(mask, np.ma.getmaskarray(value))
        return bool(same and writeable == value.flags.writeable)
    if hasattr(value, "equals"):
        return bool(before.equals(value))
    if isinstance(value, (list, tuple)):
        try:
            return bool(np.array_equal(np.asarray(before, dtype=object), np.asarray(value, dtype=object)))
        except Exception:
            return before == value
    return True


_COV_FIELDS = {"P_pred", "P_filt", "P_smooth", "P_next", "S", "y_cov", "P", "Qd", "Q", "R", "P_lagged", "P_window", "P0"}
_NAN_OK = {"innov", "se", "cov", "quantized"}  # innovations where y is missing; fit's covariance when not PD; quantize(NaN)
_NEG_INF_OK = {"loglik", "loglik_t"}
_SKIP = {"optimizer", "closed_loop_eigenvalues"}
_ECHOES = {"lag", "t_point"}  # result fields that echo an integer argument


def leaves(result, prefix="result"):
    """(dotted name, ndarray) for every numeric leaf of a result (dataclasses, named tuples,
    dicts, tuples, models)."""
    import numpy as np

    import kfast

    if result is None:
        return
    if isinstance(result, kfast.LinearGaussian):
        for k in ("F", "H", "Q", "R", "B", "D", "N"):
            yield from leaves(getattr(result, k), f"{prefix}.{k}")
        return
    if isinstance(result, (np.ndarray, float, int, complex, np.generic)) and not isinstance(result, bool):
        yield prefix, np.asarray(result)
        return
    if dataclasses.is_dataclass(result):
        items = [(f.name, getattr(result, f.name)) for f in dataclasses.fields(result) if f.name != "model"]
    elif hasattr(result, "_asdict"):
        items = list(result._asdict().items())
    elif isinstance(result, dict):
        items = list(result.items())
    elif isinstance(result, (tuple, list)):
        items = [(str(i), v) for i, v in enumerate(result)]
    else:
        return
    for k, v in items:
        if k in _SKIP:
            continue
        yield from leaves(v, f"{prefix}.{k}")


def _last(name: str) -> str:
    return name.split(".")[-1]


def sanity(result, result_name: str = "result", inf_ok: bool = False) -> Optional[tuple[str, str]]:
    """(kind, detail) of the first sanity violation of a result, or None."""
    import numpy as np

    found = {}
    leaf_list = list(leaves(result, result_name))
    # The problem's covariance scale: a smoothed covariance far below the prediction's (an
    # almost exactly known state) carries rounding errors of the prediction's size.
    problem_scale = max(
        (float(np.abs(a).max()) for name, a in leaf_list if _last(name) == "P_pred" and a.size and np.isfinite(a).all()),
        default=0.0,
    )
    for name, a in leaf_list:
        last = _last(name)
        found[name] = a
        if a.dtype.kind not in "fc":
            continue
        if np.isnan(a).any() and last not in _NAN_OK:
            return "silent-nan", f"{name} has NaN"
        if np.isinf(a).any() and not inf_ok:
            if not (last in _NEG_INF_OK and not np.isposinf(a).any()):
                return "silent-inf", f"{name} has inf"
        if last in _COV_FIELDS and a.ndim >= 2 and a.shape[-1] == a.shape[-2] and a.size and np.isfinite(a).all():
            bad = _not_psd(a, scale=max(float(np.abs(a).max()), problem_scale))
            if bad:
                return "garbage", f"{name} {bad}"
    for low, high in (("P_filt", "P_pred"), ("P_smooth", "filter.P_filt")):
        for name in found:
            if _last(name) == low:
                other = name[: -len(low)] + high
                other = other.replace(".filter.filter.", ".filter.")
                if other in found and found[other].shape == found[name].shape:
                    bad = _not_psd(found[other] - found[name], scale=max(float(np.abs(found[other]).max()), problem_scale))
                    if bad:
                        return "garbage", f"{other} - {name} (must be PSD) {bad}"
    return None


# A covariance is "garbage" when it is asymmetric or has an eigenvalue below -PSD_RTOL max|P|:
# far above rounding (n eps), so that only a real loss of precision is reported.
PSD_RTOL = 1e-6


def _not_psd(a, scale=None) -> Optional[str]:
    import numpy as np

    a = np.asarray(a, dtype=float)
    scale = float(np.abs(a).max()) if scale is None else float(scale)
    tol = PSD_RTOL * scale + 1e-300
    asym = float(np.abs(a - np.swapaxes(a, -1, -2)).max())
    if asym > tol:
        return f"not symmetric (|A - A'| = {asym:.3g}, max |A| = {scale:.3g})"
    lam = np.linalg.eigvalsh((a + np.swapaxes(a, -1, -2)) / 2).min()
    if lam < -tol:
        return f"not positive semidefinite (eigenvalue {lam:.3g}, max |A| = {scale:.3g})"
    return None


def _equal(a, b, rtol: float = 1e-12) -> Optional[str]:
    import numpy as np

    la, lb = dict(leaves(a)), dict(leaves(b))
    if la.keys() != lb.keys():
        return f"fields differ: {sorted(la)} vs {sorted(lb)}"
    for k in la:
        if _last(k) in _ECHOES:
            continue
        x, y = la[k], lb[k]
        if x.shape != y.shape:
            return f"{k}: shape {x.shape} vs reference {y.shape}"
        if x.dtype.kind in "fc" or y.dtype.kind in "fc":
            close = np.isclose(x, y, rtol=rtol, atol=rtol * float(np.nanmax(np.abs(y), initial=0.0)) if y.dtype.kind in "fc" and np.isfinite(y).all() else 1e-300, equal_nan=True)
            if not close.all():
                i = np.flatnonzero(~close.ravel())[0]
                return f"{k.rstrip('.')}: {int((~close).sum())} entries differ from the reference, e.g. [{i}]: {np.ravel(x)[i]!r} vs {np.ravel(y)[i]!r}"
        elif not np.array_equal(x, y):
            return f"{k}: {x} vs reference {y}"
    return None


def _names_arg(message: str, names: tuple) -> bool:
    """Whether the message names one of ``names``: in its head (before the first ": "), quoted,
    or as the subject of a clause ("... but y has 5 steps")."""
    head = message.split(": ", 1)[0] if ": " in message else message[:60]
    for name in names:
        word = rf"(?<![\w]){re.escape(name)}(?![\w])"
        if re.search(word, head) or f"'{name}'" in message or re.search(word + r" (has|is|must|and|at step)\b", message):
            return True
    return False


# Documented domain errors: they name the step or the equation, which is what the user needs
# (the input was valid; the problem it poses has no answer).
_DOMAIN_ERRORS = ("InnovationCovarianceError", "NoStabilizingSolutionError")


def _call(entry: Entry, ns: dict, args: dict, watch_threads: bool):
    """Evaluate the call; returns (result, exception, peak extra threads)."""
    expr = entry.render(args)
    peak = [0]
    stop = threading.Event()
    if watch_threads:
        base = _threads()

        def poll():
            while not stop.is_set():
                peak[0] = max(peak[0], _threads() - base - 1)
                time.sleep(0.0005)

        poller = threading.Thread(target=poll, daemon=True)
        poller.start()
    try:
        return eval(expr, ns), None, peak[0]
    except BaseException as exc:  # noqa: B036 - a PanicException is a BaseException
        return None, exc, peak[0]
    finally:
        stop.set()
        if watch_threads:
            poller.join()


def _threads() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Threads:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return threading.active_count()


def _describe(exc: BaseException) -> str:
    return f"{type(exc).__module__}.{type(exc).__name__}: {str(exc)[:300]}"


def run_case(case: Case) -> dict:
    """Run one case in this process and classify it: {"outcome", "kind", "detail"}."""
    import numpy as np

    entry = ENTRIES[case.entry]
    ns = _fresh_ns(case.fixture)
    args = dict(case.args)
    try:
        expressions = {a.name for a in entry.args if a.kind == "expression"}  # the call itself: not evaluated first
        values = {k: eval(v, ns) for k, v in args.items() if v is not None and k not in expressions}
    except Exception as exc:  # a bug of the campaign itself, not of kfast
        return {"outcome": "failure", "kind": "campaign-bug", "detail": f"cannot evaluate the arguments: {exc!r}"}
    # pass the evaluated objects by name, so that mutations are seen on these very objects
    call_ns = dict(ns)
    call_args = {k: args[k] for k in expressions}
    for k, v in values.items():
        call_ns[f"_arg_{k}"] = v
        call_args[k] = f"_arg_{k}"
    before = {k: _snapshot(v) for k, v in values.items()}
    result, exc, threads = _call(entry, call_ns, call_args, entry.watch_threads)
    mutated = [k for k, v in values.items() if before[k] is not None and not _unchanged(before[k], v)]
    if mutated:
        return _fail("mutated", f"argument(s) {mutated} modified by the call")
    limit = max(16, 2 * (os.cpu_count() or 1))
    if threads > limit:
        return _fail("threads", f"{threads} extra OS threads during the call (limit {limit})")
    verdict = _classify_exception(exc, case) if exc is not None else None
    if verdict is not None and verdict["outcome"] == "failure" and verdict["kind"] in ("panic", "memory"):
        return verdict

    # what the input should give: the reference (clean float64) call, and the sibling validator
    ref_result, ref_exc = None, None
    has_ref = case.reference is not None
    if has_ref:
        ref_args = dict(args)
        if case.reference == "canonical":
            try:
                ns_ref = dict(ns)
                ns_ref[f"_ref_{case.perturbed}"] = canonical(values[case.perturbed])
                ref_args[case.perturbed] = f"_ref_{case.perturbed}"
            except Exception as e:
                has_ref = False
                ref_exc = e
        else:
            ns_ref = dict(ns)
            ref_args.update(case.reference)
        if has_ref:
            ref_result, ref_exc, _ = _call(entry, ns_ref, {k: v for k, v in ref_args.items() if v is not None}, False)
    invalid_by_validator = None
    if case.validator is not None and exc is None:
        v_entry, v_args = case.validator
        v_ns = dict(ns)
        v_call = dict(ENTRIES[v_entry].good_args())
        for k, src in v_args.items():
            v_call[k] = args.get(src)
        v_call = {k: v for k, v in v_call.items() if v is not None}
        _, v_exc, _ = _call(ENTRIES[v_entry], v_ns, v_call, False)
        if type(v_exc).__name__ == "KfastError":
            invalid_by_validator = f"{ENTRIES[v_entry].template.split('(')[0]} refuses the same input: {_describe(v_exc)}"

    if exc is not None:
        if verdict["outcome"] == "error":
            if case.expect == "equal" and case.must_accept and ref_exc is None and has_ref:
                return _fail("refused", f"an equivalent form of valid input was refused: {_describe(exc)}")
            return verdict
        # not a clear error; but the same message as the clean input gives is consistent
        if ref_exc is not None and type(ref_exc) is type(exc) and str(ref_exc) == str(exc) and isinstance(exc, (ValueError, TypeError)):
            return {"outcome": "error", "kind": "", "detail": _describe(exc)}
        return verdict
    # a result
    if case.expect == "error":
        return _fail("accepted-invalid", f"invalid input gave a result instead of an error naming {case.names}")
    if invalid_by_validator:
        return _fail("accepted-invalid", invalid_by_validator)
    if has_ref and ref_exc is not None:
        return _fail("accepted-invalid", f"the clean float64 input is refused ({_describe(ref_exc)}) but this form gave a result")
    bad = sanity(result, entry.result_name, entry.inf_ok)
    if bad:
        return _fail(*bad)
    if has_ref:
        diff = _equal(result, ref_result, case.rtol)
        if diff:
            return _fail("mismatch", diff)
    return {"outcome": "valid", "kind": "", "detail": ""}


def _classify_exception(exc: BaseException, case: Case) -> dict:
    if not isinstance(exc, Exception):
        return _fail("panic", _describe(exc))
    if isinstance(exc, MemoryError):
        return _fail("memory", _describe(exc))
    if isinstance(exc, (ValueError, TypeError)) and _names_arg(str(exc), case.names):
        return {"outcome": "error", "kind": "", "detail": _describe(exc)}
    if type(exc).__name__ in _DOMAIN_ERRORS and isinstance(exc, ValueError):
        return {"outcome": "error", "kind": "", "detail": _describe(exc)}
    return _fail("unclear-error", _describe(exc))


def _fail(kind: str, detail: str) -> dict:
    return {"outcome": "failure", "kind": kind, "detail": detail}
