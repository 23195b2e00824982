//! The columns of a [`ThermalProblem`]'s basis: each term's (lagged, scaled, masked) column and
//! its derivative in the time constant, memoised per row, and the settling and decay shapes.
//!
//! Separate because it is the numerical heart of the model's evaluation, called on every trial
//! of the fit, while `problem` only sets the problem up.

use super::ln_tau_bounds;
use super::problem::{TermColumn, TermKind, ThermalProblem};
use crate::series::BarSeries;
use std::sync::Arc;

impl ThermalProblem<'_> {
    /// Zero the samples of `col` outside zero column `k`.
    fn mask_to(&self, col: &mut [f64], k: usize) {
        for (v, seg) in col.iter_mut().zip(&self.series.zero_segment) {
            if seg.and_then(|s| self.zero_columns[s as usize]) != Some(k) {
                *v = 0.0;
            }
        }
    }

    /// The model's gain columns for every sample of the bar (not only the fitted ones), for
    /// plotting and for evaluating the model outside its fit mounts.
    pub(crate) fn full_columns(&self, theta: &[f64]) -> Vec<Vec<f64>> {
        let per_term: Vec<Arc<Vec<f64>>> = (0..self.terms.len())
            .map(|j| self.term_column(j, theta, false).0)
            .collect();
        self.gain_columns()
            .into_iter()
            .map(|(j, k)| {
                let mut col = per_term[j].to_vec();
                if let Some(k) = k {
                    self.mask_to(&mut col, k);
                }
                col
            })
            .collect()
    }

    /// Time constant of term `j` (its own or the one it shares), kept within
    /// [`ln_tau_bounds`].
    pub(super) fn tau_of(&self, j: usize, theta: &[f64]) -> Option<f64> {
        let owner = self.tau_source[j]?;
        self.tau_terms.iter().position(|&i| i == owner).map(|k| {
            let (lo, hi) = ln_tau_bounds();
            theta[k].clamp(lo, hi).exp()
        })
    }

    /// Column of term `j` on the bar's whole timeline, and its derivative in `ln tau`
    /// (memoised per term: see [`ThermalProblem::memo`]; a term with a time constant is always
    /// computed with its derivative, which costs no extra exponential).
    pub(super) fn term_column(&self, j: usize, theta: &[f64], with_derivative: bool) -> TermColumn {
        let Some(tau) = self.tau_of(j, theta) else {
            let (x, d) = self.compute_term_column(j, None, with_derivative);
            return (Arc::new(x), d.map(Arc::new));
        };
        let bits = tau.to_bits();
        if let Some((x, d)) = self.memo.get(j, &bits) {
            return (x, with_derivative.then_some(d));
        }
        let (x, d) = self.compute_term_column(j, Some(tau), true);
        let x = Arc::new(x);
        let Some(d) = d.map(Arc::new) else {
            return (x, None);
        };
        self.memo.put(j, bits, (x.clone(), d.clone()));
        (x, with_derivative.then_some(d))
    }

    fn compute_term_column(
        &self,
        j: usize,
        tau: Option<f64>,
        with_derivative: bool,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let term = &self.terms[j];
        let t = &self.series.t_s;
        let (mut x, mut d) = match (term.kind, tau) {
            (TermKind::Lag, Some(tau)) => match self.lag_group[j] {
                Some(first) => self.shared_lag(first, tau, with_derivative),
                None => term.input.lag(t, tau, with_derivative),
            },
            (TermKind::Rate, Some(tau)) => {
                let (l, dl) = term.input.lag(t, tau, with_derivative);
                let u = term.input.level(t.len());
                (
                    u.iter().zip(&l).map(|(u, l)| u - l).collect(),
                    dl.map(|d| d.into_iter().map(|v| -v).collect()),
                )
            }
            (TermKind::Settling, Some(tau)) => settling(self.series, tau, with_derivative),
            (TermKind::Decay { from_s }, Some(tau)) => decay(t, from_s, tau, with_derivative),
            (TermKind::InitialState, Some(tau)) => {
                decay(t, self.initial_state_reference_s, tau, with_derivative)
            }
            _ => (term.input.level(t.len()), None),
        };
        if let Some(s) = &term.scale {
            x.iter_mut().zip(s).for_each(|(x, s)| *x *= s);
            if let Some(d) = d.as_mut() {
                d.iter_mut().zip(s).for_each(|(d, s)| *d *= s);
            }
        }
        (x, d)
    }

    /// The unscaled lag (and derivative, if asked) of the terms in `first`'s
    /// [`ThermalProblem::lag_group`] at `tau`: computed once for the group, copied for each
    /// term (the copy is scaled in place).
    fn shared_lag(
        &self,
        first: usize,
        tau: f64,
        with_derivative: bool,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let bits = tau.to_bits();
        let (x, d) = self.lag_memo.get(first, &bits).unwrap_or_else(|| {
            let (x, d) = self.terms[first].input.lag(&self.series.t_s, tau, true);
            let lag = (Arc::new(x), Arc::new(d.unwrap_or_default()));
            self.lag_memo.put(first, bits, lag.clone());
            lag
        });
        (x.to_vec(), with_derivative.then(|| d.to_vec()))
    }

    /// A full-timeline column as the engine sees it, written into `out` (one row per fitted
    /// sample): gathered at the fitted samples, kept only within zero column `seg` if given
    /// ([`ThermalProblem::mask_to`] on the fitted rows), demeaned and weighed as
    /// [`ThermalProblem::demean`] does, without the intermediate vectors (the basis is rebuilt
    /// at every evaluation of a fit).
    ///
    /// `out` must be zero on entry: a column that vanishes from some sample on (an initial-state
    /// transient, [`initial_state`]) is written only up to the end of the last zero segment it
    /// reaches; the rows after it stay zero (their segments' means are zero too).
    pub(super) fn write_row_column(&self, full: &[f64], seg: Option<usize>, out: &mut [f64]) {
        if let Some(k) = seg {
            self.write_masked_row_column(full, k, out);
            return;
        }
        let support = full.iter().rposition(|v| *v != 0.0).map_or(0, |i| i + 1);
        let mut n_rows = self.series.fit_index.partition_point(|&i| i < support);
        if let Some(Some(k)) = n_rows.checked_sub(1).map(|r| self.row_zero[r]) {
            while n_rows < out.len() && self.row_zero[n_rows] == Some(k) {
                n_rows += 1;
            }
        }
        let runs = || {
            self.zero_runs
                .iter()
                .map(move |(rows, zero)| (rows.start..rows.end.min(n_rows), *zero))
                .take_while(|(rows, _)| !rows.is_empty())
        };
        let mut sums = vec![0.0; self.n_zero_columns];
        for (rows, zero) in runs() {
            let (o, w) = (&mut out[rows.clone()], &self.sqrt_weight[rows.clone()]);
            for (o, &i) in o.iter_mut().zip(&self.series.fit_index[rows]) {
                *o = full[i];
            }
            if let Some(k) = zero {
                // Row by row in order: the same sum, to the bit, as one pass over the rows.
                sums[k] = o.iter().zip(w).fold(sums[k], |s, (x, w)| s + w * w * x);
            }
        }
        let means: Vec<f64> = sums
            .iter()
            .zip(&self.zero_weight)
            .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
            .collect();
        for (rows, zero) in runs() {
            let (o, w) = (&mut out[rows.clone()], &self.sqrt_weight[rows]);
            match zero {
                Some(k) => {
                    let mean = means[k];
                    o.iter_mut().zip(w).for_each(|(o, w)| *o = (*o - mean) * w);
                }
                None => o.iter_mut().zip(w).for_each(|(o, w)| *o *= w),
            }
        }
    }

    /// [`ThermalProblem::write_row_column`] of a column kept only within zero column `k`: the
    /// other rows stay zero (so do their segments' means), and only the rows of `k` are visited
    /// (`settling` has one such column per mount: over the whole series each, they cost as
    /// much as the rest of the basis times the number of mounts).
    fn write_masked_row_column(&self, full: &[f64], k: usize, out: &mut [f64]) {
        let rows = self.zero_rows[k].clone();
        let (mut sum, weight) = (0.0, self.zero_weight[k]);
        for r in rows.clone() {
            if self.row_zero[r] == Some(k) {
                let x = full[self.series.fit_index[r]];
                out[r] = x;
                sum += self.sqrt_weight[r] * self.sqrt_weight[r] * x;
            }
        }
        let mean = if weight > 0.0 { sum / weight } else { 0.0 };
        for r in rows {
            if self.row_zero[r] == Some(k) {
                out[r] = (out[r] - mean) * self.sqrt_weight[r];
            }
        }
    }
}

pub(super) fn settling(
    series: &BarSeries,
    tau: f64,
    with_derivative: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let n = series.t_s.len();
    let mut x = vec![0.0; n];
    let mut d = vec![0.0; if with_derivative { n } else { 0 }];
    for (k, (t, m)) in series.t_s.iter().zip(&series.mount_of).enumerate() {
        if let Some(m) = m {
            let s = (t - series.mounts[*m as usize].from_s).max(0.0);
            let e = (-s / tau).exp();
            x[k] = e;
            if with_derivative {
                d[k] = e * s / tau;
            }
        }
    }
    (x, with_derivative.then_some(d))
}

/// The decay of a lag's initial departure from steady state, `exp(-(t - t_ref)/tau)` for
/// `t >= t_ref`, 1 before, and its `ln tau` derivative `exp(-(t - t_ref)/tau) (t - t_ref)/tau`:
/// the column of [`TermKind::InitialState`] (the base paths, `t_ref` the first fitted reading)
/// and of [`TermKind::Decay`] (a powered head's initial heat, `t_ref = from_s`).
///
/// Why: a lag is computed from steady state at the bar's first sample ([`lag::lag`]), but a bar
/// whose room was drifting before the logging began is not in steady state then: its state
/// departs by `delta` and the departure decays with the lag's own time constant, whatever the
/// air does since (the lag is linear). The departure cannot be read from the logs, so it is a
/// fitted gain on this column. Unit at the bar's first fitted sample (`t_ref`), so the column
/// never vanishes on the fitted samples whatever `tau` is; held at 1 before it (samples there are
/// not fitted; the departure before is only bounded from below).
pub(crate) fn decay(
    t_s: &[f64],
    t_ref: f64,
    tau: f64,
    with_derivative: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let n = t_s.len();
    let mut x = vec![0.0; n];
    let mut d = with_derivative.then(|| vec![0.0; n]);
    // exp(-(t - t_ref)/tau) by recursion over the (sorted) samples, the step factor of each
    // step length computed once: a timeline repeats a few steps, and an exponential a sample
    // would cost as much as the lags themselves. Relative drift ~1e-16 a step.
    let mut steps = [(u64::MAX, 0.0f64); 8];
    let mut slot = 0;
    let mut previous: Option<(f64, f64)> = None;
    for (k, &t) in t_s.iter().enumerate() {
        if matches!(previous, Some((_, 0.0))) {
            // Zero from here on (below), as `x` and `d` already are.
            break;
        }
        let e = if t <= t_ref {
            1.0
        } else {
            match previous {
                Some((tp, ep)) if tp >= t_ref => {
                    let dt = t - tp;
                    let bits = dt.to_bits();
                    let a = match steps.iter().find(|(b, _)| *b == bits) {
                        Some(&(_, a)) => a,
                        None => {
                            let a = (-dt / tau).exp();
                            steps[slot] = (bits, a);
                            slot = (slot + 1) % steps.len();
                            a
                        }
                    };
                    let e = ep * a;
                    // Below anything a fit in double precision can see (the column is 1 at
                    // t_ref): exactly 0 from here on, so the basis skips the rest.
                    if e < 1e-13 {
                        0.0
                    } else {
                        e
                    }
                }
                _ => (-(t - t_ref) / tau).exp(),
            }
        };
        x[k] = e;
        if let Some(d) = d.as_mut() {
            d[k] = e * (t - t_ref).max(0.0) / tau;
        }
        previous = Some((t, e));
    }
    (x, d)
}
