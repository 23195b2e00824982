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

/// Rows `rows` of `phi` with each column divided by its `scale`, copied slice by slice.
///
/// Why not `phi.rows(..).into_owned()` and `unscale_mut`: nalgebra copies a view element by
/// element through its strides and scales in a second pass; with a factorisation at every trial
/// of every fit, the two held 8 % of a nightly run's CPU samples, this copy 2.5 % (`perf` on our
/// simulator's three-effect campaign). The same divisions: the factors are bit for bit those
/// of before. Filled column by column into one vector: through `DMatrix::from_iterator` over a
/// `flat_map` the same copy took 9 % (`b33115b`).
fn unit_rows(phi: &DMatrix<f64>, scale: &[f64], rows: std::ops::Range<usize>) -> DMatrix<f64> {
    unit_columns(phi, scale.iter().copied().enumerate(), rows)
}

/// [`unit_rows`] of some columns only: each `(column, scale)` of `columns`, in that order.
fn unit_columns(
    phi: &DMatrix<f64>,
    columns: impl ExactSizeIterator<Item = (usize, f64)>,
    rows: std::ops::Range<usize>,
) -> DMatrix<f64> {
    let (n, m) = (phi.nrows(), columns.len());
    let mut unit = Vec::with_capacity(rows.len() * m);
    for (j, s) in columns {
        let column = &phi.as_slice()[j * n + rows.start..j * n + rows.end];
        unit.extend(column.iter().map(|v| v / s));
    }
    DMatrix::from_vec(rows.len(), m, unit)
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
///
/// Columns each nonzero on a short run of rows only, the runs disjoint ([`local_columns`]:
/// `settling`'s amplitude of each mount), are orthogonal to one another: they are projected out
/// of the other columns and of each right-hand side directly, and only the other columns go
/// through the QR. The same least squares, at `O(n m_dense)` for the local columns where the QR
/// of the whole basis cost `O(n m²)`: a bar mounted 15 times has 15 such columns beside 8-10
/// others.
pub(super) struct Factorised {
    /// Column norms of the basis (the QR is of the basis with unit columns).
    scale: Vec<f64>,
    /// The local columns, projected out before the QR; empty for most bases.
    local: Vec<LocalColumn>,
    /// The basis columns the QR factorises, in order (all of them when `local` is empty).
    dense: Vec<usize>,
    /// Their QR.
    qr: BlockedQr,
}

/// The blocked QR of a basis' dense columns.
struct BlockedQr {
    /// Each block's first row and QR.
    blocks: Vec<(usize, Qr)>,
    /// The QR of the blocks' stacked `R` factors, when there is more than one block.
    top: Option<Qr>,
    /// The triangular factor `R`.
    r: DMatrix<f64>,
}

type Qr = nalgebra::linalg::QR<f64, nalgebra::Dyn, nalgebra::Dyn>;

/// Rows of one block of [`Factorised`]'s blocked QR (at least the basis' column count): 2 048
/// rows of 40 columns are 650 kB, inside a core's 2 MB L2 cache.
const BLOCK_ROWS: usize = 2048;

/// A column of the basis nonzero on `rows` only ([`local_columns`]).
struct LocalColumn {
    /// Its index in the basis.
    column: usize,
    rows: std::ops::Range<usize>,
    /// The column on `rows`, of unit norm.
    unit: Vec<f64>,
    /// Its inner product with each dense unit column (in `Factorised::dense`'s order).
    along_dense: Vec<f64>,
}

/// The columns of `phi` whose nonzero rows lie within a run at most a quarter of the rows long,
/// the runs disjoint, as `(column, run)`; none unless there are at least two (one such column
/// saves little, and a basis without them is factorised as it always was, to the bit).
///
/// A column whose run overlaps an earlier one (by their first rows) stays with the dense ones.
fn local_columns(phi: &DMatrix<f64>) -> Vec<(usize, std::ops::Range<usize>)> {
    let n = phi.nrows();
    let mut runs: Vec<(usize, std::ops::Range<usize>)> = (0..phi.ncols())
        .filter_map(|j| {
            let column = &phi.as_slice()[j * n..(j + 1) * n];
            let first = column.iter().position(|v| *v != 0.0)?;
            let last = column.iter().rposition(|v| *v != 0.0)?;
            ((last + 1 - first) * 4 <= n).then_some((j, first..last + 1))
        })
        .collect();
    runs.sort_by_key(|(j, rows)| (rows.start, *j));
    let mut kept: Vec<(usize, std::ops::Range<usize>)> = Vec::with_capacity(runs.len());
    for (j, rows) in runs {
        if kept
            .last()
            .is_none_or(|(_, before)| before.end <= rows.start)
        {
            kept.push((j, rows));
        }
    }
    if kept.len() < 2 {
        kept.clear();
    }
    kept.sort_by_key(|(j, _)| *j);
    kept
}

/// The triangular factor `R` of the QR of `m` with each column divided by its `scale`: the rows
/// taken a block ([`BLOCK_ROWS`]) at a time, each stacked under the factor so far. `R` is that of
/// one QR of the whole scaled matrix (up to the signs of its rows); `m` itself when it has no
/// more rows than columns.
///
/// Why: the question it serves ([`super::identifiability`]) needs only `R`, and the QR of the
/// whole matrix needed a scaled copy of it: one more Jacobian held by each concurrent refit
/// (27 MB on a bar of 128 k readings with `settling`'s 15 amplitudes).
pub(super) fn triangular_factor(m: &DMatrix<f64>, scale: &[f64]) -> DMatrix<f64> {
    let (n, p) = m.shape();
    let block_rows = BLOCK_ROWS.max(2 * p);
    let mut r: Option<DMatrix<f64>> = None;
    let mut start = 0;
    while start < n {
        let end = (start + block_rows).min(n);
        let block = unit_rows(m, scale, start..end);
        let stacked = match r.take() {
            None => block,
            Some(r) => {
                let mut stacked = DMatrix::zeros(r.nrows() + block.nrows(), p);
                stacked.rows_mut(0, r.nrows()).copy_from(&r);
                stacked.rows_mut(r.nrows(), block.nrows()).copy_from(&block);
                stacked
            }
        };
        r = Some(if stacked.nrows() > p {
            stacked.qr().r()
        } else {
            stacked
        });
        start = end;
    }
    r.unwrap_or_else(|| DMatrix::zeros(0, p))
}

/// The blocked QR of the rows of `unit` (columns already of unit norm, or divided by `scale`
/// here) and its triangular factor; `None` for fewer rows than columns.
fn factorise_blocks(unit: &DMatrix<f64>, scale: &[f64]) -> Option<BlockedQr> {
    let (n, m) = unit.shape();
    if n < m {
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
            (start, unit_rows(unit, scale, start..end).qr())
        })
        .collect();
    if blocks.len() > 1 {
        let mut stacked = DMatrix::zeros(blocks.len() * m, m);
        for (b, (_, qr)) in blocks.iter().enumerate() {
            stacked.rows_mut(b * m, m).copy_from(&qr.r());
        }
        let top = stacked.qr();
        let r = top.r();
        Some(BlockedQr {
            blocks,
            top: Some(top),
            r,
        })
    } else {
        let r = blocks[0].1.r();
        Some(BlockedQr {
            blocks,
            top: None,
            r,
        })
    }
}

impl Factorised {
    /// `None` when the basis has a zero or non-finite column or is rank deficient (a diagonal
    /// of `R` at most `1e-11` of the largest; a local column's is 1).
    pub(super) fn new(phi: &DMatrix<f64>) -> Option<Factorised> {
        let m = phi.ncols();
        let scale: Vec<f64> = (0..m).map(|j| phi.column(j).norm()).collect();
        if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return None;
        }
        let runs = local_columns(phi);
        let (local, dense, qr) = if runs.is_empty() {
            (Vec::new(), (0..m).collect(), factorise_blocks(phi, &scale)?)
        } else {
            let (local, dense, unit) = project_out_local(phi, &scale, runs);
            let qr = if dense.is_empty() {
                BlockedQr {
                    blocks: Vec::new(),
                    top: None,
                    r: DMatrix::zeros(0, 0),
                }
            } else {
                factorise_blocks(&unit, &vec![1.0; dense.len()])?
            };
            (local, dense, qr)
        };
        let r = &qr.r;
        let diag_max = (0..r.nrows())
            .map(|i| r[(i, i)].abs())
            .fold(if local.is_empty() { 0.0 } else { 1.0 }, f64::max);
        if r.nrows() < dense.len() || (0..dense.len()).any(|i| r[(i, i)].abs() <= 1e-11 * diag_max)
        {
            return None;
        }
        Some(Factorised {
            scale,
            local,
            dense,
            qr,
        })
    }

    /// `Qᵀy` of the dense columns split: its first `m_dense` entries (what their coefficients
    /// solve with), and the sum of squares of the rest (the residual sum of squares). `y` has
    /// had the local columns projected out. Householder reflections applied as they are:
    /// forming the `n × m` factor `Q` costs as much as the factorisation.
    fn q_tr(&self, y: &[f64]) -> (DVector<f64>, f64) {
        let m = self.dense.len();
        if m == 0 {
            return (DVector::zeros(0), y.iter().map(|v| v * v).sum());
        }
        let mut heads = DVector::zeros(self.qr.blocks.len() * m);
        let mut tail = 0.0;
        for (b, (start, qr)) in self.qr.blocks.iter().enumerate() {
            let end = self.qr.blocks.get(b + 1).map_or(y.len(), |(s, _)| *s);
            let mut part = DVector::from_column_slice(&y[*start..end]);
            qr.q_tr_mul(&mut part);
            heads.rows_mut(b * m, m).copy_from(&part.rows(0, m));
            tail += part.rows(m, part.len() - m).norm_squared();
        }
        if let Some(top) = &self.qr.top {
            top.q_tr_mul(&mut heads);
            tail += heads.rows(m, heads.len() - m).norm_squared();
            heads = heads.rows(0, m).into_owned();
        }
        (heads, tail)
    }

    /// `y` with the local columns projected out, and its inner product with each (unit) local
    /// column; `y` itself where there are none.
    fn without_local<'y>(&self, y: &'y [f64]) -> (std::borrow::Cow<'y, [f64]>, Vec<f64>) {
        if self.local.is_empty() {
            return (std::borrow::Cow::Borrowed(y), Vec::new());
        }
        let mut rest = y.to_vec();
        let along = self
            .local
            .iter()
            .map(|l| project_out(&l.unit, &mut rest[l.rows.clone()]))
            .collect();
        (std::borrow::Cow::Owned(rest), along)
    }

    /// The residual sum of squares of `y` on the basis: the squared tail of `Qᵀy` below the
    /// first `m` rows (no coefficients nor fitted values needed; `Q` is orthogonal).
    pub(super) fn residual_sum_of_squares(&self, y: &[f64]) -> f64 {
        if self.scale.is_empty() {
            return y.iter().map(|v| v * v).sum();
        }
        self.q_tr(&self.without_local(y).0).1
    }

    /// The least-squares coefficients of `y` on the basis.
    pub(super) fn coefficients(&self, y: &[f64]) -> Option<DVector<f64>> {
        if self.scale.is_empty() {
            return Some(DVector::zeros(0));
        }
        let (rest, along_local) = self.without_local(y);
        let (head, _) = self.q_tr(&rest);
        let dense = self.qr.r.solve_upper_triangular(&head)?;
        let mut c = DVector::zeros(self.scale.len());
        for (k, &j) in self.dense.iter().enumerate() {
            c[j] = dense[k];
        }
        for (l, a) in self.local.iter().zip(along_local) {
            c[l.column] = a - l
                .along_dense
                .iter()
                .zip(dense.iter())
                .map(|(w, d)| w * d)
                .sum::<f64>();
        }
        for (j, s) in self.scale.iter().enumerate() {
            c[j] /= s;
        }
        Some(c)
    }
}

/// The local columns of `phi` (`runs`, [`local_columns`]) as unit columns with their inner
/// products with the others, the other columns' indices, and those columns of unit norm with the
/// local ones projected out (`n × m_dense`).
///
/// The local columns are orthogonal to one another (disjoint rows), so each is projected out on
/// its own rows, in any order.
fn project_out_local(
    phi: &DMatrix<f64>,
    scale: &[f64],
    runs: Vec<(usize, std::ops::Range<usize>)>,
) -> (Vec<LocalColumn>, Vec<usize>, DMatrix<f64>) {
    let n = phi.nrows();
    let dense: Vec<usize> = (0..phi.ncols())
        .filter(|j| runs.iter().all(|(l, _)| l != j))
        .collect();
    let mut unit = unit_columns(phi, dense.iter().map(|&j| (j, scale[j])), 0..n);
    let local = runs
        .into_iter()
        .map(|(column, rows)| {
            let u: Vec<f64> = phi.as_slice()[column * n + rows.start..column * n + rows.end]
                .iter()
                .map(|x| x / scale[column])
                .collect();
            let along_dense = (0..dense.len())
                .map(|k| {
                    project_out(
                        &u,
                        &mut unit.as_mut_slice()[k * n + rows.start..k * n + rows.end],
                    )
                })
                .collect();
            LocalColumn {
                column,
                rows,
                unit: u,
                along_dense,
            }
        })
        .collect();
    (local, dense, unit)
}

/// `part` less its component along the unit vector `unit` (both on a local column's rows); the
/// component, `unitᵀ part`.
fn project_out(unit: &[f64], part: &mut [f64]) -> f64 {
    let along: f64 = unit.iter().zip(part.iter()).map(|(u, v)| u * v).sum();
    part.iter_mut().zip(unit).for_each(|(v, u)| *v -= along * u);
    along
}

/// The columns of a basis that a one-parameter sweep holds (those not on the swept `θ_k`,
/// `Separable::columns_on`), factorised once: the projected RSS at each trial then orthogonalises
/// only the columns on `θ_k` against them ([`HeldProjection::residual_sum_of_squares`]).
///
/// Why: the Brent start sweeps one time constant at a time, some ten trials each, and every
/// trial factorised the whole `n × m` basis again though only the one or two columns of that
/// time constant changed. On our simulator's three-effect campaign (sensor gradient, plate
/// expansion, hidden channel; 10 bars, 15 days, 10 s) the sweeps made 43 625 trials, nearly all
/// on the 300-s copies: 8.2 of the night's 31 CPU-s, 6.4 with the held columns factorised once
/// (the rest of a trial is the moving columns' lags).
///
/// The held columns' orthonormal factor is formed explicitly (`n × m_held`): a trial then costs
/// two passes of classical Gram-Schmidt a moving column (`O(n m)` each, the second restoring the
/// orthogonality the first loses), against `O(n m²)` for a Householder QR of the whole basis.
pub(super) struct HeldProjection {
    /// Orthonormal basis of the held columns' span (`n × m_held`).
    q: DMatrix<f64>,
    /// The observations less their projection on the held columns.
    y_rest: DVector<f64>,
}

/// A column whose part outside the span of the columns before it is at most this share of its
/// norm makes the basis singular: [`Factorised::new`]'s test on `R`'s diagonal (the basis' first
/// unit column makes its largest diagonal 1).
const RANK_TOLERANCE: f64 = 1e-11;

impl HeldProjection {
    /// `None` when `held` has a zero or non-finite column or is rank deficient.
    pub(super) fn new(held: &DMatrix<f64>, y: &[f64]) -> Option<HeldProjection> {
        let y = DVector::from_column_slice(y);
        if held.ncols() == 0 {
            return Some(HeldProjection {
                q: DMatrix::zeros(y.len(), 0),
                y_rest: y,
            });
        }
        let mut unit = held.clone();
        for mut column in unit.column_iter_mut() {
            let norm = column.norm();
            if !(norm.is_finite() && norm > 0.0) {
                return None;
            }
            column.unscale_mut(norm);
        }
        let qr = unit.qr();
        let r = qr.r();
        let m = held.ncols();
        if r.nrows() < m || (0..m).any(|i| r[(i, i)].abs() <= RANK_TOLERANCE) {
            return None;
        }
        let q = qr.q();
        let mut y_rest = y;
        for _ in 0..2 {
            let along = q.tr_mul(&y_rest);
            y_rest.gemv(-1.0, &q, &along, 1.0);
        }
        Some(HeldProjection { q, y_rest })
    }

    /// The residual sum of squares of the observations on the held columns and `moving`
    /// together; `None` where `moving` has a zero or non-finite column (its norm is then not
    /// finite) or makes the basis singular ([`RANK_TOLERANCE`]).
    pub(super) fn residual_sum_of_squares(&self, moving: &DMatrix<f64>) -> Option<f64> {
        let mut residual = self.y_rest.clone();
        let mut added: Vec<DVector<f64>> = Vec::with_capacity(moving.ncols());
        for column in moving.column_iter() {
            let norm = column.norm();
            if !(norm.is_finite() && norm > 0.0) {
                return None;
            }
            let mut v = column.unscale(norm);
            for _ in 0..2 {
                if self.q.ncols() > 0 {
                    let along = self.q.tr_mul(&v);
                    v.gemv(-1.0, &self.q, &along, 1.0);
                }
                for a in &added {
                    let d = a.dot(&v);
                    v.axpy(-d, a, 1.0);
                }
            }
            let rest = v.norm();
            if rest <= RANK_TOLERANCE {
                return None;
            }
            v.unscale_mut(rest);
            let d = v.dot(&residual);
            residual.axpy(-d, &v, 1.0);
            added.push(v);
        }
        Some(residual.norm_squared())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A basis of smooth, distinct columns (`n × m`) and observations on it plus a wiggle.
    fn basis_and_observations(n: usize, m: usize) -> (DMatrix<f64>, Vec<f64>) {
        let phi = DMatrix::from_fn(n, m, |i, j| {
            let x = i as f64 / n as f64;
            (x * (j + 1) as f64 * 3.1).sin() + 0.2 * (j as f64) * x * x
        });
        let y = (0..n)
            .map(|i| {
                let x = i as f64 / n as f64;
                (0..m).map(|j| (j as f64 - 1.5) * phi[(i, j)]).sum::<f64>()
                    + 1e-3 * ((i * 7919) % 13) as f64
                    + 0.05 * (x * 40.0).cos()
            })
            .collect();
        (phi, y)
    }

    /// The held columns factorised once and the moving ones added give the residual sum of
    /// squares of the whole basis (both blocked and one-block sizes), whatever columns move.
    #[test]
    fn the_held_projection_gives_the_whole_basis_residual() {
        for n in [300, 5000] {
            let (phi, y) = basis_and_observations(n, 6);
            let whole = Factorised::new(&phi).unwrap().residual_sum_of_squares(&y);
            for moving in [vec![5], vec![0, 3], vec![1, 2, 4], (0..6).collect()] {
                let held: Vec<usize> = (0..6).filter(|c| !moving.contains(c)).collect();
                let projection = HeldProjection::new(&phi.select_columns(&held), &y).unwrap();
                let rss = projection
                    .residual_sum_of_squares(&phi.select_columns(&moving))
                    .unwrap();
                assert!(
                    (rss - whole).abs() <= 1e-10 * whole,
                    "n {n}, moving {moving:?}: {rss} against {whole}"
                );
            }
        }
    }

    /// The triangular factor formed a block of rows at a time is that of one QR of the whole
    /// scaled matrix, up to the signs of its rows; a matrix with no more rows than columns comes
    /// back scaled as it is.
    #[test]
    fn the_blocked_triangular_factor_is_the_whole_qrs() {
        for n in [4, 300, 2 * BLOCK_ROWS + 17] {
            let (phi, _) = basis_and_observations(n, 6);
            let scale: Vec<f64> = phi.column_iter().map(|c| c.norm()).collect();
            let mut unit = phi.clone();
            for (mut c, s) in unit.column_iter_mut().zip(&scale) {
                c /= *s;
            }
            let blocked = triangular_factor(&phi, &scale);
            let whole = if n > 6 { unit.clone().qr().r() } else { unit };
            assert_eq!(blocked.shape(), whole.shape(), "n {n}");
            for i in 0..whole.nrows() {
                let sign = (blocked[(i, i)] * whole[(i, i)]).signum();
                for j in 0..6 {
                    let (b, w) = (sign * blocked[(i, j)], whole[(i, j)]);
                    assert!(
                        (b - w).abs() <= 1e-12,
                        "n {n}, R[{i}, {j}]: {b} against {w}"
                    );
                }
            }
        }
    }

    /// A basis with dense columns and columns each nonzero on its own short run of rows (a
    /// mount's `settling`), taken apart by `Factorised`, gives the coefficients and residual of
    /// one least-squares solve of the whole basis (by SVD here), and is singular where a dense
    /// column lies in the local columns' span.
    #[test]
    fn local_columns_projected_out_give_the_whole_least_squares() {
        let (n, runs) = (1200, [(0, 200), (200, 450), (500, 800), (900, 1200)]);
        let (dense, y) = basis_and_observations(n, 3);
        let mut columns: Vec<DVector<f64>> = Vec::new();
        for (k, &(a, b)) in runs.iter().enumerate() {
            columns.push(DVector::from_fn(n, |i, _| {
                if (a..b).contains(&i) {
                    (-((i - a) as f64) / 60.0).exp() - 0.3 * k as f64
                } else {
                    0.0
                }
            }));
            if k == 1 {
                columns.push(dense.column(0).into_owned());
            }
        }
        columns.push(dense.column(1).into_owned());
        columns.push(dense.column(2).into_owned());
        let phi = DMatrix::from_columns(&columns);
        assert_eq!(local_columns(&phi).len(), 4);
        let f = Factorised::new(&phi).unwrap();
        assert_eq!(f.local.len(), 4);
        let y_vec = DVector::from_column_slice(&y);
        let svd = phi.clone().svd(true, true);
        let c_svd = svd.solve(&y_vec, 1e-12).unwrap();
        let c = f.coefficients(&y).unwrap();
        let rss_svd = (&y_vec - &phi * &c_svd).norm_squared();
        for j in 0..phi.ncols() {
            assert!(
                (c[j] - c_svd[j]).abs() <= 1e-9 * c_svd.amax(),
                "coefficient {j}: {} against {}",
                c[j],
                c_svd[j]
            );
        }
        let rss = f.residual_sum_of_squares(&y);
        assert!(
            (rss - rss_svd).abs() <= 1e-9 * rss_svd,
            "{rss} against {rss_svd}"
        );
        // The sum of the local columns as a dense one: singular, as the QR of the whole finds.
        let mut with_sum = columns.clone();
        with_sum.push(columns[0].clone() + &columns[1] * 2.0 + &columns[3]);
        assert!(Factorised::new(&DMatrix::from_columns(&with_sum)).is_none());
        // Overlapping runs are not local; one run alone is not taken apart.
        let overlapping = DMatrix::from_columns(&[
            columns[0].clone(),
            columns[0].clone() * 0.5 + &columns[2],
            dense.column(1).into_owned(),
        ]);
        assert!(local_columns(&overlapping).len() < 2);
        let single = DMatrix::from_columns(&[columns[0].clone(), dense.column(1).into_owned()]);
        assert!(local_columns(&single).is_empty());
    }

    /// A moving column in the span of the held ones, or a zero one, makes the basis singular,
    /// as `Factorised::new` finds it; so do held columns that are.
    #[test]
    fn a_moving_column_in_the_held_span_is_singular() {
        let (phi, y) = basis_and_observations(400, 4);
        let held = phi.columns(0, 3).into_owned();
        let projection = HeldProjection::new(&held, &y).unwrap();
        let within = DMatrix::from_fn(400, 1, |i, _| 2.0 * phi[(i, 0)] - phi[(i, 2)]);
        assert!(Factorised::new(&DMatrix::from_columns(&[
            phi.column(0),
            phi.column(1),
            phi.column(2),
            within.column(0)
        ]))
        .is_none());
        assert_eq!(projection.residual_sum_of_squares(&within), None);
        assert_eq!(
            projection.residual_sum_of_squares(&DMatrix::zeros(400, 1)),
            None
        );
        let twice = DMatrix::from_columns(&[phi.column(3), phi.column(3)]);
        assert_eq!(projection.residual_sum_of_squares(&twice), None);
        let repeated = DMatrix::from_columns(&[phi.column(0), phi.column(1), phi.column(0)]);
        assert!(HeldProjection::new(&repeated, &y).is_none());
        // A non-finite value anywhere in a column: no residual (the Brent trial then costs
        // `UNSOLVED_COST`), held or moving.
        for bad in [f64::NAN, f64::INFINITY] {
            let mut broken = within.clone();
            broken[(7, 0)] = bad;
            assert_eq!(projection.residual_sum_of_squares(&broken), None);
            let mut held_broken = held.clone();
            held_broken[(7, 1)] = bad;
            assert!(HeldProjection::new(&held_broken, &y).is_none());
        }
    }
}
