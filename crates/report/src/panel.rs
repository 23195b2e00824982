//! One chart panel: a plotters chart on an [`Axis`] pair plus the drawing primitives every
//! figure shares (lines with decimation, reference lines, bars, error bars, markers, text) and
//! a legend placed where it hides the least data.

use std::ops::Range;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::axis::Axis;
use super::canvas::{text_size, Area, DrawError};
use super::data::{decimate, Polyline};
use super::legend::{self, LegendEntry, Mark, Occupancy};
use super::style::{self, CAPTION_PX, DESC_PX, TEXT, TICK_PX};

/// An f64 coordinate whose grid lines sit exactly at an [`Axis`]'s ticks (plotters'
/// `WithKeyPoints` does the same but cannot be used with `configure_mesh` on f64).
struct Ticked {
    inner: RangedCoordf64,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl Ranged for Ticked {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.inner.range()
    }
}

type Coord = Cartesian2d<Ticked, Ticked>;

/// A chart on one area with its two axes, legend entries and data-occupancy map.
pub(crate) struct Panel<'a, 'b> {
    chart: ChartContext<'a, BitMapBackend<'b>, Coord>,
    area: &'a Area<'b>,
    pub(crate) x: Axis,
    pub(crate) y: Axis,
    /// Right end of the caption text (pixels in `area`), where a legend row may start.
    caption_end: i32,
    legend: Vec<LegendEntry>,
    occupied: Occupancy,
}

const MARGIN: u32 = 10;
/// Height above the plot holding the caption (and a legend row when the plot is crowded).
const CAPTION_BAND: u32 = CAPTION_PX as u32 + 20;

fn tick_style() -> TextStyle<'static> {
    style::text(TICK_PX, TEXT, (HPos::Center, VPos::Center))
}

fn coord(a: &Axis) -> Ticked {
    Ticked {
        inner: (a.lo..a.hi).into(),
        bold: a.ticks.clone(),
        light: a.minor.clone(),
    }
}

/// Whether category labels of `x` would collide if written horizontally.
fn needs_rotation(area: &Area<'_>, x: &Axis) -> bool {
    if !x.is_categorical() || x.ticks.is_empty() {
        return false;
    }
    let slot = f64::from(area.dim_in_pixel().0) * 0.85 / x.ticks.len() as f64;
    let widest = x
        .tick_labels()
        .iter()
        .map(|l| text_size(area, l, &tick_style()).0)
        .max()
        .unwrap_or(0);
    f64::from(widest) + 8.0 > slot
}

/// Pixels the tick labels plus axis description of `a` need beside (y) or below (x) the plot.
fn label_area(area: &Area<'_>, a: &Axis, vertical_extent: bool) -> u32 {
    let sizes: Vec<(u32, u32)> = a
        .tick_labels()
        .iter()
        .map(|l| text_size(area, l, &tick_style()))
        .collect();
    let desc = if a.desc.is_empty() {
        0
    } else {
        DESC_PX as u32 + 14
    };
    let ticks = if vertical_extent {
        sizes.iter().map(|s| s.0).max().unwrap_or(0)
    } else {
        sizes.iter().map(|s| s.1).max().unwrap_or(0)
    };
    ticks + desc + 18
}

/// Pixels left of the plot that `y`'s tick labels and title need; the maximum over a stack of
/// panels goes to [`Panel::aligned`].
pub(crate) fn y_area_width(area: &Area<'_>, y: &Axis) -> u32 {
    label_area(area, y, true)
}

/// Pixels below the plot that `x`'s tick labels (rotated if crowded) and title need on `area`.
pub(crate) fn x_area_height(area: &Area<'_>, x: &Axis) -> u32 {
    label_area(area, x, needs_rotation(area, x))
}

impl<'a, 'b> Panel<'a, 'b> {
    /// Builds the chart on `area` with a caption (left-aligned above the plot, may be empty),
    /// axes, grid and tick labels.
    pub(crate) fn new(
        area: &'a Area<'b>,
        caption: &str,
        x: Axis,
        y: Axis,
    ) -> Result<Self, DrawError> {
        Self::aligned(area, caption, x, y, (0, 0))
    }

    /// Like [`Panel::new`] with at least `min_labels.0` pixels left of and `min_labels.1` below
    /// the plot, so neighbouring panels line up (see [`y_area_width`], [`x_area_height`]).
    pub(crate) fn aligned(
        area: &'a Area<'b>,
        caption: &str,
        x: Axis,
        y: Axis,
        min_labels: (u32, u32),
    ) -> Result<Self, DrawError> {
        let rotate = needs_rotation(area, &x);
        let y_area = label_area(area, &y, true).max(min_labels.0);
        let top = if caption.is_empty() {
            MARGIN
        } else {
            CAPTION_BAND
        };
        let chart = ChartBuilder::on(area)
            .margin(MARGIN)
            .margin_top(top)
            .margin_right(28)
            .x_label_area_size(label_area(area, &x, rotate).max(min_labels.1))
            .y_label_area_size(y_area)
            .build_cartesian_2d(coord(&x), coord(&y))?;
        let left = (MARGIN + y_area) as i32;
        let caption_style = style::text(CAPTION_PX, TEXT, (HPos::Left, VPos::Top));
        area.draw(&Text::new(
            caption.to_string(),
            (left, 8),
            caption_style.clone(),
        ))?;
        let caption_end = left + text_size(area, caption, &caption_style).0 as i32;
        let mut panel = Self {
            chart,
            area,
            x,
            y,
            caption_end,
            legend: Vec::new(),
            occupied: Occupancy::new(),
        };
        panel.draw_mesh(rotate)?;
        if rotate {
            panel.draw_rotated_x_labels()?;
        }
        Ok(panel)
    }

    fn draw_mesh(&mut self, rotate: bool) -> Result<(), DrawError> {
        let (x, y) = (&self.x, &self.y);
        let xf = |v: &f64| if rotate { String::new() } else { x.label(*v) };
        let yf = |v: &f64| y.label(*v);
        let mut mesh = self.chart.configure_mesh();
        mesh.x_desc(x.desc.as_str())
            .y_desc(y.desc.as_str())
            .x_label_formatter(&xf)
            .y_label_formatter(&yf)
            .label_style(tick_style())
            .axis_desc_style(style::text(DESC_PX, TEXT, (HPos::Center, VPos::Center)))
            .bold_line_style(style::stroke(style::GRID, 1))
            .light_line_style(style::stroke(style::GRID_MINOR, 1))
            .axis_style(style::stroke(style::MUTED, 1));
        if x.is_categorical() {
            mesh.disable_x_mesh();
        }
        if y.is_categorical() {
            mesh.disable_y_mesh();
        }
        mesh.draw()?;
        Ok(())
    }

    /// Category labels written bottom-to-top, ending just below the axis.
    fn draw_rotated_x_labels(&mut self) -> Result<(), DrawError> {
        let base = self.area.get_base_pixel();
        let st = tick_style().transform(FontTransform::Rotate270).pos(
            plotters::style::text_anchor::Pos::new(HPos::Right, VPos::Center),
        );
        for t in self.x.ticks.clone() {
            let (px, py) = self.chart.backend_coord(&(t, self.y.lo));
            let pos = (px - base.0, py - base.1 + 10);
            self.area
                .draw(&Text::new(self.x.label(t), pos, st.clone()))?;
        }
        Ok(())
    }

    /// Plot coordinates of a data point, `None` if either value cannot be drawn.
    fn map(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        Some((self.x.map(x)?, self.y.map(y)?))
    }

    /// Fractions of the plot area (right, up) of a point in plot coordinates.
    fn frac(&self, p: (f64, f64)) -> (f64, f64) {
        (
            (p.0 - self.x.lo) / (self.x.hi - self.x.lo),
            (p.1 - self.y.lo) / (self.y.hi - self.y.lo),
        )
    }

    fn mark_polyline(&mut self, line: &Polyline) {
        for w in line.windows(2) {
            let (a, b) = (self.frac(w[0]), self.frac(w[1]));
            self.occupied.mark_segment(a, b);
        }
        if let [only] = line.as_slice() {
            let f = self.frac(*only);
            self.occupied.mark(f.0, f.1);
        }
    }

    /// Adds a legend line (empty labels and repeats are ignored).
    pub(crate) fn legend_entry(&mut self, label: &str, mark: Mark) {
        if !label.is_empty() && !self.legend.iter().any(|e| e.label == label) {
            self.legend.push(LegendEntry {
                label: label.to_string(),
                mark,
            });
        }
    }

    /// A polyline through `(xs[i], ys[i])`, broken at unplottable values and decimated to a few
    /// points per pixel column.
    pub(crate) fn line(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        style: ShapeStyle,
    ) -> Result<(), DrawError> {
        let columns = self.chart.plotting_area().dim_in_pixel().0 as usize;
        let pts: Vec<Option<(f64, f64)>> =
            xs.iter().zip(ys).map(|(x, y)| self.map(*x, *y)).collect();
        for poly in decimate(pts, self.x.lo, self.x.hi, columns) {
            self.mark_polyline(&poly);
            if poly.len() == 1 {
                self.chart
                    .draw_series(std::iter::once(Circle::new(poly[0], 1, style.filled())))?;
            } else if style.stroke_width > 1 {
                // Separate segments: plotters' mitred joins spike far out at sharp zig-zags.
                self.chart
                    .draw_series(poly.windows(2).map(|w| PathElement::new(w.to_vec(), style)))?;
            } else {
                self.chart.draw_series(LineSeries::new(poly, style))?;
            }
        }
        Ok(())
    }

    /// A filled band between `lo[i]` and `hi[i]` at `xs[i]` (an uncertainty band), broken where
    /// any value cannot be drawn.
    pub(crate) fn band(
        &mut self,
        xs: &[f64],
        lo: &[f64],
        hi: &[f64],
        style: ShapeStyle,
    ) -> Result<(), DrawError> {
        let mut run: Vec<((f64, f64), (f64, f64))> = Vec::new();
        let mut runs = Vec::new();
        for ((x, l), h) in xs.iter().zip(lo).zip(hi) {
            match (self.map(*x, *l), self.map(*x, *h)) {
                (Some(a), Some(b)) => run.push((a, b)),
                _ => runs.push(std::mem::take(&mut run)),
            }
        }
        runs.push(run);
        for run in runs.into_iter().filter(|r| r.len() > 1) {
            let outline: Vec<(f64, f64)> = run
                .iter()
                .map(|p| p.0)
                .chain(run.iter().rev().map(|p| p.1))
                .collect();
            for w in run.windows(2) {
                let (a, b) = (self.frac(w[0].0), self.frac(w[1].1));
                self.occupied.mark_rect(a, b);
            }
            self.chart
                .draw_series(std::iter::once(Polygon::new(outline, style)))?;
        }
        Ok(())
    }

    /// A dashed straight line between two data points.
    pub(crate) fn dashed(
        &mut self,
        a: (f64, f64),
        b: (f64, f64),
        style: ShapeStyle,
    ) -> Result<(), DrawError> {
        if let (Some(a), Some(b)) = (self.map(a.0, a.1), self.map(b.0, b.1)) {
            self.chart
                .draw_series(DashedLineSeries::new(vec![a, b], 9, 6, style))?;
        }
        Ok(())
    }

    /// A horizontal line across the panel at data value `y` (dashed or solid); skipped when
    /// outside the axis range (plotters would clamp it onto the edge).
    pub(crate) fn hline(
        &mut self,
        y: f64,
        style: ShapeStyle,
        dashed: bool,
    ) -> Result<(), DrawError> {
        let Some(py) = self
            .y
            .map(y)
            .filter(|p| (self.y.lo..=self.y.hi).contains(p))
        else {
            return Ok(());
        };
        let pts = vec![(self.x.lo, py), (self.x.hi, py)];
        if dashed {
            self.chart
                .draw_series(DashedLineSeries::new(pts, 9, 6, style))?;
        } else {
            self.chart.draw_series(LineSeries::new(pts, style))?;
        }
        Ok(())
    }

    /// A vertical line across the panel at data value `x`; skipped when outside the range.
    pub(crate) fn vline(&mut self, x: f64, style: ShapeStyle) -> Result<(), DrawError> {
        let Some(px) = self
            .x
            .map(x)
            .filter(|p| (self.x.lo..=self.x.hi).contains(p))
        else {
            return Ok(());
        };
        self.chart.draw_series(LineSeries::new(
            vec![(px, self.y.lo), (px, self.y.hi)],
            style,
        ))?;
        Ok(())
    }

    /// A rectangle between two data corners; a corner off a log axis snaps to the axis end.
    pub(crate) fn rect(
        &mut self,
        a: (f64, f64),
        b: (f64, f64),
        style: ShapeStyle,
    ) -> Result<(), DrawError> {
        let snap = |ax: &Axis, v: f64| ax.map(v).or_else(|| v.is_finite().then_some(ax.lo));
        let (Some(x0), Some(y0), Some(x1), Some(y1)) = (
            snap(&self.x, a.0),
            snap(&self.y, a.1),
            snap(&self.x, b.0),
            snap(&self.y, b.1),
        ) else {
            return Ok(());
        };
        let (fa, fb) = (self.frac((x0, y0)), self.frac((x1, y1)));
        if style.filled {
            self.occupied.mark_rect(fa, fb);
        }
        self.chart
            .draw_series(std::iter::once(Rectangle::new([(x0, y0), (x1, y1)], style)))?;
        Ok(())
    }

    /// A filled vertical bar centred on `x`, `half_width` wide each side, from `from` to `to`.
    pub(crate) fn bar(
        &mut self,
        x: f64,
        half_width: f64,
        from: f64,
        to: f64,
        colour: RGBColor,
    ) -> Result<(), DrawError> {
        self.rect(
            (x - half_width, from),
            (x + half_width, to),
            colour.filled(),
        )
    }

    /// A small value label just beyond the end of a bar at (`x`, `y`): above it if `y` ≥ 0,
    /// below it otherwise.
    pub(crate) fn bar_label(&mut self, x: f64, y: f64, s: &str) -> Result<(), DrawError> {
        let v = if y >= 0.0 { VPos::Bottom } else { VPos::Top };
        self.text(
            x,
            y,
            s,
            style::text(style::NOTE_PX, TEXT, (HPos::Center, v)),
        )
    }

    /// A vertical error bar from `lo` to `hi` at `x` with caps `half_width` wide (data units).
    pub(crate) fn error_bar(
        &mut self,
        x: f64,
        lo: f64,
        hi: f64,
        half_width: f64,
        style: ShapeStyle,
    ) -> Result<(), DrawError> {
        let (Some(a), Some(b)) = (self.map(x, lo), self.map(x, hi)) else {
            return Ok(());
        };
        let segs = [
            vec![a, b],
            vec![(a.0 - half_width, a.1), (a.0 + half_width, a.1)],
            vec![(b.0 - half_width, b.1), (b.0 + half_width, b.1)],
        ];
        self.mark_polyline(&segs[0]);
        self.chart
            .draw_series(segs.into_iter().map(|s| PathElement::new(s, style)))?;
        Ok(())
    }

    /// Filled circles of `radius` pixels at the plottable points.
    pub(crate) fn points(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        colour: RGBColor,
        radius: u32,
    ) -> Result<(), DrawError> {
        let pts: Vec<(f64, f64)> = xs
            .iter()
            .zip(ys)
            .filter_map(|(x, y)| self.map(*x, *y))
            .collect();
        for p in &pts {
            let f = self.frac(*p);
            self.occupied.mark(f.0, f.1);
        }
        let r = radius as i32;
        self.chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, r, colour.filled())))?;
        self.chart.draw_series(
            pts.iter()
                .map(|p| Circle::new(*p, r, style::stroke(style::WHITE, 1))),
        )?;
        Ok(())
    }

    /// Text anchored at a data point (skipped if the point cannot be drawn).
    pub(crate) fn text(
        &mut self,
        x: f64,
        y: f64,
        s: &str,
        style: TextStyle<'_>,
    ) -> Result<(), DrawError> {
        if let Some(p) = self.map(x, y) {
            self.chart
                .draw_series(std::iter::once(Text::new(s.to_string(), p, style)))?;
        }
        Ok(())
    }

    /// A small label on a white box just above the data point (`x`, `y`).
    pub(crate) fn tag(&mut self, x: f64, y: f64, s: &str) -> Result<(), DrawError> {
        let Some(p) = self.map(x, y) else {
            return Ok(());
        };
        let plot = self.chart.plotting_area().strip_coord_spec();
        let (abs, base) = (self.chart.backend_coord(&p), plot.get_base_pixel());
        let st = style::text(style::NOTE_PX, TEXT, (HPos::Center, VPos::Bottom));
        let (w, h) = text_size(&plot, s, &st);
        let (cx, bottom) = (abs.0 - base.0, abs.1 - base.1 - 10);
        let (hw, h) = (w as i32 / 2 + 4, h as i32 + 4);
        plot.draw(&Rectangle::new(
            [(cx - hw, bottom - h), (cx + hw, bottom + 2)],
            style::WHITE.mix(0.85).filled(),
        ))?;
        plot.draw(&Text::new(s.to_string(), (cx, bottom), st))?;
        Ok(())
    }

    /// Grey "no data" in the middle of the panel.
    pub(crate) fn no_data(&mut self, what: &str) -> Result<(), DrawError> {
        let st = style::text(CAPTION_PX, style::MUTED, (HPos::Center, VPos::Center));
        let mid = ((self.x.lo + self.x.hi) / 2.0, (self.y.lo + self.y.hi) / 2.0);
        self.chart.draw_series(std::iter::once(Text::new(
            format!("no data: {what}"),
            mid,
            st,
        )))?;
        Ok(())
    }

    /// Pixel size of one data unit along x, for sizing text in cells.
    pub(crate) fn px_per_x(&self) -> f64 {
        f64::from(self.chart.plotting_area().dim_in_pixel().0) / (self.x.hi - self.x.lo)
    }

    /// Pixel size of one data unit along y.
    pub(crate) fn px_per_y(&self) -> f64 {
        f64::from(self.chart.plotting_area().dim_in_pixel().1) / (self.y.hi - self.y.lo)
    }

    /// Draws the legend inside the plot in the corner covering the least data; if every
    /// corner would hide data, in the caption band right of the caption when it fits there.
    pub(crate) fn finish(self) -> Result<(), DrawError> {
        if self.legend.is_empty() {
            return Ok(());
        }
        let plot = self.chart.plotting_area().strip_coord_spec();
        let (w, h) = plot.dim_in_pixel();
        let size = legend::box_size(&plot, &self.legend);
        let (origin, covered) = self.occupied.best_corner(size, (w as i32, h as i32));
        let row_w = legend::row_width(self.area, &self.legend);
        let plot_right = plot.get_base_pixel().0 - self.area.get_base_pixel().0 + w as i32;
        let row_x = plot_right - row_w;
        let band = plot.get_base_pixel().1 - self.area.get_base_pixel().1 >= CAPTION_BAND as i32;
        if covered > 0 && band && row_x > self.caption_end + 30 {
            return legend::draw_row(self.area, &self.legend, (row_x, 10));
        }
        legend::draw_box(&plot, &self.legend, origin)
    }
}
