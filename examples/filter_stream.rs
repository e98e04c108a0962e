//! Filter a stream one measurement at a time: a 1-D constant-velocity target (position and
//! velocity), its position measured in noise, fed to a `KalmanFilter` as the samples arrive.
//!
//! Run with `cargo run --release --example filter_stream`.

use kfast::{KalmanFilter, LinearGaussian, Matrices, StepMatrix, UpdateForm};

fn main() -> Result<(), kfast::Error> {
    let dt = 0.1;
    let q = 0.5; // white-acceleration intensity
    let f = StepMatrix::constant(2, 2, vec![1.0, dt, 0.0, 1.0])?;
    let h = StepMatrix::constant(1, 2, vec![1.0, 0.0])?;
    // Q of the sampled white-noise acceleration: q [dt³/3, dt²/2; dt²/2, dt].
    let qm = StepMatrix::constant(2, 2, vec![q * dt.powi(3) / 3.0, q * dt * dt / 2.0, q * dt * dt / 2.0, q * dt])?;
    let r = StepMatrix::constant(1, 1, vec![0.25])?;
    let model = LinearGaussian::new(Matrices::new(f, h, qm, r))?;

    // The prior x̂(0|−1), P(0|−1): the first call is an update.
    let mut kf = KalmanFilter::new(&model, &[0.0, 1.0], &[1.0, 0.0, 0.0, 1.0], UpdateForm::Joseph)?;
    // A target moving at 1.2 units/s, with a deterministic "noise" so the example needs no RNG.
    for t in 0..50 {
        let truth = 1.2 * dt * t as f64;
        let y = truth + 0.5 * (0.7 * t as f64).sin();
        kf.update(&[y], None)?;
        if t % 10 == 9 {
            let (x, p) = (kf.x(), kf.p());
            println!(
                "t = {t:2}: position {:7.3} ± {:.3}, velocity {:6.3} ± {:.3}",
                x[0],
                p[0].sqrt(),
                x[1],
                p[3].sqrt()
            );
        }
        kf.predict(None)?;
    }
    Ok(())
}
