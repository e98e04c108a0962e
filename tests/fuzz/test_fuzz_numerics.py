"""Valid but hard input, in the isolated worker: degenerate noise (Q = 0, rank-deficient or
tiny R) must give an ``InnovationCovarianceError`` naming the step or a sane result (covariances
symmetric PSD, P(t|t) <= P(t|t-1), P(t|T) <= P(t|t): the sanity checks of fuzzcases), and
``kfast.expm`` must be accurate where the exact exponential is known (symmetric matrices
Q diag(l) Q', diagonal ones, nilpotent ones: I + N + N^2/2 + N^3/6).
"""

from __future__ import annotations

from hypothesis import settings
from hypothesis import strategies as st

from fuzzcases import ENTRIES, Case
from isolation import run_strategy


def _expr_case(fixture_entry: str, e: str, variant: str, reference=None, rtol=1e-12, names=("S", "R", "Q")) -> Case:
    """``names``: the arguments a clear error may name (expm's overflow error names ``a``)."""
    entry = ENTRIES[fixture_entry]
    return Case(entry=entry.name, fixture=entry.fixture, args=(("e", e),), perturbed="e", names=names,
                family="numerics", variant=variant, expect="either", reference=None if reference is None else {"e": reference}, rtol=rtol)


_COV = {
    "zero": "np.zeros(({k}, {k}))",
    "rank1": "(_c := rng.standard_normal(({k}, 1))) @ _c.T",
    "full": "(_c := rng.standard_normal(({k}, {k}))) @ _c.T",
    "tiny": "1e-12 * np.eye({k})",
    "huge": "1e12 * np.eye({k})",
}


@st.composite
def degenerate_model(draw) -> Case:
    s = draw(st.integers(0, 10**6))
    n, m = draw(st.integers(1, 4)), draw(st.integers(1, 3))
    q, r = draw(st.sampled_from(sorted(_COV))), draw(st.sampled_from(sorted(_COV)))
    p0 = draw(st.sampled_from(["full", "zero", "huge", "rank1"]))
    scale = draw(st.sampled_from(["0.5", "1.0", "1.5"]))
    method = draw(st.sampled_from(["smooth", "filter", "smooth_fixed_lag"]))
    extra = ", 2" if method == "smooth_fixed_lag" else ""
    e = (
        f"(rng := np.random.default_rng({s}), F := {scale} * rng.standard_normal(({n}, {n})), H := rng.standard_normal(({m}, {n})), "
        f"Q := {_COV[q].format(k=n)}, R := {_COV[r].format(k=m)}, P0 := {_COV[p0].format(k=n)}, y := rng.standard_normal((30, {m})), "
        f"kfast.LinearGaussian(F, H, Q, R).{method}(y, np.zeros({n}), P0{extra}))[-1]"
    )
    return _expr_case("expression", e, f"{method} n={n} m={m} Q={q} R={r} P0={p0} F scale {scale}")


@st.composite
def expm_case(draw) -> Case:
    s = draw(st.integers(0, 10**6))
    n = draw(st.integers(1, 4))
    kind = draw(st.sampled_from(["symmetric", "diagonal", "nilpotent"]))
    size = draw(st.sampled_from([1e-8, 1.0, 10.0, 100.0, 700.0, 1e4, 1e8, 1e12, 1e15, 1e20]))
    head = f"(rng := np.random.default_rng({s}), "
    if kind == "symmetric" and size <= 700:
        head += f"Qm := np.linalg.qr(rng.standard_normal(({n}, {n})))[0], lam := {size} * rng.uniform(-1, 1, {n}), "
        return _expr_case("expression_ric", head + "kfast.expm(Qm @ np.diag(lam) @ Qm.T))[-1]", f"symmetric n={n} size {size}",
                          reference=head + "Qm @ np.diag(np.exp(lam)) @ Qm.T)[-1]", rtol=1e-8, names=("a",))
    if kind == "nilpotent":
        head += f"N := np.triu({size} * rng.uniform(-1, 1, ({n}, {n})), 1), "
        exact = f"np.eye({n}) + N + N @ N / 2 + N @ N @ N / 6"
        return _expr_case("expression_ric", head + "kfast.expm(N))[-1]", f"nilpotent n={n} size {size}", reference=head + exact + ")[-1]", rtol=1e-10, names=("a",))
    head += f"lam := {size} * rng.uniform(-1, 1, {n}), "
    return _expr_case("expression_ric", head + "kfast.expm(np.diag(lam)))[-1]", f"diagonal n={n} size {size}",
                      reference=head + "np.diag(np.exp(lam)))[-1]", rtol=1e-12, names=("a",))


def _run_all(strategy, worker, fuzz_settings):
    failures, tried = run_strategy(strategy, worker, fuzz_settings)
    assert not failures, f"{len(failures)} of {tried} cases failed:\n" + "\n".join(failures)


def test_degenerate_noise(worker, fuzz_settings):
    _run_all(degenerate_model(), worker, settings(fuzz_settings, max_examples=4 * fuzz_settings.max_examples))


def test_expm_accuracy(worker, fuzz_settings):
    _run_all(expm_case(), worker, settings(fuzz_settings, max_examples=4 * fuzz_settings.max_examples))
