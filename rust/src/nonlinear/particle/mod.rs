//! Particle filters for the [`NonlinearModel`](super::NonlinearModel): the book's bootstrap
//! filter (Söderström (9.89)–(9.100)) and sequential importance resampling with the
//! resampling schemes of [`Resampling`], triggered every step or by the effective sample size.
//!
//! [`ParticleFilter`] runs the same steps one measurement at a time. Random numbers come from
//! kfast's own counter-based generator (`random`), so a run is fixed by its seed, whatever the
//! number of threads.

mod cloud;
mod custom;
mod exp;
mod filter;
mod log;
mod random;
mod resample;
mod streaming;

pub use custom::ParticleFunction;
pub use filter::{
    particle_filter, particle_filter_into, MeasurementLikelihood, ParticleOptions, ParticleOutputs, ParticleResult,
};
pub use resample::Resampling;
pub use streaming::ParticleFilter;
