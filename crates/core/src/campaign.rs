//! The campaign manifest (`campaign.toml`, see `docs/spec/campaign-format.md`) and its
//! validated form.
//!
//! [`Manifest`] is the manifest as declared, one field a key, as plain data (the TOML text is
//! `dbbcal_io::manifest`'s: it parses it into a `Manifest` and writes one out for `simulate`);
//! [`Campaign`] is the validated, resolved form every later stage uses: mounts point at their
//! plate length, times are integer nanoseconds since the Unix epoch (UTC), tilts are filled in
//! from the plate. Validation lives in [`Campaign::from_manifest`]; every error names the key
//! that is wrong.

pub mod device;
pub use device::{Device, DeviceDecl, DeviceKind, PerLeg};

/// Nanoseconds since 1970-01-01T00:00:00Z.
pub(crate) type TimeNs = i64;

// ---------------------------------------------------------------- manifest, as declared

/// `campaign.toml` as declared (`docs/spec/campaign-format.md`), not yet validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Manifest {
    /// `[campaign]`.
    pub campaign: CampaignSection,
    /// `[plate]`.
    pub plate: PlateSection,
    /// `[[sensor]]`: the temperature sensors.
    pub sensor: Vec<SensorDecl>,
    /// `[[bar]]`: the ballbars.
    pub bar: Vec<BarDecl>,
    /// `[[mount]]`: where each bar sat, and when.
    pub mount: Vec<MountDecl>,
    /// `[[device]]`: measuring devices whose legs are working bars (`docs/spec/device-format.md`).
    pub device: Vec<DeviceDecl>,
}

/// `[campaign]`: id and reference temperature.
#[derive(Debug, Clone, PartialEq)]
pub struct CampaignSection {
    /// Campaign id (names the default output folder `reports/<id>`).
    pub id: String,
    /// Reference temperature T0, °C.
    pub reference_temperature_c: f64,
}

/// `[plate]`: the calibration plate.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateSection {
    /// Plate material (free text).
    pub material: String,
    /// Declared expansion coefficient of the plate, ppm/K; 0 when absent.
    pub cte_ppm_per_k: f64,
    /// Plate tilt from horizontal, degrees; 0 when absent.
    pub tilt_deg: f64,
    /// `[[plate.length]]`: the calibrated socket-pair distances.
    pub length: Vec<PlateLength>,
}

/// One calibrated socket-pair distance on the plate.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateLength {
    /// Length id (what `mount[].length` names).
    pub id: String,
    /// Calibrated centre distance, mm.
    pub mm: f64,
    /// Standard uncertainty (k = 1) of the calibrated length, micrometres.
    pub u_um: f64,
}

/// What a temperature sensor measures (`sensor[].kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
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
#[derive(Debug, Clone, PartialEq)]
pub struct SensorDecl {
    /// Sensor id (the `sensor` column of `temperatures/*.parquet`).
    pub id: String,
    /// What it measures.
    pub kind: SensorKind,
}

/// `[[bar]]`: one ballbar.
#[derive(Debug, Clone, PartialEq)]
pub struct BarDecl {
    /// Bar id (the `bar` column of `encoders/*.parquet`).
    pub id: String,
    /// Encoder resolution, nm a count.
    pub resolution_nm: f64,
    /// `I_min` of `docs/spec/physics.md`: the part of the centre distance that is not scale travel, mm.
    pub fixed_length_mm: f64,
    /// The air sensor nearest the bar; absent: the mean of all air sensors.
    pub sensor: Option<String>,
}

/// What a mount is for (`mount[].purpose`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
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
#[derive(Debug, Clone, PartialEq)]
pub struct MountDecl {
    /// Bar id.
    pub bar: String,
    /// Plate length id (on the plate); absent on a device.
    pub length: Option<String>,
    /// Device name (on a target device, true distance unknown); absent on the plate.
    pub device: Option<String>,
    /// The leg (1–6) of a declared hexapod the bar sits in; only on such a device.
    pub leg: Option<u8>,
    /// Tilt of the bar from horizontal, degrees; absent: the plate's.
    pub tilt_deg: Option<f64>,
    /// What the mount is for; absent: calibration.
    pub purpose: Option<Purpose>,
    /// Start of the mount (UTC).
    pub from: DeclaredTime,
    /// End of the mount (UTC).
    pub to: DeclaredTime,
}

/// A mount's start or end as `campaign.toml` gives it: the date-time as written (quoted in
/// messages) and the instant it names, or why it names none (a date alone, no such day).
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredTime {
    /// As written, e.g. `2026-11-01T00:00:00Z` or `2026-11-04T01:00:00+01:00`.
    pub text: String,
    /// Nanoseconds since the epoch (UTC); a date-time without offset is UTC.
    pub ns: Result<TimeNs, TimeError>,
}

impl DeclaredTime {
    /// The instant `ns` (since the epoch, UTC), written as RFC 3339 with `Z`, seconds always,
    /// a fraction only when there is one (`2026-11-01T00:00:00Z`, `…T00:00:00.25Z`).
    pub fn at(ns: TimeNs) -> DeclaredTime {
        use chrono::Timelike;
        let t = chrono::DateTime::from_timestamp_nanos(ns);
        let mut text = t.format("%Y-%m-%dT%H:%M:%S").to_string();
        if t.nanosecond() != 0 {
            let fraction = format!("{:09}", t.nanosecond());
            text.push('.');
            text.push_str(fraction.trim_end_matches('0'));
        }
        text.push('Z');
        DeclaredTime { text, ns: Ok(ns) }
    }
}

impl std::fmt::Display for DeclaredTime {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(&self.text)
    }
}

/// Why a declared date-time names no instant (each message quotes it as written).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TimeError {
    /// A date or a time of day alone.
    #[error("{0} is not a date-time (need e.g. 2026-11-01T00:00:00Z)")]
    NotDateTime(String),
    /// A date the calendar does not have.
    #[error("{0}: no such date")]
    NoSuchDate(String),
    /// A time of day the clock does not have.
    #[error("{0}: no such time of day")]
    NoSuchTime(String),
    /// Beyond what nanoseconds since the epoch in an `i64` hold.
    #[error("{0} is outside 1677..2262 (nanosecond range)")]
    OutOfRange(String),
}

// ---------------------------------------------------------------- validated campaign

/// A validated campaign: every reference in the manifest checked, times in ns.
#[derive(Debug, Clone, PartialEq)]
pub struct Campaign {
    /// The campaign's id (names the default output folder).
    pub id: String,
    /// The temperature the bars' lengths refer to, °C.
    pub reference_temperature_c: f64,
    /// The calibration plate.
    pub plate: Plate,
    /// The temperature sensors, in manifest order.
    pub sensors: Vec<Sensor>,
    /// The bars, in manifest order.
    pub bars: Vec<Bar>,
    /// Sorted by (bar, from_ns).
    pub mounts: Vec<Mount>,
    /// The `[[device]]` tables, validated, in manifest order.
    pub devices: Vec<Device>,
}

#[derive(Debug, Clone, PartialEq)]
/// The calibration plate: its material and its calibrated lengths.
pub struct Plate {
    /// Its material (free text).
    pub material: String,
    /// Its declared expansion coefficient, ppm/K.
    pub cte_ppm_per_k: f64,
    /// Its tilt from horizontal, degrees.
    pub tilt_deg: f64,
    /// The socket pairs of calibrated centre distance.
    pub lengths: Vec<PlateLength>,
}

#[derive(Debug, Clone, PartialEq)]
/// A declared temperature sensor.
pub struct Sensor {
    /// Its id, as in the temperature table.
    pub id: String,
    /// What it measures: the air or the plate.
    pub kind: SensorKind,
}

/// A declared bar, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    /// Its id, as in the encoder table.
    pub id: String,
    /// One encoder count, nm.
    pub resolution_nm: f64,
    /// `I_min` of `docs/spec/physics.md`: the part of the centre distance that is not scale travel.
    pub fixed_length_mm: f64,
    /// The air sensor nearest the bar; `None` = mean of all air sensors.
    pub sensor: Option<String>,
}

/// Where a bar sat during a mount.
#[derive(Debug, Clone, PartialEq)]
pub enum Place {
    /// On a plate socket pair of known centre distance.
    Length(PlateLength),
    /// On a target device: true distance unknown.
    Device(String),
}

/// A validated mount.
#[derive(Debug, Clone, PartialEq)]
pub struct Mount {
    /// Bar id.
    pub bar: String,
    /// Where the bar sat: a plate length or a device.
    pub place: Place,
    /// Tilt from horizontal, degrees: the mount's, else the plate's.
    pub tilt_deg: f64,
    /// Whether the mount gave its own `tilt_deg` (it then wins over `tilt` events, see
    /// `BarSeries::tilt_at_deg`).
    pub(crate) tilt_explicit: bool,
    /// What the mount is for.
    pub purpose: Purpose,
    /// The leg of a declared device the bar sits in (1–6), if any.
    pub leg: Option<u8>,
    /// Start, ns since the epoch (UTC).
    pub from_ns: TimeNs,
    /// End, ns since the epoch (UTC).
    pub to_ns: TimeNs,
}

impl Campaign {
    /// The bar `id`, if declared.
    pub fn bar(&self, id: &str) -> Option<&Bar> {
        self.bars.iter().find(|b| b.id == id)
    }
    /// The sensor `id`, if declared.
    pub fn sensor(&self, id: &str) -> Option<&Sensor> {
        self.sensors.iter().find(|s| s.id == id)
    }
    /// The mounts of bar `bar`, in the campaign's order.
    pub fn mounts_of<'a>(&'a self, bar: &'a str) -> impl Iterator<Item = &'a Mount> + 'a {
        self.mounts.iter().filter(move |m| m.bar == bar)
    }
    /// The air sensors, in manifest order.
    pub(crate) fn air_sensors(&self) -> impl Iterator<Item = &Sensor> {
        self.sensors.iter().filter(|s| s.kind == SensorKind::Air)
    }
}

// ---------------------------------------------------------------- validation

/// A manifest that cannot be used. Every message is one line naming the file and the key.
///
/// Array indices in keys (`mount[3]`) count from 0 in file order, as in a TOML path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CampaignError {
    /// The text is not TOML, or does not have the manifest's shape (unknown or missing key).
    #[error("{file}:{line}:{column}: {message}")]
    Syntax {
        /// The manifest's file name.
        file: String,
        /// Line of the error (0 when unknown).
        line: usize,
        /// Column of the error (0 when unknown).
        column: usize,
        /// The TOML parser's message.
        message: String,
    },
    /// Two entries of one table share an id.
    #[error("{file}: {table}[{second}]: id {id:?} is already used by {table}[{first}]")]
    DuplicateId {
        /// The manifest's file name.
        file: String,
        /// The table (e.g. `bar`).
        table: &'static str,
        /// The repeated id.
        id: String,
        /// Index of the entry that has it first.
        first: usize,
        /// Index of the repeat.
        second: usize,
    },
    /// A reference to something the manifest does not declare.
    #[error("{file}: {key}: {field} {value:?} is not {what} (known: {known})")]
    Unknown {
        /// The manifest's file name.
        file: String,
        /// The key holding the reference (e.g. `mount[3]`).
        key: String,
        /// The field that names it (e.g. `bar`).
        field: &'static str,
        /// The name given.
        value: String,
        /// What it should name (e.g. `a declared bar`).
        what: &'static str,
        /// The names that are declared, comma-separated (`Box<str>`, not `String`: keeps the
        /// error, and every `Result` carrying it, under 128 bytes).
        known: Box<str>,
    },
    /// Any other invalid value.
    #[error("{file}: {key}: {problem}")]
    Invalid {
        /// The manifest's file name.
        file: String,
        /// The key with the invalid value.
        key: String,
        /// What is wrong with it.
        problem: String,
    },
}

/// The allowed ranges of the manifest's numbers (both ends included; NaN and infinities are
/// outside every range). Generous: they refuse what no real campaign holds (a typo, a unit
/// mix-up, TOML's `nan`/`inf`), not unusual set-ups.
pub mod limits {
    /// `campaign.id`: at most this many characters of `[A-Za-z0-9._-]`, no leading dot (it names
    /// the default output folder `reports/<id>`).
    pub const ID_MAX_CHARS: usize = 100;
    use crate::limits::Limit;
    /// `campaign.reference_temperature_c`.
    pub const REFERENCE_TEMPERATURE_C: Limit = Limit::closed(-100.0, 200.0, "°C");
    /// `plate.cte_ppm_per_k` (Zerodur ~0, steel ~12, aluminium ~23).
    pub const CTE_PPM_PER_K: Limit = Limit::closed(-100.0, 100.0, "ppm/K");
    /// `plate.tilt_deg`, `mount[].tilt_deg`: from horizontal.
    pub const TILT_DEG: Limit = Limit::closed(-90.0, 90.0, "degrees");
    /// `plate.length[].mm`, `bar[].fixed_length_mm`: above 0, at most 10 m.
    pub const LENGTH_MM: Limit = Limit::above(0.0, 10_000.0, "mm");
    /// `plate.length[].u_um`: 0 to 1 mm.
    pub const U_UM: Limit = Limit::closed(0.0, 1_000.0, "µm");
    /// `bar[].resolution_nm`: above 0, at most 1 mm a count.
    pub const RESOLUTION_NM: Limit = Limit::above(0.0, 1e6, "nm");
    /// `mount[].from`, `mount[].to`: from 1970-01-01T00:00:00Z (included) to
    /// 2200-01-01T00:00:00Z (excluded), ns since the epoch.
    pub const MOUNT_TIME_NS: (i64, i64) = (0, 7_258_118_400 * 1_000_000_000);
}

pub use crate::limits::display_number;

/// The manifest's number limits as a table (`| key | allowed |`), made from the constants the
/// validation uses; `docs/guarantees.md` ("Configuration and fits") holds it word for word.
pub fn limits_table() -> String {
    use limits::*;
    let rows = [
        (
            "`campaign.reference_temperature_c`",
            REFERENCE_TEMPERATURE_C,
        ),
        ("`plate.cte_ppm_per_k`", CTE_PPM_PER_K),
        ("`plate.tilt_deg`, `mount[].tilt_deg`", TILT_DEG),
        ("`plate.length[].mm`, `bar[].fixed_length_mm`", LENGTH_MM),
        ("`plate.length[].u_um`", U_UM),
        ("`bar[].resolution_nm`", RESOLUTION_NM),
    ];
    let mut table = String::from("| key | allowed |\n|---|---|\n");
    for (key, limit) in rows {
        table.push_str(&format!("| {key} | {} |\n", limit.describe()));
    }
    table
}
use crate::limits::Limit;

/// The file name used in messages when the caller does not give one.
const MANIFEST_FILE: &str = "campaign.toml";

impl Campaign {
    /// Validates and resolves a manifest; messages name the file `campaign.toml`.
    pub fn from_manifest(manifest: Manifest) -> Result<Campaign, CampaignError> {
        Self::from_manifest_at(manifest, MANIFEST_FILE)
    }

    /// As [`Campaign::from_manifest`], naming `file` in messages.
    pub fn from_manifest_at(manifest: Manifest, file: &str) -> Result<Campaign, CampaignError> {
        let v = Validator { file };
        v.campaign_section(&manifest.campaign)?;
        v.plate(&manifest.plate)?;
        v.sensors(&manifest.sensor)?;
        v.bars(&manifest.bar, &manifest.sensor)?;
        let devices = v.devices(&manifest)?;
        let mounts = v.mounts(&manifest)?;
        Ok(Campaign {
            id: manifest.campaign.id,
            reference_temperature_c: manifest.campaign.reference_temperature_c,
            plate: Plate {
                material: manifest.plate.material,
                cte_ppm_per_k: manifest.plate.cte_ppm_per_k,
                tilt_deg: manifest.plate.tilt_deg,
                lengths: manifest.plate.length,
            },
            sensors: manifest
                .sensor
                .into_iter()
                .map(|s| Sensor {
                    id: s.id,
                    kind: s.kind,
                })
                .collect(),
            bars: manifest
                .bar
                .into_iter()
                .map(|b| Bar {
                    id: b.id,
                    resolution_nm: b.resolution_nm,
                    fixed_length_mm: b.fixed_length_mm,
                    sensor: b.sensor,
                })
                .collect(),
            mounts,
            devices,
        })
    }
}

/// `campaign.id` names the default output folder (`reports/<id>`): non-empty, at most
/// [`limits::ID_MAX_CHARS`] characters of `[A-Za-z0-9._-]`, not starting with a dot (no hidden
/// folder, no `..`, no path separator).
pub fn check_campaign_id(id: &str) -> Result<(), IdError> {
    if id.is_empty() {
        return Err(IdError::Empty);
    }
    let chars = id.chars().count();
    if chars > limits::ID_MAX_CHARS {
        return Err(IdError::TooLong { chars });
    }
    if let Some(c) = id
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-')))
    {
        return Err(IdError::Character {
            id: id.to_string(),
            character: c,
        });
    }
    if id.starts_with('.') {
        return Err(IdError::LeadingDot { id: id.to_string() });
    }
    Ok(())
}

/// Why a campaign id cannot name the output folder `reports/<id>`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IdError {
    /// No characters.
    #[error("is empty")]
    Empty,
    /// More than [`limits::ID_MAX_CHARS`] characters.
    #[error(
        "is {chars} characters long; at most {} are allowed",
        limits::ID_MAX_CHARS
    )]
    TooLong {
        /// Its length in characters.
        chars: usize,
    },
    /// A character outside `[A-Za-z0-9._-]`.
    #[error("{id:?} contains {character:?}: only letters A-Z a-z, digits, '.', '_' and '-' are allowed (it names the output folder reports/<id>)")]
    Character {
        /// The id.
        id: String,
        /// The first character not allowed.
        character: char,
    },
    /// A leading dot (a hidden folder, `..`).
    #[error("{id:?} starts with a dot (it names the output folder reports/<id>)")]
    LeadingDot {
        /// The id.
        id: String,
    },
}

/// Checks of one manifest; holds the file name for messages.
struct Validator<'a> {
    file: &'a str,
}

impl Validator<'_> {
    fn invalid(&self, key: impl Into<String>, problem: impl Into<String>) -> CampaignError {
        CampaignError::Invalid {
            file: self.file.to_string(),
            key: key.into(),
            problem: problem.into(),
        }
    }

    fn unknown(
        &self,
        key: String,
        field: &'static str,
        value: &str,
        what: &'static str,
        known: &[&str],
    ) -> CampaignError {
        CampaignError::Unknown {
            file: self.file.to_string(),
            key,
            field,
            value: value.to_string(),
            what,
            known: if known.is_empty() {
                "none".into()
            } else {
                known
                    .iter()
                    .map(|k| k.escape_debug().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
                    .into()
            },
        }
    }

    /// `value` within `limit` ([`crate::limits`]), or the message naming `key` and `name`.
    fn in_range(
        &self,
        key: &str,
        name: &str,
        value: f64,
        limit: Limit,
    ) -> Result<(), CampaignError> {
        limit
            .check(name, value)
            .map_err(|e| self.invalid(key, e.to_string()))
    }

    fn unique_ids<'i>(
        &self,
        table: &'static str,
        ids: impl Iterator<Item = &'i str>,
    ) -> Result<(), CampaignError> {
        let mut seen: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
        for (i, id) in ids.enumerate() {
            if id.trim().is_empty() {
                return Err(self.invalid(format!("{table}[{i}]"), "id is empty"));
            }
            if id.chars().any(char::is_control) {
                return Err(self.invalid(
                    format!("{table}[{i}]"),
                    format!("id {id:?} contains a control character"),
                ));
            }
            if let Some(&first) = seen.get(id) {
                return Err(CampaignError::DuplicateId {
                    file: self.file.to_string(),
                    table,
                    id: id.to_string(),
                    first,
                    second: i,
                });
            }
            seen.insert(id, i);
        }
        Ok(())
    }

    fn campaign_section(&self, c: &CampaignSection) -> Result<(), CampaignError> {
        if c.id.trim().is_empty() {
            return Err(self.invalid("campaign.id", "is empty"));
        }
        check_campaign_id(&c.id)
            .map_err(|problem| self.invalid("campaign.id", problem.to_string()))?;
        self.in_range(
            "campaign",
            "reference_temperature_c",
            c.reference_temperature_c,
            limits::REFERENCE_TEMPERATURE_C,
        )
    }

    fn plate(&self, p: &PlateSection) -> Result<(), CampaignError> {
        self.in_range(
            "plate",
            "cte_ppm_per_k",
            p.cte_ppm_per_k,
            limits::CTE_PPM_PER_K,
        )?;
        self.in_range("plate", "tilt_deg", p.tilt_deg, limits::TILT_DEG)?;
        self.unique_ids("plate.length", p.length.iter().map(|l| l.id.as_str()))?;
        for (i, l) in p.length.iter().enumerate() {
            let key = format!("plate.length[{i}] ({:?})", l.id);
            self.in_range(&key, "mm", l.mm, limits::LENGTH_MM)?;
            self.in_range(&key, "u_um", l.u_um, limits::U_UM)?;
        }
        Ok(())
    }

    fn sensors(&self, sensors: &[SensorDecl]) -> Result<(), CampaignError> {
        self.unique_ids("sensor", sensors.iter().map(|s| s.id.as_str()))
    }

    fn bars(&self, bars: &[BarDecl], sensors: &[SensorDecl]) -> Result<(), CampaignError> {
        self.unique_ids("bar", bars.iter().map(|b| b.id.as_str()))?;
        let sensor_ids: Vec<&str> = sensors.iter().map(|s| s.id.as_str()).collect();
        for (i, b) in bars.iter().enumerate() {
            let key = format!("bar[{i}] ({:?})", b.id);
            self.in_range(
                &key,
                "resolution_nm",
                b.resolution_nm,
                limits::RESOLUTION_NM,
            )?;
            self.in_range(
                &key,
                "fixed_length_mm",
                b.fixed_length_mm,
                limits::LENGTH_MM,
            )?;
            if let Some(s) = &b.sensor {
                if !sensor_ids.contains(&s.as_str()) {
                    return Err(self.unknown(key, "sensor", s, "a declared sensor", &sensor_ids));
                }
            }
        }
        Ok(())
    }

    /// Resolves every mount, then sorts them by (bar, from) and checks for overlaps.
    fn mounts(&self, m: &Manifest) -> Result<Vec<Mount>, CampaignError> {
        let mut resolved: Vec<(usize, Mount)> = Vec::with_capacity(m.mount.len());
        for (i, decl) in m.mount.iter().enumerate() {
            resolved.push((i, self.mount(i, decl, m)?));
        }
        resolved.sort_by(|(ia, a), (ib, b)| {
            (a.bar.as_str(), a.from_ns, *ia).cmp(&(b.bar.as_str(), b.from_ns, *ib))
        });
        for pair in resolved.windows(2) {
            let ((ia, a), (ib, b)) = (&pair[0], &pair[1]);
            if a.bar == b.bar && b.from_ns < a.to_ns {
                return Err(self.invalid(
                    format!("mount[{ib}] (bar {:?})", b.bar),
                    format!(
                        "interval {} .. {} overlaps mount[{ia}] ({} .. {})",
                        m.mount[*ib].from, m.mount[*ib].to, m.mount[*ia].from, m.mount[*ia].to
                    ),
                ));
            }
        }
        self.legs_hold_one_bar(&resolved, m)?;
        Ok(resolved.into_iter().map(|(_, mount)| mount).collect())
    }

    fn mount(&self, i: usize, d: &MountDecl, m: &Manifest) -> Result<Mount, CampaignError> {
        let key = format!("mount[{i}] (bar {:?})", d.bar);
        let bar_ids: Vec<&str> = m.bar.iter().map(|b| b.id.as_str()).collect();
        let Some(bar) = m.bar.iter().find(|b| b.id == d.bar) else {
            return Err(self.unknown(
                format!("mount[{i}]"),
                "bar",
                &d.bar,
                "a declared bar",
                &bar_ids,
            ));
        };
        let place = self.place(&key, d, bar, &m.plate)?;
        let leg = self.leg(&key, d.leg, d.device.as_deref(), m)?;
        let tilt_deg = d.tilt_deg.unwrap_or(m.plate.tilt_deg);
        self.in_range(&key, "tilt_deg", tilt_deg, limits::TILT_DEG)?;
        let time = |name: &str, dt: &DeclaredTime| {
            let ns = dt
                .ns
                .clone()
                .map_err(|e| self.invalid(key.clone(), format!("{name}: {e}")))?;
            let (lo, hi) = limits::MOUNT_TIME_NS;
            if !(lo..hi).contains(&ns) {
                return Err(self.invalid(
                    key.clone(),
                    format!(
                        "{name} = {dt} is outside 1970-01-01T00:00:00Z .. 2200-01-01T00:00:00Z"
                    ),
                ));
            }
            Ok(ns)
        };
        let from_ns = time("from", &d.from)?;
        let to_ns = time("to", &d.to)?;
        if from_ns >= to_ns {
            return Err(self.invalid(
                key,
                format!("from = {} is not before to = {}", d.from, d.to),
            ));
        }
        Ok(Mount {
            bar: d.bar.clone(),
            place,
            tilt_deg,
            tilt_explicit: d.tilt_deg.is_some(),
            purpose: d.purpose.unwrap_or_default(),
            leg,
            from_ns,
            to_ns,
        })
    }

    /// Exactly one of `length` / `device`; a length must exist and exceed the bar's fixed length.
    fn place(
        &self,
        key: &str,
        d: &MountDecl,
        bar: &BarDecl,
        plate: &PlateSection,
    ) -> Result<Place, CampaignError> {
        match (&d.length, &d.device) {
            (Some(_), Some(_)) => {
                Err(self.invalid(key, "gives both length and device (exactly one is allowed)"))
            }
            (None, None) => Err(self.invalid(
                key,
                "gives neither length nor device (exactly one is needed)",
            )),
            (None, Some(device)) if device.trim().is_empty() => {
                Err(self.invalid(key, "device is empty"))
            }
            (None, Some(device)) => Ok(Place::Device(device.clone())),
            (Some(length), None) => {
                let Some(l) = plate.length.iter().find(|l| &l.id == length) else {
                    let known: Vec<&str> = plate.length.iter().map(|l| l.id.as_str()).collect();
                    return Err(self.unknown(
                        key.to_string(),
                        "length",
                        length,
                        "a plate length",
                        &known,
                    ));
                };
                if bar.fixed_length_mm > l.mm {
                    return Err(self.invalid(
                        key,
                        format!(
                            "bar fixed_length_mm = {} exceeds plate length \"{}\" = {} mm (scale travel would be negative)",
                            bar.fixed_length_mm, l.id, l.mm
                        ),
                    ));
                }
                Ok(Place::Length(l.clone()))
            }
        }
    }
}
