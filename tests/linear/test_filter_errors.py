"""Bad input to ``LinearGaussian.filter`` / ``loglik``: shapes of y, x0, P0, u and their step
counts, priors that are not covariances, NaN (missing data) and inf, a singular innovation
covariance, complex data, u and the model's B/D, the update form. Tests parametrized over
``"stream"`` too check ``KalmanFilter`` the same way. Conventions of the checks: badinput.py."""

from __future__ import annotations

import re

import numpy as np
import pytest

import kfast
from badinput import (
    ASYM,
    BATCH,
    NOT_PSD,
    T,
    batch,
    data,
    fails,
    full_model,
    later_singular_model,
    model_mats,
    msg,
    per_step_model,
    plain_model,
    singular_model,
)


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
# the prior: a covariance, finite


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


# --------------------------------------------------------------------------------------------
# NaN and inf in the data


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("bad", [np.inf, -np.inf], ids=["inf", "-inf"])
def test_y_inf_names_the_step(how, bad):
    y = data()["y"].copy()
    y[4, 1] = bad
    with fails(msg("y", r"component 1 is -?inf", r"missing values are NaN", step=4)):
        batch(how, full_model(), **data(y=y))


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
def test_u_non_finite_names_the_step(how, bad):
    u = data()["u"].copy()
    u[2, 0] = bad
    with fails(msg("u", r"non-finite", r"(NaN|inf)", step=2)):
        batch(how, full_model(), **data(u=u))


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


def test_singular_innovation_covariance_where_y_is_missing_is_not_an_error():
    res = singular_model().filter(np.full((T, 2), np.nan), [0.0, 0.0], np.zeros((2, 2)))
    assert res.loglik == 0.0


# --------------------------------------------------------------------------------------------
# complex input


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("arg", ["y", "x0", "P0", "u"])
def test_data_complex(how, arg):
    d = data()
    d[arg] = d[arg].astype(complex)
    with fails(msg(arg, r"complex")):
        batch(how, full_model(), **d)


# --------------------------------------------------------------------------------------------
# u and the model's B/D; form


@pytest.mark.parametrize("how", BATCH)
def test_u_given_to_model_without_inputs(how):
    with fails(msg("u", r"given, but the model has neither B nor D")):
        batch(how, plain_model(), **data())


@pytest.mark.parametrize("how", BATCH)
@pytest.mark.parametrize("which", ["B", "D", "BD"])
def test_u_missing_for_model_with_inputs(how, which):
    mats = model_mats(**{k: None for k in "BD" if k not in which})
    d = data(u=None)
    with fails(msg("u", r"model has B or D", r"k = 1", r"required")):
        batch(how, kfast.LinearGaussian(**mats), **d)


@pytest.mark.parametrize("form", ["bad", "Joseph", "", "standard "])
@pytest.mark.parametrize("how", BATCH + ["stream"])
def test_bad_form(how, form):
    with fails(r"^form: expected .*joseph.*standard.*got .*" + re.escape(form)):
        if how == "stream":
            kfast.KalmanFilter(full_model(), [0.0, 0.0], np.eye(2), form=form)
        else:
            batch(how, full_model(), **data(), form=form)
