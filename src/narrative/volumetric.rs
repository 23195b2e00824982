//! The words of a `volumetric` run: the terminal's lines, `report.md` and the `index.html`
//! section.

use std::fmt::Write as _;

use dbbcal_machine::volumetric::solve::Quantity;
use dbbcal_machine::volumetric::study::VolumetricStudy;

use super::words::{self, num};
use crate::kinds::volumetric::VolumetricPlan;
use crate::output::volumetric::{ControllerTables, DecisionRecord};

/// `text` safe inside an HTML element or attribute.
fn html(text: &str) -> String {
    words::html(text).replace('"', "&quot;")
}

fn q(q: &Quantity) -> String {
    if q.identifiable {
        format!("{} = {} ± {}", q.name, num(q.value, 2), num(q.u_k2, 2))
    } else {
        format!("{} = {} (not seen: gauge value)", q.name, num(q.value, 2))
    }
}

/// V1, V2, V3 in words: measured with U, or said not determined (gauge values shown as such).
fn v_figures(s: &VolumetricStudy) -> String {
    let values = format!(
        "{} / {} / {} µm",
        num(s.v1.value_um, 2),
        num(s.v2.value_um, 2),
        num(s.v3.value_um, 2)
    );
    if s.figures_identifiable {
        format!(
            "{values} (U {} / {} / {} µm)",
            num(s.v1.u_k2_um, 2),
            num(s.v2.u_k2_um, 2),
            num(s.v3.u_k2_um, 2)
        )
    } else {
        format!("not determined by these readings, which cannot see every term of the grid's errors; the values in the stated gauge, {values}, are not the machine's")
    }
}

/// Each bar-read diagonal in one sentence: the bar, its segments, U at the far corner and the
/// bar's share of it.
fn bar_sentences(s: &VolumetricStudy) -> Vec<String> {
    s.bars
        .iter()
        .map(|b| {
            let st = &b.stitched;
            let far = st.target_mm.len() - 1;
            let [random, scale, cosine] = st.difference_u_um(0, far);
            let all = random.powi(2) + scale.powi(2) + cosine.powi(2);
            let share = if all > 0.0 {
                100.0 * (scale.powi(2) + cosine.powi(2)) / all
            } else {
                0.0
            };
            format!(
                "diagonal {} was read by bar {} in {} segments ({} targets, weighted RMS of the stitch {}); U at the far corner {} µm (k = 2), of which the bar's scale ({} ppm, fully correlated) and misalignment make {} % of U²",
                b.sign,
                b.bar,
                b.segments(),
                st.target_mm.len(),
                num(st.weighted_rms, 2),
                num(st.u_k2_um[far], 2),
                st.budget.scale_u_ppm,
                num(share, 0)
            )
        })
        .collect()
}

/// With both instruments: the bar's scale against the laser's, a check of its calibration.
fn bar_scale_sentence(s: &VolumetricStudy) -> Option<String> {
    let q = s.bar_scale_vs_laser.as_ref()?;
    let b = s.bars.first()?;
    let u_cal = 2.0
        * b.stitched
            .budget
            .scale_u_ppm
            .hypot(s.scale_terms.laser_u_ppm);
    Some(format!(
        "bar {}'s scale less the laser's, fitted from the diagonals both see: {} ppm (U {} ppm from the readings); its calibration and the laser's budget allow ±{} ppm (k = 2){}; the bar's scale is a nuisance of the fit, so Σ L_k² ε_k / D² is the laser's",
        b.bar,
        num(q.value, 2),
        num(q.u_k2, 2),
        num(u_cal, 2),
        if q.value.abs() > (u_cal.powi(2) + q.u_k2.powi(2)).sqrt() {
            ": beyond it, check the bar's calibration"
        } else {
            ""
        }
    ))
}

/// V_diag's budget in one sentence: where E lies, and what U holds.
fn v_diag_sentence(s: &VolumetricStudy) -> Option<String> {
    let b = s.v_diag_budget.as_ref()?;
    let instrument = if b.source == "bar" {
        "the bar's scale"
    } else {
        "the laser's scale"
    };
    Some(format!(
        "E of diagonal {} ({}) between its target means at {} mm and {} mm; U (k = 1 parts): runs{} {} µm, {instrument} {} ppm × {} mm = {} µm{}; the instrument's share of U² {} %",
        b.diagonal,
        b.source,
        num(b.d_max_mm, 1),
        num(b.d_min_mm, 1),
        if b.source == "bar" { " and stitching" } else { "" },
        num(b.random_um, 3),
        num(b.scale_u_ppm, 3),
        num((b.d_max_mm - b.d_min_mm).abs(), 1),
        num(b.scale_um, 3),
        if b.source == "bar" {
            format!(", misalignment {} µm", num(b.cosine_um, 4))
        } else {
            String::new()
        },
        num(100.0 * b.instrument_share(), 0)
    ))
}

/// The terminal's lines (label, text).
pub(crate) fn headline(
    campaign: &str,
    s: &VolumetricStudy,
    decisions: &[DecisionRecord],
    plan: &VolumetricPlan,
) -> Vec<(&'static str, String)> {
    let mut lines = vec![(
        "Volumetric",
        format!(
            "{campaign}: {} readings on {} diagonal(s); rank {} of {} parameters; residual RMS {} µm",
            s.observations.len(),
            s.curves.len(),
            s.fit.rank,
            s.fit.layout.len(),
            num(s.fit.rms_um, 3)
        ),
    )];
    if let Some(v) = s.v_diag {
        lines.push((
            "V_diag",
            format!(
                "{} µm (U {} µm), max E over the diagonals",
                num(v.value_um, 2),
                num(v.u_k2_um, 2)
            ),
        ));
    }
    if let Some(b) = v_diag_sentence(s) {
        lines.push(("V_diag budget", b));
    }
    for b in bar_sentences(s) {
        lines.push(("Bar", b));
    }
    if let Some(b) = bar_scale_sentence(s) {
        lines.push(("Bar scale", b));
    }
    lines.push((
        "Squareness",
        format!(
            "{} µrad; {} µm/m",
            s.squareness.iter().map(q).collect::<Vec<_>>().join(", "),
            q(&s.mean_scale)
        ),
    ));
    lines.push(("V1 V2 V3", v_figures(s)));
    // The engine's lost combinations and the gauge are in report.md and volumetric.json; the
    // terminal says what is unseen in words.
    for line in s
        .invisible
        .iter()
        .filter(|l| !l.starts_with("rank ") && !l.starts_with("reported in the gauge"))
    {
        lines.push(("Cannot see", line.clone()));
    }
    for d in decisions {
        lines.push((
            "ISO 14253-1",
            format!(
                "{}: {} ± {} against {}: {}",
                d.quantity,
                num(d.value.unwrap_or(f64::NAN), 2),
                num(d.u_k2.unwrap_or(f64::NAN), 2),
                d.tolerance,
                d.decision
            ),
        ));
    }
    match s.diagnosis.proposal {
        Some(e) => lines.push((
            "Missing",
            format!(
                "{} ({}); next: {}",
                e.name(),
                e.physics(),
                plan.next_command(e)
            ),
        )),
        None => lines.push((
            "Missing",
            "no effect of the catalogue lowers the BIC enough: the model explains the readings"
                .into(),
        )),
    }
    lines
}

/// `report.md`.
pub(crate) fn report_md(
    campaign: &str,
    s: &VolumetricStudy,
    decisions: &[DecisionRecord],
    tables: &ControllerTables,
    lines: &[(&'static str, String)],
) -> String {
    let mut md = format!("# Volumetric accuracy — campaign {campaign}\n\n");
    for (label, text) in lines {
        let _ = writeln!(md, "- **{label}**: {text}");
    }
    let _ = writeln!(md, "\nConventions: error = measured − commanded; displacements µm, squareness and slopes µrad (= µm/m); e = 0 at the workspace's min corner; U is expanded (k = 2).\n");
    let _ = writeln!(md, "## What these readings cannot see\n");
    for l in &s.invisible {
        let _ = writeln!(md, "- {l}");
    }
    let _ = writeln!(md, "\n## Diagonals (ISO 230-2 statistics, ISO 230-6 reading)\n\n| diagonal | source | D mm | A µm | B µm | R µm | E µm | M µm |\n|---|---|---:|---:|---:|---:|---:|---:|");
    for c in &s.curves {
        match &c.iso {
            Ok(i) => {
                let o = |v: Option<f64>| num(v.unwrap_or(f64::NAN), 2);
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {} | {} | {} | {} | {} |",
                    c.sign,
                    c.source,
                    num(c.length_mm, 1),
                    o(i.accuracy_a_um.or(i.up.map(|u| u.accuracy_um))),
                    o(i.reversal_b_um),
                    o(i.repeatability_r_um.or(i.up.map(|u| u.repeatability_um))),
                    o(c.e_um),
                    o(i.mean_range_m_um)
                );
            }
            Err(e) => {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | not evaluated: {e} |||||",
                    c.sign,
                    c.source,
                    num(c.length_mm, 1)
                );
            }
        }
    }
    if let Some(v) = s.v_diag {
        let _ = writeln!(
            md,
            "\nV_diag = {} µm (U {} µm).",
            num(v.value_um, 2),
            num(v.u_k2_um, 2)
        );
    }
    if let Some(b) = v_diag_sentence(s) {
        let _ = writeln!(md, "\nV_diag's budget: {b}.");
    }
    if !s.bars.is_empty() {
        let _ = writeln!(md, "\n## Body diagonals read by a bar\n\nThe fixed ball re-seated at sockets along each diagonal, one segment per socket; each segment's constant (the socket's place along the line) solved with Dr in one least-squares problem (`docs/bar-diagonals.md`). Dr and its U per target are in `volumetric_bar.parquet`.\n");
        for l in bar_sentences(s).into_iter().chain(bar_scale_sentence(s)) {
            let _ = writeln!(md, "- {l}.");
        }
    }
    let _ = writeln!(md, "\n## The joint least-squares fit\n\nEvery reading in one problem; model effects: {}. Rank {} of {}; residual RMS {} µm, σ {} µm.\n",
        s.fit.layout.effects.iter().map(|e| e.name()).collect::<Vec<_>>().join(", "),
        s.fit.rank, s.fit.layout.len(), num(s.fit.rms_um, 4), num(s.fit.sigma_um, 4));
    let _ = writeln!(
        md,
        "| quantity | value | U (k = 2) | seen |\n|---|---:|---:|---|"
    );
    for x in s
        .squareness
        .iter()
        .chain(std::iter::once(&s.mean_scale))
        .chain(s.slopes.iter().flatten())
    {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} |",
            x.name,
            num(x.value, 3),
            num(x.u_k2, 3),
            if x.identifiable { "yes" } else { "no (gauge)" }
        );
    }
    if !s.fit.lost.is_empty() {
        let _ = writeln!(
            md,
            "\nLost combinations (the linear engine's words): {}.",
            s.fit.lost.join("; ")
        );
    }
    let _ = writeln!(
        md,
        "\n## The naive closed-form inversion (for comparison)\n"
    );
    match &s.naive {
        Ok(n) => {
            let _ = writeln!(md, "β taken as zero: S_xy {} µrad, S_yz {} µrad, S_zx {} µrad; scales {} / {} / {} µm/m. Where the joint fit's squareness differs, pointing biased these.",
                num(n.squareness_urad[0], 2), num(n.squareness_urad[1], 2), num(n.squareness_urad[2], 2),
                num(n.scale_um_per_m[0], 2), num(n.scale_um_per_m[1], 2), num(n.scale_um_per_m[2], 2));
        }
        Err(e) => {
            let _ = writeln!(md, "Not available: {e}.");
        }
    }
    if let Some((data, res)) = s.fourth_rms_um {
        let _ = writeln!(md, "\nFourth sign pattern (sx·sy·sz) consistency residual: RMS {} µm in the readings, {} µm in the fit's residuals (zero for the additive model with β = 0).", num(data, 3), num(res, 3));
    }
    let _ = writeln!(md, "\n## Error functions (D_k(j) at the step nodes, µm, U k = 2)\n\nD_k(j) is error component k along axis j moved, zero at the workspace's min corner. Where a value's U is \"—\" the value holds a slope the readings cannot see (given in the stated gauge); its shape (the function less its least-squares line over the nodes) is seen, with U.\n\n| function | position mm | value | U | shape | U shape |\n|---|---:|---:|---:|---:|---:|");
    let f = s.fit.functions();
    let shapes = s.fit.shapes();
    for (j, row) in f.iter().enumerate() {
        for (k, series) in row.iter().enumerate() {
            for ((pos, x), (_, sh)) in series.iter().zip(&shapes[j][k]) {
                let _ = writeln!(
                    md,
                    "| D{}({}) | {} | {} | {} | {} | {} |",
                    ["x", "y", "z"][k],
                    ["x", "y", "z"][j],
                    num(*pos, 1),
                    num(x.value, 3),
                    num(x.u_k2, 3),
                    num(sh.value, 3),
                    num(sh.u_k2, 3)
                );
            }
        }
    }
    let _ = writeln!(md, "\n## The grid\n\nV1, V2, V3: {}.\n\n| l | i | j | k | x mm | y mm | z mm | ex µm | ey µm | ez µm | U ex | U ey | U ez |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        v_figures(s));
    for n in &s.nodes {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            n.line,
            n.node[0],
            n.node[1],
            n.node[2],
            num(n.position_mm[0], 1),
            num(n.position_mm[1], 1),
            num(n.position_mm[2], 1),
            num(n.error[0].value, 3),
            num(n.error[1].value, 3),
            num(n.error[2].value, 3),
            num(n.error[0].u_k2, 3),
            num(n.error[1].u_k2, 3),
            num(n.error[2].u_k2, 3)
        );
    }
    let _ = writeln!(md, "\n## Controller tables\n");
    for (file, statement) in &tables.statements {
        let _ = writeln!(md, "- `{file}`: {statement}");
    }
    let _ = writeln!(md, "\n## ISO 14253-1 decisions\n");
    if decisions.is_empty() {
        let _ = writeln!(md, "No tolerance given (`[volumetric.tolerances]`).");
    }
    for d in decisions {
        let _ = writeln!(
            md,
            "- {}: {} ± {} against {} → **{}**{}",
            d.quantity,
            num(d.value.unwrap_or(f64::NAN), 2),
            num(d.u_k2.unwrap_or(f64::NAN), 2),
            d.tolerance,
            d.decision,
            d.note.as_ref().map_or(String::new(), |n| format!(" ({n})"))
        );
    }
    let _ = writeln!(md, "\n## What the model misses (the loop)\n\nResidual RMS {} µm; fourth pattern of the residuals {} µm.\n\n| candidate | physics | ΔBIC | RMS after µm | fourth pattern after µm |\n|---|---|---:|---:|---:|",
        num(s.diagnosis.base_rms_um, 4), num(s.diagnosis.base_fourth_rms_um.unwrap_or(f64::NAN), 4));
    for c in &s.diagnosis.candidates {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} |",
            c.effect.name(),
            c.effect.physics(),
            num(c.delta_bic, 1),
            num(c.rms_after_um, 4),
            num(c.fourth_rms_after_um.unwrap_or(f64::NAN), 4)
        );
    }
    match s.diagnosis.proposal {
        Some(e) => {
            let _ = writeln!(md, "\nNamed as missing: **{}**.", e.name());
        }
        None => {
            let _ = writeln!(md, "\nNo effect of the catalogue is missing.");
        }
    }
    md
}

/// `index.html`: the volumetric section.
pub(crate) fn page(
    campaign: &str,
    s: &VolumetricStudy,
    decisions: &[DecisionRecord],
    tables: &ControllerTables,
    lines: &[(&'static str, String)],
    figures: &[(String, String)],
) -> String {
    let mut h = String::new();
    let _ = writeln!(h, "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>dbbcal — volumetric — {}</title>\n<style>body{{font-family:sans-serif;max-width:70em;margin:2em auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}.h td{{text-align:left}}img{{max-width:100%}}</style></head><body>", html(campaign));
    let _ = writeln!(h, "<section id=\"volumetric\"><h1>Volumetric accuracy — campaign {}</h1>\n<table class=\"h\">", html(campaign));
    for (label, text) in lines {
        let _ = writeln!(h, "<tr><td><b>{label}</b></td><td>{}</td></tr>", html(text));
    }
    h.push_str("</table>\n<h2>What these readings cannot see</h2><ul>\n");
    for l in &s.invisible {
        let _ = writeln!(h, "<li>{}</li>", html(l));
    }
    h.push_str("</ul>\n<h2>Diagonals (ISO 230-2 statistics, ISO 230-6 reading)</h2>\n<table><tr><th>diagonal</th><th>source</th><th>D mm</th><th>A µm</th><th>B µm</th><th>R µm</th><th>E µm</th></tr>\n");
    for c in &s.curves {
        let i = c.iso.as_ref().ok();
        let o = |v: Option<f64>| num(v.unwrap_or(f64::NAN), 2);
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            html(c.sign.as_str()),
            c.source,
            num(c.length_mm, 1),
            o(i.and_then(|i| i.accuracy_a_um.or(i.up.map(|u| u.accuracy_um)))),
            o(i.and_then(|i| i.reversal_b_um)),
            o(i.and_then(|i| i.repeatability_r_um.or(i.up.map(|u| u.repeatability_um)))),
            o(c.e_um)
        );
    }
    if let Some(v) = s.v_diag {
        let _ = writeln!(
            h,
            "</table>\n<p>V_diag = {} µm (U {} µm), the largest E.</p>",
            num(v.value_um, 2),
            num(v.u_k2_um, 2)
        );
    } else {
        h.push_str("</table>\n");
    }
    if let Some(b) = v_diag_sentence(s) {
        let _ = writeln!(h, "<p>V_diag's budget: {}.</p>", html(&b));
    }
    if !s.bars.is_empty() {
        h.push_str("<h2>Body diagonals read by a bar</h2><ul>\n");
        for l in bar_sentences(s).into_iter().chain(bar_scale_sentence(s)) {
            let _ = writeln!(h, "<li>{}.</li>", html(&l));
        }
        h.push_str("</ul>\n");
    }
    h.push_str("<h2>Squareness and scale (joint fit)</h2>\n<table><tr><th>quantity</th><th>value</th><th>U (k = 2)</th><th>seen</th></tr>\n");
    for x in s.squareness.iter().chain(std::iter::once(&s.mean_scale)) {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            html(&x.name),
            num(x.value, 3),
            num(x.u_k2, 3),
            if x.identifiable { "yes" } else { "no" }
        );
    }
    h.push_str("</table>\n");
    if let Ok(n) = &s.naive {
        let _ = writeln!(h, "<p>Naive inversion (β = 0), for comparison: S_xy {} µrad, S_yz {} µrad, S_zx {} µrad.</p>", num(n.squareness_urad[0], 2), num(n.squareness_urad[1], 2), num(n.squareness_urad[2], 2));
    }
    for (file, caption) in figures {
        let _ = writeln!(
            h,
            "<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
            html(file),
            html(caption),
            html(caption)
        );
    }
    h.push_str("<h2>ISO 14253-1 decisions</h2><ul>\n");
    for d in decisions {
        let _ = writeln!(
            h,
            "<li>{}: {} ± {} against {}: <b>{}</b></li>",
            html(&d.quantity),
            num(d.value.unwrap_or(f64::NAN), 2),
            num(d.u_k2.unwrap_or(f64::NAN), 2),
            d.tolerance,
            d.decision
        );
    }
    h.push_str("</ul>\n<h2>Controller tables</h2><ul>\n");
    for (file, statement) in &tables.statements {
        let _ = writeln!(
            h,
            "<li><a href=\"{}\">{}</a>: {}</li>",
            html(file),
            html(file),
            html(statement)
        );
    }
    h.push_str("</ul>\n<h2>What the model misses</h2>\n<table><tr><th>candidate</th><th>physics</th><th>ΔBIC</th><th>RMS after µm</th></tr>\n");
    for c in &s.diagnosis.candidates {
        let (name, physics) = (c.effect.name(), c.effect.physics());
        words::candidate_row(&mut h, name, physics, c.delta_bic, c.rms_after_um);
    }
    h.push_str("</table>\n");
    h.push_str(&words::files_paragraph(&[
        "volumetric.json",
        "volumetric_grid.parquet",
        "volumetric_functions.parquet",
        "report.md",
    ]));
    h.push_str("</section></body></html>\n");
    h
}
