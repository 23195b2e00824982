//! Simulated `roll` campaigns with known truth (`docs/spec/machine-physics.md`, "Kind roll";
//! `docs/spec/machine-formats.md`, "Kind roll"), written from the spec independently of the
//! analysis.
//!
//! The stage carries a surface z(u, y) = f₁(u) (1 − y/L) + f₂(u) y/L (f₁ under A–B, f₂ under
//! C–D, each a sum of three sines, the seed's trigonometric form), u the surface coordinate. At
//! stage position q (in steps from station 0, continuous while moving) the surface point under
//! R's origin is u₀ + q s_true and a probe at (x_P, y_P) in R reads, in µm,
//! (1 + g_P) [z(u₀ + q s_true + x_P, y_P) + δz(q) + 10⁻³ (εx(q, t) y_P − εy(q) x_P)] + o_P(t)
//! plus noise, rounded to the resolution, then divided by `um_per_v` when the unit is V
//! (`docs/spec/machine-physics.md`'s rigid-body rule; with nominal positions, g = 0 and
//! s_true = d these are the spec's four reading equations). The errors at stations are drawn
//! (`smooth`: a random sum of sines over the travel; `random`: i.i.d., the seed's simulation)
//! and interpolated linearly between them; εx(q, t) = εx(q) + ω t (roll drift), o_P(t) = o_P +
//! ρ_P t (zero drift). Samples at `rate_hz` through dwells and the moves between them (the
//! move's readings are kept in the log: the reader must leave them out). Passes alternate
//! direction; a back pass starts with its own dwell at the turning station.
//!
//! Truth (`truth.json`, `truth/roll_truth.parquet`): per station, x_mm, εx relative to station
//! 0 and the axis's roll error (−b_to_a εx), which no reader of the campaign opens.

mod config;
#[cfg(test)]
mod tests;

use std::path::Path;

use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

pub use config::{
    RollRig, RollSampling, RollSimConfig, RollSimEffects, RollSimLevels, RollSimOutput,
    RollTruthConfig,
};

use crate::{stream_rng, SimError};
use dbbcal_core::axis_campaign::{CampaignKind, KindSection};
use dbbcal_core::roll_campaign::{
    LevelRow, ProbeDecl, ProbeSample, ReadingUnit, RollCampaignTables, RollManifest, RollSection,
};

mod streams {
    pub(super) const TRUTH: u64 = 40_000;
    pub(super) const NOISE: u64 = 40_001;
    pub(super) const LEVELS: u64 = 40_002;
}

/// What was simulated.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RollTruth {
    /// Station x_mm.
    pub x_mm: Vec<f64>,
    /// εx at each station minus εx at station 0, µrad (at the campaign's start: no drift).
    pub roll_urad: Vec<f64>,
    /// The axis's roll error, −b_to_a · εx, µrad.
    pub roll_error_urad: Vec<f64>,
    /// εy, µrad, and δz, µm, per station.
    pub pitch_urad: Vec<f64>,
    /// δz per station, µm.
    pub dz_um: Vec<f64>,
    /// The combined offset o_C − o_D − o_A + o_B, µm.
    pub combined_offset_um: f64,
    /// The effects switched on.
    pub effects: RollSimEffects,
}

/// A simulated `roll` campaign.
#[derive(Debug, Clone)]
pub struct RollSimulation {
    /// Its `campaign.toml`.
    pub manifest: RollManifest,
    /// Its samples and level readings.
    pub tables: RollCampaignTables,
    /// What was simulated.
    pub truth: RollTruth,
}

/// One sine term: amplitude, ω (rad per unit), phase.
type Term = (f64, f64, f64);

fn sines(terms: &[Term], v: f64) -> f64 {
    terms.iter().map(|(a, w, p)| a * (w * v + p).sin()).sum()
}

/// The true stage and surface.
struct Stage {
    f1: Vec<Term>,
    f2: Vec<Term>,
    roll: Vec<f64>,
    pitch: Vec<f64>,
    dz: Vec<f64>,
}

impl Stage {
    fn draw(cfg: &RollSimConfig) -> Stage {
        let mut rng = stream_rng(cfg.seed, streams::TRUTH);
        let t = &cfg.truth;
        let n = cfg.rig.stations;
        let w = t.profile_omega_per_mm;
        let profile = |rng: &mut rand_chacha::ChaCha8Rng| -> Vec<Term> {
            (0..3)
                .map(|_| {
                    (
                        rng.gen_range(-1.0..=1.0) * t.profile_um,
                        rng.gen_range(-1.0..=1.0) * w,
                        rng.gen_range(0.0..std::f64::consts::TAU),
                    )
                })
                .collect()
        };
        let f1 = profile(&mut rng);
        let f2 = profile(&mut rng);
        let curve = |amp: f64, rng: &mut rand_chacha::ChaCha8Rng| -> Vec<f64> {
            if t.shape == "random" {
                return (0..n).map(|_| rng.gen_range(-1.0..=1.0) * amp).collect();
            }
            let terms: Vec<Term> = (1..=3)
                .map(|k| {
                    (
                        amp / f64::from(k) * rng.gen_range(0.3..=1.0),
                        std::f64::consts::PI * f64::from(k) / n as f64,
                        rng.gen_range(0.0..std::f64::consts::TAU),
                    )
                })
                .collect();
            (0..n).map(|i| sines(&terms, i as f64)).collect()
        };
        let roll = curve(t.roll_urad, &mut rng);
        let pitch = curve(t.pitch_urad, &mut rng);
        let dz = curve(t.dz_um, &mut rng);
        Stage {
            f1,
            f2,
            roll,
            pitch,
            dz,
        }
    }

    /// A station quantity at continuous position q (linear between stations).
    fn at(values: &[f64], q: f64) -> f64 {
        let q = q.clamp(0.0, (values.len() - 1) as f64);
        let i = (q.floor() as usize).min(values.len() - 2);
        let f = q - i as f64;
        values[i] * (1.0 - f) + values[i + 1] * f
    }
}

/// The true positions of the probes in R, mm.
fn probe_positions(cfg: &RollSimConfig) -> [[f64; 2]; 4] {
    let (l, d) = (cfg.rig.l_mm, cfg.rig.d_mm);
    let nominal = [[0.0, 0.0], [d, 0.0], [0.0, l], [d, l]];
    std::array::from_fn(|k| {
        let e = cfg.effects.position_error_um[k];
        [nominal[k][0] + 1e-3 * e[0], nominal[k][1] + 1e-3 * e[1]]
    })
}

/// The four true rises (µm, before noise and quantisation) at position q, time t (h).
fn rises(cfg: &RollSimConfig, stage: &Stage, pos: &[[f64; 2]; 4], q: f64, t_h: f64) -> [f64; 4] {
    let e = &cfg.effects;
    let l = cfg.rig.l_mm;
    let s_true = cfg.rig.d_mm + 1e-3 * e.step_error_um;
    let u0 = 17.0 + q * s_true;
    let roll = Stage::at(&stage.roll, q) + e.roll_drift_urad_per_h * t_h;
    let pitch = Stage::at(&stage.pitch, q);
    let dz = Stage::at(&stage.dz, q);
    std::array::from_fn(|k| {
        let [x, y] = pos[k];
        let u = u0 + x;
        let surface = sines(&stage.f1, u) * (1.0 - y / l) + sines(&stage.f2, u) * (y / l);
        let rise = surface + dz + 1e-3 * (roll * y - pitch * x);
        (1.0 + e.gain[k]) * rise + e.offset_um[k] + e.zero_drift_um_per_h[k] * t_h
    })
}

/// The order of stations visited, per pass.
fn pass_orders(cfg: &RollSimConfig) -> Vec<Vec<usize>> {
    let n = cfg.rig.stations;
    (0..cfg.sampling.passes)
        .map(|p| {
            if cfg.sampling.alternate && p % 2 == 1 {
                (0..n).rev().collect()
            } else {
                (0..n).collect()
            }
        })
        .collect()
}

/// Simulate the campaign `cfg` describes.
pub fn generate_roll(cfg: &RollSimConfig) -> Result<RollSimulation, SimError> {
    cfg.validate()?;
    let stage = Stage::draw(cfg);
    let pos = probe_positions(cfg);
    let mut noise_rng = stream_rng(cfg.seed, streams::NOISE);
    let mut level_rng = stream_rng(cfg.seed, streams::LEVELS);
    let normal = Normal::new(0.0, 1.0).map_err(|e| SimError::Invalid {
        key: "sampling.noise_um".into(),
        reason: e.to_string(),
    })?;
    let s = &cfg.sampling;
    let rig = &cfg.rig;
    let start_ns = cfg.start.timestamp_nanos_opt().ok_or(SimError::Time(0))?;
    let dt_ns = (1e9 / s.rate_hz).round() as i64;
    let per_dwell = (s.dwell_s * s.rate_hz).round().max(1.0) as usize;
    let per_move = (s.move_s * s.rate_hz).round().max(1.0) as usize;
    let x_of = |q: f64| rig.x_first_mm + f64::from(rig.b_to_a as i32) * q * rig.d_mm;
    let volts = |um: f64| match rig.unit {
        ReadingUnit::Um => um,
        ReadingUnit::Volt => um / rig.um_per_v,
    };
    let mut samples = Vec::new();
    let mut levels = Vec::new();
    let mut now = start_ns;
    let mut read =
        |q: f64, now: i64, station: Option<i64>, pass: i64, out: &mut Vec<ProbeSample>| {
            let t_h = (now - start_ns) as f64 / 3.6e12;
            let m = rises(cfg, &stage, &pos, q, t_h).map(|v| {
                let v = v + s.noise_um * normal.sample(&mut noise_rng);
                let v = if s.resolution_um > 0.0 {
                    (v / s.resolution_um).round() * s.resolution_um
                } else {
                    v
                };
                volts(v)
            });
            out.push(ProbeSample {
                time_ns: now,
                x_mm: x_of(q),
                m,
                station,
                pass: Some(pass),
                source: (0, 0),
            });
        };
    // Every visit (pass, station) in time order; a move between consecutive visits (a short
    // move away and back when the next visit is at the same station: the turn of a pass).
    let orders = pass_orders(cfg);
    let visits: Vec<(usize, usize, bool)> = orders
        .iter()
        .enumerate()
        .flat_map(|(p, order)| {
            let last = order.len() - 1;
            order
                .iter()
                .enumerate()
                .map(move |(k, &n)| (p, n, k == 0 || k == last))
        })
        .collect();
    for (v, &(p, n, at_end)) in visits.iter().enumerate() {
        let pass = p as i64 + 1;
        let q = n as f64;
        for j in 0..per_dwell {
            read(q, now, Some(n as i64), pass, &mut samples);
            if cfg.levels.write && at_end && j == per_dwell / 2 {
                let t_h = (now - start_ns) as f64 / 3.6e12;
                let roll = stage.roll[n] + cfg.effects.roll_drift_urad_per_h * t_h;
                levels.push(LevelRow {
                    time_ns: now,
                    roll_urad: roll
                        + cfg.levels.zero_urad
                        + cfg.levels.u_urad * normal.sample(&mut level_rng),
                    u_urad: Some(cfg.levels.u_urad),
                    source: (0, 0),
                });
            }
            now += dt_ns;
        }
        let Some(&(next_pass, next, _)) = visits.get(v + 1) else {
            continue;
        };
        for j in 1..=per_move {
            let f = j as f64 / (per_move + 1) as f64;
            let qm = if next == n {
                q + 0.25 * (std::f64::consts::PI * f).sin()
            } else {
                q + (next as f64 - q) * f
            };
            let moving_pass = if f < 0.5 { pass } else { next_pass as i64 + 1 };
            read(qm, now, None, moving_pass, &mut samples);
            now += dt_ns;
        }
    }
    let manifest = manifest(cfg);
    let truth = truth(cfg, &stage, &x_of);
    Ok(RollSimulation {
        manifest,
        tables: RollCampaignTables {
            samples,
            write_station: s.station_column,
            write_pass: s.pass_column,
            levels,
        },
        truth,
    })
}

fn manifest(cfg: &RollSimConfig) -> RollManifest {
    let rig = &cfg.rig;
    RollManifest {
        campaign: KindSection {
            kind: CampaignKind::Roll,
            id: cfg.campaign_id.clone(),
            reference_temperature_c: 20.0,
        },
        roll: RollSection {
            axis: rig.axis,
            l_mm: rig.l_mm,
            d_mm: rig.d_mm,
            s_mm: rig.d_mm,
            b_to_a: rig.b_to_a,
            unit: rig.unit,
            dwell_min_s: (0.6 * cfg.sampling.dwell_s).min(2.0),
            dwell_tol_um: 2.0,
            probe: ["A", "B", "C", "D"]
                .iter()
                .map(|id| ProbeDecl {
                    id: id.to_string(),
                    u_xy_um: rig.u_xy_um,
                    um_per_v: rig.um_per_v,
                    xy_mm: None,
                })
                .collect(),
        },
    }
}

fn truth(cfg: &RollSimConfig, stage: &Stage, x_of: &dyn Fn(f64) -> f64) -> RollTruth {
    let n = cfg.rig.stations;
    let roll: Vec<f64> = stage.roll.iter().map(|r| r - stage.roll[0]).collect();
    let o = cfg.effects.offset_um;
    RollTruth {
        x_mm: (0..n).map(|i| x_of(i as f64)).collect(),
        roll_error_urad: roll.iter().map(|r| -(cfg.rig.b_to_a as f64) * r).collect(),
        roll_urad: roll,
        pitch_urad: stage.pitch.clone(),
        dz_um: stage.dz.clone(),
        combined_offset_um: o[2] - o[3] - o[0] + o[1],
        effects: cfg.effects.clone(),
    }
}

/// Writes the campaign through `dbbcal_io::write_roll_campaign`, and its truth.
pub fn write_roll(sim: &RollSimulation, dir: &Path, cfg: &RollSimConfig) -> Result<(), SimError> {
    let out = &cfg.output;
    let opts = dbbcal_io::RollWriteOptions {
        split_by_pass: out.split_by_pass,
        time_unit: if out.ms {
            dbbcal_io::TimeUnit::Ms
        } else {
            dbbcal_io::TimeUnit::Ns
        },
        shuffle_rows: out.shuffle_rows,
        int32: out.int32,
        seed: cfg.seed,
    };
    let mut tables = sim.tables.clone();
    if !cfg.sampling.pass_column && !out.split_by_pass {
        for s in &mut tables.samples {
            s.pass = None;
        }
    }
    dbbcal_io::write_roll_campaign(dir, &sim.manifest, &tables, &opts)?;
    let folder = dir.join("truth");
    std::fs::create_dir_all(&folder).map_err(|source| SimError::Io {
        path: folder.display().to_string(),
        source,
    })?;
    let t = &sim.truth;
    let table = dbbcal_io::Table::new()
        .with(
            "station",
            dbbcal_io::Column::I64((0..t.x_mm.len() as i64).collect()),
        )
        .with("x_mm", dbbcal_io::Column::F64(t.x_mm.clone()))
        .with("ex_urad", dbbcal_io::Column::F64(t.roll_urad.clone()))
        .with(
            "roll_error_urad",
            dbbcal_io::Column::F64(t.roll_error_urad.clone()),
        );
    dbbcal_io::write_table(&folder.join("roll_truth.parquet"), &table)?;
    let path = dir.join("truth.json");
    let text = serde_json::to_string_pretty(t)?;
    std::fs::write(&path, text).map_err(|source| SimError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Whether a simulation TOML asks for a `roll` campaign (top-level `kind = "roll"`); any other
/// kind, or none, is not this simulator's.
pub fn is_roll_config(text: &str) -> Result<bool, SimError> {
    let table: toml::Table = toml::from_str(text)?;
    Ok(matches!(table.get("kind"), Some(toml::Value::String(s)) if s == "roll"))
}
