"""kfast.dask on a real distributed.LocalCluster with 2 worker processes: filter_batch, loglik,
smooth and fit over series chunked across the workers equal the in-process calls bit for bit."""

import sys

import cloudpickle
import numpy as np
import pytest

import kfast

distributed = pytest.importorskip("distributed")  # in the test extras: never skipped in CI
da = pytest.importorskip("dask.array")
db = pytest.importorskip("dask.bag")

# The workers unpickle this module's functions (fit's build) by value, not by import.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                       silence_logs=40)
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


def data(B=24, T=60, seed=5, missing=True):
    model = kfast.models.constant_velocity(2, 0.1, q=1.0, r=0.5)
    x0, P0 = np.array([0.0, 0.0, 1.0, -0.5]), np.diag([4.0, 4.0, 1.0, 1.0])
    rng = np.random.default_rng(seed)
    Y = np.stack([model.simulate(T, x0, P0, seed=int(s))[1] for s in rng.integers(0, 2**31, B)])
    if missing:
        Y[3, 10, 0] = np.nan
        Y[B - 2, 20:25] = np.nan
    return model, x0, P0, Y


def test_filter_batch_and_loglik_equal_the_in_process_call(client):
    model, x0, P0, Y = data()
    assert {w["type"] for w in client.scheduler_info()["workers"].values()} == {"Worker"}
    assert len(client.scheduler_info()["workers"]) == 2
    lazy = kfast.dask.filter_batch(model, da.from_array(Y, chunks=(5, 30, 2)), x0, P0)
    got = lazy.compute()
    want = kfast.filter_batch(model, Y, x0, P0)
    np.testing.assert_array_equal(got.x_filt, want.x_filt)
    np.testing.assert_array_equal(got.P_filt, want.P_filt)
    np.testing.assert_array_equal(got.loglik, want.loglik)
    # Both workers took chunks.
    assert len(client.run(lambda: 1)) == 2
    ll = kfast.dask.loglik(model, da.from_array(Y, chunks=7), x0, P0).compute()
    np.testing.assert_array_equal(ll, want.loglik)


def test_per_series_priors_and_inputs(client):
    model, x0, P0, Y = data(B=10, missing=False)
    rng = np.random.default_rng(1)
    X0 = x0 + rng.normal(size=(10, 4))
    lazy = kfast.dask.filter_batch(model, da.from_array(Y, chunks=3), X0, P0, return_covs=False)
    assert lazy.P_filt is None
    got = lazy.compute()
    want = kfast.filter_batch(model, Y, X0, P0, return_covs=False)
    np.testing.assert_array_equal(got.x_filt, want.x_filt)
    np.testing.assert_array_equal(got.loglik, want.loglik)


def test_smooth_equals_the_in_process_smoother(client):
    model, x0, P0, Y = data(B=9)
    x, P = kfast.dask.smooth(model, da.from_array(Y, chunks=4), x0, P0).compute()
    for b in range(len(Y)):
        res = model.smooth(Y[b], x0, P0)
        np.testing.assert_array_equal(x[b], res.x_smooth)
        np.testing.assert_array_equal(P[b], res.P_smooth)


def local_level(theta):
    q, r = np.exp(theta)
    return kfast.LinearGaussian([[1.0]], [[1.0]], [[q]], [[r]]), np.zeros(1), 10.0 * np.eye(1)


def test_fit_of_many_models_from_a_bag_and_an_array(client):
    rng = np.random.default_rng(3)
    series = [np.cumsum(rng.normal(scale=s, size=80)) + rng.normal(size=80) for s in (0.3, 0.6, 1.0, 1.5)]
    theta0 = np.zeros(2)
    want = [kfast.fit(local_level, theta0, y) for y in series]
    from_bag = kfast.dask.fit(local_level, theta0, db.from_sequence(series, npartitions=2)).compute()
    from_array = kfast.dask.fit(local_level, theta0, da.from_array(np.stack(series), chunks=(2, 80))).compute()
    for got in (from_bag, from_array):
        assert len(got) == 4
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g.theta, w.theta)
            assert g.loglik == w.loglik


def test_bad_input():
    model, x0, P0, Y = data(B=4)
    with pytest.raises(ValueError, match="Y: expected a Dask array"):
        kfast.dask.filter_batch(model, Y, x0, P0)
    with pytest.raises(ValueError, match=r"Y: expected shape \(B, T, 2\)"):
        kfast.dask.filter_batch(model, da.zeros((4, 10, 3)), x0, P0)
    with pytest.raises(ValueError, match="x0: one per series expected 4 rows"):
        kfast.dask.filter_batch(model, da.from_array(Y), np.zeros((3, 4)), P0)
    with pytest.raises(ValueError, match="series: expected a Dask bag"):
        kfast.dask.fit(local_level, np.zeros(2), [np.zeros(5)])
    # Errors inside a task carry kfast's message.
    bad = kfast.dask.filter_batch(model, da.from_array(Y, chunks=2), x0, -P0)
    with pytest.raises(ValueError, match="P0"):
        bad.compute(scheduler="synchronous")
