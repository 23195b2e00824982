//! Variable projection's linear step: the linear coefficients solved exactly at given time
//! constants, and the projected residual sum of squares every search minimises.
//!
//! Separate because every other part of the engine (starts, polish, profiles, covariances)
//! stands on it and it knows nothing of how `θ` is searched.

use super::{FitError, Separable};
use nalgebra::DMatrix;
use nalgebra::DVector;

/// Residual sum of squares of the variable-projection functional at `theta`.
pub(crate) fn projected_rss<P: Separable>(problem: &P, theta: &[f64]) -> f64 {
    let phi = problem.basis(theta);
    let y = problem.observations();
    match solve_linear(&phi, y) {
        Some(c) => {
            (&phi * &c)
                .iter()
                .zip(y)
                .map(|(f, y)| (y - f) * (y - f))
                .sum::<f64>()
                + problem.unexplained_rss()
        }
        None => f64::INFINITY,
    }
}

/// Least-squares coefficients by a column-scaled QR; `None` when the basis is rank deficient.
pub(super) fn solve_linear(phi: &DMatrix<f64>, y: &[f64]) -> Option<DVector<f64>> {
    let m = phi.ncols();
    if m == 0 {
        return Some(DVector::zeros(0));
    }
    let scale: Vec<f64> = (0..m).map(|j| phi.column(j).norm()).collect();
    if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return None;
    }
    let mut scaled = phi.clone();
    for (j, s) in scale.iter().enumerate() {
        scaled.column_mut(j).unscale_mut(*s);
    }
    let qr = scaled.qr();
    let r = qr.r();
    let diag_max = (0..m).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
    if (0..m).any(|i| r[(i, i)].abs() <= 1e-11 * diag_max) {
        return None;
    }
    // Qᵀy by the Householder reflections themselves: forming the n × m factor Q costs as much
    // as the factorisation.
    let mut qty = DVector::from_column_slice(y);
    qr.q_tr_mul(&mut qty);
    let mut c = r.solve_upper_triangular(&qty.rows(0, m))?;
    for (j, s) in scale.iter().enumerate() {
        c[j] /= s;
    }
    Some(c)
}

/// Name the first column that makes the basis singular, for a readable error.
pub(super) fn singular_term<P: Separable>(problem: &P, phi: &DMatrix<f64>) -> FitError {
    let names = problem.linear_names();
    for j in 1..=phi.ncols() {
        let sub = phi.columns(0, j).into_owned();
        if solve_linear(&sub, problem.observations()).is_none() {
            return FitError::Singular(names[j - 1].clone());
        }
    }
    FitError::Singular(names.join(", "))
}
