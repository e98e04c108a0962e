"""Bad input to the streaming ``kfast.KalmanFilter``: shapes of x0, P0, y, u, NaN and inf,
complex values, a singular innovation covariance, u and the model's B/D, and the protocol
(update twice, past the end of a per-step model). Conventions of the checks: badinput.py."""

from __future__ import annotations

import numpy as np
import pytest

import kfast
from badinput import (
    T,
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


def test_scalar_prior_shapes_for_n_1_stream():
    model = kfast.LinearGaussian(0.8, 1.0, 0.68, 1.0)
    for x0, P0 in [(0.0, 1.0), ([0.0], [[1.0]]), (np.zeros(1), np.ones(1)), (np.zeros((1, 1)), np.ones((1, 1)))]:
        kf = kfast.KalmanFilter(model, x0, P0)
        kf.step(0.3)
        kf.step([0.3])
        kf.step(np.array([[0.3]])[0])


# --------------------------------------------------------------------------------------------
# NaN and inf


@pytest.mark.parametrize("method", ["update", "step"])
@pytest.mark.parametrize("bad", [np.inf, -np.inf], ids=["inf", "-inf"])
def test_stream_y_inf_names_the_step(method, bad):
    kf = _stream(steps=3)
    with fails(msg("y", r"component 0 is -?inf", step=3)):
        getattr(kf, method)([bad, 0.0], [0.0])


@pytest.mark.parametrize("method", ["update", "predict", "step"])
@pytest.mark.parametrize("bad", [np.nan, np.inf], ids=["nan", "inf"])
def test_stream_u_non_finite_names_the_step(method, bad):
    kf = _stream(steps=2)
    with fails(msg("u", r"non-finite", r"(NaN|inf)", step=2)):
        if method == "predict":
            kf.predict([bad])
        else:
            getattr(kf, method)([0.1, 0.2], [bad])


# --------------------------------------------------------------------------------------------
# the innovation covariance S = H P H' + R cannot be factorized


@pytest.mark.parametrize("method", ["update", "step"])
def test_stream_innovation_covariance_singular_at_step_0(method):
    kf = kfast.KalmanFilter(singular_model(), [0.0, 0.0], np.zeros((2, 2)))
    with fails(r"^innovation covariance .* at step 0 cannot be factorized", kfast.InnovationCovarianceError):
        getattr(kf, method)([1.0, 1.0])


def test_stream_innovation_covariance_singular_at_later_step():
    kf = kfast.KalmanFilter(later_singular_model(), 0.0, 1.0)
    kf.step(1.0)
    with fails(r"^innovation covariance .* at step 1 cannot be factorized", kfast.InnovationCovarianceError):
        kf.update(2.0)
    # the failed update left the filter usable: predict treats the step as missing
    kf.predict()
    assert kf.t == 2


# --------------------------------------------------------------------------------------------
# complex input


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


# --------------------------------------------------------------------------------------------
# u and the model's B/D


@pytest.mark.parametrize("method", ["update", "predict", "step"])
def test_stream_u_given_to_model_without_inputs(method):
    kf = kfast.KalmanFilter(plain_model(), [0.0, 0.0], np.eye(2))
    with fails(msg("u", r"neither B nor D")):
        if method == "predict":
            kf.predict([1.0])
        else:
            getattr(kf, method)([0.0, 0.0], [1.0])


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
