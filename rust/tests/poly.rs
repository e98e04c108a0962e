//! Integration tests of the polynomial toolbox (`kfast::poly`): the spectral factor of
//! Mortensen's FIR spectrum (1 − 0.6 z⁻¹ + 0.25 z⁻², λ² = 1) and of a double zero on the unit
//! circle (Lemma 4.6); Söderström Example 7.1's predictor identity; the Diophantine identity on
//! seeded random polynomials (checked by multiplying out here); Levinson's Toeplitz solve on
//! autocovariances (checked by the residual, order by order); bad input.

mod common;

use common::Rng;
use kfast::poly::{diophantine, from_roots, levinson, predictor_identity, roots, spectral_factor};

fn mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

fn add_aligned(a: &[f64], b: &[f64]) -> Vec<f64> {
    let n = a.len().max(b.len());
    let pad = |p: &[f64]| -> Vec<f64> { std::iter::repeat_n(0.0, n - p.len()).chain(p.iter().copied()).collect() };
    pad(a).iter().zip(pad(b)).map(|(x, y)| x + y).collect()
}

#[test]
fn spectral_factors_of_textbook_spectra() {
    let f = spectral_factor(&[0.25, -0.75, 1.4225, -0.75, 0.25]).unwrap();
    for (got, want) in f.b.iter().zip([1.0, -0.6, 0.25]) {
        assert!((got - want).abs() < 1e-12, "{:?}", f.b);
    }
    assert!((f.lam2 - 1.0).abs() < 1e-12 && !f.on_circle);
    // (1 + cos ω): 0.5 z + 1 + 0.5 z⁻¹ = 0.5 (z + 1)(1 + z⁻¹): a double zero at -1.
    let g = spectral_factor(&[0.5, 1.0, 0.5]).unwrap();
    assert!(g.on_circle && (g.b[1] - 1.0).abs() < 1e-7 && (g.lam2 - 0.5).abs() < 1e-7, "{g:?}");
}

#[test]
fn roots_and_back() {
    let p = from_roots(&[(0.5, 0.0), (0.3, 0.4), (0.3, -0.4)]);
    let z = roots(&p).unwrap();
    let mut moduli: Vec<f64> = z.iter().map(|(re, im)| re.hypot(*im)).collect();
    moduli.sort_by(f64::total_cmp);
    assert!((moduli[0] - 0.5).abs() < 1e-12 && (moduli[2] - 0.5).abs() < 1e-12);
    assert_eq!(roots(&[0.0, 2.0]).unwrap(), vec![]);
}

#[test]
fn soderstrom_example_7_1_predictor_identity() {
    // z C = A F + L with A = z - 0.8, C = z + 0.5 (the invertible form), k = 2.
    let (f, l) = predictor_identity(&[1.0, -0.8], &[1.0, 0.5], 2).unwrap();
    assert!((f[0] - 1.0).abs() < 1e-15 && (f[1] - 1.3).abs() < 1e-12 && (l[0] - 1.04).abs() < 1e-12, "{f:?} {l:?}");
}

#[test]
fn diophantine_identity_on_random_polynomials() {
    let mut rng = Rng::new(3);
    for _ in 0..20 {
        let a: Vec<f64> = std::iter::once(1.0).chain((0..rng.int(0, 5)).map(|_| rng.normal())).collect();
        let b: Vec<f64> = (0..rng.int(1, 5)).map(|_| rng.normal()).collect();
        let c: Vec<f64> = (0..rng.int(1, 9)).map(|_| rng.normal()).collect();
        let d = diophantine(&a, &b, &c).unwrap();
        let lhs = add_aligned(&mul(&a, &d.x), &mul(&b, &d.y));
        let want = add_aligned(&c, &vec![0.0; lhs.len()]);
        let scale = d.condition.max(1.0);
        for (x, y) in lhs.iter().zip(&want) {
            assert!((x - y).abs() < 1e-10 * scale, "{lhs:?} vs {want:?}");
        }
    }
}

#[test]
fn levinson_solves_every_order() {
    let mut rng = Rng::new(11);
    // Autocovariance of an ARMA(2, 1) process, computed from its impulse response.
    let mut h = vec![1.0, 0.0];
    h[1] = 1.2 - 0.4;
    for j in 2..400 {
        let v = 1.2 * h[j - 1] - 0.5 * h[j - 2];
        h.push(v);
    }
    let r: Vec<f64> = (0..30).map(|k| h.iter().zip(&h[k..]).map(|(a, b)| a * b).sum()).collect();
    let b: Vec<f64> = (0..30).map(|_| rng.normal()).collect();
    let sol = levinson(&r, &b).unwrap();
    for order in 0..30 {
        // The solution of order k, by solving again with b truncated: T_k x_k = b[..=k].
        let xk = levinson(&r, &b[..=order]).unwrap().x;
        for (i, bi) in b[..=order].iter().enumerate() {
            let row: f64 = xk.iter().enumerate().map(|(j, xj)| r[i.abs_diff(j)] * xj).sum();
            assert!((row - bi).abs() < 1e-9 * (1.0 + bi.abs()), "order {order}, row {i}");
        }
        let q: f64 = xk.iter().zip(&b).map(|(x, b)| x * b).sum();
        assert!((q - sol.quadratic[order]).abs() < 1e-10 * q.abs().max(1.0), "quadratic at {order}");
    }
    assert_eq!(sol.x, levinson(&r, &b).unwrap().x);
}

#[test]
fn bad_input() {
    let msg = |e: kfast::Error| e.to_string();
    assert!(msg(spectral_factor(&[1.0, 0.0, 1.0]).unwrap_err())
        .starts_with("r: the spectrum is negative on the unit circle"));
    assert!(msg(spectral_factor(&[1.0, 2.0]).unwrap_err()).starts_with("r: a symmetric Laurent polynomial"));
    assert!(msg(spectral_factor(&[1.0, 3.0, 2.0]).unwrap_err()).starts_with("r: must be symmetric"));
    let common = diophantine(&mul(&[1.0, -0.5], &[1.0, 0.3]), &mul(&[1.0, -0.5], &[1.0, 2.0]), &[1.0, 0.0, 0.0, 0.0]);
    assert!(msg(common.unwrap_err()).starts_with("A, B: have a common factor"));
    assert!(msg(predictor_identity(&[2.0, 1.0], &[1.0, 0.0], 1).unwrap_err()).starts_with("A: must be monic"));
    assert!(msg(predictor_identity(&[1.0, 1.0], &[1.0, 0.0], 0).unwrap_err()).starts_with("k: "));
    assert!(msg(roots(&[f64::NAN, 1.0]).unwrap_err()).starts_with("p: contains a non-finite"));
    let singular = levinson(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).unwrap_err();
    assert_eq!(msg(singular), "r: the Toeplitz matrix is not positive definite at order 1");
    assert!(msg(levinson(&[1.0], &[1.0, 2.0]).unwrap_err()).starts_with("r: has 1 lags"));
}
