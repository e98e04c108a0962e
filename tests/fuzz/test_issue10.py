"""Every reproducer of issue #10, as a fuzz case in the isolated worker (fuzzcases).

Each must end as a clear error naming the argument, or a valid result (equal to the reference
where the issue names the right answer). They fail until the issue is fixed; they must never be
marked xfail. The fixtures: ``M = kfast.models.constant_velocity(2, dt=0.1)`` (fixture "cv", n = 4,
m = 2) and the model with inputs of fixture "io" (n = 3, m = 2, k = 2); see fuzzcases.FIXTURES.
"""

from __future__ import annotations

import pytest

from fuzzcases import ENTRIES, Case
from isolation import format_failure


def case(entry, expect, names, reference=None, rtol=1e-12, **args) -> Case:
    e = ENTRIES[entry]
    full = e.good_args()
    full.update(args)
    perturbed = next(iter(args))
    return Case(entry=entry, fixture=e.fixture, args=tuple(full.items()), perturbed=perturbed, names=tuple(names),
                family="issue10", variant=", ".join(f"{k}={v}" for k, v in args.items()), expect=expect,
                reference=reference, validator=e.validator, rtol=rtol)


def expr(fixture, e, expect, names, reference=None, rtol=1e-12) -> Case:
    entry = {"io": "expression", "cv": "expression_cv", "ric": "expression_ric"}[fixture]
    ref = None if reference is None else {"e": reference}
    return Case(entry=entry, fixture=fixture, args=(("e", e),), perturbed="e", names=tuple(names), family="issue10",
                variant=e, expect=expect, reference=ref, rtol=rtol)


MASKED_ROW = "np.ma.masked_array(np.where(np.arange(6)[:, None] == 3, 1e3, Y), mask=np.arange(12).reshape(6, 2) // 2 == 3)"
NAN_ROW = "np.where(np.arange(6)[:, None] == 3, nan, Y)"
NEAR_SINGULAR = (
    "(rng := np.random.default_rng(155), F := 0.5 * rng.standard_normal((4, 4)), H := rng.standard_normal((2, 4)), "
    "b := rng.standard_normal((2, 1)), C := rng.standard_normal((4, 4)), y := rng.standard_normal((30, 2)), "
    "kfast.LinearGaussian(F, H, 0 * np.eye(4), b @ b.T).smooth(y, np.zeros(4), C @ C.T))[-1]"
)

CASES = {
    # crashes and panics: allocations and threads sized from user integers
    "forecast-steps-1e10": case("forecast_cv", "either", ["steps"], steps="10**10"),
    "forecast-steps-2**62": case("forecast_cv", "either", ["steps"], steps="2**62"),
    "forecast-steps-2**63": case("forecast_cv", "either", ["steps"], steps="2**63"),
    "fixed-lag-smoother-lag-1e10": case("FixedLagSmoother", "either", ["lag"], lag="10**10"),
    "fixed-lag-smoother-lag-2**62": case("FixedLagSmoother", "either", ["lag"], lag="2**62"),
    "filter-batch-threads-2**62": case("filter_batch", "either", ["threads"], reference={"threads": "None"}, threads="2**62"),
    "filter-batch-threads-2000": case("filter_batch", "either", ["threads"], reference={"threads": "None"}, threads="2000"),
    "propagate-w-too-narrow": case("propagate", "error", ["w"], w="np.zeros((6, 2))"),
    "propagate-w-too-wide": case("propagate", "error", ["w"], w="np.zeros((6, 4))"),
    "propagate-v-too-narrow": case("propagate", "error", ["v"], v="np.zeros((6, 1))"),
    "propagate-v-too-wide": case("propagate", "error", ["v"], v="np.zeros((6, 3))"),
    "propagate-v-too-short": case("propagate", "error", ["v"], v="np.zeros((5, 2))"),
    # masked arrays: a masked entry is missing (or masked arrays are refused)
    "masked-filter": case("smooth_cv", "either", ["y"], reference={"y": NAN_ROW}, y=MASKED_ROW),
    "masked-loglik": expr("cv", f"M.loglik({MASKED_ROW}, X0, P0)", "either", ["y"], reference=f"M.loglik({NAN_ROW}, X0, P0)"),
    "masked-fixed-lag": expr("cv", f"M.smooth_fixed_lag({MASKED_ROW}, X0, P0, 2)", "either", ["y"],
                             reference=f"M.smooth_fixed_lag({NAN_ROW}, X0, P0, 2)"),
    "masked-fixed-point": expr("cv", f"M.smooth_fixed_point({MASKED_ROW}, X0, P0, 1)", "either", ["y"],
                               reference=f"M.smooth_fixed_point({NAN_ROW}, X0, P0, 1)"),
    "masked-em": case("em", "either", ["y"], reference={"y": NAN_ROW}, y=MASKED_ROW),
    "masked-filter-batch": expr("cv", f"kfast.filter_batch(M, np.ma.stack([{MASKED_ROW}] * 2), X0, P0)", "either", ["Y"],
                                reference=f"kfast.filter_batch(M, np.stack([{NAN_ROW}] * 2), X0, P0)"),
    "masked-fit": expr("cv", "kfast.fit(lambda th: (kfast.models.constant_velocity(2, dt=0.1, q=np.exp(th[0])), X0, P0), [0.0], "
                       f"{MASKED_ROW})", "either", ["y"],
                       reference=f"kfast.fit(lambda th: (kfast.models.constant_velocity(2, dt=0.1, q=np.exp(th[0])), X0, P0), [0.0], {NAN_ROW})"),
    # simulate validates the prior as filter does
    "simulate-nan-x0": case("simulate", "error", ["x0"], x0="np.array([nan, 0.0, 0.0])"),
    "simulate-nan-P0": case("simulate", "error", ["P0"], P0="np.where(np.eye(3) == 1, nan, 0.0)"),
    "simulate-inf-P0": case("simulate", "error", ["P0"], P0="np.eye(3) * inf"),
    "simulate-indefinite-P0": case("simulate", "error", ["P0"], P0="np.diag([1.0, -1.0, 1.0])"),
    "simulate-asymmetric-P0": case("simulate", "error", ["P0"], P0="np.eye(3) + np.triu(np.ones((3, 3)), 1)"),
    # filter_batch checks shapes, not element counts
    "filter-batch-x0-transposed": case("filter_batch", "error", ["x0"], x0="XB.T"),
    "filter-batch-u-swapped": case("filter_batch", "error", ["u"], u="np.swapaxes(UB, 0, 1)"),
    # expm and the sampling of continuous models
    "expm-1e20-nilpotent": expr("ric", "kfast.expm(np.array([[0.0, 1e20], [0.0, 0.0]]))", "either", ["a"],
                                reference="np.array([[1.0, 1e20], [0.0, 1.0]])"),
    "expm-1e12-nilpotent": expr("ric", "kfast.expm(np.array([[0.0, 1e12], [0.0, 0.0]]))", "either", ["a"],
                                reference="np.array([[1.0, 1e12], [0.0, 1.0]])", rtol=1e-10),
    "expm-1e15-nilpotent": expr("ric", "kfast.expm(np.array([[0.0, 1e15], [0.0, 0.0]]))", "either", ["a"],
                                reference="np.array([[1.0, 1e15], [0.0, 1.0]])", rtol=1e-10),
    "expm-overflow": expr("ric", "kfast.expm(np.diag([1e5, -1e5]))", "either", ["a"], reference="np.array([[inf, 0.0], [0.0, 0.0]])"),
    "discretize-indefinite-Qc": case("discretize", "error", ["Qc"], Qc="np.diag([1.0, -1.0])"),
    "discretize-dt-1e300": case("discretize", "either", ["dt"], dt="1e300"),
    "from-continuous-dt-1e300": case("from_continuous", "either", ["dt"], dt="1e300"),
    "from-continuous-indefinite-Qc": case("from_continuous", "error", ["Qc"], Qc="np.diag([1.0, -1.0])"),
    # nearly singular innovation covariance: an error naming the step, or a correct smoother
    "near-singular-S": expr("io", NEAR_SINGULAR, "either", ["S", "R", "Q"]),
    # unclear errors
    "simulate-x0-size": case("simulate", "error", ["x0"], x0="np.zeros(2)"),
    "simulate-P0-size": case("simulate", "error", ["P0"], P0="np.eye(2)"),
    "simulate-P0-not-square": case("simulate", "error", ["P0"], P0="np.ones((3, 2))"),
    "simulate-no-u": case("simulate", "error", ["u"], u="None"),
    "simulate-seed-negative": case("simulate", "either", ["seed"], seed="-1"),
    "simulate-seed-float": case("simulate", "either", ["seed"], seed="1.5"),
    "simulate-seed-str": case("simulate", "either", ["seed"], seed="'x'"),
    "em-y-scalar": case("em", "error", ["y"], y="5.0"),
    "em-fit-None": case("em", "either", ["fit"], fit="None"),
    "em-T-1": case("em", "either", ["y"], y="Y[:1]"),
    "em-x0-size": case("em", "error", ["x0"], x0="np.zeros(3)"),
    "em-P0-size": case("em", "error", ["P0"], P0="np.eye(3)"),
    "em-no-u": expr("io", "kfast.LinearGaussian(M.F, M.H, M.Q, M.R, B=M.B, D=M.D).em(Y, X0, P0, n_iter=1, fit=('Q',))", "error",
                    ["u", "model", "B", "D"]),
    "form-bytes": case("filter", "error", ["form"], form="b'joseph'"),
    "form-bytes-streaming": case("KalmanFilter", "error", ["form"], form="b'joseph'"),
    "lag-1.5": case("smooth_fixed_lag", "error", ["lag"], lag="1.5"),
    "lag-1.5-streaming": case("FixedLagSmoother", "error", ["lag"], lag="1.5"),
    "return-covs-no": case("filter_batch", "either", ["return_covs"], return_covs="'no'"),
    "steps-2**63": case("forecast_cv", "either", ["steps"], steps="2**63"),
    "non-psd-Qc": case("from_continuous", "error", ["Qc"], Qc="-np.eye(2)"),
    "H-zero-rows": case("LinearGaussian", "error", ["H"], H="np.zeros((0, 3))"),
    "huge-dt": case("from_continuous", "either", ["dt"], dt="1e300"),
    "filter-batch-model-None": case("filter_batch", "error", ["model"], model="None"),
}


@pytest.mark.parametrize("name", list(CASES))
def test_issue10_reproducer(name, worker):
    c = CASES[name]
    outcome = worker.run(c)
    assert outcome["outcome"] != "failure", format_failure(c, outcome)
