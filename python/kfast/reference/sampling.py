"""Sampling a continuous-time model in plain NumPy (docs/algorithms.md, "Sampling"): the test oracles.

dx = A x dt + B u dt + dbeta (intensity Qc) sampled at interval dt, zero-order-hold input, gives
x[k+1] = F x[k] + Bd u[k] + w[k] exactly, with (Söderström (4.99)-(4.103), ex. 4.6)::

    F = e^{A dt},   Qd = int_0^dt e^{As} Qc e^{A's} ds   (4.103),   Bd = int_0^dt e^{As} ds B
"""

from __future__ import annotations

import math

import numpy as np


def expm_taylor(a, max_terms=40):
    """e^a by scaling and squaring with a truncated Taylor series.

    Pick s with ||a||_1 / 2^s <= 1/2, sum the series of a / 2^s until the next term is below
    eps relative to the sum (about 15-20 terms), then square s times: e^a = (e^{a/2^s})^(2^s).
    """
    a = np.asarray(a)
    norm = np.linalg.norm(a, 1) if a.size else 0.0
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    A = a / 2**s
    E = term = np.eye(a.shape[0], dtype=np.result_type(a, float))
    for k in range(1, max_terms):
        term = term @ A / k
        E = E + term
        if np.linalg.norm(term, 1) <= np.finfo(float).eps * np.linalg.norm(E, 1):
            break
    for _ in range(s):
        E = E @ E
    return E


def van_loan(A, Qc, dt, B=None):
    """(F, Qd) or (F, Qd, Bd) by Van Loan's block exponentials, inverse-free form
    (Söderström ex. 4.6; docs/algorithms.md, "Van Loan"):

        exp(dt [[-A, Qc], [0, A']]) = [[., E12], [0, E22]]   =>   F = E22',  Qd = F E12
        exp(dt [[A, B], [0, 0]])    = [[F, Bd], [0, I]]

    (E12 = int_0^dt e^{-A(dt-s)} Qc e^{A's} ds, so F E12 is (4.103); no e^{-A dt} is inverted.)
    """
    A, Qc = np.asarray(A, dtype=float), np.asarray(Qc, dtype=float)
    n = A.shape[0]
    E = expm_taylor(dt * np.block([[-A, Qc], [np.zeros((n, n)), A.T]]))
    F = E[n:, n:].T
    Qd = F @ E[:n, n:]
    Qd = (Qd + Qd.T) / 2
    if B is None:
        return F, Qd
    B = np.asarray(B, dtype=float).reshape(n, -1)
    M = np.zeros((n + B.shape[1], n + B.shape[1]))
    M[:n, :n], M[:n, n:] = A, B
    Bd = expm_taylor(dt * M)[:n, n:]
    return F, Qd, Bd


def qd_first_order(A, Qc, dt):
    """Qd ~ Qc dt, the explicit first-order approximation (G&A Sec. 4.7.2.2;
    docs/algorithms.md, "First-order approximation").

    Error O(dt^2): it drops (A Qc + Qc A') dt^2 / 2 and higher terms. A is unused (kept for a
    signature parallel to van_loan).
    """
    return np.asarray(Qc, dtype=float) * dt
