//! The `probe` kind in the application: its pipeline file (`pipelines/probe.toml`), its run
//! (claim the output, read, analyse with `dbbcal_machine::probe`, write) and its files
//! (`probe.json`, `probe_directions.parquet`, `probe_touches.parquet`, `report.md`,
//! `index.html`, `figures/probe-polar-*.png`), and the polar figure's spec.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Deserialize;

use dbbcal_machine::probe::{self, Lobing, ProbeEffect, ProbeStudy, ProbeStudyOptions, SetupStudy};

use crate::output::probe::{directions_table, touches_table, ProbeRecord};
use crate::output::{Marker, OutputTarget, WriteFailure};
use crate::pipeline::PlanError;
use crate::runner::{Outcome, RunStatus};

/// A pipeline file for a `probe` campaign.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProbePipelineFile {
    pipeline: PipelineSection,
    #[serde(default)]
    probe: ProbeSection,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PipelineSection {
    name: String,
    /// `["probe"]`: the only stage of this kind.
    stages: Vec<String>,
    #[serde(default)]
    #[allow(dead_code)] // read by `kinds::campaign_dir` from the text
    campaign: Option<PathBuf>,
}

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
    /// `[probe] min_bic_gain`.
    pub(crate) const MIN_BIC_GAIN: Limit = Limit::closed(0.0, 1e6, "");
    /// `[probe] mpe_um`.
    pub(crate) const MPE_UM: Limit = Limit::above(0.0, 1_000.0, "µm");
}

/// A validated `probe` run.
#[derive(Debug, Clone)]
pub struct ProbePlan {
    pipeline_name: String,
    pipeline_path: PathBuf,
    pipeline_sha256: String,
    campaign_dir: PathBuf,
    out_dir: Option<PathBuf>,
    pub(crate) options: ProbeStudyOptions,
}

impl ProbePlan {
    /// Validate the pipeline `text` (of file `path`) for the `probe` campaign in `campaign_dir`.
    pub(crate) fn from_pipeline_text(
        path: &Path,
        text: &str,
        campaign_dir: PathBuf,
        out_dir: Option<PathBuf>,
        add_effects: &[String],
    ) -> Result<ProbePlan, PlanError> {
        let perr = |message: String| PlanError::Pipeline {
            path: path.display().to_string(),
            message,
        };
        let file: ProbePipelineFile =
            toml::from_str(text).map_err(|e| perr(e.to_string().replace('\n', " ")))?;
        if file.pipeline.stages != ["probe"] {
            return Err(perr(format!(
                "pipeline.stages = {:?}: a probe campaign has one stage, [\"probe\"]",
                file.pipeline.stages
            )));
        }
        let p = &file.probe;
        limits::FORWARD_STEPS
            .check("probe.forward_steps", p.forward_steps)
            .map_err(|e| perr(e.to_string()))?;
        limits::MIN_BIC_GAIN
            .check("probe.min_bic_gain", p.min_bic_gain)
            .map_err(|e| perr(e.to_string()))?;
        if let Some(m) = p.mpe_um {
            limits::MPE_UM
                .check("probe.mpe_um", m)
                .map_err(|e| perr(e.to_string()))?;
        }
        let lobing = Lobing::parse(&p.lobing).ok_or_else(|| {
            perr(format!(
                "probe.lobing = {:?}: physical | harmonic",
                p.lobing
            ))
        })?;
        let mut effects = Vec::new();
        let named = p
            .effects
            .iter()
            .enumerate()
            .map(|(i, n)| (n, format!("probe.effects[{i}]")))
            .chain(add_effects.iter().map(|n| (n, "--add-effect".to_string())));
        for (name, key) in named {
            let e = ProbeEffect::parse(name).ok_or_else(|| {
                perr(format!(
                    "{key}: {name:?} is not an effect of a probe campaign (known: {})",
                    ProbeEffect::ALL.map(|e| e.name()).join(", ")
                ))
            })?;
            if !effects.contains(&e) {
                effects.push(e);
            }
        }
        Ok(ProbePlan {
            pipeline_name: file.pipeline.name,
            pipeline_path: path.to_path_buf(),
            pipeline_sha256: crate::pipeline::sha256_hex(text.as_bytes()),
            campaign_dir,
            out_dir,
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
    let out = match &plan.out_dir {
        Some(o) => o.clone(),
        None => {
            let c = crate::io::read_probe_manifest(&plan.campaign_dir)?;
            PathBuf::from("reports").join(c.id)
        }
    };
    let target = OutputTarget::claim(&out, &plan.campaign_dir)?;
    let logs = crate::pipeline::timed("ingest", || {
        crate::io::read_probe_campaign(&plan.campaign_dir)
    })?;
    let study: ProbeStudy = crate::pipeline::timed("probe", || probe::study(&logs, &plan.options))
        .with_context(|| format!("analysing {}", plan.campaign_dir.display()))?;
    let id = &logs.campaign.id;
    let pipeline = (plan.pipeline_name.as_str(), plan.pipeline_sha256.as_str());
    let record = ProbeRecord::new(id, pipeline, &logs.inputs, &study, &plan.options);
    let marker = Marker::new(
        id,
        serde_json::json!(["probe"]),
        serde_json::to_value(
            plan.options
                .effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>(),
        )?,
        serde_json::to_value(&logs.inputs)?,
    );
    let lines = crate::narrative::probe::headline(id, &study, plan);
    target
        .write(&marker, |tmp| -> Result<()> {
            let mut json = serde_json::to_string_pretty(&record)?;
            json.push('\n');
            crate::output::write_file(&tmp.join("probe.json"), json.as_bytes())?;
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
            let page = crate::narrative::probe::page(id, &study, &lines);
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
