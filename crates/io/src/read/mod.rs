//! Reading a campaign's tables with the parquet crate's arrow reader and handing them over as
//! plain series.
//!
//! Each file is opened on its own (so every error can name its file), projected to the columns
//! the spec defines (a `ProjectionMask`: no other column is decoded) and normalised: timestamps
//! in any unit and zone become `i64` ns UTC, dictionary/categorical ids become strings, integer
//! counts become `i64`. The small tables' rows are stacked, validated (nulls, unknown ids), then
//! split per sensor and sorted by time.
//!
//! The encoder table (tens of millions of rows) is never stacked: each file is streamed row
//! group by row group in batches, and every batch is split into per-bar `time` /
//! `counts` buffers as it arrives, so ingest holds the per-bar logs and one batch, not the
//! table beside them. Temperatures are not joined onto the encoder times here: `series`
//! interpolates each sensor's log per bar (`interpolate_temperatures`), one bar at a time.
//!
//! # How it works
//!
//! - Ingest streams each encoder file in batches (the parquet crate's arrow reader, one row group
//!   at a time) into per-bar `time`/`counts` vectors or bins: the encoder table is never stacked,
//!   and temperatures are not joined onto every encoder time (each bar interpolates the sensor
//!   logs when it is processed).
//! - Every file's schema is checked from its footer before any row is read; the files' row
//!   groups are then the work items (`io::read::stream_encoders`), each batch knowing its file and
//!   its rows' offset in that file, so rows that cannot be used (a null, an undeclared id, a time
//!   out of range) are named by file and rows in the one pass.
//! - Cost and memory do not depend on the row order (the format allows any; a logger of many bars
//!   interleaves them). Each batch's bar ids are decoded as a dictionary and become small indices
//!   by looking each distinct value up once (`io::read::IdIndex`); a
//!   batch of few runs of one bar goes run by run, any other is grouped by bar with a stable
//!   counting sort, so every bar gets its rows as one slice whatever the interleaving. A full-rate
//!   log is reserved from the parquet footers' row counts and, when not sorted, sorted per bar in
//!   parallel at the end.
//! - Two consumer threads (`io::read::BATCH_CONSUMERS`) each take whole row groups, decode them
//!   and split every batch per bar, accumulating into sinks of their own
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
//!   the first three. The bin accumulator
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
//!   hook while a guard is active), which announces its file to the supervisor: a crash while
//!   several files are being decoded (one per consumer) is probed file by file by the supervisor
//!   (`supervise::probe`, `io::decode_whole_file` in a child each).
//! - Rows that several encoder files hold: `io::read::EncoderSink` records each (file, bar) time
//!   range and row count while streaming (every batch knows its file); `io::read::resolve_repeats` re-reads,
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

use crate::manifest::TomlManifest;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use arrow_array::cast::AsArray;
use arrow_array::types::Int32Type;
use arrow_array::types::{Float64Type, Int64Type};
use arrow_array::{
    Array, ArrayRef, BooleanArray, DictionaryArray, Float64Array, Int64Array, RecordBatch,
    StringArray,
};
use arrow_schema::{ArrowError, DataType, TimeUnit};
use parquet::arrow::arrow_reader::ParquetRecordBatchReader;

use super::guard::guarded;
use super::inputs::{CampaignFiles, MANIFEST};
use super::pq::{not_parquet, ParquetFile};
use super::repeats::{RepeatSketch, RepeatWindows};
use super::IngestError;
use dbbcal_core::campaign::{Campaign, Manifest, SensorKind};
use dbbcal_core::series::quality::{
    self, ChannelQuality, Flag, FlagNote, LogTable, Missing, RowProblem,
};
use dbbcal_core::series::{
    counts_ok, reading_time_ok, reading_times_ok, BarBins, BarLog, BinAccumulator, BinGrid, Event,
    EventKind, Quality, SensorLog, MAX_ABS_COUNTS,
};

mod columns;
use columns::*;
mod scan;
pub(crate) use scan::footer_rows;
use scan::*;
mod encoders;
use encoders::*;
mod overlaps;
use overlaps::*;
mod stream;
use stream::*;
mod rows;
use rows::*;
mod sensors;
use sensors::read_temperatures;
mod positions;
pub(crate) use positions::read_positions_files;

/// The path and text of `dir/campaign.toml` (any kind), read within its size bound.
pub(crate) fn read_manifest_text(dir: &Path) -> Result<(PathBuf, String), IngestError> {
    let path = dir.join(MANIFEST);
    if !path.is_file() {
        return Err(IngestError::MissingManifest {
            dir: dir.to_path_buf(),
        });
    }
    let text =
        crate::read_small_text(&path, crate::MAX_MANIFEST_BYTES).map_err(|e| IngestError::Io {
            path: path.clone(),
            message: e.why.to_string(),
        })?;
    Ok((path, text))
}

/// Reads and validates `campaign.toml`.
pub(crate) fn read_manifest(dir: &Path) -> Result<Campaign, IngestError> {
    let (path, text) = read_manifest_text(dir)?;
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
            Err(IngestError::Parquet {
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
        missing.record(q, LogTable::Encoders);
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
pub(super) type TemperatureTables = (
    BTreeMap<String, SensorLog>,
    BTreeMap<String, ChannelQuality>,
    Vec<(PathBuf, bool)>,
    Vec<Flag>,
);

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
    let mut encoders = read_encoders(&files.encoders, bar_ids, &grids, rows_hint, &mut zones)?;
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
    let note = FlagNote::MixedTimeZones {
        naive_files: naive.len(),
        zoned_files: zoned,
        naive_example: name(naive[0]),
    };
    quality.files.push(Flag::file(note, 0));
}

/// Rows of ids the manifest does not declare, per file and id (null ids are skipped).
fn unknown_id_flags(
    table: &TableRows,
    files: &[PathBuf],
    id_column: &'static str,
    known: &BTreeSet<&str>,
) -> Vec<Flag> {
    let declared: Vec<String> = known.iter().map(|k| k.to_string()).collect();
    id_summary(table, id_column)
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
                &declared,
            )
        })
        .collect()
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
    dropped.extend(unknown_id_flags(&table, files, "bar", bar_ids));
    // Events of undeclared bars are dropped (a null bar: a setup-wide event).
    let events = events_sorted(&table, bar_ids);
    q.rows = events.len() as u64;
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
    missing.record(q, LogTable::Events);
    Ok(kept)
}

/// The events of declared bars (or none), sorted by time, bar, kind and value (nulls first).
fn events_sorted(table: &TableRows, bar_ids: &BTreeSet<&str>) -> Vec<Event> {
    let (Some(bar), Some(kind)) = (table.text("bar"), table.text("kind")) else {
        return Vec::new();
    };
    let value = table.real("value").unwrap_or_default();
    let mut rows: Vec<(i64, Option<&str>, &str, Option<f64>)> = (0..table.height())
        .map(|i| {
            let v = value.get(i).copied().flatten();
            (
                table.time[i],
                bar.get(i),
                kind.get(i).unwrap_or_default(),
                v,
            )
        })
        .filter(|r| r.1.is_none_or(|b| bar_ids.contains(b)))
        .collect();
    rows.sort_by(|a, b| {
        (a.0, a.1, a.2)
            .cmp(&(b.0, b.1, b.2))
            .then_with(|| match (a.3, b.3) {
                (Some(x), Some(y)) => x.total_cmp(&y),
                (x, y) => x.is_some().cmp(&y.is_some()),
            })
    });
    rows.into_iter()
        .map(|(time_ns, bar, kind, value)| Event {
            time_ns,
            bar: bar.map(str::to_string),
            kind: EventKind::parse(kind),
            value,
        })
        .collect()
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
mod row_group_tests {
    use super::*;
    use crate::test_frames::{col, df, raw_time_col, write_df_in_groups, Unit};

    const T0: i64 = 1_793_491_200_000_000_000;

    /// An encoder file of `bars` (`None`: a null bar) at one reading a second, in row groups of
    /// four rows.
    fn write(path: &Path, bars: &[Option<&str>]) {
        let n = bars.len() as i64;
        let times = (0..n).map(|i| Some(T0 + i * 1_000_000_000)).collect();
        let batch = df(vec![
            raw_time_col("time", times, Unit::Nanoseconds, None),
            col("bar", bars.to_vec()),
            col("counts", (0..n).collect::<Vec<i64>>()),
        ]);
        write_df_in_groups(path, batch, 4);
    }

    #[test]
    fn every_row_group_is_a_task_with_its_first_row_in_its_file_and_empty_files_none() {
        let dir = tempfile::tempdir().expect("tempdir");
        let files: Vec<PathBuf> = ["a", "b", "c"]
            .iter()
            .map(|n| dir.path().join(format!("{n}.parquet")))
            .collect();
        write(&files[0], &[Some("B01"); 10]);
        write(&files[1], &[]);
        write(&files[2], &[Some("B01"); 3]);
        let scans: Vec<Scan> = files
            .iter()
            .map(|p| checked_scan(p, &ENCODER_COLUMNS).expect("scan"))
            .collect();
        let tasks: Vec<(u32, usize, u64)> = row_group_tasks(&scans)
            .iter()
            .map(|t| (t.file, t.group, t.row_offset))
            .collect();
        assert_eq!(tasks, vec![(0, 0, 0), (0, 1, 4), (0, 2, 8), (2, 0, 0)]);
    }

    #[test]
    fn rows_of_later_row_groups_are_named_by_their_row_in_their_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let files = vec![dir.path().join("a.parquet"), dir.path().join("b.parquet")];
        let mut a = vec![Some("B01"); 10];
        a[5] = None;
        a[9] = None;
        write(&files[0], &a);
        write(&files[1], &[Some("B01"), None, Some("B01")]);
        let bars: BTreeSet<&str> = ["B01"].into_iter().collect();
        let kept = |_: &str| BarRows::Kept {
            time_ns: Vec::new(),
            counts: Vec::new(),
        };
        let sink = stream_encoders(&files, &bars, &kept, &mut Vec::new()).expect("read");
        let range = |file: u32| {
            let b = &sink.bad[&(file, "bar", RowProblem::Null)];
            (b.rows, b.first_row, b.last_row)
        };
        assert_eq!(range(0), (2, 5, 9));
        assert_eq!(range(1), (1, 1, 1));
        let BarRows::Kept { time_ns, .. } = &sink.bars[0] else {
            panic!("kept rows")
        };
        assert_eq!(time_ns.len(), 8 + 2);
    }
}
