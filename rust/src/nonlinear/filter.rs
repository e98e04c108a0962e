//! The extended and unscented Kalman filters over a whole series.
//!
//! Both end each measurement update with the model-agnostic Gaussian update
//! (`core::gaussian`, Söderström Lemma 6.1): they differ only in how they predict the
//! measurement — the innovation e, the cross-covariance C = Cov(x, y) and S = Cov(y) — and in
//! how they propagate the state:
//!
//! - **EKF** (Söderström (9.2)–(9.11)): h linearized at x̂(t|t−1), C = P H', S = H P H' + R;
//!   f linearized at x̂(t|t): x̂(t+1|t) = f(x̂(t|t)), P(t+1|t) = F P(t|t) F' + Q.
//! - **UKF** (Julier & Uhlmann 1997; Wan & van der Merwe 2000): sigma points of
//!   (x̂(t|t−1), P(t|t−1)) through h give ŷ, S and C; points of (x̂(t|t), P(t|t)) through f
//!   give x̂(t+1|t) and P(t+1|t) (plus Q). P(t|t) = P − K S K'.
//!
//! Sizes are run-time; every buffer is allocated once per call, before the loop (a streaming
//! filter's measurement buffers again when a sensor with another m comes).

use super::function::{hessian_by_differences, jacobian_by_differences, wrap_angle, Differences, PointFunction};
use super::model::{NoiseScratch, NonlinearModel, Transition};
use super::sigma::{cholesky, place, semidefinite_cholesky, unscented_transform, SigmaPoints, Transformed, Weights};
use super::square_root::{downdate, tria};
use crate::core::dense::{mul, mul_bt, mul_bt_sym, symmetrize, transpose};
use crate::core::dims::{Dims, Dyn, Fixed};
use crate::core::gaussian::{GaussianUpdate, LoglikSum, MeasurementPrediction};
use crate::core::isa::{self, run_best, Kernel};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::filter::{FilterOutputs, UpdateForm};

/// How the iterated EKF relinearizes its update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Iteration {
    /// Söderström (9.12)–(9.17): the gain moves to the new linearization point, the
    /// innovation stays y − h(x̂(t|t−1)); P(t|t) from the last linearization.
    #[default]
    Book,
    /// Gauss–Newton on the MAP criterion (Bell & Cathey 1993):
    /// x_{i+1} = x̂⁻ + K_i (y − h(x_i) − H_i (x̂⁻ − x_i)); P(t|t) relinearized at the result.
    GaussNewton,
}

/// Options of [`ekf_into`].
#[derive(Debug, Clone, Copy, Default)]
pub struct EkfOptions {
    /// The covariance update (Joseph by default).
    pub form: UpdateForm,
    /// Relinearizations of the update per step (0: the EKF).
    pub iterations: usize,
    /// How to relinearize.
    pub iteration: Iteration,
    /// The second-order EKF (Söderström (9.21)–(9.26)): the predicted means corrected by
    /// `h̄_k = ½ tr(P(t|t−1) ∇²h_k)` and `f̄_k = ½ tr(P(t|t) ∇²f_k)`, Hessians given or by
    /// second differences; the covariances stay the EKF's (the book corrects means only).
    /// Not with `iterations > 0`.
    pub second_order: bool,
}

/// How the UKF carries its covariance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UkfForm {
    /// `P(t|t) = P − K S K'` (mirrored, so exactly symmetric), and a Cholesky factor of each
    /// covariance for its sigma points: fails, naming the step, when one is not positive
    /// definite to working precision.
    #[default]
    Standard,
    /// The square-root UKF (van der Merwe & Wan 2001): the lower factors of P(t|t−1) and
    /// P(t|t) are carried instead and never re-factored. The time update takes the factor of
    /// `Σ Wᵢ Dᵢ Dᵢ' (+ Q)` by a QR decomposition of the weighted deviations (and Q's factor),
    /// with Cholesky downdates for negative weights; the measurement update downdates the
    /// factor by the columns of `K S^(1/2) = C S^(−1/2)'`. P(t|t−1) and P(t|t) stay positive
    /// semidefinite by construction, and a singular P0 is accepted.
    SquareRoot,
}

/// Options of [`ukf_into`]: the sigma points and the covariance form.
#[derive(Debug, Clone, PartialEq)]
pub struct UkfOptions {
    /// The sigma-point set.
    pub points: SigmaPoints,
    /// The covariance form.
    pub form: UkfForm,
}

impl From<SigmaPoints> for UkfOptions {
    fn from(points: SigmaPoints) -> Self {
        UkfOptions { points, form: UkfForm::Standard }
    }
}

/// The extended Kalman filter over the series `y` (T × m) from the prior (x0, P0) = x(0|−1),
/// storing the outputs given in `out` (all but `K_pred`); returns the log-likelihood of its
/// Gaussian approximation (Söderström (6.142) with the linearized S). Jacobians are the
/// functions' own, or central differences ([`PointFunction::jacobian`]).
pub fn ekf_into(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: EkfOptions,
    out: FilterOutputs<'_>,
) -> Result<f64> {
    ekf_run(model, y, u, x0, p0, options, out, None)
}

/// [`ekf_into`], also storing `Cov(x(t), x(t+1) | y(0..t)) = P(t|t) F(t)'` (T × n × n) in
/// `cross` when given (for the extended RTS smoother).
#[allow(clippy::too_many_arguments)]
pub(crate) fn ekf_run(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: EkfOptions,
    out: FilterOutputs<'_>,
    cross: Option<&mut [f64]>,
) -> Result<f64> {
    let steps = model.check_run(y, u, x0, p0)?;
    let filter = Ekf::new(model.n_states(), model.n_obs(), x0, p0, options)?;
    run(model, y, u, steps, filter, out, cross)
}

/// The unscented Kalman filter over the series `y` with the sigma points and covariance form of
/// `options`; as [`ekf_into`] otherwise. The standard form fails, naming the step, when P(t|t−1)
/// or P(t|t) stops being positive definite (no Cholesky factor, so no sigma points); the
/// square-root form ([`UkfForm::SquareRoot`]) carries the factors instead.
pub fn ukf_into(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: UkfOptions,
    out: FilterOutputs<'_>,
) -> Result<f64> {
    ukf_run(model, y, u, x0, p0, options, out, None)
}

/// [`ukf_into`], also storing the sigma points' `Cov(x(t), x(t+1) | y(0..t))` (T × n × n) in
/// `cross` when given (for the unscented RTS smoother, Särkkä 2008).
#[allow(clippy::too_many_arguments)]
pub(crate) fn ukf_run(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    options: UkfOptions,
    out: FilterOutputs<'_>,
    cross: Option<&mut [f64]>,
) -> Result<f64> {
    let steps = model.check_run(y, u, x0, p0)?;
    let filter = Ukf::new(model.n_states(), model.n_obs(), x0, p0, options, model.noise_inputs())?;
    run(model, y, u, steps, filter, out, cross)
}

/// The time loop of either filter: update with y(t), store, predict to t + 1.
fn run(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    steps: usize,
    mut filter: impl GaussianFilter,
    mut out: FilterOutputs<'_>,
    mut cross: Option<&mut [f64]>,
) -> Result<f64> {
    let n = model.n_states();
    out.check_sizes(steps, n, model.n_obs())?;
    out.refuse_gain_pred(filter.name())?;
    let mut total = LoglikSum::default();
    let mut noise = NoiseScratch::default();
    for t in 0..steps {
        let (y_t, u_t) = (y.row(t), u.map(|u| u.row(t)));
        out.store_prior(t, &filter.state().x, &filter.state().p);
        filter.update(model.sensor(t), y_t, t, u_t)?;
        total.add(&filter.state().gauss);
        filter.state().store(&mut out, t);
        let cross_t = cross.as_deref_mut().map(|c| &mut c[t * n * n..(t + 1) * n * n]);
        let transition = model.transition(t, filter.state().current(true).0, u_t, &mut noise)?;
        filter.predict(transition, t, u_t, cross_t)?;
    }
    out.store_next(&filter.state().x, &filter.state().p);
    Ok(total.total())
}

/// What the time loop and the streaming filters need of a Gaussian filter.
pub(crate) trait GaussianFilter: Send + Sync {
    /// "extended Kalman filter" or "unscented Kalman filter", for messages.
    fn name(&self) -> &'static str;
    /// The state and the last update's results.
    fn state(&self) -> &Step;
    /// The same, to change (a streaming filter moves x̂(t|t) into the prior of a second
    /// update at the same step).
    fn state_mut(&mut self) -> &mut Step;
    /// The measurement update with y(t) (NaN: missing) from x̂(t|t−1), P(t|t−1) to x̂(t|t),
    /// P(t|t); nothing observed skips it.
    fn update(&mut self, sensor: Sensor<'_>, y: &[f64], t: usize, u: Option<&[f64]>) -> Result<()>;
    /// The time update from x̂(t|t), P(t|t) to x̂(t+1|t), P(t+1|t); stores
    /// Cov(x(t), x(t+1) | y(0..t)) into `cross` when given.
    fn predict(
        &mut self,
        transition: Transition<'_>,
        t: usize,
        u: Option<&[f64]>,
        cross: Option<&mut [f64]>,
    ) -> Result<()>;
    /// A copy (a multiple-model filter takes its modes' filters as they are).
    fn boxed_clone(&self) -> Box<dyn GaussianFilter>;
}

/// The measurement model of one step: h, R and the angular outputs of h.
#[derive(Clone, Copy)]
pub struct Sensor<'a> {
    /// h, with m outputs.
    pub h: &'a dyn PointFunction,
    /// R (m × m).
    pub r: &'a [f64],
    /// The outputs of h that are angles.
    pub angles: &'a [usize],
}

/// The EKF between steps, with its scratch.
#[derive(Clone)]
pub(crate) struct Ekf {
    ws: Step,
    options: EkfOptions,
    diffs: Differences,
    jac_f: Vec<f64>,
    iterate: GaussianUpdate<Dyn>,
    x_i: Vec<f64>,
    h_at_xi: Vec<f64>,
    scratch_p: Vec<f64>,
    hess: Vec<f64>,
    augmented: Augmented,
}

impl Ekf {
    pub fn new(n: usize, m: usize, x0: &[f64], p0: &[f64], options: EkfOptions) -> Result<Self> {
        options.form.require_covariance_form("the extended Kalman filter")?;
        if options.second_order && options.iterations > 0 {
            return Err(Error::arg("order", "the second-order EKF is not iterated (iterations must be 0)"));
        }
        Ok(Ekf {
            ws: Step::new(n, m, x0, p0),
            options,
            diffs: Differences::default(),
            jac_f: vec![0.0; n * n],
            iterate: GaussianUpdate::new(Dyn { n, m }),
            x_i: vec![0.0; n],
            h_at_xi: vec![0.0; m],
            scratch_p: vec![0.0; n * n],
            hess: Vec::new(),
            augmented: Augmented::default(),
        })
    }
}

impl GaussianFilter for Ekf {
    fn name(&self) -> &'static str {
        "extended Kalman filter"
    }
    fn boxed_clone(&self) -> Box<dyn GaussianFilter> {
        Box::new(self.clone())
    }

    fn state(&self) -> &Step {
        &self.ws
    }

    fn state_mut(&mut self) -> &mut Step {
        &mut self.ws
    }

    fn update(&mut self, sensor: Sensor<'_>, y: &[f64], t: usize, u: Option<&[f64]>) -> Result<()> {
        let (n, m) = (self.ws.n, sensor.h.dim_out());
        if self.ws.fit(m) {
            self.iterate = GaussianUpdate::new(Dyn { n, m });
            self.h_at_xi.resize(m, 0.0);
        }
        let Ekf { ws, options, diffs, iterate, x_i, h_at_xi, scratch_p, hess, .. } = self;
        let h = sensor.h;
        // measurement prediction at x̂(t|t−1) (9.9)
        evaluate_with_jacobian(h, "h", &ws.x, t, u, sensor.angles, diffs, &mut ws.y_hat, &mut ws.jac_h)?;
        if options.second_order {
            // h̄_k = ½ tr(P(t|t−1) ∇²h_k)  (9.23)
            hess.resize(m * n * n, 0.0);
            hessian(h, "h", &ws.x, t, u, diffs, hess)?;
            add_half_traces(&mut ws.y_hat, &ws.p, hess, n);
        }
        ws.linearize(sensor);
        ws.observe(sensor, y);
        if ws.observed.is_empty() {
            ws.skip_update();
            return Ok(());
        }
        ws.gather(sensor, None);
        ws.update(sensor, options.form, t)?;
        if options.iterations == 0 {
            return Ok(());
        }
        x_i.copy_from_slice(&ws.x_filt);
        for _ in 0..options.iterations {
            // relinearize h at the last estimate x_i
            jacobian(h, "h", x_i, t, u, sensor.angles, diffs, &mut ws.jac_h)?;
            ws.linearize(sensor);
            let residual = match options.iteration {
                Iteration::Book => None, // (9.13): the innovation stays at the prediction
                Iteration::GaussNewton => {
                    evaluate(h, "h", x_i, 1, t, u, h_at_xi)?;
                    Some(Residual { y, x_i, h_at_xi })
                }
            };
            ws.gather(sensor, residual);
            let mo = ws.observed.len();
            iterate.apply(Dyn { n, m }, mo, &ws.prediction(), &ws.x, &ws.p, x_i, scratch_p, t)?;
        }
        if options.iteration == Iteration::GaussNewton {
            jacobian(h, "h", x_i, t, u, sensor.angles, diffs, &mut ws.jac_h)?;
            ws.linearize(sensor);
        }
        // P(t|t), S and K from the last linearization, with the innovation at the prediction
        // (9.16)–(9.17)
        ws.gather(sensor, None);
        ws.update(sensor, options.form, t)?;
        ws.x_filt.copy_from_slice(x_i);
        Ok(())
    }

    fn predict(
        &mut self,
        transition: Transition<'_>,
        t: usize,
        u: Option<&[f64]>,
        cross: Option<&mut [f64]>,
    ) -> Result<()> {
        let Ekf { ws, options, diffs, jac_f, hess, augmented, .. } = self;
        let (n, r, f) = (ws.n, transition.noise_inputs, transition.f);
        let na = n + r;
        let Step { x, p, x_filt, p_filt, fp, .. } = ws;
        // (9.10): f and its Jacobian at x̂(t|t) -- with noise inputs at (x̂(t|t), 0), the
        // Jacobian [F L] applied to diag(P(t|t), Q), which adds L Q L'
        let (point, cov) =
            if r == 0 { (&x_filt[..], &p_filt[..]) } else { augmented.fill(x_filt, p_filt, transition.q, n, r) };
        jac_f.resize(n * na, 0.0);
        evaluate_with_jacobian(f, "f", point, t, u, &[], diffs, x, jac_f)?;
        if options.second_order {
            // f̄_k = ½ tr(P(t|t) ∇²f_k), with P(t|t) already computed  (9.22)
            hess.resize(n * na * na, 0.0);
            hessian(f, "f", point, t, u, diffs, &mut hess[..n * na * na])?;
            add_half_traces(x, cov, hess, na);
        }
        fp.resize(n * na, 0.0);
        propagate(ws.kernel, n, na, jac_f, cov, fp, p);
        if let Some(c) = cross {
            // P(t|t) F' = (F P(t|t))', the first n columns of J diag(P(t|t), Q)
            for (i, row) in c.chunks_exact_mut(n).enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = fp[j * na + i];
                }
            }
        }
        if r == 0 {
            ws.add_process_noise(transition.q);
        }
        Ok(())
    }
}

/// The augmented state (x̂(t|t), 0) and covariance diag(P(t|t), Q) of a time update with the
/// noise as an input of f.
#[derive(Clone, Default)]
struct Augmented {
    x: Vec<f64>,
    p: Vec<f64>,
}

impl Augmented {
    fn fill(&mut self, x: &[f64], p: &[f64], q: &[f64], n: usize, r: usize) -> (&[f64], &[f64]) {
        let na = n + r;
        self.x.resize(na, 0.0);
        self.x[..n].copy_from_slice(x);
        self.p.resize(na * na, 0.0);
        self.p.fill(0.0);
        for i in 0..n {
            self.p[i * na..][..n].copy_from_slice(&p[i * n..][..n]);
        }
        for i in 0..r {
            self.p[(n + i) * na + n..][..r].copy_from_slice(&q[i * r..][..r]);
        }
        (&self.x, &self.p)
    }
}

/// The UKF between steps, with its sigma points and scratch.
#[derive(Clone)]
pub(crate) struct Ukf {
    ws: Step,
    /// The points of x̂(t|t−1), P(t|t−1) through h.
    update_pts: PointSet,
    /// The points of x̂(t|t), P(t|t) through f -- with noise inputs, of the augmented
    /// (x̂(t|t), 0), diag(P(t|t), Q).
    predict_pts: PointSet,
    /// The augmented centre (x̂(t|t), 0) and the lower factor of Q (r × r; n × n in the
    /// square-root form without noise inputs, where Q's columns join the QR).
    centre: Vec<f64>,
    q_factor: Vec<f64>,
    /// The square-root form's scratch.
    sqrt: Option<SqrtScratch>,
}

/// A sigma-point set for one dimension d, mapped to `out` numbers per point, with its scratch.
#[derive(Clone)]
struct PointSet {
    weights: Weights,
    factor: Vec<f64>,
    sigma: Vec<f64>,
    images: Vec<f64>,
    through: Transformed,
}

impl PointSet {
    fn new(points: &SigmaPoints, d: usize, out: usize) -> Self {
        let k = points.count(d);
        PointSet {
            weights: points.weights(d),
            factor: vec![0.0; d * d],
            sigma: vec![0.0; k * d],
            images: vec![0.0; k * out],
            through: Transformed::new(k, d, out),
        }
    }
}

/// The square-root UKF's scratch: the weighted deviations (n × columns) for the QR, its
/// Householder vector, a downdate vector, and K S^(1/2) with S's factor.
#[derive(Clone)]
struct SqrtScratch {
    columns: Vec<f64>,
    reflector: Vec<f64>,
    vector: Vec<f64>,
    gain_root: Vec<f64>,
    s_factor: Vec<f64>,
}

impl Ukf {
    /// The UKF for n states and m outputs; with `noise_inputs` r > 0, f takes (x, w) and the
    /// time update places points of the augmented n + r numbers.
    pub fn new(n: usize, m: usize, x0: &[f64], p0: &[f64], options: UkfOptions, noise_inputs: usize) -> Result<Self> {
        let (points, r) = (options.points, noise_inputs);
        points.validate(n)?;
        if r > 0 {
            if let SigmaPoints::Custom(_) = points {
                return Err(Error::arg(
                    "points",
                    format!(
                        "a custom set has one size; with the noise an input of f the time update needs \
                         points for n + r = {} numbers as well as n = {n} (use merwe, julier or cubature)",
                        n + r
                    ),
                ));
            }
            points.validate(n + r)?;
        }
        let mut ws = Step::new(n, m, x0, p0);
        let sqrt = (options.form == UkfForm::SquareRoot).then(|| {
            // the factor of P0, which may be singular
            let mut pred = vec![0.0; n * n];
            semidefinite_cholesky(&mut pred, p0, n);
            ws.factors = Some(Factors { filt: pred.clone(), pred });
            // columns: every point's deviation and the centre's term, and Q's n columns
            let cols = points.count(n + r) + 1 + n;
            SqrtScratch {
                columns: vec![0.0; n * cols],
                reflector: vec![0.0; cols],
                vector: vec![0.0; n],
                gain_root: vec![0.0; n * m],
                s_factor: vec![0.0; m * m],
            }
        });
        let q_size = if r == 0 && sqrt.is_some() { n } else { r };
        Ok(Ukf {
            ws,
            update_pts: PointSet::new(&points, n, m),
            predict_pts: PointSet::new(&points, n + r, n),
            centre: vec![0.0; n + r],
            q_factor: vec![0.0; q_size * q_size],
            sqrt,
        })
    }
}

impl GaussianFilter for Ukf {
    fn name(&self) -> &'static str {
        "unscented Kalman filter"
    }
    fn boxed_clone(&self) -> Box<dyn GaussianFilter> {
        Box::new(self.clone())
    }

    fn state(&self) -> &Step {
        &self.ws
    }

    fn state_mut(&mut self) -> &mut Step {
        &mut self.ws
    }

    fn update(&mut self, sensor: Sensor<'_>, y: &[f64], t: usize, u: Option<&[f64]>) -> Result<()> {
        let (n, m) = (self.ws.n, sensor.h.dim_out());
        let k = self.update_pts.weights.mean.len();
        if self.ws.fit(m) {
            self.update_pts.images.resize(k * m, 0.0);
            self.update_pts.through = Transformed::new(k, n, m);
            if let Some(sq) = &mut self.sqrt {
                sq.gain_root.resize(n * m, 0.0);
                sq.s_factor.resize(m * m, 0.0);
            }
        }
        let Ukf { ws, update_pts: PointSet { weights, factor, sigma, images, through }, sqrt, .. } = self;
        let factor = state_factor(ws.factors.as_ref().map(|f| &f.pred[..]), factor, &ws.p, n, "P(t|t-1)", t)?;
        place(weights, &ws.x, factor, sigma);
        evaluate(sensor.h, "h", sigma, k, t, u, images)?;
        unscented_transform(weights, sigma, images, sensor.angles, true, through);
        ws.y_hat.copy_from_slice(&through.mean);
        ws.s_full.copy_from_slice(&through.cov);
        ws.c_full.copy_from_slice(&through.cross);
        ws.add_measurement_noise(sensor);
        ws.observe(sensor, y);
        if ws.observed.is_empty() {
            ws.skip_update();
            return Ok(());
        }
        ws.gather(sensor, None);
        ws.update(sensor, UpdateForm::Standard, t)?;
        if let Some(sq) = sqrt {
            ws.downdate_factor(sq, t)?;
        }
        Ok(())
    }

    fn predict(
        &mut self,
        transition: Transition<'_>,
        t: usize,
        u: Option<&[f64]>,
        cross: Option<&mut [f64]>,
    ) -> Result<()> {
        let Ukf { ws, update_pts, predict_pts, centre, q_factor, sqrt } = self;
        let PointSet { weights, factor, sigma, images, through } = predict_pts;
        let (n, r, k) = (ws.n, transition.noise_inputs, weights.mean.len());
        let carried = ws.factors.as_ref().map(|f| &f.filt[..]);
        if r == 0 {
            let l_filt = state_factor(carried, factor, &ws.p_filt, n, "P(t|t)", t)?;
            place(weights, &ws.x_filt, l_filt, sigma);
        } else {
            let l_filt = state_factor(carried, &mut update_pts.factor, &ws.p_filt, n, "P(t|t)", t)?;
            // the augmented (x̂(t|t), 0) with the factor diag(L, L_Q) of diag(P(t|t), Q); Q may
            // be singular (its factor then has zero columns)
            let na = n + r;
            semidefinite_cholesky(q_factor, transition.q, r);
            factor.fill(0.0);
            for i in 0..n {
                factor[i * na..][..n].copy_from_slice(&l_filt[i * n..][..n]);
            }
            for i in 0..r {
                factor[(n + i) * na + n..][..r].copy_from_slice(&q_factor[i * r..][..r]);
            }
            centre[..n].copy_from_slice(&ws.x_filt);
            place(weights, centre, factor, sigma);
        }
        evaluate(transition.f, "f", sigma, k, t, u, images)?;
        unscented_transform(weights, sigma, images, &[], cross.is_some(), through);
        ws.x.copy_from_slice(&through.mean);
        if let Some(c) = cross {
            // Cov(x(t), x(t+1)): the state rows of the (augmented) points' cross-covariance
            c.copy_from_slice(&through.cross[..n * n]);
        }
        match sqrt {
            None => {
                ws.p.copy_from_slice(&through.cov);
                if r == 0 {
                    ws.add_process_noise(transition.q);
                }
            }
            Some(sq) => {
                let q = (r == 0).then(|| {
                    semidefinite_cholesky(q_factor, transition.q, n);
                    &q_factor[..]
                });
                ws.predict_factor(sq, weights, through, q, t)?;
            }
        }
        Ok(())
    }
}

/// `φ` at `k` points, with its output checked finite (the error names the function and step).
fn evaluate(
    phi: &dyn PointFunction,
    name: &'static str,
    points: &[f64],
    k: usize,
    t: usize,
    u: Option<&[f64]>,
    out: &mut [f64],
) -> Result<()> {
    phi.eval(points, k, t, u, out)?;
    check_finite(name, t, &out[..k * phi.dim_out()], "returned a")
}

/// An error naming `name` and step `t` at the first non-finite number in `values`, the message
/// starting with `what` ("returned a", "its Jacobian has a", ...).
pub(crate) fn check_finite(name: &'static str, t: usize, values: &[f64], what: &str) -> Result<()> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(Error::arg_at(name, t, format!("{what} non-finite value ({v})"))),
        None => Ok(()),
    }
}

/// φ and ∂φ/∂x at one point `x`: together where the function shares their work, else
/// [`evaluate`] and [`jacobian`]; both checked finite.
#[allow(clippy::too_many_arguments)]
fn evaluate_with_jacobian(
    phi: &dyn PointFunction,
    name: &'static str,
    x: &[f64],
    t: usize,
    u: Option<&[f64]>,
    angles: &[usize],
    diffs: &mut Differences,
    value: &mut [f64],
    jac: &mut [f64],
) -> Result<()> {
    match phi.eval_with_jacobian(x, t, u, value, jac) {
        Some(result) => {
            result?;
            check_finite(name, t, &value[..phi.dim_out()], "returned a")?;
            check_finite(name, t, jac, "its Jacobian has a")
        }
        None => {
            evaluate(phi, name, x, 1, t, u, value)?;
            jacobian(phi, name, x, t, u, angles, diffs, jac)
        }
    }
}

/// `∂φ/∂x` at `x`: the function's own Jacobian, or central differences; checked finite.
#[allow(clippy::too_many_arguments)]
fn jacobian(
    phi: &dyn PointFunction,
    name: &'static str,
    x: &[f64],
    t: usize,
    u: Option<&[f64]>,
    angles: &[usize],
    diffs: &mut Differences,
    out: &mut [f64],
) -> Result<()> {
    match phi.jacobian(x, 1, t, u, out) {
        Some(result) => result?,
        None => jacobian_by_differences(phi, x, t, u, angles, diffs, out)?,
    }
    check_finite(name, t, out, "its Jacobian has a")
}

/// `∂²φ_i/∂x²` at `x` for every output: the function's own Hessians, or second differences;
/// checked finite.
fn hessian(
    phi: &dyn PointFunction,
    name: &'static str,
    x: &[f64],
    t: usize,
    u: Option<&[f64]>,
    diffs: &mut Differences,
    out: &mut [f64],
) -> Result<()> {
    match phi.hessian(x, 1, t, u, out) {
        Some(result) => result?,
        None => hessian_by_differences(phi, x, t, u, diffs, out)?,
    }
    check_finite(name, t, out, "its Hessian has a")
}

/// `mean_k += ½ tr(P H_k)` for the n × n Hessians `H_k` (one per component of `mean`).
fn add_half_traces(mean: &mut [f64], p: &[f64], hessians: &[f64], n: usize) {
    for (k, m) in mean.iter_mut().enumerate() {
        let h = &hessians[k * n * n..(k + 1) * n * n];
        // tr(P H) = Σ_ij P_ij H_ji
        let trace: f64 =
            (0..n).flat_map(|i| (0..n).map(move |j| (i, j))).map(|(i, j)| p[i * n + j] * h[j * n + i]).sum();
        *m += 0.5 * trace;
    }
}

/// The lower factor of a state covariance: the one the square-root form carries, else its
/// Cholesky factor (into `scratch`).
fn state_factor<'a>(
    carried: Option<&'a [f64]>,
    scratch: &'a mut [f64],
    p: &[f64],
    n: usize,
    what: &'static str,
    t: usize,
) -> Result<&'a [f64]> {
    match carried {
        Some(l) => Ok(l),
        None => {
            square_root(scratch, p, n, what, t)?;
            Ok(scratch)
        }
    }
}

/// The lower Cholesky factor of a state covariance, or the error naming it and the step.
fn square_root(factor: &mut [f64], p: &[f64], n: usize, what: &'static str, t: usize) -> Result<()> {
    cholesky(factor, p, n).map_err(|j| Error::NotPositiveDefinite {
        what,
        step: t,
        problem: format!(
            "pivot {j} of its Cholesky factor is not positive, so it has no sigma points \
             (a nearly singular covariance: check Q, R and P0, or use the cubature points)"
        ),
    })
}

/// The point of a Gauss–Newton relinearization: the data, x_i and h(x_i).
#[derive(Clone, Copy)]
struct Residual<'a> {
    y: &'a [f64],
    x_i: &'a [f64],
    h_at_xi: &'a [f64],
}

/// `$body` with `$d` bound to compile-time sizes for the common small (n, m) — n ≤ 6, m ≤ 3 —
/// so that the dense kernels it calls are unrolled for them, where `$kernel` has loops for
/// compile-time sizes (`Kernel::fixed_sizes`; `$body` must run `$kernel`'s loop); `$other`
/// otherwise, with separate multiplies and adds. (So on an x86-64 CPU without FMA these steps
/// are never fused, even in deterministic mode: docs/conventions.md, "Arithmetic".)
macro_rules! with_step_sizes {
    ($kernel:expr, $n:expr, $m:expr, |$d:ident| $body:expr, else $other:expr) => {
        with_step_sizes!(@arms ($kernel.fixed_sizes(), $n, $m), $d, $body, $other;
            (1, 1) (2, 1) (2, 2) (3, 1) (3, 2) (3, 3) (4, 1) (4, 2) (4, 3) (5, 1) (5, 2) (5, 3) (6, 1) (6, 2) (6, 3))
    };
    (@arms ($fixed:expr, $n:expr, $m:expr), $d:ident, $body:expr, $other:expr; $(($a:literal, $b:literal))*) => {
        match ($fixed, $n, $m) {
            $((true, $a, $b) => {
                let $d = Fixed::<$a, $b>;
                $body
            })*
            _ => $other,
        }
    };
}

/// `F P F'` into `p` (n × n, one triangle mirrored) with `F P` into `fp`, for F n × k and P
/// k × k (k = n, or n + r with noise inputs); at compile-time sizes for k = n ≤ 6.
fn propagate(kernel: Kernel, n: usize, k: usize, f: &[f64], cov: &[f64], fp: &mut [f64], p: &mut [f64]) {
    #[inline(always)]
    fn sized<D: Dims>(d: D, k: usize, f: &[f64], cov: &[f64], fp: &mut [f64], p: &mut [f64]) {
        let n = d.n();
        let (f, cov, fp, p) = (&f[..n * k], &cov[..k * k], &mut fp[..n * k], &mut p[..n * n]);
        mul::<D>(fp, f, cov, n, k, k);
        mul_bt_sym::<D>(p, fp, f, n, k);
    }
    if k == n {
        with_step_sizes!(kernel, n, 1, |d| run_best!(kernel, d, |d| sized(d, d.n(), f, cov, fp, p)), else {
            sized(Dyn { n, m: 1 }, k, f, cov, fp, p)
        })
    } else {
        sized(Dyn { n, m: 1 }, k, f, cov, fp, p)
    }
}

/// The Gaussian update (Söderström Lemma 6.1) of `prior` into `post` by the `mo` observed
/// components, its results left in `gauss`: at compile-time sizes where
/// [`with_step_sizes!`] has them (a local workspace; the results copied out), in the loop of
/// `kernel` (fused multiply-adds on AVX2 + FMA unless deterministic, as the linear filter).
#[allow(clippy::too_many_arguments)]
fn gaussian_update(
    kernel: Kernel,
    gauss: &mut GaussianUpdate<Dyn>,
    n: usize,
    m: usize,
    mo: usize,
    pred: &MeasurementPrediction<'_>,
    (x, p): (&[f64], &[f64]),
    (x_filt, p_filt): (&mut [f64], &mut [f64]),
    t: usize,
) -> Result<()> {
    #[inline(always)]
    fn sized<D: Dims>(
        d: D,
        gauss: &mut GaussianUpdate<Dyn>,
        mo: usize,
        pred: &MeasurementPrediction<'_>,
        (x, p): (&[f64], &[f64]),
        (x_filt, p_filt): (&mut [f64], &mut [f64]),
        t: usize,
    ) -> Result<()> {
        // slices of the sizes' constant lengths, so that the loops over them unroll
        let n = d.n();
        let (x, p, x_filt, p_filt) = (&x[..n], &p[..n * n], &mut x_filt[..n], &mut p_filt[..n * n]);
        let mut local = GaussianUpdate::new(d);
        if mo == d.m() {
            // every component observed (the usual step): mo a constant too
            local.apply(d, d.m(), pred, x, p, x_filt, p_filt, t)?;
        } else {
            local.apply(d, mo, pred, x, p, x_filt, p_filt, t)?;
        }
        gauss.copy_results_of(&local, mo, n);
        Ok(())
    }
    with_step_sizes!(kernel, n, m, |d| run_best!(kernel, d, |d| sized(d, gauss, mo, pred, (x, p), (x_filt, p_filt), t)), else {
        gauss.apply(Dyn { n, m }, mo, pred, x, p, x_filt, p_filt, t)
    })
}

/// The `mo` observed blocks (e, C, S) as a measurement prediction: the whole arrays `full`
/// when `whole`, else the leading blocks of the `gathered` ones.
fn blocks<'a>(
    whole: bool,
    full: [&'a [f64]; 3],
    [e, c, s]: [&'a [f64]; 3],
    joseph: Option<(&'a [f64], &'a [f64])>,
    n: usize,
    mo: usize,
) -> MeasurementPrediction<'a> {
    let [innov, cross_cov, innov_cov] = if whole { full } else { [&e[..mo], &c[..n * mo], &s[..mo * mo]] };
    MeasurementPrediction { innov, cross_cov, innov_cov, joseph }
}

/// One filter's state and step buffers (run-time sizes, allocated once per call, and again
/// only when a streaming filter's sensor changes m).
#[derive(Clone)]
pub(crate) struct Step {
    n: usize,
    m: usize,
    /// x̂(t|t−1), P(t|t−1); x̂(t+1|t), P(t+1|t) after the time update.
    x: Vec<f64>,
    p: Vec<f64>,
    x_filt: Vec<f64>,
    p_filt: Vec<f64>,
    /// ŷ, its Jacobian H (m × n) or the sigma points' S and C, for all m components.
    y_hat: Vec<f64>,
    jac_h: Vec<f64>,
    s_full: Vec<f64>,
    c_full: Vec<f64>,
    innov: Vec<f64>,
    /// The observed components and their blocks: e, C (n × mo), S, H (mo × n), R -- unused
    /// while `whole`: every component observed and e the innovation, so that the blocks are
    /// the whole arrays (`innov`, `c_full`, `s_full`, `jac_h` and the sensor's R).
    observed: Vec<usize>,
    whole: bool,
    e_obs: Vec<f64>,
    c_obs: Vec<f64>,
    s_obs: Vec<f64>,
    h_obs: Vec<f64>,
    r_obs: Vec<f64>,
    gain: Vec<f64>,
    fp: Vec<f64>,
    gauss: GaussianUpdate<Dyn>,
    /// The lower factors of P(t|t−1) and P(t|t), carried by the square-root UKF.
    factors: Option<Factors>,
    /// The loop the step's fixed-size products run in (read once per filter).
    kernel: Kernel,
}

/// The lower Cholesky factors the square-root UKF carries beside P(t|t−1) and P(t|t).
#[derive(Clone)]
struct Factors {
    pred: Vec<f64>,
    filt: Vec<f64>,
}

impl Step {
    fn new(n: usize, m: usize, x0: &[f64], p0: &[f64]) -> Self {
        Step {
            n,
            m,
            x: x0.to_vec(),
            p: p0.to_vec(),
            x_filt: vec![0.0; n],
            p_filt: vec![0.0; n * n],
            y_hat: vec![0.0; m],
            jac_h: vec![0.0; m * n],
            s_full: vec![0.0; m * m],
            c_full: vec![0.0; n * m],
            innov: vec![0.0; m],
            observed: Vec::with_capacity(m),
            whole: false,
            e_obs: vec![0.0; m],
            c_obs: vec![0.0; n * m],
            s_obs: vec![0.0; m * m],
            h_obs: vec![0.0; m * n],
            r_obs: vec![0.0; m * m],
            gain: vec![0.0; n * m],
            fp: vec![0.0; n * n],
            gauss: GaussianUpdate::new(Dyn { n, m }),
            factors: None,
            kernel: isa::kernel(),
        }
    }

    /// The square-root update of P(t|t)'s factor after [`update`](Self::update) (which gave
    /// x̂(t|t), K and the log-likelihood term): `L(t|t) L(t|t)' = L L' − U U'` with
    /// `U = C S^(−1/2)'` (= K S^(1/2)), one Cholesky downdate per observed component; P(t|t)
    /// is then `L(t|t) L(t|t)'`.
    fn downdate_factor(&mut self, sq: &mut SqrtScratch, t: usize) -> Result<()> {
        let (n, mo) = (self.n, self.observed.len());
        let SqrtScratch { gain_root, s_factor, vector, .. } = sq;
        let observed = self.prediction();
        cholesky(s_factor, observed.innov_cov, mo).map_err(|j| Error::NotPositiveDefinite {
            what: "S",
            step: t,
            problem: format!("pivot {j} of its Cholesky factor is not positive"),
        })?;
        // each row of U solves L_S u' = c' (forward substitution)
        for i in 0..n {
            for a in 0..mo {
                let mut v = observed.cross_cov[i * mo + a];
                for b in 0..a {
                    v -= s_factor[a * mo + b] * gain_root[i * mo + b];
                }
                gain_root[i * mo + a] = v / s_factor[a * mo + a];
            }
        }
        let Step { p_filt, factors: Some(factors), .. } = self else { return Ok(()) };
        factors.filt.copy_from_slice(&factors.pred);
        for a in 0..mo {
            for i in 0..n {
                vector[i] = gain_root[i * mo + a];
            }
            downdate(&mut factors.filt, vector, n).map_err(|j| Error::NotPositiveDefinite {
                what: "P(t|t)",
                step: t,
                problem: format!(
                    "the square-root update's Cholesky downdate lost pivot {j}: P(t|t) = P(t|t-1) - K S K' \
                     is not positive definite to working precision (check R and the scale of P)"
                ),
            })?;
        }
        mul_bt_sym::<Dyn>(p_filt, &factors.filt, &factors.filt, n, n);
        Ok(())
    }

    /// The square-root time update of P(t+1|t)'s factor from the transform of the points:
    /// `L L' = Σ Wᵢ Dᵢ Dᵢ' + (W⁰꜀ − W⁰ₘ − 1) d d' (+ L_Q L_Q')` (the transform's centred sums), by
    /// QR of the columns with positive weights and a downdate for each negative one.
    fn predict_factor(
        &mut self,
        sq: &mut SqrtScratch,
        w: &Weights,
        through: &Transformed,
        q_factor: Option<&[f64]>,
        t: usize,
    ) -> Result<()> {
        let n = self.n;
        let Step { p, factors, .. } = self;
        let Some(factors) = factors else { return Ok(()) };
        let (dev, d) = through.deviations();
        let first = usize::from(w.centre);
        let cov_weights = w.cov.as_deref().unwrap_or(&w.mean);
        let centre_weight = if w.centre { w.centre_excess - 1.0 } else { 0.0 };
        // (weight, vector) of every term, weights as in the transform
        let terms = (first..cov_weights.len())
            .map(|i| (cov_weights[i], &dev[i * n..][..n]))
            .chain(std::iter::once((centre_weight, d)));
        let cols = sq.reflector.len();
        let SqrtScratch { columns, reflector, vector, .. } = sq;
        columns.fill(0.0);
        let mut c = 0;
        for (wi, v) in terms.clone().filter(|(wi, _)| *wi > 0.0) {
            let s = wi.sqrt();
            for i in 0..n {
                columns[i * cols + c] = s * v[i];
            }
            c += 1;
        }
        if let Some(lq) = q_factor {
            for i in 0..n {
                columns[i * cols + c..][..n].copy_from_slice(&lq[i * n..][..n]);
            }
        }
        tria(columns, n, cols, reflector, &mut factors.pred);
        for (wi, v) in terms.filter(|(wi, _)| *wi < 0.0) {
            let s = (-wi).sqrt();
            for i in 0..n {
                vector[i] = s * v[i];
            }
            downdate(&mut factors.pred, vector, n).map_err(|j| Error::NotPositiveDefinite {
                what: "P(t|t-1)",
                step: t + 1,
                problem: format!(
                    "the square-root time update's downdate (a negative sigma-point weight) lost pivot {j}: \
                     the points' covariance is not positive definite (use Merwe points with beta >= alpha^2, \
                     or cubature points, whose weights are all positive)"
                ),
            })?;
        }
        mul_bt_sym::<Dyn>(p, &factors.pred, &factors.pred, n, n);
        Ok(())
    }

    /// For a linearized measurement (EKF): C = P H' and S = H P H' + R for all components.
    fn linearize(&mut self, sensor: Sensor<'_>) {
        #[inline(always)]
        fn sized<D: Dims>(d: D, p: &[f64], jac_h: &[f64], c: &mut [f64], s: &mut [f64]) {
            let (n, m) = (d.n(), d.m());
            let (p, jac_h, c, s) = (&p[..n * n], &jac_h[..m * n], &mut c[..n * m], &mut s[..m * m]);
            mul_bt::<D>(c, p, jac_h, n, n, m);
            mul::<D>(s, jac_h, c, m, n, m);
            symmetrize(s, m);
        }
        let (n, m, kernel) = (self.n, self.m, self.kernel);
        let Step { p, jac_h, c_full, s_full, .. } = self;
        with_step_sizes!(kernel, n, m, |d| run_best!(kernel, d, |d| sized(d, p, jac_h, c_full, s_full)), else {
            sized(Dyn { n, m }, p, jac_h, c_full, s_full)
        });
        self.add_measurement_noise(sensor);
    }

    fn add_measurement_noise(&mut self, sensor: Sensor<'_>) {
        for (s, r) in self.s_full.iter_mut().zip(sensor.r) {
            *s += r;
        }
    }

    /// The innovation y − ŷ of every component (angles wrapped; NaN where y is missing) and
    /// the observed components.
    fn observe(&mut self, sensor: Sensor<'_>, y: &[f64]) {
        for (i, e) in self.innov.iter_mut().enumerate() {
            *e = y[i] - self.y_hat[i];
            if sensor.angles.contains(&i) {
                *e = wrap_angle(*e);
            }
        }
        self.observed.clear();
        self.observed.extend((0..self.m).filter(|&i| !y[i].is_nan()));
    }

    /// The observed blocks of e, C, S, H and R; with a Gauss–Newton `residual`, e is
    /// y − h(x_i) − H (x̂⁻ − x_i) instead of the innovation.
    fn gather(&mut self, sensor: Sensor<'_>, residual: Option<Residual<'_>>) {
        let (n, m, mo) = (self.n, self.m, self.observed.len());
        let r = sensor.r;
        self.whole = mo == m && residual.is_none();
        if self.whole {
            return;
        }
        for (a, &i) in self.observed.iter().enumerate() {
            let h = &self.jac_h[i * n..(i + 1) * n];
            self.h_obs[a * n..(a + 1) * n].copy_from_slice(h);
            self.e_obs[a] = match residual {
                None => self.innov[i],
                Some(Residual { y, x_i, h_at_xi }) => {
                    let mut e = y[i] - h_at_xi[i];
                    if sensor.angles.contains(&i) {
                        e = wrap_angle(e);
                    }
                    e - h.iter().zip(&self.x).zip(x_i).map(|((h, x), xi)| h * (x - xi)).sum::<f64>()
                }
            };
            for row in 0..n {
                self.c_obs[row * mo + a] = self.c_full[row * m + i];
            }
            for (b, &j) in self.observed.iter().enumerate() {
                self.s_obs[a * mo + b] = self.s_full[i * m + j];
                self.r_obs[a * mo + b] = r[i * m + j];
            }
        }
    }

    /// The gathered blocks as a measurement prediction for the standard form.
    fn prediction(&self) -> MeasurementPrediction<'_> {
        let full = [&self.innov[..], &self.c_full, &self.s_full];
        blocks(self.whole, full, [&self.e_obs, &self.c_obs, &self.s_obs], None, self.n, self.observed.len())
    }

    /// The Gaussian update with the gathered blocks (and `sensor`'s R in the Joseph form);
    /// K's observed columns from it.
    fn update(&mut self, sensor: Sensor<'_>, form: UpdateForm, t: usize) -> Result<()> {
        let (n, m, mo) = (self.n, self.m, self.observed.len());
        let Step {
            gauss, innov, c_full, s_full, jac_h, e_obs, c_obs, s_obs, h_obs, r_obs, x, p, x_filt, p_filt, ..
        } = self;
        let joseph = (form == UpdateForm::Joseph).then(|| {
            if self.whole {
                (&jac_h[..], sensor.r)
            } else {
                (&h_obs[..mo * n], &r_obs[..mo * mo])
            }
        });
        let pred = blocks(self.whole, [innov, c_full, s_full], [e_obs, c_obs, s_obs], joseph, n, mo);
        gaussian_update(self.kernel, gauss, n, m, mo, &pred, (x, p), (x_filt, p_filt), t)?;
        let gain_t = self.gauss.gain_t(mo, n);
        if mo == m {
            transpose(&mut self.gain, gain_t, m, n);
            return Ok(());
        }
        self.gain.fill(0.0);
        for (a, &i) in self.observed.iter().enumerate() {
            for row in 0..n {
                self.gain[row * m + i] = gain_t[a * n + row];
            }
        }
        Ok(())
    }

    /// x̂ and P of the current phase: (x̂(t|t), P(t|t)) after an update, else the prediction.
    pub(crate) fn current(&self, filtered: bool) -> (&[f64], &[f64]) {
        if filtered {
            (&self.x_filt, &self.p_filt)
        } else {
            (&self.x, &self.p)
        }
    }

    /// Makes x̂(t|t), P(t|t) the prior of the next update (`to_prior`), or the prediction the
    /// filtered state (a time update with no update before it).
    pub(crate) fn carry(&mut self, to_prior: bool) {
        let Step { x, p, x_filt, p_filt, factors, .. } = self;
        if to_prior {
            x.copy_from_slice(x_filt);
            p.copy_from_slice(p_filt);
        } else {
            x_filt.copy_from_slice(x);
            p_filt.copy_from_slice(p);
        }
        if let Some(Factors { pred, filt }) = factors {
            if to_prior {
                pred.copy_from_slice(filt);
            } else {
                filt.copy_from_slice(pred);
            }
        }
    }

    /// Makes `(x, p)` the filtered state x̂(t|t), P(t|t), in place of the update's (the
    /// interacting multiple-model filter's mixed state, Söderström (9.72)–(9.73)). The
    /// square-root UKF's factor is that of `p` (a semidefinite P has one).
    pub(crate) fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        self.x_filt.copy_from_slice(x);
        self.p_filt.copy_from_slice(p);
        if let Some(Factors { filt, .. }) = &mut self.factors {
            semidefinite_cholesky(filt, p, self.n);
        }
    }

    /// The log-likelihood term of the last update (0 when nothing was observed).
    pub(crate) fn loglik_t(&self) -> f64 {
        self.gauss.loglik_t()
    }

    /// Sizes the measurement buffers for `m` outputs; `true` when they changed (a streaming
    /// filter's second sensor), so the caller resizes its own.
    fn fit(&mut self, m: usize) -> bool {
        if m == self.m {
            return false;
        }
        let fresh = Step::new(self.n, m, &self.x, &self.p);
        let Step { x, p, x_filt, p_filt, fp, factors, .. } = std::mem::replace(self, fresh);
        (self.x, self.p, self.x_filt, self.p_filt, self.fp, self.factors) = (x, p, x_filt, p_filt, fp, factors);
        true
    }

    fn skip_update(&mut self) {
        self.x_filt.copy_from_slice(&self.x);
        self.p_filt.copy_from_slice(&self.p);
        if let Some(Factors { pred, filt }) = &mut self.factors {
            filt.copy_from_slice(pred);
        }
        self.gain.fill(0.0);
        self.gauss.skip();
    }

    fn store(&self, out: &mut FilterOutputs<'_>, t: usize) {
        out.store_values(t, &self.x_filt, &self.p_filt, &self.innov, &self.s_full, &self.gain, self.gauss.loglik_t());
    }

    fn add_process_noise(&mut self, q: &[f64]) {
        for (p, q) in self.p.iter_mut().zip(q) {
            *p += q;
        }
        symmetrize(&mut self.p, self.n);
    }
}
