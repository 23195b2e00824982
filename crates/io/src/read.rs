//! Reading a campaign's tables with polars and handing them over as plain series.
//!
//! Each file is scanned lazily on its own (so every error can name its file), projected to the
//! columns the spec defines and normalised: timestamps in any unit and zone become `i64` ns UTC,
//! dictionary/categorical ids become strings, integer counts become `i64`. The per-file frames
//! are stacked, validated (nulls, unknown ids), then split per bar / sensor and sorted by time.
//!
//! The encoder table (tens of millions of rows) is never stacked: each file is streamed
//! (`sink_batches` on the streaming engine) and every batch is split into per-bar `time` /
//! `counts` buffers as it arrives, so ingest holds the per-bar logs and one batch, not the
//! table beside them. Temperatures are not joined onto the encoder times here: `series`
//! interpolates each sensor's log per bar (`interpolate_temperatures`), one bar at a time.
//!
//! # How it works
//!
//! - Ingest streams each encoder file (polars streaming engine, `sink_batches`) into per-bar
//!   `time`/`counts` vectors or bins: the encoder table is never stacked, and temperatures are not
//!   joined onto every encoder time (each bar interpolates the sensor logs when it is processed).
//! - Encoder files of one schema are decoded by one scan (`io::read::stream_files`): polars reads
//!   ahead across files (what it saves: `bench/README.md`); rows that cannot be used (a null, an undeclared id, a time out of range) found in a
//!   shared scan make ingest stream the files again one by one, which names each file's rows (only
//!   then; the first pass's rows are let go first).
//! - Cost and memory do not depend on the row order (the format allows any; a logger of many bars
//!   interleaves them). Each batch's bar ids become small indices on their string views (an id of
//!   ≤ 12 bytes is inline in its view: an open-addressed table of views, `io::read::IdIndex`); a
//!   batch of few runs of one bar goes run by run, any other is grouped by bar with a stable
//!   counting sort, so every bar gets its rows as one slice whatever the interleaving. A full-rate
//!   log is reserved from the parquet footers' row counts and, when not sorted, sorted per bar in
//!   parallel at the end.
//! - With bins, ingest decodes (polars) while two consumer threads (`io::read::BATCH_CONSUMERS`)
//!   each take whole batches, split them per bar and accumulate them into sinks of their own
//!   (bins, repeat sketches, per-file ranges), merged at the end: every part is an order-free
//!   integer sum, count or set (`BinAccumulator::merge`, `RepeatSketch::merge`, tested against one
//!   accumulator given every row). The temperature files are read on a third thread meanwhile
//!   (`io::read::read_temperatures`). The union of the sensors' reading times (the interpolation knots every binned series
//!   keeps as weight-0 samples) is sorted once per campaign (`series::sensor_knots`) and walked
//!   along each bar's nodes.
//! - Times are read as the stored integers and scaled to ns in Rust with `checked_mul`
//!   (`io::read::TimeColumn::to_ns`); a row with a time outside 1980 .. 2200
//!   (`series::reading_time_ok`) or null, a null id, an undeclared id, or counts that are not whole
//!   or beyond ±2⁴⁸ is dropped and recorded by file, column and row range (`io::read::BadRange`,
//!   `EncoderSink::bad`/`unknown`; for temperatures and events in `io::read::read_file` and
//!   `unknown_id_flags`) as an `unusable_rows` flag in `quality.files`; the narrative's notes quote
//!   the first three. A shared encoder scan that finds any re-streams file by file, so the rows
//!   named are each file's. The bin accumulator
//!   checks again (`BinAccumulator::add_all` → `BinError`: times in range, |counts| ≤ 2⁴⁸, ≤ 2³¹
//!   readings a bar), so its integer sums cannot wrap whoever calls it (property tests in
//!   `series/bins.rs`).
//! - Missing values are counted where rows are read: encoder counts per bar in
//!   `EncoderSink::checked_counts` (nulls, floats; whole floats converted), temperatures per sensor
//!   in `io::read::sensor_log`, event values in `read_events` (`series::quality::Missing`).
//! - `io::read_campaign_binned` hashes the files that share their size with another file of
//!   their table first (`io::inputs::split_by_shared_size`: only they can be byte-identical),
//!   reads a byte-identical file once, hashes the others on a thread beside the read, and after
//!   the read checks each file's size and mtime against those taken before hashing. Every read of a file runs under `io::guard::guarded` (catch_unwind, a quiet panic
//!   hook while a guard is active; `guarded_scan` for a scan of several files, which all count as
//!   being decoded). Shared scans that fail are retried file by file to name the file; a shared
//!   scan that crashes the process is probed file by file by the supervisor (`supervise::probe`,
//!   `io::decode_whole_file` in a child each).
//! - Rows that several encoder files hold: `io::read::EncoderSink` records each (file, bar) time
//!   range and row count while streaming (a shared scan's batches are cut at the files' footer row counts,
//!   `FileCursor`, so every batch knows its file); `io::read::resolve_repeats` re-reads,
//!   per bar, only the rows inside the overlapping ranges of the files involved (scan filtered by
//!   bar and time), keeps one copy of each reading (`compare_copies`) and subtracts the others
//!   from the bins (`BinAccumulator::remove_all`, exact on integer sums; a duplicate's twin stays,
//!   so first/last times and min/max counts are unchanged); flags `overlapping_files` and, on the
//!   binned path, `conflicting_readings`. At full rate the exact-duplicate rule removes the copies
//!   and `check_log` finds conflicts on the sorted rows. `gap` flags come from the pieces (readings
//!   or bins: their first/last reading times) within each mount (`quality::gap_flags`). Cost: none
//!   where no two files' ranges overlap for a bar (day files, files by bar); otherwise one filtered
//!   scan per (bar, overlap, file), so files that all span the whole campaign for the same bars
//!   without holding the same rows (rows dealt out to files at random) are re-read once per bar.
//!   Memory: one bar's rows in one merged overlap window (all files holding them); cost measured in
//!   `bench/README.md`. One scan per file for all its windows would
//!   cut the scans (a re-export is decoded once per bar) at the price of holding every bar's
//!   overlap at once.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use polars::lazy::dsl::Engine;
use polars::prelude::*;

use super::guard::{guarded, guarded_scan};
use super::inputs::{CampaignFiles, MANIFEST};
use super::repeats::{RepeatSketch, RepeatWindows};
use super::{one_line, IngestError};
use dbbcal_core::campaign::{Campaign, Manifest, SensorKind};
use dbbcal_core::series::quality::{self, ChannelQuality, Flag, FlagKind, Missing};
use dbbcal_core::series::{
    counts_ok, reading_time_ok, reading_times_ok, BarBins, BarLog, BinAccumulator, BinGrid, Event,
    EventKind, Quality, SensorLog, MAX_ABS_COUNTS,
};

/// Index of the source file of each row, added while scanning, for error messages.
const FILE_COL: &str = "__source_file";

/// The accepted physical forms of one spec column.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Timestamp, ns/us/ms, any zone or none -> i64 ns UTC.
    Time,
    /// utf8 or dictionary(utf8) -> String.
    Text,
    /// Integer -> i64; float -> f64 (whole numbers accepted, checked row by row).
    Count,
    /// Float -> f64.
    Real,
}

struct ColumnSpec {
    name: &'static str,
    kind: Kind,
    nullable: bool,
}

const fn spec(name: &'static str, kind: Kind, nullable: bool) -> ColumnSpec {
    ColumnSpec {
        name,
        kind,
        nullable,
    }
}

const ENCODER_COLUMNS: [ColumnSpec; 3] = [
    spec("time", Kind::Time, false),
    spec("bar", Kind::Text, false),
    // Null counts are missing readings: dropped and counted per bar (`EncoderSink::push`).
    spec("counts", Kind::Count, true),
];
const TEMPERATURE_COLUMNS: [ColumnSpec; 3] = [
    spec("time", Kind::Time, false),
    spec("sensor", Kind::Text, false),
    // Null, NaN, ±inf: missing readings, dropped and counted per sensor (`sensor_log`).
    spec("celsius", Kind::Real, true),
];
const EVENT_COLUMNS: [ColumnSpec; 4] = [
    spec("time", Kind::Time, false),
    spec("bar", Kind::Text, true),
    spec("kind", Kind::Text, false),
    spec("value", Kind::Real, true),
];

impl Kind {
    fn expected(self) -> &'static str {
        match self {
            Kind::Time => "a timestamp (ns, us or ms; naive or zoned)",
            Kind::Text => "utf8 or dictionary(utf8)",
            Kind::Count => "int64 or int32 (or float64 holding whole numbers)",
            Kind::Real => "float64",
        }
    }

    /// The expression turning column `name` of type `dtype` into the canonical type, or `None`
    /// when `dtype` is not an accepted form.
    fn normalise(self, name: &str, dtype: &DataType) -> Option<Expr> {
        let c = col(name);
        match (self, dtype) {
            // The physical value of a polars datetime is UTC epoch in its unit, zone or not; it
            // is scaled to ns in Rust with checked arithmetic (`to_ns`), never wrapped.
            (Kind::Time, DataType::Datetime(..)) => Some(c.cast(DataType::Int64)),
            (Kind::Text, DataType::String) => Some(c),
            (Kind::Text, DataType::Categorical(..) | DataType::Enum(..)) => {
                Some(c.cast(DataType::String))
            }
            (
                Kind::Count,
                DataType::Int64
                | DataType::Int32
                | DataType::Int16
                | DataType::Int8
                | DataType::UInt32
                | DataType::UInt16
                | DataType::UInt8,
            ) => Some(c.cast(DataType::Int64)),
            (Kind::Count, DataType::Float64 | DataType::Float32) => Some(c.cast(DataType::Float64)),
            (Kind::Real, DataType::Float64 | DataType::Float32) => Some(c.cast(DataType::Float64)),
            _ => None,
        }
    }
}

/// How a file stores its `time` column: ns per stored unit, and whether it names a zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct TimeColumn {
    ns_per_unit: i64,
    zoned: bool,
}

impl TimeColumn {
    fn of(dtype: Option<&DataType>) -> TimeColumn {
        match dtype {
            Some(DataType::Datetime(unit, zone)) => TimeColumn {
                ns_per_unit: match unit {
                    TimeUnit::Nanoseconds => 1,
                    TimeUnit::Microseconds => 1_000,
                    TimeUnit::Milliseconds => 1_000_000,
                },
                zoned: zone.is_some(),
            },
            _ => TimeColumn {
                ns_per_unit: 1,
                zoned: false,
            },
        }
    }

    fn unit(self) -> &'static str {
        match self.ns_per_unit {
            1 => "ns",
            1_000 => "us",
            _ => "ms",
        }
    }

    /// A stored value as ns, when it is an accepted reading time: `None` for an overflow of
    /// the ns range (µs/ms far out) or a time outside 1980 .. 2200 (NaT = `i64::MIN`, a 1970
    /// clock reset, a far future).
    fn to_ns(self, raw: i64) -> Option<i64> {
        raw.checked_mul(self.ns_per_unit)
            .filter(|&t| reading_time_ok(t))
    }
}

const NULL_PROBLEM: &str = "are null";

const TIME_PROBLEM: &str =
    "hold times outside 1980-01-01 .. 2200-01-01 (NaT, a clock reset, a far future, or a unit whose ns value overflows)";

/// Rows of one file with one problem: how many, the first and last row, the first value.
#[derive(Debug, Clone)]
struct BadRange {
    rows: u64,
    first_row: u64,
    last_row: u64,
    example: String,
}

impl BadRange {
    fn add(slot: &mut Option<BadRange>, row: u64, example: impl FnOnce() -> String) {
        match slot {
            Some(b) => {
                b.rows += 1;
                b.first_row = b.first_row.min(row);
                b.last_row = b.last_row.max(row);
            }
            None => {
                *slot = Some(BadRange {
                    rows: 1,
                    first_row: row,
                    last_row: row,
                    example: example(),
                })
            }
        }
    }

    /// Adds `other` to the range kept under `key` (file, column, problem); the example is the
    /// first row's.
    fn merge_into<K: Ord>(ranges: &mut BTreeMap<K, BadRange>, key: K, other: BadRange) {
        let Some(mine) = ranges.get_mut(&key) else {
            ranges.insert(key, other);
            return;
        };
        if other.first_row < mine.first_row {
            mine.example = other.example;
        }
        mine.rows += other.rows;
        mine.first_row = mine.first_row.min(other.first_row);
        mine.last_row = mine.last_row.max(other.last_row);
    }

    /// The rows dropped, as an `unusable_rows` flag of the files (`quality.files`).
    fn flag(self, path: &Path, column: &str, problem: &str) -> Flag {
        let note = format!(
            "{}: column `{column}`: {} rows (rows {} .. {}, counting from 0) {problem} (first: {}): dropped",
            path.display(),
            self.rows,
            self.first_row,
            self.last_row,
            self.example
        );
        Flag::file(FlagKind::UnusableRows, self.rows, note)
    }
}

/// Reads and validates `campaign.toml`.
pub(crate) fn read_manifest(dir: &Path) -> Result<Campaign, IngestError> {
    let path = dir.join(MANIFEST);
    if !path.is_file() {
        return Err(IngestError::MissingManifest {
            dir: dir.to_path_buf(),
        });
    }
    let text = crate::read_small_text(&path, crate::MAX_MANIFEST_BYTES).map_err(|message| {
        IngestError::Io {
            path: path.clone(),
            message: message
                .strip_prefix("cannot read: ")
                .unwrap_or(&message)
                .to_string(),
        }
    })?;
    let file = path.display().to_string();
    let manifest = Manifest::from_toml_str(&text, &file)?;
    let campaign = Campaign::from_manifest_at(manifest, &file)?;
    check_usable(&campaign, &path)?;
    Ok(campaign)
}

/// A campaign that can give no result is refused before any table is read: no bar, no mount,
/// or a bar that names no sensor in a campaign without an air sensor (its air would be the
/// mean of none).
fn check_usable(campaign: &Campaign, path: &Path) -> Result<(), IngestError> {
    let refuse = |problem: String| IngestError::UnusableCampaign {
        path: path.to_path_buf(),
        problem,
    };
    if campaign.bars.is_empty() {
        return Err(refuse(
            "declares no bar ([[bar]]): nothing to analyse".into(),
        ));
    }
    if campaign.mounts.is_empty() {
        return Err(refuse(
            "declares no mount ([[mount]]): no reading can be placed on a length".into(),
        ));
    }
    let has_air = campaign.sensors.iter().any(|s| s.kind == SensorKind::Air);
    if let Some(bar) = campaign
        .bars
        .iter()
        .find(|b| b.sensor.is_none() && !has_air)
    {
        return Err(refuse(format!(
            "declares no air sensor (kind = \"air\") and bar {} names no `sensor`: its air temperature is unknown",
            bar.id
        )));
    }
    Ok(())
}

/// The three tables, split per bar / sensor and sorted.
pub(crate) struct Tables {
    pub(crate) bars: BTreeMap<String, BarLog>,
    pub(crate) bins: BTreeMap<String, BarBins>,
    pub(crate) sensors: BTreeMap<String, SensorLog>,
    pub(crate) events: Vec<Event>,
}

/// `bin_s > 0`: every bar's encoder rows go straight into compressed bins of `bin_s` seconds
/// (`Tables::bins`), never held at full rate.
pub(crate) fn read_tables(
    files: &CampaignFiles,
    campaign: &Campaign,
    bin_s: f64,
    quality: &mut Quality,
) -> Result<Tables, IngestError> {
    let bar_ids: BTreeSet<&str> = campaign.bars.iter().map(|b| b.id.as_str()).collect();
    let sensor_ids: BTreeSet<&str> = campaign.sensors.iter().map(|s| s.id.as_str()).collect();
    let clock = std::time::Instant::now();
    // The temperatures are read on a thread of their own while the encoder files stream: the
    // bins do not need them, and the stream does not keep both cores busy all the time. Errors
    // keep their order: a temperature error is reported before any other.
    let (temperatures, rest) = std::thread::scope(|scope| {
        let temperatures = scope.spawn(|| read_temperatures(files, &sensor_ids));
        let rest = read_events_and_encoders(files, campaign, &bar_ids, bin_s);
        let temperatures = temperatures.join().unwrap_or_else(|_| {
            Err(IngestError::Polars {
                context: "temperatures".into(),
                message: "the temperature reader panicked".into(),
            })
        });
        (temperatures, rest)
    });
    let (sensors, sensor_quality, mut zones, temperatures_dropped) = temperatures?;
    let (events, event_quality, encoders, other_zones) = rest?;
    quality.files.extend(temperatures_dropped);
    quality.files.extend(encoders.dropped);
    tracing::debug!(elapsed = ?clock.elapsed(), "bar logs built");
    quality.sensors.extend(sensor_quality);
    quality.events = event_quality;
    zones.extend(other_zones);
    let (mut bars, mut bins) = (encoders.logs, encoders.bins);
    check_bars(campaign, &events, &sensors, &mut bars, &mut bins, quality);
    for (id, (rows, missing)) in encoders.rows {
        let q = quality.bars.entry(id).or_default();
        q.rows = rows;
        missing.record(q, "encoder rows");
    }
    for (id, overlap) in encoders.overlaps {
        let q = quality.bars.entry(id).or_default();
        q.duplicate_rows += overlap.removed;
        q.dropped_rows += overlap.removed;
        q.flags.extend(overlap.flags);
    }
    flag_mixed_zones(&zones, quality);
    Ok(Tables {
        bars,
        bins,
        sensors,
        events,
    })
}

/// Per sensor: its log and its quality record; and each temperature file's path and whether
/// its times are zoned.
type TemperatureTables = (
    BTreeMap<String, SensorLog>,
    BTreeMap<String, ChannelQuality>,
    Vec<(PathBuf, bool)>,
    Vec<Flag>,
);

/// Every temperature file, checked (nulls, undeclared sensors), as one log per declared sensor.
fn read_temperatures(
    files: &CampaignFiles,
    sensor_ids: &BTreeSet<&str>,
) -> Result<TemperatureTables, IngestError> {
    let clock = std::time::Instant::now();
    let mut zones = Vec::new();
    let mut dropped = Vec::new();
    let temperatures = read_table(
        &files.temperatures,
        &TEMPERATURE_COLUMNS,
        &mut zones,
        &mut dropped,
    )?;
    let readings =
        sensor_readings(&temperatures, sensor_ids).map_err(polars_error("temperatures"))?;
    let matched = readings.values().map(DataFrame::height).sum();
    dropped.extend(unknown_rows(
        &temperatures,
        matched,
        &files.temperatures,
        "sensor",
        sensor_ids,
    )?);
    drop(temperatures);
    let mut sensors = BTreeMap::new();
    let mut quality = BTreeMap::new();
    for (id, df) in &readings {
        let q: &mut ChannelQuality = quality.entry(id.clone()).or_default();
        let log = sensor_log(df, q).map_err(polars_error("temperatures"))?;
        sensors.insert(id.clone(), log);
    }
    tracing::debug!(elapsed = ?clock.elapsed(), "temperatures read");
    Ok((sensors, quality, zones, dropped))
}

/// The events and their quality record, the encoder table, and each of their files' path and
/// whether its times are zoned.
type EventAndEncoderTables = (Vec<Event>, ChannelQuality, Encoders, Vec<(PathBuf, bool)>);

/// The events first (the bins of a bar never cross its rezero events), then the encoders.
fn read_events_and_encoders(
    files: &CampaignFiles,
    campaign: &Campaign,
    bar_ids: &BTreeSet<&str>,
    bin_s: f64,
) -> Result<EventAndEncoderTables, IngestError> {
    let mut zones = Vec::new();
    let mut event_quality = ChannelQuality::default();
    let mut dropped = Vec::new();
    let events = read_events(
        &files.events,
        bar_ids,
        &mut zones,
        &mut event_quality,
        &mut dropped,
    )?;
    // The footers' rows: at full rate each bar's log is reserved once from them (no doubling
    // overshoot); with bins they set the slot width of each bar's repeat sketch.
    let footers = footer_rows_each(&files.encoders)?;
    let footer_total = footers.iter().fold(0u64, |a, &n| a.saturating_add(n));
    let rows_per_bar = footer_total / bar_ids.len().max(1) as u64;
    let grids: BTreeMap<String, (BinGrid, Option<RepeatSketch>)> = if bin_s > 0.0 {
        bar_ids
            .iter()
            .map(|id| {
                let grid = BinGrid::new(campaign, &events, id, bin_s);
                let repeats = RepeatSketch::new(campaign, id, rows_per_bar);
                (id.to_string(), (grid, repeats))
            })
            .collect()
    } else {
        BTreeMap::new()
    };
    let rows_hint = if grids.is_empty() {
        footer_total as usize
    } else {
        0
    };
    let mut encoders = read_encoders(
        &files.encoders,
        &footers,
        bar_ids,
        &grids,
        rows_hint,
        &mut zones,
    )?;
    dropped.append(&mut encoders.dropped);
    encoders.dropped = dropped;
    Ok((events, event_quality, encoders, zones))
}

/// Every bar's encoder checks (`series::quality`), bars in parallel.
fn check_bars(
    campaign: &Campaign,
    events: &[Event],
    sensors: &BTreeMap<String, SensorLog>,
    bars: &mut BTreeMap<String, BarLog>,
    bins: &mut BTreeMap<String, BarBins>,
    quality: &mut Quality,
) {
    use rayon::prelude::*;
    for id in bars.keys() {
        quality.bars.entry(id.clone()).or_default();
    }
    let mut work: Vec<(&String, &mut BarLog, Option<&mut BarBins>, ChannelQuality)> = bars
        .iter_mut()
        .map(|(id, log)| (id, log, None, ChannelQuality::default()))
        .collect();
    for (id, b) in bins.iter_mut() {
        if let Some(w) = work.iter_mut().find(|w| w.0 == id) {
            w.2 = Some(b);
        }
    }
    work.par_iter_mut()
        .for_each(|(id, log, binned, q)| match binned {
            Some(b) => quality::check_bins(campaign, events, sensors, id, b, q),
            None => quality::check_log(campaign, events, sensors, id, log, q),
        });
    for (id, _, _, q) in work {
        let entry = quality.bars.entry(id.clone()).or_default();
        entry.duplicate_rows += q.duplicate_rows;
        entry.fault_rows += q.fault_rows;
        entry.dropped_rows += q.dropped_rows;
        entry.flags.extend(q.flags);
        entry.unusable = q.unusable;
    }
}

/// Naive (UTC by the spec) and zoned time columns in one campaign: legal, but a naive file
/// written in local time would be off by the zone's offset, so it is flagged.
fn flag_mixed_zones(zones: &[(PathBuf, bool)], quality: &mut Quality) {
    let naive: Vec<&PathBuf> = zones.iter().filter(|z| !z.1).map(|z| &z.0).collect();
    let zoned = zones.len() - naive.len();
    if naive.is_empty() || zoned == 0 {
        return;
    }
    let name = |p: &PathBuf| {
        p.file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned())
    };
    let note = format!(
        "{} files have naive times (taken as UTC, e.g. {}) and {zoned} zoned ones: check the naive ones are not local time",
        naive.len(),
        name(naive[0])
    );
    quality
        .files
        .push(Flag::file(FlagKind::MixedTimeZones, 0, note));
}

/// The rows of known ids were extracted (`matched` of them); if that is not every row, some ids
/// are undeclared: their rows (dropped) as `unusable_rows` flags, by file and id. This keeps
/// the costly per-file summary off the path of a good campaign.
fn unknown_rows(
    df: &DataFrame,
    matched: usize,
    files: &[PathBuf],
    id_column: &'static str,
    known: &BTreeSet<&str>,
) -> Result<Vec<Flag>, IngestError> {
    if matched == df.height() {
        return Ok(Vec::new());
    }
    let flags = unknown_id_flags(df, files, id_column, known)?;
    if flags.is_empty() {
        return Err(IngestError::Polars {
            context: id_column.to_string(),
            message: format!(
                "{matched} of {} rows have a declared id, but no undeclared id was found",
                df.height()
            ),
        });
    }
    Ok(flags)
}

/// Rows of ids the manifest does not declare, per file and id (null ids are skipped).
fn unknown_id_flags(
    df: &DataFrame,
    files: &[PathBuf],
    id_column: &'static str,
    known: &BTreeSet<&str>,
) -> Result<Vec<Flag>, IngestError> {
    let summary = id_summary(df, id_column).map_err(polars_error(id_column))?;
    let known_list = known.iter().copied().collect::<Vec<_>>().join(", ");
    Ok(summary
        .into_iter()
        .filter(|row| !known.contains(row.id.as_str()))
        .map(|row| {
            unknown_id_flag(
                &file_path(files, row.file),
                id_column,
                &row.id,
                row.rows,
                row.first_ns,
                row.last_ns,
                &known_list,
            )
        })
        .collect())
}

fn polars_error(context: &str) -> impl Fn(PolarsError) -> IngestError + '_ {
    move |e| IngestError::Polars {
        context: context.to_string(),
        message: one_line(e),
    }
}

// ---------------------------------------------------------------- scanning

/// Scans, normalises and stacks every file of one table; adds [`FILE_COL`]. Rows that cannot
/// be used (a null in a column that must hold a value, a time out of range) are dropped and
/// flagged in `dropped`.
/// `zones`: each file's path and whether its times are zoned.
fn read_table(
    files: &[PathBuf],
    columns: &[ColumnSpec],
    zones: &mut Vec<(PathBuf, bool)>,
    dropped: &mut Vec<Flag>,
) -> Result<DataFrame, IngestError> {
    let mut stacked: Option<DataFrame> = None;
    for (index, path) in files.iter().enumerate() {
        let (df, time) = guarded(path, || read_file(path, columns, index, dropped))?;
        zones.push((path.clone(), time.zoned));
        match stacked.as_mut() {
            None => stacked = Some(df),
            Some(all) => {
                all.vstack_mut_owned(df).map_err(|e| not_parquet(path, e))?;
            }
        }
    }
    let table = stacked.unwrap_or_default();
    check_nulls(&table, files, columns)?;
    Ok(table)
}

fn not_parquet(path: &Path, e: PolarsError) -> IngestError {
    IngestError::NotParquet {
        path: path.to_path_buf(),
        reason: one_line(e),
    }
}

/// One file, projected to the spec's columns in canonical types, times in ns; rows with a null
/// where the spec wants a value, or a time out of range, are dropped and flagged in `dropped`
/// with their rows.
fn read_file(
    path: &Path,
    columns: &[ColumnSpec],
    index: usize,
    dropped: &mut Vec<Flag>,
) -> Result<(DataFrame, TimeColumn), IngestError> {
    let index = u32::try_from(index).unwrap_or(u32::MAX);
    let (lazy, schema, exprs) = checked_scan(path, columns)?;
    let unit = TimeColumn::of(schema.get("time"));
    let mut df = lazy
        .select(exprs)
        .with_column(lit(index).cast(DataType::UInt32).alias(FILE_COL))
        .collect()
        .map_err(|e| not_parquet(path, e))?;
    let mut keep: Option<Vec<bool>> = None;
    for spec in columns.iter().filter(|c| !c.nullable) {
        let column = df.column(spec.name).map_err(|e| not_parquet(path, e))?;
        if column.null_count() == 0 {
            continue;
        }
        let is_null = column.is_null();
        let mut bad = None;
        let keep = keep.get_or_insert_with(|| vec![true; df.height()]);
        for (row, null) in is_null.iter().enumerate() {
            if null == Some(true) {
                BadRange::add(&mut bad, row as u64, || "null".into());
                keep[row] = false;
            }
        }
        if let Some(b) = bad {
            dropped.push(b.flag(path, spec.name, NULL_PROBLEM));
        }
    }
    let raw = df
        .column("time")
        .and_then(|c| c.i64().cloned())
        .map_err(|e| not_parquet(path, e))?;
    let mut bad = None;
    let ns: Int64Chunked = raw
        .iter()
        .enumerate()
        .map(|(row, t)| {
            let Some(t) = t else {
                return Some(0); // dropped above
            };
            let ns = unit.to_ns(t);
            if ns.is_none() {
                BadRange::add(&mut bad, row as u64, || format!("{t} {}", unit.unit()));
                keep.get_or_insert_with(|| vec![true; raw.len()])[row] = false;
            }
            ns.or(Some(0))
        })
        .collect();
    if let Some(b) = bad {
        dropped.push(b.flag(path, "time", TIME_PROBLEM));
    }
    df.with_column(ns.into_series().with_name("time".into()).into_column())
        .map_err(|e| not_parquet(path, e))?;
    if let Some(keep) = keep {
        let mask: BooleanChunked = keep.into_iter().map(Some).collect();
        df = df.filter(&mask).map_err(|e| not_parquet(path, e))?;
    }
    Ok((df, unit))
}

/// One file's lazy scan, its whole schema, and the expressions that project it to the spec's
/// columns in canonical types; schema errors (missing column, wrong type) are raised here.
fn checked_scan(
    path: &Path,
    columns: &[ColumnSpec],
) -> Result<(LazyFrame, SchemaRef, Vec<Expr>), IngestError> {
    let source = PlRefPath::try_from_path(path).map_err(|e| not_parquet(path, e))?;
    let mut lazy =
        LazyFrame::scan_parquet(source, scan_args()).map_err(|e| not_parquet(path, e))?;
    let schema = lazy.collect_schema().map_err(|e| not_parquet(path, e))?;
    let mut exprs = Vec::with_capacity(columns.len() + 1);
    for spec in columns {
        let Some(dtype) = schema.get(spec.name) else {
            let found = schema
                .iter_names()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ");
            return Err(IngestError::MissingColumn {
                path: path.to_path_buf(),
                column: spec.name,
                found,
            });
        };
        let Some(expr) = spec.kind.normalise(spec.name, dtype) else {
            return Err(IngestError::WrongType {
                path: path.to_path_buf(),
                column: spec.name,
                found: dtype.to_string(),
                expected: spec.kind.expected(),
            });
        };
        exprs.push(expr.alias(spec.name));
    }
    Ok((lazy, schema, exprs))
}

fn scan_args() -> ScanArgsParquet {
    ScanArgsParquet {
        glob: false,
        ..Default::default()
    }
}

/// The rows the files' parquet footers announce (no data page is read).
pub(crate) fn footer_rows(files: &[PathBuf]) -> Result<u64, IngestError> {
    Ok(footer_rows_each(files)?
        .into_iter()
        .fold(0u64, u64::saturating_add))
}

/// The rows each file's parquet footer announces, in the order of `files`.
fn footer_rows_each(files: &[PathBuf]) -> Result<Vec<u64>, IngestError> {
    files
        .iter()
        .map(|path| {
            guarded(path, || {
                let file = std::fs::File::open(path).map_err(|e| IngestError::Io {
                    path: path.clone(),
                    message: e.to_string(),
                })?;
                ParquetReader::new(file)
                    .num_rows()
                    .map(|n| n as u64)
                    .map_err(|e| not_parquet(path, e))
            })
        })
        .collect()
}

// ---------------------------------------------------------------- encoders, streamed

/// The rows of a batch that are kept: bar indices, times (ns) and counts, same length.
type KeptRows = (Vec<u32>, Vec<i64>, Vec<i64>);

/// Rows of one bar gathered from every file and batch: kept (in arrival order), or added to the
/// bar's compressed bins as they arrive (`series::BinAccumulator`: order-free integer sums).
enum BarRows {
    Kept {
        time_ns: Vec<i64>,
        counts: Vec<i64>,
    },
    /// Added to the bar's bins as they arrive; `repeats` marks where its times may repeat
    /// (`None`: a bar without mounts).
    /// (`Box`: the accumulator is ~300 bytes, the other variants 48 or none.)
    Binned {
        bins: Box<BinAccumulator>,
        repeats: Option<RepeatSketch>,
    },
}

/// Time range and rows of one bar id in one file.
#[derive(Debug, Clone, Copy)]
struct FileRange {
    first_ns: i64,
    last_ns: i64,
    rows: u64,
}

impl FileRange {
    /// The range of the times `time_ns` (`None` when empty).
    fn of(time_ns: &[i64]) -> Option<FileRange> {
        Some(FileRange {
            first_ns: *time_ns.iter().min()?,
            last_ns: *time_ns.iter().max()?,
            rows: time_ns.len() as u64,
        })
    }

    /// Widens the range kept under `key` by `more` (rows added).
    fn add_to<K: Ord>(ranges: &mut BTreeMap<K, FileRange>, key: K, more: FileRange) {
        let range = ranges.entry(key).or_insert(FileRange { rows: 0, ..more });
        range.first_ns = range.first_ns.min(more.first_ns);
        range.last_ns = range.last_ns.max(more.last_ns);
        range.rows += more.rows;
    }
}

/// Bar ids of a batch as small indices, found on the string views: an id of 12 bytes or less
/// (every bar id of the spec's examples) is inline in its 16-byte view, so equal views are equal
/// ids, and a small open-addressed table of views gives the index without touching the string.
/// Longer ids are looked up by their string.
struct IdIndex {
    /// Id -> index (declared bars first, then undeclared ids as they appear).
    by_name: BTreeMap<String, u32>,
    names: Vec<String>,
    /// Open-addressed (view, index + 1) table of inline ids; 0 = empty.
    views: Vec<(u128, u32)>,
    /// Entries of `views` in use (at most half of it).
    filled: usize,
    shift: u32,
}

impl IdIndex {
    fn new<'a>(declared: impl Iterator<Item = &'a str>) -> IdIndex {
        let names: Vec<String> = declared.map(str::to_string).collect();
        let size = (4 * names.len() + 8).next_power_of_two();
        IdIndex {
            by_name: names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), i as u32))
                .collect(),
            names,
            views: vec![(0, 0); size],
            filled: 0,
            shift: 64 - size.trailing_zeros(),
        }
    }

    fn slot(&self, view: u128) -> usize {
        let mixed = (view as u64) ^ ((view >> 64) as u64).rotate_left(29);
        (mixed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    /// Index of every row's id into `out`.
    fn indices(&mut self, ids: &StringChunked, out: &mut Vec<u32>) {
        out.clear();
        out.reserve(ids.len());
        let mask = self.views.len() - 1;
        for chunk in ids.downcast_iter() {
            let views = chunk.views();
            let mut last: Option<(u128, u32)> = None;
            for (i, view) in views.iter().enumerate() {
                let bits = view.as_u128();
                if let Some((_, index)) = last.filter(|&(v, _)| v == bits) {
                    out.push(index);
                    continue;
                }
                let index = if view.length <= 12 {
                    let mut slot = self.slot(bits);
                    loop {
                        match self.views[slot] {
                            (v, found) if found != 0 && v == bits => break found - 1,
                            (_, 0) => {
                                let index = self.by_string(chunk.value(i));
                                if 2 * (self.filled + 1) <= self.views.len() {
                                    self.views[slot] = (bits, index + 1);
                                    self.filled += 1;
                                }
                                break index;
                            }
                            _ => slot = (slot + 1) & mask,
                        }
                    }
                } else {
                    self.by_string(chunk.value(i))
                };
                last = Some((bits, index));
                out.push(index);
            }
        }
    }

    fn by_string(&mut self, id: &str) -> u32 {
        if let Some(&index) = self.by_name.get(id) {
            return index;
        }
        let index = self.names.len() as u32;
        self.names.push(id.to_string());
        self.by_name.insert(id.to_string(), index);
        index
    }
}

/// What the streamed encoder batches leave behind: per-bar rows of declared bars, and what the
/// checks need (nulls per column and file, undeclared ids per file).
struct EncoderSink {
    /// Index of the file being streamed, and its rows streamed before this batch.
    file: u32,
    row_offset: u64,
    /// How the batch's times are stored (a scan's files share one schema).
    time: TimeColumn,
    ids: IdIndex,
    /// Rows of the declared bars, by index in `ids`.
    bars: Vec<BarRows>,
    /// (file, id) -> rows of an undeclared bar.
    unknown: BTreeMap<(u32, String), FileRange>,
    /// (file, column, problem) -> rows that cannot be read (times out of range, counts that are
    /// not whole numbers or beyond ±2^48): the run is refused on them.
    bad: BTreeMap<(u32, &'static str, &'static str), BadRange>,
    /// Per id index: rows read, and missing counts (null, NaN, ±inf) dropped.
    read: Vec<(u64, Missing)>,
    /// A bin accumulator's refusal (cannot happen after `push`'s checks; reported if it does).
    bin_error: Option<String>,
    /// (declared bar index, file) -> time range and rows: where two files overlap for one bar
    /// ([`resolve_repeats`]).
    ranges: BTreeMap<(u32, u32), FileRange>,
    /// Scratch: each row's id index, and the batch's rows grouped by bar.
    row_ids: Vec<u32>,
    grouped_time: Vec<i64>,
    grouped_counts: Vec<i64>,
    group_start: Vec<usize>,
}

impl EncoderSink {
    /// Split one batch per bar and add each bar's rows to its log or bins. The cost per row does
    /// not depend on the order of the rows: ids are indexed on their string views; a batch of
    /// few runs of one bar (a file sorted or grouped by bar) goes run by run, any other (bars
    /// interleaved, or shuffled) is first grouped by bar with a counting sort (stable: each bar's
    /// rows keep their order), so every bar gets its rows as one slice.
    fn push(&mut self, batch: &DataFrame) -> PolarsResult<()> {
        let offset = self.row_offset;
        self.row_offset += batch.height() as u64;
        let time = batch.column("time")?.i64()?;
        let bar = batch.column("bar")?.str()?;
        if time.null_count() > 0 || bar.null_count() > 0 {
            // Rows without a time or a bar cannot be used: dropped, named by file and rows; the
            // others go on.
            let (mut null_time, mut null_bar) = (None, None);
            let keep: BooleanChunked = time
                .iter()
                .zip(bar.iter())
                .enumerate()
                .map(|(i, (t, b))| {
                    let row = offset + i as u64;
                    if t.is_none() {
                        BadRange::add(&mut null_time, row, || "null".into());
                    }
                    if b.is_none() {
                        BadRange::add(&mut null_bar, row, || "null".into());
                    }
                    Some(t.is_some() && b.is_some())
                })
                .collect();
            if let Some(b) = null_time {
                self.merge_bad("time", NULL_PROBLEM, b);
            }
            if let Some(b) = null_bar {
                self.merge_bad("bar", NULL_PROBLEM, b);
            }
            let rows: Vec<u64> = keep
                .iter()
                .enumerate()
                .filter(|(_, k)| k.unwrap_or(false))
                .map(|(i, _)| offset + i as u64)
                .collect();
            let kept = batch.filter(&keep)?;
            return self.push_rows(&kept, &|i| rows.get(i).copied().unwrap_or(offset));
        }
        self.push_rows(batch, &|i| offset + i as u64)
    }

    /// [`Self::push`] of rows without nulls in `time` or `bar`; `row_of(i)`: the file's row of
    /// the batch's row `i` (rows with a problem are named by it).
    fn push_rows(&mut self, batch: &DataFrame, row_of: &dyn Fn(usize) -> u64) -> PolarsResult<()> {
        let time = batch.column("time")?.i64()?;
        let bar = batch.column("bar")?.str()?;
        let time = time.rechunk();
        let raw = time.cont_slice()?;
        let converted;
        let time: &[i64] = if self.time.ns_per_unit == 1 && reading_times_ok(raw) {
            raw
        } else {
            let (ns, bad_rows) = self.times_ns(raw, row_of);
            if bad_rows {
                // Rows with a time out of range are dropped (named by file and rows).
                let keep: BooleanChunked = raw
                    .iter()
                    .map(|&t| Some(self.time.to_ns(t).is_some()))
                    .collect();
                let rows: Vec<u64> = (0..raw.len())
                    .filter(|&i| self.time.to_ns(raw[i]).is_some())
                    .map(row_of)
                    .collect();
                let kept = batch.filter(&keep)?;
                if kept.height() == 0 {
                    return Ok(());
                }
                return self.push_rows(&kept, &|i| rows.get(i).copied().unwrap_or(0));
            }
            converted = ns;
            &converted
        };
        let mut ids = std::mem::take(&mut self.row_ids);
        self.ids.indices(bar, &mut ids);
        if self.read.len() < self.ids.names.len() {
            self.read
                .resize(self.ids.names.len(), (0, Missing::default()));
        }
        for &id in &ids {
            self.read[id as usize].0 += 1;
        }
        let counts = batch.column("counts")?;
        let whole = counts
            .i64()
            .ok()
            .filter(|c| c.null_count() == 0)
            .map(|c| c.rechunk());
        let clean = whole.as_ref().and_then(|c| {
            let v = c.cont_slice().ok()?;
            counts_ok(v).then_some(v)
        });
        match clean {
            Some(counts) => self.add_rows(&ids, time, counts),
            None => {
                let (ids_kept, time_kept, counts_kept) =
                    self.checked_counts(&ids, time, counts, row_of)?;
                self.add_rows(&ids_kept, &time_kept, &counts_kept);
            }
        }
        self.row_ids = ids;
        Ok(())
    }

    /// Adds what another consumer's sink gathered from its batches. Every part is a sum, a
    /// count, a range or a set, so the merged sink is the one a single consumer would have
    /// filled (full-rate rows differ only in order, and are sorted afterwards).
    fn merge(&mut self, other: EncoderSink) {
        for (key, u) in other.unknown {
            FileRange::add_to(&mut self.unknown, key, u);
        }
        for (key, b) in other.bad {
            BadRange::merge_into(&mut self.bad, key, b);
        }
        for (key, r) in other.ranges {
            FileRange::add_to(&mut self.ranges, key, r);
        }
        // Declared bars have the same indices in every sink (undeclared ids, numbered as they
        // appear, are reported by name through `unknown`).
        let declared = self.bars.len();
        let longest = self.read.len().max(other.read.len()).min(declared);
        if self.read.len() < longest {
            self.read.resize(longest, (0, Missing::default()));
        }
        for (mine, theirs) in self.read.iter_mut().zip(&other.read).take(declared) {
            mine.0 += theirs.0;
            mine.1.merge(&theirs.1);
        }
        self.bin_error = match (self.bin_error.take(), other.bin_error) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        for (mine, theirs) in self.bars.iter_mut().zip(other.bars) {
            match (mine, theirs) {
                (
                    BarRows::Kept { time_ns, counts },
                    BarRows::Kept {
                        time_ns: more_time,
                        counts: more_counts,
                    },
                ) => {
                    time_ns.extend_from_slice(&more_time);
                    counts.extend_from_slice(&more_counts);
                }
                (
                    BarRows::Binned { bins, repeats },
                    BarRows::Binned {
                        bins: more_bins,
                        repeats: more_repeats,
                    },
                ) => {
                    if let Err(e) = bins.merge(*more_bins) {
                        self.bin_error.get_or_insert(e.to_string());
                    }
                    if let (Some(mine), Some(theirs)) = (repeats.as_mut(), more_repeats) {
                        mine.merge(theirs);
                    }
                }
                _ => {}
            }
        }
    }

    /// Times of the batch in ns, and whether some are out of range (those rows recorded in
    /// `bad`, their times 0 here).
    fn times_ns(&mut self, raw: &[i64], row_of: &dyn Fn(usize) -> u64) -> (Vec<i64>, bool) {
        let unit = self.time;
        let mut bad = None;
        let ns: Vec<i64> = raw
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                unit.to_ns(t).unwrap_or_else(|| {
                    BadRange::add(&mut bad, row_of(i), || format!("{t} {}", unit.unit()));
                    0
                })
            })
            .collect();
        match bad {
            None => (ns, false),
            Some(b) => {
                self.merge_bad("time", TIME_PROBLEM, b);
                (ns, true)
            }
        }
    }

    fn merge_bad(&mut self, column: &'static str, problem: &'static str, b: BadRange) {
        BadRange::merge_into(&mut self.bad, (self.file, column, problem), b);
    }

    /// Counts that are not a clean int64 column (nulls, floats, values beyond ±2^48): missing
    /// ones (null, NaN, ±inf) dropped and counted per bar; whole floats converted exactly; a
    /// fraction or a value out of range dropped and named by file and rows (in `bad`).
    fn checked_counts(
        &mut self,
        ids: &[u32],
        time: &[i64],
        counts: &Column,
        row_of: &dyn Fn(usize) -> u64,
    ) -> PolarsResult<KeptRows> {
        const FRACTION: &str = "hold counts that are not whole numbers";
        const RANGE: &str = "hold counts beyond ±2^48";
        let values: Vec<Option<f64>> = match counts.dtype() {
            DataType::Float64 => counts.f64()?.iter().collect(),
            _ => counts.i64()?.iter().map(|c| c.map(|c| c as f64)).collect(),
        };
        let ints: Vec<Option<i64>> = match counts.dtype() {
            DataType::Float64 => vec![None; values.len()],
            _ => counts.i64()?.iter().collect(),
        };
        let (mut fraction, mut range) = (None, None);
        let mut kept = (Vec::new(), Vec::new(), Vec::new());
        for (i, (&v, &int)) in values.iter().zip(&ints).enumerate() {
            let row = row_of(i);
            let c = match (int, v) {
                (Some(c), _) => c,
                (None, Some(v)) if v.is_finite() => {
                    if v.fract() != 0.0 {
                        BadRange::add(&mut fraction, row, || v.to_string());
                        continue;
                    }
                    if v.abs() > MAX_ABS_COUNTS as f64 {
                        BadRange::add(&mut range, row, || v.to_string());
                        continue;
                    }
                    v as i64
                }
                (None, v) => {
                    self.read[ids[i] as usize].1.add(time[i], v);
                    continue;
                }
            };
            if c.unsigned_abs() > MAX_ABS_COUNTS as u64 {
                BadRange::add(&mut range, row, || c.to_string());
                continue;
            }
            kept.0.push(ids[i]);
            kept.1.push(time[i]);
            kept.2.push(c);
        }
        if let Some(b) = fraction {
            self.merge_bad("counts", FRACTION, b);
        }
        if let Some(b) = range {
            self.merge_bad("counts", RANGE, b);
        }
        Ok(kept)
    }

    /// Adds the batch's rows (id index, time ns, counts) to the bars' logs or bins.
    fn add_rows(&mut self, ids: &[u32], time: &[i64], counts: &[i64]) {
        let runs = 1 + ids.windows(2).filter(|w| w[0] != w[1]).count();
        if runs * 64 <= ids.len() {
            let mut start = 0;
            for end in 1..=ids.len() {
                if end == ids.len() || ids[end] != ids[start] {
                    self.append(ids[start], &time[start..end], &counts[start..end]);
                    start = end;
                }
            }
        } else {
            self.group_by_bar(ids, time, counts);
            let (grouped_time, grouped_counts) = (
                std::mem::take(&mut self.grouped_time),
                std::mem::take(&mut self.grouped_counts),
            );
            let starts = std::mem::take(&mut self.group_start);
            for (index, w) in starts.windows(2).enumerate() {
                if w[1] > w[0] {
                    let range = w[0]..w[1];
                    let (t, c) = (&grouped_time[range.clone()], &grouped_counts[range]);
                    self.append(index as u32, t, c);
                }
            }
            (self.grouped_time, self.grouped_counts, self.group_start) =
                (grouped_time, grouped_counts, starts);
        }
    }

    /// Counting sort of the batch's rows by id index into the grouped scratch columns;
    /// `group_start[k]..group_start[k + 1]` are the rows of index `k`.
    fn group_by_bar(&mut self, ids: &[u32], time: &[i64], counts: &[i64]) {
        let groups = self.ids.names.len();
        let starts = &mut self.group_start;
        starts.clear();
        starts.resize(groups + 1, 0);
        for &id in ids {
            starts[id as usize + 1] += 1;
        }
        for k in 0..groups {
            starts[k + 1] += starts[k];
        }
        let mut next: Vec<usize> = starts[..groups].to_vec();
        self.grouped_time.resize(ids.len(), 0);
        self.grouped_counts.resize(ids.len(), 0);
        for ((&id, &t), &c) in ids.iter().zip(time).zip(counts) {
            let at = &mut next[id as usize];
            self.grouped_time[*at] = t;
            self.grouped_counts[*at] = c;
            *at += 1;
        }
    }

    fn append(&mut self, index: u32, time: &[i64], counts: &[i64]) {
        let Some(range) = FileRange::of(time) else {
            return;
        };
        if matches!(
            self.bars.get(index as usize),
            Some(BarRows::Kept { .. } | BarRows::Binned { .. })
        ) {
            FileRange::add_to(&mut self.ranges, (index, self.file), range);
        }
        match self.bars.get_mut(index as usize) {
            Some(BarRows::Kept {
                time_ns,
                counts: kept,
            }) => {
                time_ns.extend_from_slice(time);
                kept.extend_from_slice(counts);
                return;
            }
            Some(BarRows::Binned { bins, repeats }) => {
                // Every row was checked in `push` (times and counts within the sums' range).
                if let Err(e) = bins.add_all(time, counts) {
                    self.bin_error.get_or_insert(e.to_string());
                }
                if let Some(repeats) = repeats {
                    repeats.add(time);
                }
                return;
            }
            None => {}
        }
        let id = self.ids.names[index as usize].clone();
        FileRange::add_to(&mut self.unknown, (self.file, id), range);
    }
}

/// Streams every encoder file (projection and type normalisation inside the scan) into per-bar
/// logs sorted by (time, counts), or, for the bars `grids` names, straight into compressed bins
/// (the bar's log then stays empty). Errors as [`read_table`] + [`check_nulls`] +
/// [`check_ids`] report them: schema errors at the file, then the first column with nulls
/// (first file), then the first file with an undeclared bar (first id). `rows_hint`: the
/// encoder rows the files' footers announce (per-bar logs are reserved from it).
fn read_encoders(
    files: &[PathBuf],
    footer_rows: &[u64],
    bar_ids: &BTreeSet<&str>,
    grids: &BTreeMap<String, (BinGrid, Option<RepeatSketch>)>,
    rows_hint: usize,
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<Encoders, IngestError> {
    let keep = |id: &str| match grids.get(id) {
        Some((grid, repeats)) => BarRows::Binned {
            bins: Box::new(BinAccumulator::new(grid.clone())),
            repeats: repeats.clone(),
        },
        None => BarRows::Kept {
            time_ns: Vec::with_capacity(rows_hint / bar_ids.len().max(1)),
            counts: Vec::with_capacity(rows_hint / bar_ids.len().max(1)),
        },
    };
    // Files of one schema are decoded by one scan (polars then reads ahead across files: ~2x
    // faster than a query per day file); its batches do not say which file they came from, so
    // a null or an undeclared id found there is attributed by a second pass, file by file,
    // that keeps no rows (only on that error path).
    let clean = |s: &EncoderSink| s.unknown.is_empty() && s.bad.is_empty();
    let shared = stream_encoders(files, footer_rows, bar_ids, &keep, true, zones);
    let sink = match shared {
        Ok(sink) if clean(&sink) => sink,
        // Rows that cannot be used (or a failing file) in a shared scan: read again file by
        // file, which names each file's rows exactly (the rows kept are the same); the first
        // pass's rows are let go first.
        other => {
            drop(other);
            stream_encoders(files, footer_rows, bar_ids, &keep, false, &mut Vec::new())?
        }
    };
    if let Some(message) = sink.bin_error {
        return Err(IngestError::Polars {
            context: "encoders".into(),
            message,
        });
    }
    // Rows that cannot be used are dropped, counted and flagged by file, column and rows; the
    // night goes on (`docs/guarantees.md`, "Inputs").
    let mut dropped: Vec<Flag> = sink
        .bad
        .into_iter()
        .map(|((file, column, problem), b)| b.flag(&file_path(files, file), column, problem))
        .collect();
    let known = bar_ids.iter().copied().collect::<Vec<_>>().join(", ");
    dropped.extend(sink.unknown.into_iter().map(|((file, id), u)| {
        unknown_id_flag(
            &file_path(files, file),
            "bar",
            &id,
            u.rows,
            u.first_ns,
            u.last_ns,
            &known,
        )
    }));
    let rows: BTreeMap<String, (u64, Missing)> = bar_ids
        .iter()
        .zip(
            sink.read
                .iter()
                .chain(std::iter::repeat(&(0, Missing::default()))),
        )
        .map(|(id, r)| (id.to_string(), *r))
        .collect();
    let mut bars = sink.bars;
    let clock = std::time::Instant::now();
    let overlaps = resolve_repeats(files, bar_ids, &sink.ranges, &mut bars)?;
    tracing::debug!(elapsed = ?clock.elapsed(), bars = overlaps.len(), "repeated readings resolved");
    // Bars in parallel: an unsorted full-rate log is sorted here (~0.1 s a million rows).
    use rayon::prelude::*;
    let finished: Vec<(String, BarLog, Option<BarBins>)> = bar_ids
        .iter()
        .zip(bars)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|(id, rows)| match rows {
            BarRows::Kept { time_ns, counts } => {
                let (time_ns, counts) = sorted_by_time_then_value(time_ns, counts);
                let log = BarLog {
                    time_ns,
                    counts,
                    celsius: BTreeMap::new(),
                };
                (id.to_string(), log, None)
            }
            BarRows::Binned { bins, .. } => {
                (id.to_string(), BarLog::default(), Some(bins.finish()))
            }
        })
        .collect();
    let mut logs = BTreeMap::new();
    let mut bins = BTreeMap::new();
    for (id, log, binned) in finished {
        if let Some(b) = binned {
            bins.insert(id.clone(), b);
        }
        logs.insert(id, log);
    }
    Ok(Encoders {
        logs,
        bins,
        rows,
        overlaps,
        dropped,
    })
}

/// What re-reading the rows of one bar that may repeat gave: flags, and the copies removed
/// from the bins (counted in `duplicate_rows`).
#[derive(Debug, Default)]
struct Overlap {
    flags: Vec<Flag>,
    removed: u64,
}

/// Readings of one bar that repeat: held by several files, or twice by one. They are found in
/// windows of the bar's time line, and the bar's rows inside them are read again from the files
/// whose time range meets them (filtered in the scan by bar and time, so memory is those rows):
/// - windows where the time ranges of two files overlap for the bar (recorded while streaming,
///   [`FileRange`]), on both reading paths;
/// - with bins, the windows of the bar's [`RepeatSketch`]: where two rows fell in one slot
///   (at full rate the sorted rows show repeats directly, `quality::check_log`).
///
/// There:
/// - a reading (time and counts) held more than once is counted once, as at full rate
///   (`quality::dedup_sorted`): with bins the extra copies are taken out of the bins (exact:
///   integer sums) and flagged `duplicate_rows`; held by several files, also
///   `overlapping_files` (at full rate only that flag is added here);
/// - readings of one time with different counts are `conflicting_readings`, all kept (at full
///   rate `quality::check_log` finds them, so only the binned path flags here).
fn resolve_repeats(
    files: &[PathBuf],
    bar_ids: &BTreeSet<&str>,
    ranges: &BTreeMap<(u32, u32), FileRange>,
    bars: &mut [BarRows],
) -> Result<BTreeMap<String, Overlap>, IngestError> {
    let mut found = BTreeMap::new();
    for (index, id) in bar_ids.iter().enumerate() {
        let (binned, repeats) = match bars.get_mut(index) {
            Some(BarRows::Binned { repeats, .. }) => (true, repeats.take()),
            Some(BarRows::Kept { .. }) => (false, None),
            _ => continue,
        };
        let mine: Vec<(u32, FileRange)> = ranges
            .range((index as u32, 0)..=(index as u32, u32::MAX))
            .filter(|((_, file), _)| (*file as usize) < files.len())
            .map(|(&(_, file), &r)| (file, r))
            .collect();
        let mut windows = overlap_windows(&mine);
        match repeats.map_or(RepeatWindows::None, RepeatSketch::windows) {
            RepeatWindows::None => {}
            RepeatWindows::Windows(w) => windows.extend(w),
            RepeatWindows::Everything(from, to) => windows.push((from, to)),
        }
        let windows = merged(windows);
        if windows.is_empty() {
            continue;
        }
        let mut rows: Vec<(i64, i64, u32)> = Vec::new();
        for &(file, r) in &mine {
            let meets: Vec<(i64, i64)> = windows
                .iter()
                .copied()
                .filter(|&(from, to)| r.first_ns <= to && r.last_ns >= from)
                .collect();
            if !meets.is_empty() {
                let path = &files[file as usize];
                let read = guarded(path, || rows_in_windows(path, id, &meets))?;
                rows.extend(read.into_iter().map(|(t, c)| (t, c, file)));
            }
        }
        rows.sort_unstable();
        let copies = compare_copies(&rows);
        let report: &mut Overlap = found.entry(id.to_string()).or_default();
        report_copies(files, id, binned, &copies, report);
        if let Some(BarRows::Binned { bins, .. }) = bars.get_mut(index) {
            bins.remove_all(&copies.removed.0, &copies.removed.1)
                .map_err(|e| IngestError::Polars {
                    context: "encoders".into(),
                    message: format!("bar {id}: {e}"),
                })?;
            report.removed += copies.removed.0.len() as u64;
        }
    }
    found.retain(|_, o| !o.flags.is_empty() || o.removed > 0);
    Ok(found)
}

/// Where the time ranges of two of a bar's files overlap.
fn overlap_windows(mine: &[(u32, FileRange)]) -> Vec<(i64, i64)> {
    let mut windows = Vec::new();
    for (i, (_, a)) in mine.iter().enumerate() {
        for (_, b) in &mine[i + 1..] {
            let (from, to) = (a.first_ns.max(b.first_ns), a.last_ns.min(b.last_ns));
            if from <= to {
                windows.push((from, to));
            }
        }
    }
    windows
}

/// Windows `[from, to]` sorted and merged where they meet or touch.
fn merged(mut windows: Vec<(i64, i64)>) -> Vec<(i64, i64)> {
    windows.sort_unstable();
    let mut out: Vec<(i64, i64)> = Vec::with_capacity(windows.len());
    for (from, to) in windows {
        match out.last_mut() {
            Some(last) if from <= last.1.saturating_add(1) => last.1 = last.1.max(to),
            _ => out.push((from, to)),
        }
    }
    out
}

/// The flags of one bar's repeated readings (see [`resolve_repeats`]).
fn report_copies(files: &[PathBuf], id: &str, binned: bool, copies: &Copies, report: &mut Overlap) {
    let names = |set: &BTreeSet<u32>| {
        set.iter()
            .map(|&f| file_name(&files[f as usize]))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some((a, b, n)) = copies.across_files {
        let how = if binned {
            "counted once (the copies taken out of the bins)"
        } else {
            "counted once (exact duplicates, in duplicate_rows)"
        };
        let note = format!(
            "{n} readings of bar {id} held by more than one file ({}) with the same time and \
             counts: {how}",
            names(&copies.duplicate_files)
        );
        report
            .flags
            .push(Flag::at(FlagKind::OverlappingFiles, a, b, n, note));
    }
    if !binned {
        return;
    }
    if let Some((a, b)) = copies.removed_range {
        let n = copies.removed.0.len() as u64;
        let note = format!(
            "{n} exact duplicate encoder rows (same time and value) counted once (the copies \
             taken out of the bins)"
        );
        report
            .flags
            .push(Flag::at(FlagKind::DuplicateRows, a, b, n, note));
    }
    if let Some((a, b, n)) = copies.conflicts {
        let note = format!(
            "{n} readings of bar {id} share their time with a reading of other counts ({}): a \
             logger clock set back, or two loggers; all kept",
            names(&copies.conflict_files)
        );
        report
            .flags
            .push(Flag::at(FlagKind::ConflictingReadings, a, b, n, note));
    }
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// What rows `(time, counts, file)` sorted by all three hold more than once.
#[derive(Debug, Default, PartialEq)]
struct Copies {
    /// Copies to take out: every row of a (time, counts) reading but one.
    removed: (Vec<i64>, Vec<i64>),
    removed_range: Option<(i64, i64)>,
    /// Readings held by more than one file: first, last time, copies among those removed.
    across_files: Option<(i64, i64, u64)>,
    duplicate_files: BTreeSet<u32>,
    /// Times with more than one counts value: first, last, readings concerned.
    conflicts: Option<(i64, i64, u64)>,
    conflict_files: BTreeSet<u32>,
}

fn widen(range: Option<(i64, i64, u64)>, t: i64, n: u64) -> Option<(i64, i64, u64)> {
    let (a, b, m) = range.unwrap_or((t, t, 0));
    Some((a.min(t), b.max(t), m + n))
}

fn compare_copies(rows: &[(i64, i64, u32)]) -> Copies {
    let mut out = Copies::default();
    for group in rows.chunk_by(|a, b| a.0 == b.0) {
        let t = group[0].0;
        let mut values = 0u64;
        for same in group.chunk_by(|a, b| a.1 == b.1) {
            values += 1;
            let extra = same.len() - 1;
            if extra == 0 {
                continue;
            }
            let c = same[0].1;
            out.removed.0.extend(std::iter::repeat_n(t, extra));
            out.removed.1.extend(std::iter::repeat_n(c, extra));
            out.removed_range = Some(out.removed_range.map_or((t, t), |(a, b)| (a, b.max(t))));
            if same.first().map(|r| r.2) != same.last().map(|r| r.2) {
                out.across_files = widen(out.across_files, t, extra as u64);
                out.duplicate_files.extend(same.iter().map(|r| r.2));
            }
        }
        if values > 1 {
            out.conflicts = widen(out.conflicts, t, group.len() as u64);
            out.conflict_files.extend(group.iter().map(|r| r.2));
        }
    }
    out
}

/// One bar's rows of one encoder file with times in one of `windows` (sorted, disjoint): the
/// scan filters by bar and by the windows' whole span, so only those rows are decoded into
/// memory. Missing counts (null, NaN, ±inf) are left out as in the streamed read; whole float
/// counts converted.
fn rows_in_windows(
    path: &Path,
    bar: &str,
    windows: &[(i64, i64)],
) -> Result<Vec<(i64, i64)>, IngestError> {
    let (Some(&(from_ns, _)), Some(&(_, to_ns))) = (windows.first(), windows.last()) else {
        return Ok(Vec::new());
    };
    let inside = |t: i64| {
        let k = windows.partition_point(|w| w.1 < t);
        windows.get(k).is_some_and(|w| w.0 <= t)
    };
    Ok(rows_in_window(path, bar, from_ns, to_ns)?
        .into_iter()
        .filter(|&(t, _)| inside(t))
        .collect())
}

/// One bar's rows of one encoder file with times in `[from_ns, to_ns]`: the scan filters by
/// bar and time, so only those rows are decoded into memory. Missing counts (null, NaN, ±inf)
/// are left out as in the streamed read; whole float counts converted.
fn rows_in_window(
    path: &Path,
    bar: &str,
    from_ns: i64,
    to_ns: i64,
) -> Result<Vec<(i64, i64)>, IngestError> {
    let (lazy, schema, exprs) = checked_scan(path, &ENCODER_COLUMNS)?;
    let unit = TimeColumn::of(schema.get("time"));
    let per = unit.ns_per_unit;
    let (lo, hi) = (
        from_ns.div_euclid(per) + i64::from(from_ns.rem_euclid(per) != 0),
        to_ns.div_euclid(per),
    );
    let df = lazy
        .select(exprs)
        .filter(
            col("bar")
                .eq(lit(bar))
                .and(col("time").gt_eq(lit(lo)))
                .and(col("time").lt_eq(lit(hi))),
        )
        .collect()
        .map_err(|e| not_parquet(path, e))?;
    let rows = (|| -> PolarsResult<Vec<(i64, i64)>> {
        let time = df.column("time")?.i64()?;
        let counts = df.column("counts")?;
        let counts: Vec<Option<i64>> = match counts.dtype() {
            DataType::Float64 => counts
                .f64()?
                .iter()
                .map(|v| v.filter(|v| v.is_finite()).map(|v| v as i64))
                .collect(),
            _ => counts.i64()?.iter().collect(),
        };
        Ok(time
            .iter()
            .zip(counts)
            .filter_map(|(t, c)| Some((unit.to_ns(t?)?, c?)))
            .filter(|&(t, _)| t >= from_ns && t <= to_ns)
            .collect())
    })()
    .map_err(|e| not_parquet(path, e))?;
    Ok(rows)
}

/// The encoder table per bar: full-rate logs (sorted) or bins, and per bar the rows read and
/// the missing counts dropped.
struct Encoders {
    logs: BTreeMap<String, BarLog>,
    bins: BTreeMap<String, BarBins>,
    rows: BTreeMap<String, (u64, Missing)>,
    /// Per bar: rows several files hold ([`resolve_repeats`]).
    overlaps: BTreeMap<String, Overlap>,
    /// Rows that could not be used, dropped: one `unusable_rows` flag per file, column and
    /// problem.
    dropped: Vec<Flag>,
}

/// One decoded batch of rows of one encoder file, as the consumers get it.
struct Batch {
    /// Index of the file.
    file: u32,
    /// The file's rows before this batch (bad rows are named by their row in the file).
    row_offset: u64,
    /// How the file stores its times.
    time: TimeColumn,
    frame: DataFrame,
}

/// Consumers of the decoded batches: each splits and accumulates whole batches into a sink of
/// its own, and the sinks are merged at the end (bins and repeat sketches are order-free
/// sums). One consumer was the stream's long pole: per row it costs more than polars' decoding.
const BATCH_CONSUMERS: usize = 2;

/// Streams every encoder file into sinks with rows `rows(id)` per declared bar, merged into
/// one: polars decodes while [`BATCH_CONSUMERS`] threads split and accumulate the batches it
/// hands over (a bounded queue, so at most a few batches wait). `shared_scans`: files of one
/// schema share a scan (each batch is cut at the files' footer row counts, `footer_rows`).
fn stream_encoders(
    files: &[PathBuf],
    footer_rows: &[u64],
    bar_ids: &BTreeSet<&str>,
    rows: &(dyn Fn(&str) -> BarRows + Sync),
    shared_scans: bool,
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<EncoderSink, IngestError> {
    let new_sink = || EncoderSink {
        file: 0,
        row_offset: 0,
        time: TimeColumn::of(None),
        bad: BTreeMap::new(),
        read: Vec::new(),
        bin_error: None,
        ranges: BTreeMap::new(),
        ids: IdIndex::new(bar_ids.iter().copied()),
        bars: bar_ids.iter().map(|id| rows(id)).collect(),
        unknown: BTreeMap::new(),
        row_ids: Vec::new(),
        grouped_time: Vec::new(),
        grouped_counts: Vec::new(),
        group_start: Vec::new(),
    };
    let (batches, received) = std::sync::mpsc::sync_channel::<Batch>(4);
    // Shared by the consumers only: when every consumer has stopped (an error), the receiver is
    // dropped and polars' next send fails, which ends the scan.
    let received = std::sync::Arc::new(std::sync::Mutex::new(received));
    let consumer_failed = || IngestError::Polars {
        context: "encoders".into(),
        message: "a batch consumer panicked".into(),
    };
    std::thread::scope(|scope| {
        let consumers: Vec<_> = (0..BATCH_CONSUMERS)
            .map(|_| {
                let mut sink = new_sink();
                let received = received.clone();
                scope.spawn(move || -> PolarsResult<EncoderSink> {
                    loop {
                        let next = match received.lock() {
                            Ok(queue) => queue.recv(),
                            Err(_) => break,
                        };
                        let Ok(batch) = next else { break };
                        (sink.file, sink.row_offset, sink.time) =
                            (batch.file, batch.row_offset, batch.time);
                        sink.push(&batch.frame)?;
                    }
                    Ok(sink)
                })
            })
            .collect();
        drop(received);
        let streamed = stream_files(files, footer_rows, batches, shared_scans, zones);
        let mut merged: Option<EncoderSink> = None;
        for consumer in consumers {
            let sink = consumer
                .join()
                .map_err(|_| consumer_failed())?
                .map_err(polars_error("encoders"))?;
            match merged.as_mut() {
                None => merged = Some(sink),
                Some(all) => all.merge(sink),
            }
        }
        streamed?;
        merged.ok_or_else(consumer_failed)
    })
}

/// Streams every encoder file, sending each batch with its file's index and its rows' offset in
/// that file to `batches`. `shared_scans`: consecutive files of one schema are
/// read by one scan; else one scan a file. `footer_rows`: each file's rows, as its footer says.
fn stream_files(
    files: &[PathBuf],
    footer_rows: &[u64],
    batches: std::sync::mpsc::SyncSender<Batch>,
    shared_scans: bool,
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<(), IngestError> {
    // Schemas first (footers only): every schema error is raised before any row is read.
    let mut groups: Vec<(Vec<usize>, LazyFrame, SchemaRef, Vec<Expr>)> = Vec::new();
    for (index, path) in files.iter().enumerate() {
        let (lazy, schema, exprs) = guarded(path, || checked_scan(path, &ENCODER_COLUMNS))?;
        zones.push((path.clone(), TimeColumn::of(schema.get("time")).zoned));
        match groups.last_mut() {
            Some((members, _, shared, _)) if shared_scans && *shared == schema => {
                members.push(index)
            }
            _ => groups.push((vec![index], lazy, schema, exprs)),
        }
    }
    for (members, lazy, schema, exprs) in groups {
        let first = &files[members[0]];
        let time = TimeColumn::of(schema.get("time"));
        let (file, lazy, cursor) = if members.len() == 1 {
            (u32::try_from(members[0]).unwrap_or(u32::MAX), lazy, None)
        } else {
            let paths: Vec<PlRefPath> = members
                .iter()
                .map(|&i| {
                    PlRefPath::try_from_path(&files[i]).map_err(|e| not_parquet(&files[i], e))
                })
                .collect::<Result<_, _>>()?;
            let cursor = FileCursor::new(
                members
                    .iter()
                    .map(|&i| (u32::try_from(i).unwrap_or(u32::MAX), footer_rows[i]))
                    .collect(),
            );
            let shared = LazyFrame::scan_parquet_files(paths.into(), scan_args())
                .map_err(|e| not_parquet(first, e))?;
            (
                u32::MAX,
                shared,
                Some(std::sync::Arc::new(std::sync::Mutex::new(cursor))),
            )
        };
        // A shared scan's batches arrive in file order (`maintain_order`): each is cut at the
        // files' footer row counts and sent with its file's index, so every row's file is
        // known (`FileRange`) without a per-row path column.
        let to_consumer = batches.clone();
        let batch_cursor = cursor.clone();
        // Rows of a scan of one file sent so far: each batch's offset in its file.
        let sent = std::sync::atomic::AtomicU64::new(0);
        let callback = PlanCallback::new(move |batch: DataFrame| {
            let send = |file: u32, row_offset: u64, frame: DataFrame| {
                to_consumer
                    .send(Batch {
                        file,
                        row_offset,
                        time,
                        frame,
                    })
                    .map_err(|_| polars_err!(ComputeError: "the batch consumers stopped"))
            };
            match &batch_cursor {
                None => {
                    let rows = batch.height() as u64;
                    let offset = sent.fetch_add(rows, std::sync::atomic::Ordering::Relaxed);
                    send(file, offset, batch)?
                }
                Some(cursor) => {
                    let parts = cursor
                        .lock()
                        .map_err(|_| polars_err!(ComputeError: "the file cursor was poisoned"))?
                        .split(batch)?;
                    for (file, offset, part) in parts {
                        send(file, offset, part)?;
                    }
                }
            }
            Ok(false) // keep going
        });
        let scanned: Vec<&Path> = members.iter().map(|&i| files[i].as_path()).collect();
        guarded_scan(first, &scanned, || {
            lazy.select(exprs)
                .sink_batches(callback, true, None)
                .and_then(|lazy| lazy.collect_with_engine(Engine::Streaming))
                .map_err(|e| not_parquet(first, e))
        })?;
        if let Some(cursor) = cursor {
            let cursor = cursor.lock().map_err(|_| IngestError::Polars {
                context: "encoders".into(),
                message: "the file cursor was poisoned".into(),
            })?;
            if let Some((file, missing)) = cursor.unread() {
                return Err(IngestError::Polars {
                    context: file_path(files, file).display().to_string(),
                    message: format!(
                        "{missing} rows announced by the parquet footer were not decoded"
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Where a shared scan is in its files: their indices and footer row counts, the file now
/// read and its rows not yet seen.
struct FileCursor {
    files: Vec<(u32, u64)>,
    at: usize,
    left: u64,
}

impl FileCursor {
    fn new(files: Vec<(u32, u64)>) -> FileCursor {
        let left = files.first().map_or(0, |f| f.1);
        FileCursor { files, at: 0, left }
    }

    /// Skips files whose rows have all been seen (empty files included).
    fn settle(&mut self) {
        while self.left == 0 && self.at + 1 < self.files.len() {
            self.at += 1;
            self.left = self.files[self.at].1;
        }
    }

    /// The next batch of the scan cut into runs of one file, each with its file's index and
    /// the file's rows before it. More rows than the footers announce is an error (it cannot
    /// happen with valid footers).
    fn split(&mut self, batch: DataFrame) -> PolarsResult<Vec<(u32, u64, DataFrame)>> {
        let mut parts = Vec::with_capacity(1);
        let (mut start, n) = (0usize, batch.height());
        while start < n {
            self.settle();
            if self.left == 0 {
                polars_bail!(ComputeError: "the files hold more rows than their footers announce");
            }
            let take = (self.left.min((n - start) as u64)) as usize;
            let part = if start == 0 && take == n {
                batch.clone()
            } else {
                batch.slice(start as i64, take)
            };
            let (file, rows) = self.files[self.at];
            parts.push((file, rows - self.left, part));
            self.left -= take as u64;
            start += take;
        }
        Ok(parts)
    }

    /// The first file with rows its footer announced but the scan did not give, if any.
    fn unread(&self) -> Option<(u32, u64)> {
        let mut cursor = FileCursor {
            files: self.files.clone(),
            at: self.at,
            left: self.left,
        };
        cursor.settle();
        (cursor.left > 0).then(|| (cursor.files[cursor.at].0, cursor.left))
    }
}

/// Rows sorted by time, ties by value, so that the order never depends on how the rows were
/// split into files and batches. Already sorted rows (a logger's usual output) are only checked.
fn sorted_by_time_then_value(mut time_ns: Vec<i64>, mut counts: Vec<i64>) -> (Vec<i64>, Vec<i64>) {
    let sorted = time_ns
        .windows(2)
        .zip(counts.windows(2))
        .all(|(t, c)| (t[0], c[0]) <= (t[1], c[1]));
    if sorted {
        return (time_ns, counts);
    }
    let mut rows: Vec<(i64, i64)> = time_ns
        .iter()
        .copied()
        .zip(counts.iter().copied())
        .collect();
    // Equal (time, counts) pairs are indistinguishable, so an unstable sort is deterministic.
    rows.sort_unstable();
    // Written back into the columns: one pair buffer beside them, not two more columns.
    for ((t, c), (rt, rc)) in time_ns.iter_mut().zip(counts.iter_mut()).zip(rows) {
        (*t, *c) = (rt, rc);
    }
    (time_ns, counts)
}

/// Rejects nulls in non-nullable columns, naming the first file that has some.
fn check_nulls(
    df: &DataFrame,
    files: &[PathBuf],
    columns: &[ColumnSpec],
) -> Result<(), IngestError> {
    for spec in columns.iter().filter(|c| !c.nullable) {
        let Ok(column) = df.column(spec.name) else {
            continue;
        };
        if column.null_count() == 0 {
            continue;
        }
        let per_file = null_rows_per_file(df, spec.name).map_err(polars_error(spec.name))?;
        if let Some((&file, &count)) = per_file.iter().next() {
            return Err(IngestError::Nulls {
                path: file_path(files, file),
                column: spec.name,
                count,
            });
        }
    }
    Ok(())
}

fn null_rows_per_file(df: &DataFrame, column: &str) -> PolarsResult<BTreeMap<u32, u64>> {
    let is_null = df.column(column)?.is_null();
    let files = df.column(FILE_COL)?.filter(&is_null)?;
    let mut per_file = BTreeMap::new();
    for file in files.u32()?.iter().flatten() {
        *per_file.entry(file).or_insert(0u64) += 1;
    }
    Ok(per_file)
}

/// Rows of an id `campaign.toml` does not declare, dropped: an `unusable_rows` flag.
fn unknown_id_flag(
    path: &Path,
    column: &str,
    id: &str,
    rows: u64,
    first_ns: i64,
    last_ns: i64,
    known: &str,
) -> Flag {
    let note = format!(
        "{}: {rows} rows ({} .. {}) have {column} {:?}, which campaign.toml does not declare (known: {known}): dropped",
        path.display(),
        crate::format_ns(first_ns),
        crate::format_ns(last_ns),
        id
    );
    Flag::file(FlagKind::UnusableRows, rows, note)
}

fn file_path(files: &[PathBuf], index: u32) -> PathBuf {
    files.get(index as usize).cloned().unwrap_or_default()
}

struct IdSummary {
    file: u32,
    id: String,
    rows: u64,
    first_ns: i64,
    last_ns: i64,
}

/// Rows and time range per (file, id), sorted by file then id.
fn id_summary(df: &DataFrame, id_column: &str) -> PolarsResult<Vec<IdSummary>> {
    let summary = df
        .clone()
        .lazy()
        .filter(col(id_column).is_not_null())
        .group_by([col(FILE_COL), col(id_column)])
        .agg([
            len().cast(DataType::Int64).alias("rows"),
            col("time").min().alias("first"),
            col("time").max().alias("last"),
        ])
        .sort([FILE_COL, id_column], SortMultipleOptions::default())
        .collect()?;
    let files = summary.column(FILE_COL)?.u32()?;
    let ids = summary.column(id_column)?.str()?;
    let rows = summary.column("rows")?.i64()?;
    let first = summary.column("first")?.i64()?;
    let last = summary.column("last")?.i64()?;
    let mut out = Vec::with_capacity(summary.height());
    for i in 0..summary.height() {
        out.push(IdSummary {
            file: files.get(i).unwrap_or(u32::MAX),
            id: ids.get(i).unwrap_or_default().to_string(),
            rows: rows.get(i).unwrap_or(0).max(0) as u64,
            first_ns: first.get(i).unwrap_or(0),
            last_ns: last.get(i).unwrap_or(0),
        });
    }
    Ok(out)
}

// ---------------------------------------------------------------- per bar / sensor

/// Rows of `df` whose `key` is `id`, columns `columns`, sorted by time (`columns[0]`), ties
/// broken by the value so that the order never depends on how the rows were split into files.
fn rows_of(df: &DataFrame, key: &str, id: &str, columns: [&str; 2]) -> PolarsResult<DataFrame> {
    let by_time = df
        .clone()
        .lazy()
        .filter(col(key).eq(lit(id)))
        .select([col(columns[0]), col(columns[1])])
        .sort(
            [columns[0]],
            SortMultipleOptions::default().with_maintain_order(true),
        )
        .collect()?;
    // A two-key sort is several times slower than a one-key sort: only pay for it on ties.
    if has_ties(by_time.column(columns[0])?.i64()?) {
        by_time.sort(columns, SortMultipleOptions::default())
    } else {
        Ok(by_time)
    }
}

/// Whether a sorted column holds two equal neighbours.
fn has_ties(sorted: &Int64Chunked) -> bool {
    let mut previous = None;
    sorted.iter().any(|t| {
        let tie = t.is_some() && t == previous;
        previous = t;
        tie
    })
}

/// Sensor id -> its (time, celsius) frame sorted by time; every declared sensor is present.
fn sensor_readings(
    temperatures: &DataFrame,
    sensor_ids: &BTreeSet<&str>,
) -> PolarsResult<BTreeMap<String, DataFrame>> {
    sensor_ids
        .iter()
        .map(|id| {
            Ok((
                id.to_string(),
                rows_of(temperatures, "sensor", id, ["time", "celsius"])?,
            ))
        })
        .collect()
}

/// A sensor's log from its rows sorted by (time, value): null, NaN and ±inf readings dropped
/// (a missing reading, not a temperature: one NaN would otherwise spread through every bar
/// that interpolates the sensor) and exact duplicates counted once, both recorded in `q`.
fn sensor_log(readings: &DataFrame, q: &mut ChannelQuality) -> PolarsResult<SensorLog> {
    let time = readings.column("time")?.i64()?;
    let celsius = readings.column("celsius")?.f64()?;
    let mut log = SensorLog::default();
    let mut missing = Missing::default();
    for (t, c) in time.into_no_null_iter().zip(celsius.iter()) {
        match c {
            Some(c) if c.is_finite() => {
                log.time_ns.push(t);
                log.celsius.push(c);
            }
            other => missing.add(t, other),
        }
    }
    q.rows = readings.height() as u64;
    missing.record(q, "temperature readings");
    // Sorted by time, ties by value: exact duplicates are neighbours (NaN, which would not
    // compare equal, is gone).
    let (dups, range) = quality::dedup_sorted(&mut log.time_ns, &mut log.celsius);
    quality::record_duplicates(q, dups, range, "temperature readings");
    quality::drop_implausible_temperatures(&mut log.time_ns, &mut log.celsius, q);
    Ok(log)
}

// ---------------------------------------------------------------- events

fn read_events(
    files: &[PathBuf],
    bar_ids: &BTreeSet<&str>,
    zones: &mut Vec<(PathBuf, bool)>,
    q: &mut ChannelQuality,
    dropped: &mut Vec<Flag>,
) -> Result<Vec<Event>, IngestError> {
    if files.is_empty() {
        return Ok(Vec::new());
    }
    let table = read_table(files, &EVENT_COLUMNS, zones, dropped)?;
    dropped.extend(unknown_id_flags(&table, files, "bar", bar_ids)?);
    // Events of undeclared bars are dropped (a null bar: a setup-wide event).
    let declared: BooleanChunked = table
        .column("bar")
        .and_then(|c| c.str().cloned())
        .map_err(polars_error("events"))?
        .iter()
        .map(|b| Some(b.is_none_or(|b| bar_ids.contains(b))))
        .collect();
    let table = table.filter(&declared).map_err(polars_error("events"))?;
    q.rows = table.height() as u64;
    let events = events_sorted(table).map_err(polars_error("events"))?;
    // A NaN or infinite value is a missing reading, not a level (a null value is a valueless
    // event, as the spec allows): the event is dropped and counted.
    let mut missing = Missing::default();
    let kept = events
        .into_iter()
        .filter(|e| match e.value {
            Some(v) if !v.is_finite() => {
                missing.add(e.time_ns, Some(v));
                false
            }
            _ => true,
        })
        .collect();
    missing.record(q, "event rows");
    Ok(kept)
}

fn events_sorted(table: DataFrame) -> PolarsResult<Vec<Event>> {
    let sorted = table
        .lazy()
        .select([col("time"), col("bar"), col("kind"), col("value")])
        .sort(
            ["time", "bar", "kind", "value"],
            SortMultipleOptions::default(),
        )
        .collect()?;
    let time = sorted.column("time")?.i64()?;
    let bar = sorted.column("bar")?.str()?;
    let kind = sorted.column("kind")?.str()?;
    let value = sorted.column("value")?.f64()?;
    Ok((0..sorted.height())
        .map(|i| Event {
            time_ns: time.get(i).unwrap_or(0),
            bar: bar.get(i).map(str::to_string),
            kind: EventKind::parse(kind.get(i).unwrap_or_default()),
            value: value.get(i),
        })
        .collect())
}

/// What two consumers' sinks merge: the ranges of bad rows and of a bar's rows in a file.
#[cfg(test)]
mod merge_tests {
    use super::*;

    fn bad(first_row: u64, last_row: u64, rows: u64) -> BadRange {
        BadRange {
            rows,
            first_row,
            last_row,
            example: format!("row {first_row}"),
        }
    }

    #[test]
    fn bad_rows_merge_to_one_range_whose_example_is_the_first_rows_in_either_order() {
        let key = (3u32, "counts", "hold counts beyond ±2^48");
        for (a, b) in [
            (bad(10, 20, 4), bad(500, 900, 7)),
            (bad(500, 900, 7), bad(10, 20, 4)),
        ] {
            let mut ranges = BTreeMap::new();
            BadRange::merge_into(&mut ranges, key, a);
            BadRange::merge_into(&mut ranges, key, b);
            let r = &ranges[&key];
            assert_eq!((r.rows, r.first_row, r.last_row), (11, 10, 900));
            assert_eq!(r.example, "row 10");
        }
    }

    #[test]
    fn file_ranges_widen_and_count_rows() {
        let mut ranges = BTreeMap::new();
        assert!(FileRange::of(&[]).is_none());
        FileRange::add_to(
            &mut ranges,
            (0u32, 1u32),
            FileRange::of(&[50, 20, 40]).unwrap(),
        );
        FileRange::add_to(&mut ranges, (0, 1), FileRange::of(&[90, 30]).unwrap());
        FileRange::add_to(&mut ranges, (0, 2), FileRange::of(&[5]).unwrap());
        let r = ranges[&(0, 1)];
        assert_eq!((r.first_ns, r.last_ns, r.rows), (20, 90, 5));
        assert_eq!(ranges[&(0, 2)].rows, 1);
    }
}

#[cfg(test)]
mod file_cursor_tests {
    use super::*;

    fn batch(n: usize) -> DataFrame {
        let values: Vec<i64> = (0..n as i64).collect();
        DataFrame::new(n, vec![Column::new("time".into(), values)]).unwrap()
    }

    /// (file, rows, first time) of each part; the parts' offsets in their files.
    fn firsts(parts: &[(u32, u64, DataFrame)]) -> Vec<(u32, usize, i64)> {
        parts
            .iter()
            .map(|(f, _, df)| {
                let first = df.column("time").unwrap().i64().unwrap().get(0).unwrap();
                (*f, df.height(), first)
            })
            .collect()
    }

    fn offsets(parts: &[(u32, u64, DataFrame)]) -> Vec<u64> {
        parts.iter().map(|p| p.1).collect()
    }

    #[test]
    fn batches_are_cut_at_the_footers_row_counts_and_empty_files_skipped() {
        // Files 3 (4 rows), 5 (empty), 7 (3 rows), 9 (2 rows).
        let mut cursor = FileCursor::new(vec![(3, 4), (5, 0), (7, 3), (9, 2)]);
        let parts = cursor.split(batch(6)).unwrap();
        assert_eq!(firsts(&parts), vec![(3, 4, 0), (7, 2, 4)]);
        assert_eq!(offsets(&parts), vec![0, 0]);
        assert_eq!(cursor.unread(), Some((7, 1)));
        let parts = cursor.split(batch(3)).unwrap();
        assert_eq!(firsts(&parts), vec![(7, 1, 0), (9, 2, 1)]);
        assert_eq!(offsets(&parts), vec![2, 0]);
        assert_eq!(cursor.unread(), None);
        assert!(cursor.split(batch(1)).is_err(), "rows beyond the footers");
    }

    #[test]
    fn a_batch_within_one_file_is_passed_whole() {
        let mut cursor = FileCursor::new(vec![(0, 10)]);
        let parts = cursor.split(batch(10)).unwrap();
        assert_eq!(firsts(&parts), vec![(0, 10, 0)]);
        assert_eq!(cursor.unread(), None);
        assert_eq!(FileCursor::new(vec![(2, 5)]).unread(), Some((2, 5)));
    }
}
