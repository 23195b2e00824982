//! Simulated `axis` campaigns with known truth (`docs/spec/machine-physics.md`, "Kind axis";
//! `docs/spec/machine-formats.md`, "Kind axis").
//!
//! [`generate_axis`] draws the six true errors of the axis (δx, δy, δz µm, εx, εy, εz µrad as
//! smooth curves of the target, zero at the first target: the axis's datum) from a seeded
//! ChaCha stream, and reads them through the forward model: a reading on line l at target x and
//! time t is one channel of Δ(p_l) = δ(x) + 10⁻³ ε(x) × p_l (+ the machine's drift g(t) when
//! switched on), p_l the line's reflector relative to the report point, taken since the line's
//! datum (its first target of run 1, so each line's laser datum constant is −Δ(p_l) there).
//!
//! - **Along the axis** the laser counts the optical path: OPL = n(t) (L_dead + L_m) −
//!   n(t_datum) L_dead, L_m = L cos θ_l (1 + α (T_m(t) − T0)) the true displacement L of the
//!   machine at its true temperature T_m. `compensation = "none"` reads OPL, `"air"` OPL / n_s,
//!   `"air+material"` OPL / n_s / (1 + α (T_s − T0)), n_s and T_s from the laser's sensors, which
//!   are what `environment/` logs (one row at every reading time). n is this crate's own
//!   modified Edlén ([`edlen`]). With no effect on, every mode gives exactly L back after the
//!   analysis' compensation: a sensor error, a dead path or a beam angle is an effect.
//! - **Lateral channels** read the straightness optics' line on top: a_l (drawn per line and
//!   channel) + b_l (x − x_datum), b_l = 0 unless `[effects.optics_slope]`.
//! - **Noise**: white, per reading: `laser.linear_noise_um` along, `straightness_noise_um`
//!   across. Every random stream is drawn in full whatever the effects, so switching an effect
//!   changes nothing else.
//!
//! Effects (`[effects]`, each off by default; their signatures are tested in `tests.rs`): dead
//! path, air sensor error (Edlén), material sensor error, cosine error per line, straightness
//! optics slope (moved between lines 1 and 2), machine thermal drift during the runs.
//!
//! Written ([`write_axis`]): the campaign through `dbbcal_io::write_axis_campaign`, the truth
//! as `truth.json` and `truth/axis_truth.parquet` (per target, the six true errors), which no
//! reader of the campaign opens.

mod config;
pub(crate) mod edlen;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::path::Path;

use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

pub use config::{
    AxisEffects, AxisEnvironment, AxisErrorConfig, AxisOutput, AxisSimConfig, AxisSimLaser,
    AxisSimLine, Cosine, DeadPath, ErrorShape, MachineDrift, OpticsSlope, SensorError,
};

use crate::{stream_rng, SimError};
use config::ResolvedLine;
use dbbcal_core::axis_campaign::{
    AxisCampaignTables, AxisMachineSection, AxisManifest, AxisReading, CampaignKind, Channel,
    EnvironmentRow, FixtureRow, FixtureSection, KindSection, LaserCompensation, LaserSection,
    LineDecl,
};

/// Random streams of the axis simulator (apart from the ballbar ones).
mod streams {
    pub(super) const TRUTH: u64 = 20_000;
    pub(super) const NOISE: u64 = 20_001;
    pub(super) const OPTICS: u64 = 20_002;
}

/// A simulated `axis` campaign: what `write_axis` writes, plus the truth.
#[derive(Debug, Clone)]
pub struct AxisSimulation {
    /// Its `campaign.toml`.
    pub manifest: AxisManifest,
    /// Its readings, fixture and environment rows.
    pub tables: AxisCampaignTables,
    /// What was simulated.
    pub truth: AxisTruth,
    /// Each reading's deviation without its noise (same order as `tables.readings`), µm.
    pub noise_free_deviation_um: Vec<f64>,
}

/// A sinusoid of an error curve: `amplitude · (sin(2π (x − x0)/period_mm + phase_rad) − sin(phase_rad))`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sine {
    /// Amplitude (µm or µrad).
    pub amplitude: f64,
    /// Period along the axis, mm.
    pub period_mm: f64,
    /// Phase at the datum, rad.
    pub phase_rad: f64,
}

/// One true error as a function of the target: with u = (x − x0)/travel,
/// `linear u + quadratic u² + cubic u³ + Σ sines`, zero at the datum x0 (µm or µrad).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorCurve {
    /// Coefficient of u.
    pub linear: f64,
    /// Coefficient of u².
    pub quadratic: f64,
    /// Coefficient of u³.
    pub cubic: f64,
    /// Periodic parts.
    pub sines: Vec<Sine>,
}

impl ErrorCurve {
    /// The value at `x_mm`, datum `x0_mm`, travel `travel_mm`.
    pub fn at(&self, x_mm: f64, x0_mm: f64, travel_mm: f64) -> f64 {
        let d = x_mm - x0_mm;
        let u = d / travel_mm;
        let poly = u * (self.linear + u * (self.quadratic + u * self.cubic));
        let tau = std::f64::consts::TAU;
        poly + self
            .sines
            .iter()
            .map(|s| {
                s.amplitude * ((tau * d / s.period_mm + s.phase_rad).sin() - s.phase_rad.sin())
            })
            .sum::<f64>()
    }
}

/// What one line truly was.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LineTruth {
    /// Line id.
    pub id: i64,
    /// The reflector point in F, mm.
    pub reflector_mm: [f64; 3],
    /// The channels read.
    pub channels: Vec<String>,
    /// The datum: first target of run 1, and its time (ns since the epoch).
    pub datum_target_mm: f64,
    /// Time of the datum reading, ns since the epoch.
    pub datum_time_ns: i64,
    /// The straightness optics' zero a_l per lateral channel, µm.
    pub optics_zero_um: BTreeMap<String, f64>,
    /// The straightness optics' slope b_l, µm/m.
    pub optics_slope_um_per_m: f64,
    /// The beam's angle to the motion, mrad.
    pub cosine_mrad: f64,
}

/// The truth of a simulated `axis` campaign (`truth.json`; the per-target table is also
/// `truth/axis_truth.parquet`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisTruth {
    /// The axis under test.
    pub axis: String,
    /// The ISO names of the six errors, in the order of `curves` and `errors` (δx, δy, δz in
    /// µm, εx, εy, εz in µrad).
    pub error_names: [String; 6],
    /// The datum (first target), mm; the errors are zero there.
    pub datum_mm: f64,
    /// The travel, mm.
    pub travel_mm: f64,
    /// The six curves.
    pub curves: Vec<ErrorCurve>,
    /// The targets, mm.
    pub target_mm: Vec<f64>,
    /// The six errors at each target.
    pub errors: Vec<[f64; 6]>,
    /// The lines.
    pub lines: Vec<LineTruth>,
    /// The report point, in F, mm.
    pub report_point_mm: [f64; 3],
    /// The effects switched on, with their sizes.
    pub effects: AxisEffects,
    /// What the laser applied.
    pub compensation: String,
}

impl AxisTruth {
    /// The six true errors at `x_mm` (δx, δy, δz µm; εx, εy, εz µrad).
    pub fn errors_at(&self, x_mm: f64) -> [f64; 6] {
        std::array::from_fn(|k| self.curves[k].at(x_mm, self.datum_mm, self.travel_mm))
    }

    /// The rigid-body displacement (µm, in M) at `x_mm` of a point at `p_mm` from the report
    /// point: δ + 10⁻³ ε × p.
    pub fn displacement_um(&self, x_mm: f64, p_mm: [f64; 3]) -> [f64; 3] {
        rigid_body(&self.errors_at(x_mm), p_mm)
    }
}

/// Δ(p) = δ + 10⁻³ ε × p (µm), `e` = (δx, δy, δz, εx, εy, εz).
fn rigid_body(e: &[f64; 6], p: [f64; 3]) -> [f64; 3] {
    let (d, w) = ([e[0], e[1], e[2]], [e[3], e[4], e[5]]);
    [
        d[0] + 1e-3 * (w[1] * p[2] - w[2] * p[1]),
        d[1] + 1e-3 * (w[2] * p[0] - w[0] * p[2]),
        d[2] + 1e-3 * (w[0] * p[1] - w[1] * p[0]),
    ]
}

/// The environment at a time: as it truly is, and as the laser's sensors read it.
#[derive(Debug, Clone, Copy)]
struct Air {
    air_c: f64,
    pressure_hpa: f64,
    humidity_pct: f64,
    material_c: f64,
}

fn true_environment(env: &AxisEnvironment, hours: f64) -> Air {
    let swing = env.air_swing_c * (std::f64::consts::TAU * hours * 1.5).sin();
    Air {
        air_c: env.air_c + env.air_drift_c_per_h * hours + swing,
        pressure_hpa: env.pressure_hpa + env.pressure_drift_hpa_per_h * hours,
        humidity_pct: (env.humidity_pct + env.humidity_drift_pct_per_h * hours).clamp(0.0, 100.0),
        material_c: env.material_c + env.material_drift_c_per_h * hours,
    }
}

fn sensed(fx: &AxisEffects, truth: Air, hours: f64) -> Air {
    let error = |s: &Option<SensorError>| {
        s.as_ref()
            .map_or(0.0, |s| s.bias_c + s.drift_c_per_h * hours)
    };
    Air {
        air_c: truth.air_c + error(&fx.air_sensor),
        material_c: truth.material_c + error(&fx.material_sensor),
        ..truth
    }
}

/// Draws the six curves (`[errors]`).
fn draw_curves(cfg: &AxisSimConfig) -> Vec<ErrorCurve> {
    let mut rng = stream_rng(cfg.seed, streams::TRUTH);
    let e = &cfg.errors;
    let travel_mm = cfg.last_target_mm - cfg.first_target_mm;
    let a = cfg.axis.index();
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    (0..6)
        .map(|k| {
            let (scale, linear_share) = if k == a {
                (e.positioning_um_per_m * travel_mm * 1e-3, 1.0)
            } else if k < 3 {
                (e.straightness_um, 0.3)
            } else if k - 3 == a {
                (e.roll_urad, 0.7)
            } else {
                (e.pitch_yaw_urad, 0.7)
            };
            // Every number is drawn whatever the shape, so the shape changes nothing else.
            let draws: [f64; 3] = std::array::from_fn(|_| unit.sample(&mut rng));
            let sines: Vec<Sine> = (0..2)
                .map(|_| Sine {
                    amplitude: unit.sample(&mut rng),
                    period_mm: travel_mm * rng.gen_range(0.15..0.6),
                    phase_rad: rng.gen_range(0.0..std::f64::consts::TAU),
                })
                .collect();
            let (poly, sine_share) = match e.shape {
                ErrorShape::Polynomial => (1.0, 0.0),
                ErrorShape::Sinusoid => (0.0, 0.4),
                ErrorShape::Mixed => (1.0, 0.15),
            };
            ErrorCurve {
                linear: scale * linear_share * draws[0],
                quadratic: poly * scale * 0.6 * draws[1],
                cubic: poly * scale * 0.4 * draws[2],
                sines: sines
                    .into_iter()
                    .map(|s| Sine {
                        amplitude: s.amplitude * scale * sine_share,
                        ..s
                    })
                    .collect(),
            }
        })
        .collect()
}

/// Generates an `axis` campaign from `cfg` (validated here). Deterministic from `cfg.seed`.
pub fn generate_axis(cfg: &AxisSimConfig) -> Result<AxisSimulation, SimError> {
    cfg.validate()?;
    let lines = cfg.resolved_lines()?;
    let start_ns = cfg
        .start
        .timestamp_nanos_opt()
        .ok_or(SimError::Time(i64::MAX))?;
    let x0 = cfg.first_target_mm;
    let travel_mm = cfg.last_target_mm - x0;
    let n = cfg.targets;
    let targets: Vec<f64> = (0..n)
        .map(|j| x0 + travel_mm * j as f64 / (n - 1) as f64)
        .collect();
    let curves = draw_curves(cfg);
    let fx = &cfg.effects;
    let alpha = cfg.cte_ppm_per_k * 1e-6;
    let t0_c = cfg.reference_temperature_c;
    let lambda = cfg.laser.wavelength_nm;
    let dead_mm = fx.dead_path.as_ref().map_or(0.0, |d| d.mm);
    let mut noise_rng = stream_rng(cfg.seed, streams::NOISE);
    let mut optics_rng = stream_rng(cfg.seed, streams::OPTICS);
    let linear_noise =
        Normal::new(0.0, cfg.laser.linear_noise_um).map_err(|_| SimError::Invalid {
            key: "laser.linear_noise_um".into(),
            reason: "not a standard deviation".into(),
        })?;
    let lateral_noise =
        Normal::new(0.0, cfg.laser.straightness_noise_um).map_err(|_| SimError::Invalid {
            key: "laser.straightness_noise_um".into(),
            reason: "not a standard deviation".into(),
        })?;
    let zero = Normal::new(0.0, cfg.laser.optics_zero_um).map_err(|_| SimError::Invalid {
        key: "laser.optics_zero_um".into(),
        reason: "not a standard deviation".into(),
    })?;
    let along = Channel::of_axis(cfg.axis);
    let interval_ns = (cfg.target_interval_s * 1e9).round() as i64;
    let change_ns = (cfg.line_change_s * 1e9).round() as i64;
    let hours = |t: i64| (t - start_ns) as f64 / 3.6e12;
    let drift = |t: i64| -> [f64; 3] {
        fx.drift.as_ref().map_or([0.0; 3], |d| {
            let h = match d.tau_h {
                Some(tau) => tau * (1.0 - (-hours(t) / tau).exp()),
                None => hours(t),
            };
            d.um_per_h.map(|r| r * h)
        })
    };
    let errors_at =
        |x: f64| -> [f64; 6] { std::array::from_fn(|k| curves[k].at(x, x0, travel_mm)) };
    // Machine displacement (µm, in M) of the reflector at target x and time t.
    let displacement = |x: f64, t: i64, p: [f64; 3]| -> [f64; 3] {
        let d = rigid_body(&errors_at(x), p);
        let g = drift(t);
        [d[0] + g[0], d[1] + g[1], d[2] + g[2]]
    };

    let mut readings = Vec::new();
    let mut noise_free = Vec::new();
    let mut environment = Vec::new();
    let mut fixture = Vec::new();
    let mut line_truths = Vec::new();
    let mut t = start_ns;
    for (l, line) in lines.iter().enumerate() {
        let p = std::array::from_fn(|k| line.reflector_mm[k] - cfg.report_point_mm[k]);
        let zeros: [f64; 3] = std::array::from_fn(|_| zero.sample(&mut optics_rng));
        let slope_um_per_m = fx.optics_slope.as_ref().map_or(0.0, |o| {
            if o.moved_between_lines && l >= 1 {
                o.moved_um_per_m
            } else {
                o.um_per_m
            }
        });
        let theta = fx
            .cosine
            .as_ref()
            .map_or(0.0, |c| c.mrad[l.min(c.mrad.len() - 1)] * 1e-3);
        let (datum_x, datum_t) = (targets[0], t);
        let datum_d = displacement(datum_x, datum_t, p);
        let datum_air = true_environment(&cfg.environment, hours(datum_t));
        let n_datum = edlen::refractive_index(
            lambda,
            datum_air.air_c,
            datum_air.pressure_hpa,
            datum_air.humidity_pct,
        );
        if cfg.output.write_fixture {
            fixture.push(FixtureRow {
                time_ns: t,
                line: line.id,
                reflector_mm: line.reflector_mm,
            });
        }
        for run in 1..=cfg.runs as i64 {
            let visits = (0..n)
                .map(|j| (j, 1i8))
                .chain((0..n).rev().map(|j| (j, -1i8)));
            for (j, direction) in visits {
                let x = targets[j];
                let h = hours(t);
                let air = true_environment(&cfg.environment, h);
                let seen = sensed(fx, air, h);
                let n_true =
                    edlen::refractive_index(lambda, air.air_c, air.pressure_hpa, air.humidity_pct);
                let n_laser = edlen::refractive_index(
                    lambda,
                    seen.air_c,
                    seen.pressure_hpa,
                    seen.humidity_pct,
                );
                let material_factor = 1.0 + alpha * (seen.material_c - t0_c);
                let env_factor_ppm = match cfg.laser.compensation {
                    LaserCompensation::None => None,
                    LaserCompensation::Air => Some((1.0 / n_laser - 1.0) * 1e6),
                    LaserCompensation::AirMaterial => {
                        Some((1.0 / (n_laser * material_factor) - 1.0) * 1e6)
                    }
                };
                environment.push(EnvironmentRow {
                    time_ns: t,
                    air_c: seen.air_c,
                    pressure_hpa: seen.pressure_hpa,
                    humidity_pct: seen.humidity_pct,
                    material_c: Some(seen.material_c),
                    env_factor_ppm,
                });
                let d = displacement(x, t, p);
                for &c in &line.channels {
                    let k = c.index();
                    let clean = if c == along {
                        let commanded_mm = x - datum_x;
                        let true_mm = commanded_mm + 1e-3 * (d[k] - datum_d[k]);
                        let machine_mm =
                            true_mm * theta.cos() * (1.0 + alpha * (air.material_c - t0_c));
                        let optical_mm = n_true * (dead_mm + machine_mm) - n_datum * dead_mm;
                        let read_mm = match cfg.laser.compensation {
                            LaserCompensation::None => optical_mm,
                            LaserCompensation::Air => optical_mm / n_laser,
                            LaserCompensation::AirMaterial => {
                                optical_mm / n_laser / material_factor
                            }
                        };
                        1e3 * (read_mm - commanded_mm)
                    } else {
                        d[k] - datum_d[k] + zeros[k] + 1e-3 * slope_um_per_m * (x - datum_x)
                    };
                    let noise = if c == along {
                        linear_noise.sample(&mut noise_rng)
                    } else {
                        lateral_noise.sample(&mut noise_rng)
                    };
                    noise_free.push(clean);
                    readings.push(AxisReading {
                        time_ns: t,
                        line: line.id,
                        run,
                        direction,
                        target_mm: x,
                        channel: c,
                        deviation_um: clean + noise,
                    });
                }
                t += interval_ns;
            }
        }
        line_truths.push(LineTruth {
            id: line.id,
            reflector_mm: line.reflector_mm,
            channels: line
                .channels
                .iter()
                .map(|c| c.as_str().to_string())
                .collect(),
            datum_target_mm: datum_x,
            datum_time_ns: datum_t,
            optics_zero_um: line
                .channels
                .iter()
                .filter(|&&c| c != along)
                .map(|c| (c.as_str().to_string(), zeros[c.index()]))
                .collect(),
            optics_slope_um_per_m: slope_um_per_m,
            cosine_mrad: theta * 1e3,
        });
        t += change_ns;
    }

    let manifest = manifest(cfg, &lines);
    let truth = AxisTruth {
        axis: cfg.axis.as_str().to_string(),
        error_names: cfg.axis.error_names(),
        datum_mm: x0,
        travel_mm,
        errors: targets.iter().map(|&x| errors_at(x)).collect(),
        target_mm: targets,
        curves,
        lines: line_truths,
        report_point_mm: cfg.report_point_mm,
        effects: cfg.effects.clone(),
        compensation: cfg.laser.compensation.as_str().to_string(),
    };
    Ok(AxisSimulation {
        manifest,
        tables: AxisCampaignTables {
            readings,
            fixture,
            environment,
        },
        truth,
        noise_free_deviation_um: noise_free,
    })
}

fn manifest(cfg: &AxisSimConfig, lines: &[ResolvedLine]) -> AxisManifest {
    AxisManifest {
        campaign: KindSection {
            kind: CampaignKind::Axis,
            id: cfg.campaign_id.clone(),
            reference_temperature_c: cfg.reference_temperature_c,
        },
        machine: AxisMachineSection {
            axis: cfg.axis,
            cte_ppm_per_k: cfg.cte_ppm_per_k,
        },
        laser: LaserSection {
            wavelength_nm: cfg.laser.wavelength_nm,
            compensation: cfg.laser.compensation,
            dead_path_mm: cfg
                .effects
                .dead_path
                .as_ref()
                .filter(|d| d.declared)
                .map(|d| d.mm),
        },
        line: lines
            .iter()
            .map(|l| LineDecl {
                id: l.id,
                reflector_mm: l.reflector_mm,
            })
            .collect(),
        fixture: Some(FixtureSection {
            u_um: cfg.fixture_u_um,
            report_point_mm: Some(cfg.report_point_mm),
        }),
        sensor: Vec::new(),
    }
}

/// Writes `sim` under `dir`: the campaign (`campaign.toml`, `readings/`, `fixture/`,
/// `environment/`) laid out as `output` says, `truth.json` and `truth/axis_truth.parquet`.
pub fn write_axis(
    sim: &AxisSimulation,
    dir: &Path,
    output: &AxisOutput,
    seed: u64,
) -> Result<(), SimError> {
    let opts = dbbcal_io::AxisWriteOptions {
        split_by_line: output.split_by_line,
        shuffle_rows: output.shuffle_rows,
        write_direction: output.write_direction,
        seed,
        ..Default::default()
    };
    dbbcal_io::write_axis_campaign(dir, &sim.manifest, &sim.tables, &opts)?;
    let truth = &sim.truth;
    let folder = dir.join("truth");
    std::fs::create_dir_all(&folder).map_err(|source| SimError::Io {
        path: folder.display().to_string(),
        source,
    })?;
    let mut table =
        dbbcal_io::Table::new().with("target_mm", dbbcal_io::Column::F64(truth.target_mm.clone()));
    for (k, name) in truth.error_names.iter().enumerate() {
        let unit = if k < 3 { "um" } else { "urad" };
        table = table.with(
            format!("{name}_{unit}"),
            dbbcal_io::Column::F64(truth.errors.iter().map(|e| e[k]).collect()),
        );
    }
    dbbcal_io::write_table(&folder.join("axis_truth.parquet"), &table)?;
    let path = dir.join("truth.json");
    let text = serde_json::to_string_pretty(truth)?;
    std::fs::write(&path, text).map_err(|source| SimError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Whether a simulation TOML asks for an `axis` campaign (top-level `kind = "axis"`).
pub fn is_axis_config(text: &str) -> Result<bool, SimError> {
    let table: toml::Table = toml::from_str(text)?;
    Ok(match table.get("kind") {
        None => false,
        Some(toml::Value::String(s)) if s == "axis" => true,
        Some(other) => {
            return Err(SimError::Invalid {
                key: "kind".into(),
                reason: format!(
                    "is {other}: give kind = \"axis\" for an axis campaign, or no `kind` for a ballbar campaign"
                ),
            })
        }
    })
}
