//! Where the model fails, which physical effect is missing, and what adding it buys.
//!
//! Per bar: residual statistics ([`residual`]) and a ranking of every channel the campaign
//! offers by how much of the residual its best first-order response explains. Over the fleet:
//! every catalogue effect not in the model, plus a generic `lag:CHANNEL` term for the channels
//! that explain the most, is added in turn and fitted; candidates are ranked by the fleet's
//! ΔBIC with a likelihood-ratio test in which each residual has its own AR(1)-plus-white-noise
//! model ([`noise`]), so that a slow residual wander fitted by a smooth curve is not taken for
//! an effect.
//! [`forward_selection`] repeats that, adding the best significant candidate until none is left
//! (keeping the few best paths, a beam, so that a greedy first step does not lock it in);
//! [`forward_selection_of_bar`] does the same for one bar on its own channels and tests (bars
//! that are different physical objects, like the displacement axes of a machine tool, need
//! different terms).
//!
//! Everything here is computation on plain data; the pipeline writes and draws the results.

pub mod explain;
pub mod noise;
pub mod residual;
pub mod sensors;

use rayon::prelude::*;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::fit::{self, FitOptions, Separable};
use crate::identify::{identify_from, BarModel};
use crate::model::{channels, Effect, ThermalProblem, Transform, CATALOGUE};
use crate::series::BarSeries;
use residual::{residual_stats, ResidualStats};

/// Family-wise significance level of one selection step: each candidate is tested at
/// `ALPHA / number of candidates` (Bonferroni). 5 %, the level of CTSM-R's likelihood-ratio
/// tests; the likelihoods carry a noise model of the residual ([`noise`]), so autocorrelated
/// residuals do not make everything significant (the base-only campaign raises no alarm).
pub const ALPHA: f64 = 0.05;
/// How many of the best-explaining channels get a generic `lag:` candidate.
pub const CHANNEL_CANDIDATES: usize = 10;

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ChannelScore {
    pub channel: String,
    /// Fraction of the residual variance its best first-order response removes when added to the
    /// model (a linearised refit, see `score_channel`).
    pub explained_fraction: f64,
    /// Its time constant, s (NaN for impulse-free level channels that failed to fit).
    pub tau_s: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct BarDiagnosis {
    pub bar: String,
    pub effects: Vec<String>,
    pub rms_um: f64,
    pub whiteness_p: f64,
    pub stats: ResidualStats,
    /// Best first.
    pub channels: Vec<ChannelScore>,
}

/// One candidate effect's result on one bar.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CandidateOnBar {
    pub bar: String,
    pub rms_before_um: f64,
    pub rms_after_um: f64,
    pub delta_bic: f64,
    pub p_value: f64,
    pub significant: bool,
    /// Why it could not be fitted on this bar, if so.
    pub error: Option<String>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Candidate {
    /// Accepted verbatim by `--add-effect`.
    pub effect: String,
    pub rms_before_um: f64,
    pub rms_after_um: f64,
    pub delta_bic: f64,
    pub p_value: f64,
    pub bars_improved: usize,
    pub significant: bool,
    pub explanation: String,
    pub per_bar: Vec<CandidateOnBar>,
}

/// Diagnose one bar's fit: residual statistics and the channel ranking.
pub fn diagnose_bar(series: &BarSeries, model: &BarModel) -> BarDiagnosis {
    let y: Vec<f64> = series.fit_index.iter().map(|&i| series.y_um[i]).collect();
    let stats = residual_stats(&y, &model.residuals_um, model.n_params);
    let directions = model_directions(series, model);
    let mut channels: Vec<ChannelScore> = channels::available(series)
        .into_iter()
        .filter_map(|ch| score_channel(series, &model.residuals_um, directions.as_ref(), &ch))
        .collect();
    channels.sort_by(|a, b| {
        b.explained_fraction
            .total_cmp(&a.explained_fraction)
            .then_with(|| a.channel.cmp(&b.channel))
    });
    BarDiagnosis {
        bar: model.bar.clone(),
        effects: model.effect_names(),
        rms_um: model.rms_um,
        whiteness_p: stats.whiteness_p,
        stats,
        channels,
    }
}

/// The directions a refit of `model` can move in on the fitted samples: its Jacobian in all its
/// parameters (zeros projected out), `None` if it cannot be formed.
fn model_directions(series: &BarSeries, model: &BarModel) -> Option<nalgebra::DMatrix<f64>> {
    let problem = ThermalProblem::new(series, &model.effects).ok()?;
    fit::jacobian_at(&problem, &model.theta)
}

/// Fraction of the residual variance removed by the channel's best lag when the model is
/// refitted with it (linearised: the channel's column is taken orthogonal to the model's
/// Jacobian `directions`; zeros per segment refitted). Without `directions`, the residual alone.
fn score_channel(
    series: &BarSeries,
    residual: &[f64],
    directions: Option<&nalgebra::DMatrix<f64>>,
    channel: &str,
) -> Option<ChannelScore> {
    let effect = Effect::Channel {
        transform: Transform::Lag,
        channel: channel.to_string(),
        tau0_s: None,
    };
    let problem = ThermalProblem::new(series, std::slice::from_ref(&effect))
        .ok()?
        .with_observations(residual.to_vec());
    // The residual's own RSS as the problem counts it (weighted, plus any within-bin scatter).
    let rss0: f64 =
        problem.observations().iter().map(|r| r * r).sum::<f64>() + problem.unexplained_rss();
    let options = FitOptions {
        absorbed_params: problem.n_zeros(),
        ..FitOptions::default()
    };
    let theta0 = problem.theta0();
    let fit = match directions {
        Some(d) => fit::fit(&fit::Orthogonalised::new(&problem, d), &theta0, &options),
        None => fit::fit(&problem, &theta0, &options),
    }
    .ok()?;
    let explained_fraction = if rss0 > 0.0 {
        (1.0 - fit.rss / rss0).max(0.0)
    } else {
        0.0
    };
    let tau_s = fit.values.last().map_or(f64::NAN, |t| t.exp());
    Some(ChannelScore {
        channel: channel.to_string(),
        explained_fraction,
        tau_s,
    })
}

/// The candidate effects for a fleet whose model is `effects`: catalogue effects not yet in the
/// model, and `lag:CH` for the channels that explain most of the residuals fleet-wide.
pub fn candidate_effects(effects: &[Effect], diagnoses: &[BarDiagnosis]) -> Vec<Effect> {
    let mut out: Vec<Effect> = CATALOGUE
        .iter()
        .filter_map(|n| Effect::parse(n).ok())
        .filter(|e| !effects.contains(e))
        .collect();
    let mut totals: std::collections::BTreeMap<&str, f64> = Default::default();
    for d in diagnoses {
        for c in &d.channels {
            *totals.entry(c.channel.as_str()).or_default() += c.explained_fraction;
        }
    }
    let mut ranked: Vec<(&str, f64)> = totals.into_iter().collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(b.0)));
    for (ch, _) in ranked.into_iter().take(CHANNEL_CANDIDATES) {
        let e = Effect::Channel {
            transform: Transform::Lag,
            channel: ch.to_string(),
            tau0_s: None,
        };
        if !effects.contains(&e) {
            out.push(e);
        }
    }
    out
}

/// Rewrite the channel candidates' explanations with what their sensors plausibly are.
pub fn explain_candidates(candidates: &mut [Candidate], profiles: &[sensors::SensorProfile]) {
    for c in candidates {
        if let Ok(effect) = Effect::parse(&c.effect) {
            c.explanation = explain::explain_with(&effect, profiles);
        }
    }
}

/// A candidate that could not be fitted on any bar (e.g. `head_heating` without `head_power`
/// events), with the first bar's reason.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Unavailable {
    pub effect: String,
    pub reason: String,
}

/// Fit every candidate on every bar; rank the ones that could be fitted best first (by the
/// fleet's ΔBIC) and list the others apart.
pub fn evaluate_candidates(
    bars: &[(&BarSeries, &BarModel)],
    candidates: &[Effect],
) -> (Vec<Candidate>, Vec<Unavailable>) {
    let n_candidates = candidates.len().max(1);
    let threshold = ALPHA / n_candidates as f64;
    // The current models' noise likelihoods, shared by every candidate's test.
    let base_log_likelihood: Vec<f64> = bars
        .par_iter()
        .map(|(s, m)| noise::fit_noise(&s.weighted_residuals(&m.residuals_um)).log_likelihood)
        .collect();
    let out: Vec<Candidate> = candidates
        .par_iter()
        .map(|effect| {
            let per_bar: Vec<CandidateOnBar> = bars
                .iter()
                .zip(&base_log_likelihood)
                .map(|((s, m), &l0)| candidate_on_bar(s, m, l0, effect, threshold))
                .collect();
            summarise_candidate(effect, per_bar, threshold)
        })
        .collect();
    let (mut ranked, unfit): (Vec<Candidate>, Vec<Candidate>) = out
        .into_iter()
        .partition(|c| c.per_bar.iter().any(|b| b.error.is_none()));
    ranked.sort_by(|a, b| {
        a.delta_bic
            .total_cmp(&b.delta_bic)
            .then_with(|| a.effect.cmp(&b.effect))
    });
    prefer_named_effects(&mut ranked);
    let unavailable = unfit
        .into_iter()
        .map(|c| Unavailable {
            reason: c
                .per_bar
                .iter()
                .find_map(|b| b.error.clone())
                .unwrap_or_default(),
            effect: c.effect,
        })
        .collect();
    (ranked, unavailable)
}

fn candidate_on_bar(
    series: &BarSeries,
    base: &BarModel,
    base_log_likelihood: f64,
    effect: &Effect,
    threshold: f64,
) -> CandidateOnBar {
    let mut effects = base.effects.clone();
    effects.push(effect.clone());
    let unfit = |error: String| CandidateOnBar {
        bar: base.bar.clone(),
        rms_before_um: base.rms_um,
        rms_after_um: base.rms_um,
        delta_bic: 0.0,
        p_value: 1.0,
        significant: false,
        error: Some(error),
    };
    let extended = match identify_from(series, &effects, Some(base)) {
        Ok(m) => m,
        Err(e) => return unfit(e.to_string()),
    };
    if let Some((a, b, r)) = unidentifiable_pair(base, &extended) {
        return unfit(format!(
            "not identifiable on this bar: {a} and {b} correlate at {r:.4}"
        ));
    }
    let added = extended.n_params.saturating_sub(base.n_params).max(1);
    let p_value = lr_p_value(base_log_likelihood, series, &extended, added);
    let delta_bic = extended.bic - base.bic;
    CandidateOnBar {
        bar: base.bar.clone(),
        rms_before_um: base.rms_um,
        rms_after_um: extended.rms_um,
        delta_bic,
        p_value,
        significant: p_value < threshold && delta_bic < 0.0,
        error: None,
    }
}

/// When a generic channel term and a catalogue effect fit equally well (ΔBIC within 2, "not
/// worth more than a bare mention" on Kass & Raftery's scale), the named physical effect goes
/// first: `lag:event:head_power` and `head_heating` are the same model, and the user should be
/// told the physics.
fn prefer_named_effects(ranked: &mut [Candidate]) {
    let generic = |c: &Candidate| c.effect.contains(':');
    for i in 1..ranked.len() {
        let mut j = i;
        while j > 0
            && generic(&ranked[j - 1])
            && !generic(&ranked[j])
            && (ranked[j].delta_bic - ranked[j - 1].delta_bic).abs() < 2.0
        {
            ranked.swap(j - 1, j);
            j -= 1;
        }
    }
}

/// Correlation beyond which two estimates are taken as one combination the data cannot split
/// (e.g. two equal time constants with huge, cancelling gains: a derivative in disguise).
pub const MAX_PARAM_CORRELATION: f64 = 0.9999;

/// The first pair of parameters of `model`, one of them new relative to `base`, whose
/// estimates correlate beyond [`MAX_PARAM_CORRELATION`].
fn unidentifiable_pair(base: &BarModel, model: &BarModel) -> Option<(String, String, f64)> {
    let is_new = |k: usize| base.param(&model.params[k].name).is_none();
    for (i, row) in model.correlation.iter().enumerate() {
        for (j, r) in row.iter().enumerate().skip(i + 1) {
            if (is_new(i) || is_new(j)) && r.abs() > MAX_PARAM_CORRELATION {
                return Some((
                    model.params[i].name.clone(),
                    model.params[j].name.clone(),
                    *r,
                ));
            }
        }
    }
    None
}

/// Likelihood-ratio test of nested fits, each residual under its own maximum-likelihood
/// AR(1)-plus-white-noise model ([`noise`]; `base_log_likelihood` is the base model's),
/// `χ²` with the added parameters' degrees of freedom. The fits are least squares, not the
/// noise model's generalised least squares, which makes the statistic smaller: the test errs on
/// the side of "not significant". A term that lowers the RMS but makes the residual less
/// predictable (it adds its channel's sensor noise, or fits a slow wander with a smooth curve
/// that jumps elsewhere) gets `p = 1`. Residuals are weighed by the square root of their
/// samples' weights ([`BarSeries::weighted_residuals`]).
pub fn lr_p_value(
    base_log_likelihood: f64,
    series: &BarSeries,
    extended: &BarModel,
    added_params: usize,
) -> f64 {
    let l1 = noise::fit_noise(&series.weighted_residuals(&extended.residuals_um)).log_likelihood;
    let lr = 2.0 * (l1 - base_log_likelihood);
    if !(lr > 0.0) {
        return 1.0;
    }
    ChiSquared::new(added_params as f64)
        .map(|d| 1.0 - d.cdf(lr))
        .unwrap_or(f64::NAN)
}

fn summarise_candidate(effect: &Effect, per_bar: Vec<CandidateOnBar>, threshold: f64) -> Candidate {
    let fitted: Vec<&CandidateOnBar> = per_bar.iter().filter(|c| c.error.is_none()).collect();
    let fleet_rms = |f: &dyn Fn(&CandidateOnBar) -> f64| {
        if fitted.is_empty() {
            return f64::NAN;
        }
        (fitted.iter().map(|c| f(c).powi(2)).sum::<f64>() / fitted.len() as f64).sqrt()
    };
    let rms_before_um = fleet_rms(&|c| c.rms_before_um);
    let rms_after_um = fleet_rms(&|c| c.rms_after_um);
    let delta_bic: f64 = fitted.iter().map(|c| c.delta_bic).sum();
    // Fisher's method combines the bars' p-values into one fleet-wide test.
    let p_value = if fitted.is_empty() {
        1.0
    } else {
        let x2: f64 = fitted
            .iter()
            .map(|c| -2.0 * c.p_value.max(1e-300).ln())
            .sum();
        ChiSquared::new(2.0 * fitted.len() as f64)
            .map(|d| 1.0 - d.cdf(x2))
            .unwrap_or(f64::NAN)
    };
    let bars_improved = fitted.iter().filter(|c| c.significant).count();
    Candidate {
        effect: effect.name(),
        rms_before_um,
        rms_after_um,
        delta_bic,
        p_value,
        bars_improved,
        significant: !fitted.is_empty()
            && p_value < threshold
            && delta_bic < 0.0
            && bars_improved > 0,
        explanation: explain::explain(effect),
        per_bar,
    }
}

/// One step of forward selection.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LedgerStep {
    /// `"base"` for the starting model, else the effect added at this step.
    pub added: String,
    pub effects: Vec<String>,
    pub rms_um: Vec<(String, f64)>,
    pub fleet_rms_um: f64,
    pub delta_bic: f64,
    pub p_value: f64,
}

/// One path through forward selection: its ledger, its models and the sum of its steps' ΔBIC.
#[derive(Clone)]
struct SelectionPath {
    ledger: Vec<LedgerStep>,
    models: Vec<BarModel>,
    delta_bic: f64,
    /// No significant candidate was left at its last step.
    finished: bool,
}

/// Forward selection: add the best significant candidate (fleet-wide) until none is left or
/// `max_steps` effects were added. Returns the ledger and the final models.
///
/// With `beam > 1` it keeps the `beam` best paths at each step (each extended by its own best
/// significant candidates, ranked by the path's total ΔBIC) and returns the best path at the
/// end: a greedy first step that fits well alone can lead to a worse three-term model than the
/// runner-up. `beam = 1` is plain greedy forward selection.
/// `first_candidates` are the candidates already ranked for `start` (reused for the first step).
pub fn forward_selection(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    first_candidates: &[Candidate],
    max_steps: usize,
    beam: usize,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let beam = beam.max(1);
    let mut paths = vec![SelectionPath {
        ledger: vec![ledger_step("base".into(), &start, f64::NAN, f64::NAN)],
        models: start,
        delta_bic: 0.0,
        finished: false,
    }];
    for step in 0..max_steps {
        let mut next: Vec<SelectionPath> = paths.iter().filter(|p| p.finished).cloned().collect();
        let mut extensions: Vec<(usize, Candidate)> = Vec::new();
        for (i, path) in paths.iter().enumerate().filter(|(_, p)| !p.finished) {
            let candidates = if step == 0 {
                first_candidates.to_vec()
            } else {
                rank_candidates_for(series, &path.models)
            };
            let significant: Vec<Candidate> = candidates
                .into_iter()
                .filter(|c| c.significant && Effect::parse(&c.effect).is_ok())
                .take(beam)
                .collect();
            if significant.is_empty() {
                let mut done = path.clone();
                done.finished = true;
                next.push(done);
            }
            extensions.extend(significant.into_iter().map(|c| (i, c)));
        }
        if extensions.is_empty() {
            paths = next;
            break;
        }
        extensions.sort_by(|(i, a), (j, b)| {
            (paths[*i].delta_bic + a.delta_bic).total_cmp(&(paths[*j].delta_bic + b.delta_bic))
        });
        let mut seen: std::collections::BTreeSet<Vec<String>> = Default::default();
        let chosen: Vec<(usize, Candidate)> = extensions
            .into_iter()
            .filter(|(i, c)| {
                let mut set = effect_names_of(&paths[*i].models);
                set.push(c.effect.clone());
                set.sort();
                seen.insert(set)
            })
            .take(beam)
            .collect();
        let extended: Vec<SelectionPath> = chosen
            .into_par_iter()
            .map(|(i, c)| extend_path(series, &paths[i], &c))
            .collect();
        next.extend(extended);
        next.sort_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
        next.truncate(beam);
        paths = next;
    }
    let best = paths
        .into_iter()
        .min_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic))
        .expect("forward selection keeps at least one path");
    (best.ledger, best.models)
}

/// The effect names of a fleet's models (one model for all bars).
fn effect_names_of(models: &[BarModel]) -> Vec<String> {
    models
        .first()
        .map(BarModel::effect_names)
        .unwrap_or_default()
}

/// The candidates for the fleet's current `models`, ranked best first.
fn rank_candidates_for(series: &[&BarSeries], models: &[BarModel]) -> Vec<Candidate> {
    let effects = models
        .first()
        .map(|m| m.effects.clone())
        .unwrap_or_default();
    let diagnoses: Vec<BarDiagnosis> = series
        .par_iter()
        .zip(models.par_iter())
        .map(|(s, m)| diagnose_bar(s, m))
        .collect();
    let pairs: Vec<(&BarSeries, &BarModel)> = series.iter().copied().zip(models.iter()).collect();
    evaluate_candidates(&pairs, &candidate_effects(&effects, &diagnoses)).0
}

/// `path` with `candidate` added and every bar refitted.
fn extend_path(
    series: &[&BarSeries],
    path: &SelectionPath,
    candidate: &Candidate,
) -> SelectionPath {
    let mut effects = path
        .models
        .first()
        .map(|m| m.effects.clone())
        .unwrap_or_default();
    effects.push(Effect::parse(&candidate.effect).expect("checked when chosen"));
    // A bar whose extended fit fails keeps its model (it is reported as not improved).
    let models: Vec<BarModel> = series
        .par_iter()
        .zip(path.models.par_iter())
        .map(|(s, m)| identify_from(s, &effects, Some(m)).unwrap_or_else(|_| m.clone()))
        .collect();
    let mut ledger = path.ledger.clone();
    ledger.push(ledger_step(
        candidate.effect.clone(),
        &models,
        candidate.delta_bic,
        candidate.p_value,
    ));
    SelectionPath {
        ledger,
        models,
        delta_bic: path.delta_bic + candidate.delta_bic,
        finished: false,
    }
}

/// One bar's own forward selection.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BarLedger {
    pub bar: String,
    pub steps: Vec<LedgerStep>,
}

/// Forward selection on one bar alone: candidates from its own channel ranking (`diagnosis`
/// of `model`), significance from its own likelihood-ratio tests.
pub fn forward_selection_of_bar(
    series: &BarSeries,
    model: BarModel,
    diagnosis: &BarDiagnosis,
    max_steps: usize,
    beam: usize,
) -> BarLedger {
    let candidates = candidate_effects(&model.effects, std::slice::from_ref(diagnosis));
    let (first, _) = evaluate_candidates(&[(series, &model)], &candidates);
    let bar = model.bar.clone();
    let (steps, _) = forward_selection(&[series], vec![model], &first, max_steps, beam);
    BarLedger { bar, steps }
}

fn ledger_step(added: String, models: &[BarModel], delta_bic: f64, p_value: f64) -> LedgerStep {
    let n_total: usize = models.iter().map(|m| m.n_samples).sum();
    let ss: f64 = models
        .iter()
        .map(|m| m.rms_um.powi(2) * m.n_samples as f64)
        .sum();
    LedgerStep {
        added,
        effects: models.first().map(|m| m.effect_names()).unwrap_or_default(),
        rms_um: models.iter().map(|m| (m.bar.clone(), m.rms_um)).collect(),
        fleet_rms_um: if n_total > 0 {
            (ss / n_total as f64).sqrt()
        } else {
            f64::NAN
        },
        delta_bic,
        p_value,
    }
}
