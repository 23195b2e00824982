//! The configuration of a simulated `probe` campaign (a simulation TOML with `kind = "probe"`),
//! its defaults and its checks (the one limits vocabulary, `dbbcal_core::limits`).

use chrono::{DateTime, TimeZone, Utc};
use serde::{Deserialize, Serialize};

use dbbcal_core::axis_campaign::CampaignKind;
use dbbcal_core::limits::{CountLimit, Limit};
use dbbcal_core::probe_campaign::ArtefactKind;

use crate::SimError;

/// The whole configuration.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimConfig {
    /// Must be `"probe"`.
    #[serde(with = "dbbcal_io::manifest::as_written::campaign_kind")]
    pub kind: CampaignKind,
    /// Seed of every random draw.
    pub seed: u64,
    /// Campaign id.
    pub campaign_id: String,
    /// First touch (UTC).
    #[serde(with = "crate::config::start_time")]
    pub start: DateTime<Utc>,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// The probe's model (informative).
    pub probe_model: String,
    /// The stylus.
    pub stylus: ProbeSimStylus,
    /// The artefact.
    pub artefact: ProbeSimArtefact,
    /// The touching programme.
    pub touches: ProbeSimTouches,
    /// The pretravel (seed eqs. 10–11) and the trigger.
    pub pretravel: ProbeSimPretravel,
    /// The first-touch reversal: the rest offset O(a).
    pub reversal: ProbeSimReversal,
    /// Machine drift of the functional point, µm/h along X, Y, Z.
    pub drift_um_per_h: [f64; 3],
    /// How the files are written.
    pub output: ProbeSimOutput,
}

/// `[stylus]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimStylus {
    /// Id.
    pub id: String,
    /// Nominal tip diameter (manifest), mm.
    pub tip_diameter_mm: f64,
    /// True tip diameter − nominal, µm.
    pub tip_error_um: f64,
    /// Length, mm.
    pub length_mm: f64,
}

/// `[artefact]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimArtefact {
    /// Id.
    pub id: String,
    /// Ring or sphere.
    #[serde(with = "dbbcal_io::manifest::as_written::artefact_kind")]
    pub kind: ArtefactKind,
    /// Certified (and true) diameter, mm.
    pub diameter_mm: f64,
    /// Certificate's standard uncertainty, µm.
    pub u_um: f64,
    /// Where the touching programme is centred, mm.
    pub centre_mm: [f64; 3],
    /// The true centre's offset from `centre_mm`, µm (the analysis is not told).
    pub centre_offset_um: [f64; 3],
    /// Write `centre_mm` in the manifest as known (then the offset shows as a 1st harmonic).
    pub declare_centre: bool,
    /// True form: amplitude (µm) of a lobed radius deviation a cos(n(φ − phase)).
    pub form_um: f64,
    /// Its lobes n.
    pub form_lobes: u32,
    /// Its phase, degrees.
    pub form_phase_deg: f64,
}

/// `[touches]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimTouches {
    /// Equally spaced directions (in azimuth).
    pub directions: usize,
    /// Azimuth of the first direction, degrees.
    pub first_phi_deg: f64,
    /// Touches in each direction.
    pub per_direction: usize,
    /// Elevation of every approach, degrees (a ring takes 0).
    pub elevation_deg: f64,
    /// `sequential` (φ increasing) or `shuffled` (a random order of directions).
    pub order: String,
    /// From one touch to the next, s.
    pub interval_s: f64,
    /// Approach feed, mm/min.
    pub feed_mm_min: f64,
    /// Spindle orientations; the whole pattern is repeated at each (`[]`: not written).
    pub spindle_deg: Vec<f64>,
}

/// `[pretravel]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimPretravel {
    /// δ_min = P S / (6 L K), µm (the tri-lobe: δ runs from δ_min to 2 δ_min).
    pub delta_min_um: f64,
    /// φ₀, the direction of one seat, degrees.
    pub seat_phase_deg: f64,
    /// Trigger latency τ, ms (pretravel += feed × τ).
    pub latency_ms: f64,
    /// Trigger noise along the approach, µm (1σ).
    pub noise_um: f64,
}

/// `[reversal]`: after a touch in direction a the pendulum re-seats at
/// O(a) = rest_um (cos(φ_a + twist), sin(φ_a + twist), 0).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimReversal {
    /// |O(a)|, µm.
    pub rest_um: f64,
    /// The rest offset's azimuth relative to the last approach, degrees.
    pub twist_deg: f64,
}

/// `[output]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSimOutput {
    /// Files the touches are split into.
    pub files: usize,
    /// Shuffle the rows of each file.
    pub shuffle_rows: bool,
    /// Write φ, θ instead of i, j, k.
    pub angles: bool,
}

impl Default for ProbeSimConfig {
    fn default() -> Self {
        ProbeSimConfig {
            kind: CampaignKind::Probe,
            seed: 3,
            campaign_id: "sim-probe".into(),
            start: Utc
                .with_ymd_and_hms(2027, 2, 1, 8, 0, 0)
                .single()
                .unwrap_or_default(),
            reference_temperature_c: 20.0,
            probe_model: "TP2-5".into(),
            stylus: ProbeSimStylus::default(),
            artefact: ProbeSimArtefact::default(),
            touches: ProbeSimTouches::default(),
            pretravel: ProbeSimPretravel::default(),
            reversal: ProbeSimReversal::default(),
            drift_um_per_h: [0.0; 3],
            output: ProbeSimOutput::default(),
        }
    }
}

impl Default for ProbeSimStylus {
    fn default() -> Self {
        ProbeSimStylus {
            id: "S1".into(),
            tip_diameter_mm: 6.0,
            tip_error_um: 0.0,
            length_mm: 50.0,
        }
    }
}

impl Default for ProbeSimArtefact {
    fn default() -> Self {
        ProbeSimArtefact {
            id: "ring-50".into(),
            kind: ArtefactKind::Ring,
            diameter_mm: 50.0012,
            u_um: 0.05,
            centre_mm: [250.0, 150.0, -80.0],
            centre_offset_um: [0.0; 3],
            declare_centre: false,
            form_um: 0.0,
            form_lobes: 2,
            form_phase_deg: 0.0,
        }
    }
}

impl Default for ProbeSimTouches {
    fn default() -> Self {
        ProbeSimTouches {
            directions: 24,
            first_phi_deg: 0.0,
            per_direction: 10,
            elevation_deg: 0.0,
            order: "shuffled".into(),
            interval_s: 3.0,
            feed_mm_min: 100.0,
            spindle_deg: Vec::new(),
        }
    }
}

impl Default for ProbeSimPretravel {
    fn default() -> Self {
        ProbeSimPretravel {
            delta_min_um: 0.3,
            seat_phase_deg: 20.0,
            latency_ms: 0.1,
            noise_um: 0.05,
        }
    }
}

impl Default for ProbeSimReversal {
    fn default() -> Self {
        ProbeSimReversal {
            rest_um: 0.0,
            twist_deg: 90.0,
        }
    }
}

impl Default for ProbeSimOutput {
    fn default() -> Self {
        ProbeSimOutput {
            files: 2,
            shuffle_rows: true,
            angles: false,
        }
    }
}

mod limits {
    use super::{CountLimit, Limit};
    pub(super) const DIRECTIONS: CountLimit = CountLimit::new(3, 720);
    pub(super) const PER_DIRECTION: CountLimit = CountLimit::new(1, 1_000);
    pub(super) const FILES: CountLimit = CountLimit::new(1, 100);
    pub(super) const UM: Limit = Limit::closed(0.0, 1_000.0, "µm");
    pub(super) const OFFSET_UM: Limit = Limit::closed(-10_000.0, 10_000.0, "µm");
    pub(super) const DIAMETER_MM: Limit = Limit::above(0.0, 2_000.0, "mm");
    pub(super) const ANGLE_DEG: Limit = Limit::closed(-360.0, 360.0, "degrees");
    pub(super) const ELEVATION_DEG: Limit = Limit::closed(-89.0, 89.0, "degrees");
    pub(super) const INTERVAL_S: Limit = Limit::above(0.0, 86_400.0, "s");
    pub(super) const FEED: Limit = Limit::closed(0.0, 100_000.0, "mm/min");
    pub(super) const LATENCY_MS: Limit = Limit::closed(0.0, 100.0, "ms");
    pub(super) const DRIFT: Limit = Limit::closed(-1_000.0, 1_000.0, "µm/h");
    pub(super) const T0: Limit = Limit::closed(-100.0, 200.0, "°C");
}

fn check(key: &str, v: f64, l: Limit) -> Result<(), SimError> {
    l.check(key, v).map_err(|e| SimError::Invalid {
        key: key.into(),
        reason: format!("= {} is out of range: it must be {}", e.value, e.allowed),
    })
}

fn count(key: &str, v: usize, l: CountLimit) -> Result<(), SimError> {
    l.check(key, v).map_err(|e| SimError::Invalid {
        key: key.into(),
        reason: format!("= {} is out of range: it must be {}", e.value, e.allowed),
    })
}

impl ProbeSimConfig {
    /// Every key in range, one line naming the key otherwise.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.kind != CampaignKind::Probe {
            return Err(SimError::Invalid {
                key: "kind".into(),
                reason: "must be \"probe\" for this configuration".into(),
            });
        }
        check(
            "reference_temperature_c",
            self.reference_temperature_c,
            limits::T0,
        )?;
        check(
            "stylus.tip_diameter_mm",
            self.stylus.tip_diameter_mm,
            limits::DIAMETER_MM,
        )?;
        check(
            "stylus.tip_error_um",
            self.stylus.tip_error_um,
            limits::OFFSET_UM,
        )?;
        check(
            "artefact.diameter_mm",
            self.artefact.diameter_mm,
            limits::DIAMETER_MM,
        )?;
        if self.artefact.kind == ArtefactKind::Ring
            && self.artefact.diameter_mm <= self.stylus.tip_diameter_mm
        {
            return Err(SimError::Invalid {
                key: "artefact.diameter_mm".into(),
                reason: "must exceed stylus.tip_diameter_mm for a ring".into(),
            });
        }
        check("artefact.u_um", self.artefact.u_um, limits::UM)?;
        check("artefact.form_um", self.artefact.form_um, limits::UM)?;
        for (k, v) in self.artefact.centre_offset_um.iter().enumerate() {
            check(
                &format!("artefact.centre_offset_um[{k}]"),
                *v,
                limits::OFFSET_UM,
            )?;
        }
        for (k, v) in self.artefact.centre_mm.iter().enumerate() {
            check(
                &format!("artefact.centre_mm[{k}]"),
                *v,
                Limit::closed(-10_000.0, 10_000.0, "mm"),
            )?;
        }
        check(
            "artefact.form_phase_deg",
            self.artefact.form_phase_deg,
            limits::ANGLE_DEG,
        )?;
        count(
            "touches.directions",
            self.touches.directions,
            limits::DIRECTIONS,
        )?;
        count(
            "touches.per_direction",
            self.touches.per_direction,
            limits::PER_DIRECTION,
        )?;
        check(
            "touches.first_phi_deg",
            self.touches.first_phi_deg,
            limits::ANGLE_DEG,
        )?;
        check(
            "touches.elevation_deg",
            self.touches.elevation_deg,
            limits::ELEVATION_DEG,
        )?;
        check(
            "touches.interval_s",
            self.touches.interval_s,
            limits::INTERVAL_S,
        )?;
        check(
            "touches.feed_mm_min",
            self.touches.feed_mm_min,
            limits::FEED,
        )?;
        for (k, v) in self.touches.spindle_deg.iter().enumerate() {
            check(&format!("touches.spindle_deg[{k}]"), *v, limits::ANGLE_DEG)?;
        }
        if !["sequential", "shuffled"].contains(&self.touches.order.as_str()) {
            return Err(SimError::Invalid {
                key: "touches.order".into(),
                reason: format!("is {:?}: sequential | shuffled", self.touches.order),
            });
        }
        check(
            "pretravel.delta_min_um",
            self.pretravel.delta_min_um,
            limits::UM,
        )?;
        check(
            "pretravel.seat_phase_deg",
            self.pretravel.seat_phase_deg,
            limits::ANGLE_DEG,
        )?;
        check(
            "pretravel.latency_ms",
            self.pretravel.latency_ms,
            limits::LATENCY_MS,
        )?;
        check("pretravel.noise_um", self.pretravel.noise_um, limits::UM)?;
        check("reversal.rest_um", self.reversal.rest_um, limits::UM)?;
        check(
            "reversal.twist_deg",
            self.reversal.twist_deg,
            limits::ANGLE_DEG,
        )?;
        for (k, v) in self.drift_um_per_h.iter().enumerate() {
            check(&format!("drift_um_per_h[{k}]"), *v, limits::DRIFT)?;
        }
        count("output.files", self.output.files, limits::FILES)?;
        Ok(())
    }
}
