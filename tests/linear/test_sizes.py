"""Every size the compiled loops specialize (n <= 12 with m <= min(n, 4): plain unrolled
products up to n = 8, register blocks for n = 9-12) and the run-time sizes next to them
(m = 5, n = 13), against the NumPy reference: filter and RTS smoother, with partial missing
data (the out-of-line step) and without, both update forms. filter_batch, whose shared
covariance recursion runs at run-time sizes, must equal filtering each series alone bit for
bit at every size (the two product forms sum in the same order)."""

import numpy as np
import pytest

import kfast
from kfast.reference import kalman_filter, rts_smoother
from modelgen import random_case

COMPILED = [(n, m) for n in range(1, 13) for m in range(1, min(n, 4) + 1)]
RUN_TIME = [(5, 5), (12, 5), (13, 1), (13, 4), (2, 3)]


def close(got, want, what, rtol=1e-9):
    scale = max(1.0, float(np.nanmax(np.abs(want))))
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale, err_msg=what)


@pytest.mark.parametrize("n, m", COMPILED + RUN_TIME)
def test_filter_and_smoother_match_the_reference_at_every_size(n, m):
    seed = 100 * n + m
    missing = "partial" if seed % 2 else "none"
    form = "joseph" if (n + m) % 2 else "standard"
    case = random_case(seed, n, m, T=25, missing=missing)
    model = kfast.LinearGaussian(**case.model)
    res = model.smooth(case.y, case.x0, case.P0, form=form)
    xs, Ps, _, ref = rts_smoother(**case.model, y=case.y, x0=case.x0, P0=case.P0, form=form)
    what = f"n={n} m={m} {missing} {form}"
    for name in ["x_filt", "P_filt", "x_pred", "P_pred", "K", "S"]:
        close(getattr(res.filter, name), ref[name], f"{name} {what}")
    close(res.x_smooth, xs, f"x_smooth {what}")
    close(res.P_smooth, Ps, f"P_smooth {what}")
    assert res.filter.loglik == pytest.approx(ref["loglik"], rel=1e-10)


@pytest.mark.parametrize("n, m", [(5, 2), (8, 4), (9, 1), (10, 3), (12, 4), (13, 2)])
def test_filter_batch_equals_each_series_alone_at_every_size(n, m):
    case = random_case(7 * n + m, n, m, T=20)
    model = kfast.LinearGaussian(**case.model)
    rng = np.random.default_rng(n)
    Y = case.y + rng.standard_normal((3, *case.y.shape))
    res = kfast.filter_batch(model, Y, case.x0, case.P0)
    for b in range(3):
        alone = model.filter(Y[b], case.x0, case.P0)
        np.testing.assert_array_equal(res.x_filt[b], alone.x_filt)
        np.testing.assert_array_equal(res.P_filt[b], alone.P_filt)


def test_kernel_info_names_the_instruction_set():
    info = kfast._kfast.kernel_info()
    assert info["instruction_set"] in {"avx2+fma", "baseline+fma", "avx2", "baseline"}
    assert "n <= 12" in info["fixed_sizes"]


def test_the_reference_comparison_would_catch_a_wrong_size():
    """The check above fails for a filter run on a different model (so it can fail)."""
    case = random_case(3, 5, 2, T=10)
    model = kfast.LinearGaussian(**case.model)
    res = model.filter(case.y, case.x0, case.P0)
    other = dict(case.model, F=case.model["F"] * 0.9)
    ref = kalman_filter(**other, y=case.y, x0=case.x0, P0=case.P0)
    with pytest.raises(AssertionError):
        close(res.x_filt, ref["x_filt"], "perturbed F")
