//! Integration tests of the nonlinear filters through the public API: on a linear model
//! (f and h linear maps) the EKF, the iterated EKF and the UKF with every sigma-point set are
//! the Kalman filter; the errors name what failed and the step; `ekf_batch` and `ukf_batch`
//! give each series the results of filtering it alone; the particle filter approaches the
//! Kalman filter as its particles grow and gives the same bits on any number of threads.

use std::sync::Arc;

use kfast::nonlinear::{particle_filter, MeasurementLikelihood, ParticleFunction, ParticleOptions, Resampling};
use kfast::nonlinear::{ConstantMap, LinearMap};
use kfast::{
    ekf_batch, ekf_into, filter, ukf_batch, ukf_into, Batch, BatchOutputs, EkfOptions, Error, FilterOutputs,
    FilterResult, Iteration, LinearGaussian, Matrices, NonlinearModel, Series, SigmaPoints, StepMatrix, UpdateForm,
};

const F: [f64; 9] = [0.9, 0.1, 0.0, -0.2, 0.8, 0.3, 0.0, 0.1, 0.7];
const H: [f64; 6] = [1.0, 0.0, 0.5, 0.0, 1.0, -1.0];
const Q: [f64; 9] = [0.3, 0.1, 0.0, 0.1, 0.2, 0.05, 0.0, 0.05, 0.4];
const R: [f64; 4] = [0.5, 0.1, 0.1, 0.6];
const X0: [f64; 3] = [1.0, -1.0, 0.5];
const P0: [f64; 9] = [2.0, 0.3, 0.0, 0.3, 1.0, 0.1, 0.0, 0.1, 1.5];

fn mat(rows: usize, cols: usize, data: &[f64]) -> StepMatrix {
    StepMatrix::constant(rows, cols, data.to_vec()).unwrap()
}

fn nonlinear() -> NonlinearModel {
    NonlinearModel::new(
        Arc::new(LinearMap::new(F.to_vec(), 3, 3).unwrap()),
        Arc::new(LinearMap::new(H.to_vec(), 2, 3).unwrap()),
        mat(3, 3, &Q),
        mat(2, 2, &R),
        vec![],
    )
    .unwrap()
}

fn data() -> Vec<f64> {
    let mut y: Vec<f64> = (0..60).map(|i| ((i * 7919) % 97) as f64 / 10.0 - 4.0).collect();
    y[9] = f64::NAN; // step 4, second component missing
    y[20] = f64::NAN; // step 10 missing whole
    y[21] = f64::NAN;
    y
}

/// The outputs of a nonlinear filter run into buffers filled with NaN (so nothing unwritten
/// passes for a result).
struct Outputs {
    x_filt: Vec<f64>,
    p_filt: Vec<f64>,
    x_pred: Vec<f64>,
    p_pred: Vec<f64>,
    loglik: f64,
}

fn run(into: impl FnOnce(FilterOutputs<'_>) -> kfast::Result<f64>) -> Outputs {
    let (t, n) = (30, 3);
    let mut res = Outputs {
        x_filt: vec![f64::NAN; t * n],
        p_filt: vec![f64::NAN; t * n * n],
        x_pred: vec![f64::NAN; t * n],
        p_pred: vec![f64::NAN; t * n * n],
        loglik: f64::NAN,
    };
    let mut out = FilterOutputs::default();
    out.x_filt = Some(&mut res.x_filt);
    out.p_filt = Some(&mut res.p_filt);
    out.x_pred = Some(&mut res.x_pred);
    out.p_pred = Some(&mut res.p_pred);
    res.loglik = into(out).unwrap();
    res
}

fn linear() -> LinearGaussian {
    LinearGaussian::new(Matrices::new(mat(3, 3, &F), mat(2, 3, &H), mat(3, 3, &Q), mat(2, 2, &R))).unwrap()
}

fn assert_same(got: &Outputs, want: &FilterResult, tol: f64) {
    for (name, g, w) in [
        ("x_filt", &got.x_filt, &want.x_filt),
        ("P_filt", &got.p_filt, &want.p_filt),
        ("x_pred", &got.x_pred, &want.x_pred),
        ("P_pred", &got.p_pred, &want.p_pred),
    ] {
        for (i, (a, b)) in g.iter().zip(w.iter()).enumerate() {
            assert!((a - b).abs() <= tol * b.abs().max(1.0), "{name}[{i}]: {a} vs {b}");
        }
    }
    assert!((got.loglik - want.loglik).abs() <= tol * want.loglik.abs(), "{} vs {}", got.loglik, want.loglik);
}

#[test]
fn on_a_linear_model_the_nonlinear_filters_are_the_kalman_filter() {
    let model = nonlinear();
    let y = data();
    let series = || Series::new("y", &y, 30, 2).unwrap();
    for form in [UpdateForm::Joseph, UpdateForm::Standard] {
        let want = filter(&linear(), series(), None, &X0, &P0, form).unwrap();
        for (iterations, iteration) in [(0, Iteration::Book), (2, Iteration::Book), (2, Iteration::GaussNewton)] {
            let options = EkfOptions { form, iterations, iteration, ..Default::default() };
            let got = run(|out| ekf_into(&model, series(), None, &X0, &P0, options, out));
            assert_same(&got, &want, 1e-10);
        }
        if form == UpdateForm::Standard {
            for points in [
                SigmaPoints::Merwe { alpha: 1e-3, beta: 2.0, kappa: 0.0 },
                SigmaPoints::Julier { kappa: 1.0 },
                SigmaPoints::Cubature,
            ] {
                let got = run(|out| ukf_into(&model, series(), None, &X0, &P0, points.into(), out));
                assert_same(&got, &want, 1e-9);
            }
        }
    }
}

#[test]
fn a_singular_covariance_has_no_sigma_points_and_the_error_names_the_step() {
    let model = nonlinear();
    let y = data();
    let mut p0 = P0;
    p0[8] = 0.0;
    p0[5] = 0.0;
    p0[7] = 0.0;
    let err = ukf_into(
        &model,
        Series::new("y", &y, 30, 2).unwrap(),
        None,
        &X0,
        &p0,
        SigmaPoints::Cubature.into(),
        FilterOutputs::default(),
    )
    .unwrap_err();
    assert!(matches!(err, Error::NotPositiveDefinite { what: "P(t|t-1)", step: 0, .. }), "{err}");
}

#[test]
fn bad_models_are_refused() {
    let f = Arc::new(LinearMap::new(F.to_vec(), 3, 3).unwrap());
    let h = Arc::new(LinearMap::new(H.to_vec(), 2, 3).unwrap());
    let err = NonlinearModel::new(f.clone(), h.clone(), mat(3, 3, &Q), mat(2, 2, &R), vec![2]).unwrap_err();
    assert!(err.to_string().starts_with("angles"), "{err}");
    let err = NonlinearModel::new(h.clone(), h, mat(3, 3, &Q), mat(2, 2, &R), vec![]).unwrap_err();
    assert!(err.to_string().starts_with("f: maps 3 states to 2"), "{err}");
    let err = NonlinearModel::new(f.clone(), f, mat(3, 3, &Q), mat(2, 2, &R), vec![]).unwrap_err();
    assert!(err.to_string().starts_with("R: expected (3, 3)"), "{err}");
}

/// Three series (the data shifted), per-series priors: each series of `ekf_batch` and
/// `ukf_batch` is bit for bit the single-series filter, on one thread or two.
#[test]
fn the_batch_filters_give_each_series_its_own_filter() {
    let model = nonlinear();
    let (bs, t, n, m) = (3, 30, 3, 2);
    let y: Vec<f64> = (0..bs).flat_map(|b| data().into_iter().map(move |v| v + b as f64)).collect();
    let x0: Vec<f64> = (0..bs).flat_map(|b| X0.map(|v| v * (1.0 + b as f64))).collect();
    let p0: Vec<f64> = (0..bs).flat_map(|_| P0).collect();
    let batch = Batch { y: &y, series: bs, steps: t, u: None, u_shared: false, x0: &x0, p0: &p0 };
    let points = SigmaPoints::Merwe { alpha: 0.5, beta: 2.0, kappa: 0.0 };
    let options = EkfOptions { iterations: 1, ..EkfOptions::default() };
    for threads in [Some(1), Some(2)] {
        for ukf in [false, true] {
            let (mut x, mut p, mut ll) =
                (vec![f64::NAN; bs * t * n], vec![f64::NAN; bs * t * n * n], vec![f64::NAN; bs]);
            let out = BatchOutputs { x_filt: &mut x, p_filt: Some(&mut p), loglik: &mut ll };
            if ukf {
                ukf_batch(&model, batch, points.clone().into(), out, threads).unwrap();
            } else {
                ekf_batch(&model, batch, options, out, threads).unwrap();
            }
            for b in 0..bs {
                let ys = Series::new("y", &y[b * t * m..(b + 1) * t * m], t, m).unwrap();
                let (x0b, p0b) = (&x0[b * n..(b + 1) * n], &p0[b * n * n..(b + 1) * n * n]);
                let one = run(|o| {
                    if ukf {
                        ukf_into(&model, ys, None, x0b, p0b, points.clone().into(), o)
                    } else {
                        ekf_into(&model, ys, None, x0b, p0b, options, o)
                    }
                });
                assert_eq!(x[b * t * n..(b + 1) * t * n], one.x_filt[..], "x_filt, series {b}");
                assert_eq!(p[b * t * n * n..(b + 1) * t * n * n], one.p_filt[..], "P_filt, series {b}");
                assert_eq!(ll[b], one.loglik, "loglik, series {b}");
            }
        }
    }
    // A bad prior covariance in series 2 is named with its series.
    let mut bad = p0.clone();
    bad[2 * n * n] = -1.0;
    let (mut x, mut ll) = (vec![0.0; bs * t * n], vec![0.0; bs]);
    let out = BatchOutputs { x_filt: &mut x, p_filt: None, loglik: &mut ll };
    let err = ekf_batch(&model, Batch { p0: &bad, ..batch }, options, out, None).unwrap_err();
    assert!(err.to_string().contains("(series 2)"), "{err}");
}

/// A constant noise gain G (3 × 2) with Q of size 2 × 2 is the model with Q replaced by G Q G';
/// a gain of the wrong size is refused, naming g.
#[test]
fn a_constant_noise_gain_is_the_model_with_g_q_g_transposed() {
    let g = [1.0, 0.0, 0.5, 1.0, 0.0, 2.0];
    let q_w = [0.4, 0.1, 0.1, 0.3];
    // G Q G' by hand
    let mut gqg = [0.0; 9];
    for i in 0..3 {
        for j in 0..3 {
            gqg[i * 3 + j] = (0..2)
                .flat_map(|a| (0..2).map(move |b| (a, b)))
                .map(|(a, b)| g[i * 2 + a] * q_w[a * 2 + b] * g[j * 2 + b])
                .sum();
        }
    }
    let f = || Arc::new(LinearMap::new(F.to_vec(), 3, 3).unwrap());
    let h = || Arc::new(LinearMap::new(H.to_vec(), 2, 3).unwrap());
    let with_gain = NonlinearModel::with_noise_gain(
        f(),
        Arc::new(ConstantMap::new(g.to_vec(), 3)),
        h(),
        mat(2, 2, &q_w),
        mat(2, 2, &R),
        vec![],
    )
    .unwrap();
    let folded = NonlinearModel::new(f(), h(), mat(3, 3, &gqg), mat(2, 2, &R), vec![]).unwrap();
    let y = data();
    let ys = Series::new("y", &y, 30, 2).unwrap();
    let points = SigmaPoints::Cubature;
    let a = run(|o| ukf_into(&with_gain, ys, None, &X0, &P0, points.clone().into(), o));
    let b = run(|o| ukf_into(&folded, ys, None, &X0, &P0, points.into(), o));
    for (x, z) in a.p_pred.iter().zip(&b.p_pred) {
        assert!((x - z).abs() <= 1e-12 * z.abs().max(1.0), "{x} vs {z}");
    }
    assert!((a.loglik - b.loglik).abs() <= 1e-12 * b.loglik.abs());
    let err = NonlinearModel::with_noise_gain(
        f(),
        Arc::new(ConstantMap::new(g[..4].to_vec(), 3)),
        h(),
        mat(2, 2, &q_w),
        mat(2, 2, &R),
        vec![],
    )
    .unwrap_err();
    assert!(err.to_string().starts_with("g:"), "{err}");
}

#[test]
fn the_particle_filter_approaches_the_kalman_filter_on_any_number_of_threads() {
    // data() at a quarter of its size: the full size is so unlikely under the model that the
    // effective sample size drops to 30 of 50,000
    let y: Vec<f64> = data().iter().map(|v| 0.25 * v).collect();
    let series = Series::new("y", &y, 30, 2).unwrap();
    let kf = filter(&linear(), series, None, &X0, &P0, UpdateForm::Joseph).unwrap();
    let mut options = ParticleOptions::new(50_000);
    options.resampling = Resampling::Systematic;
    options.ess_threshold = Some(0.5);
    let mut runs = Vec::new();
    for threads in [1, 2, 4] {
        options.threads = Some(threads);
        runs.push(particle_filter(&nonlinear(), series, None, &X0, &P0, options.clone()).unwrap());
    }
    for other in &runs[1..] {
        assert_eq!(other.x_filt, runs[0].x_filt);
        assert_eq!(other.loglik_t, runs[0].loglik_t);
    }
    let pf = &runs[0];
    for t in 0..30 {
        for a in 0..3 {
            // the means' standard deviation over seeds is at most 0.017 here (40 seeds)
            let error = (pf.x_filt[t * 3 + a] - kf.x_filt[t * 3 + a]).abs();
            assert!(error < 0.1, "step {t}, state {a}: {error}");
            let p_error = (pf.p_filt[t * 9 + a * 4] - kf.p_filt[t * 9 + a * 4]).abs();
            assert!(p_error < 0.05 * kf.p_filt[t * 9 + a * 4], "step {t}, state {a}: {p_error}");
        }
    }
    assert!((pf.loglik - kf.loglik).abs() < 0.5, "{} vs {}", pf.loglik, kf.loglik);
    options.particles = 0;
    let err = particle_filter(&nonlinear(), series, None, &X0, &P0, options).unwrap_err();
    assert!(err.to_string().contains("n_particles"), "{err}");
}

/// log N(y; H x, R) written by the user, on the observed components of y (R diagonal here).
struct DiagonalGaussian;

impl ParticleFunction for DiagonalGaussian {
    fn eval(
        &self,
        x: &[f64],
        k: usize,
        y: &[f64],
        _t: usize,
        _u: Option<&[f64]>,
        out: &mut [f64],
    ) -> kfast::Result<()> {
        for (xi, o) in x.chunks_exact(3).zip(&mut out[..k]) {
            *o = 0.0;
            for (i, &yi) in y.iter().enumerate().filter(|(_, v)| !v.is_nan()) {
                let var = R[i * 2 + i];
                let e = yi - (H[i * 3] * xi[0] + H[i * 3 + 1] * xi[1] + H[i * 3 + 2] * xi[2]);
                *o -= 0.5 * ((2.0 * std::f64::consts::PI * var).ln() + e * e / var);
            }
        }
        Ok(())
    }
}

/// Leaves the particles where they are.
struct Stay;

impl ParticleFunction for Stay {
    fn eval(
        &self,
        x: &[f64],
        k: usize,
        _y: &[f64],
        _t: usize,
        _u: Option<&[f64]>,
        out: &mut [f64],
    ) -> kfast::Result<()> {
        out[..k * 3].copy_from_slice(&x[..k * 3]);
        Ok(())
    }
}

#[test]
fn the_users_likelihood_move_and_copies_through_the_public_api() {
    let y: Vec<f64> = data().iter().map(|v| 0.25 * v).collect();
    let series = Series::new("y", &y, 30, 2).unwrap();
    let diagonal = NonlinearModel::new(
        Arc::new(LinearMap::new(F.to_vec(), 3, 3).unwrap()),
        Arc::new(LinearMap::new(H.to_vec(), 2, 3).unwrap()),
        mat(3, 3, &Q),
        mat(2, 2, &[R[0], 0.0, 0.0, R[3]]),
        vec![],
    )
    .unwrap();
    let options = ParticleOptions::new(10_000);
    let gaussian = particle_filter(&diagonal, series, None, &X0, &P0, options.clone()).unwrap();
    let by_hand =
        ParticleOptions { likelihood: MeasurementLikelihood::User(Arc::new(DiagonalGaussian)), ..options.clone() };
    let user = particle_filter(&diagonal, series, None, &X0, &P0, by_hand).unwrap();
    for (a, b) in user.loglik_t.iter().zip(&gaussian.loglik_t) {
        assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()), "{a} vs {b}");
    }
    // a move that stays gives the bits of no move
    let staying = ParticleOptions { rejuvenate: Some(Arc::new(Stay)), ..options.clone() };
    assert_eq!(particle_filter(&diagonal, series, None, &X0, &P0, staying).unwrap().x_filt, gaussian.x_filt);
    // r copies: another filter, still near the first
    let copies = ParticleOptions { copies: 4, ..options.clone() };
    let with_copies = particle_filter(&diagonal, series, None, &X0, &P0, copies).unwrap();
    assert_ne!(with_copies.x_filt, gaussian.x_filt);
    assert!((with_copies.loglik - gaussian.loglik).abs() < 0.5, "{} vs {}", with_copies.loglik, gaussian.loglik);
    for bad in [0, 3] {
        let options = ParticleOptions { copies: bad, ..options.clone() };
        let err = particle_filter(&diagonal, series, None, &X0, &P0, options).unwrap_err();
        assert!(err.to_string().starts_with("copies:"), "{err}");
    }
}
