//! The χ² distribution: tail probability and quantile, for the consistency bounds of NIS and
//! NEES and the p-values of the Ljung–Box and Jarque–Bera tests.
//!
//! χ²(k) is Gamma(k/2, 2), so `P(X ≤ x) = P(k/2, x/2)`, the regularized lower incomplete gamma
//! function. It is evaluated by its power series below `x = a + 1` and by its continued
//! fraction above (Press et al., *Numerical Recipes*, Sec. 6.2), with the prefactor
//! `x^a e^-x / Γ(a)` computed in the scaled form `e^{a (log1p(d) − d)} √(a / 2π) / Γ*(a)`,
//! `d = (x − a)/a`, `Γ*` Stirling's correction, so that it keeps its relative accuracy when `a`
//! is large (the averaged NIS over a long series has `a` ~ 10⁶ degrees of freedom, where
//! `a ln x − ln Γ(a)` loses seven digits to cancellation).

use crate::error::{Error, Result};

/// `P(X > x)` for `X ~ χ²(k)`, `k > 0` (upper tail; 1 for `x ≤ 0`).
pub fn chi_square_sf(x: f64, k: f64) -> f64 {
    regularized_gamma(0.5 * k, 0.5 * x).1
}

/// `P(X ≤ x)` for `X ~ χ²(k)`, `k > 0`.
pub fn chi_square_cdf(x: f64, k: f64) -> f64 {
    regularized_gamma(0.5 * k, 0.5 * x).0
}

/// The `p`-quantile of χ²(k): the x with `P(X ≤ x) = p`, for `0 < p < 1` and `k > 0`.
///
/// Newton's method on the lower or upper tail, whichever is smaller (so that both ends keep
/// their relative accuracy), from the Wilson–Hilferty approximation, safeguarded by bisection.
pub fn chi_square_quantile(p: f64, k: f64) -> Result<f64> {
    if !(p > 0.0 && p < 1.0) {
        return Err(Error::arg("p", format!("must be in (0, 1), got {p}")));
    }
    if !(k > 0.0 && k.is_finite()) {
        return Err(Error::arg("k", format!("degrees of freedom must be positive and finite, got {k}")));
    }
    let a = 0.5 * k;
    let upper_tail = p > 0.5;
    let target = if upper_tail { 1.0 - p } else { p };
    // g(x) = tail(x) − target, decreasing in x for the upper tail, increasing for the lower.
    let tail = |x: f64| {
        let (lower, upper) = regularized_gamma(a, 0.5 * x);
        if upper_tail {
            upper
        } else {
            lower
        }
    };
    let (mut lo, mut hi) = (0.0_f64, wilson_hilferty(p, k).max(f64::MIN_POSITIVE));
    // Grow the bracket until it holds the root.
    while (tail(hi) > target) == upper_tail && hi < f64::MAX / 4.0 {
        lo = hi;
        hi *= 2.0;
    }
    let mut x = 0.5 * (lo + hi);
    if let Some(start) = Some(wilson_hilferty(p, k)).filter(|&s| s > lo && s < hi) {
        x = start;
    }
    for _ in 0..200 {
        let g = tail(x) - target;
        if g == 0.0 {
            return Ok(x);
        }
        // Keep [lo, hi] around the root: tail(x) − target changes sign there.
        if (g > 0.0) == upper_tail {
            lo = x;
        } else {
            hi = x;
        }
        let density = chi_square_density(x, k);
        let step = if upper_tail { g / density } else { -g / density };
        let mut next = x + step;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - x).abs() <= 4.0 * f64::EPSILON * x || hi - lo <= 4.0 * f64::EPSILON * hi {
            return Ok(next);
        }
        x = next;
    }
    Ok(x)
}

/// The density of χ²(k) at x > 0.
fn chi_square_density(x: f64, k: f64) -> f64 {
    let a = 0.5 * k;
    // Γ(a, 1)'s density at x/2, halved: (x/2)^(a-1) e^(-x/2) / (2 Γ(a)).
    0.5 * gamma_prefactor(a, 0.5 * x) / (0.5 * x)
}

/// The Wilson–Hilferty approximation of the χ²(k) quantile (cube root of a scaled χ² nearly
/// normal), the start of the Newton iteration.
fn wilson_hilferty(p: f64, k: f64) -> f64 {
    let z = normal_quantile(p);
    let c = 2.0 / (9.0 * k);
    let w = 1.0 - c + z * c.sqrt();
    if w > 0.0 {
        k * w * w * w
    } else {
        // Small k, lower tail: P(X ≤ x) ≈ (x/2)^a / Γ(a + 1).
        let a = 0.5 * k;
        2.0 * (p * libm::tgamma(a + 1.0)).powf(1.0 / a)
    }
}

/// The standard normal quantile (Acklam's rational approximation, relative error < 1.2e-9):
/// only a starting point.
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] =
        [-5.447609879822406e1, 1.615858368580409e2, -1.556989798598866e2, 6.680131188771972e1, -1.328068155288572e1];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    let tail = |q: f64| {
        let r = (-2.0 * q.ln()).sqrt();
        (((((C[0] * r + C[1]) * r + C[2]) * r + C[3]) * r + C[4]) * r + C[5])
            / ((((D[0] * r + D[1]) * r + D[2]) * r + D[3]) * r + 1.0)
    };
    if p < 0.02425 {
        tail(p)
    } else if p > 1.0 - 0.02425 {
        -tail(1.0 - p)
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// `(P(a, x), Q(a, x))`, the regularized lower and upper incomplete gamma functions.
fn regularized_gamma(a: f64, x: f64) -> (f64, f64) {
    if x.is_nan() || a.is_nan() {
        return (f64::NAN, f64::NAN);
    }
    if x <= 0.0 {
        return (0.0, 1.0);
    }
    if x == f64::INFINITY {
        return (1.0, 0.0);
    }
    if x < a + 1.0 {
        let lower = gamma_series(a, x);
        (lower, 1.0 - lower)
    } else {
        let upper = gamma_continued_fraction(a, x);
        (1.0 - upper, upper)
    }
}

/// `x^a e^-x / Γ(a)` without the cancellation of `a ln x − x − ln Γ(a)` at large a.
fn gamma_prefactor(a: f64, x: f64) -> f64 {
    let d = (x - a) / a;
    // a ln(x/a) − (x − a) = a (log1p(d) − d); log1p(d) − d by its series when small, where the
    // difference would cancel.
    let log1p_minus = if d.abs() < 0.1 {
        let mut sum = 0.0;
        let mut power = d * d;
        for j in 2..40 {
            let term = power / j as f64;
            sum += if j % 2 == 0 { -term } else { term };
            power *= d;
            if term.abs() < 1e-18 * sum.abs() {
                break;
            }
        }
        sum
    } else {
        // (x/a rather than 1 + d: d rounds to −1 when x ≪ a.)
        (x / a).ln() - d
    };
    (a * log1p_minus - ln_stirling_correction(a)).exp() * (a / (2.0 * std::f64::consts::PI)).sqrt()
}

/// `ln Γ*(a)` with `Γ(a) = √(2π) a^(a − 1/2) e^(−a) Γ*(a)`: Stirling's series from a = 10
/// (error below 1e-16 there), ln Γ directly below.
fn ln_stirling_correction(a: f64) -> f64 {
    if a >= 10.0 {
        let r = 1.0 / (a * a);
        (1.0 / 12.0 - r * (1.0 / 360.0 - r * (1.0 / 1260.0 - r * (1.0 / 1680.0 - r / 1188.0)))) / a
    } else {
        libm::lgamma(a) - 0.5 * (2.0 * std::f64::consts::PI).ln() - (a - 0.5) * a.ln() + a
    }
}

/// P(a, x) = x^a e^-x / Γ(a + 1) Σ_n x^n / ((a + 1) ⋯ (a + n)), for x < a + 1.
fn gamma_series(a: f64, x: f64) -> f64 {
    let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
    for _ in 0..100_000 {
        ap += 1.0;
        term *= x / ap;
        sum += term;
        if term < sum * 1e-17 {
            break;
        }
    }
    (sum * gamma_prefactor(a, x)).min(1.0)
}

/// Q(a, x) by its continued fraction (modified Lentz), for x ≥ a + 1.
fn gamma_continued_fraction(a: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..100_000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (h * gamma_prefactor(a, x)).min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tails_of_small_integer_degrees_of_freedom_have_closed_forms() {
        // k = 2: P(X > x) = e^(-x/2).
        for x in [0.01_f64, 0.5, 2.0, 10.0, 100.0] {
            let exact = (-0.5 * x).exp();
            assert!((chi_square_sf(x, 2.0) - exact).abs() <= 1e-14 * exact, "x = {x}");
        }
        // k = 1: P(X > x) = erfc(√(x/2)).
        for x in [0.01_f64, 0.5, 2.0, 10.0, 50.0] {
            let exact = libm::erfc((0.5 * x).sqrt());
            assert!((chi_square_sf(x, 1.0) - exact).abs() <= 1e-13 * exact, "x = {x}");
        }
    }

    #[test]
    fn the_quantile_inverts_the_distribution_function() {
        for k in [0.5, 1.0, 2.0, 3.0, 7.0, 40.0, 1e3, 1e6] {
            for p in [1e-12, 1e-4, 0.025, 0.5, 0.975, 1.0 - 1e-9] {
                let x = chi_square_quantile(p, k).unwrap();
                let tail = p.min(1.0 - p);
                let got = if p > 0.5 { chi_square_sf(x, k) } else { chi_square_cdf(x, k) };
                assert!((got - tail).abs() <= 1e-10 * tail, "k = {k}, p = {p}: x = {x}, tail {got}");
            }
        }
    }

    #[test]
    fn probabilities_outside_zero_one_are_refused() {
        assert!(chi_square_quantile(0.0, 2.0).is_err());
        assert!(chi_square_quantile(f64::NAN, 2.0).is_err());
        assert!(chi_square_quantile(0.5, 0.0).is_err());
    }
}
