//! The steady-state Kalman gain of a model from the discrete algebraic Riccati equation. The
//! solver takes SciPy's (control) form; by duality the filter's stationary P(t|t−1) is its
//! solution X for a = F', b = H', q = Q, r = R, and the filter gain is
//! K = P H' (H P H' + R)⁻¹.
//!
//! Run with `cargo run --release --example steady_state_gain`.

use kfast::{solve_discrete_are, DareMethod, RiccatiProblem};

fn main() -> Result<(), kfast::Error> {
    // A 2-state constant-velocity model with dt = 1, position measured (n = 2, m = 1).
    let f = [1.0, 1.0, 0.0, 1.0];
    let f_t = [f[0], f[2], f[1], f[3]];
    let h_t = [1.0, 0.0]; // H' (2 × 1)
    let q = [1.0 / 3.0, 0.5, 0.5, 1.0];
    let r = [1.0];
    let sol = solve_discrete_are(RiccatiProblem::new(&f_t, &h_t, &q, &r, 2, 1), DareMethod::default())?;
    let p = &sol.x; // P(t|t−1) in steady state, row-major 2 × 2
    let s = p[0] + r[0]; // H P H' + R
    let gain = [p[0] / s, p[2] / s]; // K = P H' S⁻¹
    println!("stationary P(t|t-1) = [[{:.6}, {:.6}], [{:.6}, {:.6}]]", p[0], p[1], p[2], p[3]);
    println!(
        "filter gain K = [{:.6}, {:.6}]'  (method {}, residual {:.1e})",
        gain[0], gain[1], sol.method, sol.residual
    );
    let radius = sol.closed_loop_eigenvalues()?.iter().map(|(re, im)| re.hypot(*im)).fold(0.0, f64::max);
    println!("spectral radius of the closed loop: {radius:.6} (< 1: the stabilizing solution)");
    Ok(())
}
