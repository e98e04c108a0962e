//! `exp` of many numbers at once, for the particle weights: glibc's `exp` is a call per number;
//! this is straight-line arithmetic that the compiler puts four to a register.
//!
//! exp(x) = 2ᵏ eʳ with k = round(x / log 2) and r = x − k log 2 (Cody & Waite: log 2 in two
//! parts, the first with trailing zero bits so that k × it is exact), |r| ≤ ½ log 2, and eʳ
//! by its Taylor polynomial of degree 13 (truncation below 10⁻¹⁷ relative): within 2 ulp of
//! the correctly rounded value over the normal range (tested against `f64::exp`). The integer
//! k comes out of the rounding constant 1.5 × 2⁵² (no float-to-integer conversion, which AVX2
//! lacks) and 2ᵏ is built in the exponent bits, in two halves so that results below the
//! smallest normal number come out as subnormals.

/// log 2 = LN2_HI + LN2_LO, LN2_HI with its low 32 bits zero (fdlibm's split, by its bits:
/// 6.93147180369123816490e-01 and 1.90821492927058770002e-10).
pub(super) const LN2_HI: f64 = f64::from_bits(0x3FE6_2E42_FEE0_0000);
pub(super) const LN2_LO: f64 = f64::from_bits(0x3DEA_39EF_3579_3C76);
/// 1.5 × 2⁵²: adding it rounds to an integer held in the low mantissa bits.
const ROUNDER: f64 = 6_755_399_441_055_744.0;

/// 1/k! for k = 0..=13, the Taylor coefficients of eʳ.
const TAYLOR: [f64; 14] = {
    let mut c = [1.0; 14];
    let mut k = 1;
    while k < 14 {
        c[k] = c[k - 1] / k as f64;
        k += 1;
    }
    c
};

/// eˣ, for x ≤ 0 or −∞ (not NaN; 0 below −745.2, where eˣ rounds to 0).
#[inline(always)]
pub(crate) fn exp_nonpositive(x: f64) -> f64 {
    let x = x.max(-746.0);
    let shifted = x * std::f64::consts::LOG2_E + ROUNDER;
    let k = shifted - ROUNDER;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let mut p = TAYLOR[13];
    for &c in TAYLOR[..13].iter().rev() {
        p = p * r + c;
    }
    // k in the low bits of `shifted` (two's complement against ROUNDER's bits): 2ᵏ as
    // 2^⌊k/2⌋ × 2^(k − ⌊k/2⌋), each a normal number for k ≥ −1076
    let k_int = shifted.to_bits().wrapping_sub(ROUNDER.to_bits()) as i64;
    let half = k_int >> 1;
    let scale = |e: i64| f64::from_bits(((e + 1023) as u64) << 52);
    p * scale(half) * scale(k_int - half)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// The distance of `a` from `b` in units in the last place.
    pub(in super::super) fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    #[test]
    fn agrees_with_the_library_exp() {
        let mut worst = 0;
        for i in 0..1_000_000 {
            let x = -745.0 * i as f64 / 1e6 - (i % 7) as f64 * 1e-9;
            let (got, want) = (exp_nonpositive(x), x.exp());
            if want >= f64::MIN_POSITIVE {
                worst = worst.max(ulps(got, want));
            } else {
                // subnormal results: within an absolute 2 ulp of the smallest subnormal scale
                assert!((got - want).abs() <= 4.0 * want.abs() * f64::EPSILON + 1e-323, "{x}: {got} vs {want}");
            }
        }
        assert!(worst <= 2, "worst {worst} ulp");
        for x in [0.0, -0.0, -1e-300, -1e-10, -0.5, -1.0, -700.0] {
            assert!(ulps(exp_nonpositive(x), x.exp()) <= 2, "{x}");
        }
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert_eq!(exp_nonpositive(-746.0), 0.0);
        assert_eq!(exp_nonpositive(f64::NEG_INFINITY), 0.0);
    }
}
