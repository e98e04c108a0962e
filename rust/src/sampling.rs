//! Matrix exponential and exact discretization of continuous-time models
//! (Söderström (4.99)–(4.103), ex. 4.6; docs/algorithms.md, "Sampling"):
//!
//! ```text
//! dx = A x dt + B u dt + dβ,   E dβ dβ' = Qc dt   (Qc: a continuous white-noise intensity)
//! F = e^{A h},   Qd = ∫₀ʰ e^{As} Qc e^{A's} ds,   Bd = ∫₀ʰ e^{As} ds B   (zero-order hold)
//! ```
//!
//! [`expm`] is scaling and squaring with Padé approximants of degree 3 to 13, the degree and
//! the number of squarings chosen from ‖A^k‖^{1/k} (Al-Mohy & Higham 2009), with the exact
//! diagonals for triangular input; [`discretize`] uses Van Loan's block exponential in its
//! inverse-free form `exp(h [[−A, Qc], [0, A']]) = [[·, E12], [0, E22]]`, F = E22',
//! Qd = F E12, at h = dt / 2ˢ, then doubles the interval s times. Nothing is returned that is
//! not finite: overflow is an error naming `a` (expm) or `dt` (discretize). Matrices are
//! row-major.

use faer::linalg::solvers::Solve;
use faer::Mat;

use crate::core::mat::{checked_mat, from_mat, to_mat};
use crate::error::{Error, Result};

/// Coefficients b_j of the degree-m Padé numerator p_m(x) = Σ b_j x^j (denominator p_m(−x)),
/// scaled to integers (Higham 2005, (2.1) and Sec. 3): b_j ∝ (2m − j)! m! / ((2m)! j! (m − j)!).
const PADE3: [f64; 4] = [120.0, 60.0, 12.0, 1.0];
const PADE5: [f64; 6] = [30_240.0, 15_120.0, 3_360.0, 420.0, 30.0, 1.0];
const PADE7: [f64; 8] = [17_297_280.0, 8_648_640.0, 1_995_840.0, 277_200.0, 25_200.0, 1_512.0, 56.0, 1.0];
const PADE9: [f64; 10] = [
    17_643_225_600.0,
    8_821_612_800.0,
    2_075_673_600.0,
    302_702_400.0,
    30_270_240.0,
    2_162_160.0,
    110_880.0,
    3_960.0,
    90.0,
    1.0,
];
const PADE13: [f64; 14] = [
    64_764_752_532_480_000.0,
    32_382_376_266_240_000.0,
    7_771_770_303_897_600.0,
    1_187_353_796_428_800.0,
    129_060_195_264_000.0,
    10_559_470_521_600.0,
    670_442_572_800.0,
    33_522_128_640.0,
    1_323_241_920.0,
    40_840_800.0,
    960_960.0,
    16_380.0,
    182.0,
    1.0,
];
/// θ_m: the bound on ‖A‖ (here on the α_p of Al-Mohy & Higham 2009, Thm 4.2) below which
/// r_m(A) has backward error ≤ u = 2⁻⁵³ (Higham 2005, Table 2.3).
const THETA3: f64 = 1.495_585_217_958_292e-2;
const THETA5: f64 = 2.539_398_330_063_23e-1;
const THETA7: f64 = 9.504_178_996_162_932e-1;
const THETA9: f64 = 2.097_847_961_257_068;
const THETA13: f64 = 5.371_920_351_148_152;

/// e^A of the `n × n` row-major `a`.
///
/// Scaling and squaring after Al-Mohy & Higham (2009, Alg. 6.1): the Padé degree m ∈ {3, 5,
/// 7, 9, 13} and the number of squarings s come from ‖A^k‖^{1/k}, not ‖A‖ (which overscales
/// non-normal matrices: every squaring doubles the rounding error); a triangular `a` gets its
/// diagonal and superdiagonal recomputed exactly at each squaring (their Code Fragment 2.1), so
/// a nilpotent or triangular input is exact or nearly so at any norm.
///
/// # Errors
/// [`Error::InvalidArgument`] on `a` for a wrong size, a non-finite entry, or when e^a
/// overflows double precision (SciPy returns ±inf entries there; kfast refuses).
pub fn expm(a: &[f64], n: usize) -> Result<Vec<f64>> {
    if n.checked_mul(n) != Some(a.len()) {
        return Err(Error::arg("a", format!("expected an ({n}, {n}) matrix, got {} entries", a.len())));
    }
    if let Some(v) = a.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("a", format!("contains a non-finite value ({v})")));
    }
    let am = to_mat(a, n);
    let e = expm_mat(&am).ok_or_else(|| Error::arg("a", overflow_problem("e^a", norm1(&am))))?;
    Ok(from_mat(&e))
}

/// "… overflows double precision (‖·‖₁ = …)": the problem of an exponential that is not finite.
fn overflow_problem(what: &str, norm: f64) -> String {
    format!("{what} overflows double precision (its argument has 1-norm {norm:.6e}): an entry exceeds ±1.8e308")
}

/// ‖A‖₁, the largest absolute column sum (+inf when it overflows).
fn norm1(a: &Mat<f64>) -> f64 {
    (0..a.ncols()).map(|j| (0..a.nrows()).map(|i| a[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max)
}

/// e^A, or `None` when it is not finite (overflow, or ‖A‖₁ itself overflowing).
pub(crate) fn expm_mat(a: &Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    if is_upper_triangular(a) {
        return finite(expm_triangular(a)?);
    }
    if is_upper_triangular(&a.transpose().to_owned()) {
        // e^{A'} = (e^A)': a lower triangular A goes through the triangular path too.
        return finite(expm_triangular(&a.transpose().to_owned())?.transpose().to_owned());
    }
    let Scaling { degree, squarings } = scaling(a)?;
    let mut r = pade(&(a * faer::Scale(0.5f64.powi(squarings))), degree);
    for _ in 0..squarings {
        r = &r * &r;
    }
    debug_assert_eq!(r.nrows(), n);
    finite(r)
}

fn finite(m: Mat<f64>) -> Option<Mat<f64>> {
    let ok = (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()));
    ok.then_some(m)
}

fn is_upper_triangular(a: &Mat<f64>) -> bool {
    (0..a.nrows()).all(|i| (0..i).all(|j| a[(i, j)] == 0.0))
}

/// Padé degree m and number of squarings s: e^A ≈ r_m(2⁻ˢ A)^(2ˢ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Scaling {
    pub(crate) degree: usize,
    pub(crate) squarings: i32,
}

/// Al-Mohy & Higham (2009), Alg. 6.1 with exact 1-norms of the powers (n is small here):
/// d_k = ‖A^k‖₁^{1/k}, the smallest degree m whose θ_m bounds max(d_p, d_{p+1}) and whose
/// backward-error bound ℓ(A, m) needs no extra scaling, else m = 13 with
/// s = ⌈log₂(min(max(d₆, d₈), max(d₈, d₁₀)) / θ₁₃)⌉ + ℓ(2⁻ˢA, 13). `None` when ‖A‖₁ overflows.
pub(crate) fn scaling(a: &Mat<f64>) -> Option<Scaling> {
    let c = norm1(a);
    if !c.is_finite() {
        return None;
    }
    if c == 0.0 {
        return Some(Scaling { degree: 3, squarings: 0 });
    }
    // Powers of A / ‖A‖₁ have 1-norm ≤ 1, so they cannot overflow at any ‖A‖₁.
    let b = a * faer::Scale(1.0 / c);
    let abs_b = Mat::from_fn(b.nrows(), b.ncols(), |i, j| b[(i, j)].abs());
    let ell = |m: usize, s: i32| ell(&abs_b, c, m, s);
    let d = |m: &Mat<f64>, k: i32| c * norm1(m).powf(1.0 / f64::from(k));
    let b2 = &b * &b;
    let b4 = &b2 * &b2;
    let b6 = &b4 * &b2;
    let (d4, d6) = (d(&b4, 4), d(&b6, 6));
    let eta1 = d4.max(d6);
    for (degree, theta) in [(3, THETA3), (5, THETA5)] {
        if eta1 <= theta && ell(degree, 0) == 0 {
            return Some(Scaling { degree, squarings: 0 });
        }
    }
    let b8 = &b4 * &b4;
    let d8 = d(&b8, 8);
    let eta3 = d6.max(d8);
    for (degree, theta) in [(7, THETA7), (9, THETA9)] {
        if eta3 <= theta && ell(degree, 0) == 0 {
            return Some(Scaling { degree, squarings: 0 });
        }
    }
    let d10 = d(&(&b4 * &b6), 10);
    let eta5 = eta3.min(d8.max(d10));
    let s = if eta5 > THETA13 { (eta5 / THETA13).log2().ceil() as i32 } else { 0 };
    Some(Scaling { degree: 13, squarings: s + ell(13, s) })
}

/// ℓ(2⁻ˢA, m) = max(⌈log₂(α / u) / (2m)⌉, 0) with α = |c_{2m+1}| ‖|2⁻ˢA|^{2m+1}‖₁ / ‖2⁻ˢA‖₁
/// (Al-Mohy & Higham 2009, (5.1)): the extra squarings that keep the backward error of r_m
/// below u = 2⁻⁵³ where ‖A^k‖^{1/k} underestimates it. `abs_b` = |A| / c, c = ‖A‖₁; the
/// norm is taken in log₂ so that no power overflows.
fn ell(abs_b: &Mat<f64>, c: f64, m: usize, s: i32) -> i32 {
    let p = 2 * m + 1;
    // ‖N^p‖₁ = max_j (1' N^p)_j for N ≥ 0: p vector-matrix products instead of matrix powers.
    let n = abs_b.nrows();
    let mut row = vec![1.0; n];
    for _ in 0..p {
        row = (0..n).map(|j| (0..n).map(|i| row[i] * abs_b[(i, j)]).sum()).collect();
    }
    let norm = row.iter().fold(0.0f64, |acc, &v| acc.max(v));
    if norm == 0.0 {
        return 0; // |A|^{2m+1} = 0
    }
    let log2_scaled_norm = c.log2() - f64::from(s);
    let log2_alpha = norm.log2() + (p - 1) as f64 * log2_scaled_norm - log2_pade_error_recip(m);
    ((log2_alpha + 53.0) / (2 * m) as f64).ceil().max(0.0) as i32
}

/// log₂(1 / |c_{2m+1}|) = log₂((2m)! (2m+1)! / (m!)²): the leading coefficient of the
/// backward error of r_m (Higham 2005, (2.6)).
fn log2_pade_error_recip(m: usize) -> f64 {
    let log2_factorial = |k: usize| (1..=k).map(|i| (i as f64).log2()).sum::<f64>();
    log2_factorial(2 * m) + log2_factorial(2 * m + 1) - 2.0 * log2_factorial(m)
}

/// r_m(A) = (V − U)⁻¹ (V + U) with U, V the odd and even parts of p_m (Higham 2005, (2.8)–(2.10)).
fn pade(a: &Mat<f64>, degree: usize) -> Mat<f64> {
    let n = a.nrows();
    let id = Mat::<f64>::identity(n, n);
    let scaled = |m: &Mat<f64>, c: f64| m * faer::Scale(c);
    let a2 = a * a;
    let (u, v) = if degree == 13 {
        let b = &PADE13;
        let a4 = &a2 * &a2;
        let a6 = &a4 * &a2;
        let u_inner = &a6 * (scaled(&a6, b[13]) + scaled(&a4, b[11]) + scaled(&a2, b[9]))
            + scaled(&a6, b[7])
            + scaled(&a4, b[5])
            + scaled(&a2, b[3])
            + scaled(&id, b[1]);
        let v = &a6 * (scaled(&a6, b[12]) + scaled(&a4, b[10]) + scaled(&a2, b[8]))
            + scaled(&a6, b[6])
            + scaled(&a4, b[4])
            + scaled(&a2, b[2])
            + scaled(&id, b[0]);
        (a * u_inner, v)
    } else {
        let b: &[f64] = match degree {
            3 => &PADE3,
            5 => &PADE5,
            7 => &PADE7,
            _ => &PADE9,
        };
        // U = A Σ_j b_{2j+1} A^{2j},  V = Σ_j b_{2j} A^{2j}
        let mut u_inner = scaled(&id, b[1]);
        let mut v = scaled(&id, b[0]);
        let mut power = id.clone();
        for j in 1..=degree / 2 {
            power = &power * &a2;
            u_inner += scaled(&power, b[2 * j + 1]);
            v += scaled(&power, b[2 * j]);
        }
        (a * u_inner, v)
    };
    (&v - &u).partial_piv_lu().solve(&v + &u)
}

/// e^T of an upper triangular T: scaling and squaring with the diagonal and first
/// superdiagonal of each r_m(2⁻ʲT)^(2^(s−j)) replaced by the exact ones of e^{2⁻ʲT}
/// (Al-Mohy & Higham 2009, Code Fragment 2.1). `None` when ‖T‖₁ overflows.
fn expm_triangular(t: &Mat<f64>) -> Option<Mat<f64>> {
    let Scaling { degree, squarings } = scaling(t)?;
    let mut r = pade(&(t * faer::Scale(0.5f64.powi(squarings))), degree);
    for j in (0..=squarings).rev() {
        if j < squarings {
            r = &r * &r;
        }
        exact_diagonals(&mut r, t, 0.5f64.powi(j));
    }
    Some(r)
}

/// Diagonal and first superdiagonal of e^{hT} for upper triangular T, written into `e`:
/// e^{h t_ii}, and h t_{i,i+1} f[h t_ii, h t_{i+1,i+1}] with the divided difference of exp
/// (Higham, *Functions of Matrices*, (10.42)).
fn exact_diagonals(e: &mut Mat<f64>, t: &Mat<f64>, h: f64) {
    let n = t.nrows();
    for i in 0..n {
        e[(i, i)] = (h * t[(i, i)]).exp();
    }
    for i in 0..n.saturating_sub(1) {
        let t12 = h * t[(i, i + 1)];
        e[(i, i + 1)] =
            if t12 == 0.0 { 0.0 } else { t12 * exp_divided_difference(h * t[(i, i)], h * t[(i + 1, i + 1)]) };
    }
}

/// (e^b − e^a) / (b − a), e^a when a = b, without cancellation or spurious overflow.
fn exp_divided_difference(a: f64, b: f64) -> f64 {
    let half_gap = b / 2.0 - a / 2.0;
    if half_gap.abs() <= 0.5 {
        // e^{(a+b)/2} sinh(z) / z, z = (b − a)/2 (10.42): no cancellation for close a, b.
        let z = half_gap;
        let sinhc = if z == 0.0 { 1.0 } else { z.sinh() / z };
        (a / 2.0 + b / 2.0).exp() * sinhc
    } else {
        // e^{max} (1 − e^{−|b−a|}) / |b − a|, with the division folded into the exponent.
        let (hi, gap) = (a.max(b), 2.0 * half_gap.abs());
        let log_gap = half_gap.abs().ln() + std::f64::consts::LN_2;
        (hi - log_gap).exp() * -(-gap).exp_m1()
    }
}

/// The exact discrete model over an interval `dt > 0`: (F, Qd, Bd), Bd empty without B.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Discretized {
    /// e^{A dt}, `n × n`.
    pub f: Vec<f64>,
    /// ∫₀^dt e^{As} Qc e^{A's} ds, `n × n`, symmetric.
    pub qd: Vec<f64>,
    /// ∫₀^dt e^{As} ds B, `n × k` (empty without B).
    pub bd: Vec<f64>,
}

/// (A, Qc, B) as faer matrices after checking shapes, finiteness, and that Qc is symmetric
/// positive semidefinite (an intensity; an indefinite one would give an indefinite Qd).
#[allow(clippy::type_complexity)]
fn continuous_model(
    a: &[f64],
    qc: &[f64],
    b: Option<&[f64]>,
    n: usize,
    k: usize,
) -> Result<(Mat<f64>, Mat<f64>, Option<Mat<f64>>)> {
    let (am, qm) = (checked_mat("A", a, n, n)?, checked_mat("Qc", qc, n, n)?);
    crate::core::validate::check_symmetric(qc, n).map_err(|p| Error::arg("Qc", p))?;
    crate::core::validate::check_psd(qc, n).map_err(|p| Error::arg("Qc", p))?;
    if b.is_some() && k == 0 {
        return Err(Error::arg("B", "has no columns (k = 0 inputs)"));
    }
    Ok((am, qm, b.map(|b| checked_mat("B", b, n, k)).transpose()?))
}

/// Van Loan discretization of (A, Qc, B) over `dt` (docs/algorithms.md, "Van Loan").
///
/// # Errors
/// [`Error::InvalidArgument`] naming `A`, `Qc` (also when not positive semidefinite) or `B`
/// for a wrong size or a non-finite entry, and naming `dt` when it is not positive and finite
/// or when the sampled model overflows double precision (e^{A dt}, Qd or Bd not finite).
pub fn discretize(a: &[f64], qc: &[f64], b: Option<&[f64]>, n: usize, k: usize, dt: f64) -> Result<Discretized> {
    let (am, qm, bm) = continuous_model(a, qc, b, n, k)?;
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(Error::arg("dt", format!("must be positive and finite, got {dt}")));
    }
    discretize_mat(&am, &qm, bm.as_ref(), dt).map_err(|p| Error::arg("dt", p))
}

/// (F, Qd, Bd) over `dt`, or the problem (for an error on `dt`) when they overflow.
///
/// The blocks V = dt [[−A, Qc], [0, A']] and Z = dt [[A, B], [0, 0]] share one Padé degree m
/// and number of halvings s (each chosen as for [`expm`]). At h = dt / 2ˢ, with r_m for the
/// exponential, exp(hV) = [[·, E12], [0, E22]] gives F(h) = E22', Qd(h) = F(h) E12 (Van Loan's
/// inverse-free form) and exp(hZ) = [[F, Bd(h)], [0, I]]. Then s doublings of the interval,
/// from the semigroup property of (4.103),
///
/// ```text
/// Qd(2h) = Qd(h) + F(h) Qd(h) F(h)',   Bd(2h) = Bd(h) + F(h) Bd(h),   F(2h) = F(h)²,
/// ```
///
/// replace the s squarings of exp(V), whose block e^{−A dt} overflows for a stable A long
/// before F and Qd do (A = −1, dt = 1000 has F = e^{−1000} ≈ 0, Qd ≈ the stationary
/// covariance). Each doubling adds a positive semidefinite term, so Qd stays one.
fn discretize_mat(
    a: &Mat<f64>,
    qc: &Mat<f64>,
    b: Option<&Mat<f64>>,
    dt: f64,
) -> std::result::Result<Discretized, String> {
    let n = a.nrows();
    check_resolvable(a, dt)?;
    let overflow = |what: &str| {
        format!(
            "the sampled model overflows double precision at dt = {dt:e} ({what} not finite; ‖A dt‖₁ = {:.6e}, ‖Qc dt‖₁ = {:.6e}): A is too large for this interval, or Qc is; use a shorter one",
            norm1(a) * dt,
            norm1(qc) * dt
        )
    };
    let mut v = Mat::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        for j in 0..n {
            v[(i, j)] = -a[(i, j)] * dt;
            v[(i, n + j)] = qc[(i, j)] * dt;
            v[(n + i, n + j)] = a[(j, i)] * dt;
        }
    }
    let z = b.map(|b| {
        let k = b.ncols();
        let mut z = Mat::<f64>::zeros(n + k, n + k);
        for i in 0..n {
            for j in 0..n {
                z[(i, j)] = a[(i, j)] * dt;
            }
            for j in 0..k {
                z[(i, n + j)] = b[(i, j)] * dt;
            }
        }
        z
    });
    if finite(v.clone()).is_none() || z.as_ref().is_some_and(|z| finite(z.clone()).is_none()) {
        return Err(overflow("A dt, Qc dt or B dt"));
    }
    let sv = scaling(&v).ok_or_else(|| overflow("the 1-norm of [[−A, Qc], [0, A']] dt"))?;
    let sz = match &z {
        Some(z) => Some(scaling(z).ok_or_else(|| overflow("the 1-norm of [A, B] dt"))?),
        None => None,
    };
    let Scaling { degree, squarings } = match sz {
        Some(sz) if sz.squarings > 0 || sv.squarings > 0 => {
            Scaling { degree: 13, squarings: sv.squarings.max(sz.squarings) }
        }
        Some(sz) => Scaling { degree: sv.degree.max(sz.degree), squarings: 0 },
        None => sv,
    };
    let halving = faer::Scale(0.5f64.powi(squarings));
    let ev = pade(&(&v * halving), degree);
    let mut f = Mat::from_fn(n, n, |i, j| ev[(n + j, n + i)]);
    let e12 = Mat::from_fn(n, n, |i, j| ev[(i, n + j)]);
    let mut qd = symmetrized(&f * &e12);
    let mut bd = z.map(|z| {
        let ez = pade(&(&z * halving), degree);
        Mat::from_fn(n, z.ncols() - n, |i, j| ez[(i, n + j)])
    });
    for _ in 0..squarings {
        qd = symmetrized(&qd + &f * &qd * f.transpose());
        if let Some(bd) = bd.as_mut() {
            *bd = &*bd + &f * &*bd;
        }
        f = &f * &f;
    }
    let bd = bd.map_or(Some(Vec::new()), |bd| finite(bd).map(|bd| from_mat(&bd)));
    match (finite(f), finite(qd), bd) {
        (Some(f), Some(qd), Some(bd)) => Ok(Discretized { f: from_mat(&f), qd: from_mat(&qd), bd }),
        _ => Err(overflow("F, Qd or Bd")),
    }
}

/// Refuses an interval over which a mode of A that does not decay meets a norm ‖A dt‖ beyond
/// 1/ε. The doublings F(2h) = F(h)² then number more than 52 and multiply the rounding error of
/// every mode that is not damped by 2ˢ ε ≥ 1: the Singer model at α dt = 1e299 came out as
/// F = 0 (exact: its position and velocity rows keep their ones). Modes that decay over dt
/// (real part below −ε‖A‖, the accuracy of the computed eigenvalues) damp their errors too,
/// so a stable model sampled over any interval stays exact (F → 0, Qd → the stationary
/// covariance), as does a nilpotent one (no scaling at all) and a diagonal one.
fn check_resolvable(a: &Mat<f64>, dt: f64) -> std::result::Result<(), String> {
    let norm = norm1(a);
    let diagonal = (0..a.nrows()).all(|i| (0..a.ncols()).all(|j| i == j || a[(i, j)] == 0.0));
    if norm * dt * f64::EPSILON <= 1.0 || diagonal || nilpotent(a) {
        return Ok(());
    }
    let schur = crate::core::schur::real_schur(a)?;
    let slowest = schur.eigenvalues().iter().map(|(re, _)| *re).fold(f64::NEG_INFINITY, f64::max);
    if slowest < -f64::EPSILON * norm * a.nrows() as f64 {
        return Ok(());
    }
    Err(format!(
        "A is too large for this interval: ‖A dt‖₁ = {:.3e} exceeds 1/ε = 4.5e15 while a mode of A \
         does not decay (eigenvalue real part {slowest:.3e}), so the sampled model would have no \
         correct digit; use a shorter interval or rescale A",
        norm * dt
    ))
}

/// Whether some power of `a` (at most its size) is zero: then its exponential is a finite sum.
fn nilpotent(a: &Mat<f64>) -> bool {
    let mut power = a.clone();
    for _ in 1..a.nrows() {
        power = &power * a;
    }
    (0..a.nrows()).all(|i| (0..a.ncols()).all(|j| power[(i, j)] == 0.0))
}

/// (M + M') / 2.
fn symmetrized(m: Mat<f64>) -> Mat<f64> {
    Mat::from_fn(m.nrows(), m.ncols(), |i, j| 0.5 * (m[(i, j)] + m[(j, i)]))
}

/// [`discretize`] for each interval of `dts`, stacked step-major: F `(T, n, n)`, Qd
/// `(T, n, n)`, Bd `(T, n, k)`. Equal intervals are computed once.
///
/// # Errors
/// As [`discretize`], with the step of the offending interval; also for no interval at all.
pub fn discretize_steps(
    a: &[f64],
    qc: &[f64],
    b: Option<&[f64]>,
    n: usize,
    k: usize,
    dts: &[f64],
) -> Result<Discretized> {
    let (am, qm, bm) = continuous_model(a, qc, b, n, k)?;
    if dts.is_empty() {
        return Err(Error::arg("dt", "no interval given (an empty array)"));
    }
    if let Some((t, dt)) = dts.iter().enumerate().find(|(_, dt)| !(**dt > 0.0 && dt.is_finite())) {
        return Err(Error::arg_at("dt", t, format!("must be positive and finite, got {dt}")));
    }
    let mut out = Discretized { f: Vec::with_capacity(dts.len() * n * n), qd: Vec::new(), bd: Vec::new() };
    let mut last: Option<(f64, Discretized)> = None;
    for (t, &dt) in dts.iter().enumerate() {
        let step = match &last {
            Some((prev, d)) if *prev == dt => d.clone(),
            _ => discretize_mat(&am, &qm, bm.as_ref(), dt).map_err(|p| Error::arg_at("dt", t, p))?,
        };
        out.f.extend_from_slice(&step.f);
        out.qd.extend_from_slice(&step.qd);
        out.bd.extend_from_slice(&step.bd);
        last = Some((dt, step));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// b_j ∝ (2m − j)! m! / ((2m)! j! (m − j)!) (Higham 2005, (2.1)): the tables are that
    /// sequence scaled so that b_m = 1.
    #[test]
    fn pade_tables_follow_the_closed_form() {
        let tables: [&[f64]; 5] = [&PADE3, &PADE5, &PADE7, &PADE9, &PADE13];
        for table in tables {
            let m = table.len() - 1;
            // b_j (m − j) = b_{j+1} (j + 1)(2m − j), in exact integers (every b_j is one).
            for j in 0..m {
                let (bj, bj1) = (table[j] as u128, table[j + 1] as u128);
                assert_eq!(bj as f64, table[j], "degree {m}: b_{j} is an integer");
                assert_eq!(bj * (m - j) as u128, bj1 * ((j + 1) * (2 * m - j)) as u128, "degree {m}, b_{j}");
            }
            assert_eq!(table[m], 1.0);
        }
    }

    #[test]
    fn pade_error_constant_matches_al_mohy_higham() {
        // 1/|c_{2m+1}| = (2m)! (2m+1)! / (m!)²: 100800 for m = 3, 1.1325e35 for m = 13.
        assert!((log2_pade_error_recip(3).exp2() / 100_800.0 - 1.0).abs() < 1e-12);
        assert!((log2_pade_error_recip(13).exp2() / 1.132_507_756_060_211_1e35 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn nilpotent_and_zero_need_no_squaring() {
        let zero = Mat::<f64>::zeros(3, 3);
        assert_eq!(scaling(&zero), Some(Scaling { degree: 3, squarings: 0 }));
        // ‖A‖₁ = 1e20 but A² = 0: degree 3, no squaring (the old ‖A‖₁ rule squared 64 times).
        let mut a = Mat::<f64>::zeros(2, 2);
        a[(0, 1)] = 1e20;
        assert_eq!(scaling(&a), Some(Scaling { degree: 3, squarings: 0 }));
    }

    #[test]
    fn scaling_grows_with_the_norm_of_a_normal_matrix() {
        // A rotation generator of angle θ: d_k = θ for every k, so s = ⌈log₂(θ / θ₁₃)⌉ (+ ℓ).
        for (theta, degree, min_s, max_s) in [(0.01, 3, 0, 0), (0.2, 5, 0, 0), (2.0, 9, 0, 0), (1e3, 13, 8, 9)] {
            let mut a = Mat::<f64>::zeros(2, 2);
            (a[(0, 1)], a[(1, 0)]) = (-theta, theta);
            let s = scaling(&a).unwrap();
            assert_eq!(s.degree, degree, "θ = {theta}: {s:?}");
            assert!((min_s..=max_s).contains(&s.squarings), "θ = {theta}: {s:?}");
        }
    }

    #[test]
    fn divided_difference_of_exp() {
        for (a, b, want) in [
            (0.0, 0.0, 1.0),
            (1.0, 1.0, 1f64.exp()),
            (-2000.0, 0.0, (1.0 - (-2000f64).exp()) / 2000.0),
            (0.0, 1e-9, (1e-9f64).exp_m1() / 1e-9),
            (-1.0, -2.0, ((-1f64).exp() - (-2f64).exp())),
            (700.0, -1e300, 700f64.exp() / 1e300),
        ] {
            let got = exp_divided_difference(a, b);
            // exp amplifies the rounding of its argument x by |x| (at most 700 before overflow).
            let rtol = 1e-14 * (1.0 + a.abs().max(b.abs()).min(710.0));
            assert!((got - want).abs() <= rtol * want.abs(), "f[{a}, {b}] = {got:e}, want {want:e}");
            assert_eq!(got, exp_divided_difference(b, a), "symmetric in its arguments");
        }
    }

    #[test]
    fn empty_matrices() {
        assert_eq!(expm(&[], 0), Ok(vec![]));
        let d = discretize(&[], &[], None, 0, 0, 1.0).unwrap();
        assert!(d.f.is_empty() && d.qd.is_empty());
    }
}
