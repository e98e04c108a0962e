//! Many independent series through one model, in parallel (rayon): [`filter_batch`].
//!
//! When no value is missing, the prior covariance is shared and (so) the covariance
//! recursion does not depend on the data, it is computed once: P H', the L D L' factor of S
//! and log det S per step. Each series then only moves its state, with exactly the
//! operations of the full recursion (so its results are bit-for-bit those of filtering it
//! alone), at O(n² + nm + m²) per series-step. Otherwise every series runs the full filter.
//! `filter_batch` is a pure function of (model, block of series): it maps unchanged over
//! chunks of series.

use crate::core::batch::par::{self, *};
use crate::core::batch::{prefix_series, thread_count, Batch, BatchOutputs, SeriesSizes};
use crate::core::dims::{with_dims, Dims, Dyn};
use crate::core::gaussian::{LogDet, LoglikSum};
use crate::core::isa::{kernel, run_best, Kernel};
use crate::error::Result;
use crate::linear::filter::{check_data, check_series, FilterOutputs, Run, UpdateForm, Workspace};
use crate::linear::model::LinearGaussian;

/// Whether the covariance recursion can be shared: a covariance form (Joseph or standard), no
/// missing value and one prior covariance. The robust forms filter each series alone.
pub fn shares_covariances(model: &LinearGaussian, batch: &Batch<'_>, form: UpdateForm) -> bool {
    let n = model.n_states();
    form.is_covariance_form() && batch.p0.len() == n * n && !batch.y.iter().any(|v| v.is_nan())
}

/// Filters every series of `batch` with the covariance update `form` (in parallel on `threads` threads, all cores when `None`;
/// never more threads than series or than the machine's cores, which would only add
/// overhead); returns whether the covariances were shared (then `p_filt` is `T × n × n`).
pub fn filter_batch(
    model: &LinearGaussian,
    batch: Batch<'_>,
    form: UpdateForm,
    out: BatchOutputs<'_>,
    threads: Option<usize>,
) -> Result<bool> {
    let shared = shares_covariances(model, &batch, form);
    check_batch(model, &batch, &out, shared)?;
    // One choice of loops for the whole call, so that every series and the shared
    // covariance recursion compute with the same arithmetic.
    let kernel = kernel();
    par::on_threads(thread_count(threads, batch.series), || {
        if shared {
            run_shared(model, &batch, form, out, kernel)
        } else {
            run_each(model, &batch, form, out, kernel)
        }
    })?;
    Ok(shared)
}

fn check_batch(model: &LinearGaussian, b: &Batch<'_>, out: &BatchOutputs<'_>, shared: bool) -> Result<()> {
    let sizes = sizes(model);
    b.check_lengths(sizes)?;
    // Validate each series as the single-series filter would; a shared prior only once.
    let shared_prior = b.shared_prior(sizes.n);
    for s in 0..b.series {
        let (y, u, x0, p0) = b.part(s, sizes);
        let checked = if shared_prior && s > 0 {
            check_series(model, y, u).map(|_| ())
        } else {
            check_data(model, y, u, x0, p0).map(|_| ())
        };
        checked.map_err(|e| prefix_series(e, s))?;
    }
    let (n, t) = (sizes.n, b.steps);
    let covs = if shared { Some(t * n * n) } else { (b.series * t).checked_mul(n * n) };
    out.check_lengths(b.series, t, n, covs)
}

fn sizes(model: &LinearGaussian) -> SeriesSizes {
    SeriesSizes { n: model.n_states(), m: model.n_obs(), k: model.n_inputs() }
}

/// The data-independent covariance recursion, once: per step P H', the L D L' factor of S, log det S, P(t|t).
struct SharedGains {
    pht: Vec<f64>,
    s_factor: Vec<f64>,
    log_det: Vec<LogDet>,
    p_filt: Vec<f64>,
}

#[inline(always)]
fn shared_gains<D: Dims>(d: D, model: &LinearGaussian, b: &Batch<'_>, form: UpdateForm) -> Result<SharedGains> {
    let (n, t) = (d.n(), b.steps);
    let m = d.m();
    let mut ws = Workspace::new(d, model.n_inputs(), &vec![0.0; n], b.p0);
    let zeros = vec![0.0; m];
    let zeros_u = vec![0.0; model.n_inputs()];
    let mut g = SharedGains {
        pht: Vec::with_capacity(t * n * m),
        s_factor: Vec::with_capacity(t * m * m),
        log_det: Vec::with_capacity(t),
        p_filt: Vec::with_capacity(t * n * n),
    };
    let u = model.has_input().then_some(zeros_u.as_slice());
    for step in 0..t {
        let sys = model.at(step);
        ws.update(&sys, &zeros, u, form, step)?;
        let (pht, s_factor, log_det) = ws.gains();
        g.pht.extend_from_slice(pht);
        g.s_factor.extend_from_slice(s_factor);
        g.log_det.push(log_det);
        g.p_filt.extend_from_slice(ws.p_filt());
        ws.predict(&sys, u);
    }
    Ok(g)
}

fn run_shared(
    model: &LinearGaussian,
    b: &Batch<'_>,
    form: UpdateForm,
    out: BatchOutputs<'_>,
    kernel: Kernel,
) -> Result<()> {
    let (n, m) = (model.n_states(), model.n_obs());
    let gains = run_best!(kernel, Dyn { n, m }, |d| shared_gains(d, model, b, form))?;
    if let Some(p) = out.p_filt {
        p.copy_from_slice(&gains.p_filt);
    }
    with_dims!(kernel, n, m, |d| means_only_all(d, kernel, model, b, form, &gains, out.x_filt, out.loglik));
    Ok(())
}

/// Every series' state recursion with the shared gains, in parallel.
#[allow(clippy::too_many_arguments)]
fn means_only_all<D: Dims>(
    d: D,
    kernel: Kernel,
    model: &LinearGaussian,
    b: &Batch<'_>,
    form: UpdateForm,
    gains: &SharedGains,
    x_filt: &mut [f64],
    loglik: &mut [f64],
) {
    let (n, t) = (d.n(), b.steps);
    let rows = x_filt.par_chunks_mut(t * n).zip(loglik.par_iter_mut()).enumerate();
    rows.for_each(|(s, (x_out, ll))| {
        let (y, u, x0, p0) = b.part(s, sizes(model));
        let run = Run { model, y, u, x0, p0, form, converge_tol: None, kernel, start: 0 };
        // Each series in a loop of the call's instruction set (a closure run by the thread
        // pool is not compiled with it).
        *ll = run_best!(kernel, d, |d| run.means_only(d, gains, x_out));
    });
}

impl Run<'_> {
    /// The state recursion of one series with the shared gains; returns its log-likelihood.
    #[inline(always)]
    fn means_only<D: Dims>(&self, d: D, g: &SharedGains, x_out: &mut [f64]) -> f64 {
        let (n, m) = (self.model.n_states(), self.model.n_obs());
        let mut ws = Workspace::new(d, self.model.n_inputs(), self.x0, self.p0);
        let mut total = LoglikSum::default();
        for t in 0..self.y.steps() {
            let sys = self.model.at(t);
            let u_t = self.u.map(|u| u.row(t));
            ws.load_gains(&g.pht[t * n * m..(t + 1) * n * m], &g.s_factor[t * m * m..(t + 1) * m * m], g.log_det[t]);
            // Never fails: the data are complete and the gains were computed already.
            let _ = ws.update(&sys, self.y.row(t), u_t, self.form, t);
            ws.predict(&sys, u_t);
            ws.add_loglik(&mut total);
            x_out[t * n..(t + 1) * n].copy_from_slice(ws.x_filt());
        }
        total.total()
    }
}

fn run_each(
    model: &LinearGaussian,
    b: &Batch<'_>,
    form: UpdateForm,
    out: BatchOutputs<'_>,
    kernel: Kernel,
) -> Result<()> {
    let (n, m, t) = (model.n_states(), model.n_obs(), b.steps);
    let covs: Vec<Option<&mut [f64]>> = match out.p_filt {
        Some(p) => p.chunks_mut(t * n * n).map(Some).collect(),
        None => (0..b.series).map(|_| None).collect(),
    };
    out.x_filt.par_chunks_mut(t * n).zip(out.loglik.par_iter_mut()).zip(covs).enumerate().try_for_each(
        |(s, ((x_out, ll), p_out))| -> Result<()> {
            let (y, u, x0, p0) = b.part(s, sizes(model));
            let run = Run { model, y, u, x0, p0, form, converge_tol: None, kernel, start: 0 };
            let mut o = FilterOutputs::default();
            (o.x_filt, o.p_filt) = (Some(x_out), p_out);
            *ll = with_dims!(kernel, n, m, |d| run.filter(d, &mut o)).map_err(|e| prefix_series(e, s))?;
            Ok(())
        },
    )
}
