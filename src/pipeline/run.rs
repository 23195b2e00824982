//! The order of the stages: [`analyse`] runs those the plan names on already-read logs.

use rayon::prelude::*;

use crate::identify::identify;
use crate::series::{BarSeries, CampaignLogs, FleetContext};

use super::stages::*;
use super::*;

/// Run `f` and log how long it took (`DBBCAL_LOG=info`): stage timings go to the log, never
/// into the byte-identical outputs.
pub(crate) fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let start = std::time::Instant::now();
    let out = f();
    tracing::info!("{what}: {:.3} s", start.elapsed().as_secs_f64());
    out
}

/// Run the analysis stages on already-read logs (no output written).
pub fn analyse(plan: &RunPlan, logs: CampaignLogs) -> RunResults {
    let CampaignLogs {
        campaign,
        inputs,
        bars,
        mut bins,
        sensors,
        events,
        quality,
    } = logs;
    let t0 = campaign
        .mounts
        .iter()
        .map(|m| m.from_ns)
        .min()
        .unwrap_or_else(|| campaign_origin_from(&bars, &bins));
    let history = air_history(&campaign, &sensors, t0, 60.0);
    if !plan.runs(Stage::Identify) {
        let mut results =
            RunResults::before_stages(campaign, inputs, history, Vec::new(), Vec::new());
        results.quality = quality;
        return results;
    }
    // Every stage past identify reads the bars' samples, and so does the before/after
    // comparison of an extended model; a plain identify run keeps only the models and counts,
    // so it never holds the campaign's series at full rate.
    let samples_needed = plan.effects != crate::model::base_effects()
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
    let progress = crate::progress::bar(bars.len() as u64, "identify");
    // A compressed series samples the sensors at most twice a bin (`series::knot_logs`); the
    // full-rate logs stay for the air history and the device's sensors.
    let knot_sensors = crate::series::knot_logs(&sensors, plan.bin_s);
    let knots = crate::series::sensor_knots(&knot_sensors);
    let fleet = FleetContext {
        campaign: &campaign,
        events: &events,
        sensors: &knot_sensors,
        knots: &knots,
        t0_ns: t0,
    };
    let outcomes: Vec<(String, Result<BarOutcome, String>)> = timed("identify", || {
        bars.into_iter()
            .map(|(id, log)| {
                let binned = bins.remove(&id);
                (id, log, binned)
            })
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(id, log, binned)| {
                // A bar ingest found no usable signal in (a dead encoder) fails alone.
                if let Some(why) = quality.unusable(&id) {
                    progress.inc(1);
                    return (id, Err(why.to_string()));
                }
                let series = match binned {
                    Some(b) => BarSeries::from_bins(&fleet, &id, &b),
                    None => BarSeries::build_binned(&fleet, &id, log, plan.bin_s),
                };
                let r = series.map_err(|e| e.to_string()).and_then(|series| {
                    let model = identify(&series, &plan.effects).map_err(|e| e.to_string())?;
                    let series = if samples_needed {
                        series
                    } else {
                        series.without_samples()
                    };
                    Ok(BarOutcome { series, model })
                });
                progress.inc(1);
                (id, r)
            })
            .collect()
    });
    progress.finish_and_clear();
    let identified = StageOutcome::from_results(outcomes);
    for f in &identified.failed {
        tracing::info!("{}", f.error); // in failed_bars and the final line
    }
    let mut results =
        RunResults::before_stages(campaign, inputs, history, identified.ok, identified.failed);
    results.quality = quality;
    results.device_sensors = super::device::sensor_logs(&results.campaign, &sensors);
    if plan.runs(Stage::Match) {
        run_match(plan, &mut results);
    }
    if plan.effects != crate::model::base_effects() {
        results.before_after = Some(before_after(&results.bars));
    }
    if plan.runs(Stage::Diagnose) {
        results.diagnosis = Some(timed("diagnose", || run_diagnose(plan, &results.bars)));
    }
    if plan.runs(Stage::Calibrate) {
        results.calibration = Some(run_calibrate(&results));
    }
    if plan.runs(Stage::Compensate) {
        results.compensation = Some(run_compensate(plan, &results));
    }
    if plan.runs(Stage::Acceptance) {
        results.acceptance = Some(run_acceptance(plan, &results));
    }
    results
}
