//! The natural logarithm in straight-line arithmetic, for the normal draws' tails: glibc's
//! `log` is a call per number; this the compiler puts four to a register.
//!
//! The reduction and polynomial of fdlibm's `e_log.c` (Sun Microsystems, 1993): x = 2ᵏ (1 + f)
//! with 1 + f in [√½, √2), s = f / (2 + f), log(1 + f) = f − f²/2 + s (f²/2 + R(s²)), R of
//! degree 14 in s by fdlibm's seven coefficients, and k log 2 in two parts. Error below 1 ulp
//! (tested against `f64::ln`). The exponent and mantissa come from the bits, without a branch
//! and without a float–integer conversion (which AVX2 lacks).

use super::exp::{LN2_HI, LN2_LO};

/// fdlibm's Lg1..Lg7, by their bits.
const LG: [f64; 7] = [
    f64::from_bits(0x3FE5_5555_5555_5593),
    f64::from_bits(0x3FD9_9999_9997_FA04),
    f64::from_bits(0x3FD2_4924_9422_9359),
    f64::from_bits(0x3FCC_71C5_1D8E_78AF),
    f64::from_bits(0x3FC7_4664_96CB_03DE),
    f64::from_bits(0x3FC3_9A09_D078_C69F),
    f64::from_bits(0x3FC2_F112_DF3E_5244),
];
/// The high word of √½'s bits: mantissas at or above it are taken as 1 + f ≥ √½ with the
/// exponent k, those below as 2 (1 + f) with k − 1.
const SQRT_HALF_HIGH: u64 = 0x3FE6_A09E_0000_0000;
/// 2⁵², whose bits with a small integer in the low mantissa bits are 2⁵² + that integer.
const TWO_52: f64 = 4_503_599_627_370_496.0;

/// log x for a positive normal finite x (no check: subnormals, 0, infinities and NaN give
/// wrong numbers).
#[inline(always)]
pub(crate) fn ln_positive(x: f64) -> f64 {
    // add (1.0's high word − √½'s) so that the exponent field carries k + 1023 for the
    // reduced mantissa, then put the mantissa back over √½'s high word
    let shifted = x.to_bits().wrapping_add(0x3FF0_0000_0000_0000 - SQRT_HALF_HIGH);
    let biased = shifted >> 52;
    let mantissa = f64::from_bits((shifted & 0x000F_FFFF_FFFF_FFFF) + SQRT_HALF_HIGH);
    let k = f64::from_bits(biased | TWO_52.to_bits()) - (TWO_52 + 1023.0);
    let f = mantissa - 1.0;
    let half_square = 0.5 * f * f;
    let s = f / (2.0 + f);
    let (z, w) = (s * s, s * s * (s * s));
    let even = w * (LG[1] + w * (LG[3] + w * LG[5]));
    let odd = z * (LG[0] + w * (LG[2] + w * (LG[4] + w * LG[6])));
    let r = odd + even;
    k * LN2_HI - ((half_square - (s * (half_square + r) + k * LN2_LO)) - f)
}

#[cfg(test)]
mod tests {
    use super::super::exp::tests::ulps;
    use super::*;

    #[test]
    fn agrees_with_the_library_log() {
        let mut worst = 0;
        // over the normal range, and densely around 1 and in the normal draws' tails (0, 0.075]
        let wide = (0..200_000).map(|i| 2f64.powf(-1021.0 + 2044.0 * (i as f64 + 0.37) / 200_000.0));
        let near_one = (0..200_000).map(|i| 0.5 + (i as f64 + 0.61) / 200_000.0);
        let tails = (0..200_000).map(|i| 0.075 * ((i as f64 + 0.5) / 200_000.0).powi(8));
        for x in wide.chain(near_one).chain(tails).chain([1.0, 2.0, 0.5, f64::MIN_POSITIVE, f64::MAX]) {
            let d = ulps(ln_positive(x), x.ln());
            assert!(d <= 1, "x = {x:e}: {} against {}", ln_positive(x), x.ln());
            worst = worst.max(d);
        }
        assert_eq!(ln_positive(1.0), 0.0);
        assert!(worst <= 1);
    }
}
