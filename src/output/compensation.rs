//! `compensation.json`'s working mounts: mode, references and weights, the budget's thermal
//! terms (`compensate::WorkingSeries`; the samples are `compensated.parquet`'s).

use serde::Serialize;

use crate::compensate::{ReferenceUse, WorkingSeries};

/// One working mount, compensated (its samples left out).
#[derive(Debug, Serialize)]
pub(crate) struct WorkingRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) mount: usize,
    pub(crate) length_id: Option<&'a str>,
    pub(crate) length_mm: Option<f64>,
    pub(crate) u_length_um: f64,
    pub(crate) device: Option<&'a str>,
    /// `two_references`, `one_reference` or `model`, with `+model_difference`.
    pub(crate) mode: String,
    pub(crate) references: Vec<ReferenceRecord<'a>>,
    pub(crate) distance_for_weights_mm: f64,
    pub(crate) tilt_deg: f64,
    pub(crate) n_model_fallback: usize,
    pub(crate) n_other_epoch: usize,
    pub(crate) u_thermal_residual_um: f64,
    pub(crate) u_thermal_params_um: f64,
    pub(crate) temperature_sensitivity_um_per_k: f64,
}

impl<'a> From<&'a WorkingSeries> for WorkingRecord<'a> {
    fn from(w: &'a WorkingSeries) -> Self {
        WorkingRecord {
            bar: &w.bar,
            mount: w.mount,
            length_id: w.length_id.as_deref(),
            length_mm: w.length_mm,
            u_length_um: w.u_length_um,
            device: w.device.as_deref(),
            mode: w.mode.name(),
            references: w.references.iter().map(ReferenceRecord::from).collect(),
            distance_for_weights_mm: w.distance_for_weights_mm,
            tilt_deg: w.tilt_deg,
            n_model_fallback: w.n_model_fallback,
            n_other_epoch: w.n_other_epoch,
            u_thermal_residual_um: w.u_thermal_residual_um,
            u_thermal_params_um: w.u_thermal_params_um,
            temperature_sensitivity_um_per_k: w.temperature_sensitivity_um_per_k,
        }
    }
}

/// A reference used for one working mount, with its interpolation weight.
#[derive(Debug, Serialize)]
pub(crate) struct ReferenceRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) length_id: &'a str,
    pub(crate) length_mm: f64,
    pub(crate) weight: f64,
}

impl<'a> From<&'a ReferenceUse> for ReferenceRecord<'a> {
    fn from(r: &'a ReferenceUse) -> Self {
        ReferenceRecord {
            bar: &r.bar,
            length_id: &r.length_id,
            length_mm: r.length_mm,
            weight: r.weight,
        }
    }
}
