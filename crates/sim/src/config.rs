//! [`SimConfig`]: everything the simulator needs, loadable from TOML (`pipelines/sim-*.toml`).
//!
//! Every section has defaults, so an empty file is a valid (6-bar, 4-day) campaign. All extra
//! effects are off by default. [`SimConfig::validate`] rejects bad input with the key's name.

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use dbbcal_core::campaign::PlateLength;

mod checks;
mod defaults;
mod validate;

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
    /// readings, the bars' state before logging): by default the room's own air and a steady
    /// start, and left out of `truth.json` then.
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
    #[serde(with = "dbbcal_io::manifest::as_written::plate_lengths")]
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
    #[serde(with = "dbbcal_io::manifest::as_written::purpose")]
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
