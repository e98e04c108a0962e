//! The products of a three- or four-state filter step on AVX2 + FMA registers, one 256-bit
//! vector per row of the n × n matrices (n = 3: the fourth lane and row are padding, never
//! stored, and never enter a sum: every sum runs over l < n).
//!
//! The portable kernels of [`super::dense`] leave the vectorizing to the compiler, which at
//! n = 4 turns most of the step into scalar multiply-adds and stack traffic (callgrind, CV
//! model, standard form: ~640 instructions a step, 180 of them stack moves; see
//! docs/decisions.md, "Three- and four-state steps on AVX2 registers (issue #11, 2026-12-03, Zen 3)").
//! These kernels compute the same sums in the same order as the fused kernels there — each
//! entry from its first term, one fused multiply-add per further term — so a workspace gives
//! the same bits with them as without, on every path (`filter_batch`'s shared recursion runs
//! with run-time sizes, without them).
//!
//! They serve only [`Fused`](crate::core::dims::Fused) compile-time sizes with n = 3 or 4
//! ([`for_sizes`]): fused sizes exist only on CPUs with AVX2 and FMA and run inside a loop
//! compiled with both (`core::isa`), into which these `#[inline(always)]` functions and the
//! intrinsics they call are inlined. Vectors are made only by functions that take an
//! [`Avx2Fma`], which [`for_sizes`] alone hands out; so holding a [`Row`] proves the CPU can
//! run the rest.

use std::arch::x86_64::*;

use crate::core::dims::Dims;

/// Proof that the CPU has AVX2 and FMA, and the state size n (3 or 4) of the kernels.
#[derive(Clone, Copy)]
pub(crate) struct Avx2Fma {
    n: usize,
}

impl Avx2Fma {
    /// The state size n.
    #[inline(always)]
    pub fn n(self) -> usize {
        self.n
    }
}

/// `Some` when these kernels serve the sizes `d`: four states, or three where
/// [`three_states_pay`]; compile-time sizes, fused (so the CPU has AVX2 and FMA: `core::isa`
/// makes fused sizes only then). Either way the results are the same bits.
#[inline(always)]
pub(crate) fn for_sizes<D: Dims>(d: D) -> Option<Avx2Fma> {
    let n = d.n();
    (D::FUSED && D::FIXED && (n == 4 || (n == 3 && three_states_pay()))).then_some(Avx2Fma { n })
}

/// Whether the three-state kernels are faster than the portable loops on this CPU, which is
/// a matter of measurement (docs/decisions.md, "Three- and four-state steps on AVX2
/// registers"): on an AMD Zen 3 (AVX2, no AVX-512) they are 4–6% faster, and without them
/// W8's (4, 3) ran 13% below (3, 3); on an Intel Xeon (Sapphire Rapids) they are 10–40% slower
/// at m = 1, 2, 3, and (3, 1) ran 15% above (4, 1); on an AMD Zen 4 (2026-12-05) (3, 1) ran 16%
/// above (4, 1) with them. Both slower CPUs have AVX-512, so AMD CPUs without AVX-512 use
/// them and others do not. Read once per process.
#[inline(always)]
fn three_states_pay() -> bool {
    static PAYS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *PAYS.get_or_init(|| {
        // CPUID leaf 0: the vendor string in EBX, EDX, ECX.
        let id = __cpuid(0);
        let amd = [id.ebx, id.edx, id.ecx]
            == [u32::from_le_bytes(*b"Auth"), u32::from_le_bytes(*b"enti"), u32::from_le_bytes(*b"cAMD")];
        amd && !std::arch::is_x86_feature_detected!("avx512f")
    })
}

/// Four numbers: a row of an n × n matrix, or a column (padded to four).
pub(crate) type Row = __m256d;

/// An n × n matrix as its rows (padded to 4 × 4 with zeros).
#[derive(Clone, Copy)]
pub(crate) struct Rows(pub [Row; 4]);

/// `[f(0), f(1), f(2), f(3)]`. Not `std::array::from_fn`, whose closure is called through a
/// function that is not inlined: compiled without AVX2, it made every intrinsic in the
/// closure a function call.
#[inline(always)]
pub(crate) fn each<T>(f: impl Fn(usize) -> T) -> [T; 4] {
    [f(0), f(1), f(2), f(3)]
}

// SAFETY (every `unsafe` block below): the intrinsics need AVX2 and FMA, which the CPU has
// wherever an `Avx2Fma` or a vector exists (see the module docs); loads and stores go
// through slices of checked length.

impl Rows {
    /// The row-major n × n matrix `a[..n²]`.
    #[inline(always)]
    pub fn load(cpu: Avx2Fma, a: &[f64]) -> Rows {
        let n = cpu.n;
        Rows(each(
            #[inline(always)]
            |i| load_row_or_zero(cpu, a, i, n),
        ))
    }

    /// Writes the matrix row-major into `c[..n²]`.
    #[inline(always)]
    pub fn store(&self, cpu: Avx2Fma, c: &mut [f64]) {
        let n = cpu.n;
        for (i, row) in self.0.iter().enumerate().take(n) {
            store(cpu, &mut c[n * i..], *row);
        }
    }

    /// The transpose.
    #[inline(always)]
    pub fn transpose(&self) -> Rows {
        let [r0, r1, r2, r3] = self.0;
        unsafe {
            let (t0, t1) = (_mm256_unpacklo_pd(r0, r1), _mm256_unpackhi_pd(r0, r1));
            let (t2, t3) = (_mm256_unpacklo_pd(r2, r3), _mm256_unpackhi_pd(r2, r3));
            Rows([
                _mm256_permute2f128_pd(t0, t2, 0x20),
                _mm256_permute2f128_pd(t1, t3, 0x20),
                _mm256_permute2f128_pd(t0, t2, 0x31),
                _mm256_permute2f128_pd(t1, t3, 0x31),
            ])
        }
    }

    /// The upper triangle copied onto the lower one (as `dense::mirror_upper`).
    #[inline(always)]
    pub fn mirror_upper(&self) -> Rows {
        let t = self.transpose().0;
        let r = self.0;
        unsafe {
            Rows([
                r[0],
                _mm256_blend_pd(r[1], t[1], 0b0001),
                _mm256_blend_pd(r[2], t[2], 0b0011),
                _mm256_blend_pd(r[3], t[3], 0b0111),
            ])
        }
    }

    /// `I − self` as `dense` computes it: every entry negated, then 1 added on the diagonal.
    #[inline(always)]
    pub fn identity_minus(&self) -> Rows {
        unsafe {
            let neg: [Row; 4] = each(
                #[inline(always)]
                |i| _mm256_xor_pd(self.0[i], splat(-0.0)),
            );
            let plus_one: [Row; 4] = each(
                #[inline(always)]
                |i| _mm256_add_pd(neg[i], splat(1.0)),
            );
            Rows([
                _mm256_blend_pd(neg[0], plus_one[0], 0b0001),
                _mm256_blend_pd(neg[1], plus_one[1], 0b0010),
                _mm256_blend_pd(neg[2], plus_one[2], 0b0100),
                _mm256_blend_pd(neg[3], plus_one[3], 0b1000),
            ])
        }
    }

    /// `(self + self') / 2` off the diagonal, the diagonal kept (as `dense::symmetrize`).
    #[inline(always)]
    pub fn symmetrize(&self) -> Rows {
        let t = self.transpose();
        let r = self.0;
        unsafe {
            let half: [Row; 4] = each(
                #[inline(always)]
                |i| _mm256_mul_pd(splat(0.5), _mm256_add_pd(r[i], t.0[i])),
            );
            Rows([
                _mm256_blend_pd(half[0], r[0], 0b0001),
                _mm256_blend_pd(half[1], r[1], 0b0010),
                _mm256_blend_pd(half[2], r[2], 0b0100),
                _mm256_blend_pd(half[3], r[3], 0b1000),
            ])
        }
    }

    /// `self + b`, entry by entry.
    #[inline(always)]
    pub fn add(&self, b: &Rows) -> Rows {
        Rows(each(
            #[inline(always)]
            |i| unsafe { _mm256_add_pd(self.0[i], b.0[i]) },
        ))
    }

    /// `self − b`, entry by entry.
    #[inline(always)]
    pub fn sub(&self, b: &Rows) -> Rows {
        Rows(each(
            #[inline(always)]
            |i| unsafe { _mm256_sub_pd(self.0[i], b.0[i]) },
        ))
    }
}

/// `a[..n]` as a vector (n = 3: the fourth lane zero).
#[inline(always)]
pub(crate) fn load(cpu: Avx2Fma, a: &[f64]) -> Row {
    let a = &a[..cpu.n];
    unsafe {
        if cpu.n == 4 {
            return _mm256_loadu_pd(a.as_ptr());
        }
        let low = _mm_loadu_pd(a.as_ptr());
        _mm256_insertf128_pd(_mm256_castpd128_pd256(low), _mm_load_sd(&a[2]), 1)
    }
}

/// Writes the first n lanes of `v` into `c[..n]`.
#[inline(always)]
pub(crate) fn store(cpu: Avx2Fma, c: &mut [f64], v: Row) {
    let c = &mut c[..cpu.n];
    unsafe {
        if cpu.n == 4 {
            return _mm256_storeu_pd(c.as_mut_ptr(), v);
        }
        _mm_storeu_pd(c.as_mut_ptr(), _mm256_castpd256_pd128(v));
        _mm_store_sd(&mut c[2], _mm256_extractf128_pd(v, 1));
    }
}

/// Row `l` of `a[rows×n]`, zero for `l ≥ rows`.
#[inline(always)]
pub(crate) fn load_row_or_zero(cpu: Avx2Fma, a: &[f64], l: usize, rows: usize) -> Row {
    if l < rows {
        load(cpu, &a[cpu.n * l..])
    } else {
        unsafe { _mm256_setzero_pd() }
    }
}

/// `a + b`.
#[inline(always)]
pub(crate) fn add(a: Row, b: Row) -> Row {
    unsafe { _mm256_add_pd(a, b) }
}

/// `v · x`.
#[inline(always)]
fn scale(v: Row, x: f64) -> Row {
    unsafe { _mm256_mul_pd(v, splat(x)) }
}

/// `acc − a · b`, rounded once (as `dense`'s `msub` with fused sizes).
#[inline(always)]
fn msub(acc: Row, a: f64, b: Row) -> Row {
    unsafe { _mm256_fnmadd_pd(splat(a), b, acc) }
}

/// Solves `A X = B` in place for the `k` rows of `B` (`k × 4`), with `A = L D L'` given by
/// its `dense::ldl` factor `f[k×k]`, as `dense::ldl_solve` solves it.
#[inline(always)]
pub(crate) fn ldl_solve(f: &[f64], rows: &mut [Row; 4], k: usize) {
    let f = &f[..k * k];
    for i in 1..k {
        for j in 0..i {
            rows[i] = msub(rows[i], f[i * k + j], rows[j]);
        }
    }
    for (i, row) in rows.iter_mut().enumerate().take(k) {
        *row = scale(*row, f[i * k + i]);
    }
    for i in (0..k).rev() {
        for j in i + 1..k {
            rows[i] = msub(rows[i], f[j * k + i], rows[j]);
        }
    }
}

/// Four copies of `x` (only where a vector already exists: see the module docs).
#[inline(always)]
fn splat(x: f64) -> Row {
    unsafe { _mm256_set1_pd(x) }
}

/// Four copies of lane `l` of `v`.
#[inline(always)]
fn lane(v: Row, l: usize) -> Row {
    unsafe {
        match l {
            0 => _mm256_permute4x64_pd(v, 0x00),
            1 => _mm256_permute4x64_pd(v, 0x55),
            2 => _mm256_permute4x64_pd(v, 0xaa),
            _ => _mm256_permute4x64_pd(v, 0xff),
        }
    }
}

/// `Σ_{l<k} coef(l) · b[l]` in order from the first term, each further term one fused
/// multiply-add: an entry of the products of `core::dense` (`mul`, `mul_bt`, `mul_sym`,
/// `mul_bt_sym`) with fused sizes.
#[inline(always)]
fn sum_in_order(k: usize, coef: impl Fn(usize) -> Row, b: impl Fn(usize) -> Row) -> Row {
    unsafe {
        let mut acc = _mm256_mul_pd(coef(0), b(0));
        for l in 1..k {
            acc = _mm256_fmadd_pd(coef(l), b(l), acc);
        }
        acc
    }
}

/// `a · b` for `a[rows×k]` row-major in memory (`rows ≤ 4`) and the `k` rows `b`, as
/// `dense::mul`; rows from `rows` on are zero.
#[inline(always)]
pub(crate) fn mul_mem(a: &[f64], rows: usize, b: &[Row; 4], k: usize) -> Rows {
    let a = &a[..rows * k];
    Rows(each(
        #[inline(always)]
        |i| {
            if i < rows {
                sum_in_order(
                    k,
                    #[inline(always)]
                    |l| splat(a[i * k + l]),
                    #[inline(always)]
                    |l| b[l],
                )
            } else {
                splat(0.0)
            }
        },
    ))
}

/// `a · b` for the n × n rows `a` and `b`: row `i` is `Σ_{l<n} a_il b_l`.
#[inline(always)]
pub(crate) fn mul_rows(cpu: Avx2Fma, a: &Rows, b: &Rows) -> Rows {
    Rows(each(
        #[inline(always)]
        |i| {
            sum_in_order(
                cpu.n,
                #[inline(always)]
                |l| lane(a.0[i], l),
                #[inline(always)]
                |l| b.0[l],
            )
        },
    ))
}

/// `a · b` for `a` (4 × k) given by its `k` columns and the `k` rows `b`: row `i` is
/// `Σ_l a_il b_l`.
#[inline(always)]
pub(crate) fn mul_cols(a_cols: &[Row; 4], b: &[Row; 4], k: usize) -> Rows {
    Rows(each(
        #[inline(always)]
        |i| {
            sum_in_order(
                k,
                #[inline(always)]
                |l| lane(a_cols[l], i),
                #[inline(always)]
                |l| b[l],
            )
        },
    ))
}

/// The columns `C_j = P h_j'` of `C = P H'` (n × m) for the n × n `P` and `h[m×n]`
/// (`dense::mul_bt`: each entry `Σ_l P_il h_jl` in order).
#[inline(always)]
pub(crate) fn mul_bt_cols(cpu: Avx2Fma, p: &Rows, h: &[f64], m: usize) -> [Row; 4] {
    let n = cpu.n;
    let h = &h[..n * m];
    let p_cols = p.transpose();
    let mut cols = [splat(0.0); 4];
    for (j, col) in cols.iter_mut().enumerate().take(m) {
        *col = sum_in_order(
            n,
            #[inline(always)]
            |l| p_cols.0[l],
            #[inline(always)]
            |l| splat(h[j * n + l]),
        );
    }
    cols
}

/// Writes the n × m matrix with columns `cols` row-major into `c[..nm]`.
#[inline(always)]
pub(crate) fn store_cols(cpu: Avx2Fma, c: &mut [f64], cols: &[Row; 4], m: usize) {
    let rows = Rows(*cols).transpose();
    let c = &mut c[..cpu.n * m];
    let mut row = [0.0; 4];
    for i in 0..cpu.n {
        unsafe { _mm256_storeu_pd(row.as_mut_ptr(), rows.0[i]) };
        c[i * m..(i + 1) * m].copy_from_slice(&row[..m]);
    }
}

/// `y + Σ_{l<k} cols[l] x_l` as `dense::mul_vec_add(y, a, x)` sums it for the 4 × k `a`
/// with columns `cols`: each entry a dot product with four interleaved partial sums.
#[inline(always)]
pub(crate) fn mul_vec_cols(cols: &[Row; 4], x: &[f64], k: usize) -> Row {
    let x = &x[..k];
    unsafe {
        // dense::dot: k < 4 runs one sum from −0.0 (so from its first term); k = 4 four
        // partial sums of one term each, added (0 + 2) + (1 + 3).
        if k == 4 {
            let t: [Row; 4] = each(
                #[inline(always)]
                |l| _mm256_mul_pd(cols[l], splat(x[l])),
            );
            return _mm256_add_pd(_mm256_add_pd(t[0], t[2]), _mm256_add_pd(t[1], t[3]));
        }
        sum_in_order(
            k,
            #[inline(always)]
            |l| cols[l],
            #[inline(always)]
            |l| splat(x[l]),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::dense::{mul, mul_bt, mul_bt_sym, mul_sym, mul_vec};
    use crate::core::dims::{Fixed, Fused};

    /// Fused unrolled kernels (the sizes are arguments; `D` sets only how they run).
    type D = Fused<Fixed<4, 2>>;

    fn numbers(seed: u64, len: usize) -> Vec<f64> {
        let mut state = seed;
        (0..len)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    /// Every kernel gives the bits of the fused `core::dense` product it replaces, for n = 3
    /// and 4 (here the dense ones call the runtime's `fma`, which rounds the same).
    #[test]
    fn the_kernels_give_the_bits_of_the_fused_dense_products() {
        if !(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")) {
            eprintln!("no AVX2 + FMA: nothing to compare");
            return;
        }
        for n in [3, 4] {
            let cpu = Avx2Fma { n };
            let nn = n * n;
            let stored = |r: &Rows| {
                let mut c = vec![0.0; nn];
                r.store(cpu, &mut c);
                c
            };
            for seed in 1..20 {
                let (a, b) = (numbers(seed, nn), numbers(seed + 100, nn));
                let h = numbers(seed + 200, 2 * n);
                let x = numbers(seed + 300, n);
                let (ra, rb) = (Rows::load(cpu, &a), Rows::load(cpu, &b));

                let mut want = vec![0.0; nn];
                mul::<D>(&mut want, &a, &b, n, n, n);
                assert_eq!(stored(&mul_rows(cpu, &ra, &rb)), want, "n = {n}");
                assert_eq!(stored(&mul_mem(&a, n, &rb.0, n)), want);

                mul_bt_sym::<D>(&mut want, &a, &b, n, n);
                assert_eq!(stored(&mul_rows(cpu, &ra, &rb.transpose()).mirror_upper()), want);

                let cols = mul_bt_cols(cpu, &ra, &h, 2);
                let mut pht = vec![0.0; 2 * n];
                store_cols(cpu, &mut pht, &cols, 2);
                let mut want_pht = vec![0.0; 2 * n];
                mul_bt::<D>(&mut want_pht, &a, &h, n, n, 2);
                assert_eq!(pht, want_pht);

                let gain_rows = [load(cpu, &b), load(cpu, &b[n..]), splat(0.0), splat(0.0)];
                mul_sym::<D>(&mut want, &pht, &b[..2 * n], n, 2);
                assert_eq!(stored(&mul_cols(&cols, &gain_rows, 2).mirror_upper()), want);

                let mut want_x = vec![0.0; n];
                mul_vec::<D>(&mut want_x, &a, &x, n, n);
                let mut got_x = vec![0.0; n];
                store(cpu, &mut got_x, mul_vec_cols(&ra.transpose().0, &x, n));
                assert_eq!(got_x, want_x);
                mul_vec::<D>(&mut want_x, &pht, &x[..2], n, 2);
                store(cpu, &mut got_x, mul_vec_cols(&cols, &x[..2], 2));
                assert_eq!(got_x, want_x);
            }
        }
    }
}
