//! `campaign.toml` of a `volumetric` campaign (`docs/spec/machine-formats.md`, "Kind
//! volumetric"; `[bar_diagonal]`: `docs/bar-diagonals.md`): the file's types, one to one with
//! the TOML, and their conversions to and from `dbbcal_core::volumetric_campaign`'s.

use serde::{Deserialize, Serialize};

use dbbcal_core::volumetric_campaign as core;

use super::axis::{KindSection, LaserCompensation, MachineSensorDecl};

/// The laser's target (`[laser] target`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LaserTarget {
    /// A flat mirror: lateral motion does not change the reading (needed by step diagonals).
    FlatMirror,
    /// A retroreflector: lateral sub-moves walk the beam off.
    Retroreflector,
}

/// `[machine]` of a `volumetric` campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VolumetricMachineSection {
    /// Expansion of the machine's scales, ppm/K, for normalising to T0.
    pub cte_ppm_per_k: f64,
}

/// `[workspace]`: the corners are the diagonals' ends.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceSection {
    /// Minimum corner, mm.
    pub min_mm: [f64; 3],
    /// Maximum corner, mm.
    pub max_mm: [f64; 3],
}

/// `[laser]` of a `volumetric` campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VolumetricLaserSection {
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// What the readings already include.
    pub compensation: LaserCompensation,
    /// Optics to reflector at the datum, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dead_path_mm: Option<f64>,
    /// Flat mirror or retroreflector.
    pub target: LaserTarget,
}

/// `[bar_diagonal]` (`docs/bar-diagonals.md`): the bar that read the body diagonals of
/// `bar_diagonals/*.parquet` and what its calibration and set-up leave uncertain.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BarDiagonalSection {
    /// The bar's id (as in its calibration certificate).
    pub bar: String,
    /// The standard uncertainty (k = 1) of the bar's scale from its calibration, ppm: every
    /// segment of every diagonal shares it.
    pub scale_u_ppm: f64,
    /// The largest distance of a socket from the diagonal's line, mm.
    pub misalignment_mm: f64,
}

/// `grid = { I, J, K, origin_mm, spacing_mm }`: the lattice of V2, V3 and the 3-D table.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GridSection {
    /// Nodes along x.
    #[serde(rename = "I")]
    pub i: usize,
    /// Nodes along y.
    #[serde(rename = "J")]
    pub j: usize,
    /// Nodes along z.
    #[serde(rename = "K")]
    pub k: usize,
    /// Node (1, 1, 1), mm.
    pub origin_mm: [f64; 3],
    /// Δx, Δy, Δz, mm.
    pub spacing_mm: [f64; 3],
}

/// What the 3-D table holds (`[table] values`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TableValues {
    /// −error.
    Correction,
    /// error = measured − commanded.
    Error,
}

/// `[table]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TableSection {
    /// `"fanuc-3d"`, the only format of this version.
    pub format: String,
    /// Line l is written `N{n_base + l}`.
    pub n_base: u64,
    /// One detection unit, µm.
    pub unit_um: f64,
    /// Correction or error.
    pub values: TableValues,
}

/// `campaign.toml` of a `volumetric` campaign as written, not yet validated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VolumetricManifest {
    /// `[campaign]`.
    pub campaign: KindSection,
    /// `[machine]`.
    pub machine: VolumetricMachineSection,
    /// `[workspace]`.
    pub workspace: WorkspaceSection,
    /// `[laser]`; required when `diagonals/` or `steps/` hold readings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub laser: Option<VolumetricLaserSection>,
    /// `[bar_diagonal]`; required when `bar_diagonals/` holds readings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bar_diagonal: Option<BarDiagonalSection>,
    /// `grid`.
    pub grid: GridSection,
    /// `[table]`; absent: fanuc-3d, n_base 100000, 1 µm, correction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<TableSection>,
    /// `[[sensor]]` of `temperatures/*.parquet`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sensor: Vec<MachineSensorDecl>,
}

// ---- conversions

impl From<LaserTarget> for core::LaserTarget {
    fn from(v: LaserTarget) -> Self {
        match v {
            LaserTarget::FlatMirror => core::LaserTarget::FlatMirror,
            LaserTarget::Retroreflector => core::LaserTarget::Retroreflector,
        }
    }
}

impl From<core::LaserTarget> for LaserTarget {
    fn from(v: core::LaserTarget) -> Self {
        match v {
            core::LaserTarget::FlatMirror => LaserTarget::FlatMirror,
            core::LaserTarget::Retroreflector => LaserTarget::Retroreflector,
        }
    }
}

impl From<VolumetricMachineSection> for core::VolumetricMachineSection {
    fn from(v: VolumetricMachineSection) -> Self {
        core::VolumetricMachineSection {
            cte_ppm_per_k: v.cte_ppm_per_k,
        }
    }
}

impl From<core::VolumetricMachineSection> for VolumetricMachineSection {
    fn from(v: core::VolumetricMachineSection) -> Self {
        VolumetricMachineSection {
            cte_ppm_per_k: v.cte_ppm_per_k,
        }
    }
}

impl From<WorkspaceSection> for core::WorkspaceSection {
    fn from(v: WorkspaceSection) -> Self {
        core::WorkspaceSection {
            min_mm: v.min_mm,
            max_mm: v.max_mm,
        }
    }
}

impl From<core::WorkspaceSection> for WorkspaceSection {
    fn from(v: core::WorkspaceSection) -> Self {
        WorkspaceSection {
            min_mm: v.min_mm,
            max_mm: v.max_mm,
        }
    }
}

impl From<VolumetricLaserSection> for core::VolumetricLaserSection {
    fn from(v: VolumetricLaserSection) -> Self {
        core::VolumetricLaserSection {
            wavelength_nm: v.wavelength_nm,
            compensation: v.compensation.into(),
            dead_path_mm: v.dead_path_mm,
            target: v.target.into(),
        }
    }
}

impl From<core::VolumetricLaserSection> for VolumetricLaserSection {
    fn from(v: core::VolumetricLaserSection) -> Self {
        VolumetricLaserSection {
            wavelength_nm: v.wavelength_nm,
            compensation: v.compensation.into(),
            dead_path_mm: v.dead_path_mm,
            target: v.target.into(),
        }
    }
}

impl From<BarDiagonalSection> for core::BarDiagonalSection {
    fn from(v: BarDiagonalSection) -> Self {
        core::BarDiagonalSection {
            bar: v.bar,
            scale_u_ppm: v.scale_u_ppm,
            misalignment_mm: v.misalignment_mm,
        }
    }
}

impl From<core::BarDiagonalSection> for BarDiagonalSection {
    fn from(v: core::BarDiagonalSection) -> Self {
        BarDiagonalSection {
            bar: v.bar,
            scale_u_ppm: v.scale_u_ppm,
            misalignment_mm: v.misalignment_mm,
        }
    }
}

impl From<GridSection> for core::GridSection {
    fn from(v: GridSection) -> Self {
        core::GridSection {
            i: v.i,
            j: v.j,
            k: v.k,
            origin_mm: v.origin_mm,
            spacing_mm: v.spacing_mm,
        }
    }
}

impl From<core::GridSection> for GridSection {
    fn from(v: core::GridSection) -> Self {
        GridSection {
            i: v.i,
            j: v.j,
            k: v.k,
            origin_mm: v.origin_mm,
            spacing_mm: v.spacing_mm,
        }
    }
}

impl From<TableValues> for core::TableValues {
    fn from(v: TableValues) -> Self {
        match v {
            TableValues::Correction => core::TableValues::Correction,
            TableValues::Error => core::TableValues::Error,
        }
    }
}

impl From<core::TableValues> for TableValues {
    fn from(v: core::TableValues) -> Self {
        match v {
            core::TableValues::Correction => TableValues::Correction,
            core::TableValues::Error => TableValues::Error,
        }
    }
}

impl From<TableSection> for core::TableSection {
    fn from(v: TableSection) -> Self {
        core::TableSection {
            format: v.format,
            n_base: v.n_base,
            unit_um: v.unit_um,
            values: v.values.into(),
        }
    }
}

impl From<core::TableSection> for TableSection {
    fn from(v: core::TableSection) -> Self {
        TableSection {
            format: v.format,
            n_base: v.n_base,
            unit_um: v.unit_um,
            values: v.values.into(),
        }
    }
}

impl From<VolumetricManifest> for core::VolumetricManifest {
    fn from(v: VolumetricManifest) -> Self {
        core::VolumetricManifest {
            campaign: v.campaign.into(),
            machine: v.machine.into(),
            workspace: v.workspace.into(),
            laser: v.laser.map(Into::into),
            bar_diagonal: v.bar_diagonal.map(Into::into),
            grid: v.grid.into(),
            table: v.table.map(Into::into),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<core::VolumetricManifest> for VolumetricManifest {
    fn from(v: core::VolumetricManifest) -> Self {
        VolumetricManifest {
            campaign: v.campaign.into(),
            machine: v.machine.into(),
            workspace: v.workspace.into(),
            laser: v.laser.map(Into::into),
            bar_diagonal: v.bar_diagonal.map(Into::into),
            grid: v.grid.into(),
            table: v.table.map(Into::into),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
        }
    }
}
