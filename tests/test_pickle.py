"""Pickling and copying, as multiprocessing and Dask need them: models, every result class and
the streaming filters round-trip through pickle (every protocol), copy.copy and copy.deepcopy;
a restored stream continues bit for bit like the uninterrupted one; a pickled model gives the
same results in a spawned process."""

from __future__ import annotations

import copy
import dataclasses
import multiprocessing
import pickle

import numpy as np
import pytest

import kfast
from modelgen import random_case


def _pickled(protocol):
    def round_trip(obj):
        return pickle.loads(pickle.dumps(obj, protocol=protocol))

    return round_trip


COPIES = [pytest.param(_pickled(p), id=f"pickle{p}") for p in range(pickle.HIGHEST_PROTOCOL + 1)] + [
    pytest.param(copy.deepcopy, id="deepcopy"),
    pytest.param(copy.copy, id="copy"),
]

CASES = {
    "plain": dict(seed=1, n=3, m=2),
    "inputs-correlated-partly-missing": dict(seed=2, n=3, m=2, inputs=True, correlated=True, missing="partial"),
    "per-step-missing-rows": dict(seed=3, n=2, m=1, time_varying=True, missing="rows"),
    "scalar": dict(seed=4, n=1, m=1),
}


def case_and_model(name):
    case = random_case(T=24, **CASES[name])
    return case, kfast.LinearGaussian(**case.model)


def assert_same(a, b, where="obj"):
    """Equal bit for bit (NaN equal to NaN), recursively through results and models."""
    assert type(a) is type(b), where
    if isinstance(a, np.ndarray):
        assert a.shape == b.shape and a.dtype == b.dtype, where
        assert np.array_equal(a, b, equal_nan=True), where
    elif isinstance(a, kfast.LinearGaussian):
        for k in ("F", "H", "Q", "R", "B", "D", "N"):
            assert_same(getattr(a, k), getattr(b, k), f"{where}.{k}")
        assert (a.n_states, a.n_obs, a.n_inputs, a.steps) == (b.n_states, b.n_obs, b.n_inputs, b.steps)
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, tuple):
        assert len(a) == len(b), where
        for i, (ai, bi) in enumerate(zip(a, b)):
            assert_same(ai, bi, f"{where}[{i}]")
    elif isinstance(a, float):
        assert a == b or (np.isnan(a) and np.isnan(b)), where
    elif a is None or isinstance(a, (bool, int, str)):
        assert a == b, where
    else:  # scipy's OptimizeResult in FitResult
        assert_same(np.asarray(a.x), np.asarray(b.x), f"{where}.x")
        assert a.fun == b.fun, where


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("clone", COPIES)
def test_model_round_trips_and_filters_identically(name, clone):
    case, model = case_and_model(name)
    restored = clone(model)
    assert restored is not model and restored._core is not model._core
    assert_same(model, restored)
    for k in ("F", "H", "Q", "R"):
        assert not getattr(restored, k).flags.writeable  # still read-only
    expected = model.filter(case.y, case.x0, case.P0, u=case.u)
    assert_same(expected, restored.filter(case.y, case.x0, case.P0, u=case.u))
    # the compiled core alone pickles too
    core = clone(model._core)
    got = core.filter(case.y, case.x0, case.P0, u=case.u)
    assert np.array_equal(got["x_filt"], expected.x_filt) and got["loglik"] == expected.loglik


def test_unpickling_validates_the_matrices_again():
    _, model = case_and_model("plain")
    state = model.__getstate__()
    state["Q"] = -np.eye(3)
    bad = kfast.LinearGaussian.__new__(kfast.LinearGaussian)
    with pytest.raises(kfast.KfastError, match="Q"):
        bad.__setstate__(state)


def test_subclass_attributes_survive():
    class Tagged(kfast.LinearGaussian):
        pass

    model = Tagged(0.9, 1.0, 0.1, 1.0)
    model.tag = "sensor-7"
    restored = copy.deepcopy(model)
    assert type(restored) is Tagged and restored.tag == "sensor-7"
    assert_same(model.filter([1.0, 2.0], 0.0, 1.0), restored.filter([1.0, 2.0], 0.0, 1.0))


def all_results():
    """One instance of every result class."""
    case, model = case_and_model("inputs-correlated-partly-missing")
    args = (case.y, case.x0, case.P0)
    plain_case, plain = case_and_model("plain")
    fit = kfast.fit(
        lambda th: (kfast.LinearGaussian(np.tanh(th[0]), 1.0, np.exp(th[1]), 1.0), 0.0, 1.0),
        [0.3, 0.0],
        plain_case.y[:, 0],
    )
    return {
        "FilterResult": model.filter(*args, u=case.u),
        "FilterResult-outputs": model.filter(*args, u=case.u, outputs=("x_filt",)),
        "SmootherResult": model.smooth(*args, u=case.u),
        "FixedLagResult": model.smooth_fixed_lag(*args, lag=3, u=case.u),
        "FixedPointResult": model.smooth_fixed_point(*args, t_point=5, u=case.u),
        "Forecast": plain.filter(plain_case.y, plain_case.x0, plain_case.P0).forecast(4),
        "Simulation": plain.simulate(10, plain_case.x0, plain_case.P0, seed=5),
        "BatchResult": kfast.filter_batch(plain, np.stack([plain_case.y] * 3), plain_case.x0, plain_case.P0),
        "FitResult": fit,
        "EMResult": plain.em(plain_case.y, plain_case.x0, plain_case.P0, n_iter=2),
        "SteadyState": plain.steady_state(),
        "InnovationsForm": plain.innovations_form(),
        "KalmanBucy": kfast.kalman_bucy([[0.0, 1.0], [0.0, -1.0]], np.diag([0.0, 1.0]), [[1.0, 0.0]], 0.5),
        "Discretized": kfast.discretize([[0.0, 1.0], [0.0, -1.0]], np.diag([0.0, 1.0]), 0.1, B=[[0.0], [1.0]]),
    }


RESULTS = all_results()


@pytest.mark.parametrize("name", RESULTS)
@pytest.mark.parametrize("clone", COPIES)
def test_results_round_trip(name, clone):
    result = RESULTS[name]
    restored = clone(result)
    assert_same(result, restored, name)
    assert repr(restored) == repr(result)


def test_filter_result_keeps_a_working_model():
    restored = pickle.loads(pickle.dumps(RESULTS["FilterResult"]))
    assert_same(RESULTS["FilterResult"].forecast(3, u=np.ones((3, 2))), restored.forecast(3, u=np.ones((3, 2))))


# --- streaming filters ---------------------------------------------------------------------


def stream(obj, case, start, stop, record):
    """Steps start..stop-1 as update then predict, recording what the object shows after each."""
    for t in range(start, stop):
        u = None if case.u is None else case.u[t]
        obj.update(case.y[t], u=u)
        record(obj)
        obj.predict(u=u)
        record(obj)


def kalman_view(kf):
    return (kf.t, kf.x, kf.P, kf.loglik)


def lag_view(fl):
    return (fl.t, fl.x_lagged, fl.P_lagged, fl.x_window, fl.P_window)


STREAMERS = {
    "KalmanFilter": (lambda m, c: kfast.KalmanFilter(m, c.x0, c.P0), kalman_view),
    "KalmanFilter-standard": (lambda m, c: kfast.KalmanFilter(m, c.x0, c.P0, form="standard"), kalman_view),
    "FixedLagSmoother": (lambda m, c: kfast.FixedLagSmoother(m, c.x0, c.P0, lag=3), lag_view),
    "FixedLagSmoother-lag0": (lambda m, c: kfast.FixedLagSmoother(m, c.x0, c.P0, lag=0), lag_view),
}


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("kind", STREAMERS)
@pytest.mark.parametrize("after_update", [False, True], ids=["after-predict", "after-update"])
@pytest.mark.parametrize("clone", COPIES)
def test_restored_stream_continues_bit_for_bit(name, kind, after_update, clone):
    case, model = case_and_model(name)
    make, view = STREAMERS[kind]
    T = len(case.y)
    uninterrupted = []
    stream(make(model, case), case, 0, T, lambda o: uninterrupted.append(view(o)))

    for split in (0, 1, 2, 7):  # before, inside and after the window fills up
        obj = make(model, case)
        stream(obj, case, 0, split, lambda o: None)
        u = None if case.u is None else case.u[split]
        if after_update:
            obj.update(case.y[split], u=u)
        restored = clone(obj)
        assert_same(view(obj), view(restored), "at the copy")
        # both continue identically: the copy, and the original (which copying left alone)
        for continuing in (restored, obj):
            got = []
            if after_update:
                got.append(view(continuing))
                continuing.predict(u=u)
                got.append(view(continuing))
                stream(continuing, case, split + 1, T, lambda o: got.append(view(o)))
            else:
                stream(continuing, case, split, T, lambda o: got.append(view(o)))
            expected = uninterrupted[2 * split :]  # from the update at `split` on
            assert len(got) == len(expected)
            for i, (g, e) in enumerate(zip(got, expected)):
                assert_same(e, g, f"split {split}, record {i}")


def test_restored_stream_keeps_its_model_and_checks_its_end():
    case, model = case_and_model("per-step-missing-rows")
    kf = kfast.KalmanFilter(model, case.x0, case.P0)
    for y in case.y:
        kf.step(y)
    restored = pickle.loads(pickle.dumps(kf))
    with pytest.raises(kfast.KfastError, match="past the end"):
        restored.update(case.y[0])


def test_filter_and_its_model_pickle_together_once():
    case, model = case_and_model("plain")
    kf = kfast.KalmanFilter(model, case.x0, case.P0)
    kf.step(case.y[0])
    model2, kf2 = pickle.loads(pickle.dumps((model, kf)))
    kf2.step(case.y[1])
    kf.step(case.y[1])
    assert_same(kalman_view(kf), kalman_view(kf2))
    assert isinstance(model2, kfast.LinearGaussian)
    # the compiled core given directly pickles as well
    kf3 = pickle.loads(pickle.dumps(kfast.KalmanFilter(model._core, case.x0, case.P0)))
    kf3.step(case.y[0])
    kf4 = kfast.KalmanFilter(model, case.x0, case.P0)
    kf4.step(case.y[0])
    assert_same(kalman_view(kf4), kalman_view(kf3))


def test_state_without_the_running_sum_continues_from_the_total():
    """A state pickled before the running log-likelihood sum was kept (only "loglik")."""
    case, model = case_and_model("plain")
    kf = kfast.KalmanFilter(model, case.x0, case.P0)
    for y in case.y[:5]:
        kf.step(y)
    state = kf.__reduce__()[2]
    assert state["loglik"] == kf.loglik
    del state["loglik_sum"]
    old = kfast.KalmanFilter(model, case.x0, case.P0)
    old.__setstate__(state)
    assert old.loglik == kf.loglik
    for y in case.y[5:]:
        kf.step(y)
        old.step(y)
    np.testing.assert_array_equal(old.x, kf.x)
    assert old.loglik == pytest.approx(kf.loglik, rel=1e-13)


def test_bad_state_is_refused():
    case, model = case_and_model("plain")
    kf = kfast.KalmanFilter(model, case.x0, case.P0)
    with pytest.raises(kfast.KfastError, match="state: has no"):
        kf.__setstate__({"t": 0})
    state = kf.__reduce__()[2]
    state["x_pred"] = np.array([1.0, np.nan, 0.0])
    with pytest.raises(kfast.KfastError, match="x_pred"):
        kf.__setstate__(state)
    for parts in ([1.0, 0.5, 0.0, 0.0, 0.0], [1.5, 1.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, np.inf, 0.0]):
        state = kf.__reduce__()[2]
        state["loglik_sum"] = parts
        with pytest.raises(kfast.KfastError, match="loglik_sum"):
            kf.__setstate__(state)
    fl = kfast.FixedLagSmoother(model, case.x0, case.P0, lag=1)
    state = fl.__reduce__()[2]
    state["window"] = [(np.zeros(3), np.eye(3), np.eye(3))] * 3
    with pytest.raises(kfast.KfastError, match="window"):
        fl.__setstate__(state)


# --- multiprocessing -----------------------------------------------------------------------


def _filter_in_child(model, y, x0, P0, u):
    return model.filter(y, x0, P0, u=u)


def _continue_in_child(kf, ys):
    for y in ys:
        kf.step(y)
    return kf


def test_spawned_processes_give_the_same_results():
    case, model = case_and_model("per-step-missing-rows")
    expected = model.filter(case.y, case.x0, case.P0)
    kf = kfast.KalmanFilter(model, case.x0, case.P0)
    for y in case.y[:10]:
        kf.step(y)
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(2) as pool:
        results = pool.starmap(_filter_in_child, [(model, case.y, case.x0, case.P0, None)] * 2)
        continued = pool.starmap(_continue_in_child, [(kf, case.y[10:])])[0]
    for got in results:
        assert_same(expected, got)
    local = _continue_in_child(kf, case.y[10:])
    assert_same(kalman_view(local), kalman_view(continued))
    np.testing.assert_allclose(local.x, expected.x_next, rtol=1e-12)
