"""Hardening of the stationary analysis (issue #10): ``autocovariance`` takes integer lags
with |lag| < 2**63 and reaches any of them in O(log lag) products; ``spectral_density`` refuses
non-finite frequencies and anything but a positive real ``h``, naming the argument."""

import re
import time

import numpy as np
import pytest

import kfast


def io_model():
    return kfast.LinearGaussian(
        F=0.8 * np.eye(3) + 0.01 * np.arange(9.0).reshape(3, 3), H=np.eye(2, 3) + 0.5, Q=np.eye(3), R=np.eye(2),
        N=0.1 * np.eye(3, 2),
    )


def assert_names(exc_info, name):
    head = str(exc_info.value).split(": ", 1)[0]
    assert re.search(rf"(?<!\w){re.escape(name)}(?!\w)", head), str(exc_info.value)


@pytest.mark.parametrize("lags", [np.nan, np.inf, -np.inf, 1e155, -1e155, 1e300, [0, 1e300], 2**63, -2**63,
                                  np.uint64(2**64 - 1), 1.5, [0, 10**400], "1", [[0, 1]]])
def test_autocovariance_refuses_lags_that_are_not_int64_integers(lags):
    with pytest.raises(kfast.KfastError) as exc_info:
        io_model().autocovariance(lags)
    assert_names(exc_info, "lags")


def test_autocovariance_at_huge_lags_is_fast_and_exact():
    model = io_model()
    sequential = model.autocovariance(np.arange(-1500, 1501))
    # gaps above the stepping limit use repeated squaring: equal up to rounding
    far = model.autocovariance([0, 1500, -1500, 7])
    np.testing.assert_allclose(far, sequential[[1500, 3000, 0, 1507]], rtol=1e-10, atol=1e-12 * np.abs(sequential).max())
    start = time.perf_counter()
    huge = model.autocovariance([2**63 - 1, -(2**63 - 1), 10**18, np.int64(2**62)])
    assert time.perf_counter() - start < 1.0
    np.testing.assert_array_equal(huge, 0.0)  # rho(F) < 1: F^k underflows to 0
    np.testing.assert_array_equal(model.autocovariance(np.array([3.0, -2.0])), model.autocovariance([3, -2]))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_spectral_density_refuses_non_finite_omega(bad):
    with pytest.raises(kfast.KfastError) as exc_info:
        io_model().spectral_density([0.0, bad, 1.0])
    assert_names(exc_info, "omega")


@pytest.mark.parametrize("h", ["1", None, [], 1 + 1j, [1.0, 1.0], [1.0], True, 0.0, -1.0, np.inf, np.nan, 10**400])
def test_spectral_density_refuses_h_that_is_not_a_positive_real(h):
    with pytest.raises(kfast.KfastError) as exc_info:
        io_model().spectral_density([0.0, 1.0], h=h)
    assert_names(exc_info, "h")


def test_spectral_density_accepts_numpy_scalars_for_h():
    model = io_model()
    want = model.spectral_density([0.0, 1.0], h=0.5)
    for h in (np.float64(0.5), np.float32(0.5), np.array(0.5)):
        np.testing.assert_array_equal(model.spectral_density([0.0, 1.0], h=h), want)
    assert np.all(np.isfinite(model.spectral_density([1e300], h=1.0)))
    with pytest.raises(kfast.KfastError) as exc_info:
        model.spectral_density([1e300], h=1e10)  # omega h overflows
    assert_names(exc_info, "omega")
