//! The fleet's candidate effects and their evaluation: which effects and channel terms to try,
//! the score-test screen, the coarse tier, the exact refits and each candidate's result per bar.
//!
//! Separate because it is the costly step of a diagnosis (refits) and decides what is refitted;
//! how candidates are then compared and worded lives beside it.

use super::bar::term_identity;
use super::compare::{lr_p_value, prefer_named_effects, unidentifiable_pair};
use super::refits::Refits;
use super::screen::Screen;
use super::screen::ScreenBase;
use super::summary::summarise_candidate;
use super::{
    BarDiagnosis, Candidate, CandidateError, CandidateOnBar, Criteria, Reason, Verdict,
    CHANNEL_CANDIDATES, COARSE_RIVAL_SHARE, HEAT_CANDIDATES, MAX_EXACT_RIVALS, NAMED_TIE_SHARE,
    RIVAL_SHARE, SCREEN_SHARE,
};
use crate::identify::BarModel;
use crate::model::channels;
use crate::model::Effect;
use crate::model::Transform;
use crate::model::CATALOGUE;
use crate::series::BarSeries;
use rayon::prelude::*;
use statrs::distribution::ChiSquared;
use statrs::distribution::ContinuousCDF;
use std::collections::HashMap;

/// The candidate effects for a fleet whose model is `effects`: catalogue effects not yet in the
/// model, `lag:CH` for the channels that explain most of the residuals fleet-wide and `heat:CH`
/// for the best of them that are sensors or sensor differences; none
/// whose term is already in the model or offered under its catalogue name.
pub(crate) fn candidate_effects(effects: &[Effect], diagnoses: &[BarDiagnosis]) -> Vec<Effect> {
    let mut taken: std::collections::BTreeSet<String> = effects.iter().map(term_identity).collect();
    let mut out: Vec<Effect> = CATALOGUE
        .iter()
        .filter_map(|n| Effect::parse(n).ok())
        .filter(|e| taken.insert(term_identity(e)))
        .collect();
    let mut totals: std::collections::BTreeMap<&str, f64> = Default::default();
    for d in diagnoses {
        for c in &d.channels {
            *totals.entry(c.channel.as_str()).or_default() += c.explained_fraction;
        }
    }
    let mut ranked: Vec<(&str, f64)> = totals.into_iter().collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(b.0)));
    let generic = |transform, ch: &str| Effect::Channel {
        transform,
        channel: ch.to_string(),
        tau0_s: None,
    };
    let lags = ranked
        .iter()
        .take(CHANNEL_CANDIDATES)
        .map(|(ch, _)| generic(Transform::Lag, ch));
    let heats = ranked
        .iter()
        .filter(|(ch, _)| channels::is_sensor_channel(ch))
        .take(HEAT_CANDIDATES)
        .map(|(ch, _)| generic(Transform::Heat, ch));
    for e in lags.chain(heats) {
        if taken.insert(term_identity(&e)) {
            out.push(e);
        }
    }
    out
}

/// A candidate that could not be fitted on any bar (e.g. `head_heating` without `head_power`
/// events), with the first bar's reason.
#[derive(Debug, Clone, PartialEq)]
pub struct Unavailable {
    /// The candidate.
    pub effect: Effect,
    /// Why the first bar could not fit it (`None` without bars).
    pub reason: Option<CandidateError>,
}

/// Screen every candidate on every bar (`bases`: the bars' models linearised,
/// [`screen_bases`](super::screen_bases)), refit exactly those whose screened gain could be material, test them, and
/// rank them: proposed first, then the other refitted ones (both by the fleet's ΔBIC), then the
/// screened-out ones (by screened gain).
/// Candidates that could not be built on any bar are listed apart.
pub(crate) fn evaluate_candidates(
    bars: &[(&BarSeries, &BarModel)],
    bases: &[Option<ScreenBase>],
    candidates: &[Effect],
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<Candidate>, Vec<Unavailable>) {
    evaluate_at_most(bars, bases, candidates, criteria, refits, Refitted::All)
}

/// Which of a step's candidates that pass the screen are refitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Refitted {
    /// Every rival (a ranking of the readings), and every catalogue effect that may be material
    /// by its shift alone.
    All,
    /// At most this many rivals, the best screened, and every catalogue effect that may be
    /// material by its shift alone (a step of the coarse beam after its first).
    Best(usize),
    /// At most this many rivals, the best screened (the coarse beam's first step: the readings'
    /// ranking, whose candidates it is offered, refitted the others exactly already).
    BestOfFirstStep(usize),
}

/// [`evaluate_candidates`], refitting the candidates that pass the screen as `refitted` says
/// (at most a number of the best screened: the coarse forward selection's rule,
/// [`super::COARSE_BEAM_REFITS`]).
pub(super) fn evaluate_at_most(
    bars: &[(&BarSeries, &BarModel)],
    bases: &[Option<ScreenBase>],
    candidates: &[Effect],
    criteria: &Criteria,
    refits: &Refits,
    refitted: Refitted,
) -> (Vec<Candidate>, Vec<Unavailable>) {
    let max_refits = match refitted {
        Refitted::All => None,
        Refitted::Best(most) | Refitted::BestOfFirstStep(most) => Some(most),
    };
    let threshold = criteria.alpha / candidates.len().max(1) as f64;
    let screens: Vec<Vec<Result<Screen, CandidateError>>> = candidates
        .par_iter()
        .map(|effect| {
            bases
                .iter()
                .map(|b| match b {
                    Some(b) => b.screen(effect),
                    None => Err(CandidateError::NotLinearised),
                })
                .collect()
        })
        .collect();
    let mut unavailable = Vec::new();
    // Per candidate that could be built somewhere, as screened: the fleet RMS it removes (which
    // ranks it) and what it could matter by (a shift of the model's own terms counts only where
    // the score test finds the term and the term leaves a trace in the fit).
    let mut screened: Vec<(usize, f64, f64)> = Vec::new();
    for (c, per_bar) in screens.iter().enumerate() {
        if let Some((gain, shift, p)) = screened_change(bars, per_bar) {
            tracing::trace!(effect = %candidates[c].name(), gain, shift, p, "diagnose: screened");
            let shift_counts = p < threshold && criteria.shift_counts(&candidates[c], gain);
            screened.push((c, gain, if shift_counts { gain.max(shift) } else { gain }));
        } else {
            unavailable.push(Unavailable {
                effect: candidates[c].clone(),
                reason: per_bar.iter().find_map(|s| s.as_ref().err().cloned()),
            });
        }
    }
    screened.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let best = screened.first().map_or(0.0, |(_, g, _)| *g);
    let shift_only = |c: usize| {
        screened
            .iter()
            .any(|&(k, gain, change)| k == c && change > gain)
    };
    // A term the score test finds and that would move the model's own terms materially is
    // refitted (on the coarse copies, and exactly when it is a rival there) whatever share of
    // the best's RMS its screen removes: the linearised refit holds the time constants, and such
    // a term moves them (the second simulator's plate expansion, seed 2, 10-s readings in 60-s
    // bins: screened 0.06 nm, 0.08 of the best's, refitted 0.82 nm and the best of the step).
    // In the coarse beam's steps after its first too: on the second simulator's head-heating +
    // plate-expansion campaign (`bench/loop_check.py`, k = 2, seed 6) the copies' step after
    // `head_heating` screened `plate_expansion` at 0.10 nm against `heat:T1-P1`'s 1.37 nm, and
    // its refit there leads the step (ΔBIC −155 422 against `air_gradient`'s −147 602); the
    // CPU time of `bench/loop.sh`'s slow campaigns stayed within the VM's drift. Not at the
    // beam's first step ([`Refitted::BestOfFirstStep`]): there it refitted every such catalogue
    // effect on the copies of the settling + plate-expansion campaign (seed 4), whose paths then
    // led with `second_path` and cost 2.6 s more to rule out on the readings, for the same
    // ledger.
    let above_share = |gain: f64| gain >= RIVAL_SHARE * best;
    let material_change = |change: f64| change >= SCREEN_SHARE * criteria.min_gain_um;
    let shift_term = |c: usize| match refitted {
        Refitted::All | Refitted::Best(_) => shift_only(c),
        Refitted::BestOfFirstStep(_) => false,
    };
    let rival = |c: usize, gain: f64| above_share(gain) || shift_term(c);
    // Only a term whose screen passed the rival share on its own is kept for its shift whatever
    // its coarse refit removes (`coarse_tier`).
    let kept_for_shift = |c: usize| {
        shift_only(c)
            && screened
                .iter()
                .any(|&(k, gain, _)| k == c && above_share(gain))
    };
    let refit: Vec<usize> = screened
        .iter()
        .filter(|(c, gain, change)| material_change(*change) && rival(*c, *gain))
        .enumerate()
        .filter(|(rank, (c, _, _))| max_refits.is_none_or(|most| *rank < most) || shift_only(*c))
        .map(|(_, (c, _, _))| *c)
        .collect();
    let best_effect = screened.first().map(|(c, _, _)| candidates[*c].clone());
    let CoarseTier {
        kept: (mut refit, starts),
        deferred,
        reasons: mut coarse_reasons,
    } = coarse_tier(bars, bases, refit, candidates, kept_for_shift, refits);
    tracing::debug!(
        bars = bars.len(),
        refit = ?refit.iter().map(|&c| candidates[c].name()).collect::<Vec<_>>(),
        "diagnose: candidates refitted exactly"
    );
    let mut exact = exact_refits(
        bars, bases, &refit, &starts, candidates, &screens, threshold, refits,
    );
    // While no candidate refitted exactly is proposed, the next rivals of the coarse copies are
    // (their readings' likelihood-ratio test can fail where the smoothed copies' did not).
    let proposed = |exact: &[Vec<CandidateOnBar>], refit: &[usize]| {
        refit.iter().zip(exact).any(|(&c, per_bar)| {
            summarise_candidate(&candidates[c], per_bar.clone(), threshold, criteria).proposed()
        })
    };
    for batch in deferred.chunks(MAX_EXACT_RIVALS) {
        if proposed(&exact, &refit) {
            break;
        }
        let (more, more_starts): (Vec<usize>, Vec<Vec<Option<BarModel>>>) =
            batch.iter().cloned().unzip();
        tracing::debug!(refit = ?more.iter().map(|&c| candidates[c].name()).collect::<Vec<_>>(), "diagnose: no rival proposed on the readings; the next ones refitted exactly");
        exact.extend(exact_refits(
            bars,
            bases,
            &more,
            &more_starts,
            candidates,
            &screens,
            threshold,
            refits,
        ));
        for c in &more {
            coarse_reasons.remove(c);
        }
        refit.extend(more);
    }
    let mut ranked: Vec<Candidate> = screened
        .iter()
        .map(|&(c, gain, change)| {
            let per_bar = match refit.iter().position(|&r| r == c) {
                Some(k) => exact[k].clone(),
                None => screened_only(bars, &screens[c]),
            };
            let mut summary = summarise_candidate(&candidates[c], per_bar, threshold, criteria);
            // Why it failed on every bar says more than why it was not refitted.
            if matches!(summary.reason, Reason::NotFittedOnAnyBar { .. }) {
                return summary;
            }
            if let Some(reason) = coarse_reasons.get(&c) {
                summary.reason = reason.clone();
            } else if summary.verdict == Verdict::ScreenedOut
                && change >= SCREEN_SHARE * criteria.min_gain_um
                && rival(c, gain)
            {
                summary.reason = Reason::RefitCap {
                    refitted: max_refits.unwrap_or_default(),
                    gain_um: gain,
                };
            } else if summary.verdict == Verdict::ScreenedOut
                && change >= SCREEN_SHARE * criteria.min_gain_um
            {
                summary.reason = Reason::BelowRivalShare {
                    gain_um: gain,
                    share: RIVAL_SHARE,
                    best: best_effect.clone(),
                    best_um: best,
                };
            }
            summary
        })
        .collect();
    rank(&mut ranked, criteria);
    (ranked, unavailable)
}

/// Candidates in the ranking's order: proposed, immaterial, then the rest; within a verdict by
/// ΔBIC where both were refitted, else by what they remove; a named effect before the generic
/// terms it fits equally well ([`prefer_named_effects`]).
fn rank(ranked: &mut [Candidate], criteria: &Criteria) {
    ranked.sort_by(|a, b| {
        a.verdict
            .min(Verdict::NotSignificant)
            .cmp(&b.verdict.min(Verdict::NotSignificant))
            .then_with(|| match (a.delta_bic, b.delta_bic) {
                (Some(x), Some(y)) => x.total_cmp(&y),
                _ => b.gain_um().total_cmp(&a.gain_um()),
            })
            .then_with(|| a.effect.name().cmp(&b.effect.name()))
    });
    prefer_named_effects(ranked, criteria);
}

/// `ranked` (the ranking of the base model's candidates, `offered` of them with the unavailable
/// ones) with `first`, the fleet ledger's first step, refitted exactly and tested as the
/// ranking's other refits are (at its family-wise threshold), where the ranking
/// screened it out; then ranked again.
///
/// Why: the ledger's steps are chosen on the coarse copies and confirmed exactly, so a term the
/// linearised screen of the readings leaves out can lead the ledger; the ranking then named
/// another effect first, with no reason the page could give. On the second simulator's creep
/// campaign (`bench/foreign_check.py`, seed 5: 1-s readings over 2 days) the screen left `creep`
/// out (0.0014 µm screened) and ranked `air_gradient` first (ΔBIC −103 856), while the
/// ledger added `creep` (−123 616) and reached the noise. The refits are the ledger's own
/// (cached), so this costs their tests only.
pub(crate) fn with_the_ledgers_first_step(
    bars: &[(&BarSeries, &BarModel)],
    bases: &[Option<ScreenBase>],
    (mut ranked, offered): (Vec<Candidate>, usize),
    first: Option<&Effect>,
    criteria: &Criteria,
    refits: &Refits,
) -> Vec<Candidate> {
    let Some(first) = first else {
        return ranked;
    };
    let Some(at) = ranked
        .iter()
        .position(|c| c.effect == *first && c.delta_bic.is_none())
    else {
        return ranked;
    };
    let threshold = criteria.alpha / offered.max(1) as f64;
    let starts = vec![None; bars.len()];
    ranked[at] = refitted_candidate(bars, bases, first, &starts, threshold, criteria, refits);
    rank(&mut ranked, criteria);
    ranked
}

/// `effect` screened, refitted exactly on every bar (from `starts`, a bar's model where `None`)
/// and tested at `threshold`: the candidate as the ranking reports one it refitted.
pub(super) fn refitted_candidate(
    bars: &[(&BarSeries, &BarModel)],
    bases: &[Option<ScreenBase>],
    effect: &Effect,
    starts: &[Option<BarModel>],
    threshold: f64,
    criteria: &Criteria,
    refits: &Refits,
) -> Candidate {
    let screens: Vec<Vec<Result<Screen, CandidateError>>> = vec![bases
        .iter()
        .map(|b| match b {
            Some(b) => b.screen(effect),
            None => Err(CandidateError::NotLinearised),
        })
        .collect()];
    let per_bar = exact_refits(
        bars,
        bases,
        &[0],
        &[starts.to_vec()],
        std::slice::from_ref(effect),
        &screens,
        threshold,
        refits,
    )
    .pop()
    .unwrap_or_default();
    summarise_candidate(effect, per_bar, threshold, criteria)
}

/// The fleet RMS a candidate removes, how much it moves the model's own terms (quadratic means
/// over the bars where it could be built) and the p-value of its fleet score test (the bars'
/// statistics summed), as screened; `None` if it could be built on no bar.
fn screened_change(
    bars: &[(&BarSeries, &BarModel)],
    per_bar: &[Result<Screen, CandidateError>],
) -> Option<(f64, f64, f64)> {
    let (mut before, mut after, mut shift, mut n) = (0.0, 0.0, 0.0, 0usize);
    let (mut score, mut dof) = (0.0, 0usize);
    for ((_, m), s) in bars.iter().zip(per_bar) {
        if let Ok(s) = s {
            before += m.rms_um.powi(2);
            after += s.rms_after_um.powi(2);
            shift += s.shift_rms_um.powi(2);
            score += s.score;
            dof += s.dof.max(1);
            n += 1;
        }
    }
    let mean = |v: f64| (v / n as f64).sqrt();
    let p = ChiSquared::new(dof.max(1) as f64).map_or(1.0, |d| 1.0 - d.cdf(score));
    (n > 0).then(|| ((mean(before) - mean(after)).max(0.0), mean(shift), p))
}

/// Coarse refits of the candidates `refit` (indices into `candidates`, best screened first)
/// on every bar screened on a coarse copy ([`ScreenBase::coarse_refit`]): the candidates to
/// refit exactly (those removing at least [`COARSE_RIVAL_SHARE`] of the best's fleet RSS there,
/// and those `shift_only` may make material), the coarse refits they start from (per kept
/// candidate, per bar), and why each other one was left out. Where no bar has a coarse copy,
/// every candidate is kept and starts from the bar's model.
#[allow(clippy::type_complexity)]
fn coarse_tier(
    bars: &[(&BarSeries, &BarModel)],
    bases: &[Option<ScreenBase>],
    refit: Vec<usize>,
    candidates: &[Effect],
    shift_only: impl Fn(usize) -> bool,
    refits: &Refits,
) -> CoarseTier {
    let none = |refit: Vec<usize>| {
        let starts = vec![vec![None; bars.len()]; refit.len()];
        CoarseTier {
            kept: (refit, starts),
            deferred: Vec::new(),
            reasons: HashMap::new(),
        }
    };
    // A lone candidate is refitted on the copies too: its exact refit then starts at their
    // optimum instead of searching the readings from the model.
    if refit.is_empty() || !bases.iter().flatten().any(|b| b.coarse_refit_possible()) {
        return none(refit);
    }
    let jobs: Vec<(usize, usize)> = refit
        .iter()
        .flat_map(|&c| (0..bars.len()).map(move |b| (c, b)))
        .collect();
    let fitted: Vec<Option<(f64, BarModel)>> = jobs
        .par_iter()
        .map(|&(c, b)| {
            let base = bases[b].as_ref()?;
            base.coarse_refit(bars[b].1, &candidates[c])?.ok()
        })
        .collect();
    for (&(_, b), f) in jobs.iter().zip(&fitted) {
        if let Some((_, m)) = f {
            refits.remember_coarse(&bars[b].1.bar, m);
        }
    }
    let per_candidate: Vec<&[Option<(f64, BarModel)>]> = fitted.chunks(bars.len().max(1)).collect();
    // The fleet RSS each removes on the coarse copies (µm², each bar on its own samples' scale).
    let removed: Vec<f64> = per_candidate
        .iter()
        .map(|per_bar| per_bar.iter().flatten().map(|(d, _)| d).sum())
        .collect();
    let best = removed.iter().copied().fold(0.0, f64::max);
    let fleet_rms = |rss: f64| {
        let n: usize = bars.iter().map(|(_, m)| m.n_samples).sum();
        (rss / n.max(1) as f64).sqrt()
    };
    // The order in which rivals get an exact refit: by what they remove, a named effect first
    // among ties.
    let generic = |k: usize| matches!(candidates[refit[k]], Effect::Channel { .. });
    let mut order: Vec<usize> = (0..refit.len()).collect();
    order.sort_by(|&a, &b| {
        let tie = (removed[a] - removed[b]).abs() <= NAMED_TIE_SHARE * removed[a].max(removed[b]);
        if tie && generic(a) != generic(b) {
            generic(a).cmp(&generic(b))
        } else {
            removed[b].total_cmp(&removed[a]).then(a.cmp(&b))
        }
    });
    let rank_of = |k: usize| order.iter().position(|&o| o == k).unwrap_or(usize::MAX);
    let best_at = order[0];
    let mut kept = Vec::new();
    let mut starts = Vec::new();
    let mut deferred = Vec::new();
    let mut reasons = HashMap::new();
    let start_of = |k: usize| -> Vec<Option<BarModel>> {
        per_candidate[k]
            .iter()
            .map(|f| f.as_ref().map(|(_, m)| m.clone()))
            .collect()
    };
    for &k in &order {
        if removed[k] >= COARSE_RIVAL_SHARE * best
            && rank_of(k) >= MAX_EXACT_RIVALS
            && !shift_only(refit[k])
        {
            deferred.push((refit[k], start_of(k)));
        }
    }
    for (k, &c) in refit.iter().enumerate() {
        let rival = removed[k] >= COARSE_RIVAL_SHARE * best && rank_of(k) < MAX_EXACT_RIVALS;
        if rival || shift_only(c) {
            kept.push(c);
            starts.push(start_of(k));
        } else {
            let (removed_um2, removed_rms_um) = (removed[k], fleet_rms(removed[k]));
            let best_effect = candidates[refit[best_at]].clone();
            let reason = if removed[k] >= COARSE_RIVAL_SHARE * best {
                Reason::CoarseBehindRivals {
                    removed_um2,
                    removed_rms_um,
                    best: best_effect,
                    best_um2: best,
                    rivals: MAX_EXACT_RIVALS,
                }
            } else {
                Reason::CoarseBelowShare {
                    removed_um2,
                    removed_rms_um,
                    share: COARSE_RIVAL_SHARE,
                    best: best_effect,
                    best_um2: best,
                }
            };
            reasons.insert(c, reason);
        }
    }
    CoarseTier {
        kept: (kept, starts),
        deferred,
        reasons,
    }
}

/// What the coarse tier decided ([`coarse_tier`]).
struct CoarseTier {
    /// The candidates to refit exactly and their starts (per candidate, per bar).
    kept: (Vec<usize>, Vec<Vec<Option<BarModel>>>),
    /// The rivals close to the best on the coarse copies but past the first
    /// [`MAX_EXACT_RIVALS`], in their coarse order, with their starts: refitted exactly, a
    /// batch at a time, only while no candidate refitted exactly is proposed.
    deferred: Vec<(usize, Vec<Option<BarModel>>)>,
    /// Why each candidate left out was left out.
    reasons: HashMap<usize, Reason>,
}

/// Exact refits of the candidates `refit` (indices into `candidates`) on every bar where they
/// could be screened, with their likelihood-ratio tests; each starts from its coarse refit in
/// `starts` where there is one, else from the bar's model.
#[allow(clippy::too_many_arguments)]
pub(super) fn exact_refits(
    bars: &[(&BarSeries, &BarModel)],
    bases: &[Option<ScreenBase>],
    refit: &[usize],
    starts: &[Vec<Option<BarModel>>],
    candidates: &[Effect],
    screens: &[Vec<Result<Screen, CandidateError>>],
    threshold: f64,
    refits: &Refits,
) -> Vec<Vec<CandidateOnBar>> {
    if refit.is_empty() {
        return Vec::new();
    }
    // The current models' noise likelihoods, shared by every candidate's test (a bar without a
    // base has no screen either, so it is never refitted).
    let base_log_likelihood: Vec<f64> = bases
        .par_iter()
        .map(|b| b.as_ref().map_or(f64::NAN, |b| b.noise().log_likelihood))
        .collect();
    let jobs: Vec<(usize, usize, usize)> = refit
        .iter()
        .enumerate()
        .flat_map(|(k, &c)| (0..bars.len()).map(move |b| (k, c, b)))
        .collect();
    let done: Vec<CandidateOnBar> = jobs
        .par_iter()
        .map(|&(k, c, b)| {
            let (s, m) = bars[b];
            match &screens[c][b] {
                Ok(screen) => candidate_on_bar(
                    (s, m, starts[k][b].as_ref()),
                    base_log_likelihood[b],
                    &candidates[c],
                    screen,
                    threshold,
                    refits,
                ),
                Err(e) => unfit_on_bar(m, e.clone()),
            }
        })
        .collect();
    done.chunks(bars.len().max(1)).map(<[_]>::to_vec).collect()
}

/// A candidate's per-bar results when it was screened out (no refit).
fn screened_only(
    bars: &[(&BarSeries, &BarModel)],
    screens: &[Result<Screen, CandidateError>],
) -> Vec<CandidateOnBar> {
    bars.iter()
        .zip(screens)
        .map(|((_, m), s)| match s {
            Ok(s) => CandidateOnBar {
                bar: m.bar.clone(),
                rms_before_um: m.rms_um,
                screened_rms_after_um: s.rms_after_um,
                screened_shift_um: s.shift_rms_um,
                rms_after_um: None,
                delta_bic: None,
                p_value: None,
                significant: false,
                error: None,
            },
            Err(e) => unfit_on_bar(m, e.clone()),
        })
        .collect()
}

fn unfit_on_bar(base: &BarModel, error: CandidateError) -> CandidateOnBar {
    CandidateOnBar {
        bar: base.bar.clone(),
        rms_before_um: base.rms_um,
        screened_rms_after_um: base.rms_um,
        screened_shift_um: 0.0,
        rms_after_um: None,
        delta_bic: None,
        p_value: None,
        significant: false,
        error: Some(error),
    }
}

/// One candidate on one bar: `(series, base, start)`, the bar, its model and where the refit
/// starts (its coarse refit, or the model itself when `None`).
fn candidate_on_bar(
    (series, base, start): (&BarSeries, &BarModel, Option<&BarModel>),
    base_log_likelihood: f64,
    effect: &Effect,
    screen: &Screen,
    threshold: f64,
    refits: &Refits,
) -> CandidateOnBar {
    if let Some((first, second, correlation)) =
        start.and_then(|coarse| unidentifiable_pair(base, coarse))
    {
        return unfit_on_bar(
            base,
            CandidateError::NotIdentifiableOnCopy {
                first,
                second,
                correlation,
            },
        );
    }
    let refit = refits.refit_from(series, base, effect, start);
    let extended = match &refit.model {
        Ok(m) => m,
        Err(e) => return unfit_on_bar(base, e.clone()),
    };
    if let Some((first, second, correlation)) = unidentifiable_pair(base, extended) {
        return unfit_on_bar(
            base,
            CandidateError::NotIdentifiable {
                first,
                second,
                correlation,
            },
        );
    }
    let added = extended.n_params.saturating_sub(base.n_params).max(1);
    let p_value = lr_p_value(
        base_log_likelihood,
        refit.noise_log_likelihood(series, extended),
        added,
    );
    let delta_bic = extended.bic - base.bic;
    CandidateOnBar {
        bar: base.bar.clone(),
        rms_before_um: base.rms_um,
        screened_rms_after_um: screen.rms_after_um,
        screened_shift_um: screen.shift_rms_um,
        rms_after_um: Some(extended.rms_um),
        delta_bic: Some(delta_bic),
        p_value: Some(p_value),
        significant: p_value < threshold && delta_bic < 0.0,
        error: None,
    }
}
