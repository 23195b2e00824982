//! The words of a `probe` run: the terminal's lines, `report.md` and `index.html`.

use std::fmt::Write as _;

use dbbcal_machine::probe::{ProbeStudy, SetupStudy};

use super::words::{candidate_row, files_paragraph, html, num};
use crate::kinds::probe::{polar_file, ProbePlan};

fn lobing_line(s: &SetupStudy) -> String {
    let l = &s.lobing;
    let what = match l.model {
        dbbcal_machine::probe::Lobing::Physical => "δ_min",
        dbbcal_machine::probe::Lobing::Harmonic => "3rd harmonic",
    };
    let phase = if l.phase_deg.0.is_finite() {
        format!(
            "phase {}° ± {}°",
            num(l.phase_deg.0, 1),
            num(l.phase_deg.1, 1)
        )
    } else {
        "phase not fixed by these directions".into()
    };
    format!(
        "lobing ({}) {what} {} ± {} µm, {phase}",
        l.model.name(),
        num(l.size_um.0, 3),
        num(l.size_um.1, 3)
    )
}

/// The terminal's lines (label, text).
pub(crate) fn headline(
    campaign: &str,
    study: &ProbeStudy,
    plan: &ProbePlan,
) -> Vec<(&'static str, String)> {
    let mut lines = vec![(
        "Probe",
        format!(
            "{campaign}: {} touches, {} stylus/artefact setup(s)",
            study.touches,
            study.setups.len()
        ),
    )];
    for s in &study.setups {
        let t = &s.summary;
        lines.push((
            "Setup",
            format!(
                "{} on {}: {} directions; effective tip {} mm (U {} µm); {}",
                s.stylus,
                s.artefact,
                s.directions.len(),
                num(s.tip.effective_mm, 5),
                num(s.tip.u_k2_um, 3),
                lobing_line(s)
            ),
        ));
        lines.push((
            "Two-touch",
            format!(
                "mean range {} µm over all touches vs {} µm over touches 2… (ratio {}); 2σ {} vs {} µm",
                num(t.mean_range_all_um, 3),
                num(t.mean_range_2on_um, 3),
                num(t.range_ratio, 2),
                num(t.two_sigma_all_um, 3),
                num(t.two_sigma_2on_um, 3)
            ),
        ));
        let f = &s.form;
        lines.push((
            "P form",
            format!(
                "{} µm (U {} µm){}",
                num(f.p_form_um, 3),
                num(f.u_k2_um, 3),
                match (f.mpe_um, f.decision) {
                    (Some(m), Some(d)) => format!(" against MPE {m} µm: {}", d.as_str()),
                    _ => " (no MPE: no decision)".into(),
                }
            ),
        ));
        match s.diagnosis.proposal {
            Some(e) => {
                lines.push((
                    "Missing",
                    format!(
                        "{} ({}) — add it: {}",
                        e.name(),
                        e.physics(),
                        plan.next_command(e)
                    ),
                ));
            }
            None => lines.push(("Missing", "no effect of the catalogue is missing".into())),
        }
    }
    lines
}

/// `report.md`.
pub(crate) fn report_md(campaign: &str, study: &ProbeStudy) -> String {
    let mut md = format!(
        "# Probe campaign {campaign}\n\n{} touches. Pretravel δ in µm, positive along the approach; U is k = 2. Physics: docs/spec/machine-physics.md, \"Kind `probe`\".\n",
        study.touches
    );
    for s in &study.setups {
        setup_md(&mut md, s);
    }
    if !study.size.is_empty() {
        let _ = writeln!(md, "\n## Size (ISO 10360-5-style)\n");
        for z in &study.size {
            let _ = writeln!(
                md,
                "- stylus {} calibrated on {}, measuring {}: size error {} µm (U {} µm)",
                z.stylus,
                z.calibrated_on,
                z.artefact,
                num(z.size_error_um, 3),
                num(z.u_k2_um, 3)
            );
        }
    } else {
        let _ = writeln!(md, "\nSize error: not assessable (each stylus touched one artefact: the one its tip was calibrated on).");
    }
    md
}

fn setup_md(md: &mut String, s: &SetupStudy) {
    let t = &s.summary;
    let a = &s.artefact_fit;
    let _ = writeln!(
        md,
        "\n## Stylus {} on {} ({})\n",
        s.stylus,
        s.artefact,
        a.kind.as_str()
    );
    let _ = writeln!(md, "### Not identifiable\n");
    for n in &s.not_identifiable {
        let _ = writeln!(md, "- **{}**: {}", n.name, n.says);
    }
    let _ = writeln!(md, "\n### All touches against two touches\n");
    let _ = writeln!(
        md,
        "- mean range over all touches {} µm, over touches 2… {} µm (ratio {})",
        num(t.mean_range_all_um, 3),
        num(t.mean_range_2on_um, 3),
        num(t.range_ratio, 2)
    );
    let _ = writeln!(
        md,
        "- 2σ within a direction: all touches {} µm, touches 2… {} µm",
        num(t.two_sigma_all_um, 3),
        num(t.two_sigma_2on_um, 3)
    );
    let _ = writeln!(
        md,
        "- touch 1 minus the mean of touches 2…: from {} to {} µm; direction means spread {} µm",
        num(t.first_touch_offset_span_um.0, 3),
        num(t.first_touch_offset_span_um.1, 3),
        num(t.means_spread_um, 3)
    );
    let _ = writeln!(md, "\n### Artefact, tip, lobing\n");
    let _ = writeln!(
        md,
        "- centre ({}) {:.4}, {:.4}, {:.4} mm",
        if a.centre_declared {
            "declared"
        } else {
            "fitted"
        },
        a.centre_mm[0],
        a.centre_mm[1],
        a.centre_mm[2]
    );
    for (n, v, u) in &a.centre_offset_um {
        let _ = writeln!(
            md,
            "  - {n}: {} µm (U {} µm){}",
            num(*v, 3),
            num(*u, 3),
            if a.centre_declared {
                " — the 1st harmonic the declared centre leaves"
            } else {
                " — last step of the fit"
            }
        );
    }
    let _ = writeln!(
        md,
        "- apparent radius {} mm (U {} µm); mean pretravel δ̄ {} µm (U {} µm)",
        num(a.apparent_radius_mm, 5),
        num(a.apparent_radius_u_k2_um, 3),
        num(a.mean_pretravel_um.0, 3),
        num(a.mean_pretravel_um.1, 3)
    );
    let _ = writeln!(
        md,
        "- effective tip diameter {} mm (nominal {} mm, U {} µm)",
        num(s.tip.effective_mm, 5),
        s.tip.nominal_mm,
        num(s.tip.u_k2_um, 3)
    );
    let _ = writeln!(md, "- {}", lobing_line(s));
    let f = &s.form;
    let _ = writeln!(
        md,
        "- ISO 10360-5-style probing form error P = {} µm (U {} µm){}; {}",
        num(f.p_form_um, 3),
        num(f.u_k2_um, 3),
        match (f.mpe_um, f.decision) {
            (Some(m), Some(d)) => format!(", ISO 14253-1 against MPE {m} µm: **{}**", d.as_str()),
            _ => ", no MPE given: no decision".into(),
        },
        f.note
    );
    let _ = writeln!(md, "\n### Harmonics of the direction means\n\n| order | amplitude µm | U µm | phase ° |\n|---:|---:|---:|---:|");
    for h in &s.harmonics.harmonics {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} |",
            h.order,
            num(h.amplitude_um, 3),
            num(h.amplitude_u_k2_um, 3),
            num(h.phase_deg, 1)
        );
    }
    if !s.harmonics.lost.is_empty() {
        let _ = writeln!(
            md,
            "\nNot seen by these directions: {}",
            s.harmonics.lost.join("; ")
        );
    }
    let _ = writeln!(md, "\n### Directions (correction table: add `correction` along the approach to a point taken with the effective tip)\n\n| dir | φ ° | θ ° | n | pretravel µm | 2σ µm | touch 1 − mean(2…) µm | range all µm | range 2… µm | model µm | correction µm | U µm |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for d in &s.directions {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            d.index,
            num(d.phi_deg, 1),
            num(d.theta_deg, 1),
            d.spread.touches,
            num(d.spread.mean_2on_um, 3),
            num(d.spread.two_sigma_2on_um, 3),
            num(d.spread.first_touch_offset_um, 3),
            num(d.spread.range_all_um, 3),
            num(d.spread.range_2on_um, 3),
            num(d.model_pretravel_um, 3),
            num(d.correction_um, 3),
            num(d.correction_u_k2_um, 3)
        );
    }
    let m = &s.model;
    let _ = writeln!(
        md,
        "\n### The model\n\nLobing {}, effects [{}]; rank {}; RMS first touches {} µm, touches 2… {} µm.\n",
        m.lobing.name(),
        m.effects.iter().map(|e| e.name()).collect::<Vec<_>>().join(", "),
        m.rank,
        num(m.rms_um[0], 4),
        num(m.rms_um[1], 4)
    );
    for p in &m.parameters {
        let _ = writeln!(
            md,
            "- {} = {} (U {})",
            p.name,
            num(p.value, 4),
            num(p.u_k2, 4)
        );
    }
    if !m.lost.is_empty() {
        let _ = writeln!(md, "\nThe touches cannot see: {}", m.lost.join("; "));
    }
    let d = &s.diagnosis;
    let _ = writeln!(md, "\n### What the model misses\n");
    match d.proposal {
        Some(e) => {
            let _ = writeln!(
                md,
                "Missing effect: **{}** ({}); add it with `--add-effect {}`.\n",
                e.name(),
                e.physics(),
                e.name()
            );
        }
        None => {
            let _ = writeln!(
                md,
                "No effect of the catalogue brings the BIC gain asked for.\n"
            );
        }
    }
    let _ = writeln!(
        md,
        "| candidate | physics | ΔBIC | RMS touch 1 µm | RMS 2… µm |\n|---|---|---:|---:|---:|"
    );
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
            "- {}: RMS touch 1 {} µm, 2… {} µm (ΔBIC {})",
            step.effect.map_or("this model", |e| e.name()),
            num(step.rms_um[0], 4),
            num(step.rms_um[1], 4),
            num(step.delta_bic, 1)
        );
    }
    let _ = writeln!(md, "\nFigure: `{}`.", polar_file(s));
}

/// `index.html`: the headline, the probe section per setup (statements, figures, tables).
pub(crate) fn page(campaign: &str, study: &ProbeStudy, lines: &[(&'static str, String)]) -> String {
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>dbbcal — probe — {}</title>\n<style>body{{font-family:sans-serif;max-width:70em;margin:2em auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}.h td{{text-align:left}}img{{max-width:100%}}</style></head><body>",
        html(campaign)
    );
    let _ = writeln!(
        h,
        "<h1>Probe — campaign {}</h1>\n<table class=\"h\">",
        html(campaign)
    );
    for (label, text) in lines {
        let _ = writeln!(h, "<tr><td><b>{label}</b></td><td>{}</td></tr>", html(text));
    }
    h.push_str("</table>\n");
    for s in &study.setups {
        let _ = writeln!(
            h,
            "<section id=\"probe-{}-{}\"><h2>Probe: stylus {} on {}</h2>",
            html(&s.stylus),
            html(&s.artefact),
            html(&s.stylus),
            html(&s.artefact)
        );
        h.push_str("<h3>Not identifiable</h3><ul>\n");
        for n in &s.not_identifiable {
            let _ = writeln!(h, "<li><b>{}</b>: {}</li>", html(n.name), html(&n.says));
        }
        h.push_str("</ul>\n");
        let _ = writeln!(
            h,
            "<p><img src=\"{}\" alt=\"pretravel by direction\"></p>",
            polar_file(s)
        );
        h.push_str("<h3>Directions</h3><table><tr><th>dir</th><th>φ °</th><th>n</th><th>pretravel µm</th><th>2σ µm</th><th>touch 1 − mean(2…) µm</th><th>model µm</th><th>correction µm</th><th>U µm</th></tr>\n");
        for d in &s.directions {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                d.index,
                num(d.phi_deg, 1),
                d.spread.touches,
                num(d.spread.mean_2on_um, 3),
                num(d.spread.two_sigma_2on_um, 3),
                num(d.spread.first_touch_offset_um, 3),
                num(d.model_pretravel_um, 3),
                num(d.correction_um, 3),
                num(d.correction_u_k2_um, 3)
            );
        }
        h.push_str("</table>\n<h3>What the model misses</h3><table><tr><th>candidate</th><th>physics</th><th>ΔBIC</th><th>RMS touch 1 µm</th></tr>\n");
        for c in &s.diagnosis.candidates {
            let (name, physics) = (c.effect.name(), c.effect.physics());
            candidate_row(&mut h, name, physics, c.delta_bic, c.rms_um[0]);
        }
        h.push_str("</table></section>\n");
    }
    h.push_str(&files_paragraph(&[
        "probe.json",
        "probe_directions.parquet",
        "probe_touches.parquet",
        "report.md",
    ]));
    h.push_str("</body></html>\n");
    h
}
