//! Figure 2: the fleet — each parameter per bar with its 95 % uncertainty, the fleet mean and
//! the reference bar, plus every bar's predicted mismatch against the reference.

use std::path::Path;

use super::axis::{format_significant, Axis};
use super::canvas::{header, render_with, split_grid, Area, DrawError};
use super::legend::{self, LegendEntry, Mark};
use super::panel::Panel;
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{same_len, validated, ReportError};

/// One fitted parameter across the fleet.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParameterPanel {
    /// Name as shown in the panel title, e.g. "alpha_ppm_per_k".
    pub name: String,
    /// Unit for the y axis, e.g. "ppm/K" or "s".
    pub unit: String,
    /// Value per bar, in [`FleetFigure::bar_names`] order (NaN: not identified).
    pub values: Vec<f64>,
    /// Expanded uncertainty (95 %) per bar, same order (NaN: no error bar).
    pub u95: Vec<f64>,
    /// Fleet mean; `None` draws the mean of the finite values.
    pub fleet_mean: Option<f64>,
}

/// Fleet overview: one small panel per parameter and the mismatch-vs-reference panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FleetFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// Bar identifiers, the category axis of every panel.
    pub bar_names: Vec<String>,
    /// One panel per parameter.
    pub parameters: Vec<ParameterPanel>,
    /// Index into `bar_names` of the reference bar (highlighted everywhere).
    pub reference: Option<usize>,
    /// Predicted mismatch of each bar against the reference (µm), `bar_names` order (0 for the
    /// reference, NaN for a bar left out of matching, labelled so); empty leaves the panel with
    /// a "no data" note.
    pub mismatch_um: Vec<f64>,
    /// Acceptance limit (µm, e.g. 1.0): bars with |mismatch| above it are flagged.
    pub mismatch_limit_um: f64,
}

impl FleetFigure {
    fn check(&self) -> Result<(), SpecError> {
        let n = self.bar_names.len();
        for p in &self.parameters {
            same_len(&format!("{} values/bar_names", p.name), p.values.len(), n)?;
            same_len(&format!("{} u95/bar_names", p.name), p.u95.len(), n)?;
        }
        if !self.mismatch_um.is_empty() {
            same_len("mismatch_um/bar_names", self.mismatch_um.len(), n)?;
        }
        match self.reference {
            Some(index) if index >= n => Err(SpecError::ReferenceOutOfRange { index, bars: n }),
            _ => Ok(()),
        }
    }

    fn reference_name(&self) -> Option<&str> {
        self.reference
            .and_then(|r| self.bar_names.get(r))
            .map(String::as_str)
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_fleet(spec: &FleetFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &FleetFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let mut entries = vec![
        LegendEntry {
            label: "value ± U95 (95 %)".into(),
            mark: Mark::Dot(style::BLUE),
        },
        LegendEntry {
            label: "fleet mean".into(),
            mark: Mark::Dashed(style::MUTED, 2),
        },
    ];
    if let Some(name) = spec.reference_name() {
        entries.insert(
            1,
            LegendEntry {
                label: format!("reference {name}"),
                mark: Mark::Dot(style::RED),
            },
        );
    }
    let body = if spec.parameters.is_empty() {
        body
    } else {
        legend::strip(&body, &entries)?
    };
    let n = spec.parameters.len();
    let parts = if n == 0 {
        vec![body.clone(), body]
    } else {
        split_grid(&body, &[1.0], &[0.62, 0.38])
    };
    let cols = match n {
        0..=2 => n.max(1),
        3 | 4 => 2,
        _ => 3,
    };
    let rows = n.div_ceil(cols).max(1);
    let cells = split_grid(&parts[0], &vec![1.0; cols], &vec![1.0; rows]);
    for (p, cell) in spec.parameters.iter().zip(&cells) {
        draw_parameter(spec, p, cell)?;
    }
    draw_mismatch(spec, &parts[1])
}

fn mean_of(p: &ParameterPanel) -> Option<f64> {
    let finite: Vec<f64> = p.values.iter().copied().filter(|v| v.is_finite()).collect();
    p.fleet_mean
        .or_else(|| (!finite.is_empty()).then(|| finite.iter().sum::<f64>() / finite.len() as f64))
}

fn draw_parameter(
    spec: &FleetFigure,
    p: &ParameterPanel,
    area: &Area<'_>,
) -> Result<(), DrawError> {
    let mean = mean_of(p);
    let spans = p
        .values
        .iter()
        .zip(&p.u95)
        .flat_map(|(v, u)| [v - u.abs(), v + u.abs(), *v]);
    let y = Axis::linear(spans.chain(mean), false, 4, &p.unit);
    let x = Axis::categories(&spec.bar_names, false, "");
    let caption = match mean {
        Some(m) => format!("{}   (mean {} {})", p.name, format_significant(m), p.unit),
        None => p.name.clone(),
    };
    let mut panel = Panel::new(area, &caption, x, y)?;
    if let Some(m) = mean {
        panel.hline(m, style::stroke(style::MUTED, 2), true)?;
    }
    for (i, (v, u)) in p.values.iter().zip(&p.u95).enumerate() {
        panel.error_bar(
            i as f64,
            v - u.abs(),
            v + u.abs(),
            0.15,
            style::stroke(style::TEXT, 2),
        )?;
    }
    let xs: Vec<f64> = (0..p.values.len()).map(|i| i as f64).collect();
    panel.points(&xs, &p.values, style::BLUE, 6)?;
    if let Some(r) = spec.reference {
        panel.points(&[r as f64], &[p.values[r]], style::RED, 8)?;
    }
    if spec.bar_names.is_empty() {
        panel.no_data(&p.name)?;
    }
    panel.finish()
}

/// "Predicted mismatch vs reference B03: 2 bar(s) beyond ±1 µm".
fn mismatch_caption(spec: &FleetFigure, limit: f64, n_flagged: usize) -> String {
    let reference = spec
        .reference_name()
        .map(|r| format!(" {r}"))
        .unwrap_or_default();
    format!(
        "Predicted mismatch vs reference{reference}: {n_flagged} bar(s) beyond ±{} µm",
        format_significant(limit)
    )
}

fn draw_mismatch(spec: &FleetFigure, area: &Area<'_>) -> Result<(), DrawError> {
    let limit = spec.mismatch_limit_um.abs();
    let limit = if limit.is_finite() { limit } else { 0.0 };
    let n_flagged = spec.mismatch_um.iter().filter(|v| v.abs() > limit).count();
    let values = spec.mismatch_um.iter().copied().chain([limit, -limit]);
    let y = Axis::linear(values, true, 5, "mismatch (µm)");
    let x = Axis::categories(&spec.bar_names, false, "bar");
    let mut panel = Panel::new(area, &mismatch_caption(spec, limit, n_flagged), x, y)?;
    panel.hline(0.0, style::stroke(style::MUTED, 1), false)?;
    draw_mismatch_bars(spec, &mut panel, limit)?;
    let limit_text = format!("±{} µm", format_significant(limit));
    panel.legend_entry(&format!("within {limit_text}"), Mark::Filled(style::BLUE));
    if n_flagged > 0 {
        panel.legend_entry("beyond the limit (flagged)", Mark::Filled(style::RED));
    }
    if limit > 0.0 {
        for v in [limit, -limit] {
            panel.hline(v, style::stroke(style::RED, 2), true)?;
        }
        panel.legend_entry(&format!("limit {limit_text}"), Mark::Dashed(style::RED, 2));
    }
    if spec.mismatch_um.is_empty() {
        panel.no_data("mismatch")?;
    }
    panel.finish()
}

/// One bar per finite mismatch, red beyond `limit`, labelled with its value (or as the
/// reference); a bar left out of matching (NaN) is labelled so, without a bar.
fn draw_mismatch_bars(
    spec: &FleetFigure,
    panel: &mut Panel<'_, '_>,
    limit: f64,
) -> Result<(), DrawError> {
    let values = spec.mismatch_um.len() <= 24;
    let (reference, unmatched) = if spec.bar_names.len() > 12 {
        ("ref", "n/m")
    } else {
        ("reference", "not matched")
    };
    for (i, v) in spec.mismatch_um.iter().enumerate() {
        if !v.is_finite() {
            if values {
                panel.bar_label(i as f64, 0.0, unmatched)?;
            }
            continue;
        }
        let colour = if v.abs() > limit {
            style::RED
        } else {
            style::BLUE
        };
        panel.bar(i as f64, 0.35, 0.0, *v, colour)?;
        if spec.reference == Some(i) {
            panel.bar_label(i as f64, *v, reference)?;
        } else if values {
            panel.bar_label(i as f64, *v, &format_significant(*v))?;
        }
    }
    Ok(())
}
