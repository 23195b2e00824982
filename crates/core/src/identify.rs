//! Identify each bar's thermal model: bind the effects to the bar's series, run the fitting
//! engine, and express the estimates in physical units (taus in seconds with asymmetric
//! intervals from `ln tau`).
//!
//! # How it works
//!
//! - Adding an effect never raises a bar's RMS: `identify_from` without a start also fits the model
//!   in stages (without its last effect first) and keeps the better of the direct and staged fits.
//!   With a start (the diagnosis's refits start from the bar's current model) it fits from that
//!   start, then searches the basin of the default time constants on the 300-s coarse copy and
//!   refits from there only where that is lower (`identify::defaults_basin`: a base bent to mimic
//!   a missing effect is a poor start for the model with it). A refit that starts from the same
//!   effects already fitted on the coarse copy (the diagnosis's coarse tier and coarse forward
//!   selection) is polished from that optimum without either search
//!   (`identify::identify_from_coarse_optimum`: the coarse refit made them).
//! - `identify` starts series of at least `COARSE_START_MIN_SAMPLES` fitted samples on
//!   `COARSE_START_BIN_S` bin means (Brent + LM there), then polishes that optimum on the series by
//!   argmin's Gauss-Newton on the variable-projection residual (`fit::Start::NearOptimum`,
//!   `fit::polish`: 3-4 steps on the benchmark; LM from where it stopped if it does not converge);
//!   shorter
//!   series keep the engine's Brent start. Series of at least `COARSE_PROFILE_MIN_SAMPLES` are also
//!   profiled there (between the two, the exact profile costs less than the fit). The coarse
//!   optimum is kept (`BarModel::coarse_theta`; the check that the inputs vary within a mount,
//!   `identify::vanished_gains`, runs on the same coarse copy) and the profile intervals start there, unless the
//!   fine fit ended more than `COARSE_BASIN_LN_TAU` in `ln tau` away (then the coarse copy is
//!   refitted from the fine optimum); the constants are in `identify.rs`.

use serde::Serialize;

use crate::fit::{self, Fit, FitError, FitOptions, Start};
use crate::model::{base_effects, Effect, ModelError, NotIdentifiable, ThermalProblem};
use crate::series::BarSeries;

/// One estimated parameter.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Estimate {
    /// Physical parameter name (e.g. `alpha_ppm_per_k`), unit in the name.
    pub name: String,
    /// Estimate, in the unit its name says.
    pub value: f64,
    /// Standard uncertainty (k = 1) that accounts for autocorrelated residuals (batch-means HAC).
    pub u: f64,
    /// The textbook `s² (JᵀJ)⁻¹` standard error, valid only for white residuals.
    pub u_naive: f64,
    /// 95 % interval. Gains: `value ± t u`, Student's t on the parameter's effective
    /// (Satterthwaite) HAC degrees of freedom ([`BarModel::dof`]). Time constants from
    /// [`identify`]: the adjusted profile-likelihood interval of `ln tau`, mapped to seconds
    /// (asymmetric; the profile RSS cut where a linear model would give `ln tau ± t u_ln`);
    /// from [`identify_from`] (diagnosis trial fits): the Wald interval `exp(ln tau ± t u_ln)`.
    pub ci95: [f64; 2],
    /// Per end of `ci95`: the profile never rose to the cut before the search bound of the time
    /// constants (60 s, 30 days), so that end is the bound and the data do not limit the time
    /// constant on that side. Always `false` for gains and Wald intervals.
    pub ci95_at_search_bound: [bool; 2],
}

/// A bar's identified model.
#[derive(Debug, Clone)]
pub struct BarModel {
    /// Bar id.
    pub bar: String,
    pub(crate) effects: Vec<Effect>,
    /// Gains and time constants (physical names), without the mount zeros and the initial-state
    /// gains.
    pub params: Vec<Estimate>,
    /// The base paths' initial-state gains (`initial_fixed_ppm`, `initial_scale_ppm`: each lag's
    /// departure from steady state at the first fitted sample times its expansion), nuisance
    /// parameters like the zeros (`crate::model::INITIAL_FIXED`).
    pub initial_state: Vec<Estimate>,
    /// Every linear gain of the fit in the model's column order (params' gains and the
    /// initial-state gains interleaved as [`ThermalProblem::gain_names`] lists them): what
    /// multiplies [`ThermalProblem::full_columns`].
    pub(crate) gains: Vec<f64>,
    /// Parameters of the effects asked for that this bar's data cannot determine, left out of
    /// the fit, with the reason (`crate::model::identifiable_effects`).
    pub not_identifiable: Vec<NotIdentifiable>,
    /// Zero of each zero segment, µm.
    pub zeros_um: Vec<f64>,
    /// Correlation matrix of `params` (HAC), same order.
    pub correlation: Vec<Vec<f64>>,
    /// RMS residual, µm.
    pub rms_um: f64,
    /// Samples fitted.
    pub n_samples: usize,
    /// Bayesian information criterion of the fit.
    pub bic: f64,
    /// Gaussian log-likelihood of the fit at the ML variance `rss / n`.
    pub log_likelihood: f64,
    /// Parameters fitted (thermal terms and zeros).
    pub n_params: usize,
    /// Model value (µm) on the bar's whole timeline, zeros included where a segment applies.
    pub model_um: Vec<f64>,
    /// Thermal part of the model only (no zeros), on the whole timeline.
    pub thermal_um: Vec<f64>,
    /// Residual at the fitted samples (same order as `series.fit_index`).
    pub residuals_um: Vec<f64>,
    /// Nonlinear parameters as fitted (`ln tau`), to restart related fits.
    pub(crate) theta: Vec<f64>,
    /// Samples per batch of the batch-means HAC variance.
    pub hac_batch_len: usize,
    /// Effective degrees of freedom of each parameter's HAC variance (same order as `params`,
    /// `fit::Fit::hac_dof_param`).
    pub dof: Vec<f64>,
    /// Index in `theta` of each parameter that is a time constant (same order as `params`).
    theta_index: Vec<Option<usize>>,
    /// The time constants fitted on the series' coarse copy ([`start_fit`]), where the fit
    /// started from: the profile intervals are taken there ([`profile_on_coarse_copy`]).
    coarse_theta: Option<Vec<f64>>,
}

/// Why a bar could not be identified.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum IdentifyError {
    /// The model could not be built for this bar.
    #[error("bar {bar}: {source}")]
    Model {
        /// Bar id.
        bar: String,
        /// Why.
        source: ModelError,
    },
    /// The fit failed.
    #[error("bar {bar}: {source}")]
    Fit {
        /// Bar id.
        bar: String,
        /// Why.
        source: FitError,
    },
}

impl BarModel {
    /// The parameter `name`, if the model has it.
    pub fn param(&self, name: &str) -> Option<&Estimate> {
        self.params.iter().find(|p| p.name == name)
    }
    /// The value of parameter `name`, if the model has it.
    pub fn value(&self, name: &str) -> Option<f64> {
        self.param(name).map(|p| p.value)
    }
    /// The model's effects, by name.
    pub fn effect_names(&self) -> Vec<String> {
        self.effects.iter().map(Effect::name).collect()
    }
}

/// Fit `effects` to one bar.
///
/// The time constants get adjusted profile-likelihood intervals
/// (`profile_tau_intervals`); [`identify_from`] (the diagnosis' many trial fits) keeps the
/// cheaper Wald intervals.
pub fn identify(series: &BarSeries, effects: &[Effect]) -> Result<BarModel, IdentifyError> {
    let mut model = identify_from(series, effects, None)?;
    profile_tau_intervals(series, &mut model);
    Ok(model)
}

/// Replace each time constant's Wald interval `exp(ln tau ± t u)` by an adjusted
/// profile-likelihood interval, calibrated for autocorrelated residuals.
///
/// Why: the Wald interval trusts the curvature of the RSS at the estimate over the whole
/// interval. For a time constant it is not constant: the information about `ln tau` changes
/// with `tau` itself (on simulated bars the HAC standard error of `ln tau_R` correlates −0.6
/// with the estimate's error, and the errors of `ln tau_S` are skewed): on 1000 simulated bars
/// with AR(1) residuals Wald intervals on the same `u` and `t` covered the true `tau_R` 92.8 %
/// and `tau_S` 90.2 % of the time at nominal 95 %, the gains 94.6-94.8 %.
///
/// How: the profile RSS `P(x)` of `ln tau` (the other time constants refitted, the linear
/// parameters solved, at each `x`) is cut at `P(x) − RSS_min = t² u_hac² / [(JᵀJ)⁻¹]_kk`. For a
/// model linear near the estimate `P(x) − RSS_min = (x − x̂)² / [(JᵀJ)⁻¹]_kk`, so the cut
/// reproduces exactly `x̂ ± t u_hac` (the HAC standard error and its Satterthwaite t, as for the
/// gains); beyond it, the cut follows the real shape of the RSS. This is the one-parameter
/// form of the "adjusted" profile likelihood of Chandler and Bate (2007): the likelihood-ratio
/// statistic of a misspecified (here: autocorrelated) model rescaled by the ratio of the
/// sandwich to the naive variance. `u` stays the HAC standard uncertainty at the estimate.
///
/// Cost: about three profile points per end (bracketing from the Wald half-width, then regula
/// falsi on `√(P − RSS_min)`, close to linear in `x`), each one or two Gauss-Newton steps of the
/// other time constants started on the linearised profile trace: for the base model about 1.3
/// times the fit itself (simulated bars: 54 ms fit, 65 ms profiles). A failed profile keeps
/// the Wald interval.
///
/// A long series ([`COARSE_PROFILE_MIN_SAMPLES`]) is profiled on the 300-s bin means that
/// [`start_fit`] starts it on, from the coarse optimum found there: each profile point
/// refits the other time constants, and at 1 Hz over 30 days that cost twice the fit. The
/// shape of the profile in `ln tau` is the model's, which bin means of time constants of 15 min
/// and more keep; the cut is taken from the coarse Jacobian
/// (`t² u_hac² / [(J_cᵀJ_c)⁻¹]_kk`, `u_hac` from the full series), and the interval is moved by
/// the difference between the two estimates, so a linear model still gets exactly
/// `x̂ ± t u_hac`. Checked against the full profile in this module's tests.
fn profile_tau_intervals(series: &BarSeries, model: &mut BarModel) {
    match coarse_copy(series, COARSE_PROFILE_MIN_SAMPLES) {
        Some(coarse) => profile_on_coarse_copy(&coarse, model),
        None => profile_on_series(series, model),
    }
}

/// [`profile_tau_intervals`] on a coarse copy of the series `model` was fitted to.
fn profile_on_coarse_copy(coarse: &BarSeries, model: &mut BarModel) {
    let Ok(problem) = ThermalProblem::new(coarse, &model.effects) else {
        return;
    };
    // The coarse optimum the fit started from serves if the fit stayed in its basin (the
    // two differ by the binning, a few per cent of a time constant); else it is refitted.
    let near = |theta_c: &Vec<f64>| {
        theta_c.len() == model.theta.len()
            && theta_c
                .iter()
                .zip(&model.theta)
                .all(|(c, f)| (c - f).abs() < COARSE_BASIN_LN_TAU)
    };
    let theta_c = match model.coarse_theta.clone().filter(near) {
        Some(theta_c) => theta_c,
        None => match fit::minimise(&problem, &model.theta, false) {
            Ok((theta_c, _)) => theta_c,
            Err(_) => return,
        },
    };
    let rss_c = fit::projected_rss(&problem, &theta_c);
    if !rss_c.is_finite() {
        return;
    }
    let Some(jac) = fit::jacobian_at(&problem, &theta_c) else {
        return;
    };
    let Some(jtj_inv) = jac.tr_mul(&jac).try_inverse() else {
        return;
    };
    let n_lin = jac.ncols() - theta_c.len();
    for p in 0..model.params.len() {
        let Some(k) = model.theta_index[p] else {
            continue;
        };
        let est = &model.params[p];
        let curvature = jtj_inv[(n_lin + k, n_lin + k)];
        if !(est.u > 0.0 && curvature > 0.0) {
            continue;
        }
        let u_ln = est.u / est.value;
        let t = fit::t_quantile_975(model.dof[p]);
        let delta = t * t * u_ln * u_ln / curvature;
        if let Some(interval) = fit::profile_interval(&problem, &theta_c, k, rss_c, delta, t * u_ln)
        {
            let shift = model.theta[k] - theta_c[k];
            model.params[p].ci95 = interval.ends.map(|end| (end + shift).exp());
            model.params[p].ci95_at_search_bound = interval.at_search_bound;
        }
    }
}

/// [`profile_tau_intervals`] on the series `model` was fitted to.
fn profile_on_series(series: &BarSeries, model: &mut BarModel) {
    let Ok(problem) = ThermalProblem::new(series, &model.effects) else {
        return;
    };
    let rss_min = fit::projected_rss(&problem, &model.theta);
    let n_total = model.n_params + problem.n_zeros();
    let s2 = rss_min / model.n_samples.saturating_sub(n_total).max(1) as f64;
    for p in 0..model.params.len() {
        let Some(k) = model.theta_index[p] else {
            continue;
        };
        let est = &model.params[p];
        if !(est.u > 0.0 && est.u_naive > 0.0) {
            continue;
        }
        // In ln tau: u_ln = u / tau, and [(JᵀJ)⁻¹]_kk = u_naive_ln² / s².
        let u_ln = est.u / est.value;
        let ratio = est.u / est.u_naive;
        let t = fit::t_quantile_975(model.dof[p]);
        let delta = t * t * ratio * ratio * s2;
        if let Some(interval) =
            fit::profile_interval(&problem, &model.theta, k, rss_min, delta, t * u_ln)
        {
            model.params[p].ci95 = interval.ends.map(f64::exp);
            model.params[p].ci95_at_search_bound = interval.at_search_bound;
        }
    }
}

/// Fit `effects` to one bar, starting the time constants that `start` names from its values.
///
/// Without a `start`, a model with effects beyond the leading base effects is also fitted in
/// stages (the model without its last effect first, then the full model started from it), and
/// the better of the two fits is kept. A lagged channel's time constant started from its
/// default can trap a direct fit in a local minimum worse than the smaller model; the staged
/// fit cannot be worse than the smaller model (the new gain may stay zero), so adding an effect
/// never raises the RMS, and `--add-effect X` finds at least what the diagnosis reported.
///
/// With a `start` (the diagnosis's refits) the fit starts from its time constants, and the
/// basin of the defaults is searched too and refitted where it is lower (`defaults_basin`):
/// a base model bends its time constants to mimic what it lacks, and a refit started there alone
/// can stop short of the fit made afresh. The search runs on the coarse copy, so it costs a few
/// per cent of a nightly run; a full fresh fit for every refit would cost 1.5-2.5 times the
/// diagnosis (both measured on the second simulator's hidden-effect campaigns, `docs/model.md`,
/// "A second simulator").
pub fn identify_from(
    series: &BarSeries,
    effects: &[Effect],
    start: Option<&BarModel>,
) -> Result<BarModel, IdentifyError> {
    match start {
        Some(start) => fit_from(series, effects, Some(start)),
        None => identify_afresh(series, effects),
    }
}

/// [`identify_from`] without a start: the direct fit, and the staged one where there is a
/// smaller model to start from.
fn identify_afresh(series: &BarSeries, effects: &[Effect]) -> Result<BarModel, IdentifyError> {
    let direct = fit_from(series, effects, None);
    match staged_start(series, effects) {
        Some(smaller) => better(direct, fit_from(series, effects, Some(&smaller))),
        None => direct,
    }
}

/// The fit of lower RMS (the first on a tie), or whichever succeeded.
fn better(
    first: Result<BarModel, IdentifyError>,
    second: Result<BarModel, IdentifyError>,
) -> Result<BarModel, IdentifyError> {
    match (first, second) {
        (Ok(a), Ok(b)) => Ok(if b.rms_um < a.rms_um { b } else { a }),
        (Ok(a), Err(_)) => Ok(a),
        (Err(_), second) => second,
    }
}

/// Fit `effects` to one bar from `coarse`, the same effects already fitted on the bar's coarse
/// copy (`coarse_copy` with `COARSE_START_MIN_SAMPLES`: a refit of the diagnosis's coarse
/// tier or of its coarse forward selection): the series is polished from the coarse optimum
/// (`Start::NearOptimum`) without searching its start again.
///
/// Why: `identify_from` with a start searches the coarse copy twice (from the start and from
/// the defaults' basin, `defaults_basin`), which is what the coarse refit already did on the
/// same copy (`identify_from` there searches the defaults' basin on the copy itself); done
/// again it only finds the same optimum. On the air-gradient campaign of our simulator (10 bars,
/// 15 days, 10 s) the ranking and the ledger came out the same to the bit of their ΔBIC.
/// Falls back to `identify_from` when `coarse` is not a fit of these effects or the series has
/// no coarse copy.
pub(crate) fn identify_from_coarse_optimum(
    series: &BarSeries,
    effects: &[Effect],
    coarse: &BarModel,
) -> Result<BarModel, IdentifyError> {
    if coarse.effects != effects || series.fit_index.len() < COARSE_START_MIN_SAMPLES {
        return identify_from(series, effects, Some(coarse));
    }
    fit_from_start(series, effects, Some(coarse), true)
}

fn fit_from(
    series: &BarSeries,
    effects: &[Effect],
    start: Option<&BarModel>,
) -> Result<BarModel, IdentifyError> {
    fit_from_start(series, effects, start, false)
}

/// [`fit_from`]; `at_coarse_optimum`: `start` is the optimum of these effects on the series'
/// coarse copy ([`identify_from_coarse_optimum`]).
fn fit_from_start(
    series: &BarSeries,
    effects: &[Effect],
    start: Option<&BarModel>,
    at_coarse_optimum: bool,
) -> Result<BarModel, IdentifyError> {
    let bar = series.bar.id.clone();
    let problem = ThermalProblem::new(series, effects).map_err(|source| IdentifyError::Model {
        bar: bar.clone(),
        source,
    })?;
    let fresh_theta0 = problem.theta0();
    let mut theta0 = fresh_theta0.clone();
    if let Some(start) = start {
        warm_start(&problem, start, &mut theta0);
    }
    let mut options = FitOptions {
        absorbed_params: problem.n_zeros(),
        ..FitOptions::default()
    };
    let coarse = if theta0.is_empty() {
        None
    } else {
        coarse_copy(series, COARSE_START_MIN_SAMPLES)
    };
    let coarse_problem = coarse
        .as_ref()
        .and_then(|c| ThermalProblem::new(c, effects).ok());
    // On a long series the inputs' variation is checked on the coarse copy: its 300-s means
    // vary within a mount wherever the readings do (bins never cross a zero segment), and a
    // constant input stays constant, at a tenth of the cost (on the 30-day benchmark this
    // check was 4-10 ms of a bar's 95).
    let vanished = match (&coarse, &coarse_problem) {
        (Some(c), Some(p)) => vanished_gains(c, p, &theta0),
        _ => vanished_gains(series, &problem, &theta0),
    };
    if let Some(source) = vanished {
        return Err(IdentifyError::Fit { bar, source });
    }
    // Without a coarse problem the start is searched as usual.
    let at_coarse_optimum = at_coarse_optimum && coarse_problem.is_some();
    let mut coarse_theta = if at_coarse_optimum {
        Some(theta0.clone())
    } else {
        coarse_problem
            .as_ref()
            .and_then(|p| start_fit(p, &bar, &theta0))
    };
    if let Some(theta) = &coarse_theta {
        theta0 = theta.clone();
        options.start = Start::NearOptimum;
    }
    let mut fit = fit::fit(&problem, &theta0, &options).map_err(|source| IdentifyError::Fit {
        bar: bar.clone(),
        source,
    })?;
    if start.is_some() && !at_coarse_optimum {
        let coarse = coarse_problem.as_ref();
        if let Some((theta, lower)) =
            defaults_basin(series, &problem, coarse, &fresh_theta0, &fit, &options)
        {
            coarse_theta = coarse.map(|_| theta);
            fit = lower;
        }
    }
    let mut model = to_bar_model(series, &problem, &fit);
    model.coarse_theta = coarse_theta;
    canonical_thermal_paths(&mut model);
    Ok(model)
}

/// A gain column whose norm over the fitted samples, once the mount zeros are taken out, is at
/// most this fraction of its norm before: the input does not vary while the bar is mounted (a
/// constant temperature), and what is left is rounding (~1e-14 of the column). Taken as it is,
/// the engine would scale that rounding to a unit column and fit the noise with it: a gain of
/// any value with an uncertainty that means nothing.
pub(crate) const VANISHED_COLUMN: f64 = 1e-9;

/// The gains of `problem` at `theta` whose columns vanish within every zero segment
/// ([`VANISHED_COLUMN`]), as the error that names them; `None` when none does.
fn vanished_gains(series: &BarSeries, problem: &ThermalProblem, theta: &[f64]) -> Option<FitError> {
    let names = problem.gain_names();
    let basis = fit::Separable::basis(problem, theta);
    let full = problem.full_columns(theta);
    let vanished: Vec<&str> = full
        .iter()
        .enumerate()
        .filter(|(j, col)| {
            let before = series
                .fit_index
                .iter()
                .map(|&i| series.weight[i] * col[i] * col[i])
                .sum::<f64>()
                .sqrt();
            let after = basis.column(*j).norm();
            before > 0.0 && after <= VANISHED_COLUMN * before
        })
        .map(|(j, _)| names[j].as_str())
        .collect();
    (!vanished.is_empty()).then(|| FitError::NotIdentifiable {
        params: vanished.join(", "),
        reason: format!(
            "the input does not vary within any mount: its column, the mount zeros taken out, \
             is at most {VANISHED_COLUMN:.0e} of its size"
        ),
    })
}

/// The model without the last of `effects`, if `effects` goes beyond its leading base effects
/// and that smaller model can be fitted.
fn staged_start(series: &BarSeries, effects: &[Effect]) -> Option<BarModel> {
    let base = base_effects();
    let leading_base = effects.iter().take_while(|e| base.contains(e)).count();
    if effects.len() <= leading_base.max(1) {
        return None;
    }
    identify_from(series, &effects[..effects.len() - 1], None).ok()
}

/// Series with at least this many fitted samples start their time constants on a coarse copy.
/// The engine's own Brent start sweeps the projected residual some 40 times: on the 7.5-day
/// benchmark campaign (21 600 nodes a bar with 60-s bins) that was two thirds of identify.
pub(crate) const COARSE_START_MIN_SAMPLES: usize = 20_000;
/// Series with at least this many fitted samples are profiled on their coarse copy (each
/// profile point refits the other time constants). The coarse profile's ends are 2-6 % of the
/// interval's width off the exact profile's (benchmark campaigns of 7.5-30 days, 60-s bins);
/// below this size the exact profile costs less than the fit, so it is kept.
const COARSE_PROFILE_MIN_SAMPLES: usize = 50_000;
/// How far (in `ln tau`) the fine fit may end from the coarse optimum it started at for that
/// optimum to be taken as the coarse fit of the same basin (0.2: 22 %).
const COARSE_BASIN_LN_TAU: f64 = 0.2;
/// Bin of the coarse copy: a fifth or less of the shortest time constants of `docs/spec/physics.md`
/// (15 min to 2 h), so the start lands in the fine fit's basin.
const COARSE_START_BIN_S: f64 = 300.0;

/// The 300-s bin means of a long series, on which its fit starts and its time constants are
/// profiled; `None` for a series short enough to work on directly (below `min_samples`:
/// [`COARSE_START_MIN_SAMPLES`] or [`COARSE_PROFILE_MIN_SAMPLES`]), or whose copy would not be
/// at least 4× shorter.
pub(crate) fn coarse_copy(series: &BarSeries, min_samples: usize) -> Option<BarSeries> {
    if series.fit_index.len() < min_samples {
        return None;
    }
    let coarse = series.binned_copy(COARSE_START_BIN_S);
    (coarse.fit_index.len() * 4 <= series.fit_index.len()).then_some(coarse)
}

/// The time constants a fit starts from: fitted (Brent start + Levenberg-Marquardt) on
/// `problem`, the 300-s bin means of a series ([`coarse_copy`]; the fit of the series itself is
/// then polished from them by argmin's Gauss-Newton, [`Start::NearOptimum`]), or for
/// [`defaults_basin`] a short series itself. On the 30-day
/// benchmark campaign the polish takes 3-4 steps where Levenberg-Marquardt takes 4-7
/// evaluations (the linear solve applies Qᵀy without forming Q); the Brent sweep evaluates the projected residual some 40 times, about half of the fit on
/// the full series (`bench/results.md`), a few per cent on the coarse copy. `None`: the start
/// failed (the engine then starts as usual).
fn start_fit(problem: &ThermalProblem, bar: &str, theta0: &[f64]) -> Option<Vec<f64>> {
    let (theta, _) = fit::minimise(problem, theta0, true).ok()?;
    let n = fit::Separable::observations(problem).len();
    tracing::debug!(bar, ?theta, n, "identify: coarse start");
    theta.iter().all(|t| t.is_finite()).then_some(theta)
}

/// For a refit (`fit`, started from another model's time constants): the basin of the default
/// time constants, where it is lower. Its start is searched ([`start_fit`]) on `coarse`, else on
/// a short series' 300-s copy if that is 4× shorter, else on the series; the series is fitted
/// from there ([`Start::NearOptimum`]) only when the start's residual is already below `fit`'s,
/// and that fit is returned, with its start, when it ends lower.
///
/// Why: a base model that bent its time constants to mimic a missing effect is a poor start
/// for the model with that effect. On the second simulator's plate-expansion campaign
/// (`bench/foreign_sim.py X --effect plate_expansion --seed 2 --air linear --files bar
/// --sample-s 10 --days 5`) the refit with `plate_expansion` from the base alone stopped at
/// 20.47 nm on bar F01, where a fresh fit reaches 20.03, and the diagnosis ranked
/// `air_gradient` first (ΔBIC −12 329 against −11 973); with the defaults' basin too,
/// `plate_expansion` comes first (−14 010) and reaches the noise. In the usual case (one basin)
/// this costs a search on the coarse copy and one residual of the series: the nightly runs of
/// that simulator's 25 hidden-effect campaigns took 5 % longer in all (and 4 % less once the
/// bent starts' second full fit it made redundant was dropped), where a second full fit for
/// every refit had cost 1.5-2.5 times the diagnosis.
fn defaults_basin(
    series: &BarSeries,
    problem: &ThermalProblem,
    coarse: Option<&ThermalProblem>,
    defaults: &[f64],
    fit: &Fit,
    options: &FitOptions,
) -> Option<(Vec<f64>, Fit)> {
    let short_copy;
    let short_problem;
    let search = match coarse {
        Some(p) => p,
        None => {
            short_copy = coarse_copy(series, 0);
            short_problem = short_copy
                .as_ref()
                .and_then(|c| ThermalProblem::new(c, &problem.effects()).ok());
            short_problem.as_ref().unwrap_or(problem)
        }
    };
    let theta = start_fit(search, &series.bar.id, defaults)?;
    if fit::projected_rss(problem, &theta) >= fit.rss {
        return None;
    }
    let options = FitOptions {
        start: Start::NearOptimum,
        ..*options
    };
    let lower = fit::fit(problem, &theta, &options)
        .ok()
        .filter(|f| f.rss < fit.rss)?;
    Some((theta, lower))
}

/// Two lags on `I_min` (`fixed_part` and `second_path`) are the same model with their labels
/// swapped; by convention the fixed part is the dominant path (larger |gain|), so a fit that
/// converged the other way round is relabelled.
fn canonical_thermal_paths(model: &mut BarModel) {
    let pos = |name: &str| model.params.iter().position(|p| p.name == name);
    let (Some(a), Some(a2), Some(t), Some(t2)) = (
        pos("alpha_ppm_per_k"),
        pos("alpha2_ppm_per_k"),
        pos("tau_r_s"),
        pos("tau_2_s"),
    ) else {
        return;
    };
    if model.params[a2].value.abs() <= model.params[a].value.abs() {
        return;
    }
    for (i, j) in [(a, a2), (t, t2)] {
        let (vi, vj) = (model.params[i].clone(), model.params[j].clone());
        model.params[i] = Estimate {
            name: vi.name,
            ..vj
        };
        model.params[j] = Estimate {
            name: vj.name,
            ..vi
        };
        model.dof.swap(i, j);
        model.theta_index.swap(i, j);
        model.correlation.swap(i, j);
        for row in model.correlation.iter_mut() {
            row.swap(i, j);
        }
    }
}

/// Reuse the time constants a previous fit found for the same effects.
fn warm_start(problem: &ThermalProblem, start: &BarModel, theta0: &mut [f64]) {
    let taus = problem.tau_names();
    for (k, name) in taus.iter().enumerate() {
        if let Some(v) = start.value(name) {
            theta0[k] = v.ln();
        }
    }
}

fn to_bar_model(series: &BarSeries, problem: &ThermalProblem, fit: &Fit) -> BarModel {
    let effects = problem.effects();
    let gain_names = problem.gain_names();
    let nuisance = problem.nuisance_gains();
    let n_gains = gain_names.len();
    let n_lin = fit.n_linear;
    let theta: Vec<f64> = fit.values[n_lin..].to_vec();
    // Parameters reported: gains (0..n_gains) and taus (n_lin..), zeros and initial-state gains
    // kept apart.
    let mut order: Vec<usize> = (0..n_gains).filter(|&i| !nuisance[i]).collect();
    order.extend(n_lin..fit.n_params());
    let tau_names = problem.tau_names();
    let gain_estimate = |i: usize| {
        let (v, u) = (fit.values[i], fit.se(i));
        let t95 = fit.t95(i);
        Estimate {
            name: gain_names[i].clone(),
            value: v,
            u,
            u_naive: fit.se_naive(i),
            ci95: [v - t95 * u, v + t95 * u],
            ci95_at_search_bound: [false; 2],
        }
    };
    let params = order
        .iter()
        .map(|&i| {
            if i < n_gains {
                gain_estimate(i)
            } else {
                let (ln_tau, u_ln) = (fit.values[i], fit.se(i));
                let t95 = fit.t95(i);
                let tau = ln_tau.clamp(0.0, crate::model::MAX_TAU_S.ln()).exp();
                Estimate {
                    name: tau_names[i - n_lin].clone(),
                    value: tau,
                    u: tau * u_ln,
                    u_naive: tau * fit.se_naive(i),
                    ci95: [(ln_tau - t95 * u_ln).exp(), (ln_tau + t95 * u_ln).exp()],
                    ci95_at_search_bound: [false; 2],
                }
            }
        })
        .collect();
    let initial_state = (0..n_gains)
        .filter(|&i| nuisance[i])
        .map(gain_estimate)
        .collect();
    let corr = fit.correlation();
    let correlation = order
        .iter()
        .map(|&i| order.iter().map(|&j| corr[(i, j)]).collect())
        .collect();
    let columns = problem.full_columns(&theta);
    let n = series.t_s.len();
    let mut thermal_um = vec![0.0; n];
    for (j, col) in columns.iter().enumerate() {
        thermal_um
            .iter_mut()
            .zip(col)
            .for_each(|(m, c)| *m += fit.values[j] * c);
    }
    // One zero per zero segment; a segment without fitted samples (a check mount) has none: 0.
    let zeros_um = problem.zeros_um(&theta, &fit.values[..n_gains]);
    let model_um = thermal_um
        .iter()
        .zip(&series.zero_segment)
        .map(|(m, s)| m + s.map_or(0.0, |s| zeros_um[s as usize]))
        .collect();
    BarModel {
        bar: series.bar.id.clone(),
        effects,
        params,
        initial_state,
        gains: fit.values[..n_gains].to_vec(),
        not_identifiable: problem.not_identifiable().to_vec(),
        zeros_um,
        correlation,
        rms_um: fit.rms(),
        n_samples: fit.n_obs,
        bic: fit.bic(),
        log_likelihood: fit.log_likelihood(),
        n_params: fit.n_params(),
        model_um,
        thermal_um,
        residuals_um: problem.unweighted(&fit.residuals),
        theta,
        hac_batch_len: fit.hac_batch_len,
        dof: order.iter().map(|&i| fit.dof_of(i)).collect(),
        theta_index: order
            .iter()
            .map(|&i| (i >= n_lin).then(|| i - n_lin))
            .collect(),
        coarse_theta: None,
    }
}

#[cfg(test)]
mod conditioning_tests;

#[cfg(test)]
mod tests {
    use super::*;

    /// The start [`fit_from`] takes on a long series: [`start_fit`] on its coarse copy; `None`
    /// for a short one.
    fn coarse_start(series: &BarSeries, effects: &[Effect], theta0: &[f64]) -> Option<Vec<f64>> {
        let coarse = coarse_copy(series, COARSE_START_MIN_SAMPLES)?;
        let problem = ThermalProblem::new(&coarse, effects).ok()?;
        start_fit(&problem, &series.bar.id, theta0)
    }
    use crate::campaign::Bar;
    use crate::fit::Separable;
    use crate::series::MountSpan;
    use crate::signal::lag::lag;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use rayon::prelude::*;

    const TRUTH: [(&str, f64); 4] = [
        ("alpha_ppm_per_k", 2.0),
        ("beta_ppm_per_k", 0.6),
        ("tau_r_s", 3000.0),
        ("tau_s_s", 1500.0),
    ];

    /// One synthetic bar: 8 days at 60 s on four 2-day mounts (I_p 20, 95, 170, 95 mm), a room with a
    /// daily swing, an air-conditioning cycle and a random walk, and AR(1) noise (phi = 0.9):
    /// residuals as correlated as real ones.
    fn synthetic_bar(seed: u64) -> BarSeries {
        synthetic_bar_with_noise(seed, 60).0
    }

    /// [`synthetic_bar`] sampled every `step_s` seconds.
    fn synthetic_bar_every(seed: u64, step_s: usize) -> BarSeries {
        synthetic_bar_with_noise(seed, step_s).0
    }

    /// [`synthetic_bar_every`] and its AR(1) noise (µm, one per sample).
    fn synthetic_bar_with_noise(seed: u64, step_s: usize) -> (BarSeries, Vec<f64>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let n = 8 * 86400 / step_s;
        let t_s: Vec<f64> = (0..n).map(|i| (i * step_s) as f64).collect();
        let mut walk = 0.0;
        let air_c: Vec<f64> = t_s
            .iter()
            .map(|t| {
                walk += 0.01 * unit.sample(&mut rng);
                20.3 + 0.5 * (2.0 * std::f64::consts::PI * t / 86400.0).sin()
                    + 0.1 * (2.0 * std::f64::consts::PI * t / 1500.0).sin()
                    + walk
            })
            .collect();
        let i_min = 230.0;
        let lengths = [250.0, 325.0, 400.0, 325.0];
        let mounts: Vec<MountSpan> = lengths
            .iter()
            .enumerate()
            .map(|(k, mm)| {
                let day_s = 2.0 * 86400.0;
                MountSpan::calibration(k, *mm, i_min, k as f64 * day_s, (k + 1) as f64 * day_s)
            })
            .collect();
        let dt: Vec<f64> = air_c.iter().map(|t| t - 20.0).collect();
        let (lr, _) = lag(&t_s, &dt, TRUTH[2].1, false);
        let (ls, _) = lag(&t_s, &dt, TRUTH[3].1, false);
        let mut ar = 0.0;
        let phi: f64 = 0.9;
        let sigma_innov = 0.02 * (1.0 - phi * phi).sqrt();
        let mut noise = Vec::with_capacity(n);
        let y_um: Vec<f64> = (0..n)
            .map(|i| {
                let m = i / (2 * 86400 / step_s);
                ar = phi * ar + sigma_innov * unit.sample(&mut rng);
                noise.push(ar);
                -(TRUTH[0].1 * i_min * lr[i] + TRUTH[1].1 * mounts[m].i_p_mm * ls[i]) * 1e-3
                    + 0.3 * m as f64
                    + ar
            })
            .collect();
        let bar = Bar {
            id: format!("S{seed}"),
            resolution_nm: 1.0,
            fixed_length_mm: i_min,
            sensor: None,
        };
        (
            BarSeries::from_vectors(bar, 20.0, t_s, y_um, air_c, mounts),
            noise,
        )
    }

    /// Diagnosis of the coverage (not a check): per replicate, the fitted parameters in the
    /// fit's parametrisation (gains, ln taus), their HAC and naive standard errors, the
    /// linearised error `(JᵀJ)⁻¹Jᵀe` from the true noise at the true parameters, and the exact
    /// standard error of that linearised estimator under the true AR(1) covariance, and the
    /// reported (profile) intervals of the taus in `ln tau`. Written as CSV to
    /// `$DBB_COVERAGE_CSV`, `$DBB_COVERAGE_REPS` replicates (300).
    /// `DBB_COVERAGE_CSV=/tmp/cov.csv cargo test --release -p dbbcal-core coverage_diagnosis -- --ignored`
    #[test]
    #[ignore]
    fn coverage_diagnosis() {
        let reps: u64 = std::env::var("DBB_COVERAGE_REPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(300);
        let path = std::env::var("DBB_COVERAGE_CSV").unwrap_or("/tmp/coverage.csv".into());
        let truth_theta = [TRUTH[2].1.ln(), TRUTH[3].1.ln()];
        let truth = [TRUTH[0].1, TRUTH[1].1, truth_theta[0], truth_theta[1]];
        let rows: Vec<String> = (0..reps)
            .into_par_iter()
            .map(|seed| {
                let (series, noise) = synthetic_bar_with_noise(seed, 60);
                let effects = crate::model::base_effects();
                let problem = ThermalProblem::new(&series, &effects).unwrap();
                let opts = FitOptions {
                    absorbed_params: problem.n_zeros(),
                    ..FitOptions::default()
                };
                let f = fit::fit(&problem, &problem.theta0(), &opts).unwrap();
                let e_raw: Vec<f64> = series.fit_index.iter().map(|&i| noise[i]).collect();
                let e_problem = ThermalProblem::new(&series, &effects)
                    .unwrap()
                    .with_observations(e_raw);
                let e = nalgebra::DVector::from_column_slice(e_problem.observations());
                // Jacobian at the truth (gains solved there, within noise of the true gains).
                let jac = fit::jacobian_at(&problem, &truth_theta).unwrap();
                let jtj_inv = jac.tr_mul(&jac).try_inverse().unwrap();
                let lin = &jtj_inv * jac.tr_mul(&e);
                // Exact covariance of e (stationary AR(1), phi 0.9, sd 0.02; demeaned per
                // mount, which the fit's zeros absorb anyway): Σ J by a two-sided filter.
                let (phi, var) = (0.9f64, 0.02f64 * 0.02);
                let mut sj = jac.clone();
                for c in 0..jac.ncols() {
                    let col = jac.column(c);
                    let n = col.len();
                    let mut fwd = vec![0.0; n];
                    let mut acc = 0.0;
                    for i in 0..n {
                        acc = phi * acc + col[i];
                        fwd[i] = acc;
                    }
                    let mut acc = 0.0;
                    for i in (0..n).rev() {
                        acc = phi * acc + col[i];
                        sj[(i, c)] = var * (fwd[i] + acc - col[i]);
                    }
                }
                let exact = &jtj_inv * jac.tr_mul(&sj) * &jtj_inv;
                let m = identify(&series, &effects).unwrap();
                let ln_ci = |name: &str| m.param(name).unwrap().ci95.map(f64::ln);
                let [rl, rh] = ln_ci("tau_r_s");
                let [sl, sh] = ln_ci("tau_s_s");
                let mut row = format!(
                    "{seed},{},{},{rl},{rh},{sl},{sh}",
                    f.hac_batch_len, f.hac_dof
                );
                for k in 0..4 {
                    row += &format!(
                        ",{},{},{},{},{},{},{}",
                        f.hac_dof_param[k],
                        f.t95(k),
                        f.values[k] - truth[k],
                        f.se(k),
                        f.se_naive(k),
                        lin[k],
                        exact[(k, k)].sqrt()
                    );
                }
                row
            })
            .collect();
        let mut out =
            String::from("seed,batch,dof,ln_tau_r_lo,ln_tau_r_hi,ln_tau_s_lo,ln_tau_s_hi");
        for k in ["alpha", "beta", "ln_tau_r", "ln_tau_s"] {
            out += &format!(",{k}_nu,{k}_t95,{k}_err,{k}_u,{k}_un,{k}_lin,{k}_uex");
        }
        out.push('\n');
        for r in rows {
            out += &r;
            out.push('\n');
        }
        #[allow(clippy::disallowed_methods)] // a test's export, asked for by DBB_COVERAGE_CSV
        std::fs::write(&path, out).unwrap();
    }

    /// Cost of the profile intervals against the fit itself, one thread:
    /// `cargo test --release -p dbbcal-core profile_cost -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn profile_cost() {
        let (mut t_fit, mut t_profile) = (0.0, 0.0);
        for seed in 0..20 {
            let series = synthetic_bar(seed);
            let t0 = std::time::Instant::now();
            let mut model = identify_from(&series, &crate::model::base_effects(), None).unwrap();
            t_fit += t0.elapsed().as_secs_f64();
            let t0 = std::time::Instant::now();
            profile_tau_intervals(&series, &mut model);
            t_profile += t0.elapsed().as_secs_f64();
        }
        eprintln!("20 bars: fit {t_fit:.2} s, profile intervals {t_profile:.2} s");
    }

    /// On a long series the profile traced on the 300-s coarse copy gives the interval the full
    /// profile gives, to a small part of its width.
    #[test]
    fn coarse_profile_intervals_match_the_full_profile() {
        let series = synthetic_bar_every(5, 10); // 69 120 samples: profiled on the coarse copy
        let model = identify_from(&series, &crate::model::base_effects(), None).unwrap();
        let mut full = model.clone();
        profile_on_series(&series, &mut full);
        let mut coarse = model.clone();
        profile_tau_intervals(&series, &mut coarse);
        for name in ["tau_r_s", "tau_s_s"] {
            let (f, c) = (full.param(name).unwrap(), coarse.param(name).unwrap());
            let width = f.ci95[1].ln() - f.ci95[0].ln();
            for end in 0..2 {
                let off = (c.ci95[end].ln() - f.ci95[end].ln()).abs();
                eprintln!(
                    "{name} end {end}: full {:.2} coarse {:.2} ({:.1} % of the width)",
                    f.ci95[end],
                    c.ci95[end],
                    100.0 * off / width
                );
                assert!(
                    off < 0.1 * width,
                    "{name}: full {:?} coarse {:?}",
                    f.ci95,
                    c.ci95
                );
            }
        }
    }

    #[test]
    fn a_long_series_started_on_a_coarse_copy_reaches_the_brent_started_optimum() {
        let series = synthetic_bar_every(11, 10); // 69 120 samples: above the threshold
        assert!(series.fit_index.len() >= COARSE_START_MIN_SAMPLES);
        let effects = crate::model::base_effects();
        let theta0 = ThermalProblem::new(&series, &effects).unwrap().theta0();
        assert!(coarse_start(&series, &effects, &theta0).is_some());
        let model = identify(&series, &effects).expect("coarse-started fit");
        // The engine's own start (Brent sweep + LM) on the full series, as before.
        let problem = ThermalProblem::new(&series, &effects).unwrap();
        let options = FitOptions {
            absorbed_params: problem.n_zeros(),
            ..FitOptions::default()
        };
        let brent = fit::fit(&problem, &problem.theta0(), &options).expect("Brent-started fit");
        let reference = to_bar_model(&series, &problem, &brent);
        for (name, truth) in TRUTH {
            let (a, b) = (model.value(name).unwrap(), reference.value(name).unwrap());
            assert!((a - b).abs() <= 1e-6 * b.abs(), "{name}: {a} vs {b}");
            assert!(
                (a - truth).abs() < 0.1 * truth,
                "{name}: {a} vs truth {truth}"
            );
        }
        // Short series keep the engine's start.
        let short = synthetic_bar(11);
        assert!(coarse_start(&short, &effects, &theta0).is_none());
    }

    #[test]
    fn hac_intervals_cover_the_truth_at_their_nominal_rate() {
        let reps: u64 = std::env::var("DBB_COVERAGE_REPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(300);
        let t0 = std::time::Instant::now();
        let fits: Vec<BarModel> = (0..reps)
            .into_par_iter()
            .map(|seed| identify(&synthetic_bar(seed), &crate::model::base_effects()).expect("fit"))
            .collect();
        eprintln!(
            "{reps} identifications in {:.1} s",
            t0.elapsed().as_secs_f64()
        );
        let n = reps as f64;
        // Per parameter: reported interval (HAC; profile for taus), Wald interval on the same u
        // and t (the taus' intervals before the profile), naive interval (1.96 u_naive).
        let mut covered = [[0usize; 3]; 4];
        for (k, (name, truth)) in TRUTH.iter().enumerate() {
            let is_tau = name.starts_with("tau");
            // Standardised errors (in ln tau for the taus) against the HAC u.
            let mut z = Vec::new();
            for m in &fits {
                let i = m.params.iter().position(|p| p.name == *name).unwrap();
                let p = &m.params[i];
                let t = fit::t_quantile_975(m.dof[i]);
                let (wald, naive, zi) = if is_tau {
                    let (s, sn) = (p.u / p.value, p.u_naive / p.value);
                    let l = p.value.ln();
                    (
                        [(l - t * s).exp(), (l + t * s).exp()],
                        [(l - 1.96 * sn).exp(), (l + 1.96 * sn).exp()],
                        (l - truth.ln()) / s,
                    )
                } else {
                    (
                        [p.value - t * p.u, p.value + t * p.u],
                        [p.value - 1.96 * p.u_naive, p.value + 1.96 * p.u_naive],
                        (p.value - truth) / p.u,
                    )
                };
                z.push(zi);
                for (j, ci) in [p.ci95, wald, naive].iter().enumerate() {
                    covered[k][j] += usize::from(ci[0] <= *truth && *truth <= ci[1]);
                }
            }
            let mean = z.iter().sum::<f64>() / n;
            let sd = (z.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let tails = z.iter().filter(|x| x.abs() > 1.96).count() as f64 / n;
            let dof = fits
                .iter()
                .map(|m| m.dof[m.params.iter().position(|p| p.name == *name).unwrap()])
                .sum::<f64>()
                / n;
            eprintln!(
                "{name}: z = err/u_hac mean {mean:+.3} sd {sd:.3} P(|z|>1.96) {:.1} %, mean dof {dof:.1}; \
                 coverage reported {:.1} %, Wald {:.1} %, naive {:.1} %",
                tails * 100.0,
                covered[k][0] as f64 / n * 100.0,
                covered[k][1] as f64 / n * 100.0,
                covered[k][2] as f64 / n * 100.0
            );
        }
        // Nominal 95 % within 93-97 % (binomial SE ~1.3 % at 300 replicates) for all four:
        // gains `± t u` with the Satterthwaite t of `fit::satterthwaite_dof`, taus from the
        // adjusted profile likelihood (`profile_tau_intervals`).
        for (k, (name, _)) in TRUTH.iter().enumerate() {
            let c = covered[k][0] as f64 / n;
            assert!(
                (0.93..=0.97).contains(&c),
                "{name}: coverage {:.1} %",
                c * 100.0
            );
        }
        let naive = covered.iter().map(|c| c[2]).sum::<usize>() as f64 / (4.0 * n);
        assert!(
            naive < 0.6,
            "naive intervals should under-cover with AR(1) residuals: {:.1} %",
            naive * 100.0
        );
    }
}
