//! The Kalman filter over a whole series ([`filter`], [`loglik`]) and one step at a time
//! ([`KalmanFilter`]).
//!
//! Conventions (docs/conventions.md): the prior `(x0, P0)` is `x̂(0|−1), P(0|−1)`, so the first
//! operation is the measurement update with `y[0]`. `y` is `(T, m)` row-major; NaN marks a
//! missing component. `u` is `(T, k)`; `u[t]` enters `x[t+1]` through B and `y[t]` through D.
//! The recursion is Söderström Lemma 6.1 / (6.24) (see [`step`] for the equations).

mod fixed;
pub(crate) mod step;

use std::sync::Arc;

use step::Dims;
pub use step::UpdateForm;
pub(crate) use step::Workspace;

use crate::error::{Error, Result};
use crate::model::{check_psd, check_symmetric, LinearGaussian};

/// A borrowed row-major `(steps, width)` array: the observations `y` or the inputs `u`.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    data: &'a [f64],
    steps: usize,
    width: usize,
}

impl<'a> Series<'a> {
    /// Wraps `data` as `steps` rows of `width` numbers; `arg` names it in errors.
    pub fn new(arg: &'static str, data: &'a [f64], steps: usize, width: usize) -> Result<Self> {
        if data.len() != steps * width {
            return Err(Error::arg(arg, format!("data length {} is not {steps} × {width}", data.len())));
        }
        Ok(Series { data, steps, width })
    }

    /// Row `t`.
    #[inline]
    pub fn row(&self, t: usize) -> &'a [f64] {
        &self.data[t * self.width..(t + 1) * self.width]
    }

    /// Number of rows (time steps).
    pub fn steps(&self) -> usize {
        self.steps
    }
}

/// How the filter runs: the covariance update form and whether to freeze the gains once the
/// covariance has converged.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterOptions {
    /// Joseph (default) or standard covariance update.
    pub form: UpdateForm,
    /// Freeze P, S and the gains once ‖P(t+1|t) − P(t|t−1)‖_max ≤ tol · max(1, ‖P‖_max) at a
    /// fully observed step (like statsmodels' steady-state switch); a missing value resumes
    /// the full recursion. Then a step costs O(n² + nm + m²). Off (`None`) by default;
    /// constant models only. `Some(f64::INFINITY)` freezes after the first step, which with
    /// P0 = the stationary P(t|t−1) is the steady-state (constant-gain) filter.
    pub converge_tol: Option<f64>,
}

impl From<UpdateForm> for FilterOptions {
    fn from(form: UpdateForm) -> Self {
        FilterOptions { form, converge_tol: None }
    }
}

/// Everything the filter computes, row-major, for `T` steps, `n` states and `m` outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterResult {
    /// `x̂(t|t−1)`, `(T, n)`.
    pub x_pred: Vec<f64>,
    /// `P(t|t−1)`, `(T, n, n)`.
    pub p_pred: Vec<f64>,
    /// `x̂(t|t)`, `(T, n)`.
    pub x_filt: Vec<f64>,
    /// `P(t|t)`, `(T, n, n)`.
    pub p_filt: Vec<f64>,
    /// Innovations `e(t) = y(t) − H x̂(t|t−1) − D u(t)`, `(T, m)`, NaN where `y` is missing.
    pub innov: Vec<f64>,
    /// Innovation (forecast error) covariance `S(t) = H P(t|t−1) H' + R` of all components,
    /// `(T, m, m)`.
    pub innovation_cov: Vec<f64>,
    /// Filter gain `K(t) = P(t|t−1) H' S⁻¹`, `(T, n, m)`; zero columns for missing components.
    pub gain: Vec<f64>,
    /// Predictor gain `K_pred(t) = (F P(t|t−1) H' + N) S⁻¹`, `(T, n, m)`.
    pub gain_pred: Vec<f64>,
    /// Log-likelihood term of each step, `(T,)` (0 where nothing is observed).
    pub loglik_t: Vec<f64>,
    /// Total log-likelihood `Σ loglik_t` (Söderström (6.142)).
    pub loglik: f64,
    /// `x̂(T|T−1)`, the prediction past the last observation, `(n,)`.
    pub x_next: Vec<f64>,
    /// `P(T|T−1)`, `(n, n)`.
    pub p_next: Vec<f64>,
}

/// Output buffers for [`filter_into`], each of the size documented on [`FilterResult`];
/// `None` skips that output (it is then neither computed into memory nor copied). Given
/// buffers are written in full.
#[derive(Debug, Default)]
pub struct FilterOutputs<'a> {
    pub x_pred: Option<&'a mut [f64]>,
    pub p_pred: Option<&'a mut [f64]>,
    pub x_filt: Option<&'a mut [f64]>,
    pub p_filt: Option<&'a mut [f64]>,
    pub innov: Option<&'a mut [f64]>,
    pub innovation_cov: Option<&'a mut [f64]>,
    pub gain: Option<&'a mut [f64]>,
    pub gain_pred: Option<&'a mut [f64]>,
    pub loglik_t: Option<&'a mut [f64]>,
    pub x_next: Option<&'a mut [f64]>,
    pub p_next: Option<&'a mut [f64]>,
}

impl FilterResult {
    pub(crate) fn zeros(steps: usize, n: usize, m: usize) -> Self {
        let z = |len: usize| vec![0.0; len];
        FilterResult {
            x_pred: z(steps * n),
            p_pred: z(steps * n * n),
            x_filt: z(steps * n),
            p_filt: z(steps * n * n),
            innov: z(steps * m),
            innovation_cov: z(steps * m * m),
            gain: z(steps * n * m),
            gain_pred: z(steps * n * m),
            loglik_t: z(steps),
            loglik: 0.0,
            x_next: z(n),
            p_next: z(n * n),
        }
    }

    pub(crate) fn outputs(&mut self) -> FilterOutputs<'_> {
        FilterOutputs {
            x_pred: Some(&mut self.x_pred),
            p_pred: Some(&mut self.p_pred),
            x_filt: Some(&mut self.x_filt),
            p_filt: Some(&mut self.p_filt),
            innov: Some(&mut self.innov),
            innovation_cov: Some(&mut self.innovation_cov),
            gain: Some(&mut self.gain),
            gain_pred: Some(&mut self.gain_pred),
            loglik_t: Some(&mut self.loglik_t),
            x_next: Some(&mut self.x_next),
            p_next: Some(&mut self.p_next),
        }
    }
}

/// Runs the Kalman filter over `y` from the prior `(x0, P0) = x̂(0|−1), P(0|−1)`.
pub fn filter(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: impl Into<FilterOptions>,
) -> Result<FilterResult> {
    let mut res = FilterResult::zeros(y.steps(), model.n_states(), model.n_obs());
    res.loglik = filter_into(model, y, u, x0, p0, options, res.outputs())?;
    Ok(res)
}

/// [`filter`] writing into caller-owned buffers (e.g. NumPy arrays); returns the total
/// log-likelihood. Allocates only its workspace, once.
pub fn filter_into(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: impl Into<FilterOptions>,
    mut out: FilterOutputs<'_>,
) -> Result<f64> {
    let (n, m) = (model.n_states(), model.n_obs());
    let options = options.into();
    let steps = check_data(model, y, u, x0, p0)?;
    check_outputs(&out, steps, n, m)?;
    let mut ws = start(model, x0, p0);
    ws.converge_tol = check_converge_tol(model, options.converge_tol)?;
    ws.want_gain_pred = out.gain_pred.is_some();
    ws.want_gain = out.gain.is_some();
    let run = Run { model, y, u, form: options.form };
    let total = with_dims!(n, m, run.filter(&mut ws, &mut out))?;
    if let Some(o) = out.x_next.as_deref_mut() {
        o.copy_from_slice(&ws.x_pred);
    }
    if let Some(o) = out.p_next.as_deref_mut() {
        o.copy_from_slice(&ws.p_pred);
    }
    Ok(total)
}

/// The log-likelihood `Σ_t log p(y(t) | y(0..t−1))` alone (Söderström (6.142)), without
/// storing any per-step output.
pub fn loglik(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: impl Into<FilterOptions>,
) -> Result<f64> {
    filter_into(model, y, u, x0, p0, options, FilterOutputs::default())
}

pub(crate) fn start(model: &LinearGaussian, x0: &[f64], p0: &[f64]) -> Workspace {
    let mut ws = Workspace::new(model.n_states(), model.n_obs(), model.n_inputs());
    ws.x_pred.copy_from_slice(x0);
    ws.p_pred.copy_from_slice(p0);
    crate::dense::symmetrize(&mut ws.p_pred, model.n_states());
    ws
}

/// Calls `$run.$method(d, args)` with `d` the compile-time sizes when (n, m) is one of the
/// common small ones, so that the step kernels are unrolled for them, and with the run-time
/// sizes otherwise. The arithmetic is the same either way.
macro_rules! with_dims {
    ($n:expr, $m:expr, $run:ident . $method:ident ( $($arg:expr),* )) => {{
        use $crate::filter::step::{Dyn, Fixed};
        match ($n, $m) {
            (1, 1) => $run.$method(Fixed::<1, 1>, $($arg),*),
            (2, 1) => $run.$method(Fixed::<2, 1>, $($arg),*),
            (2, 2) => $run.$method(Fixed::<2, 2>, $($arg),*),
            (3, 1) => $run.$method(Fixed::<3, 1>, $($arg),*),
            (3, 2) => $run.$method(Fixed::<3, 2>, $($arg),*),
            (3, 3) => $run.$method(Fixed::<3, 3>, $($arg),*),
            (4, 1) => $run.$method(Fixed::<4, 1>, $($arg),*),
            (4, 2) => $run.$method(Fixed::<4, 2>, $($arg),*),
            (4, 4) => $run.$method(Fixed::<4, 4>, $($arg),*),
            (6, 2) => $run.$method(Fixed::<6, 2>, $($arg),*),
            (6, 3) => $run.$method(Fixed::<6, 3>, $($arg),*),
            (8, 4) => $run.$method(Fixed::<8, 4>, $($arg),*),
            (n, m) => $run.$method(Dyn { n, m }, $($arg),*),
        }
    }};
}
pub(crate) use with_dims;

/// One pass of the filter over the data.
#[derive(Clone, Copy)]
pub(crate) struct Run<'a> {
    pub model: &'a LinearGaussian,
    pub y: Series<'a>,
    pub u: Option<Series<'a>>,
    pub form: UpdateForm,
}

impl Run<'_> {
    /// Update with `y[t]`, then the time update to `t + 1`.
    #[inline(always)]
    pub fn advance<D: Dims>(&self, d: D, ws: &mut Workspace, t: usize) -> Result<()> {
        let sys = self.model.at(t);
        let u_t = self.u.map(|u| u.row(t));
        ws.update(d, &sys, self.y.row(t), u_t, self.form, t)?;
        ws.predict(d, &sys, u_t);
        Ok(())
    }

    /// The time loop, storing the outputs that are given; returns the log-likelihood.
    /// On x86-64 CPUs with AVX2 the same code is compiled a second time for them and chosen
    /// at run time (no fused multiply-adds, no reordered sums: results are the same bits).
    pub(crate) fn filter<D: Dims>(&self, d: D, ws: &mut Workspace, out: &mut FilterOutputs<'_>) -> Result<f64> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.filter_avx2(d, ws, out) };
        }
        self.filter_loop(d, ws, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn filter_avx2<D: Dims>(&self, d: D, ws: &mut Workspace, out: &mut FilterOutputs<'_>) -> Result<f64> {
        self.filter_loop(d, ws, out)
    }

    #[inline(always)]
    fn filter_loop<D: Dims>(&self, d: D, ws: &mut Workspace, out: &mut FilterOutputs<'_>) -> Result<f64> {
        if let Some(total) = d.filter_fixed(self, ws, out) {
            return total;
        }
        let mut total = 0.0;
        for t in 0..self.y.steps() {
            StepStore::prior(out, t, &ws.x_pred, &ws.p_pred);
            self.advance(d, ws, t)?;
            total += ws.loglik_t;
            StepStore::of(ws).save(out, t);
        }
        Ok(total)
    }
}

/// One step's filtered outputs, for the rows of the optional output buffers.
pub(crate) struct StepStore<'a> {
    pub x_filt: &'a [f64],
    pub p_filt: &'a [f64],
    pub innov: &'a [f64],
    pub innovation_cov: &'a [f64],
    pub gain: &'a [f64],
    pub gain_pred: &'a [f64],
    pub loglik_t: f64,
}

impl<'a> StepStore<'a> {
    /// The outputs of the step the workspace has just made.
    #[inline(always)]
    pub fn of(ws: &'a Workspace) -> Self {
        let (n, m) = (ws.n, ws.m);
        StepStore {
            x_filt: &ws.x_filt[..n],
            p_filt: &ws.p_filt[..n * n],
            innov: &ws.innov[..m],
            innovation_cov: &ws.s_full[..m * m],
            gain: &ws.gain[..n * m],
            gain_pred: &ws.gain_pred[..n * m],
            loglik_t: ws.loglik_t,
        }
    }

    /// Stores x̂(t|t−1), P(t|t−1) (before the step).
    #[inline(always)]
    pub fn prior(out: &mut FilterOutputs<'_>, t: usize, x_pred: &[f64], p_pred: &[f64]) {
        store(&mut out.x_pred, t, x_pred);
        store(&mut out.p_pred, t, p_pred);
    }

    /// Stores the step's filtered outputs in row t.
    #[inline(always)]
    pub fn save(&self, out: &mut FilterOutputs<'_>, t: usize) {
        store(&mut out.x_filt, t, self.x_filt);
        store(&mut out.p_filt, t, self.p_filt);
        store(&mut out.innov, t, self.innov);
        store(&mut out.innovation_cov, t, self.innovation_cov);
        store(&mut out.gain, t, self.gain);
        store(&mut out.gain_pred, t, self.gain_pred);
        store(&mut out.loglik_t, t, &[self.loglik_t]);
    }
}

/// Row t of an optional output: `out[t * len..(t + 1) * len] = src`.
#[inline(always)]
fn store(out: &mut Option<&mut [f64]>, t: usize, src: &[f64]) {
    if let Some(o) = out.as_deref_mut() {
        let len = src.len();
        o[t * len..(t + 1) * len].copy_from_slice(src);
    }
}

fn check_converge_tol(model: &LinearGaussian, tol: Option<f64>) -> Result<Option<f64>> {
    match tol {
        Some(t) if t.is_nan() || t < 0.0 => Err(Error::arg("converge_tol", format!("must be ≥ 0, got {t}"))),
        Some(_) if model.steps().is_some() => {
            Err(Error::arg("converge_tol", "needs constant model matrices (this model has per-step ones)"))
        }
        other => Ok(other),
    }
}

fn check_outputs(out: &FilterOutputs<'_>, steps: usize, n: usize, m: usize) -> Result<()> {
    let sizes = [
        ("x_pred", &out.x_pred, steps * n),
        ("P_pred", &out.p_pred, steps * n * n),
        ("x_filt", &out.x_filt, steps * n),
        ("P_filt", &out.p_filt, steps * n * n),
        ("innov", &out.innov, steps * m),
        ("S", &out.innovation_cov, steps * m * m),
        ("K", &out.gain, steps * n * m),
        ("K_pred", &out.gain_pred, steps * n * m),
        ("loglik_t", &out.loglik_t, steps),
        ("x_next", &out.x_next, n),
        ("P_next", &out.p_next, n * n),
    ];
    for (arg, buf, want) in sizes {
        if let Some(buf) = buf {
            if buf.len() != want {
                return Err(Error::arg(arg, format!("output buffer has {} entries, needs {want}", buf.len())));
            }
        }
    }
    Ok(())
}

/// Validates data and prior against the model; returns T.
pub(crate) fn check_data(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
) -> Result<usize> {
    let steps = check_series(model, y, u)?;
    check_prior(model.n_states(), x0, p0).map(|_| steps)
}

/// Validates the data and inputs of one series against the model; returns T.
pub(crate) fn check_series(model: &LinearGaussian, y: Series<'_>, u: Option<Series<'_>>) -> Result<usize> {
    let (m, steps) = (model.n_obs(), y.steps());
    if y.width != m {
        return Err(Error::arg("y", format!("expected shape (T, {m}) for m = {m} outputs, got (T, {})", y.width)));
    }
    if steps == 0 {
        return Err(Error::arg("y", "has no time steps (T = 0)"));
    }
    if let Some(tm) = model.steps() {
        if tm != steps {
            return Err(Error::arg("y", format!("has {steps} steps but the model's per-step matrices have {tm}")));
        }
    }
    for t in 0..steps {
        check_observation(y.row(t), Some(t))?;
    }
    check_input_series(model, u, steps)?;
    Ok(steps)
}

/// `y[t]` may hold NaN (missing) but not ±inf.
fn check_observation(y: &[f64], step: Option<usize>) -> Result<()> {
    if let Some(i) = y.iter().position(|v| v.is_infinite()) {
        return Err(Error::arg("y", format!("component {i} is {} (missing values are NaN, inf is not allowed)", y[i]))
            .at_step(step));
    }
    Ok(())
}

pub(crate) fn check_input_series(model: &LinearGaussian, u: Option<Series<'_>>, steps: usize) -> Result<()> {
    match u {
        Some(u) => {
            check_input_width(model, u.width)?;
            if u.steps != steps {
                return Err(Error::arg("u", format!("has {} steps but y has {steps}", u.steps)));
            }
            for t in 0..steps {
                check_input_row(u.row(t), Some(t))?;
            }
            Ok(())
        }
        None if model.has_input() => Err(Error::arg(
            "u",
            format!(
                "the model has B or D with k = {} inputs, so u of shape (T, {}) is required",
                model.n_inputs(),
                model.n_inputs()
            ),
        )),
        None => Ok(()),
    }
}

fn check_input_width(model: &LinearGaussian, width: usize) -> Result<()> {
    let k = model.n_inputs();
    if k == 0 {
        return Err(Error::arg("u", "given, but the model has neither B nor D"));
    }
    if width != k {
        return Err(Error::arg("u", format!("expected {k} inputs per step (B/D have k = {k} columns), got {width}")));
    }
    Ok(())
}

fn check_input_row(u: &[f64], step: Option<usize>) -> Result<()> {
    if let Some(v) = u.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("u", format!("contains a non-finite value ({v})")).at_step(step));
    }
    Ok(())
}

/// x0 has n finite entries; P0 is a finite symmetric PSD n × n matrix.
pub(crate) fn check_prior(n: usize, x0: &[f64], p0: &[f64]) -> Result<()> {
    if x0.len() != n {
        return Err(Error::arg("x0", format!("expected {n} entries (the state size n), got {}", x0.len())));
    }
    if let Some(v) = x0.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("x0", format!("contains a non-finite value ({v})")));
    }
    if p0.len() != n * n {
        return Err(Error::arg("P0", format!("expected an ({n}, {n}) matrix, got {} entries", p0.len())));
    }
    if let Some(v) = p0.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("P0", format!("contains a non-finite value ({v})")));
    }
    check_symmetric(p0, n).map_err(|p| Error::arg("P0", p))?;
    check_psd(p0, n).map_err(|p| Error::arg("P0", p))
}

/// The filter one step at a time, for streams: `update(y)` then `predict(u)`, or `step`.
///
/// The state starts as the prior `x̂(0|−1), P(0|−1)`. After `update` at step t, [`x`](Self::x)
/// and [`p`](Self::p) are `x̂(t|t), P(t|t)`; after `predict` they are `x̂(t+1|t), P(t+1|t)` and
/// the step counter advances. `predict` without an `update` treats the step as missing.
/// Results equal [`filter`] on the same data.
#[derive(Debug, Clone)]
pub struct KalmanFilter {
    model: Arc<LinearGaussian>,
    ws: Workspace,
    form: UpdateForm,
    t: usize,
    updated: bool,
    loglik: f64,
}

impl KalmanFilter {
    /// Starts from the prior `(x0, P0) = x̂(0|−1), P(0|−1)`.
    pub fn new(model: Arc<LinearGaussian>, x0: &[f64], p0: &[f64], form: UpdateForm) -> Result<Self> {
        check_prior(model.n_states(), x0, p0)?;
        let ws = start(&model, x0, p0);
        Ok(KalmanFilter { model, ws, form, t: 0, updated: false, loglik: 0.0 })
    }

    /// Measurement update with `y` (length m, NaN = missing); `u` is needed when the model has D.
    pub fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        let m = self.model.n_obs();
        if y.len() != m {
            return Err(
                Error::arg("y", format!("expected {m} values (m = {m}), got {}", y.len())).at_step(Some(self.t))
            );
        }
        check_observation(y, Some(self.t))?;
        self.check_input(u, "D", self.model.matrices().d.is_some())?;
        if self.updated {
            return Err(Error::arg("y", "update called twice without a predict in between").at_step(Some(self.t)));
        }
        let sys = self.model.at(self.t);
        let d = self.ws.dims();
        self.ws.update(d, &sys, y, u, self.form, self.t)?;
        self.loglik += self.ws.loglik_t;
        self.updated = true;
        Ok(())
    }

    /// Time update to the next step; `u` is needed when the model has B.
    pub fn predict(&mut self, u: Option<&[f64]>) -> Result<()> {
        self.check_input(u, "B", self.model.matrices().b.is_some())?;
        if !self.updated {
            self.ws.skip_update();
        }
        let sys = self.model.at(self.t);
        let d = self.ws.dims();
        self.ws.predict(d, &sys, u);
        self.t += 1;
        self.updated = false;
        Ok(())
    }

    /// `update(y, u)` then `predict(u)`.
    pub fn step(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        self.update(y, u)?;
        self.predict(u)
    }

    /// Checks the step is within a per-step model and `u`; `u` is required when the matrix
    /// `needs` (D for the update, B for the time update) is in the model.
    pub(crate) fn check_input(&self, u: Option<&[f64]>, needs: &str, required: bool) -> Result<()> {
        if let Some(tm) = self.model.steps() {
            if self.t >= tm {
                return Err(Error::arg(
                    "model",
                    format!("its per-step matrices cover {tm} steps; step {} is past the end", self.t),
                ));
            }
        }
        match u {
            Some(u) => {
                check_input_width(&self.model, u.len())?;
                check_input_row(u, Some(self.t))
            }
            None if required => Err(Error::arg(
                "u",
                format!("the model has {needs}, so u with {} values is required", self.model.n_inputs()),
            )
            .at_step(Some(self.t))),
            None => Ok(()),
        }
    }

    /// Current state estimate: `x̂(t|t)` after an update, `x̂(t|t−1)` otherwise.
    pub fn x(&self) -> &[f64] {
        if self.updated {
            &self.ws.x_filt
        } else {
            &self.ws.x_pred
        }
    }

    /// Covariance of [`x`](Self::x).
    pub fn p(&self) -> &[f64] {
        if self.updated {
            &self.ws.p_filt
        } else {
            &self.ws.p_pred
        }
    }

    /// The current step t (number of predicts so far).
    pub fn t(&self) -> usize {
        self.t
    }

    /// Sum of the log-likelihood terms of the updates so far.
    pub fn loglik(&self) -> f64 {
        self.loglik
    }

    /// The model.
    pub fn model(&self) -> &Arc<LinearGaussian> {
        &self.model
    }

    /// Whether the current step has been updated (x, P are then filtered estimates).
    pub fn is_updated(&self) -> bool {
        self.updated
    }

    pub(crate) fn workspace(&self) -> &Workspace {
        &self.ws
    }
}
