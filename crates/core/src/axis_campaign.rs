//! The `axis` campaign kind (`docs/spec/machine-formats.md`, "Kind axis"; seed 002): the six
//! errors of one linear axis from interferometer lines. Types only, no IO.
//!
//! [`AxisManifest`] is its `campaign.toml` as declared, one field a key (the TOML text is
//! `dbbcal_io::manifest`'s, which also reads `[campaign] kind` from any manifest so that the
//! application can choose a reader before validating); [`AxisCampaign`] is the validated form
//! ([`AxisCampaign::from_manifest_at`]), every error one line naming the file and the key, with
//! the same [`CampaignError`] as the ballbar manifest.
//!
//! The logs as plain data (readings, fixture and environment rows) and the rules every reader
//! derives from them (direction, row order under repeated times, the fixture row a reading
//! takes) are in [`logs`]: pure functions, unit-tested there.

use crate::campaign::{check_campaign_id, limits, CampaignError};
use crate::limits::{check_point, OutOfRange, PointOutOfRange};

pub mod logs;
#[cfg(test)]
mod tests;

pub use logs::{
    derive_order, environment_at, AxisCampaignLogs, AxisCampaignTables, AxisReading, Channel,
    EnvironmentRow, ExtraColumn, FixtureRow, OrderProblem, ReadingKey, ReadingOrder,
};

// ---------------------------------------------------------------- kinds

/// What a campaign directory holds, by `[campaign] kind` (`docs/spec/machine-formats.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CampaignKind {
    /// Double ballbars on a plate (`docs/spec/campaign-format.md`); a manifest without `kind`.
    Ballbar,
    /// One linear axis measured by laser lines (seed 002).
    Axis,
    /// Body and step diagonals (seed 001).
    Volumetric,
    /// Touch-trigger probe touches on an artefact (seed 003).
    Probe,
    /// Four probes under a moving stage (seed 004).
    Roll,
}

impl CampaignKind {
    /// Every kind, in the spec's order.
    pub const ALL: [CampaignKind; 5] = [
        CampaignKind::Ballbar,
        CampaignKind::Axis,
        CampaignKind::Volumetric,
        CampaignKind::Probe,
        CampaignKind::Roll,
    ];

    /// The word of `[campaign] kind`; `CampaignKind::parse(k.as_str()) == Some(k)`.
    pub fn as_str(self) -> &'static str {
        match self {
            CampaignKind::Ballbar => "ballbar",
            CampaignKind::Axis => "axis",
            CampaignKind::Volumetric => "volumetric",
            CampaignKind::Probe => "probe",
            CampaignKind::Roll => "roll",
        }
    }

    /// The kind a word names, if any.
    pub fn parse(word: &str) -> Option<CampaignKind> {
        Self::ALL.into_iter().find(|k| k.as_str() == word)
    }
}

impl std::fmt::Display for CampaignKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

// ---------------------------------------------------------------- manifest, as declared

/// `campaign.toml` of an `axis` campaign as declared, not yet validated.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisManifest {
    /// `[campaign]`: kind, id, T0.
    pub campaign: KindSection,
    /// `[machine]`: the axis under test and its scales' expansion.
    pub machine: AxisMachineSection,
    /// `[laser]`: wavelength, what the readings include, dead path.
    pub laser: LaserSection,
    /// `line = [...]`: the interferometer set-ups.
    pub line: Vec<LineDecl>,
    /// `[fixture]`: the cross-slides' scales; absent: `u_um` 0, report point at F's origin.
    pub fixture: Option<FixtureSection>,
    /// `[[sensor]]`: the sensors of `temperatures/*.parquet`, if that table is given.
    pub sensor: Vec<MachineSensorDecl>,
}

/// `[campaign]` of a machine kind: kind, id and reference temperature.
#[derive(Debug, Clone, PartialEq)]
pub struct KindSection {
    /// The campaign kind (`"axis"` here).
    pub kind: CampaignKind,
    /// Campaign id (names the default output folder `reports/<id>`).
    pub id: String,
    /// Reference temperature T0, °C, to which lengths are normalised.
    pub reference_temperature_c: f64,
}

/// `axis` is not X, Y or Z.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown axis {0:?} (X | Y | Z)")]
pub struct UnknownAxis(pub String);

impl std::str::FromStr for MachineAxis {
    type Err = UnknownAxis;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "X" | "x" => Ok(MachineAxis::X),
            "Y" | "y" => Ok(MachineAxis::Y),
            "Z" | "z" => Ok(MachineAxis::Z),
            other => Err(UnknownAxis(other.to_string())),
        }
    }
}

impl std::fmt::Display for MachineAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.letter())
    }
}

/// A linear axis of the machine frame M.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MachineAxis {
    /// X.
    X,
    /// Y.
    Y,
    /// Z.
    Z,
}

impl MachineAxis {
    /// 0, 1, 2 for X, Y, Z: the index of the axis's component in a vector of M.
    pub fn index(self) -> usize {
        match self {
            MachineAxis::X => 0,
            MachineAxis::Y => 1,
            MachineAxis::Z => 2,
        }
    }

    /// The axis of component `i` (modulo 3).
    pub fn from_index(i: usize) -> MachineAxis {
        [MachineAxis::X, MachineAxis::Y, MachineAxis::Z][i % 3]
    }

    /// `"X"`, `"Y"` or `"Z"`.
    pub fn as_str(self) -> &'static str {
        ["X", "Y", "Z"][self.index()]
    }

    /// The ISO 230-1 names of the six errors of this axis, in the order δx, δy, δz, εx, εy, εz
    /// (`EXX, EYX, EZX, EAX, EBX, ECX` for X).
    pub fn error_names(self) -> [String; 6] {
        let j = self.as_str();
        ["X", "Y", "Z", "A", "B", "C"].map(|c| format!("E{c}{j}"))
    }

    /// The axis's letter.
    pub fn letter(self) -> char {
        ['X', 'Y', 'Z'][self.index()]
    }

    /// ISO 230-1 names of the six errors when this axis moves (δx, δy, δz, εx, εy, εz): the
    /// same as [`MachineAxis::error_names`], in `docs/spec/device-format.md`'s words.
    pub fn iso230_1_names(self) -> [String; 6] {
        self.error_names()
    }

    /// Index (0–5, δx … εz) of this axis's positioning error (EXX, EYY, EZZ).
    pub fn positioning_index(self) -> usize {
        self.index()
    }

    /// Indices (0–2) of its two straightness errors (the other translations).
    pub fn straightness_indices(self) -> [usize; 2] {
        match self {
            MachineAxis::X => [1, 2],
            MachineAxis::Y => [0, 2],
            MachineAxis::Z => [0, 1],
        }
    }

    /// The channel along the axis (`dx` for X).
    pub fn along(self) -> Channel {
        Channel::of_axis(self)
    }
}

/// `[machine]` of an `axis` campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisMachineSection {
    /// The linear axis under test.
    pub axis: MachineAxis,
    /// Expansion coefficient of the machine's scales ("Exp coeff"), ppm/K, for normalising to T0.
    pub cte_ppm_per_k: f64,
}

/// What the laser's readings already include (`[laser] compensation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LaserCompensation {
    /// Counted in vacuum wavelengths: a true displacement L reads n L.
    None,
    /// Divided by the air's refractive index: L reads L.
    Air,
    /// Also normalised to T0: L reads L / (1 + α_m (T_m − T0)).
    AirMaterial,
}

impl LaserCompensation {
    /// The word of `[laser] compensation`.
    pub fn as_str(self) -> &'static str {
        match self {
            LaserCompensation::None => "none",
            LaserCompensation::Air => "air",
            LaserCompensation::AirMaterial => "air+material",
        }
    }

    /// Whether an analysis needs `environment/*.parquet` (every mode but `air+material`).
    pub(crate) fn needs_environment(self) -> bool {
        self != LaserCompensation::AirMaterial
    }
}

/// `[laser]`.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserSection {
    /// Vacuum wavelength, nm (HeNe: 632.990577).
    pub wavelength_nm: f64,
    /// What the readings already include.
    pub compensation: LaserCompensation,
    /// Optics to reflector at the datum, mm; absent: not stated.
    pub dead_path_mm: Option<f64>,
}

/// One interferometer set-up (`line = [...]`).
#[derive(Debug, Clone, PartialEq)]
pub struct LineDecl {
    /// Line id (the `line` column of the logs).
    pub id: i64,
    /// The reflector's measuring point in the fixture frame F, mm; used where `fixture/` has no
    /// row for the line.
    pub reflector_mm: [f64; 3],
}

/// `[fixture]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FixtureSection {
    /// Standard uncertainty of each reflector coordinate from the scales, µm.
    pub u_um: f64,
    /// Where translational errors are reported, in F, mm; absent: F's origin.
    pub report_point_mm: Option<[f64; 3]>,
}

/// What a machine-kind temperature sensor measures (`sensor[].kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MachineSensorKind {
    /// Air near the beam.
    Air,
    /// The workpiece or the scales' material.
    Material,
    /// A machine part.
    Machine,
    /// Anything else.
    Other,
}

/// `[[sensor]]` of a machine kind.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineSensorDecl {
    /// Sensor id (the `sensor` column of `temperatures/*.parquet`).
    pub id: String,
    /// What it measures.
    pub kind: MachineSensorKind,
}

// ---------------------------------------------------------------- validated

/// One validated line.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Its id, as in the logs.
    pub id: i64,
    /// The manifest's reflector point in F, mm (the fallback of `reflector_at`).
    pub reflector_mm: [f64; 3],
}

/// A validated `axis` campaign manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisCampaign {
    /// The campaign's id.
    pub id: String,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// The axis under test.
    pub axis: MachineAxis,
    /// Expansion of the machine's scales, ppm/K.
    pub cte_ppm_per_k: f64,
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// What the readings already include.
    pub compensation: LaserCompensation,
    /// Optics to reflector at the datum, mm (`None`: not stated).
    pub dead_path_mm: Option<f64>,
    /// The lines, in manifest order.
    pub lines: Vec<Line>,
    /// Standard uncertainty of each reflector coordinate, µm (0 without `[fixture]`).
    pub fixture_u_um: f64,
    /// Where translational errors are reported, in F, mm.
    pub report_point_mm: [f64; 3],
    /// The declared temperature sensors, in manifest order.
    pub sensors: Vec<MachineSensorDecl>,
}

/// Ranges of the `axis` manifest's numbers beyond those of the ballbar manifest.
pub(crate) mod axis_limits {
    /// `laser.wavelength_nm`: vacuum wavelengths of length-measuring lasers (UV to far IR).
    pub(crate) const WAVELENGTH_NM: crate::limits::Limit =
        crate::limits::Limit::closed(200.0, 2_000.0, "nm");
    /// `laser.dead_path_mm`.
    pub(crate) const DEAD_PATH_MM: crate::limits::Limit =
        crate::limits::Limit::closed(0.0, LENGTH_MM, "mm");
    /// `laser.dead_path_mm`, `line[].reflector_mm`, `fixture.report_point_mm`, mm.
    pub(crate) const LENGTH_MM: f64 = 10_000.0;
}

impl AxisCampaign {
    /// The line `id`, if declared.
    pub fn line(&self, id: i64) -> Option<&Line> {
        self.lines.iter().find(|l| l.id == id)
    }

    /// The declared line ids, in manifest order.
    pub fn line_ids(&self) -> Vec<i64> {
        self.lines.iter().map(|l| l.id).collect()
    }

    /// Validates a manifest, naming `file` in messages.
    pub fn from_manifest_at(m: AxisManifest, file: &str) -> Result<AxisCampaign, CampaignError> {
        let invalid = |key: &str, problem: &dyn std::fmt::Display| CampaignError::Invalid {
            file: file.to_string(),
            key: key.to_string(),
            problem: problem.to_string(),
        };
        if m.campaign.kind != CampaignKind::Axis {
            return Err(invalid(
                "campaign.kind",
                &format!(
                    "is {:?}, this manifest is read as \"axis\"",
                    m.campaign.kind.as_str()
                ),
            ));
        }
        check_campaign_id(&m.campaign.id).map_err(|p| invalid("campaign.id", &p))?;
        in_range(
            "campaign.reference_temperature_c",
            m.campaign.reference_temperature_c,
            limits::REFERENCE_TEMPERATURE_C,
        )
        .map_err(|p| invalid("campaign.reference_temperature_c", &p))?;
        in_range(
            "machine.cte_ppm_per_k",
            m.machine.cte_ppm_per_k,
            limits::CTE_PPM_PER_K,
        )
        .map_err(|p| invalid("machine.cte_ppm_per_k", &p))?;
        in_range(
            "laser.wavelength_nm",
            m.laser.wavelength_nm,
            axis_limits::WAVELENGTH_NM,
        )
        .map_err(|p| invalid("laser.wavelength_nm", &p))?;
        if let Some(d) = m.laser.dead_path_mm {
            in_range("laser.dead_path_mm", d, axis_limits::DEAD_PATH_MM)
                .map_err(|p| invalid("laser.dead_path_mm", &p))?;
        }
        if m.line.is_empty() {
            return Err(invalid(
                "line",
                &"declares no line: at least one interferometer set-up is needed",
            ));
        }
        let mut seen = std::collections::BTreeMap::new();
        for (i, l) in m.line.iter().enumerate() {
            if let Some(first) = seen.insert(l.id, i) {
                return Err(CampaignError::DuplicateId {
                    file: file.to_string(),
                    table: "line",
                    id: l.id.to_string(),
                    first,
                    second: i,
                });
            }
            point(&l.reflector_mm).map_err(|p| invalid(&format!("line[{i}].reflector_mm"), &p))?;
        }
        let (fixture_u_um, report_point_mm) = match &m.fixture {
            None => (0.0, [0.0; 3]),
            Some(f) => {
                in_range("fixture.u_um", f.u_um, limits::U_UM)
                    .map_err(|p| invalid("fixture.u_um", &p))?;
                let report = f.report_point_mm.unwrap_or([0.0; 3]);
                point(&report).map_err(|p| invalid("fixture.report_point_mm", &p))?;
                (f.u_um, report)
            }
        };
        let mut sensor_ids = std::collections::BTreeMap::new();
        for (i, s) in m.sensor.iter().enumerate() {
            if s.id.trim().is_empty() || s.id.chars().any(char::is_control) {
                return Err(invalid(
                    &format!("sensor[{i}]"),
                    &format!("id {:?} is empty or holds a control character", s.id),
                ));
            }
            if let Some(first) = sensor_ids.insert(s.id.as_str(), i) {
                return Err(CampaignError::DuplicateId {
                    file: file.to_string(),
                    table: "sensor",
                    id: s.id.clone(),
                    first,
                    second: i,
                });
            }
        }
        Ok(AxisCampaign {
            id: m.campaign.id,
            reference_temperature_c: m.campaign.reference_temperature_c,
            axis: m.machine.axis,
            cte_ppm_per_k: m.machine.cte_ppm_per_k,
            wavelength_nm: m.laser.wavelength_nm,
            compensation: m.laser.compensation,
            dead_path_mm: m.laser.dead_path_mm,
            lines: m
                .line
                .into_iter()
                .map(|l| Line {
                    id: l.id,
                    reflector_mm: l.reflector_mm,
                })
                .collect(),
            fixture_u_um,
            report_point_mm,
            sensors: m.sensor,
        })
    }

    /// The environment table's rule (`machine-formats.md`, "Laser and environment"):
    /// `environment/*.parquet` is required unless `compensation = "air+material"`. `has_rows`:
    /// whether the campaign has environment rows; `file` names the manifest.
    pub fn check_environment(&self, has_rows: bool, file: &str) -> Result<(), CampaignError> {
        if has_rows || !self.compensation.needs_environment() {
            return Ok(());
        }
        Err(CampaignError::Invalid {
            file: file.to_string(),
            key: "laser.compensation".into(),
            problem: format!(
                "is {:?}: the readings are not normalised, so environment/*.parquet (air_c, pressure_hpa, humidity_pct, material_c) is required unless compensation = \"air+material\"; none was found",
                self.compensation.as_str()
            ),
        })
    }
}

/// `value` within `limit`, named by the last part of `name`.
fn in_range(name: &str, value: f64, limit: crate::limits::Limit) -> Result<(), OutOfRange> {
    let name = name.rsplit('.').next().unwrap_or(name);
    limit.check(name, value)
}

/// A point in mm: every coordinate finite and within ±10 m.
fn point(p: &[f64; 3]) -> Result<(), PointOutOfRange> {
    check_point(p, axis_limits::LENGTH_MM)
}
