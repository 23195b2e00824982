//! Fleet forward selection: the ledger of added effects, the beam of selection paths, the coarse
//! fleet used to rank candidates cheaply and the exact confirmation of a path.
//!
//! Separate because it repeats a diagnosis step by step; one step's evaluation is in
//! `candidates`.

use super::bar::{
    air_references, diagnose_bar, response_family, screen_bases, source_family, term_identity,
};
use super::bar_selection::ledger_step;
use super::candidates::{candidate_effects, evaluate_at_most, refitted_candidate, Refitted};
use super::compare::competing_delta_bic;
use super::compare::stood_in_for;
use super::plate::{plate_named_in, plate_split_path, without_sensor};
use super::refits::Refits;
use super::{
    BarDiagnosis, Candidate, Criteria, CHANNEL_CANDIDATES, COARSE_BEAM_REFITS, HEAT_CANDIDATES,
    PATH_TIE_SHARE,
};
use crate::identify::identify_from;
use crate::identify::BarModel;
use crate::model::Effect;
use crate::model::CATALOGUE;
use crate::series::BarSeries;
use rayon::prelude::*;

/// One step of forward selection.
#[derive(Debug, Clone, PartialEq)]
pub struct LedgerStep {
    /// What this step added (written `"base"` for the starting model, else the effect's name).
    pub added: Added,
    /// The model's effects after this step.
    pub effects: Vec<Effect>,
    /// Each bar's RMS residual after this step, µm.
    pub rms_um: Vec<(String, f64)>,
    /// Fleet RMS residual after this step, µm.
    pub fleet_rms_um: f64,
    /// The added effect's ΔBIC (absent for the starting model).
    pub delta_bic: Option<f64>,
    /// The added effect's p-value (absent for the starting model).
    pub p_value: Option<f64>,
}

/// What a ledger step added to the model before it.
#[derive(Debug, Clone, PartialEq)]
pub enum Added {
    /// The starting model: nothing added.
    Base,
    /// An effect (written as its name).
    Effect(Effect),
}

impl Added {
    /// `"base"`, or the effect's name.
    pub fn name(&self) -> String {
        match self {
            Added::Base => "base".into(),
            Added::Effect(e) => e.name(),
        }
    }

    /// The axis label of the step in the ledger figures: `base`, `+EFFECT`.
    pub fn label(&self) -> String {
        match self {
            Added::Base => "base".into(),
            Added::Effect(e) => format!("+{}", e.name()),
        }
    }
}

impl std::fmt::Display for Added {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(&self.name())
    }
}

/// One path through forward selection: its ledger, its models and the sum of its steps' ΔBIC.
#[derive(Clone)]
struct SelectionPath {
    ledger: Vec<LedgerStep>,
    models: Vec<BarModel>,
    delta_bic: f64,
    /// No proposed candidate was left at its last step.
    finished: bool,
}

impl SelectionPath {
    /// The path that has added nothing yet: the ledger's base step on `models`.
    fn starting_at(models: Vec<BarModel>) -> SelectionPath {
        SelectionPath {
            ledger: vec![ledger_step(
                Added::Base,
                effects_of(&models),
                &models,
                None,
                None,
            )],
            models,
            delta_bic: 0.0,
            finished: false,
        }
    }
}

/// Forward selection: add the best proposed candidate (fleet-wide: significant and material by
/// `criteria`) until none is left or `max_steps` effects were added. Returns the ledger and the
/// final models. Each step screens every candidate and refits exactly only those that could be
/// material ([`evaluate_candidates`](super::evaluate_candidates)).
///
/// With `beam > 1` it keeps the `beam` best paths at each step (each extended by its own best
/// proposed candidates, ranked by the path's total ΔBIC) and returns the best path at the
/// end: a greedy first step that fits well alone can lead to a worse three-term model than the
/// runner-up. `beam = 1` is plain greedy forward selection.
/// `first_candidates` are the candidates already ranked for `start` (reused for the first step).
pub(crate) fn forward_selection(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    first_candidates: &[Candidate],
    max_steps: usize,
    beam: usize,
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    // Nothing proposed at the first step: nothing to search (the beam would stop there too).
    if max_steps > 0 && first_candidates.iter().any(Candidate::proposed) {
        if let Some(coarse) = CoarseFleet::new(series, &start, refits) {
            let (paths, pushed_out) = coarse.select(max_steps, beam, first_candidates, criteria);
            for (path, total) in &paths {
                tracing::debug!(path = ?path.iter().map(Effect::name).collect::<Vec<_>>(), total, "diagnose: a coarse path");
            }
            if paths.first().is_some_and(|(path, _)| !path.is_empty()) {
                return confirm_tied_paths(
                    series,
                    start,
                    first_candidates,
                    (&paths, pushed_out.as_ref(), &coarse, max_steps),
                    criteria,
                    refits,
                );
            }
            // The copies propose nothing where the readings do (their smoothed noise passes no
            // test the readings pass): the paths are searched on the readings, each step
            // refitting as many candidates as a coarse step.
            tracing::debug!("diagnose: no coarse path; the beam searches the readings");
            return beam_search(
                series,
                start,
                first_candidates,
                (max_steps, beam, Some(COARSE_BEAM_REFITS)),
                criteria,
                refits,
            );
        }
    }
    beam_search(
        series,
        start,
        first_candidates,
        (max_steps, beam, None),
        criteria,
        refits,
    )
}

/// A path of the coarse beam: the effects it adds, in order, and its total ΔBIC on the copies.
type CoarsePath = (Vec<Effect>, f64);

/// Every bar's coarse copy (`identify::coarse_copy`) and its model refitted there: where the
/// forward selection searches its paths when every bar is long enough to have one.
struct CoarseFleet {
    series: Vec<BarSeries>,
    models: Vec<BarModel>,
    /// The refits on the coarse copies, started with the ranking's coarse tier
    /// ([`Refits::for_coarse_copies`]); the exact refits of the chosen path start from them.
    refits: Refits,
}

impl CoarseFleet {
    fn new(series: &[&BarSeries], models: &[BarModel], refits: &Refits) -> Option<CoarseFleet> {
        let copies: Vec<BarSeries> = series
            .iter()
            .map(|s| crate::identify::coarse_copy(s, super::DIAGNOSE_COARSE_MIN_SAMPLES))
            .collect::<Option<_>>()?;
        let fitted: Vec<BarModel> = copies
            .par_iter()
            .zip(models.par_iter())
            .map(|(c, m)| identify_from(c, &m.effects, Some(m)).ok())
            .collect::<Option<_>>()?;
        Some(CoarseFleet {
            series: copies,
            models: fitted,
            refits: refits.for_coarse_copies(),
        })
    }

    /// The coarse refit of `bar` with `effects` and `effect` added, where the search made one:
    /// the start of that step's exact refit.
    fn start_for(&self, bar: &str, effects: &[Effect], effect: &Effect) -> Option<BarModel> {
        let mut all = effects.to_vec();
        all.push(effect.clone());
        self.refits.get(bar, &all)?.model.clone().ok()
    }

    /// `path` with the plate named ([`plate_split_path`]) where that path ends at a lower BIC
    /// on the copies ([`CoarseFleet::final_bic`]); `None` where `path` reads the plate through
    /// no generic term or the copies prefer it as it is.
    ///
    /// Why: the plate's temperature acts on a plate mount's calibrated length
    /// (`plate_expansion`, `physics.md`), a heat source through the bar; a generic lag of their
    /// difference carries much of both with one gain a bar, and the beam, which ranks one step
    /// at a time, keeps it. On the second simulator's air-gradient + plate-expansion +
    /// heat-source campaign (`bench/loop_check.py`, k = 3, seed 1) the ledger read
    /// `heat:P1-C1` → `air_gradient` (20.04 nm) where `heat:C1`, `plate_expansion` and
    /// `air_gradient` fit to 20.03 nm at a BIC lower by 833; on our simulator's sensor-gradient +
    /// plate-expansion + hidden-channel campaign `heat:P1-H1` → `heat:T2-P1` → `air_gradient`
    /// (20.09 nm) against 20.06 nm, 4 079 lower. Cost: the split path's refits on the copies
    /// (its exact refits then start from them, as a coarse path's do).
    fn with_the_plate_named(
        &self,
        path: &[Effect],
        plate: &str,
        max_steps: usize,
    ) -> Option<Vec<Effect>> {
        let split = plate_split_path(path, plate, max_steps)?;
        let (split_bic, path_bic) = (self.final_bic(&split)?, self.final_bic(path)?);
        tracing::debug!(path = ?split.iter().map(Effect::name).collect::<Vec<_>>(), split_bic, path_bic, "diagnose: the plate named on the copies");
        (split_bic < path_bic).then_some(split)
    }

    /// The summed BIC over the bars of the copies' models with `path`'s effects added in its
    /// order (each step a refit of the copies' cache, so its exact refits on the readings start
    /// there: [`CoarseFleet::start_for`]); `None` when a bar's refit fails.
    fn final_bic(&self, path: &[Effect]) -> Option<f64> {
        let mut models = self.models.clone();
        for effect in path {
            models = self
                .series
                .par_iter()
                .zip(models.par_iter())
                .map(|(s, m)| self.refits.refit(s, m, effect).model.clone().ok())
                .collect::<Option<Vec<BarModel>>>()?;
        }
        Some(models.iter().map(|m| m.bic).sum())
    }

    /// The paths the beam search keeps on the coarse copies (the effects each adds, in order)
    /// with their total ΔBIC there, best first; and the best finished path the longer ones
    /// pushed out of the beam ([`BeamEnd`]).
    fn select(
        &self,
        max_steps: usize,
        beam: usize,
        first_candidates: &[Candidate],
        criteria: &Criteria,
    ) -> (Vec<CoarsePath>, Option<CoarsePath>) {
        let refits = &self.refits;
        let series: Vec<&BarSeries> = self.series.iter().collect();
        let cap = Refitted::BestOfFirstStep(COARSE_BEAM_REFITS);
        // The readings' first candidates are offered on the copies too: a channel whose fast
        // fluctuations the copies' bins average away ranks low on them, though its lag is
        // what the readings need first (on the machine-tool log, `lag:t4-t11` on ch3).
        let from_readings: Vec<Effect> =
            first_candidates.iter().map(|c| c.effect.clone()).collect();
        let first =
            rank_candidates_with(&series, &self.models, &from_readings, criteria, refits, cap);
        let end = beam_paths(
            &series,
            self.models.clone(),
            &first,
            (max_steps, beam, Some(COARSE_BEAM_REFITS)),
            criteria,
            refits,
        );
        let effects_and_total =
            |path: &SelectionPath| (added_effects(&path.ledger), path.delta_bic);
        (
            end.kept.iter().map(effects_and_total).collect(),
            end.pushed_out.as_ref().map(effects_and_total),
        )
    }
}

/// The coarse paths whose total ΔBIC is within [`PATH_TIE_SHARE`] of the best's and that start
/// with different effects, each confirmed on the readings ([`confirm_path`]); the one whose
/// confirmed ledger ends at the lowest BIC (its steps' exact ΔBIC summed) is kept, then led by
/// the ranking's best where the ranking prefers another first step ([`led_by_the_ranking`]).
/// A tied path that reads the plate sensor through a generic term is confirmed with the plate
/// named where the copies prefer that ([`CoarseFleet::with_the_plate_named`]); one that only
/// adds terms to a confirmed path is skipped where they raise its BIC
/// ([`adds_only_what_raises_the_bic`]); and where the lowest was cut short on the readings, the
/// finished path the beam pushed out is confirmed beside it ([`rival_of_a_cut_path`]).
///
/// Why: the coarse copies decide near ties that the readings do not. On the second simulator's
/// plate-expansion campaign (`bench/foreign_sim.py --effect plate_expansion --seed 1`, 10 bars,
/// 15 days, 10 s) the ranking on the readings puts `plate_expansion` first (ΔBIC −128 669 against
/// `air_gradient`'s −125 729) while the coarse beam prefers `air_gradient`: the coarse path alone
/// would name the wrong effect. A path's first step is usually refitted already (the ranking's exact tier), so
/// confirming a tied rival costs only its later steps.
///
/// Tied paths are confirmed in the readings' ranking of their first steps, and of the paths that
/// lead with one channel's response (`lag:CH` and `heat:CH`, [`response_family`]) only the first:
/// the readings' ranking has already compared the two transforms exactly, and their later steps
/// are the same terms. On our simulator's sensor-gradient + plate-expansion + hidden-channel
/// campaign the three tied paths led with `lag:P1-H1`, `heat:P1-H1` and `heat:T1-H1`; the first
/// two ended 0.001 % apart after 20 exact refits each.
fn confirm_tied_paths(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    first_candidates: &[Candidate],
    (paths, pushed_out, coarse, max_steps): (
        &[CoarsePath],
        Option<&CoarsePath>,
        &CoarseFleet,
        usize,
    ),
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let mut confirmed: Vec<ConfirmedPath> = Vec::new();
    let confirm = |path: &[Effect]| {
        let (ledger, models) = confirm_path(
            series,
            start.clone(),
            first_candidates,
            (path, coarse, max_steps),
            criteria,
            refits,
        );
        ConfirmedPath {
            ledger,
            models,
            coarse_steps: path.len(),
        }
    };
    let plate = plate_named_in(series, first_candidates);
    for path in tied_paths(paths, first_candidates) {
        let named = plate.and_then(|plate| coarse.with_the_plate_named(path, plate, max_steps));
        let path = named.as_deref().unwrap_or(path);
        // One path per first step, as `tied_paths` keeps: a plate-named path can lead with the
        // step of a later tied path (`heat:P1-C1` → `air_gradient` named as `heat:C1` →
        // `plate_expansion` → `air_gradient`, then `heat:C1` → `air_gradient`), and where
        // `plate_expansion` is not proposed on the readings its confirmation goes on with the
        // readings' best step instead.
        let lead = path.first().map(term_identity);
        if confirmed
            .iter()
            .any(|p| added_effects(&p.ledger).first().map(term_identity) == lead)
        {
            continue;
        }
        let adds_no_gain = |p: &ConfirmedPath| {
            adds_only_what_raises_the_bic(
                series,
                p,
                path,
                (first_candidates, coarse),
                criteria,
                refits,
            )
        };
        if confirmed.iter().any(adds_no_gain) {
            continue;
        }
        if ends_above_the_lowest(series, &start, path, &confirmed, coarse, refits) {
            continue;
        }
        confirmed.push(confirm(path));
        tracing::debug!(path = ?path.iter().map(Effect::name).collect::<Vec<_>>(), total = ?confirmed.last().map(ConfirmedPath::total), "diagnose: a tied coarse path confirmed on the readings");
    }
    let lowest_of = |confirmed: &[ConfirmedPath]| {
        (0..confirmed.len()).min_by(|&a, &b| confirmed[a].total().total_cmp(&confirmed[b].total()))
    };
    let mut lowest = lowest_of(&confirmed);
    let rival = lowest.and_then(|at| {
        let ledger = added_effects(&confirmed[at].ledger);
        rival_of_a_cut_path((&ledger, confirmed[at].coarse_steps), paths, pushed_out)
    });
    if let Some(rival) = rival {
        confirmed.push(confirm(rival));
        tracing::debug!(path = ?rival.iter().map(Effect::name).collect::<Vec<_>>(), total = ?confirmed.last().map(ConfirmedPath::total), "diagnose: the rival of a path cut short confirmed on the readings");
        lowest = lowest_of(&confirmed);
    }
    let Some(lowest) = lowest else {
        return confirm_path(
            series,
            start,
            first_candidates,
            (&[], coarse, max_steps),
            criteria,
            refits,
        );
    };
    let kept = confirmed.swap_remove(lowest);
    let (ledger, models) = led_by_the_ranking(
        series,
        start.clone(),
        (kept, confirmed),
        first_candidates,
        (coarse, max_steps),
        criteria,
        refits,
    );
    in_readings_order(
        series,
        start,
        (ledger, models),
        first_candidates,
        coarse,
        criteria,
        refits,
    )
}

/// Whether `path` adds every effect of the confirmed path `done` and others, and those others,
/// added to `done`'s final model on the readings in `path`'s order ([`confirmed_step`]), raise
/// its BIC: then [`confirm_tied_paths`] skips `path`. Its confirmed total, where each of its
/// steps is proposed, is the BIC of the same final model less the base's (`done`'s total plus
/// what the others change), so it cannot end lower than `done`, and the lowest total is kept.
/// Where the others lower the BIC, even by an immaterial amount, `path` is confirmed: on the
/// second simulator's air-gradient + plate-expansion campaign `plate_expansion` is not proposed
/// after `air_gradient`, yet `plate_expansion` → `air_gradient` ends lower.
///
/// Why: such a path costs a refit of every bar at each of its steps, most of them with no
/// coarse start on the readings. On the second simulator's settling + plate-expansion campaign
/// (`bench/loop_check.py`, k = 2, seed 2) `second_path` → `settling` → `plate_expansion` took
/// 4.0 s to confirm after `settling` → `plate_expansion`, for a total 6 418 above it; `second_path`
/// on the latter's model is one step, its start the copies' refit of the same three effects (and
/// its refits are the last step's of `path` where it is confirmed after all).
fn adds_only_what_raises_the_bic(
    series: &[&BarSeries],
    done: &ConfirmedPath,
    path: &[Effect],
    (first_candidates, coarse): (&[Candidate], &CoarseFleet),
    criteria: &Criteria,
    refits: &Refits,
) -> bool {
    let done_terms: Vec<String> = added_effects(&done.ledger)
        .iter()
        .map(term_identity)
        .collect();
    let path_terms: Vec<String> = path.iter().map(term_identity).collect();
    if done_terms.is_empty() || done_terms.iter().any(|t| !path_terms.contains(t)) {
        return false;
    }
    let others: Vec<&Effect> = path
        .iter()
        .filter(|e| !done_terms.contains(&term_identity(e)))
        .collect();
    if others.is_empty() {
        return false;
    }
    let mut current = SelectionPath {
        ledger: done.ledger.clone(),
        models: done.models.clone(),
        delta_bic: 0.0,
        finished: false,
    };
    for effect in others {
        let k = current.ledger.len() - 1;
        let candidate = confirmed_step(
            series,
            &current,
            (k, effect),
            first_candidates,
            coarse,
            criteria,
            refits,
        );
        let Some(delta_bic) = candidate.delta_bic else {
            return false;
        };
        current = extend_path(series, &current, &candidate, delta_bic, refits);
    }
    let raises = current.delta_bic >= 0.0;
    tracing::debug!(path = ?path.iter().map(Effect::name).collect::<Vec<_>>(), delta_bic = current.delta_bic, skipped = raises, "diagnose: a tied coarse path's other terms on a confirmed path's model");
    raises
}

/// Whether `path`'s final model ends above the lowest of the `confirmed` paths: its BIC, every
/// bar refitted once from the copies' fit of the same effects
/// ([`Refits::refit_at_coarse_optimum`]), less `start`'s, is what its confirmed ledger would
/// total where each of its steps is proposed on the readings, and [`confirm_tied_paths`] then
/// skips it, as it could not be kept. Asked only where a confirmed path had every coarse step
/// proposed on the readings: where the readings stop a path early, the final refit is no
/// confirmation's and costs a refit of every bar for nothing (on the loop matrix's second_path
/// + air_gradient + plate_expansion, seed 4, 4.5 CPU-s on 14-s bins).
///
/// Why: a tied path's last step's exact refits are these (the same set from the same start,
/// cached), so a path confirmed after all costs nothing more; one skipped spares its middle
/// steps. On the second simulator's settling + creep + heat-source campaign
/// (`bench/loop_check.py`, k = 3, seed 5) the tied paths lead with `heat:C1`, `heat:T2-C1` and
/// `heat:T1-C1`, each → `settling` → `creep`: the second's bound is its confirmed total to the
/// last digit, 11 653 above the first's, and its confirmation took 2.6 s.
fn ends_above_the_lowest(
    series: &[&BarSeries],
    start: &[BarModel],
    path: &[Effect],
    confirmed: &[ConfirmedPath],
    coarse: &CoarseFleet,
    refits: &Refits,
) -> bool {
    let Some(lowest) = confirmed.iter().map(ConfirmedPath::total).reduce(f64::min) else {
        return false;
    };
    if !confirmed.iter().any(ConfirmedPath::completed) {
        return false;
    }
    let Some(bound) = final_total(series, start, path, coarse, refits) else {
        return false;
    };
    tracing::debug!(path = ?path.iter().map(Effect::name).collect::<Vec<_>>(), bound, lowest, skipped = bound > lowest, "diagnose: a tied coarse path's final model against the lowest confirmed");
    bound > lowest
}

/// The BIC of `path`'s final model less `start`'s ([`ends_above_the_lowest`]), each bar refitted
/// from the copies' fit of the same effects (made there first where the beam did not:
/// [`CoarseFleet::final_bic`], cached); `None` where a refit fails on the copies or the
/// readings, or the path adds a term `start` holds.
fn final_total(
    series: &[&BarSeries],
    start: &[BarModel],
    path: &[Effect],
    coarse: &CoarseFleet,
    refits: &Refits,
) -> Option<f64> {
    let (last, before) = path.split_last()?;
    let held = effects_of(start);
    if path.iter().any(|e| holds_term(&held, e)) {
        return None;
    }
    coarse.final_bic(path)?;
    let per_bar: Option<Vec<f64>> = series
        .par_iter()
        .zip(start.par_iter())
        .map(|(s, m)| {
            let mut effects = m.effects.clone();
            effects.extend(before.iter().cloned());
            let coarse_start = coarse.start_for(&m.bar, &effects, last)?;
            effects.push(last.clone());
            let refit = refits.refit_at_coarse_optimum(s, &effects, &coarse_start);
            refit.model.as_ref().ok().map(|f| f.bic - m.bic)
        })
        .collect();
    Some(per_bar?.iter().sum())
}

/// `chosen` (a confirmed ledger and its models) with its later steps in the order the readings
/// rank them: at each step after the first, of the effects the ledger adds later, the one whose
/// exact refit lowers the BIC most ([`confirmed_step`]). The ledger ends at the same model and
/// total; only its order can change. Where a step of the walk is not proposed, the walk's
/// shorter ledger replaces `chosen` when its total is lower (the effects left out are not
/// supported after the others), else `chosen` stands.
///
/// Why the shorter ledger: on the second simulator's head-heating + settling campaign
/// (`bench/foreign_sim.py --head --effect settling --seed 22 --air linear --bars 6 --days 20
/// --sample-s 30 --temp-s 60 --files day`) the coarse paths `head_heating` → `second_path` →
/// `settling` and `head_heating` → `settling` tied within 3 of 2.8 M, and the first was kept:
/// the readings rank `settling` first after `head_heating`, and `second_path` after both is not
/// significant (ΔBIC +103), yet the ledger named it, 47.2 nm after two steps for the truth's
/// 20.1. Our simulator's settling + second path (4 bars, 8 days, 30 s, seeds 1, 2, 4 and 7)
/// put `lag:T2` or `heat:T2` between the two the same way
/// (`tests/e2e/diagnose.rs::a_step_the_readings_do_not_support_after_the_others_is_left_out`).
///
/// Why: a path's total ΔBIC does not depend on the order of its steps, so two coarse paths that
/// add the same effects tie exactly, and the coarse order between them says nothing about the
/// readings. On our simulator's plate-expansion + hidden-channel campaign the path kept read
/// `heat:P1-H1` 33.0 → `second_path` 23.8 → `plate_expansion` 20.1 nm: the hidden effect named
/// last, after a step that removes less. Cost: one exact refit a bar for each later step's
/// rivals (the ledger's own refits are cached).
fn in_readings_order(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    chosen: (Vec<LedgerStep>, Vec<BarModel>),
    first_candidates: &[Candidate],
    coarse: &CoarseFleet,
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let path = added_effects(&chosen.0);
    if path.len() < 3 {
        return chosen;
    }
    let mut current = SelectionPath::starting_at(start);
    let mut rest = path.clone();
    let mut order = Vec::with_capacity(path.len());
    for k in 0..path.len() {
        let rivals = if k == 0 { &rest[..1] } else { &rest[..] };
        let best = rivals
            .iter()
            .map(|e| {
                confirmed_step(
                    series,
                    &current,
                    (k, e),
                    first_candidates,
                    coarse,
                    criteria,
                    refits,
                )
            })
            .filter(Candidate::proposed)
            .min_by(|a, b| {
                let bic = |c: &Candidate| c.delta_bic.unwrap_or(0.0);
                bic(a).total_cmp(&bic(b))
            });
        let Some(best) = best else {
            return lower_of(chosen, current);
        };
        rest.retain(|e| *e != best.effect);
        order.push(best.effect.clone());
        // What is left is forced; in the chosen order it is the chosen ledger's own step.
        if rest.len() <= 1 && path.starts_with(&order) {
            return chosen;
        }
        let score = best.delta_bic.unwrap_or(0.0);
        current = extend_path(series, &current, &best, score, refits);
    }
    if order == path {
        return chosen;
    }
    tracing::debug!(path = ?order.iter().map(Effect::name).collect::<Vec<_>>(), "diagnose: the chosen ledger in the readings' order");
    (current.ledger, current.models)
}

/// `chosen`, or the shorter ledger of `walk` (which stopped where the readings propose none of
/// `chosen`'s remaining effects) where its total is lower.
fn lower_of(
    chosen: (Vec<LedgerStep>, Vec<BarModel>),
    walk: SelectionPath,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let (walked, total) = (ledger_total(&walk.ledger), ledger_total(&chosen.0));
    let shorter = walk.ledger.len() < chosen.0.len() && walked < total;
    tracing::debug!(
        walk = ?added_effects(&walk.ledger).iter().map(Effect::name).collect::<Vec<_>>(),
        walked,
        total,
        shorter,
        "diagnose: the readings' order stopped short of the chosen ledger"
    );
    if shorter {
        (walk.ledger, walk.models)
    } else {
        chosen
    }
}

/// The effects `ledger` adds, in its order.
fn added_effects(ledger: &[LedgerStep]) -> Vec<Effect> {
    ledger
        .iter()
        .filter_map(|step| match &step.added {
            Added::Effect(e) => Some(e.clone()),
            Added::Base => None,
        })
        .collect()
}

/// A coarse path confirmed on the readings: its ledger and models, and how many steps the
/// coarse path had (the ledger has fewer where a step was not proposed on the readings).
struct ConfirmedPath {
    ledger: Vec<LedgerStep>,
    models: Vec<BarModel>,
    coarse_steps: usize,
}

impl ConfirmedPath {
    /// The sum of its steps' exact ΔBIC.
    fn total(&self) -> f64 {
        ledger_total(&self.ledger)
    }

    /// Whether the readings proposed every step of its coarse path.
    fn completed(&self) -> bool {
        added_effects(&self.ledger).len() == self.coarse_steps
    }

    /// Whether its ledger's first step adds nothing or a term of `identity` ([`term_identity`]).
    fn leads_with_nothing_or(&self, identity: &str) -> bool {
        added_effects(&self.ledger)
            .first()
            .is_none_or(|e| term_identity(e) == identity)
    }
}

/// Where the lowest confirmed path was cut short on the readings (`ledger`, the effects it
/// added, fewer than the `coarse_steps` of its coarse path): the best finished coarse path the
/// beam pushed out (`pushed_out`, [`BeamEnd`]) when it is no longer than that ledger, within
/// [`PATH_TIE_SHARE`] of the best coarse total (`paths`, best first) and not the ledger's own
/// effects.
///
/// Why: the beam ranks paths by their totals on the copies, so a path whose third step adds a
/// little there pushes out a two-step path that stops; on the readings that third step can fail,
/// and the ledger is then the two-step prefix of a path the copies did not prefer over the
/// pushed-out one. On the second simulator's head-heating + plate-expansion campaign
/// (`bench/loop_check.py`, k = 2, seed 6) the beam kept `head_heating` → `air_gradient` →
/// `settling` (total −7 429 793 on the copies) over the finished `head_heating` →
/// `plate_expansion` (−7 421 327), though the copies rank `plate_expansion` first after
/// `head_heating`; `settling` was not proposed on the readings, and the ledger read
/// `head_heating` → `air_gradient` (20.11 nm) where the truth's two terms fit to 20.06 nm.
fn rival_of_a_cut_path<'a>(
    (steps, coarse_steps): (&[Effect], usize),
    paths: &[CoarsePath],
    pushed_out: Option<&'a CoarsePath>,
) -> Option<&'a [Effect]> {
    let (rival, total) = pushed_out?;
    let best_total = paths.first().map_or(0.0, |(_, total)| *total);
    let cut = steps.len() < coarse_steps;
    let tied = (total - best_total).abs() <= PATH_TIE_SHARE * best_total.abs();
    let same = |a: &[Effect], b: &[Effect]| {
        let set = |p: &[Effect]| {
            let mut ids: Vec<String> = p.iter().map(term_identity).collect();
            ids.sort();
            ids
        };
        set(a) == set(b)
    };
    (cut && tied && rival.len() <= steps.len() && !same(rival, steps)).then_some(rival.as_slice())
}

/// Whether `effects` hold the term `effect` adds, under any of its names ([`term_identity`]).
fn holds_term(effects: &[Effect], effect: &Effect) -> bool {
    effects
        .iter()
        .any(|e| term_identity(e) == term_identity(effect))
}

/// The sum of a ledger's steps' ΔBIC: its final model's BIC less the base's.
fn ledger_total(ledger: &[LedgerStep]) -> f64 {
    ledger.iter().filter_map(|step| step.delta_bic).sum()
}

/// The coarse paths [`confirm_tied_paths`] confirms, in the order it confirms them: within
/// [`PATH_TIE_SHARE`] of the best total, one per first step (the coarse best of those that share
/// it), ordered by the readings' rank of that first step (the coarse order between equals), and
/// one per [`response_family`] of the first step.
///
/// One per first step: the first step names the effect the ledger leads with, and its exact
/// refits are the ranking's already; paths that part later are aliases at a later step (on the
/// three-effect campaign of our simulator, `air_gradient`, `heat:T2-T1` and `heat:T2` as the
/// third step, within 0.01 % of each other on the readings), whose confirmation cost 9 s for no
/// change.
fn tied_paths<'a>(paths: &'a [CoarsePath], first_candidates: &[Candidate]) -> Vec<&'a [Effect]> {
    let best_total = paths.first().map_or(0.0, |(_, total)| *total);
    let rank = |e: Option<&Effect>| {
        e.and_then(|e| {
            first_candidates
                .iter()
                .position(|c| term_identity(&c.effect) == term_identity(e))
        })
        .unwrap_or(usize::MAX)
    };
    let mut tied: Vec<&[Effect]> = Vec::new();
    for (path, total) in paths {
        let within = (total - best_total).abs() <= PATH_TIE_SHARE * best_total.abs();
        if within && tied.iter().all(|p| p.first() != path.first()) {
            tied.push(path);
        }
    }
    // A stable sort: between first steps the ranking did not see, the coarse order stays.
    tied.sort_by_key(|p| rank(p.first()));
    let mut families: Vec<Option<String>> = Vec::new();
    tied.retain(|p| {
        let family = p.first().map(response_family);
        let new = !families.contains(&family);
        families.push(family);
        new
    });
    tied
}

/// `kept`, the lowest of the confirmed tied paths (the earlier between equals), led by
/// the ranking's best proposed candidate where it leads with another: that candidate's own
/// confirmed path when there is one, else that candidate first, then the ledger's other effects
/// in their order (without the candidate's [`response_family`]), confirmed on the readings. The
/// ledger led by the ranking's best is kept when its total is lower than the best's or higher by
/// at most [`LEDGER_TIE_BIC`] ([`keeps_reordered`]); otherwise the best stands (and the page says why the two differ).
/// The reordered ledger can also stop earlier: on the second simulator's air-gradient campaign
/// (seed 3) `air_gradient` alone (ΔBIC −179 021) beat the coarse path `second_path` →
/// `air_gradient` (−143 375), `second_path` not significant after it.
///
/// Why: the coarse beam ranks whole paths, so its first step can be a term that comes first
/// only on the copies. On the second simulator's creep campaign (`bench/loop_check.py`, k = 1,
/// seed 2) the readings rank `creep` first (ΔBIC −904 795 against `second_path`'s −891 332),
/// while the coarse path's ledger reads `second_path` → `creep`: the same two terms, the hidden
/// effect named second.
fn led_by_the_ranking(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    (kept, others): (ConfirmedPath, Vec<ConfirmedPath>),
    first_candidates: &[Candidate],
    (coarse, max_steps): (&CoarseFleet, usize),
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let Some(best) = first_candidates.iter().find(|c| c.proposed()) else {
        return (kept.ledger, kept.models);
    };
    let best_identity = term_identity(&best.effect);
    // A ledger led by the ranking's best with the plate split off it
    // ([`CoarseFleet::with_the_plate_named`]) is led by the ranking's best.
    let best_named = plate_named_in(series, first_candidates)
        .and_then(|plate| without_sensor(&best.effect, plate).flatten())
        .map(|rest| term_identity(&rest));
    let led_by_best = |p: &ConfirmedPath| {
        p.leads_with_nothing_or(&best_identity)
            || best_named
                .as_ref()
                .is_some_and(|rest| p.leads_with_nothing_or(rest))
    };
    if led_by_best(&kept) {
        return (kept.ledger, kept.models);
    }
    // A confirmed rival led by the plate-named form of the best is the ledger led by the best
    // too. On the second simulator's plate-expansion + heat-source campaign
    // (`bench/loop_check.py`, k = 2, seed 3) the ranking's `heat:P1-C1` had been confirmed as
    // `heat:C1` → `plate_expansion`; building `heat:P1-C1` → `heat:T1-C1` instead cost 4.8 s of
    // exact refits (the second step is not proposed after the first, so the readings' whole
    // ranking ran) for a total 867 above the kept ledger's.
    let led = others
        .into_iter()
        .find(|p| !added_effects(&p.ledger).is_empty() && led_by_best(p));
    let (reordered, reordered_models, reordered_total) = match led {
        Some(p) => {
            let total = p.total();
            (p.ledger, p.models, total)
        }
        None => {
            let path = ranking_led_path(&best.effect, &kept.ledger, &air_references(series));
            if ends_above_the_kept(series, &start, &path, &kept, coarse, refits) {
                return (kept.ledger, kept.models);
            }
            let (ledger, models) = confirm_path(
                series,
                start,
                first_candidates,
                (&path, coarse, max_steps),
                criteria,
                refits,
            );
            let total = ledger_total(&ledger);
            tracing::debug!(path = ?path.iter().map(Effect::name).collect::<Vec<_>>(), total, "diagnose: the ledger led by the ranking's best, confirmed");
            (ledger, models, total)
        }
    };
    tracing::debug!(
        reordered_total,
        total = kept.total(),
        "diagnose: the ledger led by the ranking's best against the lowest"
    );
    if keeps_reordered(reordered_total, kept.total()) {
        (reordered, reordered_models)
    } else {
        (kept.ledger, kept.models)
    }
}

/// `best` first, then the effects `ledger` added in their order, except those that read the
/// same source as `best` ([`source_family`], with `air` the campaign's air sensors: `lag:C1`
/// and `heat:T1-C1` for `heat:C1`); as many steps as the ledger has (at least one).
///
/// Why the source and not only the channel's [`response_family`]: where the ledger leads with
/// the ranking's best referred to another air sensor, the path led by the best replaces that
/// term; it does not add the same source twice. On the second simulator's air-gradient +
/// settling + heat-source campaign (`bench/loop_check.py`, k = 3, seed 7) the ledger
/// `heat:T1-C1` → `settling` → `air_gradient` was led by `heat:C1` as `heat:C1` → `heat:T1-C1`
/// → `settling`, whose second step the readings do not propose.
fn ranking_led_path(best: &Effect, ledger: &[LedgerStep], air: &[String]) -> Vec<Effect> {
    let added = added_effects(ledger);
    let source = source_family(best, air);
    std::iter::once(best.clone())
        .chain(
            added
                .iter()
                .filter(|e| source_family(e, air) != source)
                .cloned(),
        )
        .take(added.len().max(1))
        .collect()
}

/// Whether the final model of `path` (the ledger led by the ranking's best,
/// [`ranking_led_path`]) ends above what `kept` totals by more than [`LEDGER_TIE_BIC`]: its
/// BIC less `start`'s ([`final_total`], every bar refitted once from the copies' fit of the
/// same effects) is what its confirmed ledger would total where
/// each of its steps is proposed, so [`keeps_reordered`] could not keep it. Asked only where
/// `kept` had every coarse step proposed on the readings, as [`ends_above_the_lowest`] is.
///
/// Why: where the ledger leads with the ranking's best referred to another air sensor (the
/// beam lets one reference go on, [`beam_paths`]), the path led by the best has no refits on
/// the readings beyond its first step, and its confirmation ranks the readings' candidates at
/// each step. On the second simulator's air-gradient + settling + heat-source campaign
/// (`bench/loop_check.py`, k = 3, seed 7) `heat:C1` → `settling` → `air_gradient` ends 115
/// above `heat:T1-C1` → `settling` → `air_gradient`.
fn ends_above_the_kept(
    series: &[&BarSeries],
    start: &[BarModel],
    path: &[Effect],
    kept: &ConfirmedPath,
    coarse: &CoarseFleet,
    refits: &Refits,
) -> bool {
    if !kept.completed() {
        return false;
    }
    let Some(bound) = final_total(series, start, path, coarse, refits) else {
        return false;
    };
    let above = !keeps_reordered(bound, kept.total());
    tracing::debug!(path = ?path.iter().map(Effect::name).collect::<Vec<_>>(), bound, kept = kept.total(), skipped = above, "diagnose: the final model led by the ranking's best against the kept");
    above
}

/// Whether a ledger led by the ranking's best, of total ΔBIC `reordered_total`, replaces the
/// confirmed ledger of total `total`: when it is lower, or higher by at most
/// [`LEDGER_TIE_BIC`] (a tie the ranking decides).
///
/// Why an absolute margin: both totals are the BIC of a final model less the base's on the same
/// readings, so their difference is the evidence between the two models. A share of the total
/// (the coarse paths' tie, [`PATH_TIE_SHARE`]) grows with the campaign: on the second
/// simulator's creep + heat-source campaign (`bench/loop_check.py`, k = 2, seed 1) 5 % of
/// −2 857 165 let `heat:C1` → `second_path` (−2 855 021) replace `heat:T1-C1` → `creep`, the
/// hidden effect, against a BIC difference of 2 144.
fn keeps_reordered(reordered_total: f64, total: f64) -> bool {
    reordered_total <= total + LEDGER_TIE_BIC
}

/// Two ledgers confirmed on the same readings whose totals differ by at most this much BIC are a
/// tie: 10, where Kass & Raftery's scale of evidence turns "very strong".
const LEDGER_TIE_BIC: f64 = 10.0;

/// The ledger of `path` (found on the coarse copies) on the bars' own series: each step's
/// effect refitted exactly on every bar and tested as a candidate is ([`evaluate_candidates`](super::evaluate_candidates):
/// significant and material); the ledger stops at the first step that is not proposed there.
/// The first step's exact refits and tests are those of the ranking (`first_candidates`).
fn confirm_path(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    first_candidates: &[Candidate],
    (path, coarse, max_steps): (&[Effect], &CoarseFleet, usize),
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let mut current = SelectionPath::starting_at(start);
    let mut stopped = false;
    for (k, effect) in path.iter().enumerate() {
        let in_model = holds_term(&effects_of(&current.models), effect);
        let candidate = if in_model {
            None
        } else {
            Some(confirmed_step(
                series,
                &current,
                (k, effect),
                first_candidates,
                coarse,
                criteria,
                refits,
            ))
        };
        let candidate = match candidate.filter(Candidate::proposed) {
            Some(c) => c,
            None => {
                match best_exact_step(series, &current, k, first_candidates, criteria, refits) {
                    Some(c) => c,
                    None => {
                        stopped = true;
                        break;
                    }
                }
            }
        };
        let score = candidate.delta_bic.unwrap_or(0.0);
        current = extend_path(series, &current, &candidate, score, refits);
    }
    // A short fleet's path that ended early on the copies goes on with the readings' best.
    let samples: usize = series.iter().map(|s| s.fit_index.len()).sum();
    while !stopped && samples < EXACT_CONTINUATION_MAX_SAMPLES && current.ledger.len() <= max_steps
    {
        let k = current.ledger.len() - 1;
        match best_exact_step(series, &current, k, first_candidates, criteria, refits) {
            Some(candidate) => {
                let score = candidate.delta_bic.unwrap_or(0.0);
                current = extend_path(series, &current, &candidate, score, refits);
            }
            None => stopped = true,
        }
    }
    (current.ledger, current.models)
}

/// Below this many fitted samples in all (the fleet's or a bar's own selection), a coarse path
/// that ends before `forward_steps` is continued on the readings ([`best_exact_step`]): its
/// exact refits cost little there (about 50 ms each on the machine-tool log's 11 k-sample bars),
/// and the copies' smoothed noise can stop a path the readings would extend (on that log a
/// bar's own selection stopped after one step where the readings offered two more). Above it
/// (10 bars × 15 days × 10 s is 1.3 M) an exact step would cost more than the whole search.
const EXACT_CONTINUATION_MAX_SAMPLES: usize = 100_000;

/// Step `k` of a coarse path, `effect`, refitted and tested on the readings (the ranking's
/// exact refit when the first step is one of its).
fn confirmed_step(
    series: &[&BarSeries],
    current: &SelectionPath,
    (k, effect): (usize, &Effect),
    first_candidates: &[Candidate],
    coarse: &CoarseFleet,
    criteria: &Criteria,
    refits: &Refits,
) -> Candidate {
    let ranked = first_candidates
        .iter()
        .find(|c| k == 0 && c.effect == *effect && c.rms_after_um.is_some())
        .cloned();
    ranked.unwrap_or_else(|| {
        let starts: Vec<Option<BarModel>> = current
            .models
            .iter()
            .map(|m| coarse.start_for(&m.bar, &m.effects, effect))
            .collect();
        let tested = exact_candidate(series, &current.models, effect, &starts, criteria, refits);
        tracing::debug!(step = k, effect = %effect, reason = ?tested.reason, "diagnose: a coarse path's step tested on the readings");
        tested
    })
}

/// Where a coarse path's step is not proposed on the readings: the best candidate that is,
/// ranked on the readings as the first step is (the ranking itself there); `None` when none is,
/// and the ledger stops.
///
/// Why: the coarse copies smooth the readings' noise, so a term chosen there can fail the
/// readings' likelihood-ratio test (it lowers the RMS but leaves a less predictable residual:
/// `compare::lr_p_value`). Stopping there left a bar of the machine-tool log with no step at
/// all where its readings offered several.
fn best_exact_step(
    series: &[&BarSeries],
    current: &SelectionPath,
    k: usize,
    first_candidates: &[Candidate],
    criteria: &Criteria,
    refits: &Refits,
) -> Option<Candidate> {
    let ranked = if k == 0 {
        first_candidates.to_vec()
    } else {
        rank_candidates_with(
            series,
            &current.models,
            &[],
            criteria,
            refits,
            Refitted::All,
        )
    };
    let best = ranked.into_iter().find(Candidate::proposed);
    tracing::debug!(step = k, replaced_by = ?best.as_ref().map(|c| c.effect.name()), "diagnose: a coarse path's step is not proposed on the readings");
    best
}

/// `effect` added to every bar's model in `models`, refitted exactly and tested: the candidate
/// as [`evaluate_candidates`](super::evaluate_candidates) would report it after an exact refit.
fn exact_candidate(
    series: &[&BarSeries],
    models: &[BarModel],
    effect: &Effect,
    starts: &[Option<BarModel>],
    criteria: &Criteria,
    refits: &Refits,
) -> Candidate {
    let pairs: Vec<(&BarSeries, &BarModel)> = series.iter().copied().zip(models.iter()).collect();
    let bases = screen_bases(&pairs);
    // Tested as one of a step's candidates (Bonferroni over as many as a step offers): the
    // effect was chosen on the coarse copies of these same readings.
    let threshold =
        criteria.alpha / (CATALOGUE.len() + CHANNEL_CANDIDATES + HEAT_CANDIDATES) as f64;
    refitted_candidate(&pairs, &bases, effect, starts, threshold, criteria, refits)
}

/// The beam search of [`forward_selection`] on the series it is given: the best path's ledger
/// and models ([`beam_paths`]).
fn beam_search(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    first_candidates: &[Candidate],
    limits: (usize, usize, Option<usize>),
    criteria: &Criteria,
    refits: &Refits,
) -> (Vec<LedgerStep>, Vec<BarModel>) {
    let best = beam_paths(series, start, first_candidates, limits, criteria, refits)
        .kept
        .into_iter()
        .next()
        .expect("forward selection keeps at least one path");
    (best.ledger, best.models)
}

/// The paths the beam search keeps at its end, best (lowest total ΔBIC) first: at most
/// `max_steps` steps keeping `beam` paths, each step refitting at most `max_refits` candidates
/// (all that pass the screen when `None`).
fn beam_paths(
    series: &[&BarSeries],
    start: Vec<BarModel>,
    first_candidates: &[Candidate],
    (max_steps, beam, max_refits): (usize, usize, Option<usize>),
    criteria: &Criteria,
    refits: &Refits,
) -> BeamEnd {
    let beam = beam.max(1);
    let air = air_references(series);
    let mut paths = vec![SelectionPath::starting_at(start)];
    let mut pushed_out: Option<SelectionPath> = None;
    for step in 0..max_steps {
        let mut next: Vec<SelectionPath> = paths.iter().filter(|p| p.finished).cloned().collect();
        let mut extensions: Vec<(usize, Candidate, f64)> = Vec::new();
        for (i, path) in paths.iter().enumerate().filter(|(_, p)| !p.finished) {
            let candidates = if step == 0 {
                first_candidates.to_vec()
            } else {
                let refitted = max_refits.map_or(Refitted::All, |most| {
                    Refitted::Best(last_step_refits(most, beam, step + 1 == max_steps))
                });
                rank_candidates_with(series, &path.models, &[], criteria, refits, refitted)
            };
            let proposed: Vec<Candidate> =
                candidates.into_iter().filter(Candidate::proposed).collect();
            if proposed.is_empty() {
                let mut done = path.clone();
                done.finished = true;
                next.push(done);
            }
            let kept = beam_extensions(proposed, beam, criteria);
            extensions.extend(kept.into_iter().map(|(c, d)| (i, c, d)));
        }
        if extensions.is_empty() {
            paths = next;
            break;
        }
        // A stable sort: between equal totals the ranking's order (a named effect first) stays.
        extensions.sort_by(|(i, _, a), (j, _, b)| {
            (paths[*i].delta_bic + a).total_cmp(&(paths[*j].delta_bic + b))
        });
        let set_of = |i: usize, c: &Candidate, identity: &dyn Fn(&Effect) -> String| {
            let mut set: Vec<String> = effects_of(&paths[i].models)
                .iter()
                .chain([&c.effect])
                .map(identity)
                .collect();
            set.sort();
            set
        };
        let mut seen: std::collections::BTreeSet<Vec<String>> = Default::default();
        let mut families: std::collections::BTreeSet<Vec<String>> = Default::default();
        let mut agreeing: std::collections::BTreeSet<(Vec<String>, String)> = Default::default();
        let last_step = step + 1 == max_steps;
        // The best `beam` extensions of distinct models; of those that differ only by a
        // channel's transform (`lag:CH` against `heat:CH`, [`response_family`]) the better one
        // alone. The beam then holds fewer paths rather than another alias: on our simulator's
        // three-effect campaign (sensor gradient, plate expansion, hidden channel) its three
        // first paths were `heat:P1-H1`, `lag:P1-H1` and `heat:T1-H1`, each ranked again at the
        // next step on every bar.
        //
        // Likewise, before the last step, of paths that read one heat source referred to
        // different air sensors ([`source_family`]: `heat:C1`, `heat:T1-C1`) and add the same
        // effect at this step, the better alone goes on: they agree on what comes next, and
        // each would be extended and confirmed again. Where they add different effects (the
        // reference decides the later step: on the second simulator's creep + heat-source
        // campaign `second_path` follows `heat:C1`, `creep` follows `heat:T1-C1`) all go on,
        // and at the last step the readings decide between references (`confirm_tied_paths`).
        // On the settling + creep + heat-source campaign (`bench/loop_check.py`, k = 3, seed 5)
        // the three references' paths each added `settling` at the second step, and each was
        // extended and two of them confirmed: the night took 34.3 s, with one path 22.9 s.
        let source = |e: &Effect| source_family(e, &air);
        let chosen: Vec<(usize, Candidate, f64)> = extensions
            .into_iter()
            .filter(|(i, c, _)| seen.insert(set_of(*i, c, &term_identity)))
            .take(beam)
            .filter(|(i, c, _)| families.insert(set_of(*i, c, &response_family)))
            .filter(|(i, c, _)| {
                last_step || agreeing.insert((set_of(*i, c, &source), term_identity(&c.effect)))
            })
            .collect();
        let extended: Vec<SelectionPath> = chosen
            .into_par_iter()
            .map(|(i, c, score)| extend_path(series, &paths[i], &c, score, refits))
            .collect();
        next.extend(extended);
        next.sort_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
        let kept = beam.min(next.len()).min(within_reach_of_the_best(&next));
        for dropped in next.drain(kept..) {
            if dropped.finished
                && pushed_out
                    .as_ref()
                    .is_none_or(|p| dropped.delta_bic < p.delta_bic)
            {
                pushed_out = Some(dropped);
            }
        }
        for path in &next {
            tracing::trace!(step, path = ?added_effects(&path.ledger).iter().map(Effect::name).collect::<Vec<_>>(), total = path.delta_bic, finished = path.finished, "diagnose: the beam after a step");
        }
        paths = next;
    }
    // A stable sort: between equal totals the earlier path (the ranking's order) stays first.
    paths.sort_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
    BeamEnd {
        kept: paths,
        pushed_out,
    }
}

/// How many of `paths` (sorted, best first) the beam goes on with: those whose total ΔBIC is
/// at least [`BEAM_SHARE_OF_BEST`] of the best's (the best always; all where the best gains
/// nothing).
fn within_reach_of_the_best(paths: &[SelectionPath]) -> usize {
    let Some(best) = paths.first().map(|p| p.delta_bic).filter(|b| *b < 0.0) else {
        return paths.len();
    };
    paths
        .iter()
        .position(|p| p.delta_bic > BEAM_SHARE_OF_BEST * best)
        .unwrap_or(paths.len())
        .max(1)
}

/// A beam path whose total ΔBIC is less than this share of the best path's after the same step
/// (in size: both are negative, gains) is dropped: the best path's effects already explain
/// twice what it does, and its later steps would have to make up the difference.
///
/// Why: each kept path is extended (its candidates refitted on every bar's copy) and may be
/// confirmed on the readings. Over the second simulator's 27 matrix campaigns
/// (`bench/loop_check.py`, k = 1-3, seeds 1-9) every ledger kept began with a first-step path
/// at 63 % or more of the best's ΔBIC, and no path below half the best's ever led; on k = 3,
/// seed 8 the beam's `lag:length_mm` (26 %) and `creep` (8 %) paths cost about 4 s of the
/// night's 25 and changed nothing. Checked, with the same ledgers, on `bench/loop.sh` and
/// `bench/foreign_check.py` (`bench/README.md`).
const BEAM_SHARE_OF_BEST: f64 = 0.5;

/// A path's best `beam` proposed candidates (`proposed`, in the ranking's order) with the ΔBIC
/// each competes with ([`competing_delta_bic`], among the first candidates up to the last one
/// kept), less those an earlier one stands in for ([`stood_in_for`]): the next candidates
/// take their places.
fn beam_extensions(
    proposed: Vec<Candidate>,
    beam: usize,
    criteria: &Criteria,
) -> Vec<(Candidate, f64)> {
    let mut window = beam.min(proposed.len());
    loop {
        let competing = competing_delta_bic(&proposed[..window], criteria);
        let stood_in = stood_in_for(&proposed[..window], &competing);
        let kept = stood_in.iter().filter(|s| !**s).count();
        if kept >= beam || window == proposed.len() {
            return proposed
                .into_iter()
                .zip(competing)
                .zip(stood_in)
                .filter(|(_, stood_in)| !stood_in)
                .map(|(kept, _)| kept)
                .collect();
        }
        window = (window + beam - kept).min(proposed.len());
    }
}

/// How many of a step's candidates a capped beam refits (`most`, [`COARSE_BEAM_REFITS`]): at
/// the last step no more than the `beam` extensions each path can keep.
///
/// Why: an earlier step refits twice the beam so that the paths kept are the best of more
/// rivals, whose later steps are then ranked again; after the last step nothing is ranked
/// again, and its refits carry the most time constants of the search. On the second
/// simulator's settling + creep + heat-source campaign (`bench/loop_check.py`, k = 3, seed 5)
/// the last step's 210 refits on the copies took 17.1 of the run's 48 CPU-s.
fn last_step_refits(most: usize, beam: usize, last_step: bool) -> usize {
    if last_step {
        most.min(beam)
    } else {
        most
    }
}

/// What [`beam_paths`] ends with: the paths it keeps, best (lowest total ΔBIC) first, and the
/// best of the finished paths (no candidate proposed after their last step) that paths with
/// more steps pushed out of the beam.
///
/// Why keep that one: a kept path's later steps can fail on the readings, and the ledger then
/// ends shorter than the path whose total put it ahead ([`rival_of_a_cut_path`]).
struct BeamEnd {
    kept: Vec<SelectionPath>,
    pushed_out: Option<SelectionPath>,
}

/// The effects of a fleet's models (one model for all bars).
pub(super) fn effects_of(models: &[BarModel]) -> Vec<Effect> {
    models
        .first()
        .map(|m| m.effects.clone())
        .unwrap_or_default()
}

/// The candidates for the fleet's current `models`, ranked best first (only those that could be
/// material refitted exactly).
fn rank_candidates_with(
    series: &[&BarSeries],
    models: &[BarModel],
    offered: &[Effect],
    criteria: &Criteria,
    refits: &Refits,
    refitted: Refitted,
) -> Vec<Candidate> {
    let effects = effects_of(models);
    let pairs: Vec<(&BarSeries, &BarModel)> = series.iter().copied().zip(models.iter()).collect();
    let bases = screen_bases(&pairs);
    let diagnoses: Vec<BarDiagnosis> = pairs
        .par_iter()
        .zip(bases.par_iter())
        .map(|((s, m), b)| diagnose_bar(s, m, b.as_ref()))
        .collect();
    let mut candidates = candidate_effects(&effects, &diagnoses);
    let mut taken: std::collections::BTreeSet<String> = effects
        .iter()
        .chain(&candidates)
        .map(term_identity)
        .collect();
    candidates.extend(
        offered
            .iter()
            .filter(|e| taken.insert(term_identity(e)))
            .cloned(),
    );
    evaluate_at_most(&pairs, &bases, &candidates, criteria, refits, refitted).0
}

/// `path` with `candidate` added and every bar refitted; `score` is what the step adds to the
/// path's total (its ΔBIC, or the one it competes with: [`competing_delta_bic`]).
fn extend_path(
    series: &[&BarSeries],
    path: &SelectionPath,
    candidate: &Candidate,
    score: f64,
    refits: &Refits,
) -> SelectionPath {
    let effect = &candidate.effect;
    // A bar whose extended fit fails keeps its model (it is reported as not improved). The
    // refits are those the candidate's evaluation made.
    let models: Vec<BarModel> = series
        .par_iter()
        .zip(path.models.par_iter())
        .map(|(s, m)| {
            refits
                .refit(s, m, effect)
                .model
                .clone()
                .unwrap_or_else(|_| m.clone())
        })
        .collect();
    let mut ledger = path.ledger.clone();
    // The effects in the order the path added them (a refit shared with another order keeps
    // that order's: `Refits`).
    let mut effects = ledger.last().map(|s| s.effects.clone()).unwrap_or_default();
    effects.push(effect.clone());
    ledger.push(ledger_step(
        Added::Effect(effect.clone()),
        effects,
        &models,
        candidate.delta_bic,
        candidate.p_value,
    ));
    SelectionPath {
        ledger,
        models,
        delta_bic: path.delta_bic + score,
        finished: false,
    }
}

#[cfg(test)]
mod tests {
    use super::beam_extensions;
    use super::keeps_reordered;
    use super::ranking_led_path;
    use super::response_family;
    use super::rival_of_a_cut_path;
    use super::source_family;
    use super::within_reach_of_the_best;
    use super::SelectionPath;
    use super::{Added, LedgerStep};
    use crate::diagnose::compare::tests::proposed;
    use crate::diagnose::plate::tests::effects;
    use crate::diagnose::Criteria;
    use crate::model::Effect;

    #[test]
    fn a_path_cut_short_on_the_readings_meets_the_finished_path_the_beam_pushed_out() {
        // The second simulator's head-heating + plate-expansion campaign (k = 2, seed 6): the
        // copies' totals, the readings' ledger cut after two of the three steps.
        let paths = vec![
            (
                effects(&["head_heating", "air_gradient", "settling"]),
                -7_429_793.4,
            ),
            (
                effects(&["head_heating", "air_gradient", "second_path"]),
                -7_423_572.5,
            ),
        ];
        let pushed_out = (effects(&["head_heating", "plate_expansion"]), -7_421_327.2);
        let cut = effects(&["head_heating", "air_gradient"]);
        assert_eq!(
            rival_of_a_cut_path((&cut, 3), &paths, Some(&pushed_out)),
            Some(pushed_out.0.as_slice())
        );
        // Not cut: the ledger went as far as its coarse path.
        let whole = effects(&["head_heating", "air_gradient", "settling"]);
        assert_eq!(
            rival_of_a_cut_path((&whole, 3), &paths, Some(&pushed_out)),
            None
        );
        // Longer than the ledger, or its own effects in another order: no rival.
        let one = effects(&["head_heating"]);
        assert_eq!(
            rival_of_a_cut_path((&one, 3), &paths, Some(&pushed_out)),
            None
        );
        let same = (effects(&["air_gradient", "head_heating"]), -7_421_327.2);
        assert_eq!(rival_of_a_cut_path((&cut, 3), &paths, Some(&same)), None);
        // Outside the tie share of the best coarse total.
        let far = (effects(&["head_heating", "plate_expansion"]), -6_000_000.0);
        assert_eq!(rival_of_a_cut_path((&cut, 3), &paths, Some(&far)), None);
        assert_eq!(rival_of_a_cut_path((&cut, 3), &paths, None), None);
    }

    #[test]
    fn the_beam_goes_on_with_the_paths_within_half_of_the_best_total() {
        let paths = |totals: &[f64]| -> Vec<SelectionPath> {
            totals
                .iter()
                .map(|&delta_bic| SelectionPath {
                    ledger: Vec::new(),
                    models: Vec::new(),
                    delta_bic,
                    finished: false,
                })
                .collect()
        };
        // The matrix's first steps (`bench/loop_check.py`): k = 3, seed 8 (`settling`, then
        // `lag:length_mm` at 26 % and `creep` at 8 % of it); k = 1, seed 8 (`second_path`,
        // then `air_gradient` at 63 %: the path whose ledger was kept).
        assert_eq!(within_reach_of_the_best(&paths(&[-1e6, -2.6e5, -8e4])), 1);
        assert_eq!(within_reach_of_the_best(&paths(&[-1e6, -6.3e5])), 2);
        // Exactly half stays; just below half goes.
        assert_eq!(within_reach_of_the_best(&paths(&[-1000.0, -500.0])), 2);
        assert_eq!(within_reach_of_the_best(&paths(&[-1000.0, -499.0])), 1);
        // The best always; every path where the best gains nothing (a finished base path).
        assert_eq!(within_reach_of_the_best(&paths(&[-10.0, 50.0])), 1);
        assert_eq!(within_reach_of_the_best(&paths(&[0.0, 0.0, 3.0])), 3);
        assert_eq!(within_reach_of_the_best(&[]), 0);
    }

    #[test]
    fn a_channels_lag_and_heat_are_one_family_and_nothing_else_joins_them() {
        let family = |name: &str| response_family(&Effect::parse(name).expect("an effect name"));
        assert_eq!(family("lag:P1-H1"), family("heat:P1-H1"));
        assert_eq!(family("lag:P1-H1@3600"), family("heat:P1-H1"));
        assert_ne!(family("heat:P1-H1"), family("heat:T1-H1"));
        assert_ne!(family("heat:P1"), family("rate:P1@600"));
        assert_ne!(family("heat:T2-T1"), family("air_gradient"));
        assert_eq!(family("head_heating"), family("lag:event:head_power"));
    }

    #[test]
    fn one_source_referred_to_any_air_sensor_is_one_family_and_nothing_else_joins_it() {
        let air = ["T1".to_string(), "T2".to_string()];
        let family =
            |name: &str| source_family(&Effect::parse(name).expect("an effect name"), &air);
        assert_eq!(family("heat:C1"), "source:C1");
        for alias in ["heat:T1-C1", "heat:C1-T2", "lag:T2-C1", "lag:C1@3600"] {
            assert_eq!(family(alias), family("heat:C1"), "{alias}");
        }
        // A difference of two air sensors, of two other sensors, an air sensor alone, an
        // event and a catalogue effect: each its own channel's family.
        assert_eq!(
            family("heat:T2-T1"),
            response_family(&effects(&["heat:T2-T1"])[0])
        );
        assert_ne!(family("heat:C1-P1"), family("heat:C1"));
        assert_ne!(family("heat:T1"), family("heat:T2"));
        assert_ne!(family("lag:event:head_power"), family("heat:C1"));
        assert_eq!(family("air_gradient"), "air_gradient");
        // Without air sensors nothing is referred to them.
        let none = source_family(&effects(&["heat:T1-C1"])[0], &[]);
        assert_ne!(none, family("heat:C1"));
    }

    #[test]
    fn the_ledger_led_by_the_ranking_replaces_the_source_it_leads_with() {
        let air = ["T1".to_string(), "T2".to_string()];
        let ledger: Vec<LedgerStep> = std::iter::once(Added::Base)
            .chain(
                effects(&["heat:T1-C1", "settling", "air_gradient"])
                    .into_iter()
                    .map(Added::Effect),
            )
            .map(|added| LedgerStep {
                added,
                effects: Vec::new(),
                rms_um: Vec::new(),
                fleet_rms_um: 0.02,
                delta_bic: None,
                p_value: None,
            })
            .collect();
        let led = |best: &str| {
            ranking_led_path(&effects(&[best])[0], &ledger, &air)
                .iter()
                .map(Effect::name)
                .collect::<Vec<_>>()
        };
        // The second simulator's air-gradient + settling + heat-source campaign (k = 3, seed 7).
        assert_eq!(led("heat:C1"), ["heat:C1", "settling", "air_gradient"]);
        assert_eq!(led("lag:T2-C1"), ["lag:T2-C1", "settling", "air_gradient"]);
        // Another effect first: the ledger's own, cut to its length.
        assert_eq!(led("creep"), ["creep", "heat:T1-C1", "settling"]);
        assert_eq!(
            led("air_gradient"),
            ["air_gradient", "heat:T1-C1", "settling"]
        );
    }

    #[test]
    fn the_ranking_led_ledger_is_kept_when_lower_or_tied_not_when_worse() {
        // Lower: the second simulator's air-gradient campaign (seed 3), `air_gradient` alone
        // against the coarse path `second_path` → `air_gradient`.
        assert!(keeps_reordered(-179_021.2, -143_375.9));
        // The same effects in another order: equal totals but for the refits' rounding.
        assert!(keeps_reordered(-143_370.0, -143_375.9));
        // Worse by more than the tie: the creep + heat-source campaign (k = 2, seed 1), where
        // the ranking-led `heat:C1` → `second_path` would replace `heat:T1-C1` → `creep`.
        assert!(!keeps_reordered(-2_855_020.6, -2_857_164.9));
        assert!(!keeps_reordered(-140_000.0, -143_375.9));
    }

    #[test]
    fn a_candidate_stood_in_for_gives_its_place_in_the_beam_to_the_next() {
        // 20 nm noise at a ±1 µm tolerance: equally good within 5 nm of fleet RMS.
        let criteria = Criteria::new(0.020, 1.0);
        // Each case: the proposed candidates (name, fleet RMS after, ΔBIC), in ranking order,
        // and the beam's three extensions (name, the ΔBIC it competes with).
        let check = |ranked: &[(&str, f64, f64)], kept: &[(&str, f64)]| {
            let ranked = ranked
                .iter()
                .map(|&(n, rms, d)| proposed(n, rms, d))
                .collect();
            let got: Vec<(String, f64)> = beam_extensions(ranked, 3, &criteria)
                .iter()
                .map(|(c, d)| (c.effect.name(), *d))
                .collect();
            let want: Vec<(String, f64)> = kept.iter().map(|&(n, d)| (n.to_string(), d)).collect();
            assert_eq!(got, want);
        };
        // 10 nm apart: none stands in for another, the first three keep their own ΔBIC.
        check(
            &[
                ("creep", 0.030, -900.0),
                ("settling", 0.040, -800.0),
                ("second_path", 0.050, -700.0),
                ("air_gradient", 0.060, -600.0),
            ],
            &[
                ("creep", -900.0),
                ("settling", -800.0),
                ("second_path", -700.0),
            ],
        );
        // `second_path` takes `lag:T2`'s ΔBIC and stands in for it: `air_gradient` fills the
        // third place.
        check(
            &[
                ("second_path", 0.0225, -1000.0),
                ("lag:T2", 0.0224, -1200.0),
                ("creep", 0.0325, -700.0),
                ("air_gradient", 0.0425, -600.0),
            ],
            &[
                ("second_path", -1200.0),
                ("creep", -700.0),
                ("air_gradient", -600.0),
            ],
        );
    }
}
