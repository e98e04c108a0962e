//! The filter in the textbook's robust update forms (docs/algorithms.md, "Update forms"):
//! square-root, U-D, information and sequential. Each keeps its own representation of the
//! covariance — a Cholesky factor, U and D, the information matrix, or P itself updated one
//! scalar at a time — and forms P only for the outputs that ask for it.
//!
//! All four process the observed components of y(t) one scalar at a time (Söderström Sec. 6.8.1;
//! Durbin & Koopman (2012) Sec. 6.4): with a diagonal R directly, otherwise decorrelated by the lower
//! Cholesky factor L of their R, ỹ = L⁻¹ (y − D u), z̃ = L⁻¹ H, unit variances (the
//! log-likelihood then gains −log det L, the Jacobian of ỹ ↦ y). A cross-covariance N is
//! removed before the time update (Söderström Lemma 6.4): with G = N R⁻¹,
//!
//! ```text
//! x̂(t+1|t) = F̃ x̂(t|t) + B u + G (y − D u),   F̃ = F − G H,   Q̃ = Q − G N'
//! ```
//!
//! (observed components only), which is the same filter as Söderström (6.25), (6.26). For a
//! constant model the decorrelation and the factors of Q̃ are computed once per pattern of
//! observed components; the time loop allocates nothing.
//!
//! The loops are compiled for state sizes n ≤ 12 as compile-time constants (the measurement
//! size does not matter to a scalar update), for the call's instruction set (`core::isa`), each
//! in its size's codegen unit (`core::home`).

/// Evaluates `$body` with `$d` bound to the state size n as a compile-time constant for
/// n ≤ 12 (`Fixed<n, 1>`: the measurement size is not part of a scalar update's sizes) where
/// `$kernel` has loops for compile-time sizes (`Kernel::fixed_sizes`), else to run-time sizes.
macro_rules! with_state_dims {
    ($kernel:expr, $n:expr, |$d:ident| $body:expr) => {{
        let n: usize = $n;
        match (if $crate::core::isa::Kernel::fixed_sizes($kernel) { n } else { 0 }) {
            1 => with_state_dims!(@fixed 1, $d, $body),
            2 => with_state_dims!(@fixed 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            3 => with_state_dims!(@fixed 3, $d, $body),
            4 => with_state_dims!(@fixed 4, $d, $body),
            5 => with_state_dims!(@fixed 5, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            6 => with_state_dims!(@fixed 6, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            7 => with_state_dims!(@fixed 7, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            8 => with_state_dims!(@fixed 8, $d, $body),
            9 => with_state_dims!(@fixed 9, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            10 => with_state_dims!(@fixed 10, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            11 => with_state_dims!(@fixed 11, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            12 => with_state_dims!(@fixed 12, $d, $body),
            _ => {
                let $d = Dyn { n, m: 1 };
                $body
            }
        }
    }};
    (@fixed $n:literal, $d:ident, $body:expr) => {{
        let $d = Fixed::<$n, 1>;
        $body
    }};
}

mod information;
mod sequential;
pub(crate) mod smoother;
mod sqrt;
pub(super) mod stream;
mod ud;

pub(crate) use smoother::smooth_square_root;

use super::outputs::FilterOutputs;
use super::step::overflowed;
use super::Run;
use crate::core::dense::{solve_lower, solve_lower_t};
use crate::core::dims::{Dims, Dyn, Fixed};
use crate::core::gaussian::UpdateForm;
use crate::core::isa::run_best;
use crate::error::{Error, Result};
use crate::linear::model::StepView;

/// ½ log 2π.
const HALF_LOG_2PI: f64 = 0.918_938_533_204_672_8;

/// One update form's recursion: its representation of x̂ and P, a scalar measurement update
/// and the time update.
trait Recursion<D: Dims>: Sized {
    /// Starts from x̂(0|−1) = `x0`, P(0|−1) = `p0` (validated, PSD).
    fn new(d: D, x0: &[f64], p0: &[f64]) -> Result<Self>;

    /// The current estimate x̂: x̂(t|t−1) before the update, x̂(t|t) after it.
    fn x(&self) -> &[f64];

    /// The current covariance, formed from the form's factors into `p` (n × n).
    fn covariance(&self, p: &mut [f64]);

    /// The lower triangular factor S of P = S S', for the forms that keep one.
    fn square_root(&self) -> Option<&[f64]> {
        None
    }

    /// The measurement update with the prepared components; returns the step's
    /// log-likelihood term without the decorrelation's −log det L.
    fn update(&mut self, meas: &Measurement, t: usize) -> Result<f64>;

    /// The time update's F̃ and Q̃ changed (first step, a time-varying model, another pattern
    /// of observed components): refactor what depends on them.
    fn set_dynamics(&mut self, f: &[f64], q: &[f64], t: usize) -> Result<()>;

    /// x̂ ← F̃ x̂ + `shift`, P ← F̃ P F̃' + Q̃ with the last [`set_dynamics`](Self::set_dynamics),
    /// after the update of step `t`.
    fn predict(&mut self, f: &[f64], shift: &[f64], t: usize) -> Result<()>;
}

/// Runs the filter of `run.form` (one of the four forms here) from `run.start`; returns the
/// log-likelihood.
pub(crate) fn filter(run: &Run<'_>, out: &mut FilterOutputs<'_>) -> Result<f64> {
    if run.converge_tol.is_some() {
        return Err(Error::arg("converge_tol", "gain freezing is only for form=\"joseph\" or \"standard\""));
    }
    with_state_dims!(run.kernel, run.model.n_states(), |d| by_form(d, run, out))
}

/// The loop of `run.form`, compiled for the call's instruction set (`run_best!`, as the
/// covariance forms: fused multiply-adds where the CPU has them and deterministic mode is off),
/// each in its size's codegen unit (`core::home`).
fn by_form<D: Dims>(d: D, run: &Run<'_>, out: &mut FilterOutputs<'_>) -> Result<f64> {
    run_best!(run.kernel, d, |d| by_form_inline(d, run, out))
}

#[inline(always)]
fn by_form_inline<D: Dims>(d: D, run: &Run<'_>, out: &mut FilterOutputs<'_>) -> Result<f64> {
    match run.form {
        UpdateForm::Sequential => drive::<D, sequential::Sequential<D>>(d, run, out, None),
        UpdateForm::SquareRoot => drive::<D, sqrt::SquareRoot<D>>(d, run, out, None),
        UpdateForm::UD => drive::<D, ud::UD<D>>(d, run, out, None),
        UpdateForm::Information => drive::<D, information::Information<D>>(d, run, out, None),
        UpdateForm::Joseph | UpdateForm::Standard => unreachable!("the covariance forms run in Run::filter"),
    }
}

/// Where the time loop stores the square-root form's factors for its smoother: S(t|t) and
/// S(t|t−1), `(T, n, n)` each.
pub(crate) struct FactorStore<'a> {
    pub filt: &'a mut [f64],
    pub pred: &'a mut [f64],
}

/// The time loop, shared by the forms.
#[inline(always)]
fn drive<D: Dims, R: Recursion<D>>(
    d: D,
    run: &Run<'_>,
    out: &mut FilterOutputs<'_>,
    mut factors: Option<&mut FactorStore<'_>>,
) -> Result<f64> {
    let (n, m) = (d.n(), run.model.n_obs());
    let mut form = R::new(d, run.x0, run.p0)?;
    let mut meas = Measurement::new(n, m, run.model.n_inputs());
    let mut derived = Derived::new(n, m, out);
    let constant = run.model.steps().is_none();
    // The innovations of all components: an output, and what the derived outputs read.
    let want_innov = out.innov.is_some() || derived.needed();
    // P(t|t−1): an output, and what the derived outputs are formed from.
    let want_prior = out.p_pred.is_some() || derived.needed();
    let mut total = 0.0;
    let mut p = vec![0.0; n * n];
    for t in run.start..run.y.steps() {
        let sys = run.model.at(t);
        let (y, u) = (run.y.row(t), run.u.map(|u| u.row(t)));
        if want_prior {
            form.covariance(&mut p);
        }
        out.store_prior(t, form.x(), &p);
        if let (Some(store), Some(s)) = (factors.as_deref_mut(), form.square_root()) {
            store.pred[t * n * n..][..n * n].copy_from_slice(s);
        }
        if want_innov {
            meas.innovation(&sys, y, u, form.x());
        }
        if derived.needed() {
            derived.compute(&sys, &meas, &p);
        }
        let changed = meas.prepare(&sys, y, u, constant, t)?;
        let loglik_t = if meas.mo == 0 { 0.0 } else { form.update(&meas, t)? - meas.log_det_l };
        if !loglik_t.is_finite() || form.x().iter().any(|v| !v.is_finite()) {
            return Err(overflowed(t));
        }
        total += loglik_t;
        if out.p_filt.is_some() {
            form.covariance(&mut p);
        }
        if let (Some(store), Some(s)) = (factors.as_deref_mut(), form.square_root()) {
            store.filt[t * n * n..][..n * n].copy_from_slice(s);
        }
        out.store_values(t, form.x(), &p, &meas.innov, &derived.s_full, &derived.gain, loglik_t);
        out.store_gain_pred(t, &derived.gain_pred);
        if changed {
            form.set_dynamics(meas.f_tilde(&sys), meas.q_tilde(&sys), t)?;
        }
        meas.shift(&sys, u);
        form.predict(meas.f_tilde(&sys), &meas.shift, t)?;
    }
    if form.x().iter().any(|v| !v.is_finite()) {
        return Err(overflowed(run.y.steps().saturating_sub(1)));
    }
    if out.p_next.is_some() {
        form.covariance(&mut p);
    }
    out.store_next(form.x(), &p);
    Ok(total)
}

/// The observed components of y(t) prepared for scalar updates, and the time update's F̃, Q̃
/// and input shift (see the module docs). Buffers sized once for (n, m, k).
#[derive(Debug, Clone)]
struct Measurement {
    n: usize,
    m: usize,
    /// The innovation of every component, e = y − H x̂(t|t−1) − D u (NaN where missing),
    /// when an output needs it.
    innov: Vec<f64>,
    /// Observed components and how many.
    obs: Vec<usize>,
    mo: usize,
    /// The pattern of observed components the prepared matrices belong to, if any.
    prepared: Vec<usize>,
    is_prepared: bool,
    /// Rows z̃ (mo × n), targets ỹ (mo) and variances σ² (mo): component a is
    /// ỹ_a = z̃_a x + noise of variance σ²_a, independent of the others.
    rows: Vec<f64>,
    target: Vec<f64>,
    variances: Vec<f64>,
    /// Whether R_oo is not diagonal: then L (mo × mo) holds its lower Cholesky factor.
    decorrelated: bool,
    l: Vec<f64>,
    /// log det L (0 without decorrelation).
    log_det_l: f64,
    /// Scratch: R_oo (mo × mo), its factor for G, and G' (mo × n).
    r_oo: Vec<f64>,
    l_g: Vec<f64>,
    g_t: Vec<f64>,
    /// With N: G = N_o R_oo⁻¹ (n × mo), F̃ and Q̃ (n × n).
    g: Vec<f64>,
    f_tilde: Vec<f64>,
    q_tilde: Vec<f64>,
    has_n: bool,
    /// y_o − D_o u of the observed components.
    y_minus_du: Vec<f64>,
    /// B u + G (y_o − D_o u) (n), and whether it is zero (no B u, no N).
    shift: Vec<f64>,
    shift_is_zero: bool,
    k: usize,
}

impl Measurement {
    fn new(n: usize, m: usize, k: usize) -> Self {
        Measurement {
            n,
            m,
            innov: vec![0.0; m],
            obs: vec![0; m],
            mo: 0,
            prepared: Vec::with_capacity(m),
            is_prepared: false,
            rows: vec![0.0; m * n],
            target: vec![0.0; m],
            variances: vec![0.0; m],
            decorrelated: false,
            l: vec![0.0; m * m],
            log_det_l: 0.0,
            r_oo: vec![0.0; m * m],
            l_g: vec![0.0; m * m],
            g_t: vec![0.0; m * n],
            g: vec![0.0; n * m],
            f_tilde: vec![0.0; n * n],
            q_tilde: vec![0.0; n * n],
            has_n: false,
            y_minus_du: vec![0.0; m],
            shift: vec![0.0; n],
            shift_is_zero: true,
            k,
        }
    }

    /// e = y − H x − D u of every component (NaN where y is missing).
    #[inline(always)]
    fn innovation(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>, x: &[f64]) {
        let (n, k) = (self.n, self.k);
        for (i, e) in self.innov.iter_mut().enumerate() {
            let mut pred = dot(&sys.h[i * n..][..n], x);
            if let (Some(d), Some(u)) = (sys.d, u) {
                pred += dot(&d[i * k..][..k], u);
            }
            *e = y[i] - pred;
        }
    }

    /// Prepares the observed components of `y`; returns whether F̃ and Q̃ changed since the
    /// last step (always for a time-varying model).
    #[inline(always)]
    fn prepare(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>, constant: bool, t: usize) -> Result<bool> {
        let k = self.k;
        self.mo = 0;
        for (i, yi) in y.iter().enumerate() {
            if !yi.is_nan() {
                self.obs[self.mo] = i;
                self.mo += 1;
            }
        }
        let mo = self.mo;
        for a in 0..mo {
            let i = self.obs[a];
            let mut du = 0.0;
            if let (Some(d), Some(u)) = (sys.d, u) {
                du = dot(&d[i * k..][..k], u);
            }
            self.y_minus_du[a] = y[i] - du;
        }
        // (All observed again, the common case, needs no comparison.)
        let same = constant
            && self.is_prepared
            && self.prepared.len() == mo
            && (mo == self.m || self.prepared[..] == self.obs[..mo]);
        if !same {
            self.decorrelate(sys, t)?;
            self.prepared.clear();
            self.prepared.extend_from_slice(&self.obs[..mo]);
            self.is_prepared = true;
        }
        // ỹ = L⁻¹ (y_o − D_o u), or y_o − D_o u itself.
        self.target[..mo].copy_from_slice(&self.y_minus_du[..mo]);
        if self.decorrelated {
            solve_lower(&self.l, &mut self.target[..mo], mo, 1);
        }
        Ok(!same)
    }

    /// Rows, variances, L and (with N) G, F̃, Q̃ for the current observed components.
    fn decorrelate(&mut self, sys: &StepView<'_>, t: usize) -> Result<()> {
        let (n, m, mo) = (self.n, self.m, self.mo);
        let obs = &self.obs[..mo];
        for (a, &i) in obs.iter().enumerate() {
            self.rows[a * n..][..n].copy_from_slice(&sys.h[i * n..][..n]);
            for (b, &j) in obs.iter().enumerate() {
                self.r_oo[a * mo + b] = sys.r[i * m + j];
            }
        }
        let r_oo = &self.r_oo[..mo * mo];
        self.decorrelated = (0..mo).any(|a| (0..mo).any(|b| a != b && r_oo[a * mo + b] != 0.0));
        self.has_n = sys.n.is_some() && mo > 0;
        if self.decorrelated {
            crate::nonlinear::cholesky(&mut self.l, r_oo, mo).map_err(|_| {
                Error::arg_at("R", t, "the update forms process the observed components one at a time and need their R positive definite when it is not diagonal")
            })?;
            solve_lower(&self.l, &mut self.rows[..mo * n], mo, n);
            self.variances[..mo].fill(1.0);
            self.log_det_l = (0..mo).map(|a| self.l[a * mo + a].ln()).sum();
        } else {
            for a in 0..mo {
                self.variances[a] = r_oo[a * mo + a];
            }
            self.log_det_l = 0.0;
        }
        if self.has_n {
            self.remove_cross_covariance(sys, t)?;
        }
        Ok(())
    }

    /// G = N_o R_oo⁻¹, F̃ = F − G H_o, Q̃ = Q − G N_o'.
    fn remove_cross_covariance(&mut self, sys: &StepView<'_>, t: usize) -> Result<()> {
        let (n, m, mo) = (self.n, self.m, self.mo);
        let (nn, obs) = (sys.n.unwrap_or_default(), &self.obs[..mo]);
        crate::nonlinear::cholesky(&mut self.l_g, &self.r_oo[..mo * mo], mo).map_err(|_| {
            Error::arg_at(
                "R",
                t,
                "a model with N needs R of the observed components positive definite in the update forms (G = N R⁻¹)",
            )
        })?;
        // G' = R_oo⁻¹ N_o' (mo × n) by two triangular solves.
        let g_t = &mut self.g_t[..mo * n];
        for (a, &i) in obs.iter().enumerate() {
            for r in 0..n {
                g_t[a * n + r] = nn[r * m + i];
            }
        }
        solve_lower(&self.l_g, g_t, mo, n);
        solve_lower_t(&self.l_g, g_t, mo, n);
        for r in 0..n {
            for a in 0..mo {
                self.g[r * mo + a] = g_t[a * n + r];
            }
        }
        for r in 0..n {
            for c in 0..n {
                let (mut gh, mut gn) = (0.0, 0.0);
                for (a, &i) in obs.iter().enumerate() {
                    gh += self.g[r * mo + a] * sys.h[i * n + c];
                    gn += self.g[r * mo + a] * nn[c * m + i];
                }
                self.f_tilde[r * n + c] = sys.f[r * n + c] - gh;
                self.q_tilde[r * n + c] = sys.q[r * n + c] - gn;
            }
        }
        crate::core::dense::symmetrize(&mut self.q_tilde, n);
        Ok(())
    }

    /// F̃ (F itself without N).
    fn f_tilde<'a>(&'a self, sys: &StepView<'a>) -> &'a [f64] {
        if self.has_n {
            &self.f_tilde
        } else {
            sys.f
        }
    }

    /// Q̃ (Q itself without N).
    fn q_tilde<'a>(&'a self, sys: &StepView<'a>) -> &'a [f64] {
        if self.has_n {
            &self.q_tilde
        } else {
            sys.q
        }
    }

    /// The time update's shift B u + G (y_o − D_o u).
    #[inline(always)]
    fn shift(&mut self, sys: &StepView<'_>, u: Option<&[f64]>) {
        let (n, k, mo) = (self.n, self.k, self.mo);
        if !self.has_n && (sys.b.is_none() || u.is_none()) {
            if !self.shift_is_zero {
                self.shift.fill(0.0);
                self.shift_is_zero = true;
            }
            return;
        }
        self.shift_is_zero = false;
        for r in 0..n {
            let mut s = 0.0;
            if let (Some(b), Some(u)) = (sys.b, u) {
                s = dot(&b[r * k..][..k], u);
            }
            if self.has_n {
                s += dot(&self.g[r * mo..][..mo], &self.y_minus_du[..mo]);
            }
            self.shift[r] = s;
        }
    }

    /// The prepared components: (row z̃_a, target ỹ_a, variance σ²_a) for each a.
    fn components(&self) -> impl Iterator<Item = (&[f64], f64, f64)> {
        let n = self.n;
        (0..self.mo).map(move |a| (&self.rows[a * n..][..n], self.target[a], self.variances[a]))
    }
}

/// The outputs the forms do not compute in their recursion, derived from P(t|t−1) when asked
/// for: S = H P H' + R (all components), K = P H_o' S_o⁻¹ and K_pred = (F P H_o' + N_o) S_o⁻¹.
/// Buffers sized once.
struct Derived {
    n: usize,
    m: usize,
    want_s: bool,
    want_gain: bool,
    want_gain_pred: bool,
    s_full: Vec<f64>,
    gain: Vec<f64>,
    gain_pred: Vec<f64>,
    /// Scratch: P H' (n × m); S_o and its Cholesky factor (mo × mo); K' and K_pred' (mo × n).
    pht: Vec<f64>,
    s_oo: Vec<f64>,
    l: Vec<f64>,
    k_t: Vec<f64>,
    kp_t: Vec<f64>,
}

impl Derived {
    fn new(n: usize, m: usize, out: &FilterOutputs<'_>) -> Self {
        Derived {
            n,
            m,
            want_s: out.innovation_cov.is_some(),
            want_gain: out.gain.is_some(),
            want_gain_pred: out.gain_pred.is_some(),
            s_full: vec![0.0; m * m],
            gain: vec![0.0; n * m],
            gain_pred: vec![0.0; n * m],
            pht: vec![0.0; n * m],
            s_oo: vec![0.0; m * m],
            l: vec![0.0; m * m],
            k_t: vec![0.0; m * n],
            kp_t: vec![0.0; m * n],
        }
    }

    fn needed(&self) -> bool {
        self.want_s || self.want_gain || self.want_gain_pred
    }

    /// From P = P(t|t−1), with `meas.innov` of this step (NaN marks the missing components).
    fn compute(&mut self, sys: &StepView<'_>, meas: &Measurement, p: &[f64]) {
        let (n, m) = (self.n, self.m);
        for r in 0..n {
            for i in 0..m {
                self.pht[r * m + i] = dot(&p[r * n..][..n], &sys.h[i * n..][..n]);
            }
        }
        for i in 0..m {
            for j in 0..m {
                let hph: f64 = (0..n).map(|c| sys.h[i * n + c] * self.pht[c * m + j]).sum();
                self.s_full[i * m + j] = hph + sys.r[i * m + j];
            }
        }
        crate::core::dense::symmetrize(&mut self.s_full, m);
        self.gain.fill(0.0);
        self.gain_pred.fill(0.0);
        let observed = |i: &usize| !meas.innov[*i].is_nan();
        let mo = (0..m).filter(observed).count();
        if mo == 0 || !(self.want_gain || self.want_gain_pred) {
            return;
        }
        for (a, i) in (0..m).filter(observed).enumerate() {
            for (b, j) in (0..m).filter(observed).enumerate() {
                self.s_oo[a * mo + b] = self.s_full[i * m + j];
            }
            for r in 0..n {
                self.k_t[a * n + r] = self.pht[r * m + i];
                let fph: f64 = (0..n).map(|c| sys.f[r * n + c] * self.pht[c * m + i]).sum();
                self.kp_t[a * n + r] = fph + sys.n.map_or(0.0, |nn| nn[r * m + i]);
            }
        }
        if crate::nonlinear::cholesky(&mut self.l, &self.s_oo[..mo * mo], mo).is_err() {
            // S_o singular: the recursion has refused or skipped such a step; no gain to show.
            return;
        }
        for b in [&mut self.k_t, &mut self.kp_t] {
            solve_lower(&self.l, &mut b[..mo * n], mo, n);
            solve_lower_t(&self.l, &mut b[..mo * n], mo, n);
        }
        for (a, i) in (0..m).filter(observed).enumerate() {
            for r in 0..n {
                self.gain[r * m + i] = self.k_t[a * n + r];
                self.gain_pred[r * m + i] = self.kp_t[a * n + r];
            }
        }
    }
}

#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The lower factor L of a symmetric positive semidefinite `a (n × n)` with a = L L'
/// (Cholesky, pivots below rounding taken as zero, their columns zero); `Err(j)` when pivot j
/// is clearly negative (a not PSD).
fn psd_cholesky(l: &mut [f64], a: &[f64], n: usize) -> std::result::Result<(), usize> {
    let scale = (0..n).fold(0.0_f64, |s, i| s.max(a[i * n + i].abs()));
    let floor = 64.0 * n as f64 * f64::EPSILON * scale;
    l[..n * n].fill(0.0);
    for j in 0..n {
        let d = a[j * n + j] - (0..j).map(|k| l[j * n + k] * l[j * n + k]).sum::<f64>();
        if d < -floor || d.is_nan() {
            return Err(j);
        }
        if d <= floor {
            continue;
        }
        let ljj = d.sqrt();
        l[j * n + j] = ljj;
        for i in j + 1..n {
            let s = a[i * n + j] - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
            l[i * n + j] = s / ljj;
        }
    }
    Ok(())
}

/// An error for a prior or noise covariance a form cannot factor.
fn not_psd(arg: &'static str, t: Option<usize>, what: &str) -> Error {
    let problem = format!("{what} is not positive semidefinite to working precision");
    match t {
        Some(t) => Error::arg_at(arg, t, problem),
        None => Error::arg(arg, problem),
    }
}

/// The error for a scalar innovation variance that is not positive.
fn innovation_variance(t: usize, f: f64) -> Error {
    Error::InnovationCovariance {
        step: t,
        problem: format!("a decorrelated component's innovation variance is {f:e} (not positive)"),
    }
}
