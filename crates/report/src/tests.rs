//! Renders every figure from synthetic data: into a tempdir (checked: PNG of the expected size,
//! deterministic bytes) and into `/tmp/report-preview/` for a human look.

use std::path::{Path, PathBuf};

use super::*;

/// Deterministic noise in [-1, 1] (a hash, so tests need no RNG).
fn noise(i: usize) -> f64 {
    let mut x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x % 20_001) as f64 / 10_000.0 - 1.0
}

fn bars(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("B{i:02}")).collect()
}

fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).expect("figure written");
    assert_eq!(
        &bytes[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is not a PNG",
        path.display()
    );
    let be = |o: usize| u32::from_be_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    (be(16), be(20))
}

/// Renders into a tempdir and the preview folder; checks size and determinism.
fn check<S>(name: &str, spec: &S, render: fn(&S, &Path) -> Result<(), ReportError>) {
    let dir = tempfile::tempdir().expect("tempdir");
    let (a, b) = (dir.path().join("a.png"), dir.path().join("sub/b.png"));
    render(spec, &a).expect("render");
    render(spec, &b).expect("render again");
    assert_eq!(png_size(&a), (1600, 1000));
    assert_eq!(
        std::fs::read(&a).ok(),
        std::fs::read(&b).ok(),
        "{name}: not deterministic"
    );
    let preview = PathBuf::from("/tmp/report-preview").join(format!("{name}.png"));
    render(spec, &preview).expect("preview");
}

fn first_order(t: &[f64], temp: &[f64], tau: f64, gain: f64) -> Vec<f64> {
    let mut state = temp.first().copied().unwrap_or(0.0);
    let t0 = state;
    t.iter()
        .zip(temp)
        .enumerate()
        .map(|(k, (ti, ui))| {
            let dt = if k == 0 { 0.0 } else { ti - t[k - 1] };
            let a = (-dt / tau).exp();
            state = a * state + (1.0 - a) * ui;
            -gain * (state - t0)
        })
        .collect()
}

pub(super) fn bar_fit_spec(n: usize) -> BarFitFigure {
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 4.0).collect();
    let room: Vec<f64> = t
        .iter()
        .map(|s| {
            20.0 + 0.8 * (s / 86_400.0 * std::f64::consts::TAU).sin() + 0.1 * (s / 7200.0).sin()
        })
        .collect();
    let model = first_order(&t, &room, 1800.0, 3.2);
    let measured: Vec<f64> = model
        .iter()
        .enumerate()
        .map(|(i, m)| m + 0.08 * noise(i) + 0.05 * (t[i] / 20_000.0).sin())
        .collect();
    let head: Vec<f64> = room
        .iter()
        .enumerate()
        .map(|(i, r)| r + 1.5 + 0.02 * noise(i + 7))
        .collect();
    BarFitFigure {
        title: "Bar B03 — first-order thermal model".into(),
        subtitle: "alpha = 11.8 ± 0.4 ppm/K   beta = 0.52 ± 0.08 ppm/K   tau_R = 1820 ± 60 s   tau_S = 5400 ± 900 s".into(),
        measured_um: measured,
        model_um: model,
        temperatures_c: vec![
            NamedSeries { name: "room (T1)".into(), x: t.iter().step_by(15).copied().collect(), y: room.iter().step_by(15).copied().collect() },
            NamedSeries { name: "read head (T4)".into(), x: t.iter().step_by(15).copied().collect(), y: head.iter().step_by(15).copied().collect() },
        ],
        mount_boundaries_s: vec![1.5 * 86_400.0, 3.2 * 86_400.0],
        time_s: t,
        notes: Vec::new(),
        residual_points: String::new(),
    }
}

pub(super) fn fleet_spec(n: usize) -> FleetFigure {
    let names = bars(n);
    let param =
        |name: &str, unit: &str, base: f64, spread: f64, u: f64, seed: usize| ParameterPanel {
            name: name.into(),
            unit: unit.into(),
            values: (0..n).map(|i| base + spread * noise(seed + i)).collect(),
            u95: (0..n)
                .map(|i| u * (1.0 + 0.5 * noise(seed + 100 + i)))
                .collect(),
            fleet_mean: None,
        };
    FleetFigure {
        title: "Fleet thermal parameters".into(),
        subtitle: format!(
            "{n} bars, 95 % expanded uncertainties; reference = bar nearest the fleet mean"
        ),
        parameters: vec![
            param("alpha_ppm_per_k", "ppm/K", 11.5, 0.6, 0.3, 1),
            param("beta_ppm_per_k", "ppm/K", 0.5, 0.2, 0.08, 20),
            param("tau_r_s", "s", 1800.0, 250.0, 90.0, 40),
            param("tau_s_s", "s", 5400.0, 900.0, 600.0, 60),
        ],
        reference: Some(n / 2),
        mismatch_um: (0..n)
            .map(|i| {
                if i == n / 2 {
                    0.0
                } else {
                    1.1 * noise(300 + i) + 0.2
                }
            })
            .collect(),
        mismatch_limit_um: 1.0,
        bar_names: names,
    }
}

pub(super) fn heat_map_spec(n: usize) -> HeatMapFigure {
    let names = bars(n);
    let values = (0..n)
        .map(|r| {
            (0..n)
                .map(|c| {
                    if r == c {
                        f64::NAN
                    } else {
                        0.3 + 0.25 * (r as f64 - 3.0).abs() + 0.4 * noise(r * n + c).abs()
                    }
                })
                .collect()
        })
        .collect();
    HeatMapFigure {
        title: "Predicted peak mismatch: reference candidate vs other bar".into(),
        subtitle: "max |Δ thermal error| over the campaign temperature history".into(),
        row_labels: names.clone(),
        col_labels: names,
        row_axis_label: "candidate reference".into(),
        col_axis_label: "other bar".into(),
        values,
        unit: "mismatch (µm)".into(),
        highlights: vec![
            MatrixHighlight {
                label: "nearest the fleet mean: B04".into(),
                row: Some(3.min(n.saturating_sub(1))),
                col: None,
            },
            MatrixHighlight {
                label: "actual best: B03".into(),
                row: Some(2.min(n.saturating_sub(1))),
                col: None,
            },
        ],
    }
}

pub(super) fn ledger_spec() -> LedgerFigure {
    let steps = [
        "base",
        "+head_heating",
        "+sag_tilt",
        "+scale_lag",
        "+humidity",
    ]
    .map(String::from)
    .to_vec();
    let bars = (0..6)
        .map(|b| NamedValues {
            name: format!("B{:02}", b + 1),
            values: (0..5)
                .map(|s| {
                    (0.9 + 0.3 * noise(b * 9 + s).abs()) * 2.4 / (1.0 + 2.5 * s as f64).powf(0.9)
                        + 0.05
                })
                .collect(),
        })
        .collect::<Vec<_>>();
    let fleet = (0..5)
        .map(|s| {
            bars.iter()
                .map(|b| b.values[s] * b.values[s])
                .sum::<f64>()
                .sqrt()
                / 6f64.sqrt()
        })
        .collect();
    LedgerFigure {
        title: "Diagnostics ledger: RMS after each forward-selection step".into(),
        subtitle: "effects added in order of largest BIC improvement".into(),
        steps,
        bars,
        fleet_rms_um: fleet,
        noise_um: Some(0.06),
        log_y: true,
    }
}

pub(super) fn before_after_spec(n: usize) -> BeforeAfterFigure {
    BeforeAfterFigure {
        title: "Thermal error RMS before and after compensation".into(),
        subtitle: "working bars compensated with the reference bar".into(),
        bar_names: bars(n),
        before_um: (0..n).map(|i| 3.0 + noise(i)).collect(),
        after_um: (0..n).map(|i| 0.35 + 0.15 * noise(50 + i)).collect(),
        fleet_before_um: Some(3.1),
        fleet_after_um: Some(0.37),
        before_label: "raw".into(),
        after_label: "compensated".into(),
    }
}

pub(super) fn residuals_spec() -> ResidualDiagnosticsFigure {
    let acf: Vec<f64> = (0..400)
        .map(|k| (-(k as f64) / 40.0).exp() * (k as f64 / 25.0).cos() + 0.02 * noise(k))
        .collect();
    let m = 500;
    let freq: Vec<f64> = (1..=m)
        .map(|k| k as f64 / (2.0 * m as f64) / 60.0)
        .collect();
    let cp: Vec<f64> = (1..=m)
        .map(|k| 1.0 - (-(k as f64) / 30.0).exp() * 0.8 - 0.2 * (1.0 - k as f64 / m as f64))
        .collect();
    ResidualDiagnosticsFigure {
        title: "Bar B03 — residual diagnostics".into(),
        subtitle: "residual of the first-order model".into(),
        acf,
        lag_step_s: 60.0,
        n_samples: 7200,
        cpgram_freq_hz: freq,
        cpgram: cp,
        channels: [
            "room T1",
            "room T2",
            "read head T4",
            "plate T5",
            "humidity",
            "tilt",
        ]
        .map(String::from)
        .to_vec(),
        explained_fraction: vec![0.42, 0.05, 0.31, 0.02, 0.004, -0.01],
    }
}

pub(super) fn series_panels_spec() -> SeriesPanelsFigure {
    let t: Vec<f64> = (0..20_000).map(|i| i as f64 * 20.0).collect();
    let comp = |seed: usize, a: f64| {
        t.iter()
            .enumerate()
            .map(|(i, s)| a * (s / 30_000.0).sin() + 0.15 * noise(seed + i))
            .collect::<Vec<_>>()
    };
    let tol = |v: f64| RefLine {
        label: "tolerance ±1 µm".into(),
        value: v,
    };
    SeriesPanelsFigure {
        title: "Acceptance: compensated working bars".into(),
        subtitle: "reference B04".into(),
        x_axis: XAxis::TimeSeconds,
        panels: vec![
            SeriesPanel {
                title: "Compensated error".into(),
                y_label: "error (µm)".into(),
                series: vec![
                    NamedSeries {
                        name: "B01".into(),
                        x: t.clone(),
                        y: comp(1, 0.5),
                    },
                    NamedSeries {
                        name: "B02".into(),
                        x: t.clone(),
                        y: comp(90_000, 0.8),
                    },
                ],
                ref_lines: vec![tol(1.0), tol(-1.0)],
            },
            SeriesPanel {
                title: "Uncompensated error".into(),
                y_label: "error (µm)".into(),
                series: vec![NamedSeries {
                    name: "B01 raw".into(),
                    x: t.clone(),
                    y: comp(5, 4.0),
                }],
                ref_lines: vec![],
            },
            SeriesPanel {
                title: "Room temperature".into(),
                y_label: "temperature (°C)".into(),
                series: vec![NamedSeries {
                    name: "T1".into(),
                    x: t.clone(),
                    y: t.iter()
                        .map(|s| 20.0 + 0.5 * (s / 40_000.0).sin())
                        .collect(),
                }],
                ref_lines: vec![],
            },
        ],
    }
}

#[test]
fn bar_fit_renders() {
    check("bar_fit", &bar_fit_spec(110_000), render_bar_fit);
}

#[test]
fn fleet_renders() {
    check("fleet", &fleet_spec(8), render_fleet);
    // A bar left out of matching (NaN) and a parameter one bar's data cannot determine.
    let mut unmatched = fleet_spec(8);
    unmatched.mismatch_um[3] = f64::NAN;
    unmatched.parameters[1].values[3] = f64::NAN;
    check("fleet_unmatched", &unmatched, render_fleet);
    let mut bins = bar_fit_spec(2_000);
    bins.residual_points =
        "at the 60-s bins' two nodes, which scatter less than the readings".into();
    check("bar_fit_bins", &bins, render_bar_fit);
}

#[test]
fn heat_map_renders() {
    check("heat_map", &heat_map_spec(8), render_heat_map);
}

#[test]
fn ledger_renders() {
    check("ledger", &ledger_spec(), render_ledger);
}

#[test]
fn before_after_renders() {
    check("before_after", &before_after_spec(8), render_before_after);
}

#[test]
fn residual_diagnostics_renders() {
    check(
        "residual_diagnostics",
        &residuals_spec(),
        render_residual_diagnostics,
    );
}

#[test]
fn series_panels_renders() {
    check("series_panels", &series_panels_spec(), render_series_panels);
}

#[test]
fn degenerate_inputs_do_not_panic() {
    let mut bf = bar_fit_spec(50);
    bf.measured_um.iter_mut().for_each(|v| *v = 1.0);
    bf.model_um[3] = f64::NAN;
    check("degenerate_bar_fit_flat", &bf, render_bar_fit);
    check(
        "degenerate_bar_fit_empty",
        &BarFitFigure::default(),
        render_bar_fit,
    );
    check("degenerate_fleet_single", &fleet_spec(1), render_fleet);
    check(
        "degenerate_fleet_empty",
        &FleetFigure::default(),
        render_fleet,
    );
    check(
        "degenerate_heat_map_single",
        &heat_map_spec(1),
        render_heat_map,
    );
    check(
        "degenerate_heat_map_empty",
        &HeatMapFigure::default(),
        render_heat_map,
    );
    check(
        "degenerate_ledger_empty",
        &LedgerFigure {
            log_y: true,
            ..LedgerFigure::default()
        },
        render_ledger,
    );
    check(
        "degenerate_before_after_empty",
        &BeforeAfterFigure::default(),
        render_before_after,
    );
    check(
        "degenerate_residuals_empty",
        &ResidualDiagnosticsFigure::default(),
        render_residual_diagnostics,
    );
    check(
        "degenerate_series_panels_empty",
        &SeriesPanelsFigure::default(),
        render_series_panels,
    );
}

#[test]
fn many_bars_render() {
    check("many_bars_fleet", &fleet_spec(30), render_fleet);
    check("many_bars_heat_map", &heat_map_spec(24), render_heat_map);
    check(
        "many_bars_before_after",
        &before_after_spec(30),
        render_before_after,
    );
}

#[test]
fn inconsistent_spec_is_an_error_naming_the_path() {
    let mut spec = before_after_spec(3);
    spec.after_um.pop();
    let err = render_before_after(&spec, Path::new("/tmp/report-preview/never.png")).unwrap_err();
    assert!(matches!(err, ReportError::InvalidSpec { .. }));
    assert!(err.to_string().contains("never.png"), "{err}");
}

#[test]
fn a_polar_figure_draws_lobes_and_points() {
    let dir = tempfile::tempdir().unwrap();
    let path = std::env::var("DBBCAL_POLAR_PNG")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|_| dir.path().join("polar.png"));
    let phi: Vec<f64> = (0..24).map(|i| 15.0 * f64::from(i)).collect();
    let lobe: Vec<f64> = phi
        .iter()
        .map(|p| 0.3 / (60.0 - (p - 20.0).rem_euclid(120.0)).to_radians().cos())
        .collect();
    let spec = crate::PolarFigure {
        title: "pretravel by direction".into(),
        subtitle: "24 directions".into(),
        value_desc: "pretravel (µm)".into(),
        series: vec![
            crate::PolarSeries {
                name: "model".into(),
                angle_deg: phi.clone(),
                value: lobe.clone(),
                line: true,
            },
            crate::PolarSeries {
                name: "touch 1".into(),
                angle_deg: phi.clone(),
                value: lobe.iter().map(|v| v - 0.2).collect(),
                line: false,
            },
        ],
    };
    crate::render_polar(&spec, &path).unwrap();
    assert!(std::fs::metadata(&path).unwrap().len() > 10_000);
    let bad = crate::PolarFigure {
        series: vec![crate::PolarSeries {
            name: "x".into(),
            angle_deg: vec![0.0],
            value: vec![],
            line: false,
        }],
        ..spec
    };
    assert!(crate::render_polar(&bad, &path).is_err());
}
