"""Bad input is refused with a ``kfast.KfastError`` (a ValueError) whose message names the
argument, the time step when there is one, and the problem; good input in any array-like form
gives the same float64 answer and is never modified.

Every error case is checked with ``pytest.raises(ValueError, match=...)``, anchored at the start
of the message (``"Q at step 3: ..."``), and then required to be a ``kfast.KfastError`` (so that
e.g. a NumPy ValueError leaking out with no argument name fails). A Rust panic would surface as
``pyo3_runtime.PanicException``, a BaseException that ``pytest.raises(ValueError)`` does not
catch, so any panic fails the test that provoked it.

Models used below: ``full_model`` has n = 2 states, m = 2 outputs, k = 1 input, with B, D and N;
data has T = 6 steps.
"""

from __future__ import annotations

import contextlib
import copy
import re

import numpy as np
import pytest

import kfast

T = 6
N_STATES, N_OBS, N_IN = 2, 2, 1


# --------------------------------------------------------------------------------------------
# helpers


def msg(arg, *problem, step=None):
    """Regex for ``"<arg>[ at step <step>]: ... <problem parts, in order> ..."``."""
    head = f"{arg}: " if step is None else f"{arg} at step {step}: "
    return "^" + re.escape(head) + ".*" + ".*".join(problem)


@contextlib.contextmanager
def fails(pattern, exc=kfast.KfastError):
    """``pytest.raises(ValueError, match=pattern)``, and the error must be exactly ``exc``."""
    with pytest.raises(ValueError, match=pattern) as info:
        yield info
    assert type(info.value) is exc, f"{type(info.value).__name__}: {info.value}"


def model_mats(**over):
    """Valid matrices of the full model (n = 2, m = 2, k = 1); ``over`` replaces/removes some."""
    mats = {
        "F": np.array([[0.9, 0.1], [0.0, 0.7]]),
        "H": np.array([[1.0, 0.0], [0.5, 1.0]]),
        "Q": np.array([[0.5, 0.1], [0.1, 0.3]]),
        "R": np.array([[1.0, 0.2], [0.2, 0.8]]),
        "B": np.array([[1.0], [0.5]]),
        "D": np.array([[0.1], [0.2]]),
        "N": np.array([[0.1, 0.0], [0.0, 0.05]]),
    }
    mats.update(over)
    return {k: v for k, v in mats.items() if v is not None}


def plain_mats(**over):
    """F, H, Q, R of the full model only (no B, D, N)."""
    return model_mats(B=None, D=None, N=None, **over)


def data(**over):
    rng = np.random.default_rng(1)
    d = {
        "y": rng.normal(size=(T, N_OBS)),
        "x0": np.array([0.5, -0.5]),
        "P0": np.array([[1.0, 0.3], [0.3, 2.0]]),
        "u": rng.normal(size=(T, N_IN)),
    }
    d.update(over)
    return {k: v for k, v in d.items() if v is not None}


def full_model():
    return kfast.LinearGaussian(**model_mats())


def plain_model():
    return kfast.LinearGaussian(**plain_mats())


def per_step_model(steps=T, **over):
    """The full model with F and Q given per step (``steps`` of them)."""
    mats = model_mats()
    mats["F"] = np.stack([mats["F"] * (1 - 0.05 * t) for t in range(steps)])
    mats["Q"] = np.stack([mats["Q"] * (1 + 0.1 * t) for t in range(steps)])
    mats.update(over)
    return kfast.LinearGaussian(**mats)


def batch(how, model, **d):
    """``model.filter(**d)`` or ``model.loglik(**d)``."""
    return getattr(model, how)(**d)


BATCH = ["filter", "loglik"]


def stack(a, steps=T):
    return np.stack([a] * steps)


# --------------------------------------------------------------------------------------------
# the exception classes


def test_exception_hierarchy():
    assert issubclass(kfast.KfastError, ValueError)
    assert issubclass(kfast.InnovationCovarianceError, kfast.KfastError)


# --------------------------------------------------------------------------------------------
# model constructor: ndim and shape of F, H, Q, R, B, D, N

BAD_MODEL_SHAPES = {
    # name: (overrides, expected message regex)
    "F_1d": ({"F": np.ones(2)}, msg("F", r"2-D matrix or a 3-D stack", r"\[2\]")),
    "F_4d": ({"F": np.ones((1, 1, 2, 2))}, msg("F", r"2-D matrix or a 3-D stack", r"\[1, 1, 2, 2\]")),
    "F_not_square": ({"F": np.ones((2, 3))}, msg("F", r"expected shape \(2, 2\)", r"square", r"got \(2, 3\)")),
    "F_empty": ({"F": np.ones((0, 0)), "H": np.ones((2, 0))}, msg("F", r"n = 0", r"must not be empty")),
    "F_zero_steps": ({"F": np.ones((0, 2, 2))}, msg("F", r"at least one step", r"T = 0")),
    "H_1d": ({"H": np.ones(2)}, msg("H", r"2-D matrix or a 3-D stack", r"\[2\]")),
    "H_wrong_cols": ({"H": np.ones((2, 3))}, msg("H", r"expected shape \(2, 2\)", r"got \(2, 3\)")),
    "H_no_rows": ({"H": np.ones((0, 2)), "R": np.ones((0, 0))}, msg("F", r"m = 0", r"must not be empty")),
    "Q_1d": ({"Q": np.ones(4)}, msg("Q", r"2-D matrix or a 3-D stack", r"\[4\]")),
    "Q_wrong_size": ({"Q": np.eye(3)}, msg("Q", r"expected shape \(2, 2\)", r"got \(3, 3\)")),
    "Q_not_square": ({"Q": np.ones((2, 3))}, msg("Q", r"expected shape \(2, 2\)", r"got \(2, 3\)")),
    "Q_stack_not_square": ({"Q": np.ones((T, 2, 3))}, msg("Q", r"expected shape \(2, 2\)", r"got \(2, 3\)")),
    "R_4d": ({"R": np.ones((1, 1, 2, 2))}, msg("R", r"2-D matrix or a 3-D stack")),
    "R_wrong_size": ({"R": np.eye(3)}, msg("R", r"expected shape \(2, 2\)", r"got \(3, 3\)")),
    "R_not_square": ({"R": np.ones((2, 1))}, msg("R", r"expected shape \(2, 2\)", r"got \(2, 1\)")),
    "B_1d": ({"B": np.ones(2)}, msg("B", r"2-D matrix or a 3-D stack", r"\[2\]")),
    "B_wrong_rows": ({"B": np.ones((3, 1))}, msg("B", r"expected shape \(2, 1\)", r"got \(3, 1\)")),
    "D_1d": ({"D": np.ones(2)}, msg("D", r"2-D matrix or a 3-D stack", r"\[2\]")),
    "D_wrong_rows": ({"D": np.ones((3, 1))}, msg("D", r"expected shape \(2, 1\)", r"got \(3, 1\)")),
    "D_k_differs_from_B": ({"D": np.ones((2, 2))}, msg("D", r"expected shape \(2, 1\)", r"got \(2, 2\)")),
    "N_1d": ({"N": np.ones(4)}, msg("N", r"2-D matrix or a 3-D stack", r"\[4\]")),
    "N_wrong_rows": ({"N": np.zeros((3, 2))}, msg("N", r"expected shape \(2, 2\)", r"got \(3, 2\)")),
    "N_wrong_cols": ({"N": np.zeros((2, 3))}, msg("N", r"expected shape \(2, 2\)", r"got \(2, 3\)")),
    "N_stack_wrong_shape": ({"N": np.zeros((T, 2, 1))}, msg("N", r"expected shape \(2, 2\)", r"got \(2, 1\)")),
}


@pytest.mark.parametrize("case", list(BAD_MODEL_SHAPES), ids=list(BAD_MODEL_SHAPES))
def test_model_bad_shape(case):
    over, pattern = BAD_MODEL_SHAPES[case]
    with fails(pattern):
        kfast.LinearGaussian(**model_mats(**over))


@pytest.mark.parametrize("arg", ["H", "Q", "R", "B", "D", "N"])
def test_model_per_step_matrices_must_share_T(arg):
    """F has 5 steps, ``arg`` has 4: the message names ``arg``, both step counts and F."""
    mats = model_mats()
    mats["F"] = stack(mats["F"], 5)
    mats[arg] = stack(mats[arg], 4)
    with fails(msg(arg, r"has 4 steps but F has 5", r"share T")):
        kfast.LinearGaussian(**mats)


def test_model_per_step_matrices_must_share_T_without_F():
    mats = model_mats()
    mats["Q"] = stack(mats["Q"], 3)
    mats["N"] = stack(mats["N"], 7)
    with fails(msg("N", r"has 7 steps but Q has 3")):
        kfast.LinearGaussian(**mats)


def test_model_reports_steps():
    assert per_step_model().steps == T
    assert full_model().steps is None


# --------------------------------------------------------------------------------------------
# filter / loglik: ndim and shape of y, x0, P0, u; T mismatches

BAD_DATA_SHAPES = {
    "y_1d_for_m2": ({"y": np.zeros(T)}, msg("y", r"2-D", r"\[6\]")),
    "y_3d": ({"y": np.zeros((T, 2, 1))}, msg("y", r"2-D", r"\[6, 2, 1\]")),
    "y_0d": ({"y": 1.0}, msg("y", r"2-D", r"\[\]")),
    "y_wrong_width": ({"y": np.zeros((T, 3))}, msg("y", r"\(T, 2\)", r"m = 2", r"got \(T, 3\)")),
    "y_no_steps": ({"y": np.zeros((0, 2))}, msg("y", r"no time steps", r"T = 0")),
    "x0_2d": ({"x0": np.zeros((2, 1))}, msg("x0", r"1-D", r"\[2, 1\]")),
    "x0_0d": ({"x0": 0.0}, msg("x0", r"1-D", r"\[\]")),
    "x0_wrong_length": ({"x0": np.zeros(3)}, msg("x0", r"expected 2 entries", r"got 3")),
    "P0_1d": ({"P0": np.ones(4)}, msg("P0", r"2-D", r"\[4\]")),
    "P0_3d": ({"P0": np.ones((1, 2, 2))}, msg("P0", r"2-D", r"\[1, 2, 2\]")),
    "P0_wrong_size": ({"P0": np.eye(3)}, msg("P0", r"\(2, 2\)", r"\[3, 3\]")),
    "P0_not_square": ({"P0": np.ones((2, 3))}, msg("P0", r"square \(2, 2\)", r"\[2, 3\]")),
    "P0_column_of_n2_entries": ({"P0": np.eye(2).reshape(4, 1)}, msg("P0", r"square \(2, 2\)", r"\[4, 1\]")),
    "P0_row_of_n2_entries": ({"P0": np.eye(2).reshape(1, 4)}, msg("P0", r"square \(2, 2\)", r"\[1, 4\]")),
    "u_3d": ({"u": np.zeros((T, 1, 1))}, msg("u", r"2-D", r"\[6, 1, 1\]")),
    "u_0d": ({"u": 0.0}, msg("u", r"2-D", r"\[\]")),
    "u_wrong_width": ({"u": np.zeros((T, 2))}, msg("u", r"expected 1 inputs", r"got 2")),
    "u_fewer_steps_than_y": ({"u": np.zeros((T - 1, 1))}, msg("u", r"has 5 steps but y has 6")),
    "u_more_steps_than_y": ({"u": np.zeros((T + 1, 1))}, msg("u", r"has 7 steps but y has 6")),
}


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("case", list(BAD_DATA_SHAPES), ids=list(BAD_DATA_SHAPES))
def test_data_bad_shape(how, case):
    over, pattern = BAD_DATA_SHAPES[case]
    with fails(pattern):
        batch(how, full_model(), **data(**over))


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("y_steps", [T - 1, T + 1])
def test_y_steps_must_match_per_step_model(how, y_steps):
    model = per_step_model(T)
    d = data(y=np.zeros((y_steps, 2)), u=np.zeros((y_steps, 1)))
    with fails(msg("y", rf"has {y_steps} steps but the model's per-step matrices have {T}")):
        batch(how, model, **d)


@pytest.mark.parametrize("how", BATCH)
def test_u_steps_must_match_y_with_per_step_model(how):
    model = per_step_model(T)
    with fails(msg("u", r"has 5 steps but y has 6")):
        batch(how, model, **data(u=np.zeros((T - 1, 1))))


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize(
    "over, pattern",
    [
        ({"x0": [0.0, 0.0]}, msg("x0", r"expected 1 entries", r"got 2")),
        ({"x0": np.zeros((1, 1, 2))}, msg("x0", r"1-D")),
        ({"P0": np.eye(2)}, msg("P0", r"square \(1, 1\)", r"\[2, 2\]")),
        ({"P0": [1.0, 1.0]}, msg("P0", r"2-D", r"\[2\]")),
        ({"y": np.zeros((T, 2))}, msg("y", r"\(T, 1\)", r"got \(T, 2\)")),
    ],
    ids=["x0_len2", "x0_3d", "P0_2x2", "P0_len2", "y_width2"],
)
def test_scalar_model_data_bad_shape(how, over, pattern):
    model = kfast.LinearGaussian(0.8, 1.0, 0.68, 1.0)
    d = {"y": np.zeros(T), "x0": 0.0, "P0": 1.0}
    d.update(over)
    with fails(pattern):
        batch(how, model, **d)


# --------------------------------------------------------------------------------------------
# streaming: ndim and shape of x0, P0, y, u


@pytest.mark.parametrize(
    "over, pattern",
    [
        ({"x0": np.zeros((2, 1))}, msg("x0", r"1-D", r"\[2, 1\]")),
        ({"x0": np.zeros(3)}, msg("x0", r"expected 2 entries", r"got 3")),
        ({"x0": 0.0}, msg("x0", r"1-D", r"\[\]")),
        ({"P0": np.ones(4)}, msg("P0", r"2-D", r"\[4\]")),
        ({"P0": np.ones((1, 2, 2))}, msg("P0", r"2-D")),
        ({"P0": np.ones((2, 3))}, msg("P0", r"square \(2, 2\)", r"\[2, 3\]")),
        ({"P0": np.eye(2).reshape(4, 1)}, msg("P0", r"square \(2, 2\)", r"\[4, 1\]")),
        ({"P0": np.eye(3)}, msg("P0", r"\(2, 2\)", r"\[3, 3\]")),
    ],
    ids=["x0_2d", "x0_len3", "x0_0d", "P0_1d", "P0_3d", "P0_not_square", "P0_4x1", "P0_3x3"],
)
def test_stream_prior_bad_shape(over, pattern):
    d = data(**over)
    with fails(pattern):
        kfast.KalmanFilter(full_model(), d["x0"], d["P0"])


@pytest.mark.parametrize(
    "x0, P0, pattern",
    [
        ([0.0, 0.0], 1.0, msg("x0", r"expected 1 entries", r"got 2")),
        (0.0, np.eye(2), msg("P0", r"square \(1, 1\)", r"\[2, 2\]")),
        (0.0, [1.0, 1.0], msg("P0", r"2-D", r"\[2\]")),
    ],
    ids=["x0_len2", "P0_2x2", "P0_len2"],
)
def test_stream_scalar_model_prior_bad_shape(x0, P0, pattern):
    model = kfast.LinearGaussian(0.8, 1.0, 0.68, 1.0)
    with fails(pattern):
        kfast.KalmanFilter(model, x0, P0)


def test_stream_model_must_be_a_model():
    with fails(msg("model", r"kfast.LinearGaussian")):
        kfast.KalmanFilter(model_mats(), [0.0, 0.0], np.eye(2))


def _stream(model=None, steps=0, **d):
    """A KalmanFilter on the full model advanced by ``steps`` clean steps."""
    model = full_model() if model is None else model
    dd = data(**d)
    kf = kfast.KalmanFilter(model, dd["x0"], dd["P0"])
    for t in range(steps):
        kf.step(dd["y"][t], dd["u"][t])
    return kf


@pytest.mark.parametrize("method", ["update", "step"])
@pytest.mark.parametrize("t", [0, 2])
@pytest.mark.parametrize(
    "y, pattern",
    [
        (np.zeros(3), r"expected 2 values \(m = 2\), got 3"),
        (np.zeros(1), r"expected 2 values \(m = 2\), got 1"),
        (0.0, r"expected 2 values \(m = 2\), got 1"),
    ],
    ids=["len3", "len1", "scalar"],
)
def test_stream_y_wrong_length(method, t, y, pattern):
    kf = _stream(steps=t)
    with fails(msg("y", pattern, step=t)):
        getattr(kf, method)(y, [0.0])


@pytest.mark.parametrize("method", ["update", "step"])
def test_stream_y_wrong_ndim(method):
    kf = _stream()
    with fails(msg("y", r"1-D", r"\[1, 2\]")):
        getattr(kf, method)(np.zeros((1, 2)), [0.0])


@pytest.mark.parametrize("method", ["update", "predict", "step"])
@pytest.mark.parametrize(
    "u, pattern",
    [
        (np.zeros(2), msg("u", r"expected 1 inputs", r"got 2")),
        (np.zeros((1, 1)), msg("u", r"1-D", r"\[1, 1\]")),
    ],
    ids=["len2", "2d"],
)
def test_stream_u_bad_shape(method, u, pattern):
    kf = _stream(steps=1)
    with fails(pattern):
        if method == "predict":
            kf.predict(u)
        else:
            getattr(kf, method)(np.zeros(2), u)


# --------------------------------------------------------------------------------------------
# covariances: symmetric, positive semidefinite, jointly PSD with N

ASYM = np.array([[1.0, 0.5], [0.4, 1.0]])
NOT_PSD = np.array([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3, -1


@pytest.mark.parametrize("arg", ["Q", "R"])
def test_model_covariance_not_symmetric(arg):
    with fails(msg(arg, r"not symmetric", r"\(1, 0\) is 0.4", r"\(0, 1\) is 0.5")):
        kfast.LinearGaussian(**model_mats(**{arg: ASYM}))


@pytest.mark.parametrize("arg", ["Q", "R"])
def test_model_covariance_not_psd(arg):
    with fails(msg(arg, r"not positive semidefinite", r"smallest eigenvalue -1")):
        kfast.LinearGaussian(**model_mats(**{arg: NOT_PSD}))


@pytest.mark.parametrize("arg", ["Q", "R"])
def test_model_scalar_covariance_negative(arg):
    mats = {"F": 0.5, "H": 1.0, "Q": 1.0, "R": 1.0}
    mats[arg] = -0.25
    with fails(msg(arg, r"not positive semidefinite", r"-0.25")):
        kfast.LinearGaussian(**mats)


@pytest.mark.parametrize("arg", ["Q", "R"])
def test_model_per_step_covariance_not_psd_at_step_3(arg):
    mats = model_mats()
    mats[arg] = stack(mats[arg])
    mats[arg][3] = NOT_PSD
    with fails(msg(arg, r"not positive semidefinite", step=3)):
        kfast.LinearGaussian(**mats)


@pytest.mark.parametrize("arg", ["Q", "R"])
def test_model_per_step_covariance_not_symmetric_at_step_3(arg):
    mats = model_mats()
    mats[arg] = stack(mats[arg])
    mats[arg][3] = ASYM
    with fails(msg(arg, r"not symmetric", step=3)):
        kfast.LinearGaussian(**mats)


def test_model_joint_covariance_not_psd():
    """Q and R are each PSD (identity), but [[Q, N], [N', R]] with N = 2 I is not."""
    Q, R, N = np.eye(2), np.eye(2), 2 * np.eye(2)
    assert np.linalg.eigvalsh(Q).min() > 0 and np.linalg.eigvalsh(R).min() > 0
    with fails(msg("N", r"joint noise covariance \[\[Q, N\], \[N', R\]\]", r"not positive semidefinite")):
        kfast.LinearGaussian(**model_mats(Q=Q, R=R, N=N))


def test_model_joint_covariance_not_psd_scalar():
    with fails(msg("N", r"joint", r"not positive semidefinite")):
        kfast.LinearGaussian(0.5, 1.0, 1.0, 1.0, N=1.5)


def test_model_joint_covariance_not_psd_at_step_3():
    """Per-step N, constant Q and R: only step 3's joint covariance is indefinite."""
    mats = model_mats(Q=np.eye(2), R=np.eye(2))
    mats["N"] = stack(0.1 * np.eye(2))
    mats["N"][3] = 2 * np.eye(2)
    with fails(msg("N", r"joint", r"not positive semidefinite", step=3)):
        kfast.LinearGaussian(**mats)


def test_model_joint_covariance_at_boundary_is_accepted():
    """N = I with Q = R = I: the joint covariance is singular PSD, which is allowed."""
    kfast.LinearGaussian(**model_mats(Q=np.eye(2), R=np.eye(2), N=np.eye(2)))


@pytest.mark.parametrize("how", BATCH + ["stream"])
@pytest.mark.parametrize(
    "P0, pattern",
    [
        (ASYM, msg("P0", r"not symmetric", r"0.4", r"0.5")),
        (NOT_PSD, msg("P0", r"not positive semidefinite", r"-1")),
        (-np.eye(2), msg("P0", r"not positive semidefinite")),
    ],
    ids=["asymmetric", "indefinite", "negative_definite"],
)
def test_P0_not_a_covariance(how, P0, pattern):
    d = data(P0=P0)
    with fails(pattern):
        if how == "stream":
            kfast.KalmanFilter(full_model(), d["x0"], d["P0"])
        else:
            batch(how, full_model(), **d)


# --------------------------------------------------------------------------------------------
# NaN and inf


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("arg", ["F", "H", "Q", "R", "B", "D", "N"])
def test_model_non_finite(arg, bad):
    mats = model_mats()
    a = mats[arg].copy()
    a[0, 0] = bad
    mats[arg] = a
    with fails(msg(arg, r"non-finite", r"(NaN|inf)")):
        kfast.LinearGaussian(**mats)


@pytest.mark.parametrize("bad", [np.nan, np.inf], ids=["nan", "inf"])
@pytest.mark.parametrize("arg", ["F", "H", "Q", "R", "B", "D", "N"])
def test_model_per_step_non_finite_at_step_4(arg, bad):
    mats = model_mats()
    mats[arg] = stack(mats[arg])
    mats[arg][4, -1, -1] = bad
    with fails(msg(arg, r"non-finite", r"(NaN|inf)", step=4)):
        kfast.LinearGaussian(**mats)


@pytest.mark.parametrize("how", BATCH + ["stream"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("arg", ["x0", "P0"])
def test_prior_non_finite(how, arg, bad):
    d = data()
    d[arg] = d[arg].copy()
    d[arg].flat[-1] = bad
    with fails(msg(arg, r"non-finite", r"(NaN|inf)")):
        if how == "stream":
            kfast.KalmanFilter(full_model(), d["x0"], d["P0"])
        else:
            batch(how, full_model(), **d)


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("bad", [np.inf, -np.inf], ids=["inf", "-inf"])
def test_y_inf_names_the_step(how, bad):
    y = data()["y"].copy()
    y[4, 1] = bad
    with fails(msg("y", r"component 1 is -?inf", r"missing values are NaN", step=4)):
        batch(how, full_model(), **data(y=y))


@pytest.mark.parametrize("method", ["update", "step"])
@pytest.mark.parametrize("bad", [np.inf, -np.inf], ids=["inf", "-inf"])
def test_stream_y_inf_names_the_step(method, bad):
    kf = _stream(steps=3)
    with fails(msg("y", r"component 0 is -?inf", step=3)):
        getattr(kf, method)([bad, 0.0], [0.0])


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
def test_u_non_finite_names_the_step(how, bad):
    u = data()["u"].copy()
    u[2, 0] = bad
    with fails(msg("u", r"non-finite", r"(NaN|inf)", step=2)):
        batch(how, full_model(), **data(u=u))


@pytest.mark.parametrize("method", ["update", "predict", "step"])
@pytest.mark.parametrize("bad", [np.nan, np.inf], ids=["nan", "inf"])
def test_stream_u_non_finite_names_the_step(method, bad):
    kf = _stream(steps=2)
    with fails(msg("u", r"non-finite", r"(NaN|inf)", step=2)):
        if method == "predict":
            kf.predict([bad])
        else:
            getattr(kf, method)([0.1, 0.2], [bad])


@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_nan_in_y_is_missing_data_not_an_error(form):
    """Whole and partial NaN rows are missing data: no error, finite estimates, NaN innovations
    only where y is missing, loglik_t = 0 for a whole missing row; loglik and streaming agree."""
    model = full_model()
    d = data()
    y = d["y"].copy()
    y[1, :] = np.nan
    y[3, 0] = np.nan
    res = model.filter(y, d["x0"], d["P0"], u=d["u"], form=form)
    for name in ["x_pred", "P_pred", "x_filt", "P_filt", "S", "K", "K_pred", "loglik_t", "x_next", "P_next"]:
        assert np.isfinite(getattr(res, name)).all(), name
    assert np.isfinite(res.loglik)
    np.testing.assert_array_equal(np.isnan(res.innov), np.isnan(y))
    assert res.loglik_t[1] == 0.0
    np.testing.assert_array_equal(res.x_filt[1], res.x_pred[1])
    np.testing.assert_array_equal(res.K[1], 0.0)
    np.testing.assert_array_equal(res.K[3][:, 0], 0.0)
    assert model.loglik(y, d["x0"], d["P0"], u=d["u"], form=form) == pytest.approx(res.loglik, rel=1e-12)

    kf = kfast.KalmanFilter(model, d["x0"], d["P0"], form=form)
    for t in range(T):
        kf.update(y[t], d["u"][t])
        np.testing.assert_allclose(kf.x, res.x_filt[t], rtol=1e-12, atol=1e-14)
        kf.predict(d["u"][t])
    assert kf.loglik == pytest.approx(res.loglik, rel=1e-12)


def test_nan_in_y_all_missing():
    res = full_model().filter(np.full((T, 2), np.nan), [0.0, 0.0], np.eye(2), u=np.zeros((T, 1)))
    assert res.loglik == 0.0
    assert np.isfinite(res.P_pred).all() and np.isnan(res.innov).all()


# --------------------------------------------------------------------------------------------
# the innovation covariance S = H P H' + R cannot be factorized


def singular_model(**over):
    """R = 0, Q = 0: with P0 = 0, S = 0 at step 0."""
    mats = plain_mats(Q=np.zeros((2, 2)), R=np.zeros((2, 2)))
    mats.update(over)
    return kfast.LinearGaussian(**mats)


@pytest.mark.parametrize("form", ["joseph", "standard"])
@pytest.mark.parametrize("how", BATCH)
def test_innovation_covariance_singular_at_step_0(how, form):
    pattern = r"^innovation covariance S = H P H' \+ R at step 0 cannot be factorized"
    with fails(pattern, kfast.InnovationCovarianceError):
        batch(how, singular_model(), y=np.ones((T, 2)), x0=[0.0, 0.0], P0=np.zeros((2, 2)), form=form)


def test_subnormal_innovation_covariance_is_an_error_not_nan():
    """S = 2e-310 is positive but its reciprocal overflows: an error, never inf or NaN."""
    s = 1e-310
    model = kfast.LinearGaussian(np.eye(1), np.eye(1), np.eye(1) * s, np.eye(1) * s)
    with fails(r"^innovation covariance S = H P H' \+ R at step 0 cannot be factorized", kfast.InnovationCovarianceError):
        model.filter(np.array([[0.0]]), np.zeros(1), np.eye(1) * s)


def test_innovation_covariance_error_is_a_kfast_error():
    with pytest.raises(kfast.KfastError, match=r"at step 0"):
        singular_model().loglik(np.ones((T, 2)), [0.0, 0.0], np.zeros((2, 2)))


@pytest.mark.parametrize("method", ["update", "step"])
def test_stream_innovation_covariance_singular_at_step_0(method):
    kf = kfast.KalmanFilter(singular_model(), [0.0, 0.0], np.zeros((2, 2)))
    with fails(r"^innovation covariance .* at step 0 cannot be factorized", kfast.InnovationCovarianceError):
        getattr(kf, method)([1.0, 1.0])


def later_singular_model():
    """n = m = 1, F = 0, Q = 0, R = 0, H = 1, P0 = 1: S = 1 at step 0, then P(1|0) = 0 and
    S = 0 at step 1 (constant matrices)."""
    return kfast.LinearGaussian(0.0, 1.0, 0.0, 0.0)


@pytest.mark.parametrize("how", BATCH)
def test_innovation_covariance_singular_at_later_step(how):
    with fails(r"^innovation covariance .* at step 1 cannot be factorized", kfast.InnovationCovarianceError):
        batch(how, later_singular_model(), y=[1.0, 2.0, 3.0], x0=0.0, P0=1.0)


@pytest.mark.parametrize("how", BATCH)
def test_innovation_covariance_singular_at_step_2_per_step_R(how):
    """Per-step R = 1, 1, 0, 1 with H P H' singular (only the unobserved state is uncertain)."""
    R = np.ones((4, 1, 1))
    R[2] = 0.0
    model = kfast.LinearGaussian(F=[[0.0, 0.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=np.zeros((2, 2)), R=R)
    with fails(r"^innovation covariance .* at step 2 cannot be factorized", kfast.InnovationCovarianceError):
        batch(how, model, y=np.zeros(4), x0=[0.0, 0.0], P0=np.diag([0.0, 1.0]))


def test_stream_innovation_covariance_singular_at_later_step():
    kf = kfast.KalmanFilter(later_singular_model(), 0.0, 1.0)
    kf.step(1.0)
    with fails(r"^innovation covariance .* at step 1 cannot be factorized", kfast.InnovationCovarianceError):
        kf.update(2.0)
    # the failed update left the filter usable: predict treats the step as missing
    kf.predict()
    assert kf.t == 2


def test_singular_innovation_covariance_where_y_is_missing_is_not_an_error():
    res = singular_model().filter(np.full((T, 2), np.nan), [0.0, 0.0], np.zeros((2, 2)))
    assert res.loglik == 0.0


# --------------------------------------------------------------------------------------------
# complex input


@pytest.mark.parametrize("arg", ["F", "H", "Q", "R", "B", "D", "N"])
def test_model_complex_matrix(arg):
    mats = model_mats()
    mats[arg] = mats[arg] + 0j
    with fails(msg(arg, r"complex")):
        kfast.LinearGaussian(**mats)


def test_model_complex_scalar():
    with fails(msg("F", r"complex")):
        kfast.LinearGaussian(0.5 + 1j, 1.0, 1.0, 1.0)


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("arg", ["y", "x0", "P0", "u"])
def test_data_complex(how, arg):
    d = data()
    d[arg] = d[arg].astype(complex)
    with fails(msg(arg, r"complex")):
        batch(how, full_model(), **d)


@pytest.mark.parametrize("arg", ["x0", "P0"])
def test_stream_prior_complex(arg):
    d = data()
    d[arg] = d[arg].astype(complex)
    with fails(msg(arg, r"complex")):
        kfast.KalmanFilter(full_model(), d["x0"], d["P0"])


@pytest.mark.parametrize("method", ["update", "step"])
def test_stream_y_complex(method):
    with fails(msg("y", r"complex")):
        getattr(_stream(), method)(np.array([1.0, 2.0 + 1j]), [0.0])


@pytest.mark.parametrize("method", ["update", "predict", "step"])
def test_stream_u_complex(method):
    kf = _stream()
    with fails(msg("u", r"complex")):
        if method == "predict":
            kf.predict([1j])
        else:
            getattr(kf, method)([0.0, 0.0], [1j])


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
# u and the model's B/D; form


@pytest.mark.parametrize("how", BATCH)
def test_u_given_to_model_without_inputs(how):
    with fails(msg("u", r"given, but the model has neither B nor D")):
        batch(how, plain_model(), **data())


@pytest.mark.parametrize("method", ["update", "predict", "step"])
def test_stream_u_given_to_model_without_inputs(method):
    kf = kfast.KalmanFilter(plain_model(), [0.0, 0.0], np.eye(2))
    with fails(msg("u", r"neither B nor D")):
        if method == "predict":
            kf.predict([1.0])
        else:
            getattr(kf, method)([0.0, 0.0], [1.0])


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("which", ["B", "D", "BD"])
def test_u_missing_for_model_with_inputs(how, which):
    mats = model_mats(**{k: None for k in "BD" if k not in which})
    d = data(u=None)
    with fails(msg("u", r"model has B or D", r"k = 1", r"required")):
        batch(how, kfast.LinearGaussian(**mats), **d)


def test_stream_u_missing_for_model_with_B():
    """predict needs u when the model has B; the update (no D) does not."""
    kf = kfast.KalmanFilter(kfast.LinearGaussian(**model_mats(D=None)), [0.0, 0.0], np.eye(2))
    kf.update([0.1, 0.2])
    with fails(msg("u", r"model has B", r"required", step=0)):
        kf.predict()
    with fails(msg("u", r"model has B", r"required", step=0)):
        kf.predict(None)
    kf.predict([1.0])
    with fails(msg("u", r"model has B", r"required", step=1)):
        kf.step([0.1, 0.2])


def test_stream_u_missing_for_model_with_D():
    """update needs u when the model has D; the predict (no B) does not."""
    kf = kfast.KalmanFilter(kfast.LinearGaussian(**model_mats(B=None)), [0.0, 0.0], np.eye(2))
    with fails(msg("u", r"model has D", r"required", step=0)):
        kf.update([0.1, 0.2])
    with fails(msg("u", r"model has D", r"required", step=0)):
        kf.step([0.1, 0.2])
    kf.predict()
    assert kf.t == 1


def test_stream_with_B_only_or_D_only_equals_filter():
    """update(y) then predict(u) for a B-only model, update(y, u) then predict() for D-only."""
    d = data()
    for drop, upd_u, pred_u in [("D", False, True), ("B", True, False)]:
        model = kfast.LinearGaussian(**model_mats(**{drop: None}))
        res = model.filter(**d)
        kf = kfast.KalmanFilter(model, d["x0"], d["P0"])
        for t in range(T):
            kf.update(d["y"][t], d["u"][t] if upd_u else None)
            np.testing.assert_allclose(kf.x, res.x_filt[t], rtol=1e-12, atol=1e-14)
            kf.predict(d["u"][t] if pred_u else None)
            np.testing.assert_allclose(kf.x, res.x_pred[t + 1] if t + 1 < T else res.x_next, rtol=1e-12, atol=1e-14)
        assert kf.loglik == pytest.approx(res.loglik, rel=1e-12)


@pytest.mark.parametrize("form", ["bad", "Joseph", "", "standard "])
@pytest.mark.parametrize("how", BATCH + ["stream"])
def test_bad_form(how, form):
    with fails(r"^form: expected .*joseph.*standard.*got .*" + re.escape(form)):
        if how == "stream":
            kfast.KalmanFilter(full_model(), [0.0, 0.0], np.eye(2), form=form)
        else:
            batch(how, full_model(), **data(), form=form)


# --------------------------------------------------------------------------------------------
# streaming protocol


def test_stream_update_twice_without_predict():
    kf = _stream()
    kf.update([0.1, 0.2], [0.0])
    with fails(msg("y", r"update called twice without a predict", step=0)):
        kf.update([0.1, 0.2], [0.0])


def test_stream_update_twice_at_later_step():
    kf = _stream(steps=3)
    kf.update([0.1, 0.2], [0.0])
    with fails(msg("y", r"update called twice", step=3)):
        kf.update([0.1, 0.2], [0.0])
    with fails(msg("y", r"update called twice", step=3)):
        kf.step([0.1, 0.2], [0.0])
    kf.predict([0.0])
    assert kf.t == 4


@pytest.mark.parametrize("method", ["update", "predict", "step"])
def test_stream_past_the_end_of_per_step_model(method):
    model = per_step_model(3)
    d = data()
    kf = kfast.KalmanFilter(model, d["x0"], d["P0"])
    for t in range(3):
        kf.step(d["y"][t], d["u"][t])
    assert kf.t == 3
    with fails(msg("model", r"cover 3 steps", r"step 3 is past the end")):
        if method == "predict":
            kf.predict(d["u"][3])
        else:
            getattr(kf, method)(d["y"][3], d["u"][3])


def test_stream_past_the_end_by_predicts_only():
    model = per_step_model(2)
    kf = kfast.KalmanFilter(model, [0.0, 0.0], np.eye(2))
    kf.predict([0.0])
    kf.predict([0.0])
    with fails(msg("model", r"cover 2 steps", r"step 2 is past the end")):
        kf.predict([0.0])


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


def test_scalar_prior_shapes_for_n_1_stream():
    model = kfast.LinearGaussian(0.8, 1.0, 0.68, 1.0)
    for x0, P0 in [(0.0, 1.0), ([0.0], [[1.0]]), (np.zeros(1), np.ones(1)), (np.zeros((1, 1)), np.ones((1, 1)))]:
        kf = kfast.KalmanFilter(model, x0, P0)
        kf.step(0.3)
        kf.step([0.3])
        kf.step(np.array([[0.3]])[0])


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


def test_model_copies_its_matrices():
    """The model keeps read-only copies: changing the caller's arrays afterwards changes
    nothing, and the caller's arrays keep their writeable flag."""
    mats, d = model_mats(), data()
    model = kfast.LinearGaussian(**mats)
    want = model.filter(**d)
    for k, v in mats.items():
        attr = getattr(model, k)
        assert not np.shares_memory(attr, v), k
        assert not attr.flags.writeable, k
        assert v.flags.writeable, k
        with pytest.raises(ValueError):
            attr[...] = 0.0
        v[...] = 0.0  # the caller's array is theirs to change
    got = model.filter(**d)
    np.testing.assert_array_equal(got.x_filt, want.x_filt)
    assert got.loglik == want.loglik


def test_model_symmetrizes_its_own_copy_not_the_input():
    """Q with rounding-level asymmetry is accepted; the caller's Q stays asymmetric."""
    Q = np.array([[0.5, 0.1], [0.1 + 1e-13, 0.3]])
    saved = Q.copy()
    kfast.LinearGaussian(**model_mats(Q=Q))
    np.testing.assert_array_equal(Q, saved)
