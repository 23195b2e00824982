//! [`Truth`]: what the simulator knows and the pipeline must find, written to `truth.json`.
//!
//! The true centre distance of a bar for `counts` at tilt `A` (no thermal error, plate at `T0`)
//! is [`BarTruth::true_distance_mm`]; from the JSON alone, with `g = bars[i].geometry`,
//! `k = resolution_nm`, `x = counts * k * 1e-6` (mm):
//!
//! `D = d_zero_mm + (x (1 + g.scale_ppm 1e-6) + g.nonlinearity_ppm_per_mm 1e-6 x^2) / cos(g.cosine_mrad 1e-3)
//!      - 1e-3 g.sag_um f(A) ((d_zero_mm + x) / g.sag_ref_mm)^g.sag_exponent`
//!
//! with `f(A) = cos A` (`sag_form = "cos"`) or `cos^2 A` (`"cos2"`). A reading carries on top the
//! thermal error `e` (indicated − true, µm): `D(counts, A) = D_true + e * 1e-3` up to noise and
//! quantization.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::config::{Mismatch, SimConfig};
pub use super::geometry::BarGeometry;
use dbbcal_core::campaign::Purpose;

/// Everything true about a simulated campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Truth {
    /// The configuration that produced the campaign (echo).
    pub(crate) config: SimConfig,
    /// Names of the effects switched on (as in `[effects]`).
    pub(crate) effects_on: Vec<String>,
    pub(crate) plate: PlateTruth,
    /// Each bar's true parameters.
    pub bars: Vec<BarTruth>,
    /// Each mount as simulated.
    pub mounts: Vec<MountTruth>,
    pub(crate) n_door_events: usize,
    /// Encoder rows written, all bars.
    pub(crate) n_encoder_rows: usize,
    /// The simulated hexapod, when there is one: per station the six true errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<crate::hexapod::DeviceTruth>,
}

/// The plate as simulated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PlateTruth {
    /// Expansion written in the manifest, ppm/K.
    pub(crate) declared_cte_ppm_per_k: f64,
    /// Expansion simulated (declared + undeclared `plate_expansion`), ppm/K.
    pub(crate) true_cte_ppm_per_k: f64,
    /// Plate temperature = T1 lagged by this time constant, seconds.
    pub(crate) thermal_tau_s: f64,
    /// The plate sensor id, when one is logged.
    pub(crate) sensor: Option<String>,
}

/// A bar's true parameters (`docs/spec/physics.md` notation) and its extra terms, when on.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct BarTruth {
    /// Bar id.
    pub id: String,
    /// `I_min`, millimetres.
    pub fixed_length_mm: f64,
    /// Distance at which the counter reads zero, millimetres.
    pub(crate) d_zero_mm: f64,
    /// Encoder resolution, nm a count.
    pub resolution_nm: f64,
    /// True alpha (fixed part), ppm/K.
    pub alpha_ppm_per_k: f64,
    /// True beta (scale), ppm/K.
    pub beta_ppm_per_k: f64,
    /// True tau_R, s.
    pub tau_r_s: f64,
    /// True tau_S, s.
    pub tau_s_s: f64,
    /// The sensor the manifest names for the bar.
    pub(crate) declared_sensor: String,
    /// Weights of the true air temperatures the bar actually follows (sum 1).
    pub(crate) seen_weights: BTreeMap<String, f64>,
    /// Read-head heating: growth `amplitude_um * lag(power; tau_s)`.
    pub head_heating: Option<HeadTruth>,
    /// Second path: growth `gain_ppm_per_k * I_min * lag(T - T0; tau_s)`.
    pub(crate) second_path: Option<SecondPathTruth>,
    /// Reading trend, µm/day.
    pub(crate) creep_um_per_day: Option<f64>,
    /// Growth `gain_um_per_k * lag(H - base_c; tau_s)` from the hidden channel.
    pub(crate) hidden_channel: Option<ChannelTruth>,
    /// Settling time constant after each mount (amplitudes are per mount).
    pub(crate) settling_tau_s: Option<f64>,
    /// Growth `(fixed I_min + scale I_p) lag(C - T1; tau_s)` from the heat source.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) heat_source: Option<HeatTruth>,
    /// Geometric terms of the counts -> distance mapping (all zero: ideal bar).
    #[serde(default)]
    pub(crate) geometry: BarGeometry,
    /// The factors this bar was made different by (`[[mismatch]]`), already applied to
    /// `alpha_ppm_per_k`, `beta_ppm_per_k`, the taus and `geometry.sag_um`.
    #[serde(default)]
    pub(crate) mismatch: Option<Mismatch>,
}

impl BarTruth {
    /// True centre distance (mm) for `counts` at tilt `tilt_deg` with no thermal error
    /// (`docs/spec/physics.md`: the centre distance function `D(n, A)`).
    pub fn true_distance_mm(&self, counts: f64, tilt_deg: f64) -> f64 {
        let travel_mm = counts * self.resolution_nm * 1e-6;
        self.d_zero_mm
            + self
                .geometry
                .true_travel_mm(travel_mm, tilt_deg, self.d_zero_mm)
    }

    /// Counts (unrounded) the bar reads at true distance `distance_mm` and tilt `tilt_deg` with
    /// no thermal error: the inverse of [`Self::true_distance_mm`].
    pub(crate) fn counts_at(&self, distance_mm: f64, tilt_deg: f64) -> f64 {
        let travel_mm = self.geometry.indicated_travel_mm(
            distance_mm - self.d_zero_mm,
            tilt_deg,
            self.d_zero_mm,
        );
        travel_mm * 1e6 / self.resolution_nm
    }
}

/// A bar's read-head heating as simulated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct HeadTruth {
    /// Growth of the bar with the head on, in steady state, µm.
    pub amplitude_um: f64,
    /// Time constant of the heating, s.
    pub tau_s: f64,
}

/// A bar's second thermal path as simulated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SecondPathTruth {
    pub(crate) gain_ppm_per_k: f64,
    pub(crate) tau_s: f64,
}

/// The heat source's effect on a bar as simulated (`[effects.heat_source]`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct HeatTruth {
    /// The cabinet's sensor.
    pub(crate) sensor: String,
    /// Expansion through the fixed part per kelvin of the cabinet's excess over T1, ppm/K.
    pub(crate) fixed_ppm_per_k: f64,
    /// The same through the scale (on `I_p`), ppm/K.
    pub(crate) scale_ppm_per_k: f64,
    /// Time constant of the heat reaching the bar, s.
    pub(crate) tau_s: f64,
}

/// The hidden channel's effect on a bar as simulated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ChannelTruth {
    pub(crate) sensor: String,
    pub(crate) base_c: f64,
    pub(crate) gain_um_per_k: f64,
    pub(crate) tau_s: f64,
}

/// One mount as simulated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct MountTruth {
    /// Bar id.
    pub bar: String,
    /// The plate length id; empty on a device.
    pub(crate) length: String,
    /// The target device, when the bar is on one (then `length` is empty).
    #[serde(default)]
    pub device: Option<String>,
    /// Tilt of the bar from horizontal during the mount, degrees.
    #[serde(default)]
    pub(crate) tilt_deg: f64,
    /// What the mount is for.
    #[serde(with = "dbbcal_io::manifest::as_written::purpose")]
    pub purpose: Purpose,
    /// RFC 3339, UTC (the manifest's `from`/`to`).
    pub from: String,
    /// End, RFC 3339, UTC (the manifest's `to`).
    pub to: String,
    /// Calibrated length, mm (true at `T0` of the plate); on a device its true distance.
    pub(crate) length_mm: f64,
    /// Counts at zero thermal error with the plate at `T0`:
    /// `BarTruth::counts_at(length_mm, tilt_deg)` (`(length_mm - d_zero_mm) / k` for an ideal bar).
    pub zero_counts: f64,
    /// Settling amplitude of this mount, µm added to the reading at `from`.
    pub(crate) settling_um: Option<f64>,
}
