//! Integration tests of the Lyapunov solvers through the public API, with SciPy's conventions:
//!
//! ```text
//! solve_discrete_lyapunov(a, q):    X = a X a' + q      (Söderström (4.9))
//! solve_continuous_lyapunov(a, q):  a X + X a' = q
//! stationary_covariance(F, Q):      Π = F Π F' + Q, F stable
//! ```
//!
//! Residuals on seeded random systems (computed here, independently of the crate), symmetry
//! for symmetric q, scalar closed forms, and errors when the solution is not unique.

mod common;

use common::{add, assert_close, matmul, max_abs, scale, spectral_radius_gelfand, sub, transpose, Rng};
use kfast::{solve_continuous_lyapunov, solve_discrete_lyapunov, stationary_covariance, Error, Result};

/// Relative residual of X − a X a' − q, and of a X + X a' − q.
fn discrete_residual(a: &[f64], q: &[f64], x: &[f64], n: usize) -> f64 {
    let axa = matmul(&matmul(a, x, n, n, n), &transpose(a, n, n), n, n, n);
    max_abs(&sub(&sub(x, &axa), q)) / (max_abs(x) + max_abs(&axa) + max_abs(q))
}

fn continuous_residual(a: &[f64], q: &[f64], x: &[f64], n: usize) -> f64 {
    let ax = matmul(a, x, n, n, n);
    let xat = matmul(x, &transpose(a, n, n), n, n, n);
    max_abs(&sub(&add(&ax, &xat), q)) / (max_abs(&ax) + max_abs(&xat) + max_abs(q))
}

fn assert_symmetric(what: &str, x: &[f64], n: usize) {
    for i in 0..n {
        for j in 0..i {
            assert!(
                x[i * n + j] == x[j * n + i],
                "{what}: X[{i},{j}] = {} but X[{j},{i}] = {}",
                x[i * n + j],
                x[j * n + i]
            );
        }
    }
}

/// A seeded random `n × n` matrix with spectral radius `radius`.
fn random_with_radius(rng: &mut Rng, n: usize, radius: f64) -> Vec<f64> {
    let a = rng.normals(n, n);
    scale(&a, radius / spectral_radius_gelfand(&a, n).max(1e-9))
}

#[test]
fn discrete_lyapunov_residual_and_symmetry_on_random_systems() -> Result<()> {
    for seed in 0..80 {
        let mut rng = Rng::new(seed);
        let n = rng.int(1, 10);
        // Stable and unstable a: the equation has a unique solution unless λ_i λ_j = 1.
        let radius = if seed % 4 == 3 { rng.range(1.2, 2.0) } else { rng.range(0.1, 0.95) };
        let a = random_with_radius(&mut rng, n, radius);
        let q = rng.spd(n, 0.1);
        let x = solve_discrete_lyapunov(&a, &q, n)?;
        let what = format!("seed {seed} (n {n}, ρ {radius:.2})");
        let res = discrete_residual(&a, &q, &x, n);
        assert!(res <= 1e-12, "{what}: relative residual {res:e}");
        assert_symmetric(&what, &x, n);
        if radius < 1.0 {
            // The stationary covariance of a stable model is the same solution.
            let pi = stationary_covariance(&a, &q, n)?;
            assert_close(&format!("{what}: stationary_covariance"), &pi, &x, 1e-12, 1e-12 * max_abs(&x));
        }
        // A nonsymmetric right-hand side is solved too (no symmetry assumed).
        let q_ns = rng.normals(n, n);
        let x_ns = solve_discrete_lyapunov(&a, &q_ns, n)?;
        let res = discrete_residual(&a, &q_ns, &x_ns, n);
        assert!(res <= 1e-12, "{what}: nonsymmetric q: relative residual {res:e}");
    }
    Ok(())
}

#[test]
fn continuous_lyapunov_residual_and_symmetry_on_random_systems() -> Result<()> {
    for seed in 0..80 {
        let mut rng = Rng::new(500 + seed);
        let n = rng.int(1, 10);
        // a − c I with c > max Re λ (Hurwitz) or a shifted to have no λ_i + λ_j = 0 otherwise.
        let mut a = rng.normals(n, n);
        let shift = if seed % 4 == 3 { -0.5 } else { 3.0 + 0.5 * (n as f64).sqrt() };
        for i in 0..n {
            a[i * n + i] -= shift;
        }
        let q = scale(&rng.spd(n, 0.1), -1.0);
        let x = solve_continuous_lyapunov(&a, &q, n)?;
        let what = format!("seed {seed} (n {n})");
        let res = continuous_residual(&a, &q, &x, n);
        assert!(res <= 1e-12, "{what}: relative residual {res:e}");
        assert_symmetric(&what, &x, n);
        let q_ns = rng.normals(n, n);
        let x_ns = solve_continuous_lyapunov(&a, &q_ns, n)?;
        let res = continuous_residual(&a, &q_ns, &x_ns, n);
        assert!(res <= 1e-12, "{what}: nonsymmetric q: relative residual {res:e}");
    }
    Ok(())
}

#[test]
fn scalar_closed_forms() -> Result<()> {
    // x = a² x + q ⇒ x = q / (1 − a²);  2 a x = q ⇒ x = q / (2a).
    for (a, q) in [(0.8, 0.68), (-0.5, 2.0), (3.0, 1.0), (0.0, 0.25)] {
        let x = solve_discrete_lyapunov(&[a], &[q], 1)?;
        assert_close(&format!("discrete a={a}"), &x, &[q / (1.0 - a * a)], 1e-14, 0.0);
    }
    for (a, q) in [(-1.0, -1.0), (-0.1, -3.0), (2.0, 1.0)] {
        let x = solve_continuous_lyapunov(&[a], &[q], 1)?;
        assert_close(&format!("continuous a={a}"), &x, &[q / (2.0 * a)], 1e-14, 0.0);
    }
    // Söderström ex. 6.17 (case B1): F = 0.8, Q = 0.68 has stationary variance 0.68/0.36.
    let pi = stationary_covariance(&[0.8], &[0.68], 1)?;
    assert_close("stationary B1", &pi, &[0.68 / 0.36], 1e-14, 0.0);
    // A rotation by θ scaled by ρ: X = q / (1 − ρ²) I for q I (a a' = ρ² I).
    let (rho, th) = (0.9_f64, 0.7_f64);
    let a = [rho * th.cos(), -rho * th.sin(), rho * th.sin(), rho * th.cos()];
    let x = solve_discrete_lyapunov(&a, &[2.0, 0.0, 0.0, 2.0], 2)?;
    let d = 2.0 / (1.0 - rho * rho);
    assert_close("rotation", &x, &[d, 0.0, 0.0, d], 1e-13, 1e-13);
    Ok(())
}

/// Expects `Error::InvalidArgument` on `a` saying the solution is not unique, with `detail`.
fn assert_not_unique(what: &str, got: Result<Vec<f64>>, detail: &str) {
    match got {
        Err(err @ Error::InvalidArgument { arg: "a", step: None, .. }) => {
            let msg = err.to_string();
            assert!(msg.starts_with("a: the Lyapunov equation has no unique solution"), "{what}: {msg}");
            assert!(msg.contains(detail), "{what}: {msg}");
        }
        Err(other) => panic!("{what}: expected InvalidArgument on a, got {other:?}"),
        Ok(x) => panic!("{what}: expected an error, got X = {x:?}"),
    }
}

#[test]
fn no_unique_solution_is_an_error() {
    let q2 = [1.0, 0.0, 0.0, 1.0];
    // Discrete: λ_i λ_j = 1 (2 · 0.5; a unit eigenvalue; a rotation on the unit circle).
    let th = 0.3_f64;
    for (what, a, n) in [
        ("diag(2, 0.5)", vec![2.0, 0.0, 0.0, 0.5], 2),
        ("a = 1", vec![1.0], 1),
        ("a = −1", vec![-1.0], 1),
        ("unit rotation", vec![th.cos(), -th.sin(), th.sin(), th.cos()], 2),
    ] {
        assert_not_unique(what, solve_discrete_lyapunov(&a, &q2[..n * n], n), "λ_i λ_j = 1");
    }
    // Continuous: λ_i + λ_j = 0 (1 − 1; a zero eigenvalue; an undamped oscillator ±iω).
    for (what, a, n) in [
        ("diag(1, −1)", vec![1.0, 0.0, 0.0, -1.0], 2),
        ("a = 0", vec![0.0], 1),
        ("oscillator", vec![0.0, 1.0, -4.0, 0.0], 2),
    ] {
        assert_not_unique(what, solve_continuous_lyapunov(&a, &q2[..n * n], n), "λ_i + λ_j = 0");
    }
    // stationary_covariance refuses an unstable F instead (no stationary covariance exists).
    match stationary_covariance(&[1.0], &[1.0], 1) {
        Err(Error::InvalidArgument { arg: "F", .. }) => {}
        other => panic!("expected InvalidArgument on F, got {other:?}"),
    }
}
