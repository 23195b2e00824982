//! Legends drawn by `report` itself (not plotters' series labels), so the same entries can go
//! inside a panel — in the corner with the least data under it — or in a strip outside.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::canvas::{text_size, Area, DrawError};
use super::style::{self, LEGEND_PX, TEXT};

/// The symbol drawn before a legend label.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Mark {
    /// A line sample of the given width.
    Line(RGBColor, u32),
    /// A dashed line sample of the given width.
    Dashed(RGBColor, u32),
    /// A filled square (bars, cells).
    Filled(RGBColor),
    /// A hollow square (highlight outlines).
    Outline(RGBColor),
    /// A filled circle (points).
    Dot(RGBColor),
}

/// One legend line: a symbol and its label.
#[derive(Debug, Clone)]
pub(crate) struct LegendEntry {
    pub(crate) label: String,
    pub(crate) mark: Mark,
}

const SAMPLE_W: i32 = 34;
const GAP: i32 = 8;
const PAD: i32 = 9;

fn row_height() -> i32 {
    LEGEND_PX as i32 + 8
}

fn entry_width(area: &Area<'_>, e: &LegendEntry) -> i32 {
    SAMPLE_W + GAP + text_size(area, &e.label, &style::plain(LEGEND_PX)).0 as i32
}

/// Pixel size of the boxed, one-entry-per-line legend.
pub(crate) fn box_size(area: &Area<'_>, entries: &[LegendEntry]) -> (i32, i32) {
    let w = entries
        .iter()
        .map(|e| entry_width(area, e))
        .max()
        .unwrap_or(0);
    (
        w + 2 * PAD,
        entries.len() as i32 * row_height() + 2 * PAD - 6,
    )
}

/// Draws the boxed legend with its top-left corner at `origin` (pixels in `area`).
pub(crate) fn draw_box(
    area: &Area<'_>,
    entries: &[LegendEntry],
    origin: (i32, i32),
) -> Result<(), DrawError> {
    if entries.is_empty() {
        return Ok(());
    }
    let (w, h) = box_size(area, entries);
    let corners = [origin, (origin.0 + w, origin.1 + h)];
    area.draw(&Rectangle::new(corners, style::WHITE.mix(0.88).filled()))?;
    area.draw(&Rectangle::new(corners, style::stroke(style::GRID, 1)))?;
    for (i, e) in entries.iter().enumerate() {
        draw_entry(
            area,
            e,
            (origin.0 + PAD, origin.1 + PAD + i as i32 * row_height()),
        )?;
    }
    Ok(())
}

const ROW_SPACING: i32 = 26;

/// Pixel width of the entries drawn side by side.
pub(crate) fn row_width(area: &Area<'_>, entries: &[LegendEntry]) -> i32 {
    let widths: i32 = entries.iter().map(|e| entry_width(area, e)).sum();
    widths + ROW_SPACING * (entries.len() as i32 - 1).max(0)
}

/// Draws the entries side by side on one line starting at `origin` (pixels in `area`).
pub(crate) fn draw_row(
    area: &Area<'_>,
    entries: &[LegendEntry],
    origin: (i32, i32),
) -> Result<(), DrawError> {
    let mut x = origin.0;
    for e in entries {
        draw_entry(area, e, (x, origin.1))?;
        x += entry_width(area, e) + ROW_SPACING;
    }
    Ok(())
}

/// Draws `entries` centred in a strip at the top of `area` and returns the area below it
/// (`area` itself when there are no entries).
pub(crate) fn strip<'b>(area: &Area<'b>, entries: &[LegendEntry]) -> Result<Area<'b>, DrawError> {
    if entries.is_empty() {
        return Ok(area.clone());
    }
    let (top, rest) = area.split_vertically(row_height() + 10);
    let x0 = (top.dim_in_pixel().0 as i32 - row_width(&top, entries)) / 2;
    draw_row(&top, entries, (x0, 4))?;
    Ok(rest)
}

/// One symbol and label with the line's top-left corner at `at`.
fn draw_entry(area: &Area<'_>, e: &LegendEntry, at: (i32, i32)) -> Result<(), DrawError> {
    let mid = at.1 + LEGEND_PX as i32 / 2 + 1;
    let (x0, x1) = (at.0, at.0 + SAMPLE_W);
    let square = [(x0 + 9, mid - 7), (x1 - 9, mid + 7)];
    match e.mark {
        Mark::Line(c, w) => area.draw(&PathElement::new(
            vec![(x0, mid), (x1, mid)],
            style::stroke(c, w.max(2)),
        ))?,
        Mark::Dashed(c, w) => {
            for k in 0..3 {
                let s = x0 + k * 13;
                area.draw(&PathElement::new(
                    vec![(s, mid), (s + 8, mid)],
                    style::stroke(c, w.max(2)),
                ))?;
            }
        }
        Mark::Filled(c) => area.draw(&Rectangle::new(square, c.filled()))?,
        Mark::Outline(c) => area.draw(&Rectangle::new(square, style::stroke(c, 3)))?,
        Mark::Dot(c) => area.draw(&Circle::new(((x0 + x1) / 2, mid), 6, c.filled()))?,
    }
    let st = style::text(LEGEND_PX, TEXT, (HPos::Left, VPos::Center));
    area.draw(&Text::new(e.label.clone(), (x1 + GAP, mid), st))?;
    Ok(())
}

/// A coarse map of which parts of a plotting area hold data, to place a legend where it hides
/// the least.
#[derive(Debug, Clone)]
pub(crate) struct Occupancy {
    cells: Vec<bool>,
}

const OCC_W: usize = 40;
const OCC_H: usize = 24;

impl Occupancy {
    pub(crate) fn new() -> Self {
        Self {
            cells: vec![false; OCC_W * OCC_H],
        }
    }

    /// Marks the point at fractions (`fx` right, `fy` up) of the area.
    pub(crate) fn mark(&mut self, fx: f64, fy: f64) {
        if !(0.0..=1.0).contains(&fx) || !(0.0..=1.0).contains(&fy) {
            return;
        }
        let cx = ((fx * OCC_W as f64) as usize).min(OCC_W - 1);
        let cy = (((1.0 - fy) * OCC_H as f64) as usize).min(OCC_H - 1);
        self.cells[cy * OCC_W + cx] = true;
    }

    /// Marks the straight segment between two fractional points.
    pub(crate) fn mark_segment(&mut self, a: (f64, f64), b: (f64, f64)) {
        let steps = (((b.0 - a.0).abs() * OCC_W as f64)
            .max((b.1 - a.1).abs() * OCC_H as f64)
            .ceil() as usize)
            .min(4 * (OCC_W + OCC_H));
        for k in 0..=steps {
            let t = if steps == 0 {
                0.0
            } else {
                k as f64 / steps as f64
            };
            self.mark(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        }
    }

    /// Marks the rectangle between two fractional corners.
    pub(crate) fn mark_rect(&mut self, a: (f64, f64), b: (f64, f64)) {
        let (x0, x1) = (a.0.min(b.0).max(0.0), a.0.max(b.0).min(1.0));
        let (y0, y1) = (a.1.min(b.1).max(0.0), a.1.max(b.1).min(1.0));
        let nx = ((x1 - x0) * OCC_W as f64).ceil() as usize + 1;
        let ny = ((y1 - y0) * OCC_H as f64).ceil() as usize + 1;
        for i in 0..=nx {
            for j in 0..=ny {
                self.mark(
                    x0 + (x1 - x0) * i as f64 / nx as f64,
                    y0 + (y1 - y0) * j as f64 / ny as f64,
                );
            }
        }
    }

    /// How many occupied cells the pixel box `[x0, x1) × [y0, y1)` of a `w` × `h` area touches.
    fn count(&self, (x0, y0, x1, y1): (i32, i32, i32, i32), (w, h): (i32, i32)) -> usize {
        let cell = |v: i32, len: i32, n: usize, up: bool| {
            let f = f64::from(v.clamp(0, len)) * n as f64 / f64::from(len.max(1));
            (if up { f.ceil() } else { f.floor() } as usize).min(n)
        };
        let (a, b) = (cell(x0, w, OCC_W, false), cell(x1, w, OCC_W, true));
        let (c, d) = (cell(y0, h, OCC_H, false), cell(y1, h, OCC_H, true));
        (c..d)
            .flat_map(|j| (a..b).map(move |i| (i, j)))
            .filter(|(i, j)| self.cells[j * OCC_W + i])
            .count()
    }

    /// Top-left pixel of the corner (upper right, upper left, lower right, lower left, in that
    /// order of preference) where a `size` box over a `dim` area covers the fewest data cells,
    /// and how many it covers.
    pub(crate) fn best_corner(&self, size: (i32, i32), dim: (i32, i32)) -> ((i32, i32), usize) {
        let m = 10;
        let corners = [
            (dim.0 - size.0 - m, m),
            (m, m),
            (dim.0 - size.0 - m, dim.1 - size.1 - m),
            (m, dim.1 - size.1 - m),
        ];
        let score = |c: &(i32, i32)| self.count((c.0, c.1, c.0 + size.0, c.1 + size.1), dim);
        let best = corners
            .iter()
            .map(|c| (*c, score(c)))
            .min_by_key(|(_, s)| *s);
        best.unwrap_or((corners[0], 0))
    }
}
