//! Quantized measurements, Söderström section 9.6: the quantizer (9.101), the exact
//! likelihood of a quantized Gaussian measurement (for particle filters), and the exact
//! moments of a quantized Gaussian or uniform variable by the characteristic-function series
//! (9.115)–(9.131).
//!
//! The quantizer rounds half **up**: x_Q = jΔ when jΔ − Δ/2 ≤ x < jΔ + Δ/2, i.e.
//! Δ ⌊x/Δ + ½⌋ — neither NumPy's `round` (half to even) nor Rust's `f64::round` (half away
//! from zero). Every function here works in units of Δ after moving the mean by a whole
//! number of cells (Q(x + jΔ) = Q(x) + jΔ), so large means keep their precision.

use std::cmp::Ordering;
use std::f64::consts::{FRAC_1_SQRT_2, PI};

use crate::error::{Error, Result};

/// ½ log 2π.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// Δ ⌊x/Δ + ½⌋, Söderström (9.101).
#[inline]
pub fn quantize(x: f64, delta: f64) -> f64 {
    delta * (x / delta + 0.5).floor()
}

/// Quantizes each row of `x` (rows of `delta.len()` components, row-major) into `out`,
/// component i with step `delta[i]` (> 0); NaN stays NaN.
pub fn quantize_into(x: &[f64], delta: &[f64], out: &mut [f64]) -> Result<()> {
    check_steps("delta", delta)?;
    let m = delta.len();
    if m == 0 || !x.len().is_multiple_of(m) || out.len() != x.len() {
        return Err(Error::arg("x", format!("expected rows of {m} values (one per delta), got {} values", x.len())));
    }
    for (t, (row, out_row)) in x.chunks_exact(m).zip(out.chunks_exact_mut(m)).enumerate() {
        for (i, ((&v, &d), o)) in row.iter().zip(delta).zip(out_row.iter_mut()).enumerate() {
            *o = quantize(v, d);
            if v.is_finite() && !o.is_finite() {
                return Err(Error::arg_at(
                    "x",
                    t,
                    format!("component {i}: delta is too small for x = {v} (x / delta overflows)"),
                ));
            }
        }
    }
    Ok(())
}

/// Every step Δ finite and positive.
fn check_steps(arg: &'static str, delta: &[f64]) -> Result<()> {
    match delta.iter().enumerate().find(|(_, d)| !(d.is_finite() && **d > 0.0)) {
        Some((i, d)) => {
            Err(Error::arg(arg, format!("component {i} is {d}: a quantization step must be finite and > 0")))
        }
        None => Ok(()),
    }
}

/// log Φ(x), Φ the standard normal distribution function, accurate in both tails: through
/// erfc down to x = −20 and the asymptotic series of Mills' ratio below (where erfc
/// underflows near x = −38).
pub fn log_normal_cdf(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x > 5.0 {
        return (-0.5 * libm::erfc(x * FRAC_1_SQRT_2)).ln_1p();
    }
    if x >= -20.0 {
        return (0.5 * libm::erfc(-x * FRAC_1_SQRT_2)).ln();
    }
    if x == f64::NEG_INFINITY {
        return f64::NEG_INFINITY;
    }
    // Φ(x) = φ(x)/|x| · (1 − 1/x² + 3/x⁴ − 15/x⁶ + …); at |x| ≥ 20 ten terms leave < 1e-17.
    let inv_x2 = 1.0 / (x * x);
    let (mut term, mut series) = (1.0, 1.0);
    for k in 1..=10 {
        term *= -((2 * k - 1) as f64) * inv_x2;
        series += term;
    }
    -0.5 * x * x - (-x).ln() - HALF_LN_2PI + series.ln()
}

/// log P(a ≤ Z < b) for Z ~ N(0, 1), without cancellation: a narrow interval by the midpoint
/// rule with its curvature terms, one that holds 0 by a sum of erf values, one in a tail by
/// log Φ̄(a) + log(1 − Φ̄(b)/Φ̄(a)). −∞ when the interval is empty.
pub fn log_normal_interval(a: f64, b: f64) -> f64 {
    if a.partial_cmp(&b) != Some(Ordering::Less) {
        return f64::NEG_INFINITY;
    }
    let (w, c) = (b - a, 0.5 * (a + b));
    if w.is_finite() && w * (1.0 + c.abs()) < 1e-3 {
        // ∫ φ(c + s) ds over |s| ≤ w/2 = φ(c) w [1 + (c² − 1) w²/24 + (c⁴ − 6c² + 3) w⁴/1920 + …]
        let c2 = c * c;
        let curvature = (c2 - 1.0) * w * w / 24.0 + (c2 * c2 - 6.0 * c2 + 3.0) * w.powi(4) / 1920.0;
        return -0.5 * c2 - HALF_LN_2PI + w.ln() + curvature.ln_1p();
    }
    if a < 0.0 && b > 0.0 {
        return (0.5 * (libm::erf(b * FRAC_1_SQRT_2) + libm::erf(-a * FRAC_1_SQRT_2))).ln();
    }
    // One tail: mirror the lower tail onto the upper, 0 ≤ a < b.
    let (a, b) = if b <= 0.0 { (-b, -a) } else { (a, b) };
    let (upper_a, upper_b) = (log_normal_cdf(-a), log_normal_cdf(-b));
    if upper_a == f64::NEG_INFINITY {
        return upper_a; // beyond even the asymptotic series (|a| > 1e154)
    }
    upper_a + (-(upper_b - upper_a).exp()).ln_1p()
}

/// A quantizing sensor: y = Q_Δ(h(x) + v) per component, v ~ N(0, R) with R diagonal, and
/// optionally saturating at its lowest and highest levels (a measurement at the lowest level
/// stands for everything below that level's cell, one at the highest for everything above).
#[derive(Debug, Clone, PartialEq)]
pub struct QuantizedSensor {
    delta: Vec<f64>,
    bounds: Option<(Vec<f64>, Vec<f64>)>,
}

impl QuantizedSensor {
    /// The steps Δ_i (> 0) of the m components and, for a saturating quantizer, its
    /// (lowest, highest) levels.
    pub fn new(delta: Vec<f64>, bounds: Option<(Vec<f64>, Vec<f64>)>) -> Result<Self> {
        check_steps("delta", &delta)?;
        if let Some((low, high)) = &bounds {
            let m = delta.len();
            if low.len() != m || high.len() != m {
                return Err(Error::arg("bounds", format!("expected (low, high) of {m} values each (one per delta)")));
            }
            if let Some(i) = (0..m).find(|&i| low[i].partial_cmp(&high[i]) != Some(Ordering::Less)) {
                return Err(Error::arg(
                    "bounds",
                    format!("component {i}: low = {} is not below high = {}", low[i], high[i]),
                ));
            }
        }
        Ok(QuantizedSensor { delta, bounds })
    }

    /// The number of components m.
    pub fn n_obs(&self) -> usize {
        self.delta.len()
    }

    /// The cell [lo, hi) of y's component i (open at a saturating end); `y` must be one of
    /// the levels (a multiple of Δ_i).
    pub(crate) fn cell(&self, i: usize, y: f64) -> Result<(f64, f64)> {
        let d = self.delta[i];
        let level = (y / d).round();
        if !y.is_finite() || (y / d - level).abs() > 1e-9 * level.abs().max(1.0) {
            return Err(Error::arg("y", format!("component {i} is {y}, not a quantization level (a multiple of {d})")));
        }
        let (mut lo, mut hi) = ((level - 0.5) * d, (level + 0.5) * d);
        if let Some((low, high)) = &self.bounds {
            if y < low[i] - 0.5 * d || y > high[i] + 0.5 * d {
                return Err(Error::arg(
                    "y",
                    format!("component {i} is {y}, outside the quantizer's range [{}, {}]", low[i], high[i]),
                ));
            }
            if y <= low[i] {
                lo = f64::NEG_INFINITY;
            }
            if y >= high[i] {
                hi = f64::INFINITY;
            }
        }
        Ok((lo, hi))
    }
}

/// log P(lo ≤ pred + v < hi), v ~ N(0, std²); with std = 0 the indicator of the cell.
#[inline]
pub(crate) fn log_cell_probability(lo: f64, hi: f64, pred: f64, std: f64) -> f64 {
    if std == 0.0 {
        return if lo <= pred && pred < hi { 0.0 } else { f64::NEG_INFINITY };
    }
    log_normal_interval((lo - pred) / std, (hi - pred) / std)
}

/// The log-likelihood of quantized measurements for each of M predictions: row r of `out`
/// is Σ_i log P(Q_Δi(ŷ_ri + v_i) = y_i) with v_i ~ N(0, std_i²) independent, i.e. the
/// probability that ŷ_ri + v_i falls in the cell [y_i − Δ_i/2, y_i + Δ_i/2) of y_i. `y` (m
/// values, each a level of `sensor`; NaN: missing, skipped), `y_hat` (M × m, row-major),
/// `std` (m, ≥ 0; 0 makes the likelihood the cell's indicator).
pub fn quantized_loglik(
    sensor: &QuantizedSensor,
    y: &[f64],
    y_hat: &[f64],
    std: &[f64],
    out: &mut [f64],
) -> Result<()> {
    let m = sensor.n_obs();
    for (name, len) in [("y", y.len()), ("std", std.len())] {
        if len != m {
            return Err(Error::arg(name, format!("expected {m} values (one per delta), got {len}")));
        }
    }
    if let Some((i, s)) = std.iter().enumerate().find(|(_, s)| !(s.is_finite() && **s >= 0.0)) {
        return Err(Error::arg("R", format!("component {i}: the standard deviation is {s}, not finite and >= 0")));
    }
    if y_hat.len() != out.len() * m {
        return Err(Error::arg(
            "y_hat",
            format!("expected {} rows of {m} values, got {} values", out.len(), y_hat.len()),
        ));
    }
    let mut cells = Vec::with_capacity(m);
    for (i, &v) in y.iter().enumerate() {
        cells.push(if v.is_nan() { None } else { Some(sensor.cell(i, v)?) });
    }
    out.fill(0.0);
    for (r, (row, l)) in y_hat.chunks_exact(m).zip(out.iter_mut()).enumerate() {
        for (i, (&pred, cell)) in row.iter().zip(&cells).enumerate() {
            let Some((lo, hi)) = *cell else { continue };
            if pred.is_nan() {
                return Err(Error::arg("y_hat", format!("row {r}, component {i} is NaN")));
            }
            *l += log_cell_probability(lo, hi, pred, std[i]);
        }
    }
    Ok(())
}

/// The distribution of the variable that is quantized.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Distribution {
    /// N(mean, std²).
    Gaussian,
    /// Uniform on mean ± √3 std.
    Uniform,
}

/// The exact moments of x_Q = Q_Δ(x).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantizedMoments {
    /// E x_Q.
    pub mean: f64,
    /// E x_Q².
    pub second_moment: f64,
    /// var x_Q = E x_Q² − (E x_Q)².
    pub var: f64,
}

/// The exact moments of the quantized variable Q_Δ(x), x Gaussian or uniform with the given
/// mean and standard deviation, by the characteristic-function series of Söderström
/// (9.121)–(9.131) with its sum over **all** k ≠ 0 (the book prints k > 0), paired into
/// k ≥ 1 for real x (z = x/Δ, ω_k = 2πk):
///
/// ```text
/// E z_Q  = E z + Σ_{k≥1} (−1)^k Im φ(ω_k) / (πk)
/// E z_Q² = E z² + 1/12 − 2 Σ_{k≥1} (−1)^k [ −Re φ(ω_k) / (2π²k²) + Re φ'(ω_k) / (πk) ]
/// ```
///
/// Gaussian: the terms fall as exp(−2π²k²σ²/Δ²) and are summed until negligible; below
/// σ = 1.5e-5 Δ (over 10⁵ terms) the moments are summed over the few cells instead. Uniform:
/// the terms fall only as 1/k², so the series is summed in closed form — the sums
/// Σ cos(2πkx)/k² = π² B₂(x) and Σ sin(2πkx)/k³ = (2π³/3) B₃(x) (Bernoulli polynomials,
/// 0 ≤ x ≤ 1) — except below a half-width of 10⁻³ Δ, summed over cells.
pub fn quantized_moments(delta: f64, mean: f64, std: f64, dist: Distribution) -> Result<QuantizedMoments> {
    check_steps("delta", &[delta])?;
    if !(delta * delta).is_finite() {
        return Err(Error::arg("delta", format!("{delta} is too large (delta² overflows)")));
    }
    if !mean.is_finite() || !(mean / delta).is_finite() {
        return Err(Error::arg("mean", format!("{mean} is not finite (in units of delta = {delta})")));
    }
    if !(std.is_finite() && std >= 0.0 && (std / delta).is_finite()) {
        return Err(Error::arg("std", format!("{std} is not finite and >= 0 (in units of delta = {delta})")));
    }
    let shift = (mean / delta + 0.5).floor();
    let (m, s) = (mean / delta - shift, std / delta);
    let (unit_mean, unit_second) = if s == 0.0 {
        let level = (m + 0.5).floor();
        (level, level * level)
    } else {
        match dist {
            Distribution::Gaussian if s >= 1.5e-5 => gaussian_series(m, s),
            Distribution::Uniform if s * 3f64.sqrt() >= 1e-3 => uniform_closed_form(m, s * 3f64.sqrt()),
            _ => over_cells(m, s, dist),
        }
    };
    let var = (unit_second - unit_mean * unit_mean).max(0.0) * delta * delta;
    let mean = (shift + unit_mean) * delta;
    if !var.is_finite() {
        return Err(Error::arg("std", format!("the variance overflows (std = {std}; delta is {delta})")));
    }
    let second_moment = var + mean * mean;
    if !second_moment.is_finite() {
        return Err(Error::arg("mean", format!("the second moment overflows (mean = {mean})")));
    }
    Ok(QuantizedMoments { mean, second_moment, var })
}

/// (E z_Q, E z_Q²) of z ~ N(m, s²), |m| ≤ ½, by the series.
fn gaussian_series(m: f64, s: f64) -> (f64, f64) {
    let (mut mean, mut correction) = (m, 0.0);
    for k in 1.. {
        let kf = k as f64;
        let omega = 2.0 * PI * kf;
        let decay = (-0.5 * s * s * omega * omega).exp();
        if decay * kf < 1e-20 {
            break;
        }
        let sign = if k % 2 == 1 { -1.0 } else { 1.0 };
        let (sin, cos) = (2.0 * PI * (kf * m).rem_euclid(1.0)).sin_cos();
        // φ(ω) = e^{iωm − s²ω²/2}, φ'(ω) = (i m − s² ω) φ(ω)
        let (re_phi, im_phi) = (cos * decay, sin * decay);
        let re_dphi = (-m * sin - s * s * omega * cos) * decay;
        mean += sign * im_phi / (PI * kf);
        correction += sign * (-re_phi / (2.0 * PI * PI * kf * kf) + re_dphi / (PI * kf));
    }
    (mean, m * m + s * s + 1.0 / 12.0 - 2.0 * correction)
}

/// (E z_Q, E z_Q²) of z uniform on m ± u (u > 0), the series in closed form: with
/// c_k = (−1)^k, the paired terms are products of sines and cosines of 2πk(m ± u) over k²
/// and k³, and c_k shifts their argument by ½.
fn uniform_closed_form(m: f64, u: f64) -> (f64, f64) {
    let b2 = |x: f64| {
        let x = x.rem_euclid(1.0);
        x * x - x + 1.0 / 6.0
    };
    let b3 = |x: f64| {
        let x = x.rem_euclid(1.0);
        x * (x - 0.5) * (x - 1.0)
    };
    let (below, above) = (b2(m - u + 0.5), b2(m + u + 0.5));
    let mean = m + (below - above) / (4.0 * u);
    // −Re φ/(2π²k²) and the sin(uω)/(uω²) part of Re φ' (1/k³); the m sin(ωm) and the
    // cos(uω)/ω parts of Re φ' (1/k²).
    let cubic = -(b3(u + m + 0.5) + b3(u - m + 0.5)) / (6.0 * u);
    let sine_part = -m * (below - above) / (4.0 * u);
    let cosine_part = (below + above) / 4.0;
    let second = m * m + u * u / 3.0 + 1.0 / 12.0 - 2.0 * (cubic + sine_part + cosine_part);
    (mean, second)
}

/// (E z_Q, E z_Q²) summed over the cells [j − ½, j + ½) that hold the mass.
fn over_cells(m: f64, s: f64, dist: Distribution) -> (f64, f64) {
    let reach = match dist {
        Distribution::Gaussian => 40.0 * s,
        Distribution::Uniform => 3f64.sqrt() * s,
    };
    let (first, last) = ((m - reach).floor() as i64 - 1, (m + reach).ceil() as i64 + 1);
    let (mut mean, mut second) = (0.0, 0.0);
    for j in first..=last {
        let (lo, hi) = (j as f64 - 0.5, j as f64 + 0.5);
        let p = match dist {
            Distribution::Gaussian => log_normal_interval((lo - m) / s, (hi - m) / s).exp(),
            // the overlap measured from m, so that a cell edge at m cancels exactly
            Distribution::Uniform => ((hi - m).min(reach) - (lo - m).max(-reach)).max(0.0) / (2.0 * reach),
        };
        mean += j as f64 * p;
        second += (j * j) as f64 * p;
    }
    (mean, second)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_half_up() {
        assert_eq!(
            [quantize(0.5, 1.0), quantize(-0.5, 1.0), quantize(1.5, 1.0), quantize(-1.5, 1.0)],
            [1.0, 0.0, 2.0, -1.0]
        );
    }

    #[test]
    fn the_normal_cdf_is_continuous_across_its_branches() {
        for x in [5.0, -20.0] {
            let (below, above) = (log_normal_cdf(x - 1e-9), log_normal_cdf(x + 1e-9));
            assert!((above - below).abs() < 1e-8 * (1.0 + below.abs()), "{x}: {below} {above}");
        }
        assert!((log_normal_interval(-1.0, 1.0).exp() - 0.682_689_492_137_085_9).abs() < 1e-15);
    }

    #[test]
    fn a_uniform_cell_wide_variable_centred_on_a_level_quantizes_to_it() {
        let q = quantized_moments(1.0, 0.0, 1.0 / 12f64.sqrt(), Distribution::Uniform).unwrap();
        assert!(q.mean.abs() < 1e-15 && q.var.abs() < 1e-15, "{q:?}");
    }
}
