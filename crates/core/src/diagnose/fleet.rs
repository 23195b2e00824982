//! The diagnose stage over a fleet ([`diagnose_fleet`]): its nine steps in order, each timed in
//! the log (`DBBCAL_LOG=info`).

use rayon::prelude::*;

use crate::identify::{BarModel, BarOutcome, Estimate};
use crate::model::Effect;
use crate::series::BarSeries;
use crate::stage::timed;

use super::sensors::{sensor_profiles, SensorProfile};
use super::{
    bar_ledger_from_fleet, candidate_effects, diagnose_bar, evaluate_candidates, forward_selection,
    forward_selection_of_bar, needs_own_selection, screen_bases, with_the_ledgers_first_step,
    Added, BarDiagnosis, BarLedger, Candidate, Criteria, LedgerStep, Refits, Search, Unavailable,
};

/// How the fleet is diagnosed.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// The model's effects (the candidates are the catalogue's others, and channel terms).
    pub effects: Vec<Effect>,
    /// Tolerance the bars serve, µm ([`Criteria`]'s materiality threshold).
    pub tolerance_um: f64,
    /// Forward selection adds at most this many effects (0: rank candidates only).
    pub forward_steps: usize,
    /// Forward selection keeps this many best paths at each step (1: plain greedy).
    pub beam: usize,
}

/// The diagnose stage's result.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// Per bar: where its model fails (residual statistics, channels).
    pub bars: Vec<BarDiagnosis>,
    /// What each temperature sensor plausibly measures (profiled on the first bar's timeline).
    pub sensors: Vec<SensorProfile>,
    /// When a candidate is proposed (noise floor, tolerance, materiality threshold).
    pub criteria: Criteria,
    /// The candidate effects, best first, each with its verdict and the numbers behind it.
    pub candidates: Vec<Candidate>,
    /// Candidates no bar could fit (e.g. `head_heating` without `head_power` events), with the
    /// first bar's reason.
    pub unavailable: Vec<Unavailable>,
    /// The fleet-wide forward selection: RMS as effects are added.
    pub ledger: Vec<LedgerStep>,
    /// Each bar's own forward selection, same order as `bars`.
    pub bar_ledgers: Vec<BarLedger>,
    /// The time constants the fleet ledger's last model adds to each bar's identified model
    /// (none when the ledger added nothing).
    pub ledger_time_constants: Vec<LedgerTimeConstant>,
}

/// A time constant that the model the fleet ledger ends on adds to a bar's identified model, as
/// the ledger's refit estimates it (a Wald interval): a report checks it against the bins the
/// diagnosis ran on, which were chosen for the identified model's time constants only.
#[derive(Debug, Clone)]
pub struct LedgerTimeConstant {
    /// The bar.
    pub bar: String,
    /// The time constant (`tau_…_s`, seconds), its uncertainty and interval.
    pub estimate: Estimate,
}

/// The time constants of `fleet_models` (the ledger's last model of each bar) that the bar's
/// identified model does not hold; none when the ledger added nothing.
fn ledger_time_constants(
    bars: &[BarOutcome],
    ledger: &[LedgerStep],
    fleet_models: &[BarModel],
) -> Vec<LedgerTimeConstant> {
    if ledger.len() < 2 {
        return Vec::new();
    }
    bars.iter()
        .zip(fleet_models)
        .flat_map(|(o, m)| {
            m.params
                .iter()
                .filter(|p| p.name.starts_with("tau") && o.model.param(&p.name).is_none())
                .map(|p| LedgerTimeConstant {
                    bar: m.bar.clone(),
                    estimate: p.clone(),
                })
        })
        .collect()
}

/// Diagnose the fleet's identified bars: linearise each model, rank every bar's channels (in
/// parallel; `on_bar_done` is called once per bar, a progress bar), set the noise floor and the
/// criteria, screen and refit the candidate effects, profile the sensors, run forward
/// selection fleet-wide, and per bar where the fleet's model leaves a bar short
/// (`needs_own_selection`).
pub fn diagnose_fleet(
    bars: &[BarOutcome],
    options: &DiagnoseOptions,
    on_bar_done: &(dyn Fn() + Sync),
) -> Diagnosis {
    let pairs: Vec<(&BarSeries, &BarModel)> = bars.iter().map(|o| (&o.series, &o.model)).collect();
    let bases = timed("diagnose: linearise", || screen_bases(&pairs));
    let diagnoses: Vec<BarDiagnosis> = timed("diagnose: channels", || {
        pairs
            .par_iter()
            .zip(bases.par_iter())
            .map(|((s, m), b)| {
                let d = diagnose_bar(s, m, b.as_ref());
                on_bar_done();
                d
            })
            .collect()
    });
    let criteria = timed("diagnose: noise floor", || {
        Criteria::for_fleet(&bases, options.tolerance_um)
    });
    let refits = Refits::default();
    let (candidates, unavailable) = timed("diagnose: candidates", || {
        evaluate_candidates(
            &pairs,
            &bases,
            &candidate_effects(&options.effects, &diagnoses),
            &criteria,
            &refits,
        )
    });
    // Sensors are the campaign's: profile them on the first bar's timeline.
    let sensors = bars
        .first()
        .map(|o| sensor_profiles(&o.series))
        .unwrap_or_default();
    let series: Vec<&BarSeries> = bars.iter().map(|o| &o.series).collect();
    let models: Vec<BarModel> = bars.iter().map(|o| o.model.clone()).collect();
    let (ledger, fleet_models) = timed("diagnose: fleet forward selection", || {
        forward_selection(
            &series,
            models,
            &candidates,
            options.forward_steps,
            options.beam,
            &criteria,
            &refits,
        )
    });
    let first_step = ledger.get(1).and_then(|step| match &step.added {
        Added::Effect(e) => Some(e),
        Added::Base => None,
    });
    let offered = candidates.len() + unavailable.len();
    let candidates = with_the_ledgers_first_step(
        &pairs,
        &bases,
        (candidates, offered),
        first_step,
        &criteria,
        &refits,
    );
    let search = Search {
        max_steps: options.forward_steps,
        beam: options.beam,
    };
    let bar_ledgers = timed("diagnose: per-bar forward selection", || {
        bars.par_iter()
            .zip(&bases)
            .zip(&diagnoses)
            .zip(&fleet_models)
            .map(|(((o, b), d), fleet_model)| {
                if !needs_own_selection(fleet_model, b.as_ref(), &criteria) {
                    return bar_ledger_from_fleet(&o.model.bar, &ledger);
                }
                forward_selection_of_bar(
                    &o.series,
                    o.model.clone(),
                    b,
                    d,
                    search,
                    &criteria,
                    &refits,
                )
            })
            .collect()
    });
    let ledger_time_constants = ledger_time_constants(bars, &ledger, &fleet_models);
    Diagnosis {
        bars: diagnoses,
        sensors,
        criteria,
        candidates,
        unavailable,
        ledger,
        bar_ledgers,
        ledger_time_constants,
    }
}
