//! The `axis` kind in the application: its pipeline file (`pipelines/axis.toml`), its run
//! (claim the output, read, analyse with `dbbcal_machine::axis_study`, write) and its files
//! (`axis.json`, `axis_errors.parquet`, `report.md`, `index.html`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::axis_study::{self, AxisEffect, AxisStudyOptions};

use crate::output::axis::{errors_table, AxisRecord};
use crate::output::axis_tables::{axis_tables, AxisTableFormat, AxisTablesPlan};
use crate::output::controller::TableSign;
use crate::output::{Marker, OutputTarget, WriteFailure};
use crate::pipeline::PlanError;
use crate::runner::{Outcome, RunStatus};

/// A pipeline file for an `axis` campaign.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AxisPipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    axis: AxisSection,
    #[serde(default)]
    tables: TablesSection,
}

/// `[tables]`: controller compensation tables (`docs/controller-tables.md`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TablesSection {
    /// Format names of `AxisTableFormat`; empty: none.
    #[serde(default)]
    formats: Vec<String>,
    /// `error` or `correction` (= −error). No default: a table's sign is never silent.
    sign: Option<String>,
    /// The Siemens machine axis name (`$AA_ENC_COMP[0,N,<name>]`).
    #[serde(default = "default_siemens_axis")]
    siemens_axis: String,
}

impl Default for TablesSection {
    fn default() -> Self {
        TablesSection {
            formats: Vec::new(),
            sign: None,
            siemens_axis: default_siemens_axis(),
        }
    }
}

fn default_siemens_axis() -> String {
    "X1".into()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PipelineSection {
    name: String,
    /// `["axis"]`: the only stage of this kind.
    stages: Vec<String>,
    #[serde(default)]
    #[allow(dead_code)] // read by `kinds::campaign_dir` from the text
    campaign: Option<PathBuf>,
}

/// `[axis]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AxisSection {
    /// Effects in the model (names of `AxisEffect`).
    #[serde(default)]
    effects: Vec<String>,
    /// Steps of forward selection (0: rank only).
    #[serde(default = "default_forward_steps")]
    forward_steps: usize,
    /// BIC gain an effect needs to be proposed.
    #[serde(default = "default_min_bic_gain")]
    min_bic_gain: f64,
}

impl Default for AxisSection {
    fn default() -> Self {
        AxisSection {
            effects: Vec::new(),
            forward_steps: default_forward_steps(),
            min_bic_gain: default_min_bic_gain(),
        }
    }
}

fn default_forward_steps() -> usize {
    AxisStudyOptions::default().forward_steps
}

fn default_min_bic_gain() -> f64 {
    AxisStudyOptions::default().min_bic_gain
}

/// A validated `axis` run.
#[derive(Debug, Clone)]
pub struct AxisPlan {
    pipeline_name: String,
    pipeline_path: PathBuf,
    pipeline_sha256: String,
    campaign_dir: PathBuf,
    out_dir: Option<PathBuf>,
    options: AxisStudyOptions,
    tables: AxisTablesPlan,
}

mod limits {
    use dbbcal_core::limits::{CountLimit, Limit};
    /// `[axis] forward_steps`.
    pub(super) const FORWARD_STEPS: CountLimit = CountLimit::new(0, 5);
    /// `[axis] min_bic_gain`.
    pub(super) const MIN_BIC_GAIN: Limit = Limit::closed(0.0, 1e6, "");
}

impl AxisPlan {
    /// Validate the pipeline `text` (of file `path`) for the `axis` campaign in `campaign_dir`.
    pub(crate) fn from_pipeline_text(
        path: &Path,
        text: &str,
        campaign_dir: PathBuf,
        out_dir: Option<PathBuf>,
        add_effects: &[String],
    ) -> Result<AxisPlan, PlanError> {
        let perr = |message: String| PlanError::Pipeline {
            path: path.display().to_string(),
            message,
        };
        let file: AxisPipelineFile =
            toml::from_str(text).map_err(|e| perr(e.to_string().replace('\n', " ")))?;
        if file.pipeline.stages != ["axis"] {
            return Err(perr(format!(
                "pipeline.stages = {:?}: an axis campaign has one stage, [\"axis\"]",
                file.pipeline.stages
            )));
        }
        let a = &file.axis;
        limits::FORWARD_STEPS
            .check("axis.forward_steps", a.forward_steps)
            .map_err(|e| perr(e.to_string()))?;
        limits::MIN_BIC_GAIN
            .check("axis.min_bic_gain", a.min_bic_gain)
            .map_err(|e| perr(e.to_string()))?;
        let mut effects = Vec::new();
        let named = a
            .effects
            .iter()
            .enumerate()
            .map(|(i, n)| (n, format!("axis.effects[{i}]")))
            .chain(add_effects.iter().map(|n| (n, "--add-effect".to_string())));
        for (name, key) in named {
            let e = AxisEffect::parse(name).ok_or_else(|| {
                perr(format!(
                    "{key}: {name:?} is not an effect of an axis campaign (known: {})",
                    AxisEffect::ALL.map(|e| e.name()).join(", ")
                ))
            })?;
            if !effects.contains(&e) {
                effects.push(e);
            }
        }
        let tables = tables_plan(&file.tables).map_err(perr)?;
        Ok(AxisPlan {
            tables,
            pipeline_name: file.pipeline.name,
            pipeline_path: path.to_path_buf(),
            pipeline_sha256: crate::pipeline::sha256_hex(text.as_bytes()),
            campaign_dir,
            out_dir,
            options: AxisStudyOptions {
                effects,
                forward_steps: a.forward_steps,
                min_bic_gain: a.min_bic_gain,
            },
        })
    }
}

/// `[tables]` validated: known formats, each once, and a sign whenever a table is asked for.
fn tables_plan(t: &TablesSection) -> Result<AxisTablesPlan, String> {
    let mut formats = Vec::new();
    for (i, name) in t.formats.iter().enumerate() {
        let f = AxisTableFormat::parse(name).ok_or_else(|| {
            format!(
                "tables.formats[{i}]: {name:?} is not a table format of an axis run (known: {})",
                AxisTableFormat::ALL.map(|f| f.name()).join(", ")
            )
        })?;
        if formats.contains(&f) {
            return Err(format!("tables.formats[{i}]: {name:?} is listed twice"));
        }
        formats.push(f);
    }
    let sign = match (t.sign.as_deref(), formats.is_empty()) {
        (Some("error"), _) => TableSign::Error,
        (Some("correction"), _) => TableSign::Correction,
        (Some(other), _) => {
            return Err(format!(
                "tables.sign = {other:?}: \"error\" (the value is measured − commanded) or \"correction\" (−error)"
            ))
        }
        (None, true) => TableSign::Error,
        (None, false) => {
            return Err("tables.sign is missing: say whether the tables hold the error (\"error\") or the correction (\"correction\"); the controls listed in docs/controller-tables.md want the error".into())
        }
    };
    let name_ok = !t.siemens_axis.is_empty()
        && t.siemens_axis.len() <= 16
        && t.siemens_axis
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !name_ok {
        return Err(format!(
            "tables.siemens_axis = {:?}: 1 to 16 letters, digits or _",
            t.siemens_axis
        ));
    }
    Ok(AxisTablesPlan {
        formats,
        sign,
        siemens_axis: t.siemens_axis.clone(),
    })
}

/// Claim the output, read and analyse the campaign, write the output folder.
pub(crate) fn run(plan: &AxisPlan) -> Result<Outcome> {
    let out = match &plan.out_dir {
        Some(o) => o.clone(),
        None => {
            let text = crate::io::read_small_text(
                &plan.campaign_dir.join("campaign.toml"),
                crate::io::MAX_MANIFEST_BYTES,
            )
            .map_err(anyhow::Error::msg)?;
            let c =
                dbbcal_core::axis_campaign::AxisCampaign::from_toml_str(&text, "campaign.toml")?;
            PathBuf::from("reports").join(c.id)
        }
    };
    let target = OutputTarget::claim(&out, &plan.campaign_dir)?;
    let logs = crate::pipeline::timed("ingest", || {
        crate::io::read_axis_campaign(&plan.campaign_dir)
    })?;
    let study = crate::pipeline::timed("axis", || axis_study::study(&logs, &plan.options))
        .with_context(|| format!("analysing {}", plan.campaign_dir.display()))?;
    let inputs = &logs.inputs;
    let pipeline = (plan.pipeline_name.as_str(), plan.pipeline_sha256.as_str());
    let tables = axis_tables(&study, &plan.tables);
    let record = AxisRecord::new(&logs.campaign.id, pipeline, inputs, &study, &tables);
    let marker = Marker::new(
        &logs.campaign.id,
        serde_json::json!(["axis"]),
        serde_json::to_value(
            plan.options
                .effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>(),
        )?,
        serde_json::to_value(inputs)?,
    );
    let lines = crate::narrative::axis::headline(&logs.campaign.id, &study, plan, &tables);
    target
        .write(&marker, |tmp| -> Result<()> {
            let mut json = serde_json::to_string_pretty(&record)?;
            json.push('\n');
            crate::output::write_file(&tmp.join("axis.json"), json.as_bytes())?;
            crate::io::write_table(&tmp.join("axis_errors.parquet"), &errors_table(&study))?;
            let written: Vec<_> = tables
                .iter()
                .filter_map(|t| Some((t.file.as_ref()?, t.text.as_ref()?)))
                .collect();
            if !written.is_empty() {
                crate::output::create_dir(&tmp.join("tables"))?;
            }
            for (file, text) in written {
                crate::output::write_file(&tmp.join(file), text.as_bytes())?;
            }
            crate::output::create_dir(&tmp.join("figures"))?;
            let figures = [crate::figures::render_axis(
                &logs.campaign.id,
                &study,
                &tmp.join("figures"),
            )?];
            let md =
                crate::narrative::axis::report_md(&logs.campaign.id, &study, &figures, &tables);
            crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
            let page = crate::narrative::axis::page(&logs.campaign.id, &study, &lines, &figures);
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

impl AxisPlan {
    /// The command that adds `effect` to this run (same campaign, same output).
    pub(crate) fn next_command(&self, effect: AxisEffect) -> String {
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
