//! Whole-simulation tests: determinism, units and sign of the base model, each effect switch,
//! quantization, schedule, configuration parsing.

use std::collections::BTreeMap;

use super::*;
use dbbcal_core::campaign::Manifest;
use dbbcal_io::manifest::TomlManifest;

/// A small campaign in a constant room at `mean_c` (no noise), recording the true error.
fn quiet(mean_c: f64) -> SimConfig {
    SimConfig {
        duration_days: 2.0,
        noise_um: 0.0,
        record_true_error: true,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        room: RoomConfig {
            mean_c,
            daily_amplitude_k: 0.0,
            ac_amplitude_k: 0.0,
            drift_k_per_day: 0.0,
            wander_k: 0.0,
            door_rate_per_day: 0.0,
            gradient_daily_k: 0.0,
            gradient_ac_k: 0.0,
            gradient_wander_k: 0.0,
            sensor_noise_k: 0.0,
            ..RoomConfig::default()
        },
        ..SimConfig::default()
    }
}

/// A lively room with doors, for the dynamic effects.
fn lively() -> SimConfig {
    SimConfig {
        duration_days: 2.0,
        noise_um: 0.0,
        record_true_error: true,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        room: RoomConfig {
            door_rate_per_day: 6.0,
            ..RoomConfig::default()
        },
        ..SimConfig::default()
    }
}

/// Per bar: time -> true error (µm).
fn errors_by_time(sim: &Simulation) -> BTreeMap<String, BTreeMap<i64, f64>> {
    sim.tables
        .encoders
        .iter()
        .map(|(id, log)| {
            let errors = &sim.true_error_um[id];
            (
                id.clone(),
                log.time_ns
                    .iter()
                    .copied()
                    .zip(errors.iter().copied())
                    .collect(),
            )
        })
        .collect()
}

/// Per bar: (time, error with effect − error without) for the rows both have.
fn effect_delta(base: &SimConfig, with: &SimConfig) -> BTreeMap<String, Vec<(i64, f64)>> {
    let off = errors_by_time(&generate(base).unwrap());
    let on = errors_by_time(&generate(with).unwrap());
    on.iter()
        .map(|(id, rows)| {
            let deltas = rows
                .iter()
                .filter_map(|(t, e)| off[id].get(t).map(|e0| (*t, e - e0)))
                .collect();
            (id.clone(), deltas)
        })
        .collect()
}

fn mounted_rows<'a>(
    sim: &'a Simulation,
    bar: &'a str,
) -> impl Iterator<Item = (usize, &'a MountTruth)> + 'a {
    let log = &sim.tables.encoders[bar];
    let mounts: Vec<(i64, i64, &MountTruth)> = sim
        .truth
        .mounts
        .iter()
        .filter(|m| m.bar == bar)
        .map(|m| (parse_ns(&m.from), parse_ns(&m.to), m))
        .collect();
    log.time_ns.iter().enumerate().filter_map(move |(row, t)| {
        mounts
            .iter()
            .find(|(from, to, _)| from <= t && t <= to)
            .map(|(_, _, m)| (row, *m))
    })
}

fn parse_ns(rfc3339: &str) -> i64 {
    chrono::DateTime::parse_from_rfc3339(rfc3339)
        .unwrap()
        .timestamp_nanos_opt()
        .unwrap()
}

#[test]
fn same_seed_same_campaign_other_seed_other_data() {
    let cfg = lively();
    let (a, b) = (generate(&cfg).unwrap(), generate(&cfg).unwrap());
    assert_eq!(a.manifest, b.manifest);
    assert_eq!(a.truth, b.truth);
    assert_eq!(a.tables.encoders, b.tables.encoders);
    assert_eq!(a.tables.temperatures, b.tables.temperatures);
    assert_eq!(a.tables.events, b.tables.events);
    let c = generate(&SimConfig { seed: 2, ..cfg }).unwrap();
    assert_ne!(a.tables.temperatures, c.tables.temperatures);
    assert_ne!(a.truth.bars, c.truth.bars);
}

#[test]
fn constant_room_at_t0_reads_the_plate_lengths() {
    let mut cfg = quiet(20.0);
    cfg.resolution_nm = 50.0;
    let sim = generate(&cfg).unwrap();
    for bar in &sim.truth.bars {
        let log = &sim.tables.encoders[&bar.id];
        let mut n = 0;
        for (row, mount) in mounted_rows(&sim, &bar.id) {
            assert_eq!(
                log.counts[row],
                mount.zero_counts.round() as i64,
                "quantized to the nearest count"
            );
            n += 1;
        }
        assert!(n > 1000);
    }
}

#[test]
fn warm_room_reads_short_by_alpha_and_beta() {
    // 1 K above T0 since the start (states in equilibrium): e = -(alpha I_min + beta I_p) * 1e-3 µm.
    let sim = generate(&quiet(21.0)).unwrap();
    for bar in &sim.truth.bars {
        let errors = &sim.true_error_um[&bar.id];
        let log = &sim.tables.encoders[&bar.id];
        for (row, mount) in mounted_rows(&sim, &bar.id) {
            let travel_mm = mount.length_mm - bar.fixed_length_mm;
            let expected = -(bar.alpha_ppm_per_k * bar.fixed_length_mm
                + bar.beta_ppm_per_k * travel_mm)
                * 1e-3;
            assert!(
                (errors[row] - expected).abs() < 1e-9,
                "{} vs {expected}",
                errors[row]
            );
            let counts = mount.zero_counts + expected * 1e3 / bar.resolution_nm;
            assert!((log.counts[row] as f64 - counts).abs() <= 0.5 + 1e-6);
        }
        assert!(
            errors.iter().all(|e| *e < -0.4),
            "the reading falls when warm"
        );
    }
}

#[test]
fn handling_gaps_are_logged_off_socket() {
    let sim = generate(&quiet(20.0)).unwrap();
    let lengths: Vec<&MountTruth> = sim.truth.mounts.iter().collect();
    for bar in &sim.truth.bars {
        let log = &sim.tables.encoders[&bar.id];
        let mounted: Vec<usize> = mounted_rows(&sim, &bar.id).map(|(row, _)| row).collect();
        assert!(
            mounted.len() < log.counts.len(),
            "some rows outside the mounts"
        );
        let mut in_mount = vec![false; log.counts.len()];
        mounted.iter().for_each(|&r| in_mount[r] = true);
        let zeros: Vec<f64> = lengths
            .iter()
            .filter(|m| m.bar == bar.id)
            .map(|m| m.zero_counts)
            .collect();
        for (row, _) in in_mount.iter().enumerate().filter(|(_, m)| !**m) {
            let c = log.counts[row] as f64;
            assert!(
                zeros.iter().all(|z| (c - z).abs() > 100.0),
                "gap reading off every socket"
            );
        }
        let used: std::collections::BTreeSet<&str> = sim
            .truth
            .mounts
            .iter()
            .filter(|m| m.bar == bar.id)
            .map(|m| m.length.as_str())
            .collect();
        assert!(
            used.len() >= 2,
            "rotates over the plate lengths (all three over 3+ days)"
        );
    }
    assert!(sim
        .tables
        .events
        .iter()
        .any(|e| e.kind.as_str() == "handling"));
}

#[test]
fn creep_adds_its_rate_times_time() {
    let base = quiet(20.5);
    let mut with = base.clone();
    with.effects.creep.enabled = true;
    let truth = generate(&with).unwrap().truth;
    let start = parse_ns(&truth.config.start.to_rfc3339());
    for (id, deltas) in effect_delta(&base, &with) {
        let rate = truth
            .bars
            .iter()
            .find(|b| b.id == id)
            .unwrap()
            .creep_um_per_day
            .unwrap();
        for (t, d) in deltas {
            let days = (t - start) as f64 * 1e-9 / 86400.0;
            assert!((d - rate * days).abs() < 1e-9);
        }
    }
}

#[test]
fn second_path_adds_its_gain_at_steady_state() {
    let base = quiet(21.0);
    let mut with = base.clone();
    with.effects.second_path.enabled = true;
    let truth = generate(&with).unwrap().truth;
    for (id, deltas) in effect_delta(&base, &with) {
        let bar = truth.bars.iter().find(|b| b.id == id).unwrap();
        let expected =
            -bar.second_path.as_ref().unwrap().gain_ppm_per_k * bar.fixed_length_mm * 1e-3;
        assert!(deltas.iter().all(|(_, d)| (d - expected).abs() < 1e-9));
    }
}

#[test]
fn sensor_gradient_shifts_the_seen_temperature() {
    let base = quiet(20.0);
    let mut with = base.clone();
    with.effects.sensor_gradient.enabled = true;
    let sim = generate(&with).unwrap();
    let w = with.effects.sensor_gradient.weight_t2;
    let dt_k = w * with.room.gradient_k;
    let errors = errors_by_time(&generate(&base).unwrap());
    for bar in &sim.truth.bars {
        for (row, mount) in mounted_rows(&sim, &bar.id) {
            let travel = mount.length_mm - bar.fixed_length_mm;
            let expected = -(bar.alpha_ppm_per_k * bar.fixed_length_mm
                + bar.beta_ppm_per_k * travel)
                * 1e-3
                * dt_k;
            let t = sim.tables.encoders[&bar.id].time_ns[row];
            let delta = sim.true_error_um[&bar.id][row] - errors[&bar.id][&t];
            assert!((delta - expected).abs() < 1e-9, "{delta} vs {expected}");
        }
    }
}

#[test]
fn settling_starts_at_the_mount_amplitude_and_decays() {
    let base = quiet(20.0);
    let mut with = base.clone();
    with.effects.settling.enabled = true;
    let sim = generate(&with).unwrap();
    let tau_s = with.effects.settling.tau_s;
    for mount in &sim.truth.mounts {
        let a = mount.settling_um.unwrap();
        assert!((0.5..=1.5).contains(&a));
        let log = &sim.tables.encoders[&mount.bar];
        let from = parse_ns(&mount.from);
        let row = log.time_ns.iter().position(|&t| t >= from).unwrap();
        let dt_s = (log.time_ns[row] - from) as f64 * 1e-9;
        let expected = a * (-dt_s / tau_s).exp();
        assert!((sim.true_error_um[&mount.bar][row] - expected).abs() < 1e-9);
    }
}

#[test]
fn plate_expansion_moves_the_true_distance_and_logs_the_plate() {
    let base = quiet(21.0);
    let mut with = base.clone();
    with.effects.plate_expansion.enabled = true;
    let (off, on) = (generate(&base).unwrap(), generate(&with).unwrap());
    assert!(
        on.tables.temperatures.contains_key(PLATE) && !off.tables.temperatures.contains_key(PLATE)
    );
    assert_eq!(on.truth.plate.declared_cte_ppm_per_k, 0.0);
    let cte = with.effects.plate_expansion.cte_ppm_per_k;
    for bar in &on.truth.bars {
        for (row, mount) in mounted_rows(&on, &bar.id) {
            // L [mm] * cte [ppm/K] * 1 K = L * cte nm.
            let expected = mount.length_mm * cte / bar.resolution_nm;
            let delta = (on.tables.encoders[&bar.id].counts[row]
                - off.tables.encoders[&bar.id].counts[row]) as f64;
            assert!((delta - expected).abs() <= 1.0, "{delta} vs {expected}");
        }
    }
}

#[test]
fn head_heating_lowers_the_reading_by_up_to_its_amplitude() {
    let base = lively();
    let mut with = base.clone();
    with.effects.head_heating.enabled = true;
    let sim = generate(&with).unwrap();
    assert!(sim
        .tables
        .events
        .iter()
        .any(|e| e.kind.as_str() == "head_power" && e.value == Some(1.0)));
    for (id, deltas) in effect_delta(&base, &with) {
        let head = sim
            .truth
            .bars
            .iter()
            .find(|b| b.id == id)
            .unwrap()
            .head_heating
            .clone()
            .unwrap();
        let deepest = deltas.iter().map(|(_, d)| *d).fold(0.0, f64::min);
        assert!(deltas.iter().all(|(_, d)| *d <= 1e-12), "reading falls");
        assert!(
            -deepest <= head.amplitude_um && -deepest > 0.9 * head.amplitude_um,
            "{deepest} vs {head:?}"
        );
        // First-order rise after power-on at the start.
        let start = deltas[0].0;
        let (t, d) = deltas
            .iter()
            .find(|(t, _)| (t - start) as f64 * 1e-9 >= head.tau_s)
            .unwrap();
        let expected =
            -head.amplitude_um * (1.0 - (-((t - start) as f64 * 1e-9) / head.tau_s).exp());
        assert!((d - expected).abs() < 1e-9, "{d} vs {expected}");
    }
}

/// Heads powered at the start (warm, or switched on cold with no event) and switched off once a
/// day for 1.5-4 h: each bar's first `head_power` event is an "off", no encoder row is logged
/// while a head is off, and the reading starts at the head's full growth (warm) or at none
/// (cold).
#[test]
fn heads_powered_at_the_start_are_switched_off_once_a_day() {
    let base = SimConfig {
        duration_days: 3.0,
        ..lively()
    };
    for start in [HeadStart::PoweredWarm, HeadStart::PoweredCold] {
        let mut with = base.clone();
        let h = &mut with.effects.head_heating;
        h.enabled = true;
        h.start = start;
        h.schedule = HeadSchedule::Daily;
        let sim = generate(&with).unwrap();
        let deltas = effect_delta(&base, &with);
        for bar in &sim.truth.bars {
            let head = bar.head_heating.clone().unwrap();
            let power: Vec<(i64, f64)> = sim
                .tables
                .events
                .iter()
                .filter(|e| e.kind.as_str() == "head_power" && e.bar.as_deref() == Some(&bar.id))
                .map(|e| (e.time_ns, e.value.unwrap()))
                .collect();
            // Off, on, off, on, ...: one off a day, 1.5-4 h long.
            assert_eq!(power.len(), 6, "{start:?} {}: {power:?}", bar.id);
            for (k, pair) in power.chunks(2).enumerate() {
                assert_eq!((pair[0].1, pair[1].1), (0.0, 1.0));
                let off_h = (pair[1].0 - pair[0].0) as f64 / 3.6e12;
                assert!((1.5..=4.0).contains(&off_h), "{off_h} h");
                let start_ns = with.start.timestamp_nanos_opt().unwrap();
                let day = (pair[0].0 - start_ns) as f64 / 8.64e13;
                assert!(
                    day >= k as f64 && day < k as f64 + 1.0,
                    "off {k} on day {day}"
                );
            }
            // No encoder rows while the head is off.
            let log = &sim.tables.encoders[&bar.id];
            for pair in power.chunks(2) {
                assert!(!log
                    .time_ns
                    .iter()
                    .any(|t| *t >= pair[0].0 && *t < pair[1].0));
            }
            // The head's growth at the first reading: all of it when warm, none when cold.
            let d = &deltas[&bar.id];
            let expected = match start {
                HeadStart::PoweredWarm => -head.amplitude_um,
                _ => 0.0,
            };
            assert!(
                (d[0].1 - expected).abs() < 1e-9,
                "{start:?}: {} vs {expected}",
                d[0].1
            );
            let deepest = d.iter().map(|(_, d)| *d).fold(0.0, f64::min);
            assert!(-deepest <= head.amplitude_um + 1e-12);
        }
    }
}

#[test]
fn hidden_channel_drives_the_bars_and_is_logged_as_other() {
    let base = lively();
    let mut with = base.clone();
    with.effects.hidden_channel.enabled = true;
    let sim = generate(&with).unwrap();
    let h = &with.effects.hidden_channel;
    let decl = sim
        .manifest
        .sensor
        .iter()
        .find(|s| s.id == h.sensor_id)
        .unwrap();
    assert_eq!(decl.kind, dbbcal_core::campaign::SensorKind::Other);
    let off = generate(&base).unwrap();
    assert_eq!(
        off.tables.temperatures[AIR_LOW], sim.tables.temperatures[AIR_LOW],
        "other channels untouched"
    );
    for (id, deltas) in effect_delta(&base, &with) {
        let c = sim
            .truth
            .bars
            .iter()
            .find(|b| b.id == id)
            .unwrap()
            .hidden_channel
            .clone()
            .unwrap();
        let deepest = deltas.iter().map(|(_, d)| *d).fold(0.0, f64::min);
        assert!(deltas.iter().all(|(_, d)| *d <= 1e-12));
        assert!(
            -deepest <= c.gain_um_per_k * h.amplitude_k
                && -deepest > 0.2 * c.gain_um_per_k * h.amplitude_k
        );
    }
}

#[test]
fn a_heat_source_runs_on_working_days_and_heats_the_bars_through_both_lengths() {
    // 2026-11-01 is a Sunday: the cabinet is off the first day, on from 08:00 to 18:00 Monday.
    let base = lively();
    let mut with = base.clone();
    with.effects.heat_source.enabled = true;
    let sim = generate(&with).unwrap();
    let h = &with.effects.heat_source;
    let decl = sim
        .manifest
        .sensor
        .iter()
        .find(|s| s.id == h.sensor_id)
        .unwrap();
    assert_eq!(decl.kind, dbbcal_core::campaign::SensorKind::Other);
    let off = generate(&base).unwrap();
    assert_eq!(
        off.tables.temperatures[AIR_LOW], sim.tables.temperatures[AIR_LOW],
        "other channels untouched"
    );
    assert!(off.truth.bars.iter().all(|b| b.heat_source.is_none()));
    // The cabinet reads T1 plus its excess: nothing on Sunday, up to `excess_k` on Monday.
    let cabinet = &sim.tables.temperatures[h.sensor_id.as_str()];
    let t1 = &sim.tables.temperatures[AIR_LOW];
    let start_ns = sim.tables.encoders.values().next().unwrap().time_ns[0];
    let mut sunday_max: f64 = 0.0;
    let mut monday_max: f64 = 0.0;
    for (k, (t, c)) in cabinet.time_ns.iter().zip(&cabinet.celsius).enumerate() {
        let excess = c - t1.celsius[k];
        let hours = (t - start_ns) as f64 / 3.6e12;
        if hours < 24.0 {
            sunday_max = sunday_max.max(excess.abs());
        } else if hours < 48.0 {
            monday_max = monday_max.max(excess);
        }
    }
    assert!(sunday_max < 0.1, "Sunday {sunday_max}");
    assert!(
        monday_max > 0.8 * h.excess_k && monday_max < h.excess_k + 0.1,
        "Monday {monday_max}"
    );
    let longest_mm = with.plate.length.iter().map(|l| l.mm).fold(0.0, f64::max);
    for (id, deltas) in effect_delta(&base, &with) {
        let bar = sim.truth.bars.iter().find(|b| b.id == id).unwrap();
        let heat = bar.heat_source.clone().unwrap();
        let largest_ppm_mm = heat.fixed_ppm_per_k * bar.fixed_length_mm
            + heat.scale_ppm_per_k * (longest_mm - bar.fixed_length_mm);
        let deepest = deltas.iter().map(|(_, d)| *d).fold(0.0, f64::min);
        assert!(
            deltas.iter().all(|(_, d)| *d <= 1e-12),
            "the bar grows: the reading falls"
        );
        assert!(
            -deepest <= largest_ppm_mm * h.excess_k * 1e-3
                && -deepest > 0.2 * heat.fixed_ppm_per_k * bar.fixed_length_mm * h.excess_k * 1e-3,
            "{id}: {deepest}"
        );
    }
}

#[test]
fn doors_are_events_and_bump_the_air() {
    let sim = generate(&lively()).unwrap();
    let doors: Vec<&Event> = sim
        .tables
        .events
        .iter()
        .filter(|e| e.kind.as_str() == "door")
        .collect();
    assert!(!doors.is_empty() && doors.iter().all(|e| e.bar.is_none()));
    assert_eq!(doors.len(), sim.truth.n_door_events);
}

/// Programmed set-point steps: the air starts on the high set point and settles to the other
/// one first-order (the loop's `setpoint_settle_s`) after every half period.
#[test]
fn setpoint_steps_move_the_air_between_two_levels() {
    let mut cfg = quiet(20.0);
    cfg.room.setpoint_step_k = 1.0;
    cfg.room.setpoint_half_period_s = 6.0 * 3600.0;
    cfg.room.setpoint_settle_s = 300.0;
    let grid = Grid::new(&cfg).unwrap();
    let env = Environment::build(&cfg, &grid);
    let at = |t_s: f64| env.t1_c[(t_s / grid.step_s).round() as usize] - 20.0;
    assert!((at(0.0) - 0.5).abs() < 1e-12);
    assert!((at(6.0 * 3600.0 - 1.0) - 0.5).abs() < 1e-9);
    // One settle time after the first step: 1 - 1/e of the way down.
    let one_tau = 0.5 - (1.0 - (-1.0f64).exp());
    assert!(
        (at(6.0 * 3600.0 + 300.0) - one_tau).abs() < 2e-3,
        "{}",
        at(6.0 * 3600.0 + 300.0)
    );
    assert!((at(12.0 * 3600.0 - 1.0) + 0.5).abs() < 1e-9);
    assert!((at(18.0 * 3600.0 - 1.0) - 0.5).abs() < 1e-9);
    // Both air levels step together.
    assert!(env
        .t1_c
        .iter()
        .zip(&env.t2_c)
        .all(|(low, high)| (high - low - cfg.room.gradient_k).abs() < 1e-12));
}

#[test]
fn config_round_trips_and_rejects_bad_input() {
    let cfg = SimConfig::default();
    let text = toml::to_string(&cfg).unwrap();
    assert_eq!(SimConfig::from_toml_str(&text).unwrap(), cfg);
    assert_eq!(SimConfig::from_toml_str("").unwrap(), cfg);
    let native = SimConfig::from_toml_str("start = 2026-12-01T06:00:00Z").unwrap();
    assert_eq!(native.start.to_rfc3339(), "2026-12-01T06:00:00+00:00");
    assert!(matches!(
        SimConfig::from_toml_str("bogus = 1"),
        Err(SimError::Toml(_))
    ));
    let bad = SimConfig::from_toml_str(
        "[effects.head_heating]\nschedule = \"daily\"\ndaily_off_h = [4.0, 1.5]",
    );
    assert!(
        matches!(bad, Err(SimError::Invalid { ref key, .. }) if key == "effects.head_heating.daily_off_h"),
        "{bad:?}"
    );
    let good = SimConfig::from_toml_str(
        "[effects.head_heating]\nenabled = true\nstart = \"powered_warm\"\nschedule = \"daily\"",
    )
    .unwrap();
    assert_eq!(good.effects.head_heating.start, HeadStart::PoweredWarm);
    let bad = SimConfig::from_toml_str("[effects.head_heating]\nenabled = true\ntau_s = -5.0");
    assert!(
        matches!(bad, Err(SimError::Invalid { ref key, .. }) if key == "effects.head_heating.tau_s"),
        "{bad:?}"
    );
    let too_long = "[fleet]\nfixed_length_mm = 260.0";
    assert!(matches!(
        SimConfig::from_toml_str(too_long),
        Err(SimError::Invalid { .. })
    ));
    let json = serde_json::to_string(&generate(&quiet(20.0)).unwrap().truth).unwrap();
    let back: Truth = serde_json::from_str(&json).unwrap();
    assert_eq!(back.config, quiet(20.0));
}

#[test]
fn shipped_sample_config_parses_and_generates() {
    let path = dbbcal_testkit::repo_path("pipelines/sim-sample.toml");
    let cfg = SimConfig::load(&path).unwrap();
    assert_eq!(cfg.effects, EffectsConfig::default());
    let sim = generate(&cfg).unwrap();
    assert_eq!(sim.truth.bars.len(), 6);
    assert!(sim.truth.n_door_events > 0);
}

/// 12 bars, 30 days at 1 Hz (~31 M rows): run with `--ignored` to time it.
#[test]
#[ignore]
fn large_campaign_is_fast() {
    let cfg = SimConfig {
        duration_days: 30.0,
        sample_s: 1.0,
        fleet: Some(FleetConfig {
            n_bars: 12,
            ..FleetConfig::default()
        }),
        schedule: ScheduleConfig {
            mount_days: 3.0,
            ..ScheduleConfig::default()
        },
        ..SimConfig::default()
    };
    let t = std::time::Instant::now();
    let sim = generate(&cfg).unwrap();
    let elapsed = t.elapsed();
    eprintln!("{} rows in {elapsed:?}", sim.truth.n_encoder_rows);
    assert!(sim.truth.n_encoder_rows > 31_000_000);
    assert!(elapsed.as_secs() < 60);
}

#[test]
fn manifest_validates_with_every_effect_on() {
    let mut cfg = lively();
    let e = &mut cfg.effects;
    e.head_heating.enabled = true;
    e.second_path.enabled = true;
    e.sensor_gradient.enabled = true;
    e.settling.enabled = true;
    e.plate_expansion.enabled = true;
    e.creep.enabled = true;
    e.hidden_channel.enabled = true;
    cfg.schedule.reference = vec![ReferenceMount {
        bar: "B02".into(),
        length: "min".into(),
    }];
    let sim = generate(&cfg).unwrap();
    let campaign = dbbcal_core::campaign::Campaign::from_manifest(sim.manifest.clone()).unwrap();
    assert_eq!(campaign.bars.len(), 3);
    assert_eq!(sim.truth.effects_on.len(), 7);
    let text = sim.manifest.to_toml_string().unwrap();
    assert_eq!(
        Manifest::from_toml_str(&text, "campaign.toml").unwrap(),
        sim.manifest
    );
}

#[test]
fn write_puts_truth_next_to_the_campaign() {
    let sim = generate(&quiet(20.0)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write(&sim, dir.path(), &dbbcal_io::WriteOptions::default()).unwrap();
    let truth: Truth =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("truth.json")).unwrap())
            .unwrap();
    // serde_json parses floats to within an ulp or so (no `float_roundtrip` feature).
    assert_eq!(
        (truth.config, truth.mounts.len()),
        (sim.truth.config.clone(), sim.truth.mounts.len())
    );
    for (a, b) in truth.bars.iter().zip(&sim.truth.bars) {
        assert_eq!(a.id, b.id);
        assert!(
            (a.alpha_ppm_per_k - b.alpha_ppm_per_k).abs() < 1e-12
                && (a.tau_r_s - b.tau_r_s).abs() < 1e-9
        );
    }
    assert!(dir.path().join("campaign.toml").exists());
}

#[test]
fn written_campaign_reads_back() {
    let sim = generate(&lively()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write(&sim, dir.path(), &dbbcal_io::WriteOptions::default()).unwrap();
    let logs = dbbcal_io::read_campaign(dir.path()).unwrap();
    for (id, log) in &sim.tables.encoders {
        assert_eq!(logs.bars[id].time_ns, log.time_ns);
        assert_eq!(logs.bars[id].counts, log.counts);
    }
    assert_eq!(
        logs.sensors[AIR_LOW].celsius,
        sim.tables.temperatures[AIR_LOW].celsius
    );
    assert_eq!(logs.events.len(), sim.tables.events.len());
}

/// `[generation] air_between_readings`: the sensors read the same in every variant; the bars
/// follow the air held between readings or interpolated between them, which differs from the
/// continuous air only between readings (the AC triangle's corners, the set-point steps).
#[test]
fn air_between_readings_changes_the_bars_not_the_sensors() {
    let mut base = lively();
    base.duration_days = 1.0;
    base.sample_s = 10.0;
    base.room.setpoint_step_k = 1.0;
    let with = |air: AirBetweenReadings| SimConfig {
        generation: GenerationConfig {
            air_between_readings: air,
            ..GenerationConfig::default()
        },
        ..base.clone()
    };
    let continuous = generate(&base).unwrap();
    let held = generate(&with(AirBetweenReadings::Held)).unwrap();
    let interpolated = generate(&with(AirBetweenReadings::Interpolated)).unwrap();
    // (Equal to rounding: a reading time in seconds is a grid index up to 1e-15.)
    let same_logs = |a: &Simulation, b: &Simulation| {
        a.tables.temperatures.iter().all(|(id, l)| {
            let m = &b.tables.temperatures[id];
            l.time_ns == m.time_ns
                && l.celsius
                    .iter()
                    .zip(&m.celsius)
                    .all(|(x, y)| (x - y).abs() < 1e-12)
        })
    };
    for other in [&held, &interpolated] {
        assert!(same_logs(other, &continuous));
        assert_eq!(other.manifest, continuous.manifest);
    }
    // The bars' error: each variant differs from the others, by little (the air between two
    // readings 30 s apart), the held air behind by about half a reading period.
    let max_diff = |a: &Simulation, b: &Simulation| {
        a.true_error_um
            .values()
            .zip(b.true_error_um.values())
            .flat_map(|(x, y)| x.iter().zip(y).map(|(x, y)| (x - y).abs()))
            .fold(0.0, f64::max)
    };
    let (dh, di) = (
        max_diff(&held, &continuous),
        max_diff(&interpolated, &continuous),
    );
    assert!(dh > 1e-4 && dh < 0.02, "held vs continuous {dh} µm");
    assert!(
        di > 1e-7 && di < 0.002,
        "interpolated vs continuous {di} µm"
    );
    assert!(dh > 3.0 * di, "held {dh} interpolated {di}");
    // The default is the continuous air, left out of truth.json.
    assert_eq!(base.generation, GenerationConfig::default());
    let json = serde_json::to_string(&continuous.truth).unwrap();
    assert!(!json.contains("generation"));
    assert!(serde_json::to_string(&held.truth)
        .unwrap()
        .contains("\"held\""));
}

/// `[generation] prehistory_hours`: the room runs before the logging, so a bar is not in
/// steady state at its first reading; the logs themselves (sensors) do not change.
#[test]
fn prehistory_leaves_the_bars_out_of_steady_state() {
    let mut base = quiet(20.0);
    base.room.drift_k_per_day = 2.0; // a steady drift: the lag trails by slope * tau
    base.duration_days = 1.0;
    let pre = SimConfig {
        generation: GenerationConfig {
            prehistory_hours: 24.0,
            ..GenerationConfig::default()
        },
        ..base.clone()
    };
    let (a, b) = (generate(&base).unwrap(), generate(&pre).unwrap());
    assert_eq!(a.tables.temperatures.len(), b.tables.temperatures.len());
    for (id, l) in &a.tables.temperatures {
        let m = &b.tables.temperatures[id];
        assert_eq!(l.time_ns, m.time_ns);
        assert!(l
            .celsius
            .iter()
            .zip(&m.celsius)
            .all(|(x, y)| (x - y).abs() < 1e-9));
    }
    for bar in &a.truth.bars {
        let (ea, eb) = (&a.true_error_um[&bar.id], &b.true_error_um[&bar.id]);
        // At the first reading the bar with a pre-history lags the drift by slope * tau:
        // growth alpha I_min slope tau_R + beta I_p slope tau_S smaller; it reads higher.
        // (At t = 0 the bar is in its first handling gap; the scale adds a few per cent.)
        let slope = 2.0 / 86400.0;
        let lag_um = bar.alpha_ppm_per_k * bar.fixed_length_mm * slope * bar.tau_r_s * 1e-3;
        let d0 = eb[0] - ea[0];
        assert!(
            d0 > 0.8 * lag_um && d0 < 1.5 * lag_um,
            "{}: {d0} vs {lag_um}",
            bar.id
        );
        // A day later (many time constants) both are the same.
        let last = ea.len() - 1;
        assert!((eb[last] - ea[last]).abs() < 1e-6 * lag_um.max(1.0));
    }
}

/// `schedule.lengths`: rotating bars visit only the listed plate lengths; one length gives a
/// one-length campaign (every mount of every bar on it).
#[test]
fn schedule_lengths_restricts_the_rotation() {
    let mut cfg = quiet(20.0);
    cfg.schedule.lengths = vec!["mid".into()];
    let sim = generate(&cfg).unwrap();
    assert!(sim.truth.mounts.len() > 3);
    assert!(sim.truth.mounts.iter().all(|m| m.length == "mid"));
    cfg.schedule.lengths = vec!["max".into(), "min".into()];
    let sim = generate(&cfg).unwrap();
    let b01: Vec<&str> = sim
        .truth
        .mounts
        .iter()
        .filter(|m| m.bar == "B01")
        .map(|m| m.length.as_str())
        .collect();
    assert_eq!(&b01[..2], ["max", "min"]);
    cfg.schedule.lengths = vec!["nope".into()];
    assert!(matches!(
        cfg.validate(),
        Err(SimError::Invalid { ref key, .. }) if key == "schedule.lengths[0]"
    ));
}

#[test]
fn generation_options_are_validated() {
    let bad = SimConfig::from_toml_str("[generation]\nprehistory_hours = -1.0");
    assert!(
        matches!(bad, Err(SimError::Invalid { ref key, .. }) if key == "generation.prehistory_hours"),
        "{bad:?}"
    );
    // Readings off the internal grid cannot carry a held or interpolated air.
    let off_grid = "sample_s = 10.0\nmax_internal_step_s = 4.0\n[room]\ntemperature_sample_s = 7.0\n[generation]\nair_between_readings = \"held\"";
    assert!(matches!(
        SimConfig::from_toml_str(off_grid),
        Err(SimError::Invalid { ref key, .. }) if key == "generation.air_between_readings"
    ));
    let ok = SimConfig::from_toml_str(
        "[generation]\nair_between_readings = \"interpolated\"\nprehistory_hours = 12",
    );
    assert!(ok.is_ok(), "{ok:?}");
}
