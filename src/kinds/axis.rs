//! The `axis` kind in the application: its pipeline file (`pipelines/axis.toml`), its run
//! (claim the output, read, analyse with `dbbcal_machine::axis_study`, write) and its files
//! (`axis.json`, `axis_errors.parquet`, `report.md`, `index.html`).

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_core::limits::CountLimit;

use dbbcal_machine::axis_study::{self, AxisEffect, AxisStudyOptions};

use crate::output::axis::{errors_table, AxisRecord};
use crate::output::axis_tables::{axis_tables, tables_plan, AxisTablesPlan, TablesSection};
use crate::pipeline::PlanError;
use crate::runner::Outcome;

use super::plan::{
    kind_effect, manifest_text, marker, write_json, write_output, Kind, PipelineFile,
    PipelineSection, PipelineText, PlanBase,
};

/// The `axis` kind's name in files and messages.
pub(crate) const KIND: Kind = Kind {
    stage: "axis",
    a_campaign: "an axis campaign",
};

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

impl PipelineFile for AxisPipelineFile {
    fn pipeline(&self) -> &PipelineSection {
        &self.pipeline
    }
}

kind_effect!(AxisEffect);

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
    base: PlanBase,
    options: AxisStudyOptions,
    tables: AxisTablesPlan,
}

/// `[axis] forward_steps`.
const FORWARD_STEPS: CountLimit = CountLimit::new(0, 5);

impl AxisPlan {
    /// Validate the pipeline file `pt` for its campaign (`pt.kind` is [`KIND`]).
    pub(crate) fn from_pipeline(pt: &PipelineText) -> Result<AxisPlan, PlanError> {
        let file: AxisPipelineFile = pt.parse()?;
        let a = &file.axis;
        pt.check_selection(FORWARD_STEPS, a.forward_steps, a.min_bic_gain)?;
        let effects = pt.effects(&a.effects)?;
        let tables = tables_plan(&file.tables).map_err(|e| pt.error(e.to_string()))?;
        Ok(AxisPlan {
            tables,
            base: pt.base(&file.pipeline),
            options: AxisStudyOptions {
                effects,
                forward_steps: a.forward_steps,
                min_bic_gain: a.min_bic_gain,
            },
        })
    }
}

/// Claim the output, read and analyse the campaign, write the output folder.
pub(crate) fn run(plan: &AxisPlan) -> Result<Outcome> {
    let (out, target) = plan.base.claim_output(|dir| {
        let text = manifest_text(dir)?;
        use dbbcal_io::manifest::TomlCampaign;
        let c = dbbcal_core::axis_campaign::AxisCampaign::from_toml_str(&text, "campaign.toml")?;
        Ok(c.id)
    })?;
    let dir = &plan.base.campaign_dir;
    let logs = crate::pipeline::timed("ingest", || crate::io::read_axis_campaign(dir))?;
    let study = crate::pipeline::timed("axis", || axis_study::study(&logs, &plan.options))
        .with_context(|| format!("analysing {}", dir.display()))?;
    let id = &logs.campaign.id;
    let tables = axis_tables(&study, &plan.tables);
    let record = AxisRecord::new(id, plan.base.pipeline(), &logs.inputs, &study, &tables);
    let marker = marker(id, KIND, &plan.options.effects, &logs.inputs)?;
    let lines = crate::narrative::axis::headline(id, &study, plan, &tables);
    write_output(target, &marker, out, lines, |tmp, lines| {
        write_json(&tmp.join("axis.json"), &record)?;
        crate::io::write_table(&tmp.join("axis_errors.parquet"), &errors_table(&study))?;
        crate::output::axis_tables::write_tables(tmp, &tables)?;
        crate::output::create_dir(&tmp.join("figures"))?;
        let figures = [crate::figures::render_axis(
            id,
            &study,
            &tmp.join("figures"),
        )?];
        let md = crate::narrative::axis::report_md(id, &study, &figures, &tables);
        crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
        let page = crate::narrative::axis::page(id, &study, lines, &figures);
        crate::output::write_file(&tmp.join("index.html"), page.as_bytes())?;
        Ok(())
    })
}

impl AxisPlan {
    /// The command that adds `effect` to this run (same campaign, same output).
    pub(crate) fn next_command(&self, effect: AxisEffect) -> String {
        self.base.next_command(&self.options.effects, effect)
    }
}
