//! [`MultipleModelFilter`]: r filters run side by side with Bayes probabilities over them —
//! the interacting multiple-model (IMM) filter, the fixed model bank and the Gaussian-sum
//! filter are one loop with different mixing.

use super::mixture::{moment_match, StateMap};
use super::mode::ModeFilter;
use crate::core::dense::{ldl, ldl_solve_quad};
use crate::core::dims::Dyn;
use crate::core::Series;
use crate::error::{Error, Result};

/// How the modes interact between steps.
#[derive(Debug, Clone, PartialEq)]
pub enum Interaction {
    /// The IMM (Söderström (9.64)–(9.86)): the mode is a Markov chain with the row-stochastic
    /// r × r transition matrix p_ij = P(mode j at t+1 | mode i at t) (row-major), and each
    /// mode's time update starts from the mixture of all modes' estimates.
    Markov(Vec<f64>),
    /// A fixed bank (Söderström (9.56)–(9.63)): the mode never switches; each filter runs on
    /// its own. Also the Gaussian-sum filter (9.43)–(9.55), a bank of copies of one model.
    Fixed,
}

/// Mixture reduction of a fixed bank of one state size (the Gaussian-sum filter's
/// components), applied after each update. Söderström has none; both are off by default.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Reduction {
    /// Drop components whose weight falls below this (the largest always stays).
    pub prune_below: f64,
    /// Merge two components (moment matching) when the squared Mahalanobis distance of their
    /// means, weighted as Salmond's criterion α_i α_j / (α_i + α_j) (x_i − x_j)' P⁻¹ (x_i − x_j)
    /// with P the merged covariance, is below this.
    pub merge_within: f64,
}

/// The outputs of [`MultipleModelFilter::filter_into`], row-major, each optional: the
/// combined estimates (in mode 0's state space, n0), the mode probabilities and per-mode
/// estimates (r slices, mode j's of T × n_j and T × n_j × n_j).
#[derive(Default)]
pub struct MultipleModelOutputs<'a> {
    /// x̂(t|t) = Σ μ_j x̂_j(t|t) (9.85), T × n0.
    pub x_filt: Option<&'a mut [f64]>,
    /// P(t|t) by moment matching (9.86), T × n0 × n0.
    pub p_filt: Option<&'a mut [f64]>,
    /// x̂(t|t−1) = Σ c̄_j x̂_j(t|t−1), T × n0.
    pub x_pred: Option<&'a mut [f64]>,
    /// P(t|t−1), T × n0 × n0.
    pub p_pred: Option<&'a mut [f64]>,
    /// μ_j(t) = P(mode j at t | y(0..t)), T × r.
    pub mode_probs: Option<&'a mut [f64]>,
    /// c̄_j(t) = P(mode j at t | y(0..t−1)), T × r.
    pub mode_probs_pred: Option<&'a mut [f64]>,
    /// x̂_j(t|t) of each mode (empty: not wanted).
    pub x_filt_modes: Vec<&'a mut [f64]>,
    /// P_j(t|t) of each mode (empty: not wanted).
    pub p_filt_modes: Vec<&'a mut [f64]>,
    /// log p(y(t) | y(0..t−1)), T.
    pub loglik_t: Option<&'a mut [f64]>,
}

/// r filters (the modes) and the probabilities of the modes, one step at a time: `update(y)`
/// at step t, then `predict(u)` to t + 1, from the modes' priors x̂_j(0|−1), P_j(0|−1) and
/// the prior mode probabilities c̄(0) = μ(0|−1).
///
/// Söderström (9.59)–(9.61), (9.80)–(9.84): after the update the mode probabilities are
/// μ_j(t) = ℓ_j c̄_j / c with ℓ_j = γ(y; ŷ_j, S_j) and c = Σ ℓ_j c̄_j = p(y(t) | y(0..t−1)),
/// computed in logarithms (ℓ_j underflows easily). The IMM's time update mixes (9.70)–(9.73)
/// first; the bank's does not. Mode probabilities that vanish stay zero.
pub struct MultipleModelFilter {
    modes: Vec<Box<dyn ModeFilter>>,
    /// The mode's index among those given (the Gaussian-sum filter's reduction drops some).
    ids: Vec<usize>,
    /// The state size of each mode given.
    sizes: Vec<usize>,
    interaction: Interaction,
    /// `maps[i * r + j]`: mode i's state in mode j's space; `None` for the identity.
    maps: Vec<Option<StateMap>>,
    reduction: Reduction,
    /// μ(t) after the update at t, c̄(t) before it.
    probs: Vec<f64>,
    probs_pred: Vec<f64>,
    updated: bool,
    failed: bool,
    t: usize,
    loglik: f64,
    loglik_t: f64,
    scratch: Scratch,
}

/// Buffers of the mixing, allocated once.
#[derive(Clone)]
struct Scratch {
    /// The mixed states x̂⁰_j, P⁰_j.
    mixed_x: Vec<Vec<f64>>,
    mixed_p: Vec<Vec<f64>>,
    /// The modes' estimates mapped into one mode's space.
    mapped_x: Vec<Vec<f64>>,
    mapped_p: Vec<Vec<f64>>,
    map_work: Vec<f64>,
    /// μ_{i|j} for one j, and log(c̄_j ℓ_j).
    weights: Vec<f64>,
    log_terms: Vec<f64>,
    c_bar: Vec<f64>,
    /// Which modes' estimates are in `mapped_*` (mapped into another mode's space).
    staged: Vec<bool>,
    /// The difference of two means and an L D L' factor, for merging; x_i − x of the moments.
    diff: Vec<f64>,
    moment_diff: Vec<f64>,
    factor: Vec<f64>,
}

impl Clone for MultipleModelFilter {
    fn clone(&self) -> Self {
        MultipleModelFilter {
            modes: self.modes.iter().map(|m| m.boxed_clone()).collect(),
            ids: self.ids.clone(),
            sizes: self.sizes.clone(),
            interaction: self.interaction.clone(),
            maps: self.maps.clone(),
            reduction: self.reduction,
            probs: self.probs.clone(),
            probs_pred: self.probs_pred.clone(),
            updated: self.updated,
            failed: self.failed,
            t: self.t,
            loglik: self.loglik,
            loglik_t: self.loglik_t,
            scratch: self.scratch.clone(),
        }
    }
}

/// Tolerance on the sums of probabilities before they are renormalised.
const SUM_TOL: f64 = 1e-8;

/// Probabilities: finite, ≥ 0, summing to 1 within [`SUM_TOL`]; renormalised.
fn check_probabilities(arg: &'static str, what: &str, p: &mut [f64]) -> Result<()> {
    if let Some((i, v)) = p.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
        return Err(Error::arg(arg, format!("{what}: entry {i} is {v}, not a probability")));
    }
    let sum: f64 = p.iter().sum();
    if (sum - 1.0).abs() > SUM_TOL {
        return Err(Error::arg(arg, format!("{what}: sums to {sum}, not 1")));
    }
    p.iter_mut().for_each(|v| *v /= sum);
    Ok(())
}

impl MultipleModelFilter {
    /// The filter of the modes `modes` (each from its prior, at t = 0) with prior
    /// probabilities `mode_probs`. `maps` lists the state maps `(i, j, map)` needed between
    /// modes of different sizes: for the IMM every pair with p_ij > 0, and (j, 0) for the
    /// combined estimates (always for the IMM; for a bank, without them the combined outputs
    /// are unavailable, see [`combines`](Self::combines)).
    pub fn new(
        modes: Vec<Box<dyn ModeFilter>>,
        mut mode_probs: Vec<f64>,
        interaction: Interaction,
        maps: Vec<(usize, usize, StateMap)>,
        reduction: Reduction,
    ) -> Result<Self> {
        let r = modes.len();
        if r == 0 {
            return Err(Error::arg("models", "expected at least one model"));
        }
        let m = modes[0].n_obs();
        if let Some(j) = (1..r).find(|&j| modes[j].n_obs() != m) {
            return Err(Error::arg(
                "models",
                format!("model {j} has {} outputs, model 0 has {m}: every model sees the same y", modes[j].n_obs()),
            ));
        }
        if mode_probs.len() != r {
            return Err(Error::arg(
                "mode_probs",
                format!("expected {r} values (one per model), got {}", mode_probs.len()),
            ));
        }
        check_probabilities("mode_probs", "the prior mode probabilities", &mut mode_probs)?;
        let sizes: Vec<usize> = modes.iter().map(|m| m.n_states()).collect();
        let maps = Self::place_maps(&sizes, maps)?;
        let interaction = Self::check_interaction(interaction, &modes, &maps)?;
        if reduction.prune_below.is_nan() || reduction.merge_within.is_nan() {
            return Err(Error::arg("prune", "the reduction thresholds must not be NaN"));
        }
        if reduction != Reduction::default()
            && (interaction != Interaction::Fixed || sizes.iter().any(|&n| n != sizes[0]))
        {
            return Err(Error::arg("prune", "pruning and merging apply to a fixed bank of one state size"));
        }
        if let Some((j, why)) = (reduction.merge_within > 0.0)
            .then(|| modes.iter().enumerate().find_map(|(j, m)| m.refuses_mixing().map(|why| (j, why))))
            .flatten()
        {
            return Err(Error::arg("merge", format!("model {j}: {why} (merging replaces its estimate)")));
        }
        let n_max = sizes.iter().copied().max().unwrap_or(0);
        let scratch = Scratch {
            mixed_x: sizes.iter().map(|&n| vec![0.0; n]).collect(),
            mixed_p: sizes.iter().map(|&n| vec![0.0; n * n]).collect(),
            mapped_x: vec![vec![0.0; n_max]; r],
            mapped_p: vec![vec![0.0; n_max * n_max]; r],
            map_work: vec![0.0; n_max * n_max],
            weights: vec![0.0; r],
            log_terms: vec![0.0; r],
            c_bar: vec![0.0; r],
            staged: vec![false; r],
            diff: vec![0.0; n_max],
            moment_diff: vec![0.0; n_max],
            factor: vec![0.0; n_max * n_max],
        };
        Ok(MultipleModelFilter {
            modes,
            ids: (0..r).collect(),
            sizes,
            interaction,
            maps,
            reduction,
            probs_pred: mode_probs.clone(),
            probs: mode_probs,
            updated: false,
            failed: false,
            t: 0,
            loglik: 0.0,
            loglik_t: 0.0,
            scratch,
        })
    }

    /// The r × r table of maps, checked against the sizes.
    fn place_maps(sizes: &[usize], maps: Vec<(usize, usize, StateMap)>) -> Result<Vec<Option<StateMap>>> {
        let r = sizes.len();
        let mut table = vec![None; r * r];
        for (i, j, map) in maps {
            if i >= r || j >= r || i == j {
                return Err(Error::arg("state_maps", format!("({i}, {j}) is not a pair of two of the {r} models")));
            }
            if map.sizes() != (sizes[i], sizes[j]) {
                let (a, b) = map.sizes();
                return Err(Error::arg(
                    "state_maps",
                    format!("({i}, {j}) maps {a} states to {b}; models {i} and {j} have {} and {}", sizes[i], sizes[j]),
                ));
            }
            table[i * r + j] = Some(map);
        }
        Ok(table)
    }

    /// The transition matrix checked (and renormalised); every pair that mixes has a map.
    fn check_interaction(
        interaction: Interaction,
        modes: &[Box<dyn ModeFilter>],
        maps: &[Option<StateMap>],
    ) -> Result<Interaction> {
        let r = modes.len();
        let Interaction::Markov(mut p) = interaction else { return Ok(Interaction::Fixed) };
        if p.len() != r * r {
            return Err(Error::arg("transition", format!("expected an ({r}, {r}) matrix, got {} values", p.len())));
        }
        for i in 0..r {
            check_probabilities("transition", &format!("row {i}"), &mut p[i * r..(i + 1) * r])?;
        }
        for (j, mode) in modes.iter().enumerate() {
            if let Some(why) = mode.refuses_mixing() {
                return Err(Error::arg(
                    "models",
                    format!("model {j}: {why} (the interacting multiple-model filter mixes)"),
                ));
            }
        }
        let size = |i: usize| modes[i].n_states();
        for i in 0..r {
            for j in 0..r {
                let needed = p[i * r + j] > 0.0 || j == 0;
                if i != j && needed && size(i) != size(j) && maps[i * r + j].is_none() {
                    return Err(Error::arg(
                        "state_maps",
                        format!(
                            "models {i} and {j} have {} and {} states: give the map ({i}, {j}) of model {i}'s state into model {j}'s",
                            size(i),
                            size(j)
                        ),
                    ));
                }
            }
        }
        Ok(Interaction::Markov(p))
    }

    /// The number of modes given (r).
    pub fn n_modes(&self) -> usize {
        self.sizes.len()
    }

    /// The state size of mode `id`.
    pub fn n_states(&self, id: usize) -> usize {
        self.sizes[id]
    }

    /// The current step t.
    pub fn t(&self) -> usize {
        self.t
    }

    /// The sum of the log-likelihood terms log c(t) so far.
    pub fn loglik(&self) -> f64 {
        self.loglik
    }

    /// The log-likelihood term of the last update.
    pub fn loglik_t(&self) -> f64 {
        self.loglik_t
    }

    /// Whether the combined estimates exist: every mode's state reads in mode 0's space.
    pub fn combines(&self) -> bool {
        (0..self.sizes.len()).all(|j| self.sizes[j] == self.sizes[0] || self.maps[j * self.sizes.len()].is_some())
    }

    /// The mode probabilities of the modes given (zero for dropped components): μ(t) after
    /// an update, c̄(t) before.
    pub fn mode_probs(&self, out: &mut [f64]) {
        out.fill(0.0);
        for (&id, &p) in self.ids.iter().zip(&self.probs) {
            out[id] = p;
        }
    }

    /// Mode `id`'s current estimate (`None` once the reduction dropped it).
    pub fn mode_estimate(&self, id: usize) -> Option<(&[f64], &[f64])> {
        self.ids.iter().position(|&i| i == id).map(|k| self.modes[k].current())
    }

    /// The combined estimate Σ_j μ_j x̂_j (μ = c̄ before the update) in mode 0's space,
    /// moment matched (9.85)–(9.86). `x` has n0 values, `p` n0 × n0.
    pub fn combined(&mut self, x: &mut [f64], p: &mut [f64]) -> Result<()> {
        if !self.combines() {
            return Err(Error::arg("state_maps", "the models differ in size and have no maps into model 0's space"));
        }
        let r = self.modes.len();
        self.scratch.weights[..r].copy_from_slice(&self.probs);
        self.stage(0);
        self.moments_into(0, x, p);
        Ok(())
    }

    /// The mixture of the modes' estimates with `scratch.weights`, staged for mode
    /// `target`'s space by [`stage`](Self::stage), into (x, p).
    fn moments_into(&mut self, target: usize, x: &mut [f64], p: &mut [f64]) {
        let r = self.modes.len();
        let n = self.modes[target].n_states();
        let Scratch { mapped_x, mapped_p, weights, staged, moment_diff, .. } = &mut self.scratch;
        let modes = &self.modes;
        moment_match(
            &weights[..r],
            |i| if staged[i] { (&mapped_x[i][..n], &mapped_p[i][..n * n]) } else { modes[i].current() },
            x,
            p,
            moment_diff,
        );
    }

    /// Maps into live mode `target`'s space the estimates of the modes with a positive
    /// weight in `scratch.weights` whose map is not the identity.
    fn stage(&mut self, target: usize) {
        let (given, n_to) = (self.sizes.len(), self.modes[target].n_states());
        let to = self.ids[target];
        for i in 0..self.modes.len() {
            let map = self.maps[self.ids[i] * given + to].as_ref().filter(|_| self.scratch.weights[i] > 0.0);
            self.scratch.staged[i] = map.is_some();
            if let Some(map) = map {
                let Scratch { mapped_x, mapped_p, map_work, .. } = &mut self.scratch;
                map.apply(self.modes[i].current(), &mut mapped_x[i][..n_to], &mut mapped_p[i][..n_to * n_to], map_work);
            }
        }
    }

    fn check_usable(&self) -> Result<()> {
        if self.failed {
            return Err(Error::arg_at(
                "y",
                self.t,
                "a mode's filter failed earlier at this step; the modes are out of step, make a new filter",
            ));
        }
        Ok(())
    }

    /// The measurement update of every mode with y(t) (NaN: missing) and the mode
    /// probabilities; `inputs[j]` is mode j's u(t) (or `None`).
    pub fn update(&mut self, y: &[f64], inputs: &[Option<&[f64]>]) -> Result<()> {
        self.check_usable()?;
        if self.updated {
            return Err(Error::arg_at("y", self.t, "update called twice without a predict in between"));
        }
        self.check_inputs(inputs.len())?;
        for (k, mode) in self.modes.iter_mut().enumerate() {
            match mode.update(y, inputs[self.ids[k]]) {
                Ok(log_l) => self.scratch.log_terms[k] = self.probs_pred[k].ln() + log_l,
                Err(err) => {
                    self.failed = k > 0;
                    return Err(err.within(&format!("model {}", self.ids[k])));
                }
            }
        }
        // log c = log Σ_j c̄_j ℓ_j, by the largest term (9.84). When every term underflows (an
        // observation far out for every mode) the data cannot tell the modes apart in floating
        // point: the probabilities stay c̄ and log c = −∞, as the Kalman filter's term.
        let terms = &self.scratch.log_terms[..self.modes.len()];
        let top = terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let log_c = if top == f64::NEG_INFINITY {
            self.probs.copy_from_slice(&self.probs_pred);
            top
        } else {
            let log_c = top + terms.iter().map(|v| (v - top).exp()).sum::<f64>().ln();
            for (p, v) in self.probs.iter_mut().zip(terms) {
                *p = (v - log_c).exp();
            }
            log_c
        };
        self.loglik_t = log_c;
        self.loglik += log_c;
        self.updated = true;
        if self.reduction != Reduction::default() {
            self.reduce();
        }
        Ok(())
    }

    /// One input (or None) per model given.
    fn check_inputs(&self, count: usize) -> Result<()> {
        let given = self.sizes.len();
        if count != given {
            return Err(Error::arg("u", format!("expected one input (or None) per model, {given}, got {count}")));
        }
        Ok(())
    }

    /// The time update to t + 1: the IMM mixes first (9.70)–(9.73) and predicts each mode from
    /// its mixed state (9.74), (9.76); the bank predicts each mode from its own.
    pub fn predict(&mut self, inputs: &[Option<&[f64]>]) -> Result<()> {
        self.check_usable()?;
        self.check_inputs(inputs.len())?;
        if let Interaction::Markov(_) = self.interaction {
            self.mix();
        }
        for (k, mode) in self.modes.iter_mut().enumerate() {
            if let Err(err) = mode.predict(inputs[self.ids[k]]) {
                self.failed = true;
                return Err(err.within(&format!("model {}", self.ids[k])));
            }
        }
        self.probs_pred.copy_from_slice(&self.probs);
        self.updated = false;
        self.t += 1;
        Ok(())
    }

    /// The IMM's mixing (9.70)–(9.73): each mode's x̂(t|t), P(t|t) becomes its mixed state
    /// (all mixed from the modes' own estimates first); `probs` becomes c̄(t+1) (9.71).
    fn mix(&mut self) {
        let Interaction::Markov(trans) = &self.interaction else { return };
        let r = self.modes.len();
        for j in 0..r {
            self.scratch.c_bar[j] = (0..r).map(|i| trans[i * r + j] * self.probs[i]).sum();
        }
        for j in 0..r {
            let Interaction::Markov(trans) = &self.interaction else { return };
            let c_bar = self.scratch.c_bar[j];
            // A mode no mode can reach keeps its own state (and probability zero).
            if c_bar == 0.0 {
                continue;
            }
            for i in 0..r {
                self.scratch.weights[i] = trans[i * r + j] * self.probs[i] / c_bar;
            }
            self.stage(j);
            let (mut x, mut p) =
                (std::mem::take(&mut self.scratch.mixed_x[j]), std::mem::take(&mut self.scratch.mixed_p[j]));
            self.moments_into(j, &mut x, &mut p);
            (self.scratch.mixed_x[j], self.scratch.mixed_p[j]) = (x, p);
        }
        for (j, mode) in self.modes.iter_mut().enumerate() {
            if self.scratch.c_bar[j] > 0.0 {
                mode.set_filtered(&self.scratch.mixed_x[j], &self.scratch.mixed_p[j]);
            }
        }
        self.probs.copy_from_slice(&self.scratch.c_bar[..r]);
    }

    /// Pruning and merging of a bank's components after the update (see [`Reduction`]).
    fn reduce(&mut self) {
        let Reduction { prune_below, merge_within } = self.reduction;
        let best = (0..self.modes.len()).max_by(|&a, &b| self.probs[a].total_cmp(&self.probs[b])).unwrap_or(0);
        let mut k = 0;
        while k < self.modes.len() {
            if k != best && self.probs[k] < prune_below {
                self.remove(k);
            } else {
                k += 1;
            }
        }
        if merge_within > 0.0 {
            while let Some((a, b)) = self.closest_pair(merge_within) {
                self.merge(a, b);
            }
        }
        let total: f64 = self.probs.iter().sum();
        self.probs.iter_mut().for_each(|p| *p /= total);
    }

    fn remove(&mut self, k: usize) {
        self.modes.remove(k);
        self.ids.remove(k);
        self.probs.remove(k);
        self.probs_pred.remove(k);
    }

    /// The first pair (a, b) closer than `within` by Salmond's criterion.
    fn closest_pair(&mut self, within: f64) -> Option<(usize, usize)> {
        let r = self.modes.len();
        for a in 0..r {
            for b in a + 1..r {
                if self.salmond_distance(a, b) < within {
                    return Some((a, b));
                }
            }
        }
        None
    }

    /// α_a α_b / (α_a + α_b) (x_a − x_b)' P⁻¹ (x_a − x_b), P the merged covariance
    /// (infinite when P is singular).
    fn salmond_distance(&mut self, a: usize, b: usize) -> f64 {
        let n = self.modes[a].n_states();
        let (wa, wb) = (self.probs[a], self.probs[b]);
        if wa + wb == 0.0 {
            return 0.0;
        }
        self.merged_into_scratch(a, b);
        let (xa, xb) = (self.modes[a].current().0, self.modes[b].current().0);
        let Scratch { diff, factor, mixed_p, .. } = &mut self.scratch;
        for ((d, p), q) in diff.iter_mut().zip(xa).zip(xb) {
            *d = p - q;
        }
        if ldl::<Dyn>(factor, &mixed_p[a], n).is_err() {
            return f64::INFINITY;
        }
        wa * wb / (wa + wb) * ldl_solve_quad::<Dyn>(factor, &mut diff[..n], n)
    }

    /// The moments of components a and b with their weights into `scratch.mixed_*[a]`.
    fn merged_into_scratch(&mut self, a: usize, b: usize) {
        let (wa, wb) = (self.probs[a], self.probs[b]);
        let weights = [wa / (wa + wb), wb / (wa + wb)];
        let modes = &self.modes;
        let Scratch { mixed_x, mixed_p, moment_diff, .. } = &mut self.scratch;
        moment_match(&weights, |i| modes[[a, b][i]].current(), &mut mixed_x[a], &mut mixed_p[a], moment_diff);
    }

    /// Component a becomes the merger of a and b; b is dropped.
    fn merge(&mut self, a: usize, b: usize) {
        self.merged_into_scratch(a, b);
        self.modes[a].set_filtered(&self.scratch.mixed_x[a], &self.scratch.mixed_p[a]);
        self.probs[a] += self.probs[b];
        self.remove(b);
    }

    /// Runs the series y (T × m) with per-mode inputs (each T × k_j, or `None`), from the
    /// current state, storing the `out` fields wanted; no time update after the last step.
    pub fn filter_into(
        &mut self,
        y: Series<'_>,
        inputs: &[Option<Series<'_>>],
        out: &mut MultipleModelOutputs<'_>,
    ) -> Result<()> {
        let steps = y.steps();
        let (n0, r) = (self.sizes[0], self.sizes.len());
        self.check_inputs(inputs.len())?;
        if let Some((j, u)) =
            inputs.iter().enumerate().find_map(|(j, u)| u.as_ref().map(|u| (j, u))).filter(|(_, u)| u.steps() != steps)
        {
            return Err(Error::arg("u", format!("model {j}'s input has {} rows, y has {steps}", u.steps())));
        }
        self.check_outputs(steps, out)?;
        let mut x = vec![0.0; n0];
        let mut p = vec![0.0; n0 * n0];
        let mut probs = vec![0.0; r];
        let mut row: Vec<Option<&[f64]>> = vec![None; r];
        for t in 0..steps {
            for (slot, u) in row.iter_mut().zip(inputs) {
                *slot = u.as_ref().map(|u| u.row(t));
            }
            if out.x_pred.is_some() || out.p_pred.is_some() {
                self.combined(&mut x, &mut p)?;
                store(&mut out.x_pred, t, &x);
                store(&mut out.p_pred, t, &p);
            }
            self.mode_probs(&mut probs);
            store(&mut out.mode_probs_pred, t, &probs);
            self.update(y.row(t), &row)?;
            if out.x_filt.is_some() || out.p_filt.is_some() {
                self.combined(&mut x, &mut p)?;
                store(&mut out.x_filt, t, &x);
                store(&mut out.p_filt, t, &p);
            }
            self.mode_probs(&mut probs);
            store(&mut out.mode_probs, t, &probs);
            self.store_modes(out, t);
            if let Some(l) = out.loglik_t.as_deref_mut() {
                l[t] = self.loglik_t;
            }
            if t + 1 < steps {
                self.predict(&row)?;
            }
        }
        Ok(())
    }

    /// Every output given has its length for `steps` steps.
    fn check_outputs(&self, steps: usize, out: &MultipleModelOutputs<'_>) -> Result<()> {
        let (n0, r) = (self.sizes[0], self.sizes.len());
        let combined = [&out.x_filt, &out.p_filt, &out.x_pred, &out.p_pred];
        if combined.iter().any(|o| o.is_some()) && !self.combines() {
            return Err(Error::arg("state_maps", "the models differ in size and have no maps into model 0's space"));
        }
        let fields = [
            ("x_filt", &out.x_filt, n0),
            ("P_filt", &out.p_filt, n0 * n0),
            ("x_pred", &out.x_pred, n0),
            ("P_pred", &out.p_pred, n0 * n0),
            ("mode_probs", &out.mode_probs, r),
            ("mode_probs_pred", &out.mode_probs_pred, r),
            ("loglik_t", &out.loglik_t, 1),
        ];
        let mut lengths: Vec<(&str, usize, usize)> =
            fields.iter().filter_map(|(name, o, w)| o.as_ref().map(|o| (*name, o.len(), steps * w))).collect();
        let (xs, ps) = (&out.x_filt_modes, &out.p_filt_modes);
        if !(xs.is_empty() && ps.is_empty()) {
            if xs.len() != r || ps.len() != r {
                return Err(Error::arg(
                    "out",
                    format!("expected the estimates of all {r} models, got {} and {}", xs.len(), ps.len()),
                ));
            }
            for (j, &n) in self.sizes.iter().enumerate() {
                lengths.push(("x_filt_modes", xs[j].len(), steps * n));
                lengths.push(("P_filt_modes", ps[j].len(), steps * n * n));
            }
        }
        match lengths.into_iter().find(|(_, got, want)| got != want) {
            Some((name, got, want)) => Err(Error::arg("out", format!("{name}: expected {want} values, got {got}"))),
            None => Ok(()),
        }
    }

    /// Each mode's x̂_j(t|t), P_j(t|t) at row t (NaN for a dropped component).
    fn store_modes(&self, out: &mut MultipleModelOutputs<'_>, t: usize) {
        for (id, (xs, ps)) in out.x_filt_modes.iter_mut().zip(out.p_filt_modes.iter_mut()).enumerate() {
            let n = self.sizes[id];
            let (xs, ps) = (&mut xs[t * n..(t + 1) * n], &mut ps[t * n * n..(t + 1) * n * n]);
            match self.mode_estimate(id) {
                Some((x, p)) => {
                    xs.copy_from_slice(x);
                    ps.copy_from_slice(p);
                }
                None => {
                    xs.fill(f64::NAN);
                    ps.fill(f64::NAN);
                }
            }
        }
    }
}

/// Row t of `out` (rows of `values.len()`), when wanted.
fn store(out: &mut Option<&mut [f64]>, t: usize, values: &[f64]) {
    if let Some(out) = out.as_deref_mut() {
        let w = values.len();
        out[t * w..(t + 1) * w].copy_from_slice(values);
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::linear::model::{LinearGaussian, Matrices, StepMatrix};
    use crate::{KalmanFilter, UpdateForm};

    fn scalar_model(f: f64, q: f64) -> Arc<LinearGaussian> {
        let c = |v: f64| StepMatrix::constant(1, 1, vec![v]).unwrap();
        Arc::new(LinearGaussian::new(Matrices::new(c(f), c(1.0), c(q), c(0.25))).unwrap())
    }

    fn mode(model: &Arc<LinearGaussian>) -> Box<dyn ModeFilter> {
        Box::new(KalmanFilter::new(Arc::clone(model), &[5.0], &[1.0], UpdateForm::Joseph).unwrap())
    }

    const Y: [f64; 6] = [4.1, 3.0, f64::NAN, 2.2, 1.4, 0.3];

    #[test]
    fn identical_modes_are_the_kalman_filter() {
        let model = scalar_model(0.95, 0.01);
        let mut kf = KalmanFilter::new(Arc::clone(&model), &[5.0], &[1.0], UpdateForm::Joseph).unwrap();
        let trans = Interaction::Markov(vec![0.9, 0.1, 0.3, 0.7]);
        let mut imm = MultipleModelFilter::new(
            vec![mode(&model), mode(&model)],
            vec![0.5, 0.5],
            trans,
            vec![],
            Reduction::default(),
        )
        .unwrap();
        let (mut x, mut p) = ([0.0], [0.0]);
        for y in Y {
            kf.update(&[y], None).unwrap();
            imm.update(&[y], &[None, None]).unwrap();
            imm.combined(&mut x, &mut p).unwrap();
            assert!((x[0] - kf.x()[0]).abs() < 1e-12 && (p[0] - kf.p()[0]).abs() < 1e-12);
            assert!((imm.loglik_t() - kf.loglik_t()).abs() < 1e-12);
            kf.predict(None).unwrap();
            imm.predict(&[None, None]).unwrap();
        }
    }

    #[test]
    fn the_bank_finds_the_model_of_the_data() {
        let (slow, fast) = (scalar_model(0.95, 0.01), scalar_model(0.2, 0.01));
        let mut bank = MultipleModelFilter::new(
            vec![mode(&slow), mode(&fast)],
            vec![0.5, 0.5],
            Interaction::Fixed,
            vec![],
            Reduction::default(),
        )
        .unwrap();
        let mut x: f64 = 5.0;
        for _ in 0..30 {
            bank.update(&[x], &[None, None]).unwrap();
            bank.predict(&[None, None]).unwrap();
            x *= 0.95;
        }
        let mut probs = [0.0; 2];
        bank.mode_probs(&mut probs);
        assert!(probs[0] > 0.999, "{probs:?}");
    }

    #[test]
    fn bad_probabilities_and_sizes_are_named() {
        let model = scalar_model(0.95, 0.01);
        let make = |probs: Vec<f64>, trans: Vec<f64>| {
            MultipleModelFilter::new(
                vec![mode(&model), mode(&model)],
                probs,
                Interaction::Markov(trans),
                vec![],
                Reduction::default(),
            )
            .err()
            .map(|e| e.to_string())
        };
        assert!(make(vec![0.5, 0.6], vec![1.0, 0.0, 0.0, 1.0]).unwrap().starts_with("mode_probs"));
        assert!(make(vec![0.5, 0.5], vec![0.9, 0.2, 0.0, 1.0]).unwrap().contains("row 0"));
        assert!(make(vec![0.5, 0.5], vec![f64::NAN, 1.0, 0.0, 1.0]).unwrap().starts_with("transition"));
        assert!(make(vec![0.5, 0.5], vec![1.0, 0.0]).unwrap().starts_with("transition"));
        assert!(make(vec![0.5, 0.5], vec![0.5, 0.5, 0.5, 0.5]).is_none());
    }
}
