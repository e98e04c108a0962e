//! kfast's own random numbers: a counter-based generator, so that a draw depends only on
//! (seed, step, purpose, index) and never on which thread made it or in which order — the
//! particle filters give the same bits for any thread count.
//!
//! A draw is SplitMix64's output function (Steele, Lea & Flood 2014) at a counter:
//! `mix(key + (i + 1) γ)` with γ the golden-ratio increment, the key itself a SplitMix hash of
//! the seed, the step and the purpose. Within one key this is exactly the SplitMix64 sequence
//! (it passes BigCrush); keys are pseudo-random 64-bit offsets, so two streams overlap only if
//! their keys fall within the few million draws of a step of each other (probability about
//! 2⁻⁴⁰ per pair of streams). The same arithmetic in NumPy's wrapping `uint64` reproduces every
//! draw (`kfast.reference.particle`).
//!
//! Normal draws are the inverse normal CDF of a uniform, Wichura's algorithm AS 241 (PPND16,
//! 1988: relative error about 1e−16): one uniform per normal, so the number of draws per
//! particle is fixed and a particle's noise is addressed by its index.

use super::log::ln_positive;
use crate::core::isa::run_wide;

/// The golden-ratio increment of SplitMix64.
const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's finalizer: a bijection of u64 that mixes every input bit into every output bit.
#[inline(always)]
pub(crate) fn mix(z: u64) -> u64 {
    let z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    let z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// What a stream of draws is for (part of its key).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub(crate) enum Purpose {
    /// The particles of the prior x(0|−1).
    Prior = 1,
    /// The process noise of the step from t to t + 1.
    ProcessNoise = 2,
    /// The uniforms of the resampling at step t.
    Resampling = 3,
    /// The kernel jitter of the regularization after the resampling at step t.
    Regularization = 4,
}

/// The draws of one (seed, step, purpose): `bits(i)` is the i-th 64-bit draw.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stream {
    key: u64,
}

impl Stream {
    pub(crate) fn new(seed: u64, step: usize, purpose: Purpose) -> Self {
        let seed_key = mix(seed.wrapping_add(GAMMA));
        let step_key = mix(seed_key.wrapping_add((step as u64).wrapping_add(1).wrapping_mul(GAMMA)));
        Stream { key: mix(step_key.wrapping_add((purpose as u64).wrapping_mul(GAMMA))) }
    }

    /// The i-th 64 random bits.
    #[inline(always)]
    pub(crate) fn bits(self, i: u64) -> u64 {
        mix(self.key.wrapping_add(i.wrapping_add(1).wrapping_mul(GAMMA)))
    }

    /// The i-th uniform in the open interval (0, 1): the top 52 bits, centred in their cell.
    /// (Converted through the exponent bits of 2⁵², exact for integers below 2⁵², so that four
    /// convert at once in AVX2, which has no 64-bit integer conversion.)
    #[inline(always)]
    pub(crate) fn uniform(self, i: u64) -> f64 {
        const TWO_52: f64 = (1u64 << 52) as f64;
        let top = f64::from_bits((self.bits(i) >> 12) | TWO_52.to_bits()) - TWO_52;
        (top + 0.5) * (1.0 / TWO_52)
    }

    /// The i-th standard normal: the inverse normal CDF of the i-th uniform ([`normals`]
    /// makes many at a time).
    ///
    /// [`normals`]: Self::normals
    #[cfg(test)]
    pub(crate) fn normal(self, i: u64) -> f64 {
        normal_quantile(self.uniform(i))
    }
}

/// Scratch of [`Stream::normals`].
#[derive(Debug, Clone, Default)]
pub(crate) struct NormalScratch {
    uniforms: Vec<f64>,
    tails: Vec<u32>,
    tail_values: Vec<f64>,
}

impl Stream {
    /// `out[k]` = draw `first + k` as a standard normal, the same numbers as
    /// [`normal`](Self::normal), many at a time, so that no branch depends on a random
    /// number: the uniforms and the central rational function for all of them in vector
    /// registers, then the tails (15% of the draws) gathered and done in vector registers too.
    pub(crate) fn normals(self, first: u64, out: &mut [f64], scratch: &mut NormalScratch) {
        let NormalScratch { uniforms, tails, tail_values } = scratch;
        uniforms.resize(out.len(), 0.0);
        // in AVX2 where the CPU has it (the same bits: no FMA)
        run_wide(
            #[inline(always)]
            || self.central_normals(first, uniforms, out),
        );
        // the tails' indices, without a branch per draw
        tails.resize(out.len(), 0);
        let mut count = 0;
        for (k, &p) in uniforms.iter().enumerate() {
            tails[count] = k as u32;
            count += usize::from((p - 0.5).abs() > 0.425);
        }
        tail_values.clear();
        tail_values.extend(tails[..count].iter().map(|&k| uniforms[k as usize]));
        run_wide(
            #[inline(always)]
            || tail_values.iter_mut().for_each(|v| *v = tail_quantile(*v)),
        );
        for (&k, &z) in tails[..count].iter().zip(tail_values.iter()) {
            out[k as usize] = z;
        }
    }

    /// Draws `first..` as uniforms, and AS 241's central branch of each into `out` (a wrong
    /// value for the tails, which the caller replaces).
    #[inline(always)]
    fn central_normals(self, first: u64, uniforms: &mut [f64], out: &mut [f64]) {
        for (k, u) in uniforms.iter_mut().enumerate() {
            *u = self.uniform(first + k as u64);
        }
        for (z, &p) in out.iter_mut().zip(uniforms.iter()) {
            let q = p - 0.5;
            *z = q * ratio(&CENTRE_NUM, &CENTRE_DEN, 0.180625 - q * q);
        }
    }
}

/// The standard normal quantile Φ⁻¹(p) for p in (0, 1): Wichura (1988), AS 241 PPND16 —
/// rational approximations in the centre (|p − ½| ≤ 0.425), in the tails up to
/// √(−log min(p, 1 − p)) ≤ 5 and beyond.
#[cfg(test)]
fn normal_quantile(p: f64) -> f64 {
    let q = p - 0.5;
    if q.abs() <= 0.425 {
        let r = 0.180625 - q * q;
        return q * ratio(&CENTRE_NUM, &CENTRE_DEN, r);
    }
    tail_quantile(p)
}

/// Φ⁻¹(p) for |p − ½| > 0.425, without a branch (both of AS 241's tail approximations,
/// the one that applies chosen), the logarithm our own (`log`) so that it vectorizes.
#[inline(always)]
fn tail_quantile(p: f64) -> f64 {
    let lower = p < 0.5;
    let tail = if lower { p } else { 1.0 - p };
    let r = (-ln_positive(tail)).sqrt();
    let near = ratio(&NEAR_NUM, &NEAR_DEN, r - 1.6);
    let far = ratio(&FAR_NUM, &FAR_DEN, r - 5.0);
    let value = if r <= 5.0 { near } else { far };
    if lower {
        -value
    } else {
        value
    }
}

/// `num(r) / den(r)`, both by Horner's rule, the coefficients from the constant term up
/// (`den` has an implicit leading 1 as its constant term).
#[inline(always)]
fn ratio(num: &[f64; 8], den: &[f64; 7], r: f64) -> f64 {
    let mut top = num[7];
    for &c in num[..7].iter().rev() {
        top = top * r + c;
    }
    let mut bottom = den[6];
    for &c in den[..6].iter().rev() {
        bottom = bottom * r + c;
    }
    top / (bottom * r + 1.0)
}

// AS 241's coefficients as published (20 digits; the compiler rounds them to the nearest f64)
#[allow(clippy::excessive_precision)]
const CENTRE_NUM: [f64; 8] = [
    3.387_132_872_796_366_608,
    133.141_667_891_784_377_45,
    1_971.590_950_306_551_442_7,
    13_731.693_765_509_461_125,
    45_921.953_931_549_871_457,
    67_265.770_927_008_700_853,
    33_430.575_583_588_128_105,
    2_509.080_928_730_122_672_7,
];
#[allow(clippy::excessive_precision)]
const CENTRE_DEN: [f64; 7] = [
    42.313_330_701_600_911_252,
    687.187_007_492_057_908_3,
    5_394.196_021_424_751_107_7,
    21_213.794_301_586_595_867,
    39_307.895_800_092_710_61,
    28_729.085_735_721_942_674,
    5_226.495_278_852_854_561,
];
#[allow(clippy::excessive_precision)]
const NEAR_NUM: [f64; 8] = [
    1.423_437_110_749_683_577_34,
    4.630_337_846_156_545_295_9,
    5.769_497_221_460_691_405_5,
    3.647_848_324_763_204_605_04,
    1.270_458_252_452_368_382_58,
    0.241_780_725_177_450_611_77,
    0.022_723_844_989_269_184_583_3,
    0.000_774_545_014_278_341_407_64,
];
#[allow(clippy::excessive_precision)]
const NEAR_DEN: [f64; 7] = [
    2.053_191_626_637_758_821_87,
    1.676_384_830_183_803_849_4,
    0.689_767_334_985_100_004_55,
    0.148_103_976_427_480_074_59,
    0.015_198_666_563_616_457_196_6,
    0.000_547_593_808_499_534_494_6,
    1.050_750_071_644_416_843_24e-9,
];
#[allow(clippy::excessive_precision)]
const FAR_NUM: [f64; 8] = [
    6.657_904_643_501_103_777_2,
    5.463_784_911_164_114_369_9,
    1.784_826_539_917_291_335_8,
    0.296_560_571_828_504_891_23,
    0.026_532_189_526_576_123_093,
    0.001_242_660_947_388_078_438_6,
    0.000_027_115_555_687_434_875_781_5,
    2.010_334_399_292_288_132_65e-7,
];
#[allow(clippy::excessive_precision)]
const FAR_DEN: [f64; 7] = [
    0.599_832_206_555_887_937_69,
    0.136_929_880_922_735_805_31,
    0.014_875_361_290_850_614_852_5,
    0.000_786_869_131_145_613_259_1,
    0.000_018_463_183_175_100_546_818,
    1.421_511_758_316_445_888_7e-7,
    2.044_263_103_389_939_785_64e-15,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_is_odd_and_hits_known_values() {
        // Φ⁻¹ by mpmath to 16 digits: one value in each of AS 241's three regions
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-14);
        assert!((normal_quantile(1e-10) + 6.361_340_902_404_056).abs() < 1e-13);
        assert!((normal_quantile(1e-300) + 37.047_096_299_361_2).abs() < 1e-11);
        for p in [1e-5, 0.01, 0.2, 0.3, 0.4999] {
            let (low, high) = (normal_quantile(p), normal_quantile(1.0 - p));
            assert!((low + high).abs() <= 1e-12 * high.abs(), "p = {p}");
        }
        assert_eq!(normal_quantile(0.5), 0.0);
    }

    #[test]
    fn many_normals_at_once_are_the_same_numbers() {
        let stream = Stream::new(5, 2, Purpose::ProcessNoise);
        let mut out = vec![0.0; 10_001];
        stream.normals(17, &mut out, &mut NormalScratch::default());
        for (k, &z) in out.iter().enumerate() {
            assert_eq!(z.to_bits(), stream.normal(17 + k as u64).to_bits(), "draw {k}");
        }
    }

    #[test]
    fn streams_differ_by_seed_step_and_purpose() {
        let a = Stream::new(0, 0, Purpose::Prior);
        let others = [
            Stream::new(1, 0, Purpose::Prior),
            Stream::new(0, 1, Purpose::Prior),
            Stream::new(0, 0, Purpose::ProcessNoise),
        ];
        for b in others {
            assert!((0..100).all(|i| a.bits(i) != b.bits(i)));
        }
        let u: Vec<f64> = (0..100_000).map(|i| a.uniform(i)).collect();
        assert!(u.iter().all(|&v| v > 0.0 && v < 1.0));
        let mean = u.iter().sum::<f64>() / u.len() as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
    }
}
