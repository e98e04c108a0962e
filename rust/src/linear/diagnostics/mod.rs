//! Diagnostics of a filter run: is the model consistent with the data?
//!
//! Under the true model the innovations e(t) are zero-mean and white with covariance S(t)
//! (Söderström ex. 6.16), and in simulation the estimation error x − x̂(t|t) has covariance
//! P(t|t). The tests here check exactly that:
//!
//! - standardized innovations `L(t)⁻¹ e(t)`, `S(t) = L L'` (Cholesky of the observed
//!   components' block, as statsmodels' `standardized_forecasts_error`): N(0, I) and white;
//! - NIS `e' S⁻¹ e ~ χ²(m_t)` per step and its average over the run, with two-sided χ²
//!   consistency bounds (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to
//!   Tracking and Navigation*, Sec. 5.4), and NEES `(x − x̂)' P⁻¹ (x − x̂) ~ χ²(n)` given the true
//!   states;
//! - each component's sample autocorrelation with the white-noise bound `±z_{1−α/2}/√N` and
//!   the Ljung–Box statistic `Q(h) = N (N + 2) Σ_{k≤h} r_k² / (N − k) ~ χ²(h)` (as statsmodels'
//!   `acorr_ljungbox`);
//! - the Jarque–Bera normality test `JB = N/6 (skew² + (kurtosis − 3)²/4) ~ χ²(2)`.
//!
//! Missing innovations (NaN) are left out: a step's NIS uses its observed components (m_t of
//! them), and the autocorrelation sums only the pairs observed at both ends, divided by the
//! number N of observed steps (statsmodels' `acf(..., missing="conservative")`).

mod chi_square;

pub use chi_square::{chi_square_cdf, chi_square_quantile, chi_square_sf};

use crate::error::{Error, Result};
use crate::nonlinear::cholesky;

/// What the diagnostics test, and over which steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiagnosticOptions {
    /// Largest autocorrelation lag (and the Ljung–Box statistics for 1..=lags).
    pub lags: usize,
    /// Steps at the start left out of the tests over the run (the averaged NIS and NEES, the
    /// autocorrelation, Ljung–Box, Jarque–Bera), e.g. while a vague prior is forgotten. The
    /// per-step values cover every step.
    pub burn: usize,
    /// Significance level of the two-sided bounds (the bounds hold 1 − alpha).
    pub alpha: f64,
}

impl Default for DiagnosticOptions {
    fn default() -> Self {
        DiagnosticOptions { lags: 10, burn: 0, alpha: 0.05 }
    }
}

/// The tests of the innovations of a run of T steps with m outputs (row-major arrays).
#[derive(Clone, Debug, PartialEq)]
pub struct InnovationDiagnostics {
    /// `L(t)⁻¹ e(t)` over the observed components, `(T, m)`; NaN where y is missing.
    pub standardized: Vec<f64>,
    /// `e' S⁻¹ e` over the observed components, `(T,)`; NaN where nothing is observed.
    pub nis: Vec<f64>,
    /// The number m_t of observed components (the χ² degrees of freedom of the NIS), `(T,)`.
    pub observed: Vec<usize>,
    /// The two-sided `1 − alpha` bounds of χ²(m_t), `(T, 2)`; NaN where nothing is observed.
    pub nis_bounds: Vec<f64>,
    /// The average NIS over the observed steps after `burn`.
    pub nis_mean: f64,
    /// Its bounds: the χ²(Σ m_t) quantiles divided by the number of steps averaged.
    pub nis_mean_bounds: [f64; 2],
    /// Sample autocorrelations r_0..r_lags of each standardized component, `(lags + 1, m)`.
    pub acf: Vec<f64>,
    /// The white-noise bound `z_{1−alpha/2} / √N` of each component's autocorrelation, `(m,)`.
    pub acf_bound: Vec<f64>,
    /// Ljung–Box `Q(h)` for h = 1..=lags, `(lags, m)`.
    pub ljung_box: Vec<f64>,
    /// Its p-values `P(χ²(h) > Q(h))`, `(lags, m)`.
    pub ljung_box_pvalue: Vec<f64>,
    /// Jarque–Bera statistic of each standardized component, `(m,)`.
    pub jarque_bera: Vec<f64>,
    /// Its p-value `P(χ²(2) > JB) = e^(−JB/2)`, `(m,)`.
    pub jarque_bera_pvalue: Vec<f64>,
    /// Sample skewness (biased moments, as scipy's `skew`), `(m,)`.
    pub skew: Vec<f64>,
    /// Sample kurtosis, 3 for a normal sample (biased moments), `(m,)`.
    pub kurtosis: Vec<f64>,
}

/// The normalized estimation error squared of a simulation with known states.
#[derive(Clone, Debug, PartialEq)]
pub struct StateDiagnostics {
    /// `(x − x̂)' P⁻¹ (x − x̂)` per step, `(T,)`.
    pub nees: Vec<f64>,
    /// The two-sided `1 − alpha` bounds of χ²(n).
    pub nees_bounds: [f64; 2],
    /// The average NEES over the steps after `burn`.
    pub nees_mean: f64,
    /// Its bounds: the χ²((T − burn) n) quantiles divided by T − burn.
    pub nees_mean_bounds: [f64; 2],
}

/// Tests the innovations `innov (T, m)` (NaN where missing) with their covariances
/// `s (T, m, m)` of a filter run.
///
/// Errors name the argument and the step: an observed block of S that is not positive
/// definite, an innovation that is infinite, too few observed steps of a component for the
/// lags asked for.
pub fn innovation_diagnostics(
    innov: &[f64],
    s: &[f64],
    steps: usize,
    m: usize,
    options: DiagnosticOptions,
) -> Result<InnovationDiagnostics> {
    check_options(options, steps)?;
    check_len("innov", innov, steps * m)?;
    check_len("S", s, steps * m * m)?;
    let (standardized, nis, observed) = standardize(innov, s, steps, m)?;
    let mut nis_bounds = vec![f64::NAN; 2 * steps];
    for (t, &mt) in observed.iter().enumerate() {
        if mt > 0 {
            nis_bounds[2 * t..2 * t + 2].copy_from_slice(&bounds(mt as f64, options.alpha)?);
        }
    }
    let averaged: Vec<(f64, usize)> =
        (options.burn..steps).filter(|&t| observed[t] > 0).map(|t| (nis[t], observed[t])).collect();
    if averaged.is_empty() {
        return Err(Error::arg("innov", format!("nothing is observed after burn = {}", options.burn)));
    }
    let count = averaged.len() as f64;
    let dof: usize = averaged.iter().map(|&(_, mt)| mt).sum();
    let nis_mean = averaged.iter().map(|&(v, _)| v).sum::<f64>() / count;
    let [lo, hi] = bounds(dof as f64, options.alpha)?;
    let z = chi_square_quantile(1.0 - options.alpha, 1.0)?.sqrt();

    let lags = options.lags;
    let mut out = InnovationDiagnostics {
        standardized,
        nis,
        observed,
        nis_bounds,
        nis_mean,
        nis_mean_bounds: [lo / count, hi / count],
        acf: vec![0.0; (lags + 1) * m],
        acf_bound: vec![0.0; m],
        ljung_box: vec![0.0; lags * m],
        ljung_box_pvalue: vec![0.0; lags * m],
        jarque_bera: vec![0.0; m],
        jarque_bera_pvalue: vec![0.0; m],
        skew: vec![0.0; m],
        kurtosis: vec![0.0; m],
    };
    for i in 0..m {
        let series: Vec<f64> = (options.burn..steps).map(|t| out.standardized[t * m + i]).collect();
        let component = Component::new(&series, i)?;
        let acf = component.autocorrelation(lags)?;
        let nobs = component.nobs as f64;
        out.acf_bound[i] = z / nobs.sqrt();
        let mut q = 0.0;
        for (k, &r) in acf.iter().enumerate() {
            out.acf[k * m + i] = r;
            if k > 0 {
                q += r * r / (nobs - k as f64);
                out.ljung_box[(k - 1) * m + i] = nobs * (nobs + 2.0) * q;
                out.ljung_box_pvalue[(k - 1) * m + i] = chi_square_sf(nobs * (nobs + 2.0) * q, k as f64);
            }
        }
        let (skew, kurtosis) = component.skew_kurtosis();
        let jb = nobs / 6.0 * (skew * skew + 0.25 * (kurtosis - 3.0) * (kurtosis - 3.0));
        out.skew[i] = skew;
        out.kurtosis[i] = kurtosis;
        out.jarque_bera[i] = jb;
        out.jarque_bera_pvalue[i] = (-0.5 * jb).exp();
    }
    Ok(out)
}

/// NEES of the estimates `x_est (T, n)` with covariances `p (T, n, n)` against the true states
/// `x_true (T, n)` of a simulation.
pub fn state_diagnostics(
    x_true: &[f64],
    x_est: &[f64],
    p: &[f64],
    steps: usize,
    n: usize,
    options: DiagnosticOptions,
) -> Result<StateDiagnostics> {
    check_options(options, steps)?;
    check_len("x_true", x_true, steps * n)?;
    check_len("x_filt", x_est, steps * n)?;
    check_len("P_filt", p, steps * n * n)?;
    let mut factor = vec![0.0; n * n];
    let mut error = vec![0.0; n];
    let mut nees = vec![0.0; steps];
    for t in 0..steps {
        for j in 0..n {
            let truth = x_true[t * n + j];
            if !truth.is_finite() {
                return Err(Error::arg_at(
                    "x_true",
                    t,
                    format!("component {j} is {truth}: the true states must be finite"),
                ));
            }
            error[j] = truth - x_est[t * n + j];
        }
        cholesky(&mut factor, &p[t * n * n..][..n * n], n).map_err(|j| {
            Error::arg_at("P_filt", t, format!("not positive definite (pivot {j}), so NEES is not defined"))
        })?;
        nees[t] = forward_solve_norm(&factor, &mut error, n);
        if !nees[t].is_finite() {
            return Err(Error::arg_at("x_filt", t, "the estimate is not finite"));
        }
    }
    let count = (steps - options.burn) as f64;
    let nees_mean = nees[options.burn..].iter().sum::<f64>() / count;
    let [lo, hi] = bounds(count * n as f64, options.alpha)?;
    Ok(StateDiagnostics {
        nees,
        nees_bounds: bounds(n as f64, options.alpha)?,
        nees_mean,
        nees_mean_bounds: [lo / count, hi / count],
    })
}

fn check_options(options: DiagnosticOptions, steps: usize) -> Result<()> {
    if !(options.alpha > 0.0 && options.alpha < 1.0) {
        return Err(Error::arg("alpha", format!("must be in (0, 1), got {}", options.alpha)));
    }
    if options.lags == 0 {
        return Err(Error::arg("lags", "must be at least 1"));
    }
    if options.burn >= steps {
        return Err(Error::arg("burn", format!("{} leaves none of the {steps} steps", options.burn)));
    }
    Ok(())
}

fn check_len(arg: &'static str, values: &[f64], expected: usize) -> Result<()> {
    if values.len() != expected {
        return Err(Error::arg(arg, format!("expected {expected} values, got {}", values.len())));
    }
    Ok(())
}

/// The two-sided `1 − alpha` interval of χ²(k).
fn bounds(k: f64, alpha: f64) -> Result<[f64; 2]> {
    Ok([chi_square_quantile(0.5 * alpha, k)?, chi_square_quantile(1.0 - 0.5 * alpha, k)?])
}

/// Per step: `L⁻¹ e` over the observed components, `e' S⁻¹ e` and their number.
fn standardize(innov: &[f64], s: &[f64], steps: usize, m: usize) -> Result<(Vec<f64>, Vec<f64>, Vec<usize>)> {
    let mut standardized = vec![f64::NAN; steps * m];
    let mut nis = vec![f64::NAN; steps];
    let mut observed = vec![0; steps];
    let (mut index, mut block, mut factor, mut e) = (vec![0; m], vec![0.0; m * m], vec![0.0; m * m], vec![0.0; m]);
    for t in 0..steps {
        let (e_t, s_t) = (&innov[t * m..][..m], &s[t * m * m..][..m * m]);
        let mut mo = 0;
        for (i, &v) in e_t.iter().enumerate() {
            if v.is_infinite() {
                return Err(Error::arg_at("innov", t, format!("component {i} is {v}")));
            }
            if !v.is_nan() {
                index[mo] = i;
                e[mo] = v;
                mo += 1;
            }
        }
        observed[t] = mo;
        if mo == 0 {
            continue;
        }
        for (a, &i) in index[..mo].iter().enumerate() {
            for (b, &j) in index[..mo].iter().enumerate() {
                block[a * mo + b] = s_t[i * m + j];
            }
        }
        cholesky(&mut factor, &block, mo).map_err(|j| {
            Error::arg_at("S", t, format!("the block of the observed components is not positive definite (pivot {j})"))
        })?;
        nis[t] = forward_solve_norm(&factor, &mut e, mo);
        for (a, &i) in index[..mo].iter().enumerate() {
            standardized[t * m + i] = e[a];
        }
    }
    Ok((standardized, nis, observed))
}

/// Replaces `b[..n]` by `L⁻¹ b` (L lower triangular `n×n`) and returns `‖L⁻¹ b‖²`.
fn forward_solve_norm(l: &[f64], b: &mut [f64], n: usize) -> f64 {
    let mut norm = 0.0;
    for i in 0..n {
        let mut v = b[i];
        for k in 0..i {
            v -= l[i * n + k] * b[k];
        }
        b[i] = v / l[i * n + i];
        norm += b[i] * b[i];
    }
    norm
}

/// One standardized component after `burn`, NaN where missing, demeaned over the observed.
struct Component {
    /// Deviations from the observed mean, 0 where missing.
    centred: Vec<f64>,
    nobs: usize,
}

impl Component {
    fn new(series: &[f64], i: usize) -> Result<Self> {
        let nobs = series.iter().filter(|v| !v.is_nan()).count();
        if nobs < 2 {
            return Err(Error::arg(
                "innov",
                format!("component {i} is observed at {nobs} of the steps tested; the tests need 2 or more"),
            ));
        }
        let mean = series.iter().filter(|v| !v.is_nan()).sum::<f64>() / nobs as f64;
        let centred: Vec<f64> = series.iter().map(|&v| if v.is_nan() { 0.0 } else { v - mean }).collect();
        if centred.iter().all(|&v| v == 0.0) {
            return Err(Error::arg("innov", format!("component {i}'s standardized innovations are constant")));
        }
        Ok(Component { centred, nobs })
    }

    /// r_0..r_lags: Σ of the products at lag k over the pairs both observed, over N, divided
    /// by the lag-0 value.
    fn autocorrelation(&self, lags: usize) -> Result<Vec<f64>> {
        if lags >= self.nobs {
            return Err(Error::arg(
                "lags",
                format!("{lags} needs more observed steps than that; a component has {} after burn", self.nobs),
            ));
        }
        let c = &self.centred;
        let lag = |k: usize| c[k..].iter().zip(c).map(|(a, b)| a * b).sum::<f64>();
        let c0 = lag(0);
        Ok((0..=lags).map(|k| lag(k) / c0).collect())
    }

    /// Skewness m3 / m2^(3/2) and kurtosis m4 / m2² of the observed values (biased moments).
    fn skew_kurtosis(&self) -> (f64, f64) {
        let n = self.nobs as f64;
        let moment = |p: i32| self.centred.iter().map(|v| v.powi(p)).sum::<f64>() / n;
        let m2 = moment(2);
        (moment(3) / m2.powf(1.5), moment(4) / (m2 * m2))
    }
}
