//! The manifests' file format: `campaign.toml` of every campaign kind as TOML.
//!
//! Each kind's module holds the file's types, one to one with the TOML (serde: the keys, their
//! defaults, what may be left out), and their conversions to and from the declared manifests of
//! `dbbcal-core`, which knows no file format. [`TomlManifest`] parses a manifest's text (syntax
//! and shape; messages name the file, line and column) and writes one (what the simulators
//! write); [`TomlCampaign`] parses and validates (core's validation: every message names the
//! file and the key). [`campaign_kind`] reads `[campaign] kind` from any manifest, so that the
//! application can choose a reader before validating.

pub mod as_written;
pub mod axis;
pub mod campaign;
pub mod probe;
pub mod roll;
pub mod volumetric;

#[cfg(test)]
mod axis_tests;
#[cfg(test)]
mod campaign_prop_tests;
#[cfg(test)]
mod campaign_tests;
#[cfg(test)]
mod device_tests;
#[cfg(test)]
mod machine_kind_tests;

use dbbcal_core::axis_campaign::{AxisCampaign, AxisManifest, CampaignKind};
use dbbcal_core::campaign::{CampaignError, Manifest};
use dbbcal_core::probe_campaign::{ProbeCampaign, ProbeManifest};
use dbbcal_core::roll_campaign::{RollCampaign, RollManifest};
use dbbcal_core::volumetric_campaign::{VolumetricCampaign, VolumetricManifest};

/// A declared manifest read from and written to its `campaign.toml` text.
pub trait TomlManifest: Sized {
    /// Parses `campaign.toml` text (syntax and shape only); `file` names it in messages.
    fn from_toml_str(text: &str, file: &str) -> Result<Self, CampaignError>;

    /// The manifest as TOML text (what the simulators write).
    fn to_toml_string(&self) -> Result<String, toml::ser::Error>;
}

/// A validated campaign read from its `campaign.toml` text.
pub trait TomlCampaign: Sized {
    /// Parses and validates `campaign.toml` text, naming `file` in messages.
    fn from_toml_str(text: &str, file: &str) -> Result<Self, CampaignError>;
}

impl TomlManifest for Manifest {
    fn from_toml_str(text: &str, file: &str) -> Result<Manifest, CampaignError> {
        parse::<campaign::Manifest>(text, file).map(Into::into)
    }

    fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(&campaign::Manifest::try_from(self.clone())?)
    }
}

impl TomlManifest for AxisManifest {
    fn from_toml_str(text: &str, file: &str) -> Result<AxisManifest, CampaignError> {
        parse::<axis::AxisManifest>(text, file).map(Into::into)
    }

    fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(&axis::AxisManifest::from(self.clone()))
    }
}

impl TomlManifest for VolumetricManifest {
    fn from_toml_str(text: &str, file: &str) -> Result<VolumetricManifest, CampaignError> {
        parse::<volumetric::VolumetricManifest>(text, file).map(Into::into)
    }

    fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(&volumetric::VolumetricManifest::from(self.clone()))
    }
}

impl TomlManifest for ProbeManifest {
    fn from_toml_str(text: &str, file: &str) -> Result<ProbeManifest, CampaignError> {
        parse::<probe::ProbeManifest>(text, file).map(Into::into)
    }

    fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(&probe::ProbeManifest::from(self.clone()))
    }
}

impl TomlManifest for RollManifest {
    /// A syntax error of a `roll` manifest names the file, not the line and column (0, 0).
    fn from_toml_str(text: &str, file: &str) -> Result<RollManifest, CampaignError> {
        toml::from_str::<roll::RollManifest>(text)
            .map(Into::into)
            .map_err(|e| CampaignError::Syntax {
                file: file.to_string(),
                line: 0,
                column: 0,
                message: one_line(&e.to_string()),
            })
    }

    fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(&roll::RollManifest::from(self.clone()))
    }
}

impl TomlCampaign for AxisCampaign {
    fn from_toml_str(text: &str, file: &str) -> Result<AxisCampaign, CampaignError> {
        AxisCampaign::from_manifest_at(AxisManifest::from_toml_str(text, file)?, file)
    }
}

impl TomlCampaign for VolumetricCampaign {
    fn from_toml_str(text: &str, file: &str) -> Result<VolumetricCampaign, CampaignError> {
        VolumetricCampaign::from_manifest_at(VolumetricManifest::from_toml_str(text, file)?, file)
    }
}

impl TomlCampaign for ProbeCampaign {
    fn from_toml_str(text: &str, file: &str) -> Result<ProbeCampaign, CampaignError> {
        ProbeCampaign::from_manifest_at(ProbeManifest::from_toml_str(text, file)?, file)
    }
}

impl TomlCampaign for RollCampaign {
    fn from_toml_str(text: &str, file: &str) -> Result<RollCampaign, CampaignError> {
        RollCampaign::from_manifest_at(RollManifest::from_toml_str(text, file)?, file)
    }
}

/// `text` as the file type `T`, or the syntax error naming `file`, line and column.
fn parse<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T, CampaignError> {
    toml::from_str(text).map_err(|e| syntax_error(text, file, &e))
}

/// The kind of the campaign whose `campaign.toml` is `text` (`file` names it in messages):
/// `[campaign] kind`, [`CampaignKind::Ballbar`] when the key (or `[campaign]`) is absent. Only
/// that key is looked at: the rest is validated by the kind's own parser.
pub fn campaign_kind(text: &str, file: &str) -> Result<CampaignKind, CampaignError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| syntax_error(text, file, &e))?;
    let Some(campaign) = table.get("campaign") else {
        return Ok(CampaignKind::Ballbar);
    };
    let Some(kind) = campaign.as_table().and_then(|c| c.get("kind")) else {
        return Ok(CampaignKind::Ballbar);
    };
    let Some(word) = kind.as_str() else {
        return Err(CampaignError::Invalid {
            file: file.to_string(),
            key: "campaign.kind".into(),
            problem: format!(
                "must be a string (one of {}), not {}",
                known_kinds(),
                kind.type_str()
            ),
        });
    };
    CampaignKind::parse(word).ok_or_else(|| CampaignError::Unknown {
        file: file.to_string(),
        key: "campaign".into(),
        field: "kind",
        value: word.to_string(),
        what: "a campaign kind",
        known: known_kinds().into(),
    })
}

/// Every kind's word, comma-separated.
fn known_kinds() -> String {
    CampaignKind::ALL
        .iter()
        .map(|k| k.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The TOML parser's error `e` on `text`, as one line naming `file`, line and column.
fn syntax_error(text: &str, file: &str, e: &toml::de::Error) -> CampaignError {
    let (line, column) = e.span().map_or((0, 0), |s| line_column(text, s.start));
    CampaignError::Syntax {
        file: file.to_string(),
        line,
        column,
        message: one_line(e.message()),
    }
}

/// 1-based line and column of byte `offset` in `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut end = offset.min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let before = &text[..end];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// `s` on one line: every run of white space one space.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
