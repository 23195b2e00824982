//! The calibration in words: why a calibration point was left out (`calibration.json`).

use crate::calibrate::CalibrationPoint;

/// Why `point`, of another counter epoch than the calibration's `epoch`, was left out.
pub(crate) fn excluded_reason(point: &CalibrationPoint, epoch: usize) -> String {
    format!(
        "counter epoch {} (re-zeroed): counts not comparable with epoch {epoch}",
        point.epoch
    )
}
