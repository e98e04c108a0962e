"""Hardening of the model catalogue (issue #10): every argument of every catalogue function
either gives a model / value or a ``KfastError`` whose head (before the first ": ") names the
argument: sizes that would not fit in memory, and parameters whose model overflows double
precision, are refused by name (not as "F: non-finite", OverflowError, ZeroDivisionError,
MemoryError or a hang). Extreme but meaningful parameters (omega -> 0, tau -> inf of the damped
resonator, huge AR lags) give the exact values."""

import math
import re

import numpy as np
import pytest

import kfast
import kfast.models as km


def assert_names(exc_info, name):
    """The message's head (before the first ": ") names ``name`` as a word."""
    head = str(exc_info.value).split(": ", 1)[0]
    assert re.search(rf"(?<!\w){re.escape(name)}(?!\w)", head), str(exc_info.value)


HUGE_DIMS = [10**10, 2**62, 2**63, 10**100]

REFUSED = [
    # sizes: refused before anything is allocated
    *[(km.constant_velocity, dict(dim=d, dt=0.1), "dim") for d in HUGE_DIMS],
    *[(km.constant_acceleration, dict(dim=d, dt=0.1), "dim") for d in HUGE_DIMS],
    *[(km.singer, dict(dt=0.1, alpha=0.5, sigma_m2=1.0, dim=d), "dim") for d in HUGE_DIMS],
    *[(km.continuous, dict(kind="singer", alpha=0.5, sigma_m2=1.0, dim=d), "dim") for d in HUGE_DIMS],
    (km.constant_velocity, dict(dim=True, dt=0.1), "dim"),
    (km.constant_velocity, dict(dim=-2**63, dt=0.1), "dim"),
    (km.constant_velocity, dict(dim="3", dt=0.1), "dim"),
    # overflow of the discrete model: named by the parameters, not "F" or "Q"
    (km.constant_velocity, dict(dim=2, dt=1e300), "dt"),
    (km.constant_velocity, dict(dim=2, dt=1e155), "dt"),
    (km.constant_velocity, dict(dim=2, dt=1e100, q=1e300), "q"),
    (km.constant_acceleration, dict(dim=1, dt=1e300), "dt"),
    (km.constant_acceleration, dict(dim=1, dt=1e60, q=1e300), "q"),
    (km.random_walk, dict(dt=1e300, q=1e300), "q"),
    (km.singer, dict(dt=1e300, alpha=0.5, sigma_m2=1.0), "dt"),
    (km.singer, dict(dt=0.1, alpha=1e300, sigma_m2=1.0), "alpha"),
    (km.singer, dict(dt=0.1, alpha=10.0, sigma_m2=1e308), "sigma_m2"),
    (km.gauss_markov_2, dict(omega_n=1e300, zeta=0.5, q=1.0, dt=0.1), "omega_n"),
    (km.gauss_markov_2, dict(omega_n=2.0, zeta=1e300, q=1.0, dt=0.1), "zeta"),
    (km.damped_resonator, dict(omega=1e300, tau=3.0, q=1.0, dt=0.1), "omega"),
    (km.damped_resonator, dict(omega=1e155, tau=3.0, q=1.0, dt=0.1), "omega"),
    (km.damped_resonator, dict(omega=2.0, tau=1e-300, q=1.0, dt=0.1), "tau"),
    (km.continuous, dict(kind="gauss_markov_1", sigma2=1e300, beta=1e300), "sigma2"),
    (km.continuous, dict(kind="damped_resonator", omega=2.0, tau=1e-300, q=1.0), "tau"),
    (km.random_walk, dict(dt=0.1, r=[[np.nan]]), "r"),
    (km.constant_velocity, dict(dim=2, dt=0.1, r=np.full((2, 2), np.inf)), "r"),
    # stationary autocovariances whose variance or rates overflow
    (km.gauss_markov_2_autocovariance, dict(lag=1.0, omega_n=1e-300, zeta=0.5, q=1.0), "omega_n"),
    (km.gauss_markov_2_autocovariance, dict(lag=1.0, omega_n=1e300, zeta=0.5, q=1.0), "omega_n"),
    (km.gauss_markov_2_autocovariance, dict(lag=1.0, omega_n=2.0, zeta=1e300, q=1.0), "zeta"),
    (km.damped_resonator_autocovariance, dict(lag=1.0, omega=2.0, tau=1e-300, q=1.0), "tau"),
    (km.damped_resonator_autocovariance, dict(lag=1.0, omega=1e300, tau=3.0, q=1.0), "omega"),
    # AR lags: integers with |lag| < 2**63
    *[(km.ar_autocovariance, dict(lags=v, coeffs=[0.5], noise_var=1.0), "lags")
      for v in (np.nan, np.inf, -np.inf, 1e155, 1e300, -1e300, 2**63, -2**63, 1.5, [0, 10**400], [True])],
]


@pytest.mark.parametrize("fn,kwargs,name", REFUSED, ids=[f"{f.__name__}-{n}-{i}" for i, (f, _, n) in enumerate(REFUSED)])
def test_refused_by_name(fn, kwargs, name):
    with pytest.raises(kfast.KfastError) as exc_info:
        fn(**kwargs)
    assert_names(exc_info, name)


def test_a_stable_model_over_a_huge_interval_is_its_stationary_limit():
    # F = e^{A dt} -> 0 and Qd -> the stationary covariance q diag(1 / (4 zeta w^3), 1 / (4 zeta w)).
    model = km.gauss_markov_2(omega_n=2.0, zeta=0.5, q=1.0, dt=1e300)
    np.testing.assert_array_equal(model.F, 0.0)
    np.testing.assert_allclose(model.Q, np.diag([1 / 16, 1 / 4]), rtol=1e-13, atol=1e-16)


def test_continuous_discretize_names_dt_when_it_overflows():
    with pytest.raises(kfast.KfastError) as exc_info:
        km.continuous("singer", alpha=0.5, sigma_m2=1.0).discretize(1e300)
    assert_names(exc_info, "dt")


def test_dim_that_fits_still_works():
    model = km.singer(0.1, 0.5, 1.0, dim=np.int64(3))
    assert model.F.shape == (9, 9)
    np.testing.assert_array_equal(model.F, np.kron(km.singer(0.1, 0.5, 1.0).F, np.eye(3)))


def undamped_oscillator(omega, q, h):
    """F = e^{Ah} and Qd = int_0^h e^{As} diag(0, q) e^{A's} ds of x'' = -omega^2 x + w."""
    S, C = math.sin(omega * h), math.cos(omega * h)
    F = np.array([[C, S / omega], [-omega * S, C]])
    Q = q * np.array(
        [
            [(h / 2 - math.sin(2 * omega * h) / (4 * omega)) / omega**2, S * S / (2 * omega**2)],
            [S * S / (2 * omega**2), h / 2 + math.sin(2 * omega * h) / (4 * omega)],
        ]
    )
    return F, Q


@pytest.mark.parametrize("tau", [1e155, 1e300])
def test_damped_resonator_without_damping_is_the_undamped_oscillator(tau):
    # tau -> inf: the closed form overflows (omega^2 tau^2), Van Loan gives the limit
    model = km.damped_resonator(omega=2.0, tau=tau, q=1.5, dt=0.1)
    F, Q = undamped_oscillator(2.0, 1.5, 0.1)
    np.testing.assert_allclose(model.F, F, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(model.Q, Q, rtol=1e-10, atol=1e-16)


@pytest.mark.parametrize("omega", [1e-300, 1e-170])
def test_damped_resonator_at_zero_frequency_is_critically_damped(omega):
    # omega -> 0: omega_n^2 = 1/tau^2, zeta omega_n = 1/tau, i.e. gauss_markov_2 with zeta = 1
    model = km.damped_resonator(omega=omega, tau=3.0, q=1.5, dt=0.1)
    ref = km.gauss_markov_2(omega_n=1 / 3, zeta=1.0, q=1.5, dt=0.1)
    np.testing.assert_allclose(model.F, ref.F, rtol=1e-12)
    np.testing.assert_allclose(model.Q, ref.Q, rtol=1e-9)


def ar_recursion(coeffs, noise_var, kmax):
    """r(0..kmax) by the Yule-Walker recursion (Söderström (4.29)-(4.35)) from r(0..p)."""
    p = len(coeffs)
    r = list(km.ar_autocovariance(np.arange(p + 1), coeffs, noise_var))
    for k in range(p + 1, kmax + 1):
        r.append(-sum(a * r[k - 1 - i] for i, a in enumerate(coeffs)))
    return np.array(r)


def test_ar_autocovariance_at_far_lags():
    coeffs = [-1.2, 0.36 + 1e-5]  # zeros close to the unit circle: slow decay
    kmax = 150_000
    ref = ar_recursion(coeffs, 2.0, kmax)
    lags = [0, 3, 100_000, 100_001, 120_000, kmax]
    np.testing.assert_allclose(km.ar_autocovariance(lags, coeffs, 2.0), ref[lags], rtol=1e-8, atol=1e-12 * abs(ref[0]))
    # AR(1): r(k) = lambda^2 a^k / (1 - a^2), any lag < 2**63 at once
    a = 0.99999
    for k in (200_000, 10**7):
        assert km.ar_autocovariance(k, [-a], 1.0) == pytest.approx(a**k / (1 - a * a), rel=1e-8)
    assert km.ar_autocovariance([2**63 - 1, -(2**63 - 1)], [-0.5], 1.0).tolist() == [0.0, 0.0]
