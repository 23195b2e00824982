//! The linear least-squares engine of the machine kinds: named parameters, optional per-row σ,
//! one SVD, the numerical rank, and what a rank-deficient design cannot see, by name.
//!
//! Every machine kind's evaluation at one target is a small linear problem `y ≈ A x`: the six
//! errors of an axis from interferometer channels (`docs/spec/machine-physics.md`, "Kind
//! axis"), the six pose errors from leg lengths ("Hexapod"). What matters there is not the fit
//! but its *identifiability*: with a reflector badly placed, one error is simply not measured,
//! and the report must say which one ("EAX is lost when z₁ = z₂").
//!
//! Why not `dbbcal_core::fit`: that engine fits long time series by separable nonlinear least
//! squares (variable projection, Levenberg-Marquardt, autocorrelation-consistent errors). Here
//! there is no nonlinear parameter and no time series, only one linear solve per target with
//! a handful of rows; the question it must answer is the rank, named. A separate small engine
//! keeps this crate free of the ballbar fit's dependencies and its answers in these words.
//!
//! # Method
//!
//! - Rows are weighted by 1/σᵢ when σ is given (σ ≤ 0 or non-finite is refused).
//! - The weighted design is decomposed by SVD (nalgebra), padded with zero rows to at least as
//!   many rows as parameters so that the full right singular basis is available (the padding
//!   does not change AᵀA).
//! - Numerical rank: singular values above [`SolveOptions::rank_rtol`] × the largest one
//!   (default [`DEFAULT_RANK_RTOL`] = 1e-10).
//! - Estimate: the minimum-norm least-squares solution V Σ⁺ Uᵀ y.
//! - Covariance `(AᵀWA)⁺ = V Σ⁻² Vᵀ` over the kept singular values, scaled by the residual
//!   variance when the rows are redundant (s² = RSS_w / (n − rank); with σ given this is the
//!   Birge ratio χ²/ν), taken as it is from the given σ when exactly determined. The a-priori
//!   covariance (given σ, no scaling) is kept too.
//! - Lost directions: the right singular vectors of the dropped singular values span what the
//!   data cannot see. They are brought to reduced row-echelon form (pivot coefficient 1) so
//!   that a single lost parameter reads as its name alone, a lost combination as e.g.
//!   `EBX + 0.5 ECX` *(ours)*. A parameter is *determined* when it is orthogonal to every
//!   lost direction; only determined parameters get an estimate and an uncertainty.

use nalgebra::{DMatrix, DVector};
use std::fmt;

/// Default relative tolerance of the numerical rank: singular values below this fraction of
/// the largest are treated as zero.
pub const DEFAULT_RANK_RTOL: f64 = 1e-10;

/// A parameter counts as determined when the norm of its projection onto the lost directions
/// is below this.
const DETERMINED_TOL: f64 = 1e-8;

/// Coefficients of a lost combination below this (after the pivot is scaled to 1) are printed
/// as absent.
const COEFF_TOL: f64 = 1e-9;

/// Errors of the linear engine: the input is empty or ill-shaped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinearError {
    /// No parameters were named.
    #[error("no parameters")]
    NoParameters,
    /// No rows were given.
    #[error("no rows")]
    NoRows,
    /// Two parameters share a name.
    #[error("parameter name {0:?} given twice")]
    DuplicateName(String),
    /// A design row has the wrong length.
    #[error("row {row} has {found} coefficients, expected {expected} (one per parameter)")]
    RowLength {
        /// Row index, from 0.
        row: usize,
        /// Number of parameters.
        expected: usize,
        /// Number of coefficients in the row.
        found: usize,
    },
    /// Observations or σ do not match the number of rows.
    #[error("{what}: {found} values for {rows} rows")]
    Count {
        /// `"observations"` or `"sigma"`.
        what: &'static str,
        /// Number of rows.
        rows: usize,
        /// Number of values given.
        found: usize,
    },
    /// A coefficient or an observation is NaN or infinite.
    #[error("row {row}: non-finite coefficient or observation")]
    NonFinite {
        /// Row index, from 0.
        row: usize,
    },
    /// A row's σ is not a positive finite number.
    #[error("row {row}: sigma {sigma} is not positive and finite")]
    BadSigma {
        /// Row index, from 0.
        row: usize,
        /// The value given.
        sigma: f64,
    },
    /// The rank tolerance is not in (0, 1).
    #[error("rank tolerance {0} is not in (0, 1)")]
    BadTolerance(f64),
}

/// A linear problem `y ≈ A x` with named parameters (the columns of `A`).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearProblem {
    /// Parameter names, one per column, e.g. `["EXX", "EYX", …]`.
    pub names: Vec<String>,
    /// Design rows, each with one coefficient per parameter.
    pub rows: Vec<Vec<f64>>,
    /// One observation per row.
    pub observations: Vec<f64>,
    /// Optional standard uncertainty of each observation (same unit as the observation).
    pub sigma: Option<Vec<f64>>,
}

/// Options of [`solve_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    /// Relative tolerance of the numerical rank (fraction of the largest singular value).
    pub rank_rtol: f64,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            rank_rtol: DEFAULT_RANK_RTOL,
        }
    }
}

/// Where [`LinearSolution::covariance`] takes its scale from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CovarianceSource {
    /// Redundant rows: scaled by the residual variance s² = RSS_w / (n − rank).
    Residuals,
    /// Exactly determined (no residual degree of freedom): from the given σ.
    GivenSigma,
    /// Exactly determined and no σ given: no covariance can be stated.
    None,
}

/// A direction in parameter space that the rows do not see: adding any multiple of it to the
/// estimate leaves every prediction unchanged.
#[derive(Debug, Clone, PartialEq)]
pub struct LostCombination {
    /// (parameter name, coefficient) of the non-zero terms; the first (pivot) coefficient is 1.
    pub terms: Vec<(String, f64)>,
}

impl LostCombination {
    /// The single parameter lost, when the combination is one parameter alone.
    pub fn single(&self) -> Option<&str> {
        match self.terms.as_slice() {
            [(name, _)] => Some(name),
            _ => None,
        }
    }
}

impl fmt::Display for LostCombination {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (name, c)) in self.terms.iter().enumerate() {
            let a = c.abs();
            if i == 0 {
                if *c < 0.0 {
                    write!(f, "−")?;
                }
            } else {
                write!(f, " {} ", if *c < 0.0 { "−" } else { "+" })?;
            }
            if (a - 1.0).abs() < 1e-12 {
                write!(f, "{name}")?;
            } else {
                write!(f, "{} {name}", fmt_coeff(a))?;
            }
        }
        Ok(())
    }
}

fn fmt_coeff(a: f64) -> String {
    let s = format!("{a:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// The solution of a [`LinearProblem`].
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSolution {
    /// Parameter names, as given.
    pub names: Vec<String>,
    /// Minimum-norm least-squares estimate, one per parameter (meaningful only where
    /// [`determined`](Self::determined)).
    pub estimate: Vec<f64>,
    /// Whether each parameter is determined by the rows (orthogonal to every lost direction).
    pub determined: Vec<bool>,
    /// Parameter covariance per [`covariance_source`](Self::covariance_source); `None` when no
    /// scale is available (exactly determined, no σ).
    pub covariance: Option<DMatrix<f64>>,
    /// Where the covariance's scale comes from.
    pub covariance_source: CovarianceSource,
    /// Covariance from the given σ alone, `(AᵀWA)⁺`, without residual scaling; `None` without σ.
    pub covariance_given: Option<DMatrix<f64>>,
    /// Residuals y − A x̂ (unweighted, in the observations' unit).
    pub residuals: Vec<f64>,
    /// Weighted residual sum of squares Σ ((yᵢ − aᵢ x̂)/σᵢ)² (σᵢ = 1 without σ).
    pub rss_weighted: f64,
    /// Numerical rank.
    pub rank: usize,
    /// Residual degrees of freedom, n − rank.
    pub dof: usize,
    /// Singular values of the weighted design, largest first.
    pub singular_values: Vec<f64>,
    /// The relative rank tolerance used.
    pub rank_rtol: f64,
    /// A basis of what the rows do not see, as named combinations (empty at full rank).
    pub lost: Vec<LostCombination>,
}

impl LinearSolution {
    /// Index of a parameter by name.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Estimate of a determined parameter; `None` when unknown or not determined.
    pub fn value(&self, name: &str) -> Option<f64> {
        let k = self.index(name)?;
        self.determined[k].then(|| self.estimate[k])
    }

    /// Standard uncertainty of a determined parameter from [`covariance`](Self::covariance).
    pub fn std_uncertainty(&self, name: &str) -> Option<f64> {
        let k = self.index(name)?;
        let c = self.covariance.as_ref()?;
        self.determined[k].then(|| c[(k, k)].max(0.0).sqrt())
    }

    /// Whether all parameters are determined.
    pub fn full_rank(&self) -> bool {
        self.rank == self.names.len()
    }

    /// Condition number of the weighted design (largest / smallest singular value; infinite
    /// when rank-deficient).
    pub fn condition_number(&self) -> f64 {
        match (self.singular_values.first(), self.singular_values.last()) {
            (Some(&a), Some(&b)) if b > 0.0 && self.full_rank() => a / b,
            _ => f64::INFINITY,
        }
    }

    /// Names of the parameters that are not determined.
    pub fn undetermined_names(&self) -> Vec<&str> {
        self.names
            .iter()
            .zip(&self.determined)
            .filter(|(_, d)| !**d)
            .map(|(n, _)| n.as_str())
            .collect()
    }
}

/// Solve with the default options ([`DEFAULT_RANK_RTOL`]).
pub fn solve(problem: &LinearProblem) -> Result<LinearSolution, LinearError> {
    solve_with(problem, SolveOptions::default())
}

/// Solve `problem` by SVD; see the module documentation.
pub fn solve_with(
    problem: &LinearProblem,
    options: SolveOptions,
) -> Result<LinearSolution, LinearError> {
    let p = problem.names.len();
    let n = problem.rows.len();
    validate(problem, options)?;
    let weights: Vec<f64> = match &problem.sigma {
        Some(s) => s.iter().map(|s| 1.0 / s).collect(),
        None => vec![1.0; n],
    };
    // Weighted design, padded with zero rows to at least p rows.
    let m = n.max(p);
    let mut a = DMatrix::<f64>::zeros(m, p);
    let mut y = DVector::<f64>::zeros(m);
    for (i, row) in problem.rows.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            a[(i, j)] = v * weights[i];
        }
        y[i] = problem.observations[i] * weights[i];
    }
    let svd = a.svd(true, true);
    let u = svd.u.expect("u requested");
    let v_t = svd.v_t.expect("v_t requested");
    // nalgebra does not promise an order: sort descending.
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let s: Vec<f64> = order.iter().map(|&k| svd.singular_values[k]).collect();
    let s_max = s.first().copied().unwrap_or(0.0);
    let cut = options.rank_rtol * s_max;
    let rank = s.iter().filter(|&&v| v > cut && v > 0.0).count();

    let mut x = DVector::<f64>::zeros(p);
    let mut cov = DMatrix::<f64>::zeros(p, p);
    for &k in order.iter().take(rank) {
        let sk = svd.singular_values[k];
        let vk = v_t.row(k).transpose();
        let coef = u.column(k).dot(&y) / sk;
        x += &vk * coef;
        cov += &vk * vk.transpose() / (sk * sk);
    }
    // Lost directions: right singular vectors of the dropped singular values.
    let null: Vec<DVector<f64>> = order
        .iter()
        .skip(rank)
        .map(|&k| v_t.row(k).transpose())
        .collect();
    let determined: Vec<bool> = (0..p)
        .map(|j| null.iter().map(|v| v[j] * v[j]).sum::<f64>().sqrt() < DETERMINED_TOL)
        .collect();
    let lost = name_null_space(&problem.names, &null);

    let mut residuals = Vec::with_capacity(n);
    let mut rss_w = 0.0;
    for (i, row) in problem.rows.iter().enumerate() {
        let pred: f64 = row.iter().zip(x.iter()).map(|(a, b)| a * b).sum();
        let r = problem.observations[i] - pred;
        residuals.push(r);
        rss_w += (r * weights[i]).powi(2);
    }
    let dof = n - rank;
    let covariance_given = problem.sigma.as_ref().map(|_| cov.clone());
    let (covariance, covariance_source) = if dof > 0 {
        (
            Some(&cov * (rss_w / dof as f64)),
            CovarianceSource::Residuals,
        )
    } else if problem.sigma.is_some() {
        (Some(cov.clone()), CovarianceSource::GivenSigma)
    } else {
        (None, CovarianceSource::None)
    };
    Ok(LinearSolution {
        names: problem.names.clone(),
        estimate: x.iter().copied().collect(),
        determined,
        covariance,
        covariance_source,
        covariance_given,
        residuals,
        rss_weighted: rss_w,
        rank,
        dof,
        singular_values: s.into_iter().take(p.min(n)).collect(),
        rank_rtol: options.rank_rtol,
        lost,
    })
}

fn validate(problem: &LinearProblem, options: SolveOptions) -> Result<(), LinearError> {
    let p = problem.names.len();
    let n = problem.rows.len();
    if p == 0 {
        return Err(LinearError::NoParameters);
    }
    if n == 0 {
        return Err(LinearError::NoRows);
    }
    if !(options.rank_rtol > 0.0 && options.rank_rtol < 1.0) {
        return Err(LinearError::BadTolerance(options.rank_rtol));
    }
    for (i, name) in problem.names.iter().enumerate() {
        if problem.names[..i].contains(name) {
            return Err(LinearError::DuplicateName(name.clone()));
        }
    }
    if problem.observations.len() != n {
        return Err(LinearError::Count {
            what: "observations",
            rows: n,
            found: problem.observations.len(),
        });
    }
    if let Some(s) = &problem.sigma {
        if s.len() != n {
            return Err(LinearError::Count {
                what: "sigma",
                rows: n,
                found: s.len(),
            });
        }
        if let Some((row, &sigma)) = s
            .iter()
            .enumerate()
            .find(|(_, s)| !(s.is_finite() && **s > 0.0))
        {
            return Err(LinearError::BadSigma { row, sigma });
        }
    }
    for (row, r) in problem.rows.iter().enumerate() {
        if r.len() != p {
            return Err(LinearError::RowLength {
                row,
                expected: p,
                found: r.len(),
            });
        }
        if !(r.iter().all(|v| v.is_finite()) && problem.observations[row].is_finite()) {
            return Err(LinearError::NonFinite { row });
        }
    }
    Ok(())
}

/// Reduced row-echelon form of the null basis (rows = lost directions), each row a named
/// combination with pivot coefficient 1.
fn name_null_space(names: &[String], null: &[DVector<f64>]) -> Vec<LostCombination> {
    let k = null.len();
    if k == 0 {
        return Vec::new();
    }
    let p = names.len();
    let mut m = DMatrix::<f64>::zeros(k, p);
    for (i, v) in null.iter().enumerate() {
        m.set_row(i, &v.transpose());
    }
    let mut lead = 0;
    for r in 0..k {
        // Pivot: largest magnitude in the first column (from `lead`) that has a usable one.
        let mut pivot = None;
        while lead < p {
            let (best, val) = (r..k)
                .map(|i| (i, m[(i, lead)].abs()))
                .fold((r, 0.0), |acc, c| if c.1 > acc.1 { c } else { acc });
            if val > 1e-8 {
                pivot = Some(best);
                break;
            }
            lead += 1;
        }
        let Some(pr) = pivot else { break };
        m.swap_rows(r, pr);
        let pv = m[(r, lead)];
        let row = m.row(r) / pv;
        m.set_row(r, &row);
        for i in 0..k {
            if i != r {
                let f = m[(i, lead)];
                let sub = m.row(r) * f;
                let new = m.row(i) - sub;
                m.set_row(i, &new);
            }
        }
        lead += 1;
    }
    (0..k)
        .map(|i| LostCombination {
            terms: (0..p)
                .filter(|&j| m[(i, j)].abs() > COEFF_TOL)
                .map(|j| (names[j].clone(), m[(i, j)]))
                .collect(),
        })
        .filter(|c| !c.terms.is_empty())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn a_straight_line_with_residual_scale() {
        // y = 1 + 2 x with residuals ±0.1.
        let xs = [0.0, 1.0, 2.0, 3.0];
        let e = [0.1, -0.1, -0.1, 0.1];
        let problem = LinearProblem {
            names: names(&["a", "b"]),
            rows: xs.iter().map(|&x| vec![1.0, x]).collect(),
            observations: xs.iter().zip(e).map(|(&x, e)| 1.0 + 2.0 * x + e).collect(),
            sigma: None,
        };
        let s = solve(&problem).unwrap();
        assert_eq!(s.rank, 2);
        assert_eq!(s.dof, 2);
        assert!((s.value("a").unwrap() - 1.0).abs() < 1e-12);
        assert!((s.value("b").unwrap() - 2.0).abs() < 1e-12);
        assert_eq!(s.covariance_source, CovarianceSource::Residuals);
        // s² = 0.04 / 2 = 0.02; var(b) = s² / Σ(x − x̄)² = 0.02 / 5.
        let ub = s.std_uncertainty("b").unwrap();
        assert!((ub - (0.02f64 / 5.0).sqrt()).abs() < 1e-12, "{ub}");
        let r: f64 = s.residuals.iter().zip(e).map(|(a, b)| (a - b).abs()).sum();
        assert!(r < 1e-12);
        assert!(s.lost.is_empty());
    }

    #[test]
    fn exactly_determined_takes_the_given_sigma() {
        let problem = LinearProblem {
            names: names(&["a", "b"]),
            rows: vec![vec![1.0, 0.0], vec![1.0, 1.0]],
            observations: vec![3.0, 5.0],
            sigma: Some(vec![0.1, 0.1]),
        };
        let s = solve(&problem).unwrap();
        assert_eq!(s.dof, 0);
        assert_eq!(s.covariance_source, CovarianceSource::GivenSigma);
        assert!((s.value("b").unwrap() - 2.0).abs() < 1e-12);
        // b = y2 − y1: σ √2.
        assert!((s.std_uncertainty("b").unwrap() - 0.1 * 2f64.sqrt()).abs() < 1e-12);
        let no_sigma = LinearProblem {
            sigma: None,
            ..problem
        };
        let s = solve(&no_sigma).unwrap();
        assert_eq!(s.covariance_source, CovarianceSource::None);
        assert!(s.std_uncertainty("a").is_none());
    }

    #[test]
    fn a_lost_parameter_and_a_lost_combination_are_named() {
        // c never appears; a and b appear only as a + b.
        let problem = LinearProblem {
            names: names(&["a", "b", "c", "d"]),
            rows: vec![
                vec![1.0, 1.0, 0.0, 0.0],
                vec![2.0, 2.0, 0.0, 1.0],
                vec![0.0, 0.0, 0.0, 1.0],
            ],
            observations: vec![3.0, 7.0, 1.0],
            sigma: None,
        };
        let s = solve(&problem).unwrap();
        assert_eq!(s.rank, 2);
        assert_eq!(s.undetermined_names(), vec!["a", "b", "c"]);
        assert!((s.value("d").unwrap() - 1.0).abs() < 1e-12);
        let texts: Vec<String> = s.lost.iter().map(|c| c.to_string()).collect();
        assert_eq!(texts, vec!["a − b", "c"], "{texts:?}");
        assert_eq!(s.lost[1].single(), Some("c"));
        assert!(s.condition_number().is_infinite());
    }

    #[test]
    fn fewer_rows_than_parameters() {
        let problem = LinearProblem {
            names: names(&["a", "b", "c"]),
            rows: vec![vec![1.0, 0.0, 0.0]],
            observations: vec![2.0],
            sigma: Some(vec![0.5]),
        };
        let s = solve(&problem).unwrap();
        assert_eq!(s.rank, 1);
        assert_eq!(s.value("a"), Some(2.0));
        assert_eq!(s.lost.len(), 2);
        assert_eq!(s.lost[0].to_string(), "b");
        assert_eq!(s.lost[1].to_string(), "c");
        assert!((s.std_uncertainty("a").unwrap() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn weights_change_the_estimate() {
        // Two readings of one quantity: the weighted mean.
        let problem = LinearProblem {
            names: names(&["a"]),
            rows: vec![vec![1.0], vec![1.0]],
            observations: vec![0.0, 3.0],
            sigma: Some(vec![1.0, 2.0]),
        };
        let s = solve(&problem).unwrap();
        // weights 1 and 1/4: (0 + 3/4) / (1 + 1/4) = 0.6.
        assert!((s.value("a").unwrap() - 0.6).abs() < 1e-12);
        let g = s.covariance_given.as_ref().unwrap()[(0, 0)];
        assert!((g - 0.8).abs() < 1e-12);
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let ok = LinearProblem {
            names: names(&["a", "b"]),
            rows: vec![vec![1.0, 0.0]],
            observations: vec![1.0],
            sigma: None,
        };
        let e = |p: LinearProblem| solve(&p).unwrap_err();
        assert_eq!(
            e(LinearProblem {
                names: vec![],
                ..ok.clone()
            }),
            LinearError::NoParameters
        );
        assert_eq!(
            e(LinearProblem {
                rows: vec![],
                observations: vec![],
                ..ok.clone()
            }),
            LinearError::NoRows
        );
        assert!(matches!(
            e(LinearProblem {
                rows: vec![vec![1.0]],
                ..ok.clone()
            }),
            LinearError::RowLength { row: 0, .. }
        ));
        assert!(matches!(
            e(LinearProblem {
                observations: vec![1.0, 2.0],
                ..ok.clone()
            }),
            LinearError::Count { .. }
        ));
        assert!(matches!(
            e(LinearProblem {
                sigma: Some(vec![0.0]),
                ..ok.clone()
            }),
            LinearError::BadSigma { .. }
        ));
        assert!(matches!(
            e(LinearProblem {
                observations: vec![f64::NAN],
                ..ok.clone()
            }),
            LinearError::NonFinite { row: 0 }
        ));
        assert!(matches!(
            e(LinearProblem {
                names: names(&["a", "a"]),
                ..ok.clone()
            }),
            LinearError::DuplicateName(_)
        ));
        assert!(matches!(
            solve_with(&ok, SolveOptions { rank_rtol: 0.0 }),
            Err(LinearError::BadTolerance(_))
        ));
    }
}
