//! `calibration.json`'s bars: per bar the calibration points, the points left out and why,
//! every form's cross-validation and the chosen `D(n, A)` (`calibrate::BarCalibration`).

use serde::Serialize;

use crate::calibrate::{BarCalibration, CalibrationPoint, DistanceFunction, FormScore};
use crate::campaign::Purpose;
use crate::narrative::calibration::excluded_reason;

/// One bar's calibration.
#[derive(Debug, Serialize)]
pub(crate) struct BarCalibrationRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) epoch: usize,
    pub(crate) points: Vec<PointRecord<'a>>,
    pub(crate) excluded: Vec<ExcludedRecord<'a>>,
    pub(crate) forms: Vec<FormScoreRecord>,
    pub(crate) chosen: DistanceFunctionRecord<'a>,
    pub(crate) cv_rms_um: f64,
}

impl<'a> From<&'a BarCalibration> for BarCalibrationRecord<'a> {
    fn from(c: &'a BarCalibration) -> Self {
        BarCalibrationRecord {
            bar: &c.bar,
            epoch: c.epoch,
            points: c.points.iter().map(PointRecord::from).collect(),
            excluded: c
                .excluded
                .iter()
                .map(|p| ExcludedRecord {
                    point: PointRecord::from(p),
                    reason: excluded_reason(p, c.epoch),
                })
                .collect(),
            forms: c.forms.iter().map(FormScoreRecord::from).collect(),
            chosen: DistanceFunctionRecord::from(&c.chosen),
            cv_rms_um: c.cv_rms_um,
        }
    }
}

/// One calibration point.
#[derive(Debug, Serialize)]
pub(crate) struct PointRecord<'a> {
    pub(crate) mount: usize,
    pub(crate) length_id: &'a str,
    pub(crate) length_mm: f64,
    pub(crate) u_length_um: f64,
    pub(crate) tilt_deg: f64,
    pub(crate) reading_mm: f64,
    pub(crate) u_reading_um: f64,
    pub(crate) epoch: usize,
    pub(crate) purpose: &'static str,
    pub(crate) n_samples: usize,
}

impl<'a> From<&'a CalibrationPoint> for PointRecord<'a> {
    fn from(p: &'a CalibrationPoint) -> Self {
        PointRecord {
            mount: p.mount,
            length_id: &p.length_id,
            length_mm: p.length_mm,
            u_length_um: p.u_length_um,
            tilt_deg: p.tilt_deg,
            reading_mm: p.reading_mm,
            u_reading_um: p.u_reading_um,
            epoch: p.epoch,
            purpose: purpose_word(p.purpose),
            n_samples: p.n_samples,
        }
    }
}

/// A mount's purpose as `campaign.toml` spells it.
fn purpose_word(p: Purpose) -> &'static str {
    match p {
        Purpose::Calibration => "calibration",
        Purpose::Reference => "reference",
        Purpose::Check => "check",
    }
}

/// A point left out, and why in words.
#[derive(Debug, Serialize)]
pub(crate) struct ExcludedRecord<'a> {
    pub(crate) point: PointRecord<'a>,
    pub(crate) reason: String,
}

/// One form's cross-validation.
#[derive(Debug, Serialize)]
pub(crate) struct FormScoreRecord {
    /// The form's name, e.g. `quadratic+sag_cos2*length`.
    pub(crate) form: String,
    pub(crate) n_params: usize,
    pub(crate) cv_rms_um: Option<f64>,
    pub(crate) cv_max_abs_um: Option<f64>,
    pub(crate) fit_rms_um: Option<f64>,
    /// Why the form could not be fitted or cross-validated.
    pub(crate) note: Option<String>,
}

impl From<&FormScore> for FormScoreRecord {
    fn from(f: &FormScore) -> Self {
        FormScoreRecord {
            form: f.form.name(),
            n_params: f.n_params,
            cv_rms_um: f.cv_rms_um,
            cv_max_abs_um: f.cv_max_abs_um,
            fit_rms_um: f.fit_rms_um,
            note: f.note.as_ref().map(ToString::to_string),
        }
    }
}

/// The chosen centre-distance function.
#[derive(Debug, Serialize)]
pub(crate) struct DistanceFunctionRecord<'a> {
    pub(crate) form: String,
    pub(crate) reading_centre_mm: f64,
    pub(crate) reading_half_range_mm: f64,
    /// `[name, µm]` pairs.
    pub(crate) coefficients: &'a [(String, f64)],
    pub(crate) patent_abc: Option<[f64; 3]>,
    /// `[tilt, [[reading mm, correction µm], …]]` per tilt.
    pub(crate) table: &'a [(f64, Vec<(f64, f64)>)],
    pub(crate) fit_rms_um: f64,
}

impl<'a> From<&'a DistanceFunction> for DistanceFunctionRecord<'a> {
    fn from(d: &'a DistanceFunction) -> Self {
        DistanceFunctionRecord {
            form: d.form.name(),
            reading_centre_mm: d.reading_centre_mm,
            reading_half_range_mm: d.reading_half_range_mm,
            coefficients: &d.coefficients,
            patent_abc: d.patent_abc,
            table: &d.table,
            fit_rms_um: d.fit_rms_um,
        }
    }
}
