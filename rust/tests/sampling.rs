//! Integration tests of the matrix exponential ([`kfast::expm`], the core of sampling) through
//! the public API: closed forms (diagonal, nilpotent, rotation, Jordan block), on both sides of
//! the scaling-and-squaring threshold (‖A‖₁ ≈ 5.4), and e^A e^−A = I on seeded random matrices;
//! the reproducers of issue #10 (large-norm nilpotent input, overflow as an error, long
//! intervals and an indefinite Qc in discretize).

mod common;

use common::{add, assert_close, eye, matmul, max_abs, scale, sub, Rng};
use kfast::{expm, Error, Result};

#[test]
fn scalar_and_diagonal() -> Result<()> {
    for x in [0.0, 1e-10, -0.3, 1.0, 5.0, -20.0, 40.0] {
        // Scaling and squaring (2^s squarings for |x| > 5.4) amplifies rounding by about 2^s.
        assert_close(&format!("e^{x}"), &expm(&[x], 1)?, &[x.exp()], 1e-13, 0.0);
    }
    // Entries far apart in size (‖A‖₁ = 40: scaled and squared).
    let d = [-30.0, -1.0, 0.0, 0.5, 4.0, 10.0];
    let n = d.len();
    let a: Vec<f64> = (0..n * n).map(|k| if k % (n + 1) == 0 { d[k / n] } else { 0.0 }).collect();
    let want: Vec<f64> = (0..n * n).map(|k| if k % (n + 1) == 0 { d[k / n].exp() } else { 0.0 }).collect();
    // Off-diagonal zeros must stay exact zeros; each diagonal entry is e^d to rounding.
    let got = expm(&a, n)?;
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        assert!((g - w).abs() <= 1e-13 * w.abs(), "diag[{k}]: got {g:e}, want {w:e}");
    }
    Ok(())
}

#[test]
fn nilpotent_is_a_finite_series() -> Result<()> {
    // A strictly upper triangular 5 × 5 N has N⁵ = 0, so e^N = I + N + N²/2 + N³/6 + N⁴/24.
    let n = 5;
    let mut rng = Rng::new(7);
    for size in [0.1, 1.0, 10.0] {
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in i + 1..n {
                a[i * n + j] = size * rng.normal();
            }
        }
        let mut want = eye(n);
        let mut power = eye(n);
        for k in 1..n {
            power = scale(&matmul(&power, &a, n, n, n), 1.0 / k as f64);
            want = add(&want, &power);
        }
        let got = expm(&a, n)?;
        assert_close(&format!("nilpotent, size {size}"), &got, &want, 1e-13, 1e-13 * max_abs(&want));
        // e^N is upper triangular (exact zeros below the diagonal) with ones on the diagonal.
        for i in 0..n {
            assert!((got[i * n + i] - 1.0).abs() <= 1e-14, "size {size}: diagonal {i} is {}", got[i * n + i]);
            for j in 0..i {
                assert_eq!(got[i * n + j], 0.0, "size {size}: entry ({i}, {j})");
            }
        }
    }
    Ok(())
}

#[test]
fn rotation_and_jordan_block() -> Result<()> {
    // exp([[0, −θ], [θ, 0]]) is the rotation by θ.
    for th in [0.1_f64, 1.0, std::f64::consts::PI, 10.0, 50.0] {
        let got = expm(&[0.0, -th, th, 0.0], 2)?;
        let (c, s) = (th.cos(), th.sin());
        // Squaring 2^k times amplifies rounding by about 2^k ~ θ.
        assert_close(&format!("rotation θ={th}"), &got, &[c, -s, s, c], 0.0, 1e-15 * th.max(1.0) * 4.0);
    }
    // exp(t [[λ, 1], [0, λ]]) = e^{λt} [[1, t], [0, 1]].
    for (lam, t) in [(-0.5, 1.0), (0.3, 2.0), (-2.0, 7.0)] {
        let got = expm(&[lam * t, t, 0.0, lam * t], 2)?;
        let e = (lam * t).exp();
        assert_close(&format!("Jordan λ={lam} t={t}"), &got, &[e, t * e, 0.0, e], 1e-13, 0.0);
    }
    Ok(())
}

#[test]
fn exp_a_times_exp_minus_a_is_identity() -> Result<()> {
    for seed in 0..100 {
        let mut rng = Rng::new(seed);
        let n = rng.int(1, 10);
        // ‖A‖ from 0.01 to about 8 (both sides of the squaring threshold).
        let a = scale(&rng.normals(n, n), rng.range(0.01, 8.0) / (n as f64).sqrt());
        let e_plus = expm(&a, n)?;
        let e_minus = expm(&scale(&a, -1.0), n)?;
        let product = matmul(&e_plus, &e_minus, n, n, n);
        // Rounding in the product alone is of order n ε ‖e^A‖ ‖e^−A‖.
        let tol = 1e-14 * n as f64 * max_abs(&e_plus) * max_abs(&e_minus) * 10.0;
        let err = max_abs(&sub(&product, &eye(n)));
        assert!(err <= tol, "seed {seed} (n {n}): ‖e^A e^−A − I‖ = {err:e} > {tol:e}");
        // And A commutes with e^A.
        let (ae, ea) = (matmul(&a, &e_plus, n, n, n), matmul(&e_plus, &a, n, n, n));
        let err = max_abs(&sub(&ae, &ea));
        assert!(err <= 1e-13 * n as f64 * max_abs(&ae).max(1.0), "seed {seed}: ‖A e^A − e^A A‖ = {err:e}");
    }
    Ok(())
}

#[test]
fn bad_input_is_an_error() {
    for (what, a, n, needle) in [
        ("NaN", vec![1.0, f64::NAN, 0.0, 1.0], 2, "non-finite"),
        ("inf", vec![f64::INFINITY], 1, "non-finite"),
        ("wrong size", vec![1.0, 2.0, 3.0], 2, "expected an (2, 2) matrix"),
    ] {
        match expm(&a, n) {
            Err(err @ Error::InvalidArgument { arg: "a", step: None, .. }) => {
                assert!(err.to_string().contains(needle), "{what}: {err}");
            }
            other => panic!("{what}: expected InvalidArgument on a, got {other:?}"),
        }
    }
}

#[test]
fn large_norm_nilpotent_and_triangular_are_exact() -> Result<()> {
    // Issue #10: ‖A‖₁ = 1e20 gave zeros (64 squarings of r13), 1e12 a relative error of 3e-5.
    for x in [1e8, 1e12, 1e15, 1e20, 1e300] {
        assert_eq!(expm(&[0.0, x, 0.0, 0.0], 2)?, vec![1.0, x, 0.0, 1.0], "[[0, {x:e}], [0, 0]]");
        assert_eq!(expm(&[0.0, 0.0, x, 0.0], 2)?, vec![1.0, 0.0, x, 1.0], "[[0, 0], [{x:e}, 0]]");
    }
    // exp([[a, b], [0, c]]) = [[e^a, b (e^c − e^a)/(c − a)], [0, e^c]]
    let (a, b, c) = (-1.0f64, 1e15, -2.0f64);
    let got = expm(&[a, b, 0.0, c], 2)?;
    assert_close("triangular", &got, &[a.exp(), b * (c.exp() - a.exp()) / (c - a), 0.0, c.exp()], 1e-15, 0.0);
    Ok(())
}

#[test]
fn overflow_is_an_error_on_a() {
    // Issue #10: diag(1e5, −1e5) was all NaN (SciPy: [[inf, 0], [0, 0]]).
    for (a, n) in [(vec![1e5, 0.0, 0.0, -1e5], 2), (vec![710.0], 1), (vec![1.7e308; 4], 2)] {
        match expm(&a, n) {
            Err(err @ Error::InvalidArgument { arg: "a", step: None, .. }) => {
                assert!(err.to_string().starts_with("a: e^a overflows double precision"), "{err}");
            }
            other => panic!("{a:?}: expected InvalidArgument on a, got {other:?}"),
        }
    }
    // Underflow is no error.
    assert_eq!(expm(&[-1e5, 0.0, 0.0, -1e300], 2), Ok(vec![0.0; 4]));
}

#[test]
fn discretize_long_intervals_and_overflow() -> Result<()> {
    // Ornstein–Uhlenbeck, Qc = 2: F = e^−dt, Qd = 1 − e^−2dt, also where e^{+dt} overflows.
    for dt in [1.0, 800.0, 1e300] {
        let d = kfast::discretize(&[-1.0], &[2.0], Some(&[1.0]), 1, 1, dt)?;
        assert_close(&format!("F, dt {dt}"), &d.f, &[(-dt).exp()], 1e-15 * dt.min(1e3), 1e-300);
        assert_close(&format!("Qd, dt {dt}"), &d.qd, &[-(-2.0 * dt).exp_m1()], 1e-14, 0.0);
        assert_close(&format!("Bd, dt {dt}"), &d.bd, &[-(-dt).exp_m1()], 1e-14, 0.0);
    }
    // Constant velocity at dt = 1e300: Qd = dt³/3 overflows: an error naming dt.
    let (a, qc) = ([0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]);
    match kfast::discretize(&a, &qc, None, 2, 0, 1e300) {
        Err(Error::InvalidArgument { arg: "dt", step: None, problem }) => {
            assert!(problem.contains("overflows"), "{problem}")
        }
        other => panic!("expected an error on dt, got {other:?}"),
    }
    match kfast::discretize_steps(&a, &qc, None, 2, 0, &[0.1, 1e300]) {
        Err(Error::InvalidArgument { arg: "dt", step: Some(1), .. }) => {}
        other => panic!("expected an error on dt at step 1, got {other:?}"),
    }
    assert!(matches!(kfast::discretize_steps(&a, &qc, None, 2, 0, &[]), Err(Error::InvalidArgument { arg: "dt", .. })));
    Ok(())
}

#[test]
fn discretize_rejects_an_indefinite_intensity() {
    // Issue #10: a non-PSD Qc gave a non-PSD Qd (and the model then blamed "Q").
    match kfast::discretize(&[0.0, 0.0, 0.0, 0.0], &[1.0, 0.0, 0.0, -1.0], None, 2, 0, 0.1) {
        Err(err @ Error::InvalidArgument { arg: "Qc", .. }) => {
            assert!(err.to_string().contains("not positive semidefinite"), "{err}")
        }
        other => panic!("expected an error on Qc, got {other:?}"),
    }
}
