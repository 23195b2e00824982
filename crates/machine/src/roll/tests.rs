//! The checks on the analysis, with a forward model written here from the spec's
//! reading equations (`docs/spec/machine-physics.md`, "Kind roll", "Readings"), sampled at
//! 20 Hz with moves between the dwells.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use dbbcal_core::axis_campaign::{CampaignKind, KindSection, MachineAxis};
use dbbcal_core::roll_campaign::{
    LevelRow, ProbeDecl, ProbeSample, ReadingUnit, RollCampaign, RollCampaignLogs, RollManifest,
    RollSection,
};

use super::*;

/// A rig along X: L 80 mm, d = s = 40 mm, B to A at decreasing x, readings in µm, probes A … D
/// at their nominal places (u 50 µm).
fn roll_campaign() -> RollCampaign {
    let probe = |id: &str| ProbeDecl {
        id: id.into(),
        u_xy_um: 50.0,
        um_per_v: 1.0,
        xy_mm: None,
    };
    let manifest = RollManifest {
        campaign: KindSection {
            kind: CampaignKind::Roll,
            id: "t".into(),
            reference_temperature_c: 20.0,
        },
        roll: RollSection {
            axis: MachineAxis::X,
            l_mm: 80.0,
            d_mm: 40.0,
            s_mm: 40.0,
            b_to_a: -1,
            unit: ReadingUnit::Um,
            dwell_min_s: 2.0,
            dwell_tol_um: 2.0,
            probe: ["A", "B", "C", "D"].map(probe).to_vec(),
        },
    };
    RollCampaign::from_manifest_at(manifest, "campaign.toml").unwrap()
}

/// One true stage and rig.
#[derive(Clone)]
struct Truth {
    /// εx, εy (µrad), δz (µm) per station.
    eps_x: Vec<f64>,
    eps_y: Vec<f64>,
    dz: Vec<f64>,
    /// Trigonometric profiles: (amplitude µm, ω rad/mm, phase) terms of f₁ and f₂.
    f1: Vec<(f64, f64, f64)>,
    f2: Vec<(f64, f64, f64)>,
    /// Zero offsets A … D, µm.
    offset_um: [f64; 4],
    /// White noise per sample, µm; resolution (0: none), µm.
    noise_um: f64,
    resolution_um: f64,
    /// Roll drift, µrad/h.
    drift_urad_per_h: f64,
}

fn profile(terms: &[(f64, f64, f64)], u: f64) -> f64 {
    terms.iter().map(|(a, w, p)| a * (w * u + p).sin()).sum()
}

fn random_truth(rng: &mut ChaCha8Rng, stations: usize) -> Truth {
    let terms = |rng: &mut ChaCha8Rng| -> Vec<(f64, f64, f64)> {
        (0..3)
            .map(|_| {
                (
                    rng.gen_range(-5.0..5.0),
                    rng.gen_range(-0.05..0.05),
                    rng.gen_range(0.0..6.0),
                )
            })
            .collect()
    };
    let (f1, f2) = (terms(rng), terms(rng));
    Truth {
        eps_x: (0..stations)
            .map(|_| rng.gen_range(-1000.0..1000.0))
            .collect(),
        eps_y: (0..stations)
            .map(|_| rng.gen_range(-1000.0..1000.0))
            .collect(),
        dz: (0..stations).map(|_| rng.gen_range(-20.0..20.0)).collect(),
        f1,
        f2,
        offset_um: [0.0; 4],
        noise_um: 0.0,
        resolution_um: 0.0,
        drift_urad_per_h: 0.0,
    }
}

/// The four readings at station n and time t (h), µm, before noise.
fn readings(t: &Truth, n: usize, t_h: f64) -> [f64; 4] {
    let (l, d) = (80.0, 40.0);
    let u = 13.0 + n as f64 * d;
    let ex = t.eps_x[n] + t.drift_urad_per_h * t_h;
    let (ey, dz) = (t.eps_y[n], t.dz[n]);
    [
        profile(&t.f1, u) + dz + t.offset_um[0],
        profile(&t.f1, u + d) + dz - 1e-3 * d * ey + t.offset_um[1],
        profile(&t.f2, u) + dz + 1e-3 * l * ex + t.offset_um[2],
        profile(&t.f2, u + d) + dz - 1e-3 * d * ey + 1e-3 * l * ex + t.offset_um[3],
    ]
}

/// Samples at 20 Hz: `order` the stations in time order, 5 s dwells, 2 s moves (b_to_a = −1,
/// station 0 at x = −50 mm: the seed's −770 … −50 mm for 19 stations).
fn sample(t: &Truth, order: &[usize], rng: &mut ChaCha8Rng) -> Vec<ProbeSample> {
    let noise = Normal::new(0.0, 1.0).unwrap();
    let x_of = |n: usize| -50.0 - 40.0 * n as f64;
    let mut out = Vec::new();
    let mut now_ns: i64 = 1_800_000_000_000_000_000;
    let dt = 50_000_000;
    let push = |x: f64, m: [f64; 4], now: i64, out: &mut Vec<ProbeSample>| {
        out.push(ProbeSample {
            time_ns: now,
            x_mm: x,
            m,
            station: None,
            pass: None,
            source: (0, out.len() as u64),
        })
    };
    for (k, &n) in order.iter().enumerate() {
        for _ in 0..100 {
            let t_h = (now_ns - 1_800_000_000_000_000_000) as f64 / 3.6e12;
            let m = readings(t, n, t_h).map(|v| {
                let v = v + t.noise_um * noise.sample(rng);
                if t.resolution_um > 0.0 {
                    (v / t.resolution_um).round() * t.resolution_um
                } else {
                    v
                }
            });
            push(x_of(n), m, now_ns, &mut out);
            now_ns += dt;
        }
        if let Some(&next) = order.get(k + 1) {
            for j in 1..40 {
                let x = x_of(n) + (x_of(next) - x_of(n)) * f64::from(j) / 40.0;
                push(x, [999.0; 4], now_ns, &mut out);
                now_ns += dt;
            }
        }
    }
    out
}

fn logs(samples: Vec<ProbeSample>, levels: Vec<LevelRow>) -> RollCampaignLogs {
    RollCampaignLogs {
        campaign: roll_campaign(),
        inputs: Vec::new(),
        probe_files: vec!["probes/p.parquet".into()],
        level_files: vec!["levels/l.parquet".into()],
        samples,
        has_station: false,
        has_pass: false,
        levels,
    }
}

fn forward(n: usize) -> Vec<usize> {
    (0..n).collect()
}

#[test]
fn noise_free_any_profiles_straightness_and_pitch_give_the_roll_within_1e_12_rad() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for trial in 0..20 {
        let truth = random_truth(&mut rng, 19);
        let order: Vec<usize> = if trial % 2 == 0 {
            forward(19)
        } else {
            (0..19).rev().collect()
        };
        let s = study(
            &logs(sample(&truth, &order, &mut rng), vec![]),
            &RollOptions::default(),
        )
        .unwrap();
        assert_eq!(s.stations.len(), 19);
        for st in &s.stations {
            let want = truth.eps_x[st.station] - truth.eps_x[0];
            let err_rad = (st.roll_urad - want).abs() * 1e-6;
            assert!(
                err_rad < 1e-12,
                "trial {trial} n {}: {err_rad:e} rad",
                st.station
            );
            assert_eq!(st.roll_error_urad, st.roll_urad, "b_to_a = −1: EAX = +εx");
        }
        // The global solve of one pass is the seed's eq. 10.
        let means: Vec<[f64; 4]> = {
            let mut by: Vec<&DwellResult> = s.dwells.iter().collect();
            by.sort_by_key(|d| d.station);
            by.iter().map(|d| d.mean_um).collect()
        };
        let eq10 = estimator::roll_urad(&means, 80.0);
        for (st, e) in s.stations.iter().zip(&eq10) {
            assert!((st.roll_urad - e).abs() < 1e-7);
        }
    }
}

/// Monte Carlo of εx(18) over `trials` campaigns: (empirical sd, mean reported u).
fn monte_carlo(noise_um: f64, resolution_um: f64, trials: usize) -> (f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (mut sum, mut sum2, mut u_sum) = (0.0, 0.0, 0.0);
    for _ in 0..trials {
        // A new set-up every campaign (profiles, δz, εy, εx): the readings' sub-resolution
        // parts are then independent and uniform, as the law assumes. (With one fixed set-up
        // the rounding errors of A and C at one station are tied by their common δz.)
        let mut t = random_truth(&mut rng, 19);
        t.noise_um = noise_um;
        t.resolution_um = resolution_um;
        let s = study(
            &logs(sample(&t, &forward(19), &mut rng), vec![]),
            &RollOptions::default(),
        )
        .unwrap();
        let err = s.stations[18].roll_urad - (t.eps_x[18] - t.eps_x[0]);
        sum += err;
        sum2 += err * err;
        u_sum += s.stations[18].u_noise_urad;
    }
    let n = trials as f64;
    let mean = sum / n;
    (((sum2 / n) - mean * mean).sqrt(), u_sum / n)
}

#[test]
fn the_root_n_law_holds_within_5_percent_by_monte_carlo_at_10_nm() {
    let (sd, u) = monte_carlo(0.010, 0.0, 3000);
    let law = estimator::u_law_urad(0.010 / 10.0, 18, 80.0);
    eprintln!("10 nm: sd {sd:.5} µrad, reported u {u:.5} µrad, law {law:.5} µrad");
    assert!((sd / law - 1.0).abs() < 0.05, "sd {sd} law {law}");
    assert!((u / law - 1.0).abs() < 0.05, "reported {u} law {law}");
}

#[test]
fn the_root_n_law_holds_within_5_percent_by_monte_carlo_at_1_um_resolution() {
    let (sd, u) = monte_carlo(0.010, 1.0, 3000);
    let law = estimator::u_law_urad(1.0 / 12f64.sqrt(), 18, 80.0);
    eprintln!("1 µm: sd {sd:.3} µrad, reported u {u:.3} µrad, law {law:.3} µrad");
    assert!((sd / law - 1.0).abs() < 0.05, "sd {sd} law {law}");
    assert!((u / law - 1.0).abs() < 0.05, "reported {u} law {law}");
}

#[test]
fn the_seed_experiment_reports_30_6_urad_at_station_18() {
    let mut rng = ChaCha8Rng::seed_from_u64(18);
    let mut t = random_truth(&mut rng, 19);
    t.resolution_um = 1.0;
    let s = study(
        &logs(sample(&t, &forward(19), &mut rng), vec![]),
        &RollOptions::default(),
    )
    .unwrap();
    assert_eq!(s.resolution_um, [1.0; 4]);
    let x18 = s.stations[18].x_mm;
    assert!((x18 + 770.0).abs() < 1e-9 && (s.stations[0].x_mm + 50.0).abs() < 1e-9);
    let u = s.stations[18].u_noise_urad;
    eprintln!("seed experiment: u(εx(18)) = {u:.3} µrad");
    assert!((u - 30.6).abs() < 0.05, "{u}");
}

fn level(station_time_ns: i64, roll: f64, row: u64) -> LevelRow {
    LevelRow {
        time_ns: station_time_ns,
        roll_urad: roll,
        u_urad: Some(1.0),
        source: (0, row),
    }
}

#[test]
fn a_5_um_zero_offset_on_c_is_a_62_5_urad_ramp_named_and_removed_by_a_level_datum() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut truth = random_truth(&mut rng, 19);
    // A plausible roll: 20 µrad over the travel.
    truth.eps_x = (0..19).map(|n| 20.0 * (n as f64 / 5.0).sin()).collect();
    let mut offset = truth.clone();
    offset.offset_um[2] = 5.0;
    let clean = study(
        &logs(sample(&truth, &forward(19), &mut rng), vec![]),
        &RollOptions::default(),
    )
    .unwrap();
    let samples = sample(&offset, &forward(19), &mut rng);
    let plain = study(&logs(samples.clone(), vec![]), &RollOptions::default()).unwrap();
    for (a, b) in plain.stations.iter().zip(&clean.stations) {
        let ramp = a.roll_urad - b.roll_urad;
        assert!((ramp - 62.5 * a.station as f64).abs() < 1e-9, "{ramp}");
    }
    assert!(plain.implausible.is_some());
    assert_eq!(plain.diagnosis.missing, Some(RollEffect::ProbeZeroOffset));
    assert!(plain
        .diagnosis
        .missing_because
        .contains("combined zero offset"));
    // Levels read at both ends (true roll relative to an arbitrary level zero of 7 µrad).
    let t_first = samples[50].time_ns;
    let t_last = samples[samples.len() - 50].time_ns;
    let levels = vec![
        level(t_first, truth.eps_x[0] + 7.0, 0),
        level(t_last, truth.eps_x[18] + 7.0, 1),
    ];
    let datum = study(&logs(samples, levels), &RollOptions::default()).unwrap();
    assert!(datum.level_datum);
    assert!(datum.implausible.is_none(), "{:?}", datum.implausible);
    for (a, b) in datum.stations.iter().zip(&clean.stations) {
        assert!((a.roll_urad - b.roll_urad).abs() < 1e-6, "n {}", a.station);
    }
    let offset_fit = &datum.effects[0];
    assert_eq!(offset_fit.effect, RollEffect::ProbeZeroOffset);
    assert!(
        (offset_fit.value.0 - 5.0).abs() < 1e-6,
        "{:?}",
        offset_fit.value
    );
}

#[test]
fn roll_drift_is_told_apart_by_passes_both_ways() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut t = random_truth(&mut rng, 10);
    t.noise_um = 0.01;
    t.drift_urad_per_h = 300.0;
    let order: Vec<usize> = (0..10).chain((0..9).rev()).collect();
    let s = study(
        &logs(sample(&t, &order, &mut rng), vec![]),
        &RollOptions::default(),
    )
    .unwrap();
    assert_eq!(s.passes.len(), 2);
    assert_eq!(s.passes[1].direction, -1);
    assert_eq!(
        s.diagnosis.missing,
        Some(RollEffect::RollDrift),
        "{:?}",
        s.diagnosis
    );
    let with = RollOptions {
        effects: vec![RollEffect::RollDrift],
        ..RollOptions::default()
    };
    let s = study(&logs(sample(&t, &order, &mut rng), vec![]), &with).unwrap();
    let (rate, u) = s.effects[0].value;
    assert!((rate - 300.0).abs() < 2.0 * u.max(1.0), "{rate} ± {u}");
}

#[test]
fn the_seeds_1_35_mrad_after_18_stations_is_a_6_um_combined_offset_and_is_warned_about() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let mut t = random_truth(&mut rng, 19);
    t.eps_x = vec![0.0; 19];
    t.offset_um = [0.0, 0.0, 6.0, 0.0];
    let s = study(
        &logs(sample(&t, &forward(19), &mut rng), vec![]),
        &RollOptions::default(),
    )
    .unwrap();
    assert!((s.stations[18].roll_urad - 1350.0).abs() < 1e-6);
    let i = s
        .implausible
        .as_ref()
        .expect("1.35 mrad is implausible for a machine table");
    assert!((i.equivalent_offset_um - 6.0).abs() < 1e-9, "{i:?}");
    assert!((i.max_abs_urad - 1350.0).abs() < 1e-6);
    // A typical roll (±30 µrad) is not warned about.
    t.offset_um = [0.0; 4];
    t.eps_x = (0..19).map(|n| 30.0 * (n as f64 / 4.0).sin()).collect();
    let s = study(
        &logs(sample(&t, &forward(19), &mut rng), vec![]),
        &RollOptions::default(),
    )
    .unwrap();
    assert!(s.implausible.is_none());
    assert_eq!(s.diagnosis.missing, None);
}
