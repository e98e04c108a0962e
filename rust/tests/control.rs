//! Integration tests of the LQ regulators (`kfast::control`, u = −L x) through the public API:
//! the stationary S satisfies (11.47) (residual computed here) and F − G L is stable; the finite
//! horizon equals the backward recursion (11.6)–(11.7) written out here, with time-varying data
//! and a cross weight, and converges to the stationary regulator; Söderström ex. 11.4 (a); bad
//! input is an error naming the argument and the step.

mod common;

use common::{add, assert_close, eye, matmul, max_abs, solve, spectral_radius_gelfand, sub, transpose, Rng};
use kfast::control::{lq_finite, lqr, LqProblem, LqSteps};
use kfast::{DareMethod, Error, StepMatrix};

struct Problem {
    f: Vec<f64>,
    g: Vec<f64>,
    q1: Vec<f64>,
    q2: Vec<f64>,
    q12: Vec<f64>,
}

/// The backward recursion (11.6)–(11.7) for one step: (S(t), L(t)) from S(t+1).
fn backward_step(p: &Problem, s: &[f64], n: usize, k: usize) -> (Vec<f64>, Vec<f64>) {
    let (f, g) = (&p.f, &p.g);
    let gt = transpose(g, n, k);
    let gs = matmul(&gt, s, k, n, n);
    let gamma = add(&matmul(&gs, g, k, n, k), &p.q2);
    let rhs = add(&matmul(&gs, f, k, n, n), &transpose(&p.q12, n, k));
    let l = solve(&gamma, &rhs, k, n);
    let ft = transpose(f, n, n);
    let fsf = matmul(&matmul(&ft, s, n, n, n), f, n, n, n);
    let fsg_q12 = add(&matmul(&matmul(&ft, s, n, n, n), g, n, n, k), &p.q12);
    let s_new = sub(&add(&fsf, &p.q1), &matmul(&fsg_q12, &l, n, k, n));
    (s_new, l)
}

fn problem(rng: &mut Rng, n: usize, k: usize) -> Problem {
    let w = rng.spd(n + k, 0.1);
    let block = |r0: usize, c0: usize, r: usize, c: usize| -> Vec<f64> {
        (0..r).flat_map(|i| (0..c).map(move |j| (i, j))).map(|(i, j)| w[(r0 + i) * (n + k) + c0 + j]).collect()
    };
    Problem {
        f: rng.normals(n, n),
        g: rng.normals(n, k),
        q1: block(0, 0, n, n),
        q2: block(n, n, k, k),
        q12: block(0, n, n, k),
    }
}

#[test]
fn the_stationary_regulator_solves_its_riccati_equation_and_stabilizes() {
    let mut rng = Rng::new(11);
    for _ in 0..20 {
        let (n, k) = (rng.int(1, 8), rng.int(1, 4));
        let p = problem(&mut rng, n, k);
        let sol = lqr(LqProblem::new(&p.f, &p.g, &p.q1, &p.q2, n, k).with_cross(&p.q12), DareMethod::Doubling).unwrap();
        let (s_next, l) = backward_step(&p, sol.s(), n, k);
        assert!(max_abs(&sub(&s_next, sol.s())) <= 1e-9 * max_abs(sol.s()).max(1.0));
        assert_close("L", sol.gain(), &l, 1e-9, 1e-9 * max_abs(&l).max(1.0));
        let closed = sub(&p.f, &matmul(&p.g, sol.gain(), n, k, n));
        assert!(spectral_radius_gelfand(&closed, n) < 1.0);
        let radius = sol.closed_loop_eigenvalues().unwrap().iter().map(|(re, im)| re.hypot(*im)).fold(0.0, f64::max);
        assert!((radius - spectral_radius_gelfand(&closed, n)).abs() < 1e-6);
    }
}

#[test]
fn soderstrom_example_11_4a() {
    let h = 0.5;
    let (f, g) = ([1.0, h, 0.0, 1.0], [h * h / 2.0, h]);
    let sol = lqr(LqProblem::new(&f, &g, &eye(2), &[0.1], 2, 1), DareMethod::Doubling).unwrap();
    let mut poles: Vec<f64> =
        sol.closed_loop_eigenvalues().unwrap().iter().map(|&(re, _)| (re * 100.0).round() / 100.0).collect();
    poles.sort_by(f64::total_cmp);
    assert_eq!(poles, vec![0.27, 0.58]);
}

#[test]
fn the_finite_horizon_is_the_backward_recursion_with_time_varying_data() {
    let mut rng = Rng::new(5);
    for _ in 0..8 {
        let (n, k, horizon) = (rng.int(1, 14), rng.int(1, 4), rng.int(1, 12));
        let steps: Vec<Problem> = (0..horizon).map(|_| problem(&mut rng, n, k)).collect();
        let stack = |get: &dyn Fn(&Problem) -> &Vec<f64>, r: usize, c: usize| {
            StepMatrix::per_step(horizon, r, c, steps.iter().flat_map(|p| get(p).clone()).collect()).unwrap()
        };
        let data = LqSteps::new(
            stack(&|p| &p.f, n, n),
            stack(&|p| &p.g, n, k),
            stack(&|p| &p.q1, n, n),
            stack(&|p| &p.q2, k, k),
        )
        .with_cross(stack(&|p| &p.q12, n, k));
        let q0 = rng.spd(n, 0.1);
        let res = lq_finite(&data, &q0, horizon).unwrap();
        let mut s = q0.clone();
        assert_close("S(N)", &res.s[horizon * n * n..], &q0, 0.0, 0.0);
        for t in (0..horizon).rev() {
            let p = &steps[t];
            let (s_t, l_t) = backward_step(p, &s, n, k);
            s = s_t;
            let scale = max_abs(&s).max(1.0);
            assert_close("S(t)", &res.s[t * n * n..][..n * n], &s, 1e-9, 1e-9 * scale);
            assert_close("L(t)", &res.gains[t * k * n..][..k * n], &l_t, 1e-9, 1e-9 * max_abs(&l_t).max(1.0));
            s = res.s[t * n * n..][..n * n].to_vec(); // continue from the crate's S to keep errors from compounding
        }
    }
}

#[test]
fn the_finite_horizon_converges_to_the_stationary_regulator() {
    let mut rng = Rng::new(8);
    let (n, k) = (4, 2);
    let p = problem(&mut rng, n, k);
    let c = |r: usize, cols: usize, v: &[f64]| StepMatrix::constant(r, cols, v.to_vec()).unwrap();
    let data = LqSteps::new(c(n, n, &p.f), c(n, k, &p.g), c(n, n, &p.q1), c(k, k, &p.q2)).with_cross(c(n, k, &p.q12));
    let res = lq_finite(&data, &[0.0; 16], 300).unwrap();
    let sol = lqr(LqProblem::new(&p.f, &p.g, &p.q1, &p.q2, n, k).with_cross(&p.q12), DareMethod::Doubling).unwrap();
    assert_close("L(0)", &res.gains[..k * n], sol.gain(), 1e-8, 1e-8);
    assert_close("S(0)", &res.s[..n * n], sol.s(), 1e-8, 1e-8 * max_abs(sol.s()));
}

fn message(err: Error) -> String {
    err.to_string()
}

#[test]
fn bad_input_is_an_error_naming_the_argument() {
    let f = [1.0, 1.0, 0.0, 1.0];
    let g = [0.0, 1.0];
    let lq = |q1: &[f64], q2: &[f64], q12: Option<&[f64]>| {
        let mut p = LqProblem::new(&f, &g, q1, q2, 2, 1);
        if let Some(q12) = q12 {
            p = p.with_cross(q12);
        }
        lqr(p, DareMethod::Doubling).map(|_| ()).map_err(message)
    };
    assert!(lq(&[-1.0, 0.0, 0.0, 1.0], &[1.0], None).unwrap_err().starts_with("Q1: not positive semidefinite"));
    assert!(lq(&[1.0, 0.5, 0.0, 1.0], &[1.0], None).unwrap_err().starts_with("Q1: not symmetric"));
    assert!(lq(&eye(2), &[1.0], Some(&[3.0, 0.0])).unwrap_err().starts_with("Q12: the joint weight"));
    assert!(lq(&[f64::NAN, 0.0, 0.0, 1.0], &[1.0], None).unwrap_err().starts_with("Q1: contains a non-finite value"));
    let uncontrollable =
        lqr(LqProblem::new(&[1.5, 0.0, 0.0, 0.5], &[0.0, 1.0], &eye(2), &[1.0], 2, 1), DareMethod::Doubling);
    assert!(matches!(uncontrollable, Err(Error::NoStabilizingSolution { .. })));

    let c = |r: usize, cols: usize, v: &[f64]| StepMatrix::constant(r, cols, v.to_vec()).unwrap();
    let data = LqSteps::new(c(2, 2, &f), c(2, 1, &g), c(2, 2, &[0.0; 4]), c(1, 1, &[0.0]));
    let err = message(lq_finite(&data, &[0.0; 4], 3).unwrap_err());
    assert!(err.starts_with("Q2 at step 2: G' S(t+1) G + Q2 is not positive definite"), "{err}");
    assert!(message(lq_finite(&data, &[0.0; 4], 0).unwrap_err()).starts_with("N: the horizon must be at least 1"));
    assert!(message(lq_finite(&data, &[0.0; 4], usize::MAX / 2).unwrap_err()).starts_with("N: "));
    let q2_stack = StepMatrix::per_step(3, 1, 1, vec![1.0, -1.0, 1.0]).unwrap();
    let data = LqSteps::new(c(2, 2, &f), c(2, 1, &g), c(2, 2, &eye(2)), q2_stack);
    let err = message(lq_finite(&data, &eye(2), 3).unwrap_err());
    assert!(err.starts_with("Q2 at step 1: not positive semidefinite"), "{err}");
    assert!(message(lq_finite(&data, &eye(2), 4).unwrap_err()).starts_with("Q2: a per-step stack must have N = 4"));
    assert!(
        message(lq_finite(&data, &[-1.0, 0.0, 0.0, 1.0], 3).unwrap_err()).starts_with("Q0: not positive semidefinite")
    );
}
