//! The night in words: what a person reads first. [`Headline`] is the few lines the command line
//! prints and the report page opens with; `fit_report` is the lmfit-style report per bar
//! (`report.md`).
//!
//! Every sentence the outputs hold about core's results is here, one module a subject: the
//! diagnosis' reasons (`diagnosis`), the effects' and channels' explanations (`effects`), the
//! sensors' profiles (`sensors`), the decision rule and the budget's notes (`acceptance`), what
//! a bar cannot determine (`model`), excluded calibration points (`calibration`), the inputs'
//! quality flags and a failed bar's reason (`quality`), `index.html` (`page`); each machine kind
//! has its module, and what they all write the same way is `words`.
//!
//! Plain data in, text out: no IO, no pixels.

pub(crate) mod acceptance;
pub(crate) mod axis;
pub(crate) mod calibration;
pub(crate) mod device;
pub(crate) mod device_loop;
pub mod diagnosis;
pub mod effects;
pub(crate) mod fit_report;
pub mod model;
pub(crate) mod page;
pub(crate) mod probe;
pub mod quality;
pub(crate) mod roll;
pub mod sensors;
pub(crate) mod volumetric;
mod words;

use crate::model::Effect;
use crate::pipeline::{BarFailure, RunPlan, RunResults, Stage};

/// What the diagnosis concludes for the fleet.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Conclusion {
    /// No candidate is both significant and material.
    Adequate { min_gain_um: f64 },
    /// The top proposed candidate, and the fleet RMS before and after adding it.
    Missing {
        effect: Effect,
        rms_before_um: f64,
        rms_after_um: f64,
    },
}

/// The reference bar and the worst predicted mismatch against it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ReferenceLine {
    pub(crate) bar: String,
    pub(crate) worst_bar: Option<String>,
    pub(crate) worst_mismatch_um: f64,
    pub(crate) limit_um: f64,
    pub(crate) flagged: usize,
}

/// The night in a few numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Headline {
    /// Campaign id.
    pub campaign: String,
    /// The pipeline's name.
    pub pipeline: String,
    pub(crate) bars_ok: usize,
    pub(crate) failed: Vec<BarFailure>,
    /// Quadratic mean of the bars' RMS residuals (µm), as the diagnosis' fleet RMS.
    pub(crate) fleet_rms_um: Option<f64>,
    pub(crate) noise_floor_um: Option<f64>,
    pub(crate) reference: Option<ReferenceLine>,
    pub(crate) conclusion: Option<Conclusion>,
    /// The command that adds the proposed effect (same campaign, same output).
    pub(crate) next_command: Option<String>,
    /// Acceptance, when it ran on working bars: (pass, fail, no decision, tolerance µm).
    pub(crate) acceptance: Option<(usize, usize, usize, f64)>,
    /// Why a stage has nothing to show, and bars a later stage left out, in words.
    pub(crate) notes: Vec<String>,
    /// The device's loop: its verdict and the command that adds its proposal.
    pub(crate) device: Vec<(&'static str, String)>,
}

impl Headline {
    pub(crate) fn from_results(plan: &RunPlan, results: &RunResults) -> Headline {
        let conclusion =
            results
                .diagnosis
                .as_ref()
                .map(|d| match d.candidates.iter().find(|c| c.proposed()) {
                    Some(c) => Conclusion::Missing {
                        effect: c.effect.clone(),
                        rms_before_um: c.rms_before_um,
                        rms_after_um: c.rms_after_um.unwrap_or(c.screened_rms_after_um),
                    },
                    None => Conclusion::Adequate {
                        min_gain_um: d.criteria.min_gain_um,
                    },
                });
        let next_command = match &conclusion {
            Some(Conclusion::Missing { effect, .. }) => Some(add_effect_command(plan, effect)),
            _ => None,
        };
        Headline {
            campaign: results.campaign.id.clone(),
            pipeline: plan.pipeline_name.clone(),
            bars_ok: results.bars.len(),
            failed: results.failed.clone(),
            fleet_rms_um: fleet_rms_um(results),
            noise_floor_um: results
                .diagnosis
                .as_ref()
                .map(|d| d.criteria.noise_floor_um),
            reference: reference_line(results),
            conclusion,
            next_command,
            acceptance: acceptance_counts(plan, results),
            notes: notes(plan, results),
            device: device_loop::headline_lines(plan, results),
        }
    }

    /// The headline as short labelled lines (label, text), most important first.
    pub fn lines(&self) -> Vec<(&'static str, String)> {
        let mut lines = vec![(
            "Bars",
            match self.failed.len() {
                0 => format!("{} identified", self.bars_ok),
                n => format!(
                    "{} identified, {n} failed ({})",
                    self.bars_ok,
                    self.failed
                        .iter()
                        .map(|f| f.bar.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            },
        )];
        if let Some(r) = &self.reference {
            let worst = match &r.worst_bar {
                Some(bar) => format!(
                    "worst predicted mismatch {:.3} µm ({bar}) against the {:.3} µm limit{}",
                    r.worst_mismatch_um,
                    r.limit_um,
                    match r.flagged {
                        0 => String::new(),
                        n => format!(", {n} bar(s) over it"),
                    }
                ),
                None => "no other bar to compare".into(),
            };
            lines.push(("Reference", format!("{}, {worst}", r.bar)));
        }
        if let Some(rms) = self.fleet_rms_um {
            let floor = self
                .noise_floor_um
                .map(|f| format!(" against a noise floor of {f:.4} µm"))
                .unwrap_or_default();
            lines.push(("Fleet RMS", format!("{rms:.4} µm{floor}")));
        }
        if let Some(c) = &self.conclusion {
            lines.push(("Diagnosis", conclusion_text(c)));
        }
        if let Some((pass, fail, open, tolerance_um)) = self.acceptance {
            lines.push((
                "Acceptance",
                format!(
                    "{pass} of {} conform to ±{tolerance_um:.3} µm, {fail} do not, {open} undecided",
                    pass + fail + open
                ),
            ));
        }
        lines.extend(self.device.iter().cloned());
        for note in &self.notes {
            lines.push(("Note", note.clone()));
        }
        if let Some(cmd) = &self.next_command {
            lines.push(("Next", cmd.clone()));
        }
        lines
    }
}

/// The diagnosis' conclusion in one sentence.
pub(crate) fn conclusion_text(c: &Conclusion) -> String {
    match c {
        Conclusion::Adequate { min_gain_um } => format!(
            "model adequate: no candidate effect is both significant and material (≥ {min_gain_um:.4} µm)"
        ),
        Conclusion::Missing {
            effect,
            rms_before_um,
            rms_after_um,
        } => format!(
            "missing effect: {effect}; adding it cuts the fleet RMS from {rms_before_um:.4} to {rms_after_um:.4} µm"
        ),
    }
}

fn acceptance_counts(plan: &RunPlan, results: &RunResults) -> Option<(usize, usize, usize, f64)> {
    use crate::acceptance::Decision;
    let acc = results.acceptance.as_ref().filter(|a| !a.is_empty())?;
    let count = |d: Decision| acc.iter().filter(|a| a.decision == d).count();
    Some((
        count(Decision::Pass),
        count(Decision::Fail),
        count(Decision::NoDecision),
        plan.acceptance.tolerance_um,
    ))
}

/// Stages that ran with nothing to show, and bars they left out, with the reason.
fn notes(plan: &RunPlan, results: &RunResults) -> Vec<String> {
    let mut notes = Vec::new();
    // Rows that could not be used, dropped (`docs/guarantees.md`, "Inputs"): the first few by file, column and
    // rows; all of them in summary.json.
    let unusable: Vec<&crate::series::quality::Flag> = results
        .quality
        .files
        .iter()
        .filter(|f| f.kind() == crate::series::quality::FlagKind::UnusableRows)
        .collect();
    for f in unusable.iter().take(3) {
        notes.push(format!("rows dropped: {}", quality::note(f)));
    }
    if unusable.len() > 3 {
        notes.push(format!(
            "rows dropped in {} more places (summary.json → quality.files)",
            unusable.len() - 3
        ));
    }
    if let Some(c) = &results.calibration {
        for f in &c.failed {
            notes.push(format!(
                "no centre-distance function for {}: {}",
                f.bar,
                quality::failure(f)
            ));
        }
    }
    if let Some(c) = &results.compensation {
        for f in &c.failed {
            notes.push(format!(
                "{} not compensated: {}",
                f.bar,
                quality::failure(f)
            ));
        }
    }
    notes.extend(unmatched_bars(results));
    if plan.runs(Stage::Acceptance) && results.acceptance.as_ref().is_none_or(|a| a.is_empty()) {
        notes.push(
            "nothing to accept: the campaign has no working mounts; mark a mount with purpose = \"check\" (on a plate length) or give it a device in campaign.toml".into(),
        );
    }
    notes
}

/// The identified bars the match stage left out (`matching::matched_inputs`), with why: base
/// parameters whose data leave the bar's response undetermined
/// (`BarModel::response_undetermined`: one length, a time constant run up to the model's limit),
/// else base parameters their model lacks.
fn unmatched_bars(results: &RunResults) -> Vec<String> {
    let Some(r) = &results.reference else {
        return Vec::new();
    };
    let matched = |bar: &str| r.choice.bar == bar || r.mismatches.iter().any(|m| m.bar == bar);
    let base = crate::matching::MATCH_PARAMS;
    results
        .bars
        .iter()
        .filter(|o| !matched(&o.model.bar))
        .map(|o| {
            let undetermined: Vec<&str> = base
                .iter()
                .copied()
                .filter(|p| o.model.response_undetermined(p))
                .collect();
            let why = if undetermined.is_empty() {
                "its model lacks base parameters the others have".to_string()
            } else {
                format!(
                    "its data do not determine {} (report.md → the bar's warnings)",
                    undetermined.join(", ")
                )
            };
            format!("{} left out of matching: {why}", o.model.bar)
        })
        .collect()
}

fn fleet_rms_um(results: &RunResults) -> Option<f64> {
    let n = results.bars.len();
    let ss: f64 = results.bars.iter().map(|o| o.model.rms_um.powi(2)).sum();
    (n > 0).then(|| (ss / n as f64).sqrt())
}

fn reference_line(results: &RunResults) -> Option<ReferenceLine> {
    let r = results.reference.as_ref()?;
    let worst = r
        .mismatches
        .iter()
        .max_by(|a, b| a.max_abs_um.total_cmp(&b.max_abs_um));
    Some(ReferenceLine {
        bar: r.choice.bar.clone(),
        worst_bar: worst.map(|m| m.bar.clone()),
        worst_mismatch_um: worst.map_or(0.0, |m| m.max_abs_um),
        limit_um: r.limit_um,
        flagged: r.mismatches.iter().filter(|m| m.flagged).count(),
    })
}

/// The command line that reruns `plan` with `effect` added: `dbbcal run PIPELINE` with every
/// effect beyond the base as `--add-effect`, or the stage subcommand with `--effects`.
pub(crate) fn add_effect_command(plan: &RunPlan, effect: &Effect) -> String {
    let base: Vec<String> = crate::model::base_effects()
        .iter()
        .map(|e| e.name())
        .collect();
    let mut effects: Vec<String> = plan.effects.iter().map(|e| e.name()).collect();
    if !plan.effects.contains(effect) {
        effects.push(effect.name());
    }
    let campaign = shell_word(&plan.campaign_dir.display().to_string());
    let out = plan
        .out_dir
        .as_ref()
        .map(|o| format!(" --out {}", shell_word(&o.display().to_string())))
        .unwrap_or_default();
    match &plan.pipeline_source {
        Some((path, _)) => {
            let added: String = effects
                .iter()
                .filter(|e| !base.contains(e))
                .map(|e| format!(" --add-effect {}", shell_word(e)))
                .collect();
            format!(
                "dbbcal run {} --campaign {campaign}{out}{added}",
                shell_word(&path.display().to_string())
            )
        }
        None => {
            let stage = plan
                .stages
                .iter()
                .rev()
                .find(|s| **s != Stage::Report)
                .or(plan.stages.last())
                .map(|s| stage_command(*s))
                .unwrap_or("identify");
            format!(
                "dbbcal {stage} --campaign {campaign}{out} --effects {}",
                shell_word(&effects.join(","))
            )
        }
    }
}

fn stage_command(stage: Stage) -> &'static str {
    match stage {
        Stage::Ingest => "ingest",
        Stage::Identify | Stage::Diagnose => "identify",
        Stage::Match | Stage::MatchStudy => "match",
        Stage::Report => "report",
        Stage::Calibrate => "calibrate",
        Stage::Compensate | Stage::Acceptance | Stage::Device => "compensate",
    }
}

/// `s` quoted for a POSIX shell when it holds anything beyond `[A-Za-z0-9._/:,@=+-]`.
pub(crate) fn shell_word(s: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "._/:,@=+-".contains(c);
    if !s.is_empty() && s.chars().all(plain) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_words_are_quoted_only_when_needed() {
        assert_eq!(shell_word("lag:T1@600"), "lag:T1@600");
        assert_eq!(shell_word("my campaign"), "'my campaign'");
        assert_eq!(shell_word("it's"), "'it'\\''s'");
    }

    #[test]
    fn the_conclusion_names_the_effect_and_the_numbers() {
        let c = Conclusion::Missing {
            effect: Effect::HeadHeating,
            rms_before_um: 0.1199,
            rms_after_um: 0.0201,
        };
        assert_eq!(
            conclusion_text(&c),
            "missing effect: head_heating; adding it cuts the fleet RMS from 0.1199 to 0.0201 µm"
        );
    }
}
