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
pub struct CalibrationRecord<'a> {
    pub bars: &'a [BarCalibration],
    pub campaign: &'a str,
    pub failed_bars: &'a [BarFailure],
    pub inputs: &'a [InputFile],
}

/// `compensation.json`.
#[derive(Debug, Serialize)]
pub struct CompensationRecord<'a> {
    pub campaign: &'a str,
    pub failed: &'a [BarFailure],
    pub inputs: &'a [InputFile],
    pub options: &'a AcceptanceSection,
    pub working: &'a [WorkingSeries],
}

/// `acceptance.json`.
#[derive(Debug, Serialize)]
pub struct AcceptanceRecord<'a> {
    pub campaign: &'a str,
    pub decision_rule: &'static str,
    pub tolerance_um: f64,
    pub u_temperature_k: f64,
    pub inputs: &'a [InputFile],
    pub fleet: FleetAcceptance,
    pub bars: &'a [BarAcceptance],
    /// Working bars the compensate stage could not process.
    pub not_accepted: &'a [BarFailure],
}

/// The calibrate stage's record, if it ran.
pub fn calibration_record<'a>(results: &'a RunResults) -> Option<CalibrationRecord<'a>> {
    let c = results.calibration.as_ref()?;
    Some(CalibrationRecord {
        bars: &c.ok,
        campaign: &results.campaign.id,
        failed_bars: &c.failed,
        inputs: &results.inputs,
    })
}

/// The compensate stage's record, if it ran.
pub fn compensation_record<'a>(
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
pub fn acceptance_record<'a>(
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
