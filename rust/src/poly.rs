//! Polynomial methods (Söderström ch. 4 and 7): polynomials are coefficient slices in
//! descending powers of z (NumPy's `poly1d` order), A, C and spectral factors monic.
//!
//! - [`roots`] (the companion matrix's eigenvalues) and [`from_roots`];
//! - [`spectral_factor`] of a symmetric Laurent polynomial, φ = λ² B(z) B(z⁻¹) with B's zeros in
//!   |z| ≤ 1 (Söderström Sec. 4.4, Lemma 4.6: a double zero on the circle gives one zero of B);
//! - [`diophantine`]: A X + B Y = C with deg X < deg B, by the Sylvester system;
//! - [`predictor_identity`]: z^(k−1) C = A F + L (Söderström (7.13)–(7.22)), by long division.

use faer::Mat;

use crate::error::{Error, Result};

/// A zero this close to the unit circle counts as on it.
const CIRCLE_TOL: f64 = 1e-6;

fn check_poly(arg: &'static str, p: &[f64]) -> Result<()> {
    if p.is_empty() {
        return Err(Error::arg(arg, "has no coefficients"));
    }
    if let Some(v) = p.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg(arg, format!("contains a non-finite coefficient ({v})")));
    }
    Ok(())
}

/// `p` without leading zeros (at least one coefficient).
fn trim(p: &[f64]) -> &[f64] {
    let first = p.iter().position(|&v| v != 0.0).unwrap_or(p.len().saturating_sub(1));
    &p[first..]
}

/// The zeros (re, im) of the polynomial `p` (descending coefficients, leading zeros ignored), as
/// the eigenvalues of its companion matrix.
pub fn roots(p: &[f64]) -> Result<Vec<(f64, f64)>> {
    check_poly("p", p)?;
    let p = trim(p);
    let n = p.len() - 1;
    if n == 0 {
        return Ok(Vec::new());
    }
    if p[0] == 0.0 {
        return Err(Error::arg("p", "is the zero polynomial"));
    }
    let companion = Mat::<f64>::from_fn(n, n, |i, j| {
        if i == 0 {
            -p[j + 1] / p[0]
        } else if i == j + 1 {
            1.0
        } else {
            0.0
        }
    });
    // Balanced first: the companion matrix of a degree-50 polynomial loses 1.5 digits without.
    crate::core::schur::eigenvalues(&companion)
        .map_err(|_| Error::arg("p", "the zeros could not be computed (no convergence)"))
}

/// The monic real polynomial with the given zeros (closed under conjugation), descending
/// coefficients; the imaginary parts that rounding leaves are dropped.
pub fn from_roots(zeros: &[(f64, f64)]) -> Vec<f64> {
    let mut c: Vec<(f64, f64)> = vec![(1.0, 0.0)];
    for &(zr, zi) in zeros {
        let mut next = vec![(0.0, 0.0); c.len() + 1];
        for (k, &(cr, ci)) in c.iter().enumerate() {
            next[k].0 += cr;
            next[k].1 += ci;
            // − z c_k into the next power down.
            next[k + 1].0 -= zr * cr - zi * ci;
            next[k + 1].1 -= zr * ci + zi * cr;
        }
        c = next;
    }
    c.into_iter().map(|(re, _)| re).collect()
}

/// The factor of a spectrum: φ(z) = `lam2` · B(z) B(z⁻¹).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SpectralFactor {
    /// B, monic, zeros in |z| ≤ 1 (descending coefficients).
    pub b: Vec<f64>,
    /// λ².
    pub lam2: f64,
    /// Whether B has zeros on the unit circle (Lemma 4.6).
    pub on_circle: bool,
}

/// φ(e^{iω}) = r_0 + 2 Σ r_k cos kω of the symmetric Laurent coefficients `r` (highest first);
/// cos kω by the Chebyshev recurrence cos (k+1)ω = 2 cos ω cos kω − cos (k−1)ω (one cosine per ω).
fn evaluate(r: &[f64], omega: f64) -> f64 {
    let d = (r.len() - 1) / 2;
    let c1 = omega.cos();
    let (mut prev, mut cur) = (1.0, c1);
    let mut sum = 0.0;
    for k in 1..=d {
        sum += r[d + k] * cur;
        (prev, cur) = (cur, 2.0 * c1 * cur - prev);
    }
    r[d] + 2.0 * sum
}

/// The spectral factor of φ(z) = r_0 + Σ r_k (z^k + z^−k), given as the symmetric `r` =
/// (r_d, …, r_1, r_0, r_1, …, r_d), by the zeros of z^d φ(z): they pair as (z, 1/z̄), and the d
/// smallest in modulus form B (one of each pair; also one of each double zero on the circle);
/// λ² = r_0 / Σ b_i². The spectrum must be nonnegative on the circle (checked on 4097
/// frequencies) and symmetric.
pub fn spectral_factor(r: &[f64]) -> Result<SpectralFactor> {
    check_poly("r", r)?;
    if r.len().is_multiple_of(2) {
        return Err(Error::arg(
            "r",
            format!("a symmetric Laurent polynomial has an odd number of coefficients, got {}", r.len()),
        ));
    }
    let scale = r.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    if scale == 0.0 {
        return Err(Error::arg("r", "is the zero spectrum"));
    }
    if (0..r.len()).any(|i| (r[i] - r[r.len() - 1 - i]).abs() > 1e-12 * scale) {
        return Err(Error::arg("r", "must be symmetric (r_k = r_-k)"));
    }
    // Remove outer zeros (zeros of z^d φ at 0 and ∞).
    let mut lo = 0;
    while lo + 1 < r.len() - lo && r[lo] == 0.0 {
        lo += 1;
    }
    let r = &r[lo..r.len() - lo];
    let d = (r.len() - 1) / 2;
    let grid = 4096;
    for j in 0..=grid {
        let omega = std::f64::consts::PI * j as f64 / grid as f64;
        let phi = evaluate(r, omega);
        if phi < -1e-10 * scale {
            return Err(Error::arg(
                "r",
                format!("the spectrum is negative on the unit circle (φ(ω) = {phi:.6e} at ω = {omega:.6}): not a spectral density"),
            ));
        }
    }
    if d == 0 {
        return Ok(SpectralFactor { b: vec![1.0], lam2: r[0], on_circle: false });
    }
    let mut zeros = roots(r)?;
    zeros.sort_by(|a, b| a.0.hypot(a.1).total_cmp(&b.0.hypot(b.1)));
    let inside = &zeros[..d];
    let modulus = |z: &(f64, f64)| z.0.hypot(z.1);
    let on_circle =
        inside.iter().any(|z| (modulus(z) - 1.0).abs() < CIRCLE_TOL) || modulus(&zeros[d]) < 1.0 - CIRCLE_TOL;
    let b = from_roots(inside);
    let lam2 = r[d] / b.iter().map(|v| v * v).sum::<f64>();
    if lam2.is_nan() || lam2 <= 0.0 {
        return Err(Error::arg("r", format!("the spectrum is not positive (λ² = {lam2:.6e})")));
    }
    Ok(SpectralFactor { b, lam2, on_circle })
}

/// The solution of A X + B Y = C with deg X < deg B.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Diophantine {
    /// X, deg B coefficients (descending).
    pub x: Vec<f64>,
    /// Y, max(deg C, deg A + deg B − 1) − deg B + 1 coefficients.
    pub y: Vec<f64>,
    /// The Sylvester system's 2-norm condition number.
    pub condition: f64,
}

/// Solves A X + B Y = C for deg X < deg B (unique when A and B are coprime) by the Sylvester
/// system of the coefficients (Söderström (11.84)–(11.85)). A condition number above 1e12 means
/// that A and B (nearly) share a factor: an error naming them.
pub fn diophantine(a: &[f64], b: &[f64], c: &[f64]) -> Result<Diophantine> {
    check_poly("A", a)?;
    check_poly("B", b)?;
    check_poly("C", c)?;
    let (a, b, c) = (trim(a), trim(b), trim(c));
    if a[0] == 0.0 || b[0] == 0.0 {
        return Err(Error::arg(if a[0] == 0.0 { "A" } else { "B" }, "is the zero polynomial"));
    }
    let (na, nb, nc) = (a.len() - 1, b.len() - 1, c.len() - 1);
    let top = nc.max((na + nb).saturating_sub(1));
    let (nx, ny) = (nb, top + 1 - nb);
    let rows = top + 1;
    // Column j of X multiplies z^(nx-1-j); coefficient rows are z^top .. z^0.
    let mut m = Mat::<f64>::zeros(rows, nx + ny);
    let mut place = |p: &[f64], cols: usize, offset: usize| {
        for j in 0..cols {
            for (i, &coef) in p.iter().rev().enumerate() {
                let power = i + cols - 1 - j;
                m[(rows - 1 - power, offset + j)] = coef;
            }
        }
    };
    place(a, nx, 0);
    place(b, ny, nx);
    let mut rhs = Mat::<f64>::zeros(rows, 1);
    for (i, &v) in c.iter().enumerate() {
        rhs[(rows - c.len() + i, 0)] = v;
    }
    let sv =
        m.singular_values().map_err(|_| Error::arg("A", "the Sylvester system's singular values did not converge"))?;
    let condition = if sv.is_empty() { 1.0 } else { sv[0] / sv[sv.len() - 1] };
    if condition.is_nan() || condition >= 1e12 {
        return Err(Error::arg(
            "A, B",
            format!("have a common factor (the Sylvester matrix of the Diophantine equation is singular, condition number {condition:.3e}): the solution is not unique"),
        ));
    }
    use faer::linalg::solvers::Solve;
    let sol = m.partial_piv_lu().solve(&rhs);
    let x = if nx == 0 { vec![0.0] } else { (0..nx).map(|i| sol[(i, 0)]).collect() };
    let y = (nx..nx + ny).map(|i| sol[(i, 0)]).collect();
    Ok(Diophantine { x, y, condition })
}

/// The solution of a symmetric Toeplitz system by Levinson's recursion, with what every
/// smaller order gives on the way.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Levinson {
    /// x with T x = b, T_ij = r_|i − j| of order `b.len()`.
    pub x: Vec<f64>,
    /// `quadratic[k]` = b[..=k]' T_k⁻¹ b[..=k] for the leading (k+1) × (k+1) block T_k: for
    /// normal equations, the variance explained by the first k + 1 regressors.
    pub quadratic: Vec<f64>,
}

/// Solves T x = b for the symmetric positive definite Toeplitz T with first column `r`
/// (`r.len() ≥ b.len()`) in O(n²) by Levinson's recursion (Golub & Van Loan, Algorithm 4.7.2,
/// unnormalized): the order-k predictor a (T_k a = E_k e_0) is extended by the reflection
/// coefficient κ = −(Σ_j a_j r_{k−j}) / E_k, E_{k+1} = E_k (1 − κ²), and the solution by a
/// multiple of the reversed predictor. An error names the order at which T stops being
/// positive definite (E ≤ 0).
pub fn levinson(r: &[f64], b: &[f64]) -> Result<Levinson> {
    let n = b.len();
    if n == 0 {
        return Ok(Levinson { x: Vec::new(), quadratic: Vec::new() });
    }
    if r.len() < n {
        return Err(Error::arg("r", format!("has {} lags, the system needs {n}", r.len())));
    }
    if r[..n].iter().chain(b).any(|v| !v.is_finite()) {
        return Err(Error::arg("r, b", "contain non-finite values"));
    }
    let not_pd = |k: usize| Error::arg("r", format!("the Toeplitz matrix is not positive definite at order {k}"));
    if r[0] <= 0.0 {
        return Err(not_pd(0));
    }
    let mut a = Vec::with_capacity(n);
    a.push(1.0);
    let mut e = r[0];
    let mut x = vec![b[0] / r[0]];
    x.reserve(n - 1);
    let mut quadratic = vec![b[0] * x[0]];
    let mut next = vec![0.0; n];
    for k in 1..n {
        let delta: f64 = a.iter().enumerate().map(|(j, aj)| aj * r[k - j]).sum();
        let kappa = -delta / e;
        // a ← [a, 0] + κ [0, reverse(a)]
        next[..k].copy_from_slice(&a);
        next[k] = 0.0;
        for j in 0..k {
            next[j + 1] += kappa * a[k - 1 - j];
        }
        a.clear();
        a.extend_from_slice(&next[..=k]);
        e *= 1.0 - kappa * kappa;
        if e.is_nan() || e <= r[0] * f64::EPSILON {
            return Err(not_pd(k));
        }
        // x ← [x, 0] + μ reverse(a): T_k reverse(a) = E e_k, so only the last row needs μ.
        let residual = b[k] - x.iter().enumerate().map(|(j, xj)| r[k - j] * xj).sum::<f64>();
        let mu = residual / e;
        x.push(0.0);
        for j in 0..=k {
            x[j] += mu * a[k - j];
        }
        quadratic.push(x.iter().zip(b).map(|(xi, bi)| xi * bi).sum());
    }
    Ok(Levinson { x, quadratic })
}

/// The predictor identity z^(k−1) C = A F + L (Söderström (7.13)–(7.22)) by long division:
/// F monic of degree k − 1 (the first k impulse-response coefficients of C/A), L of degree
/// < deg A (deg A coefficients). A and C monic, deg C ≤ deg A, k ≥ 1.
pub fn predictor_identity(a: &[f64], c: &[f64], k: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    check_poly("A", a)?;
    check_poly("C", c)?;
    let (a, c) = (trim(a), trim(c));
    for (arg, p) in [("A", a), ("C", c)] {
        if p[0] != 1.0 {
            return Err(Error::arg(arg, format!("must be monic (leading coefficient 1), got {}", p[0])));
        }
    }
    if k == 0 {
        return Err(Error::arg("k", "the prediction horizon must be at least 1"));
    }
    let n = a.len() - 1;
    if c.len() - 1 > n {
        return Err(Error::arg("C", format!("degree {} exceeds deg A = {n}", c.len() - 1)));
    }
    // z^(k−1) C as n + k coefficients (C padded to degree n).
    let mut rem = vec![0.0; n + k];
    rem[n + 1 - c.len()..n + 1].copy_from_slice(c);
    let mut f = vec![0.0; k];
    for j in 0..k {
        let q = rem[j];
        f[j] = q;
        for (i, &ai) in a.iter().enumerate() {
            rem[j + i] -= q * ai;
        }
    }
    Ok((f, rem[k..].to_vec()))
}
