"""`outputs=` of filter and smooth: a subset of the fields is stored, bit-for-bit the same as
in the full call, and the rest are None. The smoother's fast paths (filtered moments smoothed
in place, internal buffers for what the backward pass needs) are exercised through it."""

import itertools

import numpy as np
import pytest

import kfast
from modelgen import random_case

FILTER_FIELDS = ["x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t", "x_next", "P_next"]
SMOOTH_FIELDS = ["x_smooth", "P_smooth", "P_lag1"]
OPTIONS = list(itertools.product([False, True], [False, True], [False, True], ["none", "partial"]))


def case_for(seed):
    inputs, correlated, time_varying, missing = OPTIONS[seed % len(OPTIONS)]
    rng = np.random.default_rng(700 + seed)
    n, m = int(rng.integers(1, 6)), int(rng.integers(1, 4))
    return random_case(seed, n, m, T=20, inputs=inputs, correlated=correlated, time_varying=time_varying, missing=missing)


def subsets(rng, fields):
    """A few random non-empty subsets of `fields`, the single fields and the pairs that
    matter for the fast paths."""
    picks = [[f] for f in fields]
    picks += [list(rng.choice(fields, size=int(rng.integers(1, len(fields) + 1)), replace=False)) for _ in range(6)]
    return picks


def same(got, want, what):
    assert got is not None, what
    np.testing.assert_array_equal(got, want, err_msg=what)


@pytest.mark.parametrize("seed", range(len(OPTIONS) * 2))
def test_filter_outputs_subset_equals_the_full_call(seed):
    case = case_for(seed)
    model = kfast.LinearGaussian(**case.model)
    full = model.filter(case.y, case.x0, case.P0, u=case.u)
    for wanted in subsets(np.random.default_rng(seed), FILTER_FIELDS):
        res = model.filter(case.y, case.x0, case.P0, u=case.u, outputs=wanted)
        assert res.loglik == full.loglik
        for name in FILTER_FIELDS:
            if name in wanted:
                same(getattr(res, name), getattr(full, name), f"{name} with outputs={wanted} {case.info}")
            else:
                assert getattr(res, name) is None, name


@pytest.mark.parametrize("seed", range(len(OPTIONS) * 2))
@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_smooth_outputs_subset_equals_the_full_call(seed, form):
    case = case_for(seed)
    model = kfast.LinearGaussian(**case.model)
    full = model.smooth(case.y, case.x0, case.P0, u=case.u, form=form)
    rng = np.random.default_rng(seed)
    picks = subsets(rng, SMOOTH_FIELDS + FILTER_FIELDS)
    picks += [["x_smooth", "P_smooth"], ["x_smooth", "x_filt"], ["P_smooth", "P_filt", "K"], ["P_lag1"]]
    for wanted in picks:
        res = model.smooth(case.y, case.x0, case.P0, u=case.u, form=form, outputs=wanted)
        assert res.filter.loglik == full.filter.loglik
        for name in SMOOTH_FIELDS:
            if name in wanted:
                same(getattr(res, name), getattr(full, name), f"{name} with outputs={wanted} {case.info}")
            else:
                assert getattr(res, name) is None, name
        for name in FILTER_FIELDS:
            if name in wanted:
                same(getattr(res.filter, name), getattr(full.filter, name), f"filter {name} with {wanted}")
            else:
                assert getattr(res.filter, name) is None, name


def test_outputs_accept_one_name_and_reject_unknown_ones():
    case = case_for(0)
    model = kfast.LinearGaussian(**case.model)
    res = model.smooth(case.y, case.x0, case.P0, outputs="x_smooth")
    assert res.x_smooth is not None and res.P_smooth is None and res.filter.x_filt is None
    res = model.filter(case.y, case.x0, case.P0, outputs="P_filt")
    assert res.P_filt is not None and res.x_filt is None
    with pytest.raises(ValueError, match='outputs: unknown field "x_smoth"'):
        model.smooth(case.y, case.x0, case.P0, outputs=["x_smoth"])
    with pytest.raises(ValueError, match='outputs: unknown field "x_smooth"'):
        model.filter(case.y, case.x0, case.P0, outputs=["x_smooth"])


def test_smooth_does_not_modify_its_inputs():
    case = case_for(3)
    model = kfast.LinearGaussian(**case.model)
    args = [case.y, case.x0, case.P0]
    copies = [a.copy() for a in args]
    model.smooth(*args, u=case.u, outputs=("x_smooth", "P_smooth"))
    for a, c in zip(args, copies):
        np.testing.assert_array_equal(a, c)


def test_outputs_are_written_in_full_over_reused_memory():
    """The output arrays are allocated without zeroing: every entry must be written. Freed
    buffers full of a marker value make reused memory visible if an entry were skipped."""
    case = case_for(5)  # missing values: zero gain columns, NaN innovations
    model = kfast.LinearGaussian(**case.model)
    marker = 7.25e11
    for _ in range(3):
        junk = [np.full(size, marker) for size in (20, 80, 400, 1600, 6400) for _ in range(8)]
        del junk
        filt = model.filter(case.y, case.x0, case.P0, u=case.u)
        sm = model.smooth(case.y, case.x0, case.P0, u=case.u, outputs=SMOOTH_FIELDS + ["x_pred", "K"])
        arrays = [getattr(filt, f) for f in FILTER_FIELDS] + [sm.x_smooth, sm.P_smooth, sm.P_lag1]
        arrays += [sm.filter.x_pred, sm.filter.K]
        for a in arrays:
            assert not np.any(a == marker)
        np.testing.assert_array_equal(sm.P_lag1[0], 0.0)


def test_outputs_names_must_be_strings():
    case = case_for(1)
    model = kfast.LinearGaussian(**case.model)
    for bad in ([1], [b"x_smooth"], ["x_smooth", None]):
        with pytest.raises(ValueError, match="outputs: expected field names"):
            model.smooth(case.y, case.x0, case.P0, outputs=bad)
        with pytest.raises(ValueError, match="outputs: expected field names"):
            model.filter(case.y, case.x0, case.P0, outputs=bad)


def test_filter_result_fields_are_the_crates_output_table():
    """The Python FilterResult declares exactly the outputs of the crate's one table
    (kfast._kfast.FILTER_FIELDS), in its order, plus the total loglik, the model and the exact
    diffuse start's P_pred_inf and n_diffuse."""
    import dataclasses

    from kfast import _kfast

    names = [f.name for f in dataclasses.fields(kfast.FilterResult)]
    assert [n for n in names if n not in ("loglik", "model", "P_pred_inf", "n_diffuse")] == [name for name, _ in _kfast.FILTER_FIELDS]
    T, n, m = 7, 3, 2
    model = kfast.LinearGaussian(np.eye(n) * 0.5, np.ones((m, n)), np.eye(n), np.eye(m))
    res = model.filter(np.zeros((T, m)), np.zeros(n), np.eye(n))
    sizes = {"T": T, "n": n, "m": m}
    for name, shape in _kfast.FILTER_FIELDS:
        assert getattr(res, name).shape == tuple(sizes[d] for d in shape), name
