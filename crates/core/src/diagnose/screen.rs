//! Cheap screening of candidate terms: what adding a term to a bar's fitted model would buy,
//! predicted from the model linearised at its estimates, without refitting it.
//!
//! This is the score (Lagrange-multiplier) form of the test of an added term. At the least-
//! squares estimates the residual `r` is orthogonal to the model's Jacobian `J`; a refit with
//! the new columns `X(τ)` moves the model, to first order, within `span(J, X)`, so the RSS it
//! removes is the part of `r` along `X̃ = (I − P_J) X`, maximised over the term's own time
//! constant `τ` (the one nonlinear direction the score test cannot linearise: Davies' problem,
//! solved by searching it). The fitting engine does that search: the new terms, seen in the
//! orthogonal complement of `J` ([`fit::Orthogonalised`]), are fitted to `r`.
//!
//! Long series are screened on their 300-s coarse copy, on which their fit also starts
//! (`identify::coarse_copy`): the terms screened are smooth on that scale, and the prediction
//! only decides which candidates get an exact refit ([`super::evaluate_candidates`]).
//!
//! Channel scores ([`super::diagnose_bar`]) are screens of `lag:CHANNEL` terms.

use std::borrow::Cow;
use std::sync::OnceLock;

use nalgebra::DMatrix;
use nalgebra::DVector;

use super::noise::{self, NoiseFit};
use super::CandidateError;
use crate::fit::{self, Separable};
use crate::identify::{coarse_copy, BarModel};
use crate::model::{Effect, ThermalProblem};
use crate::series::BarSeries;

/// A bar's fitted model linearised for screening.
pub(crate) struct ScreenBase {
    /// The series screened on: the bar's own, or its coarse copy when it is long.
    series: BarSeries,
    /// `series` is the bar's coarse copy.
    coarse: bool,
    effects: Vec<Effect>,
    theta: Vec<f64>,
    n_gains: usize,
    /// The model's residual on `series` (engine rows: zeros projected out, weighted).
    residuals: Vec<f64>,
    /// Orthonormal basis of the model's Jacobian on `series`; `None` when it could not be
    /// formed (singular basis), then terms are screened against the residual alone.
    directions: Option<DMatrix<f64>>,
    /// The model's RSS on the bar's own series (µm²) and the samples it stands for.
    rss_um2: f64,
    n_samples: usize,
    /// The model's residual on the bar's own fitted samples, weighted
    /// ([`BarSeries::weighted_residuals`]), and its noise model, fitted when first asked for.
    weighted_residuals: Vec<f64>,
    /// The scatter of compressed bins' readings about their lines (µm²) and its degrees of
    /// freedom ([`BarSeries::within_bin_rss_um2`]); zeros for logged readings.
    within_bin: (f64, f64),
    noise: OnceLock<NoiseFit>,
    /// Batch length (rows of `series`) of the score's HAC variance: the model's own HAC batch
    /// ([`BarModel::hac_batch_len`]) scaled to the screened rows.
    score_batch_len: usize,
}

/// What a term would remove from a bar's residual, and change in its model, to first order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Screen {
    /// RSS removed (µm², on the bar's own samples).
    pub(crate) delta_rss_um2: f64,
    /// The bar's RMS after adding the term, predicted (µm).
    pub(crate) rms_after_um: f64,
    /// How much the model's own terms would change their prediction when the term is added, RMS
    /// over the bar's samples (µm): the part of the new term's contribution `X c` that the
    /// current terms had absorbed, `‖P_J X c‖` (their linearised refit moves by `−P_J X c`). A
    /// term can remove little of the residual and still shift the model's parameters a lot
    /// (a second thermal path on `I_min` biases alpha while the RMS barely moves).
    pub(crate) shift_rms_um: f64,
    /// The term's own time constant at the best screen (s), if it has one: within the bounds
    /// the term's column holds it to (`model::ln_tau_bounds`), which is the time constant the
    /// screen's column was computed at.
    pub(crate) tau_s: Option<f64>,
    /// Score (Lagrange-multiplier) statistic of the term, robust to autocorrelated residuals:
    /// `sᵀ V⁻¹ s` with `s = X̃ᵀ r` and `V` its batch-means variance; about χ² with
    /// [`Screen::dof`] degrees of freedom when the term is absent.
    pub(crate) score: f64,
    /// The term's parameters (gains and time constants).
    pub(crate) dof: usize,
}

impl ScreenBase {
    /// Linearise `model` (fitted to `series`); `None` when the model cannot be rebuilt there.
    pub(crate) fn new(series: &BarSeries, model: &BarModel) -> Option<ScreenBase> {
        let coarse = coarse_copy(series, super::DIAGNOSE_COARSE_MIN_SAMPLES);
        let is_coarse = coarse.is_some();
        let screened = coarse.unwrap_or_else(|| series.clone());
        let problem = ThermalProblem::new(&screened, &model.effects).ok()?;
        let n_gains = problem.n_gains();
        let residuals_len = problem.observations().len();
        let (residuals, directions) = match fit::linearise(&problem, &model.theta) {
            Some(l) => (l.residuals, Some(fit::orthonormal_basis(&l.jacobian))),
            None => (problem.observations().to_vec(), None),
        };
        drop(problem);
        Some(ScreenBase {
            series: screened,
            coarse: is_coarse,
            effects: model.effects.clone(),
            theta: model.theta.clone(),
            n_gains,
            residuals,
            directions,
            rss_um2: model.rms_um.powi(2) * model.n_samples as f64,
            n_samples: model.n_samples,
            weighted_residuals: series.weighted_residuals(&model.residuals_um),
            within_bin: (series.within_bin_rss_um2, series.within_bin_dof),
            noise: OnceLock::new(),
            score_batch_len: (model.hac_batch_len as f64 * residuals_len as f64
                / series.fit_index.len().max(1) as f64)
                .ceil()
                .max(1.0) as usize,
        })
    }

    /// Variance of the white reading noise under the model's residual (µm², per reading), from
    /// successive differences: `Σ (r_k − r_{k−1})² / (2 (n − 1))` of the weighted residual. A
    /// slow wander adds only its small change from one sample to the next, so this is the noise
    /// floor even where the model misses a slow effect.
    ///
    /// With compressed bins the readings' scatter about each bin's line is pooled in: it is white
    /// noise too (a slow wander is a straight line over a bin) and has nearly every reading's
    /// degree of freedom, where the nodes have two a bin. From the nodes alone the floor of 1 Hz
    /// campaigns in 60-s bins came out 0.4-0.9 % below the noise (`tests/e2e/false_alarms.rs`,
    /// `bench/foreign_check.py`), while the RMS it is read against was at the noise; pooled, it
    /// is within 0.05 %. Logged readings (no bins) are unchanged: their `within_bin` is zero.
    pub(crate) fn white_noise_variance(&self) -> f64 {
        let r = &self.weighted_residuals;
        if r.len() < 2 {
            return f64::NAN;
        }
        let ss: f64 = r.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
        let (within_rss, within_dof) = self.within_bin;
        (ss / 2.0 + within_rss) / ((r.len() - 1) as f64 + within_dof)
    }

    /// The maximum-likelihood noise model of the model's residual ([`noise::fit_noise`]).
    pub(crate) fn noise(&self) -> &NoiseFit {
        self.noise
            .get_or_init(|| noise::fit_noise(&self.weighted_residuals))
    }

    /// Screen `effect` added to the model: the RSS its linearised refit removes. `Err` names why
    /// the term cannot be built for this bar (e.g. no events of its kind).
    pub(crate) fn screen(&self, effect: &Effect) -> Result<Screen, CandidateError> {
        let mut effects = self.effects.clone();
        effects.push(effect.clone());
        let problem = ThermalProblem::new(&self.series, &effects)?;
        let terms = AddedTerms {
            problem: &problem,
            base_theta: &self.theta,
            first_gain: self.n_gains,
            n_gains: problem.n_gains(),
            residuals: &self.residuals,
        };
        if terms.n_gains <= terms.first_gain {
            return Err(CandidateError::NoTerm {
                effect: effect.clone(),
            });
        }
        let theta0 = problem.theta0()[self.theta.len()..].to_vec();
        let (removed, theta) = match &self.directions {
            Some(q) => removed_rss(
                &fit::Orthogonalised::with_orthonormal_basis(&terms, Cow::Borrowed(q)),
                &theta0,
            ),
            None => removed_rss(&terms, &theta0),
        }
        .ok_or_else(|| CandidateError::NotSeparable {
            effect: effect.clone(),
        })?;
        let delta_rss_um2 = removed.clamp(0.0, self.rss_um2);
        let (shift_rss_um2, score) = match &self.directions {
            Some(q) => {
                let x = terms.basis(&theta);
                let outside = &x - q * q.tr_mul(&x);
                (
                    absorbed_rss(&x, q, &self.residuals),
                    hac_score(&outside, &self.residuals, self.score_batch_len),
                )
            }
            None => (0.0, 0.0),
        };
        let n = self.n_samples.max(1) as f64;
        let dof = terms.linear_names().len() + theta.len();
        Ok(Screen {
            score,
            dof,
            delta_rss_um2,
            rms_after_um: ((self.rss_um2 - delta_rss_um2) / n).sqrt(),
            shift_rms_um: (shift_rss_um2 / n).sqrt(),
            tau_s: fit::within_bounds(&terms, &theta).first().map(|t| t.exp()),
        })
    }

    /// The model's RSS on the bar's own samples (µm²).
    pub(crate) fn rss_um2(&self) -> f64 {
        self.rss_um2
    }

    /// Whether the bar is screened on its coarse copy ([`ScreenBase::coarse_refit`]).
    pub(crate) fn coarse_refit_possible(&self) -> bool {
        self.coarse
    }

    /// `effect` added to `model` and refitted exactly on the bar's coarse copy (the series
    /// screened on), if the bar is screened on one: the RSS the refit removes there (µm², on the
    /// scale of the bar's own samples, as [`Screen::delta_rss_um2`]: the copy's bins weigh what
    /// they hold) and the refit, from whose time constants the exact refit of the bar's own
    /// series starts. `None` for a bar screened on its own series (its refit is the exact one).
    ///
    /// Why: a linearised screen cannot tell rivals apart whose exact refits differ (a term
    /// that also bends the model's own time constants); an exact refit of every rival on the
    /// bar's own series is the cost of the loop (1-5 s each on a 15-day, 10-s bar). On the
    /// coarse copy it costs a thirtieth, and only the rivals that come close to the best there
    /// are refitted on the series ([`super::COARSE_RIVAL_SHARE`]).
    pub(crate) fn coarse_refit(
        &self,
        model: &BarModel,
        effect: &Effect,
    ) -> Option<Result<(f64, BarModel), CandidateError>> {
        if !self.coarse {
            return None;
        }
        let mut effects = self.effects.clone();
        effects.push(effect.clone());
        let refit = crate::identify::identify_from(&self.series, &effects, Some(model));
        Some(refit.map_err(CandidateError::from).map(|m| {
            let after: f64 = self
                .series
                .weighted_residuals(&m.residuals_um)
                .iter()
                .map(|r| r * r)
                .sum();
            let before: f64 = self.residuals.iter().map(|r| r * r).sum();
            ((before - after).clamp(0.0, self.rss_um2), m)
        }))
    }
}

/// The score statistic `sᵀ V⁻¹ s` of columns `x` (already orthogonal to the model's Jacobian)
/// against residual `r`: `s = xᵀ r`, `V = B/(B − k) Σ_b g_b g_bᵀ` with `g_b` the score summed
/// over consecutive batches of `batch` rows (the batch-means HAC of `fit`, for the score).
fn hac_score(x: &DMatrix<f64>, r: &[f64], batch: usize) -> f64 {
    let (n, k) = x.shape();
    let n_batches = n.div_ceil(batch.max(1));
    if k == 0 || n_batches <= k + 1 {
        return 0.0;
    }
    let mut v = DMatrix::<f64>::zeros(k, k);
    let mut s = nalgebra::DVector::<f64>::zeros(k);
    let mut g = nalgebra::DVector::<f64>::zeros(k);
    for start in (0..n).step_by(batch.max(1)) {
        let end = (start + batch).min(n);
        for j in 0..k {
            let col = x.column(j);
            g[j] = (start..end).map(|i| col[i] * r[i]).sum();
        }
        s += &g;
        v.ger(1.0, &g, &g, 1.0);
    }
    v *= n_batches as f64 / (n_batches - k) as f64;
    let scale = v.diagonal().max();
    if scale.is_nan() || scale <= 0.0 {
        return 0.0;
    }
    match v.svd(true, true).solve(&s, 1e-12 * scale) {
        Ok(w) => s.dot(&w).max(0.0),
        Err(_) => 0.0,
    }
}

/// `‖P_J X c‖²`: with `q` an orthonormal basis of the model's Jacobian `J`, `x` the new
/// columns and `c` their coefficients in the linearised refit (the fit of `(I − P_J) X` to the
/// residual `r`, Frisch-Waugh-Lovell), the squared change of the model's own terms. 0 when the
/// new columns have no part outside `span(J)`.
fn absorbed_rss(x: &DMatrix<f64>, q: &DMatrix<f64>, r: &[f64]) -> f64 {
    let qtx = q.tr_mul(x);
    let outside = x - q * &qtx;
    let normal = outside.tr_mul(&outside);
    let rhs = outside.tr_mul(&nalgebra::DVector::from_column_slice(r));
    let scale = normal.diagonal().max();
    if scale.is_nan() || scale <= 0.0 {
        return 0.0;
    }
    match normal.svd(true, true).solve(&rhs, 1e-12 * scale) {
        Ok(c) => (qtx * c).norm_squared(),
        Err(_) => 0.0,
    }
}

/// The RSS of `problem`'s observations that its best fit removes, and its time constants there.
fn removed_rss<P: Separable>(problem: &P, theta0: &[f64]) -> Option<(f64, Vec<f64>)> {
    let (theta, _) = fit::minimise(
        problem,
        theta0,
        fit::StartSearch::Global,
        fit::Stop::Statistical,
    )
    .ok()?;
    let before: f64 = problem.observations().iter().map(|r| r * r).sum();
    let after = fit::projected_rss(problem, &theta);
    after.is_finite().then_some((before - after, theta))
}

/// The columns a candidate adds to a model, at the model's own time constants, fitted to the
/// model's residual: a separable problem in the candidate's own parameters only.
struct AddedTerms<'p, 'a> {
    /// The extended model (the model's effects, then the candidate).
    problem: &'p ThermalProblem<'a>,
    /// The model's time constants (`ln tau`), held: the extended problem's first nonlinear ones.
    base_theta: &'p [f64],
    /// Index of the first gain column the candidate adds, and the number of gain columns.
    first_gain: usize,
    n_gains: usize,
    residuals: &'p [f64],
}

impl AddedTerms<'_, '_> {
    fn full_theta(&self, theta: &[f64]) -> Vec<f64> {
        let mut full = self.base_theta.to_vec();
        full.extend_from_slice(theta);
        full
    }

    fn added_columns(&self, m: DMatrix<f64>) -> DMatrix<f64> {
        m.columns(self.first_gain, self.n_gains - self.first_gain)
            .into_owned()
    }
}

impl Separable for AddedTerms<'_, '_> {
    fn observations(&self) -> &[f64] {
        self.residuals
    }
    fn nonlinear_names(&self) -> Vec<String> {
        self.problem.nonlinear_names()[self.base_theta.len()..].to_vec()
    }
    fn linear_names(&self) -> Vec<String> {
        self.problem.linear_names()[self.first_gain..self.n_gains].to_vec()
    }
    fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
        self.problem
            .basis_columns(&self.full_theta(theta), self.first_gain..self.n_gains)
    }
    fn basis_derivative(&self, theta: &[f64], k: usize) -> DMatrix<f64> {
        let full = self.full_theta(theta);
        self.added_columns(
            self.problem
                .basis_derivative(&full, self.base_theta.len() + k),
        )
    }
    /// The added columns' coefficients padded with zeros for the model's own: the added time
    /// constants move the added columns alone.
    fn basis_derivative_times(&self, theta: &[f64], k: usize, coef: &DVector<f64>) -> DVector<f64> {
        let mut padded = DVector::zeros(self.problem.linear_names().len());
        padded.rows_mut(self.first_gain, coef.len()).copy_from(coef);
        let full = self.full_theta(theta);
        self.problem
            .basis_derivative_times(&full, self.base_theta.len() + k, &padded)
    }
    fn start_search_interval(&self, k: usize) -> Option<(f64, f64)> {
        self.problem
            .start_search_interval(self.base_theta.len() + k)
    }
    fn nonlinear_bounds(&self, k: usize) -> Option<(f64, f64)> {
        self.problem.nonlinear_bounds(self.base_theta.len() + k)
    }
}
