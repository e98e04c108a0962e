//! The model-agnostic core shared by every family: small dense kernels, compile-time and
//! run-time sizes, validators, allocation-size checks, faer bridging and the real Schur form.

pub(crate) mod alloc;
pub mod batch;
pub(crate) mod dense;
pub(crate) mod dims;
pub(crate) mod gaussian;
pub(crate) mod home;
pub mod isa;
pub(crate) mod mat;
#[cfg(target_arch = "x86_64")]
pub(crate) mod rows4;
pub(crate) mod schur;
pub(crate) mod series;
pub(crate) mod validate;

pub use series::Series;
