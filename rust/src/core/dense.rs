//! Small dense kernels on row-major slices.
//!
//! The filter's matrices are small (n ≤ 12 in most uses), so these are plain loops the compiler
//! can unroll once the sizes are known; they never allocate. An `a[r×c]` in the docs is a slice
//! of `r * c` numbers holding a row-major `r × c` matrix.
//!
//! The matrix products take the [`Dims`] they serve as a type: with compile-time sizes up to
//! n = 8 a plain loop over rows, which the compiler unrolls whole, is fastest; above that and
//! with run-time sizes the blocked form keeps a few results in registers (`blocked_product`).
//! Both sum every entry in the same order, from the first term, so they give the same numbers
//! (the sign of an exact zero aside: the plain products start from their first term or from
//! −0.0, which the compiler can drop, while the blocked sums start from 0.0, which vectorizes
//! better — measured both ways, ~10% of a step either side).
//!
//! With [`Fused`](crate::core::dims::Fused) sizes every multiply-add of the products, of the
//! L D L' factorization and of its solves is one `mul_add` (rounded once), in the same order;
//! those kernels must be inlined into a loop compiled with FMA (`core::isa`), or `mul_add`
//! becomes a call into the runtime library. Products of run-time sizes above 12 go to faer
//! only with fused sizes: faer picks its kernels (and their rounding) per CPU, which
//! deterministic mode rules out. With fused compile-time sizes and n = 3 or 4 the filter and
//! smoother steps use `core::rows4` instead, which computes the same sums on AVX2 registers.

use crate::core::dims::{Dims, Dyn};

/// `acc + a · b`, rounded once for [`Fused`](crate::core::dims::Fused) sizes.
#[inline(always)]
fn madd<D: Dims>(acc: f64, a: f64, b: f64) -> f64 {
    if D::FUSED {
        a.mul_add(b, acc)
    } else {
        acc + a * b
    }
}

/// `acc − a · b`, rounded once for [`Fused`](crate::core::dims::Fused) sizes.
#[inline(always)]
fn msub<D: Dims>(acc: f64, a: f64, b: f64) -> f64 {
    madd::<D>(acc, -a, b)
}

/// Products of run-time sizes with at least this many multiply-adds and a dimension above 12 go
/// to faer's blocked, SIMD matrix product; all others stay in the loops here. Measured on the
/// W8 random models (Joseph form, x_filt and P_filt stored), ns per step with run-time sizes,
/// m = 1: n = 9 loops 934, faer from 8³ 1133; n = 16 loops 3446, faer 2508 (2026-12-02).
pub(crate) const FAER_MIN_FLOPS: usize = 8 * 8 * 8 + 1;

/// Whether an `m × k` by `k × n` product goes to faer: only for sizes that allow it
/// ([`Dims::FAER`]: not compile-time sizes; fused ones not in deterministic mode, read here
/// so that a loop's products need no second instance) and only with a dimension above 12. So a problem within the compiled sizes computes the same bits whether
/// it runs with compile-time or run-time sizes (faer sums in another order), which
/// `filter_batch` relies on: its shared covariance recursion runs with run-time sizes, each
/// series' mean with compile-time ones.
#[inline(always)]
fn use_faer<D: Dims>(m: usize, k: usize, n: usize) -> bool {
    D::FAER && m * k * n >= FAER_MIN_FLOPS && m.max(k).max(n) > 12 && !(D::FUSED && crate::core::isa::deterministic())
}

fn faer_mul(c: &mut [f64], a: faer::MatRef<'_, f64>, b: faer::MatRef<'_, f64>) {
    let c = faer::MatMut::from_row_major_slice_mut(c, a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(c, faer::Accum::Replace, a, b, 1.0, faer::Par::Seq);
}

/// `c[m×n] = a[m×k] · b[k×n]`.
#[inline(always)]
pub(crate) fn mul<D: Dims>(c: &mut [f64], a: &[f64], b: &[f64], m: usize, k: usize, n: usize) {
    if use_faer::<D>(m, k, n) {
        let (a, b) = (faer::MatRef::from_row_major_slice(a, m, k), faer::MatRef::from_row_major_slice(b, k, n));
        return faer_mul(c, a, b);
    }
    if D::UNROLL {
        if k == 0 {
            return c[..m * n].fill(0.0);
        }
        for i in 0..m {
            let ci = &mut c[i * n..(i + 1) * n];
            // From the first term, not from 0.0: 0.0 + x cannot be folded (it turns −0.0
            // into 0.0), and that add sits on the step's latency chain (S = H P H', F P).
            let ai0 = a[i * k];
            for (cij, b0j) in ci.iter_mut().zip(&b[..n]) {
                *cij = ai0 * b0j;
            }
            for l in 1..k {
                let ail = a[i * k + l];
                for (cij, blj) in ci.iter_mut().zip(&b[l * n..(l + 1) * n]) {
                    *cij = madd::<D>(*cij, ail, *blj);
                }
            }
        }
        return;
    }
    blocked_product::<D>(c, a, b, m, k, n, false);
}

/// `c[m×n] = a[m×k] · b[k×n]` (with `upper`, m = n and only the upper triangle) in blocks of
/// up to 4 columns whose sums are held in registers while they run over the inner dimension:
/// with run-time sizes a loop over a whole row would keep its sums in memory, and each term
/// would wait for the previous one's store to be read back. Each sum runs in order from the
/// first term, as in the plain loops. (Blocks of 2 rows × 8 columns, four independent vector
/// sums, measured slower: 1.2 against 0.93 µs a step at n = 9.)
#[inline(always)]
fn blocked_product<D: Dims>(c: &mut [f64], a: &[f64], b: &[f64], m: usize, k: usize, n: usize, upper: bool) {
    for i in 0..m {
        let ai = &a[i * k..(i + 1) * k];
        let from = if upper { i } else { 0 };
        for_column_blocks(
            from,
            n,
            #[inline(always)]
            |j, w| match w {
                4 => row_times::<D, 4>(&mut c[i * n + j..], ai, b, n, j),
                2 => row_times::<D, 2>(&mut c[i * n + j..], ai, b, n, j),
                _ => row_times::<D, 1>(&mut c[i * n + j..], ai, b, n, j),
            },
        );
    }
}

/// `c[m×n] = a[m×k] · b[n×k]'` (with `upper`, only the upper triangle) in blocks as
/// [`blocked_product`], each entry a dot product in order from the first term.
#[inline(always)]
fn blocked_product_t<D: Dims>(c: &mut [f64], a: &[f64], b: &[f64], m: usize, k: usize, n: usize, upper: bool) {
    for i in 0..m {
        let ai = &a[i * k..(i + 1) * k];
        let from = if upper { i } else { 0 };
        for_column_blocks(
            from,
            n,
            #[inline(always)]
            |j, w| match w {
                4 => row_times_t::<D, 4>(&mut c[i * n + j..], ai, b, k, j),
                2 => row_times_t::<D, 2>(&mut c[i * n + j..], ai, b, k, j),
                _ => row_times_t::<D, 1>(&mut c[i * n + j..], ai, b, k, j),
            },
        );
    }
}

/// Calls `block(j, w)` for blocks of `w` = 4, 2 or 1 columns covering `from..n`.
#[inline(always)]
fn for_column_blocks(from: usize, n: usize, mut block: impl FnMut(usize, usize)) {
    let mut j = from;
    while j + 4 <= n {
        block(j, 4);
        j += 4;
    }
    for w in [2, 1] {
        if j + w <= n {
            block(j, w);
            j += w;
        }
    }
}

/// `c[..W] = a_row · b[:, j..j+W]` (`b` with `n` columns).
#[inline(always)]
fn row_times<D: Dims, const W: usize>(c: &mut [f64], a_row: &[f64], b: &[f64], n: usize, j: usize) {
    let mut acc = [0.0; W];
    for (l, &a_l) in a_row.iter().enumerate() {
        let b_l = &b[l * n + j..l * n + j + W];
        for q in 0..W {
            acc[q] = madd::<D>(acc[q], a_l, b_l[q]);
        }
    }
    c[..W].copy_from_slice(&acc);
}

/// `c[..W] = a_row · b[j..j+W, :]'` (`b` with `k` columns): W dot products, each in order
/// from the first term, computed side by side.
#[inline(always)]
fn row_times_t<D: Dims, const W: usize>(c: &mut [f64], a_row: &[f64], b: &[f64], k: usize, j: usize) {
    let mut acc = [0.0; W];
    for (l, &a_l) in a_row.iter().enumerate() {
        for q in 0..W {
            acc[q] = madd::<D>(acc[q], a_l, b[(j + q) * k + l]);
        }
    }
    c[..W].copy_from_slice(&acc);
}

/// `c[m×n] = a[m×k] · b[n×k]'`.
#[inline(always)]
pub(crate) fn mul_bt<D: Dims>(c: &mut [f64], a: &[f64], b: &[f64], m: usize, k: usize, n: usize) {
    if use_faer::<D>(m, k, n) {
        let a = faer::MatRef::from_row_major_slice(a, m, k);
        let b = faer::MatRef::from_row_major_slice(b, n, k).transpose();
        return faer_mul(c, a, b);
    }
    if D::UNROLL {
        for i in 0..m {
            for j in 0..n {
                c[i * n + j] = dot_in_order::<D>(&a[i * k..(i + 1) * k], &b[j * k..(j + 1) * k]);
            }
        }
        return;
    }
    blocked_product_t::<D>(c, a, b, m, k, n, false);
}

/// `c[n×n] = a[n×k] · b[k×n]` for a product known to be symmetric (e.g. P H' S⁻¹ H P): one
/// triangle is computed and mirrored (large sizes: the full product, then symmetrized).
#[inline(always)]
pub(crate) fn mul_sym<D: Dims>(c: &mut [f64], a: &[f64], b: &[f64], n: usize, k: usize) {
    if use_faer::<D>(n, k, n) {
        mul::<D>(c, a, b, n, k, n);
        return symmetrize(c, n);
    }
    if D::UNROLL {
        for i in 0..n {
            for j in i..n {
                let mut v = -0.0;
                for l in 0..k {
                    v = madd::<D>(v, a[i * k + l], b[l * n + j]);
                }
                c[i * n + j] = v;
                c[j * n + i] = v;
            }
        }
        return;
    }
    blocked_product::<D>(c, a, b, n, k, n, true);
    mirror_upper(c, n);
}

/// `c[n×n] = a[n×k] · b[n×k]'` for a product known to be symmetric (e.g. (F P) F'): one
/// triangle is computed and mirrored.
#[inline(always)]
pub(crate) fn mul_bt_sym<D: Dims>(c: &mut [f64], a: &[f64], b: &[f64], n: usize, k: usize) {
    if use_faer::<D>(n, k, n) {
        mul_bt::<D>(c, a, b, n, k, n);
        return symmetrize(c, n);
    }
    if D::UNROLL {
        for i in 0..n {
            let ai = &a[i * k..(i + 1) * k];
            for j in i..n {
                let v = dot_in_order::<D>(ai, &b[j * k..(j + 1) * k]);
                c[i * n + j] = v;
                c[j * n + i] = v;
            }
        }
        return;
    }
    blocked_product_t::<D>(c, a, b, n, k, n, true);
    mirror_upper(c, n);
}

/// `a · b` summed in order from the first term (as the blocked kernels sum).
#[inline(always)]
fn dot_in_order<D: Dims>(a: &[f64], b: &[f64]) -> f64 {
    let mut v = -0.0;
    for (x, y) in a.iter().zip(b) {
        v = madd::<D>(v, *x, *y);
    }
    v
}

/// Copies the strict upper triangle of `c[n×n]` onto the lower one.
#[inline(always)]
pub(crate) fn mirror_upper(c: &mut [f64], n: usize) {
    for i in 0..n {
        for j in i + 1..n {
            c[j * n + i] = c[i * n + j];
        }
    }
}

/// `a · b` with four interleaved partial sums: the sum's dependency chain is a quarter as long
/// and the products vectorize (a mean-only filter step at n = 20 is mostly such sums).
#[inline(always)]
pub(crate) fn dot<D: Dims>(a: &[f64], b: &[f64]) -> f64 {
    let k = a.len().min(b.len());
    let (a, b) = (&a[..k], &b[..k]);
    let chunks = k / 4;
    // −0.0, the identity of addition: the compiler drops the first add (0.0 + x it cannot).
    let mut acc = [-0.0; 4];
    for c in 0..chunks {
        for l in 0..4 {
            acc[l] = madd::<D>(acc[l], a[4 * c + l], b[4 * c + l]);
        }
    }
    let mut s = (acc[0] + acc[2]) + (acc[1] + acc[3]);
    for i in 4 * chunks..k {
        s = madd::<D>(s, a[i], b[i]);
    }
    s
}

/// `y[m] = a[m×k] · x[k]`.
#[inline(always)]
pub(crate) fn mul_vec<D: Dims>(y: &mut [f64], a: &[f64], x: &[f64], m: usize, k: usize) {
    for i in 0..m {
        y[i] = dot::<D>(&a[i * k..(i + 1) * k], &x[..k]);
    }
}

/// `y[m] += a[m×k] · x[k]`.
#[inline(always)]
pub(crate) fn mul_vec_add<D: Dims>(y: &mut [f64], a: &[f64], x: &[f64], m: usize, k: usize) {
    for i in 0..m {
        y[i] += dot::<D>(&a[i * k..(i + 1) * k], &x[..k]);
    }
}

/// `bt[c×r] = b[r×c]'`.
#[inline(always)]
pub(crate) fn transpose(bt: &mut [f64], b: &[f64], r: usize, c: usize) {
    for i in 0..r {
        for j in 0..c {
            bt[j * r + i] = b[i * c + j];
        }
    }
}

/// `b ← L⁻¹ b` for `b[n×cols]`, `L` lower triangular (`l[n×n]`) with a nonzero diagonal.
pub(crate) fn solve_lower(l: &[f64], b: &mut [f64], n: usize, cols: usize) {
    for i in 0..n {
        for k in 0..i {
            let lik = l[i * n + k];
            for j in 0..cols {
                b[i * cols + j] -= lik * b[k * cols + j];
            }
        }
        for j in 0..cols {
            b[i * cols + j] /= l[i * n + i];
        }
    }
}

/// `b ← L'⁻¹ b` for `b[n×cols]`, `L` lower triangular (`l[n×n]`) with a nonzero diagonal.
pub(crate) fn solve_lower_t(l: &[f64], b: &mut [f64], n: usize, cols: usize) {
    for i in (0..n).rev() {
        for k in i + 1..n {
            let lki = l[k * n + i];
            for j in 0..cols {
                b[i * cols + j] -= lki * b[k * cols + j];
            }
        }
        for j in 0..cols {
            b[i * cols + j] /= l[i * n + i];
        }
    }
}

/// Replaces the square `a[n×n]` by `(a + a') / 2`.
#[inline(always)]
pub(crate) fn symmetrize(a: &mut [f64], n: usize) {
    for i in 0..n {
        for j in 0..i {
            let s = 0.5 * (a[i * n + j] + a[j * n + i]);
            a[i * n + j] = s;
            a[j * n + i] = s;
        }
    }
}

/// LU factorization with partial pivoting in place (`P a = L U`, L unit lower triangular):
/// `piv[k]` is the row swapped with row k at step k. For the small dense solves of the
/// Riccati iterations, where a library call's overhead would exceed the arithmetic. A zero
/// pivot leaves infinities or NaN in the factor (callers check the results are finite).
pub(crate) fn lu_in_place(a: &mut [f64], piv: &mut [usize], n: usize) {
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs())).unwrap_or(k);
        piv[k] = p;
        if p != k {
            for c in 0..n {
                a.swap(k * n + c, p * n + c);
            }
        }
        let inv = 1.0 / a[k * n + k];
        for i in k + 1..n {
            let l = a[i * n + k] * inv;
            a[i * n + k] = l;
            for c in k + 1..n {
                a[i * n + c] -= l * a[k * n + c];
            }
        }
    }
}

/// Solves `A X = B` in place for `b[n×r]` with the factor of [`lu_in_place`].
pub(crate) fn lu_solve(lu: &[f64], piv: &[usize], b: &mut [f64], n: usize, r: usize) {
    for (k, &p) in piv.iter().enumerate() {
        if p != k {
            for c in 0..r {
                b.swap(k * r + c, p * r + c);
            }
        }
    }
    solve_unit_lower::<Dyn>(lu, b, n, r);
    for i in (0..n).rev() {
        for j in i + 1..n {
            let u = lu[i * n + j];
            for c in 0..r {
                b[i * r + c] -= u * b[j * r + c];
            }
        }
        let inv = 1.0 / lu[i * n + i];
        for c in 0..r {
            b[i * r + c] *= inv;
        }
    }
}

/// Square-root-free Cholesky factorization `a = L D L'` (Golub & Van Loan, *Matrix
/// Computations*, Algorithm 4.1.2) of the symmetric `a[n×n]` into `f[n×n]`: on success the
/// strict lower triangle of `f` holds the unit lower-triangular `L`, the diagonal holds the
/// reciprocal pivots `1 / d_j` (what the solves multiply by) and the strict upper triangle the
/// products `l_ij d_j` at `(j, i)` (what the later pivots subtract); returns `det a = Π d_j`.
/// Only the lower triangle of `a` is used; it is read entry by entry rather than copied first
/// (S has just been written entry by entry by `symmetrize`, and a whole-row copy of it would
/// stall: store forwarding fails). A symmetric `a` is positive definite iff every `d_j > 0`;
/// on failure returns the first `j` that is not, is not a normal number (a subnormal pivot
/// would make its reciprocal infinite), or is at rounding level: `d_j ≤ 32 n ε a_jj`.
///
/// Why that floor: `d_j / a_jj` is one minus the squared multiple correlation of component j
/// with the ones before it, so the test does not depend on the units of the components (S may
/// mix metres and radians squared), and the computed factor's backward error is about
/// `n ε √(a_ii a_jj)` entrywise (Higham, *Accuracy and Stability of Numerical Algorithms*,
/// ch. 10): a pivot below a small multiple of `n ε a_jj` is the pivot of a matrix within
/// rounding of a singular one, and its value carries no information — dividing by it turned
/// a singular S (Q = 0, rank-one R) into a smoothed covariance of 1e15 (issue 10).
///
/// Used for the innovation covariance S, where its latency bounds a small filter step: one
/// division per pivot, each waiting for the one before. For n = 2 (two measurements, the most
/// common case) the second reciprocal is `a_00 / det a` with `det a = a_00 a_11 − a_10²`, which
/// needs no earlier division: one division on the chain instead of two (a tenth of a CV-model
/// step). `d_1 = det a / a_00` as before up to rounding; when `det a` is not a normal number
/// (entries near the range limits) the general recursion runs.
#[inline(always)]
pub(crate) fn ldl<D: Dims>(f: &mut [f64], a: &[f64], n: usize) -> Result<f64, usize> {
    let floor = 32.0 * n as f64 * f64::EPSILON;
    let pivot_ok = |d: f64, a_jj: f64| d >= f64::MIN_POSITIVE && d > floor * a_jj && d <= f64::MAX;
    if n == 2 {
        let (a00, a10, a11) = (a[0], a[2], a[3]);
        let det = msub::<D>(a00 * a11, a10, a10);
        if det.is_normal() {
            // NaN fails the comparisons; MIN_POSITIVE is the smallest normal number.
            if !pivot_ok(a00, a00) {
                return Err(0);
            }
            let inv0 = 1.0 / a00;
            if !pivot_ok(det * inv0, a11) {
                return Err(1);
            }
            let l10 = a10 * inv0;
            f[..4].copy_from_slice(&[inv0, l10 * a00, l10, a00 / det]);
            return Ok(det);
        }
    }
    let mut det = 1.0;
    for j in 0..n {
        let a_jj = a[j * n + j];
        let mut d = a_jj;
        for l in 0..j {
            d = msub::<D>(d, f[j * n + l], f[l * n + j]);
        }
        if !pivot_ok(d, a_jj) {
            return Err(j);
        }
        det *= d;
        let inv = 1.0 / d;
        f[j * n + j] = inv;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for l in 0..j {
                s = msub::<D>(s, f[i * n + l], f[l * n + j]);
            }
            let l_ij = s * inv;
            f[i * n + j] = l_ij;
            f[j * n + i] = l_ij * d;
        }
    }
    Ok(det)
}

/// Solves `S X = B` in place for `b[n×r]`, with `S = L D L'` given by its [`ldl`] factor `f`.
#[inline(always)]
pub(crate) fn ldl_solve<D: Dims>(f: &[f64], b: &mut [f64], n: usize, r: usize) {
    solve_unit_lower::<D>(f, b, n, r);
    scale_by_inv_diag(f, b, n, r);
    solve_unit_lower_t::<D>(f, b, n, r);
}

/// For a vector `b[n]`: replaces it by `S⁻¹ b` and returns `b' S⁻¹ b = Σ w_j² / d_j` with
/// `w = L⁻¹ b` (a sum of nonnegative terms), for the [`ldl`] factor `f` of S.
#[inline(always)]
pub(crate) fn ldl_solve_quad<D: Dims>(f: &[f64], b: &mut [f64], n: usize) -> f64 {
    solve_unit_lower::<D>(f, b, n, 1);
    let mut quad = -0.0;
    for (i, bi) in b.iter_mut().enumerate() {
        let w = *bi;
        *bi = w * f[i * n + i];
        quad = madd::<D>(quad, w, *bi);
    }
    solve_unit_lower_t::<D>(f, b, n, 1);
    quad
}

/// Solves `L X = B` in place for `b[n×r]`, `L` unit lower triangular (strict lower triangle
/// of `l[n×n]`).
#[inline(always)]
fn solve_unit_lower<D: Dims>(l: &[f64], b: &mut [f64], n: usize, r: usize) {
    for i in 1..n {
        for j in 0..i {
            let lij = l[i * n + j];
            for c in 0..r {
                b[i * r + c] = msub::<D>(b[i * r + c], lij, b[j * r + c]);
            }
        }
    }
}

/// Solves `L' X = B` in place for `b[n×r]`, `L` unit lower triangular.
#[inline(always)]
fn solve_unit_lower_t<D: Dims>(l: &[f64], b: &mut [f64], n: usize, r: usize) {
    for i in (0..n).rev() {
        for j in i + 1..n {
            let lji = l[j * n + i];
            for c in 0..r {
                b[i * r + c] = msub::<D>(b[i * r + c], lji, b[j * r + c]);
            }
        }
    }
}

/// Row i of `b[n×r]` times `1 / l[i][i]`.
#[inline(always)]
fn scale_by_inv_diag(l: &[f64], b: &mut [f64], n: usize, r: usize) {
    for i in 0..n {
        let inv = l[i * n + i];
        for c in 0..r {
            b[i * r + c] *= inv;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::dims::{Dyn, Fixed, Fused};

    #[test]
    fn ldl_solves_a_spd_system() {
        let a = [4.0, 2.0, 0.4, 2.0, 5.0, 1.0, 0.4, 1.0, 3.0];
        let mut f = [0.0; 9];
        let det = ldl::<Dyn>(&mut f, &a, 3).unwrap();
        let b = [1.0, 2.0, 3.0];
        let mut x = b;
        let quad = ldl_solve_quad::<Dyn>(&f, &mut x, 3);
        let mut back = [0.0; 3];
        mul_vec::<Dyn>(&mut back, &a, &x, 3, 3);
        for (got, want) in back.iter().zip(b) {
            assert!((got - want).abs() < 1e-12);
        }
        let want_quad: f64 = b.iter().zip(&x).map(|(p, q)| p * q).sum();
        assert!((quad - want_quad).abs() < 1e-12);
        let mut cols = [1.0, 0.0, 0.0, 1.0, 0.0, 0.0]; // 3 × 2
        ldl_solve::<Dyn>(&f, &mut cols, 3, 2);
        let mut first = [cols[0], cols[2], cols[4]];
        let mut back = [0.0; 3];
        mul_vec::<Dyn>(&mut back, &a, &first, 3, 3);
        first = back;
        assert!((first[0] - 1.0).abs() < 1e-12 && first[1].abs() < 1e-12 && first[2].abs() < 1e-12);
        // det = 4 (15 − 1) − 2 (6 − 0.4) + 0.4 (2 − 2) = 44.8
        assert!((det - 44.8).abs() < 1e-12);
        let mut f2 = [0.0; 4];
        assert_eq!(ldl::<Dyn>(&mut f2, &[1.0, 2.0, 2.0, 1.0], 2), Err(1));
        assert_eq!(ldl::<Dyn>(&mut f2[..1], &[1e-310], 1), Err(0));
        // The second component is the first plus noise of variance 4 ε: a positive pivot at
        // rounding level of its own variance, refused; in other units (scaled by 1e±10) too.
        for scale in [1.0, 1e10, 1e-10] {
            let collinear = [scale * scale, scale, scale, 1.0 + 4.0 * f64::EPSILON];
            assert_eq!(ldl::<Dyn>(&mut f2, &collinear, 2), Err(1), "scale {scale}");
        }
        // Very different variances but uncorrelated components are fine.
        assert!(ldl::<Dyn>(&mut f2, &[1e16, 0.0, 0.0, 1e-16], 2).is_ok());
    }

    /// n = 2 takes the determinant shortcut; n = 2 entries near the range limits (det a not
    /// normal) the general recursion. Both solve.
    #[test]
    fn ldl_of_two_by_two_solves_at_any_scale() {
        for scale in [1.0, 1e-160, 1e160] {
            let a = [4.0 * scale, 1.5 * scale, 1.5 * scale, 0.75 * scale];
            let mut f = [0.0; 4];
            let det = ldl::<Dyn>(&mut f, &a, 2).unwrap();
            let want_det = (4.0 * 0.75 - 1.5 * 1.5) * scale * scale;
            assert!(((det - want_det) / want_det).abs() < 1e-14 || (scale != 1.0 && det > 0.0), "{scale}");
            let b = [1.0, -2.0];
            let mut x = b;
            let quad = ldl_solve_quad::<Dyn>(&f, &mut x, 2);
            let back = [a[0] * x[0] + a[1] * x[1], a[2] * x[0] + a[3] * x[1]];
            assert!((back[0] - b[0]).abs() < 1e-13 && (back[1] - b[1]).abs() < 1e-13, "{scale}: {back:?}");
            assert!((quad - (b[0] * x[0] + b[1] * x[1])).abs() <= 1e-13 * quad.abs(), "{scale}");
        }
    }

    #[test]
    fn lu_solves_a_system_that_needs_pivoting() {
        let a = [0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let (mut lu, mut piv) = (a, [0; 3]);
        lu_in_place(&mut lu, &mut piv, 3);
        let mut x = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]; // two right-hand sides
        let b = x;
        lu_solve(&lu, &piv, &mut x, 3, 2);
        let mut back = [0.0; 6];
        mul::<Dyn>(&mut back, &a, &x, 3, 3, 2);
        for (got, want) in back.iter().zip(b) {
            assert!((got - want).abs() < 1e-12, "{back:?}");
        }
    }

    #[test]
    fn products_agree() {
        let a = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]; // 2×3
        let mut at = [0.0; 6];
        transpose(&mut at, &a, 2, 3);
        let mut c1 = [0.0; 4];
        let mut c2 = [0.0; 4];
        mul::<Dyn>(&mut c1, &a, &at, 2, 3, 2);
        mul_bt::<Dyn>(&mut c2, &a, &a, 2, 3, 2);
        assert_eq!(c1, c2);
        assert_eq!(c1, [14.0, 32.0, 32.0, 77.0]);
    }

    /// The plain loops (compile-time sizes) and the blocked ones (run-time sizes) give the
    /// same bits for every shape, including those that end in 2- and 1-column blocks.
    #[test]
    fn plain_and_blocked_products_are_the_same_bits() {
        let mut state = 7u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for (m, k, n) in [(1, 1, 1), (2, 3, 5), (5, 5, 5), (7, 3, 6), (3, 7, 7), (6, 2, 9), (8, 8, 3)] {
            let a: Vec<f64> = (0..m.max(n) * k).map(|_| next()).collect();
            let b: Vec<f64> = (0..k * n.max(m)).map(|_| next()).collect();
            let bt: Vec<f64> = (0..n.max(m) * k).map(|_| next()).collect();
            let both = |f: &dyn Fn(&mut [f64], bool)| {
                let (mut plain, mut blocked) = (vec![0.0; m.max(n) * n], vec![0.0; m.max(n) * n]);
                f(&mut plain, true);
                f(&mut blocked, false);
                assert_eq!(plain, blocked, "({m}, {k}, {n})");
            };
            products::<Fixed<1, 1>, Dyn>(&both, &a, &b, &bt, m, k, n);
            // The fused forms too (here `mul_add` is a library call: same results, slower).
            products::<Fused<Fixed<1, 1>>, Fused<Dyn>>(&both, &a, &b, &bt, m, k, n);
        }
    }

    /// The four products in the plain form `P` (`plain = true`) and the blocked form `B`.
    #[allow(clippy::type_complexity)]
    fn products<P: Dims, B: Dims>(
        both: &dyn Fn(&dyn Fn(&mut [f64], bool)),
        a: &[f64],
        b: &[f64],
        bt: &[f64],
        m: usize,
        k: usize,
        n: usize,
    ) {
        both(&|c, p| if p { mul::<P>(c, a, b, m, k, n) } else { mul::<B>(c, a, b, m, k, n) });
        both(&|c, p| if p { mul_bt::<P>(c, a, bt, m, k, n) } else { mul_bt::<B>(c, a, bt, m, k, n) });
        both(&|c, p| if p { mul_sym::<P>(c, a, b, n, k) } else { mul_sym::<B>(c, a, b, n, k) });
        both(&|c, p| if p { mul_bt_sym::<P>(c, a, bt, n, k) } else { mul_bt_sym::<B>(c, a, bt, n, k) });
    }

    /// Fused products round once per multiply-add: they differ from the plain ones, by
    /// rounding only.
    #[test]
    fn fused_products_differ_from_plain_ones_by_rounding() {
        let a: Vec<f64> = (0..25).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut plain, mut fused) = ([0.0; 25], [0.0; 25]);
        mul::<Fixed<5, 4>>(&mut plain, &a, &a, 5, 5, 5);
        mul::<Fused<Fixed<5, 4>>>(&mut fused, &a, &a, 5, 5, 5);
        assert_ne!(plain, fused);
        for (p, f) in plain.iter().zip(&fused) {
            assert!((p - f).abs() <= 8.0 * f64::EPSILON, "{p} {f}");
        }
    }
}
