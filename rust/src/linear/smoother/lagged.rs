//! Fixed-lag and fixed-point smoothing alongside the filter (Söderström (6.43)–(6.79)),
//! with the structured recursion of [`PastState`]: O(lag · n³) per step, never the filter
//! on the augmented (lag+1)·n state.

use std::sync::Arc;

use super::past::{PastState, Scratch};
use crate::core::dims::{Dims, Dyn};
use crate::core::isa::{kernel, run_best};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::filter::step::LastUpdate;
use crate::linear::filter::{check_data, UpdateForm, Workspace};
use crate::linear::model::LinearGaussian;
use crate::KalmanFilter;

/// The last `lag + 1` states x̂(t−i|t), i = 0..lag, as the filter advances.
#[derive(Debug, Clone)]
struct LagWindow {
    n: usize,
    lag: usize,
    /// Slot i holds x[t−i]; only the first `len` slots are in use. The slots are allocated as
    /// the window fills (at most `lag + 1`), so a lag far beyond the data costs nothing.
    slots: Vec<PastState>,
    len: usize,
    scratch: Scratch,
}

impl LagWindow {
    fn new(n: usize, m: usize, lag: usize) -> Self {
        LagWindow { n, lag, slots: Vec::new(), len: 0, scratch: Scratch::new(n, m) }
    }

    /// A window with all its `lag + 1` slots allocated up front, for a time loop that should
    /// allocate nothing (the batch smoother, whose lag is at most T − 1).
    fn allocated(n: usize, m: usize, lag: usize) -> Self {
        LagWindow { slots: vec![PastState::new(n); lag + 1], ..Self::new(n, m, lag) }
    }

    /// Shifts the window by one step and starts slot 0 from the filter's prediction at t.
    fn begin_step(&mut self, x_pred: &[f64], p_pred: &[f64]) {
        if self.slots.len() <= self.lag {
            // Only while an online window fills; `allocated` windows never get here.
            self.slots.push(PastState::new(self.n));
        }
        self.slots.rotate_right(1);
        self.slots[0].start(x_pred, p_pred);
        self.len = (self.len + 1).min(self.slots.len());
    }

    fn update(&mut self, last: &LastUpdate<'_>) {
        for slot in &mut self.slots[..self.len] {
            slot.update(last, &mut self.scratch);
        }
    }

    /// After the filter's time update at t (with F[t], H[t]): advance every cross covariance.
    fn end_step(&mut self, f: &[f64], h: &[f64], gain_pred: &[f64]) {
        self.scratch.set_closed_loop(f, h, gain_pred);
        for slot in &mut self.slots[..self.len] {
            slot.advance(&mut self.scratch);
        }
    }

    fn lag(&self) -> usize {
        self.lag
    }

    /// Whether the window holds `lag + 1` states (slot `lag` is x̂(t−lag|t)).
    fn is_full(&self) -> bool {
        self.len > self.lag
    }
}

/// Smoothed estimates of every state from a lagged amount of data.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct FixedLagResult {
    /// The lag L.
    pub lag: usize,
    /// Row s is x̂(s | min(s + L, T − 1)), `(T, n)`.
    pub x_smooth: Vec<f64>,
    /// Row s is P(s | min(s + L, T − 1)), `(T, n, n)`.
    pub p_smooth: Vec<f64>,
}

/// The lag of [`smooth_fixed_lag`] and the update form of its filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct FixedLagOptions {
    /// The lag L: x(s) is estimated from y up to s + L.
    pub lag: usize,
    /// The filter's covariance update form.
    pub form: UpdateForm,
}

impl FixedLagOptions {
    /// Lag `lag`, Joseph form.
    pub fn new(lag: usize) -> Self {
        FixedLagOptions { lag, form: UpdateForm::default() }
    }

    /// The same options with the update form `form`.
    pub fn form(self, form: UpdateForm) -> Self {
        FixedLagOptions { form, ..self }
    }
}

/// Output buffers of [`smooth_fixed_lag_into`]: x̂(s | min(s + L, T − 1)) `(T, n)` and its
/// covariance `(T, n, n)`.
#[derive(Debug)]
#[non_exhaustive]
pub struct FixedLagOutputs<'a> {
    /// `(T, n)`.
    pub x_smooth: &'a mut [f64],
    /// `(T, n, n)`.
    pub p_smooth: &'a mut [f64],
}

impl<'a> FixedLagOutputs<'a> {
    /// Wraps the two buffers.
    pub fn new(x_smooth: &'a mut [f64], p_smooth: &'a mut [f64]) -> Self {
        FixedLagOutputs { x_smooth, p_smooth }
    }
}

/// Fixed-lag smoother: the estimate of x(s) from y up to s + `lag` (up to the last
/// observation near the end), for every s. `lag = 0` is the filter; `lag ≥ T − 1` gives the
/// RTS smoother at every s. Söderström (6.55)–(6.79), structured recursion.
pub fn smooth_fixed_lag(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: FixedLagOptions,
) -> Result<FixedLagResult> {
    let (n, steps) = (model.n_states(), y.steps());
    let mut res =
        FixedLagResult { lag: options.lag, x_smooth: vec![0.0; steps * n], p_smooth: vec![0.0; steps * n * n] };
    let out = FixedLagOutputs::new(&mut res.x_smooth, &mut res.p_smooth);
    smooth_fixed_lag_into(model, y, u, x0, p0, options, out)?;
    Ok(res)
}

/// [`smooth_fixed_lag`] writing into caller-owned buffers.
pub fn smooth_fixed_lag_into(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: FixedLagOptions,
    out: FixedLagOutputs<'_>,
) -> Result<()> {
    let FixedLagOptions { lag, form } = options;
    form.require_covariance_form("the fixed-lag smoother")?;
    let FixedLagOutputs { x_smooth: x_out, p_smooth: p_out } = out;
    let steps = check_data(model, y, u, x0, p0)?;
    let (n, m) = (model.n_states(), model.n_obs());
    check_len("x_smooth", x_out, steps * n)?;
    check_len("P_smooth", p_out, steps * n * n)?;
    let pass = Pass { model, y, u, x0, p0, form };
    run_best!(kernel(), Dyn { n, m }, |d| pass.fixed_lag(d, lag, x_out, p_out))
}

/// A smoother's forward pass over validated data.
struct Pass<'a> {
    model: &'a LinearGaussian,
    y: Series<'a>,
    u: Option<Series<'a>>,
    x0: &'a [f64],
    p0: &'a [f64],
    form: UpdateForm,
}

impl Pass<'_> {
    /// The loop of [`smooth_fixed_lag_into`], with the filter's arithmetic for sizes `D`.
    #[inline(always)]
    fn fixed_lag<D: Dims>(&self, d: D, lag: usize, x_out: &mut [f64], p_out: &mut [f64]) -> Result<()> {
        let Pass { model, y, u, x0, p0, form } = *self;
        let (n, m, steps) = (d.n(), d.m(), y.steps());
        let mut ws = Workspace::new(d, model.n_inputs(), x0, p0);
        let mut window = LagWindow::allocated(n, m, lag.min(steps - 1));
        let emit = |s: usize, slot: &PastState, x_out: &mut [f64], p_out: &mut [f64]| {
            x_out[s * n..(s + 1) * n].copy_from_slice(&slot.x);
            p_out[s * n * n..(s + 1) * n * n].copy_from_slice(&slot.p);
        };
        for t in 0..steps {
            let sys = model.at(t);
            let u_t = u.map(|u| u.row(t));
            ws.update(&sys, y.row(t), u_t, form, t)?;
            window.begin_step(ws.x_pred(), ws.p_pred());
            window.update(&ws.last_update(sys.h));
            if window.is_full() {
                emit(t - window.lag(), &window.slots[window.lag()], x_out, p_out);
            }
            ws.predict(&sys, u_t);
            window.end_step(sys.f, sys.h, ws.gain_pred());
        }
        // The last states have less than `lag` steps of data after them: x̂(T−1−i | T−1).
        let emitted = steps.saturating_sub(window.lag());
        for s in emitted..steps {
            emit(s, &window.slots[steps - 1 - s], x_out, p_out);
        }
        Ok(())
    }

    /// The loop of [`smooth_fixed_point`] into `res`.
    #[inline(always)]
    fn fixed_point<D: Dims>(&self, d: D, res: &mut FixedPointResult) -> Result<()> {
        let Pass { model, y, u, x0, p0, form } = *self;
        let (n, m, steps, t_point) = (d.n(), d.m(), y.steps(), res.t_point);
        let mut ws = Workspace::new(d, model.n_inputs(), x0, p0);
        let mut past = PastState::new(n);
        let mut scratch = Scratch::new(n, m);
        for t in 0..steps {
            let sys = model.at(t);
            let u_t = u.map(|u| u.row(t));
            ws.update(&sys, y.row(t), u_t, form, t)?;
            if t >= t_point {
                if t == t_point {
                    past.start(ws.x_pred(), ws.p_pred());
                }
                past.update(&ws.last_update(sys.h), &mut scratch);
                let j = t - t_point;
                res.x[j * n..(j + 1) * n].copy_from_slice(&past.x);
                res.p[j * n * n..(j + 1) * n * n].copy_from_slice(&past.p);
            }
            ws.predict(&sys, u_t);
            if t >= t_point {
                scratch.set_closed_loop(sys.f, sys.h, ws.gain_pred());
                past.advance(&mut scratch);
            }
        }
        Ok(())
    }
}

/// Estimates of one state from growing amounts of data.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct FixedPointResult {
    /// The fixed time s.
    pub t_point: usize,
    /// Row j is x̂(s | s + j), j = 0..T−s, `(T − s, n)`.
    pub x: Vec<f64>,
    /// Row j is P(s | s + j), `(T − s, n, n)`.
    pub p: Vec<f64>,
}

/// Fixed-point smoother: the estimate of x(`t_point`) from y up to each t ≥ t_point, with its
/// covariance. Söderström (6.45)–(6.54).
pub fn smooth_fixed_point(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    t_point: usize,
    form: UpdateForm,
) -> Result<FixedPointResult> {
    form.require_covariance_form("the fixed-point smoother")?;
    let steps = check_data(model, y, u, x0, p0)?;
    if t_point >= steps {
        return Err(Error::arg(
            "t_point",
            format!("must be a step of the data, 0 ≤ t_point < T = {steps}, got {t_point}"),
        ));
    }
    let (n, m) = (model.n_states(), model.n_obs());
    let rows = steps - t_point;
    let mut res = FixedPointResult { t_point, x: vec![0.0; rows * n], p: vec![0.0; rows * n * n] };
    let pass = Pass { model, y, u, x0, p0, form };
    let out = &mut res;
    run_best!(kernel(), Dyn { n, m }, |d| pass.fixed_point(d, out))?;
    Ok(res)
}

fn check_len(arg: &'static str, buf: &[f64], want: usize) -> Result<()> {
    if buf.len() != want {
        return Err(Error::arg(arg, format!("output buffer has {} entries, needs {want}", buf.len())));
    }
    Ok(())
}

/// Fixed-lag smoothing online: after `update(y)` at step t, [`lagged`](Self::lagged) is
/// x̂(t−lag | t) once t ≥ lag, and [`window`](Self::window) gives x̂(t−i | t) for every i the
/// window holds. Same arguments and NaN rules as [`KalmanFilter`].
#[derive(Debug, Clone)]
pub struct FixedLagSmoother {
    filter: KalmanFilter,
    window: LagWindow,
}

impl FixedLagSmoother {
    /// Starts from the prior `(x0, P0) = x̂(0|−1), P(0|−1)`.
    pub fn new(model: Arc<LinearGaussian>, x0: &[f64], p0: &[f64], lag: usize, form: UpdateForm) -> Result<Self> {
        form.require_covariance_form("the fixed-lag smoother")?;
        let (n, m) = (model.n_states(), model.n_obs());
        let filter = KalmanFilter::new(model, x0, p0, form)?;
        Ok(FixedLagSmoother { filter, window: LagWindow::new(n, m, lag) })
    }

    /// Measurement update with y at the current step.
    pub fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        self.filter.update(y, u)?;
        let sys = self.filter.model().at(self.filter.t());
        let (x_pred, p_pred) = self.filter.prediction();
        self.window.begin_step(x_pred, p_pred);
        self.window.update(&self.filter.last_update(sys.h));
        Ok(())
    }

    /// Time update to the next step (a step without `update` counts as missing).
    pub fn predict(&mut self, u: Option<&[f64]>) -> Result<()> {
        let t = self.filter.t();
        if !self.filter.is_updated() {
            self.filter.check_input(u, "B", self.filter.model().matrices().b.is_some())?;
            let (x_pred, p_pred) = self.filter.prediction();
            self.window.begin_step(x_pred, p_pred);
        }
        self.filter.predict(u)?;
        let sys = self.filter.model().at(t);
        self.window.end_step(sys.f, sys.h, self.filter.gain_pred());
        Ok(())
    }

    /// `update(y, u)` then `predict(u)`.
    pub fn step(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        self.update(y, u)?;
        self.predict(u)
    }

    /// x̂(t−lag | t) and P(t−lag | t) after an update at t ≥ lag; `None` before.
    pub fn lagged(&self) -> Option<(&[f64], &[f64])> {
        let lag = self.window.lag();
        (self.filter.is_updated() && self.window.is_full()).then(|| {
            let slot = &self.window.slots[lag];
            (slot.x.as_slice(), slot.p.as_slice())
        })
    }

    /// After an update at t: x̂(t−i | t), P(t−i | t) for i = 0..len (len ≤ lag + 1).
    pub fn window(&self) -> impl Iterator<Item = (&[f64], &[f64])> {
        let len = if self.filter.is_updated() { self.window.len } else { 0 };
        self.window.slots[..len].iter().map(|s| (s.x.as_slice(), s.p.as_slice()))
    }

    /// The lag.
    pub fn lag(&self) -> usize {
        self.window.lag()
    }

    /// The underlying filter (its x, P, t and log-likelihood).
    pub fn filter(&self) -> &KalmanFilter {
        &self.filter
    }

    /// The past states (x̂(s|·), P(s|·), C) of the window, s = t, t−1, …: with the filter,
    /// the whole state of the smoother (for pickling; see [`resume`](Self::resume)).
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub(crate) fn window_state(&self) -> impl Iterator<Item = (&[f64], &[f64], &[f64])> {
        self.window.slots[..self.window.len].iter().map(|s| (s.x.as_slice(), s.p.as_slice(), s.c.as_slice()))
    }

    /// The smoother with `filter` and the past states of [`window_state`](Self::window_state).
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub(crate) fn resume(filter: KalmanFilter, lag: usize, window: &[(&[f64], &[f64], &[f64])]) -> Result<Self> {
        let (n, m) = (filter.model().n_states(), filter.model().n_obs());
        if window.len() > lag.saturating_add(1) {
            return Err(Error::arg(
                "window",
                format!("has {} states, more than lag + 1 = {}", window.len(), lag.saturating_add(1)),
            ));
        }
        let mut lag_window = LagWindow::new(n, m, lag);
        for &(x, p, c) in window {
            if x.len() != n || p.len() != n * n || c.len() != n * n {
                return Err(Error::arg("window", format!("expected states of n = {n} and covariances of n × n")));
            }
            let mut slot = PastState::new(n);
            slot.x.copy_from_slice(x);
            slot.p.copy_from_slice(p);
            slot.c.copy_from_slice(c);
            lag_window.slots.push(slot);
        }
        lag_window.len = window.len();
        Ok(FixedLagSmoother { filter, window: lag_window })
    }
}
