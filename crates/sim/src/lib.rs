//! Campaign simulator with known truth (`docs/spec/physics.md`, `docs/spec/campaign-format.md`).
//!
//! [`generate`] turns a [`SimConfig`] into a [`Simulation`]: the manifest, the three tables and
//! the [`Truth`] (true parameters of every bar and of every effect switched on). It is
//! deterministic from `seed` (ChaCha8 streams, one per purpose and bar, so switching one effect
//! leaves every other random draw unchanged).
//!
//! How: the true room (T1 at bar height, T2 above, doors, plate, hidden channel) is computed on
//! a fine grid (`max_internal_step_s`, dividing the encoder period); each bar (in parallel)
//! integrates its first-order states exactly on that grid (`lag.rs`) from equilibrium with the
//! initial air, and logs quantized noisy counts every `sample_s` (`encoder.rs`). Bars rotate
//! over the plate lengths with handling gaps (`schedule.rs`); readings in the gaps are logged
//! at off-socket positions, for the pipeline to drop.
//!
//! For calibration and compensation (`docs/spec/physics.md`, the calibration unit): an optional
//! calibration phase visits every (plate length, tilt) with `tilt` events; reference bars then
//! stay on their lengths while working bars sit on a check length or a device; each bar's
//! counts follow its true geometric map `D(n, A)` (scale error, nonlinearity, cosine error,
//! zero offset, gravity sag, `geometry.rs`), and `[[mismatch]]` makes chosen bars different.
//!
//! The `axis` machine kind (`docs/spec/machine-formats.md`) has its own generator:
//! [`generate_axis`] from an [`AxisSimConfig`] (a simulation TOML with `kind = "axis"`,
//! [`is_axis_config`]), written by [`write_axis`]; so has the `probe` kind: [`generate_probe`]
//! from a [`ProbeSimConfig`] (`kind = "probe"`, [`is_probe_config`]), written by [`write_probe`].
//! [`is_axis_config`]), written by [`write_axis`]; the `roll` kind likewise ([`generate_roll`],
//! [`RollSimConfig`], [`is_roll_config`], [`write_roll`]).
//! The `volumetric` kind (seed 001) has its own module, [`volumetric`]: a simulation TOML with
//! `kind = "volumetric"` ([`volumetric::is_volumetric_config`]).

mod axis;
pub(crate) mod config;
mod encoder;
mod environment;
mod fleet;
mod geometry;
pub mod hexapod;
mod lag;
mod probe;
mod roll;
mod schedule;
pub(crate) mod truth;
pub mod volumetric;

use std::collections::BTreeMap;
use std::path::Path;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use dbbcal_core::campaign::{
    BarDecl, CampaignSection, DeclaredTime, Manifest, MountDecl, PlateSection, SensorDecl,
    SensorKind,
};
use dbbcal_core::series::{CampaignTables, Event, EventKind};

pub use axis::{
    generate_axis, is_axis_config, write_axis, AxisEffects, AxisEnvironment, AxisErrorConfig,
    AxisOutput, AxisSimConfig, AxisSimLaser, AxisSimLine, AxisSimulation, AxisTruth, Cosine,
    DeadPath, ErrorCurve, ErrorShape, LineTruth, MachineDrift, OpticsSlope, SensorError, Sine,
};
pub use config::{
    AirBetweenReadings, BarConfig, CalibrationPhase, Creep, DeviceLayout, EffectsConfig,
    FleetConfig, GenerationConfig, GeometryConfig, HeadHeating, HeadSchedule, HeadStart,
    HeatSource, HiddenChannel, Mismatch, PlateConfig, PlateExpansion, ReferenceMount, RoomConfig,
    SagConfig, SagForm, ScheduleConfig, SecondPath, SensorGradient, Settling, SimConfig,
    WorkingLayout,
};
pub use environment::{AIR_HIGH, AIR_LOW, PLATE};
pub use probe::{
    generate_probe, is_probe_config, write_probe, ProbeSimArtefact, ProbeSimConfig, ProbeSimOutput,
    ProbeSimPretravel, ProbeSimReversal, ProbeSimStylus, ProbeSimTouches, ProbeSimulation,
    ProbeTruth, TruthDirection, TruthTouch,
};
pub use roll::{
    generate_roll, is_roll_config, write_roll, RollRig, RollSampling, RollSimConfig,
    RollSimEffects, RollSimLevels, RollSimOutput, RollSimulation, RollTruth, RollTruthConfig,
};
pub use truth::{
    BarGeometry, BarTruth, ChannelTruth, HeadTruth, HeatTruth, MountTruth, PlateTruth,
    SecondPathTruth, Truth,
};

use encoder::{BarRun, BarSetup};
use environment::Environment;
use schedule::{BarPlan, PlannedMount, Site};

/// Largest fine grid (points) and total encoder rows accepted.
const MAX_GRID_POINTS: usize = 100_000_000;
const MAX_ENCODER_ROWS: usize = 500_000_000;

/// Why a simulation could not be configured, run or written.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A configuration value out of range (the words of `dbbcal_core::limits`) or not usable.
    #[error("simulation config: `{key}` {reason}")]
    Invalid {
        /// The key.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The configuration is not a valid `SimConfig` in TOML.
    #[error("simulation config: {0}")]
    Toml(#[from] toml::de::Error),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// `truth.json` could not be serialised.
    #[error("truth.json: {0}")]
    Json(#[from] serde_json::Error),
    /// A time, ns since the epoch, outside the representable range.
    #[error("time {0} ns outside the representable range")]
    Time(i64),
    /// Writing the campaign failed.
    #[error("writing the campaign: {0}")]
    Write(#[from] dbbcal_io::WriteError),
}

/// A simulated campaign: what `io::write_campaign` writes, plus the truth.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// The campaign's `campaign.toml`.
    pub manifest: Manifest,
    /// The campaign's encoder, temperature and event tables.
    pub tables: CampaignTables,
    /// What was simulated (written as `truth.json`).
    pub truth: Truth,
    /// Bar id -> noise-free thermal error (indicated − true, µm) of each encoder row; empty
    /// unless `record_true_error`.
    pub true_error_um: BTreeMap<String, Vec<f64>>,
    /// The `positions` log of a simulated hexapod (`positions/positions.parquet`), if any.
    pub positions: Option<dbbcal_io::Table>,
}

/// Seeded random streams, one per purpose (bar-indexed ones add the bar index).
pub(crate) mod streams {
    pub(crate) const ROOM: u64 = 1;
    pub(crate) const FLEET: u64 = 2;
    pub(crate) const HIDDEN: u64 = 3;
    pub(crate) const SENSOR: u64 = 10;
    pub(crate) const SCHEDULE: u64 = 1_000;
    pub(crate) const HEAD: u64 = 2_000;
    pub(crate) const BAR_EFFECTS: u64 = 3_000;
    pub(crate) const BAR_NOISE: u64 = 4_000;
    pub(crate) const GEOMETRY: u64 = 5_000;
    pub(crate) const HEAT_SOURCE: u64 = 6_000;
}

/// The random stream `stream` of seed `seed`.
pub(crate) fn stream_rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// Time base: encoder samples at `j * sample_ns`, fine grid at `i * step_s`, `steps_per_sample`
/// grid steps per sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Grid {
    pub(crate) sample_ns: i64,
    pub(crate) steps_per_sample: usize,
    pub(crate) step_s: f64,
    pub(crate) n_samples: usize,
    /// Campaign duration, whole seconds.
    pub(crate) duration_ns: i64,
}

impl Grid {
    pub(crate) fn new(cfg: &SimConfig) -> Result<Self, SimError> {
        let duration_ns = (cfg.duration_days * 86400.0).round() as i64 * 1_000_000_000;
        let sample_ns = (cfg.sample_s * 1e9).round() as i64;
        if duration_ns <= 0 || sample_ns <= 0 {
            return Err(SimError::Invalid {
                key: "duration_days".into(),
                reason: "shorter than a second".into(),
            });
        }
        let steps_per_sample = (cfg.sample_s / cfg.max_internal_step_s).ceil().max(1.0) as usize;
        let n_samples = ((duration_ns + sample_ns - 1) / sample_ns) as usize;
        let grid = Self {
            sample_ns,
            steps_per_sample,
            step_s: sample_ns as f64 * 1e-9 / steps_per_sample as f64,
            n_samples,
            duration_ns,
        };
        if grid.n_points() > MAX_GRID_POINTS {
            return Err(SimError::Invalid {
                key: "max_internal_step_s".into(),
                reason: "internal grid too fine for the duration".into(),
            });
        }
        Ok(grid)
    }

    pub(crate) fn n_points(&self) -> usize {
        self.n_samples
            .saturating_mul(self.steps_per_sample)
            .saturating_add(1)
    }

    pub(crate) fn duration_s(&self) -> f64 {
        self.duration_ns as f64 * 1e-9
    }
}

/// Generate a campaign from `cfg` (validated here). Deterministic from `cfg.seed`.
pub fn generate(cfg: &SimConfig) -> Result<Simulation, SimError> {
    cfg.validate()?;
    let grid = Grid::new(cfg)?;
    let bars = fleet::bar_truths(cfg);
    if grid.n_samples.saturating_mul(bars.len()) > MAX_ENCODER_ROWS {
        return Err(SimError::Invalid {
            key: "sample_s".into(),
            reason: "more than 5e8 encoder rows".into(),
        });
    }
    validate_named_bars(cfg, &bars)?;
    let start_ns = start_ns(cfg)?;
    let env = Environment::build(cfg, &grid);
    let plans: Vec<BarPlan> = bars
        .iter()
        .enumerate()
        .map(|(i, b)| schedule::plan_bar(cfg, &grid, i, &b.id))
        .collect();
    let device = simulate_hexapod(cfg, &grid, &env, &bars, &plans)?;
    let runs = run_bars(cfg, &grid, &env, &bars, &plans, start_ns, device.as_ref());
    let mut manifest = build_manifest(cfg, &bars, &plans, start_ns)?;
    let events = build_events(cfg, &grid, &env, &bars, &plans, start_ns);
    let mut truth = build_truth(cfg, &bars, &plans, &env, &runs, start_ns)?;
    let positions = device.map(|(run, h)| {
        add_device_to_manifest(cfg, h, &mut manifest);
        let table = positions_table(cfg, &run, start_ns);
        truth.device = Some(run.truth);
        table
    });
    let mut tables = CampaignTables {
        encoders: BTreeMap::new(),
        temperatures: env.sensor_logs(cfg, &grid, start_ns),
        events,
    };
    let mut true_error_um = BTreeMap::new();
    for (bar, run) in bars.iter().zip(runs) {
        if cfg.record_true_error {
            true_error_um.insert(bar.id.clone(), run.true_error_um);
        }
        tables.encoders.insert(bar.id.clone(), run.log);
    }
    Ok(Simulation {
        manifest,
        tables,
        truth,
        true_error_um,
        positions,
    })
}

/// The working device's hexapod section, when the campaign has one.
fn hexapod_layout(cfg: &SimConfig) -> Option<(&DeviceLayout, &hexapod::HexapodSim)> {
    let d = cfg.schedule.working.as_ref()?.device.as_ref()?;
    Some((d, d.hexapod.as_ref()?))
}

/// The simulated hexapod: leg tracks from the last leg's mount start, positions, truth.
fn simulate_hexapod<'c>(
    cfg: &'c SimConfig,
    grid: &Grid,
    env: &Environment,
    bars: &[BarTruth],
    plans: &[BarPlan],
) -> Result<Option<(hexapod::HexapodRun, &'c hexapod::HexapodSim)>, SimError> {
    let Some((d, h)) = hexapod_layout(cfg) else {
        return Ok(None);
    };
    let start_ns = bars
        .iter()
        .zip(plans)
        .filter(|(b, _)| d.bars.contains(&b.id))
        .flat_map(|(_, p)| p.mounts.iter())
        .filter(|m| matches!(m.site, Site::Device { .. }))
        .map(|m| m.from_ns)
        .max()
        .ok_or_else(|| SimError::Invalid {
            key: "schedule.working.device".into(),
            reason: "the hexapod's bars are never mounted on it (campaign too short?)".into(),
        })?;
    if start_ns + h.duration_ns() > grid.duration_ns {
        return Err(SimError::Invalid {
            key: "duration_days".into(),
            reason: format!(
                "too short for the hexapod test: it ends {:.2} days after the start",
                (start_ns + h.duration_ns()) as f64 / 86400e9
            ),
        });
    }
    // The bodies follow the mean air of the room (what the analysis takes without a sensor).
    let body_excess_k = |t_ns: i64| {
        let i = ((t_ns as f64 / 1e9 / grid.step_s).round().max(0.0) as usize)
            .min(env.t1_c.len().saturating_sub(1));
        0.5 * (env.t1_c[i] + env.t2_c[i]) - cfg.reference_temperature_c
    };
    Ok(Some((h.run(&d.id, cfg.seed, start_ns, &body_excess_k), h)))
}

/// The `[[device]]` table and the legs of the device's mounts (leg = index in `bars` + 1).
fn add_device_to_manifest(cfg: &SimConfig, h: &hexapod::HexapodSim, manifest: &mut Manifest) {
    let Some((d, _)) = hexapod_layout(cfg) else {
        return;
    };
    manifest.device.push(dbbcal_core::campaign::DeviceDecl {
        id: d.id.clone(),
        kind: dbbcal_core::campaign::DeviceKind::Hexapod,
        base_mm: h.base_mm.clone(),
        platform_mm: h.platform_mm.clone(),
        u_base_um: dbbcal_core::campaign::PerLeg::All(h.u_base_um),
        u_platform_um: dbbcal_core::campaign::PerLeg::All(h.u_platform_um),
        nominal_pose: h.nominal_pose,
        tool_point_mm: Some(h.tool_point_mm),
        base_orientation_deg: None,
        up: None,
        reference_mm: Some(h.reference_mm),
        cte_ppm_per_k: h.effects.declared_cte_ppm_per_k,
        sensor: None,
    });
    for m in &mut manifest.mount {
        if m.device.as_deref() == Some(d.id.as_str()) {
            m.leg = d.bars.iter().position(|b| b == &m.bar).map(|i| i as u8 + 1);
        }
    }
}

/// `positions/positions.parquet` of the simulated test.
fn positions_table(cfg: &SimConfig, run: &hexapod::HexapodRun, start_ns: i64) -> dbbcal_io::Table {
    let device = hexapod_layout(cfg).map_or(String::new(), |(d, _)| d.id.clone());
    let rows = &run.positions;
    let coordinate = |k: usize| dbbcal_io::Column::F64(rows.iter().map(|r| r.xyz_mm[k]).collect());
    dbbcal_io::Table {
        columns: vec![
            (
                "time".into(),
                dbbcal_io::Column::TimeNs(rows.iter().map(|r| start_ns + r.t_ns).collect()),
            ),
            (
                "device".into(),
                dbbcal_io::Column::Str(vec![device; rows.len()]),
            ),
            ("x_mm".into(), coordinate(0)),
            ("y_mm".into(), coordinate(1)),
            ("z_mm".into(), coordinate(2)),
            (
                "station".into(),
                dbbcal_io::Column::OptI64(rows.iter().map(|r| r.station).collect()),
            ),
            (
                "run".into(),
                dbbcal_io::Column::OptI64(rows.iter().map(|r| Some(r.run)).collect()),
            ),
        ],
    }
}

/// Every bar named in the schedule or a mismatch exists.
fn validate_named_bars(cfg: &SimConfig, bars: &[BarTruth]) -> Result<(), SimError> {
    let device_bars = cfg
        .schedule
        .working
        .iter()
        .flat_map(|w| w.device.iter())
        .flat_map(|d| d.bars.iter());
    let named = cfg
        .schedule
        .reference
        .iter()
        .enumerate()
        .map(|(i, r)| (format!("schedule.reference[{i}].bar"), &r.bar))
        .chain(
            device_bars
                .enumerate()
                .map(|(i, b)| (format!("schedule.working.device.bars[{i}]"), b)),
        )
        .chain(
            cfg.mismatch
                .iter()
                .enumerate()
                .map(|(i, m)| (format!("mismatch[{i}].bar"), &m.bar)),
        );
    for (key, id) in named {
        if !bars.iter().any(|b| &b.id == id) {
            return Err(SimError::Invalid {
                key,
                reason: format!("no bar `{id}`"),
            });
        }
    }
    Ok(())
}

fn start_ns(cfg: &SimConfig) -> Result<i64, SimError> {
    cfg.start
        .timestamp_nanos_opt()
        .ok_or_else(|| SimError::Invalid {
            key: "start".into(),
            reason: "outside 1677..2262".into(),
        })
}

/// Every bar in parallel (each has its own random streams: the order does not matter).
fn run_bars(
    cfg: &SimConfig,
    grid: &Grid,
    env: &Environment,
    bars: &[BarTruth],
    plans: &[BarPlan],
    start_ns: i64,
    device: Option<&(hexapod::HexapodRun, &hexapod::HexapodSim)>,
) -> Vec<BarRun> {
    let leg_of = |id: &str| {
        let (d, _) = hexapod_layout(cfg)?;
        let leg = d.bars.iter().position(|b| b == id)?;
        device.map(|(run, _)| &run.legs[leg])
    };
    let lengths_mm: Vec<f64> = cfg.plate.length.iter().map(|l| l.mm).collect();
    let plate_cte_ppm_per_k = true_plate_cte(cfg);
    bars.par_iter()
        .zip(plans.par_iter())
        .enumerate()
        .map(|(index, (bar, plan))| {
            let setup = BarSetup {
                bar,
                plan,
                index,
                lengths_mm: &lengths_mm,
                seed: cfg.seed,
                start_ns,
                reference_temperature_c: cfg.reference_temperature_c,
                noise_um: cfg.noise_um,
                plate_cte_ppm_per_k,
                record_true_error: cfg.record_true_error,
                leg_track: leg_of(&bar.id),
            };
            encoder::simulate_bar(&setup, env, grid)
        })
        .collect()
}

/// Declared plate expansion plus the undeclared `plate_expansion` effect, ppm/K.
fn true_plate_cte(cfg: &SimConfig) -> f64 {
    let pe = &cfg.effects.plate_expansion;
    cfg.plate.cte_ppm_per_k + if pe.enabled { pe.cte_ppm_per_k } else { 0.0 }
}

/// RFC 3339 (UTC, `Z`) of an absolute time in ns.
fn rfc3339(t_ns: i64) -> String {
    chrono::DateTime::from_timestamp_nanos(t_ns)
        .to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true)
}

fn build_manifest(
    cfg: &SimConfig,
    bars: &[BarTruth],
    plans: &[BarPlan],
    start_ns: i64,
) -> Result<Manifest, SimError> {
    // Campaigns with a calibration phase or a working layout state every mount's tilt.
    let explicit_tilts = cfg.schedule.calibration.is_some() || cfg.schedule.working.is_some();
    let mut mount = Vec::new();
    for (bar, plan) in bars.iter().zip(plans) {
        for m in &plan.mounts {
            let (length, device) = site_names(cfg, m);
            mount.push(MountDecl {
                bar: bar.id.clone(),
                length,
                device,
                leg: None,
                tilt_deg: (explicit_tilts || m.tilt_deg != cfg.plate.tilt_deg)
                    .then_some(m.tilt_deg),
                purpose: Some(m.purpose),
                from: DeclaredTime::at(start_ns + m.from_ns),
                to: DeclaredTime::at(start_ns + m.to_ns),
            });
        }
    }
    Ok(Manifest {
        campaign: CampaignSection {
            id: cfg.campaign_id.clone(),
            reference_temperature_c: cfg.reference_temperature_c,
        },
        plate: PlateSection {
            material: cfg.plate.material.clone(),
            cte_ppm_per_k: cfg.plate.cte_ppm_per_k,
            tilt_deg: cfg.plate.tilt_deg,
            length: cfg.plate.length.clone(),
        },
        sensor: sensor_decls(cfg),
        bar: bars
            .iter()
            .map(|b| BarDecl {
                id: b.id.clone(),
                resolution_nm: b.resolution_nm,
                fixed_length_mm: b.fixed_length_mm,
                sensor: Some(b.declared_sensor.clone()),
            })
            .collect(),
        mount,
        device: Vec::new(),
    })
}

/// The manifest's `length` and `device` of a mount (exactly one is `Some`).
fn site_names(cfg: &SimConfig, m: &PlannedMount) -> (Option<String>, Option<String>) {
    match &m.site {
        Site::Length(i) => (Some(cfg.plate.length[*i].id.clone()), None),
        Site::Device { id, .. } => (None, Some(id.clone())),
    }
}

fn sensor_decls(cfg: &SimConfig) -> Vec<SensorDecl> {
    let decl = |id: &str, kind| SensorDecl {
        id: id.into(),
        kind,
    };
    let mut sensors = vec![
        decl(AIR_LOW, SensorKind::Air),
        decl(AIR_HIGH, SensorKind::Air),
    ];
    if environment::logs_plate_sensor(cfg) {
        sensors.push(decl(PLATE, SensorKind::Plate));
    }
    if cfg.effects.hidden_channel.enabled {
        sensors.push(decl(
            &cfg.effects.hidden_channel.sensor_id,
            SensorKind::Other,
        ));
    }
    if cfg.effects.heat_source.enabled {
        sensors.push(decl(&cfg.effects.heat_source.sensor_id, SensorKind::Other));
    }
    sensors
}

/// Door openings and plate re-tilts (whole setup), handling gaps and head power switches (per
/// bar), sorted by time.
fn build_events(
    cfg: &SimConfig,
    grid: &Grid,
    env: &Environment,
    bars: &[BarTruth],
    plans: &[BarPlan],
    start_ns: i64,
) -> Vec<Event> {
    let event = |t_ns: i64, bar: Option<&str>, kind: EventKind, value: Option<f64>| Event {
        time_ns: start_ns + t_ns,
        bar: bar.map(str::to_string),
        kind,
        value,
    };
    let mut events: Vec<Event> = env
        .door_times_s
        .iter()
        .map(|&t| {
            event(
                (t * 1e9) as i64,
                None,
                EventKind::Other("door".into()),
                None,
            )
        })
        .collect();
    events.extend(
        schedule::plate_tilts(cfg, grid)
            .into_iter()
            .map(|(t, tilt)| event(t, None, EventKind::Tilt, Some(tilt))),
    );
    for (bar, plan) in bars.iter().zip(plans) {
        events.extend(
            plan.handling_ns
                .iter()
                .map(|&t| event(t, Some(&bar.id), EventKind::Handling, None)),
        );
        // Each switch flips the power: the first turns the head on unless it was powered.
        events.extend(plan.head_toggles_ns.iter().enumerate().map(|(k, &t)| {
            let on = (k % 2 == 0) != plan.head_powered_at_start;
            let value = if on { 1.0 } else { 0.0 };
            event(t, Some(&bar.id), EventKind::HeadPower, Some(value))
        }));
    }
    events.sort_by(|a, b| (a.time_ns, &a.bar, &a.kind).cmp(&(b.time_ns, &b.bar, &b.kind)));
    events
}

fn build_truth(
    cfg: &SimConfig,
    bars: &[BarTruth],
    plans: &[BarPlan],
    env: &Environment,
    runs: &[BarRun],
    start_ns: i64,
) -> Result<Truth, SimError> {
    let lengths_mm: Vec<f64> = cfg.plate.length.iter().map(|l| l.mm).collect();
    let mut mounts = Vec::new();
    for (bar, plan) in bars.iter().zip(plans) {
        for m in &plan.mounts {
            let (length, device) = site_names(cfg, m);
            let length_mm = m.nominal_mm(&lengths_mm);
            mounts.push(MountTruth {
                bar: bar.id.clone(),
                length: length.unwrap_or_default(),
                device,
                tilt_deg: m.tilt_deg,
                purpose: m.purpose,
                from: rfc3339(start_ns + m.from_ns),
                to: rfc3339(start_ns + m.to_ns),
                length_mm,
                zero_counts: bar.counts_at(length_mm, m.tilt_deg),
                settling_um: cfg.effects.settling.enabled.then_some(m.settling_um),
            });
        }
    }
    Ok(Truth {
        config: cfg.clone(),
        effects_on: effects_on(&cfg.effects),
        plate: PlateTruth {
            declared_cte_ppm_per_k: cfg.plate.cte_ppm_per_k,
            true_cte_ppm_per_k: true_plate_cte(cfg),
            thermal_tau_s: cfg.plate.thermal_tau_s,
            sensor: environment::logs_plate_sensor(cfg).then(|| PLATE.to_string()),
        },
        bars: bars.to_vec(),
        mounts,
        n_door_events: env.door_times_s.len(),
        n_encoder_rows: runs.iter().map(|r| r.log.time_ns.len()).sum(),
        device: None,
    })
}

/// Names of the effects switched on, in catalogue order.
pub(crate) fn effects_on(e: &EffectsConfig) -> Vec<String> {
    [
        ("head_heating", e.head_heating.enabled),
        ("second_path", e.second_path.enabled),
        ("sensor_gradient", e.sensor_gradient.enabled),
        ("settling", e.settling.enabled),
        ("plate_expansion", e.plate_expansion.enabled),
        ("creep", e.creep.enabled),
        ("hidden_channel", e.hidden_channel.enabled),
        ("heat_source", e.heat_source.enabled),
    ]
    .into_iter()
    .filter(|(_, on)| *on)
    .map(|(name, _)| name.to_string())
    .collect()
}

/// Write the simulated campaign to `dir` (`io::write_campaign`: manifest and tables laid out
/// as `opts` says) and `truth.json` next to `campaign.toml`.
pub fn write(sim: &Simulation, dir: &Path, opts: &dbbcal_io::WriteOptions) -> Result<(), SimError> {
    dbbcal_io::write_campaign(dir, &sim.manifest, &sim.tables, opts)?;
    if let Some(table) = &sim.positions {
        let folder = dir.join("positions");
        std::fs::create_dir_all(&folder).map_err(|source| SimError::Io {
            path: folder.display().to_string(),
            source,
        })?;
        dbbcal_io::write_table(&folder.join("positions.parquet"), table)?;
    }
    write_truth(&sim.truth, dir)
}

/// Write `truth.json` (pretty) in `dir`, creating the directory.
pub(crate) fn write_truth(truth: &Truth, dir: &Path) -> Result<(), SimError> {
    let io_err = |source| SimError::Io {
        path: dir.display().to_string(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(io_err)?;
    let path = dir.join("truth.json");
    let text = serde_json::to_string_pretty(truth)?;
    std::fs::write(&path, text).map_err(|source| SimError::Io {
        path: path.display().to_string(),
        source,
    })
}

#[cfg(test)]
mod acceptance_tests;
#[cfg(test)]
mod tests;
