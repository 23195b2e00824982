//! Figure 7: N stacked panels of named line series sharing one x axis (acceptance sheets:
//! compensated error over time with tolerance lines, and the like).

use std::path::Path;

use super::axis::{Axis, TimeUnit};
use super::canvas::{header, render_with, split_grid, Area, DrawError};
use super::data::finite_minmax;
use super::legend::Mark;
use super::panel::{y_area_width, Panel};
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{check_series, validated, NamedSeries, RefLine, ReportError};

/// What the shared x values are.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum XAxis {
    /// Seconds since campaign start (shown in min, h or d).
    #[default]
    TimeSeconds,
    /// Plain values, with the axis title (including the unit).
    Values {
        /// Axis title, with the unit.
        label: String,
    },
}

/// One panel: its series, y-axis title and horizontal reference lines.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SeriesPanel {
    /// The panel's title.
    pub title: String,
    /// Y-axis title including the unit, e.g. "compensated error (µm)".
    pub y_label: String,
    /// The lines drawn.
    pub series: Vec<NamedSeries>,
    /// Horizontal lines (e.g. "tolerance" at +1 and −1); lines sharing a label share a colour
    /// and a legend line.
    pub ref_lines: Vec<RefLine>,
}

/// Stacked panels sharing the x axis.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SeriesPanelsFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// What the shared x axis shows.
    pub x_axis: XAxis,
    /// The panels, top to bottom.
    pub panels: Vec<SeriesPanel>,
}

impl SeriesPanelsFigure {
    fn check(&self) -> Result<(), SpecError> {
        self.panels
            .iter()
            .try_for_each(|p| check_series(&p.title, &p.series))
    }

    /// The shared axis and the factor turning x values into its units.
    fn x_axis(&self) -> (Axis, f64) {
        let xs = self
            .panels
            .iter()
            .flat_map(|p| p.series.iter().flat_map(|s| s.x.iter().copied()));
        match &self.x_axis {
            XAxis::TimeSeconds => {
                let (a, unit): (Axis, TimeUnit) = Axis::time(xs, 12);
                (a, unit.seconds())
            }
            XAxis::Values { label } => {
                let (lo, hi) = finite_minmax(xs).unwrap_or((0.0, 1.0));
                (Axis::fixed(lo, hi, 10, label), 1.0)
            }
        }
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_series_panels(spec: &SeriesPanelsFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &SeriesPanelsFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let (x, per_unit) = spec.x_axis();
    let weights = vec![1.0; spec.panels.len().max(1)];
    let areas = split_grid(&body, &[1.0], &weights);
    let ys: Vec<Axis> = spec.panels.iter().map(y_axis).collect();
    let left = ys.iter().map(|y| y_area_width(&body, y)).max().unwrap_or(0);
    let last = spec.panels.len().saturating_sub(1);
    for (i, ((panel, area), y)) in spec.panels.iter().zip(&areas).zip(ys).enumerate() {
        let xi = if i == last {
            x.clone()
        } else {
            x.without_desc()
        };
        let p = Panel::aligned(area, &panel.title, xi, y, (left, 0))?;
        draw_panel(panel, p, per_unit)?;
    }
    Ok(())
}

fn y_axis(spec: &SeriesPanel) -> Axis {
    let values = spec
        .series
        .iter()
        .flat_map(|s| s.y.iter())
        .chain(spec.ref_lines.iter().map(|r| &r.value));
    Axis::linear(values.copied(), false, 5, &spec.y_label)
}

fn draw_panel(spec: &SeriesPanel, mut p: Panel<'_, '_>, per_unit: f64) -> Result<(), DrawError> {
    let mut labels: Vec<&str> = Vec::new();
    for r in &spec.ref_lines {
        let k = labels
            .iter()
            .position(|l| *l == r.label)
            .unwrap_or_else(|| {
                labels.push(&r.label);
                labels.len() - 1
            });
        p.hline(r.value, style::stroke(style::accent(k), 2), true)?;
        p.legend_entry(&r.label, Mark::Dashed(style::accent(k), 2));
    }
    for (i, s) in spec.series.iter().enumerate() {
        let xs: Vec<f64> = s.x.iter().map(|v| v / per_unit).collect();
        p.line(&xs, &s.y, style::stroke(style::palette(i), 2))?;
        p.legend_entry(&s.name, Mark::Line(style::palette(i), 2));
    }
    if spec.series.iter().all(|s| s.x.is_empty()) {
        p.no_data(&spec.title)?;
    }
    p.finish()
}
