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
    match Factorised::new(&phi) {
        Some(f) => f.residual_sum_of_squares(y) + problem.unexplained_rss(),
        None => f64::INFINITY,
    }
}

/// Least-squares coefficients by a column-scaled QR; `None` when the basis is rank deficient.
pub(super) fn solve_linear(phi: &DMatrix<f64>, y: &[f64]) -> Option<DVector<f64>> {
    Factorised::new(phi)?.coefficients(y)
}

/// A basis factorised once (column-scaled Householder QR) for several right-hand sides: the
/// observations' coefficients, and the projections of the Jacobian's columns that the
/// Gauss-Newton polish needs at the same point.
///
/// A tall basis is factorised by blocks of rows (TSQR): each block of [`BLOCK_ROWS`] rows on its
/// own, then the blocks' stacked triangular factors. The factors are those of one QR of the
/// whole basis (up to the signs of `R`'s rows, which no solve sees); a block stays in the
/// core's cache while its reflections sweep it, where one QR of 130 000 rows streamed the whole
/// basis from memory once per column.
pub(super) struct Factorised {
    /// Column norms of the basis (the QR is of the basis with unit columns).
    scale: Vec<f64>,
    /// Each block's first row and QR.
    blocks: Vec<(usize, Qr)>,
    /// The QR of the blocks' stacked `R` factors, when there is more than one block.
    top: Option<Qr>,
    /// The triangular factor `R` (`m × m`).
    r: DMatrix<f64>,
}

type Qr = nalgebra::linalg::QR<f64, nalgebra::Dyn, nalgebra::Dyn>;

/// Rows of one block of [`Factorised`]'s blocked QR (at least the basis' column count): 2 048
/// rows of 40 columns are 650 kB, inside a core's 2 MB L2 cache.
const BLOCK_ROWS: usize = 2048;

impl Factorised {
    /// `None` when the basis has a zero or non-finite column or is rank deficient (a diagonal
    /// of `R` at most `1e-11` of the largest).
    pub(super) fn new(phi: &DMatrix<f64>) -> Option<Factorised> {
        let (n, m) = phi.shape();
        let scale: Vec<f64> = (0..m).map(|j| phi.column(j).norm()).collect();
        if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return None;
        }
        let block_rows = BLOCK_ROWS.max(2 * m);
        let starts: Vec<usize> = if n >= 2 * block_rows {
            (0..n / block_rows).map(|b| b * block_rows).collect()
        } else {
            vec![0]
        };
        let blocks: Vec<(usize, Qr)> = starts
            .iter()
            .enumerate()
            .map(|(b, &start)| {
                let end = starts.get(b + 1).copied().unwrap_or(n);
                let mut block = phi.rows(start, end - start).into_owned();
                for (j, s) in scale.iter().enumerate() {
                    block.column_mut(j).unscale_mut(*s);
                }
                (start, block.qr())
            })
            .collect();
        let (top, r) = if blocks.len() > 1 {
            let mut stacked = DMatrix::zeros(blocks.len() * m, m);
            for (b, (_, qr)) in blocks.iter().enumerate() {
                stacked.rows_mut(b * m, m).copy_from(&qr.r());
            }
            let top = stacked.qr();
            let r = top.r();
            (Some(top), r)
        } else {
            let r = blocks[0].1.r();
            (None, r)
        };
        let diag_max = (0..m).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
        if r.nrows() < m || (0..m).any(|i| r[(i, i)].abs() <= 1e-11 * diag_max) {
            return None;
        }
        Some(Factorised {
            scale,
            blocks,
            top,
            r,
        })
    }

    /// `Qᵀy` split: its first `m` entries (what the coefficients solve with), and the sum of
    /// squares of the rest (the residual sum of squares). Householder reflections applied as
    /// they are: forming the `n × m` factor `Q` costs as much as the factorisation.
    fn q_tr(&self, y: &[f64]) -> (DVector<f64>, f64) {
        let m = self.scale.len();
        let mut heads = DVector::zeros(self.blocks.len() * m);
        let mut tail = 0.0;
        for (b, (start, qr)) in self.blocks.iter().enumerate() {
            let end = self.blocks.get(b + 1).map_or(y.len(), |(s, _)| *s);
            let mut part = DVector::from_column_slice(&y[*start..end]);
            qr.q_tr_mul(&mut part);
            heads.rows_mut(b * m, m).copy_from(&part.rows(0, m));
            tail += part.rows(m, part.len() - m).norm_squared();
        }
        if let Some(top) = &self.top {
            top.q_tr_mul(&mut heads);
            tail += heads.rows(m, heads.len() - m).norm_squared();
            heads = heads.rows(0, m).into_owned();
        }
        (heads, tail)
    }

    /// The residual sum of squares of `y` on the basis: the squared tail of `Qᵀy` below the
    /// first `m` rows (no coefficients nor fitted values needed; `Q` is orthogonal).
    pub(super) fn residual_sum_of_squares(&self, y: &[f64]) -> f64 {
        if self.scale.is_empty() {
            return y.iter().map(|v| v * v).sum();
        }
        self.q_tr(y).1
    }

    /// The least-squares coefficients of `y` on the basis.
    pub(super) fn coefficients(&self, y: &[f64]) -> Option<DVector<f64>> {
        if self.scale.is_empty() {
            return Some(DVector::zeros(0));
        }
        let (head, _) = self.q_tr(y);
        let mut c = self.r.solve_upper_triangular(&head)?;
        for (j, s) in self.scale.iter().enumerate() {
            c[j] /= s;
        }
        Some(c)
    }
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
