"""Stone Soup peer for workload N3 of benches/bench_particle.py: a bootstrap particle filter on UNGM
(systematic resampling at every step) with Stone Soup's own ParticlePredictor, ParticleUpdater and
SystematicResampler; UNGM as custom Stone Soup models (it is not built in).

    /work/venv/bin/python benches/peer_stonesoup.py      # self-check against kfast, and timing
"""

from __future__ import annotations

import datetime

import numpy as np
from scipy.special import logsumexp
from stonesoup.base import Property
from stonesoup.models.base import TimeVariantModel
from stonesoup.models.measurement.nonlinear import NonLinearGaussianMeasurement
from stonesoup.models.transition.nonlinear import GaussianTransitionModel
from stonesoup.predictor.particle import ParticlePredictor
from stonesoup.resampler import Resampler
from stonesoup.resampler.particle import SystematicResampler
from stonesoup.types.array import CovarianceMatrix, StateVector, StateVectors
from stonesoup.types.detection import Detection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import ParticleState
from stonesoup.updater.particle import ParticleUpdater

START = datetime.datetime(2000, 1, 1)  # step t is at START + t seconds


class UNGMTransition(GaussianTransitionModel, TimeVariantModel):
    """x' = x/2 + 25x/(1+x^2) + 8cos(1.2t) + w, w ~ N(0, q); t = the prior's timestamp in seconds."""

    q: float = Property(doc="process noise variance")

    @property
    def ndim_state(self):
        return 1

    def covar(self, **kwargs):
        return CovarianceMatrix([[self.q]])

    def function(self, state, noise=False, **kwargs):
        x = np.asarray(state.state_vector)
        t = (state.timestamp - START).total_seconds()
        fx = x / 2 + 25 * x / (1 + x**2) + 8 * np.cos(1.2 * t)
        if noise is True:
            noise = self.rvs(num_samples=x.shape[1], **kwargs)
        elif noise is False:
            noise = 0
        return StateVectors(fx + np.asarray(noise))


class UNGMMeasurement(NonLinearGaussianMeasurement):
    """y = x^2/20 + v, v ~ N(0, noise_covar)."""

    @property
    def ndim_meas(self):
        return 1

    def function(self, state, noise=False, **kwargs):
        x = np.asarray(state.state_vector)
        if noise is True:
            noise = self.rvs(num_samples=x.shape[1], **kwargs)
        elif noise is False:
            noise = 0
        return StateVectors(x**2 / 20 + np.asarray(noise))


class RecordingResampler(Resampler):
    """Keeps the weighted posterior handed to it by ParticleUpdater.update (after normalisation,
    before resampling), then resamples it with `resampler` (SystematicResampler: every time)."""

    resampler: Resampler = Property(default_factory=SystematicResampler)

    def resample(self, particles, nparts=None):
        self.posterior = particles
        return self.resampler.resample(particles, nparts)


def stonesoup_bootstrap(y, N, q=10.0, r=1.0, p0=5.0, seed=0):
    """returns (means (T,), variances (T,), loglik_or_None)

    Bootstrap filter with Stone Soup's ParticlePredictor and ParticleUpdater: the updater
    normalises the weights and then always calls its resampler, here SystematicResampler (which,
    unlike ESSResampler, resamples unconditionally) behind a thin wrapper that records the
    normalised posterior first, so the means and variances are the weighted ones of x(t|t) before
    resampling (ParticleState.mean / .covar, ddof 0). The transition model reads its step index t
    from the prior's timestamp (START + t s), so the predictor's LRU cache (keyed on prior and
    timestamp) cannot serve a stale step. Stone Soup does not expose the normalising constant, so
    the log-likelihood is computed here: sum over t of logsumexp(log W + log p(y_t | x_i)) with W
    the prediction's weights (1/N) and the likelihood evaluated again by the measurement model.
    Random numbers: initial particles from default_rng(seed); the transition noise from the
    model's RandomState(seed); SystematicResampler draws from NumPy's global generator, which is
    seeded with np.random.seed(seed).
    """
    y = np.asarray(y, dtype=float)
    T = len(y)
    np.random.seed(seed)
    transition = UNGMTransition(q=q, seed=seed)
    measurement = UNGMMeasurement(ndim_state=1, mapping=(0,), noise_covar=[[r]])
    recorder = RecordingResampler()
    predictor = ParticlePredictor(transition)
    updater = ParticleUpdater(measurement, resampler=recorder)

    x0 = np.random.default_rng(seed).normal(0.0, np.sqrt(p0), N)
    prediction = ParticleState(StateVectors(x0[None, :]), log_weight=np.full(N, -np.log(N)),
                               timestamp=START)
    means, variances, loglik = np.zeros(T), np.zeros(T), 0.0
    for t in range(T):
        timestamp = START + datetime.timedelta(seconds=t)
        if t > 0:
            prediction = predictor.predict(state, timestamp=timestamp)
        detection = Detection(StateVector([y[t]]), timestamp=timestamp, measurement_model=measurement)
        state = updater.update(SingleHypothesis(prediction, detection))
        posterior = recorder.posterior
        means[t] = posterior.mean[0]
        variances[t] = posterior.covar[0, 0]
        loglik += logsumexp(prediction.log_weight + measurement.logpdf(detection, prediction))
    return means, variances, loglik


if __name__ == "__main__":
    import time

    import kfast

    def simulate(T, q=10.0, r=1.0, p0=5.0, seed=1):
        rng = np.random.default_rng(seed)
        x, y = rng.normal(0, np.sqrt(p0)), np.zeros(T)
        for t in range(T):
            y[t] = x**2 / 20 + rng.normal(0, np.sqrt(r))
            x = x / 2 + 25 * x / (1 + x**2) + 8 * np.cos(1.2 * t) + rng.normal(0, np.sqrt(q))
        return y

    y = simulate(50)
    means, variances, loglik = stonesoup_bootstrap(y, 2000)
    res = kfast.models.ungm(q=10.0, r=1.0).particle_filter(y, [0.0], [[5.0]], 2000, resample="systematic", seed=0)
    ratio = np.abs(means - res.x_filt[:, 0]) / np.sqrt(res.P_filt[:, 0, 0])
    print(f"T = 50, N = 2000: |dmean|/sd_kfast max {ratio.max():.2f} (step {ratio.argmax()}), median {np.median(ratio):.2f}")
    print(f"loglik: Stone Soup {loglik:.3f}, kfast {res.loglik:.3f}")
    N, T = 100_000, 20
    y = simulate(T)
    stonesoup_bootstrap(y, N)  # warm-up
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        stonesoup_bootstrap(y, N)
        times.append(time.perf_counter() - t0)
    print(f"N = {N:,}, T = {T}: {np.median(times) / (N * T) * 1e9:.0f} ns per particle-step (median of 3)")
