//! Smoothers: estimates of x[s] that use measurements after s.
//!
//! - [`smooth`] / [`rts_into`]: fixed-interval (Rauch–Tung–Striebel), every state given all
//!   data, with lag-one covariances.
//! - [`smooth_fixed_lag`] and the online [`FixedLagSmoother`]: x[s] given data up to s + lag.
//! - [`smooth_fixed_point`]: one state x[s] given data up to each t ≥ s.

mod lagged;
mod past;
mod rts;

pub use lagged::{
    smooth_fixed_lag, smooth_fixed_lag_into, smooth_fixed_point, FixedLagResult, FixedLagSmoother, FixedPointResult,
};
pub use rts::{rts_into, FilteredView, SmootherOutputs};

use crate::error::Result;
use crate::filter::{filter, FilterResult, Series, UpdateForm};
use crate::model::LinearGaussian;

/// The RTS smoother's results with the filter's.
#[derive(Debug, Clone, PartialEq)]
pub struct SmootherResult {
    /// x̂(t|T−1), `(T, n)`.
    pub x_smooth: Vec<f64>,
    /// P(t|T−1), `(T, n, n)`.
    pub p_smooth: Vec<f64>,
    /// Cov(x[t], x[t−1] | all data), `(T, n, n)`; row 0 is zero.
    pub p_lag1: Vec<f64>,
    /// The forward pass.
    pub filter: FilterResult,
}

/// Kalman filter, then the RTS backward pass (ALGORITHMS.md §5.2–5.3).
pub fn smooth(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    form: UpdateForm,
) -> Result<SmootherResult> {
    let filt = filter(model, y, u, x0, p0, form)?;
    let (n, steps) = (model.n_states(), y.steps());
    let mut res = SmootherResult {
        x_smooth: vec![0.0; steps * n],
        p_smooth: vec![0.0; steps * n * n],
        p_lag1: vec![0.0; steps * n * n],
        filter: filt,
    };
    let view = FilteredView {
        x_pred: &res.filter.x_pred,
        p_pred: &res.filter.p_pred,
        x_filt: &res.filter.x_filt,
        p_filt: &res.filter.p_filt,
        gain: &res.filter.gain,
    };
    let out = SmootherOutputs { x_smooth: &mut res.x_smooth, p_smooth: &mut res.p_smooth, p_lag1: &mut res.p_lag1 };
    rts_into(model, steps, view, out)?;
    Ok(res)
}
