"""Complex Riccati and Lyapunov equations (through the real embedding) and generalized
Lyapunov equations (E != I): SciPy's complex DAREX cases 0-2 with SciPy's tolerances, SciPy's
own complex solvers, python-control's generalized lyap/dlyap (SLICOT), and residuals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import kfast
from kfast.riccati.solvers import care, dare

# SciPy's TestSolveDiscreteAre cases 0-2 (scipy/linalg/tests/test_solvers.py) with its
# tolerances 1.5 * 10^-min_decimal: (a, b, q, r, atol).
COMPLEX_DAREX = [
    (np.array([[2, 1 - 2j], [0, -3j]]), np.array([[0], [1]]), np.array([[1, 0], [0, 2]]), np.array([[1]]), 1.5e-12),
    (np.array([[2, 1], [0, -1]]), np.array([[-2j], [1j]]), np.array([[1, 0], [0, 2]]), np.array([[1]]), 1.5e-14),
    (
        np.array([[3, 1], [0, -1]]),
        np.array([[1, 2], [1, 3]]),
        np.array([[1, 1 + 1j], [1 - 1j, 2]]),
        np.array([[2, -2j], [2j, 3]]),
        1.5e-13,
    ),
]


def dare_residual(a, b, q, r, x):
    ah = a.conj().T
    return ah @ x @ a - x - ah @ x @ b @ np.linalg.solve(r + b.conj().T @ x @ b, b.conj().T @ x @ a) + q


@pytest.mark.parametrize("case", range(3))
@pytest.mark.parametrize("method", ["doubling", "newton", "iteration", "eigen"])
def test_complex_darex_cases(case, method):
    a, b, q, r, atol = COMPLEX_DAREX[case]
    x = kfast.solve_discrete_are(a, b, q, r, method=method)
    assert x.dtype == np.complex128
    np.testing.assert_allclose(x, x.conj().T, atol=1e-14 * np.abs(x).max())
    np.testing.assert_allclose(dare_residual(a, b, q, r, x), 0, atol=atol)
    np.testing.assert_allclose(x, sla.solve_discrete_are(a, b, q, r), rtol=1e-10, atol=1e-12)
    details = dare(a, b, q, r, method=method)
    assert np.abs(details["closed_loop_eigenvalues"]).max() < 1
    np.testing.assert_allclose(details["closed_loop_eigenvalues"], np.linalg.eigvals(a - b @ details["gain"]))


def random_complex(rng, *shape):
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


@pytest.mark.parametrize("seed", range(6))
def test_complex_care_and_dare_equal_scipy(seed):
    rng = np.random.default_rng(seed)
    n, k = 4, 2
    a, b = 0.6 * random_complex(rng, n, n), random_complex(rng, n, k)
    c = random_complex(rng, n, n)
    q = c @ c.conj().T + np.eye(n)
    d = random_complex(rng, k, k)
    r = d @ d.conj().T + np.eye(k)
    np.testing.assert_allclose(kfast.solve_continuous_are(a, b, q, r), sla.solve_continuous_are(a, b, q, r), rtol=1e-9)
    np.testing.assert_allclose(kfast.solve_discrete_are(a, b, q, r), sla.solve_discrete_are(a, b, q, r), rtol=1e-9)
    # With e and s as well.
    e = np.eye(n) + 0.1 * random_complex(rng, n, n)
    s = 0.1 * random_complex(rng, n, k)
    # Residuals and stability, not SciPy: its complex solvers with e and s report the pencils
    # of some of these as too close to the unit circle / imaginary axis (kfast's closed loops
    # keep a margin of 0.7 and more).
    x = kfast.solve_discrete_are(a, b, q, r, e=e, s=s)
    ah, bh = a.conj().T, b.conj().T
    res = ah @ x @ a - e.conj().T @ x @ e - (ah @ x @ b + s) @ np.linalg.solve(bh @ x @ b + r, bh @ x @ a + s.conj().T) + q
    assert np.abs(res).max() < 1e-10 * np.abs(x).max()
    gain = np.linalg.solve(bh @ x @ b + r, bh @ x @ a + s.conj().T)
    assert np.abs(np.linalg.eigvals(np.linalg.solve(e.T, (a - b @ gain).T).T)).max() < 1
    xc = kfast.solve_continuous_are(a, b, q, r, e=e, s=s)
    eh = e.conj().T
    res = ah @ xc @ e + eh @ xc @ a - (eh @ xc @ b + s) @ np.linalg.solve(r, bh @ xc @ e + s.conj().T) + q
    assert np.abs(res).max() < 1e-10 * np.abs(xc).max()
    gain = np.linalg.solve(r, bh @ xc @ e + s.conj().T)
    assert np.linalg.eigvals(np.linalg.solve(e, a - b @ gain)).real.max() < 0
    closed = care(a, b, q, r)["closed_loop_eigenvalues"]
    assert closed.real.max() < 0


def test_complex_riccati_refuses_non_hermitian_q():
    a, b, q, r, _ = COMPLEX_DAREX[2]
    with pytest.raises(ValueError, match="q: must be Hermitian"):
        kfast.solve_discrete_are(a, b, q + 1j * np.eye(2), r)


# SciPy's TestSolveLyapunov cases with complex entries (scipy/linalg/tests/test_solvers.py).
COMPLEX_LYAPUNOV = [
    (np.array([[1.0 + 1j, 2.0], [3.0 - 4.0j, 5.0]]), np.array([[2.0 - 2j, 2.0 + 2j], [-1.0 - 1j, 2.0]])),
    (np.array([[1.0, 2.0], [3.0, 5.0]]), np.array([[2.0 - 2j, 2.0 + 2j], [-1.0 - 1j, 2.0]])),
    (np.array([[1.0 + 1j, 2.0], [3.0 - 4.0j, 5.0]]), np.array([[2.0, 2.0], [-1.0, 2.0]])),
]


@pytest.mark.parametrize("case", range(3))
def test_complex_continuous_lyapunov_equals_scipy(case):
    a, q = COMPLEX_LYAPUNOV[case]
    x = kfast.solve_continuous_lyapunov(a, q)
    np.testing.assert_allclose(a @ x + x @ a.conj().T, q, atol=1e-12)
    np.testing.assert_allclose(x, sla.solve_continuous_lyapunov(a, q), rtol=1e-10)


@pytest.mark.parametrize("case", range(3))
def test_complex_discrete_lyapunov_equals_scipy(case):
    a, q = COMPLEX_LYAPUNOV[case]
    a = 0.15 * a  # stable: |lambda| < 1
    x = kfast.solve_discrete_lyapunov(a, q)
    np.testing.assert_allclose(a @ x @ a.conj().T - x + q, 0, atol=1e-12)
    np.testing.assert_allclose(x, sla.solve_discrete_lyapunov(a, q), rtol=1e-10)


@pytest.mark.parametrize("seed", range(5))
def test_generalized_lyapunov_equals_python_control(seed):
    control = pytest.importorskip("control")
    rng = np.random.default_rng(10 + seed)
    n = 5
    a = rng.standard_normal((n, n)) - 3 * np.eye(n)
    e = np.eye(n) + 0.3 * rng.standard_normal((n, n))
    c = rng.standard_normal((n, n))
    Q = c @ c.T
    # python-control: A X E' + E X A' + Q = 0 and A X A' - E X E' + Q = 0.
    x = kfast.solve_continuous_lyapunov(a, -Q, e=e)
    np.testing.assert_allclose(a @ x @ e.T + e @ x @ a.T + Q, 0, atol=1e-10 * np.abs(Q).max())
    np.testing.assert_allclose(x, control.lyap(a, Q, E=e), rtol=1e-8, atol=1e-10)
    ad = 0.2 * rng.standard_normal((n, n))
    xd = kfast.solve_discrete_lyapunov(ad, Q, e=e)
    np.testing.assert_allclose(ad @ xd @ ad.T - e @ xd @ e.T + Q, 0, atol=1e-10 * np.abs(Q).max())
    np.testing.assert_allclose(xd, control.dlyap(ad, Q, E=e), rtol=1e-8, atol=1e-10)


def test_complex_generalized_lyapunov_residual():
    rng = np.random.default_rng(3)
    n = 3
    a = random_complex(rng, n, n) - 4 * np.eye(n)
    e = np.eye(n) + 0.2 * random_complex(rng, n, n)
    q = random_complex(rng, n, n)
    x = kfast.solve_continuous_lyapunov(a, q, e=e)
    np.testing.assert_allclose(a @ x @ e.conj().T + e @ x @ a.conj().T, q, atol=1e-11)


def test_singular_e_is_refused():
    with pytest.raises(ValueError, match="e: must be nonsingular"):
        kfast.solve_discrete_lyapunov(np.eye(2) * 0.5, np.eye(2), e=np.ones((2, 2)))
    with pytest.raises(ValueError, match="e: expected shape"):
        kfast.solve_continuous_lyapunov(-np.eye(2), np.eye(2), e=np.eye(3))
