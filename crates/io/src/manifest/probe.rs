//! `campaign.toml` of a `probe` campaign (`docs/spec/machine-formats.md`, "Kind `probe`"): the
//! file's types, one to one with the TOML, and their conversions to and from
//! `dbbcal_core::probe_campaign`'s.

use serde::{Deserialize, Serialize};

use dbbcal_core::probe_campaign as core;

use super::axis::{KindSection, MachineSensorKind};

/// `campaign.toml` of a `probe` campaign as written, not yet validated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProbeManifest {
    /// `[campaign]`: kind, id, T0.
    pub campaign: KindSection,
    /// `[probe]`: model (informative) and the same-direction tolerance.
    pub probe: ProbeSection,
    /// `[[stylus]]`.
    pub stylus: Vec<StylusDecl>,
    /// `[[artefact]]`.
    pub artefact: Vec<ArtefactDecl>,
    /// `[[sensor]]`: sensors of `temperatures/*.parquet`, if given (not analysed by this
    /// version).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sensor: Vec<ProbeSensorDecl>,
}

/// A temperature sensor of a `probe` campaign.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProbeSensorDecl {
    /// Sensor id.
    pub id: String,
    /// What it measures.
    pub kind: MachineSensorKind,
}

/// `[probe]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProbeSection {
    /// The probe's model (informative, e.g. `TP2-5`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    /// Approach vectors within this angle are the same direction, degrees (default 1).
    #[serde(default = "default_same_direction_deg")]
    pub same_direction_deg: f64,
}

/// `[[stylus]]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StylusDecl {
    /// Stylus id (the `stylus` column).
    pub id: String,
    /// Nominal tip-ball diameter, mm.
    pub tip_diameter_mm: f64,
    /// Stylus length, mm (informative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_mm: Option<f64>,
}

/// What the artefact is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ArtefactKind {
    /// A ring gauge, axis along Z, probed from inside.
    Ring,
    /// A sphere, probed from outside.
    Sphere,
}

/// `[[artefact]]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ArtefactDecl {
    /// Artefact id (the `artefact` column).
    pub id: String,
    /// Ring or sphere.
    pub kind: ArtefactKind,
    /// Certified diameter, mm.
    pub diameter_mm: f64,
    /// Standard uncertainty (k = 1) of the diameter, µm.
    pub u_um: f64,
    /// Certified form deviation, µm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form_um: Option<f64>,
    /// Known centre, mm; absent: fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre_mm: Option<[f64; 3]>,
}

fn default_same_direction_deg() -> f64 {
    1.0
}

// ---- conversions

impl From<ProbeManifest> for core::ProbeManifest {
    fn from(v: ProbeManifest) -> Self {
        core::ProbeManifest {
            campaign: v.campaign.into(),
            probe: v.probe.into(),
            stylus: v.stylus.into_iter().map(Into::into).collect(),
            artefact: v.artefact.into_iter().map(Into::into).collect(),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<core::ProbeManifest> for ProbeManifest {
    fn from(v: core::ProbeManifest) -> Self {
        ProbeManifest {
            campaign: v.campaign.into(),
            probe: v.probe.into(),
            stylus: v.stylus.into_iter().map(Into::into).collect(),
            artefact: v.artefact.into_iter().map(Into::into).collect(),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<ProbeSensorDecl> for core::ProbeSensorDecl {
    fn from(v: ProbeSensorDecl) -> Self {
        core::ProbeSensorDecl {
            id: v.id,
            kind: v.kind.into(),
        }
    }
}

impl From<core::ProbeSensorDecl> for ProbeSensorDecl {
    fn from(v: core::ProbeSensorDecl) -> Self {
        ProbeSensorDecl {
            id: v.id,
            kind: v.kind.into(),
        }
    }
}

impl From<ProbeSection> for core::ProbeSection {
    fn from(v: ProbeSection) -> Self {
        core::ProbeSection {
            model: v.model,
            same_direction_deg: v.same_direction_deg,
        }
    }
}

impl From<core::ProbeSection> for ProbeSection {
    fn from(v: core::ProbeSection) -> Self {
        ProbeSection {
            model: v.model,
            same_direction_deg: v.same_direction_deg,
        }
    }
}

impl From<StylusDecl> for core::StylusDecl {
    fn from(v: StylusDecl) -> Self {
        core::StylusDecl {
            id: v.id,
            tip_diameter_mm: v.tip_diameter_mm,
            length_mm: v.length_mm,
        }
    }
}

impl From<core::StylusDecl> for StylusDecl {
    fn from(v: core::StylusDecl) -> Self {
        StylusDecl {
            id: v.id,
            tip_diameter_mm: v.tip_diameter_mm,
            length_mm: v.length_mm,
        }
    }
}

impl From<ArtefactKind> for core::ArtefactKind {
    fn from(v: ArtefactKind) -> Self {
        match v {
            ArtefactKind::Ring => core::ArtefactKind::Ring,
            ArtefactKind::Sphere => core::ArtefactKind::Sphere,
        }
    }
}

impl From<core::ArtefactKind> for ArtefactKind {
    fn from(v: core::ArtefactKind) -> Self {
        match v {
            core::ArtefactKind::Ring => ArtefactKind::Ring,
            core::ArtefactKind::Sphere => ArtefactKind::Sphere,
        }
    }
}

impl From<ArtefactDecl> for core::ArtefactDecl {
    fn from(v: ArtefactDecl) -> Self {
        core::ArtefactDecl {
            id: v.id,
            kind: v.kind.into(),
            diameter_mm: v.diameter_mm,
            u_um: v.u_um,
            form_um: v.form_um,
            centre_mm: v.centre_mm,
        }
    }
}

impl From<core::ArtefactDecl> for ArtefactDecl {
    fn from(v: core::ArtefactDecl) -> Self {
        ArtefactDecl {
            id: v.id,
            kind: v.kind.into(),
            diameter_mm: v.diameter_mm,
            u_um: v.u_um,
            form_um: v.form_um,
            centre_mm: v.centre_mm,
        }
    }
}
