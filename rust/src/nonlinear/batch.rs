//! Many tracks through one nonlinear model, in parallel: [`ekf_batch`] and [`ukf_batch`].
//!
//! Each series runs the whole filter of [`ekf_into`] or [`ukf_into`] (the covariances depend
//! on the data, so nothing is shared), on a pool of threads: its results are those of filtering
//! it alone, bit for bit, whatever the number of threads. A model with a Python callable holds
//! the GIL at each call of f or h, so its series run one after another
//! ([`PointFunction::parallel`](super::PointFunction::parallel)).

use super::filter::{ekf_into, ukf_into, EkfOptions, UkfOptions};
use super::model::NonlinearModel;
use crate::core::batch::par::{self, *};
use crate::core::batch::{prefix_series, thread_count, Batch, BatchOutputs, SeriesSizes};
use crate::core::Series;
use crate::error::Result;
use crate::linear::filter::FilterOutputs;

/// The extended Kalman filter ([`ekf_into`] with `options`) of every series of `batch`, in
/// parallel on `threads` threads (all cores when `None`; never more than the series or the
/// cores). `out.p_filt`, when given, is `B × T × n × n`. `batch.u` has any width k (the
/// model's f and h read it): `T × k` shared or `B × T × k`.
///
/// Errors name the series (the lowest-numbered one that failed).
pub fn ekf_batch(
    model: &NonlinearModel,
    batch: Batch<'_>,
    options: EkfOptions,
    out: BatchOutputs<'_>,
    threads: Option<usize>,
) -> Result<()> {
    run_batch(model, batch, out, threads, |y, u, x0, p0, o| ekf_into(model, y, u, x0, p0, options, o))
}

/// The unscented Kalman filter ([`ukf_into`] with `options`) of every series of `batch`; as
/// [`ekf_batch`] otherwise.
pub fn ukf_batch(
    model: &NonlinearModel,
    batch: Batch<'_>,
    options: UkfOptions,
    out: BatchOutputs<'_>,
    threads: Option<usize>,
) -> Result<()> {
    run_batch(model, batch, out, threads, |y, u, x0, p0, o| ukf_into(model, y, u, x0, p0, options.clone(), o))
}

fn run_batch(
    model: &NonlinearModel,
    b: Batch<'_>,
    out: BatchOutputs<'_>,
    threads: Option<usize>,
    // One series: (y, u, x0, P0, outputs) -> loglik.
    filter: impl Fn(Series<'_>, Option<Series<'_>>, &[f64], &[f64], FilterOutputs<'_>) -> Result<f64> + Sync,
) -> Result<()> {
    let sizes = check_batch(model, &b, &out)?;
    let (n, t) = (sizes.n, b.steps);
    let threads = if model.parallel() { thread_count(threads, b.series) } else { 1 };
    let covs: Vec<Option<&mut [f64]>> = match out.p_filt {
        Some(p) => p.chunks_mut(t * n * n).map(Some).collect(),
        None => (0..b.series).map(|_| None).collect(),
    };
    let mut results: Vec<Result<()>> = (0..b.series).map(|_| Ok(())).collect();
    let filter = &filter;
    par::on_threads(threads, || {
        let series = out.x_filt.par_chunks_mut(t * n).zip(out.loglik.par_iter_mut()).zip(covs);
        series.zip(results.par_iter_mut()).enumerate().for_each(|(s, (((x_out, ll), p_out), result))| {
            let (y, u, x0, p0) = b.part(s, sizes);
            let mut o = FilterOutputs::default();
            (o.x_filt, o.p_filt) = (Some(x_out), p_out);
            *result = filter(y, u, x0, p0, o).map(|v| *ll = v).map_err(|e| prefix_series(e, s));
        });
        Ok(())
    })?;
    results.into_iter().collect()
}

/// Checks the batch's shapes and every series' data as the single-series filter would,
/// before any filtering; returns the sizes (k: the input width, from `u`'s length).
fn check_batch(model: &NonlinearModel, b: &Batch<'_>, out: &BatchOutputs<'_>) -> Result<SeriesSizes> {
    let (n, m) = (model.n_states(), model.n_obs());
    let rows = if b.u_shared { b.steps } else { b.series.saturating_mul(b.steps) };
    // the input width from u's length (one that is not rows × k fails check_lengths)
    let k = match b.u {
        Some(u) if rows > 0 => u.len() / rows,
        _ => 0,
    };
    let sizes = SeriesSizes { n, m, k };
    b.check_lengths(sizes)?;
    for s in 0..b.series {
        let (y, u, x0, p0) = b.part(s, sizes);
        model.check_run(y, u, x0, p0).map_err(|e| prefix_series(e, s))?;
    }
    out.check_lengths(b.series, b.steps, n, (b.series * b.steps).checked_mul(n * n))?;
    Ok(sizes)
}
