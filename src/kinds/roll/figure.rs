//! The `roll` figure's spec (no pixels: `dbbcal-report` draws it): εx(n) against the stage
//! position with its U (k = 2) band and each pass's own eq. 10 curve; below, each pass minus the
//! global solution (a drift in time shows as passes run both ways fanning out).

use std::path::Path;

use crate::report;
use dbbcal_machine::roll::RollStudy;

/// The figure's file name under `figures/`.
pub(crate) const FILE: &str = "roll.png";

/// The spec of the figure of `study`.
pub(crate) fn spec(campaign: &str, s: &RollStudy) -> report::SeriesPanelsFigure {
    let x: Vec<f64> = s.stations.iter().map(|st| st.x_mm).collect();
    let roll: Vec<f64> = s.stations.iter().map(|st| st.roll_urad).collect();
    let band = |sign: f64| -> Vec<f64> {
        s.stations
            .iter()
            .map(|st| st.roll_urad + sign * st.u_k2_urad)
            .collect()
    };
    let mut top = vec![
        report::NamedSeries {
            name: "εx (all passes)".into(),
            x: x.clone(),
            y: roll.clone(),
        },
        report::NamedSeries {
            name: "εx + U (k=2)".into(),
            x: x.clone(),
            y: band(1.0),
        },
        report::NamedSeries {
            name: "εx − U (k=2)".into(),
            x: x.clone(),
            y: band(-1.0),
        },
    ];
    let mut bottom = Vec::new();
    for (p, pass) in s.passes.iter().enumerate() {
        let px: Vec<f64> = pass.stations.iter().map(|&n| s.stations[n].x_mm).collect();
        let name = format!(
            "pass {} ({})",
            p + 1,
            if pass.direction > 0 { "out" } else { "back" }
        );
        top.push(report::NamedSeries {
            name: format!("{name}, eq. 10"),
            x: px.clone(),
            y: pass.roll_urad.clone(),
        });
        bottom.push(report::NamedSeries {
            name,
            x: px,
            y: pass
                .stations
                .iter()
                .zip(&pass.roll_urad)
                .map(|(&n, r)| r - s.stations[n].roll_urad)
                .collect(),
        });
    }
    let mut ref_lines = Vec::new();
    if let Some(i) = &s.implausible {
        for v in [i.limit_urad, -i.limit_urad] {
            ref_lines.push(report::RefLine {
                label: format!("plausible for a machine table: ±{:.0} µrad", i.limit_urad),
                value: v,
            });
        }
    }
    let last = s.stations.last();
    report::SeriesPanelsFigure {
        title: format!("Roll of the {} stage, campaign {campaign}", s.roll_error_name),
        subtitle: format!(
            "εx(n) by the four-probe estimator (seed eq. 10), datum εx = 0 at station 0; {} = {:+}·εx; εx({}) = {:.1} ± {:.1} µrad (U, k = 2){}",
            s.roll_error_name,
            s.roll_error_sign,
            last.map_or(0, |l| l.station),
            last.map_or(f64::NAN, |l| l.roll_urad),
            last.map_or(f64::NAN, |l| l.u_k2_urad),
            if s.level_datum {
                "; ramp removed by the end-level datum"
            } else {
                ""
            }
        ),
        x_axis: report::XAxis::Values {
            label: "stage position x (mm)".into(),
        },
        panels: vec![
            report::SeriesPanel {
                title: "εx(n)".into(),
                y_label: "εx (µrad)".into(),
                series: top,
                ref_lines,
            },
            report::SeriesPanel {
                title: "each pass minus all passes".into(),
                y_label: "Δεx (µrad)".into(),
                series: bottom,
                ref_lines: Vec::new(),
            },
        ],
    }
}

/// Draws the figure as one write step of the output (`crate::output::writing`).
pub(crate) fn draw(spec: &report::SeriesPanelsFigure, path: &Path) -> anyhow::Result<()> {
    let _step = crate::output::writing();
    report::render_series_panels(spec, path)?;
    Ok(())
}
