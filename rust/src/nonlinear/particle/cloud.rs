//! The particles of a filter and the work on them, in blocks of [`BLOCK`] particles that run in
//! parallel. A sum over the particles is summed within each block and then over the blocks in
//! order, and every random draw is addressed by its particle, so the numbers do not depend on
//! the thread count. f and h are called once per block — or once for all particles when they
//! are Python callables, which hold the GIL (the rest of the work still runs on all threads).

use super::custom::ParticleFunction;
use super::exp::exp_nonpositive;
use super::filter::{MeasurementLikelihood, ParticleOptions};
use super::random::{NormalScratch, Purpose, Stream};
use super::resample::{resample, Scratch};
use crate::core::alloc::check_f64_arrays;
use crate::core::batch::par::*;
use crate::core::isa::run_wide;
use crate::error::{Error, Result};
use crate::nonlinear::filter::{check_finite, Sensor};
use crate::nonlinear::function::{wrap_angle, PointFunction};
use crate::nonlinear::model::{NoiseEntry, NonlinearModel};
use crate::nonlinear::quantized::log_cell_probability;
use crate::nonlinear::sigma::{cholesky, semidefinite_cholesky};

/// The particles in a block: fixed, so that the blocks' partial sums (and so the rounding) do
/// not depend on the number of threads.
const BLOCK: usize = 4096;

/// The particles xⁱ with their normalized log-weights λⁱ, and the scratch of a step.
pub(crate) struct Cloud {
    options: ParticleOptions,
    n: usize,
    m: usize,
    /// The size r of the process noise w.
    r: usize,
    /// f, h, g and the user's functions called per block (else once for all particles).
    per_block: bool,
    /// y(t) of the last update (NaN after the time update), for the user's move.
    y_t: Vec<f64>,
    /// xⁱ (M × n).
    x: Vec<f64>,
    /// f(xⁱ), then x(t+1)ⁱ; the resampled particles; the prior's draws (M × n).
    next: Vec<f64>,
    /// λⁱ + `log_w_offset` (M): the log-weights before their normalization, which is left to
    /// the next pass that reads them (log Σ exp λⁱ = 0).
    log_w: Vec<f64>,
    log_w_offset: f64,
    /// Wⁱ up to a common factor (M).
    w: Vec<f64>,
    /// h(xⁱ) (M × m).
    images: Vec<f64>,
    /// wⁱ (M × r).
    noise: Vec<f64>,
    /// g(xⁱ) (M × n r) with a noise gain; the points (xⁱ, wⁱ) (M × (n + r)) with the noise an
    /// input of f.
    noise_work: Vec<f64>,
    /// The lower factor of P0, Q(t) or P(t|t).
    factor: Vec<f64>,
    /// P(t|t) of the last [`moments`](Self::moments), for the regularization's kernel.
    last_cov: Vec<f64>,
    likelihood: Likelihood,
    /// The effective sample size after the last update.
    ess: f64,
    /// Per block: its normal draws' scratch, its outcome, its partial sums.
    normals: Vec<NormalScratch>,
    outcomes: Vec<Result<()>>,
    partials: Vec<f64>,
    ancestors: Vec<usize>,
    resampling: Scratch,
}

impl Cloud {
    pub(crate) fn new(model: &NonlinearModel, options: ParticleOptions) -> Result<Self> {
        let (n, m, count) = (model.n_states(), model.n_obs(), options.particles);
        let (entry, q) = model.process_noise(0);
        let r = (q.len() as f64).sqrt().round() as usize;
        if r == 0 {
            return Err(Error::arg("Q", "is 0 × 0: the particle filter draws process noise (pass zeros for none)"));
        }
        let work = match entry {
            NoiseEntry::Additive => 0,
            NoiseEntry::Gain(_) => n * r,
            NoiseEntry::Input => n + r,
        };
        // x, next, images, noise, noise_work, log_w, w, the indices and the normals' scratch, and
        // the blocks' partial moments
        let blocks = count.div_ceil(BLOCK);
        let per_particle: [&[usize]; 6] =
            [&[count, n], &[count, n], &[count, m], &[count, 2 * r], &[count, work], &[count, 4]];
        check_f64_arrays("n_particles", &[&per_particle[..], &[&[blocks, n * n + n + 2]]].concat())?;
        let likelihood = Likelihood::new(m, &options.likelihood)?;
        let per_block = model.parallel() && options.parallel();
        Ok(Cloud {
            options,
            n,
            m,
            r,
            per_block,
            y_t: vec![f64::NAN; m],
            x: vec![0.0; count * n],
            next: vec![0.0; count * n],
            log_w: vec![-(count as f64).ln(); count],
            log_w_offset: 0.0,
            w: vec![1.0 / count as f64; count],
            images: vec![0.0; count * m],
            noise: vec![0.0; count * r],
            noise_work: vec![0.0; count * work],
            factor: vec![0.0; n.max(r) * n.max(r)],
            last_cov: vec![0.0; n * n],
            likelihood,
            ess: count as f64,
            normals: vec![NormalScratch::default(); blocks],
            outcomes: (0..blocks).map(|_| Ok(())).collect(),
            partials: vec![0.0; blocks * (n * n + n + 2)],
            ancestors: vec![0; count],
            resampling: Scratch::default(),
        })
    }

    /// The number of blocks of particles (the most threads that can share the work).
    pub(crate) fn blocks(&self) -> usize {
        self.normals.len()
    }

    /// M.
    pub(crate) fn count(&self) -> usize {
        self.w.len()
    }

    /// xⁱ (M × n).
    pub(crate) fn particles(&self) -> &[f64] {
        &self.x
    }

    /// λⁱ (M) into `out`.
    pub(crate) fn copy_log_weights(&self, out: &mut [f64]) {
        out.iter_mut().zip(&self.log_w).for_each(|(o, &lw)| *o = lw - self.log_w_offset);
    }

    /// xⁱ = x0 + L0 zⁱ, L0 L0' = P0 (P0 may be singular).
    pub(crate) fn draw_prior(&mut self, x0: &[f64], p0: &[f64]) {
        let n = self.n;
        let l0 = &mut self.factor[..n * n];
        semidefinite_cholesky(l0, p0, n);
        let l0 = &*l0;
        let stream = Stream::new(self.options.seed, 0, Purpose::Prior);
        let blocks = self.x.par_chunks_mut(BLOCK * n).zip(self.next.par_chunks_mut(BLOCK * n));
        blocks.zip(self.normals.par_iter_mut()).enumerate().for_each(|(b, ((x, z), scratch))| {
            stream.normals((b * BLOCK * n) as u64, z, scratch);
            for (xi, zi) in x.chunks_exact_mut(n).zip(z.chunks_exact(n)) {
                for (a, v) in xi.iter_mut().enumerate() {
                    *v = x0[a] + lower_times(l0, n, a, zi);
                }
            }
        });
    }

    /// Weights the particles by p(y(t) | xⁱ); returns loglik_t (0 when nothing is observed).
    /// y(t) is kept for the user's move if it succeeds (else the move sees NaN).
    pub(crate) fn update(&mut self, model: &NonlinearModel, y: &[f64], t: usize, u: Option<&[f64]>) -> Result<f64> {
        let result = self.weigh(model, y, t, u);
        match result {
            Ok(_) => self.y_t.copy_from_slice(y),
            Err(_) => self.y_t.fill(f64::NAN),
        }
        result
    }

    /// [`update`](Self::update) but for keeping y(t).
    fn weigh(&mut self, model: &NonlinearModel, y: &[f64], t: usize, u: Option<&[f64]>) -> Result<f64> {
        let sensor = model.sensor(t);
        if !self.likelihood.prepare(sensor, y, t)? {
            return Ok(0.0);
        }
        let (n, m) = (self.n, self.m);
        let h = sensor.h;
        let user = match &self.likelihood.kind {
            MeasurementLikelihood::User(fun) => Some(&**fun),
            _ => None,
        };
        if !self.per_block {
            // ℓⁱ of the user's likelihood into `w` (overwritten below, read by nothing before;
            // restored from the log-weights after an error)
            let evaluated = match user {
                Some(fun) => fun.eval(&self.x, self.count(), y, t, u, &mut self.w),
                None => h.eval(&self.x, self.count(), t, u, &mut self.images),
            };
            if let Err(e) = evaluated {
                self.restore_weights();
                return Err(e);
            }
        }
        let (per_block, likelihood, offset) = (self.per_block, &self.likelihood, self.log_w_offset);
        let blocks = self.x.par_chunks(BLOCK * n).zip(self.images.par_chunks_mut(BLOCK * m));
        // λⁱ + ℓⁱ (λⁱ normalized here) into `w`, which becomes the log-weights only when the
        // whole update succeeded: after an error the state is what it was
        let blocks = blocks.zip(self.log_w.par_chunks(BLOCK)).zip(self.w.par_chunks_mut(BLOCK));
        let blocks = blocks.zip(self.partials.par_chunks_mut(1)).zip(self.outcomes.par_iter_mut());
        blocks.for_each(|(((((x, images), log_w), sums), top), outcome)| {
            *outcome = (|| {
                let k = log_w.len();
                if let Some(fun) = user {
                    if per_block {
                        fun.eval(x, k, y, t, u, sums)?;
                    }
                    check_log_likelihoods(sums, t)?;
                    sums.iter_mut().zip(log_w).for_each(|(a, lw)| *a += lw - offset);
                    top[0] = sums.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    return Ok(());
                }
                if per_block {
                    h.eval(x, k, t, u, images)?;
                }
                check_finite("h", t, images, "returned a")?;
                let rows = sums.iter_mut().zip(log_w).zip(images.chunks_exact(m));
                match (&likelihood.kind, likelihood.observed.len(), likelihood.any_angle) {
                    (MeasurementLikelihood::User(_), ..) => {} // weighted above
                    (MeasurementLikelihood::Quantized(_), ..) => {
                        rows.for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_cell_probability(image))
                    }
                    (MeasurementLikelihood::Uniform, ..) => {
                        rows.for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_uniform(image))
                    }
                    (&MeasurementLikelihood::StudentT { nu }, _, false) => rows
                        .for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_student::<false>(image, nu)),
                    (&MeasurementLikelihood::StudentT { nu }, _, true) => {
                        rows.for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_student::<true>(image, nu))
                    }
                    (_, 1, false) => {
                        rows.for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_density_scalar(image))
                    }
                    (_, _, false) => {
                        rows.for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_density::<false>(image))
                    }
                    (_, _, true) => {
                        rows.for_each(|((a, lw), image)| *a = (lw - offset) + likelihood.log_density::<true>(image))
                    }
                }
                top[0] = sums.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                Ok(())
            })();
        });
        let failed = first_error(&mut self.outcomes);
        let blocks = self.blocks();
        let top = self.partials[..blocks].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let failed = failed.and_then(|()| match top.is_finite() {
            true => Ok(()),
            false => Err(Error::arg_at(
                "y",
                t,
                "has no particle that explains it (every likelihood underflowed to 0): use more particles or a wider R",
            )),
        });
        if let Err(e) = failed {
            self.restore_weights();
            return Err(e);
        }
        std::mem::swap(&mut self.log_w, &mut self.w);
        // log Σ exp λⁱ with the largest subtracted, summed per block and then in block order
        let blocks_w = self.w.par_chunks_mut(BLOCK).zip(self.log_w.par_chunks(BLOCK));
        blocks_w.zip(self.partials.par_chunks_mut(1)).for_each(|((w, log_w), sum)| {
            // in AVX2 where the CPU has it (the same bits: no FMA)
            sum[0] = run_wide(
                #[inline(always)]
                || exp_and_sum(w, log_w, top),
            );
        });
        let total: f64 = self.partials[..blocks].iter().sum();
        let increment = top + total.ln();
        // λⁱ = log_w − increment from now on; W stays unnormalized (every use divides by ΣW)
        self.log_w_offset = increment;
        Ok(increment)
    }

    /// The weights again from the log-weights, which an update that failed left untouched.
    fn restore_weights(&mut self) {
        let top = self.log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        self.w.iter_mut().zip(&self.log_w).for_each(|(w, &lw)| *w = (lw - top).exp());
    }

    /// The weighted mean and covariance (two passes; one triangle, mirrored) into `mean` and
    /// `cov`; returns the effective sample size (Σ W)² / Σ W².
    pub(crate) fn moments(&mut self, mean: &mut [f64], cov: &mut [f64]) -> f64 {
        // a particle's loops unrolled for the small state sizes (the same sums in the same order)
        match self.n {
            1 => self.moments_sized(Known::<1>, mean, cov),
            2 => self.moments_sized(Known::<2>, mean, cov),
            3 => self.moments_sized(Known::<3>, mean, cov),
            4 => self.moments_sized(Known::<4>, mean, cov),
            n => self.moments_sized(n, mean, cov),
        }
    }

    fn moments_sized(&mut self, size: impl StateSize, mean: &mut [f64], cov: &mut [f64]) -> f64 {
        let (n, blocks) = (self.n, self.blocks());
        let width = n * n + n + 2;
        let sums = self.x.par_chunks(BLOCK * n).zip(self.w.par_chunks(BLOCK));
        sums.zip(self.partials.par_chunks_mut(width)).for_each(|((x, w), part)| {
            let n = size.get();
            lane_sums(w.len(), &mut part[..n + 2], |i, sums| {
                let wi = w[i];
                sums[0] += wi;
                sums[1] += wi * wi;
                for (s, &v) in sums[2..n + 2].iter_mut().zip(&x[i * n..][..n]) {
                    *s += wi * v;
                }
            });
        });
        let (mut total, mut squares) = (0.0, 0.0);
        mean.fill(0.0);
        for part in self.partials.chunks_exact(width).take(blocks) {
            total += part[0];
            squares += part[1];
            mean.iter_mut().zip(&part[2..n + 2]).for_each(|(m, &s)| *m += s);
        }
        mean.iter_mut().for_each(|m| *m /= total);
        let centre = &*mean;
        let sums = self.x.par_chunks(BLOCK * n).zip(self.w.par_chunks(BLOCK));
        sums.zip(self.partials.par_chunks_mut(width)).for_each(|((x, w), part)| {
            let n = size.get();
            lane_sums(w.len(), &mut part[..n * n], |i, upper| {
                let xi = &x[i * n..][..n];
                for a in 0..n {
                    let s = w[i] * (xi[a] - centre[a]);
                    for b in a..n {
                        upper[a * n + b] += s * (xi[b] - centre[b]);
                    }
                }
            });
        });
        cov.fill(0.0);
        for part in self.partials.chunks_exact(width).take(blocks) {
            cov.iter_mut().zip(&part[..n * n]).for_each(|(c, &s)| *c += s);
        }
        for a in 0..n {
            for b in a..n {
                cov[a * n + b] /= total;
                cov[b * n + a] = cov[a * n + b];
            }
        }
        self.last_cov.copy_from_slice(cov);
        self.ess = total * total / squares;
        self.ess
    }

    /// Resamples when the options say so (after [`moments`](Self::moments)), then moves the
    /// particles by the regularization and the user's move, if any; whether it resampled.
    pub(crate) fn resample_if_due(&mut self, t: usize, u: Option<&[f64]>) -> Result<bool> {
        let count = self.count();
        let due = match self.options.ess_threshold {
            None => true,
            Some(tau) => self.ess < tau * count as f64,
        };
        if !due {
            return Ok(false);
        }
        let stream = Stream::new(self.options.seed, t, Purpose::Resampling);
        // N = M / r ancestors, each then taken by r particles in a row (Söderström (9.98))
        let copies = self.options.copies;
        resample(self.options.resampling, &self.w, stream, &mut self.resampling, &mut self.ancestors[..count / copies]);
        if copies > 1 {
            // backwards, so that ancestors[j / r] (j / r < j) is read before it is overwritten
            for j in (0..count).rev() {
                self.ancestors[j] = self.ancestors[j / copies];
            }
        }
        let (n, x) = (self.n, &self.x);
        let blocks = self.next.par_chunks_mut(BLOCK * n).zip(self.ancestors.par_chunks(BLOCK));
        blocks.for_each(|(next, ancestors)| match n {
            // a one-number row without a call of memmove
            1 => next.iter_mut().zip(ancestors).for_each(|(v, &a)| *v = x[a]),
            _ => next.chunks_exact_mut(n).zip(ancestors).for_each(|(row, &a)| row.copy_from_slice(&x[a * n..][..n])),
        });
        std::mem::swap(&mut self.x, &mut self.next);
        let (log_uniform, uniform) = (-(count as f64).ln(), 1.0 / count as f64);
        let blocks = self.log_w.par_chunks_mut(BLOCK).zip(self.w.par_chunks_mut(BLOCK));
        blocks.for_each(|(log_w, w)| {
            log_w.fill(log_uniform);
            w.fill(uniform);
        });
        self.log_w_offset = 0.0;
        if let Some(c) = self.options.regularize {
            self.jitter(t, c);
        }
        if let Some(fun) = self.options.rejuvenate.clone() {
            self.user_move(&*fun, t, u)?;
        }
        Ok(true)
    }

    /// xⁱ ← the user's move of xⁱ (given y(t)), checked finite.
    fn user_move(&mut self, fun: &dyn ParticleFunction, t: usize, u: Option<&[f64]>) -> Result<()> {
        let (n, y) = (self.n, &self.y_t);
        if !self.per_block {
            fun.eval(&self.x, self.count(), y, t, u, &mut self.next)?;
        }
        let blocks = self.x.par_chunks(BLOCK * n).zip(self.next.par_chunks_mut(BLOCK * n));
        blocks.zip(self.outcomes.par_iter_mut()).for_each(|((x, moved), outcome)| {
            *outcome = (|| {
                if self.per_block {
                    fun.eval(x, x.len() / n, y, t, u, moved)?;
                }
                check_finite("move", t, moved, "returned a")
            })();
        });
        first_error(&mut self.outcomes)?;
        std::mem::swap(&mut self.x, &mut self.next);
        Ok(())
    }

    /// The regularization after resampling: xⁱ += h L zⁱ, L L' = P(t|t), zⁱ ~ N(0, I), with
    /// Silverman's bandwidth h = c (4 / (M (n + 2)))^(1/(n + 4)) (see `ParticleOptions`).
    fn jitter(&mut self, t: usize, c: f64) {
        let (n, count) = (self.n, self.count());
        let dims = n as f64;
        let h = c * (4.0 / (count as f64 * (dims + 2.0))).powf(1.0 / (dims + 4.0));
        let l = &mut self.factor[..n * n];
        semidefinite_cholesky(l, &self.last_cov, n);
        let l = &*l;
        let stream = Stream::new(self.options.seed, t, Purpose::Regularization);
        // the normals in `next` (free after the resampling's swap)
        let blocks = self.x.par_chunks_mut(BLOCK * n).zip(self.next.par_chunks_mut(BLOCK * n));
        blocks.zip(self.normals.par_iter_mut()).enumerate().for_each(|(b, ((x, z), scratch))| {
            stream.normals((b * BLOCK * n) as u64, z, scratch);
            for (xi, zi) in x.chunks_exact_mut(n).zip(z.chunks_exact(n)) {
                for (a, v) in xi.iter_mut().enumerate() {
                    *v += h * lower_times(l, n, a, zi);
                }
            }
        });
    }

    /// xⁱ ← f(xⁱ, t, u) + wⁱ (or g(xⁱ) wⁱ, or f(xⁱ, wⁱ)), wⁱ = L_Q zⁱ ~ N(0, Q(t)).
    pub(crate) fn propagate(&mut self, model: &NonlinearModel, t: usize, u: Option<&[f64]>) -> Result<()> {
        let (n, r, count, per_block) = (self.n, self.r, self.count(), self.per_block);
        let (entry, q) = model.process_noise(t);
        let l_q = &mut self.factor[..r * r];
        semidefinite_cholesky(l_q, q, r);
        let l_q = &*l_q;
        let f = model.transition_function();
        let stream = Stream::new(self.options.seed, t, Purpose::ProcessNoise);
        let blocks = self.noise.par_chunks_mut(BLOCK * r).zip(self.normals.par_iter_mut());
        blocks.enumerate().for_each(|(b, (noise, scratch))| {
            stream.normals((b * BLOCK * r) as u64, noise, scratch);
            match r {
                1 => noise.iter_mut().for_each(|v| *v *= l_q[0]),
                2 => correlate(Known::<2>, l_q, noise),
                3 => correlate(Known::<3>, l_q, noise),
                4 => correlate(Known::<4>, l_q, noise),
                r => correlate(r, l_q, noise),
            }
        });
        if matches!(entry, NoiseEntry::Input) {
            // the points (x, w) of f
            let rows = self.noise_work.par_chunks_mut(n + r).zip(self.x.par_chunks(n));
            rows.zip(self.noise.par_chunks(r)).for_each(|((point, xi), wi)| {
                point[..n].copy_from_slice(xi);
                point[n..].copy_from_slice(wi);
            });
        }
        if let NoiseEntry::Gain(g) = entry {
            self.noise_gains(g, t, u)?;
        }
        let (f_in, f_width) = match entry {
            NoiseEntry::Input => (&self.noise_work, n + r),
            _ => (&self.x, n),
        };
        if !per_block {
            f.eval(f_in, count, t, u, &mut self.next)?;
        }
        // f per block, and the noise added
        let gains = &self.noise_work;
        let blocks = self.next.par_chunks_mut(BLOCK * n).zip(f_in.par_chunks(BLOCK * f_width));
        let blocks = blocks.zip(self.noise.par_chunks(BLOCK * r)).zip(self.outcomes.par_iter_mut());
        blocks.enumerate().for_each(|(b, (((next, points), noise), outcome))| {
            *outcome = (|| {
                let k = next.len() / n;
                if per_block {
                    f.eval(points, k, t, u, next)?;
                }
                check_finite("f", t, next, "returned a")?;
                match entry {
                    NoiseEntry::Additive => next.iter_mut().zip(noise).for_each(|(v, &w)| *v += w),
                    NoiseEntry::Gain(_) => {
                        let gain = &gains[b * BLOCK * n * r..][..k * n * r];
                        let rows = next.chunks_exact_mut(n).zip(gain.chunks_exact(n * r));
                        for ((xi, gi), wi) in rows.zip(noise.chunks_exact(r)) {
                            for (v, g_row) in xi.iter_mut().zip(gi.chunks_exact(r)) {
                                *v += g_row.iter().zip(wi).map(|(a, b)| a * b).sum::<f64>();
                            }
                        }
                    }
                    NoiseEntry::Input => {}
                }
                Ok(())
            })();
        });
        first_error(&mut self.outcomes)?;
        std::mem::swap(&mut self.x, &mut self.next);
        self.y_t.fill(f64::NAN);
        Ok(())
    }

    /// g(xⁱ) into `noise_work` (M × n r), checked finite.
    fn noise_gains(&mut self, g: &dyn PointFunction, t: usize, u: Option<&[f64]>) -> Result<()> {
        let (n, r) = (self.n, self.r);
        if !self.per_block {
            g.eval(&self.x, self.count(), t, u, &mut self.noise_work)?;
            return check_finite("g", t, &self.noise_work, "returned a");
        }
        let blocks = self.x.par_chunks(BLOCK * n).zip(self.noise_work.par_chunks_mut(BLOCK * n * r));
        blocks.zip(self.outcomes.par_iter_mut()).for_each(|((x, gains), outcome)| {
            *outcome = g.eval(x, x.len() / n, t, u, gains).and_then(|()| check_finite("g", t, gains, "returned a"));
        });
        first_error(&mut self.outcomes)
    }
}

/// A state (or noise) size known at compile time ([`Known`]) or at run time (`usize`): the
/// loops over a particle's numbers unroll, and their sums stay in registers, for the first.
trait StateSize: Copy + Send + Sync {
    fn get(self) -> usize;
}

impl StateSize for usize {
    #[inline(always)]
    fn get(self) -> usize {
        self
    }
}

#[derive(Clone, Copy)]
struct Known<const N: usize>;

impl<const N: usize> StateSize for Known<N> {
    #[inline(always)]
    fn get(self) -> usize {
        N
    }
}

/// `w[i] = exp(log_w[i] − top)` (all ≤ 0) and their sum.
#[inline(always)]
fn exp_and_sum(w: &mut [f64], log_w: &[f64], top: f64) -> f64 {
    w.iter_mut().zip(log_w).for_each(|(wi, &lw)| *wi = exp_nonpositive(lw - top));
    let mut total = 0.0;
    lane_sums(w.len(), std::slice::from_mut(&mut total), |i, sum| sum[0] += w[i]);
    total
}

/// `sums` = Σᵢ contribution(i) over the particles `0..count` of a block, each contribution
/// added to `sums`-sized accumulators by `add(i, accumulators)`: with up to 64 sums, particle i
/// goes to lane i mod 4 of four accumulators, added together at the end — four independent
/// chains of additions instead of one, the order fixed by the block.
#[inline(always)]
fn lane_sums(count: usize, sums: &mut [f64], add: impl Fn(usize, &mut [f64])) {
    const LANES: usize = 4;
    let width = sums.len();
    sums.fill(0.0);
    if width > 64 {
        (0..count).for_each(|i| add(i, sums));
        return;
    }
    let mut lanes = [[0.0; 64]; LANES];
    let groups = count / LANES;
    for g in 0..groups {
        for (l, lane) in lanes.iter_mut().enumerate() {
            add(g * LANES + l, &mut lane[..width]);
        }
    }
    for i in groups * LANES..count {
        add(i, &mut lanes[0][..width]);
    }
    for (k, s) in sums.iter_mut().enumerate() {
        *s = (lanes[0][k] + lanes[1][k]) + (lanes[2][k] + lanes[3][k]);
    }
}

/// zⁱ ← L zⁱ in place for the rows zⁱ of `z` (L lower triangular, size × size).
#[inline(always)]
fn correlate(size: impl StateSize, l: &[f64], z: &mut [f64]) {
    let size = size.get();
    for zi in z.chunks_exact_mut(size) {
        // row a of L reads z up to a, so go from the last row up
        for a in (0..size).rev() {
            zi[a] = lower_times(l, size, a, zi);
        }
    }
}

/// Row `a` of the lower triangular `l` (size × size) times `z`: Σ_{c ≤ a} l[a, c] z[c].
#[inline(always)]
fn lower_times(l: &[f64], size: usize, a: usize, z: &[f64]) -> f64 {
    l[a * size..][..=a].iter().zip(&z[..=a]).map(|(x, y)| x * y).sum()
}

/// The user's log-likelihoods of step t: numbers or −∞ (a zero likelihood).
fn check_log_likelihoods(values: &[f64], t: usize) -> Result<()> {
    match values.iter().position(|v| v.is_nan() || *v == f64::INFINITY) {
        Some(i) => Err(Error::arg_at(
            "likelihood",
            t,
            format!("returned {} for a particle (a log-likelihood is a number or -inf)", values[i]),
        )),
        None => Ok(()),
    }
}

/// The first block's error, in block order (so the same error whatever the threads); the
/// outcomes reset.
fn first_error(outcomes: &mut [Result<()>]) -> Result<()> {
    let mut first = Ok(());
    for outcome in outcomes.iter_mut() {
        let result = std::mem::replace(outcome, Ok(()));
        if first.is_ok() {
            first = result;
        }
    }
    first
}

/// The likelihood of one step on its observed components ([`MeasurementLikelihood`]).
struct Likelihood {
    kind: MeasurementLikelihood,
    /// Per observed component: its quantization cell [lo, hi) and noise std, or (−a, a, 0)
    /// for uniform noise of half-width a.
    cells: Vec<(f64, f64, f64)>,
    observed: Vec<usize>,
    /// y on the observed components.
    y_obs: Vec<f64>,
    /// Whether each observed component is an angle, and whether any is.
    angle: Vec<bool>,
    any_angle: bool,
    /// L⁻¹, L the lower factor of R on the observed components.
    l_inv: Vec<f64>,
    r_obs: Vec<f64>,
    /// The log density's constant: −½ (m_o log 2π + log det R_o) (Gaussian), its Student-t
    /// form, or −Σ log 2a_i (uniform).
    constant: f64,
}

impl Likelihood {
    fn new(m: usize, kind: &MeasurementLikelihood) -> Result<Self> {
        if let MeasurementLikelihood::Quantized(sensor) = kind {
            if sensor.n_obs() != m {
                return Err(Error::arg(
                    "likelihood",
                    format!("the quantizer has {} components (delta), the model {m} outputs", sensor.n_obs()),
                ));
            }
        }
        Ok(Likelihood {
            kind: kind.clone(),
            cells: Vec::with_capacity(m),
            observed: Vec::with_capacity(m),
            y_obs: Vec::with_capacity(m),
            angle: Vec::with_capacity(m),
            any_angle: false,
            l_inv: vec![0.0; m * m],
            r_obs: vec![0.0; m * m],
            constant: 0.0,
        })
    }

    /// Sets up step t; false when nothing is observed.
    fn prepare(&mut self, sensor: Sensor<'_>, y: &[f64], t: usize) -> Result<bool> {
        let m = y.len();
        self.observed.clear();
        self.observed.extend((0..m).filter(|&i| !y[i].is_nan()));
        let mo = self.observed.len();
        if mo == 0 {
            return Ok(false);
        }
        if matches!(self.kind, MeasurementLikelihood::User(_)) {
            return Ok(true);
        }
        self.y_obs.clear();
        self.y_obs.extend(self.observed.iter().map(|&i| y[i]));
        self.angle.clear();
        self.angle.extend(self.observed.iter().map(|i| sensor.angles.contains(i)));
        self.any_angle = self.angle.contains(&true);
        if matches!(self.kind, MeasurementLikelihood::Quantized(_) | MeasurementLikelihood::Uniform) {
            return self.prepare_cells(sensor.r, y, t).map(|()| true);
        }
        for (a, &i) in self.observed.iter().enumerate() {
            for (b, &j) in self.observed.iter().enumerate() {
                self.r_obs[a * mo + b] = sensor.r[i * m + j];
            }
        }
        // L (into l_inv), then its inverse column by column in r_obs, copied back
        let l = &mut self.l_inv[..mo * mo];
        cholesky(l, &self.r_obs[..mo * mo], mo).map_err(|_| {
            Error::arg_at(
                "R",
                t,
                "is not positive definite on the observed components (the Gaussian likelihood needs it)",
            )
        })?;
        let log_det: f64 = 2.0 * (0..mo).map(|a| l[a * mo + a].ln()).sum::<f64>();
        let dims = mo as f64;
        self.constant = match self.kind {
            MeasurementLikelihood::StudentT { nu } => {
                libm::lgamma(0.5 * (nu + dims))
                    - libm::lgamma(0.5 * nu)
                    - 0.5 * (dims * (nu * std::f64::consts::PI).ln() + log_det)
            }
            _ => -0.5 * (dims * (2.0 * std::f64::consts::PI).ln() + log_det),
        };
        let inverse = &mut self.r_obs[..mo * mo];
        inverse.fill(0.0);
        for c in 0..mo {
            for a in c..mo {
                let mut v = if a == c { 1.0 } else { 0.0 };
                for b in c..a {
                    v -= l[a * mo + b] * inverse[b * mo + c];
                }
                inverse[a * mo + c] = v / l[a * mo + a];
            }
        }
        l.copy_from_slice(inverse);
        Ok(true)
    }

    /// Per observed component of y(t): its quantization cell and noise std, or the uniform
    /// noise's half-width (R diagonal there).
    fn prepare_cells(&mut self, r: &[f64], y: &[f64], t: usize) -> Result<()> {
        let m = y.len();
        self.cells.clear();
        self.constant = 0.0;
        for &i in &self.observed {
            if let Some(&j) = self.observed.iter().find(|&&j| j != i && r[i * m + j] != 0.0) {
                return Err(Error::arg_at(
                    "R",
                    t,
                    format!("components {i} and {j} are correlated: this likelihood needs R diagonal"),
                ));
            }
            let var = r[i * m + i];
            match &self.kind {
                MeasurementLikelihood::Quantized(quantizer) => {
                    let (lo, hi) = quantizer.cell(i, y[i]).map_err(|e| e.at_step(Some(t)))?;
                    self.cells.push((lo, hi, var.sqrt()));
                }
                _ if var <= 0.0 => {
                    return Err(Error::arg_at("R", t, format!("component {i}: uniform noise needs a variance > 0")));
                }
                _ => {
                    let half = (3.0 * var).sqrt();
                    self.cells.push((-half, half, 0.0));
                    self.constant -= (2.0 * half).ln();
                }
            }
        }
        Ok(())
    }

    /// log of the uniform density: the constant inside every component's box, −∞ outside
    /// (an angle's residual wrapped).
    #[inline(always)]
    fn log_uniform(&self, image: &[f64]) -> f64 {
        let residuals = self.observed.iter().zip(&self.y_obs).zip(&self.cells).zip(&self.angle);
        let inside = residuals.into_iter().all(|(((&i, &y), &(_, half, _)), &angle)| {
            let e = y - image[i];
            (if angle { wrap_angle(e) } else { e }).abs() <= half
        });
        if inside {
            self.constant
        } else {
            f64::NEG_INFINITY
        }
    }

    /// log of the Student-t density with scale R on the observed components.
    #[inline(always)]
    fn log_student<const ANGLES: bool>(&self, image: &[f64], nu: f64) -> f64 {
        let dims = self.observed.len() as f64;
        self.constant - 0.5 * (nu + dims) * (self.squares::<ANGLES>(image) / nu).ln_1p()
    }

    /// log P(y's cells | image): the quantized likelihood on the observed components. An
    /// angle's image is first moved by whole turns to within π of its cell (the mass that
    /// wraps around more than once is neglected).
    #[inline(always)]
    fn log_cell_probability(&self, image: &[f64]) -> f64 {
        let cells = self.observed.iter().zip(&self.cells).zip(&self.angle);
        cells
            .map(|((&i, &(lo, hi, std)), &angle)| {
                let centre = 0.5 * (lo + hi);
                let pred = if angle && centre.is_finite() { centre - wrap_angle(centre - image[i]) } else { image[i] };
                log_cell_probability(lo, hi, pred, std)
            })
            .sum()
    }

    /// log N(y; image, R) on the observed components (`ANGLES`: some are angles, whose
    /// residuals are wrapped; without, no wrapping is even computed).
    #[inline(always)]
    fn log_density<const ANGLES: bool>(&self, image: &[f64]) -> f64 {
        self.constant - 0.5 * self.squares::<ANGLES>(image)
    }

    /// e' R⁻¹ e, e = y − image on the observed components.
    #[inline(always)]
    fn squares<const ANGLES: bool>(&self, image: &[f64]) -> f64 {
        let mo = self.observed.len();
        let mut squares = 0.0;
        for a in 0..mo {
            let mut z = 0.0;
            for b in 0..=a {
                let d = self.y_obs[b] - image[self.observed[b]];
                z += self.l_inv[a * mo + b] * if ANGLES && self.angle[b] { wrap_angle(d) } else { d };
            }
            squares += z * z;
        }
        squares
    }

    /// [`log_density`](Self::log_density) of one observed component that is not an angle.
    #[inline(always)]
    fn log_density_scalar(&self, image: &[f64]) -> f64 {
        let z = self.l_inv[0] * (self.y_obs[0] - image[self.observed[0]]);
        self.constant - 0.5 * (z * z)
    }
}
