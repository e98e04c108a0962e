"""How the model, the filter and the streaming filter read their inputs: lists, ints,
float32, Fortran order, strided and read-only views give the same float64 answer, scalars
serve for n = m = 1, non-numeric input is refused, and nothing passed in is modified.
Conventions of the checks: badinput.py."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import kfast
from badinput import T, data, fails, full_model, model_mats, msg, singular_model


# --------------------------------------------------------------------------------------------
# non-numeric input


@pytest.mark.parametrize(
    "value, pattern",
    [
        ("abc", r"real numbers"),
        (np.array([[True, False], [False, True]]), r"real numbers"),
        ([[1.0, 2.0], [3.0]], r"cannot be read as an array"),
        (np.array([[1.0, None], [0.0, 1.0]], dtype=object), r"real numbers"),
    ],
    ids=["str", "bool", "ragged", "object"],
)
def test_non_numeric_input(value, pattern):
    with fails(msg("F", pattern)):
        kfast.LinearGaussian(**model_mats(F=value))
    with fails(msg("P0", pattern)):
        full_model().filter(**data(P0=value))
    with fails(msg("P0", pattern)):
        kfast.KalmanFilter(full_model(), [0.0, 0.0], value)


# --------------------------------------------------------------------------------------------
# positive: lists, ints, float32, Fortran order, strided views give the same float64 answer

# An integer-valued model and data: exactly representable in int64, float32 and float64, so
# every conversion must give bitwise the same float64 result.
EXACT_MATS = {
    "F": np.array([[1.0, 1.0], [0.0, 1.0]]),
    "H": np.array([[1.0, 0.0], [1.0, 1.0]]),
    "Q": np.array([[2.0, 1.0], [1.0, 2.0]]),
    "R": np.array([[3.0, 1.0], [1.0, 3.0]]),
    "B": np.array([[1.0], [0.0]]),
    "D": np.array([[0.0], [1.0]]),
    "N": np.array([[1.0, 0.0], [0.0, 1.0]]),
}
EXACT_DATA = {
    "y": np.array([[1, 2], [0, -1], [3, 1], [-2, 0], [1, 1], [4, -3]], dtype=float),
    "u": np.array([[1], [-1], [0], [2], [1], [-2]], dtype=float),
    "x0": np.array([1.0, -1.0]),
    "P0": np.array([[2.0, 1.0], [1.0, 2.0]]),
}
# per-step versions: F[t] and Q[t] differ from step to step
EXACT_STACKS = {
    "F": np.stack([[[1.0, t % 2], [0.0, 1.0]] for t in range(T)]),
    "Q": np.stack([[[2.0 + t, 1.0], [1.0, 2.0]] for t in range(T)]),
}


def strided(a):
    """A non-contiguous view of a copy of ``a`` (every other element along each axis)."""
    if a.ndim == 0:
        return a
    big = np.zeros(tuple(2 * s + 1 for s in a.shape), dtype=a.dtype)
    view = big[tuple(slice(1, None, 2) for _ in a.shape)]
    view[...] = a
    if a.size > 1:
        assert not view.flags.c_contiguous and not view.flags.f_contiguous
    return view


def fortran(a):
    f = np.asfortranarray(a)
    if a.ndim >= 2 and min(a.shape[-2:]) > 1:
        assert not f.flags.c_contiguous
    return f


def readonly(a):
    b = a.copy()
    b.setflags(write=False)
    return b


VARIANTS = {
    "list": lambda a: a.tolist(),
    "int64": lambda a: a.astype(np.int64),
    "int32": lambda a: a.astype(np.int32),
    "int_list": lambda a: a.astype(np.int64).tolist(),
    "float32": lambda a: a.astype(np.float32),
    "fortran": fortran,
    "strided": strided,
    "strided_float32": lambda a: strided(a.astype(np.float32)),
    "fortran_int": lambda a: fortran(a.astype(np.int64)),
    "readonly": readonly,
}


RESULT_ARRAYS = ["x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t", "x_next", "P_next"]


def run_everything(mats, d):
    """Filter, loglik (both forms) and the streaming filter, as a dict of float64 arrays."""
    model = kfast.LinearGaussian(**mats)
    out = {}
    for form in ["joseph", "standard"]:
        res = model.filter(d["y"], d["x0"], d["P0"], u=d["u"], form=form)
        for name in RESULT_ARRAYS:
            arr = getattr(res, name)
            assert arr.dtype == np.float64
            out[f"{form}.{name}"] = arr
        out[f"{form}.loglik"] = np.float64(res.loglik)
        out[f"{form}.loglik()"] = np.float64(model.loglik(d["y"], d["x0"], d["P0"], u=d["u"], form=form))
    kf = kfast.KalmanFilter(model, d["x0"], d["P0"])
    xs, Ps = [], []
    for t in range(T):
        y_t, u_t = d["y"][t], d["u"][t]
        if t % 2:
            kf.step(y_t, u_t)
        else:
            kf.update(y_t, u_t)
            xs.append(kf.x)
            Ps.append(kf.P)
            kf.predict(u_t)
        xs.append(kf.x)
        Ps.append(kf.P)
    out["stream.x"] = np.array(xs)
    out["stream.P"] = np.array(Ps)
    out["stream.loglik"] = np.float64(kf.loglik)
    assert np.isfinite(out["joseph.loglik"])
    return out


def assert_same(got, want):
    assert got.keys() == want.keys()
    for k in want:
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)
        assert np.asarray(got[k]).dtype == np.float64, k


@pytest.fixture(scope="module")
def exact_baseline():
    return run_everything(dict(EXACT_MATS), dict(EXACT_DATA))


@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("arg", list(EXACT_MATS) + list(EXACT_DATA))
def test_array_likes_give_the_float64_answer(arg, variant, exact_baseline):
    mats, d = dict(EXACT_MATS), dict(EXACT_DATA)
    target = mats if arg in mats else d
    target[arg] = VARIANTS[variant](target[arg])
    assert_same(run_everything(mats, d), exact_baseline)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_array_likes_everywhere_at_once(variant, exact_baseline):
    mats = {k: VARIANTS[variant](v) for k, v in EXACT_MATS.items()}
    d = {k: VARIANTS[variant](v) for k, v in EXACT_DATA.items()}
    assert_same(run_everything(mats, d), exact_baseline)


@pytest.fixture(scope="module")
def stack_baseline():
    return run_everything({**EXACT_MATS, **EXACT_STACKS}, dict(EXACT_DATA))


@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("arg", list(EXACT_STACKS))
def test_array_likes_for_per_step_stacks(arg, variant, stack_baseline):
    mats = {**EXACT_MATS, **EXACT_STACKS}
    mats[arg] = VARIANTS[variant](mats[arg])
    assert_same(run_everything(mats, dict(EXACT_DATA)), stack_baseline)


def test_array_likes_with_non_integer_values():
    """Lists, Fortran and strided views of arbitrary float64 values (no rounding at all)."""
    mats, d = model_mats(), data()
    want = run_everything(mats, d)
    for variant in ["list", "fortran", "strided", "readonly"]:
        f = VARIANTS[variant]
        got = run_everything({k: f(v) for k, v in mats.items()}, {k: f(v) for k, v in d.items()})
        assert_same(got, want)


def _widen(arrays):
    return {k: v.astype(np.float64) for k, v in arrays.items()}


def test_float32_is_widened_not_computed_in_float32():
    """float32 input equals the float64 run on the float32 values (exactly), not a float32 run."""
    mats = {k: v.astype(np.float32) for k, v in model_mats().items()}
    d = {k: v.astype(np.float32) for k, v in data().items()}
    want = run_everything(_widen(mats), _widen(d))
    assert_same(run_everything(mats, d), want)


# --------------------------------------------------------------------------------------------
# scalar (0-d) matrices for n = m = 1

SCALAR = {"F": 0.8, "H": 1.0, "Q": 0.68, "R": 1.0, "B": 0.5, "D": 0.25, "N": 0.1}
Y1 = np.array([0.3, -0.1, 0.7, np.nan, 1.2, 0.0])
U1 = np.array([1.0, 0.0, -1.0, 0.5, 0.0, 2.0])


@pytest.mark.parametrize(
    "kind",
    ["python_float", "python_int_where_possible", "numpy_0d", "numpy_scalar", "float32_0d"],
)
def test_scalar_matrices_for_n_m_1(kind):
    conv = {
        "python_float": float,
        "python_int_where_possible": lambda v: int(v) if float(v).is_integer() else v,
        "numpy_0d": lambda v: np.array(v),
        "numpy_scalar": np.float64,
        "float32_0d": lambda v: np.array(np.float32(v)),
    }[kind]
    as2d = {k: np.array([[v]]) for k, v in SCALAR.items()}
    if kind == "float32_0d":
        as2d = {k: np.array([[np.float32(v)]], dtype=np.float64) for k, v in SCALAR.items()}
    ref_model = kfast.LinearGaussian(**as2d)
    ref = ref_model.filter(Y1[:, None], np.zeros(1), np.ones((1, 1)), u=U1[:, None])

    model = kfast.LinearGaussian(**{k: conv(v) for k, v in SCALAR.items()})
    assert (model.n_states, model.n_obs, model.n_inputs) == (1, 1, 1)
    for x0, P0 in [(conv(0.0), conv(1.0)), (0, 1), ([0.0], [[1.0]]), (np.zeros(1), np.ones((1, 1)))]:
        for y, u in [(Y1, U1), (Y1.tolist(), U1.tolist()), (Y1[:, None], U1[:, None])]:
            res = model.filter(y, x0, P0, u=u)
            for name in ["x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t"]:
                np.testing.assert_array_equal(getattr(res, name), getattr(ref, name), err_msg=name)
            assert res.x_filt.shape == (T, 1) and res.P_filt.shape == (T, 1, 1)
            assert model.loglik(y, x0, P0, u=u) == ref.loglik

    kf = kfast.KalmanFilter(model, conv(0.0), conv(1.0))
    for t in range(T):
        kf.update(float(Y1[t]), conv(float(U1[t])))
        np.testing.assert_array_equal(kf.x, ref.x_filt[t])
        kf.predict(np.float64(U1[t]))
        assert kf.x.shape == (1,) and kf.P.shape == (1, 1)
    assert kf.loglik == ref.loglik


# --------------------------------------------------------------------------------------------
# inputs are never modified

FLAGS = ["writeable", "c_contiguous", "f_contiguous", "owndata", "aligned", "writebackifcopy"]


def _snapshot(value):
    """A deep copy of ``value`` and, for arrays, the flags that must not change."""
    if isinstance(value, np.ndarray):
        flags = {f: getattr(value.flags, f) for f in FLAGS}
        return value.copy(order="K"), flags, value.dtype, value.shape, value.strides
    return copy.deepcopy(value), None, None, None, None


def _assert_unchanged(value, snap):
    saved, flags, dtype, shape, strides = snap
    if flags is None:
        assert value == saved or np.array_equal(np.asarray(value), np.asarray(saved), equal_nan=True)
        return
    assert (value.dtype, value.shape, value.strides) == (dtype, shape, strides)
    assert {f: getattr(value.flags, f) for f in flags} == flags
    np.testing.assert_array_equal(value, saved)


def _inputs(style):
    """Model matrices and data in one of several memory layouts, with NaN in y."""
    mats, d = model_mats(), data()
    d["y"] = d["y"].copy()
    d["y"][2, 1] = np.nan
    d["y"][4, :] = np.nan
    f = {
        "float64": lambda a: a,
        "readonly": readonly,
        "fortran": fortran,
        "strided": strided,
        "float32": lambda a: a.astype(np.float32),
        "list": lambda a: a.tolist(),
    }[style]
    return {k: f(v) for k, v in mats.items()}, {k: f(v) for k, v in d.items()}


@pytest.mark.parametrize("style", ["float64", "readonly", "fortran", "strided", "float32", "list"])
def test_inputs_are_not_modified(style):
    mats, d = _inputs(style)
    snaps = {k: _snapshot(v) for k, v in {**mats, **d}.items()}

    def check(stage):
        for k, v in {**mats, **d}.items():
            try:
                _assert_unchanged(v, snaps[k])
            except AssertionError as e:  # pragma: no cover - message only
                raise AssertionError(f"{k} changed by {stage}: {e}") from None

    model = kfast.LinearGaussian(**mats)
    check("LinearGaussian()")
    for form in ["joseph", "standard"]:
        model.filter(d["y"], d["x0"], d["P0"], u=d["u"], form=form)
        check(f"filter({form})")
        model.loglik(d["y"], d["x0"], d["P0"], u=d["u"], form=form)
        check(f"loglik({form})")
    kf = kfast.KalmanFilter(model, d["x0"], d["P0"])
    check("KalmanFilter()")
    for t in range(T):
        kf.update(d["y"][t], d["u"][t])
        kf.predict(d["u"][t])
    check("update/predict")
    kf2 = kfast.KalmanFilter(model, d["x0"], d["P0"])
    for t in range(T):
        kf2.step(d["y"][t], d["u"][t])
    check("step")
    # the results handed out are fresh arrays, not views of the inputs
    x, P = kf2.x, kf2.P
    x[...] = 1e6
    P[...] = 1e6
    assert kf2.x[0] != 1e6
    check("writing to kf.x / kf.P")


def test_inputs_are_not_modified_by_failing_calls():
    """A call that fails half-way (inf in y at the last step, S singular) leaves inputs alone."""
    mats, d = model_mats(), data()
    d["y"] = d["y"].copy()
    d["y"][-1, 0] = np.inf
    snaps = {k: _snapshot(v) for k, v in {**mats, **d}.items()}
    with fails(msg("y", r"inf", step=T - 1)):
        kfast.LinearGaussian(**mats).filter(**d)
    for k, v in {**mats, **d}.items():
        _assert_unchanged(v, snaps[k])
    y, x0, P0 = np.ones((T, 2)), np.zeros(2), np.zeros((2, 2))
    s = [_snapshot(a) for a in (y, x0, P0)]
    with fails(r"at step 0", kfast.InnovationCovarianceError):
        singular_model().filter(y, x0, P0)
    for a, sn in zip((y, x0, P0), s):
        _assert_unchanged(a, sn)
