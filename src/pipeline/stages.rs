//! One thin adapter per stage: it takes the results so far, calls the stage's own module
//! (`calibrate`, `compensate`, `acceptance`, `matching`, `diagnose`) and returns its part of
//! [`RunResults`].
//!
//! # How it works
//!
//! - Nothing is allocated by time span: matching's air history (`pipeline::stages::air_history`) is
//!   a 60-s grid only where the air sensors log; across a stretch of more than 6 h without a reading
//!   it holds the two readings around it (the lag follows a straight line exactly), so a reading
//!   dated decades away costs two points; bins are at least 1 s (`pipeline::plan::MIN_BIN_S`).

use std::collections::BTreeMap;

use rayon::prelude::*;

use crate::campaign::{Campaign, Place};
use crate::diagnose::{self, BarDiagnosis};
use crate::identify::{identify_from, BarModel};
use crate::matching::{self, MatchInput, TemperatureHistory};
use crate::model::Effect;
use crate::series::BarSeries;
use dbbcal_core::signal::interpolate;

use super::*;

/// Calibrate every identified bar (a bar that cannot be calibrated is listed, the others go on).
pub(super) fn run_calibrate(r: &RunResults) -> CalibrationStage {
    let outcomes: Vec<(String, Result<crate::calibrate::BarCalibration, String>)> = r
        .bars
        .par_iter()
        .map(|o| {
            let calibrated = crate::calibrate::calibrate_bar(&o.series, &o.model, &r.campaign);
            (o.model.bar.clone(), calibrated.map_err(|e| e.to_string()))
        })
        .collect();
    logged(StageOutcome::from_results(outcomes))
}

/// `outcome`, its failures logged as warnings (they are also in the stage's JSON).
fn logged<T>(outcome: StageOutcome<T>) -> StageOutcome<T> {
    for f in &outcome.failed {
        tracing::warn!("{}", f.error);
    }
    outcome
}

/// Compensate every working mount (check lengths and devices).
pub(super) fn run_compensate(plan: &RunPlan, r: &RunResults) -> CompensationStage {
    let cals = r
        .calibration
        .as_ref()
        .map(|c| c.ok.as_slice())
        .unwrap_or_default();
    let bars: Vec<crate::compensate::CompBar> = r
        .bars
        .iter()
        .map(|o| crate::compensate::CompBar {
            series: &o.series,
            model: &o.model,
            calibration: cals.iter().find(|c| c.bar == o.model.bar),
        })
        .collect();
    let fleet_distance: BTreeMap<String, f64> = r
        .reference
        .as_ref()
        .map(|rr| rr.choice.distance.iter().cloned().collect())
        .unwrap_or_default();
    let options = crate::compensate::CompensateOptions {
        model_difference: plan.acceptance.model_difference,
        max_gap_s: plan.acceptance.max_gap_s,
    };
    let outcomes = crate::compensate::compensate(&bars, &r.campaign, &fleet_distance, &options)
        .into_iter()
        .map(|w| match w {
            Ok(w) => (w.bar.clone(), Ok(w)),
            Err(e) => (e.bar().to_string(), Err(e.to_string())),
        });
    logged(StageOutcome::from_results(outcomes))
}

/// Accept every compensated working series on a known length.
pub(super) fn run_acceptance(
    plan: &RunPlan,
    r: &RunResults,
) -> Vec<crate::acceptance::BarAcceptance> {
    let (Some(cal), Some(comp)) = (&r.calibration, &r.compensation) else {
        return Vec::new();
    };
    let options = crate::acceptance::AcceptanceOptions {
        tolerance_um: plan.acceptance.tolerance_um,
        u_temperature_k: plan.acceptance.u_temperature_k,
    };
    comp.ok
        .iter()
        .filter_map(|w| {
            let c = cal.ok.iter().find(|c| c.bar == w.bar)?;
            let resolution_nm = r.campaign.bar(&w.bar).map_or(0.0, |b| b.resolution_nm);
            crate::acceptance::accept(w, c, resolution_nm, &options)
        })
        .collect()
}

pub(super) fn campaign_origin_from(
    bars: &BTreeMap<String, crate::series::BarLog>,
    bins: &BTreeMap<String, crate::series::BarBins>,
) -> i64 {
    bars.values()
        .filter_map(|l| l.time_ns.first().copied())
        .chain(
            bins.values()
                .filter_map(crate::series::BarBins::first_reading_ns),
        )
        .min()
        .unwrap_or(0)
}

/// Mean air temperature minus the reference, on a regular grid (each sensor interpolated).
pub(super) fn air_history(
    campaign: &Campaign,
    sensors: &BTreeMap<String, crate::series::SensorLog>,
    t0_ns: i64,
    step_s: f64,
) -> TemperatureHistory {
    let logs: Vec<&crate::series::SensorLog> = campaign
        .air_sensors()
        .filter_map(|s| sensors.get(&s.id))
        .filter(|l| !l.time_ns.is_empty())
        .collect();
    let to_s = |ns: i64| (ns - t0_ns) as f64 * 1e-9;
    let start = logs
        .iter()
        .map(|l| to_s(l.time_ns[0]))
        .fold(f64::INFINITY, f64::min);
    let end = logs
        .iter()
        .map(|l| to_s(*l.time_ns.last().unwrap_or(&0)))
        .fold(f64::NEG_INFINITY, f64::max);
    if logs.is_empty() || end.partial_cmp(&start) != Some(std::cmp::Ordering::Greater) {
        return TemperatureHistory {
            t_s: vec![],
            delta_c: vec![],
        };
    }
    let t_s = history_times(&logs, to_s, start, end, step_s);
    let mut sum = vec![0.0; t_s.len()];
    for l in &logs {
        let ts: Vec<f64> = l.time_ns.iter().map(|&t| to_s(t)).collect();
        let at_history = interpolate::linear_ascending(&ts, &l.celsius, &t_s);
        for (s, v) in sum.iter_mut().zip(at_history) {
            *s += v;
        }
    }
    let k = logs.len() as f64;
    TemperatureHistory {
        t_s,
        delta_c: sum
            .into_iter()
            .map(|s| s / k - campaign.reference_temperature_c)
            .collect(),
    }
}

/// The longest stretch without an air reading that the history fills with its regular grid, s;
/// a longer one (a logger down for days, a reading dated decades away) gets only its two ends:
/// the air is a straight line between them, which the lag follows exactly, so no grid point there
/// carries anything, and the grid's size follows the readings, not the time span.
pub(super) const HISTORY_MAX_FILLED_GAP_S: f64 = 6.0 * 3600.0;

/// The history's times: `start + i step_s` up to `end`, but inside a stretch of more than
/// [`HISTORY_MAX_FILLED_GAP_S`] without a reading only the readings on either side. At most
/// `HISTORY_MAX_FILLED_GAP_S / step_s + 2` points a reading.
fn history_times(
    logs: &[&crate::series::SensorLog],
    to_s: impl Fn(i64) -> f64,
    start: f64,
    end: f64,
    step_s: f64,
) -> Vec<f64> {
    let mut knots: Vec<f64> = logs
        .iter()
        .flat_map(|l| l.time_ns.iter().map(|&t| to_s(t)))
        .collect();
    knots.sort_by(f64::total_cmp);
    knots.dedup();
    let n = ((end - start) / step_s).floor() as usize + 1;
    let grid = |i: usize| start + i as f64 * step_s;
    let mut t_s: Vec<f64> = Vec::new();
    let mut i = 0usize;
    let push = |t_s: &mut Vec<f64>, t: f64| {
        if t_s.last().is_none_or(|&last| t > last) {
            t_s.push(t);
        }
    };
    for w in knots.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b - a <= HISTORY_MAX_FILLED_GAP_S {
            continue;
        }
        while i < n && grid(i) <= a {
            push(&mut t_s, grid(i));
            i += 1;
        }
        push(&mut t_s, a);
        push(&mut t_s, b);
        // The grid resumes at its first point after `b`.
        let resume = ((b - start) / step_s).floor() as usize + 1;
        i = i.max(resume);
    }
    while i < n {
        push(&mut t_s, grid(i));
        i += 1;
    }
    t_s
}

/// What matching needs of an identified bar: `None` when its model lacks `alpha` or `tau_R`;
/// `beta` and `tau_S` are NaN when its data cannot determine them (one length,
/// `crate::model::identifiable_effects`). See [`matched_inputs`] for who is matched.
pub fn match_input(o: &BarOutcome) -> Option<MatchInput> {
    let p = |name: &str| o.model.value(name);
    let q = |name: &str| p(name).unwrap_or(f64::NAN);
    let params = [
        p(matching::MATCH_PARAMS[0])?,
        q(matching::MATCH_PARAMS[1]),
        p(matching::MATCH_PARAMS[2])?,
        q(matching::MATCH_PARAMS[3]),
    ];
    let (t_s, measured_um) = o
        .series
        .fit_index
        .iter()
        .map(|&i| {
            let zero = o.series.zero_segment[i].map_or(0.0, |s| o.model.zeros_um[s as usize]);
            (o.series.t_s[i], o.series.y_um[i] - zero)
        })
        .unzip();
    Some(MatchInput {
        bar: o.model.bar.clone(),
        fixed_length_mm: o.series.bar.fixed_length_mm,
        params,
        t_s,
        measured_um,
    })
}

/// The bars matched: those with all four base parameters; when no bar has them all (a
/// one-length campaign, where `beta` cannot be identified), every bar on `alpha` and `tau_R`
/// (each bar's predicted error is then the one at its own length). A bar lacking `beta` in a
/// fleet where others have it is left out: its `alpha` describes the whole bar at its one length
/// and is not comparable with theirs.
pub fn matched_inputs(bars: &[BarOutcome]) -> Vec<MatchInput> {
    let inputs: Vec<MatchInput> = bars.iter().filter_map(match_input).collect();
    let complete = |m: &MatchInput| m.params.iter().all(|v| v.is_finite());
    if inputs.iter().any(complete) {
        inputs.into_iter().filter(complete).collect()
    } else {
        inputs
    }
}

pub(super) fn run_match(plan: &RunPlan, results: &mut RunResults) {
    let inputs = matched_inputs(&results.bars);
    let Some(choice) = matching::choose_reference(&inputs) else {
        return;
    };
    let distance_mm = comparison_distance(&results.campaign, plan.matching.at_length.as_deref());
    let mismatches = matching::predicted_mismatch(
        &inputs,
        &choice.bar,
        &results.history,
        distance_mm,
        plan.matching.limit_um,
    );
    if plan.runs(Stage::MatchStudy) {
        results.study =
            matching::measured_mismatch_matrix(&inputs, &choice.bar, plan.matching.study_step_s);
    }
    results.reference = Some(ReferenceReport {
        choice,
        distance_mm,
        limit_um: plan.matching.limit_um,
        mismatches,
    });
}

/// The centre distance at which bars are compared: the named plate length, else the middle one.
pub(super) fn comparison_distance(campaign: &Campaign, at_length: Option<&str>) -> f64 {
    let mut lengths: Vec<f64> = campaign.plate.lengths.iter().map(|l| l.mm).collect();
    if let Some(l) = at_length.and_then(|id| campaign.plate.lengths.iter().find(|l| l.id == id)) {
        return l.mm;
    }
    lengths.sort_by(f64::total_cmp);
    lengths.get(lengths.len() / 2).copied().unwrap_or_else(|| {
        campaign
            .mounts
            .iter()
            .find_map(|m| match &m.place {
                Place::Length(l) => Some(l.mm),
                Place::Device(_) => None,
            })
            .unwrap_or(0.0)
    })
}

/// Refit each bar with the base model to show what the added effects bought.
pub(super) fn before_after(bars: &[BarOutcome]) -> BeforeAfter {
    let base = crate::model::base_effects();
    let rows: Vec<BarBeforeAfter> = bars
        .par_iter()
        .filter_map(|o| {
            // Values only: the trial-fit form, without the profile intervals of `identify`.
            let before = identify_from(&o.series, &base, None).ok()?;
            let pick = |m: &BarModel| {
                m.params
                    .iter()
                    .filter(|p| matching::MATCH_PARAMS.contains(&p.name.as_str()))
                    .map(|p| (p.name.clone(), p.value))
                    .collect()
            };
            Some(BarBeforeAfter {
                bar: o.model.bar.clone(),
                rms_before_um: before.rms_um,
                rms_after_um: o.model.rms_um,
                params_before: pick(&before),
                params_after: pick(&o.model),
            })
        })
        .collect();
    let fleet = |f: &dyn Fn(&BarBeforeAfter) -> f64| {
        (rows.iter().map(|r| f(r).powi(2)).sum::<f64>() / rows.len().max(1) as f64).sqrt()
    };
    BeforeAfter {
        before_effects: base.iter().map(Effect::name).collect(),
        after_effects: bars
            .first()
            .map(|o| o.model.effect_names())
            .unwrap_or_default(),
        fleet_rms_before_um: fleet(&|r| r.rms_before_um),
        fleet_rms_after_um: fleet(&|r| r.rms_after_um),
        bars: rows,
    }
}

/// Diagnose every bar, rank the candidate effects, run forward selection.
pub(super) fn run_diagnose(plan: &RunPlan, bars: &[BarOutcome]) -> Diagnosis {
    let pairs: Vec<(&BarSeries, &BarModel)> = bars.iter().map(|o| (&o.series, &o.model)).collect();
    let bases = timed("diagnose: linearise", || diagnose::screen_bases(&pairs));
    let progress = crate::progress::bar(bars.len() as u64, "diagnose");
    let diagnoses: Vec<BarDiagnosis> = timed("diagnose: channels", || {
        pairs
            .par_iter()
            .zip(bases.par_iter())
            .map(|((s, m), b)| {
                let d = diagnose::diagnose_bar(s, m, b.as_ref());
                progress.inc(1);
                d
            })
            .collect()
    });
    progress.finish_and_clear();
    let tolerance_um = plan.diagnose.tolerance_um.unwrap_or(plan.matching.limit_um);
    let criteria = timed("diagnose: noise floor", || {
        diagnose::Criteria::for_fleet(&bases, tolerance_um)
    });
    let refits = diagnose::Refits::default();
    let (mut candidates, unavailable) = timed("diagnose: candidates", || {
        diagnose::evaluate_candidates(
            &pairs,
            &bases,
            &diagnose::candidate_effects(&plan.effects, &diagnoses),
            &criteria,
            &refits,
        )
    });
    // Sensors are the campaign's: profile them on the first bar's timeline.
    let sensors = bars
        .first()
        .map(|o| diagnose::sensors::sensor_profiles(&o.series))
        .unwrap_or_default();
    diagnose::explain_candidates(&mut candidates, &sensors);
    let series: Vec<&BarSeries> = bars.iter().map(|o| &o.series).collect();
    let models: Vec<BarModel> = bars.iter().map(|o| o.model.clone()).collect();
    let (ledger, fleet_models) = timed("diagnose: fleet forward selection", || {
        diagnose::forward_selection(
            &series,
            models,
            &candidates,
            plan.diagnose.forward_steps,
            plan.diagnose.beam,
            &criteria,
            &refits,
        )
    });
    let bar_ledgers = timed("diagnose: per-bar forward selection", || {
        bars.par_iter()
            .zip(&bases)
            .zip(&diagnoses)
            .zip(&fleet_models)
            .map(|(((o, b), d), fleet_model)| {
                if !diagnose::needs_own_selection(fleet_model, b.as_ref(), &criteria) {
                    return diagnose::bar_ledger_from_fleet(&o.model.bar, &ledger);
                }
                diagnose::forward_selection_of_bar(
                    &o.series,
                    o.model.clone(),
                    b,
                    d,
                    diagnose::Search {
                        max_steps: plan.diagnose.forward_steps,
                        beam: plan.diagnose.beam,
                    },
                    &criteria,
                    &refits,
                )
            })
            .collect()
    });
    Diagnosis {
        bars: diagnoses,
        sensors,
        criteria,
        candidates,
        unavailable,
        ledger,
        bar_ledgers,
    }
}
