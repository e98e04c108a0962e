"""Wiener filters (kfast.poly.wiener_causal, wiener_noncausal, wiener_fir) for a signal C/A v in
coloured noise M/N e: the causal filter equals the stationary Kalman filter (m = 0) and predictor
(m < 0) of the same signal-plus-noise model, transfer function and error variance; the FIR filter
approaches the causal one from above as its order grows; the non-causal error is the lower bound
(7.93), reached by the causal smoother as the lag grows."""

from __future__ import annotations

import numpy as np
import pytest

import kfast
from modelgen import stable_monic


def problem(seed):
    rng = np.random.default_rng(900 + seed)
    n, r = int(rng.integers(1, 4)), int(rng.integers(0, 3))
    return dict(
        C=stable_monic(rng, n), A=stable_monic(rng, n), lam_v2=rng.uniform(0.5, 2.0),
        M=stable_monic(rng, r), N=stable_monic(rng, r), lam_e2=rng.uniform(0.2, 2.0),
    ), rng


def stacked_model(C, A, lam_v2, M, N, lam_e2):
    """y = s + w in state space: s = H_s x_s + v, w = H_w x_w + e (observer forms with a direct
    term, kfast.poly.arma_to_ss); returns the model, H_s (over the stacked state) and λv."""
    blocks = []
    for top, bottom, lam in ((C, A, lam_v2), (M, N, lam_e2)):
        n = len(bottom) - 1
        if n == 0:
            blocks.append((np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), lam))
            continue
        part = kfast.poly.arma_to_ss(bottom, top, lam)
        blocks.append((part.F, part.N / lam, part.H, lam))
    (Fs, gs, Hs, lv), (Fw, gw, Hw, le) = blocks
    ns, nw = len(Fs), len(Fw)
    F = np.zeros((ns + nw, ns + nw))
    F[:ns, :ns], F[ns:, ns:] = Fs, Fw
    H = np.hstack([Hs, Hw])
    Q = np.zeros_like(F)
    Q[:ns, :ns], Q[ns:, ns:] = lv * gs @ gs.T, le * gw @ gw.T
    Ncov = np.vstack([lv * gs, le * gw])
    model = kfast.LinearGaussian(F, H, Q, [[lv + le]], N=Ncov)
    return model, np.hstack([Hs, np.zeros((1, nw))]), lv


def kalman(model, Hs, lv, z, m):
    """The stationary Kalman estimate of s(t - m) from y up to t, m <= 0, as a transfer function
    at z, and its error variance."""
    ss = model.steady_state()
    F, H, Kp, K, S, P = model.F, model.H, ss.K_pred, ss.K, ss.S[0, 0], ss.P_pred
    n = len(F)
    x_pred = np.linalg.solve(z * np.eye(n) - F + Kp @ H, Kp)  # y -> x̂(t|t-1)
    innov = 1.0 - (H @ x_pred)[0, 0]  # y -> e(t)
    if m == 0:
        # s(t) = H_s x + v: ŝ(t|t) = H_s x̂(t|t) + E[v(t) | e(t)] = H_s (x̂(t|t-1) + K e) + λv/S e.
        gain = (Hs @ (x_pred + K * innov))[0, 0] + lv / S * innov
        cov_se = (Hs @ P @ H.T)[0, 0] + lv
        error = (Hs @ P @ Hs.T)[0, 0] + lv - cov_se**2 / S
        return gain, error
    k = -m
    x_next = z * x_pred  # y -> x̂(t+1|t)
    gain = (Hs @ np.linalg.matrix_power(F, k - 1) @ x_next)[0, 0]
    Pk = P
    for _ in range(k - 1):
        Pk = F @ Pk @ F.T + model.Q
    return gain, (Hs @ Pk @ Hs.T)[0, 0] + lv


@pytest.mark.parametrize("m", [0, -1, -3])
@pytest.mark.parametrize("seed", range(6))
def test_causal_wiener_is_the_stationary_kalman_filter_and_predictor(seed, m):
    spec, rng = problem(seed)
    g = kfast.poly.wiener_causal(**spec, m=m)
    model, Hs, lv = stacked_model(**spec)
    for z in rng.uniform(0.9, 1.5, 3) * np.exp(1j * rng.uniform(0, np.pi, 3)):
        want, error = kalman(model, Hs, lv, z, m)
        got = np.polyval(g.num, z) / np.polyval(g.den, z) * z ** (len(g.den) - len(g.num))
        assert got == pytest.approx(want, rel=1e-7, abs=1e-10)
    assert g.error_variance == pytest.approx(error, rel=1e-7)


@pytest.mark.parametrize("m", [0, 2, -1])
@pytest.mark.parametrize("seed", range(4))
def test_fir_approaches_causal_from_above_and_noncausal_is_the_bound(seed, m):
    spec, _ = problem(seed)
    causal = kfast.poly.wiener_causal(**spec, m=m)
    bound = kfast.poly.wiener_noncausal(**spec, m=m)
    errors = [kfast.poly.wiener_fir(**spec, order=p, m=m).error_variance for p in (1, 4, 16, 64)]
    by_order = kfast.poly.wiener_fir(**spec, order=64, m=m).error_variance_by_order
    np.testing.assert_allclose(by_order[[1, 4, 16, 64]], errors, rtol=1e-12)
    assert np.all(np.diff(by_order) <= 1e-12)
    assert all(a >= b - 1e-12 for a, b in zip(errors, errors[1:]))
    assert errors[-1] >= causal.error_variance - 1e-10
    assert errors[-1] == pytest.approx(causal.error_variance, rel=1e-6)
    assert bound.error_variance <= causal.error_variance + 1e-12
    # The smoother's error reaches the bound as the lag grows (7.93).
    assert kfast.poly.wiener_causal(**spec, m=60).error_variance == pytest.approx(bound.error_variance, rel=1e-6)


@pytest.mark.parametrize("order", [0, 3, 40])
def test_fir_levinson_solves_the_normal_equations(order):
    """Levinson's recursion against a dense solve of the same Toeplitz normal equations, every
    order: the coefficients and the error variance of each."""
    from kfast.poly.arma import arma_to_ss

    spec, _ = problem(2)
    g = kfast.poly.wiener_fir(**spec, order=order, m=1)
    lags = np.arange(order + 2)

    def autocovariance(top, bottom, lam):
        if len(bottom) == 1:
            return np.where(lags == 0, lam, 0.0)
        return arma_to_ss(bottom, top, lam).autocovariance(lags)[:, 0, 0]

    r_s = autocovariance(spec["C"], spec["A"], spec["lam_v2"])
    r_y = r_s + autocovariance(spec["M"], spec["N"], spec["lam_e2"])
    for k in range(order + 1):
        T = r_y[np.abs(np.subtract.outer(np.arange(k + 1), np.arange(k + 1)))]
        b = r_s[np.abs(np.arange(k + 1) - 1)]
        dense = np.linalg.solve(T, b)
        assert g.error_variance_by_order[k] == pytest.approx(r_s[0] - dense @ b, rel=1e-10)
    np.testing.assert_allclose(g.num, dense, rtol=1e-9, atol=1e-12)


def test_noncausal_filter_is_the_spectral_ratio():
    spec, rng = problem(1)
    nc = kfast.poly.wiener_noncausal(**spec, m=0)
    omega = rng.uniform(0, np.pi, 5)
    z = np.exp(1j * omega)
    C, A, M, N = spec["C"], spec["A"], spec["M"], spec["N"]
    phi_s = spec["lam_v2"] * np.abs(np.polyval(C, z) / np.polyval(A, z)) ** 2
    phi_w = spec["lam_e2"] * np.abs(np.polyval(M, z) / np.polyval(N, z)) ** 2
    np.testing.assert_allclose(nc.frequency_response(omega), phi_s / (phi_s + phi_w), rtol=1e-9)


def test_bad_input():
    with pytest.raises(ValueError, match="A: must be monic"):
        kfast.poly.wiener_causal([1.0, 0.0], [2.0, -0.8], 1.0)
    with pytest.raises(ValueError, match="A: must have its zeros strictly inside"):
        kfast.poly.wiener_causal([1.0, 0.0], [1.0, -1.2], 1.0)
    with pytest.raises(ValueError, match="C: must have the degree of A"):
        kfast.poly.wiener_causal([1.0], [1.0, -0.8], 1.0)
    with pytest.raises(ValueError, match="m: expected an integer lag"):
        kfast.poly.wiener_causal([1.0, 0.0], [1.0, -0.8], 1.0, m=0.5)
    with pytest.raises(ValueError, match="lam_v2: must be a finite number > 0"):
        kfast.poly.wiener_causal([1.0, 0.0], [1.0, -0.8], -1.0)
    with pytest.raises(ValueError, match="order: expected an integer"):
        kfast.poly.wiener_fir([1.0, 0.0], [1.0, -0.8], 1.0, order=2.5)


@pytest.mark.parametrize("m", [0, 2, -1])
@pytest.mark.parametrize("seed", range(4))
def test_error_spectrum_integrates_to_the_error_variance(seed, m):
    """(7.89): the error spectrum's mean over the circle is the error variance, for the causal,
    non-causal and FIR filters alike, and the non-causal spectrum is a pointwise lower bound (7.93)."""
    spec, _ = problem(seed)
    w = np.linspace(0, 2 * np.pi, 1 << 14, endpoint=False)
    filters = [kfast.poly.wiener_causal(**spec, m=m), kfast.poly.wiener_noncausal(**spec, m=m),
               kfast.poly.wiener_fir(**spec, order=8, m=m)]
    for g in filters:
        assert g.error_spectrum(w).mean() == pytest.approx(g.error_variance, rel=1e-8)
    bound = filters[1].error_spectrum(w)
    assert np.all(filters[0].error_spectrum(w) >= bound - 1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_the_prefiltered_criterion(seed):
    """(7.94)-(7.104): P = 1 gives the plain filter; a prefilter minimises E[P s̃]² (every
    perturbation of the filter's numerator does worse in that criterion), and a resonance of
    P at ω0 makes the error spectrum touch the non-causal bound there."""
    spec, rng = problem(seed)
    plain = kfast.poly.wiener_causal(**spec)
    same = kfast.poly.wiener_causal(**spec, prefilter=([1.0, 0.0], [1.0, 0.0]))
    assert same.error_variance == pytest.approx(plain.error_variance, rel=1e-10)
    w0 = rng.uniform(0.3, 2.5)
    Fp = [1.0, 0.0, 0.0]
    Hp = np.real(np.poly([0.995 * np.exp(1j * w0), 0.995 * np.exp(-1j * w0)]))
    g = kfast.poly.wiener_causal(**spec, prefilter=(Fp, Hp))
    w = np.linspace(0, 2 * np.pi, 1 << 15, endpoint=False)
    weight = np.abs(np.polyval(Fp, np.exp(1j * w)) / np.polyval(Hp, np.exp(1j * w))) ** 2

    def criterion(f):
        return float(np.mean(weight * f.error_spectrum(w)))

    best = criterion(g)
    assert best < criterion(plain)
    from dataclasses import replace

    for _ in range(3):
        other = replace(g, num=g.num * (1 + 1e-3 * rng.standard_normal(g.num.shape)))
        assert criterion(other) > best
    bound = kfast.poly.wiener_noncausal(**spec)
    at = np.array([w0])
    assert g.error_spectrum(at)[0] == pytest.approx(bound.error_spectrum(at)[0], rel=2e-2)
    assert abs(plain.error_spectrum(at)[0] - bound.error_spectrum(at)[0]) > abs(g.error_spectrum(at)[0] - bound.error_spectrum(at)[0])
