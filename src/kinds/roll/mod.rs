//! The `roll` kind in the application (seed 004): its pipeline file (`pipelines/roll.toml`), its
//! run (claim the output, read, analyse with `dbbcal_machine::roll`, write) and its files
//! (`roll.json`, `roll_stations.parquet`, `roll_dwells.parquet`, `figures/roll.png`,
//! `report.md`, `index.html`).

mod figure;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::roll::{self, RollEffect, RollOptions};

use crate::output::roll::{dwells_table, stations_table, RollRecord};
use crate::output::{Marker, OutputTarget, WriteFailure};
use crate::pipeline::PlanError;
use crate::runner::{Outcome, RunStatus};

/// A pipeline file for a `roll` campaign.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RollPipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    roll: RollSection,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PipelineSection {
    name: String,
    /// `["roll"]`: the only stage of this kind.
    stages: Vec<String>,
    #[serde(default)]
    #[allow(dead_code)] // read by `kinds::campaign_dir` from the text
    campaign: Option<PathBuf>,
}

/// `[roll]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RollSection {
    #[serde(default)]
    effects: Vec<String>,
    #[serde(default = "defaults::forward_steps")]
    forward_steps: usize,
    #[serde(default = "defaults::min_bic_gain")]
    min_bic_gain: f64,
    #[serde(default)]
    resolution_um: Option<f64>,
    #[serde(default = "defaults::level_u_urad")]
    level_u_urad: f64,
    #[serde(default = "defaults::plausible_roll_urad")]
    plausible_roll_urad: f64,
}

mod defaults {
    use dbbcal_machine::roll::RollOptions;
    pub(super) fn forward_steps() -> usize {
        RollOptions::default().forward_steps
    }
    pub(super) fn min_bic_gain() -> f64 {
        RollOptions::default().min_bic_gain
    }
    pub(super) fn level_u_urad() -> f64 {
        RollOptions::default().level_u_urad
    }
    pub(super) fn plausible_roll_urad() -> f64 {
        RollOptions::default().plausible_roll_urad
    }
}

impl Default for RollSection {
    fn default() -> Self {
        RollSection {
            effects: Vec::new(),
            forward_steps: defaults::forward_steps(),
            min_bic_gain: defaults::min_bic_gain(),
            resolution_um: None,
            level_u_urad: defaults::level_u_urad(),
            plausible_roll_urad: defaults::plausible_roll_urad(),
        }
    }
}

mod limits {
    use dbbcal_core::limits::{CountLimit, Limit};
    /// `[roll] forward_steps`.
    pub(super) const FORWARD_STEPS: CountLimit = CountLimit::new(0, 3);
    /// `[roll] min_bic_gain`.
    pub(super) const MIN_BIC_GAIN: Limit = Limit::closed(0.0, 1e6, "");
    /// `[roll] resolution_um`.
    pub(super) const RESOLUTION_UM: Limit = Limit::closed(0.0, 100.0, "µm");
    /// `[roll] level_u_urad`.
    pub(super) const LEVEL_U_URAD: Limit = Limit::above(0.0, 1e4, "µrad");
    /// `[roll] plausible_roll_urad`.
    pub(super) const PLAUSIBLE_ROLL_URAD: Limit = Limit::above(0.0, 1e6, "µrad");
}

/// A validated `roll` run.
#[derive(Debug, Clone)]
pub struct RollPlan {
    pipeline_name: String,
    pipeline_path: PathBuf,
    pipeline_sha256: String,
    campaign_dir: PathBuf,
    out_dir: Option<PathBuf>,
    options: RollOptions,
}

impl RollPlan {
    /// Validate the pipeline `text` (of file `path`) for the `roll` campaign in `campaign_dir`.
    pub(crate) fn from_pipeline_text(
        path: &Path,
        text: &str,
        campaign_dir: PathBuf,
        out_dir: Option<PathBuf>,
        add_effects: &[String],
    ) -> Result<RollPlan, PlanError> {
        let perr = |message: String| PlanError::Pipeline {
            path: path.display().to_string(),
            message,
        };
        let file: RollPipelineFile =
            toml::from_str(text).map_err(|e| perr(e.to_string().replace('\n', " ")))?;
        if file.pipeline.stages != ["roll"] {
            return Err(perr(format!(
                "pipeline.stages = {:?}: a roll campaign has one stage, [\"roll\"]",
                file.pipeline.stages
            )));
        }
        let r = &file.roll;
        let e = |e: dbbcal_core::limits::OutOfRange| perr(e.to_string());
        limits::FORWARD_STEPS
            .check("roll.forward_steps", r.forward_steps)
            .map_err(e)?;
        limits::MIN_BIC_GAIN
            .check("roll.min_bic_gain", r.min_bic_gain)
            .map_err(e)?;
        if let Some(q) = r.resolution_um {
            limits::RESOLUTION_UM
                .check("roll.resolution_um", q)
                .map_err(e)?;
        }
        limits::LEVEL_U_URAD
            .check("roll.level_u_urad", r.level_u_urad)
            .map_err(e)?;
        limits::PLAUSIBLE_ROLL_URAD
            .check("roll.plausible_roll_urad", r.plausible_roll_urad)
            .map_err(e)?;
        let mut effects = Vec::new();
        let named = r
            .effects
            .iter()
            .enumerate()
            .map(|(i, n)| (n, format!("roll.effects[{i}]")))
            .chain(add_effects.iter().map(|n| (n, "--add-effect".to_string())));
        for (name, key) in named {
            let effect = RollEffect::parse(name).ok_or_else(|| {
                perr(format!(
                    "{key}: {name:?} is not an effect of a roll campaign (known: {})",
                    RollEffect::ALL.map(|e| e.name()).join(", ")
                ))
            })?;
            if !effects.contains(&effect) {
                effects.push(effect);
            }
        }
        Ok(RollPlan {
            pipeline_name: file.pipeline.name,
            pipeline_path: path.to_path_buf(),
            pipeline_sha256: crate::pipeline::sha256_hex(text.as_bytes()),
            campaign_dir,
            out_dir,
            options: RollOptions {
                effects,
                forward_steps: r.forward_steps,
                min_bic_gain: r.min_bic_gain,
                resolution_um: r.resolution_um,
                level_u_urad: r.level_u_urad,
                plausible_roll_urad: r.plausible_roll_urad,
            },
        })
    }

    /// The command that adds `effect` to this run (same campaign, same output).
    pub(crate) fn next_command(&self, effect: RollEffect) -> String {
        let mut cmd = format!(
            "dbbcal run {} --campaign {}",
            self.pipeline_path.display(),
            self.campaign_dir.display()
        );
        if let Some(o) = &self.out_dir {
            cmd.push_str(&format!(" --out {}", o.display()));
        }
        for e in &self.options.effects {
            cmd.push_str(&format!(" --add-effect {}", e.name()));
        }
        cmd.push_str(&format!(" --add-effect {}", effect.name()));
        cmd
    }
}

/// Claim the output, read and analyse the campaign, write the output folder.
pub(crate) fn run(plan: &RollPlan) -> Result<Outcome> {
    let out = match &plan.out_dir {
        Some(o) => o.clone(),
        None => {
            let text = crate::io::read_small_text(
                &plan.campaign_dir.join("campaign.toml"),
                crate::io::MAX_MANIFEST_BYTES,
            )
            .map_err(anyhow::Error::msg)?;
            let c =
                dbbcal_core::roll_campaign::RollCampaign::from_toml_str(&text, "campaign.toml")?;
            PathBuf::from("reports").join(c.id)
        }
    };
    let target = OutputTarget::claim(&out, &plan.campaign_dir)?;
    let logs = crate::pipeline::timed("ingest", || {
        crate::io::read_roll_campaign(&plan.campaign_dir)
    })?;
    let study = crate::pipeline::timed("roll", || roll::study(&logs, &plan.options))
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("analysing {}", plan.campaign_dir.display()))?;
    let id = &logs.campaign.id;
    let inputs = &logs.inputs;
    let pipeline = (plan.pipeline_name.as_str(), plan.pipeline_sha256.as_str());
    let record = RollRecord::new(id, pipeline, inputs, &study);
    let marker = Marker::new(
        id,
        serde_json::json!(["roll"]),
        serde_json::to_value(
            plan.options
                .effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>(),
        )?,
        serde_json::to_value(inputs)?,
    );
    let lines = crate::narrative::roll::headline(id, &study, plan);
    let spec = figure::spec(id, &study);
    target
        .write(&marker, |tmp| -> Result<()> {
            let mut json = serde_json::to_string_pretty(&record)?;
            json.push('\n');
            crate::output::write_file(&tmp.join("roll.json"), json.as_bytes())?;
            crate::io::write_table(&tmp.join("roll_stations.parquet"), &stations_table(&study))?;
            crate::io::write_table(&tmp.join("roll_dwells.parquet"), &dwells_table(&study))?;
            let figures = tmp.join("figures");
            std::fs::create_dir_all(&figures)
                .with_context(|| format!("cannot create {}", figures.display()))?;
            figure::draw(&spec, &figures.join(figure::FILE))?;
            let md = crate::narrative::roll::report_md(id, &study);
            crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
            let page = crate::narrative::roll::page(id, &study, &lines, figure::FILE);
            crate::output::write_file(&tmp.join("index.html"), page.as_bytes())?;
            Ok(())
        })
        .map_err(|e| match e {
            WriteFailure::Build(e) => e,
            WriteFailure::Output(e) => anyhow::Error::from(e),
        })
        .with_context(|| format!("writing {}", out.display()))?;
    Ok(Outcome {
        status: RunStatus::AllBars,
        out: Some(out),
        headline: None,
        lines,
    })
}
