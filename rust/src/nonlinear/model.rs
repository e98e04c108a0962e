//! [`NonlinearModel`]: f, h, Q, R and the angular outputs, validated once.

use std::sync::Arc;

use super::filter::Sensor;
use super::function::PointFunction;
use crate::core::dense::{mul, mul_bt_sym};
use crate::core::dims::Dyn;
use crate::core::validate::{check_input_row, check_observations, check_prior, check_psd, check_symmetric};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::StepMatrix;

/// The nonlinear model with additive Gaussian noise (prior x(0|−1) ~ N(x0, P0)):
///
/// ```text
/// x[t+1] = f(x[t], t, u[t]) + w[t]     w ~ N(0, Q[t])
/// y[t]   = h(x[t], t, u[t]) + v[t]     v ~ N(0, R[t])
/// ```
///
/// or, with a noise gain g ([`with_noise_gain`](Self::with_noise_gain)),
/// `x[t+1] = f(x[t], t, u[t]) + g(x[t], t, u[t]) w[t]` with g(x) n × r and Q r × r: the filters
/// then add `G Q G'` with G = g(x̂(t|t)), the gain at the estimate (Söderström (9.2)–(9.11)
/// with G(t) evaluated where f is linearized),
///
/// or, with the noise an input of f ([`with_noise_input`](Self::with_noise_input)),
/// `x[t+1] = f(x[t], w[t], t, u[t])` with Q r × r: f takes the n + r numbers (x, w). The EKF
/// linearizes f in both at (x̂(t|t), 0) and adds `L Q L'` with L = ∂f/∂w; the UKF propagates
/// sigma points of the augmented (x, w) ~ N((x̂(t|t), 0), diag(P(t|t), Q)) through f
/// (Julier & Uhlmann 1997; Wan & van der Merwe 2000, the augmented UKF).
///
/// Q and R are constant or given per step as in [`LinearGaussian`](crate::LinearGaussian)
/// (`Q[t]` takes `x[t]` to `x[t+1]`, `R[t]` goes with `y[t]`); a singular Q (even 0) is allowed.
/// `angles` lists the components of y that are angles: innovations and sigma-point deviations
/// of those components are wrapped to [−π, π).
#[derive(Clone)]
pub struct NonlinearModel {
    f: Arc<dyn PointFunction>,
    h: Arc<dyn PointFunction>,
    noise: ProcessNoise,
    q: StepMatrix,
    r: StepMatrix,
    angles: Vec<usize>,
}

/// How the process noise w ~ N(0, Q) enters the transition.
#[derive(Clone)]
enum ProcessNoise {
    /// `f(x) + w`, Q n × n.
    Additive,
    /// `f(x) + g(x) w`, Q r × r.
    Gain(Arc<dyn PointFunction>),
    /// `f(x, w)`, Q r × r: f takes n + r numbers.
    Input,
}

/// How w enters x[t+1], for drawing it: `f(x) + w`, `f(x) + g(x) w` or `f(x, w)`.
#[derive(Clone, Copy)]
pub(crate) enum NoiseEntry<'a> {
    Additive,
    Gain(&'a dyn PointFunction),
    Input,
}

/// The time update's model at one step: f and the covariance of its noise.
#[derive(Clone, Copy)]
pub(crate) struct Transition<'a> {
    pub f: &'a dyn PointFunction,
    /// The n × n covariance added to the state (Q, or G Q G'), or, when the noise is an input
    /// of f, the r × r covariance of that input.
    pub q: &'a [f64],
    /// r when the noise is an input of f (which then takes n + r numbers), else 0.
    pub noise_inputs: usize,
}

impl std::fmt::Debug for NonlinearModel {
    fn fmt(&self, out: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(out, "NonlinearModel(n = {}, m = {}, angles = {:?})", self.n_states(), self.n_obs(), self.angles)
    }
}

impl NonlinearModel {
    /// Validates the model once: f maps n states to n, h maps n states to m outputs, Q is
    /// n × n and R m × m (constant or per step, stacks of one length), both symmetric positive
    /// semidefinite and finite, and `angles` are distinct output indices.
    pub fn new(
        f: Arc<dyn PointFunction>,
        h: Arc<dyn PointFunction>,
        q: StepMatrix,
        r: StepMatrix,
        angles: Vec<usize>,
    ) -> Result<Self> {
        Self::validated(f, ProcessNoise::Additive, h, q, r, angles)
    }

    /// [`new`](Self::new) with the noise gain `g`, whose `dim_out` is n·r (G row-major, n × r)
    /// for the r × r `q`.
    pub fn with_noise_gain(
        f: Arc<dyn PointFunction>,
        g: Arc<dyn PointFunction>,
        h: Arc<dyn PointFunction>,
        q: StepMatrix,
        r: StepMatrix,
        angles: Vec<usize>,
    ) -> Result<Self> {
        Self::validated(f, ProcessNoise::Gain(g), h, q, r, angles)
    }

    /// [`new`](Self::new) with the noise an input of f: `f.dim_in()` is n + r (the state,
    /// then the noise) for the r × r `q`, and `f.dim_out()` is n.
    pub fn with_noise_input(
        f: Arc<dyn PointFunction>,
        h: Arc<dyn PointFunction>,
        q: StepMatrix,
        r: StepMatrix,
        angles: Vec<usize>,
    ) -> Result<Self> {
        Self::validated(f, ProcessNoise::Input, h, q, r, angles)
    }

    fn validated(
        f: Arc<dyn PointFunction>,
        noise: ProcessNoise,
        h: Arc<dyn PointFunction>,
        q: StepMatrix,
        r: StepMatrix,
        angles: Vec<usize>,
    ) -> Result<Self> {
        let n = f.dim_out();
        let noise_dim = match &noise {
            ProcessNoise::Additive => n,
            ProcessNoise::Gain(_) | ProcessNoise::Input => q.rows(),
        };
        let f_inputs = if matches!(noise, ProcessNoise::Input) { n + noise_dim } else { n };
        if f.dim_in() != f_inputs {
            return Err(Error::arg(
                "f",
                match noise {
                    ProcessNoise::Input => format!(
                        "takes {} numbers, expected the n = {n} states and the r = {noise_dim} noise inputs of Q",
                        f.dim_in()
                    ),
                    _ => format!("maps {} states to {n} numbers, not to {}", f.dim_in(), f.dim_in()),
                },
            ));
        }
        if h.dim_in() != n {
            return Err(Error::arg("h", format!("takes {} states, but f gives n = {n}", h.dim_in())));
        }
        let m = h.dim_out();
        if let ProcessNoise::Gain(g) = &noise {
            if g.dim_in() != n {
                return Err(Error::arg("g", format!("takes {} states, but f takes n = {n}", g.dim_in())));
            }
            if g.dim_out() != n * noise_dim {
                return Err(Error::arg(
                    "g",
                    format!(
                        "gives {} numbers, expected n × r = {n} × {noise_dim} for Q of shape ({noise_dim}, {noise_dim})",
                        g.dim_out()
                    ),
                ));
            }
        }
        check_covariance("Q", &q, noise_dim)?;
        check_covariance("R", &r, m)?;
        if let (Some(a), Some(b)) = (q.steps(), r.steps()) {
            if a != b {
                return Err(Error::arg("R", format!("has {b} steps but Q has {a}")));
            }
        }
        for (i, &a) in angles.iter().enumerate() {
            if a >= m {
                return Err(Error::arg("angles", format!("index {a} is not an output of h (m = {m})")));
            }
            if angles[..i].contains(&a) {
                return Err(Error::arg("angles", format!("index {a} is listed twice")));
            }
        }
        Ok(NonlinearModel { f, h, noise, q, r, angles })
    }

    /// The state size n.
    pub fn n_states(&self) -> usize {
        self.f.dim_out()
    }

    /// The output size m.
    pub fn n_obs(&self) -> usize {
        self.h.dim_out()
    }

    /// The number of per-step noise covariances, if Q or R is given per step.
    pub fn steps(&self) -> Option<usize> {
        self.q.steps().or(self.r.steps())
    }

    /// Whether f, h and g can run on several threads at once (see [`PointFunction::parallel`]).
    pub fn parallel(&self) -> bool {
        let g_parallel = match &self.noise {
            ProcessNoise::Gain(g) => g.parallel(),
            _ => true,
        };
        self.f.parallel() && self.h.parallel() && g_parallel
    }

    /// The angular outputs.
    pub fn angles(&self) -> &[usize] {
        &self.angles
    }

    /// The measurement model of step t.
    pub(crate) fn sensor(&self, t: usize) -> Sensor<'_> {
        Sensor { h: &*self.h, r: self.r.at(t), angles: &self.angles }
    }

    /// The time update's model from x̂(t|t) = `x`: f and Q(t), or G Q(t) G' with
    /// G = g(x, t, u) (into `scratch`; g's output checked finite, an error names g and t).
    pub(crate) fn transition<'a>(
        &'a self,
        t: usize,
        x: &[f64],
        u: Option<&[f64]>,
        scratch: &'a mut NoiseScratch,
    ) -> Result<Transition<'a>> {
        let (f, q) = (&*self.f, self.q.at(t));
        let g = match &self.noise {
            ProcessNoise::Additive => return Ok(Transition { f, q, noise_inputs: 0 }),
            ProcessNoise::Input => return Ok(Transition { f, q, noise_inputs: self.q.rows() }),
            ProcessNoise::Gain(g) => g,
        };
        let (n, r) = (self.n_states(), self.q.rows());
        scratch.gain.resize(n * r, 0.0);
        scratch.gq.resize(n * r, 0.0);
        scratch.noise.resize(n * n, 0.0);
        g.eval(x, 1, t, u, &mut scratch.gain)?;
        if let Some(v) = scratch.gain.iter().find(|v| !v.is_finite()) {
            return Err(Error::arg_at("g", t, format!("returned a non-finite value ({v})")));
        }
        // G Q G', one triangle mirrored: exactly symmetric
        mul::<Dyn>(&mut scratch.gq, &scratch.gain, q, n, r, r);
        mul_bt_sym::<Dyn>(&mut scratch.noise, &scratch.gq, &scratch.gain, n, r);
        Ok(Transition { f, q: &scratch.noise, noise_inputs: 0 })
    }

    /// How the process noise of step t enters, for a filter that draws it (the particle
    /// filter): with the covariance Q(t) of w (n × n, or r × r with a gain or as an input).
    pub(crate) fn process_noise(&self, t: usize) -> (NoiseEntry<'_>, &[f64]) {
        let entry = match &self.noise {
            ProcessNoise::Additive => NoiseEntry::Additive,
            ProcessNoise::Gain(g) => NoiseEntry::Gain(&**g),
            ProcessNoise::Input => NoiseEntry::Input,
        };
        (entry, self.q.at(t))
    }

    /// f (taking n numbers, or n + r when the noise is an input).
    pub(crate) fn transition_function(&self) -> &dyn PointFunction {
        &*self.f
    }

    /// Whether the model has a noise gain g.
    pub fn has_noise_gain(&self) -> bool {
        matches!(self.noise, ProcessNoise::Gain(_))
    }

    /// r when the process noise is an input of f (f takes n + r numbers), else 0.
    pub fn noise_inputs(&self) -> usize {
        match self.noise {
            ProcessNoise::Input => self.q.rows(),
            _ => 0,
        }
    }

    /// Validates data, inputs and prior for a run; returns T.
    pub(crate) fn check_run(&self, y: Series<'_>, u: Option<Series<'_>>, x0: &[f64], p0: &[f64]) -> Result<usize> {
        let steps = check_observations(y, self.n_obs(), self.steps())?;
        if let Some(u) = u {
            if u.steps() != steps {
                return Err(Error::arg("u", format!("has {} steps but y has {steps}", u.steps())));
            }
            for t in 0..steps {
                check_input_row(u.row(t), Some(t))?;
            }
        }
        check_prior(self.n_states(), x0, p0)?;
        Ok(steps)
    }
}

fn check_covariance(arg: &'static str, mat: &StepMatrix, size: usize) -> Result<()> {
    if mat.rows() != size || mat.cols() != size {
        return Err(Error::arg(arg, format!("expected ({size}, {size}), got ({}, {})", mat.rows(), mat.cols())));
    }
    for t in 0..mat.steps().unwrap_or(1) {
        let step = mat.steps().map(|_| t);
        let a = mat.at(t);
        if let Some(v) = a.iter().find(|v| !v.is_finite()) {
            return Err(Error::arg(arg, format!("contains a non-finite value ({v})")).at_step(step));
        }
        check_symmetric(a, size).map_err(|p| Error::arg(arg, p).at_step(step))?;
        check_psd(a, size).map_err(|p| Error::arg(arg, p).at_step(step))?;
    }
    Ok(())
}

/// Scratch of [`NonlinearModel::transition`]: G, G Q and G Q G'.
#[derive(Debug, Clone, Default)]
pub(crate) struct NoiseScratch {
    gain: Vec<f64>,
    gq: Vec<f64>,
    noise: Vec<f64>,
}
