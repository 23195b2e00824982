//! The fitting engine's view of a [`ThermalProblem`] (`fit::Separable`): observations, names,
//! the basis and its derivatives, absorbed zero groups.
//!
//! Separate so that the model's own code does not depend on the engine's trait, and the trait's
//! implementation reads in one place.

use super::problem::{RowMemo, ThermalProblem};
use crate::fit::Separable;
use nalgebra::DMatrix;
use std::sync::Arc;

impl Separable for ThermalProblem<'_> {
    fn observations(&self) -> &[f64] {
        &self.y
    }

    fn nonlinear_names(&self) -> Vec<String> {
        self.tau_terms
            .iter()
            .map(|&i| format!("ln_{}", self.terms[i].effect.tau_name().unwrap_or_default()))
            .collect()
    }

    fn linear_names(&self) -> Vec<String> {
        self.gain_names()
    }

    fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
        let gains = self.gain_columns();
        let mut per_term: Vec<Option<Arc<Vec<f64>>>> = vec![None; self.terms.len()];
        let mut phi = DMatrix::zeros(self.y.len(), gains.len());
        for (c, (j, seg)) in gains.into_iter().enumerate() {
            let mut out = phi.column_mut(c);
            let out = out.as_mut_slice();
            // Masked columns (settling's, one per mount) are written over their mount alone:
            // cheap, and memoised they would hold a whole column each.
            let key = seg
                .is_none()
                .then(|| self.tau_of(j, theta).map(f64::to_bits));
            if let Some(key) = key {
                let memo = self.row_memo.lock().unwrap_or_else(|p| p.into_inner());
                if let Some(m) = memo.get(c).and_then(Option::as_ref) {
                    if m.tau_bits == key && m.column.len() == out.len() {
                        out.copy_from_slice(&m.column);
                        continue;
                    }
                }
            }
            let full = per_term[j].get_or_insert_with(|| self.term_column(j, theta, false).0);
            self.write_row_column(full, seg, out);
            if let Some(key) = key {
                let mut memo = self.row_memo.lock().unwrap_or_else(|p| p.into_inner());
                if memo.len() <= c {
                    memo.resize_with(c + 1, || None);
                }
                memo[c] = Some(RowMemo {
                    tau_bits: key,
                    column: Arc::new(out.to_vec()),
                });
            }
        }
        phi
    }

    fn basis_derivative(&self, theta: &[f64], k: usize) -> DMatrix<f64> {
        let gains = self.gain_columns();
        let mut d = DMatrix::zeros(self.y.len(), gains.len());
        let owner = self.tau_terms[k];
        // Every term on this time constant: the owner and the terms sharing it.
        for j in (0..self.terms.len()).filter(|&j| self.tau_source[j] == Some(owner)) {
            let (_, Some(full)) = self.term_column(j, theta, true) else {
                continue;
            };
            for (c, (_, seg)) in gains.iter().enumerate().filter(|(_, (term, _))| *term == j) {
                self.write_row_column(&full, *seg, d.column_mut(c).as_mut_slice());
            }
        }
        d
    }

    fn start_search_interval(&self, _k: usize) -> Option<(f64, f64)> {
        Some((60f64.ln(), (30.0 * 86400f64).ln()))
    }

    fn absorbed_groups(&self) -> Option<Vec<Option<usize>>> {
        Some((0..self.y.len()).map(|r| self.fit_row_zero(r)).collect())
    }

    fn unexplained_rss(&self) -> f64 {
        self.series.within_bin_rss_um2
    }

    fn represented_samples(&self) -> usize {
        self.series.fitted_readings().max(self.y.len())
    }
}
