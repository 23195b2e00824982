//! Thermal models as lists of composable terms.
//!
//! A model is a list of [`Effect`]s (the base model is `fixed_part` + `scale`, `docs/spec/physics.md`'s
//! first-order model) plus one zero per zero segment. Each effect contributes basis columns
//! (linear gains) and at most one time constant of its own; a column may also share another
//! effect's time constant (`air_gradient` acts through the base paths with `tau_R` and `tau_S`).
//! [`ThermalProblem`] assembles them for the one fitting engine ([`crate::fit`]). Effects are named by strings — exactly the strings the
//! diagnosis prints and `--add-effect` accepts (see [`Effect::parse`]).
//!
//! Sign convention (`docs/spec/physics.md`, "Sign"): parts that grow make the reading fall, so the thermal
//! error is `-dD`; gains are reported with the physical sign (positive = expands when warmed).
//!
//! # How it works
//!
//! - Thermal error (`docs/spec/physics.md`): `e = -(alpha I_min lag(T - T0; tau_R) + beta I_p lag(T - T0; tau_S)) + zero[segment]`,
//!   µm with lengths in mm and alpha/beta in ppm/K (`mm · ppm/K · K · 1e-3 = µm`).
//! - `lag` is the exact first-order-hold discretisation for irregular samples (`signal/lag.rs`);
//!   its `ln tau` derivative is the Jacobian column. It starts in steady state at the bar's first
//!   sample; the departure from it is fitted: each base path binds a second term
//!   (`TermKind::InitialState`, sharing the path's time constant) with the column
//!   `exp(-(t - t_ref)/tau)` on the path's length, `t_ref` the first fitted sample (unit there, so it
//!   never vanishes whatever tau; exactly 0 once below 1e-13, and `write_row_column` stops there). Its
//!   gains (`initial_fixed_ppm`, `initial_scale_ppm`) are nuisance parameters: `BarModel::initial_state`,
//!   not `params`; `BarModel::gains` holds every gain in column order for `full_columns`.
//! - What a bar's data cannot determine is left out inside `ThermalProblem::new`
//!   (`model::identifiable_effects`), so every problem built from (series, effects) — identify, the
//!   diagnosis' trial fits, compensation — agrees: one length (`I_p` constant over the fitted
//!   samples) drops the scale and `air_gradient`'s scale path. `BarModel::effects` stays the effects
//!   asked for (fleet-wide lists stay equal); `BarModel::not_identifiable` says what was left out and
//!   why (`summary.json`, the bar figure's notes). Matching (`matching::matched_inputs`) takes the bars
//!   with all four base parameters, or, when none has them, every bar on alpha and tau_R (NaN beta and
//!   tau_S in `MatchInput`).
//! - `I_p = plate length − fixed_length_mm` per mount (`series/build.rs`).
//! - Time constants are fitted as `ln tau` (positive by construction); intervals from the profile of
//!   `ln tau` mapped to seconds (diagnosis trial fits: `exp(ln tau ± t·u)`).
//! - Events with values (`head_power`, `tilt`) are held inputs integrated at their own switch times
//!   (`lag::held_lag`), so a head switched off while nothing is logged is still seen; valueless events
//!   are impulses. The value before a kind's first event and what the data leave to fit
//!   (`channels::held_start`; `docs/spec/campaign-format.md`, events): the other state
//!   (a head that logs is powered), the lag in steady state there; a powered head's heat at the
//!   first fitted reading is a decay column on its time constant (`TermKind::Decay`,
//!   `head_initial_um`), an unknown level before the first event the lagged indicator of "before"
//!   (`model::start_terms`; both share the effect's tau).
//! - `settling` has one amplitude per zero segment sharing one time constant; `air_gradient` has two
//!   gains (`gradient_fixed_ppm_per_k` on `I_min lag(dT_grad; tau_R)`, `gradient_scale_ppm_per_k` on
//!   `I_p lag(dT_grad; tau_S)`: the bar's air is its sensor plus a share of the sensor difference,
//!   through both base paths) and no time constant of its own; every other effect has one gain.
//! - `plate_expansion` uses the plate sensor smoothed forward and backward (`model::plate_temperature`,
//!   `lag::zero_phase_lag`, 300 s), as does the declared-CTE correction in `series/build.rs`: a raw noisy
//!   level is an error in a regressor and biases alpha and beta.
//! - Weights: every fit is weighted by `BarSeries::weight` (1 for a reading, the node weight for a
//!   compressed bin); `ThermalProblem` demeans the zeros with weights and multiplies each row by
//!   `√w`, so the engine sees ordinary least squares. Samples of weight 0 are never fitted, nor
//!   taken as readings by calibration or compensation. Likelihood-ratio noise models get
//!   `√w`-weighted residuals (`BarSeries::weighted_residuals`). `BarSeries::binned_copy` (weighted
//!   bin means) is only a coarse copy for starts and profile shapes.
//! - `ThermalProblem` memoises each term's lag column and derivative by tau (shared `Arc`s, not
//!   copies): a solver's basis and derivative calls at one `theta`, and a 1-D search along one tau,
//!   reuse the other columns. Terms that lag one input on one time constant (`heat:`'s two
//!   lengths) share one recursion (`ThermalProblem::lag_group`). Basis columns are gathered,
//!   masked, demeaned and weighted straight into the matrix (`ThermalProblem::write_row_column`).

mod bind;
pub(crate) mod channels;
mod columns;
mod identifiable;
mod problem;
mod separable;

pub(crate) use identifiable::at_model_limit;
pub use identifiable::{NotIdentifiable, WhyNotIdentifiable};
pub use problem::{ModelError, ThermalProblem};

/// How a generic channel enters the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Transform {
    /// First-order response (gain, tau).
    Lag,
    /// Rate of change, smoothed: `u - lag(u)` (gain, tau).
    Rate,
    /// The channel as it is (gain only).
    Level,
    /// Heat entering the bar: a first-order response of the channel with one time constant of
    /// its own, acting through both of the bar's lengths as the air does (`docs/spec/physics.md`, the
    /// first-order model): `-(g_R I_min + g_S I_p) lag(u; tau)`, two gains (ppm per unit of the
    /// channel). A generic `lag:CH` has one gain per bar, so it cannot follow a source whose
    /// effect changes from mount to mount with `I_p`.
    Heat,
}

impl Transform {
    fn as_str(self) -> &'static str {
        match self {
            Transform::Lag => "lag",
            Transform::Rate => "rate",
            Transform::Level => "level",
            Transform::Heat => "heat",
        }
    }
}

/// One physical effect a bar's model may contain.
#[derive(Debug, Clone, PartialEq, PartialOrd)]
pub enum Effect {
    /// `alpha` on the fixed part `I_min`, lag `tau_R` of the air temperature (patent).
    FixedPart,
    /// `beta` on the scale travel `I_p`, lag `tau_S` (patent).
    Scale,
    /// Read-head self-heating: first-order response to `head_power` (µm, tau).
    HeadHeating,
    /// A second thermal path on `I_min` with its own time constant (ppm/K, tau).
    SecondPath,
    /// The bar's effective air temperature is its own sensor plus a share of the difference to
    /// the other air sensors, `T_own + w dT_grad` (`docs/spec/physics.md`, "sensor placement"). Being
    /// linear, the lag splits: `-(alpha I_min lag(T_own; tau_R) + beta I_p lag(T_own; tau_S))`
    /// gains `-(g_R I_min lag(dT_grad; tau_R) + g_S I_p lag(dT_grad; tau_S))` with
    /// `g_R = alpha w_R`, `g_S = beta w_S` (ppm/K per K of sensor difference; `w_R = w_S` when the
    /// whole bar sits in the same air). Two linear gains, the base paths' time constants.
    AirGradient,
    /// Plate expansion (`docs/spec/physics.md`, "plate expansion"; `docs/spec/campaign-format.md`: true distance
    /// `mm (1 + cte (T_plate - T0))`): `+cte L (T_plate - T0)` on plate mounts (ppm/K), with
    /// `T_plate` the plate sensor smoothed without delay (`plate_temperature`).
    PlateExpansion,
    /// Exponential settling after each mount (µm, tau).
    Settling,
    /// Slow linear trend independent of temperature (µm/day).
    Creep,
    /// Generic term: `transform` of a named channel (see `channels`).
    Channel {
        /// How the channel enters.
        transform: Transform,
        /// The channel's name.
        channel: String,
        /// Starting time constant given after `@` in the name, s; `None`: the default start.
        tau0_s: Option<f64>,
    },
}

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(&self.name())
    }
}

/// Longest time constant a term takes, s (about 32 years): the end of the range the fits search.
pub(crate) const MAX_TAU_S: f64 = 1e9;

/// The interval every fitted `ln τ` is held to, `ln 1 s ..= ln MAX_TAU_S`: a solver wandering
/// off to an unidentifiable extreme never produces infinities.
pub(crate) fn ln_tau_bounds() -> (f64, f64) {
    (0.0, MAX_TAU_S.ln())
}

/// The named effects of the catalogue (`docs/spec/physics.md`), in display order.
pub(crate) const CATALOGUE: &[&str] = &[
    "fixed_part",
    "scale",
    "head_heating",
    "second_path",
    "air_gradient",
    "plate_expansion",
    "settling",
    "creep",
];

/// Names of the base paths' initial-state gains: the lag's departure from steady state at the
/// bar's first fitted sample times the path's expansion (ppm = ppm/K · K), nuisance gains like
/// the zeros ([`initial_state`]).
pub(crate) const INITIAL_FIXED: &str = "initial_fixed_ppm";
pub(crate) const INITIAL_SCALE: &str = "initial_scale_ppm";

/// The base model of `docs/spec/physics.md`.
pub fn base_effects() -> Vec<Effect> {
    vec![Effect::FixedPart, Effect::Scale]
}

/// An effect string that is not understood.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("unknown effect {0:?}: use one of {known} or lag:CHANNEL, rate:CHANNEL, level:CHANNEL, heat:CHANNEL (optionally @TAU_S)", known = CATALOGUE.join(", "))]
pub struct UnknownEffect(pub String);

impl Effect {
    /// Parse an effect name: a catalogue name, or `lag:CH`, `rate:CH`, `level:CH`, `heat:CH`, with an
    /// optional initial time constant `@SECONDS`.
    pub fn parse(s: &str) -> Result<Effect, UnknownEffect> {
        let s = s.trim();
        let named = match s {
            "fixed_part" => Some(Effect::FixedPart),
            "scale" => Some(Effect::Scale),
            "head_heating" => Some(Effect::HeadHeating),
            "second_path" => Some(Effect::SecondPath),
            "air_gradient" => Some(Effect::AirGradient),
            "plate_expansion" => Some(Effect::PlateExpansion),
            "settling" => Some(Effect::Settling),
            "creep" => Some(Effect::Creep),
            _ => None,
        };
        if let Some(e) = named {
            return Ok(e);
        }
        let (head, channel) = s
            .split_once(':')
            .ok_or_else(|| UnknownEffect(s.to_string()))?;
        let transform = match head {
            "lag" => Transform::Lag,
            "rate" => Transform::Rate,
            "level" => Transform::Level,
            "heat" => Transform::Heat,
            _ => return Err(UnknownEffect(s.to_string())),
        };
        let (channel, tau0_s) = match channel.rsplit_once('@') {
            Some((ch, tau)) => {
                let tau: f64 = tau.parse().map_err(|_| UnknownEffect(s.to_string()))?;
                if tau.is_nan() || tau <= 0.0 {
                    return Err(UnknownEffect(s.to_string()));
                }
                (ch, Some(tau))
            }
            None => (channel, None),
        };
        if channel.is_empty() {
            return Err(UnknownEffect(s.to_string()));
        }
        Ok(Effect::Channel {
            transform,
            channel: channel.to_string(),
            tau0_s,
        })
    }

    /// The effect's name; `Effect::parse(&e.name()) == e`.
    pub fn name(&self) -> String {
        match self {
            Effect::FixedPart => "fixed_part".into(),
            Effect::Scale => "scale".into(),
            Effect::HeadHeating => "head_heating".into(),
            Effect::SecondPath => "second_path".into(),
            Effect::AirGradient => "air_gradient".into(),
            Effect::PlateExpansion => "plate_expansion".into(),
            Effect::Settling => "settling".into(),
            Effect::Creep => "creep".into(),
            Effect::Channel {
                transform,
                channel,
                tau0_s,
            } => match tau0_s {
                Some(t) => format!("{}:{channel}@{t}", transform.as_str()),
                None => format!("{}:{channel}", transform.as_str()),
            },
        }
    }

    /// Name of the linear gain and its unit (for `air_gradient`, which has two gains, the gain on
    /// the fixed part; see [`Effect::gain_names`]).
    pub(crate) fn gain_name(&self) -> String {
        match self {
            Effect::FixedPart => "alpha_ppm_per_k".into(),
            Effect::Scale => "beta_ppm_per_k".into(),
            Effect::HeadHeating => "head_growth_um".into(),
            Effect::SecondPath => "alpha2_ppm_per_k".into(),
            Effect::AirGradient => "gradient_fixed_ppm_per_k".into(),
            Effect::PlateExpansion => "plate_cte_ppm_per_k".into(),
            Effect::Settling => "settling_um".into(),
            Effect::Creep => "creep_um_per_day".into(),
            Effect::Channel {
                transform: Transform::Heat,
                channel,
                ..
            } => format!("heat_{channel}_fixed_ppm_per_unit"),
            Effect::Channel {
                transform, channel, ..
            } => format!("{}_{channel}_gain_um_per_unit", transform.as_str()),
        }
    }

    /// Names of the effect's linear gains, one per column it adds (`settling`, whose amplitudes
    /// are per zero segment, is named `settling_K_um` by the problem).
    pub(crate) fn gain_names(&self) -> Vec<String> {
        match self {
            Effect::AirGradient => vec![
                "gradient_fixed_ppm_per_k".into(),
                "gradient_scale_ppm_per_k".into(),
            ],
            Effect::Channel {
                transform: Transform::Heat,
                channel,
                ..
            } => vec![
                format!("heat_{channel}_fixed_ppm_per_unit"),
                format!("heat_{channel}_scale_ppm_per_unit"),
            ],
            _ => vec![self.gain_name()],
        }
    }

    /// Names of the gains that fit an event input's unknown start ([`start_terms`]): the level
    /// before its first event, and the deviation of its lag from steady state at the first
    /// fitted reading (µm both).
    fn start_gain_names(&self) -> (String, String) {
        match self {
            Effect::HeadHeating => (
                "head_before_first_event_um".into(),
                "head_initial_um".into(),
            ),
            Effect::Channel {
                transform, channel, ..
            } => (
                format!("{}_{channel}_before_first_event_um", transform.as_str()),
                format!("{}_{channel}_initial_um", transform.as_str()),
            ),
            _ => (
                format!("{}_before_first_event_um", self.name()),
                format!("{}_initial_um", self.name()),
            ),
        }
    }

    /// Name of the effect's own time constant, if it has one (`air_gradient` shares the base
    /// paths' `tau_r_s` and `tau_s_s`).
    pub(crate) fn tau_name(&self) -> Option<String> {
        match self {
            Effect::FixedPart => Some("tau_r_s".into()),
            Effect::Scale => Some("tau_s_s".into()),
            Effect::HeadHeating => Some("tau_head_s".into()),
            Effect::SecondPath => Some("tau_2_s".into()),
            Effect::Settling => Some("tau_settling_s".into()),
            Effect::AirGradient | Effect::PlateExpansion | Effect::Creep => None,
            Effect::Channel {
                transform: Transform::Level,
                ..
            } => None,
            Effect::Channel {
                transform, channel, ..
            } => Some(format!("{}_{channel}_tau_s", transform.as_str())),
        }
    }

    /// Initial time constant, seconds.
    fn tau0_s(&self) -> f64 {
        match self {
            Effect::FixedPart => 1800.0,
            Effect::Scale => 3600.0,
            Effect::HeadHeating => 900.0,
            Effect::SecondPath => 10800.0,
            Effect::Settling => 3600.0,
            Effect::Channel { tau0_s, .. } => tau0_s.unwrap_or(1800.0),
            Effect::AirGradient | Effect::PlateExpansion | Effect::Creep => f64::NAN,
        }
    }
}

#[cfg(test)]
mod tests;
