//! The `volumetric` kind in the application: its pipeline file (`pipelines/volumetric.toml`),
//! its run (claim the output, read, analyse with `dbbcal_machine::volumetric::study`, write)
//! and its files (`volumetric.json`, `volumetric_grid.parquet`, `volumetric_functions.parquet`,
//! the FANUC 3-D table and the ISG CSV files, `figures/`, `report.md`, `index.html`).

pub(crate) mod figures;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::volumetric::model::VolumetricEffect;
use dbbcal_machine::volumetric::study::{self, VolumetricStudyOptions};

use crate::output::volumetric::{self as out, VolumetricRecord};
use crate::output::{Marker, OutputTarget, WriteFailure};
use crate::pipeline::PlanError;
use crate::runner::{Outcome, RunStatus};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    volumetric: Section,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PipelineSection {
    name: String,
    stages: Vec<String>,
    #[serde(default)]
    #[allow(dead_code)] // read by `kinds::campaign_dir` from the text
    campaign: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Section {
    #[serde(default = "default_effects")]
    effects: Vec<String>,
    #[serde(default = "default_forward_steps")]
    forward_steps: usize,
    #[serde(default = "default_min_bic_gain")]
    min_bic_gain: f64,
    #[serde(default)]
    tolerances: Tolerances,
}

impl Default for Section {
    fn default() -> Self {
        Section {
            effects: default_effects(),
            forward_steps: default_forward_steps(),
            min_bic_gain: default_min_bic_gain(),
            tolerances: Tolerances::default(),
        }
    }
}

fn default_effects() -> Vec<String> {
    vec!["pointing".into()]
}

fn default_forward_steps() -> usize {
    VolumetricStudyOptions::default().forward_steps
}

fn default_min_bic_gain() -> f64 {
    VolumetricStudyOptions::default().min_bic_gain
}

/// `[volumetric.tolerances]`: the user's tolerances for the ISO 14253-1 decisions (each
/// optional).
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct Tolerances {
    /// On V_diag, µm.
    pub(crate) v_diag_um: Option<f64>,
    /// On V1, µm.
    pub(crate) v1_um: Option<f64>,
    /// On V2, µm.
    pub(crate) v2_um: Option<f64>,
    /// On V3, µm.
    pub(crate) v3_um: Option<f64>,
    /// On each |squareness|, µrad.
    pub(crate) squareness_urad: Option<f64>,
}

/// A validated `volumetric` run.
#[derive(Debug, Clone)]
pub struct VolumetricPlan {
    pipeline_name: String,
    pipeline_path: PathBuf,
    pipeline_sha256: String,
    campaign_dir: PathBuf,
    out_dir: Option<PathBuf>,
    options: VolumetricStudyOptions,
    pub(crate) tolerances: Tolerances,
}

mod limits {
    use dbbcal_core::limits::{CountLimit, Limit};
    pub(super) const FORWARD_STEPS: CountLimit = CountLimit::new(0, 4);
    pub(super) const MIN_BIC_GAIN: Limit = Limit::closed(0.0, 1e6, "");
    pub(super) const TOLERANCE: Limit = Limit::closed(0.0, 1e6, "");
}

impl VolumetricPlan {
    /// Validate the pipeline `text` (of file `path`) for the campaign in `campaign_dir`.
    pub(crate) fn from_pipeline_text(
        path: &Path,
        text: &str,
        campaign_dir: PathBuf,
        out_dir: Option<PathBuf>,
        add_effects: &[String],
    ) -> Result<VolumetricPlan, PlanError> {
        let perr = |message: String| PlanError::Pipeline {
            path: path.display().to_string(),
            message,
        };
        let file: PipelineFile =
            toml::from_str(text).map_err(|e| perr(e.to_string().replace('\n', " ")))?;
        if file.pipeline.stages != ["volumetric"] {
            return Err(perr(format!(
                "pipeline.stages = {:?}: a volumetric campaign has one stage, [\"volumetric\"]",
                file.pipeline.stages
            )));
        }
        let v = &file.volumetric;
        limits::FORWARD_STEPS
            .check("volumetric.forward_steps", v.forward_steps)
            .map_err(|e| perr(e.to_string()))?;
        limits::MIN_BIC_GAIN
            .check("volumetric.min_bic_gain", v.min_bic_gain)
            .map_err(|e| perr(e.to_string()))?;
        let t = &v.tolerances;
        for (key, value) in [
            ("volumetric.tolerances.v_diag_um", t.v_diag_um),
            ("volumetric.tolerances.v1_um", t.v1_um),
            ("volumetric.tolerances.v2_um", t.v2_um),
            ("volumetric.tolerances.v3_um", t.v3_um),
            ("volumetric.tolerances.squareness_urad", t.squareness_urad),
        ] {
            if let Some(x) = value {
                limits::TOLERANCE
                    .check(key, x)
                    .map_err(|e| perr(e.to_string()))?;
            }
        }
        let mut effects = Vec::new();
        let named = v
            .effects
            .iter()
            .enumerate()
            .map(|(i, n)| (n, format!("volumetric.effects[{i}]")))
            .chain(add_effects.iter().map(|n| (n, "--add-effect".to_string())));
        for (name, key) in named {
            let e = VolumetricEffect::parse(name).ok_or_else(|| {
                perr(format!(
                    "{key}: {name:?} is not an effect of a volumetric campaign (known: {})",
                    VolumetricEffect::ALL.map(|e| e.name()).join(", ")
                ))
            })?;
            if !effects.contains(&e) {
                effects.push(e);
            }
        }
        Ok(VolumetricPlan {
            pipeline_name: file.pipeline.name,
            pipeline_path: path.to_path_buf(),
            pipeline_sha256: crate::pipeline::sha256_hex(text.as_bytes()),
            campaign_dir,
            out_dir,
            options: VolumetricStudyOptions {
                effects,
                forward_steps: v.forward_steps,
                min_bic_gain: v.min_bic_gain,
            },
            tolerances: v.tolerances.clone(),
        })
    }

    /// The command that adds `effect` to this run.
    pub(crate) fn next_command(&self, effect: VolumetricEffect) -> String {
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
pub(crate) fn run(plan: &VolumetricPlan) -> Result<Outcome> {
    let out = match &plan.out_dir {
        Some(o) => o.clone(),
        None => {
            let c = crate::io::read_volumetric_manifest(&plan.campaign_dir)?;
            PathBuf::from("reports").join(c.id)
        }
    };
    let target = OutputTarget::claim(&out, &plan.campaign_dir)?;
    let logs = crate::pipeline::timed("ingest", || {
        crate::io::read_volumetric_campaign(&plan.campaign_dir)
    })?;
    let study = crate::pipeline::timed("volumetric", || study::study(&logs, &plan.options))
        .with_context(|| format!("analysing {}", plan.campaign_dir.display()))?;
    let id = &logs.campaign.id;
    let pipeline = (plan.pipeline_name.as_str(), plan.pipeline_sha256.as_str());
    let decisions = out::decisions(&study, &plan.tolerances);
    let tables = out::controller_tables(&logs.campaign, &study)?;
    let record = VolumetricRecord::new(id, pipeline, &logs.inputs, &study, &decisions, &tables);
    let marker = Marker::new(
        id,
        serde_json::json!(["volumetric"]),
        serde_json::to_value(
            plan.options
                .effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>(),
        )?,
        serde_json::to_value(&logs.inputs)?,
    );
    let lines = crate::narrative::volumetric::headline(id, &study, &decisions, plan);
    target
        .write(&marker, |tmp| -> Result<()> {
            let mut json = serde_json::to_string_pretty(&record)?;
            json.push('\n');
            crate::output::write_file(&tmp.join("volumetric.json"), json.as_bytes())?;
            crate::io::write_table(
                &tmp.join("volumetric_grid.parquet"),
                &out::grid_table(&study),
            )?;
            crate::io::write_table(
                &tmp.join("volumetric_functions.parquet"),
                &out::functions_table(&study),
            )?;
            for (name, text) in &tables.files {
                crate::output::write_file(&tmp.join(name), text.as_bytes())?;
            }
            let figures = figures::render(&study, &tmp.join("figures"))?;
            let md =
                crate::narrative::volumetric::report_md(id, &study, &decisions, &tables, &lines);
            crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
            let page = crate::narrative::volumetric::page(
                id, &study, &decisions, &tables, &lines, &figures,
            );
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
