//! A polar panel: values (µm) against a direction (degrees), drawn around a circle whose
//! radius grows with the value from an inner ring (so negative values stay visible). Used for
//! a touch-trigger probe's pretravel by direction and the model's lobes.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::axis::{format_significant, Axis};
use super::canvas::{header, render_with, Area, DrawError};
use super::style::{self, FIGURE_SIZE};
use super::SpecError;
use super::{same_len, validated, ReportError};

/// One series of a polar figure.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PolarSeries {
    /// Legend label.
    pub name: String,
    /// Directions, degrees (0 along +x, counter-clockwise).
    pub angle_deg: Vec<f64>,
    /// Values, one per angle (NaN skipped).
    pub value: Vec<f64>,
    /// Joined by a closed line (true) or drawn as points.
    pub line: bool,
}

/// Values by direction.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PolarFigure {
    /// The figure's title.
    pub title: String,
    /// Line(s) under the title; `\n` starts a new line.
    pub subtitle: String,
    /// What the radius shows, with its unit (e.g. "pretravel (µm)").
    pub value_desc: String,
    /// The series.
    pub series: Vec<PolarSeries>,
}

impl PolarFigure {
    fn check(&self) -> Result<(), SpecError> {
        for s in &self.series {
            same_len(
                &format!("series '{}' angle_deg/value", s.name),
                s.angle_deg.len(),
                s.value.len(),
            )?;
        }
        Ok(())
    }
}

/// Writes `spec` as a 1600×1000 PNG at `path`.
pub fn render_polar(spec: &PolarFigure, path: &Path) -> Result<(), ReportError> {
    validated(path, spec.check())?;
    render_with(path, FIGURE_SIZE, |root| draw(spec, root))
}

fn draw(spec: &PolarFigure, root: &Area<'_>) -> Result<(), DrawError> {
    let body = header(root, &spec.title, &spec.subtitle)?;
    let (w, h) = body.dim_in_pixel();
    let (w, h) = (w as i32, h as i32);
    let cx = w * 2 / 5;
    let cy = h / 2;
    let outer = (h / 2 - 50).min(cx - 60).max(40);
    let inner = outer / 4;
    let values = spec.series.iter().flat_map(|s| s.value.iter().copied());
    let scale = Axis::linear(values, false, 5, &spec.value_desc);
    let span = (scale.hi - scale.lo).max(f64::MIN_POSITIVE);
    let radius = |v: f64| f64::from(inner) + (v - scale.lo) / span * f64::from(outer - inner);
    let at = |angle_deg: f64, r: f64| {
        let a = angle_deg.to_radians();
        (
            cx + (r * a.cos()).round() as i32,
            cy - (r * a.sin()).round() as i32,
        )
    };
    // Grid: a circle per tick, spokes every 30°.
    for t in &scale.ticks {
        let r = radius(*t);
        let ring: Vec<(i32, i32)> = (0..=360).map(|d| at(f64::from(d), r)).collect();
        body.draw(&PathElement::new(ring, style::stroke(style::GRID, 1)))?;
        let (x, y) = at(90.0, r);
        body.draw(&Text::new(
            format_significant(*t),
            (x + 4, y - 2),
            style::text(style::TICK_PX, style::MUTED, (HPos::Left, VPos::Bottom)),
        ))?;
    }
    for d in (0..360).step_by(30) {
        let d = f64::from(d);
        body.draw(&PathElement::new(
            vec![at(d, f64::from(inner)), at(d, f64::from(outer))],
            style::stroke(style::GRID, 1),
        ))?;
        let (x, y) = at(d, f64::from(outer) + 22.0);
        body.draw(&Text::new(
            format!("{d:.0}°"),
            (x, y),
            style::text(style::TICK_PX, style::TEXT, (HPos::Center, VPos::Center)),
        ))?;
    }
    let inner_ring: Vec<(i32, i32)> = (0..=360)
        .map(|d| at(f64::from(d), f64::from(inner)))
        .collect();
    body.draw(&PathElement::new(
        inner_ring,
        style::stroke(style::MUTED, 1),
    ))?;
    for (i, s) in spec.series.iter().enumerate() {
        let c = style::palette(i);
        let mut pts: Vec<(f64, f64)> = s
            .angle_deg
            .iter()
            .zip(&s.value)
            .filter(|(a, v)| a.is_finite() && v.is_finite())
            .map(|(a, v)| (*a, *v))
            .collect();
        if s.line {
            pts.sort_by(|a, b| a.0.rem_euclid(360.0).total_cmp(&b.0.rem_euclid(360.0)));
            let mut path: Vec<(i32, i32)> = pts.iter().map(|(a, v)| at(*a, radius(*v))).collect();
            if let Some(first) = path.first().copied() {
                path.push(first);
            }
            body.draw(&PathElement::new(path, style::stroke(c, 3)))?;
        } else {
            for (a, v) in &pts {
                body.draw(&Circle::new(at(*a, radius(*v)), 6, c.filled()))?;
            }
        }
        // Legend, right of the circle.
        let ly = 30 + i as i32 * 34;
        let lx = cx + outer + 90;
        if s.line {
            body.draw(&PathElement::new(
                vec![(lx, ly), (lx + 36, ly)],
                style::stroke(c, 3),
            ))?;
        } else {
            body.draw(&Circle::new((lx + 18, ly), 6, c.filled()))?;
        }
        body.draw(&Text::new(
            s.name.clone(),
            (lx + 46, ly),
            style::text(style::LEGEND_PX, style::TEXT, (HPos::Left, VPos::Center)),
        ))?;
    }
    // The note in two lines: in one it ran past the figure's right edge.
    let note_y = 30 + spec.series.len() as i32 * 34 + 20;
    let note = [
        format!("radius: {}", spec.value_desc),
        format!(
            "from {} (inner ring) to {}",
            format_significant(scale.lo),
            format_significant(scale.hi)
        ),
    ];
    for (k, line) in note.into_iter().enumerate() {
        body.draw(&Text::new(
            line,
            (cx + outer + 90, note_y + 22 * k as i32),
            style::text(style::NOTE_PX, style::MUTED, (HPos::Left, VPos::Top)),
        ))?;
    }
    if spec
        .series
        .iter()
        .all(|s| s.value.iter().all(|v| !v.is_finite()))
    {
        body.draw(&Text::new(
            "no data".to_string(),
            (cx, cy),
            style::text(style::CAPTION_PX, style::RED, (HPos::Center, VPos::Center)),
        ))?;
    }
    Ok(())
}
