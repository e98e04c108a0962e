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
//! closed-loop eigenvalues and the relative residual. A nonsingular e is removed first
//! (a → a e⁻¹, q → e⁻ᵀ q e⁻¹, s → e⁻ᵀ s; X is unchanged), then, where r is invertible,
//! the cross term (a → a − b r⁻¹ s', q → q − s r⁻¹ s', Söderström Lemma 6.4).

use faer::linalg::solvers::Solve;
use faer::{c64, Mat};

use crate::core::dense::{lu_in_place, lu_solve, mul, mul_bt, symmetrize, transpose};
use crate::core::dims::{Buf, Dims, Dyn, Fixed};
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
    /// when a is stable, else the doubling solution; with a singular r, the iteration's),
    /// quadratic convergence.
    Newton,
    /// Riccati iteration (6.90) in congruence form from X = I: linear convergence at about
    /// ρ(a − bK)² per step; needs only b'Xb + r invertible (singular r is fine).
    Iteration,
    /// Eigenvectors of the symplectic matrix (Söderström 6.8, (6.116)–(6.124)), refined by
    /// up to two Newton steps: needs r and a − b r⁻¹ s' invertible.
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
    /// Eigenvalues (re, im) of the closed loop a − bK (with e: of (a − bK) e⁻¹).
    pub closed_loop_eigenvalues: Vec<(f64, f64)>,
    /// ‖residual‖ / max(1, ‖X‖) in the max norm.
    pub residual: f64,
    /// Iterations of the method (0 for `Eigen`).
    pub iterations: usize,
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
    /// The gain of the reduced problem is K e⁻¹; map it back to K.
    fn unreduce_gain(&self, k: Mat<f64>) -> Mat<f64> {
        match &self.e {
            Some(e) => k * e,
            None => k,
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn problem(
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
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| 0.5 * (a[(i, j)] + a[(j, i)]))
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

/// Solves the DARE (SciPy's `solve_discrete_are(a, b, q, r, e, s)`); `a` is `n × n`, `b`
/// `n × m`, all row-major.
#[allow(clippy::too_many_arguments)]
pub fn solve_discrete_are(
    a: &[f64],
    b: &[f64],
    q: &[f64],
    r: &[f64],
    e: Option<&[f64]>,
    s: Option<&[f64]>,
    n: usize,
    m: usize,
    method: DareMethod,
) -> Result<RiccatiSolution> {
    let p = problem(a, b, q, r, e, s, n, m)?;
    let r_inv = invert(&p.r);
    let (x, iterations) = match (method, &r_inv) {
        (DareMethod::Doubling, Some(r_inv)) => doubling(&p, r_inv)?,
        (DareMethod::Doubling, None) | (DareMethod::Iteration, _) => {
            let (x0, it) = iteration(&p)?;
            if method == DareMethod::Doubling {
                let (x, more) = newton(&p, x0, 60)?;
                (x, it + more)
            } else {
                (x0, it)
            }
        }
        (DareMethod::Newton, _) => {
            let start = match &r_inv {
                Some(_) if spectral_radius(&p.a)? < 1.0 => Mat::zeros(n, n),
                Some(r_inv) => doubling(&p, r_inv)?.0,
                // Hewer's guarantee of stabilizing gains needs r > 0: start from the iteration.
                None => iteration(&p)?.0,
            };
            newton(&p, start, 60)?
        }
        // Eigenvectors lose digits when they are ill-conditioned: one or two Newton steps
        // restore them (Söderström ex. 6.23; docs/algorithms.md, "Newton–Hewer").
        (DareMethod::Eigen, Some(r_inv)) => newton(&p, eigen(&p, r_inv)?, 2)?,
        (DareMethod::Eigen, None) => {
            return Err(Error::arg("r", "must be invertible for method \"eigen\" (use \"doubling\" or \"iteration\")"))
        }
    };
    let solution = finish_dare(&p, sym(&x), iterations)?;
    if method != DareMethod::Doubling || solution.residual <= REFINE_ABOVE {
        return Ok(solution);
    }
    // Doubling loses digits on ill-conditioned problems (e.g. r = 1e-6 with a singular a:
    // relative residual 1e-3): Newton steps from its stabilizing solution restore them.
    let refined = newton(&p, to_mat(&solution.x, n), 3)
        .and_then(|(x, more)| finish_dare(&p, sym(&x), solution.iterations + more));
    Ok(match refined {
        Ok(better) if better.residual < solution.residual => better,
        _ => solution,
    })
}

/// Relative residual above which a doubling solution is refined by Newton steps.
const REFINE_ABOVE: f64 = 1e-12;

/// K = (b'Xb + r)⁻¹(b'Xa + s') for the reduced problem.
fn dare_gain(p: &Problem, x: &Mat<f64>) -> Option<Mat<f64>> {
    let bt = p.b.transpose();
    let sk = bt * x * &p.b + &p.r;
    let rhs = bt * x * &p.a + p.s.transpose();
    let k = solve(&sk, &rhs);
    all_finite(&k).then_some(k)
}

/// (a − bK)' X (a − bK) + q − sK − K's' + K'rK: one Riccati step in congruence form.
fn riccati_step(p: &Problem, x: &Mat<f64>, k: &Mat<f64>) -> Mat<f64> {
    let acl = &p.a - &p.b * k;
    let sk = &p.s * k;
    sym(&(acl.transpose() * x * &acl + &p.q - &sk - sk.transpose() + k.transpose() * &p.r * k))
}

/// Structure-preserving doubling on the problem with s removed (ex. 6.24; docs/algorithms.md, "Doubling"):
/// A ← A W⁻¹A, G ← G + A W⁻¹G A', H ← H + A'H W⁻¹A with W = I + G H, until H (→ X) settles.
/// The loop runs on row-major buffers with the small dense kernels and one LU of W per step
/// (at n = 4 a faer call costs more than its arithmetic; from 8³ multiply-adds the products
/// still go to faer's matmul).
fn doubling(p: &Problem, r_inv: &Mat<f64>) -> Result<(Mat<f64>, usize)> {
    let n = p.a.nrows();
    let rs = r_inv * p.s.transpose();
    let a0 = from_mat(&(&p.a - &p.b * &rs));
    let g0 = from_mat(&sym(&(&p.b * r_inv * p.b.transpose())));
    let h0 = from_mat(&sym(&(&p.q - &p.s * &rs)));
    // Compile-time sizes for small n, so that the loops unroll and the iterates stay local.
    let (x, it) = match n {
        1 => doubling_loop(Fixed::<1, 1>, &a0, &g0, &h0),
        2 => doubling_loop(Fixed::<2, 1>, &a0, &g0, &h0),
        3 => doubling_loop(Fixed::<3, 1>, &a0, &g0, &h0),
        4 => doubling_loop(Fixed::<4, 1>, &a0, &g0, &h0),
        6 => doubling_loop(Fixed::<6, 1>, &a0, &g0, &h0),
        8 => doubling_loop(Fixed::<8, 1>, &a0, &g0, &h0),
        _ => doubling_loop(Dyn { n, m: 1 }, &a0, &g0, &h0),
    }?;
    Ok((to_mat(&x, n), it))
}

/// The doubling iteration from row-major A, G, H; returns H at convergence (= X).
fn doubling_loop<D: Dims>(d: D, a0: &[f64], g0: &[f64], h0: &[f64]) -> Result<(Vec<f64>, usize)> {
    let n = d.n();
    let (mut ak, mut gk, mut hk) = (d.square(), d.square(), d.square());
    ak.get_mut().copy_from_slice(a0);
    gk.get_mut().copy_from_slice(g0);
    hk.get_mut().copy_from_slice(h0);
    let (mut w, mut v1, mut v2, mut tmp, mut at, mut next) =
        (d.square(), d.square(), d.square(), d.square(), d.square(), d.square());
    let mut piv = vec![0; n];
    let mut previous = f64::INFINITY;
    for it in 1..=100 {
        let (a, g, h) = (ak.get_mut(), gk.get_mut(), hk.get_mut());
        let w = w.get_mut();
        mul(w, g, h, n, n, n);
        for i in 0..n {
            w[i * n + i] += 1.0;
        }
        let (v1, v2, tmp, at, next) = (v1.get_mut(), v2.get_mut(), tmp.get_mut(), at.get_mut(), next.get_mut());
        v1.copy_from_slice(a);
        v2.copy_from_slice(g);
        solve_twice(w, &mut piv, v1, v2, n);
        // G + A V2 A'
        mul(tmp, a, v2, n, n, n);
        mul_bt(next, tmp, a, n, n, n);
        for (gi, di) in g.iter_mut().zip(next.iter()) {
            *gi += di;
        }
        symmetrize(g, n);
        // H + A' H V1
        mul(tmp, h, v1, n, n, n);
        transpose(at, a, n, n);
        mul(next, at, tmp, n, n, n);
        let (mut change, mut size) = (0.0f64, 0.0f64);
        for (hi, di) in h.iter_mut().zip(next.iter()) {
            *hi += di;
            change = change.max(di.abs());
        }
        symmetrize(h, n);
        // A V1
        mul(next, a, v1, n, n, n);
        a.copy_from_slice(next);
        for v in h.iter() {
            size = size.max(v.abs());
        }
        if !h.iter().chain(a.iter()).all(|v| v.is_finite()) {
            return Err(no_solution("the doubling iteration diverged (is (a, b) stabilizable?)"));
        }
        let a_size = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        if converged(change, previous, size) || a_size <= 1e-300 {
            return Ok((h.to_vec(), it));
        }
        previous = change;
    }
    Err(no_solution("the doubling iteration did not converge in 100 steps (eigenvalues on the unit circle?)"))
}

/// Solves `W X = V` in place for `v1` and `v2` (n × n each) with one LU of `w`: the small
/// kernels up to n = 8, faer's blocked LU beyond (measured: at n = 20 and 100 the plain loops
/// are 1.5× and 3.6× slower than faer).
#[inline(always)]
fn solve_twice(w: &mut [f64], piv: &mut [usize], v1: &mut [f64], v2: &mut [f64], n: usize) {
    if n <= 8 {
        lu_in_place(w, piv, n);
        lu_solve(w, piv, v1, n, n);
        lu_solve(w, piv, v2, n, n);
        return;
    }
    let lu = faer::MatRef::from_row_major_slice(w, n, n).partial_piv_lu();
    lu.solve_in_place(faer::MatMut::from_row_major_slice_mut(v1, n, n));
    lu.solve_in_place(faer::MatMut::from_row_major_slice_mut(v2, n, n));
}

/// Riccati iteration (6.90) from X = max(1, ‖q‖) I (docs/algorithms.md, "Riccati iteration").
fn iteration(p: &Problem) -> Result<(Mat<f64>, usize)> {
    let n = p.a.nrows();
    let mut x = Mat::<f64>::identity(n, n) * faer::Scale(p.q.norm_max().max(1.0));
    let mut previous = f64::INFINITY;
    for it in 1..=200_000 {
        let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r became singular in the Riccati iteration"))?;
        let next = riccati_step(p, &x, &k);
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
    let n = p.a.nrows();
    let mut x = x0;
    let mut previous = f64::INFINITY;
    for it in 1..=max_iter {
        let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r is singular at a Newton step"))?;
        let acl = &p.a - &p.b * &k;
        let sk = &p.s * &k;
        let c = sym(&(&p.q - &sk - sk.transpose() + k.transpose() * &p.r * &k));
        let next = solve_discrete_lyapunov(&from_mat(&acl.transpose().to_owned()), &from_mat(&c), n)
            .map_err(|_| no_solution("a Newton step met a closed loop with eigenvalues λ_i λ_j = 1"))?;
        let next = sym(&to_mat(&next, n));
        let change = (&next - &x).norm_max();
        x = next;
        if converged(change, previous, x.norm_max()) {
            return Ok((x, it));
        }
        previous = change;
    }
    Ok((x, max_iter))
}

/// Stable invariant subspace of the symplectic matrix, control form (docs/algorithms.md, "Eigenvector method").
fn eigen(p: &Problem, r_inv: &Mat<f64>) -> Result<Mat<f64>> {
    let n = p.a.nrows();
    let rs = r_inv * p.s.transpose();
    let a0 = &p.a - &p.b * &rs;
    let g = &p.b * r_inv * p.b.transpose();
    let q0 = &p.q - &p.s * &rs;
    let a_inv_t = invert(&a0)
        .ok_or_else(|| Error::arg("a", "a − b r⁻¹ s' must be invertible for method \"eigen\" (use \"doubling\")"))?
        .transpose()
        .to_owned();
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
    stable_subspace(&z, n, |l| l.norm() < 1.0, "inside the unit circle")
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

fn eigenvalues(a: &Mat<f64>) -> Result<Vec<(f64, f64)>> {
    let ev = a.eigenvalues().map_err(|_| no_solution("closed-loop eigenvalues did not converge"))?;
    Ok(ev.iter().map(|l| (l.re, l.im)).collect())
}

fn spectral_radius(a: &Mat<f64>) -> Result<f64> {
    Ok(eigenvalues(a)?.iter().map(|(re, im)| re.hypot(*im)).fold(0.0, f64::max))
}

/// Post-checks (docs/algorithms.md, "Stabilizing solution"): gain, closed-loop eigenvalues (must be inside the unit
/// circle), relative residual; the gain is mapped back through e.
fn finish_dare(p: &Problem, x: Mat<f64>, iterations: usize) -> Result<RiccatiSolution> {
    let k = dare_gain(p, &x).ok_or_else(|| no_solution("b'Xb + r is singular at the solution"))?;
    let acl = &p.a - &p.b * &k;
    let closed_loop_eigenvalues = eigenvalues(&acl)?;
    let rho = closed_loop_eigenvalues.iter().map(|(re, im)| re.hypot(*im)).fold(0.0, f64::max);
    let residual = (riccati_step(p, &x, &k) - &x).norm_max() / x.norm_max().max(1.0);
    if rho.is_nan() || rho >= 1.0 {
        return Err(no_solution(format!(
            "the solution found is not stabilizing (closed-loop spectral radius {rho:.6}): (a, b) is not stabilizable \
             or there are unit-circle modes"
        )));
    }
    let gain = from_mat(&p.unreduce_gain(k));
    Ok(RiccatiSolution { x: from_mat(&x), gain, closed_loop_eigenvalues, residual, iterations })
}

/// Solves the CARE (SciPy's `solve_continuous_are(a, b, q, r, e, s)`): the stable invariant
/// subspace of the Hamiltonian matrix, refined by Newton–Kleinman steps (one continuous
/// Lyapunov solve each). Needs r invertible.
#[allow(clippy::too_many_arguments)]
pub fn solve_continuous_are(
    a: &[f64],
    b: &[f64],
    q: &[f64],
    r: &[f64],
    e: Option<&[f64]>,
    s: Option<&[f64]>,
    n: usize,
    m: usize,
) -> Result<RiccatiSolution> {
    let p = problem(a, b, q, r, e, s, n, m)?;
    let r_inv =
        invert(&p.r).ok_or_else(|| Error::arg("r", "must be invertible for the continuous Riccati equation"))?;
    let rs = &r_inv * p.s.transpose();
    let a0 = &p.a - &p.b * &rs;
    let g = &p.b * &r_inv * p.b.transpose();
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
    let mut x = sym(&stable_subspace(&ham, n, |l| l.re < 0.0, "in the open left half-plane")?);
    let care_gain = |x: &Mat<f64>| &r_inv * (p.b.transpose() * x + p.s.transpose());
    let mut iterations = 0;
    for _ in 0..5 {
        // Newton–Kleinman: (a − bK)'X + X(a − bK) + q − sK − K's' + K'rK = 0
        let k = care_gain(&x);
        let acl = &p.a - &p.b * &k;
        let sk = &p.s * &k;
        let c = -sym(&(&p.q - &sk - sk.transpose() + k.transpose() * &p.r * &k));
        let Ok(next) = solve_continuous_lyapunov(&from_mat(&acl.transpose().to_owned()), &from_mat(&c), n) else {
            break;
        };
        let next = sym(&to_mat(&next, n));
        let change = (&next - &x).norm_max();
        x = next;
        iterations += 1;
        if change <= 1e-14 * x.norm_max().max(1e-300) {
            break;
        }
    }
    let k = care_gain(&x);
    let acl = &p.a - &p.b * &k;
    let closed_loop_eigenvalues = eigenvalues(&acl)?;
    let max_re = closed_loop_eigenvalues.iter().map(|l| l.0).fold(f64::NEG_INFINITY, f64::max);
    if max_re.is_nan() || max_re >= 0.0 {
        return Err(no_solution(format!(
            "the solution found is not stabilizing (largest closed-loop real part {max_re:.6})"
        )));
    }
    // a'X + Xa − (Xb + s) r⁻¹ (b'X + s') + q = a'X + Xa − K'rK + q
    let res = p.a.transpose() * &x + &x * &p.a - k.transpose() * &p.r * &k + &p.q;
    let residual = res.norm_max() / x.norm_max().max(1.0);
    let gain = from_mat(&p.unreduce_gain(k));
    Ok(RiccatiSolution { x: from_mat(&x), gain, closed_loop_eigenvalues, residual, iterations })
}
