//! A device's geometry seen from two or more sides at equal scale (a millimetre is as long
//! across as it is up): its fixed parts, its moving parts at a few poses, and a path of points.
//! Each view is a plain list of named polylines (a NaN breaks a line) and named point sets.

use std::path::Path;

use super::axis::Axis;
use super::canvas::{header, render_with, split_grid, Area, DrawError};
use super::data::finite_minmax;
use super::legend::Mark;
use super::panel::Panel;
use super::style::{self, FIGURE_SIZE};
use super::{check_series, validated, NamedSeries, ReportError};

/// One view: a projection onto two of the frame's axes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GeometryView {
    /// The view's title, e.g. "from above (x, y)".
    pub title: String,
    /// Horizontal axis title with unit.
    pub x_label: String,
    /// Vertical axis title with unit.
    pub y_label: String,
    /// Polylines (NaN in x or y breaks a line), drawn in order, one colour each.
    pub lines: Vec<NamedSeries>,
    /// Point sets, drawn after the lines.
    pub points: Vec<NamedSeries>,
}

/// Views side by side, each at equal scale on its two axes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GeometryFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// The views, left to right.
    pub views: Vec<GeometryView>,
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_geometry(spec: &GeometryFigure, path: &Path) -> Result<(), ReportError> {
    let check = spec.views.iter().try_for_each(|v| {
        check_series(&v.title, &v.lines)?;
        check_series(&v.title, &v.points)
    });
    validated(path, check)?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &GeometryFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let areas = split_grid(&body, &vec![1.0; spec.views.len().max(1)], &[1.0]);
    for (view, area) in spec.views.iter().zip(&areas) {
        let (w, h) = area.dim_in_pixel();
        // The plot inside the labels, roughly: what the equal scale is fitted to.
        let aspect =
            f64::from(w.saturating_sub(130).max(1)) / f64::from(h.saturating_sub(140).max(1));
        let (x, y) = equal_scale_axes(view, aspect);
        let mut p = Panel::new(area, &view.title, x, y)?;
        for (i, l) in view.lines.iter().enumerate() {
            let colour = style::palette(i);
            p.line(&l.x, &l.y, style::stroke(colour, 2))?;
            p.legend_entry(&l.name, Mark::Line(colour, 2));
        }
        for (i, s) in view.points.iter().enumerate() {
            let colour = style::accent(i);
            p.points(&s.x, &s.y, colour, 4)?;
            p.legend_entry(&s.name, Mark::Dot(colour));
        }
        p.finish()?;
    }
    Ok(())
}

/// Axes over every value of the view, the shorter span widened about its middle so that one
/// unit takes as many pixels across as up (`aspect` = plot width / height in pixels).
fn equal_scale_axes(view: &GeometryView, aspect: f64) -> (Axis, Axis) {
    let all = view.lines.iter().chain(&view.points);
    let (x0, x1) =
        finite_minmax(all.clone().flat_map(|s| s.x.iter().copied())).unwrap_or((0.0, 1.0));
    let (y0, y1) = finite_minmax(all.flat_map(|s| s.y.iter().copied())).unwrap_or((0.0, 1.0));
    let pad = 0.06 * (x1 - x0).max(y1 - y0).max(1e-9);
    let (mut x0, mut x1, mut y0, mut y1) = (x0 - pad, x1 + pad, y0 - pad, y1 + pad);
    let (sx, sy) = (x1 - x0, y1 - y0);
    if sx / sy < aspect {
        let grow = (sy * aspect - sx) / 2.0;
        (x0, x1) = (x0 - grow, x1 + grow);
    } else {
        let grow = (sx / aspect - sy) / 2.0;
        (y0, y1) = (y0 - grow, y1 + grow);
    }
    (
        Axis::fixed(x0, x1, 8, &view.x_label),
        Axis::fixed(y0, y1, 8, &view.y_label),
    )
}
