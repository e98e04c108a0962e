//! Integration tests of `filter_batch` through the public API: every series of a batch equals
//! `filter` run on it alone, bit for bit (x̂(t|t), P(t|t) and the log-likelihood), on the
//! shared-covariance path (complete data, one prior covariance) and the per-series path
//! (missing data or one prior covariance per series), with and without inputs (per series or
//! shared), correlated noise, per-step matrices, both update forms and 1, 3 or all threads.

mod common;

use common::{assert_bits_eq, random_model, Rng};
use kfast::{filter, filter_batch, Batch, BatchOutputs, Error, LinearGaussian, Result, Series, UpdateForm};

/// What varies between the batches tested.
#[derive(Debug, Clone, Copy)]
struct Setup {
    missing: bool,
    inputs: Inputs,
    prior_per_series: bool,
    p0_per_series: bool,
    with_n: bool,
    per_step: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Inputs {
    None,
    PerSeries,
    Shared,
}

/// A batch of `series` series of T steps for a random model, as owned arrays.
struct Data {
    model: LinearGaussian,
    series: usize,
    steps: usize,
    y: Vec<f64>,
    u: Option<Vec<f64>>,
    x0: Vec<f64>,
    p0: Vec<f64>,
}

fn random_data(seed: u64, setup: Setup) -> Result<Data> {
    let mut rng = Rng::new(seed);
    let (n, m, steps, series) = (rng.int(1, 6), rng.int(1, 3), rng.int(1, 30), rng.int(1, 9));
    let k = if setup.inputs == Inputs::None { 0 } else { 2 };
    let model = random_model(&mut rng, n, m, k, setup.with_n, setup.per_step.then_some(steps))?;
    let mut y = rng.normals(series * steps, m);
    if setup.missing {
        for v in y.iter_mut() {
            if rng.uniform() < 0.2 {
                *v = f64::NAN;
            }
        }
        // At least one NaN, so that the per-series path is taken, and one whole missing step.
        y[0] = f64::NAN;
        let (s, t) = (rng.int(0, series - 1), rng.int(0, steps - 1));
        y[(s * steps + t) * m..(s * steps + t + 1) * m].fill(f64::NAN);
    }
    let u = match setup.inputs {
        Inputs::None => None,
        Inputs::PerSeries => Some(rng.normals(series * steps, k)),
        Inputs::Shared => Some(rng.normals(steps, k)),
    };
    let x0 = rng.normals(if setup.prior_per_series { series } else { 1 }, n);
    let p0 = (0..if setup.p0_per_series { series } else { 1 }).flat_map(|_| rng.spd(n, 0.5)).collect();
    Ok(Data { model, series, steps, y, u, x0, p0 })
}

/// Runs `filter_batch` and `filter` on each series and compares them bit for bit.
fn check_batch_equals_filter(
    what: &str,
    d: &Data,
    setup: Setup,
    form: UpdateForm,
    threads: Option<usize>,
) -> Result<()> {
    let (n, m, k) = (d.model.n_states(), d.model.n_obs(), d.model.n_inputs());
    let (bs, t) = (d.series, d.steps);
    let shared_expected = !setup.missing && !setup.p0_per_series;
    let covs = if shared_expected { t * n * n } else { bs * t * n * n };
    let (mut x_filt, mut p_filt, mut loglik) = (vec![0.0; bs * t * n], vec![0.0; covs], vec![0.0; bs]);
    let batch = Batch {
        y: &d.y,
        series: bs,
        steps: t,
        u: d.u.as_deref(),
        u_shared: setup.inputs == Inputs::Shared,
        x0: &d.x0,
        p0: &d.p0,
    };
    let out = BatchOutputs { x_filt: &mut x_filt, p_filt: Some(&mut p_filt), loglik: &mut loglik };
    let shared = filter_batch(&d.model, batch, form, out, threads)?;
    assert_eq!(shared, shared_expected, "{what}: shared-covariance path");
    for s in 0..bs {
        let y = Series::new("y", &d.y[s * t * m..(s + 1) * t * m], t, m)?;
        let u = match (&d.u, setup.inputs) {
            (Some(u), Inputs::PerSeries) => Some(Series::new("u", &u[s * t * k..(s + 1) * t * k], t, k)?),
            (Some(u), Inputs::Shared) => Some(Series::new("u", u, t, k)?),
            _ => None,
        };
        let x0 = if setup.prior_per_series { &d.x0[s * n..(s + 1) * n] } else { &d.x0[..] };
        let p0 = if setup.p0_per_series { &d.p0[s * n * n..(s + 1) * n * n] } else { &d.p0[..] };
        let alone = filter(&d.model, y, u, x0, p0, form)?;
        let what = format!("{what}, series {s}");
        assert_bits_eq(&format!("{what}: x_filt"), &x_filt[s * t * n..(s + 1) * t * n], &alone.x_filt);
        let p = if shared { &p_filt[..] } else { &p_filt[s * t * n * n..(s + 1) * t * n * n] };
        assert_bits_eq(&format!("{what}: P_filt"), p, &alone.p_filt);
        assert_bits_eq(&format!("{what}: loglik"), &[loglik[s]], &[alone.loglik]);
    }
    Ok(())
}

#[test]
fn batch_equals_filter_per_series_bit_for_bit() -> Result<()> {
    let mut cases = 0;
    for seed in 0..48u64 {
        let setup = Setup {
            missing: seed % 2 == 1,
            inputs: [Inputs::None, Inputs::PerSeries, Inputs::Shared][(seed / 2 % 3) as usize],
            prior_per_series: seed % 4 >= 2,
            p0_per_series: seed % 8 >= 6,
            with_n: seed % 5 < 2,
            per_step: seed % 7 < 2,
        };
        let d = random_data(seed, setup)?;
        for form in [UpdateForm::Joseph, UpdateForm::Standard] {
            for threads in [Some(1), Some(3), None] {
                let what = format!("seed {seed} {setup:?} {form:?} threads {threads:?}");
                check_batch_equals_filter(&what, &d, setup, form, threads)?;
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 48 * 2 * 3);
    Ok(())
}

#[test]
fn thread_count_does_not_change_the_results() -> Result<()> {
    // Many series (more than threads), missing data: the per-series path split over threads.
    for (seed, missing) in [(1000, true), (1001, false)] {
        let setup = Setup {
            missing,
            inputs: Inputs::PerSeries,
            prior_per_series: true,
            p0_per_series: false,
            with_n: true,
            per_step: false,
        };
        let mut d = random_data(seed, setup)?;
        // Widen to 40 series by repeating the data with a shift, so that chunks differ.
        let (n, t) = (d.model.n_states(), d.steps);
        let reps = 40usize.div_ceil(d.series);
        d.y = (0..reps).flat_map(|r| d.y.iter().map(move |v| v + r as f64)).collect();
        d.u = d.u.map(|u| (0..reps).flat_map(|_| u.clone()).collect());
        d.x0 = (0..reps).flat_map(|_| d.x0.clone()).collect();
        d.series *= reps;
        let run = |threads: Option<usize>| -> Result<(Vec<f64>, Vec<f64>)> {
            let (mut x, mut ll) = (vec![0.0; d.series * t * n], vec![0.0; d.series]);
            let batch =
                Batch { y: &d.y, series: d.series, steps: t, u: d.u.as_deref(), u_shared: false, x0: &d.x0, p0: &d.p0 };
            filter_batch(
                &d.model,
                batch,
                UpdateForm::Joseph,
                BatchOutputs { x_filt: &mut x, p_filt: None, loglik: &mut ll },
                threads,
            )?;
            Ok((x, ll))
        };
        let (x1, ll1) = run(Some(1))?;
        for threads in [Some(2), Some(5), None] {
            let (x, ll) = run(threads)?;
            assert_bits_eq(&format!("seed {seed} threads {threads:?}: x_filt"), &x, &x1);
            assert_bits_eq(&format!("seed {seed} threads {threads:?}: loglik"), &ll, &ll1);
        }
        assert_eq!(x1.len(), d.series * t * n);
    }
    Ok(())
}

#[test]
fn a_bad_series_is_reported_with_its_index() -> Result<()> {
    let setup = Setup {
        missing: false,
        inputs: Inputs::None,
        prior_per_series: false,
        p0_per_series: false,
        with_n: false,
        per_step: false,
    };
    let mut d = random_data(7, setup)?;
    let (n, m, t) = (d.model.n_states(), d.model.n_obs(), d.steps);
    let bs = d.series.max(2);
    d.y = (0..bs * t * m).map(|i| (i as f64 * 0.37).sin()).collect();
    d.series = bs;
    let last = bs - 1;
    d.y[(last * t + t - 1) * m] = f64::INFINITY;
    let (mut x, mut ll) = (vec![0.0; bs * t * n], vec![0.0; bs]);
    let batch = Batch { y: &d.y, series: bs, steps: t, u: None, u_shared: false, x0: &d.x0, p0: &d.p0 };
    match filter_batch(
        &d.model,
        batch,
        UpdateForm::Joseph,
        BatchOutputs { x_filt: &mut x, p_filt: None, loglik: &mut ll },
        Some(2),
    ) {
        Err(err @ Error::InvalidArgument { arg: "Y", .. }) => {
            let msg = err.to_string();
            assert!(msg.contains(&format!("(series {last})")) && msg.contains(&format!("step {}", t - 1)), "{msg}");
        }
        other => panic!("expected InvalidArgument on Y, got {other:?}"),
    }
    Ok(())
}
