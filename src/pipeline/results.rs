//! What the stages hand each other and the outputs: plain data, no IO.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::campaign::Campaign;
use crate::diagnose::{self, BarDiagnosis, Candidate, LedgerStep};
use crate::identify::BarModel;
use crate::matching::{MatchStudy, Mismatch, ReferenceChoice, TemperatureHistory};
use crate::series::{BarSeries, InputFile};

/// One bar's outcome.
#[derive(Debug, Clone)]
pub struct BarOutcome {
    /// The bar's series as fitted (readings or bins, temperatures, mounts).
    pub series: BarSeries,
    /// Its fitted thermal model.
    pub model: BarModel,
}

/// Everything a run produced, as plain data.
#[derive(Debug, Clone)]
pub struct RunResults {
    pub(crate) campaign: Campaign,
    pub(crate) inputs: Vec<InputFile>,
    /// Every bar identify fitted, in the campaign's order.
    pub bars: Vec<BarOutcome>,
    /// Bars identify could not fit (`failed_bars` in `summary.json`).
    pub failed: Vec<BarFailure>,
    /// Match stage: the reference bar and the mismatches against it.
    pub reference: Option<ReferenceReport>,
    pub(crate) study: Option<MatchStudy>,
    pub(crate) history: TemperatureHistory,
    /// Diagnose stage.
    pub diagnosis: Option<Diagnosis>,
    /// When the model has more than the base effects: base-model RMS beside the model's.
    pub(crate) before_after: Option<BeforeAfter>,
    /// Calibrate stage: per-bar centre-distance functions.
    pub calibration: Option<CalibrationStage>,
    /// Compensate stage: every working mount, compensated.
    pub(crate) compensation: Option<CompensationStage>,
    /// Acceptance stage: one entry per working bar on a known length.
    pub acceptance: Option<Vec<crate::acceptance::BarAcceptance>>,
    /// What ingest dropped, counted and flagged (`series::quality`).
    pub(crate) quality: crate::series::Quality,
    /// Device stage: the six errors of the machine axis (`pipeline::device`).
    pub device: Option<super::device::DeviceStage>,
    /// The logs of the sensors `[[device]]` tables name, for their rings' temperature.
    pub(crate) device_sensors: BTreeMap<String, crate::series::SensorLog>,
}

/// A bar a stage could not process, and why: one bad bar never stops the others. Written as
/// `{bar, error}` in every JSON output that lists failures.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BarFailure {
    /// The bar's id.
    pub bar: String,
    /// Why, in one line.
    pub error: String,
}

/// What a per-bar stage gave: the bars it processed, and those it could not.
#[derive(Debug, Clone)]
pub struct StageOutcome<T> {
    /// The bars processed, in the campaign's order.
    pub ok: Vec<T>,
    /// The bars the stage could not process.
    pub failed: Vec<BarFailure>,
}

impl<T> StageOutcome<T> {
    /// Per-bar results, in their order, split into the processed and the failed.
    pub(crate) fn from_results(
        results: impl IntoIterator<Item = (String, Result<T, String>)>,
    ) -> Self {
        let mut outcome = StageOutcome {
            ok: Vec::new(),
            failed: Vec::new(),
        };
        for (bar, result) in results {
            match result {
                Ok(t) => outcome.ok.push(t),
                Err(error) => outcome.failed.push(BarFailure { bar, error }),
            }
        }
        outcome
    }
}

/// Calibrate stage: per-bar centre-distance functions.
pub(crate) type CalibrationStage = StageOutcome<crate::calibrate::BarCalibration>;
/// Compensate stage: every working mount, compensated.
pub(crate) type CompensationStage = StageOutcome<crate::compensate::WorkingSeries>;

/// The diagnose stage's result.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Per bar: where its model fails (residual statistics, channels).
    pub bars: Vec<BarDiagnosis>,
    /// What each temperature sensor plausibly measures (profiled on the first bar's timeline).
    pub sensors: Vec<diagnose::sensors::SensorProfile>,
    /// When a candidate is proposed (noise floor, tolerance, materiality threshold).
    pub criteria: diagnose::Criteria,
    /// The candidate effects, best first, each with its verdict and the numbers behind it.
    pub candidates: Vec<Candidate>,
    pub(crate) unavailable: Vec<diagnose::Unavailable>,
    /// The fleet-wide forward selection: RMS as effects are added.
    pub ledger: Vec<LedgerStep>,
    /// Each bar's own forward selection, same order as `bars`.
    pub bar_ledgers: Vec<diagnose::BarLedger>,
}

#[derive(Debug, Clone, Serialize)]
pub(crate) struct BeforeAfter {
    pub(crate) before_effects: Vec<String>,
    pub(crate) after_effects: Vec<String>,
    pub(crate) bars: Vec<BarBeforeAfter>,
    pub(crate) fleet_rms_before_um: f64,
    pub(crate) fleet_rms_after_um: f64,
}

#[derive(Debug, Clone, Serialize)]
pub(crate) struct BarBeforeAfter {
    pub(crate) bar: String,
    pub(crate) rms_before_um: f64,
    pub(crate) rms_after_um: f64,
    /// Base parameters before and after: how much adding the effects moved them.
    pub(crate) params_before: BTreeMap<String, f64>,
    pub(crate) params_after: BTreeMap<String, f64>,
}

/// The match stage's result.
#[derive(Debug, Clone, Serialize)]
pub struct ReferenceReport {
    /// The reference bar, nearest the fleet mean, and every bar's distance to that mean.
    pub choice: ReferenceChoice,
    pub(crate) distance_mm: f64,
    pub(crate) limit_um: f64,
    /// Each bar's predicted mismatch against the reference.
    pub mismatches: Vec<Mismatch>,
}

impl RunResults {
    /// Identified bars, before any later stage has filled its result in.
    pub(super) fn before_stages(
        campaign: Campaign,
        inputs: Vec<InputFile>,
        history: TemperatureHistory,
        bars: Vec<BarOutcome>,
        failed: Vec<BarFailure>,
    ) -> Self {
        RunResults {
            campaign,
            inputs,
            bars,
            failed,
            reference: None,
            study: None,
            history,
            diagnosis: None,
            before_after: None,
            calibration: None,
            compensation: None,
            acceptance: None,
            quality: Default::default(),
            device: None,
            device_sensors: BTreeMap::new(),
        }
    }
}
