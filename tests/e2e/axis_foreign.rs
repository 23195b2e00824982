//! A second `axis` simulator, written from `docs/spec/machine-formats.md` ("Laser and
//! environment", "Kind axis") and `docs/spec/machine-physics.md` ("Common model", "Interferometer
//! readings", "Kind axis") alone: it shares nothing with `crates/sim` but the parquet writer, writes
//! `campaign.toml` as text, and runs `dbbcal run pipelines/axis.toml` as a user would.
//!
//! What it varies against ours (`pipelines/sim-axis.toml`): the **Z** axis (ours X), travelling
//! from 0 down to −400 mm in 40-mm steps, three bidirectional runs a line; the lines' reflectors
//! at (0, 0, 0), (120, 0, 0) and (120, 90, 0) mm (the X pattern permuted: roll from Δy on lines
//! 1 and 2, pitch and yaw from Δz at three points), line 1 read on Δz, Δx, Δy, line 2 on Δz, Δy,
//! line 3 on Δz; readings counted in vacuum wavelengths (`compensation = "none"`: the analysis
//! applies modified Edlén and the material normalisation itself, from this file's own Edlén), a
//! machine at 21 °C with steel scales, the air drifting by a few tenths of a kelvin and a
//! hectopascal; the straightness optics' line a + b·q on the lateral channels (the same optics
//! for lines 1 and 2); readings in one shuffled file per line with times in µs; a `direction`
//! column on odd seeds only (else it is derived from the targets' order).
//!
//! Checks: every error at every target within U (k = 2) of this simulator's truth in ≥ 90 % of
//! cases pooled over three seeds, none beyond 2U, straightness compared up to a line (what the
//! readings cannot fix, `machine-physics.md`), nothing proposed on a clean test; with the spindle
//! growing along Z during the runs (1.5 µm/h slowing with a 3-h time constant) the loop names
//! `machine_drift`, then `machine_warm_up`, and with both the errors are back within U.

use std::path::Path;

use dbbcal::io::{write_table, Column, Table, TimeUnit};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use crate::support::run_record;

/// 2027-06-07T07:00:00Z, s.
const T0_S: i64 = 1_812_697_200;
const WAVELENGTH_NM: f64 = 632.9913;
const CTE_PPM: f64 = 11.5;
const TARGETS: usize = 11;
const STEP_MM: f64 = -40.0;
const RUNS: usize = 3;
/// Reflector of each line (x, y, z) mm, and the channels it reads.
const LINES: [([f64; 3], &[&str]); 3] = [
    ([0.0, 0.0, 0.0], &["dz", "dx", "dy"]),
    ([120.0, 0.0, 0.0], &["dz", "dy"]),
    ([120.0, 90.0, 0.0], &["dz"]),
];
const NAMES: [&str; 6] = ["EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ"];

/// Modified Edlén (Birch & Downs 1993/94), as `machine-physics.md` writes it: the air's
/// refractive index at `t_c` °C, `p_hpa`, `rh_pct`, for vacuum wavelength `nm`.
fn edlen(t_c: f64, p_hpa: f64, rh_pct: f64, nm: f64) -> f64 {
    let sigma2 = (1e3 / nm).powi(2);
    let p = 100.0 * p_hpa;
    let ns = (8342.54 + 2_406_147.0 / (130.0 - sigma2) + 15_998.0 / (38.9 - sigma2)) * 1e-8;
    let ntp =
        p * ns * (1.0 + 1e-8 * (0.601 - 0.00972 * t_c) * p) / (96_095.43 * (1.0 + 0.003_661 * t_c));
    let f = rh_pct / 100.0 * 611.2 * (17.62 * t_c / (243.12 + t_c)).exp();
    1.0 + ntp - f * (3.7345 - 0.0401 * sigma2) * 1e-10
}

/// One component's error along the travel (q from 0 to −400 mm), zero at the datum.
struct Curve {
    scale: f64,
    p: [f64; 2],
    cycles: f64,
    phase: f64,
}

impl Curve {
    fn draw(rng: &mut impl Rng, scale: f64) -> Curve {
        Curve {
            scale,
            p: [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)],
            cycles: rng.gen_range(0.5..2.5),
            phase: rng.gen_range(0.0..std::f64::consts::TAU),
        }
    }

    fn at(&self, q_mm: f64) -> f64 {
        let s = q_mm / (STEP_MM * (TARGETS - 1) as f64);
        let wave = |s: f64| (std::f64::consts::TAU * self.cycles * s + self.phase).cos();
        self.scale * (self.p[0] * s + self.p[1] * s * s + 0.4 * (wave(s) - wave(0.0)))
    }
}

/// The six true errors at `q` (µm, µrad).
fn truth(curves: &[Curve; 6], q_mm: f64) -> [f64; 6] {
    std::array::from_fn(|c| curves[c].at(q_mm))
}

/// Δ(p) = δ + 10⁻³ ε × p, the channel's component (µm).
fn displacement(e: &[f64; 6], p: [f64; 3], channel: &str) -> f64 {
    let (d, eps) = ([e[0], e[1], e[2]], [e[3], e[4], e[5]]);
    let cross = [
        eps[1] * p[2] - eps[2] * p[1],
        eps[2] * p[0] - eps[0] * p[2],
        eps[0] * p[1] - eps[1] * p[0],
    ];
    let k = ["dx", "dy", "dz"]
        .iter()
        .position(|c| *c == channel)
        .unwrap();
    d[k] + 1e-3 * cross[k]
}

/// Write the campaign of `seed` into `dir`; returns the true curves. `drift_um_per_h`: the
/// spindle growing along Z (and a little along X) during the test, slowing with a 3-h time
/// constant.
fn simulate(dir: &Path, seed: u64, drift_um_per_h: f64) -> [Curve; 6] {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let curves = [
        Curve::draw(&mut rng, 1.2),
        Curve::draw(&mut rng, 1.2),
        Curve::draw(&mut rng, 6.0),
        Curve::draw(&mut rng, 8.0),
        Curve::draw(&mut rng, 8.0),
        Curve::draw(&mut rng, 8.0),
    ];
    // The straightness optics' line on the lateral channels (µm, µm per mm): one set for lines
    // 1 and 2 (untouched between them).
    let optics: [(f64, f64); 2] =
        std::array::from_fn(|_| (rng.gen_range(-3.0..3.0), rng.gen_range(-0.02..0.02)));
    let (air0, p0, rh0, mat0) = (
        rng.gen_range(20.2..20.8),
        rng.gen_range(995.0..1025.0),
        rng.gen_range(30.0..60.0),
        rng.gen_range(20.8..21.4),
    );
    let (axial_noise, lateral_noise) = (
        Normal::new(0.0, 0.04).unwrap(),
        Normal::new(0.0, 0.12).unwrap(),
    );
    // The environment at t s after the start: slow drifts.
    let air = |t: f64| air0 + 0.3 * (t / 7200.0) + 0.05 * (t / 900.0).sin();
    let pressure = |t: f64| p0 + 1.2 * (t / 10_800.0);
    let humidity = |t: f64| rh0 - 3.0 * (t / 7200.0);
    let material = |t: f64| mat0 + 0.15 * (t / 7200.0);
    let tau_s = 3.0 * 3600.0;
    let drift = |t: f64| drift_um_per_h * tau_s / 3600.0 * (1.0 - (-t / tau_s).exp());

    let mut t = 0.0;
    let mut env_rows = Vec::new();
    let mut fixture_rows = Vec::new();
    for (l, (reflector, channels)) in LINES.iter().enumerate() {
        fixture_rows.push((t, l as i64 + 1, *reflector));
        let mut rows: Vec<ReadingRow> = Vec::new();
        for run in 1..=RUNS {
            let forward: Vec<usize> = (0..TARGETS).collect();
            let backward: Vec<usize> = (0..TARGETS).rev().collect();
            for (dir, order) in [(1i64, &forward), (-1, &backward)] {
                for &j in order.iter() {
                    let q = STEP_MM * j as f64;
                    let n = edlen(air(t), pressure(t), humidity(t), WAVELENGTH_NM);
                    let e = truth(&curves, q);
                    let alpha = 1e-6 * CTE_PPM * (material(t) - 20.0);
                    for channel in channels.iter() {
                        let mut value = displacement(&e, *reflector, channel);
                        if *channel == "dz" {
                            value += drift(t);
                            // The machine at its temperature: the true move from the datum is
                            // (q + e)(1 + α ΔT), counted in vacuum wavelengths (× n).
                            let true_mm = (q + 1e-3 * value) * (1.0 + alpha);
                            let read_mm = n * true_mm;
                            // The laser was zeroed at the datum (no dead path): it reads n(t) L.
                            value = 1e3 * (read_mm - q) + axial_noise.sample(&mut rng);
                        } else {
                            if *channel == "dx" {
                                value += 0.2 * drift(t);
                            }
                            let (a, b) = optics[usize::from(*channel == "dy")];
                            value += a + b * q + lateral_noise.sample(&mut rng);
                        }
                        // Outward (down, −Z) then back (up, +Z); a pass's first target, where the
                        // axis turns, counts with its pass.
                        let direction = -dir;
                        rows.push((
                            t,
                            run as i64,
                            Some(direction),
                            q,
                            channel.to_string(),
                            value,
                        ));
                    }
                    env_rows.push((t, air(t), pressure(t), humidity(t), material(t)));
                    t += 8.0;
                }
                t += 20.0;
            }
        }
        write_line(dir, l + 1, &mut rows, seed, &mut rng);
        // Re-setting the optics for the next line.
        t += 900.0;
    }
    write_environment(dir, &env_rows);
    write_fixture(dir, &fixture_rows);
    std::fs::write(dir.join("campaign.toml"), MANIFEST).unwrap();
    curves
}

const MANIFEST: &str = r#"[campaign]
kind = "axis"
id = "foreign-axis-z"
reference_temperature_c = 20.0

[machine]
axis = "Z"
cte_ppm_per_k = 11.5

[laser]
wavelength_nm = 632.9913
compensation = "none"

[[line]]
id = 1
reflector_mm = [0.0, 0.0, 0.0]

[[line]]
id = 2
reflector_mm = [120.0, 0.0, 0.0]

[[line]]
id = 3
reflector_mm = [120.0, 90.0, 0.0]

[fixture]
u_um = 3.0
"#;

fn micros(t_s: f64) -> i64 {
    (T0_S as f64 * 1e6 + t_s * 1e6).round() as i64
}

/// A reading: (time s, run, direction, target mm, channel, deviation µm).
type ReadingRow = (f64, i64, Option<i64>, f64, String, f64);

fn write_line(dir: &Path, line: usize, rows: &mut [ReadingRow], seed: u64, rng: &mut impl Rng) {
    std::fs::create_dir_all(dir.join("readings")).unwrap();
    rows.shuffle(rng);
    let mut columns = vec![
        (
            "time".to_string(),
            Column::Time {
                raw: rows.iter().map(|r| Some(micros(r.0))).collect(),
                unit: TimeUnit::Us,
                zone: None,
            },
        ),
        ("line".into(), Column::I64(vec![line as i64; rows.len()])),
        (
            "run".into(),
            Column::I64(rows.iter().map(|r| r.1).collect()),
        ),
        (
            "target_mm".into(),
            Column::F64(rows.iter().map(|r| r.3).collect()),
        ),
        (
            "channel".into(),
            Column::Str(rows.iter().map(|r| r.4.clone()).collect()),
        ),
        (
            "deviation_um".into(),
            Column::F64(rows.iter().map(|r| r.5).collect()),
        ),
    ];
    if seed % 2 == 1 {
        columns.push((
            "direction".into(),
            Column::OptI64(rows.iter().map(|r| r.2).collect()),
        ));
    }
    write_table(
        &dir.join(format!("readings/line-{line}.parquet")),
        &Table { columns },
    )
    .unwrap();
}

fn write_environment(dir: &Path, rows: &[(f64, f64, f64, f64, f64)]) {
    std::fs::create_dir_all(dir.join("environment")).unwrap();
    let col = |k: usize| Column::F64(rows.iter().map(|r| [r.1, r.2, r.3, r.4][k]).collect());
    let table = Table {
        columns: vec![
            (
                "time".into(),
                Column::TimeNs(rows.iter().map(|r| 1000 * micros(r.0)).collect()),
            ),
            ("air_c".into(), col(0)),
            ("pressure_hpa".into(), col(1)),
            ("humidity_pct".into(), col(2)),
            ("material_c".into(), col(3)),
        ],
    };
    write_table(&dir.join("environment/env.parquet"), &table).unwrap();
}

fn write_fixture(dir: &Path, rows: &[(f64, i64, [f64; 3])]) {
    std::fs::create_dir_all(dir.join("fixture")).unwrap();
    let table = Table {
        columns: vec![
            (
                "time".into(),
                Column::TimeNs(rows.iter().map(|r| 1000 * micros(r.0)).collect()),
            ),
            (
                "line".into(),
                Column::I64(rows.iter().map(|r| r.1).collect()),
            ),
            (
                "x_mm".into(),
                Column::F64(rows.iter().map(|r| r.2[0]).collect()),
            ),
            (
                "y_mm".into(),
                Column::F64(rows.iter().map(|r| r.2[1]).collect()),
            ),
            (
                "z_mm".into(),
                Column::F64(rows.iter().map(|r| r.2[2]).collect()),
            ),
        ],
    };
    write_table(&dir.join("fixture/fixture.parquet"), &table).unwrap();
}

/// `dbbcal run pipelines/axis.toml` on `campaign` (plus `extra`): axis.json.
fn run(campaign: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    run_record("pipelines/axis.toml", campaign, out, extra, "axis.json").0
}

/// Each error at each target against the truth, in units of its U: straightness (EXZ, EYZ)
/// after the least-squares slope of (estimate − truth) over each direction's targets is removed
/// (the optics' line: its offset is gone at the datum, its slope no reading fixes), the rest as
/// they are. The datum target, zero by definition with U = 0, is checked to be zero and left
/// out. Returns the |e − t| / U.
fn ratios(record: &serde_json::Value, curves: &[Curve; 6]) -> Vec<f64> {
    assert_eq!(record["axis"], "Z");
    assert_eq!(record["rank"], 6, "{}", record["lost"]);
    let targets = record["targets"].as_array().unwrap();
    let mut out = Vec::new();
    for direction in [1, -1] {
        let here: Vec<&serde_json::Value> = targets
            .iter()
            .filter(|t| t["direction"].as_i64() == Some(direction))
            .collect();
        assert!(
            here.len() >= TARGETS - 1,
            "direction {direction}: {} targets",
            here.len()
        );
        for c in 0..6 {
            let rows: Vec<(f64, f64, f64)> = here
                .iter()
                .map(|t| {
                    let e = &t["errors"][c];
                    assert_eq!(e[0], NAMES[c]);
                    let q = t["target_mm"].as_f64().unwrap();
                    let (v, u) = (e[1].as_f64().unwrap(), e[2].as_f64().unwrap());
                    (q, v - truth(curves, q)[c], u)
                })
                .collect();
            let slope = if c < 2 {
                slope_through_datum(&rows)
            } else {
                0.0
            };
            for (q, d, u) in rows {
                if u == 0.0 {
                    assert!(
                        q == 0.0 && (d - slope * q).abs() < 1e-9,
                        "{}: U 0 at {q}",
                        NAMES[c]
                    );
                    continue;
                }
                out.push((d - slope * q).abs() / u);
            }
        }
    }
    out
}

/// Least-squares slope through the datum (q = 0) of the differences against q.
fn slope_through_datum(rows: &[(f64, f64, f64)]) -> f64 {
    let sqq: f64 = rows.iter().map(|r| r.0 * r.0).sum();
    rows.iter().map(|r| r.0 * r.1).sum::<f64>() / sqq
}

/// The mean U (k = 2) of the positioning error over the targets, µm.
fn mean_u(record: &serde_json::Value) -> f64 {
    let u: Vec<f64> = record["targets"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|t| t["errors"][2][2].as_f64())
        .collect();
    u.iter().sum::<f64>() / u.len() as f64
}

fn summary(r: &[f64]) -> (usize, usize, f64) {
    let inside = r.iter().filter(|z| **z <= 1.0).count();
    let beyond = r.iter().filter(|z| **z > 2.0).count();
    (inside, beyond, r.iter().copied().fold(0.0, f64::max))
}

#[test]
fn a_second_simulator_s_z_axis_is_recovered_within_u() {
    let tmp = tempfile::tempdir().unwrap();
    let mut all = Vec::new();
    for seed in 1..=3u64 {
        let campaign = tmp.path().join(format!("axis-{seed}"));
        let curves = simulate(&campaign, seed, 0.0);
        let record = run(&campaign, &tmp.path().join(format!("out-{seed}")), &[]);
        assert!(
            record["diagnosis"]["proposal"].is_null(),
            "seed {seed}, a clean test: {}",
            record["diagnosis"]
        );
        let r = ratios(&record, &curves);
        let (inside, beyond, worst) = summary(&r);
        eprintln!(
            "second axis simulator, seed {seed}: {inside}/{} within U, {beyond} beyond 2U, worst {worst:.2} U",
            r.len()
        );
        all.extend(r);
    }
    let (inside, beyond, worst) = summary(&all);
    eprintln!("second axis simulator, pooled: {inside}/{} within U, {beyond} beyond 2U, worst {worst:.2} U", all.len());
    assert!(inside as f64 >= 0.9 * all.len() as f64);
    assert_eq!(beyond, 0);
}

#[test]
fn a_spindle_growing_during_the_runs_is_named_warm_up_and_adding_it_restores_the_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("drift");
    let curves = simulate(&campaign, 4, 1.5);
    let mut added: Vec<&str> = Vec::new();
    let mut steps = Vec::new();
    for expected in ["machine_warm_up", ""] {
        let extra: Vec<&str> = added.iter().flat_map(|e| ["--add-effect", *e]).collect();
        let record = run(
            &campaign,
            &tmp.path().join(format!("step-{}", added.len())),
            &extra,
        );
        let r = ratios(&record, &curves);
        let (inside, beyond, worst) = summary(&r);
        let proposal = record["diagnosis"]["proposal"].as_str().unwrap_or("");
        let rms_along = record["diagnosis"]["ledger"][0]["rms_along_um"]
            .as_f64()
            .unwrap();
        let u_mean = mean_u(&record);
        eprintln!(
            "second axis simulator, spindle growth, with {added:?}: RMS along {rms_along:.4} µm, \
             mean U {u_mean:.3}, {inside}/{} within U, {beyond} beyond 2U, worst {worst:.2} U; \
             proposed {proposal:?}",
            r.len()
        );
        assert_eq!(proposal, expected, "{}", record["diagnosis"]);
        steps.push((inside, beyond, rms_along, r.len(), u_mean));
        added.push(expected);
    }
    // The drift spreads the runs: it shows in the residual and in U (the runs' scatter), so
    // the error falling is the residual along the axis falling to that of the same campaign
    // without the drift (the noise), and U with it.
    let clean = tmp.path().join("clean");
    simulate(&clean, 4, 0.0);
    let record = run(&clean, &tmp.path().join("clean-out"), &[]);
    let noise = record["diagnosis"]["ledger"][0]["rms_along_um"]
        .as_f64()
        .unwrap();
    eprintln!("second axis simulator, the same campaign without drift: RMS along {noise:.4} µm");
    let (first, last) = (steps[0], steps[1]);
    assert!(first.2 > 1.5 * noise && last.2 <= 1.1 * noise, "{steps:?}");
    assert!(last.4 < first.4, "{steps:?}");
    assert!(last.0 as f64 >= 0.9 * last.3 as f64, "{steps:?}");
    assert_eq!(last.1, 0, "{steps:?}");
}
