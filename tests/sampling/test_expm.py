"""kfast.expm at every scale (issue #10): the reproducers (a nilpotent of norm 1e20 came out as
zeros, 3e-5 relative error at 1e12, all-NaN for diag(1e5, -1e5)), exact cases (nilpotent,
diagonal, rotation generators, 2 x 2 triangular closed form), and seeded random matrices of
norm 1e-8 to 1e15 against a 60-digit reference (mpmath) and scipy.linalg.expm.

Accuracy bounds: e^A is (relatively) as sensitive to A as ||A|| (Higham, *Functions of
Matrices*, Thm 10.12, for normal A), so no algorithm does better than about u ||A|| for dense
input; triangular input is exact to rounding at any norm (docs/algorithms.md, "Matrix
exponential").
"""

import math

import mpmath
import numpy as np
import pytest
import scipy.linalg as sl

import kfast

U = 2.0**-53  # unit roundoff


def mp_expm(a):
    """e^a to 60 digits (the reference), rounded to float64."""
    with mpmath.workdps(60):
        return np.array(mpmath.expm(mpmath.matrix(a.tolist())).tolist(), dtype=float)


def rel_err(got, want):
    return np.linalg.norm(got - want, 1) / np.linalg.norm(want, 1)


# --- the reproducers of issue #10 -------------------------------------------------------------


@pytest.mark.parametrize("x", [1e8, 1e12, 1e15, 1e20, 1e100, 1e300])
def test_nilpotent_2x2_is_exact_at_any_norm(x):
    """Was: zeros at 1e20, relative error 3e-5 at 1e12 and 3% at 1e15 (s = 64 squarings from
    ||A||_1 amplified the rounding of the diagonal, (1 + d)^(2^s))."""
    np.testing.assert_array_equal(kfast.expm([[0.0, x], [0.0, 0.0]]), [[1.0, x], [0.0, 1.0]])
    np.testing.assert_array_equal(kfast.expm([[0.0, 0.0], [-x, 0.0]]), [[1.0, 0.0], [-x, 1.0]])


def test_overflow_is_an_error_naming_a():
    """Was all NaN (inf * 0 in the squarings). scipy returns [[inf, 0], [0, 0]]; kfast raises
    rather than hand a Kalman filter an infinite transition matrix."""
    with np.errstate(over="ignore"):
        assert sl.expm(np.diag([1e5, -1e5]))[0, 0] == np.inf
    with pytest.raises(kfast.KfastError, match=r"^a: e\^a overflows double precision"):
        kfast.expm(np.diag([1e5, -1e5]))
    for a in ([[710.0]], [[1.0, 2.0], [3.0, 800.0]], np.full((3, 3), 1e300), np.full((2, 2), 1.7e308)):
        with pytest.raises(kfast.KfastError, match=r"^a: e\^a overflows"):
            kfast.expm(a)
    # Just below the overflow threshold, and underflow, are fine.
    assert kfast.expm([[709.0]])[0, 0] == pytest.approx(math.exp(709.0), rel=1e-13)
    np.testing.assert_array_equal(kfast.expm(np.diag([-1e5, -1e300])), np.zeros((2, 2)))
    np.testing.assert_allclose(kfast.expm(np.diag([-1e5, -2.0])), np.diag([0.0, math.exp(-2.0)]), rtol=1e-15)


# --- exact cases --------------------------------------------------------------------------------


@pytest.mark.parametrize("size", [1e-8, 1.0, 1e5, 1e15, 1e60])
@pytest.mark.parametrize("permuted", [False, True])
def test_nilpotent_5x5_is_its_finite_series(size, permuted):
    """N strictly upper triangular: e^N = I + N + ... + N^4/24. Permuted (P N P', not
    triangular) it goes through the general path, where ||N^k||^(1/k) = 0 for k >= 5 gives
    no squaring at all."""
    rng = np.random.default_rng(11)
    n = 5
    N = np.triu(rng.standard_normal((n, n)), 1) * size
    want, term = np.eye(n), np.eye(n)
    for k in range(1, n):
        term = term @ N / k
        want = want + term
    if permuted:
        p = np.array([2, 0, 4, 1, 3])
        N, want = N[np.ix_(p, p)], want[np.ix_(p, p)]
        assert np.tril(N, -1).any() and np.triu(N, 1).any()
    got = kfast.expm(N)
    # (the reference sums terms of mixed sign: it is itself only accurate to a few u)
    assert np.abs(got - want).max() <= 32 * U * np.abs(want).max()


def test_diagonal_entries_are_exp_and_zeros_stay_zero():
    d = np.array([-700.0, -30.0, -1e-9, 0.0, 0.5, 40.0, 700.0])
    got = kfast.expm(np.diag(d))
    np.testing.assert_array_equal(got - np.diag(np.diag(got)), 0.0)
    np.testing.assert_allclose(np.diag(got), np.exp(d), rtol=2 * U)


@pytest.mark.parametrize("theta", [1e-8, 0.1, 1.0, np.pi, 50.0, 1e4, 1e8, 1e12, 1e15])
def test_rotation_generator(theta):
    """exp([[0, -t], [t, 0]]) is the rotation by t. cos and sin of a large double are exact to
    rounding (libm reduces the argument exactly), but the rotation is as sensitive to t as t
    itself, so the error may reach about u t."""
    got = kfast.expm([[0.0, -theta], [theta, 0.0]])
    c, s = math.cos(theta), math.sin(theta)
    assert np.abs(got - [[c, -s], [s, c]]).max() <= 4 * U * max(1.0, theta)
    # Block-diagonal rotations, permuted so that the matrix is not block diagonal.
    thetas = np.array([0.3, theta, 2.0])
    a = np.zeros((6, 6))
    want = np.zeros((6, 6))
    for k, t in enumerate(thetas):
        a[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[0.0, -t], [t, 0.0]]
        want[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]]
    p = np.array([3, 0, 5, 1, 4, 2])
    got = kfast.expm(a[np.ix_(p, p)])
    assert np.abs(got - want[np.ix_(p, p)]).max() <= 16 * U * max(1.0, theta)


@pytest.mark.parametrize(
    "a, b, c",
    [
        (-1.0, 1e15, -2.0),
        (0.0, 1.0, 0.0),
        (-0.5, 1e20, -0.5),
        (3.0, -7.0, 3.0 + 1e-10),
        (-2000.0, 1e6, 0.0),
        (1.0, 1e300, 1.0),
        (-1e5, 1.0, -1e5 + 1.0),
        (5.0, 1e12, -40.0),
    ],
)
def test_triangular_2x2_closed_form(a, b, c):
    """exp([[a, b], [0, c]]) = [[e^a, b (e^c - e^a)/(c - a)], [0, e^c]] (b e^a for c = a),
    the divided difference taken to 60 digits."""
    with mpmath.workdps(60):
        ma, mc = mpmath.mpf(a), mpmath.mpf(c)
        dd = float(mpmath.exp(ma) if a == c else (mpmath.exp(mc) - mpmath.exp(ma)) / (mc - ma))
    want = np.array([[math.exp(a), b * dd], [0.0, math.exp(c)]])
    got = kfast.expm([[a, b], [0.0, c]])
    # exp of an argument x is sensitive to its rounding by |x|.
    tol = 8 * U * (1 + max(abs(a), abs(c)))
    np.testing.assert_allclose(got, want, rtol=tol, atol=0)
    np.testing.assert_allclose(kfast.expm([[a, 0.0], [b, c]]), want.T, rtol=tol, atol=0)


def test_integer_and_float32_input_equal_float64():
    a = np.array([[0, 2], [-3, -1]])
    np.testing.assert_array_equal(kfast.expm(a), kfast.expm(a.astype(float)))
    np.testing.assert_array_equal(kfast.expm(a.astype(np.float32)), kfast.expm(a.astype(float)))


def test_empty_matrix():
    assert kfast.expm(np.zeros((0, 0))).shape == (0, 0)


# --- seeded random matrices, norms 1e-8 ... 1e15 -------------------------------------------


def random_matrix(kind, rng, norm):
    n = int(rng.integers(2, 6))
    if kind == "skew":  # normal, e^A orthogonal: finite at any norm
        m = rng.standard_normal((n, n))
        a = m - m.T
    elif kind == "triangular":  # strongly non-normal at large norm, eigenvalues in [-3, 1]
        a = np.triu(rng.standard_normal((n, n)), 1)
    else:  # "stable": dense, shifted to spectral abscissa -1
        a = rng.standard_normal((n, n))
    a *= norm / np.linalg.norm(a, 1)
    if kind == "triangular":
        a += np.diag(rng.uniform(-3.0, 1.0, n))
    if kind == "stable":
        a -= (np.linalg.eigvals(a).real.max() + 1.0) * np.eye(n)
    return a


NORMS = [10.0**e for e in range(-8, 16)]


@pytest.mark.parametrize("kind", ["skew", "stable"])
def test_random_dense_against_60_digits(kind):
    """Relative error <= 20 n u max(1, ||A||_1): the conditioning of e^A (old code and new
    agree here; measured worst ratio to u ||A|| about 3)."""
    rng = np.random.default_rng(2024)
    for norm in NORMS:
        for _ in range(3):
            a = random_matrix(kind, rng, norm)
            n, anorm = len(a), np.linalg.norm(a, 1)
            err = rel_err(kfast.expm(a), mp_expm(a))
            assert err <= 20 * n * U * max(1.0, anorm), f"{kind}, ||A||_1 = {anorm:.3g}: relative error {err:.3g}"


def test_random_triangular_against_60_digits():
    """Triangular (the diagonals recomputed exactly after each squaring): relative error
    <= 20 n u at every norm, where scipy.linalg.expm loses everything (measured: 2e-4 at 1e8,
    inf at 1e14) and the old kfast lost about u ||A|| (2e-5 at 1e12)."""
    rng = np.random.default_rng(7)
    for norm in NORMS:
        for _ in range(3):
            a = random_matrix("triangular", rng, norm)
            err = rel_err(kfast.expm(a), mp_expm(a))
            assert err <= 20 * len(a) * U, f"||A||_1 = {norm:.3g}: relative error {err:.3g}"


def test_random_general_against_scipy():
    """Gaussian matrices of norm 1e-8 ... 100 (beyond, e^A overflows for most), where
    scipy.linalg.expm is accurate: the two agree to the conditioning of e^A."""
    rng = np.random.default_rng(5)
    for norm in [10.0**e for e in range(-8, 3)]:
        for _ in range(5):
            n = int(rng.integers(1, 8))
            a = rng.standard_normal((n, n))
            a *= norm / np.linalg.norm(a, 1)
            want = sl.expm(a)
            err = rel_err(kfast.expm(a), want)
            # scipy's own error reaches ~1e-11 at norm 100 (measured against 60 digits)
            assert err <= 1e-13 * max(1.0, norm) ** 2, f"||A||_1 = {norm:.3g}, n = {n}: {err:.3g}"
            assert rel_err(kfast.expm(a), mp_expm(a)) <= 20 * n * U * max(1.0, norm)


def test_exp_a_times_exp_minus_a_and_commutation():
    rng = np.random.default_rng(9)
    for norm in [1e-6, 1.0, 6.0, 30.0]:
        a = rng.standard_normal((4, 4))
        a *= norm / np.linalg.norm(a, 1)
        ea, ema = kfast.expm(a), kfast.expm(-a)
        scale = np.linalg.norm(ea, 1) * np.linalg.norm(ema, 1)
        assert np.abs(ea @ ema - np.eye(4)).max() <= 50 * U * scale
        assert np.abs(a @ ea - ea @ a).max() <= 50 * U * np.linalg.norm(a, 1) * np.linalg.norm(ea, 1)
