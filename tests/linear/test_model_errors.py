"""Bad input to the ``kfast.LinearGaussian`` constructor: shapes, per-step stacks, covariances
(symmetric, PSD, jointly PSD with N), NaN and inf, complex values; the model keeps its own
copies of the matrices. Conventions of the checks: badinput.py."""

from __future__ import annotations

import numpy as np
import pytest

import kfast
from kfast.linear.complex import ComplexLinearGaussian
from badinput import ASYM, NOT_PSD, T, data, fails, full_model, model_mats, msg, per_step_model, stack


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
    "F_empty": ({"F": np.ones((0, 0)), "H": np.ones((2, 0))}, msg("F", r"is empty", r"n ≥ 1")),
    "F_zero_steps": ({"F": np.ones((0, 2, 2))}, msg("F", r"at least one step", r"T = 0")),
    "H_1d": ({"H": np.ones(2)}, msg("H", r"2-D matrix or a 3-D stack", r"\[2\]")),
    "H_wrong_cols": ({"H": np.ones((2, 3))}, msg("H", r"expected shape \(2, 2\)", r"got \(2, 3\)")),
    "H_no_rows": ({"H": np.ones((0, 2)), "R": np.ones((0, 0))}, msg("H", r"has no rows", r"m ≥ 1")),
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
# covariances: symmetric, positive semidefinite, jointly PSD with N


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


# --------------------------------------------------------------------------------------------
# complex input


@pytest.mark.parametrize("arg", ["F", "H", "Q", "R", "B", "D", "N"])
def test_model_complex_matrix(arg):
    """A complex matrix makes a complex-valued model (tests/linear/test_complex.py), which
    checks its Hermitian covariances by name."""
    mats = model_mats()
    mats[arg] = mats[arg] + 0j
    model = kfast.LinearGaussian(**mats)
    assert isinstance(model, ComplexLinearGaussian)
    if arg in ("Q", "R"):
        mats[arg] = mats[arg] + 1j * np.triu(np.ones(mats[arg].shape), 1)
        with fails(msg(arg, r"Hermitian")):
            kfast.LinearGaussian(**mats)


def test_model_complex_scalar():
    assert isinstance(kfast.LinearGaussian(0.5 + 1j, 1.0, 1.0, 1.0), ComplexLinearGaussian)
    with fails(msg("Q", r"Hermitian")):
        kfast.LinearGaussian(0.5, 1.0, 1.0 + 1j, 1.0)


# --------------------------------------------------------------------------------------------
# the model keeps its own copies


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
