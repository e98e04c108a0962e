//! Many series through one model on all cores: 1,000 random-walk-plus-noise series of 500
//! steps filtered by `filter_batch`. With complete data and one prior the covariance recursion
//! is the same for every series, so it is computed once (the returned flag says so).
//!
//! Run with `cargo run --release --example batch`.

use kfast::{filter_batch, Batch, BatchOutputs, LinearGaussian, Matrices, StepMatrix, UpdateForm};

fn main() -> Result<(), kfast::Error> {
    let c = |v: f64| StepMatrix::constant(1, 1, vec![v]);
    let model = LinearGaussian::new(Matrices::new(c(1.0)?, c(1.0)?, c(0.01)?, c(1.0)?))?;
    let (series, steps) = (1_000, 500);
    // Series s is a level of s / 100 observed in a deterministic wiggle (no RNG needed).
    let y: Vec<f64> = (0..series)
        .flat_map(|s| (0..steps).map(move |t| s as f64 / 100.0 + ((s * 7 + t * 13) % 17) as f64 / 8.0 - 1.0))
        .collect();
    let (mut x_filt, mut p_filt, mut loglik) = (vec![0.0; series * steps], vec![0.0; steps], vec![0.0; series]);
    let batch = Batch { y: &y, series, steps, u: None, u_shared: false, x0: &[0.0], p0: &[100.0] };
    let out = BatchOutputs { x_filt: &mut x_filt, p_filt: Some(&mut p_filt), loglik: &mut loglik };
    let shared = filter_batch(&model, batch, UpdateForm::Joseph, out, None)?;
    println!("covariance recursion shared by all series: {shared}");
    for s in [0, 500, 999] {
        let last = x_filt[s * steps + steps - 1];
        println!(
            "series {s:3}: final level estimate {last:.3} (true {:.2}), log-likelihood {:.2}",
            s as f64 / 100.0,
            loglik[s]
        );
    }
    println!("final P(t|t) = {:.5}", p_filt[steps - 1]);
    Ok(())
}
