//! The multiple-model filter (IMM, fixed bank, Gaussian sum) for Python: `kfast.IMMFilter`,
//! `kfast.imm_filter`, `kfast.model_bank` and `kfast.gaussian_sum` wrap it.

use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::nonlinear::PyNonlinearKalmanFilter;
use super::streaming::PyKalmanFilter;
use super::{data, series_of, to_array, KfastError, OutArrays};
use crate::multiple::{Interaction, ModeFilter, MultipleModelFilter, MultipleModelOutputs, Reduction, StateMap};
use crate::Series;

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;

/// An estimate (x, P) as NumPy arrays.
type Estimate<'py> = (Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>);

/// A map `(i, j, A, b, Sigma)` of model i's state into model j's space.
type MapSpec<'py> = (usize, usize, Array<'py>, Option<Array<'py>>, Option<Array<'py>>);

#[pyclass(module = "kfast._kfast", name = "MultipleModelFilter")]
pub(super) struct PyMultipleModelFilter {
    inner: MultipleModelFilter,
}

/// The mode filter inside a streaming `KalmanFilter` or EKF/UKF object (a copy: the object
/// given stays as it is).
fn mode_filter(j: usize, filter: &Bound<'_, PyAny>) -> PyResult<Box<dyn ModeFilter>> {
    if let Ok(kf) = filter.cast::<PyKalmanFilter>() {
        return Ok(Box::new(kf.borrow().inner.clone()));
    }
    if let Ok(nl) = filter.cast::<PyNonlinearKalmanFilter>() {
        return Ok(Box::new(nl.borrow().inner.clone()));
    }
    Err(KfastError::new_err(format!(
        "models: model {j} is a {}, not a LinearGaussian or NonlinearModel filter",
        filter.get_type().name()?
    )))
}

fn state_map(
    n_from: usize,
    n_to: usize,
    (a, b, cov): (&Array<'_>, Option<&Array<'_>>, Option<&Array<'_>>),
) -> PyResult<StateMap> {
    let vec = |arg: &str, x: &Array<'_>, ndim: usize| data(arg, x, ndim).map(|s| s.to_vec());
    Ok(StateMap::new(
        n_from,
        n_to,
        vec("state_maps: A", a, 2)?,
        b.map(|b| vec("state_maps: b", b, 1)).transpose()?,
        cov.map(|c| vec("state_maps: Sigma", c, 2)).transpose()?,
    )?)
}

/// Per-model input rows `u` (a list of r arrays or None).
fn input_rows<'a>(u: &'a [Option<Array<'_>>]) -> PyResult<Vec<Option<&'a [f64]>>> {
    u.iter().map(|u| u.as_ref().map(|u| data("u", u, 1)).transpose()).collect()
}

#[pymethods]
impl PyMultipleModelFilter {
    /// `filters`: the modes' streaming filters (`KalmanFilter`, or the `_core` of an
    /// `ExtendedKalmanFilter`/`UnscentedKalmanFilter`), each at its prior; `transition`
    /// (r × r) for the IMM, `None` for a fixed bank; `prune`/`merge` the bank's reduction.
    #[new]
    #[pyo3(signature = (filters, mode_probs, transition=None, state_maps=Vec::new(), prune=0.0, merge=0.0))]
    fn new(
        filters: &Bound<'_, PyList>,
        mode_probs: Vec<f64>,
        transition: Option<Array<'_>>,
        state_maps: Vec<MapSpec<'_>>,
        prune: f64,
        merge: f64,
    ) -> PyResult<Self> {
        let modes: Vec<Box<dyn ModeFilter>> =
            filters.iter().enumerate().map(|(j, f)| mode_filter(j, &f)).collect::<PyResult<_>>()?;
        let sizes: Vec<usize> = modes.iter().map(|m| m.n_states()).collect();
        let mut maps = Vec::with_capacity(state_maps.len());
        for (i, j, a, b, cov) in &state_maps {
            let (Some(&n_from), Some(&n_to)) = (sizes.get(*i), sizes.get(*j)) else {
                return Err(KfastError::new_err(format!(
                    "state_maps: ({i}, {j}) is not a pair of the {} models",
                    sizes.len()
                )));
            };
            maps.push((*i, *j, state_map(n_from, n_to, (a, b.as_ref(), cov.as_ref()))?));
        }
        let interaction = match transition {
            Some(p) => Interaction::Markov(data("transition", &p, 2)?.to_vec()),
            None => Interaction::Fixed,
        };
        let reduction = Reduction { prune_below: prune, merge_within: merge };
        Ok(PyMultipleModelFilter { inner: MultipleModelFilter::new(modes, mode_probs, interaction, maps, reduction)? })
    }

    /// The update of every mode with y(t); `u` one input (or None) per model.
    fn update(&mut self, py: Python<'_>, y: Array<'_>, u: Vec<Option<Array<'_>>>) -> PyResult<()> {
        let y = data("y", &y, 1)?;
        let u = input_rows(&u)?;
        let inner = &mut self.inner;
        Ok(py.detach(|| inner.update(y, &u))?)
    }

    /// The time update to t + 1 (mixing first, for the IMM).
    fn predict(&mut self, py: Python<'_>, u: Vec<Option<Array<'_>>>) -> PyResult<()> {
        let u = input_rows(&u)?;
        let inner = &mut self.inner;
        Ok(py.detach(|| inner.predict(&u))?)
    }

    /// The combined estimate (x, P) in model 0's space, or None when the models differ in
    /// size without maps into it.
    fn combined<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Estimate<'py>>> {
        if !self.inner.combines() {
            return Ok(None);
        }
        let n = self.inner.n_states(0);
        let (mut x, mut p) = (vec![0.0; n], vec![0.0; n * n]);
        self.inner.combined(&mut x, &mut p)?;
        Ok(Some((to_array(py, &x, &[n])?, to_array(py, &p, &[n, n])?)))
    }

    /// Model j's current estimate (x, P), or None (a component the reduction dropped).
    fn mode_estimate<'py>(&self, py: Python<'py>, j: usize) -> PyResult<Option<Estimate<'py>>> {
        if j >= self.inner.n_modes() {
            return Err(KfastError::new_err(format!("j: {j} is not one of the {} models", self.inner.n_modes())));
        }
        self.inner
            .mode_estimate(j)
            .map(|(x, p)| Ok((to_array(py, x, &[x.len()])?, to_array(py, p, &[x.len(), x.len()])?)))
            .transpose()
    }

    #[getter]
    fn mode_probs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let mut probs = vec![0.0; self.inner.n_modes()];
        self.inner.mode_probs(&mut probs);
        to_array(py, &probs, &[probs.len()])
    }

    #[getter]
    fn t(&self) -> usize {
        self.inner.t()
    }

    #[getter]
    fn loglik(&self) -> f64 {
        self.inner.loglik()
    }

    #[getter]
    fn n_modes(&self) -> usize {
        self.inner.n_modes()
    }

    /// Runs y (T, m) from the current state; `u` one (T, k_j) array or None per model;
    /// `outputs` the combined fields wanted and whether the per-mode ones ("modes"). Returns a
    /// dict of arrays (per-mode ones as lists) and the log-likelihood (of a new filter: the
    /// total so far).
    fn filter<'py>(
        &mut self,
        py: Python<'py>,
        y: Array<'py>,
        u: Vec<Option<Array<'py>>>,
        outputs: Vec<String>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let y = series_of("y", &y)?;
        let inputs: Vec<Option<Series<'_>>> =
            u.iter().map(|u| u.as_ref().map(|u| series_of("u", u)).transpose()).collect::<PyResult<_>>()?;
        let (steps, r) = (y.steps(), self.inner.n_modes());
        let combines = self.inner.combines();
        let n0 = self.inner.n_states(0);
        let known = ["x_filt", "P_filt", "x_pred", "P_pred", "mode_probs", "mode_probs_pred", "loglik_t", "modes"];
        if let Some(bad) = outputs.iter().find(|o| !known.contains(&o.as_str())) {
            return Err(KfastError::new_err(format!("outputs: unknown field {bad:?}; choose from {known:?}")));
        }
        let wanted = |name: &str| outputs.iter().any(|o| o == name);
        let shapes: [(&'static str, Vec<usize>, bool); 7] = [
            ("x_filt", vec![steps, n0], combines),
            ("P_filt", vec![steps, n0, n0], combines),
            ("x_pred", vec![steps, n0], combines),
            ("P_pred", vec![steps, n0, n0], combines),
            ("mode_probs", vec![steps, r], true),
            ("mode_probs_pred", vec![steps, r], true),
            ("loglik_t", vec![steps], true),
        ];
        let chosen: Vec<(&'static str, &[usize])> = shapes
            .iter()
            .filter(|(name, _, ok)| *ok && wanted(name))
            .map(|(name, s, _)| (*name, s.as_slice()))
            .collect();
        let mut combined = OutArrays::new(py, "y", &chosen)?;
        let sizes: Vec<usize> = (0..r).map(|j| self.inner.n_states(j)).collect();
        let mode_shapes: Vec<Vec<usize>> = if wanted("modes") {
            sizes.iter().flat_map(|&n| [vec![steps, n], vec![steps, n, n]]).collect()
        } else {
            Vec::new()
        };
        let mode_specs: Vec<(&'static str, &[usize])> = mode_shapes.iter().map(|s| ("mode", s.as_slice())).collect();
        let mut per_mode = OutArrays::new(py, "y", &mode_specs)?;
        let names = combined.names.clone();
        let mut slices = combined.slices()?;
        let mut mode_slices = per_mode.slices()?;
        let mut out = MultipleModelOutputs::default();
        for (name, slice) in names.iter().zip(slices.iter_mut()) {
            let slot = match *name {
                "x_filt" => &mut out.x_filt,
                "P_filt" => &mut out.p_filt,
                "x_pred" => &mut out.x_pred,
                "P_pred" => &mut out.p_pred,
                "mode_probs" => &mut out.mode_probs,
                "mode_probs_pred" => &mut out.mode_probs_pred,
                _ => &mut out.loglik_t,
            };
            *slot = Some(&mut **slice);
        }
        for (k, slice) in mode_slices.iter_mut().enumerate() {
            if k % 2 == 0 {
                out.x_filt_modes.push(&mut **slice);
            } else {
                out.p_filt_modes.push(&mut **slice);
            }
        }
        let inner = &mut self.inner;
        py.detach(|| inner.filter_into(y, &inputs, &mut out))?;
        drop(out);
        drop(slices);
        drop(mode_slices);
        let dict = combined.into_dict(py)?;
        dict.set_item("loglik", self.inner.loglik())?;
        if wanted("modes") {
            let arrays = per_mode.arrays;
            let xs: Vec<_> = arrays.iter().step_by(2).cloned().collect();
            let ps: Vec<_> = arrays.iter().skip(1).step_by(2).cloned().collect();
            dict.set_item("x_filt_modes", xs)?;
            dict.set_item("P_filt_modes", ps)?;
        }
        Ok(dict)
    }
}
