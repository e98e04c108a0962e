//! Integration tests of the smoothers through the public API, on seeded random models (some with
//! per-step matrices) with inputs, correlated noise (N) and missing data:
//!
//! - fixed-lag with lag ≥ T − 1 is the RTS smoother at every step (x and P), and lag 0 the filter;
//! - fixed-point: the estimate of x[s] from all the data (its last row) is RTS's x̂(s|T−1), and
//!   its first row is the filter's x̂(s|s);
//! - RTS on a scalar model equals Gaussian conditioning of the joint prior of x[0..T) on the
//!   observed y, in closed form (means, variances and lag-one covariances).

mod common;

use common::{assert_close, mat, matmul, max_abs, random_model, solve, transpose, Rng};
use kfast::{
    filter, smooth, smooth_fixed_lag, smooth_fixed_point, FixedLagOptions, LinearGaussian, Matrices, Result, Series,
    UpdateForm,
};

/// A random model, its data and prior.
struct Case {
    model: LinearGaussian,
    y: Vec<f64>,
    u: Option<Vec<f64>>,
    x0: Vec<f64>,
    p0: Vec<f64>,
    steps: usize,
}

impl Case {
    fn y(&self) -> Result<Series<'_>> {
        Series::new("y", &self.y, self.steps, self.model.n_obs())
    }

    fn u(&self) -> Result<Option<Series<'_>>> {
        self.u.as_deref().map(|u| Series::new("u", u, self.steps, self.model.n_inputs())).transpose()
    }
}

/// n 1–5, m 1–3, T 2–25 (see [`common::random_model`]); B and D (k = 2) on odd seeds, N on
/// seeds ≡ 1, 2 (mod 4), F and Q per step on seeds ≡ 0 (mod 3); about 15 % of the observations
/// missing, and one whole step missing.
fn random_case(seed: u64) -> Result<Case> {
    let mut rng = Rng::new(seed);
    let (n, m, steps) = (rng.int(1, 5), rng.int(1, 3), rng.int(2, 25));
    let k = if seed % 2 == 1 { 2 } else { 0 };
    let per_step = seed.is_multiple_of(3).then_some(steps);
    let model = random_model(&mut rng, n, m, k, matches!(seed % 4, 1 | 2), per_step)?;
    let mut y = rng.normals(steps, m);
    for v in y.iter_mut() {
        if rng.uniform() < 0.15 {
            *v = f64::NAN;
        }
    }
    let gap = rng.int(0, steps - 1);
    y[gap * m..(gap + 1) * m].fill(f64::NAN);
    let u = (k > 0).then(|| rng.normals(steps, k));
    Ok(Case { model, y, u, x0: rng.normals(n, 1), p0: rng.spd(n, 0.5), steps })
}

const SEEDS: u64 = 40;

#[test]
fn fixed_lag_with_lag_at_least_t_minus_1_is_rts() -> Result<()> {
    for seed in 0..SEEDS {
        let c = random_case(seed)?;
        let rts = smooth(&c.model, c.y()?, c.u()?, &c.x0, &c.p0, UpdateForm::Joseph)?;
        let (xs, ps) = (max_abs(&rts.x_smooth), max_abs(&rts.p_smooth));
        for lag in [c.steps - 1, c.steps, c.steps + 7] {
            let what = format!("seed {seed} (n {}, T {}), lag {lag}", c.model.n_states(), c.steps);
            let fl = smooth_fixed_lag(&c.model, c.y()?, c.u()?, &c.x0, &c.p0, FixedLagOptions::new(lag))?;
            assert_eq!(fl.lag, lag, "{what}: lag");
            assert_close(&format!("{what}: x"), &fl.x_smooth, &rts.x_smooth, 1e-9, 1e-10 * xs.max(1.0));
            assert_close(&format!("{what}: P"), &fl.p_smooth, &rts.p_smooth, 1e-9, 1e-10 * ps.max(1.0));
        }
        // Lag 0 is the filter.
        let fl = smooth_fixed_lag(&c.model, c.y()?, c.u()?, &c.x0, &c.p0, FixedLagOptions::new(0))?;
        let what = format!("seed {seed}, lag 0");
        assert_close(&format!("{what}: x"), &fl.x_smooth, &rts.filter.x_filt, 1e-12, 1e-12 * xs.max(1.0));
        assert_close(&format!("{what}: P"), &fl.p_smooth, &rts.filter.p_filt, 1e-12, 1e-12 * ps.max(1.0));
    }
    Ok(())
}

#[test]
fn fixed_point_at_the_end_is_rts_at_the_point() -> Result<()> {
    for seed in 0..SEEDS {
        let c = random_case(100 + seed)?;
        let (n, steps) = (c.model.n_states(), c.steps);
        let rts = smooth(&c.model, c.y()?, c.u()?, &c.x0, &c.p0, UpdateForm::Joseph)?;
        let flt = filter(&c.model, c.y()?, c.u()?, &c.x0, &c.p0, UpdateForm::Joseph)?;
        let (xs, ps) = (max_abs(&rts.x_smooth).max(1.0), max_abs(&rts.p_smooth).max(1.0));
        for s in [0, steps / 2, steps - 1] {
            let what = format!("seed {seed} (n {n}, T {steps}), point {s}");
            let fp = smooth_fixed_point(&c.model, c.y()?, c.u()?, &c.x0, &c.p0, s, UpdateForm::Joseph)?;
            let rows = steps - s;
            assert_eq!((fp.t_point, fp.x.len(), fp.p.len()), (s, rows * n, rows * n * n), "{what}: shapes");
            let (x_last, p_last) = (&fp.x[(rows - 1) * n..], &fp.p[(rows - 1) * n * n..]);
            assert_close(&format!("{what}: x(s|T−1)"), x_last, &rts.x_smooth[s * n..(s + 1) * n], 1e-9, 1e-10 * xs);
            let p_rts = &rts.p_smooth[s * n * n..(s + 1) * n * n];
            assert_close(&format!("{what}: P(s|T−1)"), p_last, p_rts, 1e-9, 1e-10 * ps);
            assert_close(&format!("{what}: x(s|s)"), &fp.x[..n], &flt.x_filt[s * n..(s + 1) * n], 1e-12, 1e-12 * xs);
            let p_filt = &flt.p_filt[s * n * n..(s + 1) * n * n];
            assert_close(&format!("{what}: P(s|s)"), &fp.p[..n * n], p_filt, 1e-12, 1e-12 * ps);
        }
    }
    Ok(())
}

/// The smoothed moments of the scalar model x[t+1] = f x[t] + w, y[t] = h x[t] + v
/// (Var w = q, Var v = r, x[0] ~ N(x0, p0)) by conditioning the joint Gaussian prior of
/// x[0..T) on the observed y[t] (NaN = missing) directly: with the prior mean μ and covariance
/// Σ (μ_t = f^t x0, Σ_tt = v_t, v_{t+1} = f² v_t + q, Σ_st = f^{t−s} v_s for s ≤ t) and O the
/// observed steps, E[x|y] = μ + Σ_{·O} h G⁻¹ (y_O − h μ_O), Cov[x|y] = Σ − h² Σ_{·O} G⁻¹ Σ_{O·}
/// with G = h² Σ_OO + r I. Returns (x_smooth, diag Cov, Cov(x[t], x[t−1])).
fn scalar_conditioning(f: f64, h: f64, q: f64, r: f64, x0: f64, p0: f64, y: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let steps = y.len();
    let mu: Vec<f64> = (0..steps).map(|t| f.powi(t as i32) * x0).collect();
    let mut v = vec![p0; steps];
    for t in 1..steps {
        v[t] = f * f * v[t - 1] + q;
    }
    let sigma = |s: usize, t: usize| if s <= t { f.powi((t - s) as i32) * v[s] } else { f.powi((s - t) as i32) * v[t] };
    let obs: Vec<usize> = (0..steps).filter(|&t| !y[t].is_nan()).collect();
    let k = obs.len();
    let g: Vec<f64> =
        (0..k * k).map(|ij| h * h * sigma(obs[ij / k], obs[ij % k]) + if ij / k == ij % k { r } else { 0.0 }).collect();
    let innov: Vec<f64> = obs.iter().map(|&t| y[t] - h * mu[t]).collect();
    let sigma_xo: Vec<f64> = (0..steps * k).map(|ij| sigma(ij / k, obs[ij % k])).collect();
    let weights = solve(&g, &innov, k, 1);
    let mean_shift = matmul(&sigma_xo, &weights, steps, k, 1);
    let x_smooth: Vec<f64> = (0..steps).map(|t| mu[t] + h * mean_shift[t]).collect();
    // Cov[x|y] = Σ − h² Σ_{·O} G⁻¹ Σ_{O·}.
    let g_inv_sigma_ox = solve(&g, &transpose(&sigma_xo, steps, k), k, steps);
    let reduction = matmul(&sigma_xo, &g_inv_sigma_ox, steps, k, steps);
    let cov = |s: usize, t: usize| sigma(s, t) - h * h * reduction[s * steps + t];
    let p_smooth = (0..steps).map(|t| cov(t, t)).collect();
    let p_lag1 = (0..steps).map(|t| if t == 0 { 0.0 } else { cov(t, t - 1) }).collect();
    (x_smooth, p_smooth, p_lag1)
}

#[test]
fn rts_on_a_scalar_model_equals_gaussian_conditioning() -> Result<()> {
    let mut rng = Rng::new(2024);
    // Söderström ex. 6.17 (case B1), a random walk, an unstable model, noisy and precise data.
    for (f, h, q, r) in [(0.8, 1.0, 0.68, 1.0), (1.0, 1.0, 0.1, 0.5), (1.2, 0.7, 0.3, 0.01), (-0.6, 2.0, 1.0, 4.0)] {
        for steps in [1, 2, 7, 30] {
            let mut y = rng.normals(steps, 1);
            if steps > 2 {
                y[1] = f64::NAN; // a missing observation
            }
            let (x0, p0) = (0.4, 1.5);
            let c = |v: f64| mat(1, 1, &[v]);
            let model = LinearGaussian::new(Matrices::new(c(f)?, c(h)?, c(q)?, c(r)?))?;
            let what = format!("f {f}, h {h}, q {q}, r {r}, T {steps}");
            let (x_want, p_want, lag1_want) = scalar_conditioning(f, h, q, r, x0, p0, &y);
            // The direct conditioning solves with G = h² Σ + r I, whose condition number grows
            // like f^(2T) / r for an unstable model (about 3e6 here): it, not RTS, limits the digits.
            let rtol = if f * f > 1.0 { 1e-8 } else { 1e-10 };
            for form in [UpdateForm::Joseph, UpdateForm::Standard] {
                let res = smooth(&model, Series::new("y", &y, steps, 1)?, None, &[x0], &[p0], form)?;
                let scale_x = max_abs(&x_want).max(1.0);
                assert_close(&format!("{what} {form:?}: x"), &res.x_smooth, &x_want, rtol, 1e-12 * scale_x);
                assert_close(&format!("{what} {form:?}: P"), &res.p_smooth, &p_want, rtol, 1e-13);
                assert_close(&format!("{what} {form:?}: P_lag1"), &res.p_lag1, &lag1_want, rtol, 1e-13);
            }
        }
    }
    Ok(())
}

#[test]
fn two_step_scalar_rts_by_hand() -> Result<()> {
    // F = H = 1, Q = R = 1, x[0] ~ N(0, 1), y = (1, 3): the joint prior of (x0, x1) has
    // Σ = [[1, 1], [1, 2]]; conditioning on y = x + v with Var v = I gives
    // G = Σ + I = [[2, 1], [1, 3]], G⁻¹ = [[3, −1], [−1, 2]] / 5,
    // E[x|y] = Σ G⁻¹ y = [[2, 1], [1, 3]] / 5 · y = (1, 2), and with Σ G⁻¹ Σ = [[3, 4], [4, 7]] / 5,
    // Cov[x|y] = Σ − Σ G⁻¹ Σ = [[2, 1], [1, 3]] / 5.
    let one = || mat(1, 1, &[1.0]);
    let model = LinearGaussian::new(Matrices::new(one()?, one()?, one()?, one()?))?;
    let y = [1.0, 3.0];
    let res = smooth(&model, Series::new("y", &y, 2, 1)?, None, &[0.0], &[1.0], UpdateForm::Joseph)?;
    assert_close("x", &res.x_smooth, &[1.0, 2.0], 1e-14, 1e-14);
    assert_close("P", &res.p_smooth, &[0.4, 0.6], 1e-14, 1e-14);
    assert_close("P_lag1", &res.p_lag1, &[0.0, 0.2], 1e-14, 1e-14);
    Ok(())
}
