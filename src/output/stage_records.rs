//! `calibration.json`, `compensation.json` and `acceptance.json`: what the calibrate, compensate
//! and acceptance stages produced. The first two are written with their keys sorted at every
//! level (through a `serde_json::Value`, as they always were), so their fields are declared in
//! that order here too.

use serde::Serialize;

use crate::acceptance::{BarAcceptance, FleetAcceptance};
use crate::calibrate::BarCalibration;
use crate::compensate::WorkingSeries;
use crate::pipeline::{AcceptanceSection, BarFailure, RunPlan, RunResults};
use crate::series::InputFile;

/// `calibration.json`.
#[derive(Debug, Serialize)]
pub(crate) struct CalibrationRecord<'a> {
    pub(crate) bars: &'a [BarCalibration],
    pub(crate) campaign: &'a str,
    pub(crate) failed_bars: &'a [BarFailure],
    pub(crate) inputs: &'a [InputFile],
}

/// `compensation.json`.
#[derive(Debug, Serialize)]
pub(crate) struct CompensationRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) failed: &'a [BarFailure],
    pub(crate) inputs: &'a [InputFile],
    pub(crate) options: &'a AcceptanceSection,
    pub(crate) working: &'a [WorkingSeries],
}

/// `acceptance.json`.
#[derive(Debug, Serialize)]
pub(crate) struct AcceptanceRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) decision_rule: &'static str,
    pub(crate) tolerance_um: f64,
    pub(crate) u_temperature_k: f64,
    pub(crate) inputs: &'a [InputFile],
    pub(crate) fleet: FleetAcceptance,
    pub(crate) bars: &'a [BarAcceptance],
    /// Working bars the compensate stage could not process.
    pub(crate) not_accepted: &'a [BarFailure],
}

/// The calibrate stage's record, if it ran.
pub(crate) fn calibration_record<'a>(results: &'a RunResults) -> Option<CalibrationRecord<'a>> {
    let c = results.calibration.as_ref()?;
    Some(CalibrationRecord {
        bars: &c.ok,
        campaign: &results.campaign.id,
        failed_bars: &c.failed,
        inputs: &results.inputs,
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
        failed: &c.failed,
        inputs: &results.inputs,
        options: &plan.acceptance,
        working: &c.ok,
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
        decision_rule: crate::acceptance::DECISION_RULE,
        tolerance_um: plan.acceptance.tolerance_um,
        u_temperature_k: plan.acceptance.u_temperature_k,
        inputs: &results.inputs,
        fleet: crate::acceptance::fleet(a),
        bars: a,
        not_accepted: &c.failed,
    })
}
