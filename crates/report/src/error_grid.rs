//! The six errors of a machine axis (ISO 230-1: three translations, three rotations) against
//! the commanded position, one panel each in a grid, every curve with its U (k = 2) band.
//!
//! The machine kinds (the interferometer axis, the six-bar device) share this figure: each fills
//! an [`ErrorGridFigure`] from its results. Translations and rotations have different units, so
//! each panel has its own y axis; the x axis (commanded position) is shared.

use std::path::Path;

use super::axis::Axis;
use super::canvas::{header, render_with, split_grid, Area, DrawError};
use super::data::finite_minmax;
use super::legend::Mark;
use super::panel::{y_area_width, Panel};
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{same_len, validated, ReportError};

/// One curve of a panel: values at positions, each with its expanded uncertainty.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BandedSeries {
    /// Legend label (e.g. "mean ↑").
    pub name: String,
    /// Positions (the shared x axis' unit).
    pub x: Vec<f64>,
    /// Values (the panel's unit); NaN leaves a gap.
    pub y: Vec<f64>,
    /// U (k = 2) of each value, same unit; NaN or 0 draws no band there.
    pub u_k2: Vec<f64>,
}

/// One error's panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ErrorPanel {
    /// The panel's title, e.g. "EXX (positioning)".
    pub title: String,
    /// Y-axis title with its unit, e.g. "EXX (µm)".
    pub y_label: String,
    /// The curves, each drawn as a line with points inside its band.
    pub curves: Vec<BandedSeries>,
}

/// Panels in a grid of `columns` columns, filled row by row, sharing the x axis.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ErrorGridFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// The shared x axis' title with its unit.
    pub x_label: String,
    /// Number of columns (at least 1).
    pub columns: usize,
    /// The panels.
    pub panels: Vec<ErrorPanel>,
}

impl ErrorGridFigure {
    fn check(&self) -> Result<(), SpecError> {
        if self.columns == 0 {
            return Err(SpecError::NoColumns);
        }
        self.panels.iter().try_for_each(|p| {
            p.curves.iter().try_for_each(|c| {
                let what = format!("{} '{}'", p.title, c.name);
                same_len(&format!("{what} x/y"), c.x.len(), c.y.len())?;
                same_len(&format!("{what} x/u_k2"), c.x.len(), c.u_k2.len())
            })
        })
    }

    fn x_axis(&self) -> Axis {
        let xs = self
            .panels
            .iter()
            .flat_map(|p| p.curves.iter().flat_map(|c| c.x.iter().copied()));
        let (lo, hi) = finite_minmax(xs).unwrap_or((0.0, 1.0));
        Axis::fixed(lo, hi, 8, &self.x_label)
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_error_grid(spec: &ErrorGridFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &ErrorGridFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let rows = spec.panels.len().div_ceil(spec.columns).max(1);
    let areas = split_grid(&body, &vec![1.0; spec.columns], &vec![1.0; rows]);
    let x = spec.x_axis();
    let ys: Vec<Axis> = spec.panels.iter().map(y_axis).collect();
    let left = ys.iter().map(|y| y_area_width(&body, y)).max().unwrap_or(0);
    for (i, (panel, y)) in spec.panels.iter().zip(ys).enumerate() {
        let last_row = i / spec.columns == rows - 1;
        let xi = if last_row {
            x.clone()
        } else {
            x.without_desc()
        };
        let p = Panel::aligned(&areas[i], &panel.title, xi, y, (left, 0))?;
        draw_panel(panel, p)?;
    }
    Ok(())
}

/// The y axis covers every band's edges, so no band is clipped.
fn y_axis(panel: &ErrorPanel) -> Axis {
    let values = panel.curves.iter().flat_map(|c| {
        c.y.iter().zip(&c.u_k2).flat_map(|(y, u)| {
            let u = if u.is_finite() { *u } else { 0.0 };
            [*y - u, *y + u]
        })
    });
    Axis::linear(values, false, 5, &panel.y_label)
}

fn draw_panel(panel: &ErrorPanel, mut p: Panel<'_, '_>) -> Result<(), DrawError> {
    for (i, c) in panel.curves.iter().enumerate() {
        let colour = style::palette(i);
        let u = |sign: f64| -> Vec<f64> {
            c.y.iter()
                .zip(&c.u_k2)
                .map(|(y, u)| {
                    if u.is_finite() {
                        y + sign * u
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        };
        p.band(&c.x, &u(-1.0), &u(1.0), style::fill(colour, 0.18))?;
    }
    for (i, c) in panel.curves.iter().enumerate() {
        let colour = style::palette(i);
        p.line(&c.x, &c.y, style::stroke(colour, 2))?;
        p.points(&c.x, &c.y, colour, 3)?;
        p.legend_entry(&c.name, Mark::Line(colour, 2));
    }
    if panel.curves.iter().any(|c| c.u_k2.iter().any(|u| *u > 0.0)) {
        p.legend_entry("band: U (k = 2)", Mark::Filled(style::GREY));
    }
    if panel.curves.iter().all(|c| c.x.is_empty()) {
        p.no_data(&panel.title)?;
    }
    p.finish()
}
