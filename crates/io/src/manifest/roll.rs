//! `campaign.toml` of a `roll` campaign (`docs/spec/machine-formats.md`, "Kind roll"): the
//! file's types, one to one with the TOML, and their conversions to and from
//! `dbbcal_core::roll_campaign`'s.

use serde::{Deserialize, Serialize};

use dbbcal_core::roll_campaign as core;

use super::axis::{KindSection, MachineAxis};

/// `campaign.toml` of a `roll` campaign as written, not yet validated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RollManifest {
    /// `[campaign]`: kind, id, T0.
    pub campaign: KindSection,
    /// `[roll]`: the rig.
    pub roll: RollSection,
}

/// The unit of the probe readings (`[roll] unit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ReadingUnit {
    /// Micrometres of surface rise.
    #[serde(rename = "um")]
    Um,
    /// Volts, times each probe's `um_per_v`.
    #[serde(rename = "V")]
    Volt,
}

/// `[roll]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RollSection {
    /// The machine axis the stage moves along.
    pub axis: MachineAxis,
    /// Across: A–C and B–D, mm.
    #[serde(rename = "L_mm")]
    pub l_mm: f64,
    /// Along: A–B and C–D, mm.
    pub d_mm: f64,
    /// Step between stations, mm; must equal `d_mm`.
    pub s_mm: f64,
    /// Sign of the `x_mm` change that carries the surface from under B to under A.
    pub b_to_a: i64,
    /// Unit of `m_a` … `m_d`.
    pub unit: ReadingUnit,
    /// Dwell detection (without `station`): the shortest dwell, s.
    pub dwell_min_s: f64,
    /// Dwell detection: half the band `x_mm` stays within, µm.
    pub dwell_tol_um: f64,
    /// `[[roll.probe]]`, one per probe A, B, C, D.
    pub probe: Vec<ProbeDecl>,
}

/// `[[roll.probe]]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProbeDecl {
    /// `A`, `B`, `C` or `D`.
    pub id: String,
    /// Standard uncertainty of each coordinate of the probe centre, µm.
    pub u_xy_um: f64,
    /// Signed surface rise per volt, µm/V (used when `unit = "V"`).
    pub um_per_v: f64,
    /// Measured position in R, mm; absent: the nominal one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub xy_mm: Option<[f64; 2]>,
}

// ---- conversions

impl From<RollManifest> for core::RollManifest {
    fn from(v: RollManifest) -> Self {
        core::RollManifest {
            campaign: v.campaign.into(),
            roll: v.roll.into(),
        }
    }
}

impl From<core::RollManifest> for RollManifest {
    fn from(v: core::RollManifest) -> Self {
        RollManifest {
            campaign: v.campaign.into(),
            roll: v.roll.into(),
        }
    }
}

impl From<ReadingUnit> for core::ReadingUnit {
    fn from(v: ReadingUnit) -> Self {
        match v {
            ReadingUnit::Um => core::ReadingUnit::Um,
            ReadingUnit::Volt => core::ReadingUnit::Volt,
        }
    }
}

impl From<core::ReadingUnit> for ReadingUnit {
    fn from(v: core::ReadingUnit) -> Self {
        match v {
            core::ReadingUnit::Um => ReadingUnit::Um,
            core::ReadingUnit::Volt => ReadingUnit::Volt,
        }
    }
}

impl From<RollSection> for core::RollSection {
    fn from(v: RollSection) -> Self {
        core::RollSection {
            axis: v.axis.into(),
            l_mm: v.l_mm,
            d_mm: v.d_mm,
            s_mm: v.s_mm,
            b_to_a: v.b_to_a,
            unit: v.unit.into(),
            dwell_min_s: v.dwell_min_s,
            dwell_tol_um: v.dwell_tol_um,
            probe: v.probe.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<core::RollSection> for RollSection {
    fn from(v: core::RollSection) -> Self {
        RollSection {
            axis: v.axis.into(),
            l_mm: v.l_mm,
            d_mm: v.d_mm,
            s_mm: v.s_mm,
            b_to_a: v.b_to_a,
            unit: v.unit.into(),
            dwell_min_s: v.dwell_min_s,
            dwell_tol_um: v.dwell_tol_um,
            probe: v.probe.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<ProbeDecl> for core::ProbeDecl {
    fn from(v: ProbeDecl) -> Self {
        core::ProbeDecl {
            id: v.id,
            u_xy_um: v.u_xy_um,
            um_per_v: v.um_per_v,
            xy_mm: v.xy_mm,
        }
    }
}

impl From<core::ProbeDecl> for ProbeDecl {
    fn from(v: core::ProbeDecl) -> Self {
        ProbeDecl {
            id: v.id,
            u_xy_um: v.u_xy_um,
            um_per_v: v.um_per_v,
            xy_mm: v.xy_mm,
        }
    }
}
