//! The `axis` simulator: read back through the reader it reproduces the forward model exactly,
//! every compensation mode is honest, and each effect a model may miss leaves the signature
//! `docs/spec/machine-physics.md` ("Kind axis", the table of effects) states.

use super::*;
use dbbcal_core::axis_campaign::{AxisCampaignLogs, MachineAxis};

/// The default campaign without noise (effects as given).
fn quiet(effects: AxisEffects) -> AxisSimConfig {
    AxisSimConfig {
        effects,
        laser: AxisSimLaser {
            linear_noise_um: 0.0,
            straightness_noise_um: 0.0,
            ..AxisSimLaser::default()
        },
        ..AxisSimConfig::default()
    }
}

fn read_back(sim: &AxisSimulation, output: &AxisOutput) -> AxisCampaignLogs {
    let dir = tempfile::tempdir().unwrap();
    write_axis(sim, dir.path(), output, 7).unwrap();
    assert!(dir.path().join("truth/axis_truth.parquet").is_file());
    assert!(dir.path().join("truth.json").is_file());
    dbbcal_io::read_axis_campaign(dir.path()).unwrap()
}

/// The forward model from the truth alone: channel of Δ(p_l) since the line's datum, plus the
/// straightness optics' zero on lateral channels.
fn forward_um(truth: &AxisTruth, logs: &AxisCampaignLogs, r: &AxisReading) -> f64 {
    let line = truth.lines.iter().find(|l| l.id == r.line).unwrap();
    let f = logs.reflector_mm(r);
    let p: [f64; 3] = std::array::from_fn(|k| f[k] - logs.campaign.report_point_mm[k]);
    let k = r.channel.index();
    let delta = truth.displacement_um(r.target_mm, p)[k]
        - truth.displacement_um(line.datum_target_mm, p)[k];
    delta
        + line
            .optics_zero_um
            .get(r.channel.as_str())
            .copied()
            .unwrap_or(0.0)
}

#[test]
fn a_campaign_without_effects_reads_back_as_the_forward_model() {
    let cfg = AxisSimConfig::default();
    let sim = generate_axis(&cfg).unwrap();
    let logs = read_back(&sim, &cfg.output);
    assert_eq!(logs.readings, sim.tables.readings);
    // 3 lines (3 + 2 + 1 channels) × 5 runs × 2 directions × 15 targets.
    assert_eq!(logs.readings.len(), 6 * 5 * 2 * 15);
    let (mut along, mut lateral) = (Vec::new(), Vec::new());
    for (i, r) in logs.readings.iter().enumerate() {
        let clean = sim.noise_free_deviation_um[i];
        let model = forward_um(&sim.truth, &logs, r);
        assert!(
            (clean - model).abs() < 1e-9,
            "reading {i}: {clean} vs {model}"
        );
        let noise = r.deviation_um - clean;
        if r.channel == Channel::Dx {
            along.push(noise);
        } else {
            lateral.push(noise);
        }
    }
    let sd = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    assert!(
        (sd(&along) / 0.02 - 1.0).abs() < 0.15,
        "along noise {}",
        sd(&along)
    );
    assert!(
        (sd(&lateral) / 0.2 - 1.0).abs() < 0.15,
        "lateral noise {}",
        sd(&lateral)
    );
    // ISO 230-2: at least 5 runs each way, 10 to 20 targets.
    for line in [1, 2, 3] {
        for d in [1i8, -1] {
            let runs: std::collections::BTreeSet<i64> = logs
                .readings
                .iter()
                .filter(|r| r.line == line && r.direction == d)
                .map(|r| r.run)
                .collect();
            assert_eq!(runs.len(), 5);
        }
    }
    // Written without `direction`, shuffled and split: the reader derives the same directions.
    let output = AxisOutput {
        split_by_line: true,
        shuffle_rows: true,
        write_direction: false,
        write_fixture: true,
    };
    assert_eq!(read_back(&sim, &output).readings, sim.tables.readings);
}

#[test]
fn every_compensation_mode_gives_the_machine_back_after_an_honest_compensation() {
    for mode in [LaserCompensation::None, LaserCompensation::Air] {
        let mut cfg = quiet(AxisEffects::default());
        cfg.laser.compensation = mode;
        let sim = generate_axis(&cfg).unwrap();
        let logs = read_back(&sim, &cfg.output);
        assert_eq!(logs.campaign.compensation, mode);
        let alpha = logs.campaign.cte_ppm_per_k * 1e-6;
        let t0 = logs.campaign.reference_temperature_c;
        for r in logs.readings.iter().filter(|r| r.channel == Channel::Dx) {
            let env = logs.environment_at(r.time_ns).unwrap();
            assert_eq!(env.time_ns, r.time_ns);
            let n = edlen::refractive_index(
                cfg.laser.wavelength_nm,
                env.air_c,
                env.pressure_hpa,
                env.humidity_pct,
            );
            let commanded = r.target_mm - cfg.first_target_mm;
            let read_mm = commanded + 1e-3 * r.deviation_um;
            let air_mm = if mode == LaserCompensation::None {
                read_mm / n
            } else {
                read_mm
            };
            let machine_mm = air_mm / (1.0 + alpha * (env.material_c.unwrap() - t0));
            let deviation = 1e3 * (machine_mm - commanded);
            let model = forward_um(&sim.truth, &logs, r);
            assert!(
                (deviation - model).abs() < 1e-6,
                "{mode:?}: {deviation} vs {model}"
            );
        }
        if mode == LaserCompensation::None {
            // Uncompensated, the readings carry n − 1 ≈ 270 ppm: ~190 µm at 700 mm.
            let last = logs
                .readings
                .iter()
                .filter(|r| r.channel == Channel::Dx)
                .map(|r| r.deviation_um)
                .fold(0.0, f64::max);
            assert!(last > 150.0, "{last}");
        }
    }
}

/// Noise-free deviations with `effects` minus those without, with the readings.
fn effect_of(effects: AxisEffects) -> (AxisSimulation, Vec<f64>) {
    let base = generate_axis(&quiet(AxisEffects::default())).unwrap();
    let with = generate_axis(&quiet(effects)).unwrap();
    assert_eq!(base.tables.readings.len(), with.tables.readings.len());
    let diff = with
        .noise_free_deviation_um
        .iter()
        .zip(&base.noise_free_deviation_um)
        .map(|(a, b)| a - b)
        .collect();
    (with, diff)
}

/// Least-squares slope (per mm) and intercept of `y` against the commanded displacement, over
/// the readings `keep` selects.
fn fit_line(sim: &AxisSimulation, diff: &[f64], keep: impl Fn(&AxisReading) -> bool) -> (f64, f64) {
    let pts: Vec<(f64, f64)> = sim
        .tables
        .readings
        .iter()
        .zip(diff)
        .filter(|(r, _)| keep(r))
        .map(|(r, &d)| (r.target_mm, d))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let slope = sxy / sxx;
    (slope, my - slope * mx)
}

fn is_along(r: &AxisReading) -> bool {
    r.channel == Channel::Dx
}

#[test]
fn a_dead_path_is_constant_along_x_and_follows_the_air_since_the_datum() {
    let (sim, diff) = effect_of(AxisEffects {
        dead_path: Some(DeadPath {
            mm: 200.0,
            declared: true,
        }),
        ..AxisEffects::default()
    });
    assert_eq!(sim.manifest.laser.dead_path_mm, Some(200.0));
    let lambda = 632.990577;
    let n_at = |t: i64| {
        let e = sim
            .tables
            .environment
            .iter()
            .find(|e| e.time_ns == t)
            .unwrap();
        edlen::refractive_index(lambda, e.air_c, e.pressure_hpa, e.humidity_pct)
    };
    for (r, d) in sim.tables.readings.iter().zip(&diff) {
        if !is_along(r) {
            assert_eq!(*d, 0.0);
            continue;
        }
        let datum = sim
            .truth
            .lines
            .iter()
            .find(|l| l.id == r.line)
            .unwrap()
            .datum_time_ns;
        let e = sim
            .tables
            .environment
            .iter()
            .find(|e| e.time_ns == r.time_ns)
            .unwrap();
        let material = 1.0 + 11.5e-6 * (e.material_c.unwrap() - 20.0);
        let expected = 1e3 * 200.0 * (n_at(r.time_ns) - n_at(datum)) / n_at(r.time_ns) / material;
        assert!((d - expected).abs() < 1e-6, "{d} vs {expected}");
    }
    // Constant along x: within one pass it changes only as slowly as the air (< 0.05 µm), while
    // the air's drift over the campaign makes it grow run by run.
    let run1: Vec<f64> = sim
        .tables
        .readings
        .iter()
        .zip(&diff)
        .filter(|(r, _)| is_along(r) && r.line == 1 && r.run == 1 && r.direction == 1)
        .map(|(_, &d)| d)
        .collect();
    let spread = run1.iter().cloned().fold(f64::MIN, f64::max)
        - run1.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread < 0.05, "spread {spread}");
}

#[test]
fn an_air_sensor_error_is_proportional_to_the_reading_at_0_95_um_per_m_and_k() {
    let (sim, diff) = effect_of(AxisEffects {
        air_sensor: Some(SensorError {
            bias_c: 1.0,
            drift_c_per_h: 0.0,
        }),
        ..AxisEffects::default()
    });
    let (slope, intercept) = fit_line(&sim, &diff, is_along);
    // The sensor reads 1 K warm: n too low by ~0.95 ppm, readings too long by 0.95 µm/m.
    assert!((slope * 1e3 - 0.95).abs() < 0.02, "{} µm/m", slope * 1e3);
    assert!(intercept.abs() < 1e-3);
    assert!(diff
        .iter()
        .zip(&sim.tables.readings)
        .all(|(d, r)| is_along(r) || *d == 0.0));
}

#[test]
fn a_material_sensor_error_is_alpha_times_the_error_times_x() {
    let (sim, diff) = effect_of(AxisEffects {
        material_sensor: Some(SensorError {
            bias_c: 1.0,
            drift_c_per_h: 0.0,
        }),
        ..AxisEffects::default()
    });
    let (slope, _) = fit_line(&sim, &diff, is_along);
    // 1 K on steel (11.5 ppm/K): −11.5 µm/m (normalised as if 1 K warmer).
    assert!((slope * 1e3 + 11.5).abs() < 0.01, "{} µm/m", slope * 1e3);
}

#[test]
fn a_cosine_error_is_minus_half_theta_squared_times_x_per_line() {
    let (sim, diff) = effect_of(AxisEffects {
        cosine: Some(Cosine {
            mrad: vec![1.0, 2.0, 3.0],
        }),
        ..AxisEffects::default()
    });
    for (line, mrad) in [(1, 1.0f64), (2, 2.0), (3, 3.0)] {
        let (slope, intercept) = fit_line(&sim, &diff, |r| is_along(r) && r.line == line);
        let expected = -0.5 * (mrad * 1e-3).powi(2) * 1e3; // µm per mm
        assert!(
            (slope / expected - 1.0).abs() < 1e-3,
            "line {line}: {slope} vs {expected}"
        );
        // Zero at the datum; the true errors' own share, (cos θ − 1) · EXX, is nanometres.
        assert!(intercept.abs() < 1e-4, "line {line}: {intercept}");
    }
}

#[test]
fn an_optics_slope_is_a_line_in_the_lateral_channels_and_a_move_changes_it() {
    let (sim, diff) = effect_of(AxisEffects {
        optics_slope: Some(OpticsSlope {
            um_per_m: 5.0,
            moved_between_lines: true,
            moved_um_per_m: -3.0,
        }),
        ..AxisEffects::default()
    });
    for (line, channel, um_per_m) in [
        (1, Channel::Dy, 5.0),
        (1, Channel::Dz, 5.0),
        (2, Channel::Dy, -3.0),
    ] {
        let (slope, intercept) = fit_line(&sim, &diff, |r| r.line == line && r.channel == channel);
        assert!(
            (slope * 1e3 - um_per_m).abs() < 1e-9,
            "line {line} {channel}: {slope}"
        );
        assert!(intercept.abs() < 1e-9);
    }
    assert!(diff
        .iter()
        .zip(&sim.tables.readings)
        .all(|(d, r)| !is_along(r) || *d == 0.0));
}

#[test]
fn machine_drift_is_a_run_to_run_trend() {
    let (sim, diff) = effect_of(AxisEffects {
        drift: Some(MachineDrift {
            um_per_h: [2.0, 1.0, 0.0],
            tau_h: None,
        }),
        ..AxisEffects::default()
    });
    let run_mean = |line: i64, run: i64| {
        let v: Vec<f64> = sim
            .tables
            .readings
            .iter()
            .zip(&diff)
            .filter(|(r, _)| is_along(r) && r.line == line && r.run == run)
            .map(|(_, &d)| d)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let means: Vec<f64> = (1..=5).map(|run| run_mean(1, run)).collect();
    assert!(means.windows(2).all(|w| w[1] > w[0]), "{means:?}");
    // One run takes 30 targets × 6 s = 3 min: 2 µm/h × 0.05 h = 0.1 µm a run.
    let step = (means[4] - means[0]) / 4.0;
    assert!((step - 0.1).abs() < 0.001, "{step}");
}

#[test]
fn the_same_seed_gives_the_same_campaign_and_shapes_differ() {
    let a = generate_axis(&AxisSimConfig::default()).unwrap();
    let b = generate_axis(&AxisSimConfig::default()).unwrap();
    assert_eq!(a.tables, b.tables);
    let mut cfg = AxisSimConfig::default();
    cfg.errors.shape = ErrorShape::Polynomial;
    let poly = generate_axis(&cfg).unwrap();
    assert!(poly
        .truth
        .curves
        .iter()
        .all(|c| c.sines.iter().all(|s| s.amplitude == 0.0)));
    cfg.errors.shape = ErrorShape::Sinusoid;
    let sine = generate_axis(&cfg).unwrap();
    assert!(sine
        .truth
        .curves
        .iter()
        .all(|c| c.quadratic == 0.0 && c.cubic == 0.0));
    // Sizes within the spec's typical magnitudes (σ-scaled draws: a loose bound).
    let max = |k: usize| {
        a.truth
            .errors
            .iter()
            .map(|e| e[k].abs())
            .fold(0.0, f64::max)
    };
    assert!(
        max(0) < 30.0 && max(1) < 30.0 && max(4) < 150.0,
        "{:?}",
        (max(0), max(1), max(4))
    );
    // Every error is zero at the datum.
    assert!(a.truth.errors[0].iter().all(|e| e.abs() < 1e-12));
}

#[test]
fn a_y_axis_permutes_the_lines_and_the_names() {
    let cfg = AxisSimConfig {
        axis: MachineAxis::Y,
        ..AxisSimConfig::default()
    };
    let sim = generate_axis(&cfg).unwrap();
    assert_eq!(sim.truth.error_names[1], "EYY");
    let l2 = &sim.truth.lines[1];
    assert_eq!(l2.reflector_mm, [100.0, 0.0, 0.0]);
    assert_eq!(l2.channels, ["dy", "dz"]);
    assert_eq!(sim.truth.lines[2].reflector_mm, [100.0, 0.0, 100.0]);
}

#[test]
fn the_shipped_config_is_an_axis_config_and_bad_keys_are_named() {
    let text =
        std::fs::read_to_string(dbbcal_testkit::repo_path("pipelines/sim-axis.toml")).unwrap();
    assert!(is_axis_config(&text).unwrap());
    let cfg: AxisSimConfig = toml::from_str(&text).unwrap();
    cfg.validate().unwrap();
    assert!(!is_axis_config("seed = 1\n").unwrap());
    let e = is_axis_config("kind = \"probe\"\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("`kind`"), "{e}");
    let bad = AxisSimConfig {
        targets: 1,
        ..AxisSimConfig::default()
    };
    assert!(bad
        .validate()
        .unwrap_err()
        .to_string()
        .contains("`targets`"));
    let e =
        toml::from_str::<AxisSimConfig>("kind = \"axis\"\n[effects.dead_path]\nmm = 1\nfoo = 2\n")
            .unwrap_err();
    assert!(e.to_string().contains("foo"));
}

/// The two independent implementations (this simulator's and `dbbcal-machine`'s, the analysis'):
/// the same n at every environment row, and the analysis' normalisation of the simulated
/// readings gives the forward model back in every mode, with a declared dead path.
#[test]
fn the_analysis_edlen_and_normalisation_give_the_simulated_machine_back() {
    use dbbcal_machine::edlen::{self as other, Compensation, LaserSetup, ReadingConditions};
    // The analysis takes the dead-path term to first order, L_dead (n(t) − n(t_datum)); the
    // simulator counts the optical path, which after air compensation carries it divided by
    // n(t): they differ by L_dead Δn (n − 1), 300 mm × ~0.2 ppm × 2.7e-4 ≈ 1.5e-5 µm here
    // (measured: 1.4e-5 µm in every mode).
    let cases = [(None, 1e-8), (Some(300.0), 1e-4)];
    for ((dead_mm, bound), mode) in cases
        .into_iter()
        .flat_map(|c| ["none", "air", "air+material"].map(move |m| (c, m)))
    {
        let mut cfg = quiet(AxisEffects {
            dead_path: dead_mm.map(|mm| DeadPath { mm, declared: true }),
            ..AxisEffects::default()
        });
        cfg.laser.compensation = match mode {
            "none" => LaserCompensation::None,
            "air" => LaserCompensation::Air,
            _ => LaserCompensation::AirMaterial,
        };
        let sim = generate_axis(&cfg).unwrap();
        let logs = read_back(&sim, &cfg.output);
        let c = &logs.campaign;
        let setup = LaserSetup {
            wavelength_nm: c.wavelength_nm,
            compensation: mode.parse::<Compensation>().unwrap(),
            dead_path_mm: c.dead_path_mm,
            cte_ppm_per_k: c.cte_ppm_per_k,
            reference_temperature_c: c.reference_temperature_c,
        };
        let air = |t: i64| {
            let e = logs.environment_at(t).unwrap();
            other::Air {
                temperature_c: e.air_c,
                pressure_hpa: e.pressure_hpa,
                humidity_pct: e.humidity_pct,
            }
        };
        for e in &logs.environment {
            let mine =
                edlen::refractive_index(c.wavelength_nm, e.air_c, e.pressure_hpa, e.humidity_pct);
            let theirs = other::refractive_index(&air(e.time_ns), c.wavelength_nm).unwrap();
            assert!((mine - theirs).abs() < 1e-15, "{mine} vs {theirs}");
        }
        let mut worst = 0.0f64;
        for r in logs.readings.iter().filter(|r| is_along(r)) {
            let line = sim.truth.lines.iter().find(|l| l.id == r.line).unwrap();
            let at = ReadingConditions {
                air: Some(air(r.time_ns)),
                datum_air: Some(air(line.datum_time_ns)),
                material_c: logs.environment_at(r.time_ns).unwrap().material_c,
            };
            let commanded = r.target_mm - line.datum_target_mm;
            let reading = commanded + 1e-3 * r.deviation_um;
            let machine = other::normalise_reading_mm(reading, &setup, &at).unwrap();
            let deviation = 1e3 * (machine - commanded);
            worst = worst.max((deviation - forward_um(&sim.truth, &logs, r)).abs());
        }
        assert!(worst < bound, "{mode}, dead path {dead_mm:?}: {worst} µm");
    }
}
