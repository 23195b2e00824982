//! Staged jobs: a pipeline TOML names the stages and the model; [`RunPlan`] is its validated
//! form (checked before any heavy IO); [`run`] executes it into a temporary folder beside the
//! output and renames it into place at the end, so a failed run never leaves a half-written
//! output folder.
//!
//! Data flow: ingest (`io`) -> series -> identify (per bar, in parallel) -> match -> outputs
//! (JSON, parquet, figures). Stages talk through plain data types.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::campaign::{Campaign, Place};
use crate::diagnose::{self, BarDiagnosis, Candidate, LedgerStep};
use crate::identify::{identify, identify_from, BarModel, Estimate};
use crate::matching::{
    self, MatchInput, MatchStudy, Mismatch, ReferenceChoice, TemperatureHistory,
};
use crate::model::Effect;
use crate::series::{BarSeries, CampaignLogs, InputFile};

/// The stages a pipeline may run, in execution order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    Ingest,
    Identify,
    Match,
    MatchStudy,
    Diagnose,
    Calibrate,
    Compensate,
    Acceptance,
    Report,
}

impl Stage {
    /// The stages `self` needs before it.
    pub fn with_prerequisites(self) -> Vec<Stage> {
        use Stage::*;
        match self {
            Ingest => vec![Ingest],
            Identify => vec![Ingest, Identify],
            Match => vec![Ingest, Identify, Match],
            MatchStudy => vec![Ingest, Identify, Match, MatchStudy],
            Diagnose => vec![Ingest, Identify, Diagnose],
            Calibrate => vec![Ingest, Identify, Calibrate],
            Compensate => vec![Ingest, Identify, Match, Calibrate, Compensate],
            Acceptance => vec![Ingest, Identify, Match, Calibrate, Compensate, Acceptance],
            Report => vec![Ingest, Identify, Match, Report],
        }
    }
}

/// A pipeline file (`pipelines/*.toml`), as written.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineFile {
    pub pipeline: PipelineSection,
    #[serde(default)]
    pub model: ModelSection,
    #[serde(default, rename = "match")]
    pub matching: MatchSection,
    #[serde(default)]
    pub diagnose: DiagnoseSection,
    #[serde(default)]
    pub acceptance: AcceptanceSection,
    #[serde(default)]
    pub report: ReportSection,
    #[serde(default)]
    pub output: OutputSection,
}

/// `[report]`: what the data cannot say and a filed report must (ISO/IEC 17025 §7.8): the lab's
/// template fields, printed on the report page's provenance; absent ones stay blank lines.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ReportSection {
    pub laboratory: Option<String>,
    pub address: Option<String>,
    pub customer: Option<String>,
    /// The report's or certificate's unique identification.
    pub report_id: Option<String>,
    pub signatory: Option<String>,
}

/// `[output]`: extra formats.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// Also write the tables (`models.parquet`, `compensated.parquet`) as CSV.
    #[serde(default)]
    pub csv: bool,
}

/// `[acceptance]`: compensation and acceptance options (`calibrate`, `compensate`, `acceptance`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AcceptanceSection {
    /// Tolerance on the compensated centre-distance error, ± µm (patent: ±1 µm).
    #[serde(default = "default_limit")]
    pub tolerance_um: f64,
    /// Standard uncertainty of the temperature measurement, K (uncertainty budget).
    #[serde(default = "default_u_temperature")]
    pub u_temperature_k: f64,
    /// Also compensate the modelled reference-to-working difference.
    #[serde(default)]
    pub model_difference: bool,
    /// A reference reading farther than this from a working sample is not used, s.
    #[serde(default = "default_max_gap")]
    pub max_gap_s: f64,
}

impl Default for AcceptanceSection {
    fn default() -> Self {
        Self {
            tolerance_um: default_limit(),
            u_temperature_k: default_u_temperature(),
            model_difference: false,
            max_gap_s: default_max_gap(),
        }
    }
}

fn default_u_temperature() -> f64 {
    0.05
}
fn default_max_gap() -> f64 {
    300.0
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DiagnoseSection {
    /// Forward selection adds at most this many effects (0: rank candidates only).
    #[serde(default = "default_forward_steps")]
    pub forward_steps: usize,
    /// Forward selection keeps this many best paths at each step (1: plain greedy).
    #[serde(default = "default_beam")]
    pub beam: usize,
    /// Tolerance the bars serve, µm: a candidate is proposed only when the fleet RMS it removes
    /// is at least 0.5 % of it (and 5 % of the noise floor; `diagnose::Criteria`). Absent: the
    /// matching limit `[match] limit_um`.
    #[serde(default)]
    pub tolerance_um: Option<f64>,
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
pub struct PipelineSection {
    pub name: String,
    pub stages: Vec<Stage>,
    /// Default campaign directory, relative to the working directory.
    #[serde(default)]
    pub campaign: Option<PathBuf>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSection {
    /// Effect names (see `model::Effect::parse`); the base model when absent.
    #[serde(default = "default_effects")]
    pub effects: Vec<String>,
    /// Generic terms spelled out (`[[model.term]]`): the same as `"lag:H1@1800"` in `effects`.
    #[serde(default)]
    pub term: Vec<GenericTerm>,
    /// Compress each bar's readings into bins of this many seconds, two weighted nodes a bin,
    /// exact for the fits (`series::bins`; 0: every reading). At most an hour. Absent or
    /// `"auto"`: chosen from the campaign (`series::automatic_bin_s`: 60 s for logs of 6 s or
    /// faster) and checked against the fitted time constants (`runner`).
    #[serde(default, deserialize_with = "bin_s_or_auto")]
    pub bin_s: Option<f64>,
}

/// A generic term defined in the pipeline TOML: `transform` of `channel`, starting at `tau_s`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GenericTerm {
    pub channel: String,
    pub transform: crate::model::Transform,
    #[serde(default)]
    pub tau_s: Option<f64>,
}

impl GenericTerm {
    fn effect(&self) -> Effect {
        Effect::Channel {
            transform: self.transform,
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

fn default_effects() -> Vec<String> {
    crate::model::base_effects()
        .iter()
        .map(Effect::name)
        .collect()
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MatchSection {
    /// Flag bars whose predicted mismatch exceeds this, µm (the patent's ±1 µm).
    #[serde(default = "default_limit")]
    pub limit_um: f64,
    /// Plate length id at which bars are compared; the middle plate length when absent.
    #[serde(default)]
    pub at_length: Option<String>,
    /// Grid step of the measured-drift matching study, s.
    #[serde(default = "default_study_step")]
    pub study_step_s: f64,
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

/// Errors that make a run impossible (unusable input or configuration).
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("{path}: {message}")]
    Pipeline { path: String, message: String },
    #[error("campaign directory {0} does not exist or has no campaign.toml")]
    NoCampaign(String),
    #[error("{0}")]
    Effect(#[from] crate::model::UnknownEffect),
    /// `campaign.toml` read at plan time (cheap, before any parquet file) is not usable.
    #[error(transparent)]
    Campaign(Box<crate::campaign::CampaignError>),
    /// The plan names something the campaign's manifest does not declare (one line, naming the
    /// key).
    #[error("{0}")]
    NotInCampaign(String),
}

/// The allowed range of every number a pipeline file (or a command-line option) sets, checked
/// before any IO on the campaign: `(key, low, high, unit)`, both ends included. NaN and
/// infinities (TOML's `nan`, `inf`) are outside every range.
pub mod limits {
    /// `[match] limit_um`, `[diagnose] tolerance_um`, `[acceptance] tolerance_um`: µm (a ballbar's
    /// tolerances are microns; 1 mm is far beyond any).
    pub const TOLERANCE_UM: (f64, f64) = (1e-6, 1e3);
    /// `[match] study_step_s`: the measured-drift grid step, s (one second to a day).
    pub const STUDY_STEP_S: (f64, f64) = (1.0, 86_400.0);
    /// `[acceptance] u_temperature_k`: standard uncertainty of the air temperature, K.
    pub const U_TEMPERATURE_K: (f64, f64) = (0.0, 10.0);
    /// `[acceptance] max_gap_s`: one second to 30 days.
    pub const MAX_GAP_S: (f64, f64) = (1.0, 30.0 * 86_400.0);
    /// A starting time constant (`[[model.term]] tau_s`, the `@TAU_S` of an effect name), s: the
    /// range the model evaluates time constants in (`ln tau` clamped to [0, ln 1e9]).
    pub const TAU_S: (f64, f64) = (1.0, 1e9);
    /// `[diagnose] forward_steps` (0: rank the candidates only).
    pub const FORWARD_STEPS: (usize, usize) = (0, 10);
    /// `[diagnose] beam` (1: plain greedy selection).
    pub const BEAM: (usize, usize) = (1, 10);
}

/// `value` within `[lo, hi]` (finite), or the one-line message that names `key` and the range.
fn check_range(key: &str, value: f64, (lo, hi): (f64, f64), unit: &str) -> Result<(), String> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(format!(
            "{key} = {} is out of range: it must be a finite number from {lo} to {hi}{unit}",
            crate::campaign::display_number(value)
        ))
    }
}

fn check_count(key: &str, value: usize, (lo, hi): (usize, usize)) -> Result<(), String> {
    if (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(format!(
            "{key} = {value} is out of range: it must be a whole number from {lo} to {hi}"
        ))
    }
}

impl PipelineFile {
    /// Every number of the file in its range ([`limits`]); the message names the key.
    pub fn check_numbers(&self) -> Result<(), String> {
        use limits::*;
        let m = &self.matching;
        check_range("match.limit_um", m.limit_um, TOLERANCE_UM, " µm")?;
        check_range("match.study_step_s", m.study_step_s, STUDY_STEP_S, " s")?;
        let d = &self.diagnose;
        check_count("diagnose.forward_steps", d.forward_steps, FORWARD_STEPS)?;
        check_count("diagnose.beam", d.beam, BEAM)?;
        if let Some(t) = d.tolerance_um {
            check_range("diagnose.tolerance_um", t, TOLERANCE_UM, " µm")?;
        }
        let a = &self.acceptance;
        check_range(
            "acceptance.tolerance_um",
            a.tolerance_um,
            TOLERANCE_UM,
            " µm",
        )?;
        check_range(
            "acceptance.u_temperature_k",
            a.u_temperature_k,
            U_TEMPERATURE_K,
            " K",
        )?;
        check_range("acceptance.max_gap_s", a.max_gap_s, MAX_GAP_S, " s")?;
        if let Some(bin_s) = self.model.bin_s {
            check_bin_s("model.bin_s", bin_s)?;
        }
        for (i, t) in self.model.term.iter().enumerate() {
            if let Some(tau) = t.tau_s {
                check_range(&format!("model.term[{i}].tau_s"), tau, TAU_S, " s")?;
            }
        }
        Ok(())
    }
}

/// A bin length (`[model] bin_s`, `--bin-s`): 0 (every reading) to [`crate::series::MAX_BIN_S`].
pub fn check_bin_s(key: &str, bin_s: f64) -> Result<(), String> {
    check_range(key, bin_s, (0.0, crate::series::MAX_BIN_S), " s")
}

/// An effect's starting time constant (`@TAU_S`) in [`limits::TAU_S`].
fn check_effect(e: &Effect) -> Result<(), String> {
    match e {
        Effect::Channel {
            tau0_s: Some(tau), ..
        } => check_range(
            &format!("{:?}: the starting time constant @TAU_S", e.name()),
            *tau,
            limits::TAU_S,
            " s",
        ),
        _ => Ok(()),
    }
}

/// Channel names every campaign has (`model::channels::resolve`).
const BUILT_IN_CHANNELS: [&str; 4] = [
    "time_since_mount_h",
    "time_of_day_h",
    "length_mm",
    "tilt_deg",
];

/// Whether `channel` can exist in `campaign` as far as `campaign.toml` tells: a declared sensor,
/// a difference `A-B` of two, `event:KIND` (events are only known once read), or a built-in
/// channel ([`crate::model::channels::resolve`] resolves them the same way).
fn channel_declared(campaign: &Campaign, channel: &str) -> bool {
    let sensor = |id: &str| campaign.sensor(id).is_some();
    sensor(channel)
        || channel
            .split_once('-')
            .is_some_and(|(a, b)| sensor(a) && sensor(b))
        || channel
            .strip_prefix("event:")
            .is_some_and(|kind| !kind.is_empty())
        || BUILT_IN_CHANNELS.contains(&channel)
}

/// The plan's references into the campaign, against its manifest (read before any parquet
/// file): `[match] at_length` a plate length, every `lag:`/`rate:`/`level:` channel one the
/// campaign can provide. `effects`: each effect with the key it came from.
fn check_against_campaign(
    campaign: &Campaign,
    manifest_path: &str,
    effects: &[(Effect, String)],
    matching: &MatchSection,
    pipeline_path: &str,
) -> Result<(), String> {
    if let Some(id) = &matching.at_length {
        if !campaign.plate.lengths.iter().any(|l| &l.id == id) {
            let known: Vec<&str> = campaign
                .plate
                .lengths
                .iter()
                .map(|l| l.id.as_str())
                .collect();
            return Err(format!(
                "{pipeline_path}: match.at_length = {id:?} is not a plate length of {manifest_path} (known: {})",
                if known.is_empty() { "none".to_string() } else { known.join(", ") }
            ));
        }
    }
    for (e, key) in effects {
        if let Effect::Channel { channel, .. } = e {
            if !channel_declared(campaign, channel) {
                let sensors: Vec<&str> = campaign.sensors.iter().map(|s| s.id.as_str()).collect();
                return Err(format!(
                    "{key}: {:?}: no channel {channel:?} in {manifest_path} (sensors: {}; \
                     or a difference A-B of two, event:KIND, {})",
                    e.name(),
                    if sensors.is_empty() {
                        "none".to_string()
                    } else {
                        sensors.join(", ")
                    },
                    BUILT_IN_CHANNELS.join(", ")
                ));
            }
        }
    }
    Ok(())
}

/// A path for a one-line message: control characters escaped.
fn shown(path: &Path) -> String {
    path.display()
        .to_string()
        .chars()
        .flat_map(|c| {
            if c.is_control() {
                c.escape_debug().collect::<Vec<_>>()
            } else {
                vec![c]
            }
        })
        .collect()
}

/// Reads and validates `dir/campaign.toml` (cheap: no parquet file is opened).
fn read_campaign_manifest(dir: &Path) -> Result<(Campaign, String), PlanError> {
    let path = dir.join("campaign.toml");
    let file = shown(&path);
    let text = std::fs::read_to_string(&path).map_err(|e| PlanError::Pipeline {
        path: file.clone(),
        message: format!("cannot read: {e}"),
    })?;
    let boxed = |e| PlanError::Campaign(Box::new(e));
    let manifest = crate::campaign::Manifest::from_toml_str(&text, &file).map_err(boxed)?;
    let campaign = Campaign::from_manifest_at(manifest, &file).map_err(boxed)?;
    Ok((campaign, file))
}

/// A validated run: what to read, what to do, where to write.
#[derive(Debug, Clone)]
pub struct RunPlan {
    pub pipeline_name: String,
    /// The pipeline file and its hash (`None` for stage subcommands).
    pub pipeline_source: Option<(PathBuf, String)>,
    pub stages: Vec<Stage>,
    pub campaign_dir: PathBuf,
    /// `None`: `reports/<campaign id>`, decided after the manifest is read.
    pub out_dir: Option<PathBuf>,
    pub effects: Vec<Effect>,
    /// Bin length of the compressed readings, s (0: every reading).
    pub bin_s: f64,
    /// `bin_s` is chosen from the campaign before ingest (`io::automatic_bin_s`; the runner
    /// replaces it): no `[model] bin_s` or `--bin-s` was given.
    pub automatic_bins: bool,
    pub matching: MatchSection,
    pub diagnose: DiagnoseSection,
    pub acceptance: AcceptanceSection,
    pub report: ReportSection,
    pub output: OutputSection,
}

impl RunPlan {
    /// Validate a pipeline file plus command-line overrides.
    pub fn from_pipeline_file(
        path: &Path,
        campaign: Option<PathBuf>,
        out: Option<PathBuf>,
        add_effects: &[String],
    ) -> Result<RunPlan, PlanError> {
        let perr = |message: String| PlanError::Pipeline {
            path: shown(path),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| perr(format!("cannot read: {e}")))?;
        let file: PipelineFile =
            toml::from_str(&text).map_err(|e| perr(e.to_string().replace('\n', " ")))?;
        if file.pipeline.stages.is_empty() {
            return Err(perr("pipeline.stages is empty".into()));
        }
        // Every number first, before anything of the campaign is touched.
        file.check_numbers().map_err(perr)?;
        let mut stages: Vec<Stage> = file
            .pipeline
            .stages
            .iter()
            .flat_map(|s| s.with_prerequisites())
            .collect();
        stages.sort();
        stages.dedup();
        let mut names: Vec<(String, String)> = file
            .model
            .effects
            .iter()
            .enumerate()
            .map(|(i, e)| (e.clone(), format!("{}: model.effects[{i}]", shown(path))))
            .collect();
        for (i, t) in file.model.term.iter().enumerate() {
            names.push((
                t.effect().name(),
                format!("{}: model.term[{i}]", shown(path)),
            ));
        }
        names.extend(
            add_effects
                .iter()
                .map(|e| (e.clone(), "--add-effect".to_string())),
        );
        let campaign_dir = campaign
            .or(file.pipeline.campaign.clone())
            .unwrap_or_else(|| PathBuf::from("data/sample"));
        let sha = sha256_hex(text.as_bytes());
        let mut plan = RunPlan::new(
            file.pipeline.name.clone(),
            Some((path.to_path_buf(), sha)),
            stages,
            campaign_dir,
            out,
            &names,
            file.matching,
        )?;
        plan.diagnose = file.diagnose;
        if let Some(bin_s) = file.model.bin_s {
            (plan.bin_s, plan.automatic_bins) = (bin_s, false);
        }
        plan.acceptance = file.acceptance;
        plan.report = file.report;
        plan.output = file.output;
        Ok(plan)
    }

    /// A plan for one stage subcommand (and the stages it needs).
    pub fn for_stage(
        stage: Stage,
        campaign: PathBuf,
        out: Option<PathBuf>,
        effects: &[String],
    ) -> Result<RunPlan, PlanError> {
        let names: Vec<(String, String)> = if effects.is_empty() {
            default_effects()
                .into_iter()
                .map(|e| (e, "the base model".to_string()))
                .collect()
        } else {
            effects
                .iter()
                .map(|e| (e.clone(), "--effects/--add-effect".to_string()))
                .collect()
        };
        RunPlan::new(
            format!("{stage:?}").to_lowercase(),
            None,
            stage.with_prerequisites(),
            campaign,
            out,
            &names,
            MatchSection::default(),
        )
    }

    fn new(
        name: String,
        source: Option<(PathBuf, String)>,
        stages: Vec<Stage>,
        campaign_dir: PathBuf,
        out_dir: Option<PathBuf>,
        effect_names: &[(String, String)],
        matching: MatchSection,
    ) -> Result<RunPlan, PlanError> {
        let effects = validated_effects(&campaign_dir, effect_names, &matching, source.as_ref())?;
        Ok(RunPlan {
            pipeline_name: name,
            pipeline_source: source,
            stages,
            campaign_dir,
            out_dir,
            effects,
            bin_s: 0.0,
            automatic_bins: true,
            matching,
            diagnose: DiagnoseSection::default(),
            acceptance: AcceptanceSection::default(),
            report: ReportSection::default(),
            output: OutputSection::default(),
        })
    }

    pub fn runs(&self, stage: Stage) -> bool {
        self.stages.contains(&stage)
    }

    /// The command line's model overrides: `--effects` (replacing the plan's, when not empty),
    /// then `--add-effect`; validated against the campaign like the pipeline's own.
    pub fn with_effects(
        mut self,
        replace: &[String],
        add: &[String],
    ) -> Result<RunPlan, PlanError> {
        let mut names: Vec<(String, String)> = if replace.is_empty() {
            self.effects
                .iter()
                .map(|e| (e.name(), "model.effects".to_string()))
                .collect()
        } else {
            replace
                .iter()
                .map(|e| (e.clone(), "--effects".to_string()))
                .collect()
        };
        names.extend(add.iter().map(|e| (e.clone(), "--add-effect".to_string())));
        self.effects = validated_effects(
            &self.campaign_dir,
            &names,
            &self.matching,
            self.pipeline_source.as_ref(),
        )?;
        Ok(self)
    }
}

/// Parse, range-check and deduplicate `effect_names` (each with the key that named it), and
/// check them against the campaign's manifest (cheap to read) before any parquet.
fn validated_effects(
    campaign_dir: &Path,
    effect_names: &[(String, String)],
    matching: &MatchSection,
    source: Option<&(PathBuf, String)>,
) -> Result<Vec<Effect>, PlanError> {
    let mut keyed: Vec<(Effect, String)> = Vec::new();
    for (n, key) in effect_names {
        let e = Effect::parse(n)?;
        check_effect(&e).map_err(|message| PlanError::Pipeline {
            path: key.clone(),
            message,
        })?;
        if !keyed.iter().any(|(k, _)| *k == e) {
            keyed.push((e, key.clone()));
        }
    }
    if !campaign_dir.join("campaign.toml").is_file() {
        return Err(PlanError::NoCampaign(shown(campaign_dir)));
    }
    let (campaign, manifest_path) = read_campaign_manifest(campaign_dir)?;
    let pipeline_path = source.map_or("plan".to_string(), |(p, _)| shown(p));
    check_against_campaign(&campaign, &manifest_path, &keyed, matching, &pipeline_path)
        .map_err(PlanError::NotInCampaign)?;
    Ok(keyed.into_iter().map(|(e, _)| e).collect())
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

pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

// ------------------------------------------------------------------------------------ results

/// One bar's outcome.
#[derive(Debug, Clone)]
pub struct BarOutcome {
    pub series: BarSeries,
    pub model: BarModel,
}

/// Everything a run produced, as plain data.
#[derive(Debug, Clone)]
pub struct RunResults {
    pub campaign: Campaign,
    pub inputs: Vec<InputFile>,
    pub bars: Vec<BarOutcome>,
    pub failed: Vec<(String, String)>,
    pub reference: Option<ReferenceReport>,
    pub study: Option<MatchStudy>,
    pub history: TemperatureHistory,
    pub diagnosis: Option<Diagnosis>,
    /// When the model has more than the base effects: base-model RMS beside the model's.
    pub before_after: Option<BeforeAfter>,
    /// Calibrate stage: per-bar centre-distance functions.
    pub calibration: Option<CalibrationStage>,
    /// Compensate stage: every working mount, compensated.
    pub compensation: Option<CompensationStage>,
    /// Acceptance stage: one entry per working bar on a known length.
    pub acceptance: Option<Vec<crate::acceptance::BarAcceptance>>,
    /// What ingest dropped, counted and flagged (`series::quality`).
    pub quality: crate::series::Quality,
}

#[derive(Debug, Clone, Serialize)]
pub struct CalibrationStage {
    pub bars: Vec<crate::calibrate::BarCalibration>,
    pub failed: Vec<(String, String)>,
}

#[derive(Debug, Clone, Serialize)]
pub struct CompensationStage {
    pub working: Vec<crate::compensate::WorkingSeries>,
    pub failed: Vec<(String, String)>,
}

/// The diagnose stage's result.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    pub bars: Vec<BarDiagnosis>,
    /// What each temperature sensor plausibly measures (profiled on the first bar's timeline).
    pub sensors: Vec<diagnose::sensors::SensorProfile>,
    /// When a candidate is proposed (noise floor, tolerance, materiality threshold).
    pub criteria: diagnose::Criteria,
    pub candidates: Vec<Candidate>,
    pub unavailable: Vec<diagnose::Unavailable>,
    pub ledger: Vec<LedgerStep>,
    /// Each bar's own forward selection, same order as `bars`.
    pub bar_ledgers: Vec<diagnose::BarLedger>,
}

#[derive(Debug, Clone, Serialize)]
pub struct BeforeAfter {
    pub before_effects: Vec<String>,
    pub after_effects: Vec<String>,
    pub bars: Vec<BarBeforeAfter>,
    pub fleet_rms_before_um: f64,
    pub fleet_rms_after_um: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct BarBeforeAfter {
    pub bar: String,
    pub rms_before_um: f64,
    pub rms_after_um: f64,
    /// Base parameters before and after: how much adding the effects moved them.
    pub params_before: BTreeMap<String, f64>,
    pub params_after: BTreeMap<String, f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ReferenceReport {
    pub choice: ReferenceChoice,
    pub distance_mm: f64,
    pub limit_um: f64,
    pub mismatches: Vec<Mismatch>,
}

impl RunResults {
    /// Identified bars, before any later stage has filled its result in.
    fn before_stages(
        campaign: Campaign,
        inputs: Vec<InputFile>,
        history: TemperatureHistory,
        bars: Vec<BarOutcome>,
        failed: Vec<(String, String)>,
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
        }
    }
}

/// Run `f` and log how long it took (`DBBCAL_LOG=info`): stage timings go to the log, never
/// into the byte-identical outputs.
pub fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let start = std::time::Instant::now();
    let out = f();
    tracing::info!("{what}: {:.3} s", start.elapsed().as_secs_f64());
    out
}

/// Run the analysis stages on already-read logs (no output written).
pub fn analyse(plan: &RunPlan, logs: CampaignLogs) -> RunResults {
    let CampaignLogs {
        campaign,
        inputs,
        bars,
        mut bins,
        sensors,
        events,
        quality,
    } = logs;
    let t0 = campaign
        .mounts
        .iter()
        .map(|m| m.from_ns)
        .min()
        .unwrap_or_else(|| campaign_origin_from(&bars, &bins));
    let history = air_history(&campaign, &sensors, t0, 60.0);
    if !plan.runs(Stage::Identify) {
        let mut results =
            RunResults::before_stages(campaign, inputs, history, Vec::new(), Vec::new());
        results.quality = quality;
        return results;
    }
    // Every stage past identify reads the bars' samples, and so does the before/after
    // comparison of an extended model; a plain identify run keeps only the models and counts,
    // so it never holds the campaign's series at full rate.
    let samples_needed = plan.effects != crate::model::base_effects()
        || [
            Stage::Match,
            Stage::MatchStudy,
            Stage::Diagnose,
            Stage::Calibrate,
            Stage::Compensate,
            Stage::Acceptance,
            Stage::Report,
        ]
        .into_iter()
        .any(|s| plan.runs(s));
    let progress = crate::progress::bar(bars.len() as u64, "identify");
    let knots = crate::series::sensor_knots(&sensors);
    let outcomes: Vec<(String, Result<BarOutcome, String>)> = timed("identify", || {
        bars.into_iter()
            .map(|(id, log)| {
                let binned = bins.remove(&id);
                (id, log, binned)
            })
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(id, log, binned)| {
                // A bar ingest found no usable signal in (a dead encoder) fails alone.
                if let Some(why) = quality.unusable(&id) {
                    progress.inc(1);
                    return (id, Err(why.to_string()));
                }
                let series = match binned {
                    Some(b) => {
                        BarSeries::from_bins(&campaign, &events, &id, &b, &sensors, &knots, t0)
                    }
                    None => BarSeries::build_binned(
                        &campaign, &events, &id, log, &sensors, &knots, t0, plan.bin_s,
                    ),
                };
                let r = series.map_err(|e| e.to_string()).and_then(|series| {
                    let model = identify(&series, &plan.effects).map_err(|e| e.to_string())?;
                    let series = if samples_needed {
                        series
                    } else {
                        series.without_samples()
                    };
                    Ok(BarOutcome { series, model })
                });
                progress.inc(1);
                (id, r)
            })
            .collect()
    });
    progress.finish_and_clear();
    let mut ok = Vec::new();
    let mut failed = Vec::new();
    for (id, r) in outcomes {
        match r {
            Ok(o) => ok.push(o),
            Err(e) => {
                tracing::info!("{e}"); // in failed_bars and the final line
                failed.push((id, e));
            }
        }
    }
    let mut results = RunResults::before_stages(campaign, inputs, history, ok, failed);
    results.quality = quality;
    if plan.runs(Stage::Match) {
        run_match(plan, &mut results);
    }
    if plan.effects != crate::model::base_effects() {
        results.before_after = Some(before_after(&results.bars));
    }
    if plan.runs(Stage::Diagnose) {
        results.diagnosis = Some(timed("diagnose", || run_diagnose(plan, &results.bars)));
    }
    if plan.runs(Stage::Calibrate) {
        results.calibration = Some(run_calibrate(&results));
    }
    if plan.runs(Stage::Compensate) {
        results.compensation = Some(run_compensate(plan, &results));
    }
    if plan.runs(Stage::Acceptance) {
        results.acceptance = Some(run_acceptance(plan, &results));
    }
    results
}

/// Calibrate every identified bar (a bar that cannot be calibrated is listed, the others go on).
fn run_calibrate(r: &RunResults) -> CalibrationStage {
    let outcomes: Vec<Result<crate::calibrate::BarCalibration, String>> = r
        .bars
        .par_iter()
        .map(|o| {
            crate::calibrate::calibrate_bar(&o.series, &o.model, &r.campaign)
                .map_err(|e| e.to_string())
        })
        .collect();
    let mut stage = CalibrationStage {
        bars: Vec::new(),
        failed: Vec::new(),
    };
    for (o, c) in r.bars.iter().zip(outcomes) {
        match c {
            Ok(c) => stage.bars.push(c),
            Err(e) => {
                tracing::warn!("{e}");
                stage.failed.push((o.model.bar.clone(), e));
            }
        }
    }
    stage
}

/// Compensate every working mount (check lengths and devices).
fn run_compensate(plan: &RunPlan, r: &RunResults) -> CompensationStage {
    let cals = r
        .calibration
        .as_ref()
        .map(|c| c.bars.as_slice())
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
    let mut stage = CompensationStage {
        working: Vec::new(),
        failed: Vec::new(),
    };
    for w in crate::compensate::compensate(&bars, &r.campaign, &fleet_distance, &options) {
        match w {
            Ok(w) => stage.working.push(w),
            Err(e) => {
                tracing::warn!("{e}");
                let bar = match &e {
                    crate::compensate::CompensateError::NotCalibrated { bar }
                    | crate::compensate::CompensateError::Model { bar, .. } => bar.clone(),
                    crate::compensate::CompensateError::OtherEpoch { bar, .. }
                    | crate::compensate::CompensateError::NoReadings { bar, .. } => bar.clone(),
                };
                stage.failed.push((bar, e.to_string()));
            }
        }
    }
    stage
}

/// Accept every compensated working series on a known length.
fn run_acceptance(plan: &RunPlan, r: &RunResults) -> Vec<crate::acceptance::BarAcceptance> {
    let (Some(cal), Some(comp)) = (&r.calibration, &r.compensation) else {
        return Vec::new();
    };
    let options = crate::acceptance::AcceptanceOptions {
        tolerance_um: plan.acceptance.tolerance_um,
        u_temperature_k: plan.acceptance.u_temperature_k,
    };
    comp.working
        .iter()
        .filter_map(|w| {
            let c = cal.bars.iter().find(|c| c.bar == w.bar)?;
            let resolution_nm = r.campaign.bar(&w.bar).map_or(0.0, |b| b.resolution_nm);
            crate::acceptance::accept(w, c, resolution_nm, &options)
        })
        .collect()
}

fn campaign_origin_from(
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
fn air_history(
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
    if logs.is_empty() || !(end > start) {
        return TemperatureHistory {
            t_s: vec![],
            delta_c: vec![],
        };
    }
    let n = ((end - start) / step_s).floor() as usize + 1;
    let t_s: Vec<f64> = (0..n).map(|i| start + i as f64 * step_s).collect();
    let mut sum = vec![0.0; n];
    for l in &logs {
        let ts: Vec<f64> = l.time_ns.iter().map(|&t| to_s(t)).collect();
        for (s, t) in sum.iter_mut().zip(&t_s) {
            *s += interpolate(&ts, &l.celsius, *t);
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

fn interpolate(x: &[f64], y: &[f64], at: f64) -> f64 {
    let i = x.partition_point(|&v| v <= at);
    if i == 0 {
        return y[0];
    }
    if i >= x.len() {
        return y[x.len() - 1];
    }
    let (x0, x1) = (x[i - 1], x[i]);
    if x1 <= x0 {
        return y[i];
    }
    y[i - 1] + (y[i] - y[i - 1]) * (at - x0) / (x1 - x0)
}

/// What matching needs of an identified bar: `None` when its model lacks `alpha` or `tau_R`;
/// `beta` and `tau_S` are NaN when its data cannot determine them (one length,
/// [`crate::model::identifiable_effects`]). See [`matched_inputs`] for who is matched.
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

fn run_match(plan: &RunPlan, results: &mut RunResults) {
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
fn comparison_distance(campaign: &Campaign, at_length: Option<&str>) -> f64 {
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

// ------------------------------------------------------------------------------------ summary

/// `summary.json`: the stable contract for cron jobs and dashboards.
#[derive(Debug, Serialize)]
pub struct Summary {
    pub dbbcal_version: String,
    pub campaign: String,
    pub pipeline: PipelineRecord,
    pub inputs: Vec<InputFile>,
    pub model: ModelRecord,
    pub bars: Vec<BarSummary>,
    pub failed_bars: Vec<FailedBar>,
    pub reference: Option<ReferenceSummary>,
    /// What ingest dropped, counted and flagged, per bar, sensor, events and files.
    pub quality: crate::series::Quality,
}

#[derive(Debug, Serialize)]
pub struct PipelineRecord {
    pub name: String,
    pub path: Option<String>,
    pub sha256: Option<String>,
    pub stages: Vec<Stage>,
}

#[derive(Debug, Serialize)]
pub struct ModelRecord {
    pub effects: Vec<String>,
    /// Bin length of the compressed readings, s (0: every reading). The fits, RMS and sample
    /// counts are those of every reading either way (`series::bins`); residual statistics and
    /// figures then show the bins' nodes.
    pub bin_s: f64,
}

#[derive(Debug, Serialize)]
pub struct ParamValue {
    pub value: f64,
    pub u: f64,
    pub u_naive: f64,
    pub ci95: [f64; 2],
    /// Per end of `ci95`: the end is the time constants' search bound, not a limit set by the
    /// data ([`Estimate::ci95_at_search_bound`]).
    pub ci95_at_search_bound: [bool; 2],
}

#[derive(Debug, Serialize)]
pub struct BarSummary {
    pub bar: String,
    pub effects: Vec<String>,
    pub params: BTreeMap<String, ParamValue>,
    pub correlation: CorrelationRecord,
    pub rms_um: f64,
    pub n_samples: usize,
    pub dropped_outside_mounts: usize,
    pub hac_batch_samples: usize,
    /// The base paths' initial-state gains (nuisance parameters like the zeros: each lag's
    /// departure from steady state at the bar's first fitted sample times its expansion, ppm).
    pub initial_state: BTreeMap<String, ParamValue>,
    /// Parameters of the model's effects that this bar's data cannot determine (left out of its
    /// fit), with the reason: e.g. `beta_ppm_per_k` and `tau_s_s` of a bar mounted on one length.
    pub not_identifiable: Vec<crate::model::NotIdentifiable>,
}

#[derive(Debug, Serialize)]
pub struct CorrelationRecord {
    pub names: Vec<String>,
    pub matrix: Vec<Vec<f64>>,
}

#[derive(Debug, Serialize)]
pub struct FailedBar {
    pub bar: String,
    pub error: String,
}

#[derive(Debug, Serialize)]
pub struct ReferenceSummary {
    pub bar: String,
    pub rule: &'static str,
    pub compared_at_mm: f64,
    pub limit_um: f64,
    pub mismatch_um: BTreeMap<String, f64>,
    pub flagged: Vec<String>,
    pub scaled_distance_to_mean: BTreeMap<String, f64>,
}

fn param_value(e: &Estimate) -> ParamValue {
    ParamValue {
        value: e.value,
        u: e.u,
        u_naive: e.u_naive,
        ci95: e.ci95,
        ci95_at_search_bound: e.ci95_at_search_bound,
    }
}

pub fn summary(plan: &RunPlan, r: &RunResults) -> Summary {
    let bars = r
        .bars
        .iter()
        .map(|o| BarSummary {
            bar: o.model.bar.clone(),
            effects: o.model.effect_names(),
            params: o
                .model
                .params
                .iter()
                .map(|p| (p.name.clone(), param_value(p)))
                .collect(),
            correlation: CorrelationRecord {
                names: o.model.params.iter().map(|p| p.name.clone()).collect(),
                matrix: o.model.correlation.clone(),
            },
            rms_um: o.model.rms_um,
            n_samples: o.model.n_samples,
            dropped_outside_mounts: o.series.dropped_outside_mounts,
            hac_batch_samples: o.model.hac_batch_len,
            initial_state: o
                .model
                .initial_state
                .iter()
                .map(|p| (p.name.clone(), param_value(p)))
                .collect(),
            not_identifiable: o.model.not_identifiable.clone(),
        })
        .collect();
    let reference = r.reference.as_ref().map(|rr| ReferenceSummary {
        bar: rr.choice.bar.clone(),
        rule: if rr.choice.fleet_mean.iter().all(|v| v.is_finite()) {
            "nearest the fleet mean in (alpha, beta, tau_R, tau_S) scaled by the fleet standard deviation"
        } else {
            "nearest the fleet mean in (alpha, tau_R) scaled by the fleet standard deviation (beta and tau_S are not identifiable: every bar on one length)"
        },
        compared_at_mm: rr.distance_mm,
        limit_um: rr.limit_um,
        mismatch_um: rr.mismatches.iter().map(|m| (m.bar.clone(), m.max_abs_um)).collect(),
        flagged: rr.mismatches.iter().filter(|m| m.flagged).map(|m| m.bar.clone()).collect(),
        scaled_distance_to_mean: rr.choice.distance.iter().cloned().collect(),
    });
    Summary {
        dbbcal_version: env!("CARGO_PKG_VERSION").to_string(),
        campaign: r.campaign.id.clone(),
        pipeline: PipelineRecord {
            name: plan.pipeline_name.clone(),
            path: plan
                .pipeline_source
                .as_ref()
                .map(|(p, _)| p.display().to_string()),
            sha256: plan.pipeline_source.as_ref().map(|(_, h)| h.clone()),
            stages: plan.stages.clone(),
        },
        inputs: r.inputs.clone(),
        model: ModelRecord {
            effects: plan.effects.iter().map(Effect::name).collect(),
            bin_s: plan.bin_s,
        },
        bars,
        failed_bars: r
            .failed
            .iter()
            .map(|(bar, error)| FailedBar {
                bar: bar.clone(),
                error: error.clone(),
            })
            .collect(),
        reference,
        quality: r.quality.clone(),
    }
}

/// Refit each bar with the base model to show what the added effects bought.
fn before_after(bars: &[BarOutcome]) -> BeforeAfter {
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
fn run_diagnose(plan: &RunPlan, bars: &[BarOutcome]) -> Diagnosis {
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
    let (ledger, _) = timed("diagnose: fleet forward selection", || {
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
            .map(|((o, b), d)| {
                diagnose::forward_selection_of_bar(
                    &o.series,
                    o.model.clone(),
                    b,
                    d,
                    plan.diagnose.forward_steps,
                    plan.diagnose.beam,
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

/// `diagnosis.json`: per bar where the model fails, and the ranked candidate effects (every
/// `effect` string is accepted verbatim by `--add-effect`).
#[derive(Debug, Serialize)]
pub struct DiagnosisRecord<'a> {
    pub campaign: &'a str,
    pub model: ModelRecord,
    pub inputs: &'a [InputFile],
    pub bars: Vec<BarDiagnosisRecord<'a>>,
    /// What each temperature sensor plausibly measures, judged from its signal.
    pub sensors: &'a [diagnose::sensors::SensorProfile],
    /// When a candidate is proposed: significant and removing at least `min_gain_um` of the
    /// fleet RMS.
    pub criteria: &'a diagnose::Criteria,
    /// Every candidate: `verdict` proposed / immaterial / not_significant / screened_out, with
    /// its `reason`.
    pub candidates: &'a [Candidate],
    /// Candidates that could not be fitted on any bar, with the reason.
    pub unavailable: &'a [diagnose::Unavailable],
    /// Fleet-wide forward selection: one model for every bar.
    pub ledger: &'a [LedgerStep],
    /// Each bar's own forward selection.
    pub bar_ledgers: &'a [diagnose::BarLedger],
}

#[derive(Debug, Serialize)]
pub struct BarDiagnosisRecord<'a> {
    pub bar: &'a str,
    pub rms_um: f64,
    pub peak_to_valley_um: f64,
    pub fit_percent: f64,
    pub whiteness_p: f64,
    pub ljung_box_q: f64,
    pub residual_correlation_time_samples: f64,
    pub channels: Vec<ChannelRecord<'a>>,
}

#[derive(Debug, Serialize)]
pub struct ChannelRecord<'a> {
    pub channel: &'a str,
    pub explained_fraction: f64,
    pub tau_s: f64,
    pub description: String,
}

pub fn diagnosis_record<'a>(
    plan: &RunPlan,
    r: &'a RunResults,
    d: &'a Diagnosis,
) -> DiagnosisRecord<'a> {
    DiagnosisRecord {
        campaign: &r.campaign.id,
        model: ModelRecord {
            effects: plan.effects.iter().map(Effect::name).collect(),
            bin_s: plan.bin_s,
        },
        inputs: &r.inputs,
        bars: d
            .bars
            .iter()
            .map(|b| BarDiagnosisRecord {
                bar: &b.bar,
                rms_um: b.rms_um,
                peak_to_valley_um: b.stats.peak_to_valley_um,
                fit_percent: b.stats.fit_percent,
                whiteness_p: b.whiteness_p,
                ljung_box_q: b.stats.ljung_box_q,
                residual_correlation_time_samples: b.stats.correlation_time_samples,
                channels: b
                    .channels
                    .iter()
                    .map(|c| ChannelRecord {
                        channel: &c.channel,
                        explained_fraction: c.explained_fraction,
                        tau_s: c.tau_s,
                        description: diagnose::sensors::describe_channel_with(
                            &c.channel, &d.sensors,
                        ),
                    })
                    .collect(),
            })
            .collect(),
        sensors: &d.sensors,
        criteria: &d.criteria,
        candidates: &d.candidates,
        unavailable: &d.unavailable,
        ledger: &d.ledger,
        bar_ledgers: &d.bar_ledgers,
    }
}

#[cfg(test)]
mod plan_tests;
