//! The `probe` kind in the application: its pipeline file (`pipelines/probe.toml`), its run
//! (claim the output, read, analyse with `dbbcal_machine::probe`, write) and its files
//! (`probe.json`, `probe_directions.parquet`, `probe_touches.parquet`, `report.md`,
//! `index.html`, `figures/probe-polar-*.png`), and the polar figure's spec.

use std::path::Path;

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::probe::{self, Lobing, ProbeEffect, ProbeStudy, ProbeStudyOptions, SetupStudy};

use crate::output::probe::{directions_table, touches_table, ProbeRecord};
use crate::pipeline::PlanError;
use crate::runner::Outcome;

use super::plan::{
    kind_effect, marker, write_json, write_output, Kind, PipelineFile, PipelineSection,
    PipelineText, PlanBase,
};

/// The `probe` kind's name in files and messages.
pub(crate) const KIND: Kind = Kind {
    stage: "probe",
    a_campaign: "a probe campaign",
};

/// A pipeline file for a `probe` campaign.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProbePipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    probe: ProbeSection,
}

impl PipelineFile for ProbePipelineFile {
    fn pipeline(&self) -> &PipelineSection {
        &self.pipeline
    }
}

kind_effect!(ProbeEffect);

/// `[probe]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProbeSection {
    /// Effects in the model (names of `ProbeEffect`).
    #[serde(default)]
    effects: Vec<String>,
    /// `physical` (seed eqs. 10–11) or `harmonic`.
    #[serde(default = "default_lobing")]
    lobing: String,
    /// Steps of forward selection (0: rank only).
    #[serde(default = "default_forward_steps")]
    forward_steps: usize,
    /// BIC gain an effect needs to be proposed.
    #[serde(default = "default_min_bic_gain")]
    min_bic_gain: f64,
    /// The probe's MPE for the form error P, µm; absent: no decision.
    #[serde(default)]
    mpe_um: Option<f64>,
}

impl Default for ProbeSection {
    fn default() -> Self {
        ProbeSection {
            effects: Vec::new(),
            lobing: default_lobing(),
            forward_steps: default_forward_steps(),
            min_bic_gain: default_min_bic_gain(),
            mpe_um: None,
        }
    }
}

fn default_lobing() -> String {
    "physical".into()
}

fn default_forward_steps() -> usize {
    ProbeStudyOptions::default().forward_steps
}

fn default_min_bic_gain() -> f64 {
    ProbeStudyOptions::default().min_bic_gain
}

/// The limits of `[probe]` (the one vocabulary, `dbbcal_core::limits`).
pub(crate) mod limits {
    use dbbcal_core::limits::{CountLimit, Limit};
    /// `[probe] forward_steps`.
    pub(crate) const FORWARD_STEPS: CountLimit = CountLimit::new(0, 5);
    /// `[probe] mpe_um`.
    pub(crate) const MPE_UM: Limit = Limit::above(0.0, 1_000.0, "µm");
}

/// A validated `probe` run.
#[derive(Debug, Clone)]
pub struct ProbePlan {
    base: PlanBase,
    pub(crate) options: ProbeStudyOptions,
}

impl ProbePlan {
    /// Validate the pipeline file `pt` for its campaign (`pt.kind` is [`KIND`]).
    pub(crate) fn from_pipeline(pt: &PipelineText) -> Result<ProbePlan, PlanError> {
        let file: ProbePipelineFile = pt.parse()?;
        let p = &file.probe;
        pt.check_selection(limits::FORWARD_STEPS, p.forward_steps, p.min_bic_gain)?;
        if let Some(m) = p.mpe_um {
            limits::MPE_UM
                .check("probe.mpe_um", m)
                .map_err(|e| pt.range(e))?;
        }
        let lobing = Lobing::parse(&p.lobing).ok_or_else(|| {
            pt.error(format!(
                "probe.lobing = {:?}: physical | harmonic",
                p.lobing
            ))
        })?;
        let effects = pt.effects(&p.effects)?;
        Ok(ProbePlan {
            base: pt.base(&file.pipeline),
            options: ProbeStudyOptions {
                effects,
                lobing,
                forward_steps: p.forward_steps,
                min_bic_gain: p.min_bic_gain,
                mpe_um: p.mpe_um,
            },
        })
    }

    /// The command that adds `effect` to this run (same campaign, same output).
    pub(crate) fn next_command(&self, effect: ProbeEffect) -> String {
        self.base.next_command(&self.options.effects, effect)
    }
}

/// The file name of a setup's polar figure.
pub(crate) fn polar_file(s: &SetupStudy) -> String {
    let safe = |t: &str| {
        t.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect::<String>()
    };
    format!(
        "figures/probe-polar-{}-{}.png",
        safe(&s.stylus),
        safe(&s.artefact)
    )
}

/// The polar figure of a setup: the two-touch pretravel by direction, touch 1, the model.
fn polar_figure(campaign: &str, s: &SetupStudy) -> crate::report::PolarFigure {
    let dirs = &s.directions;
    let phi: Vec<f64> = dirs.iter().map(|d| d.phi_deg).collect();
    let first: Vec<f64> = dirs
        .iter()
        .map(|d| d.spread.mean_2on_um + d.spread.first_touch_offset_um)
        .collect();
    crate::report::PolarFigure {
        title: format!("{campaign}: pretravel by direction, stylus {} on {}", s.stylus, s.artefact),
        subtitle: format!(
            "{} directions, {} touches; two-touch 2σ {:.3} µm, all-touch {:.3} µm; lobing ({}) {:.3} ± {:.3} µm",
            dirs.len(),
            s.model.touches,
            s.summary.two_sigma_2on_um,
            s.summary.two_sigma_all_um,
            s.lobing.model.name(),
            s.lobing.size_um.0,
            s.lobing.size_um.1
        ),
        value_desc: "pretravel relative to the centre (µm)".into(),
        series: vec![
            crate::report::PolarSeries {
                name: "model (mean + lobing)".into(),
                angle_deg: phi.clone(),
                value: dirs.iter().map(|d| d.model_pretravel_um).collect(),
                line: true,
            },
            crate::report::PolarSeries {
                name: "touches 2… (two-touch mean)".into(),
                angle_deg: phi.clone(),
                value: dirs.iter().map(|d| d.spread.mean_2on_um).collect(),
                line: false,
            },
            crate::report::PolarSeries {
                name: "touch 1 after a change".into(),
                angle_deg: phi,
                value: first,
                line: false,
            },
        ],
    }
}

fn write_png(path: &Path, spec: &crate::report::PolarFigure) -> Result<()> {
    crate::output::fault::point("write", path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    let _step = crate::output::writing();
    crate::report::render_polar(spec, path)?;
    Ok(())
}

/// Claim the output, read and analyse the campaign, write the output folder.
pub(crate) fn run(plan: &ProbePlan) -> Result<Outcome> {
    let (out, target) = plan
        .base
        .claim_output(|dir| Ok(crate::io::read_probe_manifest(dir)?.id))?;
    let dir = &plan.base.campaign_dir;
    let logs = crate::pipeline::timed("ingest", || crate::io::read_probe_campaign(dir))?;
    let study: ProbeStudy = crate::pipeline::timed("probe", || probe::study(&logs, &plan.options))
        .with_context(|| format!("analysing {}", dir.display()))?;
    let id = &logs.campaign.id;
    let pipeline = plan.base.pipeline();
    let record = ProbeRecord::new(id, pipeline, &logs.inputs, &study, &plan.options);
    let marker = marker(id, KIND, &plan.options.effects, &logs.inputs)?;
    let lines = crate::narrative::probe::headline(id, &study, plan);
    write_output(target, &marker, out, lines, |tmp, lines| {
        write_json(&tmp.join("probe.json"), &record)?;
        crate::io::write_table(
            &tmp.join("probe_directions.parquet"),
            &directions_table(&study),
        )?;
        crate::io::write_table(&tmp.join("probe_touches.parquet"), &touches_table(&study))?;
        for s in &study.setups {
            write_png(&tmp.join(polar_file(s)), &polar_figure(id, s))?;
        }
        let md = crate::narrative::probe::report_md(id, &study);
        crate::output::write_file(&tmp.join("report.md"), md.as_bytes())?;
        let page = crate::narrative::probe::page(id, &study, lines);
        crate::output::write_file(&tmp.join("index.html"), page.as_bytes())?;
        Ok(())
    })
}
