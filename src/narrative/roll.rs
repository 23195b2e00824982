//! The words of a `roll` run: the terminal's lines, `report.md` and `index.html`.

use std::fmt::Write as _;

use dbbcal_machine::roll::{RollStudy, PROBE_NAMES};

use super::words::{files_paragraph, html, num};
use crate::kinds::roll::RollPlan;

/// The terminal's lines (label, text): the roll over the travel, the warning when it is
/// implausible, the verdict and the command that adds the named effect.
pub(crate) fn headline(
    campaign: &str,
    s: &RollStudy,
    plan: &RollPlan,
) -> Vec<(&'static str, String)> {
    let last = s.stations.last();
    let mut lines = vec![(
        "Roll",
        format!(
            "{campaign}: εx at {} stations from {} dwells in {} pass(es); εx({}) = {} ± {} µrad (U, k = 2); {} = {:+}·εx{}",
            s.stations.len(),
            s.dwells.len(),
            s.passes.len(),
            last.map_or(0, |l| l.station),
            num(last.map_or(f64::NAN, |l| l.roll_urad), 1),
            num(last.map_or(f64::NAN, |l| l.u_k2_urad), 1),
            s.roll_error_name,
            s.roll_error_sign,
            if s.level_datum {
                "; ramp removed by the end-level datum"
            } else {
                ""
            }
        ),
    )];
    if let Some(i) = &s.implausible {
        lines.push((
            "Warning",
            format!(
                "the roll reaches {} µrad: implausibly large for a machine table (typical 5–30 µrad, limit {} µrad); it equals a combined probe zero offset of {} µm ({} µrad per station)",
                num(i.max_abs_urad, 0),
                num(i.limit_urad, 0),
                num(i.equivalent_offset_um, 2),
                num(i.slope_urad_per_station, 1)
            ),
        ));
    }
    for e in &s.effects {
        lines.push((
            "Effect",
            format!(
                "{} ({}): {} = {} ± {} (U, k = 2)",
                e.effect.name(),
                e.effect.physics(),
                e.effect.parameter_name(),
                num(e.value.0, 3),
                num(e.value.1, 3)
            ),
        ));
    }
    let d = &s.diagnosis;
    let verdict = match d.missing {
        Some(e) => format!("missing {} ({}): {}", e.name(), e.physics(), d.missing_because),
        None => format!(
            "model adequate: no effect of the catalogue improves it (χ² = {} on {} degrees of freedom)",
            num(s.chi2.0, 1),
            s.chi2.1
        ),
    };
    lines.push(("Diagnosis", verdict));
    if let Some(e) = d.missing {
        if d.ledger.len() > 1 {
            lines.push(("Next", plan.next_command(e)));
        }
    }
    lines
}

/// `report.md`.
pub(crate) fn report_md(campaign: &str, s: &RollStudy) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Roll — campaign {campaign}\n");
    let _ = writeln!(
        md,
        "Four probes A, B, C, D (seed 004; `docs/spec/machine-physics.md`, \"Kind roll\"). εx is the stage's roll about R's +x (right-handed, µrad), datum εx = 0 at station 0; the axis's roll error is {} = {:+}·εx (the table carries the workpiece; R's +x is b_to_a times M's axis). L = {} mm.\n",
        s.roll_error_name, s.roll_error_sign, s.l_mm
    );
    let _ = writeln!(
        md,
        "- samples: {} read, {} in dwells (dwells: {}; passes: {})",
        s.samples.0, s.samples.1, s.dwell_source, s.pass_source
    );
    let _ = writeln!(
        md,
        "- resolution (µm, {}): {}",
        s.resolution_source,
        PROBE_NAMES
            .iter()
            .zip(&s.resolution_um)
            .map(|(p, r)| format!("{p} {r}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        md,
        "- station means: Type A from the 20-Hz samples with their autocorrelation (lags summed while significantly positive), plus resolution/√12; u(εx(n)) grows as 2·10³ u √n / L",
    );
    let _ = writeln!(
        md,
        "- mean step from the dwells: {} mm; χ² = {} on {} degrees of freedom (u scaled by {}); scale u of εx from the probes' lateral positions: {:.1e}\n",
        num(s.step_mm, 4),
        num(s.chi2.0, 2),
        s.chi2.1,
        num(s.chi2.2, 3),
        s.scale_u
    );
    if let Some(i) = &s.implausible {
        let _ = writeln!(
            md,
            "**Warning.** The roll reaches {} µrad, implausibly large for a machine table (typical roll 5–30 µrad; limit {} µrad). It grows by {} µrad per station, what a combined probe zero offset o_C − o_D − o_A + o_B of {} µm makes (the seed's 1.35 mrad after 18 stations equals 6 µm). Read a level at both ends of the travel (`levels/`) to separate it.\n",
            num(i.max_abs_urad, 0),
            num(i.limit_urad, 0),
            num(i.slope_urad_per_station, 1),
            num(i.equivalent_offset_um, 2)
        );
    }
    let _ = writeln!(
        md,
        "## εx per station\n\n| station | x mm | εx µrad | u (readings) µrad | U (k=2) µrad | {} µrad |\n|---|---|---|---|---|---|",
        s.roll_error_name
    );
    for st in &s.stations {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} |",
            st.station,
            num(st.x_mm, 3),
            num(st.roll_urad, 3),
            num(st.u_noise_urad, 3),
            num(st.u_k2_urad, 3),
            num(st.roll_error_urad, 3)
        );
    }
    let _ = writeln!(
        md,
        "\n## Passes\n\n| pass | direction | stations | RMS residual µrad |\n|---|---|---|---|"
    );
    for (p, pass) in s.passes.iter().enumerate() {
        let _ = writeln!(
            md,
            "| {} | {} | {} → {} | {} |",
            p + 1,
            if pass.direction > 0 { "out" } else { "back" },
            pass.stations.first().copied().unwrap_or(0),
            pass.stations.last().copied().unwrap_or(0),
            num(pass.rms_residual_urad, 4)
        );
    }
    if !s.levels.is_empty() {
        let _ = writeln!(
            md,
            "\n## Level readings\n\n| station | roll µrad | residual µrad |\n|---|---|---|"
        );
        for l in &s.levels {
            let _ = writeln!(
                md,
                "| {} | {} | {} |",
                l.station,
                num(l.roll_urad, 2),
                num(l.residual_urad, 3)
            );
        }
    }
    let _ = writeln!(
        md,
        "\n## The loop\n\n| effect | in the model | value | U (k=2) |\n|---|---|---|---|"
    );
    for e in &s.effects {
        let _ = writeln!(
            md,
            "| {} ({}) | yes | {} | {} |",
            e.effect.parameter_name(),
            e.effect.physics(),
            num(e.value.0, 4),
            num(e.value.1, 4)
        );
    }
    let _ = writeln!(
        md,
        "\n| candidate | physics | ΔBIC | χ² |\n|---|---|---|---|"
    );
    for c in &s.diagnosis.candidates {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} |",
            c.effect.name(),
            c.effect.physics(),
            c.delta_bic
                .map_or("not identifiable here".into(), |v| num(v, 1)),
            num(c.chi2, 2)
        );
    }
    match s.diagnosis.missing {
        Some(e) => {
            let _ = writeln!(
                md,
                "\n**Missing effect: {} ({}).** {}",
                e.name(),
                e.physics(),
                s.diagnosis.missing_because
            );
        }
        None => {
            let _ = writeln!(md, "\nNo effect of the catalogue improves the model.");
        }
    }
    let _ = writeln!(md, "\nNot identifiable from these data:\n");
    for u in &s.diagnosis.unseen {
        let _ = writeln!(md, "- {}: {}", u.effect, u.becomes);
    }
    md
}

/// `index.html`: the headline, the figure, then `report.md`'s tables as HTML.
pub(crate) fn page(
    campaign: &str,
    s: &RollStudy,
    lines: &[(&'static str, String)],
    figure: &str,
) -> String {
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>dbbcal — roll — {}</title>\n<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}.h td{{text-align:left}}img{{max-width:100%}}</style></head><body>",
        html(campaign)
    );
    let _ = writeln!(
        h,
        "<h1>Roll ({}) — campaign {}</h1>\n<table class=\"h\">",
        s.roll_error_name,
        html(campaign)
    );
    for (label, text) in lines {
        let _ = writeln!(h, "<tr><td><b>{label}</b></td><td>{}</td></tr>", html(text));
    }
    let caption = "εx(n) with its U (k = 2) band and each pass's own eq. 10 curve; below, each pass minus all passes";
    let _ = writeln!(
        h,
        "</table>\n<figure><img src=\"figures/{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
        html(figure),
        html(caption),
        html(caption)
    );
    let _ = writeln!(
        h,
        "<h2>εx per station (µrad; U k = 2)</h2>\n<table><tr><th>station</th><th>x mm</th><th>εx</th><th>u readings</th><th>U</th><th>{}</th></tr>",
        s.roll_error_name
    );
    for st in &s.stations {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            st.station,
            num(st.x_mm, 3),
            num(st.roll_urad, 3),
            num(st.u_noise_urad, 3),
            num(st.u_k2_urad, 3),
            num(st.roll_error_urad, 3)
        );
    }
    h.push_str("</table>\n<h2>What the model misses</h2>\n<table><tr><th>candidate</th><th>physics</th><th>ΔBIC</th></tr>\n");
    for c in &s.diagnosis.candidates {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td></tr>",
            c.effect.name(),
            html(c.effect.physics()),
            c.delta_bic
                .map_or("not identifiable here".into(), |v| num(v, 1))
        );
    }
    h.push_str("</table>\n<p>Not identifiable from these data:</p><ul>\n");
    for u in &s.diagnosis.unseen {
        let _ = writeln!(h, "<li>{}: {}</li>", html(u.effect), html(&u.becomes));
    }
    h.push_str("</ul>\n");
    h.push_str(&files_paragraph(&[
        "roll.json",
        "roll_stations.parquet",
        "roll_dwells.parquet",
        "report.md",
    ]));
    h.push_str("</body></html>\n");
    h
}
