//! Figure 1: one bar's thermal fit — measured error vs model, temperatures, residual.

use std::path::Path;

use super::axis::{format_significant, Axis, TimeUnit};
use super::canvas::{header, notes, render_with, split_grid, Area, DrawError};
use super::data::rms;
use super::legend::Mark;
use super::panel::{y_area_width, Panel};
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{check_series, same_len, validated, NamedSeries, ReportError};

/// One bar over the campaign: measured thermal error against the fitted model (top),
/// temperatures (middle) and the residual with its RMS (bottom).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarFitFigure {
    /// Title, e.g. "Bar B03 — first-order thermal model".
    pub title: String,
    /// Line(s) under the title, typically the fitted parameters; `\n` starts a new line.
    pub subtitle: String,
    /// Sample times of `measured_um` and `model_um`, seconds since campaign start.
    pub time_s: Vec<f64>,
    /// Measured thermal error (µm); may hold 100k+ points (decimated per pixel column).
    pub measured_um: Vec<f64>,
    /// Model prediction at `time_s` (µm). The residual drawn is `measured − model`.
    pub model_um: Vec<f64>,
    /// Temperatures (°C), each with its own times in seconds since campaign start.
    pub temperatures_c: Vec<NamedSeries>,
    /// Mount changes, seconds since campaign start (faint vertical lines in every panel).
    pub mount_boundaries_s: Vec<f64>,
    /// Warnings about the model shown under the subtitle in red, one line each (e.g. parameters
    /// the data cannot determine).
    pub notes: Vec<String>,
    /// What the residual panel's points are when they are not the readings themselves, after
    /// its title (e.g. "at the 60-s bins' two nodes, which scatter less than the readings");
    /// empty for every reading.
    pub residual_points: String,
}

impl BarFitFigure {
    fn check(&self) -> Result<(), SpecError> {
        same_len(
            "time_s/measured_um",
            self.time_s.len(),
            self.measured_um.len(),
        )?;
        same_len("time_s/model_um", self.time_s.len(), self.model_um.len())?;
        check_series("temperature", &self.temperatures_c)
    }

    fn residual_um(&self) -> Vec<f64> {
        self.measured_um
            .iter()
            .zip(&self.model_um)
            .map(|(m, f)| m - f)
            .collect()
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_bar_fit(spec: &BarFitFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

/// The three y axes, top to bottom.
fn y_axes(spec: &BarFitFigure, residual: &[f64]) -> [Axis; 3] {
    let errors = spec.measured_um.iter().chain(&spec.model_um).copied();
    let temps = spec.temperatures_c.iter().flat_map(|s| s.y.iter().copied());
    [
        Axis::linear(errors, false, 6, "thermal error (µm)"),
        Axis::linear(temps, false, 4, "temperature (°C)"),
        Axis::linear(
            residual.iter().copied().chain(rms(residual).map(|r| -r)),
            true,
            5,
            "residual (µm)",
        ),
    ]
}

fn draw(spec: &BarFitFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let body = notes(&body, &spec.notes)?;
    let rows = split_grid(&body, &[1.0], &[0.42, 0.26, 0.32]);
    let all_t = spec
        .time_s
        .iter()
        .chain(spec.temperatures_c.iter().flat_map(|s| &s.x))
        .copied();
    let (x, unit) = Axis::time(all_t, 12);
    let residual = spec.residual_um();
    let [ye, yt, yr] = y_axes(spec, &residual);
    let left = [&ye, &yt, &yr]
        .iter()
        .map(|y| y_area_width(&body, y))
        .max()
        .unwrap_or(0);
    let ctx = Ctx {
        spec,
        unit,
        t: unit.convert(&spec.time_s),
        left,
    };
    draw_error_panel(&ctx, &rows[0], x.without_desc(), ye)?;
    draw_temperature_panel(&ctx, &rows[1], x.without_desc(), yt)?;
    draw_residual_panel(&ctx, &rows[2], x, yr, &residual)
}

/// What every panel of the figure shares.
struct Ctx<'s> {
    spec: &'s BarFitFigure,
    unit: TimeUnit,
    /// `time_s` in `unit`.
    t: Vec<f64>,
    /// Common width left of the plots.
    left: u32,
}

impl Ctx<'_> {
    /// A panel aligned with the others, with the mount lines drawn (and in the legend if asked).
    fn panel<'a, 'b>(
        &self,
        area: &'a Area<'b>,
        caption: &str,
        x: Axis,
        y: Axis,
        legend: bool,
    ) -> Result<Panel<'a, 'b>, DrawError> {
        let mut p = Panel::aligned(area, caption, x, y, (self.left, 0))?;
        for b in self.unit.convert(&self.spec.mount_boundaries_s) {
            p.vline(b, style::stroke(style::GREY, 1))?;
        }
        if legend && !self.spec.mount_boundaries_s.is_empty() {
            p.legend_entry("mount change", Mark::Line(style::GREY, 1));
        }
        Ok(p)
    }
}

fn draw_error_panel(c: &Ctx<'_>, area: &Area<'_>, x: Axis, y: Axis) -> Result<(), DrawError> {
    let mut p = c.panel(area, "Thermal error: measured vs model", x, y, true)?;
    if c.t.is_empty() {
        p.no_data("thermal error")?;
    }
    p.line(&c.t, &c.spec.measured_um, style::stroke(style::BLUE, 1))?;
    p.line(&c.t, &c.spec.model_um, style::stroke(style::RED, 2))?;
    p.legend_entry("measured", Mark::Line(style::BLUE, 2));
    p.legend_entry("model", Mark::Line(style::RED, 2));
    p.finish()
}

fn draw_temperature_panel(c: &Ctx<'_>, area: &Area<'_>, x: Axis, y: Axis) -> Result<(), DrawError> {
    let mut p = c.panel(area, "Temperature", x, y, false)?;
    if c.spec.temperatures_c.iter().all(|s| s.x.is_empty()) {
        p.no_data("temperature")?;
    }
    for (i, s) in c.spec.temperatures_c.iter().enumerate() {
        p.line(
            &c.unit.convert(&s.x),
            &s.y,
            style::stroke(style::palette(i + 2), 2),
        )?;
        p.legend_entry(&s.name, Mark::Line(style::palette(i + 2), 2));
    }
    p.finish()
}

fn draw_residual_panel(
    c: &Ctx<'_>,
    area: &Area<'_>,
    x: Axis,
    y: Axis,
    residual: &[f64],
) -> Result<(), DrawError> {
    let r = rms(residual);
    let points = match c.spec.residual_points.as_str() {
        "" => String::new(),
        words => format!(" {words}"),
    };
    let caption = match r {
        Some(r) => format!(
            "Residual (measured − model){points}: RMS {} µm",
            format_significant(r)
        ),
        None => format!("Residual (measured − model){points}"),
    };
    let mut p = c.panel(area, &caption, x, y, false)?;
    if r.is_none() {
        p.no_data("residual")?;
    }
    p.hline(0.0, style::stroke(style::MUTED, 1), false)?;
    p.line(&c.t, residual, style::stroke(style::palette(9), 1))?;
    p.legend_entry("residual", Mark::Line(style::palette(9), 2));
    if let Some(r) = r {
        for v in [r, -r] {
            p.hline(v, style::stroke(style::ORANGE, 2), true)?;
        }
        p.legend_entry(
            &format!("±RMS = {} µm", format_significant(r)),
            Mark::Dashed(style::ORANGE, 2),
        );
    }
    p.finish()
}
