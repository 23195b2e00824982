//! The `volumetric` campaign kind (`docs/spec/machine-formats.md`, "Kind volumetric"; seed
//! 001): body diagonals (ISO 230-6) and sequential step diagonals measured by a laser, and body
//! diagonals read by a calibrated bar in re-seated segments (`docs/bar-diagonals.md`, our
//! extension: `[bar_diagonal]` and `bar_diagonals/*.parquet`). Types only, no IO.
//!
//! [`VolumetricManifest`] is its `campaign.toml` as declared, one field a key (the TOML text is
//! `dbbcal_io::manifest`'s); [`VolumetricCampaign`] is the validated form, every error one line naming the file
//! and the key. The logs as plain data and the reader rules (order, direction, sub-move order)
//! are in [`logs`].

use crate::axis_campaign::{CampaignKind, KindSection, LaserCompensation, MachineSensorDecl};
use crate::campaign::{check_campaign_id, display_number, limits, CampaignError};
use crate::limits::{check_point, PointOutOfRange};

pub mod logs;
#[cfg(test)]
mod tests;

pub use logs::{
    order_bar_readings, order_diagonal_readings, order_step_readings, BarReading, DiagonalReading,
    StepReading, VolumetricCampaignLogs, VolumetricCampaignTables,
};

/// A diagonal, named by its sign vector s = (sx, sy, sz) (`"+++"`, `"-++"`, `"+-+"`, `"++-"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DiagonalSign {
    /// `+++`.
    Ppp,
    /// `-++`.
    Mpp,
    /// `+-+`.
    Pmp,
    /// `++-`.
    Ppm,
}

impl DiagonalSign {
    /// The four diagonals, in the spec's order.
    pub const ALL: [DiagonalSign; 4] = [
        DiagonalSign::Ppp,
        DiagonalSign::Mpp,
        DiagonalSign::Pmp,
        DiagonalSign::Ppm,
    ];

    /// The sign vector as written (`"+++"` …); `parse(d.as_str()) == Some(d)`.
    pub fn as_str(self) -> &'static str {
        ["+++", "-++", "+-+", "++-"][self.index()]
    }

    /// The diagonal a word names.
    pub fn parse(word: &str) -> Option<DiagonalSign> {
        Self::ALL.into_iter().find(|d| d.as_str() == word)
    }

    /// 0 … 3 in the order of [`ALL`](Self::ALL).
    pub fn index(self) -> usize {
        match self {
            DiagonalSign::Ppp => 0,
            DiagonalSign::Mpp => 1,
            DiagonalSign::Pmp => 2,
            DiagonalSign::Ppm => 3,
        }
    }

    /// (sx, sy, sz) as ±1.
    pub fn signs(self) -> [f64; 3] {
        match self {
            DiagonalSign::Ppp => [1.0, 1.0, 1.0],
            DiagonalSign::Mpp => [-1.0, 1.0, 1.0],
            DiagonalSign::Pmp => [1.0, -1.0, 1.0],
            DiagonalSign::Ppm => [1.0, 1.0, -1.0],
        }
    }
}

impl std::fmt::Display for DiagonalSign {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

/// The laser's target (`[laser] target`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LaserTarget {
    /// A flat mirror: lateral motion does not change the reading (needed by step diagonals).
    FlatMirror,
    /// A retroreflector: lateral sub-moves walk the beam off.
    Retroreflector,
}

/// `[machine]` of a `volumetric` campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumetricMachineSection {
    /// Expansion of the machine's scales, ppm/K, for normalising to T0.
    pub cte_ppm_per_k: f64,
}

/// `[workspace]`: the corners are the diagonals' ends.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceSection {
    /// Minimum corner, mm.
    pub min_mm: [f64; 3],
    /// Maximum corner, mm.
    pub max_mm: [f64; 3],
}

/// `[laser]` of a `volumetric` campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumetricLaserSection {
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// What the readings already include.
    pub compensation: LaserCompensation,
    /// Optics to reflector at the datum, mm.
    pub dead_path_mm: Option<f64>,
    /// Flat mirror or retroreflector.
    pub target: LaserTarget,
}

/// `[bar_diagonal]` (`docs/bar-diagonals.md`): the bar that read the body diagonals of
/// `bar_diagonals/*.parquet` and what its calibration and set-up leave uncertain.
#[derive(Debug, Clone, PartialEq)]
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
#[derive(Debug, Clone, PartialEq)]
pub struct GridSection {
    /// Nodes along x.
    pub i: usize,
    /// Nodes along y.
    pub j: usize,
    /// Nodes along z.
    pub k: usize,
    /// Node (1, 1, 1), mm.
    pub origin_mm: [f64; 3],
    /// Δx, Δy, Δz, mm.
    pub spacing_mm: [f64; 3],
}

/// What the 3-D table holds (`[table] values`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TableValues {
    /// −error.
    Correction,
    /// error = measured − commanded.
    Error,
}

/// `[table]`.
#[derive(Debug, Clone, PartialEq)]
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

/// `campaign.toml` of a `volumetric` campaign as declared, not yet validated.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumetricManifest {
    /// `[campaign]`.
    pub campaign: KindSection,
    /// `[machine]`.
    pub machine: VolumetricMachineSection,
    /// `[workspace]`.
    pub workspace: WorkspaceSection,
    /// `[laser]`; required when `diagonals/` or `steps/` hold readings.
    pub laser: Option<VolumetricLaserSection>,
    /// `[bar_diagonal]`; required when `bar_diagonals/` holds readings.
    pub bar_diagonal: Option<BarDiagonalSection>,
    /// `grid`.
    pub grid: GridSection,
    /// `[table]`; absent: fanuc-3d, n_base 100000, 1 µm, correction.
    pub table: Option<TableSection>,
    /// `[[sensor]]` of `temperatures/*.parquet`.
    pub sensor: Vec<MachineSensorDecl>,
}

/// A validated `volumetric` manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumetricCampaign {
    /// The campaign's id.
    pub id: String,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Expansion of the scales, ppm/K.
    pub cte_ppm_per_k: f64,
    /// Workspace minimum corner, mm.
    pub min_mm: [f64; 3],
    /// Workspace maximum corner, mm.
    pub max_mm: [f64; 3],
    /// The laser (`[laser]`), when the campaign has laser readings.
    pub laser: Option<VolumetricLaserSection>,
    /// The bar of the bar-read diagonals (`[bar_diagonal]`).
    pub bar_diagonal: Option<BarDiagonalSection>,
    /// The grid.
    pub grid: GridSection,
    /// The 3-D table's options.
    pub table: TableSection,
    /// The declared sensors.
    pub sensors: Vec<MachineSensorDecl>,
}

/// Largest |coordinate| and length accepted, mm.
const LENGTH_MM: f64 = 10_000.0;
/// Most grid nodes per axis.
const MAX_NODES: usize = 1_000;

impl VolumetricCampaign {
    /// The workspace's extent L = max − min, mm.
    pub fn lengths_mm(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| self.max_mm[k] - self.min_mm[k])
    }

    /// Validates a manifest, naming `file` in messages.
    pub fn from_manifest_at(
        m: VolumetricManifest,
        file: &str,
    ) -> Result<VolumetricCampaign, CampaignError> {
        let invalid = |key: &str, problem: String| CampaignError::Invalid {
            file: file.to_string(),
            key: key.to_string(),
            problem,
        };
        if m.campaign.kind != CampaignKind::Volumetric {
            return Err(invalid(
                "campaign.kind",
                format!(
                    "is {:?}, this manifest is read as \"volumetric\"",
                    m.campaign.kind.as_str()
                ),
            ));
        }
        check_campaign_id(&m.campaign.id).map_err(|p| invalid("campaign.id", p.to_string()))?;
        let check = |key: &str, v: f64, limit: crate::limits::Limit| {
            let name = key.rsplit('.').next().unwrap_or(key);
            limit
                .check(name, v)
                .map_err(|e| invalid(key, e.to_string()))
        };
        check(
            "campaign.reference_temperature_c",
            m.campaign.reference_temperature_c,
            limits::REFERENCE_TEMPERATURE_C,
        )?;
        check(
            "machine.cte_ppm_per_k",
            m.machine.cte_ppm_per_k,
            limits::CTE_PPM_PER_K,
        )?;
        if let Some(laser) = &m.laser {
            check(
                "laser.wavelength_nm",
                laser.wavelength_nm,
                crate::limits::Limit::closed(200.0, 2_000.0, "nm"),
            )?;
            if let Some(d) = laser.dead_path_mm {
                check(
                    "laser.dead_path_mm",
                    d,
                    crate::limits::Limit::closed(0.0, LENGTH_MM, "mm"),
                )?;
            }
        }
        if let Some(bar) = &m.bar_diagonal {
            if bar.bar.trim().is_empty() {
                return Err(invalid(
                    "bar_diagonal.bar",
                    "is empty: name the bar that read the diagonals".into(),
                ));
            }
            check(
                "bar_diagonal.scale_u_ppm",
                bar.scale_u_ppm,
                crate::limits::Limit::closed(0.0, 1_000.0, "ppm"),
            )?;
            check(
                "bar_diagonal.misalignment_mm",
                bar.misalignment_mm,
                crate::limits::Limit::closed(0.0, 100.0, "mm"),
            )?;
        }
        let w = &m.workspace;
        for (key, p) in [
            ("workspace.min_mm", &w.min_mm),
            ("workspace.max_mm", &w.max_mm),
        ] {
            point(p).map_err(|e| invalid(key, e.to_string()))?;
        }
        if let Some(k) = (0..3).find(|&k| w.max_mm[k] <= w.min_mm[k]) {
            return Err(invalid(
                "workspace",
                format!(
                    "max_mm[{k}] = {} is not above min_mm[{k}] = {}: the corners span the workspace",
                    display_number(w.max_mm[k]),
                    display_number(w.min_mm[k])
                ),
            ));
        }
        check_grid(&m.grid, w, file)?;
        let table = m.table.unwrap_or(TableSection {
            format: "fanuc-3d".into(),
            n_base: 100_000,
            unit_um: 1.0,
            values: TableValues::Correction,
        });
        if table.format != "fanuc-3d" {
            return Err(invalid(
                "table.format",
                format!(
                    "is {:?}: \"fanuc-3d\" is the only format of this version",
                    table.format
                ),
            ));
        }
        check(
            "table.unit_um",
            table.unit_um,
            crate::limits::Limit::closed(1e-6, 1_000.0, "µm"),
        )?;
        Ok(VolumetricCampaign {
            id: m.campaign.id,
            reference_temperature_c: m.campaign.reference_temperature_c,
            cte_ppm_per_k: m.machine.cte_ppm_per_k,
            min_mm: w.min_mm,
            max_mm: w.max_mm,
            laser: m.laser,
            bar_diagonal: m.bar_diagonal,
            grid: m.grid,
            table,
            sensors: m.sensor,
        })
    }

    /// `environment/*.parquet` is required with a laser unless `compensation = "air+material"`.
    pub fn check_environment(&self, has_rows: bool, file: &str) -> Result<(), CampaignError> {
        let Some(laser) = &self.laser else {
            return Ok(());
        };
        if has_rows || !laser.compensation.needs_environment() {
            return Ok(());
        }
        Err(CampaignError::Invalid {
            file: file.to_string(),
            key: "laser.compensation".into(),
            problem: format!(
                "is {:?}: the readings are not normalised, so environment/*.parquet is required unless compensation = \"air+material\"; none was found",
                laser.compensation.as_str()
            ),
        })
    }

    /// Each instrument's section is there exactly when its readings are: `[laser]` with
    /// `diagonals/` or `steps/`, `[bar_diagonal]` with `bar_diagonals/`.
    pub fn check_instruments(
        &self,
        has_laser_rows: bool,
        has_bar_rows: bool,
        file: &str,
    ) -> Result<(), CampaignError> {
        let invalid = |key: &str, problem: &str| CampaignError::Invalid {
            file: file.to_string(),
            key: key.into(),
            problem: problem.into(),
        };
        if has_laser_rows && self.laser.is_none() {
            return Err(invalid(
                "laser",
                "is missing but diagonals/ or steps/ hold laser readings: declare [laser] (wavelength_nm, compensation, target)",
            ));
        }
        if has_bar_rows && self.bar_diagonal.is_none() {
            return Err(invalid(
                "bar_diagonal",
                "is missing but bar_diagonals/ holds bar readings: declare [bar_diagonal] (bar, scale_u_ppm, misalignment_mm)",
            ));
        }
        if !has_bar_rows && self.bar_diagonal.is_some() {
            return Err(invalid(
                "bar_diagonal",
                "is declared but bar_diagonals/*.parquet holds no readings",
            ));
        }
        Ok(())
    }

    /// Step diagonals need a flat mirror (`machine-physics.md`: a retroreflector on a step
    /// diagonal is not a valid set-up).
    pub fn check_steps(&self, has_steps: bool, file: &str) -> Result<(), CampaignError> {
        if !has_steps
            || self
                .laser
                .as_ref()
                .is_none_or(|l| l.target == LaserTarget::FlatMirror)
        {
            return Ok(());
        }
        Err(CampaignError::Invalid {
            file: file.to_string(),
            key: "laser.target".into(),
            problem: "is \"retroreflector\" but steps/*.parquet holds step diagonals: lateral sub-moves walk the beam off a retroreflector, step diagonals need target = \"flat-mirror\"".into(),
        })
    }
}

/// A point in mm: finite, within ±10 m.
fn point(p: &[f64; 3]) -> Result<(), PointOutOfRange> {
    check_point(p, LENGTH_MM)
}

/// Grid nodes must lie inside the workspace (`machine-formats.md`); `file` names the manifest.
fn check_grid(g: &GridSection, w: &WorkspaceSection, file: &str) -> Result<(), CampaignError> {
    let invalid = |key: &str, problem: String| {
        Err(CampaignError::Invalid {
            file: file.to_string(),
            key: key.to_string(),
            problem,
        })
    };
    let counts = [g.i, g.j, g.k];
    for (k, name) in ["I", "J", "K"].iter().enumerate() {
        if !(1..=MAX_NODES).contains(&counts[k]) {
            return invalid(
                &format!("grid.{name}"),
                format!("is {}: each count is 1 … {MAX_NODES}", counts[k]),
            );
        }
    }
    if let Err(p) = point(&g.origin_mm) {
        return invalid("grid.origin_mm", p.to_string());
    }
    for k in 0..3 {
        let s = g.spacing_mm[k];
        if !(s.is_finite() && s > 0.0 && s <= LENGTH_MM) {
            return invalid(
                "grid.spacing_mm",
                format!(
                    "spacing_mm[{k}] = {} is not a finite number in (0, {LENGTH_MM}] mm",
                    display_number(s)
                ),
            );
        }
        let last = g.origin_mm[k] + (counts[k] - 1) as f64 * s;
        let tol = 1e-6;
        if g.origin_mm[k] < w.min_mm[k] - tol || last > w.max_mm[k] + tol {
            return invalid(
                "grid",
                format!(
                    "nodes along {} run from {} to {} mm, outside the workspace {} … {} mm: grid nodes must lie inside it",
                    ["x", "y", "z"][k],
                    display_number(g.origin_mm[k]),
                    display_number(last),
                    display_number(w.min_mm[k]),
                    display_number(w.max_mm[k])
                ),
            );
        }
    }
    Ok(())
}
