//! The median and mean filters of Söderström section 9.7: over a causal window of n = 2m + 1 samples,
//! y(t) = median{u(t−n+1), …, u(t)} (9.105) and y(t) = (u(t−n+1) + … + u(t)) / n (9.106),
//! each column of a (T, k) series on its own.
//!
//! The median keeps the window in two ordered sets — the lower half and the upper half — so
//! that a sample enters and leaves in O(log n) and the median is the largest of the lower half.
//! The mean keeps a running sum with Neumaier's compensation, so that adding and removing T
//! samples does not accumulate rounding (its error stays that of one sum of the window).
//!
//! A window with a missing (NaN) sample gives NaN; the others are exact.

use std::collections::BTreeSet;

use crate::error::{Error, Result};

/// What the filters give before the window is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartUp {
    /// NaN for t < n − 1.
    Valid,
    /// The statistic of the t + 1 samples so far (for an even count, the mean of the two
    /// middle ones, as NumPy's median).
    Grow,
}

impl StartUp {
    /// "valid" or "grow".
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "valid" => Ok(StartUp::Valid),
            "grow" => Ok(StartUp::Grow),
            other => Err(Error::arg("mode", format!("expected \"valid\" or \"grow\", got {other:?}"))),
        }
    }
}

/// The causal running median of window `n` (odd) of each column of `u` (`steps × width`,
/// row-major) into a new array of the same shape.
pub fn median_filter(u: &[f64], steps: usize, width: usize, n: usize, start: StartUp) -> Result<Vec<f64>> {
    slide::<Halves>(u, steps, width, n, start)
}

/// The causal running mean of window `n` (odd) of each column of `u`, as [`median_filter`].
pub fn mean_filter(u: &[f64], steps: usize, width: usize, n: usize, start: StartUp) -> Result<Vec<f64>> {
    slide::<RunningMean>(u, steps, width, n, start)
}

/// The samples of a window, and their statistic.
trait Window: Default {
    fn enter(&mut self, v: f64, t: usize);
    fn leave(&mut self, v: f64, t: usize);
    fn statistic(&self) -> f64;
}

/// Slides a window of `n` down each column: every finite sample enters and leaves once; the
/// statistic goes out where the window is wanted and holds no NaN.
fn slide<W: Window>(u: &[f64], steps: usize, width: usize, n: usize, start: StartUp) -> Result<Vec<f64>> {
    if n.is_multiple_of(2) {
        return Err(Error::arg("n", format!("must be odd (a window of 2m + 1 samples), got {n}")));
    }
    if steps.checked_mul(width) != Some(u.len()) {
        return Err(Error::arg("u", format!("has {} numbers, not {steps} × {width}", u.len())));
    }
    if let Some(i) = u.iter().position(|v| v.is_infinite()) {
        return Err(Error::arg_at("u", i / width, format!("contains {}", u[i])));
    }
    let mut out = vec![f64::NAN; u.len()];
    for c in 0..width {
        let (mut window, mut missing) = (W::default(), 0usize);
        for t in 0..steps {
            let v = u[t * width + c];
            if v.is_nan() {
                missing += 1;
            } else {
                window.enter(v, t);
            }
            if t >= n {
                match u[(t - n) * width + c] {
                    old if old.is_nan() => missing -= 1,
                    old => window.leave(old, t - n),
                }
            }
            if missing == 0 && (t + 1 >= n || start == StartUp::Grow) {
                out[t * width + c] = window.statistic();
            }
        }
    }
    Ok(out)
}

/// A sample in an ordered set: its bits mapped so that unsigned order is numeric order, and
/// its step (so that equal values are distinct entries).
type Entry = (u64, usize);

fn entry(v: f64, t: usize) -> Entry {
    let bits = v.to_bits();
    (if bits >> 63 == 1 { !bits } else { bits | 1 << 63 }, t)
}

fn value(e: Entry) -> f64 {
    let bits = e.0;
    f64::from_bits(if bits >> 63 == 1 { bits & !(1 << 63) } else { !bits })
}

/// The window's samples in a lower and an upper half: every lower ≤ every upper, and the lower
/// half has as many samples as the upper or one more.
#[derive(Default)]
struct Halves {
    lower: BTreeSet<Entry>,
    upper: BTreeSet<Entry>,
}

impl Window for Halves {
    fn enter(&mut self, v: f64, t: usize) {
        let e = entry(v, t);
        match self.lower.last() {
            Some(&top) if e > top => self.upper.insert(e),
            _ => self.lower.insert(e),
        };
        self.balance();
    }

    fn leave(&mut self, v: f64, t: usize) {
        let e = entry(v, t);
        if !self.lower.remove(&e) {
            self.upper.remove(&e);
        }
        self.balance();
    }

    /// The middle sample, or the mean of the two middle ones for an even count.
    fn statistic(&self) -> f64 {
        let low = value(*self.lower.last().expect("the window is not empty"));
        if self.lower.len() > self.upper.len() {
            return low;
        }
        (low + value(*self.upper.first().expect("the upper half is not empty"))) / 2.0
    }
}

impl Halves {
    fn balance(&mut self) {
        while self.lower.len() > self.upper.len() + 1 {
            let top = self.lower.pop_last().expect("the lower half is not empty");
            self.upper.insert(top);
        }
        while self.upper.len() > self.lower.len() {
            let bottom = self.upper.pop_first().expect("the upper half is not empty");
            self.lower.insert(bottom);
        }
    }
}

/// The window's sum (compensated) and count.
#[derive(Default)]
struct RunningMean {
    sum: CompensatedSum,
    count: usize,
}

impl Window for RunningMean {
    fn enter(&mut self, v: f64, _t: usize) {
        self.sum.add(v);
        self.count += 1;
    }

    fn leave(&mut self, v: f64, _t: usize) {
        self.sum.add(-v);
        self.count -= 1;
    }

    fn statistic(&self) -> f64 {
        self.sum.value() / self.count as f64
    }
}

/// A running sum with Neumaier's compensation (Kahan–Babuška).
#[derive(Debug, Clone, Copy, Default)]
struct CompensatedSum {
    sum: f64,
    compensation: f64,
}

impl CompensatedSum {
    fn add(&mut self, v: f64) {
        let t = self.sum + v;
        self.compensation += if self.sum.abs() >= v.abs() { (self.sum - t) + v } else { (v - t) + self.sum };
        self.sum = t;
    }

    fn value(self) -> f64 {
        self.sum + self.compensation
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_order_map_is_monotone_and_invertible() {
        let values = [-f64::MAX, -1.5, -0.0, 0.0, 1e-300, 2.0, f64::MAX];
        for w in values.windows(2) {
            assert!(entry(w[0], 0) < entry(w[1], 0) || (w[0] == 0.0 && w[1] == 0.0), "{w:?}");
        }
        for v in values {
            assert_eq!(value(entry(v, 3)).to_bits(), v.to_bits());
        }
    }

    #[test]
    fn a_small_median_by_hand() {
        let u = [3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0];
        let y = median_filter(&u, 8, 1, 3, StartUp::Grow).unwrap();
        assert_eq!(y, vec![3.0, 2.0, 3.0, 1.0, 4.0, 5.0, 5.0, 6.0]);
        assert!(median_filter(&u, 8, 1, 4, StartUp::Valid).is_err());
    }
}
