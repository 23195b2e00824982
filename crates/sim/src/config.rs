//! [`SimConfig`]: everything the simulator needs, loadable from TOML (`pipelines/sim-*.toml`).
//!
//! Every section has defaults, so an empty file is a valid (6-bar, 4-day) campaign. All extra
//! effects are off by default. [`SimConfig::validate`] rejects bad input with the key's name.

use chrono::{DateTime, Utc};
use dbbcal_core::limits::Limit;
use serde::{Deserialize, Serialize};

use super::SimError;
use dbbcal_core::campaign::PlateLength;

/// The whole simulator configuration.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// Seed of every random draw: same seed, same campaign.
    pub seed: u64,
    /// Campaign id written to the manifest.
    pub campaign_id: String,
    /// Campaign start (UTC), a TOML datetime or an RFC 3339 string.
    #[serde(with = "start_time")]
    pub start: DateTime<Utc>,
    /// Campaign length, days.
    pub duration_days: f64,
    /// Encoder sampling period, seconds.
    pub sample_s: f64,
    /// Upper bound of the internal integration step of the thermal states, seconds (the step
    /// used divides `sample_s`).
    pub max_internal_step_s: f64,
    /// Encoder reading noise, white Gaussian, standard deviation in micrometres.
    pub noise_um: f64,
    /// Encoder resolution `k`, nanometres per count (the counts are quantized to it).
    pub resolution_nm: f64,
    /// `T0` of the thermal models, degrees Celsius.
    pub reference_temperature_c: f64,
    /// Keep the noise-free thermal error of every encoder row in [`super::Simulation`]
    /// (memory: 8 bytes a row).
    pub record_true_error: bool,
    /// The plate.
    pub plate: PlateConfig,
    /// Explicit bars; when empty, `fleet` (or its default) generates them.
    pub bars: Vec<BarConfig>,
    /// A generated fleet (when `bars` is empty; its default when absent).
    pub fleet: Option<FleetConfig>,
    /// The room's air.
    pub room: RoomConfig,
    /// Which bar is mounted where, and when.
    pub schedule: ScheduleConfig,
    /// Effects beyond the base model, each off by default.
    pub effects: EffectsConfig,
    /// Geometric errors and gravity sag of the bars (neutral by default).
    pub geometry: GeometryConfig,
    /// Bars made deliberately different from the fleet (none by default).
    pub mismatch: Vec<Mismatch>,
    /// How the truth is generated where the logs cannot tell (the air between two temperature
    /// readings, the bars' state before logging): by default as the simulator always did, and
    /// left out of `truth.json` then.
    #[serde(skip_serializing_if = "GenerationConfig::is_default")]
    pub generation: GenerationConfig,
}

/// What the logs cannot tell and the simulation must choose (issue 13: the base model must fit
/// any truth consistent with the logs to the noise).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields, default)]
pub struct GenerationConfig {
    /// The air that drives the bars (and the plate) between two readings of the temperature
    /// sensors: the room's own continuous air (`continuous`, the default), the air at the last
    /// reading held until the next (`held`), or the air at the readings interpolated linearly
    /// (`interpolated`). The sensors read the same values at their reading times in all three.
    pub air_between_readings: AirBetweenReadings,
    /// Hours the room runs before the logging starts (the bars, the plate and the air
    /// conditioning's set-point loop start in steady state that long before and follow the
    /// room's air since). 0: every state starts in steady state with the first air.
    pub prehistory_hours: f64,
}

impl GenerationConfig {
    pub(crate) fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// See [`GenerationConfig::air_between_readings`].
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum AirBetweenReadings {
    /// The room's own continuous air (the default).
    #[default]
    Continuous,
    /// The air at the last reading, held until the next.
    Held,
    /// The air at the readings, interpolated linearly.
    Interpolated,
}

/// The calibration plate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PlateConfig {
    pub(crate) material: String,
    /// Declared (manifest) expansion of the plate, ppm/K; the `plate_expansion` effect adds an
    /// undeclared part.
    pub(crate) cte_ppm_per_k: f64,
    pub(crate) tilt_deg: f64,
    /// Time constant of the plate temperature behind the air (T1), seconds.
    pub(crate) thermal_tau_s: f64,
    /// Calibrated socket-pair distances, as in `campaign.toml`.
    pub(crate) length: Vec<PlateLength>,
}

/// One bar given explicitly.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BarConfig {
    pub(crate) id: String,
    /// `I_min` of `docs/spec/physics.md`.
    pub(crate) fixed_length_mm: f64,
    pub(crate) alpha_ppm_per_k: f64,
    pub(crate) beta_ppm_per_k: f64,
    pub(crate) tau_r_s: f64,
    pub(crate) tau_s_s: f64,
}

/// A fleet of nominally equal bars with a spread around the mean (drawn from the seed).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct FleetConfig {
    /// Number of bars.
    pub n_bars: usize,
    /// Ids are `{id_prefix}{01..}`.
    pub id_prefix: String,
    /// Mean `I_min`, mm.
    pub fixed_length_mm: f64,
    /// Standard deviation of `I_min` across bars, mm.
    pub fixed_length_sd_mm: f64,
    /// Mean alpha (fixed part), ppm/K.
    pub alpha_ppm_per_k: f64,
    /// Standard deviation of alpha across bars, ppm/K.
    pub alpha_sd_ppm_per_k: f64,
    /// Mean beta (scale), ppm/K.
    pub beta_ppm_per_k: f64,
    /// Standard deviation of beta across bars, ppm/K.
    pub beta_sd_ppm_per_k: f64,
    /// Median time constant of the fixed part (tau_R), s.
    pub tau_r_s: f64,
    /// Median time constant of the scale (tau_S), s.
    pub tau_s_s: f64,
    /// Relative (log-normal) spread of both time constants.
    pub tau_rel_sd: f64,
}

/// The room: true air temperature at bar height (T1) and above (T2), sensors, doors.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RoomConfig {
    pub(crate) mean_c: f64,
    /// Amplitude of the daily sinusoid, K.
    pub(crate) daily_amplitude_k: f64,
    /// Local (UTC) hour of the daily maximum.
    pub(crate) daily_peak_hour: f64,
    /// Air-conditioning cycle (triangle wave): period in seconds, amplitude in K.
    pub(crate) ac_period_s: f64,
    pub(crate) ac_amplitude_k: f64,
    /// Linear drift over the campaign, K/day.
    pub(crate) drift_k_per_day: f64,
    /// Slow random wander (sum of sinusoids of 1.5–6 days), amplitude K.
    pub(crate) wander_k: f64,
    /// Door openings: Poisson rate, bump height (K), rise and decay time constants (s).
    pub(crate) door_rate_per_day: f64,
    pub(crate) door_amplitude_k: f64,
    pub(crate) door_rise_s: f64,
    pub(crate) door_decay_s: f64,
    /// Programmed set-point steps (the patent's step of room temperature, used to identify the
    /// time constants): the set point alternates between `+setpoint_step_k / 2` and
    /// `-setpoint_step_k / 2` every `setpoint_half_period_s`, and the air follows each change
    /// first-order with `setpoint_settle_s` (the air-conditioning loop). 0 K: no steps.
    pub setpoint_step_k: f64,
    pub(crate) setpoint_half_period_s: f64,
    pub(crate) setpoint_settle_s: f64,
    /// Vertical gradient T2 − T1: mean, daily amplitude, AC-synchronous amplitude, slow wander (K).
    pub(crate) gradient_k: f64,
    pub(crate) gradient_daily_k: f64,
    pub(crate) gradient_ac_k: f64,
    pub(crate) gradient_wander_k: f64,
    /// Sensor noise (white Gaussian), K.
    pub(crate) sensor_noise_k: f64,
    /// Temperature logging period, s.
    pub temperature_sample_s: f64,
    /// Log a plate sensor `P1` (kind plate) even when the plate does not expand.
    pub(crate) plate_sensor: bool,
}

/// Mount schedule: rotating bars visit every plate length in turn, with handling gaps.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ScheduleConfig {
    pub(crate) mount_days: f64,
    /// Handling time between mounts (no mount; readings still logged), minutes.
    pub(crate) gap_minutes: f64,
    /// Bar `i` starts `i * stagger_minutes` later (modulo a mount), so gaps do not coincide.
    pub(crate) stagger_minutes: f64,
    /// During handling the bar rests at a random offset up to this many mm from the socket length.
    pub(crate) handling_offset_mm: f64,
    /// Plate length ids the rotating bars visit in turn (bar `i` starts at the `i`-th); empty:
    /// every plate length. One id puts every mount of every rotating bar on that one length (a
    /// one-length campaign, like a machine tool's spindle: `beta` cannot be identified).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lengths: Vec<String>,
    /// Bars that stay on one length all campaign (after the calibration phase, if any), with
    /// purpose `reference`.
    pub reference: Vec<ReferenceMount>,
    /// Optional calibration phase at the start: every bar visits every (plate length, tilt).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) calibration: Option<CalibrationPhase>,
    /// Optional fixed layout of the non-reference bars after the calibration phase (else they
    /// rotate over the plate lengths).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) working: Option<WorkingLayout>,
}

/// The calibration phase (`docs/spec/physics.md`, calibration unit, point 1): the plate is tilted to each
/// of `tilts_deg` in turn (a `tilt` event each); at each tilt every bar visits every plate length
/// once (`mount_hours` each, purpose `calibration`, handling gaps between). All bars move
/// together, so the plate can be re-tilted while every bar is off it. Afterwards the plate goes
/// back to `plate.tilt_deg`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationPhase {
    /// Plate tilts from horizontal, degrees, in [0, 90], in visiting order.
    pub(crate) tilts_deg: Vec<f64>,
    pub(crate) mount_hours: f64,
}

/// Where the non-reference (working) bars sit for the rest of the campaign after the
/// calibration phase (`docs/spec/physics.md`, calibration unit, point 2).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WorkingLayout {
    /// The plate length id the working bars sit on (at the plate tilt).
    pub(crate) length: String,
    /// `check` (known length used only to verify; the default) or `calibration`.
    #[serde(default = "check_purpose")]
    pub(crate) purpose: dbbcal_core::campaign::Purpose,
    /// Bars on a target device instead of the plate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) device: Option<DeviceLayout>,
}

fn check_purpose() -> dbbcal_core::campaign::Purpose {
    dbbcal_core::campaign::Purpose::Check
}

/// Working bars on a target device: the manifest names only the device; the true (constant)
/// centre distance is written to the truth alone.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DeviceLayout {
    pub(crate) id: String,
    /// Bar ids mounted on the device.
    pub(crate) bars: Vec<String>,
    /// True centre distance of the device's ball pair, mm.
    pub distance_mm: f64,
    /// Tilt of the bars on the device from horizontal, degrees, in [0, 90].
    pub(crate) tilt_deg: f64,
    /// A hexapod: `bars` are its legs 1–6, the machine under test moves it (time-varying true
    /// lengths, a `positions` log, a `[[device]]` table; `crate::hexapod`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) hexapod: Option<crate::hexapod::HexapodSim>,
}

/// Geometric, time-invariant errors (`docs/spec/physics.md`, "The instrument"): fleet mean and spread of
/// each term. With `x = k n` the indicated travel from the counter zero (mm), the true centre
/// distance at tilt `A` is
///
/// `D(n, A) = D_zero + (x (1 + scale_ppm 1e-6) + q 1e-6 x^2) / cos(theta) - sag_um(A, D_zero + x) 1e-3`
///
/// with `q = nonlinearity_ppm_per_mm`, `theta = cosine_mrad 1e-3` (the scale is inclined to the
/// ball-centre line, so it sees the centre travel times `cos theta`) and
/// `D_zero = I_min + zero_offset_um 1e-3` (an Abbe-like constant offset of the counter zero).
/// All zero (the default) gives the ideal `D = D_zero + k n`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields, default)]
pub struct GeometryConfig {
    /// Linear scale error, ppm (normal spread `scale_sd_ppm`).
    pub(crate) scale_ppm: f64,
    pub(crate) scale_sd_ppm: f64,
    /// Quadratic scale nonlinearity `q`, ppm per mm of travel.
    pub(crate) nonlinearity_ppm_per_mm: f64,
    pub(crate) nonlinearity_sd_ppm_per_mm: f64,
    /// Misalignment of the scale to the ball-centre line, mrad.
    pub(crate) cosine_mrad: f64,
    pub(crate) cosine_sd_mrad: f64,
    /// Counter zero offset from `I_min`, µm.
    pub(crate) zero_offset_um: f64,
    pub(crate) zero_offset_sd_um: f64,
    pub(crate) sag: SagConfig,
}

/// Gravity sag (`docs/spec/physics.md`): the chord between the ball centres shortens as the bar bends, so
/// the reading is *long* by `sag_um(A, L) = amplitude_um f(A) (L / ref_mm)^exponent`, with
/// `f = cos A` or `cos^2 A` (`form`): largest horizontal (`A = 0`), zero vertical (`A = 90°`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SagConfig {
    /// Sag at horizontal and `L = ref_mm`, µm (0 = no sag).
    pub(crate) amplitude_um: f64,
    /// Relative (log-normal) spread of the amplitude across bars.
    pub(crate) spread: f64,
    pub(crate) form: SagForm,
    pub(crate) ref_mm: f64,
    pub(crate) exponent: f64,
}

/// The tilt dependence of the sag.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum SagForm {
    /// `cos A`.
    #[default]
    Cos,
    /// `cos^2 A`.
    Cos2,
}

impl SagForm {
    /// `f(A)` of the sag, `A` in degrees.
    pub(crate) fn factor(self, tilt_deg: f64) -> f64 {
        let c = tilt_deg.to_radians().cos();
        match self {
            Self::Cos => c,
            Self::Cos2 => c * c,
        }
    }
}

/// One bar made deliberately different from the fleet: its drawn parameters are multiplied by
/// these factors (1 = unchanged).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Mismatch {
    /// Bar id.
    pub bar: String,
    #[serde(default = "one")]
    pub(crate) alpha_factor: f64,
    #[serde(default = "one")]
    pub(crate) beta_factor: f64,
    #[serde(default = "one")]
    pub(crate) tau_r_factor: f64,
    #[serde(default = "one")]
    pub(crate) tau_s_factor: f64,
    #[serde(default = "one")]
    pub(crate) sag_factor: f64,
}

fn one() -> f64 {
    1.0
}

/// A bar that stays on one plate length all campaign, with purpose `reference`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ReferenceMount {
    /// Bar id.
    pub bar: String,
    /// A plate length id.
    pub length: String,
}

/// The switchable effects outside the base model (all off by default).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields, default)]
pub struct EffectsConfig {
    /// Read-head self-heating.
    pub head_heating: HeadHeating,
    /// A second thermal path of the fixed part.
    pub second_path: SecondPath,
    /// The bar sees a mix of T1 and T2 while it declares T1.
    pub sensor_gradient: SensorGradient,
    /// Settling after each mount.
    pub settling: Settling,
    /// Undeclared plate expansion.
    pub plate_expansion: PlateExpansion,
    /// Slow linear trend of the reading.
    pub creep: Creep,
    /// A channel outside the catalogue.
    pub hidden_channel: HiddenChannel,
    /// A heat source no catalogue names, acting through the bars' lengths (off and not
    /// written into `truth.json` unless switched on).
    #[serde(skip_serializing_if = "is_default")]
    pub heat_source: HeatSource,
}

/// Read-head self-heating: the bar grows by `amplitude_um * lag(power; tau_s)`; the head is
/// switched on and off (`head_power` events: 1 on, 0 off, one per switch), readings are logged
/// only while it is on (an unpowered head reads nothing), unless `logs_while_off`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct HeadHeating {
    /// Switched on.
    pub enabled: bool,
    /// Growth of the bar with the head on, in steady state, µm.
    pub amplitude_um: f64,
    /// Time constant of the heating, s.
    pub tau_s: f64,
    /// Relative (log-normal) spread of amplitude and tau across bars.
    pub spread: f64,
    /// How the head starts: switched on at the start with an "on" event, or already powered
    /// (first event an "off"). (Options at their defaults are not written, so that a `truth.json`
    /// stays what it was before they existed.)
    #[serde(skip_serializing_if = "is_default")]
    pub start: HeadStart,
    /// When the head is switched: exponential on and off durations, or off once a day.
    #[serde(skip_serializing_if = "is_default")]
    pub schedule: HeadSchedule,
    /// Mean on duration (exponential, `schedule = "random"`), hours.
    pub mean_on_h: f64,
    /// Mean off duration (exponential, `schedule = "random"`), hours.
    pub mean_off_h: f64,
    /// Shortest and longest off time, hours (`schedule = "daily"`: once a day, at a random time
    /// of day, for a duration drawn uniformly from this range).
    #[serde(skip_serializing_if = "is_default_daily_off")]
    pub daily_off_h: [f64; 2],
    /// Readings are logged while the head is off too: the switch powers the head's heat source,
    /// not its counter, so a minute's readings can lie on both sides of a switch.
    #[serde(skip_serializing_if = "is_default")]
    pub logs_while_off: bool,
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

fn is_default_daily_off(v: &[f64; 2]) -> bool {
    *v == HeadHeating::default().daily_off_h
}

/// The read head's state at the campaign start.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum HeadStart {
    /// Off and cold before the start, switched on at the start: an "on" event at the start.
    #[default]
    SwitchedOn,
    /// Powered long before the start (warm, in steady state); no event at the start, so each
    /// bar's first `head_power` event is an "off".
    PoweredWarm,
    /// Switched on at the start, cold, but no event says so: each bar's first `head_power`
    /// event is an "off", and the head is still warming up when the log begins.
    PoweredCold,
}

/// When the read head is switched off and on again.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum HeadSchedule {
    /// Exponential on and off durations (`mean_on_h`, `mean_off_h`; at least 5 minutes each).
    #[default]
    Random,
    /// Off once a day, for `daily_off_h`.
    Daily,
}

/// A second thermal path of the fixed part: `gain * I_min * lag(T - T0; tau_s)`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SecondPath {
    /// Switched on.
    pub enabled: bool,
    pub(crate) gain_ppm_per_k: f64,
    pub(crate) tau_s: f64,
    pub(crate) spread: f64,
}

/// The bar sees `(1 - weight_t2) * T1 + weight_t2 * T2` while it declares T1.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SensorGradient {
    /// Switched on.
    pub enabled: bool,
    pub(crate) weight_t2: f64,
}

/// After each mount the reading carries `a * exp(-(t - from) / tau_s)`, `a` drawn per mount in
/// `[0.5, 1.5] * amplitude_um`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Settling {
    /// Switched on.
    pub enabled: bool,
    pub(crate) amplitude_um: f64,
    /// Settling time constant, s.
    pub tau_s: f64,
}

/// Undeclared plate expansion: the true distance is `mm * (1 + cte * (T_plate - T0))`; turns
/// the plate sensor `P1` on.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PlateExpansion {
    /// Switched on.
    pub enabled: bool,
    pub(crate) cte_ppm_per_k: f64,
}

/// Slow linear trend of the reading, µm/day (spread across bars, relative log-normal).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Creep {
    pub(crate) enabled: bool,
    pub(crate) rate_um_per_day: f64,
    pub(crate) spread: f64,
}

/// A channel outside the catalogue: a nearby machine's temperature (sensor of kind `other`),
/// switched on and off at random, that drives every bar by `gain * lag(H - base; tau_s)`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct HiddenChannel {
    /// Switched on.
    pub enabled: bool,
    pub(crate) sensor_id: String,
    pub(crate) base_c: f64,
    pub(crate) amplitude_k: f64,
    pub(crate) mean_on_h: f64,
    pub(crate) mean_off_h: f64,
    /// Time constant of the machine's own temperature, seconds.
    pub(crate) signal_tau_s: f64,
    pub(crate) noise_k: f64,
    /// Growth of the bar per kelvin of the channel, µm/K, and its time constant.
    pub(crate) gain_um_per_k: f64,
    pub(crate) tau_s: f64,
    pub(crate) spread: f64,
}

/// A heat source no catalogue names: an electronics cabinet beside the plate, logged by a
/// sensor of kind `other`, that runs on working days (Monday to Friday, `on_hour` to
/// `off_hour` UTC). Running, its temperature rises `excess_k` above the air at bar height (T1)
/// through its own lag (`signal_tau_s`); that excess warms each bar's parts through a lag of its
/// own and acts through both lengths, as the air does: the bar grows by
/// `(fixed_ppm_per_k I_min + scale_ppm_per_k I_p) lag(C - T1; tau_s)` (µm: ppm/K · mm · K ·
/// 1e-3). Gains and tau spread across bars (relative log-normal).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct HeatSource {
    /// Switched on.
    pub enabled: bool,
    pub(crate) sensor_id: String,
    pub(crate) excess_k: f64,
    pub(crate) on_hour: f64,
    pub(crate) off_hour: f64,
    /// Time constant of the cabinet's own temperature, s.
    pub(crate) signal_tau_s: f64,
    pub(crate) noise_k: f64,
    /// Expansion per kelvin of excess through the fixed part and through the scale, ppm/K.
    pub(crate) fixed_ppm_per_k: f64,
    pub(crate) scale_ppm_per_k: f64,
    /// Time constant of the heat reaching the bar, s.
    pub(crate) tau_s: f64,
    pub(crate) spread: f64,
}

// ---------------------------------------------------------------- defaults

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            campaign_id: "sim".into(),
            start: DateTime::parse_from_rfc3339("2026-11-01T00:00:00Z")
                .expect("constant")
                .with_timezone(&Utc),
            duration_days: 4.0,
            sample_s: 10.0,
            max_internal_step_s: 1.0,
            noise_um: 0.02,
            resolution_nm: 5.0,
            reference_temperature_c: 20.0,
            record_true_error: false,
            plate: PlateConfig::default(),
            bars: Vec::new(),
            fleet: None,
            room: RoomConfig::default(),
            schedule: ScheduleConfig::default(),
            effects: EffectsConfig::default(),
            geometry: GeometryConfig::default(),
            mismatch: Vec::new(),
            generation: GenerationConfig::default(),
        }
    }
}

impl Default for PlateConfig {
    fn default() -> Self {
        let length = |id: &str, mm: f64, u_um: f64| PlateLength {
            id: id.into(),
            mm,
            u_um,
        };
        Self {
            material: "zerodur".into(),
            cte_ppm_per_k: 0.0,
            tilt_deg: 60.0,
            thermal_tau_s: 3.0 * 3600.0,
            length: vec![
                length("min", 250.0006, 0.15),
                length("mid", 325.0011, 0.15),
                length("max", 400.0019, 0.20),
            ],
        }
    }
}

impl Default for FleetConfig {
    fn default() -> Self {
        Self {
            n_bars: 6,
            id_prefix: "B".into(),
            fixed_length_mm: 230.0,
            fixed_length_sd_mm: 0.3,
            alpha_ppm_per_k: 2.0,
            alpha_sd_ppm_per_k: 0.15,
            beta_ppm_per_k: 0.6,
            beta_sd_ppm_per_k: 0.05,
            tau_r_s: 3000.0,
            tau_s_s: 1500.0,
            tau_rel_sd: 0.1,
        }
    }
}

impl Default for RoomConfig {
    fn default() -> Self {
        Self {
            mean_c: 20.3,
            daily_amplitude_k: 0.5,
            daily_peak_hour: 15.0,
            ac_period_s: 1200.0,
            ac_amplitude_k: 0.1,
            drift_k_per_day: 0.05,
            wander_k: 0.3,
            door_rate_per_day: 0.0,
            door_amplitude_k: 0.3,
            door_rise_s: 60.0,
            door_decay_s: 600.0,
            setpoint_step_k: 0.0,
            setpoint_half_period_s: 6.0 * 3600.0,
            setpoint_settle_s: 300.0,
            gradient_k: 0.3,
            gradient_daily_k: 0.25,
            gradient_ac_k: 0.05,
            gradient_wander_k: 0.2,
            sensor_noise_k: 0.008,
            temperature_sample_s: 30.0,
            plate_sensor: false,
        }
    }
}

impl Default for ScheduleConfig {
    fn default() -> Self {
        Self {
            mount_days: 1.0,
            gap_minutes: 20.0,
            stagger_minutes: 30.0,
            handling_offset_mm: 2.0,
            lengths: Vec::new(),
            reference: Vec::new(),
            calibration: None,
            working: None,
        }
    }
}

impl Default for CalibrationPhase {
    fn default() -> Self {
        Self {
            tilts_deg: vec![30.0, 60.0, 90.0],
            mount_hours: 3.0,
        }
    }
}

impl Default for SagConfig {
    fn default() -> Self {
        Self {
            amplitude_um: 0.0,
            spread: 0.0,
            form: SagForm::Cos,
            ref_mm: 400.0,
            exponent: 2.0,
        }
    }
}

impl Default for HeadHeating {
    fn default() -> Self {
        Self {
            enabled: false,
            amplitude_um: 1.5,
            tau_s: 900.0,
            spread: 0.2,
            start: HeadStart::SwitchedOn,
            schedule: HeadSchedule::Random,
            mean_on_h: 18.0,
            mean_off_h: 2.0,
            daily_off_h: [1.5, 4.0],
            logs_while_off: false,
        }
    }
}

impl Default for SecondPath {
    fn default() -> Self {
        Self {
            enabled: false,
            gain_ppm_per_k: 0.8,
            tau_s: 300.0,
            spread: 0.2,
        }
    }
}

impl Default for SensorGradient {
    fn default() -> Self {
        Self {
            enabled: false,
            weight_t2: 0.5,
        }
    }
}

impl Default for Settling {
    fn default() -> Self {
        Self {
            enabled: false,
            amplitude_um: 1.0,
            tau_s: 1800.0,
        }
    }
}

impl Default for PlateExpansion {
    fn default() -> Self {
        Self {
            enabled: false,
            cte_ppm_per_k: 1.0,
        }
    }
}

impl Default for Creep {
    fn default() -> Self {
        Self {
            enabled: false,
            rate_um_per_day: 0.1,
            spread: 0.3,
        }
    }
}

impl Default for HiddenChannel {
    fn default() -> Self {
        Self {
            enabled: false,
            sensor_id: "H1".into(),
            base_c: 25.0,
            amplitude_k: 8.0,
            mean_on_h: 3.0,
            mean_off_h: 6.0,
            signal_tau_s: 1200.0,
            noise_k: 0.05,
            gain_um_per_k: 0.05,
            tau_s: 1800.0,
            spread: 0.2,
        }
    }
}

impl Default for HeatSource {
    fn default() -> Self {
        Self {
            enabled: false,
            sensor_id: "C1".into(),
            excess_k: 4.0,
            on_hour: 8.0,
            off_hour: 18.0,
            signal_tau_s: 2400.0,
            noise_k: 0.01,
            fixed_ppm_per_k: 0.25,
            scale_ppm_per_k: 0.15,
            tau_s: 3600.0,
            spread: 0.2,
        }
    }
}

// ---------------------------------------------------------------- loading and validation

impl SimConfig {
    /// Parse and validate a TOML configuration.
    pub fn from_toml_str(text: &str) -> Result<Self, SimError> {
        let cfg: Self = toml::from_str(text)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Read, parse and validate a TOML file.
    #[cfg(test)]
    pub(crate) fn load(path: &std::path::Path) -> Result<Self, SimError> {
        let text = std::fs::read_to_string(path).map_err(|source| SimError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(&text)
    }

    /// The fleet generator in force when `bars` is empty: the given one or the default.
    pub(crate) fn fleet_or_default(&self) -> FleetConfig {
        self.fleet.clone().unwrap_or_default()
    }

    /// Check every field a simulation depends on; the error names the key.
    pub(crate) fn validate(&self) -> Result<(), SimError> {
        positive("duration_days", self.duration_days)?;
        positive("sample_s", self.sample_s)?;
        positive("max_internal_step_s", self.max_internal_step_s)?;
        non_negative("noise_um", self.noise_um)?;
        positive("resolution_nm", self.resolution_nm)?;
        finite("reference_temperature_c", self.reference_temperature_c)?;
        if self.duration_days > 3660.0 {
            return Err(invalid("duration_days", "longer than ten years"));
        }
        if self.sample_s < 1e-3 {
            return Err(invalid("sample_s", "below a millisecond"));
        }
        self.validate_plate()?;
        self.validate_bars()?;
        self.validate_room()?;
        self.validate_schedule()?;
        self.validate_phases()?;
        self.validate_geometry()?;
        self.validate_mismatch()?;
        self.validate_generation()?;
        self.validate_effects()
    }

    /// The internal integration step (seconds) the grid will use: `sample_s` divided into the
    /// fewest steps of at most `max_internal_step_s` ([`super::Grid`]).
    pub(crate) fn internal_step_s(&self) -> f64 {
        let steps = (self.sample_s / self.max_internal_step_s).ceil().max(1.0);
        (self.sample_s * 1e9).round() * 1e-9 / steps
    }

    fn validate_generation(&self) -> Result<(), SimError> {
        let g = &self.generation;
        non_negative("generation.prehistory_hours", g.prehistory_hours)?;
        if g.prehistory_hours > 24.0 * 366.0 {
            return Err(invalid("generation.prehistory_hours", "longer than a year"));
        }
        if g.air_between_readings != AirBetweenReadings::Continuous {
            // The air is rebuilt from its values at the reading times on the internal grid:
            // the readings must fall on grid points.
            let ratio = self.room.temperature_sample_s / self.internal_step_s();
            if (ratio - ratio.round()).abs() > 1e-6 || ratio.round() < 1.0 {
                return Err(invalid(
                    "generation.air_between_readings",
                    "needs room.temperature_sample_s to be a multiple of the internal step \
                     (sample_s divided into steps of at most max_internal_step_s)",
                ));
            }
        }
        Ok(())
    }

    fn validate_plate(&self) -> Result<(), SimError> {
        let p = &self.plate;
        finite("plate.cte_ppm_per_k", p.cte_ppm_per_k)?;
        tilt("plate.tilt_deg", p.tilt_deg)?;
        positive("plate.thermal_tau_s", p.thermal_tau_s)?;
        if p.length.is_empty() {
            return Err(invalid("plate.length", "no plate length"));
        }
        for (i, l) in p.length.iter().enumerate() {
            positive(&format!("plate.length[{i}].mm"), l.mm)?;
            non_negative(&format!("plate.length[{i}].u_um"), l.u_um)?;
        }
        unique("plate.length.id", p.length.iter().map(|l| l.id.as_str()))
    }

    fn validate_bars(&self) -> Result<(), SimError> {
        if !self.bars.is_empty() && self.fleet.is_some() {
            return Err(invalid("fleet", "give either `bars` or `fleet`, not both"));
        }
        let min_mm = self
            .plate
            .length
            .iter()
            .map(|l| l.mm)
            .fold(f64::INFINITY, f64::min);
        for (i, b) in self.bars.iter().enumerate() {
            let key = |f: &str| format!("bars[{i}].{f}");
            if b.id.is_empty() {
                return Err(invalid(&key("id"), "empty"));
            }
            positive(&key("fixed_length_mm"), b.fixed_length_mm)?;
            if b.fixed_length_mm >= min_mm {
                return Err(invalid(
                    &key("fixed_length_mm"),
                    "not below the shortest plate length",
                ));
            }
            finite(&key("alpha_ppm_per_k"), b.alpha_ppm_per_k)?;
            finite(&key("beta_ppm_per_k"), b.beta_ppm_per_k)?;
            positive(&key("tau_r_s"), b.tau_r_s)?;
            positive(&key("tau_s_s"), b.tau_s_s)?;
        }
        unique("bars.id", self.bars.iter().map(|b| b.id.as_str()))?;
        if self.bars.is_empty() {
            self.validate_fleet(min_mm)?;
        }
        Ok(())
    }

    fn validate_fleet(&self, min_mm: f64) -> Result<(), SimError> {
        let f = self.fleet_or_default();
        if f.n_bars == 0 || f.n_bars > 999 {
            return Err(invalid("fleet.n_bars", "must be 1..=999"));
        }
        positive("fleet.fixed_length_mm", f.fixed_length_mm)?;
        non_negative("fleet.fixed_length_sd_mm", f.fixed_length_sd_mm)?;
        if f.fixed_length_mm + 5.0 * f.fixed_length_sd_mm >= min_mm {
            return Err(invalid(
                "fleet.fixed_length_mm",
                "too close to the shortest plate length",
            ));
        }
        finite("fleet.alpha_ppm_per_k", f.alpha_ppm_per_k)?;
        non_negative("fleet.alpha_sd_ppm_per_k", f.alpha_sd_ppm_per_k)?;
        finite("fleet.beta_ppm_per_k", f.beta_ppm_per_k)?;
        non_negative("fleet.beta_sd_ppm_per_k", f.beta_sd_ppm_per_k)?;
        positive("fleet.tau_r_s", f.tau_r_s)?;
        positive("fleet.tau_s_s", f.tau_s_s)?;
        non_negative("fleet.tau_rel_sd", f.tau_rel_sd)
    }

    fn validate_room(&self) -> Result<(), SimError> {
        let r = &self.room;
        finite("room.mean_c", r.mean_c)?;
        for (k, v) in [
            ("room.daily_amplitude_k", r.daily_amplitude_k),
            ("room.ac_amplitude_k", r.ac_amplitude_k),
            ("room.wander_k", r.wander_k),
            ("room.door_rate_per_day", r.door_rate_per_day),
            ("room.door_amplitude_k", r.door_amplitude_k),
            ("room.setpoint_step_k", r.setpoint_step_k),
            ("room.gradient_daily_k", r.gradient_daily_k),
            ("room.gradient_ac_k", r.gradient_ac_k),
            ("room.gradient_wander_k", r.gradient_wander_k),
            ("room.sensor_noise_k", r.sensor_noise_k),
        ] {
            non_negative(k, v)?;
        }
        finite("room.daily_peak_hour", r.daily_peak_hour)?;
        finite("room.drift_k_per_day", r.drift_k_per_day)?;
        finite("room.gradient_k", r.gradient_k)?;
        positive("room.ac_period_s", r.ac_period_s)?;
        positive("room.door_rise_s", r.door_rise_s)?;
        positive("room.door_decay_s", r.door_decay_s)?;
        positive("room.setpoint_half_period_s", r.setpoint_half_period_s)?;
        positive("room.setpoint_settle_s", r.setpoint_settle_s)?;
        if r.door_decay_s <= r.door_rise_s {
            return Err(invalid("room.door_decay_s", "must exceed room.door_rise_s"));
        }
        if r.door_rate_per_day > 1440.0 {
            return Err(invalid("room.door_rate_per_day", "more than one a minute"));
        }
        if r.temperature_sample_s.is_nan() || r.temperature_sample_s < 0.1 {
            return Err(invalid(
                "room.temperature_sample_s",
                "must be at least 0.1 s",
            ));
        }
        Ok(())
    }

    fn validate_schedule(&self) -> Result<(), SimError> {
        let s = &self.schedule;
        positive("schedule.mount_days", s.mount_days)?;
        non_negative("schedule.gap_minutes", s.gap_minutes)?;
        non_negative("schedule.stagger_minutes", s.stagger_minutes)?;
        non_negative("schedule.handling_offset_mm", s.handling_offset_mm)?;
        if s.mount_days * 86400.0 < 60.0 {
            return Err(invalid("schedule.mount_days", "shorter than a minute"));
        }
        for (i, id) in s.lengths.iter().enumerate() {
            if !self.plate.length.iter().any(|l| &l.id == id) {
                return Err(invalid(
                    &format!("schedule.lengths[{i}]"),
                    "no such plate length",
                ));
            }
        }
        unique("schedule.lengths", s.lengths.iter().map(String::as_str))?;
        for (i, r) in s.reference.iter().enumerate() {
            if !self.plate.length.iter().any(|l| l.id == r.length) {
                return Err(invalid(
                    &format!("schedule.reference[{i}].length"),
                    "no such plate length",
                ));
            }
        }
        unique(
            "schedule.reference.bar",
            s.reference.iter().map(|r| r.bar.as_str()),
        )
    }

    /// The calibration phase and the working layout.
    fn validate_phases(&self) -> Result<(), SimError> {
        let s = &self.schedule;
        if let Some(c) = &s.calibration {
            if c.tilts_deg.is_empty() {
                return Err(invalid("schedule.calibration.tilts_deg", "no tilt"));
            }
            for (i, &t) in c.tilts_deg.iter().enumerate() {
                tilt(&format!("schedule.calibration.tilts_deg[{i}]"), t)?;
            }
            positive("schedule.calibration.mount_hours", c.mount_hours)?;
            if c.mount_hours < 1.0 / 60.0 {
                return Err(invalid(
                    "schedule.calibration.mount_hours",
                    "shorter than a minute",
                ));
            }
            let rounds = (c.tilts_deg.len() * self.plate.length.len()) as f64;
            let phase_s = rounds * (c.mount_hours * 3600.0 + s.gap_minutes.max(1.0 / 60.0) * 60.0);
            if phase_s >= self.duration_days * 86400.0 {
                return Err(invalid(
                    "schedule.calibration",
                    "the calibration phase does not end before the campaign",
                ));
            }
        }
        let Some(w) = &s.working else { return Ok(()) };
        if !self.plate.length.iter().any(|l| l.id == w.length) {
            return Err(invalid("schedule.working.length", "no such plate length"));
        }
        if w.purpose == dbbcal_core::campaign::Purpose::Reference {
            return Err(invalid(
                "schedule.working.purpose",
                "must be check or calibration (references go in schedule.reference)",
            ));
        }
        let Some(d) = &w.device else { return Ok(()) };
        if d.id.trim().is_empty() {
            return Err(invalid("schedule.working.device.id", "empty"));
        }
        unique(
            "schedule.working.device.bars",
            d.bars.iter().map(String::as_str),
        )?;
        if let Some(b) = d
            .bars
            .iter()
            .find(|b| s.reference.iter().any(|r| &r.bar == *b))
        {
            return Err(invalid(
                "schedule.working.device.bars",
                &format!("`{b}` is also a reference bar"),
            ));
        }
        let min_mm = self
            .plate
            .length
            .iter()
            .map(|l| l.mm)
            .fold(f64::INFINITY, f64::min);
        if !(d.distance_mm.is_finite() && d.distance_mm >= min_mm) {
            return Err(invalid(
                "schedule.working.device.distance_mm",
                "must be at least the shortest plate length",
            ));
        }
        if let Some(h) = &d.hexapod {
            if d.bars.len() != 6 {
                return Err(invalid(
                    "schedule.working.device.bars",
                    "a hexapod needs six bars (its legs 1-6, in order)",
                ));
            }
            h.validate("schedule.working.device.hexapod")?;
        }
        tilt("schedule.working.device.tilt_deg", d.tilt_deg)
    }

    fn validate_geometry(&self) -> Result<(), SimError> {
        let g = &self.geometry;
        bounded("geometry.scale_ppm", g.scale_ppm, g.scale_sd_ppm, 1000.0)?;
        bounded(
            "geometry.nonlinearity_ppm_per_mm",
            g.nonlinearity_ppm_per_mm,
            g.nonlinearity_sd_ppm_per_mm,
            1.0,
        )?;
        bounded(
            "geometry.cosine_mrad",
            g.cosine_mrad,
            g.cosine_sd_mrad,
            100.0,
        )?;
        bounded(
            "geometry.zero_offset_um",
            g.zero_offset_um,
            g.zero_offset_sd_um,
            1000.0,
        )?;
        non_negative("geometry.scale_sd_ppm", g.scale_sd_ppm)?;
        non_negative(
            "geometry.nonlinearity_sd_ppm_per_mm",
            g.nonlinearity_sd_ppm_per_mm,
        )?;
        non_negative("geometry.cosine_sd_mrad", g.cosine_sd_mrad)?;
        non_negative("geometry.zero_offset_sd_um", g.zero_offset_sd_um)?;
        let sag = &g.sag;
        finite("geometry.sag.amplitude_um", sag.amplitude_um)?;
        if sag.amplitude_um.abs() > 100.0 {
            return Err(invalid("geometry.sag.amplitude_um", "beyond ±100 µm"));
        }
        non_negative("geometry.sag.spread", sag.spread)?;
        if sag.spread > 1.0 {
            return Err(invalid(
                "geometry.sag.spread",
                "above 1 (log-normal relative spread)",
            ));
        }
        positive("geometry.sag.ref_mm", sag.ref_mm)?;
        if !(sag.exponent.is_finite() && sag.exponent.abs() <= 10.0) {
            return Err(invalid("geometry.sag.exponent", "must be in [-10, 10]"));
        }
        Ok(())
    }

    fn validate_mismatch(&self) -> Result<(), SimError> {
        for (i, m) in self.mismatch.iter().enumerate() {
            let key = |f: &str| format!("mismatch[{i}].{f}");
            if m.bar.is_empty() {
                return Err(invalid(&key("bar"), "empty"));
            }
            for (f, v) in [
                ("alpha_factor", m.alpha_factor),
                ("beta_factor", m.beta_factor),
                ("tau_r_factor", m.tau_r_factor),
                ("tau_s_factor", m.tau_s_factor),
                ("sag_factor", m.sag_factor),
            ] {
                if !(v.is_finite() && (0.0..=100.0).contains(&v)) {
                    return Err(invalid(&key(f), "must be in [0, 100]"));
                }
            }
            if !(m.tau_r_factor > 0.0 && m.tau_s_factor > 0.0) {
                return Err(invalid(
                    &key("tau_r_factor"),
                    "time-constant factors must be positive",
                ));
            }
        }
        unique("mismatch.bar", self.mismatch.iter().map(|m| m.bar.as_str()))
    }

    fn validate_effects(&self) -> Result<(), SimError> {
        let e = &self.effects;
        let h = &e.head_heating;
        finite("effects.head_heating.amplitude_um", h.amplitude_um)?;
        positive("effects.head_heating.tau_s", h.tau_s)?;
        non_negative("effects.head_heating.spread", h.spread)?;
        positive("effects.head_heating.mean_on_h", h.mean_on_h)?;
        positive("effects.head_heating.mean_off_h", h.mean_off_h)?;
        let [off_lo, off_hi] = h.daily_off_h;
        if !(off_lo > 0.0 && off_lo <= off_hi && off_hi < 24.0) {
            return Err(invalid(
                "effects.head_heating.daily_off_h",
                "must be [shortest, longest] hours with 0 < shortest <= longest < 24",
            ));
        }
        finite(
            "effects.second_path.gain_ppm_per_k",
            e.second_path.gain_ppm_per_k,
        )?;
        positive("effects.second_path.tau_s", e.second_path.tau_s)?;
        non_negative("effects.second_path.spread", e.second_path.spread)?;
        let w = e.sensor_gradient.weight_t2;
        if !(0.0..=1.0).contains(&w) {
            return Err(invalid(
                "effects.sensor_gradient.weight_t2",
                "must be in [0, 1]",
            ));
        }
        finite("effects.settling.amplitude_um", e.settling.amplitude_um)?;
        positive("effects.settling.tau_s", e.settling.tau_s)?;
        finite(
            "effects.plate_expansion.cte_ppm_per_k",
            e.plate_expansion.cte_ppm_per_k,
        )?;
        finite("effects.creep.rate_um_per_day", e.creep.rate_um_per_day)?;
        non_negative("effects.creep.spread", e.creep.spread)?;
        self.validate_hidden()?;
        self.validate_heat_source()
    }

    fn validate_heat_source(&self) -> Result<(), SimError> {
        let h = &self.effects.heat_source;
        let taken = [
            "T1",
            "T2",
            "P1",
            self.effects.hidden_channel.sensor_id.as_str(),
        ];
        if h.enabled && (h.sensor_id.is_empty() || taken.contains(&h.sensor_id.as_str())) {
            return Err(SimError::Invalid {
                key: "effects.heat_source.sensor_id".into(),
                reason: format!("{:?} is empty or names another sensor", h.sensor_id),
            });
        }
        finite("effects.heat_source.excess_k", h.excess_k)?;
        let hours_ok = (0.0..=24.0).contains(&h.on_hour)
            && (0.0..=24.0).contains(&h.off_hour)
            && h.on_hour < h.off_hour;
        if !hours_ok {
            return Err(invalid(
                "effects.heat_source.on_hour",
                "on_hour and off_hour must be hours of the day, on before off",
            ));
        }
        positive("effects.heat_source.signal_tau_s", h.signal_tau_s)?;
        non_negative("effects.heat_source.noise_k", h.noise_k)?;
        finite("effects.heat_source.fixed_ppm_per_k", h.fixed_ppm_per_k)?;
        finite("effects.heat_source.scale_ppm_per_k", h.scale_ppm_per_k)?;
        positive("effects.heat_source.tau_s", h.tau_s)?;
        non_negative("effects.heat_source.spread", h.spread)
    }

    fn validate_hidden(&self) -> Result<(), SimError> {
        let h = &self.effects.hidden_channel;
        if h.sensor_id.is_empty() || ["T1", "T2", "P1"].contains(&h.sensor_id.as_str()) {
            return Err(invalid(
                "effects.hidden_channel.sensor_id",
                "empty or taken (T1, T2, P1)",
            ));
        }
        finite("effects.hidden_channel.base_c", h.base_c)?;
        finite("effects.hidden_channel.amplitude_k", h.amplitude_k)?;
        positive("effects.hidden_channel.mean_on_h", h.mean_on_h)?;
        positive("effects.hidden_channel.mean_off_h", h.mean_off_h)?;
        positive("effects.hidden_channel.signal_tau_s", h.signal_tau_s)?;
        non_negative("effects.hidden_channel.noise_k", h.noise_k)?;
        finite("effects.hidden_channel.gain_um_per_k", h.gain_um_per_k)?;
        positive("effects.hidden_channel.tau_s", h.tau_s)?;
        non_negative("effects.hidden_channel.spread", h.spread)
    }
}

fn invalid(key: &str, reason: &str) -> SimError {
    SimError::Invalid {
        key: key.into(),
        reason: reason.into(),
    }
}

/// `v` within `limit`, or the key named with the range in `dbbcal_core::limits`' words.
fn within(key: &str, v: f64, limit: Limit) -> Result<(), SimError> {
    limit.check(key, v).map_err(|e| SimError::Invalid {
        key: key.into(),
        reason: format!("= {} is out of range: it must be {}", e.value, e.allowed),
    })
}

fn finite(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::FINITE)
}

fn positive(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::POSITIVE)
}

fn non_negative(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::NON_NEGATIVE)
}

/// A tilt from horizontal in [0, 90] degrees.
fn tilt(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::closed(0.0, 90.0, "degrees"))
}

/// A fleet mean and spread with `|mean| + 5 sd <= limit`.
fn bounded(key: &str, mean: f64, sd: f64, limit: f64) -> Result<(), SimError> {
    finite(key, mean)?;
    if mean.abs() + 5.0 * sd.abs() <= limit {
        Ok(())
    } else {
        Err(invalid(key, &format!("mean + 5 sd beyond {limit}")))
    }
}

fn unique<'a>(key: &str, ids: impl Iterator<Item = &'a str>) -> Result<(), SimError> {
    let mut seen = std::collections::BTreeSet::new();
    for id in ids {
        if !seen.insert(id) {
            return Err(invalid(key, &format!("duplicate id `{id}`")));
        }
    }
    Ok(())
}

/// `start` as an RFC 3339 string on output; a TOML datetime or a string on input.
pub(crate) mod start_time {
    use chrono::{DateTime, Utc};
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub(crate) fn serialize<S: Serializer>(t: &DateTime<Utc>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&t.to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true))
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<DateTime<Utc>, D::Error> {
        let text = match toml::Value::deserialize(d)? {
            toml::Value::Datetime(dt) => dt.to_string(),
            toml::Value::String(s) => s,
            other => {
                return Err(D::Error::custom(format!(
                    "start: expected a datetime, got {other}"
                )))
            }
        };
        DateTime::parse_from_rfc3339(&text)
            .map(|t| t.with_timezone(&Utc))
            .map_err(|e| {
                D::Error::custom(format!("start `{text}`: {e} (give a full UTC datetime)"))
            })
    }
}
