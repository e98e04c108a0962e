//! One step of the Kalman filter for a linear model: how the model predicts the measurement
//! (for the model-agnostic [`GaussianUpdate`]) and the time update, on a workspace allocated
//! once per sequence so that the time loop allocates nothing.
//!
//! Söderström Lemma 6.1, (6.22)–(6.27) (docs/algorithms.md, "Filter recursion"):
//!
//! ```text
//! e = y − H x̂(t|t−1) − D u            S = H P(t|t−1) H' + R,   C = P(t|t−1) H'
//! K = C S⁻¹                            x̂(t|t) = x̂(t|t−1) + K e
//! P(t|t) = P − K S K'                   (standard)
//!        = (I − K H) P (I − K H)' + K R K'    (Joseph form, valid for any gain)
//! x̂(t+1|t) = F x̂(t|t) + B u + N S⁻¹ e
//! P(t+1|t) = F P(t|t) F' + Q − N S⁻¹ N' − F K N' − N K' F'
//! K_pred  = F K + N S⁻¹ = (F P H' + N) S⁻¹
//! ```
//!
//! Missing data: only the observed components of y update (their rows of H, D, R and columns of
//! N); a step with nothing observed skips the update and its time update has no N term.
//!
//! The workspace is generic over its [`Dims`]: with compile-time sizes every buffer is a local
//! array the compiler keeps in registers, with run-time sizes a heap vector. The arithmetic is
//! the same, so both give the same bits (which `filter_batch`'s shared recursion relies on).

use crate::core::dense::{ldl_solve, mul, mul_bt, mul_bt_sym, mul_sym, mul_vec, mul_vec_add, symmetrize, transpose};
use crate::core::dims::{Buf, Dims};
use crate::core::gaussian::{GaussianUpdate, LogDet, LoglikSum, MeasurementPrediction};
#[cfg(target_arch = "x86_64")]
use crate::core::rows4::{self, Avx2Fma, Rows};
use crate::error::{Error, Result};
use crate::linear::model::StepView;

pub use crate::core::gaussian::UpdateForm;

/// The filter's state and buffers; sizes fixed by (n, m, k) at construction.
#[derive(Debug, Clone)]
pub(crate) struct Workspace<D: Dims> {
    d: D,
    k: usize,
    /// x̂(t|t−1), P(t|t−1): the state before the update (and after the time update).
    x_pred: D::Vector,
    p_pred: D::Square,
    /// x̂(t|t), P(t|t).
    x_filt: D::Vector,
    p_filt: D::Square,
    /// Innovation of every component (NaN where missing), and the full S (m × m).
    innov: D::Obs,
    s_full: D::ObsSquare,
    /// P H' of all components (n × m).
    pht: D::StateObs,
    /// Filter gain and predictor gain, n × m, zero columns for missing components.
    gain: D::StateObs,
    gain_pred: D::StateObs,
    update: GaussianUpdate<D>,
    /// Freeze the covariance recursion once ‖P(t+1|t) − P(t|t−1)‖ ≤ tol · max(1, ‖P‖)
    /// (max norms) at a fully observed step; a missing value unfreezes it.
    converge_tol: Option<f64>,
    /// Whether the covariances and gains are frozen (then a step costs O(n² + nm + m²)).
    frozen: bool,
    /// Whether to compute the predictor gain when the model has no N (it is then only an
    /// output; with N it enters the time update anyway).
    want_gain_pred: bool,
    /// Whether to fill `gain` (only an output).
    want_gain: bool,
    /// Components observed at this step, and how many (0 = no update; m = all, `obs` unused).
    obs: Vec<usize>,
    m_obs: usize,
    /// The observed block when some component is missing: e_o, P H'_o, S_o, H_o, R_o, N_o.
    partial: Partial<D>,
    // Scratch: F P(t|t) (n × n), K and F K (n × mo), S⁻¹ N' (mo × n); P(t|t−1) before the
    // time update.
    fp: D::Square,
    gain_o: D::StateObs,
    f_gain: D::StateObs,
    s_inv_nt: D::StateObs,
    p_prev: D::Square,
}

/// Which parts of the recursion a time loop can meet, decided once per call. With neither
/// (the common case) the fully observed step is compiled without the branches for them:
/// they cost ~15% of a step at n = 4 even when never taken, because the code they guard
/// keeps more values alive across the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Features {
    /// The model has a cross-covariance N = E[w v'] (Söderström (6.25), (6.26)).
    pub cross_cov: bool,
    /// The gains may freeze once converged (`converge_tol`).
    pub freezing: bool,
}

impl Features {
    /// Everything possible: what the steps other than a time loop's fully observed ones use.
    pub const ALL: Features = Features { cross_cov: true, freezing: true };
    /// Neither N nor freezing.
    pub const PLAIN: Features = Features { cross_cov: false, freezing: false };
}

/// The rows and columns of the observed components, gathered when some are missing.
#[derive(Debug, Clone)]
struct Partial<D: Dims> {
    innov: D::Obs,
    pht: D::StateObs,
    s: D::ObsSquare,
    h: D::StateObs,
    r: D::ObsSquare,
    n: D::StateObs,
}

/// What the last measurement update used, for estimators that ride along the filter (the
/// fixed-point and fixed-lag smoothers): the observed components' rows of H, the L D L' factor
/// of their S and S⁻¹ e.
pub(crate) struct LastUpdate<'a> {
    /// Number of observed components (0: no update).
    pub m_obs: usize,
    pub h: &'a [f64],
    pub s_factor: &'a [f64],
    pub s_inv_e: &'a [f64],
}

impl<D: Dims> Workspace<D> {
    /// A workspace for sizes `d` and `k` inputs, starting from the prior `(x0, P0)`.
    #[inline(always)]
    pub fn new(d: D, k: usize, x0: &[f64], p0: &[f64]) -> Self {
        let mut ws = Workspace {
            d,
            k,
            x_pred: d.vector(),
            p_pred: d.square(),
            x_filt: d.vector(),
            p_filt: d.square(),
            innov: d.obs(),
            s_full: d.obs_square(),
            pht: d.state_obs(),
            gain: d.state_obs(),
            gain_pred: d.state_obs(),
            update: GaussianUpdate::new(d),
            converge_tol: None,
            frozen: false,
            want_gain_pred: true,
            want_gain: true,
            obs: vec![0; d.m()],
            m_obs: 0,
            partial: Partial {
                innov: d.obs(),
                pht: d.state_obs(),
                s: d.obs_square(),
                h: d.state_obs(),
                r: d.obs_square(),
                n: d.state_obs(),
            },
            fp: d.square(),
            gain_o: d.state_obs(),
            f_gain: d.state_obs(),
            s_inv_nt: d.state_obs(),
            p_prev: d.square(),
        };
        ws.set_state(x0, p0);
        ws
    }

    /// Sets x̂(t|t−1), P(t|t−1) (P symmetrized).
    #[inline(always)]
    pub fn set_state(&mut self, x: &[f64], p: &[f64]) {
        self.x_pred.get_mut().copy_from_slice(x);
        self.p_pred.get_mut().copy_from_slice(p);
        symmetrize(self.p_pred.get_mut(), self.d.n());
    }

    /// Sets x̂(t|t), P(t|t) in place of an update's, for a time update with no update terms
    /// (no predictor gain, no N): the multiple-model filter's mixed state.
    #[inline(always)]
    pub fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        self.x_filt.get_mut().copy_from_slice(x);
        self.p_filt.get_mut().copy_from_slice(p);
        self.m_obs = 0;
    }

    /// Makes this workspace ready to take the step that `other` would take next: the same
    /// configuration and prior x̂(t|t−1), P(t|t−1). Only for a step with a missing value (which
    /// recomputes everything else, frozen gains included). Copying nothing else matters for
    /// speed: what the time loop never reads back from its workspace stays in registers.
    #[inline(always)]
    pub fn copy_prior_from(&mut self, other: &Self) {
        (self.d, self.k, self.converge_tol) = (other.d, other.k, other.converge_tol);
        (self.want_gain_pred, self.want_gain) = (other.want_gain_pred, other.want_gain);
        self.x_pred.clone_from(&other.x_pred);
        self.p_pred.clone_from(&other.p_pred);
    }

    /// Makes this workspace a copy of `other` without allocating (vectors keep their
    /// capacity). The destructuring names every field, so a new field cannot be forgotten.
    #[inline(always)]
    pub fn copy_from(&mut self, other: &Self) {
        let Workspace {
            d,
            k,
            x_pred,
            p_pred,
            x_filt,
            p_filt,
            innov,
            s_full,
            pht,
            gain,
            gain_pred,
            update,
            converge_tol,
            frozen,
            want_gain_pred,
            want_gain,
            obs,
            m_obs,
            partial: Partial { innov: p_innov, pht: p_pht, s: p_s, h: p_h, r: p_r, n: p_n },
            fp,
            gain_o,
            f_gain,
            s_inv_nt,
            p_prev,
        } = other;
        (self.d, self.k, self.converge_tol, self.frozen) = (*d, *k, *converge_tol, *frozen);
        (self.want_gain_pred, self.want_gain, self.m_obs) = (*want_gain_pred, *want_gain, *m_obs);
        self.update.copy_from(update);
        // The slices (not `Vec::clone_from`, which takes the address of the field).
        self.obs.copy_from_slice(obs);
        // Field by field, no loop over references: nothing may take the workspace's address.
        self.x_pred.clone_from(x_pred);
        self.p_pred.clone_from(p_pred);
        self.x_filt.clone_from(x_filt);
        self.p_filt.clone_from(p_filt);
        self.innov.clone_from(innov);
        self.s_full.clone_from(s_full);
        self.pht.clone_from(pht);
        self.gain.clone_from(gain);
        self.gain_pred.clone_from(gain_pred);
        self.partial.innov.clone_from(p_innov);
        self.partial.pht.clone_from(p_pht);
        self.partial.s.clone_from(p_s);
        self.partial.h.clone_from(p_h);
        self.partial.r.clone_from(p_r);
        self.partial.n.clone_from(p_n);
        self.fp.clone_from(fp);
        self.gain_o.clone_from(gain_o);
        self.f_gain.clone_from(f_gain);
        self.s_inv_nt.clone_from(s_inv_nt);
        self.p_prev.clone_from(p_prev);
    }

    /// Which outputs to compute: the filter gain, the predictor gain (without N it is only an
    /// output), and whether to freeze the recursion once it has converged to `converge_tol`.
    pub fn configure(&mut self, want_gain: bool, want_gain_pred: bool, converge_tol: Option<f64>) {
        self.want_gain = want_gain;
        self.want_gain_pred = want_gain_pred;
        self.converge_tol = converge_tol;
    }

    /// The sizes.
    #[inline(always)]
    pub fn dims(&self) -> D {
        self.d
    }

    /// x̂(t|t−1).
    #[inline(always)]
    pub fn x_pred(&self) -> &[f64] {
        self.x_pred.get()
    }
    /// P(t|t−1).
    #[inline(always)]
    pub fn p_pred(&self) -> &[f64] {
        self.p_pred.get()
    }
    /// x̂(t|t) (after an update).
    #[inline(always)]
    pub fn x_filt(&self) -> &[f64] {
        self.x_filt.get()
    }
    /// P(t|t) (after an update).
    #[inline(always)]
    pub fn p_filt(&self) -> &[f64] {
        self.p_filt.get()
    }
    /// The innovation of every component (NaN where missing).
    #[inline(always)]
    pub fn innov(&self) -> &[f64] {
        self.innov.get()
    }
    /// S = H P H' + R of all components.
    #[inline(always)]
    pub fn innovation_cov(&self) -> &[f64] {
        self.s_full.get()
    }
    /// The filter gain (n × m, zero columns for missing components), when wanted.
    #[inline(always)]
    pub fn gain(&self) -> &[f64] {
        self.gain.get()
    }
    /// The predictor gain (n × m), after the time update.
    #[inline(always)]
    pub fn gain_pred(&self) -> &[f64] {
        self.gain_pred.get()
    }
    /// The log-likelihood term of the last update.
    #[inline(always)]
    pub fn loglik_t(&self) -> f64 {
        self.update.loglik_t()
    }

    /// Adds the log-likelihood term of the last update to `sum`.
    #[inline(always)]
    pub fn add_loglik(&self, sum: &mut LoglikSum) {
        sum.add(&self.update);
    }

    /// What the last update used; `h` is the step's full H.
    pub fn last_update<'a>(&'a self, h: &'a [f64]) -> LastUpdate<'a> {
        let (n, mo) = (self.d.n(), self.m_obs);
        LastUpdate {
            m_obs: mo,
            h: if mo == self.d.m() { &h[..mo * n] } else { &self.partial.h.get()[..mo * n] },
            s_factor: self.update.s_factor(mo),
            s_inv_e: self.update.s_inv_e(mo),
        }
    }

    /// The data-independent part of the last fully observed update: P H' (n × m), the
    /// L D L' factor of S (m × m) and ln det S.
    pub fn gains(&self) -> (&[f64], &[f64], LogDet) {
        (self.pht.get(), self.update.s_factor(self.d.m()), self.update.log_det())
    }

    /// Loads gains recorded by [`gains`](Self::gains) and freezes the covariance recursion:
    /// the next fully observed update and time update then move only the state, with exactly
    /// the operations of the full recursion.
    pub fn load_gains(&mut self, pht: &[f64], s_factor: &[f64], log_det: LogDet) {
        self.pht.get_mut().copy_from_slice(pht);
        self.update.load_factor(s_factor, log_det);
        self.m_obs = self.d.m();
        self.frozen = true;
    }

    /// Measurement update with `y` (NaN = missing), from (x_pred, p_pred) to (x_filt, p_filt).
    /// Fails when S is not positive definite, or when the state has left float64's range (a
    /// NaN reaches the log-likelihood term at the first step whose innovation or state
    /// overflowed: an unstable F over a long series, data near 1e308).
    #[inline(always)]
    pub fn update(
        &mut self,
        sys: &StepView<'_>,
        y: &[f64],
        u: Option<&[f64]>,
        form: UpdateForm,
        t: usize,
    ) -> Result<()> {
        if all_observed(y) {
            return self.update_observed(sys, y, u, form, t, Features::ALL);
        }
        self.update_missing(sys, y, u, form, t)
    }

    /// [`update`](Self::update) then [`predict`](Self::predict) in a function of its own (the
    /// rare steps of a time loop that keeps its own workspace in registers).
    #[inline(always)]
    pub fn step_out_of_line(
        &mut self,
        sys: &StepView<'_>,
        y: &[f64],
        u: Option<&[f64]>,
        form: UpdateForm,
        t: usize,
    ) -> Result<()> {
        // Not inlined into the loop, so compiled for the instruction set of its own.
        crate::core::isa::run_out_of_line::<D, _>(
            #[inline(always)]
            || {
                self.update(sys, y, u, form, t)?;
                self.predict(sys, u);
                Ok(())
            },
        )
    }

    /// [`update`](Self::update) for a `y` with every component observed. Everything it does
    /// has the compile-time sizes of `D`: a time loop that calls only this and
    /// [`predict_observed`](Self::predict_observed) on a fixed-size workspace lets the compiler
    /// keep the workspace in registers (see `Run::steps`). `features` must hold for this
    /// workspace and `sys` (a constant at the call, so that what it rules out is compiled out).
    #[inline(always)]
    pub fn update_observed(
        &mut self,
        sys: &StepView<'_>,
        y: &[f64],
        u: Option<&[f64]>,
        form: UpdateForm,
        t: usize,
        features: Features,
    ) -> Result<()> {
        let (d, n, m) = (self.d, self.d.n(), self.d.m());
        self.innovation(sys, y, u);
        if features.freezing && self.frozen {
            self.update.apply_mean(d, self.innov.get(), self.pht.get(), self.x_pred.get(), self.x_filt.get_mut());
            return self.check_finite(t);
        }
        #[cfg(target_arch = "x86_64")]
        if let Some(cpu) = rows4::for_sizes(d) {
            return self.update_observed_rows4(cpu, sys, form, t);
        }
        self.measurement_covariances(sys);
        self.m_obs = m;
        let pred = MeasurementPrediction {
            innov: self.innov.get(),
            cross_cov: self.pht.get(),
            innov_cov: self.s_full.get(),
            joseph: (form == UpdateForm::Joseph).then_some((sys.h, sys.r)),
        };
        self.update.apply(
            d,
            m,
            &pred,
            self.x_pred.get(),
            self.p_pred.get(),
            self.x_filt.get_mut(),
            self.p_filt.get_mut(),
            t,
        )?;
        if self.want_gain {
            transpose(self.gain.get_mut(), self.update.gain_t(m, n), m, n);
        }
        self.check_finite(t)
    }

    /// [`update_observed`](Self::update_observed) for three or four states on AVX2 registers
    /// (`core::rows4`): the same operations in the same order, so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn update_observed_rows4(&mut self, cpu: Avx2Fma, sys: &StepView<'_>, form: UpdateForm, t: usize) -> Result<()> {
        let (n, m) = (self.d.n(), self.d.m());
        let cols = rows4::mul_bt_cols(cpu, &Rows::load(cpu, self.p_pred.get()), sys.h, m);
        rows4::store_cols(cpu, self.pht.get_mut(), &cols, m);
        self.compute_innovation_cov(sys);
        self.m_obs = m;
        let pred = MeasurementPrediction {
            innov: self.innov.get(),
            cross_cov: self.pht.get(),
            innov_cov: self.s_full.get(),
            joseph: (form == UpdateForm::Joseph).then_some((sys.h, sys.r)),
        };
        self.update.apply_rows4(
            cpu,
            m,
            &pred,
            &cols,
            self.x_pred.get(),
            self.p_pred.get(),
            self.x_filt.get_mut(),
            self.p_filt.get_mut(),
            t,
        )?;
        if self.want_gain {
            transpose(self.gain.get_mut(), self.update.gain_t(m, n), m, n);
        }
        self.check_finite(t)
    }

    /// Fails when the state has left float64's range: a NaN reaches the log-likelihood term at
    /// the first step whose innovation or state overflowed (an unstable F over a long series,
    /// data near 1e308).
    #[inline(always)]
    fn check_finite(&self, t: usize) -> Result<()> {
        if self.update.overflowed() {
            return Err(overflowed(t));
        }
        Ok(())
    }

    /// [`update`](Self::update) for a `y` with some component missing: the observed ones
    /// update (none: the update is skipped). In a function of its own for the sizes'
    /// instruction set: compiled alone, without FMA enabled, a fused workspace's update made
    /// every multiply-add a call of the software `fma`.
    #[inline(always)]
    fn update_missing(
        &mut self,
        sys: &StepView<'_>,
        y: &[f64],
        u: Option<&[f64]>,
        form: UpdateForm,
        t: usize,
    ) -> Result<()> {
        crate::core::isa::run_out_of_line::<D, _>(
            #[inline(always)]
            || {
                self.innovation(sys, y, u);
                self.frozen = false;
                self.measurement_covariances(sys);
                self.m_obs = 0;
                for (i, yi) in y.iter().enumerate() {
                    if !yi.is_nan() {
                        self.obs[self.m_obs] = i;
                        self.m_obs += 1;
                    }
                }
                if self.want_gain {
                    self.gain.get_mut().fill(0.0);
                }
                if self.m_obs == 0 {
                    self.x_filt.get_mut().copy_from_slice(self.x_pred.get());
                    self.p_filt.get_mut().copy_from_slice(self.p_pred.get());
                    self.update.skip();
                    return Ok(());
                }
                self.update_partial(sys, form, t)?;
                self.check_finite(t)
            },
        )
    }

    /// The innovation of every component: e = y − H x − D u (NaN where y is missing).
    #[inline(always)]
    fn innovation(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>) {
        let (n, m) = (self.d.n(), self.d.m());
        let innov = self.innov.get_mut();
        mul_vec::<D>(innov, sys.h, self.x_pred.get(), m, n);
        if let (Some(dm), Some(u)) = (sys.d, u) {
            mul_vec_add::<D>(innov, dm, u, m, self.k);
        }
        // `[..m]`: a loop over the compile-time m (y's length is m, checked by the caller).
        for (e, yi) in innov.iter_mut().zip(&y[..m]) {
            *e = yi - *e;
        }
    }

    /// C = P H' and S = H P H' + R for all components (S is the forecast error covariance of
    /// y(t), reported for missing components too).
    #[inline(always)]
    fn measurement_covariances(&mut self, sys: &StepView<'_>) {
        let (n, m) = (self.d.n(), self.d.m());
        let pht = self.pht.get_mut();
        mul_bt::<D>(pht, self.p_pred.get(), sys.h, n, n, m);
        self.compute_innovation_cov(sys);
    }

    /// S = H (P H') + R for all components, from `pht`.
    #[inline(always)]
    fn compute_innovation_cov(&mut self, sys: &StepView<'_>) {
        let (n, m) = (self.d.n(), self.d.m());
        let pht = self.pht.get();
        // H (P H') computed as one triangle and mirrored, plus the symmetric R: S is exactly
        // symmetric without a symmetrization on the step's latency chain.
        let s = self.s_full.get_mut();
        mul_sym::<D>(s, sys.h, pht, m, n);
        for (s, r) in s.iter_mut().zip(&sys.r[..m * m]) {
            *s += r;
        }
    }

    /// The update with the observed components only (some, not all, are missing).
    #[inline(always)]
    fn update_partial(&mut self, sys: &StepView<'_>, form: UpdateForm, t: usize) -> Result<()> {
        let (d, n, m, mo) = (self.d, self.d.n(), self.d.m(), self.m_obs);
        let obs = &self.obs[..mo];
        let p = &mut self.partial;
        let (innov, pht, s_full) = (self.innov.get(), self.pht.get(), self.s_full.get());
        for (a, &i) in obs.iter().enumerate() {
            p.innov.get_mut()[a] = innov[i];
            p.h.get_mut()[a * n..(a + 1) * n].copy_from_slice(&sys.h[i * n..(i + 1) * n]);
            for (b, &j) in obs.iter().enumerate() {
                p.s.get_mut()[a * mo + b] = s_full[i * m + j];
                p.r.get_mut()[a * mo + b] = sys.r[i * m + j];
            }
        }
        for r in 0..n {
            for (a, &i) in obs.iter().enumerate() {
                p.pht.get_mut()[r * mo + a] = pht[r * m + i];
                if let Some(nn) = sys.n {
                    p.n.get_mut()[r * mo + a] = nn[r * m + i];
                }
            }
        }
        let pred = MeasurementPrediction {
            innov: p.innov.get(),
            cross_cov: p.pht.get(),
            innov_cov: p.s.get(),
            joseph: (form == UpdateForm::Joseph).then_some((p.h.get(), p.r.get())),
        };
        self.update.apply(
            d,
            mo,
            &pred,
            self.x_pred.get(),
            self.p_pred.get(),
            self.x_filt.get_mut(),
            self.p_filt.get_mut(),
            t,
        )?;
        if self.want_gain {
            let gain_t = self.update.gain_t(mo, n);
            let gain = self.gain.get_mut();
            for (j, &i) in obs.iter().enumerate() {
                for r in 0..n {
                    gain[r * m + i] = gain_t[j * n + r];
                }
            }
        }
        Ok(())
    }

    /// Skips the measurement update (nothing observed, as for an all-NaN y).
    pub fn skip_update(&mut self) {
        self.frozen = false;
        self.m_obs = 0;
        self.innov.get_mut().fill(f64::NAN);
        self.gain.get_mut().fill(0.0);
        self.update.skip();
        self.x_filt.get_mut().copy_from_slice(self.x_pred.get());
        self.p_filt.get_mut().copy_from_slice(self.p_pred.get());
    }

    /// Time update from (x_filt, p_filt) to the next (x_pred, p_pred), and the predictor gain
    /// `K_pred = F K + N S⁻¹` of the update just made.
    #[inline(always)]
    pub fn predict(&mut self, sys: &StepView<'_>, u: Option<&[f64]>) {
        self.time_update(sys, u, self.m_obs, Features::ALL);
    }

    /// [`predict`](Self::predict) after [`update_observed`](Self::update_observed): all m
    /// components observed, known at compile time for fixed sizes; `features` as there.
    #[inline(always)]
    pub fn predict_observed(&mut self, sys: &StepView<'_>, u: Option<&[f64]>, features: Features) {
        self.time_update(sys, u, self.d.m(), features);
    }

    /// The time update after an update with `mo` observed components (`mo = m_obs`).
    #[inline(always)]
    fn time_update(&mut self, sys: &StepView<'_>, u: Option<&[f64]>, mo: usize, features: Features) {
        let (n, m) = (self.d.n(), self.d.m());
        debug_assert!(features.cross_cov || sys.n.is_none());
        debug_assert!(features.freezing || self.converge_tol.is_none());
        let cross_cov = sys.n.filter(|_| features.cross_cov);
        let x_pred = self.x_pred.get_mut();
        mul_vec_f::<D>(self.d, x_pred, sys.f, self.x_filt.get());
        if let (Some(b), Some(u)) = (sys.b, u) {
            mul_vec_add::<D>(x_pred, b, u, n, self.k);
        }
        if features.freezing && self.frozen {
            if let Some(nn) = cross_cov {
                mul_vec_add::<D>(x_pred, nn, self.update.s_inv_e(m), n, m);
            }
            return;
        }
        if features.freezing && self.converge_tol.is_some() {
            self.p_prev.get_mut().copy_from_slice(self.p_pred.get());
        }
        self.covariance_time_update(sys);
        if self.want_gain_pred || cross_cov.is_some() {
            if mo == m {
                self.predictor_gain(m, sys.f, cross_cov);
            } else {
                self.gain_pred.get_mut().fill(0.0);
                if mo > 0 {
                    self.predictor_gain(mo, sys.f, cross_cov);
                }
            }
        }
        if let (Some(tol), true, true) = (self.converge_tol, mo == m, features.freezing) {
            let (p_pred, p_prev) = (self.p_pred.get(), self.p_prev.get());
            let change = p_pred.iter().zip(p_prev).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            let size = p_pred.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            self.frozen = change <= tol * size;
        }
    }

    /// P(t+1|t) = F P(t|t) F' + Q (the N terms apart).
    #[inline(always)]
    fn covariance_time_update(&mut self, sys: &StepView<'_>) {
        let n = self.d.n();
        #[cfg(target_arch = "x86_64")]
        if let Some(cpu) = rows4::for_sizes(self.d) {
            let fp = rows4::mul_mem(sys.f, n, &Rows::load(cpu, self.p_filt.get()).0, n);
            let f_cols = Rows::load(cpu, sys.f).transpose();
            let p_pred = rows4::mul_rows(cpu, &fp, &f_cols).mirror_upper().add(&Rows::load(cpu, sys.q));
            return p_pred.store(cpu, self.p_pred.get_mut());
        }
        let fp = self.fp.get_mut();
        mul::<D>(fp, sys.f, self.p_filt.get(), n, n, n);
        let p_pred = self.p_pred.get_mut();
        mul_bt_sym::<D>(p_pred, fp, sys.f, n, n);
        // `[..n * n]`: a loop over the compile-time n (Q is n × n).
        for (p, q) in p_pred.iter_mut().zip(&sys.q[..n * n]) {
            *p += q;
        }
    }

    /// K_pred = F K + N S⁻¹ over the `mo` observed components, and the N terms of the time
    /// update (Söderström (6.25), (6.26)); `cross_cov` is N when the model has one.
    #[inline(always)]
    fn predictor_gain(&mut self, mo: usize, f: &[f64], cross_cov: Option<&[f64]>) {
        let (n, m) = (self.d.n(), self.d.m());
        // F K (n × mo), with K = (K')'.
        let gain = &mut self.gain_o.get_mut()[..n * mo];
        transpose(gain, self.update.gain_t(mo, n), mo, n);
        let fk = &mut self.f_gain.get_mut()[..n * mo];
        mul::<D>(fk, f, gain, n, n, mo);
        if let Some(nn) = cross_cov {
            let n_o = if mo == m { &nn[..n * m] } else { &self.partial.n.get()[..n * mo] };
            // x̂(t+1|t) += N S⁻¹ e
            mul_vec_add::<D>(self.x_pred.get_mut(), n_o, self.update.s_inv_e(mo), n, mo);
            // G' = S⁻¹ N' (mo × n); K_pred = F K + G.
            let g_t = &mut self.s_inv_nt.get_mut()[..mo * n];
            transpose(g_t, n_o, n, mo);
            ldl_solve::<D>(self.update.s_factor(mo), g_t, mo, n);
            // P(t+1|t) −= K_pred N' + N (F K)'
            let p_pred = self.p_pred.get_mut();
            for r in 0..n {
                for c in 0..n {
                    let mut acc = 0.0;
                    for a in 0..mo {
                        let kp = fk[r * mo + a] + g_t[a * n + r];
                        acc += kp * n_o[c * mo + a] + n_o[r * mo + a] * fk[c * mo + a];
                    }
                    p_pred[r * n + c] -= acc;
                }
            }
            // The two products of an entry and of its mirror round differently; F P F' + Q
            // alone is exactly symmetric already (mirrored, and the model's Q is symmetric).
            symmetrize(p_pred, n);
            for r in 0..n {
                for a in 0..mo {
                    fk[r * mo + a] += g_t[a * n + r];
                }
            }
        }
        let gain_pred = self.gain_pred.get_mut();
        if mo == m {
            gain_pred.copy_from_slice(&fk[..n * m]);
        } else {
            for (a, &i) in self.obs[..mo].iter().enumerate() {
                for r in 0..n {
                    gain_pred[r * m + i] = fk[r * mo + a];
                }
            }
        }
    }
}

/// `x[n] = F x_filt`, on AVX2 registers for three or four states (`core::rows4`; the same bits).
#[inline(always)]
fn mul_vec_f<D: Dims>(d: D, x: &mut [f64], f: &[f64], x_filt: &[f64]) {
    let n = d.n();
    #[cfg(target_arch = "x86_64")]
    if let Some(cpu) = rows4::for_sizes(d) {
        return rows4::store(cpu, x, rows4::mul_vec_cols(&Rows::load(cpu, f).transpose().0, x_filt, n));
    }
    mul_vec::<D>(x, f, x_filt, n, n);
}

/// The error for a state estimate that left float64's range at step `t` (out of line: the
/// time loop keeps only a branch).
#[cold]
#[inline(never)]
pub(crate) fn overflowed(t: usize) -> Error {
    Error::arg_at(
        "y",
        t,
        "the state estimate overflowed (it is no longer finite): the data or F drive it beyond float64's range",
    )
}

/// Whether every component of `y` is observed (no NaN).
#[inline(always)]
pub(crate) fn all_observed(y: &[f64]) -> bool {
    !y.iter().any(|v| v.is_nan())
}
