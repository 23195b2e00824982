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
//!   refitted from the fine optimum); the constants are in `identify/start.rs`.

use crate::fit::{self, Fit, FitError, FitOptions, Start};
use crate::model::{
    base_effects, Effect, ModelError, NotIdentifiable, ThermalProblem, WhyNotIdentifiable,
};
use crate::series::BarSeries;

mod before_after;
mod fleet;
mod profile;
mod start;

pub use before_after::{compare_with_base, BarBeforeAfter, BeforeAfter};
pub use fleet::{identify_fleet, BarOutcome, FleetLogs, FleetReadings, IdentifyOptions};

use profile::profile_tau_intervals;
pub(crate) use start::{coarse_copy, COARSE_START_MIN_SAMPLES};
use start::{defaults_basin, nearer_start, start_fit, warm_start, SearchNew};

/// One estimated parameter.
#[derive(Debug, Clone, PartialEq)]
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
    /// from `identify_from` (diagnosis trial fits): the Wald interval `exp(ln tau ± t u_ln)`.
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
    /// Model value (µm) on the bar's whole timeline, zeros included where a segment applies
    /// (empty in the diagnosis' refits: `BarModel::without_curves`).
    pub model_um: Vec<f64>,
    /// Thermal part of the model only (no zeros), on the whole timeline (empty in the
    /// diagnosis' refits).
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
    /// The model without its curves over the bar's timeline (`model_um` and `thermal_um`
    /// empty): what the diagnosis keeps of its many refits, which it reads by their
    /// parameters, statistics and residuals only.
    pub(crate) fn without_curves(mut self) -> BarModel {
        self.model_um = Vec::new();
        self.thermal_um = Vec::new();
        self
    }
    /// Whether the parameter `name` is one the bar's data cannot determine
    /// ([`BarModel::not_identifiable`]).
    pub fn undetermined(&self, name: &str) -> bool {
        self.undetermined_where(name, |_| true)
    }
    /// Whether the parameter `name` is undetermined in a way that leaves the bar's predicted
    /// response undetermined too ([`WhyNotIdentifiable::leaves_the_response_undetermined`]):
    /// what matching leaves a bar out for.
    pub fn response_undetermined(&self, name: &str) -> bool {
        self.undetermined_where(name, WhyNotIdentifiable::leaves_the_response_undetermined)
    }
    fn undetermined_where(&self, name: &str, why: impl Fn(&WhyNotIdentifiable) -> bool) -> bool {
        self.not_identifiable
            .iter()
            .any(|n| why(&n.reason) && n.params.iter().any(|p| p == name))
    }
    /// The model's effects, by name.
    pub fn effect_names(&self) -> Vec<String> {
        self.effects.iter().map(Effect::name).collect()
    }
}

/// Fit `effects` to one bar.
///
/// The time constants get adjusted profile-likelihood intervals
/// (`profile_tau_intervals`); `identify_from` (the diagnosis' many trial fits) keeps the
/// cheaper Wald intervals.
pub fn identify(series: &BarSeries, effects: &[Effect]) -> Result<BarModel, IdentifyError> {
    let mut model = identify_from(series, effects, None)?;
    profile_tau_intervals(series, &mut model);
    Ok(model)
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
/// "A second simulator"). A warm fit that fails as not identifiable is made again from the
/// defaults ([`or_from_defaults`]).
pub(crate) fn identify_from(
    series: &BarSeries,
    effects: &[Effect],
    start: Option<&BarModel>,
) -> Result<BarModel, IdentifyError> {
    match start {
        Some(start) => or_from_defaults(series, effects, fit_from(series, effects, Some(start))),
        None => identify_afresh(series, effects),
    }
}

/// `warm`, a fit started from another model, or, where it stopped at an optimum the data cannot
/// determine, the fit of `effects` from their defaults (the original error if that fails too).
///
/// Why: a start carries the smaller model's time constants, and one the smaller model ran to a
/// degenerate value can hold the larger fit there. On the loop matrix's air_gradient + creep +
/// plate_expansion (seed 6) a bar's `second_path` model has `tau_r_s` near 9e5 s; `creep`
/// started there makes that lag a straight line, collinear with the creep and the fixed part,
/// and the refit failed as not identifiable, so the ledger kept the bar without `creep` (21.6
/// nm where `dbbcal identify --add-effect` fits 20.2 nm). The defaults' basin is searched after
/// a warm fit that succeeds (`defaults_basin`); this covers the one that fails.
fn or_from_defaults(
    series: &BarSeries,
    effects: &[Effect],
    warm: Result<BarModel, IdentifyError>,
) -> Result<BarModel, IdentifyError> {
    match warm {
        Err(IdentifyError::Fit {
            source: FitError::NotIdentifiable { .. },
            ..
        }) => fit_from(series, effects, None).or(warm),
        warm => warm,
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
    if !same_effects(&coarse.effects, effects) || series.fit_index.len() < COARSE_START_MIN_SAMPLES
    {
        return identify_from(series, effects, Some(coarse));
    }
    or_from_defaults(
        series,
        effects,
        fit_from_start(series, effects, Some(coarse), true),
    )
}

/// Whether `a` and `b` hold the same effects, in any order (a model's terms are a set; its
/// time constants are matched by name, `start::warm_start`).
fn same_effects(a: &[Effect], b: &[Effect]) -> bool {
    let names = |e: &[Effect]| {
        let mut n: Vec<String> = e.iter().map(Effect::name).collect();
        n.sort();
        n
    };
    names(a) == names(b)
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
    let reused = match start {
        Some(start) => warm_start(&problem, start, &mut theta0),
        None => vec![false; theta0.len()],
    };
    let mut options = FitOptions {
        absorbed_params: problem.n_zeros(),
        stop: fit::Stop::Statistical,
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
        coarse_problem.as_ref().and_then(|problem| {
            let searched = SearchNew {
                problem,
                reused: &reused,
            };
            start_fit(&searched, &bar, &theta0)
        })
    };
    if let Some(theta) = &coarse_theta {
        theta0 = theta.clone();
        options.start = Start::NearOptimum;
        if let Some(nearer) = nearer_start(series, effects, &theta0) {
            theta0 = nearer;
        }
    }
    let searched = SearchNew {
        problem: &problem,
        reused: &reused,
    };
    let mut fit = fit::fit(&searched, &theta0, &options).map_err(|source| IdentifyError::Fit {
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
        let (a, b) = (model.params[i].name.clone(), model.params[j].name.clone());
        for n in &mut model.not_identifiable {
            let tau = match &mut n.reason {
                WhyNotIdentifiable::AtModelLimit { tau, .. } => Some(tau),
                WhyNotIdentifiable::OneLength { .. } => None,
            };
            for name in n.params.iter_mut().chain(tau) {
                if *name == a {
                    *name = b.clone();
                } else if *name == b {
                    *name = a.clone();
                }
            }
        }
        model.correlation.swap(i, j);
        for row in model.correlation.iter_mut() {
            row.swap(i, j);
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
                let (lo, hi) = crate::model::ln_tau_bounds();
                let tau = ln_tau.clamp(lo, hi).exp();
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
        not_identifiable: problem
            .not_identifiable()
            .iter()
            .cloned()
            .chain(crate::model::at_model_limit(problem, &theta))
            .collect(),
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
mod tests;
