//! Many independent series through one model, in parallel (rayon): [`filter_batch`].
//!
//! When no value is missing, the prior covariance is shared and (so) the covariance
//! recursion does not depend on the data, it is computed once: P H', the L D L' factor of S
//! and log det S per step. Each series then only moves its state, with exactly the
//! operations of the full recursion (so its results are bit-for-bit those of filtering it
//! alone), at O(n² + nm + m²) per series-step. Otherwise every series runs the full filter.
//! `filter_batch` is a pure function of (model, block of series): it maps unchanged over
//! chunks of series.

use par::*;

use crate::core::alloc::check_f64_arrays;
use crate::core::dims::{with_dims, Dims, Dyn};
use crate::core::gaussian::{LogDet, LoglikSum};
use crate::core::isa::{kernel, run_best, Kernel};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::filter::{check_data, check_series, FilterOutputs, Run, UpdateForm, Workspace};
use crate::linear::model::LinearGaussian;

/// Series `(B, T, m)`, inputs, priors and options of a batch.
#[derive(Debug, Clone, Copy)]
pub struct Batch<'a> {
    /// Observations, `B × T × m` row-major; NaN = missing.
    pub y: &'a [f64],
    /// Number of series B.
    pub series: usize,
    /// Steps per series T.
    pub steps: usize,
    /// Inputs `B × T × k`, or `T × k` shared by all series.
    pub u: Option<&'a [f64]>,
    /// Whether `u` is shared (`T × k`).
    pub u_shared: bool,
    /// Prior means: `n` (shared) or `B × n`.
    pub x0: &'a [f64],
    /// Prior covariances: `n × n` (shared) or `B × n × n`.
    pub p0: &'a [f64],
    /// Covariance update form.
    pub form: UpdateForm,
}

/// Output buffers of [`filter_batch`].
#[derive(Debug)]
pub struct BatchOutputs<'a> {
    /// x̂(t|t) of every series, `B × T × n`.
    pub x_filt: &'a mut [f64],
    /// P(t|t): `T × n × n` when [`filter_batch`] returns `true` (shared by all series),
    /// else `B × T × n × n`; `None` to skip covariances.
    pub p_filt: Option<&'a mut [f64]>,
    /// Log-likelihood of each series, `B`.
    pub loglik: &'a mut [f64],
}

/// Whether the covariance recursion can be shared: no missing value and one prior covariance.
pub fn shares_covariances(model: &LinearGaussian, batch: &Batch<'_>) -> bool {
    let n = model.n_states();
    batch.p0.len() == n * n && !batch.y.iter().any(|v| v.is_nan())
}

/// Filters every series of `batch` (in parallel on `threads` threads, all cores when `None`;
/// never more threads than series or than the machine's cores, which would only add
/// overhead); returns whether the covariances were shared (then `p_filt` is `T × n × n`).
pub fn filter_batch(
    model: &LinearGaussian,
    batch: Batch<'_>,
    out: BatchOutputs<'_>,
    threads: Option<usize>,
) -> Result<bool> {
    let shared = shares_covariances(model, &batch);
    check_batch(model, &batch, &out, shared)?;
    // One choice of loops for the whole call, so that every series and the shared
    // covariance recursion compute with the same arithmetic.
    let kernel = kernel();
    par::on_threads(thread_count(threads, batch.series), || {
        if shared {
            run_shared(model, &batch, out, kernel)
        } else {
            run_each(model, &batch, out, kernel)
        }
    })?;
    Ok(shared)
}

/// The pool size for `series` series: `requested` (all cores when `None`), at most one thread
/// per series or per core.
fn thread_count(requested: Option<usize>, series: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    requested.unwrap_or(cores).min(cores).min(series).max(1)
}

fn check_batch(model: &LinearGaussian, b: &Batch<'_>, out: &BatchOutputs<'_>, shared: bool) -> Result<()> {
    let (n, m, k) = (model.n_states(), model.n_obs(), model.n_inputs());
    let (bs, t) = (b.series, b.steps);
    if bs.checked_mul(t).and_then(|bt| bt.checked_mul(m)) != Some(b.y.len()) {
        return Err(Error::arg("Y", format!("expected {bs} × {t} × {m} values, got {}", b.y.len())));
    }
    if bs == 0 {
        return Err(Error::arg("Y", "has no series (B = 0)"));
    }
    // B × T × max(n, k) fits in memory, so the products below cannot overflow.
    check_f64_arrays("Y", &[&[bs, t, n.max(k)]])?;
    if b.x0.len() != n && bs.checked_mul(n) != Some(b.x0.len()) {
        return Err(Error::arg("x0", format!("expected shape ({n},) or ({bs}, {n}), got {} values", b.x0.len())));
    }
    if b.p0.len() != n * n && bs.checked_mul(n * n) != Some(b.p0.len()) {
        return Err(Error::arg(
            "P0",
            format!("expected shape ({n}, {n}) or ({bs}, {n}, {n}), got {} values", b.p0.len()),
        ));
    }
    if let Some(u) = b.u {
        let want = if b.u_shared { t * k } else { bs * t * k };
        if u.len() != want {
            return Err(Error::arg("u", format!("expected {want} values, got {}", u.len())));
        }
    }
    // Validate each series as the single-series filter would; a shared prior only once.
    let shared_prior = b.x0.len() == n && b.p0.len() == n * n;
    for s in 0..bs {
        let (y, u, x0, p0) = series_parts(model, b, s);
        let checked = if shared_prior && s > 0 {
            check_series(model, y, u).map(|_| ())
        } else {
            check_data(model, y, u, x0, p0).map(|_| ())
        };
        checked.map_err(|e| prefix_series(e, s))?;
    }
    let covs = if shared { Some(t * n * n) } else { (bs * t).checked_mul(n * n) };
    for (arg, got, want) in [
        ("x_filt", Some(out.x_filt.len()), Some(bs * t * n)),
        ("P_filt", out.p_filt.as_ref().map(|p| p.len()), covs),
        ("loglik", Some(out.loglik.len()), Some(bs)),
    ] {
        if let Some(got) = got {
            if Some(got) != want {
                let want = want.map_or("more than fit in memory".to_string(), |w| w.to_string());
                return Err(Error::arg(arg, format!("output buffer has {got} entries, needs {want}")));
            }
        }
    }
    Ok(())
}

fn prefix_series(e: Error, s: usize) -> Error {
    match e {
        Error::InvalidArgument { arg, step, problem } => Error::InvalidArgument {
            arg: if arg == "y" { "Y" } else { arg },
            step,
            problem: format!("(series {s}) {problem}"),
        },
        Error::InnovationCovariance { step, problem } => {
            Error::InnovationCovariance { step, problem: format!("(series {s}) {problem}") }
        }
        other => other,
    }
}

/// Series `s`: its data, inputs and prior.
fn series_parts<'a>(
    model: &LinearGaussian,
    b: &Batch<'a>,
    s: usize,
) -> (Series<'a>, Option<Series<'a>>, &'a [f64], &'a [f64]) {
    let (n, m, k, t) = (model.n_states(), model.n_obs(), model.n_inputs(), b.steps);
    let y = Series::new("Y", &b.y[s * t * m..(s + 1) * t * m], t, m).expect("sizes checked");
    let u = b.u.map(|u| {
        let rows = if b.u_shared { u } else { &u[s * t * k..(s + 1) * t * k] };
        Series::new("u", rows, t, k).expect("sizes checked")
    });
    let x0 = if b.x0.len() == n { b.x0 } else { &b.x0[s * n..(s + 1) * n] };
    let p0 = if b.p0.len() == n * n { b.p0 } else { &b.p0[s * n * n..(s + 1) * n * n] };
    (y, u, x0, p0)
}

/// The data-independent covariance recursion, once: per step P H', the L D L' factor of S, log det S, P(t|t).
struct SharedGains {
    pht: Vec<f64>,
    s_factor: Vec<f64>,
    log_det: Vec<LogDet>,
    p_filt: Vec<f64>,
}

#[inline(always)]
fn shared_gains<D: Dims>(d: D, model: &LinearGaussian, b: &Batch<'_>) -> Result<SharedGains> {
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
        ws.update(&sys, &zeros, u, b.form, step)?;
        let (pht, s_factor, log_det) = ws.gains();
        g.pht.extend_from_slice(pht);
        g.s_factor.extend_from_slice(s_factor);
        g.log_det.push(log_det);
        g.p_filt.extend_from_slice(ws.p_filt());
        ws.predict(&sys, u);
    }
    Ok(g)
}

fn run_shared(model: &LinearGaussian, b: &Batch<'_>, out: BatchOutputs<'_>, kernel: Kernel) -> Result<()> {
    let (n, m) = (model.n_states(), model.n_obs());
    let gains = run_best!(kernel, Dyn { n, m }, |d| shared_gains(d, model, b))?;
    if let Some(p) = out.p_filt {
        p.copy_from_slice(&gains.p_filt);
    }
    with_dims!(n, m, |d| means_only_all(d, kernel, model, b, &gains, out.x_filt, out.loglik));
    Ok(())
}

/// Every series' state recursion with the shared gains, in parallel.
fn means_only_all<D: Dims>(
    d: D,
    kernel: Kernel,
    model: &LinearGaussian,
    b: &Batch<'_>,
    gains: &SharedGains,
    x_filt: &mut [f64],
    loglik: &mut [f64],
) {
    let (n, t) = (d.n(), b.steps);
    let rows = x_filt.par_chunks_mut(t * n).zip(loglik.par_iter_mut()).enumerate();
    rows.for_each(|(s, (x_out, ll))| {
        let (y, u, x0, p0) = series_parts(model, b, s);
        let run = Run { model, y, u, x0, p0, form: b.form, converge_tol: None, kernel };
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

fn run_each(model: &LinearGaussian, b: &Batch<'_>, out: BatchOutputs<'_>, kernel: Kernel) -> Result<()> {
    let (n, m, t) = (model.n_states(), model.n_obs(), b.steps);
    let covs: Vec<Option<&mut [f64]>> = match out.p_filt {
        Some(p) => p.chunks_mut(t * n * n).map(Some).collect(),
        None => (0..b.series).map(|_| None).collect(),
    };
    out.x_filt.par_chunks_mut(t * n).zip(out.loglik.par_iter_mut()).zip(covs).enumerate().try_for_each(
        |(s, ((x_out, ll), p_out))| -> Result<()> {
            let (y, u, x0, p0) = series_parts(model, b, s);
            let run = Run { model, y, u, x0, p0, form: b.form, converge_tol: None, kernel };
            let mut o = FilterOutputs::default();
            (o.x_filt, o.p_filt) = (Some(x_out), p_out);
            *ll = with_dims!(n, m, |d| run.filter(d, &mut o)).map_err(|e| prefix_series(e, s))?;
            Ok(())
        },
    )
}

/// Parallel iteration over series: rayon's with the default feature `rayon`, else the same
/// names over sequential iterators (one thread, same results).
#[cfg(feature = "rayon")]
mod par {
    pub use rayon::prelude::*;

    use crate::error::{Error, Result};

    /// Runs `f` on a pool of `threads` threads.
    pub fn on_threads(threads: usize, f: impl FnOnce() -> Result<()> + Send) -> Result<()> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| Error::arg("threads", e.to_string()))?;
        pool.install(f)
    }
}

#[cfg(not(feature = "rayon"))]
mod par {
    use crate::error::Result;

    /// Runs `f` on this thread (`threads` is ignored without the feature `rayon`).
    pub fn on_threads(_threads: usize, f: impl FnOnce() -> Result<()>) -> Result<()> {
        f()
    }

    /// rayon's slice methods, sequential.
    pub trait ParSlice<T> {
        fn par_chunks_mut(&mut self, size: usize) -> std::slice::ChunksMut<'_, T>;
        fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T>;
    }

    impl<T> ParSlice<T> for [T] {
        fn par_chunks_mut(&mut self, size: usize) -> std::slice::ChunksMut<'_, T> {
            self.chunks_mut(size)
        }
        fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
            self.iter_mut()
        }
    }
}
