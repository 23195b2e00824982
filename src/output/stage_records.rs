//! `calibration.json`, `compensation.json` and `acceptance.json`: what the calibrate, compensate
//! and acceptance stages produced (their bars' records: `calibration.rs`, `compensation.rs`,
//! `acceptance.rs`), and the `{bar, error}` failures every record lists. The first two are
//! written with their keys sorted at every level (through a `serde_json::Value`, as they always
//! were), so their fields are declared in that order here too.

use std::borrow::Cow;

use serde::Serialize;

use crate::pipeline::{AcceptanceSection, BarFailure, RunPlan, RunResults};

use super::acceptance::{BarAcceptanceRecord, FleetAcceptanceRecord};
use super::calibration::BarCalibrationRecord;
use super::compensation::WorkingRecord;
use super::inputs::{input_records, InputRecord};

/// A bar a stage could not process, and why (`stage::BarFailure`).
#[derive(Debug, Serialize)]
pub(crate) struct FailureRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) error: Cow<'a, str>,
}

/// The records of `failures`, in their order.
pub(crate) fn failure_records(failures: &[BarFailure]) -> Vec<FailureRecord<'_>> {
    failures
        .iter()
        .map(|f| FailureRecord {
            bar: &f.bar,
            error: crate::narrative::quality::failure(f),
        })
        .collect()
}

/// `calibration.json`.
#[derive(Debug, Serialize)]
pub(crate) struct CalibrationRecord<'a> {
    pub(crate) bars: Vec<BarCalibrationRecord<'a>>,
    pub(crate) campaign: &'a str,
    pub(crate) failed_bars: Vec<FailureRecord<'a>>,
    pub(crate) inputs: Vec<InputRecord>,
}

/// `compensation.json`.
#[derive(Debug, Serialize)]
pub(crate) struct CompensationRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) failed: Vec<FailureRecord<'a>>,
    pub(crate) inputs: Vec<InputRecord>,
    pub(crate) options: &'a AcceptanceSection,
    pub(crate) working: Vec<WorkingRecord<'a>>,
}

/// `acceptance.json`.
#[derive(Debug, Serialize)]
pub(crate) struct AcceptanceRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) decision_rule: &'static str,
    pub(crate) tolerance_um: f64,
    pub(crate) u_temperature_k: f64,
    pub(crate) inputs: Vec<InputRecord>,
    pub(crate) fleet: FleetAcceptanceRecord,
    pub(crate) bars: Vec<BarAcceptanceRecord<'a>>,
    /// Working bars the compensate stage could not process.
    pub(crate) not_accepted: Vec<FailureRecord<'a>>,
}

/// The calibrate stage's record, if it ran.
pub(crate) fn calibration_record(results: &RunResults) -> Option<CalibrationRecord<'_>> {
    let c = results.calibration.as_ref()?;
    Some(CalibrationRecord {
        bars: c.ok.iter().map(BarCalibrationRecord::from).collect(),
        campaign: &results.campaign.id,
        failed_bars: failure_records(&c.failed),
        inputs: input_records(&results.inputs),
    })
}

/// The compensate stage's record, if it ran.
pub(crate) fn compensation_record<'a>(
    plan: &'a RunPlan,
    results: &'a RunResults,
) -> Option<CompensationRecord<'a>> {
    let c = results.compensation.as_ref()?;
    Some(CompensationRecord {
        campaign: &results.campaign.id,
        failed: failure_records(&c.failed),
        inputs: input_records(&results.inputs),
        options: &plan.acceptance,
        working: c.ok.iter().map(WorkingRecord::from).collect(),
    })
}

/// The acceptance stage's record, if it ran (it needs the compensate stage's).
pub(crate) fn acceptance_record<'a>(
    plan: &RunPlan,
    results: &'a RunResults,
) -> Option<AcceptanceRecord<'a>> {
    let (a, c) = (results.acceptance.as_ref()?, results.compensation.as_ref()?);
    Some(AcceptanceRecord {
        campaign: &results.campaign.id,
        decision_rule: crate::narrative::acceptance::DECISION_RULE,
        tolerance_um: plan.acceptance.tolerance_um,
        u_temperature_k: plan.acceptance.u_temperature_k,
        inputs: input_records(&results.inputs),
        fleet: FleetAcceptanceRecord::from(&crate::acceptance::fleet(a)),
        bars: a.iter().map(BarAcceptanceRecord::from).collect(),
        not_accepted: failure_records(&c.failed),
    })
}
