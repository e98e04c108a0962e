//! The particle filter over a whole series: sequential importance resampling with the
//! bootstrap proposal (the particles move by the model), log-domain weights, resampling every
//! step or when the effective sample size is low.
//!
//! At step t, from the particles xⁱ and normalized log-weights λⁱ of p(x(t) | y(0..t−1)):
//!
//! ```text
//! ℓⁱ = log p(y(t) | xⁱ)                      Gaussian: N(y; h(xⁱ), R), observed components only
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

use super::random::{Purpose, Stream};
use super::resample::{resample, Resampling, Scratch};
use crate::core::alloc::check_f64_arrays;
use crate::core::Series;
use crate::error::{Error, Result};
use crate::nonlinear::filter::check_finite;
use crate::nonlinear::function::wrap_angle;
use crate::nonlinear::model::{NoiseEntry, NonlinearModel};
use crate::nonlinear::sigma::{cholesky, semidefinite_cholesky};

/// The particle filter's settings.
#[derive(Debug, Clone, Copy)]
pub struct ParticleOptions {
    /// M, the number of particles (at least 1).
    pub particles: usize,
    /// How the ancestors are drawn.
    pub resampling: Resampling,
    /// `None`: resample after every update (the book's filter); `Some(τ)`, τ in (0, 1]:
    /// resample when ESS < τ M.
    pub ess_threshold: Option<f64>,
    /// The seed of kfast's generator (the same seed gives the same bits).
    pub seed: u64,
}

impl ParticleOptions {
    /// M particles, multinomial resampling every step (Söderström (9.95)–(9.97)), seed 0.
    pub fn new(particles: usize) -> Self {
        ParticleOptions { particles, resampling: Resampling::Multinomial, ess_threshold: None, seed: 0 }
    }

    fn check(&self) -> Result<()> {
        if self.particles == 0 {
            return Err(Error::arg("n_particles", "must be at least 1"));
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
    let mut cloud = Cloud::new(model, options)?;
    cloud.draw_prior(x0, p0);
    let mut loglik = 0.0;
    for t in 0..steps {
        let (y_t, u_t) = (y.row(t), u.map(|u| u.row(t)));
        out.loglik_t[t] = cloud.update(model, y_t, t, u_t)?;
        loglik += out.loglik_t[t];
        cloud.moments(&mut out.x_filt[t * n..][..n], &mut out.p_filt[t * n * n..][..n * n]);
        out.ess[t] = cloud.ess();
        let kept = if every_step { Some(t) } else { (t + 1 == steps).then_some(0) };
        if let (Some(slot), Some(p)) = (kept, out.particles.as_deref_mut()) {
            p[slot * count * n..][..count * n].copy_from_slice(&cloud.x);
        }
        if let (Some(slot), Some(w)) = (kept, out.log_weights.as_deref_mut()) {
            w[slot * count..][..count].copy_from_slice(&cloud.log_w);
        }
        if t + 1 < steps {
            out.resampled[t] = cloud.resample_if_due(t);
            cloud.propagate(model, t, u_t)?;
        }
    }
    Ok(loglik)
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

/// The particles with their scratch, allocated once.
struct Cloud {
    options: ParticleOptions,
    n: usize,
    /// xⁱ (M × n).
    x: Vec<f64>,
    /// f(xⁱ), then x(t+1)ⁱ; or the resampled particles (M × n).
    next: Vec<f64>,
    /// λⁱ, normalized: log Σ exp λⁱ = 0.
    log_w: Vec<f64>,
    /// exp λⁱ.
    w: Vec<f64>,
    /// h(xⁱ) (M × m).
    images: Vec<f64>,
    /// The noise wⁱ of the time update (M × r).
    noise: Vec<f64>,
    /// g(xⁱ) (M × n × r) with a noise gain; the points (xⁱ, wⁱ) (M × (n + r)) with the noise
    /// an input of f.
    noise_work: Vec<f64>,
    /// The factor of P0 or Q(t), and of R on the observed components.
    factor: Vec<f64>,
    r_obs: Vec<f64>,
    r_factor: Vec<f64>,
    observed: Vec<usize>,
    innovation: Vec<f64>,
    ancestors: Vec<usize>,
    scratch: Scratch,
}

impl Cloud {
    fn new(model: &NonlinearModel, options: ParticleOptions) -> Result<Self> {
        let (n, m, count) = (model.n_states(), model.n_obs(), options.particles);
        let (entry, q) = model.process_noise(0);
        let r = (q.len() as f64).sqrt() as usize;
        let work = match entry {
            NoiseEntry::Additive => 0,
            NoiseEntry::Gain(_) => n * r,
            NoiseEntry::Input => n + r,
        };
        // x, next, images, noise, noise_work, log_w, w and the indices
        check_f64_arrays(
            "n_particles",
            &[&[count, n], &[count, n], &[count, m], &[count, r], &[count, work], &[count, 4]],
        )?;
        Ok(Cloud {
            options,
            n,
            x: vec![0.0; count * n],
            next: vec![0.0; count * n],
            log_w: vec![-(count as f64).ln(); count],
            w: vec![1.0 / count as f64; count],
            images: vec![0.0; count * m],
            noise: vec![0.0; count * r],
            noise_work: vec![0.0; count * work],
            factor: vec![0.0; n.max(r) * n.max(r)],
            r_obs: vec![0.0; m * m],
            r_factor: vec![0.0; m * m],
            observed: Vec::with_capacity(m),
            innovation: vec![0.0; m],
            ancestors: vec![0; count],
            scratch: Scratch::default(),
        })
    }

    /// xⁱ = x0 + L0 zⁱ, L0 L0' = P0 (P0 may be singular).
    fn draw_prior(&mut self, x0: &[f64], p0: &[f64]) {
        let n = self.n;
        semidefinite_cholesky(&mut self.factor[..n * n], p0, n);
        draw_noise(&mut self.x, &self.factor[..n * n], n, Stream::new(self.options.seed, 0, Purpose::Prior));
        for xi in self.x.chunks_exact_mut(n) {
            for (v, &m) in xi.iter_mut().zip(x0) {
                *v += m;
            }
        }
    }

    /// Weights the particles by p(y(t) | xⁱ); returns loglik_t (0 when nothing is observed).
    fn update(&mut self, model: &NonlinearModel, y: &[f64], t: usize, u: Option<&[f64]>) -> Result<f64> {
        self.observed.clear();
        self.observed.extend((0..y.len()).filter(|&i| !y[i].is_nan()));
        if self.observed.is_empty() {
            return Ok(0.0);
        }
        let (count, m, mo) = (self.x.len() / self.n, y.len(), self.observed.len());
        let sensor = model.sensor(t);
        sensor.h.eval(&self.x, count, t, u, &mut self.images)?;
        check_finite("h", t, &self.images, "returned a")?;
        // R on the observed components, factored once for all particles
        for (a, &i) in self.observed.iter().enumerate() {
            for (b, &j) in self.observed.iter().enumerate() {
                self.r_obs[a * mo + b] = sensor.r[i * m + j];
            }
        }
        let l = &mut self.r_factor[..mo * mo];
        cholesky(l, &self.r_obs[..mo * mo], mo).map_err(|_| {
            Error::arg_at(
                "R",
                t,
                "is not positive definite on the observed components (the Gaussian likelihood needs it)",
            )
        })?;
        let log_det: f64 = (0..mo).map(|a| l[a * mo + a].ln()).sum::<f64>() * 2.0;
        let constant = -0.5 * (mo as f64 * (2.0 * std::f64::consts::PI).ln() + log_det);
        let e = &mut self.innovation[..mo];
        for (lw, image) in self.log_w.iter_mut().zip(self.images.chunks_exact(m)) {
            for (a, &i) in self.observed.iter().enumerate() {
                let d = y[i] - image[i];
                e[a] = if sensor.angles.contains(&i) { wrap_angle(d) } else { d };
            }
            *lw += constant - 0.5 * solved_norm2(l, e, mo);
        }
        let increment = log_sum_exp(&self.log_w);
        if !increment.is_finite() {
            return Err(Error::arg_at(
                "y",
                t,
                "has no particle that explains it (every likelihood underflowed to 0): use more particles or a wider R",
            ));
        }
        for (lw, w) in self.log_w.iter_mut().zip(&mut self.w) {
            *lw -= increment;
            *w = lw.exp();
        }
        Ok(increment)
    }

    /// The weighted mean and covariance (two passes, one triangle mirrored).
    fn moments(&self, mean: &mut [f64], cov: &mut [f64]) {
        let n = self.n;
        let total: f64 = self.w.iter().sum();
        mean.fill(0.0);
        for (xi, &wi) in self.x.chunks_exact(n).zip(&self.w) {
            for (m, &v) in mean.iter_mut().zip(xi) {
                *m += wi * v;
            }
        }
        mean.iter_mut().for_each(|m| *m /= total);
        cov.fill(0.0);
        let mut d = [0.0; 16];
        let mut d_heap = Vec::new();
        let d: &mut [f64] = if n <= 16 {
            &mut d[..n]
        } else {
            d_heap.resize(n, 0.0);
            &mut d_heap
        };
        for (xi, &wi) in self.x.chunks_exact(n).zip(&self.w) {
            for ((dj, &v), &m) in d.iter_mut().zip(xi).zip(mean.iter()) {
                *dj = v - m;
            }
            for a in 0..n {
                let s = wi * d[a];
                for b in a..n {
                    cov[a * n + b] += s * d[b];
                }
            }
        }
        for a in 0..n {
            for b in a..n {
                cov[a * n + b] /= total;
                cov[b * n + a] = cov[a * n + b];
            }
        }
    }

    /// 1 / Σ Wᵢ² (with the weights normalized by their sum).
    fn ess(&self) -> f64 {
        let (total, squares) = self.w.iter().fold((0.0, 0.0), |(s, q), &w| (s + w, q + w * w));
        total * total / squares
    }

    /// Resamples when the options say so; whether it did.
    fn resample_if_due(&mut self, t: usize) -> bool {
        let count = self.w.len();
        let due = match self.options.ess_threshold {
            None => true,
            Some(tau) => self.ess() < tau * count as f64,
        };
        if !due {
            return false;
        }
        let stream = Stream::new(self.options.seed, t, Purpose::Resampling);
        resample(self.options.resampling, &self.w, stream, &mut self.scratch, &mut self.ancestors);
        let n = self.n;
        for (row, &a) in self.next.chunks_exact_mut(n).zip(&self.ancestors) {
            row.copy_from_slice(&self.x[a * n..][..n]);
        }
        std::mem::swap(&mut self.x, &mut self.next);
        self.log_w.fill(-(count as f64).ln());
        self.w.fill(1.0 / count as f64);
        true
    }

    /// xⁱ ← f(xⁱ, t, u) + wⁱ (or g(xⁱ) wⁱ, or f(xⁱ, wⁱ)), wⁱ ~ N(0, Q(t)).
    fn propagate(&mut self, model: &NonlinearModel, t: usize, u: Option<&[f64]>) -> Result<()> {
        let (n, count) = (self.n, self.w.len());
        let (entry, q) = model.process_noise(t);
        let r = self.noise.len() / count;
        semidefinite_cholesky(&mut self.factor[..r * r], q, r);
        draw_noise(&mut self.noise, &self.factor[..r * r], r, Stream::new(self.options.seed, t, Purpose::ProcessNoise));
        let f = model.transition_function();
        match entry {
            NoiseEntry::Additive => {
                f.eval(&self.x, count, t, u, &mut self.next)?;
                check_finite("f", t, &self.next, "returned a")?;
                for (v, &w) in self.next.iter_mut().zip(&self.noise) {
                    *v += w;
                }
            }
            NoiseEntry::Gain(g) => {
                f.eval(&self.x, count, t, u, &mut self.next)?;
                check_finite("f", t, &self.next, "returned a")?;
                g.eval(&self.x, count, t, u, &mut self.noise_work)?;
                check_finite("g", t, &self.noise_work, "returned a")?;
                let rows = self.next.chunks_exact_mut(n).zip(self.noise_work.chunks_exact(n * r));
                for ((xi, gain), wi) in rows.zip(self.noise.chunks_exact(r)) {
                    for (v, g_row) in xi.iter_mut().zip(gain.chunks_exact(r)) {
                        *v += g_row.iter().zip(wi).map(|(a, b)| a * b).sum::<f64>();
                    }
                }
            }
            NoiseEntry::Input => {
                let rows = self.noise_work.chunks_exact_mut(n + r).zip(self.x.chunks_exact(n));
                for ((point, xi), wi) in rows.zip(self.noise.chunks_exact(r)) {
                    point[..n].copy_from_slice(xi);
                    point[n..].copy_from_slice(wi);
                }
                f.eval(&self.noise_work, count, t, u, &mut self.next)?;
                check_finite("f", t, &self.next, "returned a")?;
            }
        }
        std::mem::swap(&mut self.x, &mut self.next);
        Ok(())
    }
}

/// `out` (rows of `r`) = L zⁱ for the rows i, zⁱ standard normal draws `i r .. (i + 1) r` of
/// `stream`, L lower triangular (r × r).
fn draw_noise(out: &mut [f64], l: &[f64], r: usize, stream: Stream) {
    let mut z = [0.0; 16];
    let mut z_heap = Vec::new();
    let z: &mut [f64] = if r <= 16 {
        &mut z[..r]
    } else {
        z_heap.resize(r, 0.0);
        &mut z_heap
    };
    for (i, row) in out.chunks_exact_mut(r.max(1)).enumerate() {
        for (j, zj) in z.iter_mut().enumerate() {
            *zj = stream.normal((i * r + j) as u64);
        }
        for (a, v) in row.iter_mut().enumerate() {
            *v = l[a * r..][..=a].iter().zip(&z[..=a]).map(|(x, y)| x * y).sum();
        }
    }
}

/// |L⁻¹ e|² by forward substitution (L lower triangular, k × k), e overwritten.
fn solved_norm2(l: &[f64], e: &mut [f64], k: usize) -> f64 {
    let mut total = 0.0;
    for a in 0..k {
        let mut v = e[a];
        for b in 0..a {
            v -= l[a * k + b] * e[b];
        }
        v /= l[a * k + a];
        e[a] = v;
        total += v * v;
    }
    total
}

/// log Σ exp aᵢ, the largest subtracted first; −∞ when every aᵢ is −∞ (or the sum is empty).
fn log_sum_exp(a: &[f64]) -> f64 {
    let top = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !top.is_finite() {
        return top;
    }
    top + a.iter().map(|&v| (v - top).exp()).sum::<f64>().ln()
}
