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
//!   why (`summary.json`, the bar figure's notes). Matching (`pipeline::matched_inputs`) takes the bars
//!   with all four base parameters, or, when none has them, every bar on alpha and tau_R (NaN beta and
//!   tau_S in `MatchInput`).
//! - `I_p = plate length − fixed_length_mm` per mount (`series.rs`).
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
//!   `lag::zero_phase_lag`, 300 s), as does the declared-CTE correction in `series.rs`: a raw noisy
//!   level is an error in a regressor and biases alpha and beta.
//! - Weights: every fit is weighted by `BarSeries::weight` (1 for a reading, the node weight for a
//!   compressed bin); `ThermalProblem` demeans the zeros with weights and multiplies each row by
//!   `√w`, so the engine sees ordinary least squares. Samples of weight 0 are never fitted, nor
//!   taken as readings by calibration or compensation. Likelihood-ratio noise models get
//!   `√w`-weighted residuals (`BarSeries::weighted_residuals`). `BarSeries::binned_copy` (weighted
//!   bin means) is only a coarse copy for starts and profile shapes.
//! - `ThermalProblem` memoises each term's lag column and derivative by tau (shared `Arc`s, not
//!   copies): a solver's basis and derivative calls at one `theta`, and a 1-D search along one tau,
//!   reuse the other columns. Basis columns are gathered, masked, demeaned and weighted straight
//!   into the matrix (`ThermalProblem::write_row_column`).

pub(crate) mod channels;

use std::sync::{Arc, Mutex};

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::fit::Separable;
use crate::series::BarSeries;
use crate::signal::plate_temperature;
use channels::{Channel, ChannelError};

/// How a generic channel enters the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
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

/// An effect is written as its name (`diagnosis.json`, `summary.json`), the form `--add-effect`
/// and `[model] effects` accept.
impl serde::Serialize for Effect {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.name())
    }
}

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(&self.name())
    }
}

/// Longest time constant a term takes, s (about 32 years): the end of the range the fits search.
pub(crate) const MAX_TAU_S: f64 = 1e9;

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

/// One column source of an effect bound to one bar's data: its input channel and its column
/// scale. An effect binds to one term, `air_gradient` to one per base path.
#[derive(Debug, Clone)]
struct BoundTerm {
    effect: Effect,
    /// Name of the term's gain (with its unit).
    gain_name: String,
    input: Channel,
    /// Multiplies the (lagged) input per sample, e.g. `-I_min / 1000`; `None` = 1.
    scale: Option<Vec<f64>>,
    kind: TermKind,
    /// The term uses the time constant of another effect's term instead of its own.
    shares_tau_of: Option<Effect>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum TermKind {
    Lag,
    Rate,
    Level,
    /// `exp(-(t - mount start)/tau)` within each mount.
    Settling,
    /// `exp(-(t - from_s)/tau)` from `from_s` on, 1 before: the decay of an unknown deviation
    /// of a lag's state from the steady state it is assumed to start in, scaled to its value at
    /// `from_s` (the first fitted reading). Before `from_s` nothing is fitted and the deviation
    /// is held there, not extrapolated backwards.
    Decay {
        from_s: f64,
    },
    /// The decay of a base lag's departure from steady state when the logging started:
    /// `exp(-(t - t_ref)/tau)` with the path's time constant, `t_ref` the bar's first fitted
    /// sample ([`ThermalProblem::initial_state_reference_s`]).
    InitialState,
}

/// One bar's thermal model, ready for the fitting engine.
pub struct ThermalProblem<'a> {
    series: &'a BarSeries,
    effects: Vec<Effect>,
    /// The terms of `effects` this bar's data cannot determine, left out of the problem
    /// ([`not_identifiable`]).
    not_identifiable: Vec<NotIdentifiable>,
    /// Where the initial-state columns are 1: the bar's first fitted sample, seconds.
    initial_state_reference_s: f64,
    terms: Vec<BoundTerm>,
    /// Indices (into `terms`) of the terms with a time constant of their own, in `theta` order.
    tau_terms: Vec<usize>,
    /// Per term: index (into `terms`) of the term whose time constant it uses (itself for a
    /// term with its own; `None` for a term without one).
    tau_source: Vec<Option<usize>>,
    y: Vec<f64>,
    /// Zero column of each zero segment: only segments with fitted samples get one (a check
    /// mount is a zero segment without fitted samples; its column would be all zeros).
    zero_columns: Vec<Option<usize>>,
    n_zero_columns: usize,
    /// Zero column of each fitted sample (`None`: its segment has no zero).
    row_zero: Vec<Option<usize>>,
    /// Square root of each fitted sample's weight ([`BarSeries::weight`]): every row the engine
    /// sees is multiplied by it, so that its least squares are the weighted ones.
    sqrt_weight: Vec<f64>,
    /// Sum of the fitted samples' weights in each zero column.
    zero_weight: Vec<f64>,
    /// The fitted rows of each zero column lie within this range (first row, one past the
    /// last): a column masked to one zero column (`settling`'s amplitude per mount) is written
    /// there alone, not over the whole series.
    zero_rows: Vec<std::ops::Range<usize>>,
    /// The last column (and `ln tau` derivative) computed for each term with a time constant,
    /// keyed by the bits of its tau: a solver asks for the basis and then its derivatives at the
    /// same `theta`, and a 1-D search moves one time constant while the others stay put, so
    /// most lag recursions (the cost of a fit) are repeats. Results are the same bits.
    memo: Mutex<Vec<Option<TermMemo>>>,
    /// The last engine column written for each unmasked gain column of the basis
    /// ([`ThermalProblem::write_row_column`]), keyed by the bits of its term's tau (`None`: a
    /// term without one): a 1-D search or a screen moves one time constant while the other
    /// columns stay put, and gathering, demeaning and weighing every column again at each
    /// evaluation was the largest single cost of the diagnosis's fits. Same bits.
    row_memo: Mutex<Vec<Option<RowMemo>>>,
}

/// One engine column of [`ThermalProblem::row_memo`].
struct RowMemo {
    tau_bits: Option<u64>,
    column: Arc<Vec<f64>>,
}

struct TermMemo {
    tau_bits: u64,
    x: Arc<Vec<f64>>,
    d: Arc<Vec<f64>>,
}

/// A term's column on the bar's whole timeline and its `ln tau` derivative, shared with the
/// memo (a basis reads them, it does not copy them).
type TermColumn = (Arc<Vec<f64>>, Option<Arc<Vec<f64>>>);

/// A model that cannot be built for a bar.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ModelError {
    /// An effect's channel term could not be built.
    #[error("effect {effect}: {source}")]
    Channel {
        /// The effect's name.
        effect: String,
        /// Why.
        source: ChannelError,
    },
    /// The effect acts through the base paths, and the model has neither.
    #[error("effect {effect} acts through the base paths: add fixed_part or scale to the model")]
    NoBasePath {
        /// The effect's name.
        effect: String,
    },
}

impl<'a> ThermalProblem<'a> {
    /// `effects` bound to `series`. Terms the series cannot determine are left out and listed
    /// (`ThermalProblem::not_identifiable`): the scale's (`beta`, `tau_S`) when every fitted
    /// mount has the same travel `I_p`.
    pub fn new(series: &'a BarSeries, effects: &[Effect]) -> Result<Self, ModelError> {
        let (bound_effects, not_identifiable) = identifiable_effects(series, effects);
        let mut terms = Vec::with_capacity(2 * effects.len() + 2);
        for e in &bound_effects {
            let bound = bind(series, e, &bound_effects).map_err(|source| ModelError::Channel {
                effect: e.name(),
                source,
            })?;
            if bound.is_empty() {
                return Err(ModelError::NoBasePath { effect: e.name() });
            }
            terms.extend(bound);
        }
        let tau_terms: Vec<usize> = terms
            .iter()
            .enumerate()
            .filter(|(_, t)| t.shares_tau_of.is_none() && t.effect.tau_name().is_some())
            .map(|(i, _)| i)
            .collect();
        let tau_source = terms
            .iter()
            .enumerate()
            .map(|(j, t)| match &t.shares_tau_of {
                None => tau_terms.contains(&j).then_some(j),
                Some(owner) => tau_terms
                    .iter()
                    .copied()
                    .find(|&i| terms[i].effect == *owner),
            })
            .collect();
        let y_raw: Vec<f64> = series.fit_index.iter().map(|&i| series.y_um[i]).collect();
        let mut fitted = vec![false; series.n_zero_segments];
        for &i in &series.fit_index {
            if let Some(s) = series.zero_segment[i] {
                fitted[s as usize] = true;
            }
        }
        let mut n_zero_columns = 0;
        let zero_columns: Vec<Option<usize>> = fitted
            .iter()
            .map(|&f| {
                f.then(|| {
                    n_zero_columns += 1;
                    n_zero_columns - 1
                })
            })
            .collect();
        let mut problem = ThermalProblem {
            series,
            effects: effects.to_vec(),
            not_identifiable,
            initial_state_reference_s: series.fit_index.first().map_or(0.0, |&i| series.t_s[i]),
            terms,
            tau_terms,
            tau_source,
            y: Vec::new(),
            row_zero: series
                .fit_index
                .iter()
                .map(|&i| series.zero_segment[i].and_then(|s| zero_columns[s as usize]))
                .collect(),
            zero_columns,
            n_zero_columns,
            sqrt_weight: series
                .fit_index
                .iter()
                .map(|&i| series.weight[i].sqrt())
                .collect(),
            zero_weight: Vec::new(),
            zero_rows: Vec::new(),
            memo: Mutex::new(Vec::new()),
            row_memo: Mutex::new(Vec::new()),
        };
        problem.zero_weight = problem.segment_weights();
        problem.zero_rows = problem.segment_rows();
        problem.y = problem.demean(&y_raw);
        Ok(problem)
    }

    /// Fit these observations (one per fitted sample) instead of the bar's reading: the
    /// diagnosis explains a residual with a single channel this way.
    pub fn with_observations(mut self, y: Vec<f64>) -> Self {
        assert_eq!(y.len(), self.y.len(), "one observation per fitted sample");
        self.y = self.demean(&y);
        self
    }

    /// Zero column of each fitted sample (`None`: a sample whose segment has no zero).
    fn fit_row_zero(&self, r: usize) -> Option<usize> {
        self.row_zero[r]
    }

    /// Subtract each zero segment's weighted mean over the fitted samples (`v` indexed by fitted
    /// sample), then weigh each row by the square root of its sample's weight: a row as the
    /// engine sees it.
    ///
    /// The zeros are projected out (Frisch-Waugh-Lovell): fitting demeaned observations with
    /// demeaned gain columns gives exactly the gains, residuals and gain covariance of the fit
    /// with one indicator column per zero, at a cost that does not grow with the number of
    /// mounts. The zeros follow from the residual means ([`ThermalProblem::zeros_um`]).
    fn demean(&self, v: &[f64]) -> Vec<f64> {
        let means = self.segment_means(v.iter().copied());
        v.iter()
            .enumerate()
            .map(|(r, x)| {
                let centred = self.fit_row_zero(r).map_or(*x, |k| x - means[k]);
                centred * self.sqrt_weight[r]
            })
            .collect()
    }

    /// Weighted mean of `v` (one value per fitted sample) over each zero column's samples.
    fn segment_means(&self, v: impl Iterator<Item = f64>) -> Vec<f64> {
        let mut sum = vec![0.0; self.n_zero_columns];
        for (r, x) in v.enumerate() {
            if let Some(k) = self.fit_row_zero(r) {
                let w = self.sqrt_weight[r] * self.sqrt_weight[r];
                sum[k] += w * x;
            }
        }
        sum.iter()
            .zip(&self.zero_weight)
            .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
            .collect()
    }

    /// The range of fitted rows holding each zero column's samples.
    fn segment_rows(&self) -> Vec<std::ops::Range<usize>> {
        let mut rows: Vec<Option<(usize, usize)>> = vec![None; self.n_zero_columns];
        for (r, zero) in self.row_zero.iter().enumerate() {
            if let Some(k) = zero {
                let (first, _) = rows[*k].unwrap_or((r, r));
                rows[*k] = Some((first, r + 1));
            }
        }
        rows.into_iter()
            .map(|r| r.map_or(0..0, |(first, end)| first..end))
            .collect()
    }

    /// Sum of the fitted samples' weights over each zero column's samples.
    fn segment_weights(&self) -> Vec<f64> {
        let mut weight = vec![0.0; self.n_zero_columns];
        for (zero, s) in self.row_zero.iter().zip(&self.sqrt_weight) {
            if let Some(k) = zero {
                weight[*k] += s * s;
            }
        }
        weight
    }

    /// Residuals in µm at the fitted samples from the engine's (weighted) residuals.
    pub(crate) fn unweighted(&self, residuals: &[f64]) -> Vec<f64> {
        residuals
            .iter()
            .zip(&self.sqrt_weight)
            .map(|(r, s)| r / s)
            .collect()
    }

    /// Number of zeros projected out of the problem (parameters the engine does not see).
    pub fn n_zeros(&self) -> usize {
        self.n_zero_columns
    }

    /// The zeros (µm) of a fit with `gains` at `theta`: each segment's mean of reading minus
    /// thermal model over its fitted samples; 0 for a segment without fitted samples.
    pub(crate) fn zeros_um(&self, theta: &[f64], gains: &[f64]) -> Vec<f64> {
        let columns = self.full_columns(theta);
        let means = self.segment_means(self.series.fit_index.iter().map(|&i| {
            let thermal: f64 = columns.iter().zip(gains).map(|(c, g)| c[i] * g).sum();
            self.series.y_um[i] - thermal
        }));
        self.zero_columns
            .iter()
            .map(|c| c.map_or(0.0, |k| means[k]))
            .collect()
    }

    /// `theta0`: `ln tau` of every term with a time constant.
    pub(crate) fn theta0(&self) -> Vec<f64> {
        self.tau_terms
            .iter()
            .map(|&i| self.terms[i].effect.tau0_s().ln())
            .collect()
    }

    /// The effects asked for (some of their terms may be left out: [`Self::not_identifiable`]).
    pub(crate) fn effects(&self) -> Vec<Effect> {
        self.effects.clone()
    }

    /// The terms of the effects asked for that this bar's data cannot determine, left out.
    pub(crate) fn not_identifiable(&self) -> &[NotIdentifiable] {
        &self.not_identifiable
    }

    /// Names of the time constants in `theta` order (e.g. `tau_r_s`).
    pub(crate) fn tau_names(&self) -> Vec<String> {
        self.tau_terms
            .iter()
            .map(|&i| self.terms[i].effect.tau_name().unwrap_or_default())
            .collect()
    }

    /// Per gain column: whether it is a nuisance gain (an initial-state transient, like the
    /// zeros not a property of the bar) rather than a parameter of the model.
    pub(crate) fn nuisance_gains(&self) -> Vec<bool> {
        self.gain_columns()
            .into_iter()
            .map(|(j, _)| self.terms[j].kind == TermKind::InitialState)
            .collect()
    }

    /// Zero column (after the gains) of each zero segment; `None` for a segment without fitted
    /// samples (its zero is unknown).
    pub fn zero_columns(&self) -> &[Option<usize>] {
        &self.zero_columns
    }

    /// The gain columns: `(term, zero column)`. Most terms have one gain; `settling` has one per
    /// zero segment (`settling_K_um`: its amplitude differs from mount to mount), masked to
    /// that segment.
    fn gain_columns(&self) -> Vec<(usize, Option<usize>)> {
        let mut out = Vec::new();
        for (j, t) in self.terms.iter().enumerate() {
            if t.kind == TermKind::Settling {
                out.extend((0..self.n_zero_columns).map(|k| (j, Some(k))));
            } else {
                out.push((j, None));
            }
        }
        out
    }

    /// Number of linear columns before the zeros.
    pub(crate) fn n_gains(&self) -> usize {
        self.gain_columns().len()
    }

    /// Names of the gain columns, in order.
    pub(crate) fn gain_names(&self) -> Vec<String> {
        self.gain_columns()
            .into_iter()
            .map(|(j, k)| match k {
                Some(k) => format!("settling_{k}_um"),
                None => self.terms[j].gain_name.clone(),
            })
            .collect()
    }

    /// Zero the samples of `col` outside zero column `k`.
    fn mask_to(&self, col: &mut [f64], k: usize) {
        for (v, seg) in col.iter_mut().zip(&self.series.zero_segment) {
            if seg.and_then(|s| self.zero_columns[s as usize]) != Some(k) {
                *v = 0.0;
            }
        }
    }

    /// The model's gain columns for every sample of the bar (not only the fitted ones), for
    /// plotting and for evaluating the model outside its fit mounts.
    pub(crate) fn full_columns(&self, theta: &[f64]) -> Vec<Vec<f64>> {
        let per_term: Vec<Arc<Vec<f64>>> = (0..self.terms.len())
            .map(|j| self.term_column(j, theta, false).0)
            .collect();
        self.gain_columns()
            .into_iter()
            .map(|(j, k)| {
                let mut col = per_term[j].to_vec();
                if let Some(k) = k {
                    self.mask_to(&mut col, k);
                }
                col
            })
            .collect()
    }

    /// Time constant of term `j` (its own or the one it shares), kept within 1 s ..
    /// [`MAX_TAU_S`] so that a solver wandering off to an unidentifiable extreme never produces
    /// infinities.
    fn tau_of(&self, j: usize, theta: &[f64]) -> Option<f64> {
        let owner = self.tau_source[j]?;
        self.tau_terms
            .iter()
            .position(|&i| i == owner)
            .map(|k| theta[k].clamp(0.0, MAX_TAU_S.ln()).exp())
    }

    /// Column of term `j` on the bar's whole timeline, and its derivative in `ln tau`
    /// (memoised per term: see [`ThermalProblem::memo`]; a term with a time constant is always
    /// computed with its derivative, which costs no extra exponential).
    fn term_column(&self, j: usize, theta: &[f64], with_derivative: bool) -> TermColumn {
        let Some(tau) = self.tau_of(j, theta) else {
            let (x, d) = self.compute_term_column(j, None, with_derivative);
            return (Arc::new(x), d.map(Arc::new));
        };
        let bits = tau.to_bits();
        {
            let memo = self.memo.lock().unwrap_or_else(|p| p.into_inner());
            if let Some(m) = memo
                .get(j)
                .and_then(Option::as_ref)
                .filter(|m| m.tau_bits == bits)
            {
                return (m.x.clone(), with_derivative.then(|| m.d.clone()));
            }
        }
        let (x, d) = self.compute_term_column(j, Some(tau), true);
        let x = Arc::new(x);
        let Some(d) = d.map(Arc::new) else {
            return (x, None);
        };
        let out = (x.clone(), with_derivative.then(|| d.clone()));
        let mut memo = self.memo.lock().unwrap_or_else(|p| p.into_inner());
        if memo.len() <= j {
            memo.resize_with(j + 1, || None);
        }
        memo[j] = Some(TermMemo {
            tau_bits: bits,
            x,
            d,
        });
        out
    }

    fn compute_term_column(
        &self,
        j: usize,
        tau: Option<f64>,
        with_derivative: bool,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let term = &self.terms[j];
        let t = &self.series.t_s;
        let (mut x, mut d) = match (term.kind, tau) {
            (TermKind::Lag, Some(tau)) => term.input.lag(t, tau, with_derivative),
            (TermKind::Rate, Some(tau)) => {
                let (l, dl) = term.input.lag(t, tau, with_derivative);
                let u = term.input.level(t.len());
                (
                    u.iter().zip(&l).map(|(u, l)| u - l).collect(),
                    dl.map(|d| d.into_iter().map(|v| -v).collect()),
                )
            }
            (TermKind::Settling, Some(tau)) => settling(self.series, tau, with_derivative),
            (TermKind::Decay { from_s }, Some(tau)) => decay(t, from_s, tau, with_derivative),
            (TermKind::InitialState, Some(tau)) => {
                decay(t, self.initial_state_reference_s, tau, with_derivative)
            }
            _ => (term.input.level(t.len()), None),
        };
        if let Some(s) = &term.scale {
            x.iter_mut().zip(s).for_each(|(x, s)| *x *= s);
            if let Some(d) = d.as_mut() {
                d.iter_mut().zip(s).for_each(|(d, s)| *d *= s);
            }
        }
        (x, d)
    }

    /// A full-timeline column as the engine sees it, written into `out` (one row per fitted
    /// sample): gathered at the fitted samples, kept only within zero column `seg` if given
    /// ([`ThermalProblem::mask_to`] on the fitted rows), demeaned and weighed as
    /// [`ThermalProblem::demean`] does, without the intermediate vectors (the basis is rebuilt
    /// at every evaluation of a fit).
    ///
    /// `out` must be zero on entry: a column that vanishes from some sample on (an initial-state
    /// transient, [`initial_state`]) is written only up to the end of the last zero segment it
    /// reaches; the rows after it stay zero (their segments' means are zero too).
    fn write_row_column(&self, full: &[f64], seg: Option<usize>, out: &mut [f64]) {
        if let Some(k) = seg {
            self.write_masked_row_column(full, k, out);
            return;
        }
        let support = full.iter().rposition(|v| *v != 0.0).map_or(0, |i| i + 1);
        let mut n_rows = self.series.fit_index.partition_point(|&i| i < support);
        if let Some(Some(k)) = n_rows.checked_sub(1).map(|r| self.row_zero[r]) {
            while n_rows < out.len() && self.row_zero[n_rows] == Some(k) {
                n_rows += 1;
            }
        }
        let out = &mut out[..n_rows];
        let mut sums = vec![0.0; self.n_zero_columns];
        let rows = out
            .iter_mut()
            .zip(&self.series.fit_index)
            .zip(&self.row_zero);
        for (((o, &i), zero), w) in rows.zip(&self.sqrt_weight) {
            let x = full[i];
            *o = x;
            if let Some(k) = zero {
                sums[*k] += w * w * x;
            }
        }
        let means: Vec<f64> = sums
            .iter()
            .zip(&self.zero_weight)
            .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
            .collect();
        for ((o, zero), w) in out.iter_mut().zip(&self.row_zero).zip(&self.sqrt_weight) {
            let centred = zero.map_or(*o, |k| *o - means[k]);
            *o = centred * w;
        }
    }

    /// [`ThermalProblem::write_row_column`] of a column kept only within zero column `k`: the
    /// other rows stay zero (so do their segments' means), and only the rows of `k` are visited
    /// (`settling` has one such column per mount: over the whole series each, they cost as
    /// much as the rest of the basis times the number of mounts).
    fn write_masked_row_column(&self, full: &[f64], k: usize, out: &mut [f64]) {
        let rows = self.zero_rows[k].clone();
        let (mut sum, weight) = (0.0, self.zero_weight[k]);
        for r in rows.clone() {
            if self.row_zero[r] == Some(k) {
                let x = full[self.series.fit_index[r]];
                out[r] = x;
                sum += self.sqrt_weight[r] * self.sqrt_weight[r] * x;
            }
        }
        let mean = if weight > 0.0 { sum / weight } else { 0.0 };
        for r in rows {
            if self.row_zero[r] == Some(k) {
                out[r] = (out[r] - mean) * self.sqrt_weight[r];
            }
        }
    }
}

fn settling(series: &BarSeries, tau: f64, with_derivative: bool) -> (Vec<f64>, Option<Vec<f64>>) {
    let mut x = Vec::with_capacity(series.t_s.len());
    let mut d = with_derivative.then(|| Vec::with_capacity(series.t_s.len()));
    for (t, m) in series.t_s.iter().zip(&series.mount_of) {
        let (v, dv) = match m {
            Some(m) => {
                let s = (t - series.mounts[*m as usize].from_s).max(0.0);
                let e = (-s / tau).exp();
                (e, e * s / tau)
            }
            None => (0.0, 0.0),
        };
        x.push(v);
        if let Some(d) = d.as_mut() {
            d.push(dv);
        }
    }
    (x, d)
}

/// The decay of a lag's initial departure from steady state, `exp(-(t - t_ref)/tau)` for
/// `t >= t_ref`, 1 before, and its `ln tau` derivative `exp(-(t - t_ref)/tau) (t - t_ref)/tau`:
/// the column of [`TermKind::InitialState`] (the base paths, `t_ref` the first fitted reading)
/// and of [`TermKind::Decay`] (a powered head's initial heat, `t_ref = from_s`).
///
/// Why: a lag is computed from steady state at the bar's first sample ([`lag::lag`]), but a bar
/// whose room was drifting before the logging began is not in steady state then: its state
/// departs by `delta` and the departure decays with the lag's own time constant, whatever the
/// air does since (the lag is linear). The departure cannot be read from the logs, so it is a
/// fitted gain on this column. Unit at the bar's first fitted sample (`t_ref`), so the column
/// never vanishes on the fitted samples whatever `tau` is; held at 1 before it (samples there are
/// not fitted; the departure before is only bounded from below).
pub(crate) fn decay(
    t_s: &[f64],
    t_ref: f64,
    tau: f64,
    with_derivative: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let n = t_s.len();
    let mut x = vec![0.0; n];
    let mut d = with_derivative.then(|| vec![0.0; n]);
    // exp(-(t - t_ref)/tau) by recursion over the (sorted) samples, the step factor of each
    // step length computed once: a timeline repeats a few steps, and an exponential a sample
    // would cost as much as the lags themselves. Relative drift ~1e-16 a step.
    let mut steps = [(u64::MAX, 0.0f64); 8];
    let mut slot = 0;
    let mut previous: Option<(f64, f64)> = None;
    for (k, &t) in t_s.iter().enumerate() {
        let e = if t <= t_ref {
            1.0
        } else {
            match previous {
                Some((_, 0.0)) => 0.0,
                Some((tp, ep)) if tp >= t_ref => {
                    let dt = t - tp;
                    let bits = dt.to_bits();
                    let a = match steps.iter().find(|(b, _)| *b == bits) {
                        Some(&(_, a)) => a,
                        None => {
                            let a = (-dt / tau).exp();
                            steps[slot] = (bits, a);
                            slot = (slot + 1) % steps.len();
                            a
                        }
                    };
                    let e = ep * a;
                    // Below anything a fit in double precision can see (the column is 1 at
                    // t_ref): exactly 0 from here on, so the basis skips the rest.
                    if e < 1e-13 {
                        0.0
                    } else {
                        e
                    }
                }
                _ => (-(t - t_ref) / tau).exp(),
            }
        };
        x[k] = e;
        if let Some(d) = d.as_mut() {
            d[k] = e * (t - t_ref).max(0.0) / tau;
        }
        previous = Some((t, e));
    }
    (x, d)
}

/// A group of parameters of the effects asked for that one bar's data cannot determine, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NotIdentifiable {
    /// The parameters' names.
    pub params: Vec<String>,
    /// Why the data cannot determine them.
    pub reason: String,
}

/// Travel spread (mm) below which a bar's fitted mounts are taken as one length.
const ONE_LENGTH_SPREAD_MM: f64 = 1e-6;

/// The effects whose terms `series` can determine, and what was left out.
///
/// One length: when every fitted sample of the bar has the same travel `I_p` (all its plate
/// mounts on one length, e.g. a bar on a machine tool's spindle), the scale's term
/// `-beta I_p lag(T; tau_S)` is a second lag of the air with a constant factor: nothing in the
/// data says which of two lags is the scale's, so `beta` and `tau_S` are not identifiable (and
/// with `I_p = 0` the column vanishes). The scale (and `air_gradient`'s scale path) is left out;
/// the fixed part's `alpha` and `tau_R` then describe the whole bar at that length (its
/// expansion referred to `I_min`: `alpha + beta I_p / I_min` when the taus are close). A second
/// time constant, if the data call for one, is the diagnosis' `second_path`.
pub(crate) fn identifiable_effects(
    series: &BarSeries,
    effects: &[Effect],
) -> (Vec<Effect>, Vec<NotIdentifiable>) {
    if !effects.contains(&Effect::Scale) {
        return (effects.to_vec(), Vec::new());
    }
    let travel =
        |i: usize| series.mount_of[i].map_or(f64::NAN, |m| series.mounts[m as usize].i_p_mm);
    let (lo, hi) = series
        .fit_index
        .iter()
        .map(|&i| travel(i))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let spread_mm = hi - lo;
    if spread_mm.is_nan() || spread_mm > ONE_LENGTH_SPREAD_MM {
        return (effects.to_vec(), Vec::new());
    }
    let mut params = vec![
        Effect::Scale.gain_name(),
        Effect::Scale.tau_name().unwrap_or_default(),
    ];
    for e in effects {
        if matches!(
            e,
            Effect::AirGradient
                | Effect::Channel {
                    transform: Transform::Heat,
                    ..
                }
        ) {
            params.push(e.gain_names()[1].clone());
        }
    }
    let reason = format!(
        "every fitted mount of the bar is at one length (I_p = {lo:.3} mm): the scale's \
         expansion (beta, tau_S) cannot be told from the fixed part's with one length; \
         alpha_ppm_per_k and tau_r_s describe the whole bar at this length (alpha + beta I_p / \
         I_min when the time constants are close); mount the bar on two lengths to separate them"
    );
    let kept = effects
        .iter()
        .filter(|e| **e != Effect::Scale)
        .cloned()
        .collect();
    (kept, vec![NotIdentifiable { params, reason }])
}

/// Bind an effect to a bar's data: its input channel and per-sample scale, one term per column
/// (`air_gradient`: one per base path of `model`, none when the model has neither).
fn bind(
    series: &BarSeries,
    effect: &Effect,
    model: &[Effect],
) -> Result<Vec<BoundTerm>, ChannelError> {
    let t0 = series.reference_temperature_c;
    let minus_i_min = || Some(vec![-series.bar.fixed_length_mm * 1e-3; series.t_s.len()]);
    let minus_i_p = || Some(series.i_p_mm().iter().map(|ip| -ip * 1e-3).collect());
    let air = || Channel::Sampled(series.air_c.iter().map(|t| t - t0).collect());
    let term = |input, scale, kind| BoundTerm {
        effect: effect.clone(),
        gain_name: effect.gain_name(),
        input,
        scale,
        kind,
        shares_tau_of: None,
    };
    // A base path: its lag of the air and the decay of its initial departure from steady
    // state ([`initial_state`]), on the same length and time constant.
    let base_path = |scale: Option<Vec<f64>>, initial_name: &str| {
        vec![
            term(air(), scale.clone(), TermKind::Lag),
            BoundTerm {
                gain_name: initial_name.to_string(),
                shares_tau_of: Some(effect.clone()),
                ..term(Channel::Sampled(Vec::new()), scale, TermKind::InitialState)
            },
        ]
    };
    let single = match effect {
        Effect::FixedPart => return Ok(base_path(minus_i_min(), INITIAL_FIXED)),
        Effect::Scale => return Ok(base_path(minus_i_p(), INITIAL_SCALE)),
        Effect::SecondPath => term(air(), minus_i_min(), TermKind::Lag),
        Effect::HeadHeating => {
            let (input, start) = channels::held_event_channel(series, "head_power")?;
            let scale = Some(vec![-1.0; series.t_s.len()]);
            let mut terms = vec![term(input, scale.clone(), TermKind::Lag)];
            terms.extend(start_terms(series, effect, &start, scale, TermKind::Lag));
            return Ok(terms);
        }
        Effect::AirGradient => {
            // `docs/spec/physics.md` model with `T = T_own + w dT_grad`: the gradient's share through each
            // base path, on that path's length and with that path's time constant.
            let gradient = channels::air_gradient(series)?;
            let names = effect.gain_names();
            let paths = [
                (Effect::FixedPart, minus_i_min(), &names[0]),
                (Effect::Scale, minus_i_p(), &names[1]),
            ];
            return Ok(paths
                .into_iter()
                .filter(|(path, ..)| model.contains(path))
                .map(|(path, scale, name)| BoundTerm {
                    gain_name: name.clone(),
                    shares_tau_of: Some(path),
                    ..term(gradient.clone(), scale, TermKind::Lag)
                })
                .collect());
        }
        Effect::PlateExpansion => {
            // `docs/spec/campaign-format.md`: the true distance is `mm (1 + cte (T_plate - T0))`, so an
            // undeclared expansion raises the reading by `cte L (T_plate - T0)` (µm: mm · ppm/K ·
            // K · 1e-3).
            let plate = plate_temperature(&series.t_s, &channels::plate_temperature(series)?);
            let length: Vec<f64> = series
                .mount_of
                .iter()
                .map(|m| {
                    m.and_then(|m| series.mounts[m as usize].length_mm)
                        .unwrap_or(0.0)
                        * 1e-3
                })
                .collect();
            term(
                Channel::Sampled(plate.iter().map(|t| t - t0).collect()),
                Some(length),
                TermKind::Level,
            )
        }
        Effect::Settling => term(
            Channel::Sampled(vec![0.0; series.t_s.len()]),
            None,
            TermKind::Settling,
        ),
        Effect::Creep => term(
            Channel::Sampled(series.t_s.iter().map(|t| t / 86400.0).collect()),
            None,
            TermKind::Level,
        ),
        Effect::Channel {
            transform: Transform::Heat,
            channel,
            ..
        } => {
            // Heat from the channel reaches both of the bar's lengths through one lag of its
            // own: the fixed part's share on `I_min`, the scale's on `I_p` (left out when the
            // model has no scale: one length cannot tell the two apart, as for `air_gradient`).
            if channel.starts_with("event:") {
                return Err(ChannelError::HeatNeedsSampled(channel.clone()));
            }
            let input = channels::resolve(series, channel)?;
            let names = effect.gain_names();
            let mut terms = vec![BoundTerm {
                gain_name: names[0].clone(),
                ..term(input.clone(), minus_i_min(), TermKind::Lag)
            }];
            if model.contains(&Effect::Scale) {
                terms.push(BoundTerm {
                    gain_name: names[1].clone(),
                    shares_tau_of: Some(effect.clone()),
                    ..term(input, minus_i_p(), TermKind::Lag)
                });
            }
            return Ok(terms);
        }
        Effect::Channel {
            transform, channel, ..
        } => {
            let kind = match transform {
                // (`heat:` is bound above, as lags.)
                Transform::Lag | Transform::Heat => TermKind::Lag,
                Transform::Rate => TermKind::Rate,
                Transform::Level => TermKind::Level,
            };
            if let Some(event_kind) = channel.strip_prefix("event:") {
                let (input, start) = channels::held_event_channel(series, event_kind)?;
                let mut terms = vec![term(input, None, kind)];
                terms.extend(start_terms(series, effect, &start, None, kind));
                return Ok(terms);
            }
            term(channels::resolve(series, channel)?, None, kind)
        }
    };
    Ok(vec![single])
}

/// The extra terms that fit what the data leave unknown about a held event input's start
/// ([`channels::HeldStart`]), on the time constant of `effect`'s own term: a free level before
/// the first event (the indicator of "before", transformed as the effect's input is), and the
/// decay of an unknown initial deviation of its lag ([`TermKind::Decay`]; a level has no lag).
fn start_terms(
    series: &BarSeries,
    effect: &Effect,
    start: &channels::HeldStart,
    scale: Option<Vec<f64>>,
    kind: TermKind,
) -> Vec<BoundTerm> {
    let (level_name, deviation_name) = effect.start_gain_names();
    let shares_tau_of = (kind != TermKind::Level).then(|| effect.clone());
    let mut terms = Vec::new();
    if let Some(indicator) = start.level_channel(&series.t_s) {
        terms.push(BoundTerm {
            effect: effect.clone(),
            gain_name: level_name,
            input: indicator,
            scale: scale.clone(),
            kind,
            shares_tau_of: shares_tau_of.clone(),
        });
    }
    if let (Some(from_s), Some(_)) = (start.free_deviation_from_s, &shares_tau_of) {
        terms.push(BoundTerm {
            effect: effect.clone(),
            gain_name: deviation_name,
            input: Channel::Sampled(Vec::new()),
            scale,
            kind: TermKind::Decay { from_s },
            shares_tau_of,
        });
    }
    terms
}

impl Separable for ThermalProblem<'_> {
    fn observations(&self) -> &[f64] {
        &self.y
    }

    fn nonlinear_names(&self) -> Vec<String> {
        self.tau_terms
            .iter()
            .map(|&i| format!("ln_{}", self.terms[i].effect.tau_name().unwrap_or_default()))
            .collect()
    }

    fn linear_names(&self) -> Vec<String> {
        self.gain_names()
    }

    fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
        let gains = self.gain_columns();
        let mut per_term: Vec<Option<Arc<Vec<f64>>>> = vec![None; self.terms.len()];
        let mut phi = DMatrix::zeros(self.y.len(), gains.len());
        for (c, (j, seg)) in gains.into_iter().enumerate() {
            let mut out = phi.column_mut(c);
            let out = out.as_mut_slice();
            // Masked columns (settling's, one per mount) are written over their mount alone:
            // cheap, and memoised they would hold a whole column each.
            let key = seg
                .is_none()
                .then(|| self.tau_of(j, theta).map(f64::to_bits));
            if let Some(key) = key {
                let memo = self.row_memo.lock().unwrap_or_else(|p| p.into_inner());
                if let Some(m) = memo.get(c).and_then(Option::as_ref) {
                    if m.tau_bits == key && m.column.len() == out.len() {
                        out.copy_from_slice(&m.column);
                        continue;
                    }
                }
            }
            let full = per_term[j].get_or_insert_with(|| self.term_column(j, theta, false).0);
            self.write_row_column(full, seg, out);
            if let Some(key) = key {
                let mut memo = self.row_memo.lock().unwrap_or_else(|p| p.into_inner());
                if memo.len() <= c {
                    memo.resize_with(c + 1, || None);
                }
                memo[c] = Some(RowMemo {
                    tau_bits: key,
                    column: Arc::new(out.to_vec()),
                });
            }
        }
        phi
    }

    fn basis_derivative(&self, theta: &[f64], k: usize) -> DMatrix<f64> {
        let gains = self.gain_columns();
        let mut d = DMatrix::zeros(self.y.len(), gains.len());
        let owner = self.tau_terms[k];
        // Every term on this time constant: the owner and the terms sharing it.
        for j in (0..self.terms.len()).filter(|&j| self.tau_source[j] == Some(owner)) {
            let (_, Some(full)) = self.term_column(j, theta, true) else {
                continue;
            };
            for (c, (_, seg)) in gains.iter().enumerate().filter(|(_, (term, _))| *term == j) {
                self.write_row_column(&full, *seg, d.column_mut(c).as_mut_slice());
            }
        }
        d
    }

    fn start_search_interval(&self, _k: usize) -> Option<(f64, f64)> {
        Some((60f64.ln(), (30.0 * 86400f64).ln()))
    }

    fn absorbed_groups(&self) -> Option<Vec<Option<usize>>> {
        Some((0..self.y.len()).map(|r| self.fit_row_zero(r)).collect())
    }

    fn unexplained_rss(&self) -> f64 {
        self.series.within_bin_rss_um2
    }

    fn represented_samples(&self) -> usize {
        self.series.fitted_readings().max(self.y.len())
    }
}

#[cfg(test)]
mod tests;
