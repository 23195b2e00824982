//! [`ThermalProblem`]: one bar's model bound to its series, its terms and zero segments, the
//! memo of computed columns, and what the rest of the crate asks of it (names, starts, zeros).
//!
//! Separate from the effect vocabulary in `model` (what an effect is) because this is one bar's
//! instance of a model, ready for the fitting engine.

use super::bind::bind;
use super::channels::Channel;
use super::channels::ChannelError;
use super::identifiable::{identifiable_effects, NotIdentifiable};
use super::Effect;
use crate::series::BarSeries;
use std::sync::Arc;
use std::sync::Mutex;

/// One column source of an effect bound to one bar's data: its input channel and its column
/// scale. An effect binds to one term, `air_gradient` to one per base path.
#[derive(Debug, Clone)]
pub(super) struct BoundTerm {
    pub(super) effect: Effect,
    /// Name of the term's gain (with its unit).
    pub(super) gain_name: String,
    pub(super) input: Channel,
    /// Multiplies the (lagged) input per sample, e.g. `-I_min / 1000`; `None` = 1.
    pub(super) scale: Option<Vec<f64>>,
    pub(super) kind: TermKind,
    /// The term uses the time constant of another effect's term instead of its own.
    pub(super) shares_tau_of: Option<Effect>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum TermKind {
    Lag,
    Rate,
    Level,
    /// `exp(-(t - mount start)/tau)` within each mount.
    Settling,
    /// `exp(-(t - from_s)/tau)` from `from_s` on, 1 before: the decay of an unknown deviation
    /// of a lag's state from the steady state it is assumed to start in, scaled to its value at
    /// `from_s` (the first fitted reading). Before `from_s` nothing is fitted and the deviation
    /// is held there, not extrapolated backwards.
    Decay {
        from_s: f64,
    },
    /// The decay of a base lag's departure from steady state when the logging started:
    /// `exp(-(t - t_ref)/tau)` with the path's time constant, `t_ref` the bar's first fitted
    /// sample ([`ThermalProblem::initial_state_reference_s`]).
    InitialState,
}

/// One bar's thermal model, ready for the fitting engine.
pub struct ThermalProblem<'a> {
    pub(super) series: &'a BarSeries,
    effects: Vec<Effect>,
    /// The terms of `effects` this bar's data cannot determine, left out of the problem
    /// ([`not_identifiable`]).
    not_identifiable: Vec<NotIdentifiable>,
    /// Where the initial-state columns are 1: the bar's first fitted sample, seconds.
    pub(super) initial_state_reference_s: f64,
    pub(super) terms: Vec<BoundTerm>,
    /// Indices (into `terms`) of the terms with a time constant of their own, in `theta` order.
    pub(super) tau_terms: Vec<usize>,
    /// Per term: index (into `terms`) of the term whose time constant it uses (itself for a
    /// term with its own; `None` for a term without one).
    pub(super) tau_source: Vec<Option<usize>>,
    pub(super) y: Vec<f64>,
    /// Zero column of each zero segment: only segments with fitted samples get one (a check
    /// mount is a zero segment without fitted samples; its column would be all zeros).
    pub(super) zero_columns: Vec<Option<usize>>,
    pub(super) n_zero_columns: usize,
    /// Zero column of each fitted sample (`None`: its segment has no zero).
    pub(super) row_zero: Vec<Option<usize>>,
    /// Square root of each fitted sample's weight ([`BarSeries::weight`]): every row the engine
    /// sees is multiplied by it, so that its least squares are the weighted ones.
    pub(super) sqrt_weight: Vec<f64>,
    /// Sum of the fitted samples' weights in each zero column.
    pub(super) zero_weight: Vec<f64>,
    /// The fitted rows of each zero column lie within this range (first row, one past the
    /// last): a column masked to one zero column (`settling`'s amplitude per mount) is written
    /// there alone, not over the whole series.
    pub(super) zero_rows: Vec<std::ops::Range<usize>>,
    /// The fitted rows as runs of one zero column each (`None`: rows without one), in row
    /// order: the basis is demeaned run by run (`write_row_column`), slices the compiler
    /// vectorises; testing `row_zero` row by row instead costs about a tenth of the
    /// machine-tool log's nightly CPU.
    pub(super) zero_runs: Vec<(std::ops::Range<usize>, Option<usize>)>,
    /// The last column (and `ln tau` derivative) computed for each term with a time constant,
    /// keyed by the bits of its tau: a solver asks for the basis and then its derivatives at the
    /// same `theta`, and a 1-D search moves one time constant while the others stay put, so
    /// most lag recursions (the cost of a fit) are repeats. Results are the same bits.
    pub(super) memo: SlotMemo<u64, LagColumns>,
    /// The last engine column written for each unmasked gain column of the basis
    /// ([`ThermalProblem::write_row_column`]), keyed by the bits of its term's tau (`None`: a
    /// term without one): a 1-D search or a screen moves one time constant while the other
    /// columns stay put, and gathering, demeaning and weighing every column again at each
    /// evaluation was the largest single cost of the diagnosis's fits. Same bits.
    pub(super) row_memo: SlotMemo<Option<u64>, Arc<Vec<f64>>>,
    /// Per term: the first of the terms that lag the same input on the same time constant, when
    /// there are two or more (`None` otherwise). `heat:` binds one such term per base path,
    /// differing only in their scale: their common lag is computed once
    /// ([`ThermalProblem::lag_memo`]), where the per-term memo would run its recursion twice.
    pub(super) lag_group: Vec<Option<usize>>,
    /// The unscaled lag and `ln tau` derivative of each [`ThermalProblem::lag_group`]'s first
    /// term, keyed by the bits of its tau. Same bits as a lag of its own.
    pub(super) lag_memo: SlotMemo<u64, LagColumns>,
}

/// A column on the bar's whole timeline and its `ln tau` derivative, as memoised.
pub(super) type LagColumns = (Arc<Vec<f64>>, Arc<Vec<f64>>);

/// The last value computed at each index (a term, a gain column) and the key it was computed
/// at (the bits of a time constant): [`ThermalProblem::memo`], [`ThermalProblem::lag_memo`] and
/// [`ThermalProblem::row_memo`]. A poisoned lock is taken as it is: a slot is written whole.
pub(super) struct SlotMemo<K, V>(Mutex<Vec<Option<(K, V)>>>);

impl<K: PartialEq, V: Clone> SlotMemo<K, V> {
    fn new() -> Self {
        SlotMemo(Mutex::new(Vec::new()))
    }

    /// The value at `index`, if it was computed at `key`.
    pub(super) fn get(&self, index: usize, key: &K) -> Option<V> {
        let slots = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let (k, v) = slots.get(index)?.as_ref()?;
        (k == key).then(|| v.clone())
    }

    /// Keep `value`, computed at `key`, at `index`.
    pub(super) fn put(&self, index: usize, key: K, value: V) {
        let mut slots = self.0.lock().unwrap_or_else(|p| p.into_inner());
        if slots.len() <= index {
            slots.resize_with(index + 1, || None);
        }
        slots[index] = Some((key, value));
    }

    /// How many indices hold a value.
    #[cfg(test)]
    pub(super) fn filled(&self) -> usize {
        let slots = self.0.lock().unwrap_or_else(|p| p.into_inner());
        slots.iter().flatten().count()
    }
}

/// A term's column on the bar's whole timeline and its `ln tau` derivative, shared with the
/// memo (a basis reads them, it does not copy them).
pub(super) type TermColumn = (Arc<Vec<f64>>, Option<Arc<Vec<f64>>>);

/// [`ThermalProblem::lag_group`] of `terms`: a lag term's first twin (same input, same time
/// constant), for the terms that have one or are one.
fn lag_groups(terms: &[BoundTerm], tau_source: &[Option<usize>]) -> Vec<Option<usize>> {
    let twins = |i: usize, j: usize| {
        i != j
            && terms[i].kind == TermKind::Lag
            && terms[j].kind == TermKind::Lag
            && tau_source[i].is_some()
            && tau_source[i] == tau_source[j]
            && terms[i].input == terms[j].input
    };
    (0..terms.len())
        .map(|j| {
            let first = (0..j).find(|&i| twins(i, j)).unwrap_or(j);
            (first != j || (j + 1..terms.len()).any(|k| twins(j, k))).then_some(first)
        })
        .collect()
}

/// A model that cannot be built for a bar.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ModelError {
    /// An effect's channel term could not be built.
    #[error("effect {effect}: {source}")]
    Channel {
        /// The effect's name.
        effect: String,
        /// Why.
        source: ChannelError,
    },
    /// The effect acts through the base paths, and the model has neither.
    #[error("effect {effect} acts through the base paths: add fixed_part or scale to the model")]
    NoBasePath {
        /// The effect's name.
        effect: String,
    },
}

impl<'a> ThermalProblem<'a> {
    /// `effects` bound to `series`. Terms the series cannot determine are left out and listed
    /// (`ThermalProblem::not_identifiable`): the scale's (`beta`, `tau_S`) when every fitted
    /// mount has the same travel `I_p`.
    pub fn new(series: &'a BarSeries, effects: &[Effect]) -> Result<Self, ModelError> {
        let (bound_effects, not_identifiable) = identifiable_effects(series, effects);
        let mut terms = Vec::with_capacity(2 * effects.len() + 2);
        for e in &bound_effects {
            let bound = bind(series, e, &bound_effects).map_err(|source| ModelError::Channel {
                effect: e.name(),
                source,
            })?;
            if bound.is_empty() {
                return Err(ModelError::NoBasePath { effect: e.name() });
            }
            terms.extend(bound);
        }
        let tau_terms: Vec<usize> = terms
            .iter()
            .enumerate()
            .filter(|(_, t)| t.shares_tau_of.is_none() && t.effect.tau_name().is_some())
            .map(|(i, _)| i)
            .collect();
        let tau_source: Vec<Option<usize>> = terms
            .iter()
            .enumerate()
            .map(|(j, t)| match &t.shares_tau_of {
                None => tau_terms.contains(&j).then_some(j),
                Some(owner) => tau_terms
                    .iter()
                    .copied()
                    .find(|&i| terms[i].effect == *owner),
            })
            .collect();
        let lag_group = lag_groups(&terms, &tau_source);
        let y_raw: Vec<f64> = series.fit_index.iter().map(|&i| series.y_um[i]).collect();
        let mut fitted = vec![false; series.n_zero_segments];
        for &i in &series.fit_index {
            if let Some(s) = series.zero_segment[i] {
                fitted[s as usize] = true;
            }
        }
        let mut n_zero_columns = 0;
        let zero_columns: Vec<Option<usize>> = fitted
            .iter()
            .map(|&f| {
                f.then(|| {
                    n_zero_columns += 1;
                    n_zero_columns - 1
                })
            })
            .collect();
        let mut problem = ThermalProblem {
            series,
            effects: effects.to_vec(),
            not_identifiable,
            initial_state_reference_s: series.fit_index.first().map_or(0.0, |&i| series.t_s[i]),
            terms,
            tau_terms,
            tau_source,
            y: Vec::new(),
            row_zero: series
                .fit_index
                .iter()
                .map(|&i| series.zero_segment[i].and_then(|s| zero_columns[s as usize]))
                .collect(),
            zero_columns,
            n_zero_columns,
            sqrt_weight: series
                .fit_index
                .iter()
                .map(|&i| series.weight[i].sqrt())
                .collect(),
            zero_weight: Vec::new(),
            zero_rows: Vec::new(),
            zero_runs: Vec::new(),
            memo: SlotMemo::new(),
            row_memo: SlotMemo::new(),
            lag_group,
            lag_memo: SlotMemo::new(),
        };
        problem.zero_weight = problem.segment_weights();
        problem.zero_rows = problem.segment_rows();
        problem.zero_runs = problem.segment_runs();
        problem.y = problem.demean(&y_raw);
        Ok(problem)
    }

    /// Fit these observations (one per fitted sample) instead of the bar's reading: the
    /// diagnosis explains a residual with a single channel this way.
    pub fn with_observations(mut self, y: Vec<f64>) -> Self {
        assert_eq!(y.len(), self.y.len(), "one observation per fitted sample");
        self.y = self.demean(&y);
        self
    }

    /// Zero column of each fitted sample (`None`: a sample whose segment has no zero).
    pub(super) fn fit_row_zero(&self, r: usize) -> Option<usize> {
        self.row_zero[r]
    }

    /// Subtract each zero segment's weighted mean over the fitted samples (`v` indexed by fitted
    /// sample), then weigh each row by the square root of its sample's weight: a row as the
    /// engine sees it.
    ///
    /// The zeros are projected out (Frisch-Waugh-Lovell): fitting demeaned observations with
    /// demeaned gain columns gives exactly the gains, residuals and gain covariance of the fit
    /// with one indicator column per zero, at a cost that does not grow with the number of
    /// mounts. The zeros follow from the residual means ([`ThermalProblem::zeros_um`]).
    fn demean(&self, v: &[f64]) -> Vec<f64> {
        let means = self.segment_means(v.iter().copied());
        v.iter()
            .enumerate()
            .map(|(r, x)| {
                let centred = self.fit_row_zero(r).map_or(*x, |k| x - means[k]);
                centred * self.sqrt_weight[r]
            })
            .collect()
    }

    /// Weighted mean of `v` (one value per fitted sample) over each zero column's samples.
    fn segment_means(&self, v: impl Iterator<Item = f64>) -> Vec<f64> {
        let mut sum = vec![0.0; self.n_zero_columns];
        for (r, x) in v.enumerate() {
            if let Some(k) = self.fit_row_zero(r) {
                let w = self.sqrt_weight[r] * self.sqrt_weight[r];
                sum[k] += w * x;
            }
        }
        sum.iter()
            .zip(&self.zero_weight)
            .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
            .collect()
    }

    /// The range of fitted rows holding each zero column's samples.
    fn segment_rows(&self) -> Vec<std::ops::Range<usize>> {
        let mut rows: Vec<Option<(usize, usize)>> = vec![None; self.n_zero_columns];
        for (r, zero) in self.row_zero.iter().enumerate() {
            if let Some(k) = zero {
                let (first, _) = rows[*k].unwrap_or((r, r));
                rows[*k] = Some((first, r + 1));
            }
        }
        rows.into_iter()
            .map(|r| r.map_or(0..0, |(first, end)| first..end))
            .collect()
    }

    /// The fitted rows cut into runs of equal zero column ([`ThermalProblem::zero_runs`]).
    fn segment_runs(&self) -> Vec<(std::ops::Range<usize>, Option<usize>)> {
        let mut runs: Vec<(std::ops::Range<usize>, Option<usize>)> = Vec::new();
        for (r, zero) in self.row_zero.iter().enumerate() {
            match runs.last_mut() {
                Some((range, k)) if *k == *zero => range.end = r + 1,
                _ => runs.push((r..r + 1, *zero)),
            }
        }
        runs
    }

    /// Sum of the fitted samples' weights over each zero column's samples.
    fn segment_weights(&self) -> Vec<f64> {
        let mut weight = vec![0.0; self.n_zero_columns];
        for (zero, s) in self.row_zero.iter().zip(&self.sqrt_weight) {
            if let Some(k) = zero {
                weight[*k] += s * s;
            }
        }
        weight
    }

    /// Residuals in µm at the fitted samples from the engine's (weighted) residuals.
    pub(crate) fn unweighted(&self, residuals: &[f64]) -> Vec<f64> {
        residuals
            .iter()
            .zip(&self.sqrt_weight)
            .map(|(r, s)| r / s)
            .collect()
    }

    /// Number of zeros projected out of the problem (parameters the engine does not see).
    pub fn n_zeros(&self) -> usize {
        self.n_zero_columns
    }

    /// The zeros (µm) of a fit with `gains` at `theta`: each segment's mean of reading minus
    /// thermal model over its fitted samples; 0 for a segment without fitted samples.
    pub(crate) fn zeros_um(&self, theta: &[f64], gains: &[f64]) -> Vec<f64> {
        let columns = self.full_columns(theta);
        let means = self.segment_means(self.series.fit_index.iter().map(|&i| {
            let thermal: f64 = columns.iter().zip(gains).map(|(c, g)| c[i] * g).sum();
            self.series.y_um[i] - thermal
        }));
        self.zero_columns
            .iter()
            .map(|c| c.map_or(0.0, |k| means[k]))
            .collect()
    }

    /// `theta0`: `ln tau` of every term with a time constant.
    pub(crate) fn theta0(&self) -> Vec<f64> {
        self.tau_terms
            .iter()
            .map(|&i| self.terms[i].effect.tau0_s().ln())
            .collect()
    }

    /// The effects asked for (some of their terms may be left out: [`Self::not_identifiable`]).
    pub(crate) fn effects(&self) -> Vec<Effect> {
        self.effects.clone()
    }

    /// The terms of the effects asked for that this bar's data cannot determine, left out.
    pub(crate) fn not_identifiable(&self) -> &[NotIdentifiable] {
        &self.not_identifiable
    }

    /// Names of the time constants in `theta` order (e.g. `tau_r_s`).
    pub(crate) fn tau_names(&self) -> Vec<String> {
        self.tau_terms
            .iter()
            .map(|&i| self.terms[i].effect.tau_name().unwrap_or_default())
            .collect()
    }

    /// Per gain column: whether it is a nuisance gain (an initial-state transient, like the
    /// zeros not a property of the bar) rather than a parameter of the model.
    pub(crate) fn nuisance_gains(&self) -> Vec<bool> {
        self.gain_columns()
            .into_iter()
            .map(|(j, _)| self.terms[j].kind == TermKind::InitialState)
            .collect()
    }

    /// Zero column (after the gains) of each zero segment; `None` for a segment without fitted
    /// samples (its zero is unknown).
    pub fn zero_columns(&self) -> &[Option<usize>] {
        &self.zero_columns
    }

    /// The gain columns: `(term, zero column)`. Most terms have one gain; `settling` has one per
    /// zero segment (`settling_K_um`: its amplitude differs from mount to mount), masked to
    /// that segment.
    pub(super) fn gain_columns(&self) -> Vec<(usize, Option<usize>)> {
        let mut out = Vec::new();
        for (j, t) in self.terms.iter().enumerate() {
            if t.kind == TermKind::Settling {
                out.extend((0..self.n_zero_columns).map(|k| (j, Some(k))));
            } else {
                out.push((j, None));
            }
        }
        out
    }

    /// Number of linear columns before the zeros.
    pub(crate) fn n_gains(&self) -> usize {
        self.gain_columns().len()
    }

    /// Names of the gain columns, in order.
    pub(crate) fn gain_names(&self) -> Vec<String> {
        self.gain_columns()
            .into_iter()
            .map(|(j, k)| match k {
                Some(k) => format!("settling_{k}_um"),
                None => self.terms[j].gain_name.clone(),
            })
            .collect()
    }
}
