//! Linear-quadratic regulators, u = −L x (Söderström ch. 11): the stationary one ([`lqr`],
//! (11.47)–(11.48)) and the finite-horizon one ([`lq_finite`], (11.6)–(11.7)).
//!
//! Both run on the filter's Riccati code by duality (Söderström (11.19)–(11.31)): the control
//! problem (F, G, Q1, Q2, Q12, Q0) is the filter problem (F', G', Q1, Q2, Q12, P0 = Q0) in
//! reversed time, with S(t) = P(t̄|t̄−1) and L(t) = K_pred(t̄)', t̄ = N − 1 − t. The stationary S is
//! the DARE of [`crate::solve_discrete_are`] with SciPy's (a, b, q, r, s) = (F, G, Q1, Q2, Q12);
//! the backward recursion is the compiled Kalman filter (Joseph form, fixed-size kernels for
//! small n) run over the horizon reversed.

use crate::core::alloc::check_f64_arrays;
use crate::core::validate::{check_joint_psd, check_psd, check_symmetric};
use crate::error::{Error, Result};
use crate::linear::filter::{filter_into, FilterOutputs, Series, UpdateForm};
use crate::linear::model::{LinearGaussian, Matrices, StepMatrix};
use crate::riccati::{solve_discrete_are, DareMethod, RiccatiProblem, RiccatiSolution};

/// The data of a stationary LQ problem, row-major: x(t+1) = F x + G u with the cost
/// Σ [x' Q1 x + 2 x' Q12 u + u' Q2 u] (Söderström (11.3)).
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub struct LqProblem<'a> {
    /// `F`, n × n.
    pub f: &'a [f64],
    /// `G`, n × k (kfast's `B`).
    pub g: &'a [f64],
    /// `Q1`, n × n.
    pub q1: &'a [f64],
    /// `Q2`, k × k.
    pub q2: &'a [f64],
    /// `Q12`, n × k, or zero.
    pub q12: Option<&'a [f64]>,
    /// The state size n.
    pub n: usize,
    /// The input size k.
    pub k: usize,
}

impl<'a> LqProblem<'a> {
    /// `(F, G, Q1, Q2)` for sizes n and k, without a cross weight.
    pub fn new(f: &'a [f64], g: &'a [f64], q1: &'a [f64], q2: &'a [f64], n: usize, k: usize) -> Self {
        LqProblem { f, g, q1, q2, q12: None, n, k }
    }

    /// The same problem with the cross weight `Q12`.
    pub fn with_cross(self, q12: &'a [f64]) -> Self {
        LqProblem { q12: Some(q12), ..self }
    }
}

/// The stationary regulator u = −L x.
#[derive(Debug, Clone)]
pub struct LqSolution {
    riccati: RiccatiSolution,
}

impl LqSolution {
    /// L (k × n) = (G' S G + Q2)⁻¹ (G' S F + Q12').
    pub fn gain(&self) -> &[f64] {
        &self.riccati.gain
    }

    /// The stabilizing S (n × n) of (11.47).
    pub fn s(&self) -> &[f64] {
        &self.riccati.x
    }

    /// F − G L (n × n), stable.
    pub fn closed_loop(&self) -> &[f64] {
        &self.riccati.closed_loop
    }

    /// The Riccati equation's relative residual.
    pub fn residual(&self) -> f64 {
        self.riccati.residual
    }

    /// Eigenvalues (re, im) of F − G L, computed on the first call.
    pub fn closed_loop_eigenvalues(&self) -> Result<&[(f64, f64)]> {
        self.riccati.closed_loop_eigenvalues()
    }
}

fn check_len(arg: &'static str, data: &[f64], rows: usize, cols: usize) -> Result<()> {
    if data.len() != rows * cols {
        return Err(Error::arg(arg, format!("expected {rows} × {cols} = {} entries, got {}", rows * cols, data.len())));
    }
    if let Some(v) = data.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg(arg, format!("contains a non-finite value ({v})")));
    }
    Ok(())
}

/// Q1 and Q2 symmetric, the joint weight [[Q1, Q12], [Q12', Q2]] positive semidefinite.
fn check_weights(q1: &[f64], q2: &[f64], q12: Option<&[f64]>, n: usize, k: usize, step: Option<usize>) -> Result<()> {
    let named = |arg: &'static str, problem: String| Error::arg(arg, problem).at_step(step);
    check_symmetric(q1, n).map_err(|p| named("Q1", p))?;
    check_symmetric(q2, k).map_err(|p| named("Q2", p))?;
    check_psd(q2, k).map_err(|p| named("Q2", p))?;
    match q12 {
        Some(q12) => check_joint_psd(q1, q12, q2, n, k)
            .map_err(|p| named("Q12", p.replace("[[Q, N], [N', R]]", "the joint weight [[Q1, Q12], [Q12', Q2]]"))),
        None => check_psd(q1, n).map_err(|p| named("Q1", p)),
    }
}

/// The stationary LQ regulator u = −L x (Söderström (11.47)–(11.48)): the stabilizing S of
/// S = F'SF + Q1 − (F'SG + Q12)(G'SG + Q2)⁻¹(G'SF + Q12') and L = (G'SG + Q2)⁻¹(G'SF + Q12'),
/// python-control's `dlqr`. The weights must form a positive semidefinite joint matrix;
/// [`Error::NoStabilizingSolution`] when (F, G) is not stabilizable or an unstable or
/// unit-circle mode is not seen by the weights.
pub fn lqr(problem: LqProblem<'_>, method: DareMethod) -> Result<LqSolution> {
    let LqProblem { f, g, q1, q2, q12, n, k } = problem;
    if n == 0 || k == 0 {
        return Err(Error::arg(if n == 0 { "F" } else { "G" }, "is empty (n ≥ 1 states and k ≥ 1 inputs needed)"));
    }
    check_len("F", f, n, n)?;
    check_len("G", g, n, k)?;
    check_len("Q1", q1, n, n)?;
    check_len("Q2", q2, k, k)?;
    if let Some(q12) = q12 {
        check_len("Q12", q12, n, k)?;
    }
    check_weights(q1, q2, q12, n, k, None)?;
    let mut riccati = RiccatiProblem::new(f, g, q1, q2, n, k);
    if let Some(q12) = q12 {
        riccati = riccati.with_s(q12);
    }
    match solve_discrete_are(riccati, method) {
        Ok(riccati) => Ok(LqSolution { riccati }),
        Err(Error::NoStabilizingSolution { problem }) => Err(Error::NoStabilizingSolution {
            problem: format!(
                "lqr: no stabilizing feedback: (F, G) is not stabilizable, or a mode on or outside the unit circle is not seen by Q1 ({problem})"
            ),
        }),
        Err(other) => Err(other.renamed("a", "F").renamed("b", "G").renamed("q", "Q1").renamed("r", "Q2").renamed("s", "Q12")),
    }
}

/// The data of a finite-horizon LQ problem: each matrix constant or given per step (a stack of
/// N, the matrix of step t acting from t to t + 1).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct LqSteps {
    /// `F`, n × n.
    pub f: StepMatrix,
    /// `G`, n × k.
    pub g: StepMatrix,
    /// `Q1`, n × n.
    pub q1: StepMatrix,
    /// `Q2`, k × k.
    pub q2: StepMatrix,
    /// `Q12`, n × k, or zero.
    pub q12: Option<StepMatrix>,
}

impl LqSteps {
    /// `(F, G, Q1, Q2)` without a cross weight.
    pub fn new(f: StepMatrix, g: StepMatrix, q1: StepMatrix, q2: StepMatrix) -> Self {
        LqSteps { f, g, q1, q2, q12: None }
    }

    /// The same data with the cross weight `Q12`.
    pub fn with_cross(self, q12: StepMatrix) -> Self {
        LqSteps { q12: Some(q12), ..self }
    }
}

/// The finite-horizon regulator u(t) = −L(t) x(t).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LqFinite {
    /// L(t) for t = 0..N−1, `(N, k, n)` row-major.
    pub gains: Vec<f64>,
    /// S(t) for t = 0..N, `(N + 1, n, n)`, S(N) = Q0: the cost to go from x(t) is x' S(t) x
    /// (plus the noise terms Σ tr S(s+1) Q(s)).
    pub s: Vec<f64>,
}

/// A stack's matrices in reversed time, each transposed when `transpose`: the dual problem's.
fn dual_matrix(arg: &'static str, m: &StepMatrix, transpose: bool, horizon: usize) -> Result<StepMatrix> {
    let (rows, cols) = if transpose { (m.cols(), m.rows()) } else { (m.rows(), m.cols()) };
    let at = |t: usize| -> Vec<f64> {
        let a = m.at(t);
        if !transpose {
            return a.to_vec();
        }
        let mut out = vec![0.0; a.len()];
        for i in 0..m.rows() {
            for j in 0..m.cols() {
                out[j * m.rows() + i] = a[i * m.cols() + j];
            }
        }
        out
    };
    match m.steps() {
        None => StepMatrix::constant(rows, cols, at(0)),
        Some(t) if t != horizon => {
            Err(Error::arg(arg, format!("a per-step stack must have N = {horizon} matrices, got {t}")))
        }
        Some(_) => StepMatrix::per_step(horizon, rows, cols, (0..horizon).rev().flat_map(at).collect()),
    }
}

fn check_shape(arg: &'static str, m: &StepMatrix, rows: usize, cols: usize) -> Result<()> {
    if m.rows() != rows || m.cols() != cols {
        return Err(Error::arg(arg, format!("expected shape ({rows}, {cols}), got ({}, {})", m.rows(), m.cols())));
    }
    Ok(())
}

/// The finite-horizon LQ regulator (Söderström (11.6)–(11.7)): S(N) = Q0,
/// L(t) = (G'S(t+1)G + Q2)⁻¹(G'S(t+1)F + Q12'), S(t) = F'S(t+1)F + Q1 − (F'S(t+1)G + Q12) L(t),
/// for t = N−1..0, computed by the Kalman filter on the dual problem in reversed time.
/// An S(t+1) that leaves G'S(t+1)G + Q2 singular is reported as `Q2 at step t`.
pub fn lq_finite(data: &LqSteps, q0: &[f64], horizon: usize) -> Result<LqFinite> {
    let (n, k) = (data.f.rows(), data.g.cols());
    if horizon == 0 {
        return Err(Error::arg("N", "the horizon must be at least 1"));
    }
    if n == 0 || k == 0 {
        return Err(Error::arg(if n == 0 { "F" } else { "G" }, "is empty (n ≥ 1 states and k ≥ 1 inputs needed)"));
    }
    check_shape("F", &data.f, n, n)?;
    check_shape("G", &data.g, n, k)?;
    check_shape("Q1", &data.q1, n, n)?;
    check_shape("Q2", &data.q2, k, k)?;
    if let Some(q12) = &data.q12 {
        check_shape("Q12", q12, n, k)?;
    }
    check_len("Q0", q0, n, n)?;
    check_symmetric(q0, n).map_err(|p| Error::arg("Q0", p))?;
    check_psd(q0, n).map_err(|p| Error::arg("Q0", p))?;
    let mut mats = Matrices::new(
        dual_matrix("F", &data.f, true, horizon)?,
        dual_matrix("G", &data.g, true, horizon)?,
        dual_matrix("Q1", &data.q1, false, horizon)?,
        dual_matrix("Q2", &data.q2, false, horizon)?,
    );
    if let Some(q12) = &data.q12 {
        mats.n = Some(dual_matrix("Q12", q12, false, horizon)?);
    }
    // The dual model's checks are the control problem's (finite entries, Q1 and Q2 symmetric
    // positive semidefinite, the joint weight positive semidefinite), under the dual names and
    // in reversed time: renamed back.
    let back = |err: Error| -> Error {
        let err = match err {
            Error::InvalidArgument { arg, step, problem } => Error::InvalidArgument {
                arg,
                step: step.map(|tau| horizon - 1 - tau),
                problem: problem.replace("[[Q, N], [N', R]]", "the joint weight [[Q1, Q12], [Q12', Q2]]"),
            },
            Error::InnovationCovariance { step, problem } => Error::arg_at(
                "Q2",
                horizon - 1 - step,
                format!("G' S(t+1) G + Q2 is not positive definite ({problem})"),
            ),
            other => other,
        };
        err.renamed("H", "G").renamed("Q", "Q1").renamed("R", "Q2").renamed("N", "Q12")
    };
    let dual = LinearGaussian::new(mats).map_err(back)?;
    // The outputs and the zero data: their sizes come from N.
    check_f64_arrays(
        "N",
        &[&[horizon + 1, n, n], &[horizon, n, n], &[horizon, n, k], &[horizon, k, n], &[horizon, k]],
    )?;
    let zeros = vec![0.0; horizon * k];
    let mut p_pred = vec![0.0; horizon * n * n];
    let mut k_pred = vec![0.0; horizon * n * k];
    let mut s = vec![0.0; (horizon + 1) * n * n];
    {
        let out = FilterOutputs {
            p_pred: Some(&mut p_pred),
            gain_pred: Some(&mut k_pred),
            p_next: Some(&mut s[..n * n]),
            ..FilterOutputs::default()
        };
        let y = Series::new("y", &zeros, horizon, k)?;
        filter_into(&dual, y, None, &vec![0.0; n], q0, UpdateForm::Joseph, out).map_err(back)?;
    }
    // S(N − τ) = P(τ|τ−1); L(t) = K_pred(N − 1 − t)'.
    for tau in 0..horizon {
        let t = horizon - tau;
        s[t * n * n..(t + 1) * n * n].copy_from_slice(&p_pred[tau * n * n..(tau + 1) * n * n]);
    }
    let mut gains = vec![0.0; horizon * k * n];
    for t in 0..horizon {
        let kp = &k_pred[(horizon - 1 - t) * n * k..][..n * k];
        let l = &mut gains[t * k * n..][..k * n];
        for i in 0..n {
            for j in 0..k {
                l[j * n + i] = kp[i * k + j];
            }
        }
    }
    Ok(LqFinite { gains, s })
}
