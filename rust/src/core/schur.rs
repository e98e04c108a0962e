//! Real Schur decomposition `A = Z T Z'` (Z orthogonal, T upper quasi-triangular with 1×1 and
//! 2×2 diagonal blocks), by Householder reduction to Hessenberg form and Francis double-shift
//! QR steps (Golub & Van Loan, Algorithms 7.4.2 and 7.5.1–7.5.2). The Bartels–Stewart
//! Lyapunov solvers are built on it. faer does not expose its real Schur form, hence this.

use faer::Mat;

/// `A = Z T Z'`.
#[derive(Debug, Clone)]
pub(crate) struct RealSchur {
    pub t: Mat<f64>,
    pub z: Mat<f64>,
}

impl RealSchur {
    /// The diagonal blocks of T as (start, size) with size 1 or 2.
    pub fn blocks(&self) -> Vec<(usize, usize)> {
        let n = self.t.nrows();
        let mut out = Vec::with_capacity(n);
        let mut i = 0;
        while i < n {
            let size = if i + 1 < n && self.t[(i + 1, i)] != 0.0 { 2 } else { 1 };
            out.push((i, size));
            i += size;
        }
        out
    }

    /// Eigenvalues (re, im) from the diagonal blocks.
    pub fn eigenvalues(&self) -> Vec<(f64, f64)> {
        let t = &self.t;
        let mut out = Vec::with_capacity(t.nrows());
        for (i, size) in self.blocks() {
            if size == 1 {
                out.push((t[(i, i)], 0.0));
            } else {
                let (a, b, c, d) = (t[(i, i)], t[(i, i + 1)], t[(i + 1, i)], t[(i + 1, i + 1)]);
                let half_tr = 0.5 * (a + d);
                let disc = 0.25 * (a - d) * (a - d) + b * c;
                if disc >= 0.0 {
                    out.push((half_tr + disc.sqrt(), 0.0));
                    out.push((half_tr - disc.sqrt(), 0.0));
                } else {
                    out.push((half_tr, (-disc).sqrt()));
                    out.push((half_tr, -(-disc).sqrt()));
                }
            }
        }
        out
    }
}

/// Householder vector `v` (v[0] = 1 implied by scaling) and β with (I − β v v') x = α e1.
fn householder(x: &[f64], v: &mut [f64]) -> f64 {
    let norm = x.iter().map(|a| a * a).sum::<f64>().sqrt();
    v.copy_from_slice(x);
    if norm == 0.0 {
        return 0.0;
    }
    let alpha = if x[0] > 0.0 { -norm } else { norm };
    v[0] -= alpha;
    let vv: f64 = v.iter().map(|a| a * a).sum();
    if vv == 0.0 {
        0.0
    } else {
        2.0 / vv
    }
}

/// Rows `rows` of `h`, columns `cols`: h ← (I − β v v') h.
fn reflect_rows(h: &mut Mat<f64>, v: &[f64], beta: f64, r0: usize, cols: std::ops::Range<usize>) {
    for j in cols {
        let s: f64 = v.iter().enumerate().map(|(a, va)| va * h[(r0 + a, j)]).sum::<f64>() * beta;
        for (a, va) in v.iter().enumerate() {
            h[(r0 + a, j)] -= s * va;
        }
    }
}

/// Columns starting at `c0` of `h`, rows `rows`: h ← h (I − β v v').
fn reflect_cols(h: &mut Mat<f64>, v: &[f64], beta: f64, c0: usize, rows: std::ops::Range<usize>) {
    for i in rows {
        let s: f64 = v.iter().enumerate().map(|(a, va)| va * h[(i, c0 + a)]).sum::<f64>() * beta;
        for (a, va) in v.iter().enumerate() {
            h[(i, c0 + a)] -= s * va;
        }
    }
}

/// Real Schur decomposition of the square `a`; `Err` if the QR iteration does not converge
/// (non-finite input or pathological cases).
pub(crate) fn real_schur(a: &Mat<f64>) -> Result<RealSchur, String> {
    let n = a.nrows();
    let mut h = a.clone();
    let mut z = Mat::<f64>::identity(n, n);
    if (0..n).any(|j| (0..n).any(|i| !h[(i, j)].is_finite())) {
        return Err("the matrix has non-finite entries".into());
    }
    // Hessenberg reduction: zero column k below the subdiagonal.
    let mut v = vec![0.0; n];
    for k in 0..n.saturating_sub(2) {
        let x: Vec<f64> = (k + 1..n).map(|i| h[(i, k)]).collect();
        let len = x.len();
        let beta = householder(&x, &mut v[..len]);
        if beta == 0.0 {
            continue;
        }
        reflect_rows(&mut h, &v[..len], beta, k + 1, k..n);
        reflect_cols(&mut h, &v[..len], beta, k + 1, 0..n);
        reflect_cols(&mut z, &v[..len], beta, k + 1, 0..n);
        for i in k + 2..n {
            h[(i, k)] = 0.0;
        }
    }
    // Francis QR iterations with deflation, on the active window [lo, hi].
    let eps = f64::EPSILON;
    let mut hi = n as isize - 1;
    let mut iter = 0;
    let mut total = 0;
    while hi >= 1 {
        let hu = hi as usize;
        let mut lo = hu;
        while lo > 0 {
            let scale = h[(lo - 1, lo - 1)].abs() + h[(lo, lo)].abs();
            let scale = if scale == 0.0 { 1.0 } else { scale };
            if h[(lo, lo - 1)].abs() <= eps * scale {
                h[(lo, lo - 1)] = 0.0;
                break;
            }
            lo -= 1;
        }
        if lo == hu {
            hi -= 1;
            iter = 0;
            continue;
        }
        if lo + 1 == hu {
            hi -= 2;
            iter = 0;
            continue;
        }
        iter += 1;
        total += 1;
        if iter > 100 || total > 100 * n.max(1) {
            return Err("the QR iteration did not converge".into());
        }
        let (s, t) = if iter % 11 == 10 {
            // Exceptional shift to break cycles.
            let x = h[(hu, hu - 1)].abs() + h[(hu - 1, hu - 2)].abs();
            (1.5 * x, x * x)
        } else {
            let (a, b, c, d) = (h[(hu - 1, hu - 1)], h[(hu - 1, hu)], h[(hu, hu - 1)], h[(hu, hu)]);
            (a + d, a * d - b * c)
        };
        francis_step(&mut h, &mut z, lo, hu, s, t);
    }
    Ok(RealSchur { t: h, z })
}

/// One implicit double-shift QR step on the window [lo, hi] with shifts of sum `s` and
/// product `t`; T is kept complete (rows right of and columns above the window updated).
fn francis_step(h: &mut Mat<f64>, z: &mut Mat<f64>, lo: usize, hi: usize, s: f64, t: f64) {
    let n = h.nrows();
    let mut x = h[(lo, lo)] * h[(lo, lo)] + h[(lo, lo + 1)] * h[(lo + 1, lo)] - s * h[(lo, lo)] + t;
    let mut y = h[(lo + 1, lo)] * (h[(lo, lo)] + h[(lo + 1, lo + 1)] - s);
    let mut w = h[(lo + 1, lo)] * h[(lo + 2, lo + 1)];
    let mut v = [0.0; 3];
    for k in lo..hi - 1 {
        let beta = householder(&[x, y, w], &mut v);
        let q = if k > lo { k - 1 } else { lo };
        if beta != 0.0 {
            reflect_rows(h, &v, beta, k, q..n);
            let r = (k + 3).min(hi);
            reflect_cols(h, &v, beta, k, 0..r + 1);
            reflect_cols(z, &v, beta, k, 0..n);
        }
        if k > lo {
            h[(k + 1, k - 1)] = 0.0;
            h[(k + 2, k - 1)] = 0.0;
        }
        x = h[(k + 1, k)];
        y = h[(k + 2, k)];
        if k + 3 <= hi {
            w = h[(k + 3, k)];
        }
    }
    let mut v2 = [0.0; 2];
    let beta = householder(&[x, y], &mut v2);
    if beta != 0.0 {
        reflect_rows(h, &v2, beta, hi - 1, hi - 2..n);
        reflect_cols(h, &v2, beta, hi - 1, 0..hi + 1);
        reflect_cols(z, &v2, beta, hi - 1, 0..n);
    }
    h[(hi, hi - 2)] = 0.0;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random(n: usize, seed: u64) -> Mat<f64> {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        Mat::from_fn(n, n, |_, _| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
    }

    #[test]
    fn reconstructs_and_is_quasi_triangular() {
        for n in [1, 2, 3, 5, 8, 17, 40] {
            for seed in 0..5 {
                let a = random(n, seed * 31 + n as u64);
                let s = real_schur(&a).unwrap();
                let back = &s.z * &s.t * s.z.transpose();
                assert!((&back - &a).norm_max() < 1e-12 * (1.0 + a.norm_max()) * n as f64, "n={n}");
                let ztz = s.z.transpose() * &s.z;
                assert!((&ztz - Mat::<f64>::identity(n, n)).norm_max() < 1e-13 * n as f64);
                for (i, size) in s.blocks() {
                    for r in i + size..n {
                        for c in i..i + size {
                            assert_eq!(s.t[(r, c)], 0.0, "below the blocks, n={n}");
                        }
                    }
                }
                let mut ours: Vec<f64> = s.eigenvalues().iter().map(|e| e.0 * e.0 + e.1 * e.1).collect();
                let mut theirs: Vec<f64> = a.eigenvalues().unwrap().iter().map(|e| e.re * e.re + e.im * e.im).collect();
                ours.sort_by(f64::total_cmp);
                theirs.sort_by(f64::total_cmp);
                for (o, t) in ours.iter().zip(&theirs) {
                    assert!((o - t).abs() < 1e-9 * (1.0 + t), "n={n}: {o} vs {t}");
                }
            }
        }
    }

    #[test]
    fn handles_structured_matrices() {
        // A rotation (complex pair on the unit circle), a Jordan block, the zero matrix.
        let rot = Mat::from_fn(2, 2, |i, j| [[0.0, -1.0], [1.0, 0.0]][i][j]);
        let jordan = Mat::from_fn(3, 3, |i, j| {
            if i == j {
                2.0
            } else if j == i + 1 {
                1.0
            } else {
                0.0
            }
        });
        for a in [rot, jordan, Mat::<f64>::zeros(4, 4)] {
            let s = real_schur(&a).unwrap();
            let back = &s.z * &s.t * s.z.transpose();
            assert!((&back - &a).norm_max() < 1e-13);
        }
    }
}
