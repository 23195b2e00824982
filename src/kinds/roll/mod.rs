//! The `roll` kind in the application (seed 004): its pipeline file (`pipelines/roll.toml`), its
//! run (claim the output, read, analyse with `dbbcal_machine::roll`, write) and its files
//! (`roll.json`, `roll_stations.parquet`, `roll_dwells.parquet`, `figures/roll.png`,
//! `report.md`, `index.html`).

mod figure;

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::roll::{self, RollEffect, RollOptions};

use crate::output::roll::{dwells_table, stations_table, RollRecord};
use crate::pipeline::PlanError;
use crate::runner::Outcome;

use super::plan::{
    kind_effect, manifest_text, marker, write_json, write_output, Kind, PipelineFile,
    PipelineSection, PipelineText, PlanBase,
};

/// The `roll` kind's name in files and messages.
pub(crate) const KIND: Kind = Kind {
    stage: "roll",
    a_campaign: "a roll campaign",
};

/// A pipeline file for a `roll` campaign.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RollPipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    roll: RollSection,
}

impl PipelineFile for RollPipelineFile {
    fn pipeline(&self) -> &PipelineSection {
        &self.pipeline
    }
}

kind_effect!(RollEffect);

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
    base: PlanBase,
    options: RollOptions,
}

impl RollPlan {
    /// Validate the pipeline file `pt` for its campaign (`pt.kind` is [`KIND`]).
    pub(crate) fn from_pipeline(pt: &PipelineText) -> Result<RollPlan, PlanError> {
        let file: RollPipelineFile = pt.parse()?;
        let r = &file.roll;
        let e = |e: dbbcal_core::limits::OutOfRange| pt.range(e);
        pt.check_selection(limits::FORWARD_STEPS, r.forward_steps, r.min_bic_gain)?;
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
        let effects = pt.effects(&r.effects)?;
        Ok(RollPlan {
            base: pt.base(&file.pipeline),
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
        self.base.next_command(&self.options.effects, effect)
    }
}

/// Claim the output, read and analyse the campaign, write the output folder.
pub(crate) fn run(plan: &RollPlan) -> Result<Outcome> {
    let (out, target) = plan.base.claim_output(|dir| {
        let text = manifest_text(dir)?;
        use dbbcal_io::manifest::TomlCampaign;
        let c = dbbcal_core::roll_campaign::RollCampaign::from_toml_str(&text, "campaign.toml")?;
        Ok(c.id)
    })?;
    let dir = &plan.base.campaign_dir;
    let logs = crate::pipeline::timed("ingest", || crate::io::read_roll_campaign(dir))?;
    let study = crate::pipeline::timed("roll", || roll::study(&logs, &plan.options))
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("analysing {}", dir.display()))?;
    let id = &logs.campaign.id;
    let record = RollRecord::new(id, plan.base.pipeline(), &logs.inputs, &study);
    let marker = marker(id, KIND, &plan.options.effects, &logs.inputs)?;
    let lines = crate::narrative::roll::headline(id, &study, plan);
    let spec = figure::spec(id, &study);
    write_output(target, &marker, out, lines, |tmp, lines| {
        write_json(&tmp.join("roll.json"), &record)?;
        crate::io::write_table(&tmp.join("roll_stations.parquet"), &stations_table(&study))?;
        crate::io::write_table(&tmp.join("roll_dwells.parquet"), &dwells_table(&study))?;
        let figures = tmp.join("figures");
        std::fs::create_dir_all(&figures)
            .with_context(|| format!("cannot create {}", figures.display()))?;
        figure::draw(&spec, &figures.join(figure::FILE))?;
        let md = crate::narrative::roll::report_md(id, &study);
        crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
        let page = crate::narrative::roll::page(id, &study, lines, figure::FILE);
        crate::output::write_file(&tmp.join("index.html"), page.as_bytes())?;
        Ok(())
    })
}
