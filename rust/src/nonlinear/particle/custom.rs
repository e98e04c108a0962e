//! [`ParticleFunction`]: a user's function of all the particles at one step — the measurement
//! log-likelihood of [`MeasurementLikelihood::User`](super::MeasurementLikelihood::User) or the
//! move of [`ParticleOptions::rejuvenate`](super::ParticleOptions::rejuvenate).

use crate::error::Result;

/// A function of the k particles xⁱ at step t, given y(t) and u(t), evaluated for all of them
/// in one call (per block of particles when [`parallel`](Self::parallel), else once for all):
///
/// - as a likelihood, `out[i]` = log p(y(t) | xⁱ) (k numbers; −∞ for a particle that cannot
///   have produced y(t));
/// - as a move, `out[i]` = the moved particle (k × n numbers), e.g. a Metropolis–Hastings step
///   that leaves p(x(t) | y(0..t)) invariant (resample–move, Gilks & Berzuini 2001).
pub trait ParticleFunction: Send + Sync {
    /// `out` from the k particles `particles` (k × n, row-major), y(t) (all m components; NaN
    /// where missing), the step t and the input row u(t) (if the model has inputs).
    fn eval(&self, particles: &[f64], k: usize, y: &[f64], t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Result<()>;

    /// Whether calls from several threads may run at once (true but for a Python callable,
    /// which holds the GIL while it runs).
    fn parallel(&self) -> bool {
        true
    }
}

impl std::fmt::Debug for dyn ParticleFunction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("<user's particle function>")
    }
}
