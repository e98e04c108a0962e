"""The NumPy reference Lyapunov, Riccati and sampling solvers (python/kfast/reference) against
scipy.linalg on seeded random systems, and against textbook cases B3 (Söderström ex. 6.6) and
D3 (G&A ex. 4.9) of tests/data/textbook_cases.json."""

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg as sl

from kfast.reference.lyapunov import (
    discrete_lyapunov_doubling,
    solve_continuous_lyapunov_kron,
    solve_discrete_lyapunov_kron,
)
from kfast.reference.riccati import (
    care_closed_loop_eigenvalues,
    care_eigen,
    care_residual,
    dare_closed_loop_eigenvalues,
    dare_eigen,
    dare_gain,
    dare_iteration,
    dare_residual,
    is_stabilizing_dare,
)
from kfast.reference.sampling import expm_taylor, qd_first_order, van_loan

SEEDS = range(30)
RTOL = 1e-9


# SciPy 1.17's generalized ARE solvers (e given) return a wrong X, or raise "eigenvalues too close
# to the unit circle / imaginary axis", on about 1 in 10 of these random systems when balancing
# is on (the default): the final e-correction of the subspace basis seems to use the unbalanced
# e. With balanced=False they agree with the references to ~1e-12, so that is the peer for e.
def scipy_kw(e):
    return {"balanced": False} if e is not None else {}


def rel_err(got, want):
    return float(np.linalg.norm(got - want) / max(np.linalg.norm(want), 1e-300))


def random_spd(rng, n, jitter=0.1):
    A = rng.standard_normal((n, n))
    return A @ A.T / n + jitter * np.eye(n)


def matrix_with_eigenvalues(rng, lam):
    """A real matrix with the given real eigenvalues, via a well-conditioned similarity."""
    n = len(lam)
    V = np.linalg.qr(rng.standard_normal((n, n)))[0] + 0.3 * rng.standard_normal((n, n))
    return V @ np.diag(lam) @ np.linalg.inv(V)


def random_matrix(rng, n, complex_=False):
    a = rng.standard_normal((n, n))
    return a + 1j * rng.standard_normal((n, n)) if complex_ else a


# ----------------------------------------------------------------------------------------------
# Lyapunov


def lyap_case(seed, kind):
    """a, q with a unique, well-conditioned solution: stable for even seeds, unstable otherwise."""
    rng = np.random.default_rng(500 + seed)
    n = int(rng.integers(1, 9))
    complex_ = seed % 5 == 4
    while True:
        a = random_matrix(rng, n, complex_)
        lam = np.linalg.eigvals(a)
        if kind == "discrete":
            a = a * rng.uniform(0.3, 0.95 if seed % 2 == 0 else 1.6) / max(abs(lam))
            lam = np.linalg.eigvals(a)
            gap = np.min(np.abs(1 - np.outer(lam, lam.conj())))
        else:
            a = a - (rng.uniform(0.1, 2) * np.max(lam.real) if seed % 2 == 0 else 0) * np.eye(n)
            lam = np.linalg.eigvals(a)
            gap = np.min(np.abs(np.add.outer(lam, lam.conj())))
        if gap > 0.05:
            break
    q = random_matrix(rng, n, complex_)
    return a, (q + q.conj().T) / 2


@pytest.mark.parametrize("seed", SEEDS)
def test_discrete_lyapunov_kron_matches_scipy(seed):
    a, q = lyap_case(seed, "discrete")
    X = solve_discrete_lyapunov_kron(a, q)
    assert rel_err(X, sl.solve_discrete_lyapunov(a, q)) <= RTOL
    res = a @ X @ a.conj().T - X + q
    assert np.linalg.norm(res) <= 1e-10 * (2 * np.linalg.norm(a) ** 2 * np.linalg.norm(X) + np.linalg.norm(q))


@pytest.mark.parametrize("seed", SEEDS)
def test_continuous_lyapunov_kron_matches_scipy(seed):
    a, q = lyap_case(seed, "continuous")
    X = solve_continuous_lyapunov_kron(a, q)
    assert rel_err(X, sl.solve_continuous_lyapunov(a, q)) <= RTOL
    res = a @ X + X @ a.conj().T - q
    assert np.linalg.norm(res) <= 1e-10 * (2 * np.linalg.norm(a) * np.linalg.norm(X) + np.linalg.norm(q))


@pytest.mark.parametrize("seed", [s for s in SEEDS if s % 2 == 0])
def test_discrete_lyapunov_doubling_matches_scipy(seed):
    a, q = lyap_case(seed, "discrete")  # even seeds: rho(a) < 1
    X = discrete_lyapunov_doubling(a, q)
    assert rel_err(X, sl.solve_discrete_lyapunov(a, q)) <= RTOL
    assert rel_err(X, solve_discrete_lyapunov_kron(a, q)) <= RTOL


def test_doubling_near_unit_circle():
    rng = np.random.default_rng(7)
    a = matrix_with_eigenvalues(rng, [0.999, -0.99, 0.5, 0.0])
    q = random_spd(rng, 4)
    assert rel_err(discrete_lyapunov_doubling(a, q), sl.solve_discrete_lyapunov(a, q)) <= 1e-8


def test_doubling_rejects_unstable():
    with pytest.raises(ValueError):
        discrete_lyapunov_doubling(np.array([[1.0]]), np.array([[1.0]]))  # B4: random walk
    with pytest.raises(ValueError):
        discrete_lyapunov_doubling(np.diag([0.5, 1.2]), np.eye(2))


@pytest.mark.parametrize(
    "a",
    [
        np.array([[1.0]]),  # B4 discrete: F = 1 (random walk)
        np.eye(3),
        np.diag([2.0, 0.5, 0.3]),  # 2 * 0.5 = 1
        matrix_with_eigenvalues(np.random.default_rng(1), [-2.0, 0.3, -0.5, 0.9]),  # (-2)(-0.5) = 1
        np.array([[0.0, 1.0], [-1.0, 0.0]]),  # eigenvalues +-i: i * conj(i) = 1
        np.array([[1.0, 1.0], [0.0, 1.0]]),  # defective
    ],
)
def test_discrete_kron_no_unique_solution(a):
    with pytest.raises(ValueError, match="no unique solution"):
        solve_discrete_lyapunov_kron(a, np.eye(len(a)))


@pytest.mark.parametrize(
    "a",
    [
        np.zeros((1, 1)),  # integrator
        np.diag([1.0, -1.0, -3.0]),  # 1 + (-1) = 0
        np.array([[0.0, 2.0], [-2.0, 0.0]]),  # undamped oscillator, eigenvalues +-2i
        np.array([[-1.0, 5.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -2.0]]),
    ],
)
def test_continuous_kron_no_unique_solution(a):
    with pytest.raises(ValueError, match="no unique solution"):
        solve_continuous_lyapunov_kron(a, np.eye(len(a)))


def test_b4_continuous_negative_solution():
    # B4 (G&A problem 4.27): A = 1, Qc = 1; A X + X A' = -Qc has the unique "solution" -1/2,
    # which is no covariance. The Kronecker solver (SciPy's convention) returns it; callers must
    # check Hurwitz A themselves.
    assert solve_continuous_lyapunov_kron(np.array([[1.0]]), np.array([[-1.0]]))[0, 0] == pytest.approx(-0.5)


# ----------------------------------------------------------------------------------------------
# Riccati


def pbh_margin(a, b, e):
    """min over the eigenvalues l of the pencil (a, e) of sigma_min([l e - a, b]) / ||[a, b]||:
    far from 0 means well controllable (Popov-Belevitch-Hautus), hence a well-conditioned X."""
    lam = np.linalg.eigvals(np.linalg.solve(e, a))
    sig = [np.linalg.svd(np.hstack([l * e - a, b]), compute_uv=False)[-1] for l in lam]
    return min(sig) / np.linalg.norm(np.hstack([a, b]), 2)


def riccati_case(seed, with_e=True, with_s=True, radius=(0.5, 1.5), shift=(0.0, 0.0)):
    """A random controllable (with margin) system with [[q, s], [s', r]] > 0, so r > 0 and the
    reduced q~ > 0 (observable). a is scaled to a spectral radius in ``radius``, then shifted by
    -c I with c uniform in ``shift`` (continuous: Hurwitz and unstable)."""
    rng = np.random.default_rng(900 + seed)
    n, m = int(rng.integers(1, 7)), int(rng.integers(1, 4))
    while True:
        a = rng.standard_normal((n, n))
        a = a * rng.uniform(*radius) / max(abs(np.linalg.eigvals(a))) - rng.uniform(*shift) * np.eye(n)
        b = rng.standard_normal((n, m))
        e = np.eye(n) + 0.2 * rng.standard_normal((n, n)) if with_e else None
        if pbh_margin(a, b, np.eye(n) if e is None else e) > 0.05:
            break
    J = random_spd(rng, n + m)
    q, r, s = J[:n, :n], J[n:, n:], J[:n, n:]
    if not with_s:
        q, s = q - s @ np.linalg.solve(r, s.T), None  # keep the reduced q PSD
        q = (q + q.T) / 2
    return a, b, q, r, e, s


@pytest.mark.parametrize("seed", SEEDS)
def test_dare_eigen_matches_scipy(seed):
    a, b, q, r, e, s = riccati_case(seed, with_e=seed % 3 != 0, with_s=seed % 4 != 0)
    X = dare_eigen(a, b, q, r, e, s)
    assert rel_err(X, sl.solve_discrete_are(a, b, q, r, e, s, **scipy_kw(e))) <= RTOL
    assert dare_residual(a, b, q, r, X, e, s) <= 1e-10
    assert max(abs(dare_closed_loop_eigenvalues(a, b, r, s, X, e))) < 1


@pytest.mark.parametrize("seed", SEEDS)
def test_dare_iteration_matches_scipy(seed):
    a, b, q, r, _, s = riccati_case(seed, with_e=False, with_s=seed % 4 != 0)
    X = dare_iteration(a, b, q, r, s)
    assert rel_err(X, sl.solve_discrete_are(a, b, q, r, s=s)) <= RTOL
    assert dare_residual(a, b, q, r, X, s=s) <= 1e-10
    assert is_stabilizing_dare(a, b, r, s, X)


@pytest.mark.parametrize("seed", SEEDS)
def test_care_eigen_matches_scipy(seed):
    a, b, q, r, e, s = riccati_case(seed, seed % 3 != 0, seed % 4 != 0, radius=(0.2, 2.0), shift=(-1.0, 2.0))
    X = care_eigen(a, b, q, r, e, s)
    assert rel_err(X, sl.solve_continuous_are(a, b, q, r, e, s, **scipy_kw(e))) <= RTOL
    assert care_residual(a, b, q, r, X, e, s) <= 1e-10
    assert max(care_closed_loop_eigenvalues(a, b, r, s, X, e).real) < 0


def test_dare_kalman_mapping():
    # a = F', b = H', s = N: the gain (b'Xb + r)^-1 (b'Xa + s') is K_pred'
    # (docs/algorithms.md, "DARE and the Kalman filter").
    a, b, q, r, _, s = riccati_case(3, with_e=False)
    F, H, N = a.T, b.T, s
    P = dare_eigen(a, b, q, r, s=s)
    S = H @ P @ H.T + r
    K_pred = (F @ P @ H.T + N) @ np.linalg.inv(S)
    np.testing.assert_allclose(dare_gain(a, b, r, P, s), K_pred.T, rtol=1e-10, atol=1e-12)
    P_next = F @ P @ F.T + q - K_pred @ S @ K_pred.T  # (6.91)
    np.testing.assert_allclose(P_next, P, rtol=1e-10, atol=1e-12)


def b3(a_, c):
    F = np.array([[-a_, 1.0], [0.0, 0.0]])
    Q = np.array([[1.0, c], [c, c * c]])
    H = np.array([[1.0, 0.0]])
    return F.T, H.T, Q, np.zeros((1, 1))


@pytest.mark.parametrize(
    "c, P, K_pred, eig",
    [
        (1.5, [[2.25, 1.5], [1.5, 2.25]], [1 / 6, 0.0], [-2 / 3, 0.0]),
        (-0.8, [[1.0, -0.8], [-0.8, 0.64]], [-1.3, 0.0], [0.8, 0.0]),
    ],
)
def test_b3_riccati_iteration_singular_r(c, P, K_pred, eig):
    # Söderström ex. 6.6 (case B3 of tests/data/textbook_cases.json): R = 0, two solutions,
    # only the stabilizing one is right.
    a, b, q, r = b3(0.5, c)
    X = dare_iteration(a, b, q, r)
    np.testing.assert_allclose(X, P, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(dare_gain(a, b, r, X)[0], K_pred, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.sort(dare_closed_loop_eigenvalues(a, b, r, None, X).real), np.sort(eig), atol=1e-9)
    assert is_stabilizing_dare(a, b, r, None, X)


def test_b3_other_root_is_a_non_stabilizing_fixed_point():
    # c = 1.5: P = [[1, c], [c, c^2]] (q = 0 in the book's family) solves the DARE too, with
    # K_pred = [1, 0] and eig(F - K_pred H) = {-1.5, 0}: started there, the iteration stays there
    # (failure mode 2 in docs/algorithms.md, "Stabilizing solution"); the default start x0 = I does not.
    a, b, q, r = b3(0.5, 1.5)
    X_bad = np.array([[1.0, 1.5], [1.5, 2.25]])
    np.testing.assert_allclose(dare_iteration(a, b, q, r, x0=X_bad), X_bad, atol=1e-12)
    assert not is_stabilizing_dare(a, b, r, None, X_bad)
    np.testing.assert_allclose(np.sort(dare_closed_loop_eigenvalues(a, b, r, None, X_bad).real), [-1.5, 0.0], atol=1e-12)


def test_cross_term_iteration_from_zero_is_a_non_stabilizing_fixed_point():
    # Söderström ex. 7.1, y(t) - 0.8 y(t-1) = e(t) + 2 e(t-1), var e = 1, in observer form:
    # F = 0.8, k = 2.8, Q = k^2, N = k, R = 1 (tests/data/dare_cross_term.json). q - s r^-1 s' = 0,
    # so from X = 0 the gain is r^-1 s' = 2.8, the closed loop a - bK = -2 and the next iterate
    # is 0 again: a non-stabilizing fixed point (issue 9). From X = I the iteration reaches the
    # stabilizing P = 3 (innovation variance 4, closed loop -0.5).
    a, b, q, r, s = np.array([[0.8]]), np.eye(1), np.array([[2.8**2]]), np.eye(1), np.array([[2.8]])
    X_zero = dare_iteration(a, b, q, r, s, x0=np.zeros((1, 1)))
    np.testing.assert_allclose(X_zero, 0.0, atol=1e-15)
    np.testing.assert_allclose(dare_closed_loop_eigenvalues(a, b, r, s, X_zero), [-2.0], atol=1e-12)
    X = dare_iteration(a, b, q, r, s)
    np.testing.assert_allclose(X, [[3.0]], rtol=1e-12)
    assert is_stabilizing_dare(a, b, r, s, X)
    np.testing.assert_allclose(dare_closed_loop_eigenvalues(a, b, r, s, X), [-0.5], atol=1e-12)


# ----------------------------------------------------------------------------------------------
# Sampling


@pytest.mark.parametrize("seed", SEEDS)
def test_expm_taylor_matches_scipy(seed):
    rng = np.random.default_rng(1300 + seed)
    n = int(rng.integers(1, 9))
    a = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-3, 0.7)
    if seed % 5 == 4:
        a = a + 1j * rng.standard_normal((n, n))
    assert rel_err(expm_taylor(a), sl.expm(a)) <= 1e-12


def resonator(wr=2.0, wd=1 / 3):
    return np.array([[0.0, 1.0], [-(wr**2 + wd**2), -2 * wd]])


def test_d3_damped_resonator():
    # G&A ex. 4.9 (case D3 of tests/data/textbook_cases.json).
    A, Qc = resonator(), np.diag([0.0, 1.0])
    F, Qd = van_loan(A, Qc, 0.1)
    want = np.array([[3.14589889e-4, 4.615499469e-3], [4.615499469e-3, 9.2369208819e-2]])
    np.testing.assert_allclose(Qd, want, rtol=1e-9)
    np.testing.assert_allclose(F, sl.expm(0.1 * A), rtol=1e-12, atol=1e-14)
    # The stationary continuous covariance diag(q / (4 wd (wr^2 + wd^2)), q / (4 wd)) solves
    # A Pi + Pi A' = -Qc, and Pi = F Pi F' + Qd for any dt.
    wr, wd = 2.0, 1 / 3
    Pi = solve_continuous_lyapunov_kron(A, -Qc)
    np.testing.assert_allclose(Pi, np.diag([1 / (4 * wd * (wr**2 + wd**2)), 1 / (4 * wd)]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(F @ Pi @ F.T + Qd, Pi, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("seed", SEEDS)
def test_van_loan_matches_quadrature(seed):
    rng = np.random.default_rng(1700 + seed)
    n, k = int(rng.integers(1, 6)), int(rng.integers(1, 3))
    A = rng.standard_normal((n, n))
    Qc, B = random_spd(rng, n), rng.standard_normal((n, k))
    dt = 10.0 ** rng.uniform(-2, 0)
    F, Qd, Bd = van_loan(A, Qc, dt, B)
    np.testing.assert_allclose(F, sl.expm(A * dt), rtol=1e-12, atol=1e-13 * np.linalg.norm(F))
    # (4.103) and the ZOH input, by adaptive quadrature of the integrands.
    Qd_quad = scipy.integrate.quad_vec(lambda t: sl.expm(A * t) @ Qc @ sl.expm(A * t).T, 0, dt, epsabs=0, epsrel=1e-13)[0]
    Bd_quad = scipy.integrate.quad_vec(lambda t: sl.expm(A * t) @ B, 0, dt, epsabs=0, epsrel=1e-13)[0]
    assert rel_err(Qd, Qd_quad) <= RTOL
    assert rel_err(Bd, Bd_quad) <= RTOL
    np.testing.assert_array_equal(Qd, Qd.T)


def test_first_order_is_the_small_dt_limit():
    # Qd - Qc dt = (A Qc + Qc A') dt^2 / 2 + O(dt^3)  (docs/algorithms.md, "First-order approximation")
    A, Qc = resonator(), np.diag([0.0, 1.0])
    lead = (A @ Qc + Qc @ A.T) / 2
    for dt in (1e-2, 1e-3, 1e-4):
        err = van_loan(A, Qc, dt)[1] - qd_first_order(A, Qc, dt)
        assert rel_err(err / dt**2, lead) <= 5 * dt * np.linalg.norm(A)
