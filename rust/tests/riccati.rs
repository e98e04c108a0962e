//! Integration tests of the algebraic Riccati solvers through the public API: on seeded random
//! systems with the cross term s and the descriptor matrix e, every method returns a solution
//! whose relative residual (computed here, independently of the crate) is below 1e-10, which is
//! symmetric and stabilizing (closed-loop spectral radius by Gelfand's formula, not by the
//! crate's eigenvalue solver), and a system without a stabilizing solution is an error.
//! `DareMethod::Newton` with a cross term once started from a gain that was not stabilizing
//! (issue 9; `newton_with_a_cross_term_returns_the_stabilizing_solution`).
//!
//! Conventions are SciPy's `solve_discrete_are(a, b, q, r, e, s)` /
//! `solve_continuous_are(a, b, q, r, e, s)` (docs/conventions.md, "Riccati and Lyapunov
//! equations"):
//!
//! ```text
//! DARE  a'Xa − e'Xe − (a'Xb + s)(b'Xb + r)⁻¹(b'Xa + s') + q = 0,   K = (b'Xb + r)⁻¹(b'Xa + s')
//! CARE  a'Xe + e'Xa − (e'Xb + s) r⁻¹ (b'Xe + s') + q = 0,        K = r⁻¹(b'Xe + s')
//! ```

mod common;

use common::{add, eye, matmul, max_abs, scale, solve, spectral_radius_gelfand, sub, transpose, Rng};
use kfast::{solve_continuous_are, solve_discrete_are, DareMethod, Error, Result, RiccatiProblem, RiccatiSolution};

const METHODS: [DareMethod; 4] = [DareMethod::Doubling, DareMethod::Newton, DareMethod::Iteration, DareMethod::Eigen];

/// A Riccati problem `(a, b, q, r, e, s)` with `a`, `e` `n × n` and `b`, `s` `n × m`.
struct System {
    n: usize,
    m: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    q: Vec<f64>,
    r: Vec<f64>,
    e: Option<Vec<f64>>,
    s: Option<Vec<f64>>,
}

/// A seeded random system: n 1–8, m 1–3; `a` of spectral radius 0.3–1.5 (a third of them
/// unstable); the weights `[[q, s], [s', r]]` are one random positive definite matrix (so
/// q − s r⁻¹ s' > 0 and the stabilizing solution exists when (a, b) is stabilizable, which a
/// random b makes it almost surely); e = I + 0.2·G/√n when `with_e`.
fn random_system(seed: u64, with_s: bool, with_e: bool) -> System {
    let mut rng = Rng::new(seed);
    let (n, m) = (rng.int(1, 8), rng.int(1, 3));
    let a = rng.normals(n, n);
    let rho = spectral_radius_gelfand(&a, n).max(1e-9);
    let a = scale(&a, rng.range(0.3, 1.5) / rho);
    let b = rng.normals(n, m);
    let w = rng.spd(n + m, 0.5);
    let block = |r0: usize, c0: usize, rows: usize, cols: usize| -> Vec<f64> {
        (0..rows * cols).map(|k| w[(r0 + k / cols) * (n + m) + c0 + k % cols]).collect()
    };
    let (q, r) = (block(0, 0, n, n), block(n, n, m, m));
    let s = with_s.then(|| block(0, n, n, m));
    let e = with_e.then(|| add(&eye(n), &scale(&rng.normals(n, n), 0.2 / (n as f64).sqrt())));
    System { n, m, a, b, q, r, e, s }
}

impl System {
    fn e(&self) -> Vec<f64> {
        self.e.clone().unwrap_or_else(|| eye(self.n))
    }

    fn s(&self) -> Vec<f64> {
        self.s.clone().unwrap_or_else(|| vec![0.0; self.n * self.m])
    }

    fn dare(&self, method: DareMethod) -> Result<RiccatiSolution> {
        solve_discrete_are(self.problem(), method)
    }

    fn care(&self) -> Result<RiccatiSolution> {
        solve_continuous_are(self.problem())
    }

    fn problem(&self) -> RiccatiProblem<'_> {
        let mut p = RiccatiProblem::new(&self.a, &self.b, &self.q, &self.r, self.n, self.m);
        if let Some(e) = &self.e {
            p = p.with_e(e);
        }
        if let Some(s) = &self.s {
            p = p.with_s(s);
        }
        p
    }

    /// ‖DARE residual‖ / (sum of the norms of its four terms), and the gain computed here.
    fn dare_residual(&self, x: &[f64]) -> (f64, Vec<f64>) {
        let (n, m) = (self.n, self.m);
        let (a, b, e, s) = (&self.a, &self.b, self.e(), self.s());
        let at = transpose(a, n, n);
        let atxa = matmul(&matmul(&at, x, n, n, n), a, n, n, n);
        let etxe = matmul(&matmul(&transpose(&e, n, n), x, n, n, n), &e, n, n, n);
        let xb = matmul(x, b, n, n, m);
        let btxb_r = add(&matmul(&transpose(b, n, m), &xb, m, n, m), &self.r);
        let atxb_s = add(&matmul(&at, &xb, n, n, m), &s);
        let gain = solve(&btxb_r, &transpose(&atxb_s, n, m), m, n);
        let cross = matmul(&atxb_s, &gain, n, m, n);
        let res = add(&sub(&sub(&atxa, &etxe), &cross), &self.q);
        let size = max_abs(&atxa) + max_abs(&etxe) + max_abs(&cross) + max_abs(&self.q);
        (max_abs(&res) / size, gain)
    }

    /// ‖CARE residual‖ / (sum of the norms of its terms), and the gain computed here.
    fn care_residual(&self, x: &[f64]) -> (f64, Vec<f64>) {
        let (n, m) = (self.n, self.m);
        let (a, b, e, s) = (&self.a, &self.b, self.e(), self.s());
        let atxe = matmul(&matmul(&transpose(a, n, n), x, n, n, n), &e, n, n, n);
        let etxb_s = add(&matmul(&matmul(&transpose(&e, n, n), x, n, n, n), b, n, n, m), &s);
        let gain = solve(&self.r, &transpose(&etxb_s, n, m), m, n);
        let cross = matmul(&etxb_s, &gain, n, m, n);
        let res = add(&sub(&add(&atxe, &transpose(&atxe, n, n)), &cross), &self.q);
        let size = 2.0 * max_abs(&atxe) + max_abs(&cross) + max_abs(&self.q);
        (max_abs(&res) / size, gain)
    }

    /// The closed-loop matrix e⁻¹(a − bK) (similar to the crate's (a − bK)e⁻¹).
    fn closed_loop(&self, gain: &[f64]) -> Vec<f64> {
        let n = self.n;
        let acl = sub(&self.a, &matmul(&self.b, gain, n, self.m, n));
        solve(&self.e(), &acl, n, n)
    }

    /// Whether `DareMethod::Newton` would meet the bug of its old starting point (issue 9; see
    /// `newton_with_a_cross_term_returns_the_stabilizing_solution`): it started from X = 0 when
    /// e⁻¹a is stable, but X = 0 gives the gain r⁻¹s', whose closed loop e⁻¹(a − b r⁻¹ s') may
    /// be unstable, and Newton–Hewer needs a stabilizing first gain (Söderström ex. 6.23;
    /// docs/algorithms.md, "Newton–Hewer"). It now starts from the gain 0.
    fn newton_starts_unstable(&self) -> bool {
        let n = self.n;
        let stable_a = spectral_radius_gelfand(&solve(&self.e(), &self.a, n, n), n) < 1.0;
        let first_gain = solve(&self.r, &transpose(&self.s(), n, self.m), self.m, n);
        stable_a && spectral_radius_gelfand(&self.closed_loop(&first_gain), n) >= 1.0
    }
}

fn assert_symmetric(what: &str, x: &[f64], n: usize) {
    let tol = 1e-12 * max_abs(x).max(1.0);
    for i in 0..n {
        for j in 0..i {
            let (xij, xji) = (x[i * n + j], x[j * n + i]);
            assert!((xij - xji).abs() <= tol, "{what}: X[{i},{j}] = {xij} but X[{j},{i}] = {xji}");
        }
    }
}

/// The largest modulus of the eigenvalues the solver reports.
fn reported_radius(sol: &RiccatiSolution) -> f64 {
    sol.closed_loop_eigenvalues().unwrap().iter().map(|(re, im)| re.hypot(*im)).fold(0.0, f64::max)
}

const SEEDS: u64 = 60;

#[test]
fn dare_residual_is_small_and_solution_stabilizing_for_every_method() -> Result<()> {
    for seed in 0..SEEDS {
        let sys = random_system(seed, seed % 2 == 1, seed % 3 != 0);
        let n = sys.n;
        let mut first: Option<Vec<f64>> = None;
        for method in METHODS {
            let what = format!("seed {seed} (n {n}, m {}), {method:?}", sys.m);
            let sol = sys.dare(method).inspect_err(|e| eprintln!("{what}: {e}"))?;
            assert_eq!((sol.x.len(), sol.gain.len()), (n * n, sys.m * n), "{what}: shapes");
            assert_symmetric(&what, &sol.x, n);
            let (residual, gain) = sys.dare_residual(&sol.x);
            assert!(residual <= 1e-10, "{what}: relative residual {residual:e}");
            assert!(sol.residual <= 1e-10, "{what}: reported residual {:e}", sol.residual);
            common::assert_close(&format!("{what}: gain"), &sol.gain, &gain, 1e-8, 1e-8 * max_abs(&gain));
            // Stabilizing: the closed loop e⁻¹(a − bK) has spectral radius < 1 (Gelfand), and
            // the eigenvalues the solver reports agree with it.
            let rho = spectral_radius_gelfand(&sys.closed_loop(&sol.gain), n);
            assert!(rho < 1.0, "{what}: closed-loop spectral radius {rho}");
            let reported = reported_radius(&sol);
            assert!((reported - rho).abs() <= 1e-6 * rho.max(1e-3), "{what}: reported ρ {reported}, Gelfand {rho}");
            // The stabilizing solution is unique: every method finds the same X.
            match &first {
                None => first = Some(sol.x),
                Some(x0) => {
                    common::assert_close(&format!("{what}: X vs Doubling"), &sol.x, x0, 1e-8, 1e-8 * max_abs(x0))
                }
            }
        }
    }
    Ok(())
}

#[test]
fn care_residual_is_small_and_solution_stabilizing() -> Result<()> {
    for seed in 0..SEEDS {
        let sys = random_system(1000 + seed, seed % 2 == 1, seed % 3 != 0);
        let n = sys.n;
        let what = format!("seed {seed} (n {n}, m {})", sys.m);
        let sol = sys.care().inspect_err(|e| eprintln!("{what}: {e}"))?;
        assert_symmetric(&what, &sol.x, n);
        let (residual, gain) = sys.care_residual(&sol.x);
        assert!(residual <= 1e-10, "{what}: relative residual {residual:e}");
        assert!(sol.residual <= 1e-10, "{what}: reported residual {:e}", sol.residual);
        common::assert_close(&format!("{what}: gain"), &sol.gain, &gain, 1e-8, 1e-8 * max_abs(&gain));
        // Stabilizing: Re λ < 0 for the closed loop M = e⁻¹(a − bK) ⇔ its Cayley transform
        // (I − M)⁻¹(I + M) has spectral radius < 1 (λ ↦ (1 + λ)/(1 − λ) maps the open left
        // half-plane onto the open unit disc).
        let cl = sys.closed_loop(&sol.gain);
        let cayley = solve(&sub(&eye(n), &cl), &add(&eye(n), &cl), n, n);
        let rho = spectral_radius_gelfand(&cayley, n);
        assert!(rho < 1.0, "{what}: Cayley-transformed closed-loop spectral radius {rho}");
        let max_re = sol.closed_loop_eigenvalues()?.iter().map(|l| l.0).fold(f64::NEG_INFINITY, f64::max);
        assert!(max_re < 0.0, "{what}: reported closed-loop eigenvalue with real part {max_re}");
        let reported_cayley = sol
            .closed_loop_eigenvalues()?
            .iter()
            .map(|&(re, im)| ((1.0 + re).hypot(im)) / ((1.0 - re).hypot(im)))
            .fold(0.0, f64::max);
        assert!(
            (reported_cayley - rho).abs() <= 1e-6,
            "{what}: reported eigenvalues give {reported_cayley}, Gelfand {rho}"
        );
    }
    Ok(())
}

#[test]
fn scalar_dare_and_care_match_their_closed_forms() -> Result<()> {
    // Scalar DARE a²x − x − (abx)²/(b²x + r) + q = 0 ⇔ b²x² + (r(1 − a²) − qb²)x − qr = 0: the
    // positive root. Söderström ex. 6.17 (case B1): a = 0.8, b = 1, q = 0.68, r = 1 gives x = 1.
    for (a, b, q, r) in [(0.8_f64, 1.0_f64, 0.68_f64, 1.0_f64), (1.7, 0.5, 2.0, 0.3), (-0.4, 2.0, 0.1, 5.0)] {
        let (bq, bl) = (b * b, r * (1.0 - a * a) - q * b * b);
        let want = (-bl + (bl * bl + 4.0 * bq * q * r).sqrt()) / (2.0 * bq);
        for method in METHODS {
            let sol = solve_discrete_are(RiccatiProblem::new(&[a], &[b], &[q], &[r], 1, 1), method)?;
            common::assert_close(&format!("DARE a={a} {method:?}"), &sol.x, &[want], 1e-12, 0.0);
        }
        // Scalar CARE 2ax − (bx)²/r + q = 0: x = r(a + √(a² + b²q/r))/b².
        let want = r * (a + (a * a + b * b * q / r).sqrt()) / (b * b);
        let sol = solve_continuous_are(RiccatiProblem::new(&[a], &[b], &[q], &[r], 1, 1))?;
        common::assert_close(&format!("CARE a={a}"), &sol.x, &[want], 1e-12, 0.0);
    }
    Ok(())
}

/// SciPy's CAREX 10 (Benner–Laub–Mehrmann): a closed-loop eigenvalue within rounding of the
/// imaginary axis picks a non-stabilizing Hamiltonian subspace; Newton–Kleinman from a
/// stabilizing gain finds the stabilizing solution, to SciPy's tolerance 1.5e-14.
#[test]
fn care_near_the_imaginary_axis_falls_back_to_newton_kleinman() -> Result<()> {
    let (a, b, q, r) = ([3.0, 1.0, 4.0, 2.0], [1.0, 1.0], [-11.0, -5.0, -5.0, -2.0], [1.0]);
    let sol = solve_continuous_are(RiccatiProblem::new(&a, &b, &q, &r, 2, 1))?;
    let x = &sol.x;
    // a'X + Xa − X b r⁻¹ b' X + q, r = 1.
    let xb = [x[0] * b[0] + x[1] * b[1], x[2] * b[0] + x[3] * b[1]];
    for i in 0..2 {
        for j in 0..2 {
            let ax: f64 = (0..2).map(|k| a[k * 2 + i] * x[k * 2 + j] + x[i * 2 + k] * a[k * 2 + j]).sum();
            let res = ax - xb[i] * xb[j] + q[i * 2 + j];
            assert!(res.abs() <= 1.5e-14, "residual {res} at ({i}, {j})");
        }
    }
    let largest = sol.closed_loop_eigenvalues()?.iter().map(|l| l.0).fold(f64::NEG_INFINITY, f64::max);
    assert!(largest < 0.0, "closed loop {largest}");
    Ok(())
}

#[test]
fn scalar_dare_with_a_cross_term_matches_its_closed_form() -> Result<()> {
    // a = 0, b = 1, q = 5, r = 1, s = 2: removing the cross term (Söderström Lemma 6.4) gives
    // ã = a − b s/r = −2, q̃ = q − s²/r = 1 and x = ã² x − ã² x²/(x + 1) + q̃, i.e.
    // x² − 4x − 1 = 0, whose stabilizing root is x = 2 + √5 (closed loop ã/(x + 1) ≈ −0.38).
    let want = 2.0 + 5f64.sqrt();
    for method in [DareMethod::Doubling, DareMethod::Iteration, DareMethod::Eigen] {
        let sol = solve_discrete_are(RiccatiProblem::new(&[0.0], &[1.0], &[5.0], &[1.0], 1, 1).with_s(&[2.0]), method)?;
        common::assert_close(&format!("{method:?}"), &sol.x, &[want], 1e-12, 0.0);
    }
    Ok(())
}

#[test]
fn newton_with_a_cross_term_returns_the_stabilizing_solution() -> Result<()> {
    // The system of scalar_dare_with_a_cross_term_matches_its_closed_form.
    let sol = solve_discrete_are(
        RiccatiProblem::new(&[0.0], &[1.0], &[5.0], &[1.0], 1, 1).with_s(&[2.0]),
        DareMethod::Newton,
    )?;
    common::assert_close("Newton", &sol.x, &[2.0 + 5f64.sqrt()], 1e-12, 0.0);
    // And the random systems the main test skips for Newton.
    for seed in 0..SEEDS {
        let sys = random_system(seed, seed % 2 == 1, seed % 3 != 0);
        if sys.newton_starts_unstable() {
            let sol = sys.dare(DareMethod::Newton).inspect_err(|e| eprintln!("seed {seed}: {e}"))?;
            let (residual, _) = sys.dare_residual(&sol.x);
            assert!(residual <= 1e-10, "seed {seed}: relative residual {residual:e}");
        }
    }
    Ok(())
}

/// Expects `Error::NoStabilizingSolution`, whose message says so.
fn assert_no_stabilizing(what: &str, got: Result<RiccatiSolution>) {
    match got {
        Err(err @ Error::NoStabilizingSolution { .. }) => {
            let msg = err.to_string();
            assert!(msg.starts_with("no stabilizing solution of the Riccati equation: "), "{what}: {msg}");
        }
        Err(other) => panic!("{what}: expected NoStabilizingSolution, got {other:?}"),
        Ok(sol) => panic!("{what}: expected NoStabilizingSolution, got X = {:?}", sol.x),
    }
}

#[test]
fn no_stabilizing_solution_is_an_error() {
    // (a, b) not stabilizable: the unstable mode 2 is not reached by the input.
    let (a, b) = ([2.0, 0.0, 0.0, 0.5], [0.0, 1.0]);
    for method in METHODS {
        assert_no_stabilizing(
            &format!("DARE {method:?}"),
            solve_discrete_are(RiccatiProblem::new(&a, &b, &eye(2), &[1.0], 2, 1), method),
        );
    }
    // A unit-circle mode without noise: the only solution is X = 0 with closed loop 1. (Not
    // `Iteration`: it creeps towards 0 like 1/k and fails only at its iteration cap, 200 000
    // steps, which takes 20 s in a debug build.)
    for method in [DareMethod::Doubling, DareMethod::Newton, DareMethod::Eigen] {
        let got = solve_discrete_are(RiccatiProblem::new(&[1.0], &[1.0], &[0.0], &[1.0], 1, 1), method);
        assert_no_stabilizing(&format!("DARE random walk {method:?}"), got);
    }
    // CARE: the mode +1 is not reached by the input.
    let a = [1.0, 0.0, 0.0, -1.0];
    assert_no_stabilizing("CARE", solve_continuous_are(RiccatiProblem::new(&a, &b, &eye(2), &[1.0], 2, 1)));
    // Scalar: b = 0 and a = 2; the only solution x = −1/3 leaves the closed loop at 2.
    for method in METHODS {
        let got = solve_discrete_are(RiccatiProblem::new(&[2.0], &[0.0], &[1.0], &[1.0], 1, 1), method);
        assert_no_stabilizing(&format!("DARE b = 0 {method:?}"), got);
    }
}
