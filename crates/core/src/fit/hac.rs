//! The uncertainties of a fit: the naive and the batch-means HAC covariances, each parameter's
//! Satterthwaite degrees of freedom and the Student t quantile used with them.
//!
//! Separate because the residuals of thermal fits are autocorrelated and how that is accounted
//! for is its own piece of statistics, independent of how the optimum was found.

use super::autocorrelation::{batch_edge_bias, batch_length_from, initial_autocorrelation};
use nalgebra::DMatrix;
use nalgebra::DVector;

/// Naive and batch-means HAC covariances from the Jacobian and residuals; `s2` is the residual
/// variance of the naive one (RSS over the represented samples' degrees of freedom).
///
/// HAC: `(JᵀJ)⁻¹ (Σ_b G_b G_bᵀ) (JᵀJ)⁻¹` with `G_b = Σ_{i∈b} J_iᵀ r_i` summed over consecutive
/// batches of length `L`: the scores of samples closer than `L` keep their correlation, batch
/// sums are close to independent when `L` exceeds the residual correlation time.
pub(super) fn covariances(
    jac: &DMatrix<f64>,
    jtj_inv: &DMatrix<f64>,
    residuals: &[f64],
    s2: f64,
    batch_len: Option<usize>,
    absorbed: usize,
) -> Option<(DMatrix<f64>, DMatrix<f64>, usize)> {
    let (n, p) = jac.shape();
    let p_total = p + absorbed;
    let cov_naive = jtj_inv * s2;
    // One autocorrelation serves the batch choice and the batch-edge correction.
    let acf = initial_autocorrelation(residuals);
    let batch = batch_len
        .unwrap_or_else(|| batch_length_from(residuals, &acf))
        .clamp(1, n.max(1));
    let columns: Vec<&[f64]> = jac.as_slice().chunks_exact(n.max(1)).collect();
    let mut meat = DMatrix::<f64>::zeros(p, p);
    let mut g = DVector::<f64>::zeros(p);
    let mut start = 0;
    while start < n {
        let end = (start + batch).min(n);
        for (gj, col) in g.iter_mut().zip(&columns) {
            *gj = dot(&col[start..end], &residuals[start..end]);
        }
        meat.ger(1.0, &g, &g, 1.0);
        start = end;
    }
    // Degrees-of-freedom correction at the batch level, B/(B-p): the fitted parameters make the
    // batch sums sum to zero in p directions (for mount zeros, within each mount), so the raw
    // sum of squares underestimates the long-run variance (the batch analogue of HC1's n/(n-p)).
    let b = n_batches(n, batch) as f64;
    meat *= b / (b - p_total as f64).max(1.0);
    // Batch sums miss the correlation across batch edges: relative bias -2 Σ k ρ_k / (L τ_int)
    // (ρ_k the residual autocorrelation); undo it.
    meat /= (1.0 - batch_edge_bias(&acf, batch)).max(0.5);
    let cov_hac = jtj_inv * meat * jtj_inv;
    Some((cov_naive, cov_hac, batch))
}

/// Student's t quantile 0.975 with `dof` degrees of freedom (1.96 if `dof` is not usable).
pub(crate) fn t_quantile_975(dof: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    StudentsT::new(0.0, 1.0, dof.max(1.0))
        .map(|t| t.inverse_cdf(0.975))
        .unwrap_or(1.96)
}

/// Effective degrees of freedom of each parameter's batch-means HAC variance (Satterthwaite, in
/// the form Bell and McCaffrey (2002) give for cluster-robust variances, batches as clusters).
///
/// Parameter `k`'s HAC variance is `V = Σ_b (a_bᵀ r_b)²` with `a = J (JᵀJ)⁻¹ e_k` and `r_b` the
/// residuals of batch `b`. With the residuals `r = (I − H) e` (`H` the projection on the
/// Jacobian and on the absorbed group means) and batches independent with a common long-run
/// variance per sample (the working model of batch means), `V` is a weighted sum of χ²₁
/// variables with weights the eigenvalues of `M = (I − H) A (I − H)`, `A = blockdiag(a_b a_bᵀ)`,
/// and Satterthwaite's `ν = (tr M)² / tr(M²)` matches its first two moments. `ν` equals the
/// number of batches − parameters only when every batch carries the same share of `k`'s
/// information; in thermal fits a few batches where the temperature moves fast carry most of
/// it (for time constants even more than for gains), so `ν` is several times smaller and
/// intervals on `B − p` degrees of freedom under-cover (simulated AR(1) residuals: the spread
/// of `u_hac / u_true` was that of ~10-20 degrees of freedom, not ~56).
///
/// With `w_b = |a_b|²`, `u_b = [J_bᵀ a_b; Z_bᵀ a_b]` and `W = blockdiag((JᵀJ)⁻¹, (ZᵀZ)⁻¹)`
/// (`Z` the group indicators; `J` is orthogonal to them because the problem demeaned it):
/// `tr M = Σ w_b − Σ u_bᵀ W u_b`, `tr M² = Σ w_b² − 2 Σ w_b u_bᵀ W u_b + tr((W Σ u_b u_bᵀ)²)`.
/// Since `A = J K⁻¹` (`K = JᵀJ`, symmetric), batch `b`'s Jacobian part of every `u_b` is a
/// column of `G_b = J_bᵀ A_b`, and `K⁻¹ G_b = A_bᵀ A_b = S_b`: so `w_b = S_b[k, k]` and the
/// Jacobian part of `u_bᵀ W u_b` is `G_b[:, k] · S_b[:, k]`, two `p × p` products a batch for
/// every parameter at once. `P = Σ_b u_b u_bᵀ` is summed as `Uᵀ U` over chunks of
/// [`SCORE_ROWS`] batches. Cost `O(n p² + B p q²)` in matrix products (`B` batches,
/// `q = p` + groups), no refits: the per-parameter scalar loops it replaced took 35-86 ms a fit
/// at 42 k samples and 26 parameters, a tenth of the CPU of a diagnosis with three hidden effects
/// (`bench/README.md`). `None` when `JᵀJ` is singular.
pub(super) fn satterthwaite_dof(
    jac: &DMatrix<f64>,
    k_inv: &DMatrix<f64>,
    batch: usize,
    groups: Option<&[Option<usize>]>,
) -> Option<Vec<f64>> {
    let (n, p) = jac.shape();
    let inv_size = inverse_group_sizes(groups);
    let q = p + inv_size.len();
    let batch = batch.max(1);
    let mut sums = vec![BatchSums::default(); p];
    let mut big_p: Vec<DMatrix<f64>> = (0..p).map(|_| DMatrix::zeros(q, q)).collect();
    let mut scores: Vec<DMatrix<f64>> = (0..p).map(|_| DMatrix::zeros(SCORE_ROWS, q)).collect();
    let (mut g_b, mut s_b) = (DMatrix::<f64>::zeros(p, p), DMatrix::<f64>::zeros(p, p));
    let mut group_sums = DMatrix::<f64>::zeros(inv_size.len(), p);
    let mut touched: Vec<usize> = Vec::new();
    // `A = J K⁻¹` a block of whole batches at a time: the n × p product at once was one more
    // copy of the Jacobian held by every concurrent refit (27 MB on a bar of 128 k readings
    // with `settling`'s 15 amplitudes), and each row of it is the same product either way.
    let block_rows = batch * A_BLOCK_ROWS.div_ceil(batch);
    let (mut a_block, mut block_start) = (DMatrix::<f64>::zeros(0, p), 0);
    let (mut row, mut start) = (0, 0);
    while start < n {
        let end = (start + batch).min(n);
        if end > block_start + a_block.nrows() {
            block_start = start;
            a_block = jac.rows(start, block_rows.min(n - start)) * k_inv;
        }
        let a_b = a_block.rows(start - block_start, end - start);
        g_b.gemm_tr(1.0, &jac.rows(start, end - start), &a_b, 0.0);
        s_b.gemm_tr(1.0, &a_b, &a_b, 0.0);
        touched.clear();
        if let Some(groups) = groups {
            for (i, g) in groups[start..end].iter().enumerate() {
                if let Some(g) = *g {
                    if !touched.contains(&g) {
                        touched.push(g);
                    }
                    let mut sum = group_sums.row_mut(g);
                    sum += a_b.row(i);
                }
            }
        }
        for (k, (sums, u)) in sums.iter_mut().zip(&mut scores).enumerate() {
            let w = s_b[(k, k)];
            let mut uwu = g_b.column(k).dot(&s_b.column(k));
            u.view_mut((row, 0), (1, p))
                .copy_from(&g_b.column(k).transpose());
            for &g in &touched {
                let s = group_sums[(g, k)];
                uwu += s * s * inv_size[g];
                u[(row, p + g)] = s;
            }
            sums.add(w, uwu);
        }
        for &g in &touched {
            group_sums.row_mut(g).fill(0.0);
        }
        row += 1;
        start = end;
        if row == SCORE_ROWS || start >= n {
            for (big_p, u) in big_p.iter_mut().zip(&mut scores) {
                let rows = u.rows(0, row);
                big_p.gemm_tr(1.0, &rows, &rows, 1.0);
                u.fill(0.0);
            }
            row = 0;
        }
    }
    let mut w_mat = DMatrix::<f64>::zeros(q, q);
    w_mat.view_mut((0, 0), (p, p)).copy_from(k_inv);
    for (g, inv) in inv_size.iter().enumerate() {
        w_mat[(p + g, p + g)] = *inv;
    }
    let dof = sums.iter().zip(&big_p).map(|(sums, big_p)| {
        let wp = &w_mat * big_p;
        // tr((W P)²) = Σ_ij (WP)_ij (WP)_ji.
        let trace_sq: f64 = (0..q)
            .flat_map(|i| (0..q).map(move |j| (i, j)))
            .map(|(i, j)| wp[(i, j)] * wp[(j, i)])
            .sum();
        let tr2 = sums.w2 - 2.0 * sums.cross + trace_sq;
        let nu = if tr2 > 0.0 && sums.tr > 0.0 {
            sums.tr * sums.tr / tr2
        } else {
            1.0
        };
        nu.max(1.0)
    });
    Some(dof.collect())
}

/// Rows of `A = J K⁻¹` that [`satterthwaite_dof`] forms at a time (rounded up to whole batches):
/// 4 096 rows of 30 parameters are 1 MB.
const A_BLOCK_ROWS: usize = 4096;

/// Batches whose score rows [`satterthwaite_dof`] stacks before summing their outer products in
/// one matrix product: 128 rows of `q` columns for each parameter stay in cache.
const SCORE_ROWS: usize = 128;

/// One parameter's sums over the batches in [`satterthwaite_dof`]: `tr M = Σ (w_b − u_bᵀ W u_b)`,
/// `Σ w_b²` and `Σ w_b u_bᵀ W u_b`.
#[derive(Clone, Default)]
struct BatchSums {
    tr: f64,
    w2: f64,
    cross: f64,
}

impl BatchSums {
    fn add(&mut self, w: f64, uwu: f64) {
        self.tr += w - uwu;
        self.w2 += w * w;
        self.cross += w * uwu;
    }
}

/// `1 / size` of each absorbed group (by index; a group no sample belongs to counts as size 1).
fn inverse_group_sizes(groups: Option<&[Option<usize>]>) -> Vec<f64> {
    let Some(groups) = groups else {
        return Vec::new();
    };
    let n_groups = groups.iter().flatten().map(|&g| g + 1).max().unwrap_or(0);
    let mut size = vec![0usize; n_groups];
    for &g in groups.iter().flatten() {
        size[g] += 1;
    }
    size.iter().map(|&s| 1.0 / s.max(1) as f64).collect()
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

pub(super) fn n_batches(n: usize, batch_len: usize) -> usize {
    n.div_ceil(batch_len.max(1))
}
