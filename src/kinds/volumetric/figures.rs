//! The figures of a `volumetric` run as plain specs (pixels in `dbbcal-report`): the diagonal
//! curves up and down, the residuals and the fourth sign pattern, the error vectors on the grid.

use std::path::Path;

use anyhow::Result;

use dbbcal_machine::volumetric::model::Place;
use dbbcal_machine::volumetric::study::VolumetricStudy;
use dbbcal_machine::volumetric::DiagonalSign;
use dbbcal_report::{
    render_series_panels, NamedSeries, RefLine, SeriesPanel, SeriesPanelsFigure, XAxis,
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
    render_series_panels(&residual_figure(s), &dir.join("residuals.png"))?;
    out.push((
        "figures/residuals.png".into(),
        "Residuals of the joint fit per diagonal, and the fourth sign pattern".into(),
    ));
    render_series_panels(&grid_figure(s), &dir.join("grid_vectors.png"))?;
    out.push((
        "figures/grid_vectors.png".into(),
        "Error vectors (ex, ey) on the grid, one panel per z level".into(),
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
    SeriesPanelsFigure {
        title: "Diagonal displacement tests".into(),
        subtitle: format!(
            "V_diag = {}",
            s.v_diag.map_or("—".into(), |v| format!(
                "{:.2} µm (U {:.2} µm)",
                v.value_um, v.u_k2_um
            ))
        ),
        x_axis: XAxis::Values {
            label: "distance from P0 along the diagonal (mm)".into(),
        },
        panels,
    }
}

fn residual_figure(s: &VolumetricStudy) -> SeriesPanelsFigure {
    let mut panels = Vec::new();
    let mut series = Vec::new();
    for sign in DiagonalSign::ALL {
        for (step, name) in [(false, "body"), (true, "step")] {
            let (x, y): (Vec<f64>, Vec<f64>) = s
                .observations
                .iter()
                .zip(&s.fit.residuals)
                .filter(|(o, _)| {
                    o.diagonal == sign && matches!(o.place, Place::Step { .. }) == step
                })
                .enumerate()
                .map(|(i, (_, r))| (i as f64, *r))
                .unzip();
            if !x.is_empty() {
                series.push(NamedSeries {
                    name: format!("{sign} {name}"),
                    x,
                    y,
                });
            }
        }
    }
    panels.push(SeriesPanel {
        title: format!("joint-fit residuals (RMS {:.3} µm)", s.fit.rms_um),
        y_label: "residual (µm)".into(),
        series,
        ref_lines: vec![],
    });
    if let Some(f) = &s.fourth_residual_um {
        let n = f[0].len().max(2) - 1;
        let series = (0..3)
            .map(|j| NamedSeries {
                name: format!("ρ along {}", ["x", "y", "z"][j]),
                x: (0..f[j].len())
                    .map(|i| i as f64 * 100.0 / n as f64)
                    .collect(),
                y: f[j].clone(),
            })
            .collect();
        panels.push(SeriesPanel {
            title: "fourth sign pattern of the residuals (x axis: % of the travel)".into(),
            y_label: "ρ (µm)".into(),
            series,
            ref_lines: vec![],
        });
    }
    SeriesPanelsFigure {
        title: "Residuals".into(),
        subtitle: format!(
            "model effects: {}",
            s.fit
                .layout
                .effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        x_axis: XAxis::Values {
            label: "reading number on the diagonal / % of the travel".into(),
        },
        panels,
    }
}

fn grid_figure(s: &VolumetricStudy) -> SeriesPanelsFigure {
    let g = &s.grid;
    let max_e = s
        .nodes
        .iter()
        .map(|n| n.error[0].value.hypot(n.error[1].value))
        .fold(0.0, f64::max)
        .max(1e-9);
    let scale = 0.45 * g.spacing_mm[0].min(g.spacing_mm[1]) / max_e; // mm per µm
    let mut panels = Vec::new();
    for k in 1..=g.counts[2] {
        let nodes: Vec<_> = s.nodes.iter().filter(|n| n.node[2] == k).collect();
        let (mut ax, mut ay) = (Vec::new(), Vec::new());
        for n in &nodes {
            ax.extend([
                n.position_mm[0],
                n.position_mm[0] + scale * n.error[0].value,
                f64::NAN,
            ]);
            ay.extend([
                n.position_mm[1],
                n.position_mm[1] + scale * n.error[1].value,
                f64::NAN,
            ]);
        }
        panels.push(SeriesPanel {
            title: format!(
                "z = {:.0} mm",
                g.origin_mm[2] + (k - 1) as f64 * g.spacing_mm[2]
            ),
            y_label: "y (mm)".into(),
            series: vec![
                NamedSeries {
                    name: "node".into(),
                    x: nodes
                        .iter()
                        .flat_map(|n| [n.position_mm[0], f64::NAN])
                        .collect(),
                    y: nodes
                        .iter()
                        .flat_map(|n| [n.position_mm[1], f64::NAN])
                        .collect(),
                },
                NamedSeries {
                    name: format!("error (1 µm = {scale:.1} mm)"),
                    x: ax,
                    y: ay,
                },
            ],
            ref_lines: vec![],
        });
    }
    SeriesPanelsFigure {
        title: "Error vectors on the grid (ex, ey)".into(),
        subtitle: format!(
            "V1 {:.2} µm, V2 {:.2} µm, V3 {:.2} µm{}",
            s.v1.value_um,
            s.v2.value_um,
            s.v3.value_um,
            if s.figures_identifiable {
                ""
            } else {
                " (in the stated gauge: not all seen)"
            }
        ),
        x_axis: XAxis::Values {
            label: "x (mm)".into(),
        },
        panels,
    }
}
