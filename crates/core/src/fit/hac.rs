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
    residuals: &[f64],
    s2: f64,
    batch_len: Option<usize>,
    absorbed: usize,
) -> Option<(DMatrix<f64>, DMatrix<f64>, usize)> {
    let (n, p) = jac.shape();
    let p_total = p + absorbed;
    let jtj = jac.tr_mul(jac);
    // No pseudo-inverse: it would give the directions the data do not determine a zero
    // variance. [`fit`] refuses those first ([`undetermined_parameters`]).
    let jtj_inv = jtj.try_inverse()?;
    let cov_naive = &jtj_inv * s2;
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
    let cov_hac = &jtj_inv * meat * &jtj_inv;
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
/// Cost `O(n p²)`, no refits. `None` when `JᵀJ` is singular.
pub(super) fn satterthwaite_dof(
    jac: &DMatrix<f64>,
    batch: usize,
    groups: Option<&[Option<usize>]>,
) -> Option<Vec<f64>> {
    let (n, p) = jac.shape();
    let k_inv = jac.tr_mul(jac).try_inverse()?;
    let a_all = jac * &k_inv;
    let n_groups = groups
        .map(|g| g.iter().flatten().map(|&g| g + 1).max().unwrap_or(0))
        .unwrap_or(0);
    let mut group_size = vec![0usize; n_groups];
    if let Some(g) = groups {
        for &gi in g.iter().flatten() {
            group_size[gi] += 1;
        }
    }
    let q = p + n_groups;
    let mut w_mat = DMatrix::<f64>::zeros(q, q);
    w_mat.view_mut((0, 0), (p, p)).copy_from(&k_inv);
    for (g, &size) in group_size.iter().enumerate() {
        w_mat[(p + g, p + g)] = 1.0 / size.max(1) as f64;
    }
    let batch = batch.max(1);
    let mut out = Vec::with_capacity(p);
    // `u_b` is nonzero in the p Jacobian entries and in the few groups batch b touches; `W` is
    // block-diagonal. Both are used to keep each batch's cost at O((p + touched)²), not O(q²).
    let mut nonzero: Vec<usize> = Vec::with_capacity(q);
    let mut u = DVector::<f64>::zeros(q);
    let columns: Vec<&[f64]> = jac.as_slice().chunks_exact(n.max(1)).collect();
    for k in 0..p {
        let a = a_all.column(k);
        let a = a.as_slice();
        let (mut tr, mut w2, mut cross) = (0.0, 0.0, 0.0);
        let mut big_p = DMatrix::<f64>::zeros(q, q);
        let mut start = 0;
        while start < n {
            let end = (start + batch).min(n);
            nonzero.clear();
            nonzero.extend(0..p);
            let a_b = &a[start..end];
            let w = dot(a_b, a_b);
            for (j, col) in columns.iter().enumerate() {
                u[j] = dot(&col[start..end], a_b);
            }
            if let Some(groups) = groups {
                for (g, a_i) in groups[start..end].iter().zip(a_b) {
                    if let Some(g) = g {
                        if !nonzero.contains(&(p + g)) {
                            nonzero.push(p + g);
                        }
                        u[p + g] += a_i;
                    }
                }
            }
            let mut uwu = 0.0;
            for j in 0..p {
                for l in 0..p {
                    uwu += u[j] * k_inv[(j, l)] * u[l];
                }
            }
            for &g in &nonzero[p..] {
                uwu += u[g] * u[g] * w_mat[(g, g)];
            }
            tr += w - uwu;
            w2 += w * w;
            cross += w * uwu;
            for &r in &nonzero {
                for &c in &nonzero {
                    big_p[(r, c)] += u[r] * u[c];
                }
            }
            for &r in &nonzero {
                u[r] = 0.0;
            }
            start = end;
        }
        let wp = &w_mat * &big_p;
        let tr2 = w2 - 2.0 * cross + (&wp * &wp).trace();
        let nu = if tr2 > 0.0 && tr > 0.0 {
            tr * tr / tr2
        } else {
            1.0
        };
        out.push(nu.max(1.0));
    }
    Some(out)
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

pub(super) fn n_batches(n: usize, batch_len: usize) -> usize {
    n.div_ceil(batch_len.max(1))
}
