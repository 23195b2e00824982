//! The six errors of an axis against the commanded position (ISO 230-1 names), for every kind
//! that measures them: the interferometer axis (seed 002) and the six-bar device (seed 000).
//! Both reduce their results to [`ErrorPoint`]s; one builder makes the figure, so the two kinds'
//! figures read alike: translations left (µm), rotations right (µrad), one curve per direction
//! of approach (the mean over runs), each inside its U (k = 2) band.

use std::collections::BTreeMap;
use std::path::Path;

use dbbcal_machine::axis_study::AxisStudy;
use dbbcal_machine::device_test;

use super::{drawn, FigureFile, FigureKind};
use crate::pipeline::RunResults;
use crate::report::{self, BandedSeries, ErrorGridFigure, ErrorPanel, ReportError};

/// The six errors at one position, as one run measured them.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ErrorPoint {
    /// +1 / −1: approached moving in the axis's + / − direction; 0: not known.
    pub(crate) direction: i8,
    /// Commanded coordinate of the axis, mm.
    pub(crate) position_mm: f64,
    /// δx, δy, δz (µm), εx, εy, εz (µrad).
    pub(crate) errors: [f64; 6],
    /// Their U (k = 2).
    pub(crate) u_k2: [f64; 6],
}

/// Positions closer than this are one station (commanded coordinates repeat to the µm).
const SAME_POSITION_MM: f64 = 1e-3;

/// The grid: panels in row order, so translations fill the left column and rotations the right.
const PANEL_ORDER: [usize; 6] = [0, 3, 1, 4, 2, 5];
const UNITS: [&str; 6] = ["µm", "µm", "µm", "µrad", "µrad", "µrad"];

/// One figure from the points: per direction, the mean over the runs at each position, with the
/// largest U among them (a run's U, not the smaller U of the mean: the figure shows what one
/// run of the test can tell).
pub(crate) fn six_errors_grid(
    title: String,
    subtitle: String,
    x_label: String,
    names: &[String; 6],
    points: &[ErrorPoint],
) -> ErrorGridFigure {
    let mut by_direction: BTreeMap<i8, Vec<ErrorPoint>> = BTreeMap::new();
    for p in points {
        by_direction.entry(p.direction).or_default().push(*p);
    }
    let stations: BTreeMap<i8, Vec<(f64, Vec<ErrorPoint>)>> = by_direction
        .into_iter()
        .map(|(d, mut pts)| {
            pts.sort_by(|a, b| a.position_mm.total_cmp(&b.position_mm));
            let mut groups: Vec<(f64, Vec<ErrorPoint>)> = Vec::new();
            for p in pts {
                match groups.last_mut() {
                    Some((x, g)) if (p.position_mm - *x).abs() < SAME_POSITION_MM => g.push(p),
                    _ => groups.push((p.position_mm, vec![p])),
                }
            }
            (d, groups)
        })
        .collect();
    let panels = PANEL_ORDER
        .iter()
        .map(|&c| ErrorPanel {
            title: names[c].clone(),
            y_label: format!("{} ({})", names[c], UNITS[c]),
            curves: stations
                .iter()
                .map(|(d, groups)| direction_curve(*d, groups, c))
                .collect(),
        })
        .collect();
    ErrorGridFigure {
        title,
        subtitle,
        x_label,
        columns: 2,
        panels,
    }
}

fn direction_curve(direction: i8, groups: &[(f64, Vec<ErrorPoint>)], c: usize) -> BandedSeries {
    let name = match direction {
        1 => "mean ↑ (moving +)",
        -1 => "mean ↓ (moving −)",
        _ => "mean",
    };
    let mean = |g: &[ErrorPoint]| g.iter().map(|p| p.errors[c]).sum::<f64>() / g.len() as f64;
    BandedSeries {
        name: name.into(),
        x: groups.iter().map(|g| g.0).collect(),
        y: groups.iter().map(|g| mean(&g.1)).collect(),
        u_k2: groups
            .iter()
            .map(|g| g.1.iter().map(|p| p.u_k2[c]).fold(f64::NAN, f64::max))
            .collect(),
    }
}

/// The device stage's figure, from its evaluated dwells.
pub(super) fn device_errors_figure(results: &RunResults) -> Option<ErrorGridFigure> {
    let s = results.device.as_ref()?;
    let t = s.outcome.as_ref().ok()?;
    let k = t.axis.map_or(0, |a| a.index());
    let approach: Vec<i8> = t.dwells.iter().map(|d| d.input.approach[k]).collect();
    let points: Vec<ErrorPoint> = t
        .dwells
        .iter()
        .enumerate()
        .filter_map(|(i, d)| {
            Some(ErrorPoint {
                direction: device_test::sweep_direction(&approach, i),
                position_mm: d.input.position_mm[k],
                errors: d.errors?.to_array(),
                u_k2: d.u_k2?.to_array(),
            })
        })
        .collect();
    if points.is_empty() {
        return None;
    }
    let axis = t.axis.map_or('?', |a| a.letter());
    Some(six_errors_grid(
        format!("Device {}: the six errors of axis {axis}", s.device.id),
        format!(
            "{} of {} dwells evaluated; datum station {}; error = measured − commanded in M's axes at the tool point; band: U (k = 2) of one dwell",
            points.len(),
            t.dwells.len(),
            s.dwells.get(t.datum).map_or(0, |d| d.station)
        ),
        format!("commanded {axis} (mm)"),
        &t.names,
        &points,
    ))
}

/// The `axis` kind's figure: its six errors at every target and direction.
pub(crate) fn axis_errors_figure(campaign_id: &str, study: &AxisStudy) -> ErrorGridFigure {
    let points: Vec<ErrorPoint> = study
        .targets
        .iter()
        .map(|t| ErrorPoint {
            direction: t.direction,
            position_mm: t.target_mm,
            errors: t.errors,
            u_k2: t.u_k2,
        })
        .collect();
    let axis = study.axis.letter();
    let lost = if study.lost.is_empty() {
        String::new()
    } else {
        format!("; not determined: {}", study.lost.join(", "))
    };
    six_errors_grid(
        format!("Axis {axis} of {campaign_id}: the six errors (measured − commanded)"),
        format!(
            "rank {} from {} readings; relative to the datum (target {} mm, direction {:+}){lost}; band: U (k = 2)",
            study.rank, study.readings, study.datum.0, study.datum.1
        ),
        format!("commanded {axis} (mm)"),
        &study.names,
        &points,
    )
}

/// Draws the axis kind's figure into `dir` as `axis-errors.png`.
pub(crate) fn render_axis(
    campaign_id: &str,
    study: &AxisStudy,
    dir: &Path,
) -> Result<FigureFile, ReportError> {
    let file = "axis-errors.png".to_string();
    let path = dir.join(&file);
    crate::output::fault::point("write", &path).map_err(|source| ReportError::Write {
        path: path.clone(),
        source,
    })?;
    drawn(|| report::render_error_grid(&axis_errors_figure(campaign_id, study), &path))?;
    Ok(FigureFile {
        file,
        kind: FigureKind::Axis,
        bar: None,
        caption: "The six errors of the axis against the commanded position, with U (k = 2)".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_averages_runs_per_direction_and_keeps_the_largest_u() {
        let p = |direction, position_mm, e: f64, u: f64| ErrorPoint {
            direction,
            position_mm,
            errors: [e; 6],
            u_k2: [u; 6],
        };
        let names = ["a", "b", "c", "d", "e", "f"].map(String::from);
        let points = [
            p(1, 0.0, 1.0, 0.1),
            p(1, 0.0004, 3.0, 0.3),
            p(1, 10.0, 5.0, 0.2),
            p(-1, 10.0, 7.0, 0.4),
        ];
        let fig = six_errors_grid(String::new(), String::new(), String::new(), &names, &points);
        assert_eq!(fig.panels.len(), 6);
        assert_eq!(fig.panels[1].title, "d", "rotations fill the right column");
        let up = &fig.panels[0].curves[1];
        assert_eq!(up.x, [0.0, 10.0]);
        assert_eq!(up.y, [2.0, 5.0]);
        assert_eq!(up.u_k2, [0.3, 0.2]);
        assert_eq!(fig.panels[0].curves[0].y, [7.0]);
    }
}
