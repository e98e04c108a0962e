//! The filter's outputs, declared once: [`FilterResult`] (owned), [`FilterOutputs`] (borrowed
//! buffers, each optional) and [`FILTER_FIELDS`] (the names and shapes the Python results use)
//! all come from the one table in `filter_outputs!` below.

use super::step::Workspace;
use crate::core::dims::Dims;
use crate::error::{Error, Result};

/// A dimension of an output array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Dim {
    /// The number of time steps T.
    Steps,
    /// The state size n.
    States,
    /// The output size m.
    Outputs,
}

/// One output of the filter: its name (as in Python and in error messages) and its shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct OutputField {
    /// The name, e.g. `"P_filt"`.
    pub name: &'static str,
    /// The shape, e.g. `[Steps, States, States]`.
    pub shape: &'static [Dim],
}

impl OutputField {
    /// The shape for T steps, n states and m outputs.
    pub fn shape_for(&self, steps: usize, n: usize, m: usize) -> Vec<usize> {
        self.shape
            .iter()
            .map(|d| match d {
                Dim::Steps => steps,
                Dim::States => n,
                Dim::Outputs => m,
            })
            .collect()
    }

    /// The number of entries for T steps, n states and m outputs.
    pub fn len_for(&self, steps: usize, n: usize, m: usize) -> usize {
        self.shape_for(steps, n, m).iter().product()
    }
}

macro_rules! filter_outputs {
    ($( $(#[doc = $doc:literal])* $field:ident: $name:literal [$($dim:ident),*]; )*) => {
        /// Everything the filter computes, row-major, for `T` steps, `n` states and `m` outputs.
        #[derive(Debug, Clone, PartialEq)]
        #[non_exhaustive]
        pub struct FilterResult {
            $( $(#[doc = $doc])* pub $field: Vec<f64>, )*
            /// Total log-likelihood `Σ loglik_t` (Söderström (6.142)), summed with one
            /// logarithm at the end (equal to the sum of the terms to rounding).
            pub loglik: f64,
        }

        /// Output buffers for [`filter_into`](super::filter_into), each of the size documented
        /// on [`FilterResult`]; `None` skips that output (it is then neither computed into
        /// memory nor copied). Given buffers are written in full.
        #[derive(Debug, Default)]
        #[non_exhaustive]
        pub struct FilterOutputs<'a> {
            $( $(#[doc = $doc])* pub $field: Option<&'a mut [f64]>, )*
        }

        /// The filter's per-step and final outputs, by name and shape, in [`FilterResult`]'s
        /// order (`loglik`, a number, is not among them).
        pub const FILTER_FIELDS: &[OutputField] =
            &[$( OutputField { name: $name, shape: &[$(Dim::$dim),*] }, )*];

        impl FilterResult {
            pub(crate) fn zeros(steps: usize, n: usize, m: usize) -> Self {
                let mut fields = FILTER_FIELDS.iter().map(|f| vec![0.0; f.len_for(steps, n, m)]);
                FilterResult { $( $field: fields.next().unwrap_or_default(), )* loglik: 0.0 }
            }

            /// All outputs, as buffers for [`filter_into`](super::filter_into).
            pub fn outputs(&mut self) -> FilterOutputs<'_> {
                FilterOutputs { $( $field: Some(&mut self.$field), )* }
            }
        }

        impl FilterOutputs<'_> {
            /// The same buffers, borrowed for a shorter time (to pass on and use again).
            pub(crate) fn reborrow(&mut self) -> FilterOutputs<'_> {
                FilterOutputs { $( $field: self.$field.as_deref_mut(), )* }
            }
        }

        impl<'a> FilterOutputs<'a> {
            /// The buffer slots with their fields, in [`FILTER_FIELDS`]' order.
            pub fn slots(&mut self) -> impl Iterator<Item = (&'static OutputField, &mut Option<&'a mut [f64]>)> {
                FILTER_FIELDS.iter().zip([$( &mut self.$field, )*])
            }
        }
    };
}

filter_outputs! {
    /// `x̂(t|t−1)`, `(T, n)`.
    x_pred: "x_pred" [Steps, States];
    /// `P(t|t−1)`, `(T, n, n)`.
    p_pred: "P_pred" [Steps, States, States];
    /// `x̂(t|t)`, `(T, n)`.
    x_filt: "x_filt" [Steps, States];
    /// `P(t|t)`, `(T, n, n)`.
    p_filt: "P_filt" [Steps, States, States];
    /// Innovations `e(t) = y(t) − H x̂(t|t−1) − D u(t)`, `(T, m)`, NaN where `y` is missing.
    innov: "innov" [Steps, Outputs];
    /// Innovation (forecast error) covariance `S(t) = H P(t|t−1) H' + R` of all components,
    /// `(T, m, m)`.
    innovation_cov: "S" [Steps, Outputs, Outputs];
    /// Filter gain `K(t) = P(t|t−1) H' S⁻¹`, `(T, n, m)`; zero columns for missing components.
    gain: "K" [Steps, States, Outputs];
    /// Predictor gain `K_pred(t) = (F P(t|t−1) H' + N) S⁻¹`, `(T, n, m)`.
    gain_pred: "K_pred" [Steps, States, Outputs];
    /// Log-likelihood term of each step, `(T,)` (0 where nothing is observed).
    loglik_t: "loglik_t" [Steps];
    /// `x̂(T|T−1)`, the prediction past the last observation, `(n,)`.
    x_next: "x_next" [States];
    /// `P(T|T−1)`, `(n, n)`.
    p_next: "P_next" [States, States];
}

impl FilterOutputs<'_> {
    /// An error naming the first given buffer whose size is not its field's.
    pub(crate) fn check_sizes(&mut self, steps: usize, n: usize, m: usize) -> Result<()> {
        for (field, slot) in self.slots() {
            let want = field.len_for(steps, n, m);
            if let Some(buf) = slot {
                if buf.len() != want {
                    return Err(Error::arg(
                        field.name,
                        format!("output buffer has {} entries, needs {want}", buf.len()),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Stores x̂(t|t−1), P(t|t−1) (before the step) in row t.
    #[inline(always)]
    pub(crate) fn store_prior(&mut self, t: usize, x_pred: &[f64], p_pred: &[f64]) {
        store(&mut self.x_pred, t, x_pred);
        store(&mut self.p_pred, t, p_pred);
    }

    /// Stores the outputs of the step the workspace has just made in row t.
    #[inline(always)]
    pub(crate) fn store_step<D: Dims>(&mut self, t: usize, ws: &Workspace<D>) {
        store(&mut self.x_filt, t, ws.x_filt());
        store(&mut self.p_filt, t, ws.p_filt());
        store(&mut self.innov, t, ws.innov());
        store(&mut self.innovation_cov, t, ws.innovation_cov());
        store(&mut self.gain, t, ws.gain());
        store(&mut self.gain_pred, t, ws.gain_pred());
        // Only when asked for: the term's logarithm is ~10% of a small step.
        if let Some(o) = self.loglik_t.as_deref_mut() {
            o[t] = ws.loglik_t();
        }
    }

    /// Stores the outputs of a step that are given as slices (the nonlinear filters, whose
    /// workspaces are their own): x̂(t|t), P(t|t), the innovation, S, K and the log-likelihood
    /// term. `K_pred` is not one of them: such a filter refuses it ([`Self::refuse_gain_pred`]).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn store_values(
        &mut self,
        t: usize,
        x_filt: &[f64],
        p_filt: &[f64],
        innov: &[f64],
        innovation_cov: &[f64],
        gain: &[f64],
        loglik_t: f64,
    ) {
        store(&mut self.x_filt, t, x_filt);
        store(&mut self.p_filt, t, p_filt);
        store(&mut self.innov, t, innov);
        store(&mut self.innovation_cov, t, innovation_cov);
        store(&mut self.gain, t, gain);
        if let Some(o) = self.loglik_t.as_deref_mut() {
            o[t] = loglik_t;
        }
    }

    /// Stores the predictor gain of step t (given as a slice).
    pub(crate) fn store_gain_pred(&mut self, t: usize, gain_pred: &[f64]) {
        store(&mut self.gain_pred, t, gain_pred);
    }

    /// An error if the predictor gain `K_pred` was asked for (a filter that does not compute it).
    pub(crate) fn refuse_gain_pred(&self, filter: &str) -> Result<()> {
        if self.gain_pred.is_some() {
            return Err(Error::arg("outputs", format!("K_pred is not computed by the {filter}")));
        }
        Ok(())
    }

    /// Stores x̂(T|T−1), P(T|T−1).
    pub(crate) fn store_next(&mut self, x_next: &[f64], p_next: &[f64]) {
        store(&mut self.x_next, 0, x_next);
        store(&mut self.p_next, 0, p_next);
    }
}

/// Row t of an optional output: `out[t * len..(t + 1) * len] = src`.
#[inline(always)]
fn store(out: &mut Option<&mut [f64]>, t: usize, src: &[f64]) {
    if let Some(o) = out.as_deref_mut() {
        let len = src.len();
        o[t * len..(t + 1) * len].copy_from_slice(src);
    }
}
