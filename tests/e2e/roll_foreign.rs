//! A second `roll` simulator, written from `docs/spec/machine-formats.md` ("Kind roll") and
//! `docs/spec/machine-physics.md` ("Kind roll", the readings) alone, sharing nothing with
//! `crates/sim/src/roll/` but the format types and the parquet writer. It varies what ours keeps
//! fixed: the rig (L = 60 mm, d = s = 25 mm, `b_to_a = +1`, the stage stepping towards +x,
//! readings in µm), the truth (εx a random walk plus a bow; δz and εy drawn afresh at every
//! visit, up to ±15 µm and ±300 µrad; profiles of 24 random sines, 1.5-150 mm), three passes
//! (out, back, out) at 50 Hz with dwells of random length and noisy `x_mm` readout, no `station`,
//! `pass` or level columns, times in ms, rows shuffled; the readings follow the stage through its
//! moves, and on half the seeds the stage rings after each arrival (δz and εy, which the
//! estimator cancels). Checks: εx within U (k = 2) at ≥ 90 % of the stations over 16 seeds each,
//! the standardised errors' RMS near 1 (U neither too small nor inflated by what cancels), and U
//! growing station by station.

use std::path::Path;

use dbbcal::io::manifest::TomlManifest;
use dbbcal_core::roll_campaign::{ProbeSample, RollCampaignTables, RollManifest};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

const L_MM: f64 = 60.0;
const D_MM: f64 = 25.0;
const STATIONS: usize = 24;
const X_REF_MM: f64 = 12.5;
const RATE_HZ: f64 = 50.0;
const NOISE_UM: f64 = 0.02;

const MANIFEST: &str = r#"
campaign = { kind = "roll", id = "foreign-roll", reference_temperature_c = 20.0 }

[roll]
axis = "Y"
L_mm = 60.0
d_mm = 25.0
s_mm = 25.0
b_to_a = 1
unit = "um"
dwell_min_s = 2.0
dwell_tol_um = 1.0

[[roll.probe]]
id = "A"
u_xy_um = 30.0
um_per_v = 1.0

[[roll.probe]]
id = "B"
u_xy_um = 30.0
um_per_v = 1.0

[[roll.probe]]
id = "C"
u_xy_um = 30.0
um_per_v = 1.0

[[roll.probe]]
id = "D"
u_xy_um = 30.0
um_per_v = 1.0
"#;

/// A surface track: a sum of sines of random wavelength, amplitude and phase, and a slope (µm
/// at surface coordinate `u_mm`).
struct Track {
    sines: Vec<(f64, f64, f64)>,
    slope_um_per_mm: f64,
}

impl Track {
    fn draw(rng: &mut impl Rng) -> Track {
        let sines = (0..24)
            .map(|_| {
                let wavelength_mm = 1.5 * 100f64.powf(rng.gen::<f64>());
                // Shorter waves are smaller (a ground surface): ~0.5 µm at 150 mm.
                let amplitude_um = 0.5 * (wavelength_mm / 150.0).sqrt() * rng.gen::<f64>();
                let phase = std::f64::consts::TAU * rng.gen::<f64>();
                (std::f64::consts::TAU / wavelength_mm, amplitude_um, phase)
            })
            .collect();
        Track {
            sines,
            slope_um_per_mm: rng.gen_range(-0.02..0.02),
        }
    }

    fn at(&self, u_mm: f64) -> f64 {
        self.slope_um_per_mm * u_mm
            + self
                .sines
                .iter()
                .map(|(k, a, p)| a * (k * u_mm + p).sin())
                .sum::<f64>()
    }
}

/// The campaign of `seed` written into `dir`; returns εx(n) − εx(0), µrad (the datum the
/// analysis reports against when no level is logged).
///
/// `settling_um`: the stage rings after each arrival, a 6 Hz oscillation of that amplitude
/// decaying in 0.6 s, in δz (all four probes) and, 10 µrad per µm, in εy (B and D).
fn simulate(dir: &Path, seed: u64, settling_um: f64) -> Vec<f64> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, NOISE_UM).unwrap();
    let (f1, f2) = (Track::draw(&mut rng), Track::draw(&mut rng));
    // εx: a random walk of 3 µrad steps plus a bow of up to ±20 µrad over the travel.
    let bow = rng.gen_range(-20.0..20.0);
    let mut walk = 0.0;
    let roll_urad: Vec<f64> = (0..STATIONS)
        .map(|n| {
            walk += Normal::new(0.0, 3.0).unwrap().sample(&mut rng);
            let s = n as f64 / (STATIONS - 1) as f64;
            walk + bow * 4.0 * s * (1.0 - s)
        })
        .collect();
    let u0_mm = rng.gen_range(0.0..50.0);
    // The four readings at station n with the stage's δz (µm) and εy (µrad) of that visit,
    // noise-free (`docs/spec/machine-physics.md`, "Kind roll", the readings; offsets zero).
    let reading = |n: usize, dz: f64, ey: f64| -> [f64; 4] {
        let u = u0_mm + n as f64 * D_MM;
        let ex = roll_urad[n];
        [
            f1.at(u) + dz,
            f1.at(u + D_MM) + dz - 1e-3 * D_MM * ey,
            f2.at(u) + dz + 1e-3 * L_MM * ex,
            f2.at(u + D_MM) + dz - 1e-3 * D_MM * ey + 1e-3 * L_MM * ex,
        ]
    };
    let order: Vec<usize> = (0..STATIONS)
        .chain((0..STATIONS).rev())
        .chain(0..STATIONS)
        .collect();
    let mut samples = Vec::new();
    let mut t_ms: i64 = 1_805_000_000_000; // 2027-03-15
    let step_ms = (1000.0 / RATE_HZ) as i64;
    let mut previous: Option<(usize, [f64; 4])> = None;
    for &n in &order {
        let x_n = X_REF_MM + n as f64 * D_MM;
        // This visit's δz and εy, drawn afresh.
        let here = reading(n, rng.gen_range(-15.0..15.0), rng.gen_range(-300.0..300.0));
        if let Some((p, there)) = previous.filter(|(p, _)| *p != n) {
            // The move: a smooth ramp of 1.5-3 s; the readings go from one visit's to the next
            // with the position (they are logged and never used).
            let x_p = X_REF_MM + p as f64 * D_MM;
            let move_samples = (rng.gen_range(1.5..3.0) * RATE_HZ) as usize;
            for k in 0..move_samples {
                let f = (k as f64 + 0.5) / move_samples as f64;
                let g = f * f * (3.0 - 2.0 * f);
                let m = std::array::from_fn(|i| {
                    there[i] + g * (here[i] - there[i]) + noise.sample(&mut rng)
                });
                samples.push(sample(t_ms, x_p + (x_n - x_p) * g, m));
                t_ms += step_ms;
            }
        }
        previous = Some((n, here));
        // The dwell: 3-6 s, `x_mm` read to ±0.1 µm, times jittered by ±2 ms.
        let dwell_samples = (rng.gen_range(3.0..6.0) * RATE_HZ) as usize;
        for k in 0..dwell_samples {
            let x = x_n + 1e-4 * rng.gen_range(-1.0..1.0);
            let t_s = k as f64 / RATE_HZ;
            let ring = settling_um * (-t_s / 0.6).exp() * (std::f64::consts::TAU * 6.0 * t_s).cos();
            let tilt = -1e-3 * D_MM * 10.0 * ring;
            let m: [f64; 4] = std::array::from_fn(|i| {
                let along = if i % 2 == 1 { tilt } else { 0.0 };
                here[i] + ring + along + noise.sample(&mut rng)
            });
            samples.push(sample(t_ms + rng.gen_range(-2..=2), x, m));
            t_ms += step_ms;
        }
    }
    let manifest = RollManifest::from_toml_str(MANIFEST, "campaign.toml").unwrap();
    let tables = RollCampaignTables {
        samples,
        write_station: false,
        write_pass: false,
        levels: Vec::new(),
    };
    let options = dbbcal::io::RollWriteOptions {
        time_unit: dbbcal::io::TimeUnit::Ms,
        shuffle_rows: true,
        seed,
        ..Default::default()
    };
    dbbcal::io::write_roll_campaign(dir, &manifest, &tables, &options).unwrap();
    roll_urad.iter().map(|e| e - roll_urad[0]).collect()
}

fn sample(t_ms: i64, x_mm: f64, m: [f64; 4]) -> ProbeSample {
    ProbeSample {
        time_ns: t_ms * 1_000_000,
        x_mm,
        m,
        station: None,
        pass: None,
        source: (0, 0),
    }
}

#[test]
fn a_second_simulator_s_roll_is_recovered_within_u() {
    let tmp = tempfile::tempdir().unwrap();
    // Per group (a calm stage, a ringing one): stations within U, stations, Σ z².
    let mut groups = [(0usize, 0usize, 0.0f64); 2];
    for seed in 1..=32u64 {
        let campaign = tmp.path().join(format!("roll-{seed}"));
        // Even seeds: the stage rings for a second after each arrival.
        let settling_um = if seed % 2 == 0 { 2.0 } else { 0.0 };
        let truth = simulate(&campaign, seed, settling_um);
        let out = tmp.path().join(format!("out-{seed}"));
        let (code, said) = super::roll::run(&campaign, &out, &[]);
        assert_eq!(code, 0, "seed {seed}: {said}");
        let record = super::roll::json(&out.join("roll.json"));
        assert_eq!(record["passes"].as_array().unwrap().len(), 3, "seed {seed}");
        assert_eq!(record["level_datum"], false, "seed {seed}");
        let stations = record["stations"].as_array().unwrap();
        assert_eq!(stations.len(), STATIONS, "seed {seed}");
        let u_of = |s: &serde_json::Value| s["u_k2_urad"].as_f64().unwrap();
        // U(εx(n))² sums the station steps' variances (`docs/spec/machine-physics.md`: consecutive
        // steps share no reading): it grows with every station.
        for pair in stations.windows(2) {
            assert!(
                u_of(&pair[1]) > u_of(&pair[0]),
                "seed {seed}: U falls from {} to {}",
                pair[0],
                pair[1]
            );
        }
        for s in &stations[1..] {
            let n = s["station"].as_u64().unwrap() as usize;
            let error = s["roll_urad"].as_f64().unwrap() - truth[n];
            let u = u_of(s);
            let g = &mut groups[usize::from(settling_um > 0.0)];
            g.1 += 1;
            g.0 += usize::from(error.abs() <= u);
            g.2 += (error / (u / 2.0)).powi(2);
        }
    }
    for ((within, total, z2), stage) in groups.into_iter().zip(["calm", "ringing"]) {
        let share = within as f64 / total as f64;
        let rms_z = (z2 / total as f64).sqrt();
        eprintln!(
            "second roll simulator, {stage} stage: {within}/{total} within U, RMS z {rms_z:.3}"
        );
        assert!(share >= 0.90, "{stage}: {within}/{total} within U");
        assert!((0.6..=1.4).contains(&rms_z), "{stage}: RMS z {rms_z}");
    }
}
