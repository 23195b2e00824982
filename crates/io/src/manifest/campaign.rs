//! `campaign.toml` of a ballbar campaign (`docs/spec/campaign-format.md`), `[[device]]` tables
//! included (`docs/spec/device-format.md`): the file's types, one to one with the TOML, and their
//! conversions to and from `dbbcal_core::campaign`'s declared manifest. Mount times convert
//! here: a TOML date-time to nanoseconds since the epoch, UTC unless it gives an offset.

use serde::{Deserialize, Serialize};

use dbbcal_core::campaign as core;
use dbbcal_core::campaign::{DeclaredTime, TimeError};

/// `campaign.toml` as written (`docs/spec/campaign-format.md`), not yet validated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// `[campaign]`.
    pub campaign: CampaignSection,
    /// `[plate]`.
    pub plate: PlateSection,
    /// `[[sensor]]`: the temperature sensors.
    #[serde(default)]
    pub sensor: Vec<SensorDecl>,
    /// `[[bar]]`: the ballbars.
    #[serde(default)]
    pub bar: Vec<BarDecl>,
    /// `[[mount]]`: where each bar sat, and when.
    #[serde(default)]
    pub mount: Vec<MountDecl>,
    /// `[[device]]`: measuring devices whose legs are working bars (`docs/spec/device-format.md`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub device: Vec<DeviceDecl>,
}

/// `[campaign]`: id and reference temperature.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CampaignSection {
    /// Campaign id (names the default output folder `reports/<id>`).
    pub id: String,
    /// Reference temperature T0, °C.
    pub reference_temperature_c: f64,
}

/// `[plate]`: the calibration plate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlateSection {
    /// Plate material (free text).
    pub material: String,
    /// Declared expansion coefficient of the plate, ppm/K; 0 when absent.
    #[serde(default)]
    pub cte_ppm_per_k: f64,
    /// Plate tilt from horizontal, degrees; 0 when absent.
    #[serde(default)]
    pub tilt_deg: f64,
    /// `[[plate.length]]`: the calibrated socket-pair distances.
    #[serde(default)]
    pub length: Vec<PlateLength>,
}

/// One calibrated socket-pair distance on the plate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlateLength {
    /// Length id (what `mount[].length` names).
    pub id: String,
    /// Calibrated centre distance, mm.
    pub mm: f64,
    /// Standard uncertainty (k = 1) of the calibrated length, micrometres.
    pub u_um: f64,
}

/// What a temperature sensor measures (`sensor[].kind`).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[serde(rename_all = "lowercase")]
pub enum SensorKind {
    /// Air near the bars.
    Air,
    /// The plate.
    Plate,
    /// A bar itself.
    Bar,
    /// A read head.
    Head,
    /// Anything else (a machine part, coolant, …).
    Other,
}

/// `[[sensor]]`: one temperature sensor.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorDecl {
    /// Sensor id (the `sensor` column of `temperatures/*.parquet`).
    pub id: String,
    /// What it measures.
    pub kind: SensorKind,
}

/// `[[bar]]`: one ballbar.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BarDecl {
    /// Bar id (the `bar` column of `encoders/*.parquet`).
    pub id: String,
    /// Encoder resolution, nm a count.
    pub resolution_nm: f64,
    /// `I_min` of `docs/spec/physics.md`: the part of the centre distance that is not scale travel, mm.
    pub fixed_length_mm: f64,
    /// The air sensor nearest the bar; absent: the mean of all air sensors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<String>,
}

/// What a mount is for (`mount[].purpose`).
#[derive(
    Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, PartialOrd, Ord, Hash, Default,
)]
#[serde(rename_all = "lowercase")]
pub enum Purpose {
    /// A calibration point, and data for the thermal model (the default).
    #[default]
    Calibration,
    /// The bar serves as a reference bar during the mount.
    Reference,
    /// A known length used only to verify the result, never fitted.
    Check,
}

/// `[[mount]]`: one bar on a plate length or a device for a time span.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MountDecl {
    /// Bar id.
    pub bar: String,
    /// Plate length id (on the plate); absent on a device.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<String>,
    /// Device name (on a target device, true distance unknown); absent on the plate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// The leg (1–6) of a declared hexapod the bar sits in; only on such a device.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leg: Option<u8>,
    /// Tilt of the bar from horizontal, degrees; absent: the plate's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tilt_deg: Option<f64>,
    /// What the mount is for; absent: calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub purpose: Option<Purpose>,
    /// Start of the mount (UTC).
    pub from: toml::value::Datetime,
    /// End of the mount (UTC).
    pub to: toml::value::Datetime,
}

/// The kind of a device (`device[].kind`).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[serde(rename_all = "lowercase")]
pub enum DeviceKind {
    /// A six-link parallel mechanism: six legs numbered 1–6.
    Hexapod,
}

/// A value for every leg: one for all, or one per leg (`u_base_um`, `u_platform_um`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum PerLeg {
    /// The same value for every leg.
    All(f64),
    /// One value per leg, leg 1 first.
    Each(Vec<f64>),
}

/// `[[device]]` as written (`docs/spec/device-format.md`), not yet validated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DeviceDecl {
    /// Device id, as in mounts and `positions`.
    pub id: String,
    /// `"hexapod"`.
    pub kind: DeviceKind,
    /// Base joint centres in frame B, mm, leg 1 first.
    pub base_mm: Vec<[f64; 3]>,
    /// Platform joint centres in frame P, mm, leg 1 first.
    pub platform_mm: Vec<[f64; 3]>,
    /// Standard uncertainty (k = 1) of each coordinate of a base joint centre, µm.
    pub u_base_um: PerLeg,
    /// The same for the platform joint centres, µm.
    pub u_platform_um: PerLeg,
    /// Pose of P in B at the datum: [x, y, z] mm, [rx, ry, rz] degrees.
    pub nominal_pose: [f64; 6],
    /// The point of P whose translational errors are reported, mm; default P's origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_point_mm: Option<[f64; 3]>,
    /// Orientation of B in M, degrees; default [0, 0, 0].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_orientation_deg: Option<[f64; 3]>,
    /// The upward vertical in B; default [0, 0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// The commanded machine position whose first dwell is the datum, mm; default the first
    /// dwell in `positions`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_mm: Option<[f64; 3]>,
    /// Expansion of the base and platform bodies, ppm/K; default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cte_ppm_per_k: Option<f64>,
    /// Temperature sensor of those bodies; default the mean of the air sensors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<String>,
}

// ---- conversions

impl From<Manifest> for core::Manifest {
    fn from(v: Manifest) -> Self {
        core::Manifest {
            campaign: v.campaign.into(),
            plate: v.plate.into(),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
            bar: v.bar.into_iter().map(Into::into).collect(),
            mount: v.mount.into_iter().map(Into::into).collect(),
            device: v.device.into_iter().map(Into::into).collect(),
        }
    }
}

impl TryFrom<core::Manifest> for Manifest {
    type Error = toml::ser::Error;
    fn try_from(v: core::Manifest) -> Result<Self, Self::Error> {
        Ok(Manifest {
            campaign: v.campaign.into(),
            plate: v.plate.into(),
            sensor: v.sensor.into_iter().map(Into::into).collect(),
            bar: v.bar.into_iter().map(Into::into).collect(),
            mount: v
                .mount
                .into_iter()
                .map(MountDecl::try_from)
                .collect::<Result<_, _>>()?,
            device: v.device.into_iter().map(Into::into).collect(),
        })
    }
}

impl From<MountDecl> for core::MountDecl {
    fn from(v: MountDecl) -> Self {
        core::MountDecl {
            bar: v.bar,
            length: v.length,
            device: v.device,
            leg: v.leg,
            tilt_deg: v.tilt_deg,
            purpose: v.purpose.map(Into::into),
            from: declared_time(&v.from),
            to: declared_time(&v.to),
        }
    }
}

impl TryFrom<core::MountDecl> for MountDecl {
    type Error = toml::ser::Error;
    fn try_from(v: core::MountDecl) -> Result<Self, Self::Error> {
        Ok(MountDecl {
            bar: v.bar,
            length: v.length,
            device: v.device,
            leg: v.leg,
            tilt_deg: v.tilt_deg,
            purpose: v.purpose.map(Into::into),
            from: toml_datetime(&v.from)?,
            to: toml_datetime(&v.to)?,
        })
    }
}

impl From<CampaignSection> for core::CampaignSection {
    fn from(v: CampaignSection) -> Self {
        core::CampaignSection {
            id: v.id,
            reference_temperature_c: v.reference_temperature_c,
        }
    }
}

impl From<core::CampaignSection> for CampaignSection {
    fn from(v: core::CampaignSection) -> Self {
        CampaignSection {
            id: v.id,
            reference_temperature_c: v.reference_temperature_c,
        }
    }
}

impl From<PlateSection> for core::PlateSection {
    fn from(v: PlateSection) -> Self {
        core::PlateSection {
            material: v.material,
            cte_ppm_per_k: v.cte_ppm_per_k,
            tilt_deg: v.tilt_deg,
            length: v.length.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<core::PlateSection> for PlateSection {
    fn from(v: core::PlateSection) -> Self {
        PlateSection {
            material: v.material,
            cte_ppm_per_k: v.cte_ppm_per_k,
            tilt_deg: v.tilt_deg,
            length: v.length.into_iter().map(Into::into).collect(),
        }
    }
}

impl From<PlateLength> for core::PlateLength {
    fn from(v: PlateLength) -> Self {
        core::PlateLength {
            id: v.id,
            mm: v.mm,
            u_um: v.u_um,
        }
    }
}

impl From<core::PlateLength> for PlateLength {
    fn from(v: core::PlateLength) -> Self {
        PlateLength {
            id: v.id,
            mm: v.mm,
            u_um: v.u_um,
        }
    }
}

impl From<SensorKind> for core::SensorKind {
    fn from(v: SensorKind) -> Self {
        match v {
            SensorKind::Air => core::SensorKind::Air,
            SensorKind::Plate => core::SensorKind::Plate,
            SensorKind::Bar => core::SensorKind::Bar,
            SensorKind::Head => core::SensorKind::Head,
            SensorKind::Other => core::SensorKind::Other,
        }
    }
}

impl From<core::SensorKind> for SensorKind {
    fn from(v: core::SensorKind) -> Self {
        match v {
            core::SensorKind::Air => SensorKind::Air,
            core::SensorKind::Plate => SensorKind::Plate,
            core::SensorKind::Bar => SensorKind::Bar,
            core::SensorKind::Head => SensorKind::Head,
            core::SensorKind::Other => SensorKind::Other,
        }
    }
}

impl From<SensorDecl> for core::SensorDecl {
    fn from(v: SensorDecl) -> Self {
        core::SensorDecl {
            id: v.id,
            kind: v.kind.into(),
        }
    }
}

impl From<core::SensorDecl> for SensorDecl {
    fn from(v: core::SensorDecl) -> Self {
        SensorDecl {
            id: v.id,
            kind: v.kind.into(),
        }
    }
}

impl From<BarDecl> for core::BarDecl {
    fn from(v: BarDecl) -> Self {
        core::BarDecl {
            id: v.id,
            resolution_nm: v.resolution_nm,
            fixed_length_mm: v.fixed_length_mm,
            sensor: v.sensor,
        }
    }
}

impl From<core::BarDecl> for BarDecl {
    fn from(v: core::BarDecl) -> Self {
        BarDecl {
            id: v.id,
            resolution_nm: v.resolution_nm,
            fixed_length_mm: v.fixed_length_mm,
            sensor: v.sensor,
        }
    }
}

impl From<Purpose> for core::Purpose {
    fn from(v: Purpose) -> Self {
        match v {
            Purpose::Calibration => core::Purpose::Calibration,
            Purpose::Reference => core::Purpose::Reference,
            Purpose::Check => core::Purpose::Check,
        }
    }
}

impl From<core::Purpose> for Purpose {
    fn from(v: core::Purpose) -> Self {
        match v {
            core::Purpose::Calibration => Purpose::Calibration,
            core::Purpose::Reference => Purpose::Reference,
            core::Purpose::Check => Purpose::Check,
        }
    }
}

impl From<DeviceKind> for core::DeviceKind {
    fn from(v: DeviceKind) -> Self {
        match v {
            DeviceKind::Hexapod => core::DeviceKind::Hexapod,
        }
    }
}

impl From<core::DeviceKind> for DeviceKind {
    fn from(v: core::DeviceKind) -> Self {
        match v {
            core::DeviceKind::Hexapod => DeviceKind::Hexapod,
        }
    }
}

impl From<PerLeg> for core::PerLeg {
    fn from(v: PerLeg) -> Self {
        match v {
            PerLeg::All(x) => core::PerLeg::All(x),
            PerLeg::Each(x) => core::PerLeg::Each(x),
        }
    }
}

impl From<core::PerLeg> for PerLeg {
    fn from(v: core::PerLeg) -> Self {
        match v {
            core::PerLeg::All(x) => PerLeg::All(x),
            core::PerLeg::Each(x) => PerLeg::Each(x),
        }
    }
}

impl From<DeviceDecl> for core::DeviceDecl {
    fn from(v: DeviceDecl) -> Self {
        core::DeviceDecl {
            id: v.id,
            kind: v.kind.into(),
            base_mm: v.base_mm,
            platform_mm: v.platform_mm,
            u_base_um: v.u_base_um.into(),
            u_platform_um: v.u_platform_um.into(),
            nominal_pose: v.nominal_pose,
            tool_point_mm: v.tool_point_mm,
            base_orientation_deg: v.base_orientation_deg,
            up: v.up,
            reference_mm: v.reference_mm,
            cte_ppm_per_k: v.cte_ppm_per_k,
            sensor: v.sensor,
        }
    }
}

impl From<core::DeviceDecl> for DeviceDecl {
    fn from(v: core::DeviceDecl) -> Self {
        DeviceDecl {
            id: v.id,
            kind: v.kind.into(),
            base_mm: v.base_mm,
            platform_mm: v.platform_mm,
            u_base_um: v.u_base_um.into(),
            u_platform_um: v.u_platform_um.into(),
            nominal_pose: v.nominal_pose,
            tool_point_mm: v.tool_point_mm,
            base_orientation_deg: v.base_orientation_deg,
            up: v.up,
            reference_mm: v.reference_mm,
            cte_ppm_per_k: v.cte_ppm_per_k,
            sensor: v.sensor,
        }
    }
}

// ---- mount times

/// The instant a TOML date-time names, as `core::DeclaredTime` (the text kept for messages): a
/// date-time without offset is UTC; a date or time alone names none.
pub(crate) fn declared_time(dt: &toml::value::Datetime) -> DeclaredTime {
    DeclaredTime {
        text: dt.to_string(),
        ns: toml_datetime_to_ns(dt),
    }
}

/// Nanoseconds since the epoch of a TOML date-time (UTC when it has no offset).
pub(crate) fn toml_datetime_to_ns(dt: &toml::value::Datetime) -> Result<i64, TimeError> {
    let text = || dt.to_string();
    let (Some(d), Some(t)) = (dt.date, dt.time) else {
        return Err(TimeError::NotDateTime(text()));
    };
    let date =
        chrono::NaiveDate::from_ymd_opt(i32::from(d.year), u32::from(d.month), u32::from(d.day))
            .ok_or_else(|| TimeError::NoSuchDate(text()))?;
    // Leap seconds (second = 60) are folded into the next second by chrono's nanosecond field.
    let (second, extra_ns) = if t.second == 60 {
        (59, 1_000_000_000)
    } else {
        (t.second, 0)
    };
    let time = chrono::NaiveTime::from_hms_nano_opt(
        u32::from(t.hour),
        u32::from(t.minute),
        u32::from(second),
        t.nanosecond + extra_ns,
    )
    .ok_or_else(|| TimeError::NoSuchTime(text()))?;
    let local_ns = date
        .and_time(time)
        .and_utc()
        .timestamp_nanos_opt()
        .ok_or_else(|| TimeError::OutOfRange(text()))?;
    let offset_minutes = match dt.offset {
        None | Some(toml::value::Offset::Z) => 0,
        Some(toml::value::Offset::Custom { minutes }) => i64::from(minutes),
    };
    local_ns
        .checked_sub(offset_minutes * 60 * 1_000_000_000)
        .ok_or_else(|| TimeError::OutOfRange(text()))
}

/// Nanoseconds since the epoch as a UTC TOML date-time (`...Z`), the inverse of
/// [`toml_datetime_to_ns`].
pub(crate) fn ns_to_toml_datetime(ns: i64) -> toml::value::Datetime {
    let t = chrono::DateTime::from_timestamp_nanos(ns);
    use chrono::{Datelike, Timelike};
    toml::value::Datetime {
        date: Some(toml::value::Date {
            // Years outside u16 cannot occur: i64 nanoseconds span 1677..2262.
            year: u16::try_from(t.year()).unwrap_or(0),
            month: t.month() as u8,
            day: t.day() as u8,
        }),
        time: Some(toml::value::Time {
            hour: t.hour() as u8,
            minute: t.minute() as u8,
            second: t.second() as u8,
            nanosecond: t.nanosecond(),
        }),
        offset: Some(toml::value::Offset::Z),
    }
}

/// A declared time as TOML writes it: as it was written when that is a TOML date-time (a
/// manifest read and written again keeps its offsets), else its instant in UTC.
fn toml_datetime(t: &DeclaredTime) -> Result<toml::value::Datetime, toml::ser::Error> {
    if let Ok(dt) = t.text.parse() {
        return Ok(dt);
    }
    match t.ns {
        Ok(ns) => Ok(ns_to_toml_datetime(ns)),
        Err(_) => Err(<toml::ser::Error as serde::ser::Error>::custom(format!(
            "{:?} is not a TOML date-time",
            t.text
        ))),
    }
}
