"""kfast.discretize and LinearGaussian.from_continuous at every scale and on bad input (issue
#10): a non-PSD Qc gave a non-PSD Qd, dt = 1e300 gave NaN (then reported as "F: non-finite"),
long intervals of stable models overflowed inside the Van Loan block. Every bad argument is a
KfastError (a ValueError) naming it; nothing that is returned is non-finite.

References: closed forms (docs/algorithms.md, "Constant velocity", "First-order Gauss-Markov"),
the continuous Lyapunov equation for dt -> inf (Söderström (4.90)), scipy's block exponential,
and F, Qd = Pi - F Pi F', Bd = A^-1 (F - I) B for stable A evaluated with mpmath at 60 digits.
"""

import math

import mpmath
import numpy as np
import pytest
import scipy.linalg as sl

import kfast

U = 2.0**-53
CV_A = np.array([[0.0, 1.0], [0.0, 0.0]])
CV_QC = np.diag([0.0, 1.0])


def mp_sampled(A, Qc, dt, B):
    """(F, Qd, Bd) of a stable A at 60 digits, without Van Loan: F = e^{A dt},
    Qd = Pi - F Pi F' with A Pi + Pi A' + Qc = 0 (Söderström (4.90), (4.103)), and
    Bd = A^-1 (F - I) B. (The Van Loan block holds e^{-A dt}, and F E12 cancels e^{|A| dt}
    digits: no fixed precision suffices at dt = 1e4.)"""
    n = len(A)
    with mpmath.workdps(60):
        Am, Qm, Bm = mpmath.matrix(A.tolist()), mpmath.matrix(Qc.tolist()), mpmath.matrix(B.tolist())
        F = mpmath.expm(Am * mpmath.mpf(dt))
        # vec(A Pi + Pi A') = (I (x) A + A (x) I) vec(Pi), row-major vec
        K = mpmath.zeros(n * n, n * n)
        for i in range(n):
            for j in range(n):
                for k in range(n):
                    K[i * n + j, k * n + j] += Am[i, k]
                    K[i * n + j, i * n + k] += Am[j, k]
        pi_vec = mpmath.lu_solve(K, mpmath.matrix([-Qm[i, j] for i in range(n) for j in range(n)]))
        Pi = mpmath.matrix(n, n)
        for i in range(n):
            for j in range(n):
                Pi[i, j] = pi_vec[i * n + j]
        Qd = Pi - F * Pi * F.T
        Bd = mpmath.inverse(Am) * (F - mpmath.eye(n)) * Bm
        return tuple(np.array(x.tolist(), dtype=float) for x in (F, Qd, Bd))


def rel_err(got, want):
    return np.linalg.norm(got - want, 1) / np.linalg.norm(want, 1)


# --- long intervals and large norms ---------------------------------------------------------


@pytest.mark.parametrize("dt", [1.0, 10.0, 100.0, 709.0, 1000.0, 1e5, 1e300])
def test_ornstein_uhlenbeck_any_interval(dt):
    """dx = -x dt + dbeta, Qc = 2: F = e^-dt, Qd = 1 - e^-2dt (-> the stationary variance 1).
    Was NaN from dt ~ 710 on: the block exponential holds e^{+dt}."""
    F, Qd, Bd = kfast.discretize(-1.0, 2.0, dt, B=[[3.0]])
    # exp is sensitive to its argument's rounding by |dt|
    assert F[0, 0] == pytest.approx(math.exp(-dt), rel=4 * U * dt, abs=1e-300)
    assert Qd[0, 0] == pytest.approx(-math.expm1(-2 * dt), rel=1e-14)
    assert Bd[0, 0] == pytest.approx(-3.0 * math.expm1(-dt), rel=1e-14)


def test_stable_model_long_interval_tends_to_the_stationary_covariance():
    """Qd(dt) -> Pi with A Pi + Pi A' + Qc = 0 and F -> 0 (the resonator, Hurwitz A)."""
    A = np.array([[0.0, 1.0], [-(4 + 1 / 9), -2 / 3]])
    Qc = np.diag([0.0, 1.0])
    wr, wd = 2.0, 1 / 3
    Pi = np.diag([1 / (4 * wd * (wr**2 + wd**2)), 1 / (4 * wd)])  # docs/algorithms.md, "Damped resonator"
    np.testing.assert_allclose(A @ Pi + Pi @ A.T + Qc, 0.0, atol=1e-15)
    for dt in [1e3, 1e6, 1e300]:
        F, Qd, _ = kfast.discretize(A, Qc, dt)
        # the eigenvalues have real part -1/3: |F| ~ e^{-dt/3} (1e-145 at dt = 1000)
        assert np.abs(F).max() <= 10 * math.exp(-dt / 3)
        np.testing.assert_allclose(Qd, Pi, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("dt", [1e-8, 1e-3, 1.0, 1e3, 1e8, 1e60, 1e100])
def test_constant_velocity_closed_form_at_any_interval(dt):
    """F = [[1, h], [0, 1]], Qd = q [[h^3/3, h^2/2], [h^2/2, h]] for as long as it is finite:
    the Van Loan block is nilpotent, so no scaling and squaring at all."""
    q = 2.5
    B = np.array([[0.0], [1.0]])
    F, Qd, Bd = kfast.discretize(CV_A, q * CV_QC, dt, B=B)
    np.testing.assert_allclose(F, [[1.0, dt], [0.0, 1.0]], rtol=4 * U, atol=0)
    np.testing.assert_allclose(Qd, q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]]), rtol=4 * U, atol=0)
    np.testing.assert_allclose(Bd, [[dt**2 / 2], [dt]], rtol=4 * U, atol=0)


def random_stable(rng, n):
    A = rng.standard_normal((n, n))
    return A - (np.linalg.eigvals(A).real.max() + 0.5) * np.eye(n)


def test_random_stable_models_against_60_digits():
    """Seeded stable A (spectral abscissa -0.5), singular PSD Qc, B; dt from 1e-6 to 1e4:
    relative errors of F, Qd, Bd within 50 n u max(1, ||A dt||_1) (the conditioning of e^{A dt}),
    and Qd positive semidefinite."""
    rng = np.random.default_rng(31)
    for dt in [1e-6, 1e-3, 0.1, 1.0, 10.0, 100.0, 1e4]:
        for _ in range(3):
            n = int(rng.integers(2, 5))
            A = random_stable(rng, n)
            G = rng.standard_normal((n, n - 1))
            Qc = G @ G.T
            B = rng.standard_normal((n, 2))
            F, Qd, Bd = kfast.discretize(A, Qc, dt, B=B)
            F_ref, Qd_ref, Bd_ref = mp_sampled(A, Qc, dt, B)
            tol = 50 * n * U * max(1.0, np.linalg.norm(A, 1) * dt)
            if np.abs(F_ref).max() > 1e-300:
                assert rel_err(F, F_ref) <= tol, f"dt {dt}: F"
            assert rel_err(Qd, Qd_ref) <= tol, f"dt {dt}: Qd {rel_err(Qd, Qd_ref):.3g}"
            assert rel_err(Bd, Bd_ref) <= tol, f"dt {dt}: Bd"
            np.testing.assert_array_equal(Qd, Qd.T)
            assert np.linalg.eigvalsh(Qd).min() >= -4 * n * U * np.linalg.norm(Qd, 2)


def test_agrees_with_scipy_block_exponential_at_moderate_norms():
    """Van Loan with scipy.linalg.expm (accurate for ||A dt|| <= 10) agrees."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        n = int(rng.integers(1, 6))
        A = rng.standard_normal((n, n))
        G = rng.standard_normal((n, n))
        Qc = G @ G.T
        dt = float(rng.uniform(0.01, 2.0))
        E = sl.expm(dt * np.block([[-A, Qc], [np.zeros((n, n)), A.T]]))
        F_ref = E[n:, n:].T
        Qd_ref = F_ref @ E[:n, n:]
        F, Qd, _ = kfast.discretize(A, Qc, dt)
        assert rel_err(F, F_ref) <= 1e-12
        assert rel_err(Qd, Qd_ref) <= 1e-12


def test_nilpotent_model_with_huge_entries_is_exact():
    """A = [[0, 1e20], [0, 0]] (units), Qc = 0: F = [[1, 1e20 dt], [0, 1]] exactly."""
    F, Qd, _ = kfast.discretize([[0.0, 1e20], [0.0, 0.0]], np.zeros((2, 2)), 0.5)
    np.testing.assert_array_equal(F, [[1.0, 5e19], [0.0, 1.0]])
    np.testing.assert_array_equal(Qd, 0.0)


def test_random_walk_with_huge_interval_is_exact():
    F, Qd, _ = kfast.discretize(0.0, 3.0, 1e300)
    assert F[0, 0] == 1.0 and Qd[0, 0] == 3e300


# --- overflow names dt ----------------------------------------------------------------------


def test_overflow_names_dt():
    """Was: NaN for dt = 1e300, then "F: non-finite" from the model."""
    with pytest.raises(kfast.KfastError, match=r"^dt: the sampled model overflows double precision at dt = 1e300"):
        kfast.discretize(CV_A, CV_QC, 1e300)
    with pytest.raises(kfast.KfastError, match=r"^dt: the sampled model overflows"):
        kfast.discretize(1.0, 1.0, 1000.0)  # e^1000
    with pytest.raises(kfast.KfastError, match=r"^dt: the sampled model overflows"):
        kfast.discretize(0.0, 1e10, 1e300)  # Qd = 1e310
    with pytest.raises(kfast.KfastError, match=r"^dt at step 2: the sampled model overflows"):
        kfast.discretize(CV_A, CV_QC, [0.1, 0.2, 1e300])
    with pytest.raises(kfast.KfastError, match=r"^dt: the sampled model overflows"):
        kfast.LinearGaussian.from_continuous(CV_A, CV_QC, [[1.0, 0.0]], [[1.0]], dt=1e300)
    with pytest.raises(kfast.KfastError, match=r"^dt at step 1: the sampled model overflows"):
        kfast.LinearGaussian.from_continuous(CV_A, CV_QC, [[1.0, 0.0]], [[1.0]], dt=[0.1, 1e300])
    with pytest.raises(kfast.KfastError, match=r"^dt: the sampled model overflows"):
        kfast.discretize(1.0, 1.0, 1.0, B=[[1e308]])  # Bd only


# --- bad arguments: a clear ValueError naming the argument ----------------------------------

GOOD = dict(A=CV_A, Qc=CV_QC, dt=0.1)
MASKED_A = np.ma.masked_array(CV_A, mask=[[False, True], [False, False]])
BAD = [
    # (argument, value, message pattern)
    ("Qc", np.diag([1.0, -1.0]), r"^Qc: not positive semidefinite \(smallest eigenvalue -1"),
    ("Qc", np.array([[1.0, 2.0], [2.0, 1.0]]), r"^Qc: not positive semidefinite"),
    ("Qc", -1.0 * np.eye(2), r"^Qc: not positive semidefinite"),
    ("Qc", np.array([[1.0, 0.5], [0.0, 1.0]]), r"^Qc: not symmetric"),
    ("Qc", np.eye(3), r"^Qc"),
    ("Qc", np.ones(2), r"^Qc: expected a 2-D array"),
    ("Qc", np.array([[np.nan, 0.0], [0.0, 1.0]]), r"^Qc: contains a non-finite value"),
    ("Qc", np.eye(2) * (1 + 1j), r"^Qc: complex input"),
    ("Qc", np.eye(2, dtype=bool), r"^Qc: expected real numbers"),
    ("Qc", np.ma.masked_array(np.eye(2), mask=np.eye(2, dtype=bool)), r"^Qc: has masked entries"),
    ("A", np.zeros((2, 3)), r"^A"),
    ("A", np.zeros((2, 2, 2)), r"^A: expected a 2-D array"),
    ("A", np.array([[0.0, np.inf], [0.0, 0.0]]), r"^A: contains a non-finite value"),
    ("A", np.array([[0.0, 1.0], [0.0, np.nan]]), r"^A: contains a non-finite value"),
    ("A", CV_A.astype(complex), r"^A: complex input"),
    ("A", CV_A.astype(object), r"^A: expected real numbers"),
    ("A", MASKED_A, r"^A: has masked entries"),
    ("A", [[0.0, 1.0], [0.0]], r"^A: cannot be read as an array"),
    ("A", "ab", r"^A: expected real numbers"),
    ("dt", 0.0, r"^dt: must be positive and finite, got 0"),
    ("dt", -0.1, r"^dt: must be positive and finite"),
    ("dt", np.nan, r"^dt: must be positive and finite, got NaN"),
    ("dt", np.inf, r"^dt: must be positive and finite, got inf"),
    ("dt", -np.inf, r"^dt: must be positive and finite"),
    ("dt", [0.1, 0.0, 0.2], r"^dt at step 1: must be positive and finite"),
    ("dt", [0.1, np.nan], r"^dt at step 1: must be positive and finite"),
    ("dt", [[0.1, 0.2]], r"^dt: expected a scalar or a non-empty 1-D array"),
    ("dt", [], r"^dt: expected a scalar or a non-empty 1-D array"),
    ("dt", True, r"^dt: expected real numbers"),
    ("dt", 0.1 + 0j, r"^dt: complex input"),
    ("dt", None, r"^dt: expected real numbers"),
    ("dt", "0.1", r"^dt: expected real numbers"),
    ("dt", 10**400, r"^dt: expected real numbers"),
    ("dt", np.ma.masked_array([0.1, 0.2], mask=[False, True]), r"^dt: has masked entries"),
    ("B", np.ones((3, 1)), r"^B: expected 2 rows"),
    ("B", np.ones(2), r"^B: expected a 2-D array"),
    ("B", np.array([[np.nan], [1.0]]), r"^B: contains a non-finite value"),
    ("B", np.ones((2, 1), dtype=complex), r"^B: complex input"),
    ("B", np.ones((2, 1), dtype=bool), r"^B: expected real numbers"),
    ("B", np.ma.masked_array(np.ones((2, 1)), mask=[[True], [False]]), r"^B: has masked entries"),
]


@pytest.mark.parametrize("arg, value, pattern", BAD, ids=[f"{a}-{i}" for i, (a, _, _) in enumerate(BAD)])
def test_bad_argument_is_a_value_error_naming_it(arg, value, pattern):
    kwargs = dict(GOOD, **{arg: value})
    with pytest.raises(kfast.KfastError, match=pattern) as info:
        kfast.discretize(**kwargs)
    assert isinstance(info.value, ValueError)
    # from_continuous hands A, Qc, dt and B to discretize: the same error
    H, R = [[1.0, 0.0]], [[1.0]]
    if arg == "dt" and value is None:  # from_continuous: dt=None means "give times instead"
        pattern = r"^dt, times: give exactly one of them"
    with pytest.raises(kfast.KfastError, match=pattern):
        kfast.LinearGaussian.from_continuous(kwargs["A"], kwargs["Qc"], H, R, dt=kwargs["dt"], B=kwargs.get("B"))


@pytest.mark.parametrize(
    "value, pattern",
    [
        (np.array([[0.0, 1.0, 2.0]]), r"^a"),
        (np.ones(3), r"^a: expected a 2-D array"),
        (np.ones((2, 2, 2)), r"^a: expected a 2-D array"),
        (np.array([[np.nan]]), r"^a: contains a non-finite value"),
        (np.array([[-np.inf]]), r"^a: contains a non-finite value"),
        (np.eye(2) * 1j, r"^a: complex input"),
        (np.eye(2, dtype=bool), r"^a: expected real numbers"),
        (np.ma.masked_array(np.eye(2), mask=np.eye(2, dtype=bool)), r"^a: has masked entries"),
        (np.diag([1e5, -1e5]), r"^a: e\^a overflows double precision"),
    ],
)
def test_expm_bad_argument_names_a(value, pattern):
    with pytest.raises(kfast.KfastError, match=pattern) as info:
        kfast.expm(value)
    assert isinstance(info.value, ValueError)


def test_masked_array_without_masked_entries_is_its_data():
    plain = kfast.discretize(CV_A, CV_QC, [0.1, 0.2])
    masked = kfast.discretize(np.ma.masked_array(CV_A), np.ma.masked_array(CV_QC), np.ma.masked_array([0.1, 0.2]))
    for a, b in zip(plain[:2], masked[:2]):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(kfast.expm(np.ma.masked_array(CV_A)), kfast.expm(CV_A))


def test_times_with_masked_entries_are_refused():
    with pytest.raises(kfast.KfastError, match=r"^times: has masked entries"):
        kfast.LinearGaussian.from_continuous(
            CV_A, CV_QC, [[1.0, 0.0]], [[1.0]], times=np.ma.masked_array([0.0, 1.0, 2.0], mask=[0, 1, 0])
        )
    with pytest.raises(kfast.KfastError, match=r"^dt: expected a scalar or a non-empty 1-D array"):
        kfast.LinearGaussian.from_continuous(CV_A, CV_QC, [[1.0, 0.0]], [[1.0]], dt=[])


def test_integer_input_equals_float_and_inputs_are_not_modified():
    A_int = np.array([[0, 1], [-2, -1]])
    Qc_int = np.array([[0, 0], [0, 3]])
    B = np.array([[0.0], [1.0]])
    dt = np.array([0.1, 0.25])
    copies = [x.copy() for x in (A_int, Qc_int, B, dt)]
    F, Qd, Bd = kfast.discretize(A_int, Qc_int, dt, B=B)
    F2, Qd2, Bd2 = kfast.discretize(A_int.astype(float), Qc_int.astype(float), dt, B=B)
    for a, b in [(F, F2), (Qd, Qd2), (Bd, Bd2)]:
        np.testing.assert_array_equal(a, b)
    for x, c in zip((A_int, Qc_int, B, dt), copies):
        np.testing.assert_array_equal(x, c)
    # read-only and non-contiguous input is fine
    A_ro = np.asfortranarray(A_int.astype(float))
    A_ro.setflags(write=False)
    np.testing.assert_array_equal(kfast.discretize(A_ro, Qc_int, 0.1).F, F[0])


# --- the other continuous-time entry points: the same class of problems ---------------------

RESONATOR_A = np.array([[0.0, 1.0], [-(4 + 1 / 9), -2 / 3]])
CT_BAD = [
    # (function, kwargs overriding the good ones, message pattern)
    ("stationary", {"Qc": np.diag([1.0, -1.0])}, r"^Qc: not positive semidefinite"),
    ("stationary", {"Qc": np.array([[1.0, 0.3], [0.0, 1.0]])}, r"^Qc: not symmetric"),
    ("stationary", {"Qc": np.eye(3)}, r"^Qc: expected shape \(2, 2\)"),
    ("stationary", {"Qc": np.ma.masked_array(np.eye(2), mask=np.eye(2, dtype=bool))}, r"^Qc: has masked entries"),
    ("stationary", {"A": np.ma.masked_array(RESONATOR_A, mask=np.eye(2, dtype=bool))}, r"^A: has masked entries"),
    ("stationary", {"A": np.zeros((2, 3))}, r"^A: expected a square matrix"),
    ("stationary", {"A": np.array([[np.nan, 0.0], [0.0, -1.0]])}, r"^A: contains a non-finite value"),
    ("stationary", {"A": np.eye(2)}, r"^A: is not stable"),
    ("kalman_bucy", {"Qc": np.diag([1.0, -1.0])}, r"^Qc: not positive semidefinite"),
    ("kalman_bucy", {"Rc": -np.eye(1)}, r"^Rc: not positive definite"),
    ("kalman_bucy", {"Rc": np.zeros((1, 1))}, r"^Rc: not positive definite"),
    ("kalman_bucy", {"Rc": np.eye(2)}, r"^Rc: expected shape \(1, 1\)"),
    ("kalman_bucy", {"H": np.ones((1, 3))}, r"^H: expected 2 columns like A"),
    ("kalman_bucy", {"H": np.ma.masked_array(np.ones((1, 2)), mask=[[True, False]])}, r"^H: has masked entries"),
    ("kalman_bucy", {"Qc": np.eye(2) * 1j}, r"^Qc: complex input"),
]


@pytest.mark.parametrize("which, override, pattern", CT_BAD, ids=[f"{w}-{i}" for i, (w, _, _) in enumerate(CT_BAD)])
def test_continuous_time_entry_points_name_the_argument(which, override, pattern):
    """A non-PSD Qc gave a "stationary covariance" with a negative variance; a negative Rc
    reached the Riccati solver as "no stabilizing solution"."""
    good = dict(A=RESONATOR_A, Qc=np.diag([0.0, 1.0]))
    if which == "kalman_bucy":
        good.update(H=np.array([[1.0, 0.0]]), Rc=np.array([[0.1]]))
        call = kfast.kalman_bucy
    else:
        call = kfast.stationary_cov_continuous
    with pytest.raises(kfast.KfastError, match=pattern):
        call(**dict(good, **override))


def test_a_mode_that_does_not_decay_with_a_huge_norm_is_refused():
    """The Singer model at alpha dt = 1e299 (eigenvalues 0, 0, -alpha): more than 52 doublings
    multiply the rounding of the undamped position/velocity modes beyond any accuracy; it came
    out as F = 0. Refused naming A (the catalogue names alpha)."""
    alpha = 1e300
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -alpha]])
    with pytest.raises(kfast.KfastError, match=r"^dt: A is too large for this interval.*does not decay"):
        kfast.discretize(A, np.diag([0.0, 0.0, 1.0]), 0.1)
    with pytest.raises(kfast.KfastError, match=r"^alpha\b|^dt, alpha\b"):
        kfast.models.singer(dt=0.1, alpha=alpha, sigma_m2=1.0)
    # A moderate alpha dt keeps the closed-form position row: F[0] = [1, dt, (a dt - 1 + e^-a dt) / a^2].
    dt, a = 0.1, 1e6
    F, _, _ = kfast.discretize([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -a]], np.diag([0.0, 0.0, 1.0]), dt)
    np.testing.assert_allclose(F[0], [1.0, dt, (a * dt - 1 + np.exp(-a * dt)) / a**2], rtol=1e-9)
