//! [`AxisSimConfig`]: an `axis` campaign to simulate (`pipelines/sim-axis.toml`), selected in
//! a simulation TOML by the top-level `kind = "axis"`. Every key has a default (an empty file
//! with `kind = "axis"` is a valid X-axis campaign); every effect a model may miss is off unless
//! its table is given. [`AxisSimConfig::validate`] names the key that is wrong.

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use crate::SimError;
use dbbcal_core::axis_campaign::{CampaignKind, Channel, LaserCompensation, MachineAxis};

/// The whole configuration of a simulated `axis` campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisSimConfig {
    /// Must be `"axis"` (what makes `dbbcal simulate` read this configuration).
    #[serde(with = "dbbcal_io::manifest::as_written::campaign_kind")]
    pub kind: CampaignKind,
    /// Seed of every random draw.
    pub seed: u64,
    /// Campaign id written to the manifest.
    pub campaign_id: String,
    /// When the first reading is taken (UTC).
    #[serde(with = "crate::config::start_time")]
    pub start: DateTime<Utc>,
    /// The axis under test.
    #[serde(with = "dbbcal_io::manifest::as_written::machine_axis")]
    pub axis: MachineAxis,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Expansion of the machine's scales, ppm/K (manifest and truth).
    pub cte_ppm_per_k: f64,
    /// First target (the axis's datum, where the true errors are zero), mm.
    pub first_target_mm: f64,
    /// Last target, mm.
    pub last_target_mm: f64,
    /// Number of equally spaced targets (10–20 in ISO 230-2 practice).
    pub targets: usize,
    /// Runs of each line; each run goes up through the targets, then down (the turn target is
    /// read twice), so this is also the runs in each direction.
    pub runs: usize,
    /// Time from one target reading to the next, s.
    pub target_interval_s: f64,
    /// Time to set up the next line, s.
    pub line_change_s: f64,
    /// The lines; empty: the patent's three for the axis (`docs/spec/machine-formats.md`).
    pub lines: Vec<AxisSimLine>,
    /// Where translational errors are reported, in F, mm.
    pub report_point_mm: [f64; 3],
    /// `[fixture] u_um` of the manifest.
    pub fixture_u_um: f64,
    /// The laser.
    pub laser: AxisSimLaser,
    /// How the six true errors are drawn.
    pub errors: AxisErrorConfig,
    /// The room's air and the machine's temperature, as they truly are.
    pub environment: AxisEnvironment,
    /// Effects a model may miss, each off unless given.
    pub effects: AxisEffects,
    /// How the files are laid out (exercising the reader rules).
    pub output: AxisOutput,
}

/// One simulated line.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisSimLine {
    /// Line id.
    pub id: i64,
    /// The reflector point in F, mm (manifest and fixture rows).
    pub reflector_mm: [f64; 3],
    /// The channels read (`dx`, `dy`, `dz`).
    pub channels: Vec<String>,
}

/// `[laser]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisSimLaser {
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// What the laser applies to its readings (written to the manifest).
    #[serde(with = "dbbcal_io::manifest::as_written::laser_compensation")]
    pub compensation: LaserCompensation,
    /// Noise of the along-axis (linear) readings, µm (standard deviation).
    pub linear_noise_um: f64,
    /// Noise of the straightness readings, µm.
    pub straightness_noise_um: f64,
    /// Standard deviation of the straightness optics' zero `a_l` per line and channel, µm.
    pub optics_zero_um: f64,
}

/// The shape of the true error curves.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ErrorShape {
    /// A cubic in the target.
    Polynomial,
    /// A line plus two sinusoids (screw-pitch-like periods).
    Sinusoid,
    /// Both.
    Mixed,
}

/// `[errors]`: the sizes of the six true errors (`machine-physics.md`, "Typical magnitudes").
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisErrorConfig {
    /// Shape of every curve.
    pub shape: ErrorShape,
    /// Positioning error slope (standard deviation), µm per metre of travel.
    pub positioning_um_per_m: f64,
    /// Straightness (each lateral translation), µm over the travel.
    pub straightness_um: f64,
    /// Pitch and yaw, µrad over the travel.
    pub pitch_yaw_urad: f64,
    /// Roll, µrad over the travel.
    pub roll_urad: f64,
}

/// `[environment]`: the true air and machine temperature, linear drifts from the start plus a
/// slow air-conditioning swing.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisEnvironment {
    /// Air temperature at the start, °C.
    pub air_c: f64,
    /// Its drift, K/h.
    pub air_drift_c_per_h: f64,
    /// Amplitude of the air conditioning's swing (period 40 min), K.
    pub air_swing_c: f64,
    /// Pressure at the start, hPa.
    pub pressure_hpa: f64,
    /// Its drift, hPa/h.
    pub pressure_drift_hpa_per_h: f64,
    /// Relative humidity at the start, %.
    pub humidity_pct: f64,
    /// Its drift, %/h.
    pub humidity_drift_pct_per_h: f64,
    /// Machine (material) temperature at the start, °C.
    pub material_c: f64,
    /// Its drift, K/h.
    pub material_drift_c_per_h: f64,
}

/// `[effects]`: each a table; absent = off.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields, default)]
pub struct AxisEffects {
    /// Dead path: optics to reflector at the datum, not compensated by the laser.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dead_path: Option<DeadPath>,
    /// Edlén error: the laser's air sensor reads wrong (bias and drift).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub air_sensor: Option<SensorError>,
    /// The laser's material sensor reads wrong.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub material_sensor: Option<SensorError>,
    /// The beam at an angle to the motion, per line.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cosine: Option<Cosine>,
    /// A slope of the straightness optics.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optics_slope: Option<OpticsSlope>,
    /// Machine thermal drift of the functional point during the runs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drift: Option<MachineDrift>,
}

/// `[effects.dead_path]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DeadPath {
    /// The true dead path, mm.
    pub mm: f64,
    /// Write it as `laser.dead_path_mm` in the manifest (so an analysis may correct it).
    #[serde(default = "yes")]
    pub declared: bool,
}

fn yes() -> bool {
    true
}

/// `[effects.air_sensor]`, `[effects.material_sensor]`: logged = true + bias + drift × hours.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields, default)]
pub struct SensorError {
    /// Constant error, K.
    pub bias_c: f64,
    /// Error growing with time from the start, K/h.
    pub drift_c_per_h: f64,
}

/// `[effects.cosine]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Cosine {
    /// The beam's angle to the motion per line (in line order; the last repeats), mrad.
    pub mrad: Vec<f64>,
}

/// `[effects.optics_slope]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OpticsSlope {
    /// Slope of the straightness optics on every lateral channel, µm/m.
    pub um_per_m: f64,
    /// The optics were moved between the first two lines: from the second line on, the slope is
    /// `moved_um_per_m` instead.
    #[serde(default)]
    pub moved_between_lines: bool,
    /// The slope after the move, µm/m.
    #[serde(default)]
    pub moved_um_per_m: f64,
}

/// `[effects.drift]`: g(t) = rate × hours since the start, per component of M; with `tau_h`,
/// a warm-up levelling off: g(t) = rate × τ (1 − e^(−t/τ)).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MachineDrift {
    /// Drift of the functional point along X, Y, Z, µm/h (the initial rate with `tau_h`).
    pub um_per_h: [f64; 3],
    /// The warm-up's time constant, h; absent: a constant rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_h: Option<f64>,
}

/// `[output]`: the layout of the files.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisOutput {
    /// One readings file per line.
    pub split_by_line: bool,
    /// Shuffle the rows inside each file.
    pub shuffle_rows: bool,
    /// Write the optional `direction` column.
    pub write_direction: bool,
    /// Write the fixture rows (else the reader falls back on the manifest's points).
    pub write_fixture: bool,
}

impl Default for AxisOutput {
    fn default() -> Self {
        Self {
            split_by_line: false,
            shuffle_rows: false,
            write_direction: true,
            write_fixture: true,
        }
    }
}

impl Default for AxisSimConfig {
    fn default() -> Self {
        Self {
            kind: CampaignKind::Axis,
            seed: 2,
            campaign_id: "sim-axis".into(),
            start: DateTime::parse_from_rfc3339("2026-12-01T08:00:00Z")
                .map(|t| t.with_timezone(&Utc))
                .unwrap_or_default(),
            axis: MachineAxis::X,
            reference_temperature_c: 20.0,
            cte_ppm_per_k: 11.5,
            first_target_mm: 0.0,
            last_target_mm: 700.0,
            targets: 15,
            runs: 5,
            target_interval_s: 6.0,
            line_change_s: 1800.0,
            lines: Vec::new(),
            report_point_mm: [0.0; 3],
            fixture_u_um: 5.0,
            laser: AxisSimLaser::default(),
            errors: AxisErrorConfig::default(),
            environment: AxisEnvironment::default(),
            effects: AxisEffects::default(),
            output: AxisOutput::default(),
        }
    }
}

impl Default for AxisSimLaser {
    fn default() -> Self {
        Self {
            wavelength_nm: 632.990577,
            compensation: LaserCompensation::AirMaterial,
            linear_noise_um: 0.02,
            straightness_noise_um: 0.2,
            optics_zero_um: 2.0,
        }
    }
}

impl Default for AxisErrorConfig {
    fn default() -> Self {
        Self {
            shape: ErrorShape::Mixed,
            positioning_um_per_m: 6.0,
            straightness_um: 4.0,
            pitch_yaw_urad: 20.0,
            roll_urad: 10.0,
        }
    }
}

impl Default for AxisEnvironment {
    fn default() -> Self {
        Self {
            air_c: 20.4,
            air_drift_c_per_h: 0.3,
            air_swing_c: 0.1,
            pressure_hpa: 1008.0,
            pressure_drift_hpa_per_h: -0.4,
            humidity_pct: 45.0,
            humidity_drift_pct_per_h: 1.0,
            material_c: 20.8,
            material_drift_c_per_h: 0.2,
        }
    }
}

/// A line of the simulation, resolved: id, reflector point, channels.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ResolvedLine {
    pub(crate) id: i64,
    pub(crate) reflector_mm: [f64; 3],
    pub(crate) channels: Vec<Channel>,
}

impl AxisSimConfig {
    /// The lines: the configured ones, or the patent's three with the axis names permuted
    /// cyclically (X: line 1 at (0, 0, 0) reads dx, dy, dz; line 2 at (0, 0, 100) dx, dy; line 3
    /// at (0, 100, 100) dx).
    pub(crate) fn resolved_lines(&self) -> Result<Vec<ResolvedLine>, SimError> {
        if self.lines.is_empty() {
            let a = self.axis.index();
            let permute = |p: [f64; 3]| {
                let mut q = [0.0; 3];
                for (k, v) in p.iter().enumerate() {
                    q[(k + a) % 3] = *v;
                }
                q
            };
            let channel = |k: usize| Channel::ALL[(a + k) % 3];
            return Ok(vec![
                ResolvedLine {
                    id: 1,
                    reflector_mm: permute([0.0, 0.0, 0.0]),
                    channels: vec![channel(0), channel(1), channel(2)],
                },
                ResolvedLine {
                    id: 2,
                    reflector_mm: permute([0.0, 0.0, 100.0]),
                    channels: vec![channel(0), channel(1)],
                },
                ResolvedLine {
                    id: 3,
                    reflector_mm: permute([0.0, 100.0, 100.0]),
                    channels: vec![channel(0)],
                },
            ]);
        }
        self.lines
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let channels = l
                    .channels
                    .iter()
                    .map(|c| {
                        Channel::parse(c).ok_or_else(|| {
                            invalid(
                                &format!("lines[{i}].channels"),
                                &format!("{c:?} is not dx, dy or dz"),
                            )
                        })
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Ok(ResolvedLine {
                    id: l.id,
                    reflector_mm: l.reflector_mm,
                    channels,
                })
            })
            .collect()
    }

    /// Checks every value, naming the key.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.kind != CampaignKind::Axis {
            return Err(invalid("kind", "must be \"axis\" for this configuration"));
        }
        finite("reference_temperature_c", self.reference_temperature_c)?;
        finite("cte_ppm_per_k", self.cte_ppm_per_k)?;
        finite("first_target_mm", self.first_target_mm)?;
        finite("last_target_mm", self.last_target_mm)?;
        if self.last_target_mm <= self.first_target_mm {
            return Err(invalid("last_target_mm", "must be above first_target_mm"));
        }
        if !(2..=1000).contains(&self.targets) {
            return Err(invalid("targets", "must be 2 .. 1000"));
        }
        if !(1..=100).contains(&self.runs) {
            return Err(invalid("runs", "must be 1 .. 100"));
        }
        positive("target_interval_s", self.target_interval_s)?;
        non_negative("line_change_s", self.line_change_s)?;
        non_negative("fixture_u_um", self.fixture_u_um)?;
        for v in self.report_point_mm {
            finite("report_point_mm", v)?;
        }
        let lines = self.resolved_lines()?;
        let mut ids: Vec<i64> = lines.iter().map(|l| l.id).collect();
        ids.sort_unstable();
        ids.dedup();
        if ids.len() != lines.len() {
            return Err(invalid("lines", "line ids must be unique"));
        }
        for (i, l) in lines.iter().enumerate() {
            if l.channels.is_empty() {
                return Err(invalid(&format!("lines[{i}].channels"), "reads no channel"));
            }
            for v in l.reflector_mm {
                finite(&format!("lines[{i}].reflector_mm"), v)?;
            }
        }
        let laser = &self.laser;
        if !(200.0..=2000.0).contains(&laser.wavelength_nm) {
            return Err(invalid("laser.wavelength_nm", "must be 200 .. 2000 nm"));
        }
        non_negative("laser.linear_noise_um", laser.linear_noise_um)?;
        non_negative("laser.straightness_noise_um", laser.straightness_noise_um)?;
        non_negative("laser.optics_zero_um", laser.optics_zero_um)?;
        let e = &self.errors;
        non_negative("errors.positioning_um_per_m", e.positioning_um_per_m)?;
        non_negative("errors.straightness_um", e.straightness_um)?;
        non_negative("errors.pitch_yaw_urad", e.pitch_yaw_urad)?;
        non_negative("errors.roll_urad", e.roll_urad)?;
        let env = &self.environment;
        for (key, v) in [
            ("environment.air_c", env.air_c),
            ("environment.air_drift_c_per_h", env.air_drift_c_per_h),
            ("environment.air_swing_c", env.air_swing_c),
            ("environment.pressure_hpa", env.pressure_hpa),
            (
                "environment.pressure_drift_hpa_per_h",
                env.pressure_drift_hpa_per_h,
            ),
            ("environment.humidity_pct", env.humidity_pct),
            (
                "environment.humidity_drift_pct_per_h",
                env.humidity_drift_pct_per_h,
            ),
            ("environment.material_c", env.material_c),
            (
                "environment.material_drift_c_per_h",
                env.material_drift_c_per_h,
            ),
        ] {
            finite(key, v)?;
        }
        if !(800.0..=1100.0).contains(&env.pressure_hpa) {
            return Err(invalid(
                "environment.pressure_hpa",
                "must be 800 .. 1100 hPa",
            ));
        }
        if !(0.0..=100.0).contains(&env.humidity_pct) {
            return Err(invalid("environment.humidity_pct", "must be 0 .. 100 %"));
        }
        let fx = &self.effects;
        if let Some(d) = &fx.dead_path {
            non_negative("effects.dead_path.mm", d.mm)?;
        }
        for (key, s) in [
            ("effects.air_sensor", &fx.air_sensor),
            ("effects.material_sensor", &fx.material_sensor),
        ] {
            if let Some(s) = s {
                finite(&format!("{key}.bias_c"), s.bias_c)?;
                finite(&format!("{key}.drift_c_per_h"), s.drift_c_per_h)?;
            }
        }
        if let Some(c) = &fx.cosine {
            if c.mrad.is_empty() {
                return Err(invalid("effects.cosine.mrad", "gives no angle"));
            }
            if c.mrad.iter().any(|m| !m.is_finite() || m.abs() > 100.0) {
                return Err(invalid(
                    "effects.cosine.mrad",
                    "each must be finite, |θ| <= 100 mrad",
                ));
            }
        }
        if let Some(o) = &fx.optics_slope {
            finite("effects.optics_slope.um_per_m", o.um_per_m)?;
            finite("effects.optics_slope.moved_um_per_m", o.moved_um_per_m)?;
        }
        if let Some(d) = &fx.drift {
            for v in d.um_per_h {
                finite("effects.drift.um_per_h", v)?;
            }
            if d.tau_h.is_some_and(|t| !(t.is_finite() && t > 0.0)) {
                return Err(SimError::Invalid {
                    key: "effects.drift.tau_h".into(),
                    reason: "must be a finite time above 0 h".into(),
                });
            }
        }
        Ok(())
    }
}

fn invalid(key: &str, reason: &str) -> SimError {
    SimError::Invalid {
        key: key.into(),
        reason: reason.into(),
    }
}

fn finite(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(key, "must be a finite number"))
    }
}

fn positive(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(key, "must be a finite number > 0"))
    }
}

fn non_negative(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(key, "must be a finite number >= 0"))
    }
}
