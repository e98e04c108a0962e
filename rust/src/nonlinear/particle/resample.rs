//! Resampling: M ancestor indices drawn so that particle i is copied M·Wᵢ times in
//! expectation (Söderström (9.95)–(9.97) for the multinomial scheme; Kitagawa 1996 and Douc,
//! Cappé & Moulines 2005 for the others).
//!
//! Every scheme maps ordered uniforms u₁ ≤ … ≤ u_M in (0, 1) through the inverse of the
//! cumulative weights: aₖ is the first j with W₁ + … + Wⱼ ≥ uₖ · ΣW (the book's
//! W_{j−1} < u ≤ W_j, with the total in place of 1 so that rounding cannot run off the end,
//! and a zero weight is never chosen). The indices come out in increasing order (the residual
//! scheme's: the sure copies in increasing order, then the drawn ones).

use super::random::Stream;
use crate::error::{Error, Result};

/// How the ancestors are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Resampling {
    /// M independent draws from the weights (the book's, (9.95)–(9.97)): the uniforms are
    /// ordered in O(M) as the normalized partial sums of M + 1 exponential spacings.
    Multinomial,
    /// uₖ = (k − 1 + U)/M with a single U: the least variance in most cases.
    Systematic,
    /// uₖ = (k − 1 + Uₖ)/M with M independent Uₖ.
    Stratified,
    /// ⌊M Wᵢ⌋ copies of each particle, then the remaining R draws multinomially from the
    /// remainders M Wᵢ − ⌊M Wᵢ⌋ (Liu & Chen 1998).
    Residual,
}

impl Resampling {
    /// The scheme named `name` ("multinomial", "systematic", "stratified" or "residual").
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "multinomial" => Ok(Resampling::Multinomial),
            "systematic" => Ok(Resampling::Systematic),
            "stratified" => Ok(Resampling::Stratified),
            "residual" => Ok(Resampling::Residual),
            other => Err(Error::arg(
                "resample",
                format!("expected \"multinomial\", \"systematic\", \"stratified\" or \"residual\", got {other:?}"),
            )),
        }
    }
}

/// The scratch of [`resample`]: kept by the filter, so that resampling allocates nothing
/// after the first step.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scratch {
    uniforms: Vec<f64>,
    remainders: Vec<f64>,
}

/// The ancestors `out` (M indices) of the M particles with weights `w` (not
/// negative, finite, not all zero; normalized or not), the uniforms from `stream`.
pub(crate) fn resample(scheme: Resampling, w: &[f64], stream: Stream, scratch: &mut Scratch, out: &mut [usize]) {
    let m = w.len();
    let mf = m as f64;
    let u = &mut scratch.uniforms;
    match scheme {
        Resampling::Multinomial => {
            ordered_uniforms(stream, m, u);
            inverse_cdf(w, u, out);
        }
        Resampling::Systematic => {
            let u0 = stream.uniform(0);
            u.clear();
            u.extend((0..m).map(|k| (k as f64 + u0) / mf));
            inverse_cdf(w, u, out);
        }
        Resampling::Stratified => {
            u.clear();
            u.extend((0..m).map(|k| (k as f64 + stream.uniform(k as u64)) / mf));
            inverse_cdf(w, u, out);
        }
        Resampling::Residual => residual(w, stream, scratch, out),
    }
}

/// M ordered uniforms into `u`: the partial sums of M + 1 standard exponentials (draws
/// `0..=M` of `stream`) over their total, which are distributed as the order statistics of M
/// independent uniforms.
fn ordered_uniforms(stream: Stream, m: usize, u: &mut Vec<f64>) {
    u.clear();
    let mut sum = 0.0;
    for k in 0..=m as u64 {
        sum -= stream.uniform(k).ln();
        u.push(sum);
    }
    let total = u.pop().unwrap_or(1.0);
    for v in u.iter_mut() {
        *v /= total;
    }
}

/// `out[k]` = the first j with w₀ + … + wⱼ ≥ u[k] · Σw, for increasing `u` in (0, 1).
fn inverse_cdf(w: &[f64], u: &[f64], out: &mut [usize]) {
    let total: f64 = w.iter().sum();
    let last = w.len() - 1;
    let (mut j, mut cumulative) = (0, w[0]);
    for (a, &uk) in out.iter_mut().zip(u) {
        let target = uk * total;
        while cumulative < target && j < last {
            j += 1;
            cumulative += w[j];
        }
        *a = j;
    }
}

fn residual(w: &[f64], stream: Stream, scratch: &mut Scratch, out: &mut [usize]) {
    let m = w.len();
    let total: f64 = w.iter().sum();
    let scale = m as f64 / total;
    let mut filled = 0;
    for (i, &wi) in w.iter().enumerate() {
        // at most M copies in all: M Wᵢ sum to M up to rounding
        let copies = ((wi * scale).floor() as usize).min(m - filled);
        out[filled..filled + copies].fill(i);
        filled += copies;
    }
    let rest = m - filled;
    if rest == 0 {
        return;
    }
    // the rest drawn multinomially from the remainders
    let Scratch { uniforms, remainders } = scratch;
    remainders.clear();
    remainders.extend(w.iter().map(|&wi| wi * scale - (wi * scale).floor()));
    if remainders.iter().all(|&r| r <= 0.0) {
        // rounding left draws but no remainder: spread them by the weights themselves
        remainders.clear();
        remainders.extend_from_slice(w);
    }
    ordered_uniforms(stream, rest, uniforms);
    inverse_cdf(remainders, uniforms, &mut out[filled..]);
}

#[cfg(test)]
mod tests {
    use super::super::random::Purpose;
    use super::*;

    const SCHEMES: [Resampling; 4] =
        [Resampling::Multinomial, Resampling::Systematic, Resampling::Stratified, Resampling::Residual];

    #[test]
    fn zero_weights_are_never_chosen_and_indices_increase() {
        let w = [0.0, 0.3, 0.0, 0.0, 0.5, 0.2, 0.0];
        for scheme in SCHEMES {
            for seed in 0..200 {
                let mut out = [0; 7];
                resample(scheme, &w, Stream::new(seed, 0, Purpose::Resampling), &mut Scratch::default(), &mut out);
                assert!(out.iter().all(|&a| w[a] > 0.0), "{scheme:?} {out:?}");
                let sorted = out.windows(2).all(|p| p[0] <= p[1]);
                assert!(sorted || scheme == Resampling::Residual, "{scheme:?} {out:?}");
            }
        }
    }

    #[test]
    fn expected_copies_are_m_times_the_weights() {
        let w = [0.05, 0.4, 0.15, 0.1, 0.3];
        for scheme in SCHEMES {
            let mut counts = [0usize; 5];
            let runs = 20_000;
            for seed in 0..runs {
                let mut out = [0; 5];
                resample(scheme, &w, Stream::new(seed, 3, Purpose::Resampling), &mut Scratch::default(), &mut out);
                out.iter().for_each(|&a| counts[a] += 1);
            }
            for (i, &c) in counts.iter().enumerate() {
                let mean = c as f64 / runs as f64;
                // the standard error of the mean count is at most √(M w (1 − w) / runs) < 0.008
                assert!((mean - 5.0 * w[i]).abs() < 0.04, "{scheme:?} particle {i}: {mean}");
            }
        }
    }
}
