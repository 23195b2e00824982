//! Core's manifest values inside other files' types (the simulators' configurations and
//! `truth.json`): `#[serde(with = "dbbcal_io::manifest::as_written::machine_axis")]` on a field
//! of core's type writes and reads it exactly as `campaign.toml` does.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A module of `serialize`/`deserialize` for core's `$core` through its file type `$file`.
macro_rules! as_written {
    ($(#[$doc:meta])* $name:ident, $core:ty, $file:ty) => {
        $(#[$doc])*
        pub mod $name {
            use super::*;

            /// Writes `v` as its file type does.
            pub fn serialize<S: Serializer>(v: &$core, s: S) -> Result<S::Ok, S::Error> {
                <$file>::from(v.clone()).serialize(s)
            }

            /// Reads a value as its file type does.
            pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<$core, D::Error> {
                <$file>::deserialize(d).map(Into::into)
            }
        }
    };
}

as_written!(
    /// `[campaign] kind`.
    campaign_kind,
    dbbcal_core::axis_campaign::CampaignKind,
    crate::manifest::axis::CampaignKind
);
as_written!(
    /// A machine axis, `"X"`, `"Y"` or `"Z"`.
    machine_axis,
    dbbcal_core::axis_campaign::MachineAxis,
    crate::manifest::axis::MachineAxis
);
as_written!(
    /// `[laser] compensation`.
    laser_compensation,
    dbbcal_core::axis_campaign::LaserCompensation,
    crate::manifest::axis::LaserCompensation
);
as_written!(
    /// `artefact[].kind`.
    artefact_kind,
    dbbcal_core::probe_campaign::ArtefactKind,
    crate::manifest::probe::ArtefactKind
);
as_written!(
    /// `[roll] unit`.
    reading_unit,
    dbbcal_core::roll_campaign::ReadingUnit,
    crate::manifest::roll::ReadingUnit
);
as_written!(
    /// `mount[].purpose`.
    purpose,
    dbbcal_core::campaign::Purpose,
    crate::manifest::campaign::Purpose
);

/// `[[plate.length]]`, a list of calibrated lengths.
pub mod plate_lengths {
    use super::*;
    use dbbcal_core::campaign::PlateLength;

    /// Writes the lengths as `campaign.toml` does.
    pub fn serialize<S: Serializer>(v: &[PlateLength], s: S) -> Result<S::Ok, S::Error> {
        v.iter()
            .cloned()
            .map(crate::manifest::campaign::PlateLength::from)
            .collect::<Vec<_>>()
            .serialize(s)
    }

    /// Reads the lengths as `campaign.toml` does.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<PlateLength>, D::Error> {
        Vec::<crate::manifest::campaign::PlateLength>::deserialize(d)
            .map(|v| v.into_iter().map(Into::into).collect())
    }
}
