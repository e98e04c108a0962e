"""Riccati, Lyapunov and matrix-exponential solvers against SciPy, python-control/slycot and
each other, on 200+ seeded random systems; relative residuals <= 1e-10; failures raise."""

import control
import numpy as np
import pytest
import scipy.linalg as sl
import slycot  # noqa: F401  (python-control uses it for dare/care with S and E)

import kfast
from kfast.riccati.solvers import care, dare

METHODS = ["doubling", "newton", "iteration", "eigen"]


def controllable_enough(a, b, e=None):
    """Keeps random systems away from near-uncontrollable ones (ill-posed for every solver)."""
    n = len(a)
    e = np.eye(n) if e is None else e
    lam = np.linalg.eigvals(np.linalg.solve(e, a))
    return min(np.linalg.svd(np.hstack([l * e - a, b]), compute_uv=False)[-1] for l in lam) > 0.05


def random_system(seed):
    """(a, b, q, r, e, s): n 1-12, m 1-4, a of spectral radius 0.3-1.5 (unstable too), s and e
    on a third of the systems each."""
    rng = np.random.default_rng(seed)
    while True:
        n, m = int(rng.integers(1, 13)), int(rng.integers(1, 5))
        a = rng.standard_normal((n, n))
        a *= rng.uniform(0.3, 1.5) / max(1e-9, max(abs(np.linalg.eigvals(a))))
        b = rng.standard_normal((n, m))
        q = rng.standard_normal((n, n))
        q = q @ q.T + 0.1 * np.eye(n)
        r = rng.standard_normal((m, m))
        r = r @ r.T + 0.5 * np.eye(m)
        s = 0.1 * rng.standard_normal((n, m)) if seed % 3 == 1 else None
        e = np.eye(n) + 0.1 * rng.standard_normal((n, n)) if seed % 3 == 2 else None
        if controllable_enough(a, b, e):
            return a, b, q, r, e, s


def dare_residual(a, b, q, r, e, s, X):
    e = np.eye(len(a)) if e is None else e
    s = np.zeros(b.shape) if s is None else s
    R = a.T @ X @ a - e.T @ X @ e - (a.T @ X @ b + s) @ np.linalg.solve(b.T @ X @ b + r, b.T @ X @ a + s.T) + q
    return np.abs(R).max() / max(1.0, np.abs(X).max())


def care_residual(a, b, q, r, e, s, X):
    e = np.eye(len(a)) if e is None else e
    s = np.zeros(b.shape) if s is None else s
    R = a.T @ X @ e + e.T @ X @ a - (e.T @ X @ b + s) @ np.linalg.solve(r, b.T @ X @ e + s.T) + q
    return np.abs(R).max() / max(1.0, np.abs(X).max())


def close(got, want, rtol):
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * np.abs(want).max())


@pytest.mark.parametrize("seed", range(210))
def test_dare_agrees_with_scipy_and_across_methods(seed):
    a, b, q, r, e, s = random_system(seed)
    # SciPy 1.17 balances e inconsistently (wrong X on ~10% of systems with e): use balanced=False.
    want = sl.solve_discrete_are(a, b, q, r, e=e, s=s, balanced=False)
    # Where SciPy's own residual is poor (ill-conditioned X), compare only as far as it goes.
    rtol = max(1e-8, 1e3 * dare_residual(a, b, q, r, e, s, want))
    for method in METHODS:
        sol = dare(a, b, q, r, e=e, s=s, method=method)
        close(sol["x"], want, rtol)
        assert dare_residual(a, b, q, r, e, s, sol["x"]) <= 1e-10, method
        assert sol["residual"] <= 1e-10
        assert np.abs(sol["closed_loop_eigenvalues"]).max() < 1
    x = kfast.solve_discrete_are(a, b, q, r, e=e, s=s)
    np.testing.assert_array_equal(x, x.T)


@pytest.mark.parametrize("seed", range(210))
def test_care_agrees_with_scipy(seed):
    a, b, q, r, e, s = random_system(seed)
    want = sl.solve_continuous_are(a, b, q, r, e=e, s=s, balanced=False)
    sol = care(a, b, q, r, e=e, s=s)
    close(sol["x"], want, max(1e-8, 1e3 * care_residual(a, b, q, r, e, s, want)))
    assert care_residual(a, b, q, r, e, s, sol["x"]) <= 1e-10
    assert np.real(sol["closed_loop_eigenvalues"]).max() < 0


@pytest.mark.parametrize("seed", range(30))
def test_riccati_agrees_with_python_control_and_slycot(seed):
    a, b, q, r, e, s = random_system(seed)
    X, _, _ = control.dare(a, b, q, r, S=s, E=e)
    close(kfast.solve_discrete_are(a, b, q, r, e=e, s=s), X, 1e-8)
    Xc, _, _ = control.care(a, b, q, r, S=s, E=e)
    close(kfast.solve_continuous_are(a, b, q, r, e=e, s=s), Xc, 1e-8)


@pytest.mark.parametrize("seed", range(210))
def test_lyapunov_agrees_with_scipy(seed):
    rng = np.random.default_rng(10_000 + seed)
    n = int(rng.integers(1, 25))
    a = rng.standard_normal((n, n))
    a *= rng.uniform(0.2, 1.6) / max(1e-9, max(abs(np.linalg.eigvals(a))))  # unstable but unique too
    q = rng.standard_normal((n, n))
    q = q @ q.T if seed % 2 else q  # general q too
    lam = np.linalg.eigvals(a)
    if np.abs(1 - np.outer(lam, lam)).min() > 1e-3:
        X = kfast.solve_discrete_lyapunov(a, q)
        close(X, sl.solve_discrete_lyapunov(a, q), 1e-8)
        assert np.abs(a @ X @ a.T - X + q).max() / max(1, np.abs(X).max()) <= 1e-10
    if np.abs(np.add.outer(lam, lam)).min() > 1e-3:
        X = kfast.solve_continuous_lyapunov(a, q)
        close(X, sl.solve_continuous_lyapunov(a, q), 1e-8)
        assert np.abs(a @ X + X @ a.T - q).max() / max(1, np.abs(X).max()) <= 1e-10


@pytest.mark.parametrize("seed", range(210))
def test_expm_agrees_with_scipy(seed):
    rng = np.random.default_rng(20_000 + seed)
    n = int(rng.integers(1, 20))
    a = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-3, 1.5) / np.sqrt(n)
    close(kfast.expm(a), sl.expm(a), 1e-10)


def test_solvers_are_fast_enough_to_be_direct():
    """n = 100 in one call (Bartels-Stewart, doubling): a smoke test of scale, not of time."""
    rng = np.random.default_rng(0)
    a = rng.standard_normal((100, 100))
    a *= 0.95 / max(abs(np.linalg.eigvals(a)))
    b = rng.standard_normal((100, 50))
    X = kfast.solve_discrete_are(a, b, np.eye(100), np.eye(50))
    assert dare_residual(a, b, np.eye(100), np.eye(50), None, None, X) <= 1e-10
    Y = kfast.solve_discrete_lyapunov(a, np.eye(100))
    assert np.abs(a @ Y @ a.T - Y + np.eye(100)).max() / np.abs(Y).max() <= 1e-10


@pytest.mark.parametrize("seed", range(8))
def test_doubling_above_the_small_kernels_agrees_with_scipy(seed):
    """n = 13-60: the doubling's symmetric updates as faer triangle products, the step that
    would only confirm convergence skipped; the stabilizing check of solve_discrete_are by
    powers of the closed loop, of dare() by its eigenvalues (which must agree with NumPy's)."""
    rng = np.random.default_rng(400 + seed)
    n = int(rng.integers(13, 61))
    m = int(rng.integers(1, n // 2 + 1))
    a = rng.standard_normal((n, n))
    a *= rng.uniform(0.5, 1.3) / max(abs(np.linalg.eigvals(a)))
    b = rng.standard_normal((n, m))
    c = rng.standard_normal((n, n))
    q, r = c @ c.T / n + 0.1 * np.eye(n), np.eye(m)
    want = sl.solve_discrete_are(a, b, q, r)
    x = kfast.solve_discrete_are(a, b, q, r)
    close(x, want, max(1e-9, 1e3 * dare_residual(a, b, q, r, None, None, want)))
    assert dare_residual(a, b, q, r, None, None, x) <= 1e-12
    sol = dare(a, b, q, r)
    np.testing.assert_array_equal(sol["x"], x)
    K = sol["gain"]
    np.testing.assert_allclose(np.sort_complex(sol["closed_loop_eigenvalues"]), np.sort_complex(np.linalg.eigvals(a - b @ K)), atol=1e-9)


def test_stabilizing_check_falls_back_to_eigenvalues_near_the_unit_circle():
    """A closed loop of radius ~0.999 (a nearly uncontrollable slow mode): no power up to 64
    has norm below 1/2, so the eigenvalues decide, and the answer is still the stabilizing X."""
    a = np.diag([0.999, 0.5, -0.3])
    b = np.array([[1e-4], [1.0], [0.5]])
    q, r = np.eye(3), np.eye(1)
    want = sl.solve_discrete_are(a, b, q, r)
    sol = dare(a, b, q, r)
    close(sol["x"], want, 1e-9)
    assert 0.99 < np.abs(sol["closed_loop_eigenvalues"]).max() < 1
    close(kfast.solve_discrete_are(a, b, q, r), want, 1e-9)


def ill_conditioned_dare(seed, n=7):
    """r = 1e-6, a with a zero column and spectral radius above 1, q of rank one: doubling
    alone leaves a relative residual of 1e-3 to 1e-7 on such problems."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n)) * 1.5
    a[:, 0] = 0
    b = rng.normal(size=(n, 1))
    q = np.zeros((n, n))
    q[0, 0] = 1.0
    return a, b, q, np.eye(1) * 1e-6


@pytest.mark.parametrize("seed", range(12))
def test_doubling_is_refined_on_ill_conditioned_problems(seed):
    a, b, q, r = ill_conditioned_dare(seed)
    sol = dare(a, b, q, r)
    assert dare_residual(a, b, q, r, None, None, sol["x"]) <= 1e-10
    assert sol["residual"] <= 1e-10
    # Residuals at rounding level pin X only to about 1e-7 relative here (X ~ 1e8 with r = 1e-6:
    # methods and SciPy, whose residual is 1e-7, differ by that much).
    np.testing.assert_allclose(sol["x"], dare(a, b, q, r, method="newton")["x"], rtol=1e-6, atol=1e-6 * np.abs(sol["x"]).max())


def test_no_stabilizing_solution_raises():
    # (a, b) not stabilizable: an unstable mode the input cannot reach.
    a = np.diag([2.0, 0.5])
    b = np.array([[0.0], [1.0]])
    for method in METHODS:
        with pytest.raises(kfast.NoStabilizingSolutionError, match="no stabilizing solution"):
            kfast.solve_discrete_are(a, b, np.eye(2), np.eye(1), method=method)
    with pytest.raises(kfast.NoStabilizingSolutionError):
        kfast.solve_continuous_are(np.diag([1.0, -1.0]), b, np.eye(2), np.eye(1))
    assert issubclass(kfast.NoStabilizingSolutionError, ValueError)


def test_unit_circle_mode_without_noise_is_not_stabilizing():
    """A random walk with no process noise has the maximal solution P = 0 with F - K H = 1:
    not stabilizing (failure mode 1 in docs/algorithms.md, "Stabilizing solution"); kfast raises
    instead of returning it."""
    with pytest.raises(kfast.NoStabilizingSolutionError):
        kfast.solve_discrete_are([[1.0]], [[1.0]], [[0.0]], [[1.0]])


def test_lyapunov_without_unique_solution_raises():
    with pytest.raises(kfast.KfastError, match=r"^a: the Lyapunov equation has no unique solution: two eigenvalues of a have λ_i λ_j = 1"):
        kfast.solve_discrete_lyapunov(np.diag([2.0, 0.5]), np.eye(2))
    with pytest.raises(kfast.KfastError, match=r"^a: the Lyapunov equation has no unique solution: two eigenvalues of a have λ_i \+ λ_j = 0"):
        kfast.solve_continuous_lyapunov(np.diag([1.0, -1.0]), np.eye(2))


def test_solver_bad_arguments():
    with pytest.raises(kfast.KfastError, match=r"^b: expected 2 rows like a"):
        kfast.solve_discrete_are(np.eye(2), np.ones((3, 1)), np.eye(2), np.eye(1))
    with pytest.raises(kfast.KfastError, match=r"^q: not symmetric"):
        kfast.solve_discrete_are(np.eye(2), np.ones((2, 1)), [[1.0, 2.0], [0.0, 1.0]], np.eye(1))
    with pytest.raises(kfast.KfastError, match=r"^e: must be nonsingular"):
        kfast.solve_discrete_are(np.eye(2), np.ones((2, 1)), np.eye(2), np.eye(1), e=np.zeros((2, 2)))
    with pytest.raises(kfast.KfastError, match=r"^method: expected one of"):
        kfast.solve_discrete_are(np.eye(2), np.ones((2, 1)), np.eye(2), np.eye(1), method="qz")
    with pytest.raises(kfast.KfastError, match=r"^r: must be invertible for method \"eigen\""):
        kfast.solve_discrete_are(np.eye(2), np.ones((2, 1)), np.eye(2), np.zeros((1, 1)), method="eigen")
    # Complex input is solved (tests/riccati/test_complex_generalized.py); a = i I makes
    # a X a^H - X = 0 singular.
    with pytest.raises(kfast.KfastError, match=r"^a: the Lyapunov equation has no unique solution"):
        kfast.solve_discrete_lyapunov(np.eye(2) * 1j, np.eye(2))
    with pytest.raises(kfast.KfastError, match=r"^a: contains a non-finite value"):
        kfast.expm([[np.nan]])
    with pytest.raises(kfast.KfastError, match=r"^dt at step 1: must be positive"):
        kfast.discretize(np.eye(2), np.eye(2), [0.1, -0.1])
