//! The one fitting engine: separable nonlinear least squares by variable projection.
//!
//! Every fit in dbbcal (thermal models, diagnostics candidates, NIST reference problems) is
//! `y ≈ Φ(θ) c`: linear coefficients `c` (gains, zeros, drifts) and a few nonlinear parameters
//! `θ` (time constants, usually as `ln tau`). A problem says how to evaluate the basis `Φ(θ)` and
//! its derivatives ([`Separable`]); this module
//! 1. starts `θ` by a coordinate-wise 1-D Brent search (argmin) of the variable-projection
//!    residual (the linear part solved exactly at each trial), when the problem asks for it,
//! 2. polishes with Levenberg-Marquardt (the `levenberg-marquardt` crate) on the projected
//!    problem, Kaufman's Jacobian, or, from a nearby
//!    problem's optimum (a long series' coarse copy), with argmin's Gauss-Newton on the same
//!    projected residual ([`Start::NearOptimum`]),
//! 3. returns estimates with two covariances: the textbook `s² (JᵀJ)⁻¹` and a heteroscedasticity-
//!    and-autocorrelation-consistent sandwich (batch-means HAC), because residuals of thermal fits
//!    are strongly autocorrelated and the textbook errors are then far too small.
//!
//! Fit does no IO.
//!
//! # How it works
//!
//! - Uncertainty: batch-means HAC with batch = 10 × the residual correlation time, lengthened where
//!   the residuals' variance-time curve shows a slow part under white noise, a batch-level
//!   B/(B−p) correction, a batch-edge bias correction and Student's t on each parameter's
//!   Satterthwaite (Bell-McCaffrey) degrees of freedom, far fewer than B − p when a few batches carry
//!   the information. The reported u is never below the white-noise one (`Fit::se`; then
//!   with the residual degrees of freedom, `Fit::dof_of`). Time constants from `identify`: adjusted profile-likelihood
//!   intervals of `ln tau` (profile RSS cut at `t² u_hac² / [(JᵀJ)⁻¹]_kk`, the Wald interval when
//!   linear; `identify::profile_tau_intervals`, ~1.3 fits' cost for two taus; series of ≥ 50 000
//!   samples are profiled on their 300-s coarse copy, `identify::coarse_copy`). Tested for coverage
//!   (93-97 % for gains and taus) in `identify`'s tests (`identify/tests.rs`).
//! - Linear algebra on tall matrices: every solve and projected residual goes through one
//!   column-scaled Householder QR of the basis, by blocks of rows (`projection::Factorised`),
//!   applied without forming `Q`; columns each nonzero on their own short run of rows
//!   (`settling`'s amplitude of each mount) are projected out directly first, and only the
//!   other columns go through the QR; the Jacobian's rank check takes the SVD of its `R` factor;
//!   `JᵀJ` is a matrix product (`gram`). Against varpro's SVD at every evaluation this takes
//!   20-36 % of the CPU off the nightly runs of 10-bar, 15-day, 10-s campaigns with a hidden
//!   effect, with the same ledgers (ΔBIC equal to 12 digits; `bench/results-speed26b.md`).
//!   A Brent sweep of one `θ_k` factorises the columns not on `θ_k` once
//!   (`Separable::columns_on`, `projection::HeldProjection`) and orthogonalises only the moving
//!   columns at each trial; a problem that does not name its columns is refactorised whole.
//! - The HAC covariance needs the residual autocorrelation only up to its first non-positive lag:
//!   direct sums, O(n) a lag, the FFT only past 32 lags (`fit::initial_autocorrelation`).

use nalgebra::DMatrix;
use nalgebra::DVector;

mod autocorrelation;
mod hac;
mod identifiability;
mod levmar;
mod linearise;
mod polish;
mod profile;
mod projection;

pub use autocorrelation::hac_batch_length;
pub(crate) use autocorrelation::{autocorrelation, integrated_autocorrelation_time};
pub(crate) use hac::t_quantile_975;
use hac::{covariances, n_batches, satterthwaite_dof};
pub(crate) use identifiability::{undetermined_parameters, MIN_RELATIVE_SINGULAR_VALUE};
use levmar::{brent_start, levenberg_marquardt};
use linearise::full_jacobian;
pub(crate) use linearise::{jacobian_at, linearise, orthonormal_basis, Orthogonalised};
use polish::polish;
pub(crate) use profile::profile_interval;
pub(crate) use projection::projected_rss;
use projection::{singular_term, solve_linear};

/// A separable least-squares problem `y ≈ Φ(θ) c`.
pub trait Separable: Sync {
    /// Observations `y`.
    fn observations(&self) -> &[f64];
    /// Names of the nonlinear parameters `θ`, in order.
    fn nonlinear_names(&self) -> Vec<String>;
    /// Names of the linear coefficients `c` (the columns of `Φ`), in order.
    fn linear_names(&self) -> Vec<String>;
    /// `Φ(θ)`, `n × m`.
    fn basis(&self, theta: &[f64]) -> DMatrix<f64>;
    /// `∂Φ/∂θ_k`, `n × m` (columns that do not depend on `θ_k` are zero).
    fn basis_derivative(&self, theta: &[f64], k: usize) -> DMatrix<f64>;
    /// `∂Φ/∂θ_k c`, the Jacobian's column of `θ_k` before projection. A problem whose
    /// derivative has few non-zero columns may sum those alone instead of filling the `n × m`
    /// matrix (every solver step asks for one per time constant).
    fn basis_derivative_times(&self, theta: &[f64], k: usize, coef: &DVector<f64>) -> DVector<f64> {
        self.basis_derivative(theta, k) * coef
    }
    /// The columns of `Φ` that depend on `θ_k`, or `None` when the problem does not say. Where
    /// a problem says, the Brent start factorises the other columns once a sweep of `θ_k`
    /// instead of the whole basis at every trial (`projection::HeldProjection`).
    fn columns_on(&self, _k: usize) -> Option<Vec<usize>> {
        None
    }
    /// Columns `columns` of `Φ(θ)`, in that order (`n × columns.len()`).
    fn basis_columns_of(&self, theta: &[f64], columns: &[usize]) -> DMatrix<f64> {
        self.basis(theta).select_columns(columns)
    }
    /// Search interval for a coordinate-wise Brent start of `θ_k`, or `None` to start at the
    /// given value as it is.
    fn start_search_interval(&self, _k: usize) -> Option<(f64, f64)> {
        None
    }
    /// The interval the basis holds `θ_k` to (it clamps `θ_k` there, so beyond it the basis
    /// does not change), or `None` when it takes every value as it is. The minimisers start
    /// inside it and see a `θ_k` beyond it as held (`held_beyond_bounds`).
    fn nonlinear_bounds(&self, _k: usize) -> Option<(f64, f64)> {
        None
    }
    /// Group of each observation whose mean the problem projected out before the engine saw it
    /// (e.g. the mount zeros: observations and every basis column already demeaned within each
    /// group), `None` for an observation in no group; `None` altogether when nothing was
    /// projected out. Used by the degrees of freedom of the HAC variance
    /// (`Fit::hac_dof_param`); the count must match [`FitOptions::absorbed_params`].
    fn absorbed_groups(&self) -> Option<Vec<Option<usize>>> {
        None
    }
    /// Residual sum of squares that no fit of this problem can change, added to every RSS the
    /// engine reports: e.g. the scatter of compressed bins about their own straight lines
    /// (`series::bins`). A problem whose observations are the samples themselves has none.
    fn unexplained_rss(&self) -> f64 {
        0.0
    }
    /// Number of samples the observations stand for (`n` of the RMS, the likelihood and the
    /// BIC): more than `observations().len()` when each observation is a weighted node of a
    /// compressed bin.
    fn represented_samples(&self) -> usize {
        self.observations().len()
    }
}

/// A linear least-squares problem `y ≈ Φ c` with fixed columns (no nonlinear parameters): the
/// engine's covariances and degrees of freedom for a plain linear fit (the calibration's
/// centre-distance functions, tests of the uncertainty rules).
pub(crate) struct FixedColumns {
    pub(crate) y: Vec<f64>,
    pub(crate) phi: DMatrix<f64>,
    pub(crate) names: Vec<String>,
}

impl Separable for FixedColumns {
    fn observations(&self) -> &[f64] {
        &self.y
    }
    fn nonlinear_names(&self) -> Vec<String> {
        Vec::new()
    }
    fn linear_names(&self) -> Vec<String> {
        self.names.clone()
    }
    fn basis(&self, _theta: &[f64]) -> DMatrix<f64> {
        self.phi.clone()
    }
    fn basis_derivative(&self, _theta: &[f64], _k: usize) -> DMatrix<f64> {
        DMatrix::zeros(self.phi.nrows(), self.phi.ncols())
    }
}

/// Why a fit could not be done.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum FitError {
    /// Fewer samples than parameters.
    #[error("too few samples ({n}) for {p} parameters")]
    TooFewSamples {
        /// Samples.
        n: usize,
        /// Parameters.
        p: usize,
    },
    /// The basis is singular; names the term that cannot be separated.
    #[error("the basis is singular: {0} cannot be separated from the other terms with these data")]
    Singular(String),
    /// Parameters the data cannot determine: a direction of the model's Jacobian that the data
    /// do not constrain (`undetermined_parameters`), or (for the thermal model) a column that
    /// vanishes once the mount zeros are taken out. Reported instead of an estimate whose
    /// uncertainty would come from a (pseudo-)inverse of a singular matrix.
    #[error("not identifiable: these data cannot determine {params} ({reason})")]
    NotIdentifiable {
        /// The parameters concerned.
        params: String,
        /// Why the data cannot determine them.
        reason: String,
    },
    /// The solver did not converge (its message).
    #[error("the solver did not converge ({0})")]
    NoConvergence(String),
    /// NaN or infinite values in the data or the model.
    #[error("non-finite values in the data or the model")]
    NonFinite,
}

/// Estimates of one fit, in the problem's parametrisation: linear coefficients first, then the
/// nonlinear parameters.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Parameter names, same order as `values`.
    pub names: Vec<String>,
    /// Linear coefficients then nonlinear parameters.
    pub values: Vec<f64>,
    pub(crate) n_linear: usize,
    pub(crate) residuals: Vec<f64>,
    /// Residual sum of squares at the minimum.
    pub rss: f64,
    pub(crate) n_obs: usize,
    /// `s² (JᵀJ)⁻¹`: valid only for white residuals.
    pub(crate) cov_naive: DMatrix<f64>,
    /// Batch-means HAC sandwich: honest under autocorrelated residuals.
    pub(crate) cov_hac: DMatrix<f64>,
    /// Batch length (samples) used by the HAC estimate.
    pub(crate) hac_batch_len: usize,
    /// Number of batches − number of parameters: the degrees of freedom the HAC variance would
    /// have if every batch carried the same share of information.
    pub hac_dof: usize,
    /// Effective (Satterthwaite) degrees of freedom of each parameter's HAC variance, same order
    /// as `values`: at most about [`Fit::hac_dof`], fewer when a few batches carry most of that
    /// parameter's information. Intervals use Student's t with these.
    pub(crate) hac_dof_param: Vec<f64>,
    /// Solver iterations.
    pub iterations: usize,
}

impl Fit {
    pub(crate) fn n_params(&self) -> usize {
        self.values.len()
    }
    /// Residual degrees of freedom: observations − parameters, at least 1.
    pub fn dof(&self) -> usize {
        self.n_obs.saturating_sub(self.n_params()).max(1)
    }
    pub(crate) fn rms(&self) -> f64 {
        (self.rss / self.n_obs.max(1) as f64).sqrt()
    }
    /// Standard error of parameter `i` for white residuals (from `s² (JᵀJ)⁻¹`).
    pub fn se_naive(&self, i: usize) -> f64 {
        self.cov_naive[(i, i)].max(0.0).sqrt()
    }
    /// Standard error of parameter `i` as reported: the HAC one, never below the white-noise
    /// one ([`Fit::se_naive`]).
    ///
    /// Why the floor: the model's regressors (lags, decays, levels) are smooth, and a thermal
    /// fit's residuals are white or positively correlated, so the long-run variance of every
    /// score is at least its white-noise variance. A batch-means estimate below it is that
    /// estimator's own sampling noise, large for a parameter whose information sits in a few
    /// batches (a head's gain on a 2-day campaign: few switches). On the second simulator
    /// (`bench/foreign_check.py --cases head`) the head parameters' HAC u ran as low as half the
    /// white-noise u (10th percentile 0.76-0.86 of it), and one gain lay 3.46 HAC u from the
    /// truth, 1.8 white-noise u.
    pub(crate) fn se(&self, i: usize) -> f64 {
        self.cov_hac[(i, i)]
            .max(self.cov_naive[(i, i)])
            .max(0.0)
            .sqrt()
    }
    /// Half-width factor of a 95 % interval from the standard error of parameter `i` ([`Fit::se`]):
    /// Student's t quantile with [`Fit::dof_of`]`(i)` degrees of freedom.
    pub(crate) fn t95(&self, i: usize) -> f64 {
        t_quantile_975(self.dof_of(i))
    }
    /// Degrees of freedom of [`Fit::se`]`(i)`: the Satterthwaite ones of the HAC variance
    /// ([`Fit::hac_dof_param`]), or the residual ones where the white-noise variance is taken.
    pub(crate) fn dof_of(&self, i: usize) -> f64 {
        if self.cov_hac[(i, i)] >= self.cov_naive[(i, i)] {
            self.hac_dof_param[i]
        } else {
            self.dof() as f64
        }
    }

    /// Gaussian log-likelihood at the ML variance `rss / n`.
    pub(crate) fn log_likelihood(&self) -> f64 {
        let n = self.n_obs as f64;
        -0.5 * n * ((2.0 * std::f64::consts::PI * self.rss / n).ln() + 1.0)
    }
    /// Bayesian information criterion (`k` counts the noise variance too).
    pub(crate) fn bic(&self) -> f64 {
        let k = self.n_params() as f64 + 1.0;
        -2.0 * self.log_likelihood() + k * (self.n_obs as f64).ln()
    }
    /// Correlation matrix of the HAC covariance.
    pub(crate) fn correlation(&self) -> DMatrix<f64> {
        let p = self.n_params();
        DMatrix::from_fn(p, p, |i, j| {
            let d = (self.cov_hac[(i, i)] * self.cov_hac[(j, j)]).sqrt();
            if d > 0.0 {
                self.cov_hac[(i, j)] / d
            } else if i == j {
                1.0
            } else {
                0.0
            }
        })
    }
}

/// `AᵀA` of a tall matrix: by the transpose and a matrix product (nalgebra's blocked,
/// vectorised kernel), about four times faster than `tr_mul`'s column dot products on the
/// diagnosis' 130 000-row Jacobians.
pub(crate) fn gram(a: &DMatrix<f64>) -> DMatrix<f64> {
    a.transpose() * a
}

/// Whether `θ_k` lies beyond the interval `problem`'s basis holds it to
/// ([`Separable::nonlinear_bounds`]): the basis is flat in `θ_k` there, so the minimisers'
/// Jacobian column of `θ_k` is zero and the step leaves it where it is.
///
/// Why: the derivative of a clamped basis beyond its bound is zero, not the derivative at the
/// bound. Given the latter, Levenberg-Marquardt kept predicting a gain from moving a time
/// constant that had run off (a `scale` lag with `ln τ` at −300 on half the bars of the second
/// simulator's campaigns), refused step after step, and spent 10-20 evaluations of the
/// readings on each refit of those bars.
pub(crate) fn held_beyond_bounds<P: Separable + ?Sized>(
    problem: &P,
    theta: &[f64],
    k: usize,
) -> bool {
    problem
        .nonlinear_bounds(k)
        .is_some_and(|(lo, hi)| theta[k] < lo || theta[k] > hi)
}

/// `theta` with each parameter brought inside its bounds ([`Separable::nonlinear_bounds`]): the
/// same basis, and a start from which every parameter can move.
pub(crate) fn within_bounds<P: Separable + ?Sized>(problem: &P, theta: &[f64]) -> Vec<f64> {
    theta
        .iter()
        .enumerate()
        .map(|(k, &t)| match problem.nonlinear_bounds(k) {
            Some((lo, hi)) => t.clamp(lo, hi),
            None => t,
        })
        .collect()
}

/// How the engine reaches the minimum from the nonlinear start it is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// A coordinate-wise Brent sweep of each time constant first, then Levenberg-Marquardt.
    Brent,
    /// Levenberg-Marquardt from the start.
    Given,
    /// The start is the optimum of a nearby problem (a long series' coarse copy): argmin's
    /// Gauss-Newton on the variable-projection residual from it (`polish`),
    /// Levenberg-Marquardt from the better of start and stop if it does not converge.
    NearOptimum,
}

/// When the minimiser stops: a step that lowers the residual sum of squares by less than a
/// share of it (`Stop::relative_rss_tolerance`) is no progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// A fixed share, 1e-10: the optimum to the digits a reference solution certifies (the
    /// NIST StRD problems of the tests, a handful of points each).
    Numerical,
    /// 0.01 noise variances (`STOP_CHI2`): what a fit read as a statistic can resolve (the thermal
    /// models' fits, which feed likelihood-ratio tests, BICs and uncertainties).
    Statistical,
}

/// A step of a [`Stop::Statistical`] fit that lowers the residual sum of squares by less than
/// this many noise variances is no progress.
///
/// Why 0.01: the fit's statistics read its RSS as `χ²` (a likelihood-ratio statistic, `n ln RSS`
/// in a BIC); 0.01 of one `χ²` unit is far below any test's resolution, and the parameters are
/// then within about a tenth of their standard uncertainty of the optimum. A fixed share of the
/// RSS instead (1e-10) kept refits whose time constants lie in a long valley (a `scale` lag with
/// little to determine it, a candidate running off to `τ → ∞`) creeping for dozens of
/// evaluations on a 10-s, 15-day bar's 130 k readings, each moving the RSS by less than that.
pub(crate) const STOP_CHI2: f64 = 0.01;

impl Stop {
    /// The share of the residual sum of squares a step must lower it by to count as progress,
    /// for `n` observations. Statistical: [`STOP_CHI2`] noise variances when the model fits to
    /// the noise (`RSS ≈ n σ²`), less strict in `χ²` where it does not; between 1e-10 and 1e-6.
    pub(crate) fn relative_rss_tolerance(self, n: usize) -> f64 {
        match self {
            Stop::Numerical => 1e-10,
            Stop::Statistical => (STOP_CHI2 / n.max(1) as f64).clamp(1e-10, 1e-6),
        }
    }

    /// Convergence of the Gauss-Newton polish ([`Start::NearOptimum`]): a step changed the
    /// residual norm by less than this share of it, half of the share of the sum of squares,
    /// the same stop as Levenberg-Marquardt's.
    pub(crate) fn polish_tolerance(self, n: usize) -> f64 {
        0.5 * self.relative_rss_tolerance(n)
    }
}

/// Steps the polish may take before Levenberg-Marquardt takes over.
pub(crate) const POLISH_MAX_STEPS: u64 = 8;

/// Options of the engine.
#[derive(Debug, Clone, Copy)]
pub struct FitOptions {
    /// How to reach the minimum from the start.
    pub start: Start,
    /// Batch length for the HAC covariance; `None` chooses it from the residual autocorrelation.
    pub hac_batch_len: Option<usize>,
    /// Linear parameters the problem projected out before the engine saw it (e.g. mount zeros):
    /// they count in every degrees-of-freedom correction.
    pub absorbed_params: usize,
    /// When the minimiser stops.
    pub stop: Stop,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            start: Start::Brent,
            hac_batch_len: None,
            absorbed_params: 0,
            stop: Stop::Numerical,
        }
    }
}

/// Fit `problem` from the nonlinear start `theta0`.
///
/// The returned [`Fit::values`] hold the linear coefficients, then the nonlinear parameters,
/// in the order of [`Separable::linear_names`] and [`Separable::nonlinear_names`].
///
/// # Example
///
/// A decay `y = a exp(-t / tau)` with one linear coefficient `a` and one nonlinear parameter,
/// `ln tau` (positive `tau` by construction, as the thermal models fit their time constants),
/// fitted from a start far from the truth (`a = 2`, `tau = 30 s`):
///
/// ```
/// use dbbcal_core::fit::{fit, FitOptions, Separable, Start};
/// use nalgebra::DMatrix;
///
/// struct Decay {
///     t: Vec<f64>,
///     y: Vec<f64>,
/// }
///
/// impl Separable for Decay {
///     fn observations(&self) -> &[f64] {
///         &self.y
///     }
///     fn nonlinear_names(&self) -> Vec<String> {
///         vec!["ln_tau".into()]
///     }
///     fn linear_names(&self) -> Vec<String> {
///         vec!["a".into()]
///     }
///     /// One column: `exp(-t / tau)`, `tau = exp(theta[0])`.
///     fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
///         let tau = theta[0].exp();
///         DMatrix::from_iterator(self.t.len(), 1, self.t.iter().map(|t| (-t / tau).exp()))
///     }
///     /// Its derivative by `ln tau`: `exp(-t / tau) t / tau`.
///     fn basis_derivative(&self, theta: &[f64], _k: usize) -> DMatrix<f64> {
///         let tau = theta[0].exp();
///         let column = self.t.iter().map(|t| (-t / tau).exp() * t / tau);
///         DMatrix::from_iterator(self.t.len(), 1, column)
///     }
/// }
///
/// // 100 samples, 1 s apart, with a small deterministic wiggle standing in for noise.
/// let t: Vec<f64> = (0..100).map(f64::from).collect();
/// let y = t
///     .iter()
///     .enumerate()
///     .map(|(i, t)| 2.0 * (-t / 30.0).exp() + 1e-4 * ((i * 7) % 5) as f64 - 2e-4)
///     .collect();
/// let problem = Decay { t, y };
/// let options = FitOptions { start: Start::Given, ..FitOptions::default() };
/// let estimate = fit(&problem, &[5.0_f64.ln()], &options).unwrap();
/// let (a, tau) = (estimate.values[0], estimate.values[1].exp());
/// assert!((a - 2.0).abs() < 1e-3, "a = {a}");
/// assert!((tau - 30.0).abs() < 0.05, "tau = {tau}");
/// ```
pub fn fit<P: Separable>(
    problem: &P,
    theta0: &[f64],
    options: &FitOptions,
) -> Result<Fit, FitError> {
    let y = problem.observations();
    let n_lin = problem.linear_names().len();
    let p = n_lin + theta0.len();
    let polished = match options.start {
        Start::NearOptimum if !theta0.is_empty() && y.len() > p => {
            polish(problem, &within_bounds(problem, theta0), options.stop)
        }
        _ => Err(theta0.to_vec()),
    };
    let (theta, iterations, solved) = match polished {
        Ok(done) => (done.theta, done.steps, done.solved),
        Err(start) => {
            let (theta, iterations) = minimise(
                problem,
                &start,
                if options.start == Start::Brent {
                    StartSearch::Brent
                } else {
                    StartSearch::None
                },
                options.stop,
            )?;
            (theta, iterations, None)
        }
    };
    let (phi, coef) = match solved {
        Some(solved) => solved,
        None => {
            let phi = problem.basis(&theta);
            let coef = solve_linear(&phi, y).ok_or_else(|| singular_term(problem, &phi))?;
            (phi, coef)
        }
    };
    let residuals: Vec<f64> = (&phi * &coef).iter().zip(y).map(|(f, y)| y - f).collect();
    let rss: f64 = residuals.iter().map(|r| r * r).sum::<f64>() + problem.unexplained_rss();
    let n_obs = problem.represented_samples();
    if !rss.is_finite() {
        return Err(FitError::NonFinite);
    }
    let jac = full_jacobian(problem, &theta, &phi, &coef);
    // Not needed past the Jacobian: the uncertainties' copies of it are as large.
    drop(phi);
    let mut names = problem.linear_names();
    names.extend(problem.nonlinear_names());
    if let Some((undetermined, ratio)) = undetermined_parameters(&jac) {
        let params: Vec<&str> = undetermined.iter().map(|&i| names[i].as_str()).collect();
        return Err(FitError::NotIdentifiable {
            params: params.join(", "),
            reason: format!(
                "the Jacobian, each column scaled to unit norm, has a singular value {ratio:.1e} \
                 of its largest, below {MIN_RELATIVE_SINGULAR_VALUE:.0e}"
            ),
        });
    }
    let mut values: Vec<f64> = coef.iter().copied().collect();
    values.extend(&theta);
    // No pseudo-inverse: it would give the directions the data do not determine a zero
    // variance; those were refused above ([`undetermined_parameters`]).
    let jtj_inv = gram(&jac)
        .try_inverse()
        .ok_or_else(|| FitError::Singular(names.join(", ")))?;
    let (cov_naive, cov_hac, hac_batch_len) = covariances(
        &jac,
        &jtj_inv,
        &residuals,
        rss / n_obs.saturating_sub(p + options.absorbed_params).max(1) as f64,
        options.hac_batch_len,
        options.absorbed_params,
    )
    .ok_or_else(|| FitError::Singular(names.join(", ")))?;
    let hac_dof = n_batches(y.len(), hac_batch_len)
        .saturating_sub(p + options.absorbed_params)
        .max(1);
    let groups = problem.absorbed_groups();
    let hac_dof_param = satterthwaite_dof(&jac, &jtj_inv, hac_batch_len, groups.as_deref())
        .unwrap_or_else(|| vec![hac_dof as f64; p]);
    Ok(Fit {
        hac_dof,
        hac_dof_param,
        names,
        values,
        n_linear: n_lin,
        residuals,
        rss,
        n_obs,
        cov_naive,
        cov_hac,
        hac_batch_len,
        iterations,
    })
}

/// How [`minimise`] searches the time constants before Levenberg-Marquardt.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StartSearch {
    /// Levenberg-Marquardt from `theta0` itself.
    None,
    /// One sweep of 1-D Brent searches, each over the parameter's whole search interval.
    Brent,
    /// The same sweep, each Brent search within the bracket of the best point of a grid over
    /// the interval: the lowest minimum, where Brent alone may settle in another. For the
    /// screens, whose statistic is a supremum over the added term's time constant. With one
    /// time constant that search is the minimisation (to 1e-3 of `ln tau`): Levenberg-Marquardt
    /// is not run after it.
    Global,
}

/// The least-squares time constants of `problem` from `theta0` (after the start `search`),
/// and the number of model evaluations: [`fit`] without its uncertainties, for starts and
/// refits that need only the minimum.
pub(crate) fn minimise<P: Separable>(
    problem: &P,
    theta0: &[f64],
    search: StartSearch,
    stop: Stop,
) -> Result<(Vec<f64>, usize), FitError> {
    let y = problem.observations();
    let p = problem.linear_names().len() + theta0.len();
    if y.len() <= p {
        return Err(FitError::TooFewSamples { n: y.len(), p });
    }
    if y.iter().any(|v| !v.is_finite()) {
        return Err(FitError::NonFinite);
    }
    let mut theta = within_bounds(problem, theta0);
    if search != StartSearch::None {
        brent_start(problem, &mut theta, search);
    }
    tracing::debug!(?theta, "fit: nonlinear start after the Brent sweep");
    let searched_alone = search == StartSearch::Global
        && theta.len() == 1
        && problem.start_search_interval(0).is_some();
    let (theta, iterations) = if theta.is_empty() || searched_alone {
        (theta, 0)
    } else {
        levenberg_marquardt(problem, &theta, stop)?
    };
    tracing::debug!(?theta, iterations, "fit: after Levenberg-Marquardt");
    Ok((theta, iterations))
}

#[cfg(test)]
mod conditioning_tests;

#[cfg(test)]
mod tests;
