//! Figure 4: the diagnostics ledger — residual RMS after each forward-selection step, per bar
//! and for the fleet, against the noise level.

use std::path::Path;

use super::axis::{format_significant, Axis};
use super::canvas::{header, render_with, Area, DrawError};
use super::legend::Mark;
use super::panel::Panel;
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{same_len, validated, NamedValues, ReportError};

/// RMS after each model step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LedgerFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// Step labels along x, e.g. "base", "+head_heating", "+sag".
    pub steps: Vec<String>,
    /// Per bar: RMS residual (µm) after each step (NaN: not evaluated).
    pub bars: Vec<NamedValues>,
    /// Fleet RMS (µm) after each step (thick line; empty: not drawn).
    pub fleet_rms_um: Vec<f64>,
    /// Measurement noise level (µm), drawn dashed.
    pub noise_um: Option<f64>,
    /// Logarithmic y axis (non-positive values are then skipped).
    pub log_y: bool,
}

impl LedgerFigure {
    fn check(&self) -> Result<(), SpecError> {
        let n = self.steps.len();
        for b in &self.bars {
            same_len(&format!("bar '{}' values/steps", b.name), b.values.len(), n)?;
        }
        if !self.fleet_rms_um.is_empty() {
            same_len("fleet_rms_um/steps", self.fleet_rms_um.len(), n)?;
        }
        Ok(())
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_ledger(spec: &LedgerFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &LedgerFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let all = spec
        .bars
        .iter()
        .flat_map(|b| b.values.iter())
        .chain(&spec.fleet_rms_um)
        .chain(&spec.noise_um)
        .copied();
    let desc = "RMS residual (µm)";
    let y = if spec.log_y {
        Axis::log(all, desc)
    } else {
        Axis::linear(all, true, 6, desc)
    };
    let x = Axis::categories(&spec.steps, false, "model step (effect added)");
    let mut p = Panel::new(&body, "", x, y)?;
    let xs: Vec<f64> = (0..spec.steps.len()).map(|i| i as f64).collect();
    if let Some(noise) = spec.noise_um {
        p.hline(noise, style::stroke(style::MUTED, 2), true)?;
        p.legend_entry(
            &format!("noise level {} µm", format_significant(noise)),
            Mark::Dashed(style::MUTED, 2),
        );
    }
    for (i, b) in spec.bars.iter().enumerate() {
        let c = style::palette(i);
        p.line(&xs, &b.values, style::stroke(c, 2))?;
        p.points(&xs, &b.values, c, 4)?;
        p.legend_entry(&b.name, Mark::Line(c, 2));
        // One bar alone: its values are the figure's message.
        if spec.bars.len() == 1 && spec.fleet_rms_um.is_empty() {
            for (x, v) in xs.iter().zip(&b.values) {
                p.tag(*x, *v, &format_significant(*v))?;
            }
        }
    }
    if !spec.fleet_rms_um.is_empty() {
        p.line(&xs, &spec.fleet_rms_um, style::stroke(style::BLACK, 5))?;
        p.points(&xs, &spec.fleet_rms_um, style::BLACK, 7)?;
        p.legend_entry("fleet", Mark::Line(style::BLACK, 5));
        for (x, v) in xs.iter().zip(&spec.fleet_rms_um) {
            p.tag(*x, *v, &format_significant(*v))?;
        }
    }
    if spec.steps.is_empty() {
        p.no_data("steps")?;
    }
    p.finish()
}
