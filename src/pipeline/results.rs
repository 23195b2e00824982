//! What the stages hand each other and the outputs: plain data, no IO. The stages' own result
//! types are core's (each stage's entry point returns one), re-exported here beside
//! [`RunResults`], which gathers them.

use std::collections::BTreeMap;

use crate::campaign::Campaign;
use crate::matching::{MatchStudy, TemperatureHistory};
use crate::series::InputFile;

pub use dbbcal_core::diagnose::Diagnosis;
pub use dbbcal_core::identify::{BarBeforeAfter, BarOutcome, BeforeAfter};
pub use dbbcal_core::matching::ReferenceReport;
pub use dbbcal_core::stage::{BarFailure, FailureReason, StageOutcome};

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

/// Calibrate stage: per-bar centre-distance functions.
pub(crate) type CalibrationStage = StageOutcome<crate::calibrate::BarCalibration>;
/// Compensate stage: every working mount, compensated.
pub(crate) type CompensationStage = StageOutcome<crate::compensate::WorkingSeries>;

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
