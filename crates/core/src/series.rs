//! Plain, typed time series: what ingest hands to every later stage (no polars past this point).
//!
//! [`CampaignLogs`] is the whole campaign as read from disk, per bar and per sensor, sorted by
//! time. [`BarSeries`] (built by `BarSeries::build`) is what the fits use: one bar's readings
//! inside its plate mounts, as thermal error in micrometres up to each mount's zero, with the
//! temperatures seen at the same instants.

use std::collections::BTreeMap;

use crate::campaign::{Bar, Campaign, TimeNs};
use crate::signal::interpolate;

mod bins;
pub mod quality;
pub use bins::MAX_BIN_S;
pub use bins::{
    automatic_bin_s, counts_ok, reading_time_ok, reading_times_ok, BarBins, BinAccumulator,
    BinError, BinGrid, BinKey, BinMoments, Node, Readings, Region, AUTOMATIC_BIN_S,
    AUTOMATIC_MAX_INTERVAL_S, EARLIEST_READING_NS, LATEST_READING_NS, MAX_ABS_COUNTS,
    MAX_BAR_READINGS, MIN_BINS_PER_TAU,
};
pub use quality::Quality;

/// One input file the run read, with its hash, for the output's provenance record.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct InputFile {
    /// Path relative to the campaign directory, `/`-separated.
    pub path: String,
    /// SHA-256 of its bytes, hex.
    pub sha256: String,
    /// Its size in bytes.
    pub bytes: u64,
    /// Another input file with the same bytes (same sha256): this one was not read again.
    #[serde(skip_serializing_if = "Option::is_none")]
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
pub enum SeriesError {
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
pub struct FleetContext<'a> {
    /// The validated manifest.
    pub campaign: &'a Campaign,
    /// The campaign's events, sorted by time.
    pub events: &'a [Event],
    /// Every sensor's log.
    pub sensors: &'a BTreeMap<String, SensorLog>,
    /// The sensors' reading times ([`sensor_knots`]).
    pub knots: &'a [TimeNs],
    /// The campaign's time origin: its first mount start.
    pub t0_ns: TimeNs,
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

    /// Build bar `bar_id`'s series from its log, every reading a sample (taken by value: the
    /// series owns the data, so a large campaign is never held twice), with the temperatures
    /// the log carries ([`interpolate_temperatures`]) and the campaign's events.
    #[cfg(test)]
    pub(crate) fn build(
        campaign: &Campaign,
        events: &[Event],
        bar_id: &str,
        log: BarLog,
        t0_ns: TimeNs,
    ) -> Result<BarSeries, SeriesError> {
        let BarLog {
            time_ns,
            counts,
            celsius,
        } = log;
        let n = time_ns.len();
        let readings = Readings {
            time_ns,
            counts: counts.into_iter().map(|c| c as f64).collect(),
            weight: vec![1.0; n],
            line_rss_counts2: vec![0.0; n],
        };
        Self::from_readings(campaign, events, bar_id, readings, celsius, t0_ns)
    }

    /// Bar `bar_id`'s series from its log compressed into bins of `bin_s` seconds (`bins`:
    /// two weighted nodes a bin, exact for a model that is a straight line within each bin);
    /// `bin_s <= 0`: every reading, as `BarSeries::build`. Temperatures are interpolated from
    /// `sensors` at the samples' times here (`knots`: [`sensor_knots`] of `sensors`, used with
    /// bins). The full-rate log lives only inside this call.
    pub fn build_binned(
        fleet: &FleetContext<'_>,
        bar_id: &str,
        mut log: BarLog,
        bin_s: f64,
    ) -> Result<BarSeries, SeriesError> {
        let FleetContext {
            campaign,
            events,
            sensors,
            knots,
            t0_ns,
        } = *fleet;
        if bin_s.is_nan() || bin_s <= 0.0 {
            let n = log.time_ns.len();
            let readings = with_knots_between(
                Readings {
                    time_ns: std::mem::take(&mut log.time_ns),
                    counts: log.counts.iter().map(|&c| c as f64).collect(),
                    weight: vec![1.0; n],
                    line_rss_counts2: vec![0.0; n],
                },
                knots,
            );
            drop(log);
            let celsius = temperatures_at(&readings.time_ns, sensors);
            return Self::from_readings(campaign, events, bar_id, readings, celsius, t0_ns);
        }
        let grid = BinGrid::new(campaign, events, bar_id, bin_s);
        let bins = BarBins::from_log(grid, &log.time_ns, &log.counts).map_err(|e| {
            SeriesError::Readings {
                bar: bar_id.to_string(),
                reason: e.to_string(),
            }
        })?;
        drop(log);
        Self::from_bins(fleet, bar_id, &bins)
    }

    /// Bar `bar_id`'s series from its compressed bins (ingest can make them while it streams the
    /// encoder files), temperatures interpolated from `sensors` at the nodes' times. `knots`:
    /// [`sensor_knots`] of `sensors`.
    pub fn from_bins(
        fleet: &FleetContext<'_>,
        bar_id: &str,
        bins: &BarBins,
    ) -> Result<BarSeries, SeriesError> {
        let readings = with_knots_between(bins.readings(fleet.knots), fleet.knots);
        let celsius = temperatures_at(&readings.time_ns, fleet.sensors);
        Self::from_readings(
            fleet.campaign,
            fleet.events,
            bar_id,
            readings,
            celsius,
            fleet.t0_ns,
        )
    }

    /// The series of weighted readings with every sensor's temperature at their times.
    fn from_readings(
        campaign: &Campaign,
        events: &[Event],
        bar_id: &str,
        readings: Readings,
        celsius: BTreeMap<String, Vec<f64>>,
        t0_ns: TimeNs,
    ) -> Result<BarSeries, SeriesError> {
        let bar = campaign
            .bar(bar_id)
            .cloned()
            .ok_or_else(|| SeriesError::NoReadings {
                bar: bar_id.to_string(),
            })?;
        if readings.time_ns.is_empty() {
            return Err(SeriesError::NoReadings {
                bar: bar_id.to_string(),
            });
        }
        let to_s = |ns: TimeNs| (ns - t0_ns) as f64 * 1e-9;
        let t_s: Vec<f64> = readings.time_ns.iter().map(|&t| to_s(t)).collect();
        let mounts = mount_spans(campaign, &bar, &to_s);
        let mount_of = assign_mounts(&t_s, &mounts);
        let dropped_outside_mounts = mount_of
            .iter()
            .zip(&readings.weight)
            .filter(|(m, _)| m.is_none())
            .map(|(_, w)| w)
            .sum::<f64>()
            .round() as usize;
        let events: Vec<(f64, Event)> = events
            .iter()
            .filter(|e| e.bar.as_deref().is_none_or(|b| b == bar_id))
            .map(|e| (to_s(e.time_ns), e.clone()))
            .collect();
        let (zero_segment, n_zero_segments) = zero_segments(&t_s, &mount_of, &events);
        let air_c = air_temperature(campaign, &bar, &celsius, t_s.len())?;
        let um_per_count = bar.resolution_nm * 1e-3;
        let mut y_um: Vec<f64> = readings.counts.iter().map(|&c| c * um_per_count).collect();
        subtract_plate_expansion(campaign, &celsius, &t_s, &mount_of, &mounts, &mut y_um);
        let segment_offset_um = centre_segments(&mut y_um, &zero_segment, n_zero_segments);
        let fit_index: Vec<usize> = (0..t_s.len())
            .filter(|&i| {
                readings.weight[i] > 0.0
                    && mount_of[i].is_some_and(|m| mounts[m as usize].is_fitted())
            })
            .collect();
        if fit_index.is_empty() {
            return Err(SeriesError::NoMountedReadings {
                bar: bar_id.to_string(),
            });
        }
        let within_bin_rss_um2 = fit_index
            .iter()
            .map(|&i| readings.line_rss_counts2[i])
            .sum::<f64>()
            * um_per_count
            * um_per_count;
        // A node stands for `weight` readings and takes one degree of freedom of them.
        let within_bin_dof = fit_index
            .iter()
            .map(|&i| readings.weight[i] - 1.0)
            .sum::<f64>()
            .max(0.0);
        Ok(BarSeries {
            bar,
            reference_temperature_c: campaign.reference_temperature_c,
            t0_ns,
            t_s,
            y_um,
            mount_of,
            zero_segment,
            n_zero_segments,
            segment_offset_um,
            mounts,
            air_c,
            celsius,
            air_sensor_ids: campaign.air_sensors().map(|s| s.id.clone()).collect(),
            plate_sensor_id: campaign
                .sensors
                .iter()
                .find(|s| s.kind == crate::campaign::SensorKind::Plate)
                .map(|s| s.id.clone()),
            fit_index,
            weight: readings.weight,
            within_bin_rss_um2,
            within_bin_dof,
            dropped_outside_mounts,
            events,
        })
    }

    /// A series from plain vectors (no campaign files): for tests and tools that make their own
    /// data. Samples are assigned to `mounts` by time; `y_um` is taken as it is.
    #[cfg(test)]
    pub(crate) fn from_vectors(
        bar: Bar,
        reference_temperature_c: f64,
        t_s: Vec<f64>,
        y_um: Vec<f64>,
        air_c: Vec<f64>,
        mounts: Vec<MountSpan>,
    ) -> BarSeries {
        let n = t_s.len();
        let mount_of = assign_mounts(&t_s, &mounts);
        let dropped_outside_mounts = mount_of.iter().filter(|m| m.is_none()).count();
        let (zero_segment, n_zero_segments) = zero_segments(&t_s, &mount_of, &[]);
        let fit_index = (0..t_s.len())
            .filter(|&i| mount_of[i].is_some_and(|m| mounts[m as usize].is_fitted()))
            .collect();
        let celsius = BTreeMap::from([("T1".to_string(), air_c.clone())]);
        BarSeries {
            bar,
            reference_temperature_c,
            t0_ns: 0,
            t_s,
            y_um,
            mount_of,
            zero_segment,
            segment_offset_um: vec![0.0; n_zero_segments],
            n_zero_segments,
            mounts,
            air_c,
            celsius,
            air_sensor_ids: vec!["T1".into()],
            plate_sensor_id: None,
            fit_index,
            weight: vec![1.0; n],
            within_bin_rss_um2: 0.0,
            within_bin_dof: 0.0,
            dropped_outside_mounts,
            events: Vec::new(),
        }
    }

    /// The series averaged over consecutive bins of at most `bin_s` seconds that never cross a
    /// mount or zero-segment boundary (nor a gap longer than `bin_s`): weighted means, each bin
    /// weighing the readings it stands for. A coarse copy to start a fit's time constants on
    /// and to trace the shape of its profiles; unlike [`BarSeries::build_binned`] it is not
    /// exact, and its [`BarSeries::within_bin_rss_um2`] is the source's, so only RSS
    /// *differences* of fits to it mean anything. `bin_s <= 0`: a copy.
    ///
    /// Bin edges are decided on integer nanoseconds (`t_s` rounded to ns), so a 1 Hz log gives
    /// bins of exactly `bin_s` samples.
    pub(crate) fn binned_copy(&self, bin_s: f64) -> BarSeries {
        if bin_s.is_nan() || bin_s <= 0.0 || self.t_s.len() < 2 {
            return self.clone();
        }
        let time_ns: Vec<TimeNs> = self
            .t_s
            .iter()
            .map(|&t| (t * 1e9).round() as TimeNs)
            .collect();
        let bin_ns = (bin_s * 1e9).round() as TimeNs;
        self.averaged(&bin_groups(
            &time_ns,
            &self.mount_of,
            &self.zero_segment,
            bin_ns,
        ))
    }

    /// Weighted means over the sample ranges `groups` (see [`bin_groups`]).
    fn averaged(&self, groups: &[(usize, usize)]) -> BarSeries {
        let w = &self.weight;
        let weight: Vec<f64> = groups.iter().map(|&(a, b)| w[a..b].iter().sum()).collect();
        let mean = |v: &[f64]| -> Vec<f64> {
            groups
                .iter()
                .zip(&weight)
                .map(|(&(a, b), &total)| {
                    if total > 0.0 {
                        v[a..b]
                            .iter()
                            .zip(&w[a..b])
                            .map(|(x, w)| x * w)
                            .sum::<f64>()
                            / total
                    } else {
                        v[a..b].iter().sum::<f64>() / (b - a) as f64
                    }
                })
                .collect()
        };
        let pick =
            |v: &[Option<u32>]| -> Vec<Option<u32>> { groups.iter().map(|&(a, _)| v[a]).collect() };
        let mount_of = pick(&self.mount_of);
        let fit_index = (0..groups.len())
            .filter(|&i| {
                weight[i] > 0.0 && mount_of[i].is_some_and(|m| self.mounts[m as usize].is_fitted())
            })
            .collect();
        BarSeries {
            bar: self.bar.clone(),
            reference_temperature_c: self.reference_temperature_c,
            t0_ns: self.t0_ns,
            t_s: mean(&self.t_s),
            y_um: mean(&self.y_um),
            zero_segment: pick(&self.zero_segment),
            n_zero_segments: self.n_zero_segments,
            segment_offset_um: self.segment_offset_um.clone(),
            mounts: self.mounts.clone(),
            air_c: mean(&self.air_c),
            celsius: self
                .celsius
                .iter()
                .map(|(k, v)| (k.clone(), mean(v)))
                .collect(),
            air_sensor_ids: self.air_sensor_ids.clone(),
            plate_sensor_id: self.plate_sensor_id.clone(),
            mount_of,
            fit_index,
            weight,
            within_bin_rss_um2: self.within_bin_rss_um2,
            within_bin_dof: self.within_bin_dof,
            dropped_outside_mounts: self.dropped_outside_mounts,
            events: self.events.clone(),
        }
    }

    /// The series without its samples (every per-sample vector emptied): the bar, its mounts,
    /// zero-segment offsets and `dropped_outside_mounts` stay. For runs that need nothing of a
    /// bar but its fitted model once it is identified.
    pub fn without_samples(self) -> BarSeries {
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

/// Every sensor's temperature at the encoder times of `log`, by linear interpolation of the
/// sensor's own log (replacing any column already there). Linear, not as-of: a backward as-of
/// join holds each reading until the next one, a delay of half the sensor period on average
/// (15 s at 30 s) that would bias every fitted time constant by about that much. Outside a
/// sensor's log the nearest reading is used; a sensor without readings gets no column.
pub fn interpolate_temperatures(log: &mut BarLog, sensors: &BTreeMap<String, SensorLog>) {
    log.celsius = temperatures_at(&log.time_ns, sensors);
}

/// `readings` (sorted) with a weight-0 sample at every sensor reading time (`knots`, sorted)
/// that falls strictly between two consecutive readings.
///
/// Why: lags are computed along the series' own times, the input held linear between them
/// (`signal::lag`). Where a bar logs nothing for a while (a read head switched off for hours: no
/// encoder rows, `docs/spec/campaign-format.md`) the air went on changing and the sensors went on logging;
/// bridged by a straight line, the lags enter every later reading with the wrong state (measured:
/// 2.4-4 nm RMS noise-free and tau_S off by up to 50 % on a 5-day campaign with a head off 1.5-4 h
/// a day). Where the sensors log on the encoder's grid nothing is added (compressed bins already
/// keep the knots between close nodes: only longer gaps gain samples). Counts there are
/// interpolated (for plots only); samples of weight 0 are never fitted.
fn with_knots_between(readings: Readings, knots: &[TimeNs]) -> Readings {
    let t = &readings.time_ns;
    // The knots strictly inside (t[k], t[k + 1]), for each k in turn (one walk).
    let mut j = 0;
    let mut inside = |k: usize| {
        while knots.get(j).is_some_and(|&x| x <= t[k]) {
            j += 1;
        }
        let from = j;
        while knots.get(j).is_some_and(|&x| x < t[k + 1]) {
            j += 1;
        }
        from..j
    };
    let added: usize = (0..t.len().saturating_sub(1))
        .map(|k| inside(k).len())
        .sum();
    if added == 0 {
        return readings;
    }
    let n = t.len() + added;
    let mut out = Readings {
        time_ns: Vec::with_capacity(n),
        counts: Vec::with_capacity(n),
        weight: Vec::with_capacity(n),
        line_rss_counts2: Vec::with_capacity(n),
    };
    let mut j = 0;
    for k in 0..t.len() {
        out.time_ns.push(t[k]);
        out.counts.push(readings.counts[k]);
        out.weight.push(readings.weight[k]);
        out.line_rss_counts2.push(readings.line_rss_counts2[k]);
        if k + 1 == t.len() {
            break;
        }
        while knots.get(j).is_some_and(|&x| x <= t[k]) {
            j += 1;
        }
        while let Some(&x) = knots.get(j).filter(|&&x| x < t[k + 1]) {
            let f = (x - t[k]) as f64 / (t[k + 1] - t[k]) as f64;
            let (c0, c1) = (readings.counts[k], readings.counts[k + 1]);
            out.time_ns.push(x);
            out.counts.push(c0 + f * (c1 - c0));
            out.weight.push(0.0);
            out.line_rss_counts2.push(0.0);
            j += 1;
        }
    }
    out
}

/// Every sensor's reading times, sorted and deduplicated: the knots of the temperature
/// interpolation, which a compressed series keeps as samples ([`BarSeries::from_bins`]). The
/// same for every bar, so made once per campaign.
pub fn sensor_knots(sensors: &BTreeMap<String, SensorLog>) -> Vec<TimeNs> {
    let mut knots: Vec<TimeNs> = sensors
        .values()
        .flat_map(|s| s.time_ns.iter().copied())
        .collect();
    knots.sort_unstable();
    knots.dedup();
    knots
}

/// Every sensor's temperature at the sorted times `time_ns` (see [`interpolate_temperatures`]).
pub(crate) fn temperatures_at(
    time_ns: &[TimeNs],
    sensors: &BTreeMap<String, SensorLog>,
) -> BTreeMap<String, Vec<f64>> {
    let mut out = BTreeMap::new();
    for (id, sensor) in sensors {
        if sensor.time_ns.is_empty() {
            continue;
        }
        let column = interpolate::linear_ascending(&sensor.time_ns, &sensor.celsius, time_ns);
        out.insert(id.clone(), column);
    }
    out
}

/// Campaign time origin: the earliest mount start (else the earliest reading).
pub fn campaign_origin_ns(logs: &CampaignLogs) -> TimeNs {
    let first_mount = logs.campaign.mounts.iter().map(|m| m.from_ns).min();
    let first_reading = logs
        .bars
        .values()
        .filter_map(|l| l.time_ns.first().copied())
        .min();
    first_mount.or(first_reading).unwrap_or(0)
}

fn mount_spans(campaign: &Campaign, bar: &Bar, to_s: &dyn Fn(TimeNs) -> f64) -> Vec<MountSpan> {
    campaign
        .mounts
        .iter()
        .enumerate()
        .filter(|(_, m)| m.bar == bar.id)
        .map(|(i, m)| {
            let (length_id, length_mm, device) = match &m.place {
                crate::campaign::Place::Length(l) => (Some(l.id.clone()), Some(l.mm), None),
                crate::campaign::Place::Device(d) => (None, None, Some(d.clone())),
            };
            MountSpan {
                campaign_index: i,
                i_p_mm: length_mm.map_or(0.0, |mm| mm - bar.fixed_length_mm),
                length_id,
                length_mm,
                tilt_deg: m.tilt_deg,
                purpose: m.purpose,
                device,
                from_s: to_s(m.from_ns),
                to_s: to_s(m.to_ns),
            }
        })
        .collect()
}

/// Mount index of each sample (mounts of one bar never overlap, `Campaign` checks it;
/// intervals are `[from, to)`): one sweep over the mounts by start for sorted times, else a binary
/// search per sample; never O(samples × mounts).
fn assign_mounts(t_s: &[f64], mounts: &[MountSpan]) -> Vec<Option<u32>> {
    let mut by_start: Vec<usize> = (0..mounts.len()).collect();
    by_start.sort_by(|&a, &b| {
        mounts[a]
            .from_s
            .total_cmp(&mounts[b].from_s)
            .then(a.cmp(&b))
    });
    // Sorted times (every series `build` makes) sweep the mounts once.
    let sorted = t_s.windows(2).all(|w| w[0] <= w[1]);
    let mut k = 0; // mounts starting at or before t
    t_s.iter()
        .map(|&t| {
            if sorted {
                while k < by_start.len() && mounts[by_start[k]].from_s <= t {
                    k += 1;
                }
            } else {
                k = by_start.partition_point(|&i| mounts[i].from_s <= t);
            }
            let i = *by_start.get(k.checked_sub(1)?)?;
            (t < mounts[i].to_s).then_some(i as u32)
        })
        .collect()
}

/// Zero segments: each mount, split again at every `rezero` event inside it.
fn zero_segments(
    t_s: &[f64],
    mount_of: &[Option<u32>],
    events: &[(f64, Event)],
) -> (Vec<Option<u32>>, usize) {
    let rezeros: Vec<f64> = events
        .iter()
        .filter(|(_, e)| e.kind == EventKind::Rezero)
        .map(|(t, _)| *t)
        .collect();
    let mut out = Vec::with_capacity(t_s.len());
    let mut next: u32 = 0;
    let mut last: Option<(u32, usize)> = None; // (mount, rezeros passed)
    let mut current: u32 = 0;
    for (i, m) in mount_of.iter().enumerate() {
        let Some(m) = m else {
            out.push(None);
            continue;
        };
        let passed = rezeros.partition_point(|&r| r <= t_s[i]);
        if last != Some((*m, passed)) {
            current = next;
            next += 1;
            last = Some((*m, passed));
        }
        out.push(Some(current));
    }
    (out, next as usize)
}

fn air_temperature(
    campaign: &Campaign,
    bar: &Bar,
    celsius: &BTreeMap<String, Vec<f64>>,
    n: usize,
) -> Result<Vec<f64>, SeriesError> {
    let ids: Vec<String> = match &bar.sensor {
        Some(s) => vec![s.clone()],
        None => campaign.air_sensors().map(|s| s.id.clone()).collect(),
    };
    if ids.is_empty() {
        return Err(SeriesError::NoAirSensor {
            bar: bar.id.clone(),
        });
    }
    let mut sum = vec![0.0; n];
    for id in &ids {
        let col = celsius
            .get(id)
            .filter(|c| c.len() == sum.len() && c.iter().all(|v| v.is_finite()))
            .ok_or_else(|| SeriesError::NoAirTemperature {
                bar: bar.id.clone(),
                sensor: id.clone(),
            })?;
        sum.iter_mut().zip(col).for_each(|(s, v)| *s += v);
    }
    let k = ids.len() as f64;
    Ok(sum.into_iter().map(|s| s / k).collect())
}

/// Remove the known plate expansion from the reading (only when the manifest gives a CTE and
/// a plate sensor exists), with the plate temperature the `plate_expansion` term uses
/// ([`crate::signal::plate_temperature`]: the sensor smoothed without delay).
fn subtract_plate_expansion(
    campaign: &Campaign,
    celsius: &BTreeMap<String, Vec<f64>>,
    t_s: &[f64],
    mount_of: &[Option<u32>],
    mounts: &[MountSpan],
    y_um: &mut [f64],
) {
    let cte = campaign.plate.cte_ppm_per_k;
    if cte == 0.0 {
        return;
    }
    let Some(plate) = campaign
        .sensors
        .iter()
        .find(|s| s.kind == crate::campaign::SensorKind::Plate)
    else {
        return;
    };
    let Some(tp) = celsius.get(&plate.id) else {
        return;
    };
    let tp = crate::signal::plate_temperature(t_s, tp);
    for (i, y) in y_um.iter_mut().enumerate() {
        if let Some(mm) = mount_of[i].and_then(|m| mounts[m as usize].length_mm) {
            *y -= cte * mm * 1e-3 * (tp[i] - campaign.reference_temperature_c);
        }
    }
}

/// Subtract each zero segment's median, so every segment reads near zero; returns the medians.
fn centre_segments(y_um: &mut [f64], segment: &[Option<u32>], n_segments: usize) -> Vec<f64> {
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); n_segments];
    for (y, s) in y_um.iter().zip(segment) {
        if let Some(s) = s {
            values[*s as usize].push(*y);
        }
    }
    let medians: Vec<f64> = values
        .iter_mut()
        .map(|v| {
            if v.is_empty() {
                return 0.0;
            }
            let mid = v.len() / 2;
            *v.select_nth_unstable_by(mid, f64::total_cmp).1
        })
        .collect();
    // Samples outside mounts are centred on the nearest earlier segment for plotting.
    let mut last = 0.0;
    for (y, s) in y_um.iter_mut().zip(segment) {
        if let Some(s) = s {
            last = medians[*s as usize];
        }
        *y -= last;
    }
    medians
}

/// Sample ranges `[a, b)` of the bins of [`BarSeries::binned_copy`]: a bin starts at a sample and
/// takes the following ones while they are in the same mount and zero segment and less than
/// `bin_ns` after its first sample (integer ns: no rounding decides a bin edge).
fn bin_groups(
    time_ns: &[TimeNs],
    mount_of: &[Option<u32>],
    segment: &[Option<u32>],
    bin_ns: TimeNs,
) -> Vec<(usize, usize)> {
    let mut groups = Vec::with_capacity(time_ns.len() / 4 + 1);
    let mut start = 0;
    for i in 1..=time_ns.len() {
        let closes = i == time_ns.len()
            || mount_of[i] != mount_of[start]
            || segment[i] != segment[start]
            || time_ns[i] - time_ns[start] >= bin_ns;
        if closes {
            groups.push((start, i));
            start = i;
        }
    }
    groups
}

#[cfg(test)]
pub(crate) mod tests;
