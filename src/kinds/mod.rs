//! Campaign kinds: where `dbbcal run` chooses what a campaign is (`[campaign] kind` of its
//! `campaign.toml`, `docs/spec/machine-formats.md`) and hands it to that kind's plan and run.
//! A new kind registers here, in [`plan_run`]'s `match` and [`KindPlan`]; the compiler then
//! points at [`run`]. Everything else of a kind lives in its own rooms (ARCHITECTURE.md, "A room
//! for a new kind").

pub mod axis;
pub mod probe;
pub mod roll;
pub mod volumetric;

mod plan;

use std::path::{Path, PathBuf};

use dbbcal_core::axis_campaign::CampaignKind;
use dbbcal_io::manifest::campaign_kind;

use plan::PipelineText;

use crate::pipeline::{PlanError, RunPlan, DEFAULT_CAMPAIGN_DIR};
use crate::runner::Outcome;

/// A validated plan of any kind.
#[derive(Debug, Clone)]
pub enum KindPlan {
    /// A ballbar campaign (`campaign-format.md`): the stages of [`crate::pipeline`].
    Ballbar(Box<RunPlan>),
    /// An `axis` campaign (seed 002).
    Axis(axis::AxisPlan),
    /// A `probe` campaign (seed 003).
    Probe(probe::ProbePlan),
    /// A `roll` campaign (seed 004).
    Roll(roll::RollPlan),
    /// A `volumetric` campaign (seed 001).
    Volumetric(volumetric::VolumetricPlan),
}

/// The campaign directory a run reads: `--campaign`, else the pipeline's `[pipeline] campaign`,
/// else the shipped sample.
fn campaign_dir(pipeline_text: &str, campaign: Option<PathBuf>) -> PathBuf {
    campaign
        .or_else(|| {
            let value: toml::Value = toml::from_str(pipeline_text).ok()?;
            value
                .get("pipeline")?
                .get("campaign")?
                .as_str()
                .map(PathBuf::from)
        })
        .unwrap_or_else(|| PathBuf::from(DEFAULT_CAMPAIGN_DIR))
}

/// Validate `dbbcal run PIPELINE`: read the campaign's kind (its manifest alone, no parquet),
/// then that kind's plan.
pub fn plan_run(
    pipeline: &Path,
    campaign: Option<PathBuf>,
    out: Option<PathBuf>,
    add_effects: &[String],
) -> Result<KindPlan, PlanError> {
    let shown = pipeline.display().to_string();
    let text =
        crate::io::read_small_text(pipeline, crate::io::MAX_PIPELINE_BYTES).map_err(|e| {
            PlanError::Pipeline {
                path: shown.clone(),
                message: e.to_string(),
            }
        })?;
    let dir = campaign_dir(&text, campaign);
    let manifest = dir.join("campaign.toml");
    let kind = match crate::io::read_small_text(&manifest, crate::io::MAX_MANIFEST_BYTES) {
        Ok(m) => campaign_kind(&m, &manifest.display().to_string())
            .map_err(|e| PlanError::Campaign(Box::new(e)))?,
        // The ballbar plan says what is wrong with a missing or unreadable manifest.
        Err(_) => CampaignKind::Ballbar,
    };
    let pt = |kind| PipelineText {
        path: pipeline,
        text: &text,
        kind,
        campaign_dir: dir.clone(),
        out_dir: out.clone(),
        add_effects,
    };
    match kind {
        // The ballbar plan takes `--add-effect` with the other model flags (`with_effects`).
        CampaignKind::Ballbar => Ok(KindPlan::Ballbar(Box::new(RunPlan::from_pipeline_file(
            pipeline,
            Some(dir.clone()),
            out.clone(),
            &[],
        )?))),
        // Say which kind the campaign is: a ballbar pipeline on it fails on its keys.
        CampaignKind::Axis => plan_kind(
            &pt(axis::KIND),
            axis::AxisPlan::from_pipeline,
            KindPlan::Axis,
        ),
        CampaignKind::Probe => plan_kind(
            &pt(probe::KIND),
            probe::ProbePlan::from_pipeline,
            KindPlan::Probe,
        ),
        CampaignKind::Roll => plan_kind(
            &pt(roll::KIND),
            roll::RollPlan::from_pipeline,
            KindPlan::Roll,
        ),
        // A volumetric pipeline's own mistakes need no pointer to the right pipeline.
        CampaignKind::Volumetric if names_stage(&text, "volumetric") => {
            volumetric::VolumetricPlan::from_pipeline(&pt(volumetric::KIND))
                .map(KindPlan::Volumetric)
        }
        CampaignKind::Volumetric => plan_kind(
            &pt(volumetric::KIND),
            volumetric::VolumetricPlan::from_pipeline,
            KindPlan::Volumetric,
        ),
    }
}

/// A machine kind's plan of `pt` as a [`KindPlan`], its pipeline errors saying which pipeline
/// runs the campaign.
fn plan_kind<P>(
    pt: &PipelineText,
    from_pipeline: fn(&PipelineText) -> Result<P, PlanError>,
    wrap: fn(P) -> KindPlan,
) -> Result<KindPlan, PlanError> {
    from_pipeline(pt)
        .map(wrap)
        .map_err(|e| pt.kind.pointed(&pt.campaign_dir, e))
}

/// Whether the pipeline text's `[pipeline] stages` is `[stage]`.
fn names_stage(pipeline_text: &str, stage: &str) -> bool {
    toml::from_str::<toml::Value>(pipeline_text)
        .ok()
        .and_then(|v| {
            let stages = v.get("pipeline")?.get("stages")?.as_array()?.clone();
            Some(stages.len() == 1 && stages[0].as_str() == Some(stage))
        })
        .unwrap_or(false)
}

/// Run a plan of a kind other than ballbar (ballbar plans run through [`crate::runner::run`]).
pub fn run(plan: &KindPlan) -> anyhow::Result<Outcome> {
    match plan {
        KindPlan::Ballbar(p) => crate::runner::run(p),
        KindPlan::Axis(p) => axis::run(p),
        KindPlan::Probe(p) => probe::run(p),
        KindPlan::Roll(p) => roll::run(p),
        KindPlan::Volumetric(p) => volumetric::run(p),
    }
}
