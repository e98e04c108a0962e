//! Algebraic Riccati equations with SciPy's conventions (docs/algorithms.md, "Riccati equations"), so that these are
//! drop-in replacements for `scipy.linalg.solve_discrete_are` / `solve_continuous_are`:
//!
//! ```text
//! DARE  a'Xa − e'Xe − (a'Xb + s)(b'Xb + r)⁻¹(b'Xa + s') + q = 0
//! CARE  a'Xe + e'Xa − (e'Xb + s) r⁻¹ (b'Xe + s') + q = 0
//! ```
//!
//! The Kalman filter's stationary P(t|t−1) is the DARE with a = F', b = H', q = Q, r = R,
//! s = N (Söderström (6.91)); its gain `K = (b'Xb + r)⁻¹(b'Xa + s')` is K_pred'.
//!
//! Every method returns the stabilizing solution (ρ(a − bK) < 1 relative to e, resp.
//! Re λ < 0) or [`Error::NoStabilizingSolution`]; the result carries the gain, the
//! closed-loop eigenvalues, the relative residual and the method that produced it. When the
//! DARE method asked for finds no stabilizing solution, the solver falls back to Newton–Hewer
//! from a stabilizing gain, then to the eigenvectors of the extended pencil, and raises only
//! when these find none either ([`solve_discrete_are`]). A nonsingular e is removed first
//! (a → a e⁻¹, q → e⁻ᵀ q e⁻¹, s → e⁻ᵀ s; X is unchanged), then, where r is invertible,
//! the cross term (a → a − b r⁻¹ s', q → q − s r⁻¹ s', Söderström Lemma 6.4).

use faer::linalg::solvers::Solve;
use std::sync::OnceLock;

use faer::{c64, Mat};

use crate::core::dense::{lu_in_place, lu_solve, mirror_upper, mul, mul_bt_sym, symmetrize, transpose};
use crate::core::dims::{Buf, Dims, Dyn, Fixed, Solver};
use crate::core::mat::{checked_mat, from_mat, to_mat};
use crate::error::{Error, Result};
use crate::riccati::lyapunov::{solve_continuous_lyapunov, solve_discrete_lyapunov};

/// How the DARE is solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum DareMethod {
    /// Structure-preserving doubling (ex. 6.24): quadratic convergence, no inverse of a.
    /// Needs r invertible; with a singular r it falls back to `Iteration` refined by `Newton`.
    /// A solution whose relative residual exceeds 1e-12 is refined by up to three Newton steps.
    #[default]
    Doubling,
    /// Newton–Hewer (ex. 6.23): one Lyapunov solve per step from a stabilizing gain (K = 0
    /// when a is stable, whatever s is; else the doubling solution's; with a singular r, the
    /// iteration's), quadratic convergence.
    Newton,
    /// Riccati iteration (6.90) in congruence form from X = I: linear convergence at about
    /// ρ(a − bK)² per step; needs only b'Xb + r invertible (singular r is fine).
    Iteration,
    /// Eigenvectors of the symplectic matrix (Söderström 6.8, (6.116)–(6.124)), refined by
    /// up to two Newton steps: needs r invertible; with a − b r⁻¹ s' singular, the
    /// eigenvectors of the extended pencil ((6.125)–(6.129)) instead.
    Eigen,
}

/// A solution of a Riccati equation and how good it is.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RiccatiSolution {
    /// X, `n × n` row-major, symmetric.
    pub x: Vec<f64>,
    /// The gain K (`m × n`): `(b'Xb + r)⁻¹(b'Xa + s')` (DARE), `r⁻¹(b'Xe + s')` (CARE).
    pub gain: Vec<f64>,
    /// The closed loop a − bK (with e: (a − bK) e⁻¹), `n × n` row-major: its spectral radius
    /// is below 1 (DARE), its eigenvalues are in the open left half-plane (CARE).
    pub closed_loop: Vec<f64>,
    /// ‖residual‖ / max(1, ‖X‖) in the max norm.
    pub residual: f64,
    /// Iterations of the method (0 for `Eigen`).
    pub iterations: usize,
    /// The method that produced X: "doubling", "newton", "iteration", "eigen" or "pencil"
    /// (the DARE's fallbacks can differ from the method asked for), "hamiltonian" (CARE).
    pub method: &'static str,
    /// The closed loop's eigenvalues once computed ([`RiccatiSolution::closed_loop_eigenvalues`]).
    eigenvalues: OnceLock<Vec<(f64, f64)>>,
}

impl RiccatiSolution {
    /// The solution X of the reduced problem `p` with its gain K (mapped back through e) and
    /// closed loop a − bK; eigenvalues not yet computed.
    fn of(
        p: &Problem,
        x: &Mat<f64>,
        k: Mat<f64>,
        acl: &Mat<f64>,
        residual: f64,
        iterations: usize,
        method: &'static str,
    ) -> Self {
        let gain = from_mat(&p.unreduce_gain(k));
        Self {
            x: from_mat(x),
            gain,
            closed_loop: from_mat(acl),
            residual,
            iterations,
            method,
            eigenvalues: OnceLock::new(),
        }
    }

    /// Eigenvalues (re, im) of [`closed_loop`](Self::closed_loop), computed on the first call
    /// (Francis QR, `core::schur`, O(n³)) unless the stabilizing check already needed them: for
    /// the DARE a Lyapunov inequality or a power of the closed loop with norm below 1/2
    /// usually shows it stable for less (docs/algorithms.md, "Stabilizing solution").
    pub fn closed_loop_eigenvalues(&self) -> Result<&[(f64, f64)]> {
        if let Some(ev) = self.eigenvalues.get() {
            return Ok(ev);
        }
        let n = self.closed_loop.len().isqrt();
        let ev = eigenvalues(&to_mat(&self.closed_loop, n))?;
        Ok(self.eigenvalues.get_or_init(|| ev))
    }
}

/// The Riccati data after removing e: (a, b, q, r, s) as faer matrices, with e kept to map
/// the gain back.
struct Problem {
    a: Mat<f64>,
    b: Mat<f64>,
    q: Mat<f64>,
    r: Mat<f64>,
    s: Mat<f64>,
    e: Option<Mat<f64>>,
}

impl Problem {
    /// Whether s is nonzero (the products with it are skipped otherwise).
    fn has_cross_term(&self) -> bool {
        self.s.norm_max() > 0.0
    }

    /// The gain of the reduced problem is K e⁻¹; map it back to K.
    fn unreduce_gain(&self, k: Mat<f64>) -> Mat<f64> {
        match &self.e {
            Some(e) => k * e,
            None => k,
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn checked_problem(
    a: &[f64],
    b: &[f64],
    q: &[f64],
    r: &[f64],
    e: Option<&[f64]>,
    s: Option<&[f64]>,
    n: usize,
    m: usize,
) -> Result<Problem> {
    let check = checked_mat;
    let (a, b, q, r) = (check("a", a, n, n)?, check("b", b, n, m)?, check("q", q, n, n)?, check("r", r, m, m)?);
    for (arg, mat, size) in [("q", &q, n), ("r", &r, m)] {
        crate::core::validate::check_symmetric(&from_mat(mat), size).map_err(|p| Error::arg(arg, p))?;
    }
    let s = match s {
        Some(s) => check("s", s, n, m)?,
        None => Mat::zeros(n, m),
    };
    let Some(e) = e else {
        return Ok(Problem { a, b, q: sym(&q), r: sym(&r), s, e: None });
    };
    let e = check("e", e, n, n)?;
    let e_inv = invert(&e).ok_or_else(|| Error::arg("e", "must be nonsingular"))?;
    let e_inv_t = e_inv.transpose().to_owned();
    Ok(Problem { a: &a * &e_inv, b, q: sym(&(&e_inv_t * &q * &e_inv)), r: sym(&r), s: &e_inv_t * &s, e: Some(e) })
}

fn sym(a: &Mat<f64>) -> Mat<f64> {
    (a + a.transpose()) * faer::Scale(0.5)
}

/// The inverse by LU with partial pivoting, or `None` if numerically singular.
fn invert(a: &Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    let inv = a.partial_piv_lu().solve(Mat::<f64>::identity(n, n));
    let residual = a * &inv - Mat::<f64>::identity(n, n);
    // (norm_max skips NaN, so check every entry)
    let ok = (0..n).all(|i| (0..n).all(|j| inv[(i, j)].is_finite() && residual[(i, j)].abs() < 1e-8));
    ok.then_some(inv)
}

/// Every entry finite (faer's norm_max skips NaN, so it cannot tell).
fn all_finite(m: &Mat<f64>) -> bool {
    (0..m.nrows()).all(|i| (0..m.ncols()).all(|j| m[(i, j)].is_finite()))
}

fn solve(a: &Mat<f64>, rhs: &Mat<f64>) -> Mat<f64> {
    a.partial_piv_lu().solve(rhs)
}

/// Converged: the relative change is at rounding level, or it stopped shrinking (a rounding
/// floor) once already small.
fn converged(change: f64, previous: f64, size: f64) -> bool {
    let rel = change / size.max(1e-300);
    rel <= 1e-14 || (rel <= 1e-12 && change >= previous)
}

fn no_solution(problem: impl Into<String>) -> Error {
    Error::NoStabilizingSolution { problem: problem.into() }
}

/// The matrices of an algebraic Riccati equation with SciPy's names, row-major: `a` (n × n),
/// `b` (n × m), `q` (n × n), `r` (m × m) and the optional `e` (n × n, identity when absent)
/// and `s` (n × m, zero when absent). The Kalman filter's DARE is `a = F'`, `b = H'`, `q = Q`,
/// `r = R`, `s = N` (docs/conventions.md).
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub struct RiccatiProblem<'a> {
    /// `a`, n × n.
    pub a: &'a [f64],
    /// `b`, n × m.
    pub b: &'a [f64],
    /// `q`, n × n, symmetric.
    pub q: &'a [f64],
    /// `r`, m × m, symmetric.
    pub r: &'a [f64],
    /// `e`, n × n (the descriptor form), or the identity.
    pub e: Option<&'a [f64]>,
    /// `s`, n × m (the cross term), or zero.
    pub s: Option<&'a [f64]>,
    /// The state size n.
    pub n: usize,
    /// The input size m.
    pub m: usize,
}

impl<'a> RiccatiProblem<'a> {
    /// `(a, b, q, r)` for sizes n and m, without `e` and `s`.
    pub fn new(a: &'a [f64], b: &'a [f64], q: &'a [f64], r: &'a [f64], n: usize, m: usize) -> Self {
        RiccatiProblem { a, b, q, r, e: None, s: None, n, m }
    }

    /// The same problem with `e`.
    pub fn with_e(self, e: &'a [f64]) -> Self {
        RiccatiProblem { e: Some(e), ..self }
    }

    /// The same problem with the cross term `s`.
    pub fn with_s(self, s: &'a [f64]) -> Self {
        RiccatiProblem { s: Some(s), ..self }
    }
}

/// Solves the DARE (SciPy's `solve_discrete_are(a, b, q, r, e, s)`):
/// `a'Xa − e'Xe − (a'Xb + s)(b'Xb + r)⁻¹(b'Xa + s') + q = 0`, with `method` first and the
/// fallbacks of docs/algorithms.md ("Stabilizing solution") when it finds no stabilizing X.
pub fn solve_discrete_are(problem: RiccatiProblem<'_>, method: DareMethod) -> Result<RiccatiSolution> {
    let RiccatiProblem { a, b, q, r, e, s, n, m } = problem;
    let p = checked_problem(a, b, q, r, e, s, n, m)?;
    let r_inv = invert(&p.r);
    match solve_dare_by(&p, r_inv.as_ref(), method) {
        // The method found no stabilizing solution or diverged. That does not mean there is
        // none: with s, doubling and the iteration from zero can settle on a non-stabilizing
        // fixed point (q − s r⁻¹ s' = 0 with an unstable a − b r⁻¹ s', issue 9), or diverge
        // when q − s r⁻¹ s' is indefinite. The fallbacks cost nothing when the method succeeds.
        Err(Error::NoStabilizingSolution { problem }) => dare_fallbacks(&p, problem),
        other => other,
    }
}

/// The DARE by the method asked for; the result is checked to be stabilizing.
fn solve_dare_by(p: &Problem, r_inv: Option<&Mat<f64>>, method: DareMethod) -> Result<RiccatiSolution> {
    let (n, m) = (p.a.nrows(), p.b.ncols());
    let (x, iterations, used) = match (method, r_inv) {
        (DareMethod::Doubling, Some(r_inv)) => {
            let (x, it) = doubling(p, r_inv)?;
            (x, it, "doubling")
        }
        (DareMethod::Doubling, None) | (DareMethod::Iteration, _) => {
            let (x0, it) = iteration(p)?;
            if method == DareMethod::Doubling {
                let (x, more) = newton(p, x0, 60)?;
                (x, it + more, "iteration")
            } else {
                (x0, it, "iteration")
            }
        }
        (DareMethod::Newton, _) => {
            let (x, it) = match r_inv {
                // K0 = 0 makes a − b K0 = a stable whatever s is (the gain of X0 = 0 is
                // r⁻¹ s', which need not be).
                Some(_) if shown_stable(&p.a) || spectral_radius(&p.a)? < 1.0 => {
                    newton_from_gain(p, Mat::zeros(m, n), 60)?
                }
                Some(r_inv) => newton(p, doubling(p, r_inv)?.0, 60)?,
                // Hewer's guarantee of stabilizing gains needs r > 0: start from the iteration.
                None => newton(p, iteration(p)?.0, 60)?,
            };
            (x, it, "newton")
        }
        // Eigenvectors lose digits when they are ill-conditioned: one or two Newton steps
        // restore them (Söderström ex. 6.23; docs/algorithms.md, "Newton–Hewer").
        (DareMethod::Eigen, Some(r_inv)) => {
            let (x0, used) = eigen(p, r_inv)?;
            let (x, it) = newton(p, x0, 2)?;
            (x, it, used)
        }
        (DareMethod::Eigen, None) => {
            return Err(Error::arg("r", "must be invertible for method \"eigen\" (use \"doubling\" or \"iteration\")"))
        }
    };
    let solution = finish_dare(p, sym(&x), iterations, used)?;
    // The iteration and Newton are not the fast default: they are always polished.
    if solution.residual == 0.0
        || (method != DareMethod::Iteration && method != DareMethod::Newton && solution.residual <= REFINE_ABOVE)
    {
        return Ok(solution);
    }
    // Doubling loses digits on ill-conditioned problems (e.g. r = 1e-6 with a singular a:
    // relative residual 1e-3), the iteration stops at its convergence test and Newton at a
    // Lyapunov solve's accuracy: Newton steps in correction form from the stabilizing
    // solution restore them (the better of the two is kept).
    let refined = polish(p, &to_mat(&solution.x, n), POLISH_STEPS)
        .and_then(|x| finish_dare(p, sym(&x), solution.iterations + POLISH_STEPS, used));
    Ok(match refined {
        Ok(better) if better.residual < solution.residual => better,
        _ => solution,
    })
}

/// When the method asked for found no stabilizing solution: Newton–Hewer from a stabilizing
/// gain (ex. 6.23), then the eigenvectors of the extended pencil refined by Newton steps. The
/// first answer with a residual at rounding level wins, else the stabilizing one with the
/// smaller residual; [`Error::NoStabilizingSolution`] (with the method's own reason) when
/// neither finds a stabilizing solution.
///
/// A fallback's answer must also have converged and keep its closed loop clear of the unit
/// circle by [`FALLBACK_MARGIN`]: when there is no stabilizing solution, Newton–Hewer still
/// converges (linearly) towards the maximal solution, whose closed loop has an eigenvalue on
/// the circle, and stops within rounding of it.
#[cold]
fn dare_fallbacks(p: &Problem, first_problem: String) -> Result<RiccatiSolution> {
    let newton_limit = 60;
    let by_newton = stabilizing_gain(p)
        .and_then(|k0| newton_from_gain(p, k0, newton_limit))
        .and_then(|(x, it)| finish_dare(p, sym(&x), it, "newton"))
        .and_then(|sol| clear_of_unit_circle(sol, newton_limit));
    if matches!(&by_newton, Ok(sol) if sol.residual <= REFINE_ABOVE) {
        return by_newton;
    }
    let refine_limit = 10;
    let by_pencil = pencil(p)
        .and_then(|x| newton(p, x, refine_limit))
        .and_then(|(x, it)| finish_dare(p, sym(&x), it, "pencil"))
        .and_then(|sol| clear_of_unit_circle(sol, refine_limit));
    match (by_newton, by_pencil) {
        (Ok(by_newton), Ok(by_pencil)) => {
            Ok(if by_pencil.residual < by_newton.residual { by_pencil } else { by_newton })
        }
        (Ok(sol), Err(_)) | (Err(_), Ok(sol)) => Ok(sol),
        (Err(_), Err(_)) => Err(no_solution(format!(
            "{first_problem}; neither Newton–Hewer from a stabilizing gain nor the extended pencil found one"
        ))),
    }
}

/// How far inside the unit circle a fallback's closed loop must stay. A spectral density
/// with a double zero on the circle perturbed by δ moves the closed-loop eigenvalues by about
/// √δ, so with rounding errors (δ ≈ 1e-16) closed-loop radii above 1 − 1e-8 cannot tell a
/// stabilizing solution from the maximal, non-stabilizing one.
const FALLBACK_MARGIN: f64 = 1e-8;

/// `sol` unless its Newton iteration hit `limit` without converging or its closed loop is
/// within [`FALLBACK_MARGIN`] of the unit circle.
fn clear_of_unit_circle(sol: RiccatiSolution, limit: usize) -> Result<RiccatiSolution> {
    let rho = radius(sol.closed_loop_eigenvalues()?);
    if sol.iterations >= limit || rho >= 1.0 - FALLBACK_MARGIN {
        return Err(no_solution(format!(
            "{} approached a solution with closed-loop spectral radius {rho:.10} (unit-circle modes)",
            sol.method
        )));
    }
    Ok(sol)
}

/// The problem (a, b, q = I, r = I, s = 0), whose stabilizing solution's gain stabilizes a − bK
/// whenever (a, b) is stabilizable (q = I makes every mode detectable).
fn auxiliary_problem(p: &Problem) -> Problem {
    let (n, m) = (p.a.nrows(), p.b.ncols());
    Problem {
        a: p.a.clone(),
        b: p.b.clone(),
        q: Mat::identity(n, n),
        r: Mat::identity(m, m),
        s: Mat::zeros(n, m),
        e: None,
    }
}

/// A gain K with ρ(a − bK) < 1: K = 0 when a is stable; else the gain of the stabilizing
/// solution of the auxiliary DARE ([`auxiliary_problem`]), which doubling finds from zero.
fn stabilizing_gain(p: &Problem) -> Result<Mat<f64>> {
    let (n, m) = (p.a.nrows(), p.b.ncols());
    if shown_stable(&p.a) || spectral_radius(&p.a)? < 1.0 {
        return Ok(Mat::zeros(m, n));
    }
    let identity_m = Mat::<f64>::identity(m, m);
    let auxiliary = auxiliary_problem(p);
    let (x, _) = doubling(&auxiliary, &identity_m)?;
    let k = dare_gain(&auxiliary, &x).ok_or_else(|| no_solution("no stabilizing gain: b'Xb + r is singular"))?;
    let acl = &p.a - &p.b * &k;
    if !shown_stable(&acl) && spectral_radius(&acl)? >= 1.0 {
        return Err(no_solution("(a, b) is not stabilizable: no gain makes a − bK stable"));
    }
    Ok(k)
}

/// Relative residual above which a doubling solution is refined by Newton steps.
const REFINE_ABOVE: f64 = 1e-12;

/// K = (b'Xb + r)⁻¹(b'Xa + s') for the reduced problem.
fn dare_gain(p: &Problem, x: &Mat<f64>) -> Option<Mat<f64>> {
    let btx = p.b.transpose() * x;
    let sk = &btx * &p.b + &p.r;
    let mut rhs = &btx * &p.a;
    if p.has_cross_term() {
        rhs += p.s.transpose();
    }
    let k = solve(&sk, &rhs);
    all_finite(&k).then_some(k)
}

/// (a − bK)' X (a − bK) + q − sK − K's' + K'rK: one Riccati step in congruence form, from
/// `decay` = (a − bK)' X (a − bK) ([`congruence`]).
fn riccati_step(p: &Problem, decay: &Mat<f64>, k: &Mat<f64>) -> Mat<f64> {
    let mut step = decay + &p.q + k.transpose() * &p.r * k;
    if p.has_cross_term() {
        let sk = &p.s * k;
        step -= &sk + sk.transpose();
    }
    sym(&step)
}

/// M' X M.
fn congruence(x: &Mat<f64>, m: &Mat<f64>) -> Mat<f64> {
    m.transpose() * (x * m)
}

/// Structure-preserving doubling on the problem with s removed (ex. 6.24; docs/algorithms.md, "Doubling"):
/// A ← A W⁻¹A, G ← G + A W⁻¹G A', H ← H + A'H W⁻¹A with W = I + G H, until H (→ X) settles.
/// The loop runs on row-major buffers with the small dense kernels and one LU of W per step
/// (at n = 4 a faer call costs more than its arithmetic; from 8³ multiply-adds the products
/// still go to faer's matmul).
fn doubling(p: &Problem, r_inv: &Mat<f64>) -> Result<(Mat<f64>, usize)> {
    let n = p.a.nrows();
    let g0 = sym(&(&p.b * r_inv * p.b.transpose()));
    let (a0, h0) = if p.has_cross_term() {
        let rs = r_inv * p.s.transpose();
        (&p.a - &p.b * &rs, sym(&(&p.q - &p.s * &rs)))
    } else {
        (p.a.clone(), p.q.clone())
    };
    let start = Start { step: 1, previous: f64::INFINITY };
    if n > FAER_TRIANGLE_ABOVE && 2 * p.b.ncols() <= n {
        if let Some((next, previous)) = low_rank_first_step(&a0, &p.b, &p.r, &g0, &h0) {
            let (a1, g1, h1) = (from_mat(&next.a), from_mat(&next.g), from_mat(&next.h));
            let (x, it) = doubling_loop(Dyn { n, m: 1 }, &a1, &g1, &h1, Start { step: 2, previous })?;
            return Ok((to_mat(&x, n), it));
        }
    }
    let (a0, g0, h0) = (from_mat(&a0), from_mat(&g0), from_mat(&h0));
    // Compile-time sizes for small n, so that the loops unroll and the iterates stay local.
    let (x, it) = match n {
        1 => doubling_loop(Fixed::<1, 1>, &a0, &g0, &h0, start),
        2 => doubling_loop(Fixed::<2, 1>, &a0, &g0, &h0, start),
        3 => doubling_loop(Fixed::<3, 1>, &a0, &g0, &h0, start),
        4 => doubling_loop(Fixed::<4, 1>, &a0, &g0, &h0, start),
        6 => doubling_loop(Fixed::<6, 1>, &a0, &g0, &h0, start),
        8 => doubling_loop(Fixed::<8, 1>, &a0, &g0, &h0, start),
        _ => doubling_loop(Dyn { n, m: 1 }, &a0, &g0, &h0, start),
    }?;
    Ok((to_mat(&x, n), it))
}

/// The first doubling step through the rank of G₀ = b r⁻¹ b' (m ≤ n/2): by Woodbury,
/// W₀⁻¹ = (I + G₀H₀)⁻¹ = I − b S⁻¹ b'H₀ with S = r + b'H₀b (m × m), so W₀⁻¹A₀ = A₀ − bK₀
/// with K₀ = S⁻¹ b'H₀A₀ (the closed loop of X = H₀) and W₀⁻¹G₀ = b S⁻¹ b'. No n × n LU or
/// solve: about 5¾ n³ multiply-adds at m = n/2 instead of the general step's 7⅚ n³, whose two
/// solves also run at half the speed of a product. Returns A₁, G₁, H₁ and the relative change
/// of H, or None when S is singular (the general step then runs instead).
fn low_rank_first_step(
    a0: &Mat<f64>,
    b: &Mat<f64>,
    r: &Mat<f64>,
    g0: &Mat<f64>,
    h0: &Mat<f64>,
) -> Option<(Iterates, f64)> {
    let n = a0.nrows();
    let bt_h = b.transpose() * h0;
    let s = sym(&(&bt_h * b + r));
    let lu = s.partial_piv_lu();
    let k0 = lu.solve(&bt_h * a0);
    let ab = a0 * b;
    let sab = lu.solve(ab.transpose());
    if !all_finite(&k0) || !all_finite(&sab) {
        return None;
    }
    let closed_loop = a0 - b * &k0;
    // H₁ = H₀ + A₀'H₀ W₀⁻¹A₀, in full and symmetrized (as in the loop, for its rounding).
    let h1 = sym(&(h0 + a0.transpose() * (h0 * &closed_loop)));
    // G₁ = G₀ + (A₀b) S⁻¹ (A₀b)': one triangle of the symmetric product.
    let mut g1 = vec![0.0; n * n];
    upper_triangle_product(&mut g1, ab.as_ref(), sab.as_ref());
    let g1 = g0 + to_mat(&g1, n);
    let a1 = a0 * &closed_loop;
    let previous = (&h1 - h0).norm_max() / h1.norm_max().max(1e-300);
    all_finite(&h1).then_some((Iterates { a: a1, g: g1, h: h1 }, previous))
}

/// A, G, H of one doubling step.
struct Iterates {
    a: Mat<f64>,
    g: Mat<f64>,
    h: Mat<f64>,
}

/// Where [`doubling_loop`] starts: the number of its first step and the relative change of H
/// in the step before it (infinite for the first).
#[derive(Clone, Copy)]
struct Start {
    step: usize,
    previous: f64,
}

/// The doubling iteration from row-major A, G, H; returns H at convergence (= X).
///
/// Each step factors W = I + G H once and updates H first, from V₁ = W⁻¹A: when H has
/// settled the step ends there, without the solve for V₂ = W⁻¹G and the products for the next
/// A and G.
fn doubling_loop<D: Dims>(d: D, a0: &[f64], g0: &[f64], h0: &[f64], start: Start) -> Result<(Vec<f64>, usize)> {
    let n = d.n();
    let (mut ak, mut gk, mut hk) = (d.square(), d.square(), d.square());
    ak.get_mut().copy_from_slice(a0);
    gk.get_mut().copy_from_slice(g0);
    hk.get_mut().copy_from_slice(h0);
    let (mut w, mut v1, mut v2) = (d.square(), d.square(), d.square());
    let (mut at, mut tmp, mut next) = (d.square(), d.square(), d.square());
    let mut piv = vec![0; n];
    let mut previous = start.previous;
    for it in start.step..=100 {
        let (a, g, h) = (ak.get_mut(), gk.get_mut(), hk.get_mut());
        let (w, v1, v2) = (w.get_mut(), v1.get_mut(), v2.get_mut());
        let (at, tmp, next) = (at.get_mut(), tmp.get_mut(), next.get_mut());
        mul::<Solver>(w, g, h, n, n, n);
        for i in 0..n {
            w[i * n + i] += 1.0;
        }
        let lu = Lu::factor(w, &mut piv, n);
        // H + A' H V₁, symmetric (H W⁻¹ = (I + H G)⁻¹H is), in full and then symmetrized: the
        // two triangles average out rounding that one alone keeps (on the ill-conditioned
        // problems of the tests, r = 1e-6, one triangle left residuals up to 40× larger).
        v1.copy_from_slice(a);
        lu.solve(v1, n);
        mul::<Solver>(tmp, h, v1, n, n, n);
        product_at_b(next, a, tmp, at, n);
        symmetrize(next, n);
        let (mut change, mut size, mut finite) = (0.0f64, 0.0f64, true);
        for (hi, di) in h.iter_mut().zip(next.iter()) {
            *hi += di;
            change = change.max(di.abs());
            size = size.max(hi.abs());
            finite &= hi.is_finite();
        }
        if !finite {
            return Err(no_solution("the doubling iteration diverged (is (a, b) stabilizable?)"));
        }
        let rel = change / size.max(1e-300);
        if doubling_converged(rel, previous) {
            return Ok((h.to_vec(), it));
        }
        previous = rel;
        // G + A V₂ A', then A V₁. V₂ = W⁻¹G = (I + G H)⁻¹G is symmetric: symmetrized, it
        // makes A V₂ A' symmetric up to the product's own rounding, so one triangle is enough.
        v2.copy_from_slice(g);
        lu.solve(v2, n);
        symmetrize(v2, n);
        mul::<Solver>(tmp, a, v2, n, n, n);
        symmetric_a_bt(next, tmp, a, n);
        for (gi, di) in g.iter_mut().zip(next.iter()) {
            *gi += di;
        }
        mul::<Solver>(next, a, v1, n, n, n);
        a.copy_from_slice(next);
    }
    Err(no_solution("the doubling iteration did not converge in 100 steps (eigenvalues on the unit circle?)"))
}

/// Whether the doubling has converged, from the relative changes of H in this step (`rel`)
/// and in the one before (`previous`): the rules of [`converged`], and one more. Doubling
/// converges quadratically, r₊ ≈ r²/c with c ≈ r₋²/r (r₋ = `previous`), so once the changes
/// fall that fast (r ≤ r₋^1.5, r₋ ≤ 1e-2) the next one is about r³/r₋²; when that is below
/// 1e-16, H is as good as the next step would make it and the step that would only confirm it
/// is skipped. A wrong prediction shows in the residual, which [`solve_dare_by`] refines by
/// Newton steps above 1e-12.
fn doubling_converged(rel: f64, previous: f64) -> bool {
    let quadratic = previous <= 1e-2 && rel <= 1e-6 && rel <= previous.powf(1.5);
    converged(rel, previous, 1.0) || (quadratic && rel * rel * rel <= 1e-16 * previous * previous)
}

/// W = I + G H factored once for both solves of a doubling step: the small kernels up to
/// n = 8, faer's blocked LU beyond (measured: at n = 20 and 100 the plain loops are 1.5× and
/// 3.6× slower than faer).
enum Lu<'a> {
    Small { lu: &'a [f64], piv: &'a [usize] },
    Faer(faer::linalg::solvers::PartialPivLu<f64>),
}

impl<'a> Lu<'a> {
    fn factor(w: &'a mut [f64], piv: &'a mut [usize], n: usize) -> Self {
        if n <= 8 {
            lu_in_place(w, piv, n);
            return Lu::Small { lu: w, piv };
        }
        Lu::Faer(faer::MatRef::from_row_major_slice(w, n, n).partial_piv_lu())
    }

    /// Solves `W X = V` in place for `v` (n × n).
    fn solve(&self, v: &mut [f64], n: usize) {
        match self {
            Lu::Small { lu, piv } => lu_solve(lu, piv, v, n, n),
            Lu::Faer(lu) => lu.solve_in_place(faer::MatMut::from_row_major_slice_mut(v, n, n)),
        }
    }
}

/// Above this n the doubling's products go to faer directly: A V₂ A' as faer's triangular
/// product (half the multiply-adds of a full one), A'(H V₁) from a transposed view; up to it
/// the small kernels compute them (one triangle of A V₂ A').
const FAER_TRIANGLE_ABOVE: usize = 12;

/// `c[n×n] = a' · b`; `at` is scratch for a' (faer takes the transposed view as it is).
fn product_at_b(c: &mut [f64], a: &[f64], b: &[f64], at: &mut [f64], n: usize) {
    if n > FAER_TRIANGLE_ABOVE {
        let a = faer::MatRef::from_row_major_slice(a, n, n).transpose();
        let c = faer::MatMut::from_row_major_slice_mut(c, n, n);
        let b = faer::MatRef::from_row_major_slice(b, n, n);
        return faer::linalg::matmul::matmul(c, faer::Accum::Replace, a, b, 1.0, faer::Par::Seq);
    }
    transpose(at, a, n, n);
    mul::<Solver>(c, at, b, n, n, n);
}

/// `c[n×n] = a · b'` for a product known to be symmetric.
fn symmetric_a_bt(c: &mut [f64], a: &[f64], b: &[f64], n: usize) {
    if n > FAER_TRIANGLE_ABOVE {
        let b = faer::MatRef::from_row_major_slice(b, n, n).transpose();
        return upper_triangle_product(c, faer::MatRef::from_row_major_slice(a, n, n), b);
    }
    mul_bt_sym::<Solver>(c, a, b, n, n);
}

/// `c = a · b` (row-major n × n) from its upper triangle, mirrored onto the lower one.
fn upper_triangle_product(c: &mut [f64], a: faer::MatRef<'_, f64>, b: faer::MatRef<'_, f64>) {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    let n = a.nrows();
    let dst = faer::MatMut::from_row_major_slice_mut(c, n, n);
    let full = BlockStructure::Rectangular;
    matmul(dst, BlockStructure::TriangularUpper, faer::Accum::Replace, a, full, b, full, 1.0, faer::Par::Seq);
    mirror_upper(c, n);
}

/// Riccati iteration (6.90) from X = max(1, ‖q‖) I (docs/algorithms.md, "Riccati iteration").
fn iteration(p: &Problem) -> Result<(Mat<f64>, usize)> {
    let n = p.a.nrows();
    let mut x = Mat::<f64>::identity(n, n) * faer::Scale(p.q.norm_max().max(1.0));
    let mut previous = f64::INFINITY;
    for it in 1..=200_000 {
        let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r became singular in the Riccati iteration"))?;
        let next = riccati_step(p, &congruence(&x, &(&p.a - &p.b * &k)), &k);
        let change = (&next - &x).norm_max();
        let size = next.norm_max();
        if !all_finite(&next) {
            return Err(no_solution("the Riccati iteration diverged (is (a, b) stabilizable?)"));
        }
        x = next;
        if converged(change, previous, size) {
            return Ok((x, it));
        }
        previous = change;
    }
    Err(no_solution("the Riccati iteration did not converge (eigenvalues on or near the unit circle?)"))
}

/// Newton–Hewer from X0 (whose gain must be stabilizing): X_{k+1} solves
/// X = A_k' X A_k + [I, −K_k] J [I, −K_k]' with A_k = a − b K_k (ex. 6.23).
fn newton(p: &Problem, x0: Mat<f64>, max_iter: usize) -> Result<(Mat<f64>, usize)> {
    let mut x = x0;
    let mut previous = f64::INFINITY;
    for it in 1..=max_iter {
        let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r is singular at a Newton step"))?;
        let next = newton_step(p, &k)?;
        let change = (&next - &x).norm_max();
        x = next;
        if converged(change, previous, x.norm_max()) {
            return Ok((x, it));
        }
        previous = change;
    }
    Ok((x, max_iter))
}

/// One Newton–Hewer step for the gain K: the X of X = (a − bK)' X (a − bK) + q − sK − K's' +
/// K'rK, the cost of the closed loop a − bK (ex. 6.23).
fn newton_step(p: &Problem, k: &Mat<f64>) -> Result<Mat<f64>> {
    let n = p.a.nrows();
    let acl = &p.a - &p.b * k;
    let sk = &p.s * k;
    let c = sym(&(&p.q - &sk - sk.transpose() + k.transpose() * &p.r * k));
    let next = solve_discrete_lyapunov(&from_mat(&acl.transpose().to_owned()), &from_mat(&c), n)
        .map_err(|_| no_solution("a Newton step met a closed loop with eigenvalues λ_i λ_j = 1"))?;
    Ok(sym(&to_mat(&next, n)))
}

/// Newton steps of [`polish`] at most (it stops once the correction is at rounding level).
const POLISH_STEPS: usize = 4;

/// Newton–Hewer steps in correction form: X ← X + Δ with Δ solving A_c' Δ A_c − Δ + R(X) = 0,
/// R(X) the Riccati residual and A_c = a − b K(X). The same step as [`newton_step`], but the
/// Lyapunov solve's rounding is relative to the small Δ instead of to X, so the residual
/// reaches rounding level (SciPy's benchmark tolerances).
fn polish(p: &Problem, x: &Mat<f64>, steps: usize) -> Result<Mat<f64>> {
    let n = p.a.nrows();
    let mut x = x.clone();
    for _ in 0..steps {
        let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r is singular at a Newton step"))?;
        let acl = &p.a - &p.b * &k;
        let residual = riccati_step(p, &congruence(&x, &acl), &k) - &x;
        let delta = solve_discrete_lyapunov(&from_mat(&acl.transpose().to_owned()), &from_mat(&sym(&residual)), n)
            .map_err(|_| no_solution("a Newton step met a closed loop with eigenvalues λ_i λ_j = 1"))?;
        let delta = to_mat(&delta, n);
        x = sym(&(&x + &delta));
        if delta.norm_max() <= 8.0 * f64::EPSILON * x.norm_max() {
            break;
        }
    }
    Ok(x)
}

/// Newton–Hewer started from a gain K0 with a − b K0 stable instead of from an X0: the first
/// step is the cost of K0, after which every gain stays stabilizing (ex. 6.23).
fn newton_from_gain(p: &Problem, k0: Mat<f64>, max_iter: usize) -> Result<(Mat<f64>, usize)> {
    let x1 = newton_step(p, &k0)?;
    let (x, it) = newton(p, x1, max_iter.saturating_sub(1).max(1))?;
    Ok((x, it + 1))
}

/// Stable invariant subspace of the symplectic matrix, control form (docs/algorithms.md,
/// "Eigenvector method"); when a − b r⁻¹ s' is singular, that of the extended pencil instead
/// ([`pencil`]). Returns X and which of the two produced it.
fn eigen(p: &Problem, r_inv: &Mat<f64>) -> Result<(Mat<f64>, &'static str)> {
    let n = p.a.nrows();
    let rs = r_inv * p.s.transpose();
    let a0 = &p.a - &p.b * &rs;
    let g = &p.b * r_inv * p.b.transpose();
    let q0 = &p.q - &p.s * &rs;
    let Some(a_inv) = invert(&a0) else {
        return Ok((pencil(p)?, "pencil"));
    };
    let a_inv_t = a_inv.transpose().to_owned();
    let mut z = Mat::<f64>::zeros(2 * n, 2 * n);
    let top_left = &a0 + &g * &a_inv_t * &q0;
    let top_right = -(&g * &a_inv_t);
    let bottom_left = -(&a_inv_t * &q0);
    for i in 0..n {
        for j in 0..n {
            z[(i, j)] = top_left[(i, j)];
            z[(i, n + j)] = top_right[(i, j)];
            z[(n + i, j)] = bottom_left[(i, j)];
            z[(n + i, n + j)] = a_inv_t[(i, j)];
        }
    }
    Ok((stable_subspace(&z, n, |l| l.norm() < 1.0, "inside the unit circle")?, "eigen"))
}

/// The stabilizing X from the generalized eigenvectors of the extended pencil λ L − M of size
/// 2n + m (Söderström (6.125)–(6.129) and the remark after them, here in control form), which
/// needs neither r nor a − b r⁻¹ s' invertible:
///
/// ```text
/// M = [[a, 0, b], [−q, I, −s], [s', 0, r]],      L = [[I, 0, 0], [0, a', 0], [0, −b', 0]]
/// ```
///
/// For the stabilizing X with gain K and (a − bK) v = λ v, the vector [v; X v; −K v] solves
/// M w = λ L w: the first block row is the closed loop, the third is (b'Xb + r) K = b'Xa + s'
/// and the second is the DARE. So the n eigenvalues inside the unit circle are the closed-loop
/// ones and X = U2 U1⁻¹ from their eigenvectors; the other n + m are their reciprocals or
/// infinite. Eigenvectors of a defective eigenvalue lose digits; the caller refines by Newton.
fn pencil(p: &Problem) -> Result<Mat<f64>> {
    let (n, m) = (p.a.nrows(), p.b.ncols());
    let size = 2 * n + m;
    let mut big_m = Mat::<f64>::zeros(size, size);
    let mut big_l = Mat::<f64>::zeros(size, size);
    for i in 0..n {
        for j in 0..n {
            big_m[(i, j)] = p.a[(i, j)];
            big_m[(n + i, j)] = -p.q[(i, j)];
            big_l[(n + i, n + j)] = p.a[(j, i)];
        }
        big_m[(n + i, n + i)] = 1.0;
        big_l[(i, i)] = 1.0;
        for j in 0..m {
            big_m[(i, 2 * n + j)] = p.b[(i, j)];
            big_m[(n + i, 2 * n + j)] = -p.s[(i, j)];
            big_m[(2 * n + j, i)] = p.s[(i, j)];
            big_l[(2 * n + j, n + i)] = -p.b[(i, j)];
        }
    }
    for i in 0..m {
        for j in 0..m {
            big_m[(2 * n + i, 2 * n + j)] = p.r[(i, j)];
        }
    }
    let gevd = big_m.generalized_eigen(&big_l).map_err(|_| no_solution("the pencil's QZ did not converge"))?;
    let (u, alpha, beta) = (gevd.U(), gevd.S_a().column_vector(), gevd.S_b().column_vector());
    // λ = α/β inside the unit circle (β = 0: infinite).
    let chosen: Vec<usize> = (0..size).filter(|&i| alpha[i].norm() < beta[i].norm()).collect();
    if chosen.len() != n {
        return Err(no_solution(format!(
            "{} of the pencil's {size} eigenvalues are inside the unit circle, not {n}: eigenvalues on the circle",
            chosen.len()
        )));
    }
    // X U1 = U2  ⇔  U1' X' = U2'
    let u1t = Mat::<c64>::from_fn(n, n, |i, j| u[(j, chosen[i])]);
    let u2t = Mat::<c64>::from_fn(n, n, |i, j| u[(n + j, chosen[i])]);
    let xt = u1t.partial_piv_lu().solve(&u2t);
    let x = Mat::<f64>::from_fn(n, n, |i, j| xt[(j, i)].re);
    if !all_finite(&x) {
        return Err(no_solution("the pencil's stable eigenvectors have a singular top block"));
    }
    Ok(sym(&x))
}

/// X = Re(U2 U1⁻¹) from the eigenvectors of `z` (2n × 2n) whose eigenvalues pass `stable`.
fn stable_subspace(z: &Mat<f64>, n: usize, stable: impl Fn(c64) -> bool, region: &str) -> Result<Mat<f64>> {
    let evd = z.eigen().map_err(|_| no_solution("the eigendecomposition did not converge"))?;
    let (u, s) = (evd.U(), evd.S().column_vector());
    let chosen: Vec<usize> = (0..2 * n).filter(|&i| stable(s[i])).collect();
    if chosen.len() != n {
        return Err(no_solution(format!(
            "{} of the {} eigenvalues are {region}, not {n}: eigenvalues on the boundary",
            chosen.len(),
            2 * n
        )));
    }
    // X U1 = U2  ⇔  U1' X' = U2'
    let u1t = Mat::<c64>::from_fn(n, n, |i, j| u[(j, chosen[i])]);
    let u2t = Mat::<c64>::from_fn(n, n, |i, j| u[(n + j, chosen[i])]);
    let xt = u1t.partial_piv_lu().solve(&u2t);
    let x = Mat::<f64>::from_fn(n, n, |i, j| xt[(j, i)].re);
    if !all_finite(&x) {
        return Err(no_solution("the stable eigenvectors have a singular top block"));
    }
    Ok(x)
}

/// Eigenvalues (re, im) of a row-major n × n matrix (faer's Hessenberg QR), for the bindings.
#[cfg(feature = "python")]
pub(crate) fn eigenvalues_of(a: &[f64], n: usize) -> Result<Vec<(f64, f64)>> {
    eigenvalues(&to_mat(a, n))
}

fn eigenvalues(a: &Mat<f64>) -> Result<Vec<(f64, f64)>> {
    crate::core::schur::eigenvalues(a).map_err(|_| no_solution("closed-loop eigenvalues did not converge"))
}

/// The largest modulus of `eigenvalues` (NaN if one is NaN).
fn radius(eigenvalues: &[(f64, f64)]) -> f64 {
    eigenvalues.iter().map(|(re, im)| re.hypot(*im)).fold(0.0, |r, v| if v.is_nan() { v } else { r.max(v) })
}

fn spectral_radius(a: &Mat<f64>) -> Result<f64> {
    Ok(radius(&eigenvalues(a)?))
}

/// Post-checks (docs/algorithms.md, "Stabilizing solution"): gain, closed loop (must be stable:
/// [`lyapunov_shows_stable`] from the residual's own product, else [`shown_stable`], else by
/// its eigenvalues), relative residual; the gain is mapped back through e.
fn finish_dare(p: &Problem, x: Mat<f64>, iterations: usize, method: &'static str) -> Result<RiccatiSolution> {
    let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r is singular at the solution"))?;
    let acl = &p.a - &p.b * &k;
    let decay = congruence(&x, &acl);
    let mut eigenvalues = OnceLock::new();
    if !lyapunov_shows_stable(&x, &decay, &acl) && !shown_stable(&acl) {
        let ev = self::eigenvalues(&acl)?;
        let rho = radius(&ev);
        if rho.is_nan() || rho >= 1.0 {
            return Err(no_solution(format!(
                "the solution found is not stabilizing (closed-loop spectral radius {rho:.6}): (a, b) is not \
                 stabilizable or there are unit-circle modes"
            )));
        }
        eigenvalues = OnceLock::from(ev);
    }
    let residual = (riccati_step(p, &decay, &k) - &x).norm_max() / x.norm_max().max(1.0);
    Ok(RiccatiSolution { eigenvalues, ..RiccatiSolution::of(p, &x, k, &acl, residual, iterations, method) })
}

/// Whether X ≻ 0 and X − M'XM ≻ 0 show ρ(M) < 1, with `decay` = M'XM: for M v = λ v,
/// (1 − |λ|²) v*Xv = v*(X − M'XM)v > 0 (Lyapunov). At a DARE solution X − M'XM is
/// [I; −K]' [[q, s], [s', r]] [I; −K], positive definite whenever q is, so the residual's
/// product (computed anyway) and two Cholesky factorizations (n³/3 multiply-adds) replace the
/// squarings of [`shown_stable`]. Both matrices are factored less δI, δ = (n + 2)² u (1 +
/// ‖M‖_F²) ‖X‖_F, a bound on the rounding of M'XM and of the factorizations, so that rounding
/// cannot pass a closed loop on the unit circle (there v*(X − M'XM)v = 0).
fn lyapunov_shows_stable(x: &Mat<f64>, decay: &Mat<f64>, m: &Mat<f64>) -> bool {
    let n = x.nrows();
    let delta = (n as f64 + 2.0).powi(2) * f64::EPSILON * (1.0 + m.norm_l2().powi(2)) * x.norm_l2();
    if !delta.is_finite() {
        return false;
    }
    let shifted = |a: Mat<f64>| a - Mat::<f64>::identity(n, n) * faer::Scale(delta);
    let positive_definite = |a: Mat<f64>| shifted(a).llt(faer::Side::Lower).is_ok();
    positive_definite(x.clone()) && positive_definite(sym(&(x - decay)))
}

/// Largest power 2^j of the closed loop tried by [`shown_stable`].
const STABLE_POWER_STEPS: usize = 6;

/// Whether ρ(m) < 1 shows for little work: ρ(m) ≤ ‖mᵖ‖^(1/p) in any norm (Gelfand), so
/// ‖mᵖ‖∞ ≤ 1/2 for p = 1, 2, 4, …, 64 (one product per squaring, at most six) proves the
/// closed loop stable with a margin far above the rounding of the products. A closed loop
/// with radius above ~0.99, or much transient growth, is left to its eigenvalues (10 n³
/// flops and more, against n³ per squaring).
fn shown_stable(m: &Mat<f64>) -> bool {
    // The max norm of the row sums, NaN if one is (f64::max would drop it).
    let norm_inf = |m: &Mat<f64>| {
        let row_sums = (0..m.nrows()).map(|i| m.row(i).iter().map(|v| v.abs()).sum::<f64>());
        row_sums.fold(0.0, |norm: f64, v| if v.is_nan() || v > norm { v } else { norm })
    };
    let mut power = m.clone();
    for step in 0..=STABLE_POWER_STEPS {
        let norm = norm_inf(&power);
        if norm <= 0.5 {
            return true;
        }
        if !norm.is_finite() || step == STABLE_POWER_STEPS {
            return false;
        }
        power = &power * &power;
    }
    false
}

/// Newton–Kleinman steps after the CARE's eigenvector solution, at most.
const CARE_NEWTON_STEPS: usize = 5;

/// Solves the CARE (SciPy's `solve_continuous_are(a, b, q, r, e, s)`): the stable invariant
/// subspace of the Hamiltonian matrix, refined by Newton–Kleinman steps in correction form (one
/// continuous Lyapunov solve each, kept while the residual decreases). When that subspace gives
/// no stabilizing solution (eigenvalues of the Hamiltonian within rounding of the imaginary
/// axis, SciPy's CAREX 10), Newton–Kleinman from a stabilizing gain, which converges to the
/// stabilizing solution whenever there is one (Kleinman 1968). Needs r invertible.
pub fn solve_continuous_are(problem: RiccatiProblem<'_>) -> Result<RiccatiSolution> {
    let RiccatiProblem { a, b, q, r, e, s, n, m } = problem;
    let p = checked_problem(a, b, q, r, e, s, n, m)?;
    let r_inv =
        invert(&p.r).ok_or_else(|| Error::arg("r", "must be invertible for the continuous Riccati equation"))?;
    let first = hamiltonian_solution(&p, &r_inv).and_then(|x| finish_care(&p, &r_inv, x, 0, "hamiltonian"));
    let Err(first_error) = first else { return first };
    let first_problem = first_error.to_string();
    let fallback = care_stabilizing_gain(&p)
        .and_then(|k0| kleinman(&p, &r_inv, k0, KLEINMAN_STEPS))
        .and_then(|(x, iterations)| finish_care(&p, &r_inv, x, iterations, "newton"));
    fallback
        .map_err(|_| no_solution(format!("{first_problem}; Newton–Kleinman from a stabilizing gain found none either")))
}

/// Newton–Kleinman steps of the fallback, at most.
const KLEINMAN_STEPS: usize = 60;

/// The solution from the stable invariant subspace of the Hamiltonian matrix (symmetrized).
fn hamiltonian_solution(p: &Problem, r_inv: &Mat<f64>) -> Result<Mat<f64>> {
    let n = p.a.nrows();
    let rs = r_inv * p.s.transpose();
    let a0 = &p.a - &p.b * &rs;
    let g = &p.b * r_inv * p.b.transpose();
    let q0 = &p.q - &p.s * &rs;
    let mut ham = Mat::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        for j in 0..n {
            ham[(i, j)] = a0[(i, j)];
            ham[(i, n + j)] = -g[(i, j)];
            ham[(n + i, j)] = -q0[(i, j)];
            ham[(n + i, n + j)] = -a0[(j, i)];
        }
    }
    Ok(sym(&stable_subspace(&ham, n, |l| l.re < 0.0, "in the open left half-plane")?))
}

/// K = r⁻¹ (b'X + s').
fn care_gain(p: &Problem, r_inv: &Mat<f64>, x: &Mat<f64>) -> Mat<f64> {
    r_inv * (p.b.transpose() * x + p.s.transpose())
}

/// a'X + Xa − (Xb + s) r⁻¹ (b'X + s') + q = a'X + Xa − K'rK + q with K the gain at X.
fn care_residual(p: &Problem, x: &Mat<f64>, k: &Mat<f64>) -> Mat<f64> {
    sym(&(p.a.transpose() * x + x * &p.a - k.transpose() * &p.r * k + &p.q))
}

/// A gain K with a − bK Hurwitz: zero for a Hurwitz a, else the gain of the auxiliary CARE
/// (a, b, q = I, r = I, s = 0), whose Hamiltonian has no imaginary eigenvalues when (a, b) is
/// stabilizable.
fn care_stabilizing_gain(p: &Problem) -> Result<Mat<f64>> {
    let (n, m) = (p.a.nrows(), p.b.ncols());
    let largest_real =
        |a: &Mat<f64>| -> Result<f64> { Ok(eigenvalues(a)?.iter().map(|l| l.0).fold(f64::NEG_INFINITY, f64::max)) };
    if largest_real(&p.a)? < 0.0 {
        return Ok(Mat::zeros(m, n));
    }
    let identity_m = Mat::<f64>::identity(m, m);
    let auxiliary = auxiliary_problem(p);
    let k = care_gain(&auxiliary, &identity_m, &hamiltonian_solution(&auxiliary, &identity_m)?);
    if largest_real(&(&p.a - &p.b * &k))? >= 0.0 {
        return Err(no_solution("(a, b) is not stabilizable: no gain makes a − bK Hurwitz"));
    }
    Ok(k)
}

/// Newton–Kleinman from the stabilizing gain `k0`: X(k) solves
/// (a − bK)'X + X(a − bK) + q − sK − K's' + K'rK = 0, then K = r⁻¹ (b'X + s'); returns X and
/// the steps taken.
fn kleinman(p: &Problem, r_inv: &Mat<f64>, k0: Mat<f64>, max_steps: usize) -> Result<(Mat<f64>, usize)> {
    let n = p.a.nrows();
    let mut k = k0;
    let mut x = Mat::<f64>::zeros(n, n);
    for step in 1..=max_steps {
        let acl = &p.a - &p.b * &k;
        let sk = &p.s * &k;
        let c = -sym(&(&p.q - &sk - sk.transpose() + k.transpose() * &p.r * &k));
        let next = solve_continuous_lyapunov(&from_mat(&acl.transpose().to_owned()), &from_mat(&c), n)
            .map_err(|_| no_solution("a Newton–Kleinman step met a closed loop with λ_i + λ_j = 0"))?;
        let next = sym(&to_mat(&next, n));
        let change = (&next - &x).norm_max();
        x = next;
        k = care_gain(p, r_inv, &x);
        if !all_finite(&x) {
            return Err(no_solution("Newton–Kleinman diverged"));
        }
        if change <= 1e-14 * x.norm_max().max(1e-300) {
            return Ok((x, step));
        }
    }
    Ok((x, max_steps))
}

/// Newton–Kleinman steps in correction form from `x`, the stabilizing check and the residual.
fn finish_care(
    p: &Problem,
    r_inv: &Mat<f64>,
    x: Mat<f64>,
    steps: usize,
    method: &'static str,
) -> Result<RiccatiSolution> {
    let n = p.a.nrows();
    let mut x = x;
    let mut iterations = steps;
    let mut res = care_residual(p, &x, &care_gain(p, r_inv, &x));
    for _ in 0..CARE_NEWTON_STEPS {
        // Newton–Kleinman in correction form: (a − bK)'Δ + Δ(a − bK) = −Res(X), X ← X + Δ.
        // Solving for the correction, not for X itself, makes the Lyapunov solve's rounding
        // relative to Δ (as the DARE's polish): with entries of 1e6 (SciPy's CAREX 8) the
        // plain step stalls at residuals 40× SciPy's tolerance.
        let k = care_gain(p, r_inv, &x);
        let acl = &p.a - &p.b * &k;
        let Ok(delta) = solve_continuous_lyapunov(&from_mat(&acl.transpose().to_owned()), &from_mat(&(-&res)), n)
        else {
            break;
        };
        let next = sym(&(&x + to_mat(&delta, n)));
        let next_res = care_residual(p, &next, &care_gain(p, r_inv, &next));
        let (new_size, old_size) = (next_res.norm_max(), res.norm_max());
        if new_size.is_nan() || new_size >= old_size {
            break;
        }
        let change = to_mat(&delta, n).norm_max();
        (x, res) = (next, next_res);
        iterations += 1;
        if change <= 1e-14 * x.norm_max().max(1e-300) {
            break;
        }
    }
    let k = care_gain(p, r_inv, &x);
    let acl = &p.a - &p.b * &k;
    let closed_loop_eigenvalues = eigenvalues(&acl)?;
    let max_re = closed_loop_eigenvalues.iter().map(|l| l.0).fold(f64::NEG_INFINITY, f64::max);
    if max_re.is_nan() || max_re >= 0.0 {
        return Err(no_solution(format!(
            "the solution found is not stabilizing (largest closed-loop real part {max_re:.6})"
        )));
    }
    let residual = care_residual(p, &x, &k).norm_max() / x.norm_max().max(1.0);
    let eigenvalues = OnceLock::from(closed_loop_eigenvalues);
    Ok(RiccatiSolution { eigenvalues, ..RiccatiSolution::of(p, &x, k, &acl, residual, iterations, method) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dare(
        a: &[f64],
        b: &[f64],
        q: &[f64],
        r: &[f64],
        s: &[f64],
        n: usize,
        method: DareMethod,
    ) -> Result<RiccatiSolution> {
        solve_discrete_are(RiccatiProblem::new(a, b, q, r, n, b.len() / n).with_s(s), method)
    }

    /// Söderström ex. 7.1: y(t) − 0.8 y(t−1) = e(t) + 2 e(t−1), var e = 1, in observer form
    /// (F = 0.8, k = 2.8, Q = k², N = k, R = 1): q − s r⁻¹ s' = 0 and a − b r⁻¹ s' = −2. The
    /// stabilizing P = 3 (innovation variance 4, K_pred = 1.3, closed loop −0.5); doubling
    /// from zero stops at the non-stabilizing P = 0, so the answer comes from a fallback.
    #[test]
    fn noninvertible_arma_falls_back_to_newton() {
        let k = 2.8;
        for method in [DareMethod::Doubling, DareMethod::Newton, DareMethod::Iteration, DareMethod::Eigen] {
            let sol = dare(&[0.8], &[1.0], &[k * k], &[1.0], &[k], 1, method).unwrap();
            assert!((sol.x[0] - 3.0).abs() < 1e-12, "{method:?}: {sol:?}");
            assert!((sol.gain[0] - 1.3).abs() < 1e-12);
            assert!((sol.closed_loop_eigenvalues().unwrap()[0].0 + 0.5).abs() < 1e-12);
            let expected = match method {
                DareMethod::Doubling | DareMethod::Newton => "newton",
                DareMethod::Iteration => "iteration",
                DareMethod::Eigen => "eigen",
            };
            assert_eq!(sol.method, expected);
        }
    }

    #[test]
    fn singular_decorrelated_a_uses_the_pencil() {
        // C = q² + 2.5 q (zeros −2.5, 0), A = q² − 0.5 q: a − b r⁻¹ s' = (F − k H)' is singular.
        let (f, k) = ([0.5, 1.0, 0.0, 0.0], [3.0, 0.0]);
        let a = [f[0], f[2], f[1], f[3]];
        let q = [k[0] * k[0], k[0] * k[1], k[1] * k[0], k[1] * k[1]];
        let sol = dare(&a, &[1.0, 0.0], &q, &[1.0], &k, 2, DareMethod::Eigen).unwrap();
        assert_eq!(sol.method, "pencil");
        // Innovation variance 2.5² = 6.25, so P₁₁ = 5.25; P has rank one.
        assert!((sol.x[0] - 5.25).abs() < 1e-12 && sol.x[1..].iter().all(|v| v.abs() < 1e-12), "{sol:?}");
        assert!(sol.residual < 1e-14);
    }

    #[test]
    fn powers_show_stability_only_with_a_margin() {
        let shown = |v: &[f64]| shown_stable(&to_mat(v, 2));
        assert!(shown(&[0.5, 1e3, 0.0, 0.5]), "radius 0.5 despite transient growth");
        assert!(shown(&[0.0, 1.0, 0.0, 0.0]), "nilpotent");
        assert!(!shown(&[0.995, 0.0, 0.0, 0.1]), "radius 0.995 is left to the eigenvalues");
        assert!(!shown(&[1.2, 0.0, 0.0, 0.1]));
        assert!(!shown(&[f64::NAN, 0.0, 0.0, 0.1]));
    }

    #[test]
    fn lyapunov_shows_stability_only_off_the_unit_circle() {
        let shown = |x: &[f64], m: &[f64]| {
            let (x, m) = (to_mat(x, 2), to_mat(m, 2));
            lyapunov_shows_stable(&x, &congruence(&x, &m), &m)
        };
        let identity = [1.0, 0.0, 0.0, 1.0];
        assert!(shown(&identity, &[0.995, 0.0, 0.0, 0.1]), "radius 0.995, left to eigenvalues by the powers");
        assert!(shown(&[1.0, 0.0, 0.0, 1e6], &[0.5, 1e2, 0.0, 0.5]), "transient growth with a weight that shows it");
        let (c, s) = (0.6, 0.8);
        assert!(!shown(&identity, &[c, -s, s, c]), "a rotation: on the unit circle");
        assert!(!shown(&identity, &[1.2, 0.0, 0.0, 0.1]));
        assert!(!shown(&[1.0, 0.0, 0.0, 0.0], &[0.5, 0.0, 0.0, 0.5]), "X singular proves nothing");
        assert!(!shown(&identity, &[f64::NAN, 0.0, 0.0, 0.1]));
    }

    /// The first step through G₀'s rank gives the general step's A₁, G₁, H₁.
    #[test]
    fn low_rank_first_step_is_the_doubling_step() {
        let (n, m) = (6, 2);
        let entry = |i: usize, j: usize, k: usize| ((i * 7 + j * 3 + k) % 11) as f64 / 11.0 - 0.45;
        let a0 = Mat::from_fn(n, n, |i, j| 0.3 * entry(i, j, 1));
        let b = Mat::from_fn(n, m, |i, j| entry(i, j, 2));
        let c = Mat::from_fn(n, n, |i, j| entry(i, j, 5));
        let h0 = sym(&(&c * c.transpose() + Mat::<f64>::identity(n, n)));
        let r = Mat::from_fn(m, m, |i, j| if i == j { 2.0 } else { 0.3 });
        let g0 = sym(&(&b * invert(&r).unwrap() * b.transpose()));
        let (Iterates { a: a1, g: g1, h: h1 }, _) = low_rank_first_step(&a0, &b, &r, &g0, &h0).unwrap();
        let w = Mat::<f64>::identity(n, n) + &g0 * &h0;
        let (v1, v2) = (solve(&w, &a0), solve(&w, &g0));
        let close = |x: &Mat<f64>, y: Mat<f64>| (x - &y).norm_max() < 1e-13 * y.norm_max();
        assert!(close(&a1, &a0 * &v1));
        assert!(close(&g1, &g0 + &a0 * v2 * a0.transpose()));
        assert!(close(&h1, &h0 + a0.transpose() * &h0 * &v1));
    }

    #[test]
    fn pencil_alone_gives_the_stabilizing_solution() {
        let k = 2.8;
        let p = checked_problem(&[0.8], &[1.0], &[k * k], &[1.0], None, Some(&[k]), 1, 1).unwrap();
        let x = pencil(&p).unwrap();
        assert!((x[(0, 0)] - 3.0).abs() < 1e-12);
    }

    #[test]
    fn ordinary_problems_keep_the_method_asked_for() {
        let (a, b, q, r) = ([0.9, 0.1, 0.0, 1.1], [0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [1.0]);
        for (method, name) in
            [(DareMethod::Doubling, "doubling"), (DareMethod::Newton, "newton"), (DareMethod::Eigen, "eigen")]
        {
            let sol = solve_discrete_are(RiccatiProblem::new(&a, &b, &q, &r, 2, 1), method).unwrap();
            assert_eq!(sol.method, name);
        }
    }

    #[test]
    fn unit_circle_noise_zero_still_has_no_stabilizing_solution() {
        // C = q + 1: the zero −1 is on the circle; only a maximal solution exists. (The
        // iteration's 200 000 slow steps are left to the Python tests: unoptimized they take
        // most of a minute.)
        let (f, k) = (0.5, 1.5);
        for method in [DareMethod::Doubling, DareMethod::Newton, DareMethod::Eigen] {
            let err = dare(&[f], &[1.0], &[k * k], &[1.0], &[k], 1, method).unwrap_err();
            assert!(matches!(err, Error::NoStabilizingSolution { .. }), "{method:?}: {err}");
        }
    }
}
