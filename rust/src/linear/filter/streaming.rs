//! [`KalmanFilter`]: the filter one step at a time, for streams.

use std::borrow::Borrow;
use std::sync::Arc;

use super::step::LastUpdate;
use super::step::{UpdateForm, Workspace};
use crate::core::dense::symmetrize;
use crate::core::dims::{with_dims, Dims, Fused};
use crate::core::gaussian::LoglikSum;
use crate::core::isa::{kernel, run_out_of_line};
use crate::core::validate::{
    check_input_row, check_joint_psd, check_observation, check_prior, check_psd, check_symmetric,
};
use crate::error::{Error, Result};
use crate::linear::model::{LinearGaussian, StepView};
use crate::linear::validate::check_input_width;

/// The filter one step at a time, for streams: `update(y)` then `predict(u)`, or `step`.
///
/// The state starts as the prior `x̂(0|−1), P(0|−1)`. After `update` at step t, [`x`](Self::x)
/// and [`p`](Self::p) are `x̂(t|t), P(t|t)`; after `predict` they are `x̂(t+1|t), P(t+1|t)` and
/// the step counter advances. `predict` without an `update` treats the step as missing.
/// Results equal [`filter`](super::filter) on the same data, computed with the arithmetic
/// chosen when the filter was made (fused multiply-adds or not, `core::isa`), for its life.
#[derive(Debug, Clone)]
pub struct KalmanFilter<M: Borrow<LinearGaussian> = Arc<LinearGaussian>> {
    model: M,
    ws: StreamWorkspace,
    form: UpdateForm,
    t: usize,
    updated: bool,
    loglik: LoglikSum,
}

impl<M: Borrow<LinearGaussian>> KalmanFilter<M> {
    /// Starts from the prior `(x0, P0) = x̂(0|−1), P(0|−1)`. The model may be owned, borrowed
    /// (`&LinearGaussian`) or shared (`Arc<LinearGaussian>`).
    pub fn new(model: M, x0: &[f64], p0: &[f64], form: UpdateForm) -> Result<Self> {
        let lg = model.borrow();
        check_prior(lg.n_states(), x0, p0)?;
        let ws = StreamWorkspace::new(form, lg.n_states(), lg.n_obs(), lg.n_inputs(), x0, p0)?;
        Ok(KalmanFilter { model, ws, form, t: 0, updated: false, loglik: LoglikSum::default() })
    }

    /// Measurement update with `y` (length m, NaN = missing); `u` is needed when the model has D.
    pub fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        self.update_with(y, u, None, None)
    }

    /// [`update`](Self::update) with this step's observation matrix `h` (m × n) and/or
    /// measurement noise covariance `r` (m × m), row-major, in place of the model's, for this
    /// update only (filterpy's `update(z, R, H)`). Both must be finite, `r` symmetric (it is
    /// symmetrized, as the model's R) positive semidefinite, and with N the joint covariance
    /// [[Q, N], [N', r]] too. The time update that follows uses the model's F, B, Q, N with the
    /// gains of this update.
    pub fn update_with(&mut self, y: &[f64], u: Option<&[f64]>, h: Option<&[f64]>, r: Option<&[f64]>) -> Result<()> {
        let (n, m, t) = (self.model().n_states(), self.model().n_obs(), self.t);
        if y.len() != m {
            return Err(Error::arg_at("y", t, format!("expected {m} values (m = {m}), got {}", y.len())));
        }
        check_observation(y, Some(t))?;
        self.check_input(u, "D", self.model().matrices().d.is_some())?;
        if self.updated {
            return Err(Error::arg_at("y", t, "update called twice without a predict in between"));
        }
        let mut sys = self.model.borrow().at(t);
        if let Some(h) = h {
            check_step_matrix("H", h, m, n, t)?;
            sys.h = h;
        }
        let r_sym;
        if let Some(r) = r {
            check_step_matrix("R", r, m, m, t)?;
            check_symmetric(r, m).map_err(|p| Error::arg_at("R", t, p))?;
            r_sym = symmetrized(r, m);
            check_psd(&r_sym, m).map_err(|p| Error::arg_at("R", t, p))?;
            if let Some(nn) = sys.n {
                check_joint_psd(sys.q, nn, &r_sym, n, m)
                    .map_err(|p| Error::arg_at("R", t, format!("with the model's Q and N, {p}")))?;
            }
            sys.r = &r_sym;
        }
        self.ws.0.update(&sys, y, u, self.form, t)?;
        self.ws.0.add_loglik(&mut self.loglik);
        self.updated = true;
        Ok(())
    }

    /// Time update to the next step; `u` is needed when the model has B.
    pub fn predict(&mut self, u: Option<&[f64]>) -> Result<()> {
        self.check_input(u, "B", self.model().matrices().b.is_some())?;
        let sys = self.model.borrow().at(self.t);
        self.ws.0.predict(&sys, u, self.updated, self.t)?;
        self.t += 1;
        self.updated = false;
        Ok(())
    }

    /// Makes `(x, p)` the filtered estimate x̂(t|t), P(t|t) of this step, in place of an
    /// update's: the interacting multiple-model filter's mixed state (Söderström
    /// (9.72)–(9.74)) or a Gaussian-sum filter's merged component. The next
    /// [`predict`](Self::predict) is F x + B u and F p F' + Q, without an update's N terms
    /// (the multiple-model filter refuses models with N). `x` has n values, `p` n × n.
    pub fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        self.ws.0.set_filtered(x, p);
        self.updated = true;
    }

    /// The log-likelihood term of the last update (0 when nothing was observed).
    pub fn loglik_t(&self) -> f64 {
        self.ws.0.loglik_t()
    }

    /// `update(y, u)` then `predict(u)`.
    pub fn step(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        self.update(y, u)?;
        self.predict(u)
    }

    /// Checks the step is within a per-step model and `u`; `u` is required when the matrix
    /// `needs` (D for the update, B for the time update) is in the model.
    pub(crate) fn check_input(&self, u: Option<&[f64]>, needs: &str, required: bool) -> Result<()> {
        if let Some(tm) = self.model().steps() {
            if self.t >= tm {
                return Err(Error::arg(
                    "model",
                    format!("its per-step matrices cover {tm} steps; step {} is past the end", self.t),
                ));
            }
        }
        match u {
            Some(u) => {
                check_input_width(self.model(), u.len())?;
                check_input_row(u, Some(self.t))
            }
            None if required => Err(Error::arg(
                "u",
                format!("the model has {needs}, so u with {} values is required", self.model().n_inputs()),
            )
            .at_step(Some(self.t))),
            None => Ok(()),
        }
    }

    /// Current state estimate: `x̂(t|t)` after an update, `x̂(t|t−1)` otherwise.
    pub fn x(&self) -> &[f64] {
        if self.updated {
            self.ws.0.x_filt()
        } else {
            self.ws.0.x_pred()
        }
    }

    /// Covariance of [`x`](Self::x).
    pub fn p(&self) -> &[f64] {
        if self.updated {
            self.ws.0.p_filt()
        } else {
            self.ws.0.p_pred()
        }
    }

    /// The current step t (number of predicts so far).
    pub fn t(&self) -> usize {
        self.t
    }

    /// Sum of the log-likelihood terms of the updates so far.
    pub fn loglik(&self) -> f64 {
        self.loglik.total()
    }

    /// The running sum behind [`loglik`](Self::loglik) (for pickling).
    #[cfg_attr(not(feature = "python"), allow(dead_code))]
    pub(crate) fn loglik_sum(&self) -> LoglikSum {
        self.loglik
    }

    /// The model.
    pub fn model(&self) -> &LinearGaussian {
        self.model.borrow()
    }

    /// Whether the current step has been updated (x, P are then filtered estimates).
    pub fn is_updated(&self) -> bool {
        self.updated
    }

    /// What the last update used (`h`: the step's full H), for the fixed-lag smoother.
    pub(crate) fn last_update<'a>(&'a self, h: &'a [f64]) -> LastUpdate<'a> {
        self.ws.0.last_update(h)
    }

    /// The predictor gain of the last time update, for the fixed-lag smoother.
    pub(crate) fn gain_pred(&self) -> &[f64] {
        self.ws.0.gain_pred()
    }

    /// The covariance update form.
    pub fn form(&self) -> UpdateForm {
        self.form
    }

    /// `x̂(t|t−1), P(t|t−1)` of the current step t, also after its update (which leaves them
    /// as they were). With `t`, the log-likelihood before the update and the update's data,
    /// they determine everything the filter does next (see [`resume`](Self::resume)).
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub(crate) fn prediction(&self) -> (&[f64], &[f64]) {
        (self.ws.0.x_pred(), self.ws.0.p_pred())
    }

    /// The filter at step `t` before its update, from the [`prediction`](Self::prediction)
    /// `x̂(t|t−1), P(t|t−1)` and the log-likelihood of the updates before t: it continues
    /// bit for bit as the filter these came from (for pickling). P is not checked for
    /// definiteness, which rounding may have touched in a long stream; it is symmetrized,
    /// which leaves a filter's P(t|t−1) (exactly symmetric) as it is.
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub(crate) fn resume(
        model: M,
        x_pred: &[f64],
        p_pred: &[f64],
        form: UpdateForm,
        t: usize,
        loglik: LoglikSum,
    ) -> Result<Self> {
        let lg = model.borrow();
        let (n, m, k, steps) = (lg.n_states(), lg.n_obs(), lg.n_inputs(), lg.steps());
        for (arg, values, len) in [("x_pred", x_pred, n), ("P_pred", p_pred, n * n)] {
            if values.len() != len {
                return Err(Error::arg(arg, format!("expected {len} values (n = {n}), got {}", values.len())));
            }
            if let Some(v) = values.iter().find(|v| !v.is_finite()) {
                return Err(Error::arg(arg, format!("contains a non-finite value ({v})")));
            }
        }
        if let Some(tm) = steps {
            if t > tm {
                return Err(Error::arg("t", format!("is {t}, past the {tm} steps of the model's per-step matrices")));
            }
        }
        let ws = StreamWorkspace::new(form, n, m, k, x_pred, p_pred)?;
        Ok(KalmanFilter { model, ws, form, t, updated: false, loglik })
    }
}

/// The streaming filter's workspace: of compile-time sizes for n ≤ 12, m ≤ 4 (`with_dims!`;
/// an update of run-time sizes at n = 4 executed ~5,000 instructions, a whole step of
/// the compile-time loop ~600), with the arithmetic of
/// the loops chosen when it was made (fused sizes run with FMA enabled, `run_out_of_line`). Boxed
/// behind a trait so that the filter has one type whatever its sizes.
pub(super) trait Stream: std::fmt::Debug + Send + Sync {
    fn update(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>, form: UpdateForm, t: usize) -> Result<()>;
    fn predict(&mut self, sys: &StepView<'_>, u: Option<&[f64]>, updated: bool, t: usize) -> Result<()>;
    fn add_loglik(&self, sum: &mut LoglikSum);
    fn loglik_t(&self) -> f64;
    fn set_filtered(&mut self, x: &[f64], p: &[f64]);
    fn x_pred(&self) -> &[f64];
    fn p_pred(&self) -> &[f64];
    fn x_filt(&self) -> &[f64];
    fn p_filt(&self) -> &[f64];
    fn gain_pred(&self) -> &[f64];
    fn last_update<'a>(&'a self, h: &'a [f64]) -> LastUpdate<'a>;
    fn boxed_clone(&self) -> Box<dyn Stream>;
}

impl<D: Dims + std::fmt::Debug + 'static> Stream for Workspace<D>
where
    Workspace<D>: Sync,
{
    fn update(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>, form: UpdateForm, t: usize) -> Result<()> {
        run_out_of_line::<D, _>(
            #[inline(always)]
            || Workspace::update(self, sys, y, u, form, t),
        )
    }
    fn predict(&mut self, sys: &StepView<'_>, u: Option<&[f64]>, updated: bool, _t: usize) -> Result<()> {
        run_out_of_line::<D, _>(
            #[inline(always)]
            || {
                if !updated {
                    self.skip_update();
                }
                Workspace::predict(self, sys, u)
            },
        );
        Ok(())
    }
    fn add_loglik(&self, sum: &mut LoglikSum) {
        Workspace::add_loglik(self, sum)
    }
    fn loglik_t(&self) -> f64 {
        Workspace::loglik_t(self)
    }
    fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        Workspace::set_filtered(self, x, p)
    }
    fn x_pred(&self) -> &[f64] {
        Workspace::x_pred(self)
    }
    fn p_pred(&self) -> &[f64] {
        Workspace::p_pred(self)
    }
    fn x_filt(&self) -> &[f64] {
        Workspace::x_filt(self)
    }
    fn p_filt(&self) -> &[f64] {
        Workspace::p_filt(self)
    }
    fn gain_pred(&self) -> &[f64] {
        Workspace::gain_pred(self)
    }
    fn last_update<'a>(&'a self, h: &'a [f64]) -> LastUpdate<'a> {
        Workspace::last_update(self, h)
    }
    fn boxed_clone(&self) -> Box<dyn Stream> {
        Box::new(self.clone())
    }
}

#[derive(Debug)]
struct StreamWorkspace(Box<dyn Stream>);

impl Clone for StreamWorkspace {
    fn clone(&self) -> Self {
        StreamWorkspace(self.0.boxed_clone())
    }
}

impl StreamWorkspace {
    /// The covariance forms' workspace, or a robust form's recursion (`forms`).
    fn new(form: UpdateForm, n: usize, m: usize, k: usize, x0: &[f64], p0: &[f64]) -> Result<Self> {
        if !form.is_covariance_form() {
            return Ok(StreamWorkspace(super::forms::stream::new_stream(form, n, m, k, x0, p0)?));
        }
        let kernel = kernel();
        Ok(StreamWorkspace(with_dims!(kernel, n, m, |d| new_stream(d, kernel.fused(), k, x0, p0))))
    }
}

fn new_stream<D: Dims + std::fmt::Debug + 'static>(
    d: D,
    fused: bool,
    k: usize,
    x0: &[f64],
    p0: &[f64],
) -> Box<dyn Stream>
where
    Workspace<D>: Sync,
    Workspace<Fused<D>>: Sync,
{
    if fused {
        Box::new(Workspace::new(Fused(d), k, x0, p0))
    } else if cfg!(target_arch = "x86_64") && (!D::FIXED || crate::core::isa::UNFUSED_SIZES) {
        Box::new(Workspace::new(d, k, x0, p0))
    } else {
        crate::core::isa::not_compiled()
    }
}

/// A matrix given for one step ([`KalmanFilter::update_with`]): `rows × cols` finite values.
fn check_step_matrix(arg: &'static str, values: &[f64], rows: usize, cols: usize, t: usize) -> Result<()> {
    if values.len() != rows * cols {
        return Err(Error::arg_at(arg, t, format!("expected {rows} × {cols} values, got {}", values.len())));
    }
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(Error::arg_at(arg, t, format!("contains a non-finite value ({v})"))),
        None => Ok(()),
    }
}

/// A symmetrized copy of the m × m `a`.
fn symmetrized(a: &[f64], m: usize) -> Vec<f64> {
    let mut sym = a.to_vec();
    symmetrize(&mut sym, m);
    sym
}
