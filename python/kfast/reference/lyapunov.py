"""Lyapunov equations in plain NumPy (docs/algorithms.md, "Lyapunov"): the test oracles, never the fast path.

SciPy's argument conventions, so the tests compare 1:1 with ``scipy.linalg``::

    discrete    a X a' - X + q = 0     (Söderström (4.9), (4.22)-(4.24): Pi = F Pi F' + Qd)
    continuous  a X + X a' = q         (note the sign: (4.90)-(4.92) is A Pi + Pi A' + Qc = 0,
                                        i.e. q = -Qc)

' is the conjugate transpose, so complex a and q work too.

The Kronecker forms solve an n^2 x n^2 linear system, O(n^6), which Söderström (Sec. 4.8.5)
rates far too large for real use: tests only, n up to about 12. The doubling (squared Smith)
iteration (4.194)-(4.195) is O(n^3 log log) but needs rho(a) < 1.
"""

from __future__ import annotations

import numpy as np


def _ct(M):
    """Conjugate transpose (plain transpose for real M)."""
    return M.conj().T


def _check_unique(pairs, what, tol):
    """Raise unless every entry of ``pairs`` (the eigenvalues of the Kronecker operator's
    defect, e.g. 1 - l_i conj(l_j)) is clearly nonzero."""
    if pairs.size and np.min(np.abs(pairs)) <= tol:
        raise ValueError(f"{what}: the Kronecker matrix is singular, no unique solution exists")


def solve_discrete_lyapunov_kron(a, q, tol=1e-8):
    """X with a X a' - X + q = 0 (scipy.linalg.solve_discrete_lyapunov), by vectorization.

    Row-major vec: vec(a X a') = (a kron conj(a)) vec(X), so (I - a kron conj(a)) vec X = vec q.
    Its eigenvalues are 1 - l_i conj(l_j): the solution is unique iff l_i conj(l_j) != 1
    (docs/algorithms.md, "Lyapunov"; for real a this is l_i l_j != 1). Raises ValueError otherwise (relative
    tolerance ``tol``, loose because a defective a has eigenvalues only to ~sqrt(eps)).
    """
    a, q = np.asarray(a), np.asarray(q)
    n = a.shape[0]
    lam = np.linalg.eigvals(a)
    prod = np.outer(lam, lam.conj())
    _check_unique((1 - prod) / np.maximum(1, np.abs(prod)), "discrete Lyapunov", tol)
    K = np.eye(n * n) - np.kron(a, a.conj())
    return np.linalg.solve(K, q.reshape(-1)).reshape(n, n)


def solve_continuous_lyapunov_kron(a, q, tol=1e-8):
    """X with a X + X a' = q (scipy.linalg.solve_continuous_lyapunov), by vectorization.

    Row-major vec: vec(a X) = (a kron I) vec X and vec(X a') = (I kron conj(a)) vec X. The
    eigenvalues of the sum are l_i + conj(l_j): unique iff l_i + conj(l_j) != 0 (Söderström
    (4.90)-(4.92)). Raises ValueError otherwise (tolerance relative to max|l|).
    """
    a, q = np.asarray(a), np.asarray(q)
    n = a.shape[0]
    lam = np.linalg.eigvals(a)
    scale = max(1.0, float(np.max(np.abs(lam)))) if n else 1.0
    _check_unique(np.add.outer(lam, lam.conj()) / scale, "continuous Lyapunov", tol)
    I = np.eye(n)
    K = np.kron(a, I) + np.kron(I, a.conj())
    return np.linalg.solve(K, q.reshape(-1)).reshape(n, n)


def discrete_lyapunov_doubling(a, q, tol=1e-16, max_iter=64):
    """X with a X a' - X + q = 0 by doubling (squared Smith), Söderström (4.194)-(4.195).

        P_0 = q, F_0 = a;   P_{k+1} = P_k + F_k P_k F_k',   F_{k+1} = F_k F_k
        P_k = sum_{j < 2^k} a^j q a'^j,   and exactly  X - P_k = F_k X F_k'   (ex. 4.15)

    So the relative error of P_k is at most ||F_k||^2; stop once ||F_k||_2^2 <= tol.
    Only for rho(a) < 1 (then X = sum_j a^j q a'^j); raises ValueError otherwise.
    """
    a, q = np.asarray(a), np.asarray(q)
    if a.size and np.max(np.abs(np.linalg.eigvals(a))) >= 1:
        raise ValueError("discrete_lyapunov_doubling needs rho(a) < 1 (no stationary solution)")
    P, F = q.copy(), a.copy()
    for _ in range(max_iter):
        if not F.size or np.linalg.norm(F, 2) ** 2 <= tol:
            return P
        P = P + F @ P @ _ct(F)
        F = F @ F
    raise RuntimeError("discrete_lyapunov_doubling did not converge (rho(a) too close to 1)")
