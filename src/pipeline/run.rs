//! The order of the stages: [`analyse`] runs those the plan names on already-read logs, each
//! as one call of its entry point in core (`identify::identify_fleet`, `matching::match_fleet`,
//! `diagnose::diagnose_fleet`, `calibrate::calibrate_fleet`, `compensate::compensate_fleet`,
//! `acceptance::accept_fleet`) with its options from the plan. No analysis rule lives here.

use crate::acceptance::AcceptanceOptions;
use crate::compensate::CompensateOptions;
use crate::diagnose::DiagnoseOptions;
use crate::identify::{FleetLogs, FleetReadings, IdentifyOptions};
use crate::matching::{MatchOptions, AIR_HISTORY_STEP_S};
use crate::series::CampaignLogs;

use super::*;

pub(crate) use dbbcal_core::stage::timed;

/// Run the analysis stages on already-read logs (no output written).
pub fn analyse(plan: &RunPlan, logs: CampaignLogs) -> RunResults {
    let mut results = identify_stage(plan, logs);
    run_later_stages(plan, &mut results);
    results
}

/// The stages up to identify on already-read logs: what [`analyse`] has before the later
/// stages ([`run_later_stages`]), which the runner may skip when it reads the campaign again
/// with shorter bins.
pub fn identify_stage(plan: &RunPlan, logs: CampaignLogs) -> RunResults {
    let t0_ns = crate::series::campaign_origin_ns(&logs);
    let CampaignLogs {
        campaign,
        inputs,
        bars,
        bins,
        sensors,
        events,
        quality,
    } = logs;
    let history = crate::matching::air_history(&campaign, &sensors, t0_ns, AIR_HISTORY_STEP_S);
    if !plan.runs(Stage::Identify) {
        let mut results =
            RunResults::before_stages(campaign, inputs, history, Vec::new(), Vec::new());
        results.quality = quality;
        return results;
    }
    let fleet = FleetLogs {
        campaign: &campaign,
        events: &events,
        sensors: &sensors,
        quality: &quality,
        t0_ns,
    };
    let progress = crate::progress::bar(bars.len() as u64, "identify");
    let identified = timed("identify", || {
        crate::identify::identify_fleet(
            fleet,
            FleetReadings { bars, bins },
            &identify_options(plan),
            &|| progress.inc(1),
        )
    });
    progress.finish_and_clear();
    let mut results =
        RunResults::before_stages(campaign, inputs, history, identified.ok, identified.failed);
    results.quality = quality;
    results.device_sensors = super::device::sensor_logs(&results.campaign, &sensors);
    results
}

/// The stages past identify, in order, each filling its part of `results` (none when the plan
/// does not identify).
pub fn run_later_stages(plan: &RunPlan, results: &mut RunResults) {
    if !plan.runs(Stage::Identify) {
        return;
    }
    if plan.runs(Stage::Match) {
        let options = match_options(plan);
        let matched = crate::matching::match_fleet(
            &results.bars,
            &results.campaign,
            &results.history,
            &options,
        );
        if let Some(m) = matched {
            results.reference = Some(m.reference);
            results.study = m.study;
        }
    }
    if plan.effects != crate::model::base_effects() {
        results.before_after = Some(crate::identify::compare_with_base(&results.bars));
    }
    if plan.runs(Stage::Diagnose) {
        let progress = crate::progress::bar(results.bars.len() as u64, "diagnose");
        let diagnosis = timed("diagnose", || {
            crate::diagnose::diagnose_fleet(&results.bars, &diagnose_options(plan), &|| {
                progress.inc(1)
            })
        });
        progress.finish_and_clear();
        results.diagnosis = Some(diagnosis);
    }
    if plan.runs(Stage::Calibrate) {
        results.calibration = Some(crate::calibrate::calibrate_fleet(
            &results.bars,
            &results.campaign,
        ));
    }
    if plan.runs(Stage::Compensate) {
        results.compensation = Some(crate::compensate::compensate_fleet(
            &results.bars,
            &results.campaign,
            ok_or_empty(&results.calibration),
            results.reference.as_ref().map(|r| &r.choice),
            &compensate_options(plan),
        ));
    }
    if plan.runs(Stage::Acceptance) {
        results.acceptance = Some(crate::acceptance::accept_fleet(
            ok_or_empty(&results.compensation),
            ok_or_empty(&results.calibration),
            &results.campaign,
            &acceptance_options(plan),
        ));
    }
}

/// A stage's processed bars, none when it did not run.
fn ok_or_empty<T>(stage: &Option<StageOutcome<T>>) -> &[T] {
    stage.as_ref().map(|s| s.ok.as_slice()).unwrap_or_default()
}

/// Identify's options: the model, the bins, and whether later stages read the samples.
fn identify_options(plan: &RunPlan) -> IdentifyOptions {
    // Every stage past identify reads the bars' samples, and so does the before/after
    // comparison of an extended model; a plain identify run keeps only the models and counts,
    // so it never holds the campaign's series at full rate.
    let keep_samples = plan.effects != crate::model::base_effects()
        || [
            Stage::Match,
            Stage::MatchStudy,
            Stage::Diagnose,
            Stage::Calibrate,
            Stage::Compensate,
            Stage::Acceptance,
            Stage::Report,
        ]
        .into_iter()
        .any(|s| plan.runs(s));
    IdentifyOptions {
        effects: plan.effects.clone(),
        bin_s: plan.bin_s,
        keep_samples,
    }
}

/// `[match]`; the study only when the plan runs `match_study`.
fn match_options(plan: &RunPlan) -> MatchOptions {
    MatchOptions {
        limit_um: plan.matching.limit_um,
        at_length: plan.matching.at_length.clone(),
        study_step_s: plan
            .runs(Stage::MatchStudy)
            .then_some(plan.matching.study_step_s),
    }
}

/// `[diagnose]`; its tolerance defaults to the matching limit.
fn diagnose_options(plan: &RunPlan) -> DiagnoseOptions {
    DiagnoseOptions {
        effects: plan.effects.clone(),
        tolerance_um: plan.diagnose.tolerance_um.unwrap_or(plan.matching.limit_um),
        forward_steps: plan.diagnose.forward_steps,
        beam: plan.diagnose.beam,
    }
}

/// `[acceptance]`'s compensation settings.
fn compensate_options(plan: &RunPlan) -> CompensateOptions {
    CompensateOptions {
        model_difference: plan.acceptance.model_difference,
        max_gap_s: plan.acceptance.max_gap_s,
    }
}

/// `[acceptance]`'s tolerance and temperature uncertainty.
fn acceptance_options(plan: &RunPlan) -> AcceptanceOptions {
    AcceptanceOptions {
        tolerance_um: plan.acceptance.tolerance_um,
        u_temperature_k: plan.acceptance.u_temperature_k,
    }
}
