//! What every machine kind's plan and run share, so that a kind's own module holds only its
//! specifics (its `[kind]` section, its limits, its analysis and its files): the pipeline file's
//! `[pipeline]` header and one-stage check, effect names from `[kind] effects` and
//! `--add-effect`, the forward-selection limits, the next command, and the run's output tail
//! (output folder, marker, atomic write, outcome). The words users read here are the same for
//! every kind, with the kind's name put in.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use dbbcal_core::limits::{CountLimit, Limit, OutOfRange};

use crate::output::{Marker, OutputTarget, WriteFailure};
use crate::pipeline::PlanError;
use crate::runner::{Outcome, RunStatus};

/// A machine kind's name as its files and messages spell it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Kind {
    /// The one stage, the `[section]` of its pipeline file and the file `pipelines/<stage>.toml`.
    pub(crate) stage: &'static str,
    /// The campaign with its article, as sentences say it (`an axis campaign`).
    pub(crate) a_campaign: &'static str,
}

impl Kind {
    /// A pipeline message for a campaign of this kind in `dir`: which pipeline runs it.
    pub(crate) fn pointed(self, dir: &Path, e: PlanError) -> PlanError {
        match e {
            PlanError::Pipeline { path, message } => PlanError::Pipeline {
                path,
                message: format!(
                    "{} is {} (run it with pipelines/{}.toml): {message}",
                    dir.display(),
                    self.a_campaign,
                    self.stage
                ),
            },
            other => other,
        }
    }
}

/// `[pipeline]` of a machine kind's pipeline file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PipelineSection {
    pub(crate) name: String,
    /// `["<kind>"]`: the only stage of a machine kind.
    pub(crate) stages: Vec<String>,
    #[serde(default)]
    #[allow(dead_code)] // read by `kinds::campaign_dir` from the text
    campaign: Option<PathBuf>,
}

/// A kind's whole pipeline file: its `[pipeline]` header plus its own sections.
pub(crate) trait PipelineFile: DeserializeOwned {
    fn pipeline(&self) -> &PipelineSection;
}

/// An effect of a kind's model, named in `[kind] effects` and by `--add-effect`.
pub(crate) trait KindEffect: Copy + PartialEq + Sized {
    fn parse(name: &str) -> Option<Self>;
    fn name(self) -> &'static str;
    /// Every effect's name, comma-separated, for the message naming an unknown one.
    fn known() -> String;
}

/// Implements [`KindEffect`] for an effect enum with `parse`, `name` and `ALL`.
macro_rules! kind_effect {
    ($effect:ty) => {
        impl $crate::kinds::plan::KindEffect for $effect {
            fn parse(name: &str) -> Option<Self> {
                <$effect>::parse(name)
            }
            fn name(self) -> &'static str {
                <$effect>::name(self)
            }
            fn known() -> String {
                <$effect>::ALL.map(|e| e.name()).join(", ")
            }
        }
    };
}
pub(crate) use kind_effect;

/// The limit of `[kind] min_bic_gain`, the same for every kind.
const MIN_BIC_GAIN: Limit = Limit::closed(0.0, 1e6, "");

/// A pipeline file being validated for a campaign of the kind `kind`: its path and text, and
/// the command line's campaign, output and `--add-effect` names.
pub(crate) struct PipelineText<'a> {
    pub(crate) path: &'a Path,
    pub(crate) text: &'a str,
    pub(crate) kind: Kind,
    pub(crate) campaign_dir: PathBuf,
    pub(crate) out_dir: Option<PathBuf>,
    pub(crate) add_effects: &'a [String],
}

impl PipelineText<'_> {
    /// A pipeline error naming this file.
    pub(crate) fn error(&self, message: String) -> PlanError {
        PlanError::Pipeline {
            path: self.path.display().to_string(),
            message,
        }
    }

    /// An out-of-range value as a pipeline error naming this file.
    pub(crate) fn range(&self, e: OutOfRange) -> PlanError {
        self.error(e.to_string())
    }

    /// The file parsed (unknown keys refused), with its one stage checked.
    pub(crate) fn parse<F: PipelineFile>(&self) -> Result<F, PlanError> {
        let file: F =
            toml::from_str(self.text).map_err(|e| self.error(e.to_string().replace('\n', " ")))?;
        let stages = &file.pipeline().stages;
        if stages.len() != 1 || stages[0] != self.kind.stage {
            return Err(self.error(format!(
                "pipeline.stages = {stages:?}: {} has one stage, [{:?}]",
                self.kind.a_campaign, self.kind.stage
            )));
        }
        Ok(file)
    }

    /// `[kind] forward_steps` within `steps` and `[kind] min_bic_gain` within its limit.
    pub(crate) fn check_selection(
        &self,
        steps: CountLimit,
        forward_steps: usize,
        min_bic_gain: f64,
    ) -> Result<(), PlanError> {
        let stage = self.kind.stage;
        steps
            .check(&format!("{stage}.forward_steps"), forward_steps)
            .map_err(|e| self.range(e))?;
        MIN_BIC_GAIN
            .check(&format!("{stage}.min_bic_gain"), min_bic_gain)
            .map_err(|e| self.range(e))
    }

    /// The effects of `[kind] effects` (`listed`) then `--add-effect`, each once, in that order.
    pub(crate) fn effects<E: KindEffect>(&self, listed: &[String]) -> Result<Vec<E>, PlanError> {
        let stage = self.kind.stage;
        let named = listed
            .iter()
            .enumerate()
            .map(|(i, n)| (n, format!("{stage}.effects[{i}]")))
            .chain(
                self.add_effects
                    .iter()
                    .map(|n| (n, "--add-effect".to_string())),
            );
        let mut effects = Vec::new();
        for (name, key) in named {
            let e = E::parse(name).ok_or_else(|| {
                self.error(format!(
                    "{key}: {name:?} is not an effect of {} (known: {})",
                    self.kind.a_campaign,
                    E::known()
                ))
            })?;
            if !effects.contains(&e) {
                effects.push(e);
            }
        }
        Ok(effects)
    }

    /// The validated run's common part.
    pub(crate) fn base(&self, pipeline: &PipelineSection) -> PlanBase {
        PlanBase {
            pipeline_name: pipeline.name.clone(),
            pipeline_path: self.path.to_path_buf(),
            pipeline_sha256: crate::pipeline::sha256_hex(self.text.as_bytes()),
            campaign_dir: self.campaign_dir.clone(),
            out_dir: self.out_dir.clone(),
        }
    }
}

/// What every validated machine-kind run holds besides its options.
#[derive(Debug, Clone)]
pub(crate) struct PlanBase {
    pub(crate) pipeline_name: String,
    pub(crate) pipeline_path: PathBuf,
    pub(crate) pipeline_sha256: String,
    pub(crate) campaign_dir: PathBuf,
    pub(crate) out_dir: Option<PathBuf>,
}

impl PlanBase {
    /// The command that adds `effect` to a run of `effects` (same campaign, same output).
    pub(crate) fn next_command<E: KindEffect>(&self, effects: &[E], effect: E) -> String {
        let mut cmd = format!(
            "dbbcal run {} --campaign {}",
            self.pipeline_path.display(),
            self.campaign_dir.display()
        );
        if let Some(o) = &self.out_dir {
            cmd.push_str(&format!(" --out {}", o.display()));
        }
        for e in effects {
            cmd.push_str(&format!(" --add-effect {}", e.name()));
        }
        cmd.push_str(&format!(" --add-effect {}", effect.name()));
        cmd
    }

    /// `(name, sha256)` of the pipeline, as the output records hold it.
    pub(crate) fn pipeline(&self) -> (&str, &str) {
        (&self.pipeline_name, &self.pipeline_sha256)
    }

    /// `--out`, else `reports/<campaign id>` (the id read by `campaign_id` from the campaign
    /// folder), claimed before anything is read.
    pub(crate) fn claim_output(
        &self,
        campaign_id: impl FnOnce(&Path) -> Result<String>,
    ) -> Result<(PathBuf, OutputTarget)> {
        let out = match &self.out_dir {
            Some(o) => o.clone(),
            None => PathBuf::from("reports").join(campaign_id(&self.campaign_dir)?),
        };
        let target = OutputTarget::claim(&out, &self.campaign_dir)?;
        Ok((out, target))
    }
}

/// The text of `dir/campaign.toml` (a kind whose reader has no manifest function).
pub(crate) fn manifest_text(dir: &Path) -> Result<String> {
    Ok(crate::io::read_small_text(
        &dir.join("campaign.toml"),
        crate::io::MAX_MANIFEST_BYTES,
    )?)
}

/// The marker of a kind's output folder: campaign, its one stage, effects and inputs.
pub(crate) fn marker<E: KindEffect>(
    campaign_id: &str,
    kind: Kind,
    effects: &[E],
    inputs: &[crate::series::InputFile],
) -> Result<Marker> {
    Ok(Marker::new(
        campaign_id,
        serde_json::json!([kind.stage]),
        serde_json::to_value(effects.iter().map(|e| e.name()).collect::<Vec<_>>())?,
        serde_json::to_value(crate::output::inputs::input_records(inputs))?,
    ))
}

/// `record` as pretty JSON with a final newline, written to `path`.
pub(crate) fn write_json(path: &Path, record: &impl Serialize) -> Result<()> {
    let mut json = serde_json::to_string_pretty(record)?;
    json.push('\n');
    crate::output::write_file(path, json.as_bytes())?;
    Ok(())
}

/// Build the output folder `out` with `build` (all or nothing, `OutputTarget::write`) and end
/// the run with the terminal's `lines`.
pub(crate) fn write_output(
    target: OutputTarget,
    marker: &Marker,
    out: PathBuf,
    lines: Vec<(&'static str, String)>,
    build: impl FnOnce(&Path, &[(&'static str, String)]) -> Result<()>,
) -> Result<Outcome> {
    target
        .write(marker, |tmp| build(tmp, &lines))
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
