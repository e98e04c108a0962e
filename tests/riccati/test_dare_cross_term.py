"""DARE problems with a cross term s that have a stabilizing solution the default solvers once
refused (issue 9), against SciPy (balanced=False: see docs/decisions.md), python-control and
closed forms; tests/data/dare_cross_term.json names the sources.

(a) q - s r^-1 s' = 0 with a - b r^-1 s' unstable: the Kalman filter of an ARMA model whose
    noise polynomial C has zeros outside the unit circle (Söderström ex. 7.1 and variants).
    Doubling from zero stays at the non-stabilizing fixed point X = 0.
(b) python-control's test_dare_g2: e and s given, q - s r^-1 s' indefinite; doubling diverged.
"""

import json
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.linalg as sl

import kfast
from kfast.riccati.solvers import dare

CASES = json.loads((Path(__file__).parent.parent / "data" / "dare_cross_term.json").read_text())
METHODS = ["doubling", "newton", "iteration", "eigen"]


def arma_observer(a, c, lambda2=1.0):
    """(F, H, Q, R, N) of A(q) y = C(q) e, A = q^n + a1 q^(n-1) + ..., C likewise, var e =
    lambda2, in observer form: x(t+1) = F x(t) + k e(t), y(t) = H x(t) + e(t), F with first
    column -a and ones above the diagonal, k = c - a, H = [1, 0, ..., 0]."""
    a, c = np.asarray(a, float), np.asarray(c, float)
    n = len(a)
    F = np.zeros((n, n))
    F[:, 0] = -a
    F[: n - 1, 1:] = np.eye(n - 1)
    k = (c - a)[:, None]
    return F, np.eye(1, n), lambda2 * k @ k.T, np.array([[lambda2]]), lambda2 * k


def dare_residual(a, b, q, r, e, s, X):
    e = np.eye(len(a)) if e is None else e
    s = np.zeros(b.shape) if s is None else s
    R = a.T @ X @ a - e.T @ X @ e - (a.T @ X @ b + s) @ np.linalg.solve(b.T @ X @ b + r, b.T @ X @ a + s.T) + q
    return np.abs(R).max() / max(1.0, np.abs(X).max())


def closed_loop_radius(a, b, r, e, s, X):
    e = np.eye(len(a)) if e is None else e
    s = np.zeros(b.shape) if s is None else s
    G = np.linalg.solve(b.T @ X @ b + r, b.T @ X @ a + s.T)
    return np.abs(sl.eigvals(a - b @ G, e)).max()


def close(got, want, rtol):
    want = np.asarray(want, float)
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * max(1.0, np.abs(want).max()))


# ---------------------------------------------------------------------------------------------
# (a) ARMA models with a noise polynomial that is not invertible


@pytest.mark.parametrize("method", METHODS)
def test_textbook_noninvertible_arma(method):
    case = CASES["arma_noninvertible"]
    F, H, Q, R, N = arma_observer(case["a"], case["c"], case["lambda2"])
    want, tol = case["expected"], case["expected"]["tol"]
    np.testing.assert_allclose(Q - N @ np.linalg.solve(R, N.T), 0.0, atol=1e-15)  # nothing left to decorrelate
    sol = dare(F.T, H.T, Q, R, s=N, method=method)
    close(sol["x"], want["P_pred"], tol)
    close(sol["gain"].T, want["K_pred"], tol)
    close(sol["closed_loop_eigenvalues"], want["closed_loop_eigenvalues"], tol)
    assert sol["residual"] <= 1e-14
    close(sol["x"], sl.solve_discrete_are(F.T, H.T, Q, R, s=N, balanced=False), tol)


def test_textbook_noninvertible_arma_innovations_form():
    """The steady-state filter is the book's invertible form C = 1 + 0.5 q^-1, innovation
    variance 4, and the two-step prediction error variance is 10.76."""
    case = CASES["arma_noninvertible"]
    want = case["expected"]
    F, H, Q, R, N = arma_observer(case["a"], case["c"], case["lambda2"])
    model = kfast.LinearGaussian(F, H, Q, R, N=N)
    ss = model.steady_state()
    close(ss.P_pred, want["P_pred"], 1e-12)
    close(ss.S, want["S"], 1e-12)
    close(ss.K_pred, want["K_pred"], 1e-12)
    inn = model.innovations_form()
    close(np.poly(inn.F - inn.K_pred @ inn.H), want["invertible_C"], 1e-12)
    # From the stationary x(t+1|t) with covariance P_pred: y(t+2) has covariance H (F P F' + Q) H' + R.
    forecast = model.forecast(np.zeros(1), ss.P_pred, steps=2)
    close(forecast.y_cov[1], [[want["two_step_prediction_error_variance"]]], 1e-12)


def reflected_zeros(c):
    """The zeros of C (q^n + c1 q^(n-1) + ...) with those outside the unit circle replaced by
    1/conj(z), and how many were outside."""
    z = np.roots(np.r_[1.0, c])
    outside = np.abs(z) > 1
    reflected = z.astype(complex)
    reflected[outside] = 1 / np.conj(z[outside])
    return reflected, z[outside]


VARIANTS = [
    # (a, c, lambda2): zeros of C
    ([-0.8], [2.0], 1.0),  # the book's -2
    ([-0.8], [2.0], 2.5),  # scaled noise
    ([-1.5], [2.0], 1.0),  # unstable A: no stable start gain K = 0
    ([-0.5, 0.06], [-1.5, -1.0], 1.0),  # 2 and -0.5: P of rank 1
    ([-0.5, 0.0], [2.5, 0.0], 1.0),  # -2.5 and 0: F - N R^-1 H singular, P of rank 1
    ([-0.5, 0.0, 0.0], [2.5, 0.0, 0.0], 0.7),  # -2.5 and a double 0 (defective), P of rank 1
    ([0.1, -0.2, 0.3], [0.5, 1.0, 3.0], 1.0),  # a complex pair and a real zero, all outside
    ([-1.2, 0.5], [0.4, 4.0], 3.0),  # a complex pair outside, |z| = 2
    ([-0.9, 0.2, 0.1], [-1.1, -3.3, 0.9], 1.0),  # 2.39, -1.60, 0.24 (two outside)
]


@pytest.mark.parametrize("a, c, lambda2", VARIANTS)
@pytest.mark.parametrize("method", METHODS)
def test_noninvertible_arma_variants(a, c, lambda2, method):
    """Closed forms of the spectral factorization (Söderström Thm 4.2): the steady-state filter
    has the zeros of C with those outside the circle reflected, innovation variance lambda2
    times the product of |z|^2 over those zeros, and P_pred of rank their number."""
    F, H, Q, R, N = arma_observer(a, c, lambda2)
    sol = dare(F.T, H.T, Q, R, s=N, method=method)
    P = sol["x"]
    close(P, sl.solve_discrete_are(F.T, H.T, Q, R, s=N, balanced=False), 1e-9)
    assert dare_residual(F.T, H.T, Q, R, None, N, P) <= 1e-12
    stable_zeros, outside = reflected_zeros(c)
    np.testing.assert_allclose(np.sort_complex(sol["closed_loop_eigenvalues"]), np.sort_complex(stable_zeros), atol=1e-7)
    close(H @ P @ H.T + R, [[lambda2 * np.prod(np.abs(outside) ** 2)]], 1e-10)
    eig_P = np.linalg.eigvalsh(P)
    assert np.sum(eig_P > 1e-9 * eig_P.max()) == len(outside)
    assert eig_P.min() >= -1e-9 * eig_P.max()


def test_unit_circle_noise_zero_has_no_stabilizing_solution():
    """C = q + 1 has its zero on the circle: the spectral density vanishes at w = pi and only a
    maximal, non-stabilizing solution exists (closed loop -1). Every method must raise, the
    fallbacks included."""
    F, H, Q, R, N = arma_observer([-0.5], [1.0])
    for method in METHODS:
        with pytest.raises(kfast.NoStabilizingSolutionError, match="no stabilizing solution"):
            dare(F.T, H.T, Q, R, s=N, method=method)


def test_not_stabilizable_with_cross_term_raises():
    # The unstable mode 2 is not reached by b: no gain stabilizes it, whatever s is.
    a, b = np.diag([2.0, 0.5]), np.array([[0.0], [1.0]])
    s = np.array([[0.3], [0.2]])
    for method in METHODS:
        with pytest.raises(kfast.NoStabilizingSolutionError):
            dare(a, b, np.eye(2), np.eye(1), s=s, method=method)


# ---------------------------------------------------------------------------------------------
# (b) e and s with q - s r^-1 s' indefinite


def g2():
    case = CASES["python_control_dare_g2"]
    return tuple(np.array(case[k], float) for k in ("a", "b", "q", "r", "e", "s"))


@pytest.mark.parametrize("method", METHODS)
def test_python_control_dare_g2(method):
    a, b, q, r, e, s = g2()
    assert np.linalg.eigvalsh(q - s @ np.linalg.solve(r, s.T)).min() < 0  # indefinite
    sol = dare(a, b, q, r, e=e, s=s, method=method)
    X = sol["x"]
    close(X, sl.solve_discrete_are(a, b, q, r, e=e, s=s, balanced=False), 1e-10)
    close(X, control.dare(a, b, q, r, S=s, E=e)[0], 1e-8)
    # python-control's own checks (to its 6 decimals; here to rounding).
    lhs = e.T @ X @ e
    rhs = a.T @ X @ a - (a.T @ X @ b + s) @ np.linalg.solve(b.T @ X @ b + r, b.T @ X @ a + s.T) + q
    close(lhs, rhs, 1e-12)
    G = np.linalg.solve(b.T @ X @ b + r, b.T @ X @ a + s.T)
    close(sol["gain"], G, 1e-12)
    assert np.abs(sl.eigvals(a - b @ G, e)).max() < 1


def indefinite_system(seed):
    """A random DARE with r > 0 but q - s r^-1 s' indefinite (e on half of the systems) that
    has a stabilizing solution by SciPy's account (residual at rounding level, closed loop
    clear of the unit circle)."""
    rng = np.random.default_rng(7000 + seed)
    while True:
        n, m = int(rng.integers(1, 6)), int(rng.integers(1, 4))
        a = rng.standard_normal((n, n))
        a *= rng.uniform(0.3, 1.5) / max(1e-9, max(abs(np.linalg.eigvals(a))))
        b = rng.standard_normal((n, m))
        q = rng.standard_normal((n, n))
        q = (q + q.T) / 2 + rng.uniform(0, 2) * np.eye(n)
        r = rng.standard_normal((m, m))
        r = r @ r.T + 0.5 * np.eye(m)
        s = rng.standard_normal((n, m))
        e = np.eye(n) + 0.2 * rng.standard_normal((n, n)) if seed % 2 else None
        if np.linalg.eigvalsh(q - s @ np.linalg.solve(r, s.T)).min() >= 0:
            continue
        try:
            X = sl.solve_discrete_are(a, b, q, r, e=e, s=s, balanced=False)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if dare_residual(a, b, q, r, e, s, X) <= 1e-11 and closed_loop_radius(a, b, r, e, s, X) < 0.999:
            return a, b, q, r, e, s, X


@pytest.mark.parametrize("seed", range(40))
def test_indefinite_cross_term_systems_are_solved(seed):
    """Never refuse a solvable problem: every method finds SciPy's stabilizing solution."""
    a, b, q, r, e, s, want = indefinite_system(seed)
    rtol = max(1e-8, 1e3 * dare_residual(a, b, q, r, e, s, want))
    for method in METHODS:
        sol = dare(a, b, q, r, e=e, s=s, method=method)
        close(sol["x"], want, rtol)
        assert dare_residual(a, b, q, r, e, s, sol["x"]) <= 1e-10, method
        assert np.abs(sol["closed_loop_eigenvalues"]).max() < 1


def test_the_solution_names_the_method_that_produced_it():
    # Doubling from zero stops at the non-stabilizing X = 0 here; a fallback produced X.
    F, H, Q, R, N = arma_observer(CASES["arma_noninvertible"]["a"], CASES["arma_noninvertible"]["c"])
    assert dare(F.T, H.T, Q, R, s=N)["method"] in ("newton", "pencil")
    # An ordinary problem is solved by the method asked for.
    assert dare(np.array([[0.5]]), np.eye(1), np.eye(1), np.eye(1))["method"] == "doubling"
    assert dare(np.array([[0.5]]), np.eye(1), np.eye(1), np.eye(1), method="eigen")["method"] == "eigen"
