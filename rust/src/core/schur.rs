//! Real Schur decomposition `A = Z T Z'` (Z orthogonal, T upper quasi-triangular with 1×1 and
//! 2×2 diagonal blocks), by Householder reduction to Hessenberg form and Francis double-shift
//! QR steps (Golub & Van Loan, Algorithms 7.4.2 and 7.5.1–7.5.2). The Bartels–Stewart
//! Lyapunov solvers are built on it. faer does not expose its real Schur form, hence this.

use faer::Mat;

use crate::core::dense::dot;
use crate::core::dims::Dyn;
use crate::core::isa::run_wide;

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

/// A square matrix stored by columns in one buffer: the QR sweeps' inner loops run down
/// contiguous columns (faer's element indexing cost 2× at n = 20).
struct Square {
    n: usize,
    a: Vec<f64>,
    /// Scratch for the column reflections (one entry per row).
    work: Vec<f64>,
}

impl Square {
    fn from_mat(m: &Mat<f64>) -> Self {
        let n = m.nrows();
        let a = (0..n).flat_map(|j| (0..n).map(move |i| m[(i, j)])).collect();
        Square { n, a, work: vec![0.0; n] }
    }

    fn identity(n: usize) -> Self {
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            a[i * n + i] = 1.0;
        }
        Square { n, a, work: vec![0.0; n] }
    }

    fn to_mat(&self) -> Mat<f64> {
        Mat::from_fn(self.n, self.n, |i, j| self[(i, j)])
    }

    /// Rows `r0 ..` (as many as `v`) of columns `cols`: h ← (I − β v v') h.
    #[inline(always)]
    fn reflect_rows(&mut self, v: &[f64], beta: f64, r0: usize, cols: std::ops::Range<usize>) {
        let n = self.n;
        for j in cols {
            let col = &mut self.a[j * n + r0..j * n + r0 + v.len()];
            // Four partial sums: a sequential sum, one dependent addition per entry, made
            // these reflections half of the eigenvalue solve at n = 100.
            let s = beta * dot::<Dyn>(col, v);
            for (c, va) in col.iter_mut().zip(v) {
                *c -= s * va;
            }
        }
    }

    /// Columns `c0 ..` (as many as `v`) of rows `rows`: h ← h (I − β v v').
    #[inline(always)]
    fn reflect_cols(&mut self, v: &[f64], beta: f64, c0: usize, rows: std::ops::Range<usize>) {
        let n = self.n;
        let w = &mut self.work[rows.clone()];
        w.fill(0.0);
        for (a, va) in v.iter().enumerate() {
            let col = &self.a[(c0 + a) * n..][rows.clone()];
            for (wi, c) in w.iter_mut().zip(col) {
                *wi += va * c;
            }
        }
        for (a, va) in v.iter().enumerate() {
            let col = &mut self.a[(c0 + a) * n..][rows.clone()];
            let f = beta * va;
            for (c, wi) in col.iter_mut().zip(w.iter()) {
                *c -= f * wi;
            }
        }
    }

    /// [`reflect_rows`](Self::reflect_rows) for a short reflector of the QR sweeps (length 2
    /// or 3) in one pass per column.
    #[inline(always)]
    fn reflect_rows_short<const L: usize>(&mut self, v: [f64; L], beta: f64, r0: usize, cols: std::ops::Range<usize>) {
        let n = self.n;
        let bv = v.map(|x| beta * x);
        for j in cols {
            let col = &mut self.a[j * n + r0..j * n + r0 + L];
            let s: f64 = col.iter().zip(&v).map(|(c, va)| c * va).sum();
            for (c, b) in col.iter_mut().zip(&bv) {
                *c -= s * b;
            }
        }
    }

    /// [`reflect_cols`](Self::reflect_cols) for a short reflector in one pass over the rows,
    /// where the general one passes twice through a work buffer: the sweeps' column
    /// reflections vectorize across the rows.
    #[inline(always)]
    fn reflect_cols_short<const L: usize>(&mut self, v: [f64; L], beta: f64, c0: usize, rows: std::ops::Range<usize>) {
        let n = self.n;
        let bv = v.map(|x| beta * x);
        let block = &mut self.a[c0 * n..(c0 + L) * n];
        let mut cols: [&mut [f64]; L] = split_columns(block, n).map(|c| &mut c[rows.clone()]);
        for i in 0..rows.len() {
            let mut s = 0.0;
            for (c, va) in cols.iter().zip(&v) {
                s += c[i] * va;
            }
            for (c, b) in cols.iter_mut().zip(&bv) {
                c[i] -= s * b;
            }
        }
    }
}

/// The `L` columns of a column-major block of height `n`, as separate slices.
#[inline(always)]
fn split_columns<const L: usize>(block: &mut [f64], n: usize) -> [&mut [f64]; L] {
    let mut rest = block;
    std::array::from_fn(|_| {
        let (col, tail) = std::mem::take(&mut rest).split_at_mut(n);
        rest = tail;
        col
    })
}

impl std::ops::Index<(usize, usize)> for Square {
    type Output = f64;
    fn index(&self, (i, j): (usize, usize)) -> &f64 {
        &self.a[i + j * self.n]
    }
}

impl std::ops::IndexMut<(usize, usize)> for Square {
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut f64 {
        &mut self.a[i + j * self.n]
    }
}

/// Householder vector `v` (v[0] = 1 implied by scaling) and β with (I − β v v') x = α e1.
#[inline(always)]
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

/// Real Schur decomposition of the square `a`; `Err` if the QR iteration does not converge
/// (non-finite input or pathological cases).
pub(crate) fn real_schur(a: &Mat<f64>) -> Result<RealSchur, String> {
    let mut h = Square::from_mat(a);
    let mut z = Square::identity(a.nrows());
    run_wide(
        #[inline(always)]
        || reduce(&mut h, Some(&mut z)),
    )?;
    Ok(RealSchur { t: h.to_mat(), z: z.to_mat() })
}

/// Eigenvalues (re, im) of the square `a`, without the Schur vectors: the matrix is balanced
/// first (Parlett & Reinsch, scaling by powers of 2, exact in floating point) and the QR steps
/// touch only the active window (LAPACK's `dhseqr` with job "E"). About 3× cheaper than
/// [`real_schur`], and 2–3× faster than faer's `eigenvalues` at n = 20–100 (Zen 3;
/// docs/decisions.md). Both run with AVX2 where the CPU has it ([`run_wide`]: separate
/// multiplies and adds, the same bits on every CPU).
pub(crate) fn eigenvalues(a: &Mat<f64>) -> Result<Vec<(f64, f64)>, String> {
    let mut h = Square::from_mat(a);
    run_wide(
        #[inline(always)]
        || {
            balance(&mut h);
            reduce(&mut h, None)
        },
    )?;
    Ok(RealSchur { t: h.to_mat(), z: Mat::new() }.eigenvalues())
}

/// Parlett–Reinsch balancing: D⁻¹ A D with D diagonal powers of 2 chosen so that each row and
/// column have comparable norms; the eigenvalues are unchanged and their computed values much
/// less sensitive (companion matrices above all).
#[inline(always)]
fn balance(a: &mut Square) {
    let n = a.n;
    let radix = 2.0_f64;
    let mut converged = false;
    while !converged {
        converged = true;
        for i in 0..n {
            let c: f64 = (0..n).filter(|&j| j != i).map(|j| a[(j, i)].abs()).sum();
            let r: f64 = (0..n).filter(|&j| j != i).map(|j| a[(i, j)].abs()).sum();
            if c == 0.0 || r == 0.0 || !(c + r).is_finite() {
                continue;
            }
            let (mut g, mut f, s) = (r / radix, 1.0, c + r);
            let mut c = c;
            while c < g {
                f *= radix;
                c *= radix * radix;
            }
            g = r * radix;
            while c > g {
                f /= radix;
                c /= radix * radix;
            }
            if (c + r / f) < 0.95 * s * f {
                converged = false;
                for j in 0..n {
                    a[(i, j)] /= f;
                }
                for j in 0..n {
                    a[(j, i)] *= f;
                }
            }
        }
    }
}

/// Hessenberg reduction and Francis QR iterations in place: `h` becomes T. With `z`, the
/// transformations are accumulated and T is kept complete; without, only the active window
/// is updated (T's eigenvalue blocks are right, the rest of T is not).
#[inline(always)]
fn reduce(h: &mut Square, mut z: Option<&mut Square>) -> Result<(), String> {
    let n = h.n;
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
        h.reflect_rows(&v[..len], beta, k + 1, k..n);
        h.reflect_cols(&v[..len], beta, k + 1, 0..n);
        if let Some(z) = z.as_deref_mut() {
            z.reflect_cols(&v[..len], beta, k + 1, 0..n);
        }
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
        francis_step(h, z.as_deref_mut(), lo, hu, s, t);
    }
    Ok(())
}

/// One implicit double-shift QR step on the window [lo, hi] with shifts of sum `s` and
/// product `t`. With `z`, T is kept complete (rows right of and columns above the window
/// updated) and the reflections accumulated; without, only the window is touched.
#[inline(always)]
fn francis_step(h: &mut Square, mut z: Option<&mut Square>, lo: usize, hi: usize, s: f64, t: f64) {
    let n = h.n;
    let (row_end, col_start) = if z.is_some() { (n, 0) } else { (hi + 1, lo) };
    let mut x = h[(lo, lo)] * h[(lo, lo)] + h[(lo, lo + 1)] * h[(lo + 1, lo)] - s * h[(lo, lo)] + t;
    let mut y = h[(lo + 1, lo)] * (h[(lo, lo)] + h[(lo + 1, lo + 1)] - s);
    let mut w = h[(lo + 1, lo)] * h[(lo + 2, lo + 1)];
    let mut v = [0.0; 3];
    for k in lo..hi - 1 {
        let beta = householder(&[x, y, w], &mut v);
        let q = if k > lo { k - 1 } else { lo };
        if beta != 0.0 {
            h.reflect_rows_short(v, beta, k, q..row_end);
            let r = (k + 3).min(hi);
            h.reflect_cols_short(v, beta, k, col_start..r + 1);
            if let Some(z) = z.as_deref_mut() {
                z.reflect_cols_short(v, beta, k, 0..n);
            }
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
        h.reflect_rows_short(v2, beta, hi - 1, hi - 2..row_end);
        h.reflect_cols_short(v2, beta, hi - 1, col_start..hi + 1);
        if let Some(z) = z {
            z.reflect_cols_short(v2, beta, hi - 1, 0..n);
        }
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
    fn eigenvalues_only_agree_with_the_schur_form() {
        for n in [1, 2, 3, 5, 8, 20, 50] {
            for seed in 0..5 {
                let unscaled = random(n, seed * 17 + n as u64);
                let mut a = unscaled.clone();
                // Badly scaled: balancing must not change the eigenvalues.
                for i in 0..n {
                    a[(i, 0)] *= 1e4;
                    a[(0, i)] *= 1e-4;
                }
                let mut ours = eigenvalues(&a).unwrap();
                let mut theirs = real_schur(&unscaled).unwrap().eigenvalues();
                let key = |e: &(f64, f64)| (e.0 * 1e6).round() as i64 * 1_000_000 + (e.1 * 1e3).round() as i64;
                ours.sort_by_key(key);
                theirs.sort_by_key(key);
                for (o, t) in ours.iter().zip(&theirs) {
                    let scale = 1.0 + t.0.hypot(t.1);
                    assert!((o.0 - t.0).abs() + (o.1 - t.1).abs() < 1e-8 * scale, "n={n}: {o:?} vs {t:?}");
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
