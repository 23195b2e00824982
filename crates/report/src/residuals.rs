//! Figure 6: residual diagnostics of one bar — autocorrelation with its white-noise band, the
//! cumulative periodogram with its Kolmogorov band, and the explained fraction per channel.

use std::path::Path;

use plotters::style::text_anchor::{HPos, VPos};

use super::axis::{format_fixed, format_significant, Axis, TimeUnit};
use super::canvas::{header, render_with, split_grid, Area, DrawError};
use super::legend::Mark;
use super::panel::Panel;
use super::style::{self, FIGURE_SIZE, TEXT};
use super::SpecError;
use super::{same_len, validated, ReportError};

/// Residual diagnostics for one bar.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ResidualDiagnosticsFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// Residual autocorrelation at lags 0, 1, 2, … × `lag_step_s`.
    pub acf: Vec<f64>,
    /// Time between consecutive ACF lags (s).
    pub lag_step_s: f64,
    /// Number of residual samples behind the ACF (sets the ±1.96/√n band; 0: no band).
    pub n_samples: usize,
    /// Frequencies of the cumulative periodogram (Hz), ascending.
    pub cpgram_freq_hz: Vec<f64>,
    /// Cumulative periodogram (0 → 1) at `cpgram_freq_hz`.
    pub cpgram: Vec<f64>,
    /// Channel names (temperatures, candidate effects, ...).
    pub channels: Vec<String>,
    /// Fraction (0..1) of the residual each channel explains, `channels` order.
    pub explained_fraction: Vec<f64>,
}

impl ResidualDiagnosticsFigure {
    fn check(&self) -> Result<(), SpecError> {
        same_len(
            "cpgram_freq_hz/cpgram",
            self.cpgram_freq_hz.len(),
            self.cpgram.len(),
        )?;
        same_len(
            "explained_fraction/channels",
            self.explained_fraction.len(),
            self.channels.len(),
        )
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_residual_diagnostics(
    spec: &ResidualDiagnosticsFigure,
    path: &Path,
) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &ResidualDiagnosticsFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let rows = split_grid(&body, &[1.0], &[0.55, 0.45]);
    let top = split_grid(&rows[0], &[1.0, 1.0], &[1.0]);
    draw_acf(spec, &top[0])?;
    draw_cpgram(spec, &top[1])?;
    draw_explained(spec, &rows[1])
}

fn draw_acf(spec: &ResidualDiagnosticsFigure, area: &Area<'_>) -> Result<(), DrawError> {
    let step = if spec.lag_step_s.is_finite() && spec.lag_step_s > 0.0 {
        spec.lag_step_s
    } else {
        1.0
    };
    let lags_s: Vec<f64> = (0..spec.acf.len()).map(|k| k as f64 * step).collect();
    let unit = TimeUnit::for_span(lags_s.last().copied().unwrap_or(0.0));
    let lags = unit.convert(&lags_s);
    let band = (spec.n_samples > 0).then(|| 1.96 / (spec.n_samples as f64).sqrt());
    let x = Axis::fixed(
        0.0,
        lags.last().copied().unwrap_or(1.0),
        6,
        &format!("lag ({})", unit.symbol()),
    );
    let y = Axis::linear(
        spec.acf
            .iter()
            .copied()
            .chain([1.0, 0.0])
            .chain(band.map(|b| -b)),
        false,
        5,
        "autocorrelation",
    );
    let mut p = Panel::new(area, "Residual autocorrelation", x, y)?;
    p.hline(0.0, style::stroke(style::MUTED, 1), false)?;
    if let Some(b) = band {
        for v in [b, -b] {
            p.hline(v, style::stroke(style::RED, 2), true)?;
        }
        p.legend_entry(
            &format!("±1.96/√n = ±{}", format_significant(b)),
            Mark::Dashed(style::RED, 2),
        );
    }
    p.line(&lags, &spec.acf, style::stroke(style::BLUE, 2))?;
    p.legend_entry("ACF", Mark::Line(style::BLUE, 2));
    if spec.acf.is_empty() {
        p.no_data("autocorrelation")?;
    }
    p.finish()
}

/// Half-width of the 95 % Kolmogorov–Smirnov band for `m` periodogram ordinates (as in R's
/// `cpgram`).
fn kolmogorov_band(m: usize) -> Option<f64> {
    let q = (m.checked_sub(1)? as f64).sqrt();
    (q > 0.0).then(|| 1.358 / (q + 0.12 + 0.11 / q))
}

fn draw_cpgram(spec: &ResidualDiagnosticsFigure, area: &Area<'_>) -> Result<(), DrawError> {
    let f: Vec<f64> = spec.cpgram_freq_hz.iter().map(|v| v * 3600.0).collect();
    let fmax = f
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let fmax = if fmax > 0.0 { fmax } else { 1.0 };
    let x = Axis::fixed(0.0, fmax, 6, "frequency (cycles/h)");
    let y = Axis::fixed(0.0, 1.0, 5, "cumulative periodogram");
    let mut p = Panel::new(area, "Cumulative periodogram", x, y)?;
    p.dashed((0.0, 0.0), (fmax, 1.0), style::stroke(style::MUTED, 1))?;
    p.legend_entry("white noise", Mark::Dashed(style::MUTED, 1));
    if let Some(c) = kolmogorov_band(spec.cpgram.len()).filter(|c| *c < 1.0) {
        p.dashed(
            (0.0, c),
            ((1.0 - c) * fmax, 1.0),
            style::stroke(style::RED, 2),
        )?;
        p.dashed(
            (c * fmax, 0.0),
            (fmax, 1.0 - c),
            style::stroke(style::RED, 2),
        )?;
        p.legend_entry(
            &format!("95 % Kolmogorov band ±{}", format_significant(c)),
            Mark::Dashed(style::RED, 2),
        );
    }
    p.line(&f, &spec.cpgram, style::stroke(style::BLUE, 2))?;
    p.legend_entry("residual", Mark::Line(style::BLUE, 2));
    if spec.cpgram.is_empty() {
        p.no_data("periodogram")?;
    }
    p.finish()
}

fn draw_explained(spec: &ResidualDiagnosticsFigure, area: &Area<'_>) -> Result<(), DrawError> {
    let pct: Vec<f64> = spec.explained_fraction.iter().map(|v| v * 100.0).collect();
    let x = Axis::linear(
        pct.iter().copied().chain([0.0]),
        true,
        8,
        "explained fraction of the residual (%)",
    );
    let y = Axis::categories(&spec.channels, true, "");
    let mut p = Panel::new(area, "Explained fraction per channel", x, y)?;
    p.vline(0.0, style::stroke(style::MUTED, 1))?;
    for (i, v) in pct.iter().enumerate().filter(|(_, v)| v.is_finite()) {
        let yc = p.y.category(i);
        p.rect(
            (0.0, yc - 0.32),
            (*v, yc + 0.32),
            style::fill(style::palette(2), 1.0),
        )?;
        let st = style::text(style::NOTE_PX + 1.0, TEXT, (HPos::Left, VPos::Center));
        p.text(v.max(0.0), yc, &format!(" {} %", format_fixed(*v, 1)), st)?;
    }
    if spec.channels.is_empty() {
        p.no_data("channels")?;
    }
    p.finish()
}
