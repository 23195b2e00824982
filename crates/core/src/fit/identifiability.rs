//! Which parameters the data do not determine: directions of the Jacobian with singular values
//! below [`MIN_RELATIVE_SINGULAR_VALUE`] of the largest, and the parameters loading on them.
//!
//! Separate because it is a question about the Jacobian alone, asked before a fit is trusted
//! (`identify` leaves such parameters out and says why).

use super::projection::triangular_factor;
use nalgebra::DMatrix;

/// Directions of the Jacobian, each column scaled to unit norm, whose singular value is below
/// this fraction of the largest are not determined by the data (condition number above 1e8,
/// `JᵀJ`'s above 1e16: past what double precision resolves, and far below what the thermal
/// model's columns are computed to, ~1e-12). Well-posed fits stay far above it: the base model
/// on a week of a daily swing ~0.16, `tau_S` a thousand times the campaign's length ~4e-3
/// (beta then well determined at 0, tau_S with a large u), `tau_R` so (the estimate wanders to
/// 1e9 s) ~5e-5. A linear temperature ramp (no time constant can be told from a mount's zero)
/// gives ~1e-16.
pub(crate) const MIN_RELATIVE_SINGULAR_VALUE: f64 = 1e-8;

/// A parameter is named as undetermined when its share of a singular direction (the absolute
/// component of the unit right singular vector) is at least this.
const UNDETERMINED_LOADING: f64 = 0.1;

/// The parameters (indices into the Jacobian's columns) in the directions the data do not
/// determine, and the smallest singular value relative to the largest; `None` when every
/// direction is determined. A zero or non-finite column is undetermined on its own.
///
/// Columns are scaled to unit norm first: gains and `ln tau` derivatives differ by orders of
/// magnitude that say nothing about identifiability. Cost `O(n p²)` (QR of the `n × p`
/// Jacobian, then the SVD of its `p × p` factor).
pub(crate) fn undetermined_parameters(jac: &DMatrix<f64>) -> Option<(Vec<usize>, f64)> {
    let p = jac.ncols();
    if p == 0 || jac.nrows() == 0 {
        return None;
    }
    let norms: Vec<f64> = jac.column_iter().map(|c| c.norm()).collect();
    let bad: Vec<usize> = (0..p)
        .filter(|&j| !(norms[j].is_finite() && norms[j] > 0.0))
        .collect();
    if !bad.is_empty() {
        return Some((bad, 0.0));
    }
    // The right singular vectors and singular values of `J = QR` are those of `R` (`p × p`):
    // the SVD of the tall Jacobian itself cost twice the QR and dominated a refit's
    // uncertainties. `R` is formed by blocks of rows, without a scaled copy of `J`.
    let r = triangular_factor(jac, &norms);
    let svd = r.svd(false, true);
    let v_t = svd.v_t?;
    let s = &svd.singular_values;
    let s_max = s.iter().copied().fold(0.0, f64::max);
    let mut undetermined: Vec<usize> = Vec::new();
    let mut smallest = f64::INFINITY;
    for (i, &si) in s.iter().enumerate() {
        let ratio = si / s_max;
        smallest = smallest.min(ratio);
        if ratio.is_nan() || ratio < MIN_RELATIVE_SINGULAR_VALUE {
            undetermined.extend((0..p).filter(|&j| v_t[(i, j)].abs() >= UNDETERMINED_LOADING));
        }
    }
    undetermined.sort_unstable();
    undetermined.dedup();
    (!undetermined.is_empty()).then_some((undetermined, smallest))
}
