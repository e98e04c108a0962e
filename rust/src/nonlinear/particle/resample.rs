//! Resampling: N ancestor indices drawn from M particles so that particle i is copied N·Wᵢ
//! times in expectation (N = M, or M / r with the book's r copies; Söderström (9.95)–(9.97)
//! for the multinomial scheme; Kitagawa 1996 and Douc, Cappé & Moulines 2005 for the others).
//!
//! Every scheme maps ordered uniforms u₁ ≤ … ≤ u_N in (0, 1) through the inverse of the
//! cumulative weights: aₖ is the first j with W₁ + … + Wⱼ ≥ uₖ · ΣW (the book's
//! W_{j−1} < u ≤ W_j, with the total in place of 1 so that rounding cannot run off the end,
//! and a zero weight is never chosen). The indices come out in increasing order (the residual
//! scheme's: the sure copies in increasing order, then the drawn ones).

use super::random::Stream;
use crate::core::batch::par::*;
use crate::error::{Error, Result};

/// The indices of a parallel block (fixed, so that the sums do not depend on the threads).
const BLOCK: usize = 4096;

/// How the ancestors are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Resampling {
    /// N independent draws from the weights (the book's, (9.95)–(9.97)): the uniforms are
    /// ordered in O(N) as the normalized partial sums of N + 1 exponential spacings.
    Multinomial,
    /// uₖ = (k − 1 + U)/N with a single U: the least variance in most cases.
    Systematic,
    /// uₖ = (k − 1 + Uₖ)/N with N independent Uₖ.
    Stratified,
    /// ⌊N Wᵢ⌋ copies of each particle, then the remaining draws multinomially from the
    /// remainders N Wᵢ − ⌊N Wᵢ⌋ (Liu & Chen 1998).
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
    cumulative: Vec<f64>,
    block_totals: Vec<f64>,
}

/// The ancestors `out` (N = `out.len()` indices) of the M particles with weights `w` (not
/// negative, finite, not all zero; normalized or not), the uniforms from `stream`: particle i
/// is chosen N Wᵢ times in expectation (N = M but for the book's r copies, N = M / r).
pub(crate) fn resample(scheme: Resampling, w: &[f64], stream: Stream, scratch: &mut Scratch, out: &mut [usize]) {
    let draws = out.len();
    let nf = draws as f64;
    let Scratch { uniforms: u, cumulative, block_totals, .. } = scratch;
    match scheme {
        Resampling::Multinomial => ordered_uniforms(stream, draws, u),
        Resampling::Systematic | Resampling::Stratified => {
            u.resize(draws, 0.0);
            let u0 = stream.uniform(0);
            u.par_chunks_mut(BLOCK).enumerate().for_each(|(b, u)| {
                let ks = (b * BLOCK..).zip(u.iter_mut());
                // two loops, so that the systematic one computes no draw per k
                match scheme {
                    Resampling::Systematic => ks.for_each(|(k, v)| *v = (k as f64 + u0) / nf),
                    _ => ks.for_each(|(k, v)| *v = (k as f64 + stream.uniform(k as u64)) / nf),
                }
            });
        }
        Resampling::Residual => return residual(w, stream, scratch, out),
    }
    cumulative_sums(w, cumulative, block_totals);
    inverse_cdf(cumulative, u, out);
}

/// The cumulative sums of `w` into `c`: each block's running sums in parallel, then the
/// blocks' totals in order, added to the later blocks (nondecreasing, as each step rounds
/// monotonically).
fn cumulative_sums(w: &[f64], c: &mut Vec<f64>, block_totals: &mut Vec<f64>) {
    c.resize(w.len(), 0.0);
    block_totals.resize(w.len().div_ceil(BLOCK), 0.0);
    let blocks = c.par_chunks_mut(BLOCK).zip(w.par_chunks(BLOCK));
    blocks.zip(block_totals.par_iter_mut()).for_each(|((c, w), total)| {
        let mut sum = 0.0;
        for (ci, &wi) in c.iter_mut().zip(w) {
            sum += wi;
            *ci = sum;
        }
        *total = sum;
    });
    let mut offset = 0.0;
    for total in block_totals.iter_mut() {
        let start = offset;
        offset += *total;
        *total = start;
    }
    c.par_chunks_mut(BLOCK).zip(block_totals.par_iter_mut()).skip(1).for_each(|(c, &mut start)| {
        c.iter_mut().for_each(|ci| *ci += start);
    });
}

/// N ordered uniforms into `u`: the partial sums of N + 1 standard exponentials (draws
/// `0..=N` of `stream`) over their total, which are distributed as the order statistics of N
/// independent uniforms.
fn ordered_uniforms(stream: Stream, draws: usize, u: &mut Vec<f64>) {
    // the exponentials in parallel, their running sums in order (the same bits either way)
    u.resize(draws + 1, 0.0);
    u.par_chunks_mut(BLOCK).enumerate().for_each(|(b, u)| {
        for (i, v) in u.iter_mut().enumerate() {
            *v = -stream.uniform((b * BLOCK + i) as u64).ln();
        }
    });
    let mut sum = 0.0;
    for v in u.iter_mut() {
        sum += *v;
        *v = sum;
    }
    let total = u.pop().unwrap_or(1.0);
    for v in u.iter_mut() {
        *v /= total;
    }
}

/// `out[k]` = the first j with `c[j]` ≥ u[k] · c[M − 1], for the cumulative weights `c` and
/// increasing `u` in (0, 1): blocks of k in parallel, each from a binary search for its
/// first j.
fn inverse_cdf(c: &[f64], u: &[f64], out: &mut [usize]) {
    let (last, total) = (c.len() - 1, c[c.len() - 1]);
    out.par_chunks_mut(BLOCK).zip(u.par_chunks(BLOCK)).for_each(|(out, u)| {
        let mut j = c.partition_point(|&v| v < u[0] * total).min(last);
        for (a, &uk) in out.iter_mut().zip(u) {
            let target = uk * total;
            while c[j] < target && j < last {
                j += 1;
            }
            *a = j;
        }
    });
}

fn residual(w: &[f64], stream: Stream, scratch: &mut Scratch, out: &mut [usize]) {
    let draws = out.len();
    let total: f64 = w.iter().sum();
    let scale = draws as f64 / total;
    let mut filled = 0;
    for (i, &wi) in w.iter().enumerate() {
        // at most N copies in all: N Wᵢ sum to N up to rounding
        let copies = ((wi * scale).floor() as usize).min(draws - filled);
        out[filled..filled + copies].fill(i);
        filled += copies;
    }
    let rest = draws - filled;
    if rest == 0 {
        return;
    }
    // the rest drawn multinomially from the remainders
    let Scratch { uniforms, remainders, cumulative, block_totals } = scratch;
    remainders.clear();
    remainders.extend(w.iter().map(|&wi| wi * scale - (wi * scale).floor()));
    if remainders.iter().all(|&r| r <= 0.0) {
        // rounding left draws but no remainder: spread them by the weights themselves
        remainders.clear();
        remainders.extend_from_slice(w);
    }
    ordered_uniforms(stream, rest, uniforms);
    cumulative_sums(remainders, cumulative, block_totals);
    inverse_cdf(cumulative, uniforms, &mut out[filled..]);
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

    /// The mean number of times each of the weights `W` is chosen by `draws` draws, over
    /// 20,000 seeds (step `t` of the streams).
    fn mean_copies(scheme: Resampling, draws: usize, t: usize) -> [f64; 5] {
        let runs = 20_000;
        let mut counts = [0usize; 5];
        let mut out = vec![0; draws];
        for seed in 0..runs {
            resample(scheme, &W, Stream::new(seed, t, Purpose::Resampling), &mut Scratch::default(), &mut out);
            out.iter().for_each(|&a| counts[a] += 1);
        }
        counts.map(|c| c as f64 / runs as f64)
    }

    const W: [f64; 5] = [0.05, 0.4, 0.15, 0.1, 0.3];

    #[test]
    fn expected_copies_are_m_times_the_weights() {
        for scheme in SCHEMES {
            for (i, mean) in mean_copies(scheme, 5, 3).into_iter().enumerate() {
                // the standard error of the mean count is at most √(M w (1 − w) / runs) < 0.008
                assert!((mean - 5.0 * W[i]).abs() < 0.04, "{scheme:?} particle {i}: {mean}");
            }
        }
    }

    #[test]
    fn fewer_draws_than_particles_choose_each_n_times_its_weight() {
        // N = 2 draws from M = 5 particles (the book's r copies: M = r N, here with M / N not
        // whole, which the filter never asks, but the schemes do not need it)
        for scheme in SCHEMES {
            for (i, mean) in mean_copies(scheme, 2, 1).into_iter().enumerate() {
                // standard error at most √(N w (1 − w) / runs) < 0.005
                assert!((mean - 2.0 * W[i]).abs() < 0.025, "{scheme:?} particle {i}: {mean}");
            }
        }
    }
}
