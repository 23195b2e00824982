//! The fitting engine's view of a [`ThermalProblem`] (`fit::Separable`): observations, names,
//! the basis and its derivatives, absorbed zero groups.
//!
//! Separate so that the model's own code does not depend on the engine's trait, and the trait's
//! implementation reads in one place.

use super::ln_tau_bounds;
use super::problem::ThermalProblem;
use crate::fit::Separable;
use nalgebra::DMatrix;
use nalgebra::DVector;
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
        self.basis_columns(theta, 0..self.gain_columns().len())
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

    /// The columns on `θ_k` alone, each written into one scratch column and summed with its
    /// coefficient: the full derivative matrix is mostly zero columns.
    fn basis_derivative_times(&self, theta: &[f64], k: usize, coef: &DVector<f64>) -> DVector<f64> {
        let gains = self.gain_columns();
        let n = self.y.len();
        let mut sum = DVector::zeros(n);
        let mut scratch = vec![0.0; n];
        let owner = self.tau_terms[k];
        for j in (0..self.terms.len()).filter(|&j| self.tau_source[j] == Some(owner)) {
            let (_, Some(full)) = self.term_column(j, theta, true) else {
                continue;
            };
            for (c, (_, seg)) in gains.iter().enumerate().filter(|(_, (term, _))| *term == j) {
                scratch.iter_mut().for_each(|v| *v = 0.0);
                self.write_row_column(&full, *seg, &mut scratch);
                for (s, v) in sum.iter_mut().zip(&scratch) {
                    *s += coef[c] * v;
                }
            }
        }
        sum
    }

    /// The gain columns of every term on `θ_k`'s time constant (its owner and the terms
    /// sharing it).
    fn columns_on(&self, k: usize) -> Option<Vec<usize>> {
        let owner = *self.tau_terms.get(k)?;
        let columns = self
            .gain_columns()
            .into_iter()
            .enumerate()
            .filter(|(_, (term, _))| self.tau_source[*term] == Some(owner))
            .map(|(c, _)| c)
            .collect();
        Some(columns)
    }

    fn basis_columns_of(&self, theta: &[f64], columns: &[usize]) -> DMatrix<f64> {
        self.columns_at(theta, columns)
    }

    fn start_search_interval(&self, _k: usize) -> Option<(f64, f64)> {
        Some((60f64.ln(), (30.0 * 86400f64).ln()))
    }

    /// Every time constant is held to `ln_tau_bounds` (`ThermalProblem::tau_of`).
    fn nonlinear_bounds(&self, _k: usize) -> Option<(f64, f64)> {
        Some(ln_tau_bounds())
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

impl ThermalProblem<'_> {
    /// The basis' gain columns `columns` alone (the screen of a candidate needs only the
    /// columns it adds, the model's own held at their time constants).
    pub(crate) fn basis_columns(
        &self,
        theta: &[f64],
        columns: std::ops::Range<usize>,
    ) -> DMatrix<f64> {
        self.columns_at(theta, &columns.collect::<Vec<usize>>())
    }

    /// The basis' gain columns `columns`, in that order.
    fn columns_at(&self, theta: &[f64], columns: &[usize]) -> DMatrix<f64> {
        let gains = self.gain_columns();
        let mut per_term: Vec<Option<Arc<Vec<f64>>>> = vec![None; self.terms.len()];
        let mut phi = DMatrix::zeros(self.y.len(), columns.len());
        for (out_c, &c) in columns.iter().enumerate() {
            let (j, seg) = gains[c];
            let mut out = phi.column_mut(out_c);
            let out = out.as_mut_slice();
            // Masked columns (settling's, one per mount) are written over their mount alone:
            // cheap, and memoised they would hold a whole column each.
            let key = seg
                .is_none()
                .then(|| self.tau_of(j, theta).map(f64::to_bits));
            if let Some(column) = key
                .and_then(|key| self.row_memo.get(c, &key))
                .filter(|column| column.len() == out.len())
            {
                out.copy_from_slice(&column);
                continue;
            }
            let full = per_term[j].get_or_insert_with(|| self.term_column(j, theta, false).0);
            self.write_row_column(full, seg, out);
            if let Some(key) = key {
                self.row_memo.put(c, key, Arc::new(out.to_vec()));
            }
        }
        phi
    }
}
