//! Sine, cosine and atan2 of a few numbers at once, for the built-in models' sigma points.
//!
//! A UKF step on the coordinated-turn model with a range–bearing sensor takes a sine and
//! cosine and an `atan2` at each of its 11 points; one at a time through the C library they
//! were 40% of the step (Zen 4, 2026-12-05). These evaluate [`LANES`] numbers together in
//! branch-free lane-wise arithmetic (`V`, `Mask`) that the compiler turns into vector
//! instructions — one AVX2 instruction per operation where the models run them in
//! [`run_wide`](crate::core::isa::run_wide) — with the
//! minimax polynomials of fdlibm (Sun Microsystems, 1993: `k_sin.c`, `k_cos.c`, `s_atan.c`),
//! which are accurate to within an ulp on their reduced ranges; the tests bound the error
//! against the C library at 2 ulp. They multiply and add separately (no fused multiply-adds),
//! so every CPU gets the same bits. Arguments outside the fast path's range (|x| > 10⁵ for the
//! sine and cosine; NaN, ±∞, and (0, 0) for atan2) go to the C library one at a time.

// The constants are fdlibm's, digit for digit as published (more digits than a double holds).
#![allow(clippy::excessive_precision)]

use std::array::from_fn;

/// The numbers evaluated together.
pub(crate) const LANES: usize = 4;

/// 1.5 · 2⁵²: `v + ROUNDER − ROUNDER` rounds v (|v| < 2⁵¹) to an integer, which the low bits of
/// `v + ROUNDER` then hold in two's complement.
const ROUNDER: f64 = 6_755_399_441_055_744.0;

// π/2 in three parts (fdlibm's pio2_1, pio2_2, pio2_2t): the first two have 33 significant
// bits, so that j · part is exact for the |j| < 2²⁰ of the fast path (Cody & Waite).
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e+00;
const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;

const S1: f64 = -1.666_666_666_666_663_243_48e-01;
const S2: f64 = 8.333_333_333_322_489_461_24e-03;
const S3: f64 = -1.984_126_982_985_794_931_34e-04;
const S4: f64 = 2.755_731_370_707_006_767_89e-06;
const S5: f64 = -2.505_076_025_340_686_341_95e-08;
const S6: f64 = 1.589_690_995_211_550_102_21e-10;

const C1: f64 = 4.166_666_666_666_660_190_37e-02;
const C2: f64 = -1.388_888_888_887_410_957_49e-03;
const C3: f64 = 2.480_158_728_947_672_941_78e-05;
const C4: f64 = -2.755_731_435_139_066_330_35e-07;
const C5: f64 = 2.087_572_321_298_174_827_90e-09;
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

/// The largest |x| of the sine and cosine's fast path (|j| = |x| 2/π < 2²⁰ with room).
const SIN_COS_LIMIT: f64 = 1e5;

/// Below this |r|, sin r = r and cos r = 1 in double precision.
const TINY: f64 = 7.450_580_596_923_828e-9; // 2⁻²⁷

/// `LANES` doubles, with lane-wise arithmetic written as loops over the lanes: a form the
/// compiler turns into one vector instruction per operation (AVX2) or two (SSE2), where the
/// same kernels written on one `f64` at a time were compiled to scalar code with branches
/// under AVX2.
#[derive(Clone, Copy)]
struct V([f64; LANES]);

/// A lane mask: all bits set where true.
#[derive(Clone, Copy)]
struct Mask([u64; LANES]);

impl V {
    #[inline(always)]
    fn splat(v: f64) -> V {
        V([v; LANES])
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> V {
        V(self.0.map(f))
    }

    #[inline(always)]
    fn zip(self, other: V, f: impl Fn(f64, f64) -> f64) -> V {
        V(from_fn(|l| f(self.0[l], other.0[l])))
    }

    #[inline(always)]
    fn compare(self, other: V, f: impl Fn(f64, f64) -> bool) -> Mask {
        Mask(from_fn(|l| if f(self.0[l], other.0[l]) { u64::MAX } else { 0 }))
    }

    #[inline(always)]
    fn abs(self) -> V {
        self.map(f64::abs)
    }

    #[inline(always)]
    fn bits(self) -> [u64; LANES] {
        self.0.map(f64::to_bits)
    }

    #[inline(always)]
    fn from_bits(bits: [u64; LANES]) -> V {
        V(bits.map(f64::from_bits))
    }

    /// The sign bits of `sign` put on self's magnitudes.
    #[inline(always)]
    fn copysign(self, sign: V) -> V {
        let (a, b) = (self.bits(), sign.bits());
        V::from_bits(from_fn(|l| (a[l] & !SIGN) | (b[l] & SIGN)))
    }

    /// The lanes with the sign bit set (−0 and NaNs with it included).
    #[inline(always)]
    fn negative(self) -> Mask {
        Mask(self.bits().map(|b| if b & SIGN != 0 { u64::MAX } else { 0 }))
    }

    /// Self with its sign flipped where `flip` has the sign bit set.
    #[inline(always)]
    fn flip_sign(self, flip: [u64; LANES]) -> V {
        let a = self.bits();
        V::from_bits(from_fn(|l| a[l] ^ (flip[l] & SIGN)))
    }
}

const SIGN: u64 = 1 << 63;

impl Mask {
    /// `a` where the mask is set, else `b`.
    #[inline(always)]
    fn select(self, a: V, b: V) -> V {
        let (a, b) = (a.bits(), b.bits());
        V::from_bits(from_fn(|l| (a[l] & self.0[l]) | (b[l] & !self.0[l])))
    }

    #[inline(always)]
    fn or(self, other: Mask) -> Mask {
        Mask(from_fn(|l| self.0[l] | other.0[l]))
    }

    #[inline(always)]
    fn all(self) -> bool {
        self.0.iter().fold(u64::MAX, |acc, m| acc & m) != 0
    }
}

macro_rules! lane_ops {
    ($($trait:ident $method:ident),*) => {$(
        impl std::ops::$trait for V {
            type Output = V;
            #[inline(always)]
            fn $method(self, other: V) -> V {
                self.zip(other, |a, b| std::ops::$trait::$method(a, b))
            }
        }
        impl std::ops::$trait<V> for f64 {
            type Output = V;
            #[inline(always)]
            fn $method(self, other: V) -> V {
                std::ops::$trait::$method(V::splat(self), other)
            }
        }
        impl std::ops::$trait<f64> for V {
            type Output = V;
            #[inline(always)]
            fn $method(self, other: f64) -> V {
                std::ops::$trait::$method(self, V::splat(other))
            }
        }
    )*};
}
lane_ops!(Add add, Sub sub, Mul mul, Div div);

/// `(sin x, cos x)` for each lane of `x`.
#[inline(always)]
pub(crate) fn sin_cos(x: [f64; LANES]) -> ([f64; LANES], [f64; LANES]) {
    let (sin, cos, ok) = sin_cos_reduced(V(x));
    let (mut sin, mut cos) = (sin.0, cos.0);
    if !ok.all() {
        for l in 0..LANES {
            if ok.0[l] == 0 {
                (sin[l], cos[l]) = x[l].sin_cos();
            }
        }
    }
    (sin, cos)
}

/// [`sin_cos`] in the fast path: x − j π/2 = r with |r| ≤ π/4, the kernels at r, and the
/// quadrant j mod 4 choosing which is which and their signs; and the lanes in the fast path.
#[inline(always)]
fn sin_cos_reduced(x: V) -> (V, V, Mask) {
    let ok = x.abs().compare(V::splat(SIN_COS_LIMIT), |a, b| a <= b);
    let x = ok.select(x, V::splat(0.0));
    let shifted = x * std::f64::consts::FRAC_2_PI + ROUNDER;
    let quadrant = shifted.bits().map(|b| b & 3);
    let j = shifted - ROUNDER;
    let r = ((x - j * PIO2_1) - j * PIO2_2) - j * PIO2_2T;
    let z = r * r;
    let w = z * z;
    // fdlibm's __kernel_sin and __kernel_cos (no tail)
    let poly_s = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    // (r itself where r is tiny, as fdlibm: the sign of a zero kept)
    let tiny = r.abs().compare(V::splat(TINY), |a, b| a < b);
    let s = tiny.select(r, r + z * r * (S1 + z * poly_s));
    let poly_c = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let half_z = 0.5 * z;
    let one_minus = 1.0 - half_z;
    let c = one_minus + (((1.0 - one_minus) - half_z) + z * poly_c);
    let swap = Mask(quadrant.map(|q| if q & 1 == 1 { u64::MAX } else { 0 }));
    let (sin, cos) = (swap.select(c, s), swap.select(s, c));
    // sin changes sign in quadrants 2 and 3, cos in 1 and 2
    let sin_sign = quadrant.map(|q| (q & 2) << 62);
    let cos_sign = quadrant.map(|q| ((q + 1) & 2) << 62);
    (sin.flip_sign(sin_sign), cos.flip_sign(cos_sign), ok)
}

const AT: [f64; 11] = [
    3.333_333_333_333_293_180_27e-01,
    -1.999_999_999_987_648_324_76e-01,
    1.428_571_427_250_346_637_11e-01,
    -1.111_111_040_546_235_578_80e-01,
    9.090_887_133_436_506_561_96e-02,
    -7.691_876_205_044_829_994_95e-02,
    6.661_073_137_387_531_206_69e-02,
    -5.833_570_133_790_573_486_45e-02,
    4.976_877_994_615_932_360_17e-02,
    -3.653_157_274_421_691_552_70e-02,
    1.628_582_011_536_578_236_23e-02,
];
// atan(1/2) and atan(1), each as a double and the rest
const ATAN_HALF: (f64, f64) = (4.636_476_090_008_060_935_15e-01, 2.269_877_745_296_168_709_24e-17);
const ATAN_ONE: (f64, f64) = (std::f64::consts::FRAC_PI_4, 3.061_616_997_868_383_017_93e-17);
// π/2 and π, each as a double and the rest
const PIO2: (f64, f64) = (std::f64::consts::FRAC_PI_2, 6.123_233_995_736_766_035_87e-17);
const PI: (f64, f64) = (std::f64::consts::PI, 1.224_646_799_147_353_207_17e-16);

/// `atan2(y, x)` for each lane, in (−π, π] as the C library's.
#[inline(always)]
pub(crate) fn atan2(y: [f64; LANES], x: [f64; LANES]) -> [f64; LANES] {
    let (angle, ok) = atan2_reduced(V(y), V(x));
    let mut out = angle.0;
    if !ok.all() {
        for l in 0..LANES {
            if ok.0[l] == 0 {
                out[l] = y[l].atan2(x[l]);
            }
        }
    }
    out
}

/// [`atan2`] in the fast path: t = min(|x|, |y|) / max(|x|, |y|) ∈ [0, 1], atan t by
/// fdlibm's reduction (t < 7/16: itself; < 11/16: atan ½ + atan((2t − 1)/(2 + t)); else
/// atan 1 + atan((t − 1)/(t + 1))) and polynomial, then the octant and the sign of y; and
/// the lanes where t is a number (not for NaN arguments, both zero or both infinite).
#[inline(always)]
fn atan2_reduced(y: V, x: V) -> (V, Mask) {
    let (ax, ay) = (x.abs(), y.abs());
    let steep = ay.compare(ax, |a, b| a > b);
    let (num, den) = (steep.select(ax, ay), steep.select(ay, ax));
    let t = num / den;
    let ok = t.compare(V::splat(1.0), |a, b| a <= b);
    let t = ok.select(t, V::splat(0.0));
    let upper = t.compare(V::splat(11.0 / 16.0), |a, b| a >= b);
    let middle = t.compare(V::splat(7.0 / 16.0), |a, b| a >= b);
    let top = upper.select(t - 1.0, middle.select(2.0 * t - 1.0, t));
    let bottom = upper.select(t + 1.0, middle.select(2.0 + t, V::splat(1.0)));
    let v = top / bottom;
    let z = v * v;
    let w = z * z;
    let s1 = z * (AT[0] + w * (AT[2] + w * (AT[4] + w * (AT[6] + w * (AT[8] + w * AT[10])))));
    let s2 = w * (AT[1] + w * (AT[3] + w * (AT[5] + w * (AT[7] + w * AT[9]))));
    let hi = upper.select(V::splat(ATAN_ONE.0), V::splat(ATAN_HALF.0));
    let lo = upper.select(V::splat(ATAN_ONE.1), V::splat(ATAN_HALF.1));
    let reduced = hi - ((v * (s1 + s2) - lo) - v);
    let atan_t = middle.or(upper).select(reduced, v - v * (s1 + s2));
    // the angle of (|x|, |y|) turned to x's side: π − atan t (flat) or π/2 ± atan t (steep)
    let atan_t = atan_t.flip_sign(x.bits());
    let flat = x.negative().select(PI.0 + (atan_t + PI.1), atan_t);
    let angle = steep.select(PIO2.0 - (atan_t - PIO2.1), flat);
    (angle.copysign(y), ok)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The distance in units in the last place between two finite doubles of the same sign
    /// (or zeros).
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b {
            return 0;
        }
        assert_eq!(a.is_sign_negative(), b.is_sign_negative(), "{a} vs {b}");
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    fn numbers(seed: u64, len: usize) -> impl Iterator<Item = f64> {
        let mut s = seed;
        (0..len).map(move |_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        })
    }

    #[test]
    fn sin_cos_within_two_ulps_of_the_c_library() {
        let mut worst = 0;
        for (scale, seed) in [(1e-8, 1), (0.1, 2), (1.0, 3), (10.0, 4), (1e3, 5), (1e5, 6)] {
            let xs: Vec<f64> = numbers(seed, 100_000).map(|u| (2.0 * u - 1.0) * scale).collect();
            for chunk in xs.chunks_exact(LANES) {
                let (s, c) = sin_cos(chunk.try_into().unwrap());
                for l in 0..LANES {
                    let (s0, c0) = chunk[l].sin_cos();
                    // near a zero of the function the C library's own error is relative to
                    // the argument's rounding; compare absolutely there
                    for (got, want) in [(s[l], s0), (c[l], c0)] {
                        if want.abs() > 1e-3 {
                            worst = worst.max(ulps(got, want));
                        } else {
                            assert!((got - want).abs() <= 1e-16 * scale.max(1.0), "{} {got} {want}", chunk[l]);
                        }
                    }
                }
            }
        }
        assert!(worst <= 2, "{worst} ulp");
    }

    #[test]
    fn sin_cos_special_arguments() {
        let (s, c) = sin_cos([0.0, -0.0, f64::NAN, 1e300]);
        assert_eq!((s[0].to_bits(), s[1].to_bits(), c[0], c[1]), (0.0f64.to_bits(), (-0.0f64).to_bits(), 1.0, 1.0));
        assert!(s[2].is_nan() && c[2].is_nan());
        assert_eq!((s[3], c[3]), 1e300f64.sin_cos());
        let (s, c) = sin_cos([f64::INFINITY, -f64::INFINITY, 2e5, -3e7]);
        assert!(s[0].is_nan() && c[1].is_nan());
        assert_eq!((s[2], c[3]), (2e5f64.sin(), (-3e7f64).cos()));
    }

    #[test]
    fn atan2_within_two_ulps_of_the_c_library() {
        let mut worst = 0;
        for (scale, seed) in [(1e-200, 11), (1.0, 12), (1e3, 13), (1e200, 14)] {
            let a: Vec<f64> = numbers(seed, 200_000).map(|u| (2.0 * u - 1.0) * scale).collect();
            for chunk in a.chunks_exact(2 * LANES) {
                let (y, x) = chunk.split_at(LANES);
                let got = atan2(y.try_into().unwrap(), x.try_into().unwrap());
                for l in 0..LANES {
                    worst = worst.max(ulps(got[l], y[l].atan2(x[l])));
                }
            }
        }
        // every octant boundary and the reduction's interval ends, both signs
        for &(y, x) in &[(1.0, 1.0), (7.0, 16.0), (11.0, 16.0), (16.0, 7.0), (1.0, 1e-300), (1e-300, 1.0), (3.0, -4.0)]
        {
            for (sy, sx) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
                let got = atan2([sy * y; LANES], [sx * x; LANES])[0];
                worst = worst.max(ulps(got, (sy * y).atan2(sx * x)));
            }
        }
        assert!(worst <= 2, "{worst} ulp");
    }

    #[test]
    fn vector_instruction_sets_give_the_same_bits() {
        // the models run these compiled for AVX2 where the CPU has it (isa::run_wide)
        let a: Vec<f64> = numbers(21, 40_000).map(|u| (2.0 * u - 1.0) * 50.0).collect();
        for chunk in a.chunks_exact(2 * LANES) {
            let (y, x): ([f64; LANES], [f64; LANES]) =
                (chunk[..LANES].try_into().unwrap(), chunk[LANES..].try_into().unwrap());
            let baseline = (sin_cos(x), atan2(y, x));
            let wide = crate::core::isa::run_wide(
                #[inline(always)]
                || (sin_cos(x), atan2(y, x)),
            );
            let bits =
                |((s, c), a): (([f64; LANES], [f64; LANES]), [f64; LANES])| [s, c, a].map(|v| v.map(f64::to_bits));
            assert_eq!(bits(baseline), bits(wide), "at {x:?}, {y:?}");
        }
    }

    #[test]
    fn atan2_special_arguments() {
        let inf = f64::INFINITY;
        let cases = [
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, -0.0),
            (inf, inf),
            (-inf, 1.0),
            (1.0, -inf),
            (f64::NAN, 1.0),
        ];
        for pair in cases.chunks(LANES) {
            let (y, x): (Vec<f64>, Vec<f64>) = pair.iter().copied().unzip();
            let got = atan2(y.clone().try_into().unwrap(), x.clone().try_into().unwrap());
            for l in 0..LANES {
                let want = y[l].atan2(x[l]);
                assert!(
                    got[l].to_bits() == want.to_bits() || (got[l].is_nan() && want.is_nan()),
                    "atan2({}, {}) = {} vs {want}",
                    y[l],
                    x[l],
                    got[l]
                );
            }
        }
    }
}
