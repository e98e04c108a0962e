"""The fuzz campaign of issue #10 over every public entry point (fuzzcases.ENTRIES).

One test per (entry point, family): Hypothesis draws perturbations (fuzzstrategies: special
values, wrong shapes, broken covariances), each case runs in the isolated worker and is
classified (fuzzcases.run_case). The forms of array arguments (containers, dtypes, layouts) and
the scalar arguments are few enough to be tried exhaustively. A test runs all its cases
and then fails with the list of every failing one: the case, its classification, the
exception or the difference, and a one-line reproducer. The scalar arguments are integers such as
``steps``, ``lag``, ``threads`` (up to 10**100 in the long profile), floats, strings, booleans,
models and callables.
"""

from __future__ import annotations

import os

import pytest

from fuzzcases import ENTRIES
from fuzzstrategies import FAMILIES, all_form_cases, families_of, scalar_case_for, scalar_variants
from isolation import format_failure, run_strategy

HYPOTHESIS_FAMILIES = [(e.name, f) for e in ENTRIES.values() for f in families_of(e) if f not in ("scalar", "form")]
FORM_ENTRIES = [e.name for e in ENTRIES.values() if "form" in families_of(e)]
SCALAR_ENTRIES = [e.name for e in ENTRIES.values() if "scalar" in families_of(e)]


def _report(failures: list, tried: int) -> str:
    return f"{len(failures)} of {tried} cases failed:\n" + "\n".join(failures)


@pytest.mark.parametrize("entry,family", HYPOTHESIS_FAMILIES, ids=[f"{e}-{f}" for e, f in HYPOTHESIS_FAMILIES])
def test_campaign(entry, family, worker, fuzz_settings):
    failures, tried = run_strategy(FAMILIES[family](ENTRIES[entry]), worker, fuzz_settings)
    assert tried, "no case was tried"
    assert not failures, _report(failures, tried)


@pytest.mark.parametrize("entry", FORM_ENTRIES)
def test_array_forms(entry, worker):
    """Every container and dtype of every array argument (fuzzstrategies.FORMS)."""
    failures = []
    cases = all_form_cases(ENTRIES[entry])
    for case in cases:
        outcome = worker.run(case)
        if outcome["outcome"] == "failure":
            failures.append(format_failure(case, outcome))
    assert not failures, _report(failures, len(cases))


@pytest.mark.parametrize("entry", SCALAR_ENTRIES)
def test_scalar_arguments(entry, worker, fuzz_profile):
    e = ENTRIES[entry]
    failures, tried = [], 0
    for arg in e.args:
        if arg.kind == "array":
            continue
        for variant in scalar_variants(arg, long=fuzz_profile == "long"):
            case = scalar_case_for(e, arg, variant)
            tried += 1
            outcome = worker.run(case)
            if outcome["outcome"] == "failure":
                failures.append(format_failure(case, outcome))
    assert not failures, _report(failures, tried)
