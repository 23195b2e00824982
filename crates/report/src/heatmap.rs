//! Figure 3: a labelled matrix (e.g. predicted mismatch of every bar against every candidate
//! reference) with values in the cells, a colour scale and outlined rows/columns.

use std::path::Path;

use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::Color;

use super::axis::{format_fixed, Axis};
use super::canvas::{header, render_with, split_grid, Area, DrawError};
use super::data::finite_minmax;
use super::legend::{self, LegendEntry, Mark};
use super::panel::{x_area_height, Panel};
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{same_len, validated, ReportError};

/// A row and/or column to outline, with its legend label.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MatrixHighlight {
    /// Legend text, e.g. "nearest the fleet mean: B03".
    pub label: String,
    /// Row index to outline.
    pub row: Option<usize>,
    /// Column index to outline.
    pub col: Option<usize>,
}

/// A matrix of values with row and column labels.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HeatMapFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// Row labels, top to bottom (e.g. candidate reference bars).
    pub row_labels: Vec<String>,
    /// Column labels, left to right (e.g. the other bars).
    pub col_labels: Vec<String>,
    /// Axis titles, e.g. "candidate reference" and "other bar".
    pub row_axis_label: String,
    /// The column axis's title.
    pub col_axis_label: String,
    /// `values[row][col]`; NaN cells are grey with a dash.
    pub values: Vec<Vec<f64>>,
    /// Unit of the values, e.g. "µm" (colour-scale title).
    pub unit: String,
    /// Outlined rows/columns, drawn in accent colours with a legend line above the matrix.
    pub highlights: Vec<MatrixHighlight>,
}

impl HeatMapFigure {
    fn check(&self) -> Result<(), SpecError> {
        same_len(
            "values rows/row_labels",
            self.values.len(),
            self.row_labels.len(),
        )?;
        for (i, row) in self.values.iter().enumerate() {
            same_len(
                &format!("values row {i}/col_labels"),
                row.len(),
                self.col_labels.len(),
            )?;
        }
        let bad = self.highlights.iter().find(|h| {
            h.row.is_some_and(|r| r >= self.row_labels.len())
                || h.col.is_some_and(|c| c >= self.col_labels.len())
        });
        bad.map_or(Ok(()), |h| {
            Err(SpecError::HighlightOutside {
                label: h.label.clone(),
            })
        })
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_heat_map(spec: &HeatMapFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &HeatMapFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let entries: Vec<LegendEntry> = spec
        .highlights
        .iter()
        .enumerate()
        .map(|(i, hl)| LegendEntry {
            label: hl.label.clone(),
            mark: Mark::Outline(style::accent(i)),
        })
        .collect();
    let rest = legend::strip(&body, &entries)?;
    let cols = split_grid(&rest, &[0.89, 0.11], &[1.0]);
    let (lo, hi) = finite_minmax(spec.values.iter().flatten().copied()).unwrap_or((0.0, 1.0));
    let scale = Axis::fixed(lo, hi, 6, &spec.unit);
    let bottom = draw_matrix(spec, &cols[0], &scale)?;
    draw_colour_bar(&cols[1], scale, bottom)
}

/// Cell colour of `v` on the colour scale.
fn cell_colour(v: f64, scale: &Axis) -> plotters::style::RGBColor {
    if v.is_finite() {
        style::colour_map((v - scale.lo) / (scale.hi - scale.lo))
    } else {
        style::GRID_MINOR
    }
}

/// Draws the cells and outlines; returns the height of the label area below the matrix.
fn draw_matrix(spec: &HeatMapFigure, area: &Area<'_>, scale: &Axis) -> Result<u32, DrawError> {
    let x = Axis::categories(&spec.col_labels, false, &spec.col_axis_label);
    let y = Axis::categories(&spec.row_labels, true, &spec.row_axis_label);
    let bottom = x_area_height(area, &x);
    let mut p = Panel::new(area, "", x, y)?;
    let decimals = if scale.hi.abs().max(scale.lo.abs()) < 10.0 {
        2
    } else {
        1
    };
    let chars = format_fixed(scale.hi.abs().max(scale.lo.abs()), decimals)
        .chars()
        .count() as f64
        + 1.0;
    let font = (p.px_per_y() * 0.42)
        .min(p.px_per_x() / (0.62 * chars))
        .min(20.0);
    let show_text = font >= 10.0;
    for (i, row) in spec.values.iter().enumerate() {
        let yc = p.y.category(i);
        for (j, v) in row.iter().enumerate() {
            let bg = cell_colour(*v, scale);
            p.rect(
                (j as f64 - 0.5, yc - 0.5),
                (j as f64 + 0.5, yc + 0.5),
                bg.filled(),
            )?;
            if show_text {
                let s = if v.is_finite() {
                    format_fixed(*v, decimals)
                } else {
                    "–".to_string()
                };
                let st = style::text(font, style::contrast_text(bg), (HPos::Center, VPos::Center));
                p.text(j as f64, yc, &s, st)?;
            }
        }
    }
    draw_highlights(spec, &mut p)?;
    if spec.values.is_empty() {
        p.no_data("matrix")?;
    }
    p.finish()?;
    Ok(bottom)
}

/// Outlines of the highlighted rows and columns, inset a little so two can share a row.
fn draw_highlights(spec: &HeatMapFigure, p: &mut Panel<'_, '_>) -> Result<(), DrawError> {
    let (nr, nc) = (spec.row_labels.len() as f64, spec.col_labels.len() as f64);
    for (i, hl) in spec.highlights.iter().enumerate() {
        let inset = 0.03 + 0.05 * (i % 3) as f64;
        let st = style::stroke(style::accent(i), 4);
        if let Some(r) = hl.row {
            let yc = p.y.category(r);
            p.rect(
                (-0.5 + inset, yc - 0.5 + inset),
                (nc - 0.5 - inset, yc + 0.5 - inset),
                st,
            )?;
        }
        if let Some(c) = hl.col {
            let c = c as f64;
            p.rect(
                (c - 0.5 + inset, -0.5 + inset),
                (c + 0.5 - inset, nr - 0.5 - inset),
                st,
            )?;
        }
    }
    Ok(())
}

/// The colour scale, its plot aligned with the matrix (`bottom`: the matrix's x label area).
fn draw_colour_bar(area: &Area<'_>, scale: Axis, bottom: u32) -> Result<(), DrawError> {
    let (lo, hi) = (scale.lo, scale.hi);
    let mut p = Panel::aligned(area, "", Axis::hidden(0.0, 1.0), scale, (0, bottom))?;
    let steps = 128;
    for k in 0..steps {
        let a = lo + (hi - lo) * k as f64 / steps as f64;
        let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
        p.rect(
            (0.0, a),
            (1.0, b),
            style::colour_map((k as f64 + 0.5) / steps as f64).filled(),
        )?;
    }
    p.rect((0.0, lo), (1.0, hi), style::stroke(style::MUTED, 1))?;
    Ok(())
}
