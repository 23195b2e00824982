//! The pipeline file (`pipelines/*.toml`): one section per stage, its defaults and limits, and
//! [`RunPlan`], its validated form, checked against the campaign manifest before any parquet file
//! is read.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::file::*;
use crate::campaign::Campaign;
use crate::model::Effect;
use dbbcal_core::limits::{CountLimit, Limit};

/// The stages a pipeline may run, in execution order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Read the campaign's parquet logs (always runs).
    Ingest,
    /// Fit each bar's thermal model (alpha, beta, tau_R, tau_S, and any added effects).
    Identify,
    /// Pick the reference bar nearest the fleet mean; predicted mismatches against it.
    Match,
    /// Mismatch of every pair of bars over the campaign's temperature history (heat map).
    MatchStudy,
    /// Where the model fails, the candidate effects ranked, forward selection.
    Diagnose,
    /// Tilt-dependent centre-distance functions on the plate's calibrated lengths.
    Calibrate,
    /// Working bars compensated by the reference bars.
    Compensate,
    /// Working bars accepted or not against the tolerance (the ISO 14253-1 decision rule,
    /// `dbbcal_core::acceptance`).
    Acceptance,
    /// The six errors of a machine axis from a hexapod device's compensated legs and the
    /// `positions` log (`docs/spec/device-format.md`).
    Device,
    /// The PNG figures, `report.md` and `index.html`.
    Report,
}

impl Stage {
    /// The stages `self` needs before it.
    pub(crate) fn with_prerequisites(self) -> Vec<Stage> {
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
            Device => vec![Ingest, Identify, Match, Calibrate, Compensate, Device],
            Report => vec![Ingest, Identify, Match, Report],
        }
    }
}

/// Errors that make a run impossible (unusable input or configuration).
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The pipeline file (`path`) cannot be read or is not valid; `message` says where.
    #[error("{path}: {message}")]
    Pipeline {
        /// The pipeline file.
        path: String,
        /// What is wrong, naming the key.
        message: String,
    },
    /// The campaign directory named does not exist or has no `campaign.toml`.
    #[error("campaign directory {0} does not exist or has no campaign.toml")]
    NoCampaign(String),
    /// An effect name (`--add-effect`, `[model] effects`) that is not understood.
    #[error("{0}")]
    Effect(#[from] crate::model::UnknownEffect),
    /// `campaign.toml` read at plan time (cheap, before any parquet file) is not usable.
    #[error(transparent)]
    Campaign(Box<crate::campaign::CampaignError>),
    /// The plan names something the campaign's manifest does not declare (one line, naming the
    /// key).
    #[error("{0}")]
    NotInCampaign(Box<PlanProblem>),
}

/// A value of a pipeline file or a command-line option that cannot be used: one line naming the
/// key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanProblem {
    /// A number outside its range (`dbbcal_core::limits`).
    #[error(transparent)]
    OutOfRange(#[from] dbbcal_core::limits::OutOfRange),
    /// A bin above 0 but shorter than `MIN_BIN_S`.
    #[error("{key} = {} is out of range: it must be 0 (every reading) or from {MIN_BIN_S} to {} s (a shorter bin compresses nothing and costs memory by the time span)", crate::campaign::display_number(*.bin_s), crate::series::MAX_BIN_S)]
    BinTooShort {
        /// The key (`model.bin_s`, `--bin-s`).
        key: String,
        /// The bin given, s.
        bin_s: f64,
    },
    /// More refit rounds than `MAX_SELECTION_ROUNDS`.
    #[error("diagnose.forward_steps × diagnose.beam = {forward_steps} × {beam} is out of range: the product must be at most {MAX_SELECTION_ROUNDS} (each step refits every path of the beam)")]
    TooManyRounds {
        /// `[diagnose] forward_steps`.
        forward_steps: usize,
        /// `[diagnose] beam`.
        beam: usize,
    },
    /// `[match] at_length` is not a plate length of the campaign.
    #[error(
        "{pipeline}: match.at_length = {id:?} is not a plate length of {manifest} (known: {known})"
    )]
    UnknownLength {
        /// The pipeline file.
        pipeline: String,
        /// The length named.
        id: String,
        /// The campaign's manifest.
        manifest: String,
        /// Its plate lengths, comma-separated (`none`).
        known: String,
    },
    /// `--effects` or `--bin-s` given for a machine kind's campaign.
    #[error(
        "--effects and --bin-s are for ballbar campaigns; this campaign's kind takes --add-effect"
    )]
    BallbarOptions,
    /// An effect's channel the campaign cannot provide.
    #[error("{key}: {effect:?}: no channel {channel:?} in {manifest} (sensors: {sensors}; or a difference A-B of two, event:KIND, {})", BUILT_IN_CHANNELS.join(", "))]
    UnknownChannel {
        /// Where the effect was named.
        key: String,
        /// The effect's name.
        effect: String,
        /// The channel.
        channel: String,
        /// The campaign's manifest.
        manifest: String,
        /// Its sensors, comma-separated (`none`).
        sensors: String,
    },
}

/// The allowed range of every number a pipeline file (or a command-line option) sets, checked
/// before any IO on the campaign: `(key, low, high, unit)`, both ends included. NaN and
/// infinities (TOML's `nan`, `inf`) are outside every range.
pub(crate) mod limits {
    use dbbcal_core::limits::{CountLimit, Limit};
    /// `[match] limit_um`, `[diagnose] tolerance_um`, `[acceptance] tolerance_um` (a ballbar's
    /// tolerances are microns; 1 mm is far beyond any).
    pub(crate) const TOLERANCE_UM: Limit = Limit::closed(1e-6, 1e3, "µm");
    /// `[match] study_step_s`: the measured-drift grid step (one second to a day).
    pub(crate) const STUDY_STEP_S: Limit = Limit::closed(1.0, 86_400.0, "s");
    /// `[acceptance] u_temperature_k`: standard uncertainty of the air temperature.
    pub(crate) const U_TEMPERATURE_K: Limit = Limit::closed(0.0, 10.0, "K");
    /// `[acceptance] max_gap_s`: one second to 30 days.
    pub(crate) const MAX_GAP_S: Limit = Limit::closed(1.0, 30.0 * 86_400.0, "s");
    /// A starting time constant (`[[model.term]] tau_s`, the `@TAU_S` of an effect name): the
    /// range the model evaluates time constants in (`ln tau` clamped to [0, ln 1e9]).
    pub(crate) const TAU_S: Limit = Limit::closed(1.0, 1e9, "s");
    /// `[model] bin_s`, `--bin-s`: 0 (every reading) or [`super::MIN_BIN_S`] to
    /// [`crate::series::MAX_BIN_S`] (the gap is checked by `check_bin_s`).
    pub(crate) const BIN_S: Limit = Limit::closed(0.0, crate::series::MAX_BIN_S, "s");
    /// `[diagnose] forward_steps` (0: rank the candidates only).
    pub(crate) const FORWARD_STEPS: CountLimit = CountLimit::new(0, 10);
    /// `[device] min_bic_gain`: the BIC gain the device's loop needs to propose an effect.
    pub(crate) const DEVICE_MIN_BIC_GAIN: Limit = Limit::closed(0.0, 1e6, "");
    /// `[diagnose] beam` (1: plain greedy selection).
    pub(crate) const BEAM: CountLimit = CountLimit::new(1, 10);
}

/// The table of `docs/guarantees.md` ("Configuration and fits"), made from the `limits` the
/// checks use: `| key | allowed |`, one row a limit (tests/e2e/docs.rs holds the doc to it).
pub fn limits_table() -> String {
    use limits::*;
    let bins = format!(
        "0 (every reading) or {}",
        Limit::closed(MIN_BIN_S, crate::series::MAX_BIN_S, "s").describe()
    );
    let rows: [(&str, String); 11] = [
        (
            "`[match] limit_um`, `[diagnose] tolerance_um`, `[acceptance] tolerance_um`",
            TOLERANCE_UM.describe(),
        ),
        ("`[match] study_step_s`", STUDY_STEP_S.describe()),
        ("`[model] bin_s`, `--bin-s`", bins),
        (
            "`[[model.term]] tau_s`, `lag:CH@TAU_S` (also `rate:`, `level:`)",
            TAU_S.describe(),
        ),
        ("`[diagnose] forward_steps`", FORWARD_STEPS.describe()),
        ("`[diagnose] beam`", BEAM.describe()),
        (
            "`[diagnose] forward_steps` × `beam`",
            format!("at most {MAX_SELECTION_ROUNDS}"),
        ),
        ("`[acceptance] u_temperature_k`", U_TEMPERATURE_K.describe()),
        ("`[acceptance] max_gap_s`", MAX_GAP_S.describe()),
        ("`[device] min_bic_gain`", DEVICE_MIN_BIC_GAIN.describe()),
        ("`[device] min_effect_um`", TOLERANCE_UM.describe()),
    ];
    let mut table = String::from("| key | allowed |\n|---|---|\n");
    for (key, allowed) in rows {
        table.push_str(&format!("| {key} | {allowed} |\n"));
    }
    table
}

/// `value` within `limit`, or the one-line message that names `key` and the range.
fn check_range(key: &str, value: f64, limit: Limit) -> Result<(), PlanProblem> {
    Ok(limit.check(key, value)?)
}

/// `value` within `limit`, or the one-line message that names `key` and the range.
fn check_count(key: &str, value: usize, limit: CountLimit) -> Result<(), PlanProblem> {
    Ok(limit.check(key, value)?)
}

impl PipelineFile {
    /// Every number of the file in its range ([`limits`]); the message names the key.
    pub(crate) fn check_numbers(&self) -> Result<(), PlanProblem> {
        use limits::*;
        let m = &self.matching;
        check_range("match.limit_um", m.limit_um, TOLERANCE_UM)?;
        check_range("match.study_step_s", m.study_step_s, STUDY_STEP_S)?;
        let d = &self.diagnose;
        check_count("diagnose.forward_steps", d.forward_steps, FORWARD_STEPS)?;
        check_count("diagnose.beam", d.beam, BEAM)?;
        check_selection(d.forward_steps, d.beam)?;
        if let Some(t) = d.tolerance_um {
            check_range("diagnose.tolerance_um", t, TOLERANCE_UM)?;
        }
        let a = &self.acceptance;
        check_range("acceptance.tolerance_um", a.tolerance_um, TOLERANCE_UM)?;
        check_range(
            "acceptance.u_temperature_k",
            a.u_temperature_k,
            U_TEMPERATURE_K,
        )?;
        check_range("acceptance.max_gap_s", a.max_gap_s, MAX_GAP_S)?;
        check_range(
            "device.min_bic_gain",
            self.device.min_bic_gain,
            DEVICE_MIN_BIC_GAIN,
        )?;
        check_range(
            "device.min_effect_um",
            self.device.min_effect_um,
            TOLERANCE_UM,
        )?;
        if let Some(bin_s) = self.model.bin_s {
            check_bin_s("model.bin_s", bin_s)?;
        }
        for (i, t) in self.model.term.iter().enumerate() {
            if let Some(tau) = t.tau_s {
                check_range(&format!("model.term[{i}].tau_s"), tau, TAU_S)?;
            }
        }
        Ok(())
    }
}

/// The campaign a plan reads when neither the pipeline file nor the command line names one: the
/// shipped sample.
pub const DEFAULT_CAMPAIGN_DIR: &str = "data/sample";

/// A bin length (`[model] bin_s`, `--bin-s`): 0 (every reading) to [`crate::series::MAX_BIN_S`].
/// A bin shorter than [`MIN_BIN_S`] (but 0) is refused: it compresses no logger's readings and
/// its cost grows with the campaign's time span divided by the bin.
pub(crate) fn check_bin_s(key: &str, bin_s: f64) -> Result<(), PlanProblem> {
    check_range(key, bin_s, limits::BIN_S)?;
    if bin_s > 0.0 && bin_s < MIN_BIN_S {
        return Err(PlanProblem::BinTooShort {
            key: key.to_string(),
            bin_s,
        });
    }
    Ok(())
}

/// The shortest bin (s) other than 0.
pub(crate) const MIN_BIN_S: f64 = 1.0;

/// `[diagnose] forward_steps × beam`: the refit rounds of forward selection, bounded so that the
/// diagnosis' cost is (`docs/guarantees.md`, "Configuration and fits").
pub(crate) const MAX_SELECTION_ROUNDS: usize = 12;

fn check_selection(forward_steps: usize, beam: usize) -> Result<(), PlanProblem> {
    if forward_steps.saturating_mul(beam) > MAX_SELECTION_ROUNDS {
        Err(PlanProblem::TooManyRounds {
            forward_steps,
            beam,
        })
    } else {
        Ok(())
    }
}

/// An effect's starting time constant (`@TAU_S`) in [`limits::TAU_S`].
fn check_effect(e: &Effect) -> Result<(), PlanProblem> {
    match e {
        Effect::Channel {
            tau0_s: Some(tau), ..
        } => check_range(
            &format!("{:?}: the starting time constant @TAU_S", e.name()),
            *tau,
            limits::TAU_S,
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
) -> Result<(), PlanProblem> {
    let listed = |ids: Vec<&str>| {
        if ids.is_empty() {
            "none".to_string()
        } else {
            ids.join(", ")
        }
    };
    if let Some(id) = &matching.at_length {
        if !campaign.plate.lengths.iter().any(|l| &l.id == id) {
            return Err(PlanProblem::UnknownLength {
                pipeline: pipeline_path.to_string(),
                id: id.clone(),
                manifest: manifest_path.to_string(),
                known: listed(
                    campaign
                        .plate
                        .lengths
                        .iter()
                        .map(|l| l.id.as_str())
                        .collect(),
                ),
            });
        }
    }
    for (e, key) in effects {
        if let Effect::Channel { channel, .. } = e {
            if !channel_declared(campaign, channel) {
                return Err(PlanProblem::UnknownChannel {
                    key: key.clone(),
                    effect: e.name(),
                    channel: channel.clone(),
                    manifest: manifest_path.to_string(),
                    sensors: listed(campaign.sensors.iter().map(|s| s.id.as_str()).collect()),
                });
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
    let text = crate::io::read_small_text(&path, crate::io::MAX_MANIFEST_BYTES).map_err(|e| {
        PlanError::Pipeline {
            path: file.clone(),
            message: e.to_string(),
        }
    })?;
    let boxed = |e| PlanError::Campaign(Box::new(e));
    use crate::io::manifest::TomlManifest;
    let manifest = crate::campaign::Manifest::from_toml_str(&text, &file).map_err(boxed)?;
    let campaign = Campaign::from_manifest_at(manifest, &file).map_err(boxed)?;
    Ok((campaign, file))
}

/// A validated run: what to read, what to do, where to write.
#[derive(Debug, Clone)]
pub struct RunPlan {
    pub(crate) pipeline_name: String,
    /// The pipeline file and its hash (`None` for stage subcommands).
    pub(crate) pipeline_source: Option<(PathBuf, String)>,
    pub(crate) stages: Vec<Stage>,
    pub(crate) campaign_dir: PathBuf,
    /// `None`: `reports/<campaign id>`, decided after the manifest is read.
    pub(crate) out_dir: Option<PathBuf>,
    pub(crate) effects: Vec<Effect>,
    /// Bin length of the compressed readings, s (0: every reading).
    pub(crate) bin_s: f64,
    /// `bin_s` is chosen from the campaign before ingest (`io::automatic_bin_s`; the runner
    /// replaces it): no `[model] bin_s` or `--bin-s` was given.
    pub(crate) automatic_bins: bool,
    pub(crate) matching: MatchSection,
    /// `[diagnose]`, as given or defaulted.
    pub(crate) diagnose: DiagnoseSection,
    pub(crate) acceptance: AcceptanceSection,
    pub(crate) report: ReportSection,
    pub(crate) output: OutputSection,
    /// The device stage's loop: its effects and proposal threshold.
    pub(crate) device: dbbcal_machine::device_study::DeviceStudyOptions,
    /// The controller tables the device stage writes (`[tables]`; none by default).
    pub(crate) tables: crate::output::axis_tables::AxisTablesPlan,
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
        let text = crate::io::read_small_text(path, crate::io::MAX_PIPELINE_BYTES)
            .map_err(|e| perr(e.to_string()))?;
        let file: PipelineFile =
            toml::from_str(&text).map_err(|e| perr(e.to_string().replace('\n', " ")))?;
        if file.pipeline.stages.is_empty() {
            return Err(perr("pipeline.stages is empty".into()));
        }
        // Every number first, before anything of the campaign is touched.
        file.check_numbers().map_err(|p| perr(p.to_string()))?;
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
            .unwrap_or_else(|| PathBuf::from(DEFAULT_CAMPAIGN_DIR));
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
        let keyed: Vec<(String, String)> = file
            .device
            .effects
            .iter()
            .enumerate()
            .map(|(i, e)| (e.clone(), format!("{}: device.effects[{i}]", shown(path))))
            .collect();
        plan.device = dbbcal_machine::device_study::DeviceStudyOptions {
            effects: device_effects(&keyed)?,
            min_bic_gain: file.device.min_bic_gain,
            min_effect_um: file.device.min_effect_um,
        };
        plan.tables = crate::output::axis_tables::tables_plan(&file.tables)
            .map_err(|e| perr(e.to_string()))?;
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
            device: Default::default(),
            tables: Default::default(),
        })
    }

    pub(crate) fn runs(&self, stage: Stage) -> bool {
        self.stages.contains(&stage)
    }

    /// The plan with `[diagnose] forward_steps = steps`, range-checked like the pipeline file's.
    pub fn with_forward_steps(mut self, steps: usize) -> Result<RunPlan, PlanError> {
        check_count("diagnose.forward_steps", steps, limits::FORWARD_STEPS)
            .and_then(|()| check_selection(steps, self.diagnose.beam))
            .map_err(|problem| PlanError::Pipeline {
                path: "the plan".into(),
                message: problem.to_string(),
            })?;
        self.diagnose.forward_steps = steps;
        Ok(self)
    }

    /// The plan with the bin length chosen for it (the runner's automatic choice, after the
    /// plan was validated: within [`check_bin_s`]'s range by construction).
    pub(crate) fn with_chosen_bins(&self, bin_s: f64) -> RunPlan {
        RunPlan {
            bin_s,
            automatic_bins: false,
            ..self.clone()
        }
    }

    /// The command line's `--bin-s`, range-checked like `[model] bin_s`; `None` keeps the plan's.
    pub fn with_bin_s(mut self, bin_s: Option<f64>) -> Result<RunPlan, PlanError> {
        if let Some(bin_s) = bin_s {
            check_bin_s("--bin-s", bin_s).map_err(|problem| PlanError::Pipeline {
                path: "the command line".into(),
                message: problem.to_string(),
            })?;
            (self.bin_s, self.automatic_bins) = (bin_s, false);
        }
        Ok(self)
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
        // The device's loop has effects of its own: `--add-effect` names either kind.
        let (device, add): (Vec<&String>, Vec<&String>) = add.iter().partition(|e| {
            self.runs(Stage::Device)
                && dbbcal_machine::device_study::DeviceEffect::parse(e).is_some()
        });
        let device: Vec<(String, String)> = device
            .into_iter()
            .map(|e| (e.clone(), "--add-effect".to_string()))
            .collect();
        for e in device_effects(&device)? {
            if !self.device.effects.contains(&e) {
                self.device.effects.push(e);
            }
        }
        names.extend(
            add.iter()
                .map(|e| ((*e).clone(), "--add-effect".to_string())),
        );
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
        let e = Effect::parse(n).map_err(|err| PlanError::Pipeline {
            path: key.clone(),
            message: effect_parse_message(n, &err),
        })?;
        check_effect(&e).map_err(|problem| PlanError::Pipeline {
            path: key.clone(),
            message: problem.to_string(),
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
        .map_err(|p| PlanError::NotInCampaign(Box::new(p)))?;
    Ok(keyed.into_iter().map(|(e, _)| e).collect())
}

/// Why `name` is no effect: for a `@TAU_S` that is a number out of range (`lag:T1@0`,
/// `@nan`), the allowed range; else the parser's message (the known effects).
fn effect_parse_message(name: &str, err: &crate::model::UnknownEffect) -> String {
    name.rsplit_once('@')
        .and_then(|(_, tau)| tau.trim().parse::<f64>().ok())
        .and_then(|tau| {
            check_range(
                &format!("{name:?}: the starting time constant @TAU_S"),
                tau,
                limits::TAU_S,
            )
            .err()
        })
        .map_or_else(|| err.to_string(), |problem| problem.to_string())
}

pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}
