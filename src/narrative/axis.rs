//! The words of an `axis` run: the terminal's lines, `report.md` and `index.html`.

use std::fmt::Write as _;

use dbbcal_machine::axis_study::AxisStudy;

use super::words::{candidate_row, files_paragraph, html, num};
use crate::figures::FigureFile;
use crate::kinds::axis::AxisPlan;
use crate::output::axis_tables::TableRecord;

/// The terminal's lines (label, text): what was measured, the ISO 230-2 figures, the verdict
/// and the command that adds the proposed effect.
pub(crate) fn headline(
    campaign: &str,
    s: &AxisStudy,
    plan: &AxisPlan,
    tables: &[TableRecord],
) -> Vec<(&'static str, String)> {
    let mut lines = vec![(
        "Axis",
        format!(
            "{campaign}: {} errors of {} at {} targets × 2 directions from {} readings; rank {}{}",
            s.names.len(),
            s.axis.letter(),
            s.targets.len() / 2,
            s.readings,
            s.rank,
            if s.lost.is_empty() {
                String::new()
            } else {
                format!(" (lost: {})", s.lost.join("; "))
            }
        ),
    )];
    if let Some(i) = &s.iso230_2 {
        lines.push((
            "ISO 230-2",
            format!(
                "{}: A {} µm, B {} µm, R {} µm, E {} µm, M {} µm",
                s.names[s.axis.positioning_index()],
                num(i.accuracy_a_um.unwrap_or(f64::NAN), 2),
                num(i.reversal_b_um.unwrap_or(f64::NAN), 2),
                num(i.repeatability_r_um.unwrap_or(f64::NAN), 2),
                num(i.systematic_e_um.unwrap_or(f64::NAN), 2),
                num(i.mean_range_m_um.unwrap_or(f64::NAN), 2)
            ),
        ));
    }
    let d = &s.diagnosis;
    let verdict = match d.proposal {
        Some(e) => format!(
            "missing {} ({}): RMS along {} → {} µm{}",
            e.name(),
            e.physics(),
            num(s.rms_um[0], 3),
            num(d.ledger.get(1).map_or(f64::NAN, |l| l.rms_um[0]), 3),
            rival_note(s)
        ),
        None => format!(
            "model adequate: no effect of the catalogue improves it (RMS along {} µm, across {} µm)",
            num(s.rms_um[0], 3),
            num(s.rms_um[1], 3)
        ),
    };
    lines.push(("Diagnosis", verdict));
    if let Some(t) = tables_line(tables) {
        lines.push(("Tables", t));
    }
    if let Some(e) = d.proposal {
        lines.push(("Next", plan.next_command(e)));
    }
    lines
}

/// `report.md`'s "Controller tables" section (none without tables): each file with its sign and
/// unit statement, or why it was not written. `at` names the places the values are means at.
pub(crate) fn tables_markdown(md: &mut String, tables: &[TableRecord], at: &str) {
    if tables.is_empty() {
        return;
    }
    let _ = writeln!(md, "\n## Controller tables\n\nFrom the mean of both directions at each {at} (docs/controller-tables.md).\n");
    for t in tables {
        match (&t.file, &t.meta, &t.refused) {
            (Some(f), Some(m), _) => {
                let _ = writeln!(md, "- `{f}` ({}): {}", t.format, m.statement);
            }
            (_, _, why) => {
                let _ = writeln!(
                    md,
                    "- {}: not written ({})",
                    t.format,
                    why.as_deref().unwrap_or("no reason given")
                );
            }
        }
    }
}

/// The controller tables: the files written with their sign, and each refusal with its reason.
pub(crate) fn tables_line(tables: &[TableRecord]) -> Option<String> {
    let parts: Vec<String> = tables
        .iter()
        .map(|t| match (&t.file, &t.meta, &t.refused) {
            (Some(f), Some(m), _) => format!("{f} ({})", m.sign.describe()),
            (_, _, Some(why)) => format!("{} not written: {why}", t.format),
            _ => format!("{} not written", t.format),
        })
        .collect();
    (!parts.is_empty()).then(|| parts.join("; "))
}

/// BIC differences below this tell two explanations apart only weakly (Kass & Raftery: < 2 is
/// "not worth more than a bare mention").
const WEAK_BIC: f64 = 2.0;

/// The candidates that explain the readings about as well as the proposal, in words.
fn rival_note(s: &AxisStudy) -> String {
    let c = &s.diagnosis.candidates;
    let Some(best) = c.first() else {
        return String::new();
    };
    let rivals: Vec<&str> = c[1..]
        .iter()
        .filter(|r| r.delta_bic - best.delta_bic < WEAK_BIC)
        .map(|r| r.effect.name())
        .collect();
    if rivals.is_empty() {
        String::new()
    } else {
        format!(
            "; {} explains these readings about as well (ΔBIC within {WEAK_BIC}): the same signature, told apart only by a sensor check",
            rivals.join(", ")
        )
    }
}

/// `report.md`.
pub(crate) fn report_md(
    campaign: &str,
    s: &AxisStudy,
    figures: &[FigureFile],
    tables: &[TableRecord],
) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Axis {} — campaign {campaign}\n", s.axis.letter());
    let _ = writeln!(
        md,
        "Errors are measured − commanded, relative to the datum (target {} mm, direction {:+}); δ in µm, ε in µrad, U with k = 2 from the scatter of {} readings. Rank {}{}.\n",
        s.datum.0,
        s.datum.1,
        s.readings,
        s.rank,
        if s.lost.is_empty() {
            String::new()
        } else {
            format!("; the readings do not determine {}", s.lost.join(", "))
        }
    );
    let _ = writeln!(md, "## The six errors\n");
    for f in figures {
        let _ = writeln!(md, "![{}](figures/{})\n", f.caption, f.file);
    }
    let _ = write!(md, "| target mm | dir |");
    for n in &s.names {
        let _ = write!(md, " {n} | U |");
    }
    let _ = writeln!(md, "\n|---:|---:|{}", "---:|---:|".repeat(6));
    for t in &s.targets {
        let _ = write!(md, "| {} | {:+} |", t.target_mm, t.direction);
        for k in 0..6 {
            let _ = write!(md, " {} | {} |", num(t.errors[k], 3), num(t.u_k2[k], 3));
        }
        md.push('\n');
    }
    if let Some(i) = &s.iso230_2 {
        let _ = writeln!(
            md,
            "\n## ISO 230-2 ({})\n\n| A µm | B µm | R µm | E µm | M µm |\n|---:|---:|---:|---:|---:|\n| {} | {} | {} | {} | {} |",
            s.names[s.axis.positioning_index()],
            num(i.accuracy_a_um.unwrap_or(f64::NAN), 3),
            num(i.reversal_b_um.unwrap_or(f64::NAN), 3),
            num(i.repeatability_r_um.unwrap_or(f64::NAN), 3),
            num(i.systematic_e_um.unwrap_or(f64::NAN), 3),
            num(i.mean_range_m_um.unwrap_or(f64::NAN), 3)
        );
    } else if let Some(why) = &s.iso230_2_missing {
        let _ = writeln!(md, "\n## ISO 230-2\n\nNot evaluated: {why}.");
    }
    let _ = writeln!(md, "\n## Straightness\n\n| error | raw range µm | slope µm/m | range without its line µm |\n|---|---:|---:|---:|");
    for st in &s.straightness {
        let raw = &st.straightness.raw_um;
        let range = raw.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - raw.iter().copied().fold(f64::INFINITY, f64::min);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} |",
            st.name,
            num(range, 3),
            num(1e3 * st.straightness.slope_um_per_mm, 3),
            num(st.straightness.detrended_range_um(), 3)
        );
    }
    let d = &s.diagnosis;
    let _ = writeln!(md, "\n## What the model misses\n\nRMS residual along the axis {} µm, across {} µm.\n\n| candidate | physics | ΔBIC | RMS along µm | RMS across µm |\n|---|---|---:|---:|---:|", num(s.rms_um[0], 4), num(s.rms_um[1], 4));
    for c in &d.candidates {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} |",
            c.effect.name(),
            c.effect.physics(),
            num(c.delta_bic, 1),
            num(c.rms_um[0], 4),
            num(c.rms_um[1], 4)
        );
    }
    let _ = writeln!(md, "\nLedger (forward selection from this model):\n");
    for step in &d.ledger {
        let _ = writeln!(
            md,
            "- {}: RMS along {} µm, across {} µm (ΔBIC {})",
            step.effect.map_or("this model", |e| e.name()),
            num(step.rms_um[0], 4),
            num(step.rms_um[1], 4),
            num(step.delta_bic, 1)
        );
    }
    let _ = writeln!(
        md,
        "\nWhat these readings cannot tell apart from the six errors:\n"
    );
    for u in &d.unseen {
        let _ = writeln!(md, "- {}: {}", u.effect, u.becomes);
    }
    if !s.effects.is_empty() {
        let _ = writeln!(md, "\n## Effects in the model\n");
        for e in &s.effects {
            for (name, v, u) in &e.parameters {
                let _ = writeln!(
                    md,
                    "- {} ({}): {name} = {} ± {}",
                    e.effect.name(),
                    e.effect.physics(),
                    num(*v, 4),
                    num(*u, 4)
                );
            }
        }
    }
    tables_markdown(&mut md, tables, "target");
    let _ = writeln!(md, "\n## Residuals by line and run\n\n| line | run | channel | RMS µm | readings |\n|---:|---:|---|---:|---:|");
    for r in &s.residuals {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} |",
            r.line,
            r.run,
            r.channel,
            num(r.rms_um, 4),
            r.readings
        );
    }
    md
}

/// `index.html`: the headline, then `report.md`'s tables as HTML.
pub(crate) fn page(
    campaign: &str,
    s: &AxisStudy,
    lines: &[(&'static str, String)],
    figures: &[FigureFile],
) -> String {
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>dbbcal — axis {} — {}</title>\n<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}.h td{{text-align:left}}</style></head><body>",
        s.axis.letter(),
        html(campaign)
    );
    let _ = writeln!(
        h,
        "<h1>Axis {} — campaign {}</h1>\n<table class=\"h\">",
        s.axis.letter(),
        html(campaign)
    );
    for (label, text) in lines {
        let _ = writeln!(h, "<tr><td><b>{label}</b></td><td>{}</td></tr>", html(text));
    }
    h.push_str("</table>\n<h2>The six errors (µm, µrad; U k = 2)</h2>\n");
    for f in figures {
        super::page::figure(&mut h, f);
    }
    h.push_str("<table><tr><th>target mm</th><th>dir</th>");
    for n in &s.names {
        let _ = write!(h, "<th>{n}</th><th>U</th>");
    }
    h.push_str("</tr>\n");
    for t in &s.targets {
        let _ = write!(h, "<tr><td>{}</td><td>{:+}</td>", t.target_mm, t.direction);
        for k in 0..6 {
            let _ = write!(
                h,
                "<td>{}</td><td>{}</td>",
                num(t.errors[k], 3),
                num(t.u_k2[k], 3)
            );
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n<h2>What the model misses</h2>\n<table><tr><th>candidate</th><th>physics</th><th>ΔBIC</th><th>RMS along µm</th></tr>\n");
    for c in &s.diagnosis.candidates {
        let (name, physics) = (c.effect.name(), c.effect.physics());
        candidate_row(&mut h, name, physics, c.delta_bic, c.rms_um[0]);
    }
    h.push_str("</table>\n<p>Not identifiable from these readings:</p><ul>\n");
    for u in &s.diagnosis.unseen {
        let _ = writeln!(h, "<li>{}: {}</li>", html(u.effect), html(u.becomes));
    }
    h.push_str("</ul>\n");
    h.push_str(&files_paragraph(&[
        "axis.json",
        "axis_errors.parquet",
        "report.md",
    ]));
    h.push_str("</body></html>\n");
    h
}
