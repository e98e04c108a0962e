//! The particle filter over a whole series: sequential importance resampling with the
//! bootstrap proposal (the particles move by the model), log-domain weights, resampling every
//! step or when the effective sample size is low.
//!
//! At step t, from the particles xⁱ and normalized log-weights λⁱ of p(x(t) | y(0..t−1)):
//!
//! ```text
//! ℓⁱ = log p(y(t) | xⁱ)                      Gaussian: N(y; h(xⁱ), R), observed components only
//!                                             (or a quantized measurement's cell: [`MeasurementLikelihood`])
//! loglik_t = log Σᵢ exp(λⁱ + ℓⁱ)             the estimate of log p(y(t) | y(0..t−1))
//! λⁱ ← λⁱ + ℓⁱ − loglik_t                     Söderström (9.94), in logs
//! x̂(t|t) = Σ Wⁱ xⁱ,  P(t|t) = Σ Wⁱ (xⁱ − x̂)(xⁱ − x̂)'        (9.99)–(9.100), Wⁱ = exp λⁱ
//! ESS = 1 / Σ (Wⁱ)²;  resample if asked (always, or ESS < τ M): xⁱ ← x^{aⁱ}, λⁱ = −log M
//! xⁱ ← f(xⁱ, t, u) + wⁱ,  wⁱ ~ N(0, Q(t))                    (9.98), or g(xⁱ) wⁱ, or f(xⁱ, wⁱ)
//! ```
//!
//! The increments use the weights carried into the step, so Σ_t loglik_t is the standard
//! unbiased estimator of p(y) (as an estimate of p(y), not of its log) with adaptive
//! resampling too (Del Moral 2004); using the plain mean of the likelihoods at a step that was
//! not preceded by resampling is the known bug of some peers. The last step is not followed by
//! a time update, so nothing is resampled there: its particles are the weighted ones.

use std::sync::Arc;

use super::cloud::Cloud;
use super::custom::ParticleFunction;
use super::resample::Resampling;
use crate::core::alloc::check_f64_arrays;
use crate::core::batch::{par, thread_count};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::nonlinear::model::NonlinearModel;
use crate::nonlinear::quantized::QuantizedSensor;

/// How the particle filter weighs y(t) given a particle's h(x): ℓ = log p(y(t) | x).
#[derive(Debug, Clone, Default)]
pub enum MeasurementLikelihood {
    /// y = h(x) + v, v ~ N(0, R): log N(y; h(x), R) on the observed components (angular
    /// outputs with their residuals wrapped).
    #[default]
    Gaussian,
    /// y = h(x) + v, v multivariate Student-t with ν degrees of freedom and scale matrix R
    /// (covariance ν/(ν − 2) R for ν > 2): heavy tails, so that an outlier moves the
    /// particles' weights far less than under the Gaussian:
    /// log p = log Γ((ν + m)/2) − log Γ(ν/2) − (m/2) log νπ − ½ log det R − (ν + m)/2 log(1 + e'R⁻¹e/ν).
    StudentT {
        /// ν > 0.
        nu: f64,
    },
    /// y = h(x) + v, v_i uniform on ±√(3 R_ii) (R diagonal; its diagonal the variances):
    /// p = Π 1/(2 a_i) inside the box, 0 outside.
    Uniform,
    /// y = Q_Δ(h(x) + v), v ~ N(0, R) with R diagonal (Söderström section 9.6): the log
    /// probability of y's cell, Σ_i log P(y_i − Δ_i/2 ≤ h_i(x) + v_i < y_i + Δ_i/2)
    /// ([`quantized_loglik`](crate::nonlinear::quantized_loglik)); an angular output's h(x) is
    /// first moved by whole turns to within π of y's cell.
    Quantized(QuantizedSensor),
    /// The user's log p(y(t) | x) at all the particles at once (h and R are not used); a
    /// particle's −∞ is a zero likelihood, NaN or +∞ an error.
    User(Arc<dyn ParticleFunction>),
}

/// The particle filter's settings.
#[derive(Debug, Clone)]
pub struct ParticleOptions {
    /// M, the number of particles (at least 1).
    pub particles: usize,
    /// r, the copies of each resampled particle (Söderström (9.98)): resampling draws
    /// N = M / r ancestors and each is propagated r times; M must be a multiple of r. 1 (the
    /// default) draws M ancestors, the standard bootstrap filter.
    pub copies: usize,
    /// How the ancestors are drawn.
    pub resampling: Resampling,
    /// `None`: resample after every update (the book's filter); `Some(τ)`, τ in (0, 1]:
    /// resample when ESS < τ M.
    pub ess_threshold: Option<f64>,
    /// The seed of kfast's generator (the same seed gives the same bits, for any `threads`).
    pub seed: u64,
    /// Threads for the particle loops (all cores when `None`; a model's functions that cannot
    /// run in parallel — Python callables, which hold the GIL — are called once for all
    /// particles, the rest of the step still on all threads). The work is split in blocks of a
    /// size fixed by M alone and the blocks' sums are added in order, so the result does not
    /// depend on it.
    pub threads: Option<usize>,
    /// p(y | x): Gaussian (the default), Student-t, uniform, quantized or the user's.
    pub likelihood: MeasurementLikelihood,
    /// `Some(c)`: after each resampling, move every particle by a draw of the Gaussian kernel
    /// h L z, L L' = P(t|t), z ~ N(0, I), h = c (4 / (M (n + 2)))^(1/(n + 4)) (Silverman's
    /// bandwidth for a Gaussian density, times c): the regularized particle filter, which
    /// keeps copies of one particle apart. `None`: off (the book's filter).
    pub regularize: Option<f64>,
    /// `Some(move)`: after each resampling (and the regularization, if any), the particles are
    /// replaced by `move`'s output (the resample–move filter: an MCMC step that leaves
    /// p(x(t) | y(0..t)) invariant restores the diversity that resampling lost). `None`: off.
    pub rejuvenate: Option<Arc<dyn ParticleFunction>>,
}

impl ParticleOptions {
    /// M particles, multinomial resampling every step (Söderström (9.95)–(9.97)), seed 0.
    pub fn new(particles: usize) -> Self {
        ParticleOptions {
            particles,
            copies: 1,
            resampling: Resampling::Multinomial,
            ess_threshold: None,
            seed: 0,
            threads: None,
            likelihood: MeasurementLikelihood::Gaussian,
            regularize: None,
            rejuvenate: None,
        }
    }

    /// Whether the user's functions (if any) may run on several threads at once.
    pub(crate) fn parallel(&self) -> bool {
        let likelihood = match &self.likelihood {
            MeasurementLikelihood::User(fun) => fun.parallel(),
            _ => true,
        };
        likelihood && self.rejuvenate.as_ref().is_none_or(|fun| fun.parallel())
    }

    pub(crate) fn check(&self) -> Result<()> {
        if let MeasurementLikelihood::StudentT { nu } = self.likelihood {
            if !(nu.is_finite() && nu > 0.0) {
                return Err(Error::arg(
                    "likelihood",
                    format!("the Student-t's degrees of freedom must be finite and > 0, got {nu}"),
                ));
            }
        }
        if let Some(c) = self.regularize {
            if !(c.is_finite() && c > 0.0) {
                return Err(Error::arg("regularize", format!("the bandwidth factor must be finite and > 0, got {c}")));
            }
        }
        if self.particles == 0 {
            return Err(Error::arg("n_particles", "must be at least 1"));
        }
        if self.copies == 0 || !self.particles.is_multiple_of(self.copies) {
            return Err(Error::arg(
                "copies",
                format!("must be at least 1 and divide n_particles = {}, got {}", self.particles, self.copies),
            ));
        }
        if self.threads == Some(0) {
            return Err(Error::arg("threads", "must be at least 1"));
        }
        if let Some(tau) = self.ess_threshold {
            if !(tau > 0.0 && tau <= 1.0) {
                return Err(Error::arg("ess_threshold", format!("must be in (0, 1], got {tau}")));
            }
        }
        Ok(())
    }
}

/// Where [`particle_filter_into`] writes (row-major, T steps).
#[derive(Debug)]
pub struct ParticleOutputs<'a> {
    /// x̂(t|t), T × n: the weighted mean of the particles.
    pub x_filt: &'a mut [f64],
    /// P(t|t), T × n × n: their weighted covariance.
    pub p_filt: &'a mut [f64],
    /// The effective sample size 1 / Σ Wᵢ² after the update of each step (T).
    pub ess: &'a mut [f64],
    /// Whether the particles were resampled after the update of step t (T).
    pub resampled: &'a mut [bool],
    /// The estimates of log p(y(t) | y(0..t−1)) (T; 0 where nothing is observed).
    pub loglik_t: &'a mut [f64],
    /// The particles of the last step (M × n), or of every step (T × M × n), if wanted.
    pub particles: Option<&'a mut [f64]>,
    /// Their normalized log-weights (M, or T × M), if wanted.
    pub log_weights: Option<&'a mut [f64]>,
}

/// What [`particle_filter`] returns.
#[derive(Debug, Clone)]
pub struct ParticleResult {
    /// x̂(t|t), T × n.
    pub x_filt: Vec<f64>,
    /// P(t|t), T × n × n.
    pub p_filt: Vec<f64>,
    /// The effective sample size after each update (T).
    pub ess: Vec<f64>,
    /// Whether each step's particles were resampled (T).
    pub resampled: Vec<bool>,
    /// The estimates of log p(y(t) | y(0..t−1)) (T).
    pub loglik_t: Vec<f64>,
    /// The estimate of log p(y(0..T−1)).
    pub loglik: f64,
}

/// The particle filter of `y` (T × m, NaN: missing) with inputs `u`, from the prior
/// x(0|−1) ~ N(x0, P0).
pub fn particle_filter(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: ParticleOptions,
) -> Result<ParticleResult> {
    let (steps, n) = (y.steps(), model.n_states());
    check_f64_arrays("y", &[&[steps, n, n], &[steps, n + 3]])?;
    let mut x_filt = vec![0.0; steps * n];
    let mut p_filt = vec![0.0; steps * n * n];
    let (mut ess, mut resampled, mut loglik_t) = (vec![0.0; steps], vec![false; steps], vec![0.0; steps]);
    let out = ParticleOutputs {
        x_filt: &mut x_filt,
        p_filt: &mut p_filt,
        ess: &mut ess,
        resampled: &mut resampled,
        loglik_t: &mut loglik_t,
        particles: None,
        log_weights: None,
    };
    let loglik = particle_filter_into(model, y, u, x0, p0, options, out)?;
    Ok(ParticleResult { x_filt, p_filt, ess, resampled, loglik_t, loglik })
}

/// [`particle_filter`] into given outputs; returns the estimate of log p(y(0..T−1)).
pub fn particle_filter_into(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: ParticleOptions,
    mut out: ParticleOutputs<'_>,
) -> Result<f64> {
    let steps = model.check_run(y, u, x0, p0)?;
    options.check()?;
    let (n, count) = (model.n_states(), options.particles);
    let every_step = check_outputs(&out, steps, n, count)?;
    let requested = options.threads;
    let mut cloud = Cloud::new(model, options)?;
    let threads = thread_count(requested, cloud.blocks());
    let mut loglik = 0.0;
    par::on_threads(threads, || {
        cloud.draw_prior(x0, p0);
        for t in 0..steps {
            loglik += step(&mut cloud, model, y, u, t, every_step, &mut out)?;
        }
        Ok(())
    })?;
    Ok(loglik)
}

/// One step of [`particle_filter_into`]: the update with y(t), the outputs, and (but at the
/// last step) resampling and the time update; returns loglik_t.
fn step(
    cloud: &mut Cloud,
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    t: usize,
    every_step: bool,
    out: &mut ParticleOutputs<'_>,
) -> Result<f64> {
    let (n, count, steps) = (model.n_states(), cloud.count(), y.steps());
    let (y_t, u_t) = (y.row(t), u.map(|u| u.row(t)));
    out.loglik_t[t] = cloud.update(model, y_t, t, u_t)?;
    out.ess[t] = cloud.moments(&mut out.x_filt[t * n..][..n], &mut out.p_filt[t * n * n..][..n * n]);
    let kept = if every_step { Some(t) } else { (t + 1 == steps).then_some(0) };
    if let (Some(slot), Some(p)) = (kept, out.particles.as_deref_mut()) {
        p[slot * count * n..][..count * n].copy_from_slice(cloud.particles());
    }
    if let (Some(slot), Some(w)) = (kept, out.log_weights.as_deref_mut()) {
        cloud.copy_log_weights(&mut w[slot * count..][..count]);
    }
    if t + 1 < steps {
        out.resampled[t] = cloud.resample_if_due(t, u_t)?;
        cloud.propagate(model, t, u_t)?;
    }
    Ok(out.loglik_t[t])
}

/// Checks the output sizes; whether the particles are kept for every step.
fn check_outputs(out: &ParticleOutputs<'_>, steps: usize, n: usize, count: usize) -> Result<bool> {
    let sizes = [
        ("x_filt", out.x_filt.len(), steps * n),
        ("P_filt", out.p_filt.len(), steps * n * n),
        ("ess", out.ess.len(), steps),
        ("resampled", out.resampled.len(), steps),
        ("loglik_t", out.loglik_t.len(), steps),
    ];
    for (name, got, expected) in sizes {
        if got != expected {
            return Err(Error::arg(name, format!("has {got} numbers, expected {expected}")));
        }
    }
    let mut every_step = false;
    for (name, got, per_step) in [
        ("particles", out.particles.as_ref().map(|p| p.len()), count * n),
        ("log_weights", out.log_weights.as_ref().map(|w| w.len()), count),
    ] {
        match got {
            None => {}
            Some(len) if len == per_step => {}
            Some(len) if len == steps * per_step => every_step = true,
            Some(len) => {
                return Err(Error::arg(
                    name,
                    format!(
                        "has {len} numbers, expected {per_step} (the last step) or {} (every step)",
                        steps * per_step
                    ),
                ))
            }
        }
    }
    Ok(every_step)
}
