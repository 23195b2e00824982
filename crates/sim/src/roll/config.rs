//! [`RollSimConfig`]: a `roll` campaign to simulate (`pipelines/sim-roll.toml`), selected in a
//! simulation TOML by the top-level `kind = "roll"`. Every key has a default (the seed's rig and
//! experiment: L = 80 mm, d = s = 40 mm, 19 stations from −50 to −770 mm, 20 Hz); every effect
//! a model may miss is off unless given. [`RollSimConfig::validate`] names the key that is wrong.

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use crate::SimError;
use dbbcal_core::axis_campaign::{CampaignKind, MachineAxis};
use dbbcal_core::limits::{CountLimit, Limit};
use dbbcal_core::roll_campaign::ReadingUnit;

/// The whole configuration of a simulated `roll` campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollSimConfig {
    /// Must be `"roll"`.
    #[serde(with = "dbbcal_io::manifest::as_written::campaign_kind")]
    pub kind: CampaignKind,
    /// Seed of every random draw.
    pub seed: u64,
    /// Campaign id written to the manifest.
    pub campaign_id: String,
    /// When the first sample is taken (UTC).
    #[serde(with = "crate::config::start_time")]
    pub start: DateTime<Utc>,
    /// The rig (written to the manifest).
    pub rig: RollRig,
    /// How the stage is stepped and the probes sampled.
    pub sampling: RollSampling,
    /// The true stage and surface.
    pub truth: RollTruthConfig,
    /// Effects a model may miss, each off unless given.
    pub effects: RollSimEffects,
    /// The level log.
    pub levels: RollSimLevels,
    /// How the files are laid out.
    pub output: RollSimOutput,
}

/// `[rig]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollRig {
    /// The axis the stage moves along.
    #[serde(with = "dbbcal_io::manifest::as_written::machine_axis")]
    pub axis: MachineAxis,
    /// A–C and B–D, mm.
    #[serde(rename = "L_mm")]
    pub l_mm: f64,
    /// A–B and C–D, mm (= the manifest's `s_mm`).
    pub d_mm: f64,
    /// +1 or −1.
    pub b_to_a: i64,
    /// `um` or `V`.
    #[serde(with = "dbbcal_io::manifest::as_written::reading_unit")]
    pub unit: ReadingUnit,
    /// µm/V of every probe (the manifest's; the true gain may differ: `[effects] gain`).
    pub um_per_v: f64,
    /// The manifest's `u_xy_um`.
    pub u_xy_um: f64,
    /// `x_mm` of station 0, mm.
    pub x_first_mm: f64,
    /// Number of stations.
    pub stations: usize,
}

/// `[sampling]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollSampling {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Dwell at each station, s.
    pub dwell_s: f64,
    /// Move between stations, s.
    pub move_s: f64,
    /// Passes; they alternate direction unless `alternate = false`.
    pub passes: usize,
    /// Whether passes alternate direction (out and back).
    pub alternate: bool,
    /// White noise of every sample, µm.
    pub noise_um: f64,
    /// Resolution of the probes, µm (0: continuous).
    pub resolution_um: f64,
    /// Write the `station` column (else the reader detects dwells).
    pub station_column: bool,
    /// Write the `pass` column (else the reader splits at reversals).
    pub pass_column: bool,
}

/// `[truth]`: the true stage errors and surface.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollTruthConfig {
    /// `smooth` (a random sum of sines over the travel) or `random` (i.i.d. per station, the
    /// seed's simulation).
    pub shape: String,
    /// Amplitude of εx, µrad.
    pub roll_urad: f64,
    /// Amplitude of εy, µrad.
    pub pitch_urad: f64,
    /// Amplitude of δz, µm.
    pub dz_um: f64,
    /// Amplitude of each term of the profiles f₁, f₂ (3 terms each), µm.
    pub profile_um: f64,
    /// Largest |ω| of a profile term, rad/mm.
    pub profile_omega_per_mm: f64,
}

/// `[effects]`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollSimEffects {
    /// Zero offsets of A, B, C, D, µm.
    pub offset_um: [f64; 4],
    /// Gain errors g of A … D: a reading is (1 + g) × the true rise.
    pub gain: [f64; 4],
    /// True probe positions minus nominal, [x, y] per probe, µm.
    pub position_error_um: [[f64; 2]; 4],
    /// The true step minus d, µm (s ≠ d).
    pub step_error_um: f64,
    /// Roll drifting in time, µrad/h.
    pub roll_drift_urad_per_h: f64,
    /// Zero drift of A … D, µm/h.
    pub zero_drift_um_per_h: [f64; 4],
}

/// `[levels]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollSimLevels {
    /// Write `levels/` with a reading in the first and last station's dwells of each pass.
    pub write: bool,
    /// Standard uncertainty (written as `u_urad`), µrad.
    pub u_urad: f64,
    /// The level pair's zero: what it reads at zero roll, µrad.
    pub zero_urad: f64,
}

/// `[output]`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RollSimOutput {
    /// One probes file per pass.
    pub split_by_pass: bool,
    /// Shuffle the rows inside each file.
    pub shuffle_rows: bool,
    /// `station`/`pass` as int32.
    pub int32: bool,
    /// Timestamps in ms.
    pub ms: bool,
}

impl Default for RollSimConfig {
    fn default() -> Self {
        Self {
            kind: CampaignKind::Roll,
            seed: 4,
            campaign_id: "sim-roll".into(),
            start: DateTime::parse_from_rfc3339("2027-03-01T08:00:00Z")
                .map(|t| t.with_timezone(&Utc))
                .unwrap_or_default(),
            rig: RollRig::default(),
            sampling: RollSampling::default(),
            truth: RollTruthConfig::default(),
            effects: RollSimEffects::default(),
            levels: RollSimLevels::default(),
            output: RollSimOutput::default(),
        }
    }
}

impl Default for RollRig {
    fn default() -> Self {
        Self {
            axis: MachineAxis::X,
            l_mm: 80.0,
            d_mm: 40.0,
            b_to_a: -1,
            unit: ReadingUnit::Volt,
            um_per_v: -10.0,
            u_xy_um: 50.0,
            x_first_mm: -50.0,
            stations: 19,
        }
    }
}

impl Default for RollSampling {
    fn default() -> Self {
        Self {
            rate_hz: 20.0,
            dwell_s: 5.0,
            move_s: 3.0,
            passes: 1,
            alternate: true,
            noise_um: 0.01,
            resolution_um: 0.0,
            station_column: false,
            pass_column: false,
        }
    }
}

impl Default for RollTruthConfig {
    fn default() -> Self {
        Self {
            shape: "smooth".into(),
            roll_urad: 20.0,
            pitch_urad: 20.0,
            dz_um: 5.0,
            profile_um: 5.0,
            profile_omega_per_mm: 0.05,
        }
    }
}

impl Default for RollSimLevels {
    fn default() -> Self {
        Self {
            write: false,
            u_urad: 1.0,
            zero_urad: 7.0,
        }
    }
}

impl RollSimConfig {
    /// Checks every value, naming the key.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |key: &str, reason: String| SimError::Invalid {
            key: key.into(),
            reason,
        };
        let check =
            |key: &str, v: f64, l: Limit| l.check(key, v).map_err(|e| bad(key, e.to_string()));
        if self.kind != CampaignKind::Roll {
            return Err(bad("kind", "must be \"roll\"".into()));
        }
        let len = Limit::above(0.0, 2_000.0, "mm");
        check("rig.L_mm", self.rig.l_mm, len)?;
        check("rig.d_mm", self.rig.d_mm, len)?;
        if self.rig.b_to_a.abs() != 1 {
            return Err(bad("rig.b_to_a", "must be +1 or -1".into()));
        }
        check(
            "rig.um_per_v",
            self.rig.um_per_v.abs(),
            Limit::closed(1e-3, 1e4, "µm/V"),
        )?;
        check(
            "rig.u_xy_um",
            self.rig.u_xy_um,
            Limit::closed(0.0, 1_000.0, "µm"),
        )?;
        check(
            "rig.x_first_mm",
            self.rig.x_first_mm,
            Limit::closed(-1e4, 1e4, "mm"),
        )?;
        CountLimit::new(2, 1_000)
            .check("rig.stations", self.rig.stations)
            .map_err(|e| bad("rig.stations", e.to_string()))?;
        let s = &self.sampling;
        check(
            "sampling.rate_hz",
            s.rate_hz,
            Limit::above(0.0, 10_000.0, "Hz"),
        )?;
        check(
            "sampling.dwell_s",
            s.dwell_s,
            Limit::above(0.0, 3_600.0, "s"),
        )?;
        check("sampling.move_s", s.move_s, Limit::above(0.0, 3_600.0, "s"))?;
        CountLimit::new(1, 100)
            .check("sampling.passes", s.passes)
            .map_err(|e| bad("sampling.passes", e.to_string()))?;
        check(
            "sampling.noise_um",
            s.noise_um,
            Limit::closed(0.0, 100.0, "µm"),
        )?;
        check(
            "sampling.resolution_um",
            s.resolution_um,
            Limit::closed(0.0, 100.0, "µm"),
        )?;
        let samples =
            s.passes as f64 * self.rig.stations as f64 * (s.dwell_s + s.move_s) * s.rate_hz;
        if samples > 5e7 {
            return Err(bad(
                "sampling",
                format!("makes {samples:.0} samples; at most 5e7"),
            ));
        }
        if !matches!(self.truth.shape.as_str(), "smooth" | "random") {
            return Err(bad(
                "truth.shape",
                format!(
                    "{:?} is neither \"smooth\" nor \"random\"",
                    self.truth.shape
                ),
            ));
        }
        for (key, v) in [
            ("truth.roll_urad", self.truth.roll_urad),
            ("truth.pitch_urad", self.truth.pitch_urad),
            ("truth.dz_um", self.truth.dz_um),
            ("truth.profile_um", self.truth.profile_um),
            (
                "truth.profile_omega_per_mm",
                self.truth.profile_omega_per_mm,
            ),
        ] {
            check(key, v, Limit::closed(0.0, 1e5, ""))?;
        }
        check(
            "levels.u_urad",
            self.levels.u_urad,
            Limit::above(0.0, 1e4, "µrad"),
        )?;
        Ok(())
    }
}
