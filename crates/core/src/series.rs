//! Plain, typed time series: what ingest hands to every later stage (no parquet/arrow past this point).
//!
//! [`CampaignLogs`] is the whole campaign as read from disk, per bar and per sensor, sorted by
//! time. [`BarSeries`] (built by `BarSeries::build`) is what the fits use: one bar's readings
//! inside its plate mounts, as thermal error in micrometres up to each mount's zero, with the
//! temperatures seen at the same instants.

use std::collections::BTreeMap;

use crate::campaign::{Bar, Campaign, TimeNs};

mod bins;
mod build;
mod coarse;
pub mod quality;
mod temperatures;
pub(crate) use bins::Region;
pub use bins::MAX_BIN_S;
pub use bins::{
    automatic_bin_s, counts_ok, min_bins_per_tau, reading_time_ok, reading_times_ok,
    too_short_for_bins, BarBins, BinAccumulator, BinError, BinGrid, Readings,
    LONG_BINS_MIN_PER_TAU, MAX_ABS_COUNTS, MIN_BINS_PER_TAU, REREAD_BINS_PER_TAU,
};
pub use quality::Quality;
pub(crate) use temperatures::knot_logs;
pub use temperatures::{campaign_origin_ns, interpolate_temperatures, sensor_knots};

/// One input file the run read, with its hash, for the output's provenance record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputFile {
    /// Path relative to the campaign directory, `/`-separated.
    pub path: String,
    /// SHA-256 of its bytes, hex.
    pub sha256: String,
    /// Its size in bytes.
    pub bytes: u64,
    /// Another input file with the same bytes (same sha256): this one was not read again.
    pub duplicate_of: Option<String>,
}

/// One event row (`events/*.parquet`).
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// Time, ns since the epoch (UTC).
    pub time_ns: TimeNs,
    /// `None`: the whole setup.
    pub bar: Option<String>,
    /// What happened.
    pub kind: EventKind,
    /// The value of a valued kind (`head_power`: 1 on, 0 off; `tilt`: degrees).
    pub value: Option<f64>,
}

/// What an event marks (`docs/spec/campaign-format.md`, events table, `kind`): the spec's four kinds, or
/// any other word, kept and offered to the diagnosis as a channel (`lag:event:WORD`). Ordered
/// by its word, as the events table is sorted.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum EventKind {
    /// Value 1: the read head powered, 0: off. An event marks a change.
    HeadPower,
    /// Value: the plate's tilt, degrees.
    Tilt,
    /// The bar's counter was reset: counts before and after are not comparable.
    Rezero,
    /// Someone touched the bar; value unused.
    Handling,
    /// Any other word.
    Other(String),
}

impl EventKind {
    /// The kind a word of the `kind` column names.
    pub fn parse(word: &str) -> EventKind {
        match word {
            "head_power" => EventKind::HeadPower,
            "tilt" => EventKind::Tilt,
            "rezero" => EventKind::Rezero,
            "handling" => EventKind::Handling,
            other => EventKind::Other(other.to_string()),
        }
    }

    /// The word in the `kind` column; `EventKind::parse(k.as_str()) == k`.
    pub fn as_str(&self) -> &str {
        match self {
            EventKind::HeadPower => "head_power",
            EventKind::Tilt => "tilt",
            EventKind::Rezero => "rezero",
            EventKind::Handling => "handling",
            EventKind::Other(word) => word,
        }
    }
}

impl std::fmt::Display for EventKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

impl PartialOrd for EventKind {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for EventKind {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.as_str().cmp(other.as_str())
    }
}

/// A bar's encoder log, sorted by time, with every sensor's temperature at the same instants
/// once [`interpolate_temperatures`] has run (ingest leaves `celsius` empty).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarLog {
    /// Reading times, ns since the epoch (UTC).
    pub time_ns: Vec<TimeNs>,
    /// Encoder counts at each time.
    pub counts: Vec<i64>,
    /// Sensor id -> temperature (°C) at each `time_ns`.
    pub celsius: BTreeMap<String, Vec<f64>>,
}

/// A sensor's own log, sorted by time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SensorLog {
    /// Reading times, ns since the epoch (UTC).
    pub time_ns: Vec<TimeNs>,
    /// Temperature at each time, °C.
    pub celsius: Vec<f64>,
}

/// Everything a campaign directory holds, validated and sorted.
#[derive(Debug, Clone)]
pub struct CampaignLogs {
    /// The validated manifest.
    pub campaign: Campaign,
    /// Every file read (manifest first), sorted by path.
    pub inputs: Vec<InputFile>,
    /// Bar id -> its log. Every manifest bar has an entry (possibly empty).
    pub bars: BTreeMap<String, BarLog>,
    /// Bar id -> its readings compressed into bins while ingest streamed them
    /// (`io::read_campaign_binned`); such a bar's log in `bars` is empty. Empty otherwise.
    pub bins: BTreeMap<String, BarBins>,
    /// Sensor id -> its log. Every manifest sensor has an entry (possibly empty).
    pub sensors: BTreeMap<String, SensorLog>,
    /// Sorted by time.
    pub events: Vec<Event>,
    /// What ingest dropped, counted and flagged (`summary.json` → `quality`).
    pub quality: Quality,
}

/// A bar's raw encoder readings (what a logger writes), not necessarily sorted.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EncoderLog {
    /// Reading times, ns since the epoch (UTC).
    pub time_ns: Vec<TimeNs>,
    /// Encoder counts at each time.
    pub counts: Vec<i64>,
}

/// The three tables of a campaign as plain columns: what `simulate` produces and
/// `io::write_campaign` writes (see `docs/spec/campaign-format.md`).
#[derive(Debug, Clone, Default)]
pub struct CampaignTables {
    /// Bar id -> readings.
    pub encoders: BTreeMap<String, EncoderLog>,
    /// Sensor id -> readings.
    pub temperatures: BTreeMap<String, SensorLog>,
    /// Event rows.
    pub events: Vec<Event>,
}

/// A mount as the fits see it.
#[derive(Debug, Clone, PartialEq)]
pub struct MountSpan {
    /// Index into `Campaign::mounts`.
    pub(crate) campaign_index: usize,
    /// Plate length id and its calibrated centre distance; `None` on a device.
    pub(crate) length_id: Option<String>,
    pub(crate) length_mm: Option<f64>,
    /// `I_p = D_p - I_min` (`docs/spec/physics.md`): scale travel at this mount, mm (0 on a device).
    pub(crate) i_p_mm: f64,
    pub(crate) tilt_deg: f64,
    pub(crate) purpose: crate::campaign::Purpose,
    pub(crate) device: Option<String>,
    /// Mount start, s since the campaign's time origin.
    pub from_s: f64,
    /// Mount end, s since the campaign's time origin.
    pub to_s: f64,
}

impl MountSpan {
    /// A calibration mount `k` on plate length `L{k}` of `length_mm`, from `from_s` to `to_s`
    /// (tilt 60°): the test fixtures' mount.
    #[cfg(test)]
    pub(crate) fn calibration(
        k: usize,
        length_mm: f64,
        i_min_mm: f64,
        from_s: f64,
        to_s: f64,
    ) -> Self {
        MountSpan {
            campaign_index: k,
            length_id: Some(format!("L{k}")),
            length_mm: Some(length_mm),
            i_p_mm: length_mm - i_min_mm,
            tilt_deg: 60.0,
            purpose: crate::campaign::Purpose::Calibration,
            device: None,
            from_s,
            to_s,
        }
    }

    /// Whether the thermal model is fitted on this mount: a plate length used for calibration
    /// or as a reference (checks are never fitted; devices have no known distance).
    pub(crate) fn is_fitted(&self) -> bool {
        self.length_mm.is_some() && self.purpose != crate::campaign::Purpose::Check
    }
}

/// One bar's data as the fits use it. Every vector is indexed by sample, sorted by time.
#[derive(Debug, Clone)]
pub struct BarSeries {
    /// The bar, as declared.
    pub bar: Bar,
    pub(crate) reference_temperature_c: f64,
    /// Time origin of `t_s`: the campaign's first mount start.
    pub(crate) t0_ns: TimeNs,
    /// Seconds since `t0_ns`; the bar's whole log, handling time included, so that lags carry
    /// the thermal state through the gaps between mounts.
    pub t_s: Vec<f64>,
    /// Indicated reading `k * counts` in micrometres, minus the plate's known expansion
    /// (`docs/spec/campaign-format.md`: true distance grows by `cte * (T_plate - T0)`), minus the median
    /// of its zero segment: the thermal error up to each segment's unknown zero.
    pub y_um: Vec<f64>,
    /// Mount of each sample, `None` for handling time.
    pub(crate) mount_of: Vec<Option<u32>>,
    /// Zero segment of each sample (a mount, split at `rezero` events), `None` outside mounts.
    pub zero_segment: Vec<Option<u32>>,
    pub(crate) n_zero_segments: usize,
    /// What was subtracted from each zero segment (its median, µm): `y_um + offset` is the
    /// indicated reading `k * counts` (minus known plate expansion) that calibration needs.
    pub(crate) segment_offset_um: Vec<f64>,
    /// The bar's mounts, in time order.
    pub mounts: Vec<MountSpan>,
    /// The bar's air temperature: its `sensor`, else the mean of the air sensors.
    pub air_c: Vec<f64>,
    /// Every sensor at the sample times.
    pub celsius: BTreeMap<String, Vec<f64>>,
    /// The campaign's air sensors, and its plate sensor if any.
    pub(crate) air_sensor_ids: Vec<String>,
    /// The campaign's plate sensor, if any.
    pub plate_sensor_id: Option<String>,
    /// Samples used by the thermal fit (inside fitted mounts), ascending.
    pub fit_index: Vec<usize>,
    /// Number of readings each sample stands for: 1 for a logged reading, the node weight for a
    /// compressed bin ([`bins`]), the sum of its parts for a bin mean. Fits are weighted by it.
    pub(crate) weight: Vec<f64>,
    /// Scatter (µm²) of the readings of the fitted compressed bins about each bin's straight
    /// line: the part of a fit's RSS at full rate that the nodes do not carry ([`bins`]); 0 for
    /// a series of logged readings.
    pub(crate) within_bin_rss_um2: f64,
    /// Degrees of freedom of [`BarSeries::within_bin_rss_um2`]: the fitted bins' readings less
    /// the nodes that stand for them (a bin's line takes two, one where its readings share one
    /// time); 0 for a series of logged readings.
    pub(crate) within_bin_dof: f64,
    /// Readings outside every mount of the bar (handling time), dropped from the fits.
    pub dropped_outside_mounts: usize,
    /// The bar's own events and the setup-wide ones, sorted by time, times in seconds.
    pub events: Vec<(f64, Event)>,
}

/// Why a bar's series could not be built.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub(crate) enum SeriesError {
    #[error("bar {bar}: no encoder readings")]
    /// The encoder table has no row of the bar.
    NoReadings {
        /// Bar id.
        bar: String,
    },
    #[error("bar {bar}: no readings inside any plate mount")]
    /// No reading falls inside a plate mount.
    NoMountedReadings {
        /// Bar id.
        bar: String,
    },
    #[error("bar {bar}: no air temperature (sensor {sensor} has no readings)")]
    /// The bar's air sensor has no readings.
    NoAirTemperature {
        /// Bar id.
        bar: String,
        /// The air sensor's id.
        sensor: String,
    },
    #[error("bar {bar}: the campaign declares no air sensor and the bar names none")]
    /// No air sensor to take the bar's air temperature from.
    NoAirSensor {
        /// Bar id.
        bar: String,
    },
    #[error("bar {bar}: {reason}")]
    /// The readings cannot be used (the reason says why).
    Readings {
        /// Bar id.
        bar: String,
        /// What is wrong.
        reason: String,
    },
}

/// What every bar's series is built from, the same for the whole fleet: the manifest, the
/// events, the sensors' logs and their reading times (`knots`: [`sensor_knots`]), and the
/// campaign's time origin.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FleetContext<'a> {
    /// The validated manifest.
    pub(crate) campaign: &'a Campaign,
    /// The campaign's events, sorted by time.
    pub(crate) events: &'a [Event],
    /// Every sensor's log.
    pub(crate) sensors: &'a BTreeMap<String, SensorLog>,
    /// The sensors' reading times ([`sensor_knots`]).
    pub(crate) knots: &'a [TimeNs],
    /// The campaign's time origin: its first mount start.
    pub(crate) t0_ns: TimeNs,
}

impl BarSeries {
    /// Tilt of the bar at sample `i` (`docs/spec/campaign-format.md`): the mount's own `tilt_deg`, else
    /// the latest `tilt` event at or before the sample, else the plate's.
    pub(crate) fn tilt_at_deg(&self, campaign: &Campaign, i: usize) -> f64 {
        let explicit = self.mount_of[i]
            .and_then(|m| campaign.mounts.get(self.mounts[m as usize].campaign_index))
            .filter(|m| m.tilt_explicit)
            .map(|m| m.tilt_deg);
        explicit
            .or_else(|| self.latest_tilt_event(self.t_s[i]))
            .unwrap_or(campaign.plate.tilt_deg)
    }

    fn latest_tilt_event(&self, t_s: f64) -> Option<f64> {
        self.events
            .iter()
            .take_while(|(t, _)| *t <= t_s)
            .filter(|(_, e)| e.kind == EventKind::Tilt)
            .filter_map(|(_, e)| e.value.filter(|v| v.is_finite()))
            .last()
    }

    /// Counter epoch of each sample: the number of `rezero` events at or before it.
    pub(crate) fn counter_epochs(&self) -> Vec<usize> {
        let rezeros: Vec<f64> = self
            .events
            .iter()
            .filter(|(_, e)| e.kind == EventKind::Rezero)
            .map(|(t, _)| *t)
            .collect();
        self.t_s
            .iter()
            .map(|t| rezeros.partition_point(|r| r <= t))
            .collect()
    }

    /// The indicated reading `k n` in µm at sample `i`: the measured value with its zero
    /// segment's offset added back (plate expansion removed).
    pub(crate) fn reading_um(&self, i: usize) -> f64 {
        self.y_um[i] + self.zero_segment[i].map_or(0.0, |s| self.segment_offset_um[s as usize])
    }

    /// The series without its samples (every per-sample vector emptied): the bar, its mounts,
    /// zero-segment offsets and `dropped_outside_mounts` stay. For runs that need nothing of a
    /// bar but its fitted model once it is identified.
    pub(crate) fn without_samples(self) -> BarSeries {
        BarSeries {
            t_s: Vec::new(),
            y_um: Vec::new(),
            mount_of: Vec::new(),
            zero_segment: Vec::new(),
            air_c: Vec::new(),
            celsius: BTreeMap::new(),
            fit_index: Vec::new(),
            weight: Vec::new(),
            ..self
        }
    }

    /// Number of readings the fitted samples stand for.
    pub(crate) fn fitted_readings(&self) -> usize {
        self.fit_index
            .iter()
            .map(|&i| self.weight[i])
            .sum::<f64>()
            .round() as usize
    }

    /// A residual at the fitted samples (µm) weighed by the square root of each sample's weight:
    /// under white noise every value then has the variance of one reading, which is what a
    /// noise model of the residual needs when the samples are compressed bins.
    pub(crate) fn weighted_residuals(&self, residuals_um: &[f64]) -> Vec<f64> {
        residuals_um
            .iter()
            .zip(&self.fit_index)
            .map(|(r, &i)| r * self.weight[i].sqrt())
            .collect()
    }

    /// `I_p` of each sample (0 outside mounts).
    pub(crate) fn i_p_mm(&self) -> Vec<f64> {
        self.mount_of
            .iter()
            .map(|m| m.map_or(0.0, |m| self.mounts[m as usize].i_p_mm))
            .collect()
    }
}

#[cfg(test)]
pub(crate) mod tests;
