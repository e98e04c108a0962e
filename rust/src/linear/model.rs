//! The linear Gaussian state-space model (docs/conventions.md):
//!
//! ```text
//! x[t+1] = F x[t] + B u[t] + w[t]        w ~ N(0, Q)
//! y[t]   = H x[t] + D u[t] + v[t]        v ~ N(0, R),   E[w[t] v[t]'] = N
//! ```
//!
//! Each matrix is constant or given per step. Per-step matrices are indexed by the step they
//! leave: `F[t], B[t], Q[t], N[t]` take `x[t]` to `x[t+1]`; `H[t], D[t], R[t]` produce `y[t]`.
//! The model is validated once, when it is built; the filters then trust it.

use crate::core::validate::{check_joint_psd, check_psd, check_symmetric};
use crate::error::{Error, Result};

/// A matrix that is either constant over time or given per step (a stack of `steps` matrices),
/// stored row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct StepMatrix {
    data: Vec<f64>,
    rows: usize,
    cols: usize,
    steps: Option<usize>,
}

impl StepMatrix {
    /// A constant `rows × cols` matrix from row-major `data`.
    pub fn constant(rows: usize, cols: usize, data: Vec<f64>) -> Result<Self> {
        Self::from_shape("matrix", &[rows, cols], data)
    }

    /// A stack of `steps` matrices of `rows × cols` from row-major `data` (step-major).
    pub fn per_step(steps: usize, rows: usize, cols: usize, data: Vec<f64>) -> Result<Self> {
        Self::from_shape("matrix", &[steps, rows, cols], data)
    }

    /// From an array shape as NumPy gives it: `()` is a 1×1 matrix, `(r, c)` a constant
    /// matrix, `(T, r, c)` a stack of per-step matrices. `arg` names the argument in errors.
    pub fn from_shape(arg: &'static str, shape: &[usize], data: Vec<f64>) -> Result<Self> {
        let (steps, rows, cols) = match *shape {
            [] => (None, 1, 1),
            [r, c] => (None, r, c),
            [t, r, c] => (Some(t), r, c),
            _ => {
                return Err(Error::arg(
                    arg,
                    format!(
                        "expected a 2-D matrix or a 3-D stack of per-step matrices (T, rows, cols), got shape {shape:?}"
                    ),
                ))
            }
        };
        if steps == Some(0) {
            return Err(Error::arg(arg, "a per-step stack needs at least one step (T = 0)"));
        }
        if [rows, cols].iter().try_fold(steps.unwrap_or(1), |acc, &d| acc.checked_mul(d)) != Some(data.len()) {
            return Err(Error::arg(arg, format!("data length {} does not match shape {shape:?}", data.len())));
        }
        Ok(StepMatrix { data, rows, cols, steps })
    }

    /// The matrix used at step `t` (the constant one, or the `t`-th of the stack).
    #[inline]
    pub fn at(&self, t: usize) -> &[f64] {
        match self.steps {
            None => &self.data,
            Some(_) => {
                let size = self.rows * self.cols;
                &self.data[t * size..(t + 1) * size]
            }
        }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// `Some(T)` for a per-step stack, `None` for a constant matrix.
    pub fn steps(&self) -> Option<usize> {
        self.steps
    }

    /// The steps to validate: `None` once for a constant matrix, `Some(t)` for each of a stack.
    fn step_indices(&self) -> Vec<Option<usize>> {
        match self.steps {
            None => vec![None],
            Some(t) => (0..t).map(Some).collect(),
        }
    }

    fn expect_shape(&self, arg: &'static str, rows: usize, cols: usize, what: &str) -> Result<()> {
        if self.rows != rows || self.cols != cols {
            return Err(Error::arg(
                arg,
                format!("expected shape ({rows}, {cols}) {what}, got ({}, {})", self.rows, self.cols),
            ));
        }
        Ok(())
    }

    fn check_finite(&self, arg: &'static str) -> Result<()> {
        for t in self.step_indices() {
            if let Some(v) = self.at(t.unwrap_or(0)).iter().find(|v| !v.is_finite()) {
                return Err(Error::arg(arg, format!("contains a non-finite value ({v})")).at_step(t));
            }
        }
        Ok(())
    }

    /// Checks symmetry and positive semidefiniteness of each matrix, then stores `(A + A')/2`
    /// so that rounding-level asymmetry never reaches the filter.
    fn check_covariance(&mut self, arg: &'static str) -> Result<()> {
        let n = self.rows;
        if n != self.cols {
            return Err(Error::arg(arg, format!("a covariance must be square, got shape ({n}, {})", self.cols)));
        }
        for t in self.step_indices() {
            let size = n * n;
            let start = t.unwrap_or(0) * size;
            let a = &mut self.data[start..start + size];
            check_symmetric(a, n).map_err(|p| Error::arg(arg, p).at_step(t))?;
            crate::core::dense::symmetrize(a, n);
            check_psd(a, n).map_err(|p| Error::arg(arg, p).at_step(t))?;
        }
        Ok(())
    }
}

/// The model matrices, before validation. Start from [`Matrices::new`] and set the optional
/// ones with struct update syntax: `Matrices { b: Some(b), ..Matrices::new(f, h, q, r) }`.
#[derive(Debug, Clone)]
pub struct Matrices {
    /// Transition `F` (n × n).
    pub f: StepMatrix,
    /// Observation `H` (m × n).
    pub h: StepMatrix,
    /// Process noise covariance `Q` (n × n), a discrete-time covariance.
    pub q: StepMatrix,
    /// Measurement noise covariance `R` (m × m).
    pub r: StepMatrix,
    /// Input matrix of the state `B` (n × k).
    pub b: Option<StepMatrix>,
    /// Input matrix of the output `D` (m × k).
    pub d: Option<StepMatrix>,
    /// Cross covariance `N = E[w[t] v[t]']` (n × m).
    pub n: Option<StepMatrix>,
}

impl Matrices {
    /// `F, H, Q, R` with no inputs and uncorrelated noises.
    pub fn new(f: StepMatrix, h: StepMatrix, q: StepMatrix, r: StepMatrix) -> Self {
        Matrices { f, h, q, r, b: None, d: None, n: None }
    }
}

/// The matrices in force at one step (slices into the model).
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepView<'a> {
    pub f: &'a [f64],
    pub h: &'a [f64],
    pub q: &'a [f64],
    pub r: &'a [f64],
    pub b: Option<&'a [f64]>,
    pub d: Option<&'a [f64]>,
    pub n: Option<&'a [f64]>,
}

/// A validated linear Gaussian state-space model.
#[derive(Debug, Clone)]
pub struct LinearGaussian {
    mats: Matrices,
    n_states: usize,
    n_obs: usize,
    n_inputs: usize,
    steps: Option<usize>,
}

impl LinearGaussian {
    /// Validates the matrices: shapes agree, every entry is finite, `Q` and `R` are symmetric
    /// positive semidefinite, the joint covariance `[[Q, N], [N', R]]` is positive semidefinite,
    /// and all per-step stacks have the same number of steps.
    pub fn new(mut mats: Matrices) -> Result<Self> {
        let n = mats.f.rows;
        mats.f.expect_shape("F", n, n, "(F must be square)")?;
        let m = mats.h.rows;
        mats.h.expect_shape("H", m, n, "(H must have n = F's size columns)")?;
        if n == 0 {
            return Err(Error::arg("F", "is empty: the state needs at least one component (n ≥ 1)"));
        }
        if m == 0 {
            return Err(Error::arg("H", "has no rows: the output needs at least one component (m ≥ 1)"));
        }
        mats.q.expect_shape("Q", n, n, "(n × n, n = F's size)")?;
        mats.r.expect_shape("R", m, m, &format!("(m × m: H has {m} rows)"))?;
        let k = match (&mats.b, &mats.d) {
            (Some(b), _) => b.cols,
            (None, Some(d)) => d.cols,
            (None, None) => 0,
        };
        if k == 0 && (mats.b.is_some() || mats.d.is_some()) {
            return Err(Error::arg(if mats.b.is_some() { "B" } else { "D" }, "has no columns (k = 0 inputs)"));
        }
        if let Some(b) = &mats.b {
            b.expect_shape("B", n, k, "(n × k)")?;
        }
        if let Some(d) = &mats.d {
            d.expect_shape("D", m, k, &format!("(m × k: B has {k} columns)"))?;
        }
        if let Some(nn) = &mats.n {
            nn.expect_shape("N", n, m, "(n × m)")?;
        }
        let named = Self::named(&mats);
        let mut steps: Option<(&'static str, usize)> = None;
        for (arg, mat) in &named {
            if let Some(t) = mat.steps {
                match steps {
                    None => steps = Some((arg, t)),
                    Some((first, t0)) if t0 != t => {
                        return Err(Error::arg(
                            arg,
                            format!("has {t} steps but {first} has {t0}: per-step matrices must share T"),
                        ))
                    }
                    _ => {}
                }
            }
            mat.check_finite(arg)?;
        }
        mats.q.check_covariance("Q")?;
        mats.r.check_covariance("R")?;
        if let Some(nn) = &mats.n {
            check_joint_psd_steps(&mats.q, &mats.r, nn, steps.map(|s| s.1))?;
        }
        Ok(LinearGaussian { mats, n_states: n, n_obs: m, n_inputs: k, steps: steps.map(|s| s.1) })
    }

    fn named(mats: &Matrices) -> Vec<(&'static str, &StepMatrix)> {
        let mut v = vec![("F", &mats.f), ("H", &mats.h), ("Q", &mats.q), ("R", &mats.r)];
        for (arg, m) in [("B", &mats.b), ("D", &mats.d), ("N", &mats.n)] {
            if let Some(m) = m {
                v.push((arg, m));
            }
        }
        v
    }

    /// State dimension n.
    pub fn n_states(&self) -> usize {
        self.n_states
    }

    /// Output dimension m.
    pub fn n_obs(&self) -> usize {
        self.n_obs
    }

    /// Input dimension k (0 without B and D).
    pub fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    /// `Some(T)` when some matrix is given per step (then data must have T steps).
    pub fn steps(&self) -> Option<usize> {
        self.steps
    }

    /// The validated matrices.
    pub fn matrices(&self) -> &Matrices {
        &self.mats
    }

    /// Whether the model has a known input (B or D).
    pub fn has_input(&self) -> bool {
        self.n_inputs > 0
    }

    #[inline]
    pub(crate) fn at(&self, t: usize) -> StepView<'_> {
        let m = &self.mats;
        StepView {
            f: m.f.at(t),
            h: m.h.at(t),
            q: m.q.at(t),
            r: m.r.at(t),
            b: m.b.as_ref().map(|b| b.at(t)),
            d: m.d.as_ref().map(|d| d.at(t)),
            n: m.n.as_ref().map(|nn| nn.at(t)),
        }
    }
}

/// The joint covariance `[[Q, N], [N', R]]` of `(w, v)` must be positive semidefinite at every
/// step.
fn check_joint_psd_steps(q: &StepMatrix, r: &StepMatrix, nn: &StepMatrix, steps: Option<usize>) -> Result<()> {
    let (n, m) = (q.rows, r.rows);
    let indices: Vec<Option<usize>> = match steps {
        None => vec![None],
        Some(t) => (0..t).map(Some).collect(),
    };
    for t in indices {
        let s = t.unwrap_or(0);
        check_joint_psd(q.at(s), nn.at(s), r.at(s), n, m)
            .map_err(|p| Error::arg("N", format!("the joint noise covariance {p}")).at_step(t))?;
    }
    Ok(())
}
