//! `campaign.toml` of an `axis` campaign (`docs/spec/machine-formats.md`, "Kind axis"), and the
//! `[campaign]` section and sensor declarations every machine kind shares: the file's types, one
//! to one with the TOML, and their conversions to and from `dbbcal_core::axis_campaign`'s.

use serde::{Deserialize, Serialize};

use dbbcal_core::axis_campaign as core;

/// What a campaign directory holds, by `[campaign] kind` (`docs/spec/machine-formats.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
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

/// `campaign.toml` of an `axis` campaign as written, not yet validated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
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
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixture: Option<FixtureSection>,
    /// `[[sensor]]`: the sensors of `temperatures/*.parquet`, if that table is given.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sensor: Vec<MachineSensorDecl>,
}

/// `[campaign]` of a machine kind: kind, id and reference temperature.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct KindSection {
    /// The campaign kind (`"axis"` here).
    pub kind: CampaignKind,
    /// Campaign id (names the default output folder `reports/<id>`).
    pub id: String,
    /// Reference temperature T0, °C, to which lengths are normalised.
    pub reference_temperature_c: f64,
}

/// A linear axis of the machine frame M.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum MachineAxis {
    /// X.
    X,
    /// Y.
    Y,
    /// Z.
    Z,
}

/// `[machine]` of an `axis` campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisMachineSection {
    /// The linear axis under test.
    pub axis: MachineAxis,
    /// Expansion coefficient of the machine's scales ("Exp coeff"), ppm/K, for normalising to T0.
    pub cte_ppm_per_k: f64,
}

/// What the laser's readings already include (`[laser] compensation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LaserCompensation {
    /// Counted in vacuum wavelengths: a true displacement L reads n L.
    #[serde(rename = "none")]
    None,
    /// Divided by the air's refractive index: L reads L.
    #[serde(rename = "air")]
    Air,
    /// Also normalised to T0: L reads L / (1 + α_m (T_m − T0)).
    #[serde(rename = "air+material")]
    AirMaterial,
}

/// `[laser]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LaserSection {
    /// Vacuum wavelength, nm (HeNe: 632.990577).
    pub wavelength_nm: f64,
    /// What the readings already include.
    pub compensation: LaserCompensation,
    /// Optics to reflector at the datum, mm; absent: not stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dead_path_mm: Option<f64>,
}

/// One interferometer set-up (`line = [...]`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LineDecl {
    /// Line id (the `line` column of the logs).
    pub id: i64,
    /// The reflector's measuring point in the fixture frame F, mm; used where `fixture/` has no
    /// row for the line.
    pub reflector_mm: [f64; 3],
}

/// `[fixture]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FixtureSection {
    /// Standard uncertainty of each reflector coordinate from the scales, µm.
    pub u_um: f64,
    /// Where translational errors are reported, in F, mm; absent: F's origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report_point_mm: Option<[f64; 3]>,
}

/// What a machine-kind temperature sensor measures (`sensor[].kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
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
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MachineSensorDecl {
    /// Sensor id (the `sensor` column of `temperatures/*.parquet`).
    pub id: String,
    /// What it measures.
    pub kind: MachineSensorKind,
}

// ---- conversions

impl From<CampaignKind> for core::CampaignKind {
    fn from(v: CampaignKind) -> Self {
        match v {
            CampaignKind::Ballbar => core::CampaignKind::Ballbar,
            CampaignKind::Axis => core::CampaignKind::Axis,
            CampaignKind::Volumetric => core::CampaignKind::Volumetric,
            CampaignKind::Probe => core::CampaignKind::Probe,
            CampaignKind::Roll => core::CampaignKind::Roll,
        }
    }
}

impl From<core::CampaignKind> for CampaignKind {
    fn from(v: core::CampaignKind) -> Self {
        match v {
            core::CampaignKind::Ballbar => CampaignKind::Ballbar,
            core::CampaignKind::Axis => CampaignKind::Axis,
            core::CampaignKind::Volumetric => CampaignKind::Volumetric,
            core::CampaignKind::Probe => CampaignKind::Probe,
            core::CampaignKind::Roll => CampaignKind::Roll,
        }
    }
}

impl From<AxisManifest> for core::AxisManifest {
    fn from(v: AxisManifest) -> Self {
        core::AxisManifest {
            campaign: v.campaign.into(),
            machine: v.machine.into(),
            laser: v.laser.into(),
            line: v.line.into_iter().map(Into::into).collect(),
            fixture: v.fixture.map(Into::into),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<core::AxisManifest> for AxisManifest {
    fn from(v: core::AxisManifest) -> Self {
        AxisManifest {
            campaign: v.campaign.into(),
            machine: v.machine.into(),
            laser: v.laser.into(),
            line: v.line.into_iter().map(Into::into).collect(),
            fixture: v.fixture.map(Into::into),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<KindSection> for core::KindSection {
    fn from(v: KindSection) -> Self {
        core::KindSection {
            kind: v.kind.into(),
            id: v.id,
            reference_temperature_c: v.reference_temperature_c,
        }
    }
}

impl From<core::KindSection> for KindSection {
    fn from(v: core::KindSection) -> Self {
        KindSection {
            kind: v.kind.into(),
            id: v.id,
            reference_temperature_c: v.reference_temperature_c,
        }
    }
}

impl From<MachineAxis> for core::MachineAxis {
    fn from(v: MachineAxis) -> Self {
        match v {
            MachineAxis::X => core::MachineAxis::X,
            MachineAxis::Y => core::MachineAxis::Y,
            MachineAxis::Z => core::MachineAxis::Z,
        }
    }
}

impl From<core::MachineAxis> for MachineAxis {
    fn from(v: core::MachineAxis) -> Self {
        match v {
            core::MachineAxis::X => MachineAxis::X,
            core::MachineAxis::Y => MachineAxis::Y,
            core::MachineAxis::Z => MachineAxis::Z,
        }
    }
}

impl From<AxisMachineSection> for core::AxisMachineSection {
    fn from(v: AxisMachineSection) -> Self {
        core::AxisMachineSection {
            axis: v.axis.into(),
            cte_ppm_per_k: v.cte_ppm_per_k,
        }
    }
}

impl From<core::AxisMachineSection> for AxisMachineSection {
    fn from(v: core::AxisMachineSection) -> Self {
        AxisMachineSection {
            axis: v.axis.into(),
            cte_ppm_per_k: v.cte_ppm_per_k,
        }
    }
}

impl From<LaserCompensation> for core::LaserCompensation {
    fn from(v: LaserCompensation) -> Self {
        match v {
            LaserCompensation::None => core::LaserCompensation::None,
            LaserCompensation::Air => core::LaserCompensation::Air,
            LaserCompensation::AirMaterial => core::LaserCompensation::AirMaterial,
        }
    }
}

impl From<core::LaserCompensation> for LaserCompensation {
    fn from(v: core::LaserCompensation) -> Self {
        match v {
            core::LaserCompensation::None => LaserCompensation::None,
            core::LaserCompensation::Air => LaserCompensation::Air,
            core::LaserCompensation::AirMaterial => LaserCompensation::AirMaterial,
        }
    }
}

impl From<LaserSection> for core::LaserSection {
    fn from(v: LaserSection) -> Self {
        core::LaserSection {
            wavelength_nm: v.wavelength_nm,
            compensation: v.compensation.into(),
            dead_path_mm: v.dead_path_mm,
        }
    }
}

impl From<core::LaserSection> for LaserSection {
    fn from(v: core::LaserSection) -> Self {
        LaserSection {
            wavelength_nm: v.wavelength_nm,
            compensation: v.compensation.into(),
            dead_path_mm: v.dead_path_mm,
        }
    }
}

impl From<LineDecl> for core::LineDecl {
    fn from(v: LineDecl) -> Self {
        core::LineDecl {
            id: v.id,
            reflector_mm: v.reflector_mm,
        }
    }
}

impl From<core::LineDecl> for LineDecl {
    fn from(v: core::LineDecl) -> Self {
        LineDecl {
            id: v.id,
            reflector_mm: v.reflector_mm,
        }
    }
}

impl From<FixtureSection> for core::FixtureSection {
    fn from(v: FixtureSection) -> Self {
        core::FixtureSection {
            u_um: v.u_um,
            report_point_mm: v.report_point_mm,
        }
    }
}

impl From<core::FixtureSection> for FixtureSection {
    fn from(v: core::FixtureSection) -> Self {
        FixtureSection {
            u_um: v.u_um,
            report_point_mm: v.report_point_mm,
        }
    }
}

impl From<MachineSensorKind> for core::MachineSensorKind {
    fn from(v: MachineSensorKind) -> Self {
        match v {
            MachineSensorKind::Air => core::MachineSensorKind::Air,
            MachineSensorKind::Material => core::MachineSensorKind::Material,
            MachineSensorKind::Machine => core::MachineSensorKind::Machine,
            MachineSensorKind::Other => core::MachineSensorKind::Other,
        }
    }
}

impl From<core::MachineSensorKind> for MachineSensorKind {
    fn from(v: core::MachineSensorKind) -> Self {
        match v {
            core::MachineSensorKind::Air => MachineSensorKind::Air,
            core::MachineSensorKind::Material => MachineSensorKind::Material,
            core::MachineSensorKind::Machine => MachineSensorKind::Machine,
            core::MachineSensorKind::Other => MachineSensorKind::Other,
        }
    }
}

impl From<MachineSensorDecl> for core::MachineSensorDecl {
    fn from(v: MachineSensorDecl) -> Self {
        core::MachineSensorDecl {
            id: v.id,
            kind: v.kind.into(),
        }
    }
}

impl From<core::MachineSensorDecl> for MachineSensorDecl {
    fn from(v: core::MachineSensorDecl) -> Self {
        MachineSensorDecl {
            id: v.id,
            kind: v.kind.into(),
        }
    }
}
