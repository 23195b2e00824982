//! Tests of the calibration / compensation / acceptance extensions: geometric map, sag, the
//! calibration phase over lengths and tilts, the reference/check/device layout, the mismatch knob,
//! and the shipped `sim-acceptance*.toml`.

use std::collections::BTreeSet;

use super::*;
use dbbcal_core::campaign::Purpose;
use dbbcal_io::manifest::TomlManifest;

/// A constant room at `mean_c`, no noise, 3 bars, a calibration phase over 3 lengths × `tilts`.
fn calibrating(mean_c: f64, tilts: &[f64]) -> SimConfig {
    let mut cfg = SimConfig {
        duration_days: 2.0,
        noise_um: 0.0,
        record_true_error: true,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    };
    let r = &mut cfg.room;
    r.mean_c = mean_c;
    (
        r.daily_amplitude_k,
        r.ac_amplitude_k,
        r.drift_k_per_day,
        r.wander_k,
    ) = (0.0, 0.0, 0.0, 0.0);
    (
        r.gradient_daily_k,
        r.gradient_ac_k,
        r.gradient_wander_k,
        r.sensor_noise_k,
    ) = (0.0, 0.0, 0.0, 0.0);
    cfg.schedule.calibration = Some(CalibrationPhase {
        tilts_deg: tilts.to_vec(),
        mount_hours: 2.0,
    });
    cfg.geometry = rough_geometry();
    cfg
}

fn rough_geometry() -> GeometryConfig {
    GeometryConfig {
        scale_ppm: 3.0,
        scale_sd_ppm: 1.0,
        nonlinearity_ppm_per_mm: 0.01,
        nonlinearity_sd_ppm_per_mm: 0.002,
        cosine_mrad: 1.5,
        cosine_sd_mrad: 0.5,
        zero_offset_um: 0.0,
        zero_offset_sd_um: 20.0,
        sag: SagConfig {
            amplitude_um: 1.0,
            spread: 0.2,
            ..SagConfig::default()
        },
    }
}

fn parse_ns(s: &str) -> i64 {
    chrono::DateTime::parse_from_rfc3339(s)
        .unwrap()
        .timestamp_nanos_opt()
        .unwrap()
}

/// (row, mount) for every encoder row of `bar` strictly inside one of its mounts.
fn mounted_rows<'a>(
    sim: &'a Simulation,
    bar: &'a str,
) -> impl Iterator<Item = (usize, &'a MountTruth)> + 'a {
    let log = &sim.tables.encoders[bar];
    sim.truth
        .mounts
        .iter()
        .filter(move |m| m.bar == bar)
        .flat_map(move |m| {
            let (from, to) = (parse_ns(&m.from), parse_ns(&m.to));
            log.time_ns
                .iter()
                .enumerate()
                .filter(move |(_, &t)| t > from && t < to)
                .map(move |(row, _)| (row, m))
        })
}

fn bar<'a>(truth: &'a Truth, id: &str) -> &'a BarTruth {
    truth.bars.iter().find(|b| b.id == id).unwrap()
}

#[test]
fn truth_map_reproduces_the_counts_written() {
    // Warm room: the map sends the counts to the true distance plus the thermal error.
    let sim = generate(&calibrating(21.0, &[30.0, 60.0, 90.0])).unwrap();
    for b in &sim.truth.bars {
        assert!(!b.geometry.is_ideal() && b.geometry.sag_um > 0.0);
        let log = &sim.tables.encoders[&b.id];
        let half_count_mm = 0.5 * b.resolution_nm * 1e-6 * 1.001;
        let mut n = 0;
        for (row, m) in mounted_rows(&sim, &b.id) {
            let indicated_mm = b.true_distance_mm(log.counts[row] as f64, m.tilt_deg);
            let expected_mm = m.length_mm + sim.true_error_um[&b.id][row] * 1e-3;
            assert!(
                (indicated_mm - expected_mm).abs() <= half_count_mm,
                "{} vs {expected_mm}",
                indicated_mm
            );
            n += 1;
        }
        assert!(n > 1000);
    }
}

#[test]
fn truth_map_at_t0_reads_the_zero_counts() {
    let sim = generate(&calibrating(20.0, &[30.0, 60.0, 90.0])).unwrap();
    for b in &sim.truth.bars {
        for (row, m) in mounted_rows(&sim, &b.id) {
            assert_eq!(
                sim.tables.encoders[&b.id].counts[row],
                m.zero_counts.round() as i64
            );
            assert!((b.true_distance_mm(m.zero_counts, m.tilt_deg) - m.length_mm).abs() < 1e-10);
        }
    }
}

#[test]
fn sag_reads_long_by_its_law_and_vanishes_vertical() {
    let mut cfg = calibrating(20.0, &[0.0, 30.0, 60.0, 90.0]);
    cfg.geometry = GeometryConfig {
        sag: SagConfig {
            amplitude_um: 2.0,
            spread: 0.0,
            ..SagConfig::default()
        },
        ..GeometryConfig::default()
    };
    for form in [SagForm::Cos, SagForm::Cos2] {
        cfg.geometry.sag.form = form;
        let truth = generate(&cfg).unwrap().truth;
        for m in &truth.mounts {
            let b = bar(&truth, &m.bar);
            let vertical = b.counts_at(m.length_mm, 90.0);
            let long_um = (m.zero_counts - vertical) * b.resolution_nm * 1e-3;
            let expected_um = 2.0 * form.factor(m.tilt_deg) * (m.length_mm / 400.0).powi(2);
            assert!(
                (long_um - expected_um).abs() < 1e-4,
                "{form:?} A={} L={}: {long_um} vs {expected_um}",
                m.tilt_deg,
                m.length_mm
            );
            assert!(long_um >= -1e-9, "sag makes the reading long");
        }
        let b = &truth.bars[0];
        assert!(b.geometry.sag_at_um(90.0, 400.0).abs() < 1e-12);
        assert!((b.geometry.sag_at_um(0.0, 400.0) - 2.0).abs() < 1e-12);
    }
}

#[test]
fn calibration_phase_covers_every_length_and_tilt() {
    let tilts = [30.0, 60.0, 90.0];
    let sim = generate(&calibrating(20.5, &tilts)).unwrap();
    let tilt_events: Vec<&Event> = sim
        .tables
        .events
        .iter()
        .filter(|e| e.kind.as_str() == "tilt")
        .collect();
    assert_eq!(
        tilt_events
            .iter()
            .map(|e| e.value.unwrap())
            .collect::<Vec<_>>(),
        vec![30.0, 60.0, 90.0, 60.0]
    );
    assert!(tilt_events.iter().all(|e| e.bar.is_none()));
    let manifest_tilts: BTreeSet<u64> = sim
        .manifest
        .mount
        .iter()
        .map(|m| m.tilt_deg.unwrap().to_bits())
        .collect();
    assert_eq!(manifest_tilts.len(), 3, "mounts carry tilt_deg");
    for b in &sim.truth.bars {
        let calibration: Vec<&MountTruth> = sim
            .truth
            .mounts
            .iter()
            .filter(|m| m.bar == b.id)
            .take(9)
            .collect();
        let pairs: BTreeSet<(String, u64)> = calibration
            .iter()
            .map(|m| (m.length.clone(), m.tilt_deg.to_bits()))
            .collect();
        assert_eq!(pairs.len(), 9, "{}: every (length, tilt) once", b.id);
        assert!(calibration
            .iter()
            .all(|m| m.purpose == Purpose::Calibration));
        // Re-tilts happen while the bar is off the plate.
        for e in &tilt_events {
            let on = sim
                .truth
                .mounts
                .iter()
                .filter(|m| m.bar == b.id)
                .any(|m| parse_ns(&m.from) <= e.time_ns && e.time_ns <= parse_ns(&m.to));
            assert!(!on, "{} mounted at a re-tilt", b.id);
        }
        // Each mount's tilt is the plate tilt in force (the last tilt event before it).
        for m in sim.truth.mounts.iter().filter(|m| m.bar == b.id) {
            let from = parse_ns(&m.from);
            let plate = tilt_events
                .iter()
                .rfind(|e| e.time_ns <= from)
                .unwrap()
                .value
                .unwrap();
            assert_eq!(plate, m.tilt_deg);
        }
    }
    let campaign = dbbcal_core::campaign::Campaign::from_manifest(sim.manifest.clone()).unwrap();
    assert_eq!(campaign.mounts.len(), sim.truth.mounts.len());
}

/// The acceptance layout: 5 bars, references B01 (min) and B02 (max), checks B03 and B04 on
/// mid, B05 on a device.
fn layout() -> SimConfig {
    let mut cfg = calibrating(20.5, &[30.0, 60.0, 90.0]);
    cfg.duration_days = 3.0;
    cfg.fleet = Some(FleetConfig {
        n_bars: 5,
        ..FleetConfig::default()
    });
    cfg.schedule.reference = vec![
        ReferenceMount {
            bar: "B01".into(),
            length: "min".into(),
        },
        ReferenceMount {
            bar: "B02".into(),
            length: "max".into(),
        },
    ];
    cfg.schedule.working = Some(WorkingLayout {
        length: "mid".into(),
        purpose: Purpose::Check,
        device: Some(DeviceLayout {
            id: "hexapod-1".into(),
            bars: vec!["B05".into()],
            distance_mm: 333.3,
            tilt_deg: 45.0,
            hexapod: None,
        }),
    });
    cfg
}

#[test]
fn reference_check_and_device_layout() {
    let sim = generate(&layout()).unwrap();
    let end = parse_ns(&sim.truth.config.start.to_rfc3339()) + 3 * 86_400_000_000_000;
    let last = |id: &str| {
        sim.truth
            .mounts
            .iter()
            .rfind(|m| m.bar == id)
            .unwrap()
            .clone()
    };
    for (id, length, purpose) in [
        ("B01", "min", Purpose::Reference),
        ("B02", "max", Purpose::Reference),
        ("B03", "mid", Purpose::Check),
        ("B04", "mid", Purpose::Check),
    ] {
        let m = last(id);
        assert_eq!(
            (m.length.as_str(), m.purpose, m.device.as_deref()),
            (length, purpose, None),
            "{id}"
        );
        assert_eq!(parse_ns(&m.to), end, "{id} stays to the end");
        assert_eq!(m.tilt_deg, 60.0, "plate tilt");
        assert_eq!(
            sim.truth.mounts.iter().filter(|m| m.bar == id).count(),
            10,
            "9 calibration mounts, then one"
        );
    }
    let d = last("B05");
    assert_eq!(
        (
            d.length.as_str(),
            d.device.as_deref(),
            d.length_mm,
            d.tilt_deg
        ),
        ("", Some("hexapod-1"), 333.3, 45.0)
    );
    let decl = sim.manifest.mount.iter().rfind(|m| m.bar == "B05").unwrap();
    assert_eq!(
        (decl.length.as_ref(), decl.device.as_deref()),
        (None, Some("hexapod-1"))
    );
    // The device reading is the truth map at the device distance (plus the thermal error).
    let b = bar(&sim.truth, "B05");
    for (row, m) in mounted_rows(&sim, "B05").filter(|(_, m)| m.device.is_some()) {
        let indicated = b.true_distance_mm(sim.tables.encoders["B05"].counts[row] as f64, 45.0);
        assert!((indicated - m.length_mm - sim.true_error_um["B05"][row] * 1e-3).abs() < 3e-6);
    }
    let campaign = dbbcal_core::campaign::Campaign::from_manifest(sim.manifest.clone()).unwrap();
    assert!(campaign
        .mounts
        .iter()
        .any(|m| matches!(&m.place, dbbcal_core::campaign::Place::Device(d) if d == "hexapod-1")));
    let text = sim.manifest.to_toml_string().unwrap();
    assert_eq!(
        dbbcal_core::campaign::Manifest::from_toml_str(&text, "campaign.toml").unwrap(),
        sim.manifest
    );
}

#[test]
fn mismatch_changes_only_that_bar() {
    let base = layout();
    let mut with = base.clone();
    with.mismatch = vec![Mismatch {
        bar: "B04".into(),
        alpha_factor: 1.5,
        beta_factor: 1.0,
        tau_r_factor: 2.0,
        tau_s_factor: 1.0,
        sag_factor: 1.0,
    }];
    let (a, b) = (generate(&base).unwrap(), generate(&with).unwrap());
    for (x, y) in a.truth.bars.iter().zip(&b.truth.bars) {
        if x.id == "B04" {
            assert!((y.alpha_ppm_per_k - 1.5 * x.alpha_ppm_per_k).abs() < 1e-12);
            assert!((y.tau_r_s - 2.0 * x.tau_r_s).abs() < 1e-9);
            assert_eq!(
                (y.beta_ppm_per_k, y.geometry),
                (x.beta_ppm_per_k, x.geometry)
            );
            assert!(y.mismatch.is_some() && x.mismatch.is_none());
            assert_ne!(a.tables.encoders["B04"], b.tables.encoders["B04"]);
        } else {
            assert_eq!(x, y);
            assert_eq!(a.tables.encoders[&x.id], b.tables.encoders[&x.id]);
        }
    }
    assert_eq!(a.manifest, b.manifest);
    assert_eq!(a.tables.temperatures, b.tables.temperatures);
}

#[test]
fn new_keys_are_validated() {
    let bad = |text: &str, key: &str| {
        let err = SimConfig::from_toml_str(text);
        assert!(
            matches!(&err, Err(SimError::Invalid { key: k, .. }) if k == key),
            "{text}: {err:?}"
        );
    };
    bad("[plate]\ntilt_deg = 120.0", "plate.tilt_deg");
    bad(
        "[schedule.calibration]\ntilts_deg = [30.0, -5.0]",
        "schedule.calibration.tilts_deg[1]",
    );
    bad(
        "[schedule.calibration]\ntilts_deg = []",
        "schedule.calibration.tilts_deg",
    );
    bad(
        "duration_days = 1.0\n[schedule.calibration]\nmount_hours = 3.0",
        "schedule.calibration",
    );
    bad(
        "[schedule.working]\nlength = \"huge\"",
        "schedule.working.length",
    );
    bad(
        "[schedule.working]\nlength = \"mid\"\npurpose = \"reference\"",
        "schedule.working.purpose",
    );
    bad("[geometry]\ncosine_mrad = 200.0", "geometry.cosine_mrad");
    bad("[geometry.sag]\nref_mm = 0.0", "geometry.sag.ref_mm");
    bad(
        "[[mismatch]]\nbar = \"B01\"\nalpha_factor = -1.0",
        "mismatch[0].alpha_factor",
    );
    let unknown = SimConfig::from_toml_str("[[mismatch]]\nbar = \"Z9\"").unwrap();
    assert!(
        matches!(generate(&unknown), Err(SimError::Invalid { key, .. }) if key == "mismatch[0].bar")
    );
    let form =
        SimConfig::from_toml_str("[geometry.sag]\namplitude_um = 1.0\nform = \"cos2\"").unwrap();
    assert_eq!(form.geometry.sag.form, SagForm::Cos2);
    let mut cfg = layout();
    cfg.geometry.sag.form = SagForm::Cos2;
    assert_eq!(
        SimConfig::from_toml_str(&toml::to_string(&cfg).unwrap()).unwrap(),
        cfg
    );
}

#[test]
fn neutral_defaults_leave_the_base_campaign_unchanged() {
    let cfg = SimConfig {
        duration_days: 1.0,
        ..SimConfig::default()
    };
    let sim = generate(&cfg).unwrap();
    for b in &sim.truth.bars {
        assert!(b.geometry.is_ideal() && b.mismatch.is_none());
        assert_eq!(b.d_zero_mm, b.fixed_length_mm);
    }
    assert!(sim.manifest.mount.iter().all(|m| m.tilt_deg.is_none()));
    assert!(!sim.tables.events.iter().any(|e| e.kind.as_str() == "tilt"));
}

/// Worst |thermal error of a check bar − two-reference interpolation| over the measurement
/// phase, mean removed (`docs/spec/physics.md`, two reference bars), noise-free.
fn worst_compensated_um(sim: &Simulation, check: &str) -> f64 {
    let at = |id: &str| -> std::collections::BTreeMap<i64, (f64, f64)> {
        let m = sim.truth.mounts.iter().rfind(|m| m.bar == id).unwrap();
        mounted_rows(sim, id)
            .filter(|(_, mm)| mm.from == m.from)
            .map(|(row, mm)| {
                (
                    sim.tables.encoders[id].time_ns[row],
                    (sim.true_error_um[id][row], mm.length_mm),
                )
            })
            .collect()
    };
    let (lo, hi, w) = (at("B01"), at("B02"), at(check));
    let residuals: Vec<f64> = w
        .iter()
        .filter_map(|(t, &(e, d))| {
            let (&(e0, d0), &(e1, d1)) = (lo.get(t)?, hi.get(t)?);
            Some(e - (e0 + (e1 - e0) * (d - d0) / (d1 - d0)))
        })
        .collect();
    let mean = residuals.iter().sum::<f64>() / residuals.len() as f64;
    residuals
        .iter()
        .map(|r| (r - mean).abs())
        .fold(0.0, f64::max)
}

fn shipped(name: &str) -> SimConfig {
    let path = dbbcal_testkit::repo_path("pipelines").join(name);
    SimConfig {
        record_true_error: true,
        ..SimConfig::load(&path).unwrap()
    }
}

#[test]
fn shipped_acceptance_configs_compensate_and_mismatch() {
    let good = generate(&shipped("sim-acceptance.toml")).unwrap();
    let checks: Vec<String> = good
        .truth
        .mounts
        .iter()
        .filter(|m| m.purpose == Purpose::Check)
        .map(|m| m.bar.clone())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    assert_eq!(checks, ["B03", "B04", "B05", "B06"]);
    for id in &checks {
        let worst = worst_compensated_um(&good, id);
        assert!(
            worst < 0.15,
            "{id}: {worst} µm after ideal two-reference compensation"
        );
    }
    let bad = generate(&shipped("sim-acceptance-mismatch.toml")).unwrap();
    let odd = bad
        .truth
        .bars
        .iter()
        .find(|b| b.mismatch.is_some())
        .unwrap();
    // ~0.43 µm with the shipped factors (peak-to-peak ~0.8 µm): beyond ±0.3 µm however zeroed.
    assert!(
        worst_compensated_um(&bad, &odd.id) > 0.35,
        "mismatched {}",
        odd.id
    );
    for id in checks.iter().filter(|id| **id != odd.id) {
        assert!(worst_compensated_um(&bad, id) < 0.15);
    }
}

#[test]
fn truth_written_before_the_geometry_fields_still_reads() {
    let path = dbbcal_testkit::repo_path("data/sample/truth.json");
    let text = std::fs::read_to_string(&path).expect("the shipped sample's truth.json");
    let truth: Truth = serde_json::from_str(&text).unwrap();
    assert!(truth
        .bars
        .iter()
        .all(|b| b.geometry.is_ideal() && b.mismatch.is_none()));
}
