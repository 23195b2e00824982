//! The figures of a `volumetric` run as plain specs (pixels in `dbbcal-report`): the diagonal
//! curves up and down, the body diagonals a bar read (stitched Dr with U), the residuals along
//! each diagonal, the fourth sign pattern's consistency residual, the error vectors on the grid
//! (two equal-scale projections).

use std::path::Path;

use anyhow::Result;

use dbbcal_machine::volumetric::model::AXES;
use dbbcal_machine::volumetric::solve;
use dbbcal_machine::volumetric::study::{NodeError, VolumetricStudy};
use dbbcal_machine::volumetric::DiagonalSign;
use dbbcal_report::{
    render_error_grid, render_geometry, render_series_panels, BandedSeries, ErrorGridFigure,
    ErrorPanel, GeometryFigure, GeometryView, NamedSeries, RefLine, SeriesPanel,
    SeriesPanelsFigure, XAxis,
};

/// Renders the figures into `dir`; returns (file relative to the output, caption).
pub(crate) fn render(s: &VolumetricStudy, dir: &Path) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    let curves = curves_figure(s);
    if !curves.panels.is_empty() {
        render_series_panels(&curves, &dir.join("diagonals.png"))?;
        out.push((
            "figures/diagonals.png".into(),
            "Diagonal deviations, mean of the runs up (↑) and down (↓) (ISO 230-6)".into(),
        ));
    }
    if !s.bars.is_empty() {
        render_error_grid(&bar_figure(s), &dir.join("bar_diagonals.png"))?;
        out.push((
            "figures/bar_diagonals.png".into(),
            "Body diagonals read by the bar in re-seated segments: Dr stitched, with U (k = 2: the stitching, the bar's scale, the misalignment)".into(),
        ));
    }
    render_series_panels(&residual_figure(s), &dir.join("residuals.png"))?;
    out.push((
        "figures/residuals.png".into(),
        "Residuals of the joint fit along each diagonal (body and step readings)".into(),
    ));
    if let Some(f) = fourth_figure(s) {
        render_series_panels(&f, &dir.join("fourth_pattern.png"))?;
        out.push((
            "figures/fourth_pattern.png".into(),
            "The fourth sign pattern's consistency residual ρ_j, of the readings and of the joint fit's residuals".into(),
        ));
    }
    if s.fit.layout.intervals >= 2 {
        render_error_grid(&shapes_figure(s), &dir.join("error_shapes.png"))?;
        out.push((
            "figures/error_shapes.png".into(),
            "The error functions' shapes D_k(j) less their least-squares lines, with U (k = 2)"
                .into(),
        ));
    }
    render_geometry(&grid_figure(s, [0, 1], 2), &dir.join("grid_vectors_xy.png"))?;
    out.push((
        "figures/grid_vectors_xy.png".into(),
        "Error vectors (ex, ey) at the grid nodes, seen from above, one view per z level".into(),
    ));
    render_geometry(&grid_figure(s, [0, 2], 1), &dir.join("grid_vectors_xz.png"))?;
    out.push((
        "figures/grid_vectors_xz.png".into(),
        "Error vectors (ex, ez) at the grid nodes, seen from the front, one view per y level"
            .into(),
    ));
    Ok(out)
}

fn curves_figure(s: &VolumetricStudy) -> SeriesPanelsFigure {
    let panels = s
        .curves
        .iter()
        .filter_map(|c| {
            let iso = c.iso.as_ref().ok()?;
            let x: Vec<f64> = iso.targets.iter().map(|t| t.position_mm).collect();
            let mut series = Vec::new();
            for (name, pick) in [("mean ↑", true), ("mean ↓", false)] {
                let y: Vec<f64> = iso
                    .targets
                    .iter()
                    .map(|t| {
                        let d = if pick { t.up } else { t.down };
                        d.map_or(f64::NAN, |d| d.mean_um)
                    })
                    .collect();
                if y.iter().any(|v| v.is_finite()) {
                    series.push(NamedSeries {
                        name: name.into(),
                        x: x.clone(),
                        y,
                    });
                }
            }
            Some(SeriesPanel {
                title: format!(
                    "diagonal {} ({}, D = {:.0} mm): E = {}",
                    c.sign,
                    c.source,
                    c.length_mm,
                    c.e_um.map_or("—".into(), |e| format!("{e:.2} µm"))
                ),
                y_label: "deviation (µm)".into(),
                series,
                ref_lines: vec![RefLine {
                    label: "zero".into(),
                    value: 0.0,
                }],
            })
        })
        .collect();
    let body_only = s
        .invisible
        .iter()
        .any(|l| l.starts_with("with body diagonals only: 4 of 9"));
    SeriesPanelsFigure {
        title: "Diagonal displacement tests".into(),
        subtitle: format!(
            "V_diag = {}{}",
            s.v_diag.map_or("—".into(), |v| format!(
                "{:.2} µm (U {:.2} µm)",
                v.value_um, v.u_k2_um
            )),
            if body_only {
                "\nbody diagonals see 4 of 9 linear terms: per-axis scale differences do not show here"
            } else {
                ""
            }
        ),
        x_axis: XAxis::Values {
            label: "distance from P0 along the diagonal (mm)".into(),
        },
        panels,
    }
}

fn residual_figure(s: &VolumetricStudy) -> SeriesPanelsFigure {
    let mut panels = Vec::new();
    for sign in DiagonalSign::ALL {
        let diag = s.fit.layout.diagonal(sign);
        let mut series = Vec::new();
        for name in ["body", "bar", "step"] {
            let (mut x, mut y) = (Vec::new(), Vec::new());
            let mut last: Option<(i64, i8)> = None;
            for (o, r) in s.observations.iter().zip(&s.fit.residuals) {
                if o.diagonal != sign || solve::source(o) != name {
                    continue;
                }
                // A gap between runs and directions: each line is one pass.
                if last.is_some_and(|l| l != (o.run, o.direction)) {
                    x.push(f64::NAN);
                    y.push(f64::NAN);
                }
                last = Some((o.run, o.direction));
                let p = o.position_mm(diag);
                x.push((0..3).map(|k| diag.u[k] * (p[k] - diag.p0_mm[k])).sum());
                y.push(*r);
            }
            if !x.is_empty() {
                series.push(NamedSeries {
                    name: format!("{name} readings"),
                    x,
                    y,
                });
            }
        }
        if series.is_empty() {
            continue;
        }
        let rms = s
            .residual_rms
            .iter()
            .filter(|(d, ..)| *d == sign)
            .map(|(_, src, r, n)| format!("{src} {r:.3} µm ({n})"))
            .collect::<Vec<_>>()
            .join(", ");
        panels.push(SeriesPanel {
            title: format!("diagonal {sign}: residual RMS {rms}"),
            y_label: "residual (µm)".into(),
            series,
            ref_lines: vec![RefLine {
                label: "zero".into(),
                value: 0.0,
            }],
        });
    }
    SeriesPanelsFigure {
        title: "Residuals of the joint least-squares fit".into(),
        subtitle: format!(
            "model effects: {}; all readings RMS {:.3} µm",
            effects(s),
            s.fit.rms_um
        ),
        x_axis: XAxis::Values {
            label: "distance from P0 along the diagonal, u·(P − P0) (mm)".into(),
        },
        panels,
    }
}

fn effects(s: &VolumetricStudy) -> String {
    let e: Vec<&str> = s.fit.layout.effects.iter().map(|e| e.name()).collect();
    if e.is_empty() {
        "none (the additive model alone)".into()
    } else {
        e.join(", ")
    }
}

/// ρ_j of the readings and of the residuals, per axis, against % of the axis's travel.
fn fourth_figure(s: &VolumetricStudy) -> Option<SeriesPanelsFigure> {
    let data: Vec<f64> = s.observations.iter().map(|o| o.deviation_um).collect();
    let layout = &s.fit.layout;
    let of_data = solve::step_series(layout, &s.observations, &data)
        .ok()
        .and_then(|f| solve::fourth_pattern(&f))?;
    let of_residuals = s.fourth_residual_um.as_ref()?;
    let panels = (0..3)
        .map(|j| {
            let nodes = layout.nodes(j);
            let (lo, len) = (layout.min_mm[j], layout.lengths_mm[j]);
            let x: Vec<f64> = nodes.iter().map(|q| 100.0 * (q - lo) / len).collect();
            SeriesPanel {
                title: format!("ρ along {} ({:.0} … {:.0} mm)", AXES[j], lo, lo + len),
                y_label: "ρ (µm)".into(),
                series: vec![
                    NamedSeries {
                        name: "of the readings".into(),
                        x: x.clone(),
                        y: of_data[j].clone(),
                    },
                    NamedSeries {
                        name: "of the joint fit's residuals".into(),
                        x,
                        y: of_residuals[j].clone(),
                    },
                ],
                ref_lines: vec![RefLine {
                    label: "zero".into(),
                    value: 0.0,
                }],
            }
        })
        .collect();
    let (d, r) = s.fourth_rms_um.unwrap_or((f64::NAN, f64::NAN));
    Some(SeriesPanelsFigure {
        title: "Fourth sign pattern: ρ_j = ¼ Σ_d sx·sy·sz F_dj".into(),
        subtitle: format!(
            "zero for the additive model with zero pointing; RMS {d:.3} µm in the readings, {r:.3} µm in the residuals (model effects: {})",
            effects(s)
        ),
        x_axis: XAxis::Values {
            label: "position along the sub-moved axis (% of its travel from the min corner)".into(),
        },
        panels,
    })
}

/// Error vectors in the plane of axes `plane` (equal scale), one view per level of axis
/// `level`.
fn grid_figure(s: &VolumetricStudy, plane: [usize; 2], level: usize) -> GeometryFigure {
    let g = &s.grid;
    let [a, b] = plane;
    let value = |n: &NodeError, k: usize| n.error[k].value;
    let max_e = s
        .nodes
        .iter()
        .map(|n| value(n, a).hypot(value(n, b)))
        .fold(0.0, f64::max);
    let room_mm = [a, b]
        .map(|k| {
            if g.counts[k] > 1 {
                g.spacing_mm[k]
            } else {
                s.fit.layout.lengths_mm[k]
            }
        })
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    // Floor of 1 µm: noise-sized vectors are drawn noise-sized, not blown up into a field.
    let max_e = max_e.max(1.0);
    let ref_um = round_scale(max_e);
    let scale = 0.8 * room_mm / max_e; // mm of the drawing per µm
    let views = (1..=g.counts[level])
        .map(|lv| {
            let nodes: Vec<&NodeError> = s.nodes.iter().filter(|n| n.node[level] == lv).collect();
            let (mut ax, mut ay) = (Vec::new(), Vec::new());
            let (mut ux, mut uy) = (Vec::new(), Vec::new());
            for n in &nodes {
                let from = [n.position_mm[a], n.position_mm[b]];
                let d = [scale * value(n, a), scale * value(n, b)];
                arrow(&mut ax, &mut ay, from, d);
                let u = [n.error[a].u_k2, n.error[b].u_k2];
                if u.iter().all(|u| u.is_finite()) {
                    let tip = [from[0] + d[0], from[1] + d[1]];
                    ellipse(&mut ux, &mut uy, tip, [scale * u[0], scale * u[1]]);
                }
            }
            // The scale arrow, below the min corner.
            let (mut rx, mut ry) = (Vec::new(), Vec::new());
            let below = g.origin_mm[b] - 0.5 * room_mm;
            arrow(
                &mut rx,
                &mut ry,
                [g.origin_mm[a], below],
                [scale * ref_um, 0.0],
            );
            let mut lines = vec![
                NamedSeries {
                    name: format!("e{}, e{} (1 µm = {scale:.1} mm)", AXES[a], AXES[b]),
                    x: ax,
                    y: ay,
                },
                NamedSeries {
                    name: format!("{} µm", num_short(ref_um)),
                    x: rx,
                    y: ry,
                },
            ];
            if !ux.is_empty() {
                lines.push(NamedSeries {
                    name: "U (k = 2) about the tip".into(),
                    x: ux,
                    y: uy,
                });
            }
            GeometryView {
                title: format!(
                    "{} = {:.0} mm",
                    AXES[level],
                    g.origin_mm[level] + (lv - 1) as f64 * g.spacing_mm[level]
                ),
                x_label: format!("{} (mm)", AXES[a]),
                y_label: format!("{} (mm)", AXES[b]),
                lines,
                points: vec![NamedSeries {
                    name: "grid node".into(),
                    x: nodes.iter().map(|n| n.position_mm[a]).collect(),
                    y: nodes.iter().map(|n| n.position_mm[b]).collect(),
                }],
            }
        })
        .collect();
    GeometryFigure {
        title: if s.figures_identifiable {
            format!(
                "Error vectors on the grid: (e{}, e{}), error = measured − commanded",
                AXES[a], AXES[b]
            )
        } else {
            format!(
                "Error vectors (e{}, e{}) in the stated gauge: NOT measured by these readings",
                AXES[a], AXES[b]
            )
        },
        subtitle: if s.figures_identifiable {
            format!(
                "V1 {:.2} µm, V2 {:.2} µm, V3 {:.2} µm",
                s.v1.value_um, s.v2.value_um, s.v3.value_um
            )
        } else {
            format!(
                "gauge values, not the machine's (V1 {:.2}, V2 {:.2}, V3 {:.2} µm): report.md, \"What these readings cannot see\"",
                s.v1.value_um, s.v2.value_um, s.v3.value_um
            )
        },
        views,
    }
}

/// A polyline arrow from `from` by `d` (with a head), NaN-terminated.
/// The ellipse of semi-axes `half` about `centre` (each component's U, drawn to the arrows'
/// scale), as one closed polyline.
fn ellipse(x: &mut Vec<f64>, y: &mut Vec<f64>, centre: [f64; 2], half: [f64; 2]) {
    for k in 0..=24 {
        let t = std::f64::consts::TAU * k as f64 / 24.0;
        x.push(centre[0] + half[0] * t.cos());
        y.push(centre[1] + half[1] * t.sin());
    }
    x.push(f64::NAN);
    y.push(f64::NAN);
}

fn arrow(x: &mut Vec<f64>, y: &mut Vec<f64>, from: [f64; 2], d: [f64; 2]) {
    let to = [from[0] + d[0], from[1] + d[1]];
    x.extend([from[0], to[0], f64::NAN]);
    y.extend([from[1], to[1], f64::NAN]);
    let len = d[0].hypot(d[1]);
    if len <= 0.0 {
        return;
    }
    let head = 0.25 * len;
    let (ux, uy) = (d[0] / len, d[1] / len);
    for side in [1.0, -1.0] {
        let (c, s) = (0.94_f64, 0.34 * side); // ±20°
        let hx = -(c * ux - s * uy) * head;
        let hy = -(s * ux + c * uy) * head;
        x.extend([to[0], to[0] + hx, f64::NAN]);
        y.extend([to[1], to[1] + hy, f64::NAN]);
    }
}

/// A round reference length (1, 2 or 5 × 10ⁿ µm) near half the largest error.
fn round_scale(max_um: f64) -> f64 {
    let target = (0.5 * max_um).max(1e-3);
    let p = 10f64.powf(target.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .rfind(|v| *v <= target)
        .unwrap_or(p)
}

fn num_short(v: f64) -> String {
    if v >= 1.0 {
        format!("{v:.0}")
    } else {
        format!("{v}")
    }
}

/// The nine shapes with their U bands, one panel each (rows: axis moved; columns: component).
/// Each bar-read diagonal: the stitched Dr with U, and where the segments start.
fn bar_figure(s: &VolumetricStudy) -> ErrorGridFigure {
    let panels = s
        .bars
        .iter()
        .map(|b| {
            let st = &b.stitched;
            ErrorPanel {
                title: format!(
                    "diagonal {} by bar {}: {} segments, U at the far corner {:.2} µm",
                    b.sign,
                    b.bar,
                    b.segments(),
                    st.u_k2_um.last().copied().unwrap_or(f64::NAN)
                ),
                y_label: "Dr (µm)".into(),
                curves: vec![BandedSeries {
                    name: "Dr ± U".into(),
                    x: st.target_mm.clone(),
                    y: st.dr_um.clone(),
                    u_k2: st.u_k2_um.clone(),
                }],
            }
        })
        .collect();
    let b = &s.bars[0];
    ErrorGridFigure {
        title: format!("Body diagonals read by bar {}", b.bar),
        subtitle: format!(
            "Dr = u · [e(P) − e(P0)], each segment's constant solved for; bar scale u {} ppm (fully correlated), sockets within {:.2} mm of the line",
            b.stitched.budget.scale_u_ppm,
            b.stitched.budget.max_misalignment_rad * b.shortest_centre_distance_mm
        ),
        x_label: "distance from P0 along the diagonal (mm)".into(),
        columns: s.bars.len().min(2),
        panels,
    }
}

fn shapes_figure(s: &VolumetricStudy) -> ErrorGridFigure {
    let shapes = s.fit.shapes();
    let layout = &s.fit.layout;
    let mut panels = Vec::new();
    for (j, row) in shapes.iter().enumerate() {
        for (k, series) in row.iter().enumerate() {
            let (lo, len) = (layout.min_mm[j], layout.lengths_mm[j]);
            panels.push(ErrorPanel {
                title: format!(
                    "D{}({}) {}, {} {:.0} … {:.0} mm",
                    AXES[k],
                    AXES[j],
                    if j == k {
                        "positioning"
                    } else {
                        "straightness"
                    },
                    AXES[j],
                    lo,
                    lo + len
                ),
                y_label: "shape (µm)".into(),
                curves: vec![BandedSeries {
                    name: "shape ± U".into(),
                    x: series.iter().map(|(q, _)| 100.0 * (q - lo) / len).collect(),
                    y: series.iter().map(|(_, v)| v.value).collect(),
                    u_k2: series.iter().map(|(_, v)| v.u_k2).collect(),
                }],
            });
        }
    }
    ErrorGridFigure {
        title: "Error functions less their least-squares lines (what pointing cannot hide)".into(),
        subtitle: format!(
            "error = measured − commanded; the lines' slopes: squareness and Σ L_k² ε_k / D² in report.md{}",
            if s.slopes.iter().flatten().all(|q| q.identifiable) {
                ""
            } else {
                "; the per-axis slopes are not seen (pointing)"
            }
        ),
        x_label: "% of the moved axis's travel".into(),
        columns: 3,
        panels,
    }
}
