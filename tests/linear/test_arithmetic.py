"""Fused multiply-adds and deterministic mode (docs/conventions.md, "Arithmetic").

The fused loops must give the same bits with every instruction set (here: the AVX2 + FMA
loops of compile-time sizes against the baseline loops of run-time sizes with software FMA,
forced with the private ``_force_kernel``), deterministic mode must change nothing at n <= 12
and only rounding above (faer's products), the unfused loops of CPUs without FMA must agree
with the fused ones to rounding, and in either mode the filter, the batch filter, the
streaming filter and the smoothers must agree with each other to the bit.
"""

import os
import subprocess
import sys

import numpy as np
import pytest

import kfast
from modelgen import random_case

SIZES = [(4, 2), (5, 2), (9, 2), (12, 3), (13, 2), (20, 3)]  # unrolled, blocked, run-time, faer
HAS_AVX2 = "avx2" in kfast.kernel_info()["cpu_features"].split()
HAS_FMA = HAS_AVX2 and "fma" in kfast.kernel_info()["cpu_features"].split()


@pytest.fixture
def kernel():
    """Forces the loops for one test, then restores the default choice and mode."""
    previous = kfast.deterministic()
    yield kfast._kfast._force_kernel
    kfast._kfast._force_kernel(None)
    kfast.set_deterministic(previous)


def everything(n, m, seed=1):
    """filter, smooth, fixed-lag, filter_batch and the streaming filter on one random case."""
    case = random_case(seed, n, m, T=30, missing="partial")
    model = kfast.LinearGaussian(**case.model)
    res = model.filter(case.y, case.x0, case.P0, form="standard")
    sm = model.smooth(case.y, case.x0, case.P0)
    lag = model.smooth_fixed_lag(case.y, case.x0, case.P0, lag=3)
    complete = random_case(seed, n, m, T=30).y
    batch = kfast.filter_batch(model, np.stack([complete, complete + 1.0]), case.x0, case.P0)
    kf = kfast.KalmanFilter(model, case.x0, case.P0, form="standard")
    xs = []
    for y in case.y:
        kf.update(y)
        xs.append(kf.x.copy())
        kf.predict()
    return {
        "x_filt": res.x_filt, "P_filt": res.P_filt, "loglik": res.loglik,
        "x_smooth": sm.x_smooth, "P_smooth": sm.P_smooth, "P_lag1": sm.P_lag1,
        "x_lag": lag.x_smooth, "P_lag": lag.P_smooth,
        "batch_x": batch.x_filt, "batch_P": batch.P_filt, "stream_x": np.array(xs),
    }


def assert_same_bits(kernel, first, second, n, m):
    """everything() in the loops `first` and in the loops `second` (None: the default)."""
    kernel(first)
    one = everything(n, m)
    kernel(second)
    other = everything(n, m)
    for name in one:
        np.testing.assert_array_equal(other[name], one[name], err_msg=name)


@pytest.mark.skipif(not HAS_FMA, reason="needs a CPU with AVX2 and FMA")
@pytest.mark.parametrize("n, m", SIZES)
def test_fused_loops_give_the_same_bits_with_every_instruction_set(kernel, n, m):
    kfast.set_deterministic(True)
    assert kfast.kernel_info()["instruction_set"] == "avx2+fma"
    # the AVX2 + FMA loops (compile-time sizes) against run-time sizes with the C library's fma()
    assert_same_bits(kernel, None, "baseline+fma", n, m)


@pytest.mark.skipif(not HAS_AVX2, reason="needs a CPU with AVX2 to compare with the baseline loops")
@pytest.mark.parametrize("n, m", SIZES)
def test_unfused_loops_give_the_same_bits_with_every_instruction_set(kernel, n, m):
    assert_same_bits(kernel, "baseline", "avx2", n, m)


@pytest.mark.skipif(not HAS_FMA, reason="needs a CPU with AVX2 and FMA")
@pytest.mark.parametrize("n, m", SIZES)
def test_fused_results_differ_from_unfused_ones_only_by_rounding(kernel, n, m):
    kfast.set_deterministic(False)
    assert kfast.kernel_info()["instruction_set"] == "avx2+fma"
    fused = everything(n, m)
    kernel("baseline")
    plain = everything(n, m)
    differ = 0
    for name in fused:
        np.testing.assert_allclose(fused[name], plain[name], rtol=1e-9, atol=1e-9, err_msg=name)
        differ += not np.array_equal(fused[name], plain[name])
    assert differ > 0, "the fused loops computed the unfused bits: FMA is not used"


@pytest.mark.skipif(not HAS_FMA, reason="needs a CPU with AVX2 and FMA")
@pytest.mark.parametrize("n, m", SIZES)
def test_deterministic_mode_changes_only_faers_products(kernel, n, m):
    kfast.set_deterministic(False)
    default = everything(n, m)
    kfast.set_deterministic(True)
    exact = everything(n, m)
    differ = 0
    for name in default:
        np.testing.assert_allclose(exact[name], default[name], rtol=1e-9, atol=1e-9, err_msg=name)
        differ += not np.array_equal(exact[name], default[name])
    # n <= 12 never reaches faer; (13, 2) and (20, 3) do, outside deterministic mode.
    assert (differ > 0) == (n > 12)


@pytest.mark.parametrize("form", ["joseph", "standard"])
@pytest.mark.parametrize("deterministic", [True, False])
@pytest.mark.parametrize("n, m", [(3, 2), (4, 1), (4, 2), (9, 2), (13, 2)])
def test_every_path_computes_the_same_bits_in_either_mode(kernel, deterministic, n, m, form):
    # n = 3, 4 have kernels of their own on AVX2 + FMA (core/rows4.rs); filter_batch's shared
    # covariance recursion runs with run-time sizes, without them.
    kfast.set_deterministic(deterministic)
    case = random_case(5, n, m, T=25)
    model = kfast.LinearGaussian(**case.model)
    res = model.filter(case.y, case.x0, case.P0, form=form)
    sm = model.smooth(case.y, case.x0, case.P0, form=form)
    batch = kfast.filter_batch(model, case.y[None], case.x0, case.P0, form=form)
    lag = model.smooth_fixed_lag(case.y, case.x0, case.P0, lag=0, form=form)
    online = kfast.FixedLagSmoother(model, case.x0, case.P0, lag=0, form=form)
    kf = kfast.KalmanFilter(model, case.x0, case.P0, form=form)
    xs, Ps, lagged, lagged_P = [], [], [], []
    for y in case.y:
        kf.update(y)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
        kf.predict()
        online.update(y)
        lagged.append(online.x_lagged.copy())
        lagged_P.append(online.P_lagged.copy())
        online.predict()
    for got in [sm.filter.x_filt, batch.x_filt[0], np.array(xs)]:
        np.testing.assert_array_equal(got, res.x_filt)
    for got in [sm.filter.P_filt, batch.P_filt, np.array(Ps)]:
        np.testing.assert_array_equal(got.reshape(res.P_filt.shape), res.P_filt)
    # The fixed-lag smoothers' estimates come from their own recursion (unfused in either
    # mode): online equals batch.
    np.testing.assert_array_equal(np.array(lagged), lag.x_smooth)
    np.testing.assert_array_equal(np.array(lagged_P), lag.P_smooth)
    assert kf.loglik == res.loglik


@pytest.mark.skipif(not HAS_FMA, reason="needs a CPU with AVX2 and FMA")
def test_a_streaming_filter_keeps_the_loops_it_was_made_with(kernel):
    case = random_case(2, 4, 2, T=20)
    model = kfast.LinearGaussian(**case.model)

    def run(made_with, stepped_with):
        kernel(made_with)
        kf = kfast.KalmanFilter(model, case.x0, case.P0)
        kernel(stepped_with)
        for y in case.y:
            kf.step(y)
        kernel(None)
        return kf

    fused, plain = run(None, "baseline"), run("baseline", None)
    np.testing.assert_array_equal(fused.P, run(None, None).P)
    np.testing.assert_array_equal(plain.P, run("baseline", "baseline").P)
    assert not np.array_equal(plain.P, fused.P)
    assert fused.loglik == model.loglik(case.y, case.x0, case.P0)


def test_the_environment_variable_turns_deterministic_mode_on():
    code = "import kfast; i = kfast.kernel_info(); print(i['deterministic'], i['instruction_set'])"
    env = dict(os.environ, KFAST_DETERMINISTIC="1")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    deterministic, isa = out.stdout.split()
    assert deterministic == "True" and isa in {"avx2+fma", "baseline+fma"}
    env["KFAST_DETERMINISTIC"] = "0"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split()[0] == "False"


def test_set_deterministic_returns_the_previous_setting_and_checks_its_argument(kernel):
    kfast.set_deterministic(False)
    assert kfast.set_deterministic(True) is False
    assert kfast.deterministic() is True
    assert kfast.kernel_info()["instruction_set"].endswith("+fma") or not HAS_FMA
    with pytest.raises(kfast.KfastError, match="on: expected True or False"):
        kfast.set_deterministic("yes")
    with pytest.raises(ValueError, match="unknown kernel"):
        kfast._kfast._force_kernel("avx1024")


def every_family(n, m):
    """One call of each family whose loops are compiled per size: the robust forms (filter,
    square-root smoother, streaming), the covariance forms with a time-varying model, the
    EKF and UKF (their steps at n <= 6 have compile-time sizes), the IMM and the DARE."""
    case = random_case(9, n, m, T=30, missing="partial")
    model = kfast.LinearGaussian(**case.model)
    out = {}
    for form in ("sqrt", "ud", "information", "sequential"):
        out[form] = model.filter(case.y, case.x0, case.P0, form=form).P_filt
        kf = kfast.KalmanFilter(model, case.x0, case.P0, form=form)
        for y in case.y:
            kf.step(y)
        out[f"{form} stream"] = kf.P
    out["sqrt smooth"] = model.smooth(case.y, case.x0, case.P0, form="sqrt").P_smooth
    varying = kfast.LinearGaussian(**{**case.model, "F": np.stack([case.model["F"]] * 30)})
    out["time-varying"] = varying.filter(case.y, case.x0, case.P0).P_filt
    nonlinear = kfast.NonlinearModel.from_linear(model)
    out["ekf"] = nonlinear.ekf(case.y, case.x0, case.P0).P_filt
    out["ukf"] = nonlinear.ukf(case.y, case.x0, case.P0).P_filt
    out["imm"] = kfast.imm_filter([model, model], np.array([[0.9, 0.1], [0.2, 0.8]]), case.y, case.x0, case.P0).x_filt
    out["steady state"] = model.steady_state().P_pred
    return out


@pytest.mark.parametrize("n, m", [(2, 1), (4, 2), (6, 3), (9, 2), (13, 2)])
@pytest.mark.parametrize("forced", ["baseline", "avx2", "baseline+fma"])
def test_every_family_runs_in_every_loop_the_cpu_has(kernel, forced, n, m):
    # The loops of compile-time sizes exist only for AVX2 + FMA on x86-64: every other kernel
    # must reach run-time sizes (a compile-time size there would be a bug, not a slow path).
    want = every_family(n, m)
    try:
        kernel(forced)
    except ValueError:
        pytest.skip(f"this CPU cannot run the {forced} loops")
    got = every_family(n, m)
    for name in want:
        np.testing.assert_allclose(got[name], want[name], rtol=1e-8, atol=1e-8, err_msg=name)
