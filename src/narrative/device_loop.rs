//! The device's loop in words (`dbbcal_machine::device_study`): the verdict for the headline,
//! the command that adds the proposed effect, and the loop's part of the Device section of
//! `report.md` and `index.html` (candidates, ledger, the model's effects, the residual per leg,
//! what repeats cannot show).

use std::fmt::Write;

use dbbcal_machine::device_study::{DeviceEffect, DeviceStudy, DeviceStudyError};

use super::page::escape;
use super::shell_word;
use crate::pipeline::{RunPlan, RunResults};

fn study(results: &RunResults) -> Option<&Result<DeviceStudy, DeviceStudyError>> {
    results.device.as_ref()?.study.as_ref()
}

/// The command that adds `effect` to the device's model: this run's pipeline, campaign and
/// output, the device effects already in the model, and `effect`.
fn add_command(plan: &RunPlan, effect: DeviceEffect) -> Option<String> {
    let (path, _) = plan.pipeline_source.as_ref()?;
    let mut cmd = format!(
        "dbbcal run {} --campaign {}",
        shell_word(&path.display().to_string()),
        shell_word(&plan.campaign_dir.display().to_string())
    );
    if let Some(o) = &plan.out_dir {
        let _ = write!(cmd, " --out {}", shell_word(&o.display().to_string()));
    }
    for e in plan.device.effects.iter().chain([&effect]) {
        let _ = write!(cmd, " --add-effect {}", e.name());
    }
    Some(cmd)
}

/// The headline's lines of the device stage's loop and tables: the loop's verdict and, with a
/// proposal, the command; the controller tables written or refused.
pub(crate) fn headline_lines(plan: &RunPlan, results: &RunResults) -> Vec<(&'static str, String)> {
    let mut lines = loop_lines(plan, results);
    if let Some(t) = results
        .device
        .as_ref()
        .and_then(|d| super::axis::tables_line(&d.tables))
    {
        lines.push(("Tables", t));
    }
    lines
}

fn loop_lines(plan: &RunPlan, results: &RunResults) -> Vec<(&'static str, String)> {
    let Some(s) = study(results) else {
        return Vec::new();
    };
    let s = match s {
        Err(e) => return vec![("Device loop", format!("not run: {e}"))],
        Ok(s) => s,
    };
    let model = if s.effects.is_empty() {
        String::new()
    } else {
        format!(
            " (model: {})",
            s.effects
                .iter()
                .map(|e| e.effect.name())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let mut lines = vec![(
        "Device loop",
        match s.proposal {
            Some(e) => format!(
                "missing {} ({}): legs' RMS across repeats {:.3} → {:.3} µm{model}",
                e.name(),
                e.physics(),
                s.rms_um,
                s.candidates.first().map_or(f64::NAN, |c| c.rms_um)
            ),
            None => format!(
                "legs agree across repeats: RMS {:.3} µm over {} station groups; no effect of the catalogue improves them{model}",
                s.rms_um, s.groups
            ),
        },
    )];
    if let Some(cmd) = s.proposal.and_then(|e| add_command(plan, e)) {
        lines.push(("Device next", cmd));
    }
    lines
}

/// The loop's part of the Device section of `report.md`.
pub(crate) fn markdown(md: &mut String, results: &RunResults) {
    let Some(s) = study(results) else {
        return;
    };
    md.push_str("### The loop: the legs across repeated dwells\n\n");
    let s = match s {
        Err(e) => {
            let _ = writeln!(md, "Not run: {e}\n");
            return;
        }
        Ok(s) => s,
    };
    let _ = writeln!(
        md,
        "Each leg gets one length per station and approach direction; what the lengths do beyond that, from run to run and in time, is the residual: RMS {:.4} µm over {} values that can disagree ({} station groups). Per leg (µm): {}.\n",
        s.rms_um,
        s.redundant,
        s.groups,
        s.rms_per_leg_um
            .iter()
            .map(|v| format!("{v:.4}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for e in &s.effects {
        let params: Vec<String> = e
            .parameters
            .iter()
            .map(|(n, v, u)| format!("{n} = {v:.4} ± {u:.4}"))
            .collect();
        let _ = writeln!(
            md,
            "- in the model: `{}` ({}): {}; removed from the legs before the poses",
            e.effect.name(),
            e.effect.physics(),
            params.join(", ")
        );
    }
    md.push_str(
        "\n| candidate | physics | ΔBIC | RMS with it µm | largest change to a leg µm | where |\n|---|---|---:|---:|---:|---|\n",
    );
    for c in &s.candidates {
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} | {:.4} | {:.4} | {} |",
            c.effect.name(),
            c.effect.physics(),
            c.delta_bic,
            c.rms_um,
            c.size_um,
            c.detail.as_deref().unwrap_or("")
        );
    }
    md.push_str("\nProposed: the best candidate with a BIC gain of at least `[device] min_bic_gain` whose largest change to a leg reaches `[device] min_effect_um` (a slow residue of the bars' compensation is significant over a long test but does not matter).\n");
    md.push_str("\nLedger (forward selection from this model): ");
    let steps: Vec<String> = s
        .ledger
        .iter()
        .map(|l| {
            format!(
                "{} {:.4} µm",
                l.effect.map_or("this model", |e| e.name()),
                l.rms_um
            )
        })
        .collect();
    let _ = writeln!(
        md,
        "{}.\n\nWhat repeated dwells cannot show:\n",
        steps.join(" → ")
    );
    for (what, becomes) in &s.unseen {
        let _ = writeln!(md, "- {what}: {becomes}");
    }
    md.push('\n');
}

/// The loop's part of the Device section of `index.html`.
pub(crate) fn html(h: &mut String, results: &RunResults) {
    let Some(s) = study(results) else {
        return;
    };
    h.push_str("<h3>The loop: the legs across repeated dwells</h3>\n");
    let s = match s {
        Err(e) => {
            let _ = writeln!(h, "<p>Not run: {}</p>", escape(&e.to_string()));
            return;
        }
        Ok(s) => s,
    };
    let _ = writeln!(
        h,
        "<p>Residual of the legs about their station groups: RMS {:.4} µm ({} groups).</p>",
        s.rms_um, s.groups
    );
    h.push_str("<table><thead><tr><th>candidate</th><th>physics</th><th>ΔBIC</th><th>RMS with it µm</th><th>largest change to a leg µm</th><th>where</th></tr></thead><tbody>\n");
    for c in &s.candidates {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.1}</td><td>{:.4}</td><td>{:.4}</td><td>{}</td></tr>",
            c.effect.name(),
            escape(c.effect.physics()),
            c.delta_bic,
            c.rms_um,
            c.size_um,
            escape(c.detail.as_deref().unwrap_or(""))
        );
    }
    h.push_str("</tbody></table>\n<ul>\n");
    for e in &s.effects {
        let _ = writeln!(
            h,
            "<li>in the model: {} ({})</li>",
            e.effect.name(),
            escape(e.effect.physics())
        );
    }
    for (what, becomes) in &s.unseen {
        let _ = writeln!(
            h,
            "<li>not shown by repeats: {}: {}</li>",
            escape(what),
            escape(becomes)
        );
    }
    h.push_str("</ul>\n");
}
