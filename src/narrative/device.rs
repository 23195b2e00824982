//! The device stage in words: a section of `report.md` and of `index.html`
//! (`docs/spec/device-format.md`): the axis moved, the datum, per error its range and largest U,
//! and every dwell flagged (near-singular, rotary axes moved, no pose).

use std::fmt::Write;

use crate::figures::{FigureFile, FigureKind};
use crate::pipeline::RunResults;

use super::page::escape;

/// (name, unit, min, max, largest U, straightness range with the line removed) of one error.
type Row = (String, &'static str, f64, f64, f64, Option<f64>);

/// A [`Row`] per error.
fn ranges(results: &RunResults) -> Option<Vec<Row>> {
    let t = results.device.as_ref()?.outcome.as_ref().ok()?;
    let units = ["µm", "µm", "µm", "µrad", "µrad", "µrad"];
    let straight = t.axis.map(|a| a.straightness_indices());
    Some(
        (0..6)
            .map(|c| {
                let vals: Vec<f64> = t
                    .dwells
                    .iter()
                    .filter_map(|d| Some(d.errors?.to_array()[c]))
                    .collect();
                let u = t
                    .dwells
                    .iter()
                    .filter_map(|d| Some(d.u_k2?.to_array()[c]))
                    .fold(0.0, f64::max);
                let line_removed = straight.and_then(|idx| {
                    let j = idx.iter().position(|&i| i == c)?;
                    let v: Vec<f64> = t
                        .dwells
                        .iter()
                        .filter_map(|d| Some(d.straightness_line_removed_um?[j]))
                        .collect();
                    let (lo, hi) = v
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                            (a.min(*x), b.max(*x))
                        });
                    (!v.is_empty()).then_some(hi - lo)
                });
                let (lo, hi) = vals
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                        (a.min(*x), b.max(*x))
                    });
                (t.names[c].clone(), units[c], lo, hi, u, line_removed)
            })
            .collect(),
    )
}

fn headline(results: &RunResults) -> Option<String> {
    let s = results.device.as_ref()?;
    Some(match &s.outcome {
        Err(e) => format!("Device {}: not evaluated: {e}", s.device.id),
        Ok(t) => {
            let n = t.dwells.iter().filter(|d| d.errors.is_some()).count();
            format!(
                "Device {}: {} dwells, {n} evaluated; axis moved: {}; datum: station {}.",
                s.device.id,
                t.dwells.len(),
                t.axis
                    .map_or("none or several (generic names)".to_string(), |a| a
                        .letter()
                        .to_string()),
                s.dwells.get(t.datum).map_or(0, |d| d.station)
            )
        }
    })
}

/// ISO 230-2 on the positioning error, in one sentence (or why it is missing).
fn iso_line(results: &RunResults) -> Option<String> {
    let iso = crate::output::device_record::positioning_iso(results.device.as_ref()?)?;
    Some(match iso {
        Err(why) => format!("ISO 230-2 not evaluated: {why}."),
        Ok((name, i)) => {
            let v = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.3}"));
            let runs = i
                .targets
                .iter()
                .flat_map(|t| [t.up.map(|d| d.runs), t.down.map(|d| d.runs)])
                .flatten()
                .min()
                .unwrap_or(0);
            format!(
                "ISO 230-2 on {name} (µm): A {}, B {}, R {}, E {}, M {}; {runs} run(s) per direction at the fewest{}.",
                v(i.accuracy_a_um),
                v(i.reversal_b_um),
                v(i.repeatability_r_um),
                v(i.systematic_e_um),
                v(i.mean_range_m_um),
                if runs < 5 { " (ISO 230-2 asks for at least 5: R and A rest on few runs)" } else { "" }
            )
        }
    })
}

fn flagged(results: &RunResults) -> Vec<String> {
    let Some(t) = results
        .device
        .as_ref()
        .and_then(|s| s.outcome.as_ref().ok())
    else {
        return Vec::new();
    };
    t.dwells
        .iter()
        .filter(|d| d.errors.is_none())
        .map(|d| {
            format!(
                "station {} (run {}): {}",
                d.input.station,
                d.input.run.map_or("-".to_string(), |r| r.to_string()),
                d.flag.as_deref().unwrap_or("not evaluated")
            )
        })
        .collect()
}

/// The section of `report.md`, when the device stage ran.
pub(crate) fn markdown(results: &RunResults) -> Option<String> {
    let mut md = String::from("## Device\n\n");
    let _ = writeln!(md, "{}\n", headline(results)?);
    if let Some(rows) = ranges(results) {
        md.push_str("| error | min | max | largest U (k=2) | range, line removed | unit |\n|---|---|---|---|---|---|\n");
        for (name, unit, lo, hi, u, lr) in rows {
            let _ = writeln!(
                md,
                "| {name} | {lo:.3} | {hi:.3} | {u:.3} | {} | {unit} |",
                lr.map_or("-".to_string(), |v| format!("{v:.3}"))
            );
        }
        md.push_str("\nError = measured − commanded, in the machine's axes at the tool point; straightness also with its least-squares line removed (device.json, device_errors.parquet).\n");
    }
    for f in flagged(results) {
        let _ = writeln!(md, "- {f}");
    }
    if let Some(line) = iso_line(results) {
        let _ = writeln!(md, "\n{line}");
    }
    if let Some(s) = results.device.as_ref() {
        super::axis::tables_markdown(&mut md, &s.tables, "station");
    }
    md.push('\n');
    super::device_loop::markdown(&mut md, results);
    Some(md)
}

/// The section of `index.html`, when the device stage ran.
pub(crate) fn html(h: &mut String, results: &RunResults, figures: &[FigureFile]) {
    let Some(line) = headline(results) else {
        return;
    };
    let _ = writeln!(
        h,
        "<section id=\"device\"><h2>Device</h2>\n<p>{}</p>",
        escape(&line)
    );
    if let Some(rows) = ranges(results) {
        h.push_str("<table><thead><tr><th>error</th><th>min</th><th>max</th><th>largest U (k=2)</th><th>range, line removed</th><th>unit</th></tr></thead><tbody>\n");
        for (name, unit, lo, hi, u, lr) in rows {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{lo:.3}</td><td>{hi:.3}</td><td>{u:.3}</td><td>{}</td><td>{unit}</td></tr>",
                escape(&name),
                lr.map_or("-".to_string(), |v| format!("{v:.3}"))
            );
        }
        h.push_str("</tbody></table>\n<p>Error = measured − commanded, in the machine's axes at the tool point (ISO 230-1 names).</p>\n");
    }
    let flags = flagged(results);
    if !flags.is_empty() {
        h.push_str("<ul class=\"warn\">\n");
        for f in flags {
            let _ = writeln!(h, "<li>{}</li>", escape(&f));
        }
        h.push_str("</ul>\n");
    }
    for f in figures.iter().filter(|f| f.kind == FigureKind::Device) {
        super::page::figure(h, f);
    }
    if let Some(line) = iso_line(results) {
        let _ = writeln!(h, "<p>{}</p>", escape(&line));
    }
    super::device_loop::html(h, results);
    h.push_str("</section>\n");
}
