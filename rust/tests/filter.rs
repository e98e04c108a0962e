//! Integration tests of the Kalman filter through the public API: textbook cases, the
//! streaming filter against the batch one, the two update forms, the log-likelihood and the
//! errors returned on bad input.
//!
//! Textbook values are from T. Söderström, *Discrete-time Stochastic Systems: Estimation and
//! Control*, 2nd ed., Springer 2002: Example 6.2 (case A3) and Example 6.17 (case B1).

use std::sync::Arc;

use kfast::{filter, loglik, Error, KalmanFilter, LinearGaussian, Matrices, Series, StepMatrix, UpdateForm};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// A constant `rows × cols` matrix from row-major data.
fn mat(rows: usize, cols: usize, data: &[f64]) -> StepMatrix {
    StepMatrix::constant(rows, cols, data.to_vec()).unwrap()
}

/// A constant 1 × 1 matrix.
fn scalar(v: f64) -> StepMatrix {
    mat(1, 1, &[v])
}

/// A scalar model `x[t+1] = f x[t] + w`, `y = h x + v`, `Var w = q`, `Var v = r`.
fn scalar_model(f: f64, h: f64, q: f64, r: f64) -> LinearGaussian {
    LinearGaussian::new(Matrices::new(scalar(f), scalar(h), scalar(q), scalar(r))).unwrap()
}

/// `|a − b| ≤ tol` elementwise (NaN matches NaN).
fn assert_close(what: &str, got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let ok = (g.is_nan() && w.is_nan()) || (g - w).abs() <= tol;
        assert!(ok, "{what}[{i}]: got {g}, want {w} (tol {tol})");
    }
}

/// `|a − b| ≤ rtol · |b|` elementwise.
fn assert_rel(what: &str, got: &[f64], want: &[f64], rtol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= rtol * w.abs(), "{what}[{i}]: got {g}, want {w} (rtol {rtol})");
    }
}

/// Unwraps an [`Error::InvalidArgument`] into `(arg, step)`.
fn invalid_arg(err: &Error) -> (&'static str, Option<usize>) {
    match err {
        Error::InvalidArgument { arg, step, .. } => (arg, *step),
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
}

/// Three states, two outputs, two inputs through B and D, correlated noises (N ≠ 0).
fn model_3x2(with_n: bool) -> LinearGaussian {
    #[rustfmt::skip]
    let mats = Matrices {
        b: Some(mat(3, 2, &[
            1.0, 0.0,
            0.5, 0.2,
            0.0, -0.3,
        ])),
        d: Some(mat(2, 2, &[
            0.1, 0.0,
            0.0, 0.2,
        ])),
        n: with_n.then(|| mat(3, 2, &[
            0.05, 0.00,
            0.00, 0.04,
            0.02, 0.01,
        ])),
        ..Matrices::new(
            mat(3, 3, &[
                0.9, 0.1, 0.0,
                0.0, 0.8, 0.2,
                0.1, 0.0, 0.7,
            ]),
            mat(2, 3, &[
                1.0, 0.0, 0.5,
                0.0, 1.0, -0.3,
            ]),
            mat(3, 3, &[
                0.50, 0.10, 0.00,
                0.10, 0.40, 0.05,
                0.00, 0.05, 0.30,
            ]),
            mat(2, 2, &[
                0.20, 0.05,
                0.05, 0.30,
            ]),
        )
    };
    LinearGaussian::new(mats).unwrap()
}

const T3: usize = 8;
const X0_3: [f64; 3] = [0.5, -0.2, 0.1];
#[rustfmt::skip]
const P0_3: [f64; 9] = [
    1.0, 0.2, 0.0,
    0.2, 0.8, 0.1,
    0.0, 0.1, 0.6,
];

/// Observations (8 × 2) with a missing component at steps 2 and 6 and all of step 4 missing.
#[rustfmt::skip]
fn y_3x2_missing() -> Vec<f64> {
    let nan = f64::NAN;
    vec![
        0.3, -0.1,
        0.7, 0.2,
        nan, 0.4,
        -0.2, 0.1,
        nan, nan,
        0.5, -0.6,
        1.1, nan,
        0.9, 0.3,
    ]
}

/// Observations (8 × 2), all present.
fn y_3x2_full() -> Vec<f64> {
    y_3x2_missing().iter().enumerate().map(|(i, v)| if v.is_nan() { 0.1 * i as f64 - 0.4 } else { *v }).collect()
}

/// Inputs (8 × 2).
fn u_3x2() -> Vec<f64> {
    (0..T3 * 2).map(|i| ((i as f64) * 0.7).sin()).collect()
}

// ---------------------------------------------------------------------------------------------
// 1. Söderström Example 6.17 (case B1): the stationary filter
// ---------------------------------------------------------------------------------------------

#[test]
fn soderstrom_b1_stationary_scalar_filter() {
    // F = 0.8, H = 1, Q = 0.68, R = 1; P = 1 solves the Riccati equation, so from P0 = 1 every
    // step has P(t|t−1) = 1, S = 2, K = 1/2, P(t|t) = 1/2 and K_pred = F K = 0.4.
    let model = scalar_model(0.8, 1.0, 0.68, 1.0);
    let y = [0.3, -0.1, 0.7, 1.2, -0.5, 0.0, 0.25, -0.8];
    let steps = y.len();
    for form in [UpdateForm::Joseph, UpdateForm::Standard] {
        let res = filter(&model, Series::new("y", &y, steps, 1).unwrap(), None, &[0.0], &[1.0], form).unwrap();
        assert_close("P_pred", &res.p_pred, &vec![1.0; steps], 1e-12);
        assert_close("K_pred", &res.gain_pred, &vec![0.4; steps], 1e-12);
        assert_close("K", &res.gain, &vec![0.5; steps], 1e-12);
        assert_close("S", &res.innovation_cov, &vec![2.0; steps], 1e-12);
        assert_close("P_filt", &res.p_filt, &vec![0.5; steps], 1e-12);
        assert_close("P_next", &res.p_next, &[1.0], 1e-12);
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Söderström Example 6.2 (case A3): the transient from P0 = 1 with Q = 0
// ---------------------------------------------------------------------------------------------

#[test]
fn soderstrom_a3_transient_scalar_filter() {
    // Söderström (2002), Example 6.2, case A3: F = 0.9, H = 1, Q = 0, R = 0.04, P0 = 1.
    let model = scalar_model(0.9, 1.0, 0.0, 0.04);
    let y = [0.1, -0.3, 0.2, 0.05, 0.4, -0.1, 0.0, 0.3];
    let p_pred = [1.0, 0.0311538, 0.0141859, 0.00848236, 0.00566863, 0.00402166, 0.00295994, 0.00223236];
    let k_pred = [0.865385, 0.394054, 0.235621, 0.157462, 0.111713, 0.0822207, 0.0620101, 0.0475732];
    for form in [UpdateForm::Joseph, UpdateForm::Standard] {
        let res = filter(&model, Series::new("y", &y, 8, 1).unwrap(), None, &[0.0], &[1.0], form).unwrap();
        assert_rel("P_pred", &res.p_pred, &p_pred, 1e-5);
        assert_rel("K_pred", &res.gain_pred, &k_pred, 1e-5);
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Streaming KalmanFilter = batch filter
// ---------------------------------------------------------------------------------------------

/// Runs the streaming filter over `y`, `u` and checks every intermediate state against `filter`.
/// With `skip_missing_rows`, a step with nothing observed calls only `predict` (no `update`).
fn check_stream_matches_batch(form: UpdateForm, skip_missing_rows: bool) {
    const TOL: f64 = 1e-14;
    let model = Arc::new(model_3x2(true));
    let (n, m, k) = (3, 2, 2);
    let (y, u) = (y_3x2_missing(), u_3x2());
    let res = filter(
        &model,
        Series::new("y", &y, T3, m).unwrap(),
        Some(Series::new("u", &u, T3, k).unwrap()),
        &X0_3,
        &P0_3,
        form,
    )
    .unwrap();

    let mut kf = KalmanFilter::new(Arc::clone(&model), &X0_3, &P0_3, form).unwrap();
    for t in 0..T3 {
        let (y_t, u_t) = (&y[t * m..(t + 1) * m], &u[t * k..(t + 1) * k]);
        assert_eq!(kf.t(), t);
        assert_close(&format!("x_pred at {t}"), kf.x(), &res.x_pred[t * n..(t + 1) * n], TOL);
        assert_close(&format!("P_pred at {t}"), kf.p(), &res.p_pred[t * n * n..(t + 1) * n * n], TOL);
        if !(skip_missing_rows && y_t.iter().all(|v| v.is_nan())) {
            kf.update(y_t, Some(u_t)).unwrap();
        }
        assert_close(&format!("x_filt at {t}"), kf.x(), &res.x_filt[t * n..(t + 1) * n], TOL);
        assert_close(&format!("P_filt at {t}"), kf.p(), &res.p_filt[t * n * n..(t + 1) * n * n], TOL);
        kf.predict(Some(u_t)).unwrap();
    }
    assert_eq!(kf.t(), T3);
    assert_close("x_next", kf.x(), &res.x_next, TOL);
    assert_close("P_next", kf.p(), &res.p_next, TOL);
    assert_close("loglik", &[kf.loglik()], &[res.loglik], TOL * res.loglik.abs().max(1.0));
}

#[test]
fn streaming_equals_batch_joseph() {
    check_stream_matches_batch(UpdateForm::Joseph, false);
}

#[test]
fn streaming_equals_batch_standard() {
    check_stream_matches_batch(UpdateForm::Standard, false);
}

#[test]
fn streaming_predict_without_update_equals_all_nan_row() {
    check_stream_matches_batch(UpdateForm::Joseph, true);
}

#[test]
fn streaming_step_equals_update_then_predict() {
    let model = Arc::new(model_3x2(true));
    let (y, u) = (y_3x2_missing(), u_3x2());
    let mut a = KalmanFilter::new(Arc::clone(&model), &X0_3, &P0_3, UpdateForm::Joseph).unwrap();
    let mut b = a.clone();
    for t in 0..T3 {
        let (y_t, u_t) = (&y[t * 2..(t + 1) * 2], &u[t * 2..(t + 1) * 2]);
        a.step(y_t, Some(u_t)).unwrap();
        b.update(y_t, Some(u_t)).unwrap();
        b.predict(Some(u_t)).unwrap();
        assert_eq!(a.x(), b.x());
        assert_eq!(a.p(), b.p());
    }
    assert_eq!(a.loglik(), b.loglik());
}

#[test]
fn missing_components_are_reported_as_such() {
    let model = model_3x2(true);
    let (y, u) = (y_3x2_missing(), u_3x2());
    let res = filter(
        &model,
        Series::new("y", &y, T3, 2).unwrap(),
        Some(Series::new("u", &u, T3, 2).unwrap()),
        &X0_3,
        &P0_3,
        UpdateForm::Joseph,
    )
    .unwrap();
    let (n, m) = (3, 2);
    // Step 4: nothing observed — no update, no likelihood term, NaN innovations, zero gains.
    let t = 4;
    assert!(res.innov[t * m..(t + 1) * m].iter().all(|e| e.is_nan()));
    assert_eq!(res.loglik_t[t], 0.0);
    assert!(res.gain[t * n * m..(t + 1) * n * m].iter().all(|&g| g == 0.0));
    assert!(res.gain_pred[t * n * m..(t + 1) * n * m].iter().all(|&g| g == 0.0));
    assert_eq!(res.x_filt[t * n..(t + 1) * n], res.x_pred[t * n..(t + 1) * n]);
    assert_eq!(res.p_filt[t * n * n..(t + 1) * n * n], res.p_pred[t * n * n..(t + 1) * n * n]);
    // Step 2: component 0 missing — its innovation is NaN and its gain column zero.
    let t = 2;
    assert!(res.innov[t * m].is_nan() && res.innov[t * m + 1].is_finite());
    for r in 0..n {
        assert_eq!(res.gain[t * n * m + r * m], 0.0);
        assert_ne!(res.gain[t * n * m + r * m + 1], 0.0);
    }
    assert!(res.loglik_t.iter().enumerate().all(|(t, l)| t == 4 || *l != 0.0));
}

// ---------------------------------------------------------------------------------------------
// 3b. Batch filter against an independent reference: plain Gaussian conditioning
// ---------------------------------------------------------------------------------------------

/// `a[r×k] · b[k×c]`.
fn matmul(a: &[f64], b: &[f64], r: usize, k: usize, c: usize) -> Vec<f64> {
    let mut out = vec![0.0; r * c];
    for i in 0..r {
        for j in 0..c {
            out[i * c + j] = (0..k).map(|l| a[i * k + l] * b[l * c + j]).sum();
        }
    }
    out
}

/// `a[r×c]'`.
fn transposed(a: &[f64], r: usize, c: usize) -> Vec<f64> {
    let mut out = vec![0.0; r * c];
    for i in 0..r {
        for j in 0..c {
            out[j * r + i] = a[i * c + j];
        }
    }
    out
}

/// Inverse and determinant of a 1 × 1 or 2 × 2 matrix.
fn inv_det_small(s: &[f64], k: usize) -> (Vec<f64>, f64) {
    match k {
        1 => (vec![1.0 / s[0]], s[0]),
        2 => {
            let det = s[0] * s[3] - s[1] * s[2];
            (vec![s[3] / det, -s[1] / det, -s[2] / det, s[0] / det], det)
        }
        _ => unreachable!("the reference handles m ≤ 2"),
    }
}

/// The filter as textbook Gaussian conditioning, sharing no code with kfast: at each step
/// `z = [x; w; v] ~ N([x̂; 0; 0], [[P, 0, 0], [0, Q, N], [0, N', R]])` is conditioned on the
/// observed `y_o = A z + D_o u` with `A = [H_o, 0, I_o]`, and `x[t+1] = [F, I, 0] z + B u`.
/// Returns `(x_filt, P_filt, x_next, P_next, K, K_pred, loglik_t)` concatenated over steps.
#[allow(clippy::type_complexity)]
fn reference_filter(
    model: &LinearGaussian,
    y: &[f64],
    u: &[f64],
    steps: usize,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let (n, m, k) = (model.n_states(), model.n_obs(), model.n_inputs());
    let mats = model.matrices();
    let (f, h, q, r) = (mats.f.at(0), mats.h.at(0), mats.q.at(0), mats.r.at(0));
    let (b, d, nn) = (mats.b.as_ref().unwrap().at(0), mats.d.as_ref().unwrap().at(0), mats.n.as_ref().unwrap().at(0));
    let nz = 2 * n + m;
    let (mut x, mut p) = (X0_3.to_vec(), P0_3.to_vec());
    let mut outs: [Vec<f64>; 7] = Default::default();
    for t in 0..steps {
        let (y_t, u_t) = (&y[t * m..(t + 1) * m], &u[t * k..(t + 1) * k]);
        let mut mz = vec![0.0; nz];
        mz[..n].copy_from_slice(&x);
        let mut c = vec![0.0; nz * nz];
        for i in 0..n {
            for j in 0..n {
                c[i * nz + j] = p[i * n + j];
                c[(n + i) * nz + n + j] = q[i * n + j];
            }
            for j in 0..m {
                c[(n + i) * nz + 2 * n + j] = nn[i * m + j];
                c[(2 * n + j) * nz + n + i] = nn[i * m + j];
            }
        }
        for i in 0..m {
            for j in 0..m {
                c[(2 * n + i) * nz + 2 * n + j] = r[i * m + j];
            }
        }
        let obs: Vec<usize> = (0..m).filter(|&i| !y_t[i].is_nan()).collect();
        let mo = obs.len();
        let mut a = vec![0.0; mo * nz];
        let mut e = vec![0.0; mo];
        for (row, &i) in obs.iter().enumerate() {
            a[row * nz..row * nz + n].copy_from_slice(&h[i * n..(i + 1) * n]);
            a[row * nz + 2 * n + i] = 1.0;
            let pred: f64 =
                (0..n).map(|j| h[i * n + j] * x[j]).sum::<f64>() + (0..k).map(|j| d[i * k + j] * u_t[j]).sum::<f64>();
            e[row] = y_t[i] - pred;
        }
        let (mut k_full, mut kp_full) = (vec![0.0; n * m], vec![0.0; n * m]);
        let mut ll = 0.0;
        if mo > 0 {
            let cat = matmul(&c, &transposed(&a, mo, nz), nz, nz, mo);
            let s = matmul(&a, &cat, mo, nz, mo);
            let (s_inv, det) = inv_det_small(&s, mo);
            let g = matmul(&cat, &s_inv, nz, mo, mo);
            let ge = matmul(&g, &e, nz, mo, 1);
            let quad: f64 = matmul(&e, &matmul(&s_inv, &e, mo, mo, 1), 1, mo, 1)[0];
            ll = -0.5 * (mo as f64 * (2.0 * std::f64::consts::PI).ln() + det.ln() + quad);
            let gsg = matmul(&g, &matmul(&s, &transposed(&g, nz, mo), mo, mo, nz), nz, mo, nz);
            for (mzi, gei) in mz.iter_mut().zip(&ge) {
                *mzi += gei;
            }
            for (ci, v) in c.iter_mut().zip(&gsg) {
                *ci -= v;
            }
            for (col, &i) in obs.iter().enumerate() {
                for row in 0..n {
                    k_full[row * m + i] = g[row * mo + col];
                    kp_full[row * m + i] =
                        (0..n).map(|j| f[row * n + j] * g[j * mo + col]).sum::<f64>() + g[(n + row) * mo + col];
                }
            }
        }
        outs[0].extend_from_slice(&mz[..n]);
        outs[1].extend((0..n * n).map(|ij| c[(ij / n) * nz + ij % n]));
        outs[4].extend_from_slice(&k_full);
        outs[5].extend_from_slice(&kp_full);
        outs[6].push(ll);
        // x[t+1] = T z + B u with T = [F, I, 0].
        let mut tm = vec![0.0; n * nz];
        for i in 0..n {
            tm[i * nz..i * nz + n].copy_from_slice(&f[i * n..(i + 1) * n]);
            tm[i * nz + n + i] = 1.0;
        }
        x = matmul(&tm, &mz, n, nz, 1);
        for (xi, bu) in x.iter_mut().zip(matmul(b, u_t, n, k, 1)) {
            *xi += bu;
        }
        p = matmul(&tm, &matmul(&c, &transposed(&tm, n, nz), nz, nz, n), n, nz, n);
    }
    outs[2] = x;
    outs[3] = p;
    let [a, b, c, d, e, f, g] = outs;
    (a, b, c, d, e, f, g)
}

#[test]
fn batch_filter_matches_gaussian_conditioning_reference() {
    let model = model_3x2(true);
    let u = u_3x2();
    for y in [y_3x2_full(), y_3x2_missing()] {
        let (x_filt, p_filt, x_next, p_next, gain, gain_pred, loglik_t) = reference_filter(&model, &y, &u, T3);
        for form in ALL_FORMS {
            let res = filter(
                &model,
                Series::new("y", &y, T3, 2).unwrap(),
                Some(Series::new("u", &u, T3, 2).unwrap()),
                &X0_3,
                &P0_3,
                form,
            )
            .unwrap();
            let tol = 1e-12;
            assert_close("x_filt", &res.x_filt, &x_filt, tol);
            assert_close("P_filt", &res.p_filt, &p_filt, tol);
            assert_close("x_next", &res.x_next, &x_next, tol);
            assert_close("P_next", &res.p_next, &p_next, tol);
            assert_close("K", &res.gain, &gain, tol);
            assert_close("K_pred", &res.gain_pred, &gain_pred, tol);
            assert_close("loglik_t", &res.loglik_t, &loglik_t, tol);
        }
    }
}

/// Every update form: the covariance forms and the robust ones of `linear::filter::forms`.
const ALL_FORMS: [UpdateForm; 6] = [
    UpdateForm::Joseph,
    UpdateForm::Standard,
    UpdateForm::SquareRoot,
    UpdateForm::UD,
    UpdateForm::Information,
    UpdateForm::Sequential,
];

// ---------------------------------------------------------------------------------------------
// 4. Joseph and standard forms agree on a well-conditioned model
// ---------------------------------------------------------------------------------------------

#[test]
fn joseph_and_standard_forms_agree() {
    for (with_n, y) in [(false, y_3x2_full()), (true, y_3x2_full()), (true, y_3x2_missing())] {
        let model = model_3x2(with_n);
        let u = u_3x2();
        let run = |form| {
            filter(
                &model,
                Series::new("y", &y, T3, 2).unwrap(),
                Some(Series::new("u", &u, T3, 2).unwrap()),
                &X0_3,
                &P0_3,
                form,
            )
            .unwrap()
        };
        let (j, s) = (run(UpdateForm::Joseph), run(UpdateForm::Standard));
        let tol = 1e-10;
        assert_close("x_pred", &j.x_pred, &s.x_pred, tol);
        assert_close("P_pred", &j.p_pred, &s.p_pred, tol);
        assert_close("x_filt", &j.x_filt, &s.x_filt, tol);
        assert_close("P_filt", &j.p_filt, &s.p_filt, tol);
        assert_close("innov", &j.innov, &s.innov, tol);
        assert_close("S", &j.innovation_cov, &s.innovation_cov, tol);
        assert_close("K", &j.gain, &s.gain, tol);
        assert_close("K_pred", &j.gain_pred, &s.gain_pred, tol);
        assert_close("loglik_t", &j.loglik_t, &s.loglik_t, tol);
        assert_close("loglik", &[j.loglik], &[s.loglik], tol);
        assert_close("x_next", &j.x_next, &s.x_next, tol);
        assert_close("P_next", &j.p_next, &s.p_next, tol);
    }
}

// ---------------------------------------------------------------------------------------------
// 5. loglik
// ---------------------------------------------------------------------------------------------

#[test]
fn loglik_equals_filter_loglik_and_sum_of_terms() {
    let u = u_3x2();
    for (with_n, y) in [(false, y_3x2_full()), (true, y_3x2_missing())] {
        let model = model_3x2(with_n);
        for form in [UpdateForm::Joseph, UpdateForm::Standard] {
            let ys = Series::new("y", &y, T3, 2).unwrap();
            let us = Some(Series::new("u", &u, T3, 2).unwrap());
            let res = filter(&model, ys, us, &X0_3, &P0_3, form).unwrap();
            let ll = loglik(&model, ys, us, &X0_3, &P0_3, form).unwrap();
            assert!(ll.is_finite());
            assert_eq!(ll, res.loglik);
            let sum: f64 = res.loglik_t.iter().sum();
            assert_close("Σ loglik_t", &[sum], &[res.loglik], 1e-12 * res.loglik.abs().max(1.0));
        }
    }
}

#[test]
fn loglik_of_one_scalar_step_is_the_gaussian_density() {
    // y[0] ~ N(0, H P0 H' + R) = N(0, 2) in case B1.
    let model = scalar_model(0.8, 1.0, 0.68, 1.0);
    let y = [0.7];
    let ll = loglik(&model, Series::new("y", &y, 1, 1).unwrap(), None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap();
    let want = -0.5 * ((2.0 * std::f64::consts::PI * 2.0).ln() + 0.49 / 2.0);
    assert_close("loglik", &[ll], &[want], 1e-14);
}

// ---------------------------------------------------------------------------------------------
// 6. Errors are returned, not panics
// ---------------------------------------------------------------------------------------------

#[test]
fn h_with_wrong_column_count_is_invalid_argument() {
    let mats = Matrices::new(
        mat(2, 2, &[0.9, 0.0, 0.0, 0.8]),
        mat(1, 3, &[1.0, 0.0, 0.0]),
        mat(2, 2, &[1.0, 0.0, 0.0, 1.0]),
        scalar(1.0),
    );
    let err = LinearGaussian::new(mats).unwrap_err();
    assert_eq!(invalid_arg(&err), ("H", None));
    assert!(err.to_string().starts_with("H: "), "{err}");
}

#[test]
fn non_psd_q_in_per_step_stack_reports_its_step() {
    #[rustfmt::skip]
    let q = StepMatrix::per_step(4, 2, 2, vec![
        1.0, 0.0, 0.0, 1.0,
        1.0, 0.5, 0.5, 1.0,
        1.0, 0.0, 0.0, -0.5, // step 2: eigenvalue −0.5
        1.0, 0.0, 0.0, 1.0,
    ])
    .unwrap();
    let mats = Matrices::new(mat(2, 2, &[0.9, 0.0, 0.0, 0.8]), mat(1, 2, &[1.0, 0.0]), q, scalar(1.0));
    let err = LinearGaussian::new(mats).unwrap_err();
    assert_eq!(invalid_arg(&err), ("Q", Some(2)));
    let msg = err.to_string();
    assert!(msg.contains('Q') && msg.contains("step 2"), "{msg}");
}

#[test]
fn inf_in_y_reports_its_step() {
    let model = scalar_model(0.8, 1.0, 0.68, 1.0);
    let y = [0.1, 0.2, f64::NAN, 0.3, f64::INFINITY, 0.5];
    let ys = Series::new("y", &y, 6, 1).unwrap();
    for err in [
        filter(&model, ys, None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap_err(),
        loglik(&model, ys, None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap_err(),
    ] {
        assert_eq!(invalid_arg(&err), ("y", Some(4)));
        let msg = err.to_string();
        assert!(msg.contains('y') && msg.contains("step 4"), "{msg}");
    }
    // The streaming filter rejects it at the same step.
    let mut kf = KalmanFilter::new(Arc::new(model), &[0.0], &[1.0], UpdateForm::Joseph).unwrap();
    for y_t in &y[..4] {
        kf.step(&[*y_t], None).unwrap();
    }
    let err = kf.update(&[f64::NEG_INFINITY], None).unwrap_err();
    assert_eq!(invalid_arg(&err), ("y", Some(4)));
    assert!(err.to_string().contains("step 4"), "{err}");
}

#[test]
fn singular_innovation_covariance_is_an_error() {
    // R = 0, Q = 0, P0 = 0: S = H P0 H' + R = 0 at the very first step.
    let model = scalar_model(0.9, 1.0, 0.0, 0.0);
    let y = [0.1, 0.2, 0.3];
    let ys = Series::new("y", &y, 3, 1).unwrap();
    for form in [UpdateForm::Joseph, UpdateForm::Standard] {
        let err = filter(&model, ys, None, &[0.0], &[0.0], form).unwrap_err();
        assert!(matches!(err, Error::InnovationCovariance { step: 0, .. }), "{err:?}");
        assert!(err.to_string().contains("step 0"), "{err}");
        let err = loglik(&model, ys, None, &[0.0], &[0.0], form).unwrap_err();
        assert!(matches!(err, Error::InnovationCovariance { step: 0, .. }), "{err:?}");
    }
    let mut kf = KalmanFilter::new(Arc::new(model), &[0.0], &[0.0], UpdateForm::Joseph).unwrap();
    let err = kf.update(&[0.1], None).unwrap_err();
    assert!(matches!(err, Error::InnovationCovariance { step: 0, .. }), "{err:?}");
}

#[test]
fn singular_innovation_covariance_reports_a_later_step() {
    // R = 0, Q = 0, P0 = 1: y[0] determines x exactly, so P(1|0) = 0 and S(1) = 0.
    let model = scalar_model(1.0, 1.0, 0.0, 0.0);
    let y = [0.1, 0.2, 0.3];
    for form in [UpdateForm::Joseph, UpdateForm::Standard] {
        let err = filter(&model, Series::new("y", &y, 3, 1).unwrap(), None, &[0.0], &[1.0], form).unwrap_err();
        assert!(matches!(err, Error::InnovationCovariance { step: 1, .. }), "{err:?}");
        assert!(err.to_string().contains("step 1"), "{err}");
    }
}

#[test]
fn y_with_wrong_width_is_invalid_argument() {
    let model = scalar_model(0.8, 1.0, 0.68, 1.0);
    let y = [0.1, 0.2, 0.3, 0.4];
    let ys = Series::new("y", &y, 2, 2).unwrap();
    let err = filter(&model, ys, None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap_err();
    assert_eq!(invalid_arg(&err), ("y", None));
    assert!(err.to_string().starts_with("y: "), "{err}");
    let err = loglik(&model, ys, None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap_err();
    assert_eq!(invalid_arg(&err), ("y", None));
    // Streaming: a y of the wrong length at step 0.
    let mut kf = KalmanFilter::new(Arc::new(model), &[0.0], &[1.0], UpdateForm::Joseph).unwrap();
    let err = kf.update(&[0.1, 0.2], None).unwrap_err();
    assert_eq!(invalid_arg(&err), ("y", Some(0)));
    // A Series whose data does not fill (steps, width).
    let err = Series::new("y", &y, 3, 1).unwrap_err();
    assert_eq!(invalid_arg(&err), ("y", None));
}

#[test]
fn missing_u_for_a_model_with_b_is_invalid_argument() {
    let model = model_3x2(false);
    let y = y_3x2_full();
    let ys = Series::new("y", &y, T3, 2).unwrap();
    let err = filter(&model, ys, None, &X0_3, &P0_3, UpdateForm::Joseph).unwrap_err();
    assert_eq!(invalid_arg(&err), ("u", None));
    assert!(err.to_string().starts_with("u: "), "{err}");
    let err = loglik(&model, ys, None, &X0_3, &P0_3, UpdateForm::Joseph).unwrap_err();
    assert_eq!(invalid_arg(&err), ("u", None));
    // Streaming: update (D) and predict (B) both need u.
    let mut kf = KalmanFilter::new(Arc::new(model), &X0_3, &P0_3, UpdateForm::Joseph).unwrap();
    let err = kf.update(&y[..2], None).unwrap_err();
    assert_eq!(invalid_arg(&err), ("u", Some(0)));
    let err = kf.predict(None).unwrap_err();
    assert_eq!(invalid_arg(&err), ("u", Some(0)));
    assert!(err.to_string().contains("step 0"), "{err}");
}

#[test]
fn rts_into_accepts_zero_steps() {
    use kfast::linear::smoother::{rts_into, FilteredView, RtsOutputs};
    let model = scalar_model(0.8, 1.0, 0.68, 1.0);
    let view = FilteredView { x_pred: &[], p_pred: &[], x_filt: &[], p_filt: &[], gain: &[] };
    let out = RtsOutputs { x_smooth: &mut [], p_smooth: &mut [], p_lag1: &mut [] };
    assert!(rts_into(&model, 0, view, out).is_ok());
}

#[test]
fn diagnostics_of_the_true_model_stay_inside_their_bounds() {
    use kfast::linear::diagnostics::{innovation_diagnostics, state_diagnostics, DiagnosticOptions};
    // Söderström ex. 6.17's model, simulated: the innovations are white with variance S(t).
    let model = scalar_model(0.8, 1.0, 0.68, 1.0);
    let steps = 2000;
    let mut seed = 5u64;
    let mut normal = move || {
        // Box–Muller from a small LCG: enough for a seeded test.
        let mut uniform = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (u1, u2) = (uniform(), uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let (mut x, mut xs, mut y) = (normal(), Vec::new(), Vec::new());
    for _ in 0..steps {
        xs.push(x);
        y.push(x + normal());
        x = 0.8 * x + 0.68f64.sqrt() * normal();
    }
    let res =
        filter(&model, Series::new("y", &y, steps, 1).unwrap(), None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap();
    let options = DiagnosticOptions::default();
    let d = innovation_diagnostics(&res.innov, &res.innovation_cov, steps, 1, options).unwrap();
    assert!(d.nis_mean_bounds[0] < d.nis_mean && d.nis_mean < d.nis_mean_bounds[1], "{d:?}");
    assert!(d.ljung_box_pvalue[options.lags - 1] > 0.01 && d.jarque_bera_pvalue[0] > 0.01);
    assert!((d.standardized[7] - res.innov[7] / res.innovation_cov[7].sqrt()).abs() < 1e-14);
    let e = state_diagnostics(&xs, &res.x_filt, &res.p_filt, steps, 1, options).unwrap();
    assert!(e.nees_mean_bounds[0] < e.nees_mean && e.nees_mean < e.nees_mean_bounds[1]);
    // Bad input is an error naming the argument, never a panic.
    let short = innovation_diagnostics(&res.innov[1..], &res.innovation_cov, steps, 1, options).unwrap_err();
    assert_eq!(invalid_arg(&short).0, "innov");
    let lags = DiagnosticOptions { lags: steps, ..options };
    assert_eq!(
        invalid_arg(&innovation_diagnostics(&res.innov, &res.innovation_cov, steps, 1, lags).unwrap_err()).0,
        "lags"
    );
}

#[test]
fn exact_diffuse_start_of_a_local_level_is_koopmans_closed_form() {
    use kfast::filter_diffuse_into;
    // Koopman (1997): a random walk with unknown start. After y(0), x(1|0) = y(0) and
    // P(1|0) = R + Q exactly; the first log-likelihood term is −½ log 2π (F_∞ = 1).
    let (q, r) = (8.253, 1.993);
    let model = scalar_model(1.0, 1.0, q, r);
    let y = [10.2394, 1.0, 1.0];
    // Buffers of the right sizes: any filter result of the same shape.
    let mut res =
        filter(&model, Series::new("y", &y, 3, 1).unwrap(), None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap();
    let mut p_inf = vec![0.0; 3];
    let (loglik, diffuse) = filter_diffuse_into(
        &model,
        Series::new("y", &y, 3, 1).unwrap(),
        None,
        &[0.0],
        &[0.0],
        &[1.0],
        UpdateForm::Joseph,
        res.outputs(),
        Some(&mut p_inf),
    )
    .unwrap();
    assert_eq!(diffuse, 1);
    assert_eq!(p_inf, [1.0, 0.0, 0.0]);
    assert_close("x_pred", &res.x_pred[1..2], &[10.2394], 1e-14);
    assert_close("P_pred", &res.p_pred[1..2], &[q + r], 1e-14);
    assert_close("loglik_t", &res.loglik_t[..1], &[-0.5 * (2.0 * std::f64::consts::PI).ln()], 1e-14);
    assert!((loglik - res.loglik_t.iter().sum::<f64>()).abs() < 1e-12);
    // A diffuse part that is not a covariance is refused by name.
    let bad = filter_diffuse_into(
        &model,
        Series::new("y", &y, 3, 1).unwrap(),
        None,
        &[0.0],
        &[0.0],
        &[-1.0],
        UpdateForm::Joseph,
        res.outputs(),
        None,
    );
    assert_eq!(invalid_arg(&bad.unwrap_err()).0, "P0_inf");
}
