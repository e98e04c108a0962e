//! Matrix exponential and exact discretization of continuous-time models
//! (Söderström (4.99)–(4.103), ex. 4.6; docs/algorithms.md, "Sampling"):
//!
//! ```text
//! dx = A x dt + B u dt + dβ,   E dβ dβ' = Qc dt   (Qc: a continuous white-noise intensity)
//! F = e^{A h},   Qd = ∫₀ʰ e^{As} Qc e^{A's} ds,   Bd = ∫₀ʰ e^{As} ds B   (zero-order hold)
//! ```
//!
//! [`expm`] is scaling and squaring with the degree-13 Padé approximant (Higham 2005);
//! [`discretize`] uses Van Loan's block exponential in its inverse-free form
//! `exp(h [[−A, Qc], [0, A']]) = [[·, E12], [0, E22]]`, F = E22', Qd = F E12, which never
//! inverts e^{A'h}. Matrices are row-major.

use faer::linalg::solvers::Solve;
use faer::Mat;

use crate::core::mat::{checked_mat, from_mat, to_mat};
use crate::error::{Error, Result};

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
/// ‖A‖₁ up to which the degree-13 Padé approximant is accurate to double precision.
const THETA13: f64 = 5.371_920_351_148_152;

/// e^A of the `n × n` row-major `a`.
pub fn expm(a: &[f64], n: usize) -> Result<Vec<f64>> {
    if a.len() != n * n {
        return Err(Error::arg("a", format!("expected an ({n}, {n}) matrix, got {} entries", a.len())));
    }
    if let Some(v) = a.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("a", format!("contains a non-finite value ({v})")));
    }
    Ok(from_mat(&expm_mat(&to_mat(a, n))))
}

pub(crate) fn expm_mat(a: &Mat<f64>) -> Mat<f64> {
    let n = a.nrows();
    let norm1 = (0..n).map(|j| (0..n).map(|i| a[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max);
    let squarings = if norm1 > THETA13 { (norm1 / THETA13).log2().ceil() as i32 } else { 0 };
    let a = a * faer::Scale(0.5f64.powi(squarings));
    let id = Mat::<f64>::identity(n, n);
    let a2 = &a * &a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let b = &PADE13;
    let scaled = |m: &Mat<f64>, c: f64| m * faer::Scale(c);
    let u_inner = &a6 * (scaled(&a6, b[13]) + scaled(&a4, b[11]) + scaled(&a2, b[9]))
        + scaled(&a6, b[7])
        + scaled(&a4, b[5])
        + scaled(&a2, b[3])
        + scaled(&id, b[1]);
    let u = &a * u_inner;
    let v = &a6 * (scaled(&a6, b[12]) + scaled(&a4, b[10]) + scaled(&a2, b[8]))
        + scaled(&a6, b[6])
        + scaled(&a4, b[4])
        + scaled(&a2, b[2])
        + scaled(&id, b[0]);
    let mut r = (&v - &u).partial_piv_lu().solve(&v + &u);
    for _ in 0..squarings {
        r = &r * &r;
    }
    r
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

/// (A, Qc, B) as faer matrices after checking shapes, finiteness and the symmetry of Qc.
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
    Ok((am, qm, b.map(|b| checked_mat("B", b, n, k)).transpose()?))
}

/// Van Loan discretization of (A, Qc, B) over `dt` (docs/algorithms.md, "Van Loan").
pub fn discretize(a: &[f64], qc: &[f64], b: Option<&[f64]>, n: usize, k: usize, dt: f64) -> Result<Discretized> {
    let (am, qm, bm) = continuous_model(a, qc, b, n, k)?;
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(Error::arg("dt", format!("must be positive and finite, got {dt}")));
    }
    Ok(discretize_mat(&am, &qm, bm.as_ref(), dt))
}

fn discretize_mat(a: &Mat<f64>, qc: &Mat<f64>, b: Option<&Mat<f64>>, dt: f64) -> Discretized {
    let n = a.nrows();
    // exp(dt [[−A, Qc], [0, A']]) = [[·, E12], [0, E22]]:  F = E22',  Qd = F E12.
    let mut m = Mat::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = -a[(i, j)] * dt;
            m[(i, n + j)] = qc[(i, j)] * dt;
            m[(n + i, n + j)] = a[(j, i)] * dt;
        }
    }
    let e = expm_mat(&m);
    let f = Mat::from_fn(n, n, |i, j| e[(n + j, n + i)]);
    let e12 = Mat::from_fn(n, n, |i, j| e[(i, n + j)]);
    let qd = &f * &e12;
    let mut qd_v = from_mat(&qd);
    crate::core::dense::symmetrize(&mut qd_v, n);
    let bd = match b {
        Some(b) => {
            // exp(dt [[A, B], [0, 0]]) = [[F, Bd], [0, I]]
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
            let ez = expm_mat(&z);
            from_mat(&Mat::from_fn(n, k, |i, j| ez[(i, n + j)]))
        }
        None => Vec::new(),
    };
    Discretized { f: from_mat(&f), qd: qd_v, bd }
}

/// [`discretize`] for each interval of `dts`, stacked step-major: F `(T, n, n)`, Qd
/// `(T, n, n)`, Bd `(T, n, k)`. Equal intervals are computed once.
pub fn discretize_steps(
    a: &[f64],
    qc: &[f64],
    b: Option<&[f64]>,
    n: usize,
    k: usize,
    dts: &[f64],
) -> Result<Discretized> {
    let (am, qm, bm) = continuous_model(a, qc, b, n, k)?;
    if let Some((t, dt)) = dts.iter().enumerate().find(|(_, dt)| !(**dt > 0.0 && dt.is_finite())) {
        return Err(Error::arg_at("dt", t, format!("must be positive and finite, got {dt}")));
    }
    let mut out = Discretized { f: Vec::with_capacity(dts.len() * n * n), qd: Vec::new(), bd: Vec::new() };
    let mut last: Option<(f64, Discretized)> = None;
    for &dt in dts {
        let step = match &last {
            Some((prev, d)) if *prev == dt => d.clone(),
            _ => discretize_mat(&am, &qm, bm.as_ref(), dt),
        };
        out.f.extend_from_slice(&step.f);
        out.qd.extend_from_slice(&step.qd);
        out.bd.extend_from_slice(&step.bd);
        last = Some((dt, step));
    }
    Ok(out)
}
