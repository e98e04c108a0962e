//! Criterion benchmarks of the Rust kernels through the public API: the whole-series filter
//! and log-likelihood, the streaming filter, the filter at growing state sizes, the RTS
//! smoother, the DARE solvers, the discrete Lyapunov solver, expm / Van Loan discretization
//! and the batch filter.
//!
//! Run with `cargo bench --bench kernels` (a few minutes at most: small sample sizes and short
//! measurement times are set below). Filter-like benchmarks report a throughput in elements,
//! one element per time step (per series-step for the batch), so criterion's "thrpt" line
//! reads as steps per second and "time / T" as the time of one step.
//!
//! Models: the constant-velocity (CV) model (n = 4, m = 2, dt = 0.1) and fixed pseudo-random
//! stable models made by a small inline LCG, so every run sees the same numbers.

use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use kfast::{
    discretize, expm, filter, filter_batch, loglik, smooth, solve_discrete_are, solve_discrete_lyapunov, Batch,
    BatchOutputs, DareMethod, FilterOptions, KalmanFilter, LinearGaussian, Matrices, RiccatiProblem, Series,
    StepMatrix, UpdateForm,
};

// ---------------------------------------------------------------------------------------------
// Data
// ---------------------------------------------------------------------------------------------

/// A 64-bit linear congruential generator (Knuth's MMIX constants); uniforms from the top 53
/// bits, normals by Box–Muller. Enough for benchmark data, not for statistics.
struct Lcg(u64);

impl Lcg {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        self.0
    }

    /// Uniform on [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on [−1, 1).
    fn symmetric(&mut self) -> f64 {
        2.0 * self.uniform() - 1.0
    }

    /// Standard normal.
    fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Dense row-major matrices of a model: F (n × n), H (m × n), Q (n × n), R (m × m).
struct Mats {
    n: usize,
    m: usize,
    f: Vec<f64>,
    h: Vec<f64>,
    q: Vec<f64>,
    r: Vec<f64>,
}

impl Mats {
    /// The constant-velocity model, state (px, py, vx, vy), positions observed, R = I.
    fn cv(dt: f64) -> Self {
        let (d2, d3) = (dt * dt / 2.0, dt * dt * dt / 3.0);
        #[rustfmt::skip]
        let f = vec![
            1.0, 0.0, dt,  0.0,
            0.0, 1.0, 0.0, dt,
            0.0, 0.0, 1.0, 0.0,
            0.0, 0.0, 0.0, 1.0,
        ];
        #[rustfmt::skip]
        let h = vec![
            1.0, 0.0, 0.0, 0.0,
            0.0, 1.0, 0.0, 0.0,
        ];
        // Per axis [[dt³/3, dt²/2], [dt²/2, dt]] on (p, v); the axes are independent.
        #[rustfmt::skip]
        let q = vec![
            d3,  0.0, d2,  0.0,
            0.0, d3,  0.0, d2,
            d2,  0.0, dt,  0.0,
            0.0, d2,  0.0, dt,
        ];
        Mats { n: 4, m: 2, f, h, q, r: identity(2) }
    }

    /// A fixed pseudo-random stable model: F with ‖F‖_∞ = 0.95 (so ρ(F) < 1), H with entries
    /// in [−1, 1), Q = G G'/n + 0.1 I, R = G₂ G₂'/m + I.
    fn random(n: usize, m: usize, seed: u64) -> Self {
        let mut rng = Lcg(seed);
        let mut f: Vec<f64> = (0..n * n).map(|_| rng.symmetric()).collect();
        for row in f.chunks_mut(n) {
            let s = 0.95 / row.iter().map(|v| v.abs()).sum::<f64>();
            row.iter_mut().for_each(|v| *v *= s);
        }
        let h = (0..m * n).map(|_| rng.symmetric()).collect();
        let q = gram(&mut rng, n, 0.1);
        let r = gram(&mut rng, m, 1.0);
        Mats { n, m, f, h, q, r }
    }

    fn model(&self) -> LinearGaussian {
        let c = |rows: usize, cols: usize, v: &[f64]| StepMatrix::constant(rows, cols, v.to_vec()).unwrap();
        let (n, m) = (self.n, self.m);
        LinearGaussian::new(Matrices::new(c(n, n, &self.f), c(m, n, &self.h), c(n, n, &self.q), c(m, m, &self.r)))
            .unwrap()
    }

    /// `steps` observations (row-major `(steps, m)`) simulated from the model.
    fn simulate(&self, steps: usize, seed: u64) -> Vec<f64> {
        let (n, m) = (self.n, self.m);
        let mut rng = Lcg(seed);
        let (lq, lr) = (cholesky(&self.q, n), cholesky(&self.r, m));
        let mut x = vec![0.0; n];
        let mut y = Vec::with_capacity(steps * m);
        for _ in 0..steps {
            let v = correlated(&mut rng, &lr, m);
            y.extend((0..m).map(|i| (0..n).map(|j| self.h[i * n + j] * x[j]).sum::<f64>() + v[i]));
            let w = correlated(&mut rng, &lq, n);
            x = (0..n).map(|i| (0..n).map(|j| self.f[i * n + j] * x[j]).sum::<f64>() + w[i]).collect();
        }
        y
    }
}

fn identity(n: usize) -> Vec<f64> {
    let mut a = vec![0.0; n * n];
    (0..n).for_each(|i| a[i * n + i] = 1.0);
    a
}

fn transpose(a: &[f64], rows: usize, cols: usize) -> Vec<f64> {
    (0..cols * rows).map(|k| a[(k % rows) * cols + k / rows]).collect()
}

/// `G G' / n + shift · I` for a random `n × n` G: exactly symmetric, positive definite.
fn gram(rng: &mut Lcg, n: usize, shift: f64) -> Vec<f64> {
    let g: Vec<f64> = (0..n * n).map(|_| rng.symmetric()).collect();
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let v = (0..n).map(|k| g[i * n + k] * g[j * n + k]).sum::<f64>() / n as f64;
            a[i * n + j] = v;
            a[j * n + i] = v;
        }
        a[i * n + i] += shift;
    }
    a
}

/// Lower Cholesky factor of a symmetric positive semidefinite matrix (zero columns where a
/// pivot vanishes).
fn cholesky(a: &[f64], n: usize) -> Vec<f64> {
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let d = a[j * n + j] - (0..j).map(|k| l[j * n + k] * l[j * n + k]).sum::<f64>();
        let d = d.max(0.0).sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let s = a[i * n + j] - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
            l[i * n + j] = if d > 0.0 { s / d } else { 0.0 };
        }
    }
    l
}

/// `L z` with `z` standard normal.
fn correlated(rng: &mut Lcg, l: &[f64], n: usize) -> Vec<f64> {
    let z: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
    (0..n).map(|i| (0..=i).map(|k| l[i * n + k] * z[k]).sum()).collect()
}

/// Prior of the filters: x̂(0|−1) = 0, P(0|−1) = 10 I.
fn prior(n: usize) -> (Vec<f64>, Vec<f64>) {
    (vec![0.0; n], identity(n).into_iter().map(|v| 10.0 * v).collect())
}

const DT: f64 = 0.1;
const FORMS: [(UpdateForm, &str); 2] = [(UpdateForm::Joseph, "joseph"), (UpdateForm::Standard, "standard")];

// ---------------------------------------------------------------------------------------------
// Filter, log-likelihood, streaming filter, smoother
// ---------------------------------------------------------------------------------------------

fn bench_filter_cv(c: &mut Criterion) {
    const T: usize = 10_000;
    let cv = Mats::cv(DT);
    let model = cv.model();
    let y = cv.simulate(T, 1);
    let (x0, p0) = prior(cv.n);
    let series = || Series::new("y", &y, T, cv.m).unwrap();

    let mut g = c.benchmark_group("cv_t10k");
    g.throughput(Throughput::Elements(T as u64));
    for (form, name) in FORMS {
        g.bench_function(BenchmarkId::new("filter", name), |b| {
            b.iter(|| filter(&model, black_box(series()), None, &x0, &p0, form).unwrap())
        });
        g.bench_function(BenchmarkId::new("loglik", name), |b| {
            b.iter(|| loglik(&model, black_box(series()), None, &x0, &p0, FilterOptions::from(form)).unwrap())
        });
    }
    g.bench_function("smooth_rts", |b| {
        b.iter(|| smooth(&model, black_box(series()), None, &x0, &p0, UpdateForm::Joseph).unwrap())
    });
    g.finish();
}

fn bench_streaming(c: &mut Criterion) {
    const T: usize = 10_000;
    let cv = Mats::cv(DT);
    let model = Arc::new(cv.model());
    let y = cv.simulate(T, 2);
    let (x0, p0) = prior(cv.n);

    let mut g = c.benchmark_group("cv_streaming");
    g.throughput(Throughput::Elements(1));
    for (form, name) in FORMS {
        // One step (update with y[t], then predict) per iteration, cycling through the data;
        // the filter is restarted at the end of the data so its state stays realistic.
        g.bench_function(BenchmarkId::new("step", name), |b| {
            let mut kf = KalmanFilter::new(model.clone(), &x0, &p0, form).unwrap();
            let mut t = 0;
            b.iter(|| {
                if t == T {
                    kf = KalmanFilter::new(model.clone(), &x0, &p0, form).unwrap();
                    t = 0;
                }
                kf.step(black_box(&y[t * cv.m..(t + 1) * cv.m]), None).unwrap();
                t += 1;
            })
        });
    }
    g.finish();
}

fn bench_filter_sizes(c: &mut Criterion) {
    const T: usize = 1_000;
    let mut g = c.benchmark_group("filter_size_t1k");
    g.throughput(Throughput::Elements(T as u64));
    for n in [2, 8, 16, 32] {
        let mats = Mats::random(n, n / 2, 100 + n as u64);
        let model = mats.model();
        let y = mats.simulate(T, 3);
        let (x0, p0) = prior(n);
        g.bench_with_input(BenchmarkId::new("joseph", format!("n{n}_m{}", n / 2)), &n, |b, _| {
            b.iter(|| {
                let y = Series::new("y", black_box(&y), T, mats.m).unwrap();
                filter(&model, y, None, &x0, &p0, UpdateForm::Joseph).unwrap()
            })
        });
    }
    g.finish();
}

// ---------------------------------------------------------------------------------------------
// Solvers: DARE, Lyapunov, expm, discretize
// ---------------------------------------------------------------------------------------------

const METHODS: [(DareMethod, &str); 4] = [
    (DareMethod::Doubling, "doubling"),
    (DareMethod::Newton, "newton"),
    (DareMethod::Iteration, "iteration"),
    (DareMethod::Eigen, "eigen"),
];

fn bench_dare(c: &mut Criterion) {
    // Kalman (filter) form of the DARE: a = F', b = H', q = Q, r = R.
    let cases = [("cv_n4_m2", Mats::cv(DT)), ("rand_n20_m10", Mats::random(20, 10, 7))];
    let mut g = c.benchmark_group("dare");
    for (label, mats) in &cases {
        let (n, m) = (mats.n, mats.m);
        let (a, b) = (transpose(&mats.f, n, n), transpose(&mats.h, m, n));
        for (method, name) in METHODS {
            let run = || solve_discrete_are(RiccatiProblem::new(&a, &b, &mats.q, &mats.r, n, m), method);
            let sol = run().unwrap_or_else(|e| panic!("DARE {label} {name}: {e}"));
            assert!(sol.residual < 1e-8, "DARE {label} {name}: residual {}", sol.residual);
            g.bench_function(BenchmarkId::new(name, label), |bch| bch.iter(|| black_box(run()).unwrap()));
        }
    }
    g.finish();
}

fn bench_small_solvers(c: &mut Criterion) {
    let cases = [Mats::random(4, 2, 11), Mats::random(20, 10, 12)];
    let mut g = c.benchmark_group("dense");
    for mats in &cases {
        let n = mats.n;
        g.bench_with_input(BenchmarkId::new("lyapunov_discrete", n), &n, |b, &n| {
            b.iter(|| solve_discrete_lyapunov(black_box(&mats.f), &mats.q, n).unwrap())
        });
        // A continuous-time-like matrix with ‖A‖₁ ≈ 5, so scaling and squaring is exercised.
        let a: Vec<f64> = mats.f.iter().map(|v| 5.0 * v).collect();
        g.bench_with_input(BenchmarkId::new("expm", n), &n, |b, &n| b.iter(|| expm(black_box(&a), n).unwrap()));
    }
    // Van Loan discretization of the continuous CV model (white-noise acceleration).
    #[rustfmt::skip]
    let a = [
        0.0, 0.0, 1.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
        0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0,
    ];
    let qc: Vec<f64> = (0..16).map(|k| if k == 10 || k == 15 { 1.0 } else { 0.0 }).collect();
    g.bench_function(BenchmarkId::new("discretize", 4), |b| {
        b.iter(|| discretize(black_box(&a), &qc, None, 4, 0, DT).unwrap())
    });
    g.finish();
}

// ---------------------------------------------------------------------------------------------
// Batch filter
// ---------------------------------------------------------------------------------------------

fn bench_batch(c: &mut Criterion) {
    const SERIES: usize = 200;
    const T: usize = 500;
    let cv = Mats::cv(DT);
    let model = cv.model();
    let n = cv.n;
    let y: Vec<f64> = (0..SERIES).flat_map(|s| cv.simulate(T, 1000 + s as u64)).collect();
    let (x0, p0) = prior(n);
    let mut x_filt = vec![0.0; SERIES * T * n];
    let mut p_filt = vec![0.0; T * n * n];
    let mut ll = vec![0.0; SERIES];

    let mut g = c.benchmark_group("batch_cv_200x500");
    g.throughput(Throughput::Elements((SERIES * T) as u64));
    let batch = Batch { y: &y, series: SERIES, steps: T, u: None, u_shared: false, x0: &x0, p0: &p0 };
    g.bench_function("filter_batch", |b| {
        b.iter(|| {
            let out = BatchOutputs { x_filt: &mut x_filt, p_filt: Some(&mut p_filt), loglik: &mut ll };
            let shared = filter_batch(&model, black_box(batch), UpdateForm::Joseph, out, None).unwrap();
            assert!(shared);
        })
    });
    g.finish();
    black_box(&ll);
}

// ---------------------------------------------------------------------------------------------

fn config() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_millis(1500))
        .nresamples(20_000)
}

criterion_group! {
    name = kernels;
    config = config();
    targets = bench_filter_cv, bench_streaming, bench_filter_sizes, bench_dare, bench_small_solvers, bench_batch
}
criterion_main!(kernels);
