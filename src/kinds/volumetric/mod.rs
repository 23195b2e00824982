//! The `volumetric` kind in the application: its pipeline file (`pipelines/volumetric.toml`),
//! its run (claim the output, read, analyse with `dbbcal_machine::volumetric::study`, write)
//! and its files (`volumetric.json`, `volumetric_grid.parquet`, `volumetric_functions.parquet`,
//! `volumetric_bar.parquet` when a bar read body diagonals, the FANUC 3-D table and the ISG CSV
//! files, `figures/`, `report.md`, `index.html`). A bar-read diagonal that cannot be stitched
//! (no datum, segments that do not chain) is bad input, refused before any output is written.

pub(crate) mod figures;

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::volumetric::model::VolumetricEffect;
use dbbcal_machine::volumetric::study::{self, VolumetricStudyOptions};

use crate::output::volumetric::{self as out, VolumetricRecord};
use crate::pipeline::PlanError;
use crate::runner::Outcome;

use super::plan::{
    kind_effect, marker, write_json, write_output, Kind, PipelineFile, PipelineSection,
    PipelineText, PlanBase,
};

/// The `volumetric` kind's name in files and messages.
pub(crate) const KIND: Kind = Kind {
    stage: "volumetric",
    a_campaign: "a volumetric campaign",
};

/// A pipeline file for a `volumetric` campaign.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct VolumetricPipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    volumetric: Section,
}

impl PipelineFile for VolumetricPipelineFile {
    fn pipeline(&self) -> &PipelineSection {
        &self.pipeline
    }
}

kind_effect!(VolumetricEffect);

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
    #[serde(default)]
    scale_budget: ScaleBudgetSection,
}

impl Default for Section {
    fn default() -> Self {
        Section {
            effects: default_effects(),
            forward_steps: default_forward_steps(),
            min_bic_gain: default_min_bic_gain(),
            tolerances: Tolerances::default(),
            scale_budget: ScaleBudgetSection::default(),
        }
    }
}

/// `[volumetric.scale_budget]`: the standard uncertainties (k = 1) of the laser's environment
/// sensors and wavelength (`study::ScaleBudget`; each optional, its default a laser system's
/// stated accuracy taken as rectangular).
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct ScaleBudgetSection {
    air_k: Option<f64>,
    pressure_hpa: Option<f64>,
    humidity_pct: Option<f64>,
    material_k: Option<f64>,
    wavelength_ppm: Option<f64>,
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
    base: PlanBase,
    options: VolumetricStudyOptions,
    pub(crate) tolerances: Tolerances,
}

mod limits {
    use dbbcal_core::limits::{CountLimit, Limit};
    pub(super) const FORWARD_STEPS: CountLimit = CountLimit::new(0, 4);
    pub(super) const TOLERANCE: Limit = Limit::closed(0.0, 1e6, "");
    pub(super) const BUDGET: Limit = Limit::closed(0.0, 1e3, "");
}

impl VolumetricPlan {
    /// Validate the pipeline file `pt` for its campaign (`pt.kind` is [`KIND`]).
    pub(crate) fn from_pipeline(pt: &PipelineText) -> Result<VolumetricPlan, PlanError> {
        let file: VolumetricPipelineFile = pt.parse()?;
        let v = &file.volumetric;
        pt.check_selection(limits::FORWARD_STEPS, v.forward_steps, v.min_bic_gain)?;
        let t = &v.tolerances;
        for (key, value) in [
            ("volumetric.tolerances.v_diag_um", t.v_diag_um),
            ("volumetric.tolerances.v1_um", t.v1_um),
            ("volumetric.tolerances.v2_um", t.v2_um),
            ("volumetric.tolerances.v3_um", t.v3_um),
            ("volumetric.tolerances.squareness_urad", t.squareness_urad),
        ] {
            if let Some(x) = value {
                limits::TOLERANCE.check(key, x).map_err(|e| pt.range(e))?;
            }
        }
        let b = &v.scale_budget;
        let mut scale_budget = study::ScaleBudget::default();
        for (key, given, slot) in [
            (
                "volumetric.scale_budget.air_k",
                b.air_k,
                &mut scale_budget.air_k,
            ),
            (
                "volumetric.scale_budget.pressure_hpa",
                b.pressure_hpa,
                &mut scale_budget.pressure_hpa,
            ),
            (
                "volumetric.scale_budget.humidity_pct",
                b.humidity_pct,
                &mut scale_budget.humidity_pct,
            ),
            (
                "volumetric.scale_budget.material_k",
                b.material_k,
                &mut scale_budget.material_k,
            ),
            (
                "volumetric.scale_budget.wavelength_ppm",
                b.wavelength_ppm,
                &mut scale_budget.wavelength_ppm,
            ),
        ] {
            if let Some(x) = given {
                limits::BUDGET.check(key, x).map_err(|e| pt.range(e))?;
                *slot = x;
            }
        }
        let effects = pt.effects(&v.effects)?;
        Ok(VolumetricPlan {
            base: pt.base(&file.pipeline),
            options: VolumetricStudyOptions {
                effects,
                forward_steps: v.forward_steps,
                min_bic_gain: v.min_bic_gain,
                scale_budget,
            },
            tolerances: v.tolerances.clone(),
        })
    }

    /// The command that adds `effect` to this run.
    pub(crate) fn next_command(&self, effect: VolumetricEffect) -> String {
        self.base.next_command(&self.options.effects, effect)
    }
}

/// Claim the output, read and analyse the campaign, write the output folder.
pub(crate) fn run(plan: &VolumetricPlan) -> Result<Outcome> {
    let (out, target) = plan
        .base
        .claim_output(|dir| Ok(crate::io::read_volumetric_manifest(dir)?.id))?;
    let dir = &plan.base.campaign_dir;
    let logs = crate::pipeline::timed("ingest", || crate::io::read_volumetric_campaign(dir))?;
    let bars = study::bar::stitch_campaign(&logs)?;
    let study = crate::pipeline::timed("volumetric", || {
        study::study_with_bars(&logs, bars, &plan.options)
    })
    .with_context(|| format!("analysing {}", dir.display()))?;
    let id = &logs.campaign.id;
    let pipeline = plan.base.pipeline();
    let decisions = out::decisions(&study, &plan.tolerances);
    let tables = out::controller_tables(&logs.campaign, &study)?;
    let record = VolumetricRecord::new(id, pipeline, &logs.inputs, &study, &decisions, &tables);
    let marker = marker(id, KIND, &plan.options.effects, &logs.inputs)?;
    let lines = crate::narrative::volumetric::headline(id, &study, &decisions, plan);
    write_output(target, &marker, out, lines, |tmp, lines| {
        write_json(&tmp.join("volumetric.json"), &record)?;
        crate::io::write_table(
            &tmp.join("volumetric_grid.parquet"),
            &out::grid_table(&study),
        )?;
        crate::io::write_table(
            &tmp.join("volumetric_functions.parquet"),
            &out::functions_table(&study),
        )?;
        if !study.bars.is_empty() {
            crate::io::write_table(&tmp.join("volumetric_bar.parquet"), &out::bar_table(&study))?;
        }
        for (name, text) in &tables.files {
            crate::output::write_file(&tmp.join(name), text.as_bytes())?;
        }
        let figures = figures::render(&study, &tmp.join("figures"))?;
        let md = crate::narrative::volumetric::report_md(id, &study, &decisions, &tables, lines);
        crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
        let page =
            crate::narrative::volumetric::page(id, &study, &decisions, &tables, lines, &figures);
        crate::output::write_file(&tmp.join("index.html"), page.as_bytes())?;
        Ok(())
    })
}
