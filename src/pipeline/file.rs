//! The pipeline file's sections as written (`pipelines/*.toml`): serde types one to one with
//! its tables, with their defaults. [`RunPlan`](super::RunPlan) is their validated form (`plan`).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::{PlanError, Stage};
use crate::model::Effect;

/// A pipeline file (`pipelines/*.toml`), as written.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PipelineFile {
    pub(crate) pipeline: PipelineSection,
    #[serde(default)]
    pub(crate) model: ModelSection,
    #[serde(default, rename = "match")]
    pub(crate) matching: MatchSection,
    #[serde(default)]
    pub(crate) diagnose: DiagnoseSection,
    #[serde(default)]
    pub(crate) acceptance: AcceptanceSection,
    #[serde(default)]
    pub(crate) report: ReportSection,
    #[serde(default)]
    pub(crate) output: OutputSection,
    #[serde(default)]
    pub(crate) device: DeviceSection,
    /// Controller tables from the device's six errors (`[tables]`, as an axis run's).
    #[serde(default)]
    pub(crate) tables: crate::output::axis_tables::TablesSection,
}

/// `[device]`: the device stage's loop (`dbbcal_machine::device_study`).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct DeviceSection {
    /// Effects in the device's model: machine_drift, machine_warm_up, body_expansion,
    /// reseated_leg.
    #[serde(default)]
    pub(crate) effects: Vec<String>,
    /// The BIC gain an effect must bring to be proposed.
    #[serde(default = "default_device_min_bic_gain")]
    pub(crate) min_bic_gain: f64,
    /// The largest change to a leg an effect must make to be proposed, µm.
    #[serde(default = "default_device_min_effect_um")]
    pub(crate) min_effect_um: f64,
}

impl Default for DeviceSection {
    fn default() -> Self {
        DeviceSection {
            effects: Vec::new(),
            min_bic_gain: default_device_min_bic_gain(),
            min_effect_um: default_device_min_effect_um(),
        }
    }
}

fn default_device_min_bic_gain() -> f64 {
    dbbcal_machine::device_study::DeviceStudyOptions::default().min_bic_gain
}

fn default_device_min_effect_um() -> f64 {
    dbbcal_machine::device_study::DeviceStudyOptions::default().min_effect_um
}

/// Effect names for the device's loop, each with the key that gave it: parsed, deduplicated.
pub(super) fn device_effects(
    names: &[(String, String)],
) -> Result<Vec<dbbcal_machine::device_study::DeviceEffect>, PlanError> {
    use dbbcal_machine::device_study::DeviceEffect;
    let mut out = Vec::new();
    for (name, key) in names {
        let e = DeviceEffect::parse(name).ok_or_else(|| PlanError::Pipeline {
            path: key.clone(),
            message: format!(
                "{name:?} is not an effect of the device's loop (known: {})",
                DeviceEffect::ALL.map(|e| e.name()).join(", ")
            ),
        })?;
        if !out.contains(&e) {
            out.push(e);
        }
    }
    Ok(out)
}

/// `[report]`: what the data cannot say and a filed report must (ISO/IEC 17025 §7.8): the lab's
/// template fields, printed on the report page's provenance; absent ones stay blank lines.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct ReportSection {
    pub(crate) laboratory: Option<String>,
    pub(crate) address: Option<String>,
    pub(crate) customer: Option<String>,
    /// The report's or certificate's unique identification.
    pub(crate) report_id: Option<String>,
    pub(crate) signatory: Option<String>,
}

/// `[output]`: extra formats.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct OutputSection {
    /// Also write the tables (`models.parquet`, `compensated.parquet`) as CSV.
    #[serde(default)]
    pub(crate) csv: bool,
}

/// `[acceptance]`: compensation and acceptance options (`calibrate`, `compensate`, `acceptance`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct AcceptanceSection {
    /// Tolerance on the compensated centre-distance error, ± µm (patent: ±1 µm).
    #[serde(default = "default_tolerance")]
    pub(crate) tolerance_um: f64,
    /// Standard uncertainty of the temperature measurement, K (uncertainty budget).
    #[serde(default = "default_u_temperature")]
    pub(crate) u_temperature_k: f64,
    /// Also compensate the modelled reference-to-working difference.
    #[serde(default)]
    pub(crate) model_difference: bool,
    /// A reference reading farther than this from a working sample is not used, s.
    #[serde(default = "default_max_gap")]
    pub(crate) max_gap_s: f64,
}

impl Default for AcceptanceSection {
    fn default() -> Self {
        Self {
            tolerance_um: default_tolerance(),
            u_temperature_k: default_u_temperature(),
            model_difference: crate::compensate::CompensateOptions::default().model_difference,
            max_gap_s: default_max_gap(),
        }
    }
}

// The stages' own defaults, written once, in their modules.
fn default_tolerance() -> f64 {
    crate::acceptance::AcceptanceOptions::default().tolerance_um
}
fn default_u_temperature() -> f64 {
    crate::acceptance::AcceptanceOptions::default().u_temperature_k
}
fn default_max_gap() -> f64 {
    crate::compensate::CompensateOptions::default().max_gap_s
}

/// `[diagnose]`: forward selection and the materiality rule.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DiagnoseSection {
    /// Forward selection adds at most this many effects (0: rank candidates only).
    #[serde(default = "default_forward_steps")]
    pub forward_steps: usize,
    /// Forward selection keeps this many best paths at each step (1: plain greedy).
    #[serde(default = "default_beam")]
    pub(crate) beam: usize,
    /// Tolerance the bars serve, µm: a candidate is proposed only when the fleet RMS it removes
    /// is at least 0.5 % of it (and 5 % of the noise floor; `diagnose::Criteria`). Absent: the
    /// matching limit `[match] limit_um`.
    #[serde(default)]
    pub(crate) tolerance_um: Option<f64>,
}

impl Default for DiagnoseSection {
    fn default() -> Self {
        Self {
            forward_steps: default_forward_steps(),
            beam: default_beam(),
            tolerance_um: None,
        }
    }
}

fn default_forward_steps() -> usize {
    3
}
fn default_beam() -> usize {
    3
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PipelineSection {
    pub(crate) name: String,
    pub(crate) stages: Vec<Stage>,
    /// Default campaign directory, relative to the working directory.
    #[serde(default)]
    pub(crate) campaign: Option<PathBuf>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ModelSection {
    /// Effect names (see `model::Effect::parse`); the base model when absent.
    #[serde(default = "default_effects")]
    pub(crate) effects: Vec<String>,
    /// Generic terms spelled out (`[[model.term]]`): the same as `"lag:H1@1800"` in `effects`.
    #[serde(default)]
    pub(crate) term: Vec<GenericTerm>,
    /// Compress each bar's readings into bins of this many seconds, two weighted nodes a bin,
    /// exact for the fits (`series::bins`; 0: every reading). At most an hour. Absent or
    /// `"auto"`: chosen from the campaign (`series::automatic_bin_s`: 60 s for logs of 12 s or
    /// faster) and checked against the fitted time constants (`runner`).
    #[serde(default, deserialize_with = "bin_s_or_auto")]
    pub(crate) bin_s: Option<f64>,
}

/// A generic term defined in the pipeline TOML: `transform` of `channel`, starting at `tau_s`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GenericTerm {
    pub(crate) channel: String,
    pub(crate) transform: TransformWord,
    #[serde(default)]
    pub(crate) tau_s: Option<f64>,
}

/// `[[model.term]] transform`: how a generic channel enters the model (`model::Transform`).
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum TransformWord {
    Lag,
    Rate,
    Level,
    Heat,
}

impl From<TransformWord> for crate::model::Transform {
    fn from(w: TransformWord) -> Self {
        match w {
            TransformWord::Lag => crate::model::Transform::Lag,
            TransformWord::Rate => crate::model::Transform::Rate,
            TransformWord::Level => crate::model::Transform::Level,
            TransformWord::Heat => crate::model::Transform::Heat,
        }
    }
}

impl GenericTerm {
    pub(super) fn effect(&self) -> Effect {
        Effect::Channel {
            transform: self.transform.into(),
            channel: self.channel.clone(),
            tau0_s: self.tau_s,
        }
    }
}

impl Default for ModelSection {
    fn default() -> Self {
        Self {
            effects: default_effects(),
            term: Vec::new(),
            bin_s: None,
        }
    }
}

pub(super) fn default_effects() -> Vec<String> {
    crate::model::base_effects()
        .iter()
        .map(Effect::name)
        .collect()
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MatchSection {
    /// Flag bars whose predicted mismatch exceeds this, µm (the patent's ±1 µm).
    #[serde(default = "default_limit")]
    pub(crate) limit_um: f64,
    /// Plate length id at which bars are compared; the middle plate length when absent.
    #[serde(default)]
    pub(crate) at_length: Option<String>,
    /// Grid step of the measured-drift matching study, s.
    #[serde(default = "default_study_step")]
    pub(crate) study_step_s: f64,
}

impl Default for MatchSection {
    fn default() -> Self {
        Self {
            limit_um: default_limit(),
            at_length: None,
            study_step_s: default_study_step(),
        }
    }
}

fn default_limit() -> f64 {
    1.0
}
fn default_study_step() -> f64 {
    60.0
}

/// `bin_s = 60` or `bin_s = "auto"` (= absent).
fn bin_s_or_auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum BinS {
        Seconds(f64),
        Word(String),
    }
    match BinS::deserialize(d)? {
        BinS::Seconds(s) => Ok(Some(s)),
        BinS::Word(w) if w == "auto" => Ok(None),
        BinS::Word(w) => Err(serde::de::Error::custom(format!(
            "model.bin_s must be a number of seconds or \"auto\", not {w:?}"
        ))),
    }
}
