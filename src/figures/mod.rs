//! Results → report specs. This module knows the results and what a metrologist wants to see
//! in each figure; `report` knows the pixels.

use std::path::Path;

mod device_poses;
mod six_errors;

pub(crate) use six_errors::render_axis;

use crate::diagnose::sensors::SensorProfile;
use crate::diagnose::{BarDiagnosis, LedgerStep};
use crate::narrative::sensors::channel_sensor_summaries;
use crate::pipeline::{BarOutcome, RunPlan, RunResults, Stage};
use crate::report::{self, NamedSeries, ReportError};

/// Which part of a report a figure belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FigureKind {
    BarFit,
    Fleet,
    MatchStudy,
    Diagnosis,
    Ledger,
    BeforeAfter,
    Acceptance,
    Device,
    Axis,
}

/// A figure written: its file name in `figures/`, what it shows, and its bar when it has one.
#[derive(Debug, Clone)]
pub(crate) struct FigureFile {
    pub(crate) file: String,
    pub(crate) kind: FigureKind,
    pub(crate) bar: Option<String>,
    pub(crate) caption: String,
}

/// Every figure the run's stages call for, into `dir`; returns what was written, in order.
pub(crate) fn render_all(
    plan: &RunPlan,
    results: &RunResults,
    dir: &Path,
) -> Result<Vec<FigureFile>, ReportError> {
    let mut written = Vec::new();
    let mut add = |file: String, kind, bar: Option<&str>, caption: String| {
        let path = dir.join(&file);
        // The report crate draws; writing into the output is this crate's: a fault point here,
        // and each figure drawn as one write step ([`drawn`]).
        crate::output::fault::point("write", &path).map_err(|source| ReportError::Write {
            path: path.clone(),
            source,
        })?;
        written.push(FigureFile {
            file,
            kind,
            bar: bar.map(str::to_string),
            caption,
        });
        Ok::<_, ReportError>(path)
    };
    for o in &results.bars {
        let bar = o.model.bar.as_str();
        let path = add(
            format!("bar-{}.png", file_safe(bar)),
            FigureKind::BarFit,
            Some(bar),
            format!("Bar {bar}: measured against model, temperatures, residual"),
        )?;
        drawn(|| report::render_bar_fit(&bar_fit_figure(o, plan.bin_s), &path))?;
    }
    if !results.bars.is_empty() {
        let path = add(
            "fleet.png".into(),
            FigureKind::Fleet,
            None,
            "The fleet's parameters, the reference bar and the predicted mismatches".into(),
        )?;
        drawn(|| report::render_fleet(&fleet(results), &path))?;
    }
    if plan.runs(Stage::MatchStudy) {
        if let Some(study) = &results.study {
            let path = add(
                "match-study.png".into(),
                FigureKind::MatchStudy,
                None,
                "Measured mismatch of every pair of bars".into(),
            )?;
            drawn(|| report::render_heat_map(&heat_map(study), &path))?;
        }
    }
    if let Some(d) = &results.diagnosis {
        for (bd, o) in d.bars.iter().zip(&results.bars) {
            let path = add(
                format!("diagnosis-{}.png", file_safe(&bd.bar)),
                FigureKind::Diagnosis,
                Some(&bd.bar),
                format!("Bar {}: residual diagnostics and channels ranked", bd.bar),
            )?;
            drawn(|| {
                report::render_residual_diagnostics(&residual_figure(bd, o, &d.sensors), &path)
            })?;
        }
        if d.ledger.len() > 1 {
            let path = add(
                "ledger.png".into(),
                FigureKind::Ledger,
                None,
                "Forward selection: the fleet RMS as effects are added".into(),
            )?;
            drawn(|| {
                report::render_ledger(&ledger(&d.ledger, &d.sensors, plan.diagnose.beam), &path)
            })?;
        }
        for bl in d.bar_ledgers.iter().filter(|bl| bl.steps.len() > 1) {
            let path = add(
                format!("ledger-{}.png", file_safe(&bl.bar)),
                FigureKind::Ledger,
                Some(&bl.bar),
                format!("Bar {}: forward selection", bl.bar),
            )?;
            drawn(|| {
                report::render_ledger(&bar_ledger(bl, &d.sensors, plan.diagnose.beam), &path)
            })?;
        }
    }
    if let Some(ba) = &results.before_after {
        let path = add(
            "before-after.png".into(),
            FigureKind::BeforeAfter,
            None,
            "RMS per bar with the base model and with the effects added".into(),
        )?;
        drawn(|| report::render_before_after(&before_after(ba), &path))?;
    }
    if let Some(acc) = &results.acceptance {
        for a in acc {
            let path = add(
                format!(
                    "acceptance-{}@{}.png",
                    file_safe(&a.bar),
                    file_safe(&a.length_id)
                ),
                FigureKind::Acceptance,
                Some(&a.bar),
                format!(
                    "Bar {} on {}: error before and after compensation",
                    a.bar, a.length_id
                ),
            )?;
            drawn(|| report::render_series_panels(&acceptance_sheet(a), &path))?;
        }
        if !acc.is_empty() {
            let path = add(
                "acceptance-fleet.png".into(),
                FigureKind::Acceptance,
                None,
                "Every working bar's error after compensation".into(),
            )?;
            drawn(|| report::render_series_panels(&acceptance_fleet(acc), &path))?;
            let path = add(
                "acceptance-rms.png".into(),
                FigureKind::Acceptance,
                None,
                "RMS error before and after compensation".into(),
            )?;
            drawn(|| report::render_before_after(&acceptance_rms(acc), &path))?;
        }
    }
    if let Some(spec) = six_errors::device_errors_figure(results) {
        let path = add(
            "device-errors.png".into(),
            FigureKind::Device,
            None,
            "The six errors of the moved axis against the commanded position, with U (k = 2)"
                .into(),
        )?;
        drawn(|| report::render_error_grid(&spec, &path))?;
    }
    let poses = results.device.as_ref().and_then(|s| {
        device_poses::device_poses_figure(s, &crate::pipeline::hexapod_of(&s.device))
    });
    if let Some(spec) = poses {
        let path = add(
            "device-poses.png".into(),
            FigureKind::Device,
            None,
            "The device from above and from the side: base, legs and platform at the datum and at the farthest station, the tool point at every dwell".into(),
        )?;
        drawn(|| report::render_geometry(&spec, &path))?;
    }
    Ok(written)
}

/// Draws one figure as one write step of the output ([`crate::output::writing`]): a signal
/// removes the partial folder before or after it, never while the PNG is being written.
fn drawn(render: impl FnOnce() -> Result<(), ReportError>) -> Result<(), ReportError> {
    let _step = crate::output::writing();
    render()
}

fn tolerance_lines(t: f64) -> Vec<report::RefLine> {
    let line = |v: f64| report::RefLine {
        label: format!("tolerance ±{t} µm"),
        value: v,
    };
    vec![line(t), line(-t)]
}

fn acceptance_sheet(a: &crate::acceptance::BarAcceptance) -> report::SeriesPanelsFigure {
    let budget: Vec<String> = a
        .budget
        .iter()
        .map(|t| {
            format!(
                "{} {:.3}",
                t.source
                    .name()
                    .replace("thermal_model_", "thermal_")
                    .replace("_measurement", ""),
                t.u_um
            )
        })
        .collect();
    let refs = if a.references.is_empty() {
        "none".to_string()
    } else {
        a.references.join(", ")
    };
    report::SeriesPanelsFigure {
        title: format!("Acceptance — bar {} on {} ({:.4} mm): {}", a.bar, a.length_id, a.length_mm, a.decision.as_str().to_uppercase()),
        subtitle: format!(
            "Mode {} (references: {refs}). Compensated: max|e| {:.3} µm, PV {:.3}, RMS {:.3}; without: max|e| {:.3}, PV {:.3}, RMS {:.3}.\nu (µm, k=1): {}. U(k=2) = {:.3} µm.\n{}",
            a.mode, a.max_abs_error_um, a.pv_um, a.rms_um, a.before.max_abs_um, a.before.pv_um, a.before.rms_um, budget.join(", "), a.u_k2_um, crate::narrative::acceptance::DECISION_RULE_SHORT
        ),
        x_axis: report::XAxis::TimeSeconds,
        panels: vec![
            report::SeriesPanel {
                title: "Centre-distance error, compensated and not".into(),
                y_label: "error (µm)".into(),
                series: vec![
                    NamedSeries { name: "without compensation".into(), x: a.t_s.clone(), y: a.error_before_um.clone() },
                    NamedSeries { name: "compensated".into(), x: a.t_s.clone(), y: a.error_um.clone() },
                ],
                ref_lines: tolerance_lines(a.tolerance_um),
            },
            report::SeriesPanel {
                title: "Compensated error with its expanded uncertainty (decision zone)".into(),
                y_label: "error (µm)".into(),
                series: vec![NamedSeries { name: "compensated".into(), x: a.t_s.clone(), y: a.error_um.clone() }],
                ref_lines: vec![
                    report::RefLine { label: format!("tolerance − U = ±{:.3} µm (pass zone)", a.tolerance_um - a.u_k2_um), value: a.tolerance_um - a.u_k2_um },
                    report::RefLine { label: format!("tolerance − U = ±{:.3} µm (pass zone)", a.tolerance_um - a.u_k2_um), value: -(a.tolerance_um - a.u_k2_um) },
                ],
            },
        ],
    }
}

fn acceptance_fleet(acc: &[crate::acceptance::BarAcceptance]) -> report::SeriesPanelsFigure {
    let f = crate::acceptance::fleet(acc);
    let tol = acc.first().map_or(1.0, |a| a.tolerance_um);
    let series = |after: bool| -> Vec<NamedSeries> {
        acc.iter()
            .map(|a| NamedSeries {
                name: format!("{} ({})", a.bar, a.decision.as_str()),
                x: a.t_s.clone(),
                y: if after {
                    a.error_um.clone()
                } else {
                    a.error_before_um.clone()
                },
            })
            .collect()
    };
    report::SeriesPanelsFigure {
        title: format!("Fleet acceptance — {} pass, {} fail, {} no decision (tolerance ±{tol} µm)", f.n_pass, f.n_fail, f.n_no_decision),
        subtitle: format!(
            "Modes: {}. Max|e| {:.3} µm compensated, {:.3} µm without; RMS {:.3} vs {:.3} µm; largest U(k=2) {:.3} µm.\n{}",
            f.modes.iter().map(|m| m.name()).collect::<Vec<_>>().join(", "), f.max_abs_error_um, f.max_abs_error_before_um, f.rms_um, f.rms_before_um, f.max_u_k2_um, crate::narrative::acceptance::DECISION_RULE_SHORT
        ),
        x_axis: report::XAxis::TimeSeconds,
        panels: vec![
            report::SeriesPanel { title: "Compensated error".into(), y_label: "error (µm)".into(), series: series(true), ref_lines: tolerance_lines(tol) },
            report::SeriesPanel { title: "Error without thermal compensation".into(), y_label: "error (µm)".into(), series: series(false), ref_lines: tolerance_lines(tol) },
        ],
    }
}

fn acceptance_rms(acc: &[crate::acceptance::BarAcceptance]) -> report::BeforeAfterFigure {
    let f = crate::acceptance::fleet(acc);
    report::BeforeAfterFigure {
        title: "Acceptance — RMS error per working bar without and with thermal compensation"
            .into(),
        subtitle: format!(
            "Modes: {}",
            f.modes
                .iter()
                .map(|m| m.name())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        bar_names: acc
            .iter()
            .map(|a| format!("{}@{}", a.bar, a.length_id))
            .collect(),
        before_um: acc.iter().map(|a| a.before.rms_um).collect(),
        after_um: acc.iter().map(|a| a.rms_um).collect(),
        fleet_before_um: Some(f.rms_before_um),
        fleet_after_um: Some(f.rms_um),
        before_label: "without compensation".into(),
        after_label: "compensated".into(),
    }
}

/// A file-name part for an id: the id itself when it is made of `[A-Za-z0-9._-]` only, does
/// not start with a dot, is at most [`MAX_NAME_PART`] bytes and does not end like an encoded id
/// (`-` and 8 hex digits); else its safe characters (`_` for the others, cut to
/// [`MAX_NAME_PART`] bytes) and 8 hex digits of its SHA-256, so two ids never share a file
/// (`B.1` and `B_1` stay apart; `B/1` → `B_1-…`, and `B_1-fb95c374` is encoded too) and every
/// name fits the file system's 255 bytes. The result never holds `@`, which joins two ids in one
/// name.
pub(crate) fn file_safe(id: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.');
    let looks_encoded = id.len() > 9
        && id.as_bytes()[id.len() - 9] == b'-'
        && id.as_bytes()[id.len() - 8..]
            .iter()
            .all(|&b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b));
    if !id.is_empty()
        && !id.starts_with('.')
        && id.len() <= MAX_NAME_PART
        && id.chars().all(safe)
        && !looks_encoded
    {
        return id.to_string();
    }
    use sha2::{Digest, Sha256};
    let digest = Sha256::digest(id.as_bytes());
    let cleaned: String = id
        .chars()
        .map(|c| if safe(c) { c } else { '_' })
        .skip_while(|&c| c == '.')
        .take(MAX_NAME_PART)
        .collect();
    let hex: String = digest[..4].iter().map(|b| format!("{b:02x}")).collect();
    format!("{cleaned}-{hex}")
}

/// The longest id used as a file-name part as it is (bytes); `acceptance-<bar>@<length>.png`
/// then stays far below 255 bytes.
const MAX_NAME_PART: usize = 64;

fn params_line(o: &BarOutcome) -> String {
    let p: Vec<String> = o
        .model
        .params
        .iter()
        .map(|p| {
            let (value, u) = crate::narrative::fit_report::value_and_uncertainty(p.value, p.u);
            format!("{} = {value} ± {u}", p.name)
        })
        .collect();
    format!("{}\nRMS {:.4} µm over {} samples (± are standard uncertainties, autocorrelation-consistent)", p.join("   "), o.model.rms_um, o.model.n_samples)
}

/// The spec of a bar's figure (`figures/bar-<id>.png`): measured vs model, temperatures,
/// residual, and the model's warnings (parameters the bar's data cannot determine); `bin_s`:
/// the length of the compressed bins the bar was read in (0: every reading).
///
/// Why the residual panel names the bins: it draws the series fitted, a compressed bin's two
/// nodes, which scatter less than the readings (0.0050 against 0.0203 µm at 60-s bins of 1-s
/// readings), where the subtitle gives the readings' RMS.
pub fn bar_fit_figure(o: &BarOutcome, bin_s: f64) -> report::BarFitFigure {
    let s = &o.series;
    let idx = &s.fit_index;
    let time_s: Vec<f64> = idx.iter().map(|&i| s.t_s[i]).collect();
    let measured_um: Vec<f64> = idx
        .iter()
        .map(|&i| s.y_um[i] - s.zero_segment[i].map_or(0.0, |z| o.model.zeros_um[z as usize]))
        .collect();
    let model_um: Vec<f64> = idx.iter().map(|&i| o.model.thermal_um[i]).collect();
    let mut temperatures_c = vec![NamedSeries {
        name: "air seen by the bar".into(),
        x: time_s.clone(),
        y: idx.iter().map(|&i| s.air_c[i]).collect(),
    }];
    if let Some(plate) = &s.plate_sensor_id {
        if let Some(c) = s.celsius.get(plate) {
            temperatures_c.push(NamedSeries {
                name: format!("plate ({plate})"),
                x: time_s.clone(),
                y: idx.iter().map(|&i| c[i]).collect(),
            });
        }
    }
    let mut mount_boundaries_s: Vec<f64> =
        s.mounts.iter().flat_map(|m| [m.from_s, m.to_s]).collect();
    mount_boundaries_s.sort_by(f64::total_cmp);
    mount_boundaries_s.dedup();
    report::BarFitFigure {
        title: format!(
            "Bar {} — measured thermal error vs model [{}]",
            o.model.bar,
            o.model.effect_names().join(" + ")
        ),
        subtitle: params_line(o),
        time_s,
        measured_um,
        model_um,
        temperatures_c,
        mount_boundaries_s,
        notes: bar_notes(o),
        residual_points: if bin_s > 0.0 {
            format!("at the {bin_s:.0}-s bins' two nodes, which scatter less than the readings")
        } else {
            String::new()
        },
    }
}

/// The bar figure's warnings: parameters the bar's data cannot determine, and why.
fn bar_notes(o: &BarOutcome) -> Vec<String> {
    o.model
        .not_identifiable
        .iter()
        .map(|n| format!("Not identifiable: {}.", n.params.join(", ")))
        .chain(o.model.not_identifiable.iter().flat_map(|n| {
            // The reason is long: wrap it at its clauses.
            crate::narrative::model::not_identifiable_reason(&n.reason)
                .split("; ")
                .map(|part| format!("{part};"))
                .collect::<Vec<_>>()
        }))
        .map(|l| {
            let l = l.trim_end_matches(';');
            let mut c = l.chars();
            c.next()
                .map(|f| f.to_uppercase().chain(c).collect())
                .unwrap_or_default()
        })
        .collect()
}

fn fleet(r: &RunResults) -> report::FleetFigure {
    let bar_names: Vec<String> = r.bars.iter().map(|o| o.model.bar.clone()).collect();
    // Every parameter some bar has, in the order of the first bar that has it (a bar on one
    // length lacks beta and tau_S).
    let mut names: Vec<String> = Vec::new();
    for p in r.bars.iter().flat_map(|o| &o.model.params) {
        if !names.contains(&p.name) {
            names.push(p.name.clone());
        }
    }
    let parameters = names
        .iter()
        .map(|name| {
            // A parameter the bar's data cannot determine is left out of the panel and its mean.
            let est: Vec<Option<&crate::identify::Estimate>> = r
                .bars
                .iter()
                .map(|o| o.model.param(name).filter(|_| !o.model.undetermined(name)))
                .collect();
            report::ParameterPanel {
                name: name.clone(),
                unit: unit_of(name).into(),
                values: est
                    .iter()
                    .map(|e| e.map_or(f64::NAN, |e| e.value))
                    .collect(),
                u95: est
                    .iter()
                    .map(|e| e.map_or(f64::NAN, |e| (e.ci95[1] - e.ci95[0]) / 2.0))
                    .collect(),
                fleet_mean: None,
            }
        })
        .collect();
    let reference = r
        .reference
        .as_ref()
        .and_then(|rr| bar_names.iter().position(|b| *b == rr.choice.bar));
    let mismatch_um = match &r.reference {
        Some(rr) => bar_names
            .iter()
            .map(|b| match rr.mismatches.iter().find(|m| m.bar == *b) {
                Some(m) => m.max_abs_um,
                None if *b == rr.choice.bar => 0.0,
                None => f64::NAN,
            })
            .collect(),
        None => Vec::new(),
    };
    let subtitle = match &r.reference {
        Some(rr) => format!(
            "Reference: {} (nearest the fleet mean of {} scaled by the fleet spread).\nMismatch = max |predicted difference| over this campaign's temperature history at {:.1} mm.",
            rr.choice.bar,
            if rr.choice.fleet_mean.iter().all(|v| v.is_finite()) {
                "alpha, beta, tau_R, tau_S"
            } else {
                "alpha, tau_R: beta, tau_S not identifiable on one length"
            },
            rr.distance_mm
        ),
        None => "No reference chosen (no bar with the base parameters).".into(),
    };
    report::FleetFigure {
        title: format!(
            "Fleet of campaign {} — thermal parameters and reference matching",
            r.campaign.id
        ),
        subtitle,
        bar_names,
        parameters,
        reference,
        mismatch_um,
        mismatch_limit_um: r.reference.as_ref().map_or(1.0, |rr| rr.limit_um),
    }
}

fn unit_of(name: &str) -> &'static str {
    if name.ends_with("_ppm_per_k") {
        "ppm/K"
    } else if name.ends_with("_um_per_day") {
        "µm/day"
    } else if name.ends_with("_um") {
        "µm"
    } else if name.ends_with("_s") {
        "s"
    } else {
        ""
    }
}

fn heat_map(study: &crate::matching::MatchStudy) -> report::HeatMapFigure {
    let row = |b: &str| study.bars.iter().position(|x| x == b);
    report::HeatMapFigure {
        title: "Reference-bar matching study — measured mismatch".into(),
        subtitle: format!(
            "Cell = max |measured drift(other) − measured drift(candidate)| over the times both were measured.\nNearest-the-mean pick {} (worst {:.3} µm); best candidate {} (worst {:.3} µm); excess {:.3} µm.",
            study.nearest_mean,
            row(&study.nearest_mean).map_or(f64::NAN, |i| study.worst_um[i]),
            study.best,
            row(&study.best).map_or(f64::NAN, |i| study.worst_um[i]),
            study.excess_um
        ),
        row_labels: study.bars.clone(),
        col_labels: study.bars.clone(),
        row_axis_label: "candidate reference".into(),
        col_axis_label: "other bar".into(),
        values: study.matrix_um.clone(),
        unit: "µm".into(),
        highlights: vec![
            report::MatrixHighlight { label: format!("nearest the fleet mean: {}", study.nearest_mean), row: row(&study.nearest_mean), col: None },
            report::MatrixHighlight { label: format!("best on measured drifts: {}", study.best), row: row(&study.best), col: None },
        ],
    }
}

fn residual_figure(
    d: &BarDiagnosis,
    o: &BarOutcome,
    sensors: &[SensorProfile],
) -> report::ResidualDiagnosticsFigure {
    let dt = median_step(&o.series.t_s);
    let top: Vec<&crate::diagnose::ChannelScore> = d.channels.iter().take(12).collect();
    report::ResidualDiagnosticsFigure {
        title: format!("Bar {} — where the model [{}] fails", d.bar, d.effects.iter().map(crate::model::Effect::name).collect::<Vec<_>>().join(" + ")),
        subtitle: format!(
            "RMS {:.4} µm, peak-to-valley {:.3} µm, fit {:.1} %, Ljung-Box p = {:.2e} ({} lags), residual correlation time {:.0} s",
            d.stats.rms_um, d.stats.peak_to_valley_um, d.stats.fit_percent, d.whiteness_p, d.stats.ljung_box_lags, d.stats.correlation_time_samples * dt
        ) + &sensor_lines(top.iter().take(3).map(|c| c.channel.as_str()), sensors),
        acf: d.stats.acf.clone(),
        lag_step_s: dt,
        n_samples: o.model.n_samples,
        cpgram_freq_hz: d.stats.periodogram_freq_per_sample.iter().map(|f| f / dt).collect(),
        cpgram: d.stats.cumulative_periodogram.clone(),
        channels: top.iter().map(|c| c.channel.clone()).collect(),
        explained_fraction: top.iter().map(|c| c.explained_fraction).collect(),
    }
}

fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return 1.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Subtitle lines naming what the sensors of `channels` plausibly are (each sensor once).
fn sensor_lines<S: AsRef<str>>(
    channels: impl IntoIterator<Item = S>,
    sensors: &[SensorProfile],
) -> String {
    let mut lines: Vec<String> = Vec::new();
    for channel in channels {
        for line in channel_sensor_summaries(channel.as_ref(), sensors) {
            if !lines.contains(&line) {
                lines.push(line);
            }
        }
    }
    lines.iter().map(|l| format!("\n{l}")).collect()
}

/// The channel a generic term added at a ledger step reads (`lag:t4-t1` → `t4-t1`).
fn term_channel(added: &crate::diagnose::Added) -> Option<String> {
    match added {
        crate::diagnose::Added::Effect(crate::model::Effect::Channel { channel, .. }) => {
            Some(channel.clone())
        }
        _ => None,
    }
}

fn ledger(steps: &[LedgerStep], sensors: &[SensorProfile], beam: usize) -> report::LedgerFigure {
    let bars: Vec<String> = steps[0].rms_um.iter().map(|(b, _)| b.clone()).collect();
    report::LedgerFigure {
        title: "Forward selection — RMS residual as effects are added".into(),
        subtitle: format!("Each step adds a proposed candidate (significant and material, diagnosis.json → criteria); the best of {beam} paths by fleet ΔBIC.{}", sensor_lines(steps.iter().filter_map(|s| term_channel(&s.added)), sensors)),
        steps: steps.iter().map(|s| s.added.label()).collect(),
        bars: bars
            .iter()
            .map(|b| report::NamedValues {
                name: b.clone(),
                values: steps.iter().map(|s| s.rms_um.iter().find(|(x, _)| x == b).map_or(f64::NAN, |(_, v)| *v)).collect(),
            })
            .collect(),
        fleet_rms_um: steps.iter().map(|s| s.fleet_rms_um).collect(),
        noise_um: None,
        log_y: true,
    }
}

/// One bar's own forward selection: its RMS after each of its own steps.
fn bar_ledger(
    bl: &crate::diagnose::BarLedger,
    sensors: &[SensorProfile],
    beam: usize,
) -> report::LedgerFigure {
    report::LedgerFigure {
        title: format!("Forward selection for bar {} alone", bl.bar),
        subtitle: format!("Each step adds a candidate proposed on this bar (significant and material); the best of {beam} paths by ΔBIC.{}", sensor_lines(bl.steps.iter().filter_map(|s| term_channel(&s.added)), sensors)),
        steps: bl.steps.iter().map(|s| s.added.label()).collect(),
        bars: vec![report::NamedValues {
            name: bl.bar.clone(),
            values: bl.steps.iter().map(|s| s.fleet_rms_um).collect(),
        }],
        fleet_rms_um: Vec::new(),
        noise_um: None,
        log_y: true,
    }
}

fn before_after(ba: &crate::pipeline::BeforeAfter) -> report::BeforeAfterFigure {
    report::BeforeAfterFigure {
        title: "RMS residual before and after adding effects".into(),
        subtitle: format!(
            "before: [{}]   after: [{}]",
            ba.before_effects.join(" + "),
            ba.after_effects.join(" + ")
        ),
        bar_names: ba.bars.iter().map(|b| b.bar.clone()).collect(),
        before_um: ba.bars.iter().map(|b| b.rms_before_um).collect(),
        after_um: ba.bars.iter().map(|b| b.rms_after_um).collect(),
        fleet_before_um: Some(ba.fleet_rms_before_um),
        fleet_after_um: Some(ba.fleet_rms_after_um),
        before_label: "base model".into(),
        after_label: "with added effects".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::file_safe;

    #[test]
    fn id_file_names_are_distinct_and_short() {
        assert_eq!(file_safe("B01"), "B01");
        assert_eq!(file_safe("B.1"), "B.1");
        let slash = file_safe("B/1");
        assert!(slash.starts_with("B_1-") && slash.len() == 12, "{slash}");
        // An id that looks like an encoded one is encoded too: no collision.
        assert_ne!(file_safe(&slash), slash);
        assert!(file_safe(&slash).starts_with(&format!("{slash}-")));
        let long = file_safe(&"B".repeat(252));
        assert_eq!(long.len(), 64 + 9);
        assert_ne!(long, file_safe(&"B".repeat(253)));
        assert_eq!(file_safe(".x"), format!("x-{}", &file_safe(".x")[2..]));
        assert!(!file_safe("ü/@").contains('@'));
    }
}
