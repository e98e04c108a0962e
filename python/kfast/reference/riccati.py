"""Algebraic Riccati equations in plain NumPy: the test oracles, never the fast path
(docs/algorithms.md, "Riccati equations").

SciPy's conventions and argument order (real matrices)::

    DARE  a'Xa - e'Xe - (a'Xb + s)(b'Xb + r)^-1 (b'Xa + s') + q = 0     solve_discrete_are
    CARE  a'Xe + e'Xa - (e'Xb + s) r^-1 (b'Xe + s') + q = 0            solve_continuous_are

The Kalman filter's stationary P(t|t-1) (Söderström (6.91), (4.48)) is the DARE with
a = F', b = H', q = Q, r = R, s = N, e = I; its gain (b'Xb + r)^-1 (b'Xa + s') is K_pred'.

Reductions used by the eigenvector methods (derived; checked against SciPy in the tests):

* s (Lemma 6.4 in control notation): with a~ = a - b r^-1 s' and q~ = q - s r^-1 s' the s terms
  disappear, because (a'Xb + s) r^-1 (b'Xa + s') expands into the cross terms of a~.
* e (invertible): multiply the equation by e^-T on the left and e^-1 on the right. The same X
  solves the e = I equation with a -> a e^-1, q -> e^-T q e^-1, s -> e^-T s (b and r unchanged).
  So e only right-multiplies a, and congruence-transforms q and s.
"""

from __future__ import annotations

import numpy as np


def _sym(X):
    return (X + X.T) / 2


def _defaults(a, b, q, r, e, s):
    a, b, q, r = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (a, b, q, r))
    n, m = b.shape
    e = np.eye(n) if e is None else np.asarray(e, dtype=float)
    s = np.zeros((n, m)) if s is None else np.asarray(s, dtype=float)
    return a, b, q, r, e, s


def _remove_e(a, q, s, e):
    """(a e^-1, e^-T q e^-1, e^-T s): the e = I problem with the same X (module docstring)."""
    ei = np.linalg.inv(e)
    return a @ ei, ei.T @ q @ ei, ei.T @ s


def _remove_s(a, b, q, r, s):
    """(a~, q~) = (a - b r^-1 s', q - s r^-1 s'), the s = 0 problem (Lemma 6.4;
    docs/algorithms.md, "Correlated noise")."""
    rs = np.linalg.solve(r, s.T)  # r^-1 s'
    return a - b @ rs, q - s @ rs


def dare_gain(a, b, r, X, s=None):
    """K = (b'Xb + r)^-1 (b'Xa + s')  (= K_pred' in the Kalman mapping, (6.25))."""
    a, b, r = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (a, b, r))
    s = np.zeros(b.shape) if s is None else np.asarray(s, dtype=float)
    return np.linalg.solve(b.T @ X @ b + r, b.T @ X @ a + s.T)


def dare_closed_loop_eigenvalues(a, b, r, s, X, e=None):
    """eig(a - bK), K = dare_gain (the Kalman filter's eig(F - K_pred H), Söderström (4.55)); with e, the
    generalized eigenvalues eig((a - bK) e^-1)."""
    a, b = np.atleast_2d(np.asarray(a, dtype=float)), np.atleast_2d(np.asarray(b, dtype=float))
    Acl = a - b @ dare_gain(a, b, r, X, s)
    return np.linalg.eigvals(Acl if e is None else Acl @ np.linalg.inv(e))


def is_stabilizing_dare(a, b, r, s, X, e=None, margin=0.0):
    """True iff X is stabilizing: rho(a - bK) < 1 - margin (with e: of (a - bK) e^-1;
    docs/algorithms.md, "Stabilizing solution")."""
    return bool(np.max(np.abs(dare_closed_loop_eigenvalues(a, b, r, s, X, e))) < 1 - margin)


def care_closed_loop_eigenvalues(a, b, r, s, X, e=None):
    """eig(a - b r^-1 (b'Xe + s')), generalized by e: eig of the pencil, i.e. of (...) e^-1."""
    a, b, _, r, e, s = _defaults(a, b, a, r, e, s)
    Acl = a - b @ np.linalg.solve(r, b.T @ X @ e + s.T)
    return np.linalg.eigvals(Acl @ np.linalg.inv(e))


def dare_residual(a, b, q, r, X, e=None, s=None):
    """Relative residual of the DARE: ||lhs||_F / (sum of the terms' norms)."""
    a, b, q, r, e, s = _defaults(a, b, q, r, e, s)
    L = a.T @ X @ b + s
    corr = L @ np.linalg.solve(b.T @ X @ b + r, L.T)
    terms = [a.T @ X @ a, e.T @ X @ e, corr, q]
    res = terms[0] - terms[1] - terms[2] + terms[3]
    return float(np.linalg.norm(res) / max(sum(np.linalg.norm(t) for t in terms), np.finfo(float).tiny))


def care_residual(a, b, q, r, X, e=None, s=None):
    """Relative residual of the CARE: ||lhs||_F / (sum of the terms' norms)."""
    a, b, q, r, e, s = _defaults(a, b, q, r, e, s)
    L = e.T @ X @ b + s
    terms = [a.T @ X @ e, e.T @ X @ a, L @ np.linalg.solve(r, L.T), q]
    res = terms[0] + terms[1] - terms[2] + terms[3]
    return float(np.linalg.norm(res) / max(sum(np.linalg.norm(t) for t in terms), np.finfo(float).tiny))


def dare_iteration(a, b, q, r, s=None, x0=None, tol=1e-13, max_iter=100000):
    """DARE (e = I) by the Riccati iteration (6.90) in congruence form (docs/algorithms.md, "Riccati iteration"):

        K = (b'Xb + r)^-1 (b'Xa + s')
        X <- (a - bK)' X (a - bK) + [I; -K]' [[q, s], [s', r]] [I; -K]

    which equals a'Xa - (a'Xb + s)(b'Xb + r)^-1 (b'Xa + s') + q but is a sum of congruences
    (PSD when [[q, s], [s', r]] >= 0). Singular r is fine while b'Xb + r stays invertible (case
    B3 of ex. 6.6 has r = 0). Default start x0 = I (P0 > 0 avoids the non-stabilizing fixed
    points of failure mode 2 in docs/algorithms.md, "Stabilizing solution"). Stops when
    ||X_{k+1} - X_k||_F <= tol max(1, ||X_{k+1}||_F);
    converges linearly at about rho(a - bK)^2 per step.
    """
    a, b, q, r, _, s = _defaults(a, b, q, r, None, s)
    n = a.shape[0]
    X = np.eye(n) if x0 is None else np.asarray(x0, dtype=float)
    J = np.block([[q, s], [s.T, r]])
    for _ in range(max_iter):
        K = dare_gain(a, b, r, X, s)
        Acl, T = a - b @ K, np.vstack([np.eye(n), -K])
        X_new = _sym(Acl.T @ X @ Acl + T.T @ J @ T)
        if np.linalg.norm(X_new - X) <= tol * max(1.0, np.linalg.norm(X_new)):
            return X_new
        X = X_new
    raise RuntimeError(f"dare_iteration: no convergence in {max_iter} steps")


def _split(U, lam, select, what):
    """X = U2 U1^-1 from the eigenvectors of the n selected eigenvalues (real part, symmetrized)."""
    n = U.shape[0] // 2
    idx = np.flatnonzero(select)
    if len(idx) != n:
        raise ValueError(f"{what}: {len(idx)} eigenvalues selected instead of {n} (no clean split)")
    U1, U2 = U[:n, idx], U[n:, idx]
    return _sym(np.real(np.linalg.solve(U1.T, U2.T).T))


def dare_eigen(a, b, q, r, e=None, s=None, tol=1e-10):
    """DARE by the eigenvectors of the symplectic (Euler) matrix, Lemmas 6.5-6.6, (6.116)-(6.124).

    After removing e and s (module docstring), with W = b r^-1 b' and the Kalman mapping
    F~ = a~' (so F~^-T = a~^-1), the matrix of the linear-fractional Riccati map (Lemma 6.5) is

        Phi = [[a~^-1,      a~^-1 W       ],
               [q~ a~^-1,   a~' + q~ a~^-1 W]]

    Its eigenvalues come in pairs (l, 1/l). The stabilizing X = U2 U1^-1 (6.124) spans the
    eigenvectors of the n eigenvalues with |l| > 1 (the dominant subspace of the forward map;
    equivalently the stable ones of Phi^-1); the closed-loop eigenvalues are their reciprocals.
    Needs r, e and a~ invertible; raises ValueError when eigenvalues sit on |l| = 1 (within tol).
    """
    a, b, q, r, e, s = _defaults(a, b, q, r, e, s)
    a, q, s = _remove_e(a, q, s, e)
    a, q = _remove_s(a, b, q, r, s)
    W = b @ np.linalg.solve(r, b.T)
    ai = np.linalg.inv(a)
    Phi = np.block([[ai, ai @ W], [q @ ai, a.T + q @ ai @ W]])
    lam, U = np.linalg.eig(Phi)
    if np.any(np.abs(np.abs(lam) - 1) <= tol):
        raise ValueError("dare_eigen: eigenvalues on the unit circle (no stabilizing solution)")
    return _split(U, lam, np.abs(lam) > 1, "dare_eigen")


def care_eigen(a, b, q, r, e=None, s=None, tol=1e-10):
    """CARE by the eigenvectors of the Hamiltonian matrix (the continuous analogue of (6.124)).

    After removing e and s (module docstring) the equation is a'X + Xa - X G X + q = 0 with
    G = b r^-1 b'. [I; X] spans an invariant subspace of

        Ham = [[a, -G], [-q, -a']]     (Ham [I; X] = [I; X] (a - G X))

    and the stabilizing X takes the n eigenvalues with Re l < 0: X = U2 U1^-1. Needs r and e
    invertible; raises ValueError for eigenvalues on the imaginary axis (within tol).
    """
    a, b, q, r, e, s = _defaults(a, b, q, r, e, s)
    a, q, s = _remove_e(a, q, s, e)
    a, q = _remove_s(a, b, q, r, s)
    G = b @ np.linalg.solve(r, b.T)
    Ham = np.block([[a, -G], [-q, -a.T]])
    lam, U = np.linalg.eig(Ham)
    scale = max(1.0, float(np.max(np.abs(lam))))
    if np.any(np.abs(lam.real) <= tol * scale):
        raise ValueError("care_eigen: eigenvalues on the imaginary axis (no stabilizing solution)")
    return _split(U, lam, lam.real < 0, "care_eigen")
