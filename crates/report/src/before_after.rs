//! Figure 5: RMS per bar before and after compensation (grouped bars), plus the fleet total.

use std::path::Path;

use super::axis::{format_significant, Axis};
use super::canvas::{header, render_with, Area, DrawError};
use super::legend::Mark;
use super::panel::Panel;
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{same_len, validated, ReportError};

/// Per-bar RMS before and after, with optional fleet totals as a last group.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BeforeAfterFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// The bars, the category axis.
    pub bar_names: Vec<String>,
    /// RMS per bar before (µm), `bar_names` order.
    pub before_um: Vec<f64>,
    /// RMS per bar after (µm), `bar_names` order.
    pub after_um: Vec<f64>,
    /// Fleet totals (µm); the "fleet" group is drawn when either is given.
    pub fleet_before_um: Option<f64>,
    /// Fleet total after (µm).
    pub fleet_after_um: Option<f64>,
    /// Legend labels; empty means "before" / "after".
    pub before_label: String,
    /// Legend label of the "after" bars.
    pub after_label: String,
}

impl BeforeAfterFigure {
    fn check(&self) -> Result<(), SpecError> {
        same_len(
            "before_um/bar_names",
            self.before_um.len(),
            self.bar_names.len(),
        )?;
        same_len(
            "after_um/bar_names",
            self.after_um.len(),
            self.bar_names.len(),
        )
    }

    fn has_fleet(&self) -> bool {
        self.fleet_before_um.is_some() || self.fleet_after_um.is_some()
    }

    /// (before, after) per category, the fleet last if present.
    fn groups(&self) -> Vec<(f64, f64)> {
        let mut g: Vec<(f64, f64)> = self
            .before_um
            .iter()
            .copied()
            .zip(self.after_um.iter().copied())
            .collect();
        if self.has_fleet() {
            g.push((
                self.fleet_before_um.unwrap_or(f64::NAN),
                self.fleet_after_um.unwrap_or(f64::NAN),
            ));
        }
        g
    }

    /// "fleet RMS 3.2 → 0.41 µm (−87 %)" when both totals are known.
    fn caption(&self) -> String {
        match (self.fleet_before_um, self.fleet_after_um) {
            (Some(b), Some(a)) if b.is_finite() && a.is_finite() && b != 0.0 => {
                let change = format!("{:+.0}", 100.0 * (a - b) / b).replace('-', "−");
                format!(
                    "Fleet RMS {} → {} µm ({change} %)",
                    format_significant(b),
                    format_significant(a)
                )
            }
            _ => "RMS per bar".to_string(),
        }
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_before_after(spec: &BeforeAfterFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn label_or<'s>(s: &'s str, default: &'s str) -> &'s str {
    if s.is_empty() {
        default
    } else {
        s
    }
}

fn draw(spec: &BeforeAfterFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let mut names = spec.bar_names.clone();
    if spec.has_fleet() {
        names.push("fleet".to_string());
    }
    let groups = spec.groups();
    let y = Axis::linear(groups.iter().flat_map(|g| [g.0, g.1]), true, 6, "RMS (µm)");
    let x = Axis::categories(&names, false, "bar");
    let mut p = Panel::new(&body, &spec.caption(), x, y)?;
    let (before_c, after_c) = (style::ORANGE, style::BLUE);
    let labels = groups.len() <= 20;
    for (i, (b, a)) in groups.iter().enumerate() {
        for (v, dx, c) in [(*b, -0.2, before_c), (*a, 0.2, after_c)] {
            if v.is_finite() {
                p.bar(i as f64 + dx, 0.18, 0.0, v, c)?;
                if labels {
                    p.bar_label(i as f64 + dx, v, &format_significant(v))?;
                }
            }
        }
    }
    if spec.has_fleet() {
        let sep = spec.bar_names.len() as f64 - 0.5;
        p.dashed((sep, p.y.lo), (sep, p.y.hi), style::stroke(style::MUTED, 1))?;
    }
    p.legend_entry(
        label_or(&spec.before_label, "before"),
        Mark::Filled(before_c),
    );
    p.legend_entry(label_or(&spec.after_label, "after"), Mark::Filled(after_c));
    if groups.is_empty() {
        p.no_data("bars")?;
    }
    p.finish()
}
