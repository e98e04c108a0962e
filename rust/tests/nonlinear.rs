//! Integration tests of the nonlinear filters through the public API: on a linear model
//! (f and h linear maps) the EKF, the iterated EKF and the UKF with every sigma-point set are
//! the Kalman filter; the errors name what failed and the step.

use std::sync::Arc;

use kfast::nonlinear::LinearMap;
use kfast::{
    ekf_into, filter, ukf_into, EkfOptions, Error, FilterOutputs, FilterResult, Iteration, LinearGaussian, Matrices,
    NonlinearModel, Series, SigmaPoints, StepMatrix, UpdateForm,
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
                let got = run(|out| ukf_into(&model, series(), None, &X0, &P0, points, out));
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
        SigmaPoints::Cubature,
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
