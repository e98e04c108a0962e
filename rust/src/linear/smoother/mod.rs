//! Smoothers: estimates of x(s) that use measurements after s.
//!
//! - [`smooth`] / [`rts_into`]: fixed-interval (Rauch–Tung–Striebel), every state given all
//!   data, with lag-one covariances.
//! - [`smooth_fixed_lag`] and the online [`FixedLagSmoother`]: x(s) given data up to s + lag.
//! - [`smooth_fixed_point`]: one state x(s) given data up to each t ≥ s.

mod lagged;
mod past;
mod rts;

pub use lagged::{
    smooth_fixed_lag, smooth_fixed_lag_into, smooth_fixed_point, FixedLagOptions, FixedLagOutputs, FixedLagResult,
    FixedLagSmoother, FixedPointResult,
};
pub use rts::{rts_into, FilteredView, RtsOutputs};

use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::filter::{filter_into, FilterOutputs, FilterResult, UpdateForm};
use crate::linear::model::LinearGaussian;
pub(crate) use rts::{pseudo_inverse_failed, solve_psd};
use rts::{rts_in_place, Priors};

/// The RTS smoother's results with the filter's.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SmootherResult {
    /// x̂(t|T−1), `(T, n)`.
    pub x_smooth: Vec<f64>,
    /// P(t|T−1), `(T, n, n)`.
    pub p_smooth: Vec<f64>,
    /// Cov(x(t), x(t−1) | all data), `(T, n, n)`; row 0 is zero.
    pub p_lag1: Vec<f64>,
    /// The forward pass.
    pub filter: FilterResult,
}

/// Kalman filter, then the RTS backward pass (docs/algorithms.md, "RTS", "Lag-one covariance").
pub fn smooth(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    form: UpdateForm,
) -> Result<SmootherResult> {
    let (n, m, steps) = (model.n_states(), model.n_obs(), y.steps());
    let mut filter = FilterResult::zeros(steps, n, m);
    let (mut x_smooth, mut p_smooth, mut p_lag1) =
        (vec![0.0; steps * n], vec![0.0; steps * n * n], vec![0.0; steps * n * n]);
    let out = SmoothOutputs { x_smooth: Some(&mut x_smooth), p_smooth: Some(&mut p_smooth), p_lag1: Some(&mut p_lag1) };
    filter.loglik = smooth_into(model, y, u, x0, p0, form, filter.outputs(), out)?;
    Ok(SmootherResult { x_smooth, p_smooth, p_lag1, filter })
}

/// Output buffers of [`smooth_into`]: x̂(t|T−1) `(T, n)`, P(t|T−1) and the lag-one
/// covariances `(T, n, n)`; `None` skips one.
#[derive(Debug, Default)]
pub struct SmoothOutputs<'a> {
    /// x̂(t|T−1), `(T, n)`.
    pub x_smooth: Option<&'a mut [f64]>,
    /// P(t|T−1), `(T, n, n)`.
    pub p_smooth: Option<&'a mut [f64]>,
    /// Cov(x(t), x(t−1) | all data), `(T, n, n)`; row 0 is zero.
    pub p_lag1: Option<&'a mut [f64]>,
}

/// [`smooth`] writing into caller-owned buffers: the filter's outputs given in `filt` and the
/// smoother's given in `out`; returns the log-likelihood. What the backward pass needs but
/// the caller did not ask for (x̂(t|t−1), P(t|t−1), K with N) is kept in buffers allocated
/// here; the filtered moments are computed into the smoother's buffers and smoothed in place
/// (copied out first when `filt` asks for them too).
#[allow(clippy::too_many_arguments)]
pub fn smooth_into(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    form: UpdateForm,
    mut filt: FilterOutputs<'_>,
    out: SmoothOutputs<'_>,
) -> Result<f64> {
    let (n, m, steps) = (model.n_states(), model.n_obs(), y.steps());
    let (xs, ps, ks) = (steps * n, steps * n * n, steps * n * m);
    for (arg, buf, want) in [
        ("x_smooth", &out.x_smooth, xs),
        ("P_smooth", &out.p_smooth, ps),
        ("P_lag1", &out.p_lag1, ps),
        ("x_filt", &filt.x_filt, xs),
        ("P_filt", &filt.p_filt, ps),
    ] {
        if let Some(got) = buf.as_ref().map(|b| b.len()).filter(|&got| got != want) {
            return Err(Error::arg(arg, format!("output buffer has {got} entries, needs {want}")));
        }
    }
    if form == UpdateForm::SquareRoot {
        return crate::linear::filter::smooth_square_root_into(
            model,
            y,
            u,
            x0,
            p0,
            filt,
            out.x_smooth,
            out.p_smooth,
            out.p_lag1,
        );
    }
    let mut own: [Vec<f64>; 5] = Default::default();
    let [own_x, own_p, own_xp, own_pp, own_k] = &mut own;
    let x = given_or(out.x_smooth, own_x, xs);
    let p = given_or(out.p_smooth, own_p, ps);
    let x_pred = given_or(filt.x_pred.take(), own_xp, xs);
    let p_pred = given_or(filt.p_pred.take(), own_pp, ps);
    let mut gain = match (filt.gain.take(), model.matrices().n.is_some()) {
        (Some(k), _) => Some(k),
        (None, true) => Some(given_or(None, own_k, ks)),
        (None, false) => None,
    };
    let (x_filt, p_filt) = (filt.x_filt.take(), filt.p_filt.take());
    let forward = FilterOutputs {
        x_pred: Some(&mut *x_pred),
        p_pred: Some(&mut *p_pred),
        x_filt: Some(&mut *x),
        p_filt: Some(&mut *p),
        gain: gain.as_deref_mut(),
        ..filt
    };
    let loglik = filter_into(model, y, u, x0, p0, form, forward)?;
    if let Some(xf) = x_filt {
        xf.copy_from_slice(x);
    }
    if let Some(pf) = p_filt {
        pf.copy_from_slice(p);
    }
    let priors = Priors { x_pred, p_pred, gain: gain.as_deref().unwrap_or(&[]) };
    rts_in_place(model, priors, x, p, out.p_lag1)?;
    Ok(loglik)
}

/// The caller's buffer, or `own` resized to `len` zeros.
fn given_or<'a>(given: Option<&'a mut [f64]>, own: &'a mut Vec<f64>, len: usize) -> &'a mut [f64] {
    match given {
        Some(b) => b,
        None => {
            own.resize(len, 0.0);
            own
        }
    }
}
