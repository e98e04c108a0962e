//! Many independent series through one model: the data of a batch ([`Batch`]), its output
//! buffers ([`BatchOutputs`]), each series' part of them, and the pool of threads that runs
//! the series in parallel (rayon with the default feature `rayon`, else one after another
//! with the same results). Used by the linear `filter_batch` and the nonlinear `ekf_batch` /
//! `ukf_batch`.

use crate::core::alloc::check_f64_arrays;
use crate::core::Series;
use crate::error::{Error, Result};

/// Series `(B, T, m)`, inputs and priors of a batch.
#[derive(Debug, Clone, Copy)]
pub struct Batch<'a> {
    /// Observations, `B × T × m` row-major; NaN = missing.
    pub y: &'a [f64],
    /// Number of series B.
    pub series: usize,
    /// Steps per series T.
    pub steps: usize,
    /// Inputs `B × T × k`, or `T × k` shared by all series.
    pub u: Option<&'a [f64]>,
    /// Whether `u` is shared (`T × k`).
    pub u_shared: bool,
    /// Prior means x(0|−1): `n` (shared) or `B × n`.
    pub x0: &'a [f64],
    /// Prior covariances P(0|−1): `n × n` (shared) or `B × n × n`.
    pub p0: &'a [f64],
}

/// Output buffers of a batch filter.
#[derive(Debug)]
pub struct BatchOutputs<'a> {
    /// x̂(t|t) of every series, `B × T × n`.
    pub x_filt: &'a mut [f64],
    /// P(t|t): `B × T × n × n`, or `T × n × n` where the linear `filter_batch` shares the
    /// covariance recursion; `None` to skip covariances.
    pub p_filt: Option<&'a mut [f64]>,
    /// Log-likelihood of each series, `B`.
    pub loglik: &'a mut [f64],
}

/// The sizes of a batch's series: n states, m outputs, k inputs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SeriesSizes {
    pub n: usize,
    pub m: usize,
    pub k: usize,
}

impl<'a> Batch<'a> {
    /// Checks the lengths of Y, x0, P0 and u for the sizes `z` (B ≥ 1; B × T × max(n, m, k)
    /// fits in memory, so the products of sizes below cannot overflow).
    pub(crate) fn check_lengths(&self, z: SeriesSizes) -> Result<()> {
        let SeriesSizes { n, m, k } = z;
        let (bs, t) = (self.series, self.steps);
        if bs.checked_mul(t).and_then(|bt| bt.checked_mul(m)) != Some(self.y.len()) {
            return Err(Error::arg("Y", format!("expected {bs} × {t} × {m} values, got {}", self.y.len())));
        }
        if bs == 0 {
            return Err(Error::arg("Y", "has no series (B = 0)"));
        }
        check_f64_arrays("Y", &[&[bs, t, n.max(k)]])?;
        if self.x0.len() != n && bs.checked_mul(n) != Some(self.x0.len()) {
            return Err(Error::arg(
                "x0",
                format!("expected shape ({n},) or ({bs}, {n}), got {} values", self.x0.len()),
            ));
        }
        if self.p0.len() != n * n && bs.checked_mul(n * n) != Some(self.p0.len()) {
            return Err(Error::arg(
                "P0",
                format!("expected shape ({n}, {n}) or ({bs}, {n}, {n}), got {} values", self.p0.len()),
            ));
        }
        if let Some(u) = self.u {
            let want = if self.u_shared { t * k } else { bs * t * k };
            if u.len() != want {
                return Err(Error::arg("u", format!("expected {want} values, got {}", u.len())));
            }
        }
        Ok(())
    }

    /// Whether every series starts from the same prior.
    pub(crate) fn shared_prior(&self, n: usize) -> bool {
        self.x0.len() == n && self.p0.len() == n * n
    }

    /// Series `s`: its data, inputs and prior.
    pub(crate) fn part(&self, s: usize, z: SeriesSizes) -> (Series<'a>, Option<Series<'a>>, &'a [f64], &'a [f64]) {
        let SeriesSizes { n, m, k } = z;
        let t = self.steps;
        let y = Series::new("Y", &self.y[s * t * m..(s + 1) * t * m], t, m).expect("sizes checked");
        let u = self.u.map(|u| {
            let rows = if self.u_shared { u } else { &u[s * t * k..(s + 1) * t * k] };
            Series::new("u", rows, t, k).expect("sizes checked")
        });
        let x0 = if self.x0.len() == n { self.x0 } else { &self.x0[s * n..(s + 1) * n] };
        let p0 = if self.p0.len() == n * n { self.p0 } else { &self.p0[s * n * n..(s + 1) * n * n] };
        (y, u, x0, p0)
    }
}

impl BatchOutputs<'_> {
    /// Checks the buffers' lengths: `covs` is the length P_filt must have (`None`: more than
    /// fits in memory).
    pub(crate) fn check_lengths(&self, series: usize, steps: usize, n: usize, covs: Option<usize>) -> Result<()> {
        for (arg, got, want) in [
            ("x_filt", Some(self.x_filt.len()), Some(series * steps * n)),
            ("P_filt", self.p_filt.as_ref().map(|p| p.len()), covs),
            ("loglik", Some(self.loglik.len()), Some(series)),
        ] {
            if let Some(got) = got {
                if Some(got) != want {
                    let want = want.map_or("more than fit in memory".to_string(), |w| w.to_string());
                    return Err(Error::arg(arg, format!("output buffer has {got} entries, needs {want}")));
                }
            }
        }
        Ok(())
    }
}

/// The pool size for `series` series: `requested` (all cores when `None`), at most one thread
/// per series or per core.
pub(crate) fn thread_count(requested: Option<usize>, series: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    requested.unwrap_or(cores).min(cores).min(series).max(1)
}

/// `e` with the series it came from named (and the single-series argument `y` called `Y`).
pub(crate) fn prefix_series(e: Error, s: usize) -> Error {
    match e {
        Error::InvalidArgument { arg, step, problem } => Error::InvalidArgument {
            arg: if arg == "y" { "Y" } else { arg },
            step,
            problem: format!("(series {s}) {problem}"),
        },
        Error::InnovationCovariance { step, problem } => {
            Error::InnovationCovariance { step, problem: format!("(series {s}) {problem}") }
        }
        other => other,
    }
}

/// Parallel iteration over series: rayon's with the default feature `rayon`, else the same
/// names over sequential iterators (one thread, same results).
#[cfg(feature = "rayon")]
pub(crate) mod par {
    pub use rayon::prelude::*;

    use crate::error::{Error, Result};

    /// Runs `f` on a pool of `threads` threads.
    pub fn on_threads(threads: usize, f: impl FnOnce() -> Result<()> + Send) -> Result<()> {
        Pool::new(threads)?.install(f)
    }

    /// A pool of threads kept for many calls (a streaming filter's).
    pub struct Pool(rayon::ThreadPool);

    impl Pool {
        /// A pool of `threads` threads.
        pub fn new(threads: usize) -> Result<Self> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::arg("threads", e.to_string()))?;
            Ok(Pool(pool))
        }

        /// Runs `f` on the pool.
        pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
            self.0.install(f)
        }
    }
}

#[cfg(not(feature = "rayon"))]
pub(crate) mod par {
    use crate::error::Result;

    /// Runs `f` on this thread (`threads` is ignored without the feature `rayon`).
    pub fn on_threads(_threads: usize, f: impl FnOnce() -> Result<()>) -> Result<()> {
        f()
    }

    /// A stand-in for rayon's pool: runs everything on the calling thread.
    pub struct Pool;

    impl Pool {
        /// The stand-in (`threads` is ignored).
        pub fn new(_threads: usize) -> Result<Self> {
            Ok(Pool)
        }

        /// Runs `f`.
        pub fn install<R>(&self, f: impl FnOnce() -> R) -> R {
            f()
        }
    }

    /// rayon's slice methods, sequential.
    pub trait ParSlice<T> {
        fn par_chunks(&self, size: usize) -> std::slice::Chunks<'_, T>;
        fn par_chunks_mut(&mut self, size: usize) -> std::slice::ChunksMut<'_, T>;
        fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T>;
    }

    impl<T> ParSlice<T> for [T] {
        fn par_chunks(&self, size: usize) -> std::slice::Chunks<'_, T> {
            self.chunks(size)
        }
        fn par_chunks_mut(&mut self, size: usize) -> std::slice::ChunksMut<'_, T> {
            self.chunks_mut(size)
        }
        fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
            self.iter_mut()
        }
    }
}
