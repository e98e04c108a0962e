//! The Kalman filter over a whole series ([`filter`], [`loglik`]) and one step at a time
//! ([`KalmanFilter`]).
//!
//! Conventions (docs/conventions.md): the prior `(x0, P0)` is `x̂(0|−1), P(0|−1)`, so the
//! first operation is the measurement update with `y[0]`. `y` is `(T, m)` row-major; NaN marks
//! a missing component. `u` is `(T, k)`; `u[t]` enters `x[t+1]` through B and `y[t]` through D.
//! The recursion is Söderström Lemma 6.1 / (6.24) (docs/algorithms.md, "Filter recursion").

mod diffuse;
pub(crate) mod forms;
mod outputs;
pub(crate) mod step;
mod streaming;

pub use outputs::{Dim, FilterOutputs, FilterResult, OutputField, FILTER_FIELDS};
pub use step::UpdateForm;
pub(crate) use step::Workspace;
pub use streaming::KalmanFilter;

use std::borrow::Borrow;

use crate::core::dims::{with_dims, Buf, Dims};
use crate::core::gaussian::LoglikSum;
use crate::core::isa::{kernel, run_best, Kernel};
use crate::core::validate::check_prior;
pub use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::{LinearGaussian, StepView};
use crate::linear::validate::check_converge_tol;
pub(crate) use crate::linear::validate::{check_data, check_series};
use step::{all_observed, overflowed, Features};

/// How the filter runs: the covariance update form and whether to freeze the gains once the
/// covariance has converged.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[non_exhaustive]
pub struct FilterOptions {
    /// The update form: Joseph (default), standard, or one of the robust forms (square-root,
    /// U-D, information, sequential; `forms`).
    pub form: UpdateForm,
    /// Freeze P, S and the gains once ‖P(t+1|t) − P(t|t−1)‖_max ≤ tol · max(1, ‖P‖_max) at a
    /// fully observed step (like statsmodels' steady-state switch); a missing value resumes
    /// the full recursion until it has converged again. Then a step costs O(n² + nm + m²).
    /// Off (`None`) by default; constant models only. With P0 the stationary P(t|t−1) and a
    /// small tolerance this is the steady-state (constant-gain) filter that returns to the
    /// stationary gains after a gap.
    pub converge_tol: Option<f64>,
}

impl FilterOptions {
    /// The given update form, no gain freezing.
    pub fn new(form: UpdateForm) -> Self {
        FilterOptions { form, converge_tol: None }
    }

    /// The same options with gains frozen once converged to `tol` (see the field).
    pub fn converge_tol(self, tol: f64) -> Self {
        FilterOptions { converge_tol: Some(tol), ..self }
    }
}

impl From<UpdateForm> for FilterOptions {
    fn from(form: UpdateForm) -> Self {
        FilterOptions::new(form)
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
    out.check_sizes(steps, n, m)?;
    let converge_tol = check_converge_tol(model, options.converge_tol)?;
    let run = Run { model, y, u, x0, p0, form: options.form, converge_tol, kernel: kernel(), start: 0 };
    with_dims!(run.kernel, n, m, |d| run.filter(d, &mut out))
}

/// [`filter_into`] with an exact diffuse start (docs/algorithms.md, "Exact diffuse
/// initialization"): P(0|−1) = `p0` + κ `p0_inf`, κ → ∞, for states whose initial value is
/// unknown (Koopman 1997; Durbin & Koopman (2012) Sec. 5.2 and 6.4). The first d steps run the
/// univariate exact diffuse recursion (their P_pred and P_filt are the finite parts P_*, and
/// `p_pred_inf`, if given, `(T, n, n)`, receives P_∞(t|t−1) for t < d, zero after); the
/// ordinary filter takes over once P_∞ = 0. Returns the diffuse log-likelihood (Durbin &
/// Koopman (2012) Sec. 7.2.2, with log 2π for every observation) and d.
#[allow(clippy::too_many_arguments)]
pub fn filter_diffuse_into(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    p0_inf: &[f64],
    options: impl Into<FilterOptions>,
    mut out: FilterOutputs<'_>,
    mut p_pred_inf: Option<&mut [f64]>,
) -> Result<(f64, usize)> {
    let (n, m) = (model.n_states(), model.n_obs());
    let options = options.into();
    let steps = check_data(model, y, u, x0, p0)?;
    check_prior(n, x0, p0_inf).map_err(|e| e.renamed("P0", "P0_inf"))?;
    out.check_sizes(steps, n, m)?;
    if let Some(buf) = p_pred_inf.as_deref_mut() {
        if buf.len() != steps * n * n {
            return Err(Error::arg(
                "P_pred_inf",
                format!("output buffer has {} entries, needs {}", buf.len(), steps * n * n),
            ));
        }
        buf.fill(0.0);
    }
    let converge_tol = check_converge_tol(model, options.converge_tol)?;
    let start = diffuse::diffuse_start(model, y, u, x0, p0, p0_inf, &mut out, p_pred_inf)?;
    if start.steps == steps {
        out.store_next(&start.x, &start.p);
        return Ok((start.loglik, start.steps));
    }
    check_prior(n, &start.x, &start.p).map_err(|e| e.renamed("P0", "P(d|d-1)"))?;
    let run = Run {
        model,
        y,
        u,
        x0: &start.x,
        p0: &start.p,
        form: options.form,
        converge_tol,
        kernel: kernel(),
        start: start.steps,
    };
    let rest = with_dims!(run.kernel, n, m, |d| run.filter(d, &mut out))?;
    Ok((start.loglik + rest, start.steps))
}

/// The RTS smoother in square-root form after the square-root filter (`forms`): the filter's
/// outputs given in `filt`, the smoother's in `smooth` (sizes checked by the caller); returns
/// the log-likelihood.
#[allow(clippy::too_many_arguments)]
pub(crate) fn smooth_square_root_into(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    mut filt: FilterOutputs<'_>,
    x_smooth: Option<&mut [f64]>,
    p_smooth: Option<&mut [f64]>,
    p_lag1: Option<&mut [f64]>,
) -> Result<f64> {
    let (n, m) = (model.n_states(), model.n_obs());
    let steps = check_data(model, y, u, x0, p0)?;
    filt.check_sizes(steps, n, m)?;
    let (mut own_x, mut own_xp) = (Vec::new(), Vec::new());
    let x_smooth = x_smooth.unwrap_or_else(|| {
        own_x.resize(steps * n, 0.0);
        &mut own_x
    });
    let x_pred = filt.x_pred.take().unwrap_or_else(|| {
        own_xp.resize(steps * n, 0.0);
        &mut own_xp
    });
    let smooth = forms::smoother::SquareRootSmootherOutputs { x_filt: filt.x_filt.take(), p_smooth, p_lag1 };
    let mut forward = FilterOutputs { x_pred: Some(x_pred), x_filt: Some(x_smooth), ..filt };
    let run = Run { model, y, u, x0, p0, form: UpdateForm::SquareRoot, converge_tol: None, kernel: kernel(), start: 0 };
    forms::smooth_square_root(&run, &mut forward, smooth)
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

/// One pass of the filter over the data from the prior `(x0, p0)` (all validated already).
#[derive(Clone, Copy)]
pub(crate) struct Run<'a> {
    pub model: &'a LinearGaussian,
    pub y: Series<'a>,
    pub u: Option<Series<'a>>,
    pub x0: &'a [f64],
    pub p0: &'a [f64],
    pub form: UpdateForm,
    /// Freeze the gains once converged (see [`FilterOptions::converge_tol`]).
    pub converge_tol: Option<f64>,
    /// The loops to run (`core::isa`), read once per call.
    pub kernel: Kernel,
    /// The first step to filter (after an exact diffuse start; 0 otherwise): `x0`, `p0` are
    /// then x̂(start|start−1), P(start|start−1).
    pub start: usize,
}

/// A constant model's F, H, Q, R and N copied once into buffers of the call's sizes (local
/// arrays for compile-time sizes, which the compiler keeps in registers across the loop).
struct LocalMatrices<D: Dims> {
    f: D::Square,
    h: D::StateObs,
    q: D::Square,
    r: D::ObsSquare,
    n: Option<D::StateObs>,
}

impl<D: Dims> LocalMatrices<D> {
    fn new(d: D, sys: &StepView<'_>) -> Self {
        let copy = |mut buf: D::Square, src: &[f64]| {
            buf.get_mut().copy_from_slice(src);
            buf
        };
        let mut h = d.state_obs();
        h.get_mut().copy_from_slice(sys.h);
        let mut r = d.obs_square();
        r.get_mut().copy_from_slice(sys.r);
        let n = sys.n.map(|nn| {
            let mut buf = d.state_obs();
            buf.get_mut().copy_from_slice(nn);
            buf
        });
        LocalMatrices { f: copy(d.square(), sys.f), h, q: copy(d.square(), sys.q), r, n }
    }

    /// The step's matrices: these, with B and D of `sys` (they only touch the mean).
    #[inline(always)]
    fn view<'a>(&'a self, sys: &StepView<'a>) -> StepView<'a> {
        StepView {
            f: self.f.get(),
            h: self.h.get(),
            q: self.q.get(),
            r: self.r.get(),
            b: sys.b,
            d: sys.d,
            n: self.n.as_ref().map(|nn| nn.get()),
        }
    }
}

impl Run<'_> {
    /// The filter from the prior `(x0, p0)`, storing the outputs that are given; returns the
    /// log-likelihood. Two loops, each its own function compiled for each instruction set
    /// (`run_best!`; in one function they share registers and slow each other down): a
    /// constant model without N or gain freezing, its matrices copied into local buffers and
    /// the branches for those compiled out (~7% of a step at n = 4), and everything else.
    pub(crate) fn filter<D: Dims>(&self, d: D, out: &mut FilterOutputs<'_>) -> Result<f64> {
        if !self.form.is_covariance_form() {
            return forms::filter(self, out);
        }
        if self.model.steps().is_none() && self.model.at(0).n.is_none() && self.converge_tol.is_none() {
            return run_best!(self.kernel, d, |d| self.filter_plain(d, out));
        }
        run_best!(self.kernel, d, |d| self.filter_general(d, out))
    }

    /// A constant model without N or gain freezing. The workspace lives here, on this
    /// function's stack, for the whole loop.
    #[inline(always)]
    fn filter_plain<D: Dims>(&self, d: D, out: &mut FilterOutputs<'_>) -> Result<f64> {
        let mut ws = self.workspace(d, out);
        let first = self.model.at(0);
        let local = LocalMatrices::new(d, &first);
        let sys = local.view(&first);
        // A reference, not a copy per step: the out-of-line missing-value step takes the
        // step's matrices by address, so a per-step copy is written to the stack every step.
        let total = self.steps(&mut ws, out, |_| &sys, Features::PLAIN)?;
        out.store_next(ws.x_pred(), ws.p_pred());
        Ok(total)
    }

    /// Any model and options.
    #[inline(always)]
    fn filter_general<D: Dims>(&self, d: D, out: &mut FilterOutputs<'_>) -> Result<f64> {
        let mut ws = self.workspace(d, out);
        let total = self.steps(&mut ws, out, |t| self.model.at(t), Features::ALL)?;
        out.store_next(ws.x_pred(), ws.p_pred());
        Ok(total)
    }

    #[inline(always)]
    fn workspace<D: Dims>(&self, d: D, out: &FilterOutputs<'_>) -> Workspace<D> {
        let mut ws = Workspace::new(d, self.model.n_inputs(), self.x0, self.p0);
        ws.configure(out.gain.is_some(), out.gain_pred.is_some(), self.converge_tol);
        ws
    }

    /// Update with `y[t]`, then the time update to `t + 1`, for every t.
    ///
    /// With compile-time sizes the compiler keeps the workspace in registers (its buffers are
    /// small local arrays) only if every access to it has a constant offset and its address
    /// never leaves this function; otherwise every intermediate goes through the stack, where
    /// a row loaded right after being stored in pieces stalls (store forwarding fails). So
    /// the fully observed step, all of compile-time sizes, runs here, and a step with a
    /// missing value (a run-time number of observed components) runs out of line on a heap
    /// copy of the workspace. Both run the same code, so the results are the same bits.
    #[inline(always)]
    fn steps<'m, D: Dims, S: Borrow<StepView<'m>>>(
        &self,
        ws: &mut Workspace<D>,
        out: &mut FilterOutputs<'_>,
        at: impl Fn(usize) -> S,
        features: Features,
    ) -> Result<f64> {
        let mut copy: Option<Box<Workspace<D>>> = None;
        let mut total = LoglikSum::default();
        for t in self.start..self.y.steps() {
            let sys = at(t);
            let sys = sys.borrow();
            let (y, u_t) = (self.y.row(t), self.u.map(|u| u.row(t)));
            out.store_prior(t, ws.x_pred(), ws.p_pred());
            if all_observed(y) {
                ws.update_observed(sys, y, u_t, self.form, t, features)?;
                ws.predict_observed(sys, u_t, features);
            } else if D::FIXED {
                let d = ws.dims();
                let copy = copy.get_or_insert_with(|| Box::new(Workspace::new(d, 0, self.x0, self.p0)));
                copy.copy_prior_from(ws);
                copy.step_out_of_line(sys, y, u_t, self.form, t)?;
                ws.copy_from(copy);
            } else {
                ws.update(sys, y, u_t, self.form, t)?;
                ws.predict(sys, u_t);
            }
            ws.add_loglik(&mut total);
            out.store_step(t, ws);
        }
        // Each update checks its own result; a state that overflows during trailing missing
        // steps is caught here.
        if ws.x_pred().iter().any(|v| !v.is_finite()) {
            return Err(overflowed(self.y.steps().saturating_sub(1)));
        }
        Ok(total.total())
    }
}
