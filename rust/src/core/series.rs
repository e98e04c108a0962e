//! [`Series`]: the observations `y` or inputs `u` of a whole series, borrowed.

use crate::error::{Error, Result};

/// A borrowed row-major `(steps, width)` array: the observations `y` or the inputs `u`.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    data: &'a [f64],
    steps: usize,
    width: usize,
}

impl<'a> Series<'a> {
    /// Wraps `data` as `steps` rows of `width` numbers; `arg` names it in errors.
    pub fn new(arg: &'static str, data: &'a [f64], steps: usize, width: usize) -> Result<Self> {
        if steps.checked_mul(width) != Some(data.len()) {
            return Err(Error::arg(arg, format!("data length {} is not {steps} × {width}", data.len())));
        }
        Ok(Series { data, steps, width })
    }

    /// Row `t`.
    #[inline]
    pub fn row(&self, t: usize) -> &'a [f64] {
        &self.data[t * self.width..(t + 1) * self.width]
    }

    /// Number of rows (time steps).
    pub fn steps(&self) -> usize {
        self.steps
    }
}

impl Series<'_> {
    /// Numbers per row.
    pub fn width(&self) -> usize {
        self.width
    }
}
