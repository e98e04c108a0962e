//! [`ParticleFilter`]: the particle filter one step at a time, for streams.

use std::sync::Arc;

use super::cloud::Cloud;
use super::filter::ParticleOptions;
use crate::core::batch::{par::Pool, thread_count};
use crate::core::validate::{check_input_row, check_observation, check_prior};
use crate::error::{Error, Result};
use crate::nonlinear::model::NonlinearModel;

/// The particle filter over a stream: `update(y)` at step t, then `predict()` to t + 1, from
/// the prior x(0|−1) ~ N(x0, P0) at t = 0. The same steps give the numbers of
/// [`particle_filter`](super::particle_filter) (with the same options and seed), bit for bit.
pub struct ParticleFilter {
    model: Arc<NonlinearModel>,
    cloud: Cloud,
    pool: Pool,
    t: usize,
    loglik: f64,
    /// The weighted mean and covariance of the particles now, and their effective size.
    x: Vec<f64>,
    p: Vec<f64>,
    ess: f64,
}

impl ParticleFilter {
    /// Draws the particles of the prior (x0, P0).
    pub fn new(model: Arc<NonlinearModel>, x0: &[f64], p0: &[f64], options: ParticleOptions) -> Result<Self> {
        let n = model.n_states();
        check_prior(n, x0, p0)?;
        options.check()?;
        let requested = options.threads;
        let mut cloud = Cloud::new(&model, options)?;
        let threads = thread_count(requested, cloud.blocks());
        let pool = Pool::new(threads)?;
        let (mut x, mut p) = (vec![0.0; n], vec![0.0; n * n]);
        let ess = pool.install(|| {
            cloud.draw_prior(x0, p0);
            cloud.moments(&mut x, &mut p)
        });
        Ok(ParticleFilter { model, cloud, pool, t: 0, loglik: 0.0, x, p, ess })
    }

    /// The current step t.
    pub fn t(&self) -> usize {
        self.t
    }

    /// The weighted mean of the particles: x̂(t|t) after an update, x̂(t|t−1) otherwise.
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// Their weighted covariance.
    pub fn p(&self) -> &[f64] {
        &self.p
    }

    /// Their effective sample size 1 / Σ Wᵢ².
    pub fn ess(&self) -> f64 {
        self.ess
    }

    /// The sum of the updates' estimates of log p(y(t) | y(0..t−1)) so far.
    pub fn loglik(&self) -> f64 {
        self.loglik
    }

    /// The particles (M × n).
    pub fn particles(&self) -> &[f64] {
        self.cloud.particles()
    }

    /// Their normalized log-weights into `out` (M).
    pub fn log_weights(&self, out: &mut [f64]) {
        self.cloud.copy_log_weights(out)
    }

    /// The measurement update with y(t) (NaN: missing); returns its estimate of
    /// log p(y(t) | y(0..t−1)). After an error the particles and weights are unchanged.
    pub fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<f64> {
        let (t, m) = (self.t, self.model.n_obs());
        self.check_step("y")?;
        if y.len() != m {
            return Err(Error::arg_at("y", t, format!("expected {m} values (the outputs of h), got {}", y.len())));
        }
        check_observation(y, Some(t))?;
        if let Some(u) = u {
            check_input_row(u, Some(t))?;
        }
        let ParticleFilter { model, cloud, pool, x, p, .. } = self;
        let (loglik_t, ess) = pool.install(|| -> Result<(f64, f64)> {
            let loglik_t = cloud.update(model, y, t, u)?;
            Ok((loglik_t, cloud.moments(x, p)))
        })?;
        self.loglik += loglik_t;
        self.ess = ess;
        Ok(loglik_t)
    }

    /// Resampling (every step, or when the ESS is below the threshold) and the time update to
    /// t + 1; returns whether the particles were resampled.
    pub fn predict(&mut self, u: Option<&[f64]>) -> Result<bool> {
        let t = self.t;
        self.check_step("u")?;
        if let Some(u) = u {
            check_input_row(u, Some(t))?;
        }
        let ParticleFilter { model, cloud, pool, x, p, .. } = self;
        let (resampled, ess) = pool.install(|| -> Result<(bool, f64)> {
            let resampled = cloud.resample_if_due(t, u)?;
            cloud.propagate(model, t, u)?;
            Ok((resampled, cloud.moments(x, p)))
        })?;
        self.ess = ess;
        self.t += 1;
        Ok(resampled)
    }

    fn check_step(&self, arg: &'static str) -> Result<()> {
        match self.model.steps() {
            Some(steps) if self.t >= steps => {
                Err(Error::arg_at(arg, self.t, format!("the model's per-step Q/R end at step {}", steps - 1)))
            }
            _ => Ok(()),
        }
    }
}
