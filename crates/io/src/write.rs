//! Writing a campaign directory (what `simulate` produces), with options that exercise the
//! reader's tolerance: files split by day, coarser time units, shuffled rows, dictionary ids.

use crate::manifest::TomlManifest;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use arrow_array::ArrayRef;
use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::inputs::{parquet_files, ENCODERS, EVENTS, MANIFEST, TEMPERATURES};
use super::kind_write::{column, timestamps, Columns};
use super::one_line;
use arrow_array::cast::AsArray;
use arrow_array::{Array, StringViewArray};
use dbbcal_core::campaign::Manifest;
use dbbcal_core::series::CampaignTables;
use std::sync::Arc;

/// Resolution of the written `time` columns (values are floored to it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeUnit {
    /// Nanoseconds.
    #[default]
    Ns,
    /// Microseconds.
    Us,
    /// Milliseconds.
    Ms,
}

impl TimeUnit {
    pub(crate) fn ns_per_unit(self) -> i64 {
        match self {
            TimeUnit::Ns => 1,
            TimeUnit::Us => 1_000,
            TimeUnit::Ms => 1_000_000,
        }
    }
}

/// How [`write_campaign`] lays out the tables. The default is one file per table, ns, rows in
/// (id, time) order, plain strings.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct WriteOptions {
    /// One file per UTC day (`2026-11-01.parquet`) instead of one per table.
    pub split_by_day: bool,
    /// Unit of the timestamp columns.
    pub time_unit: TimeUnit,
    /// Shuffle the rows inside each file (seeded by `seed`).
    pub shuffle_rows: bool,
    /// Rows sorted by time, ties by id, inside each file: the ids interleaved, as a logger of
    /// many bars writes them (unless `shuffle_rows`).
    pub interleave_rows: bool,
    /// Write `bar` / `sensor` as dictionary (categorical) columns.
    pub dictionary_strings: bool,
    /// Seed of the row shuffle.
    pub seed: u64,
}

/// Why a campaign or an output table could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// A file could not be written.
    #[error("{}: {message}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        message: String,
    },
    /// The parquet writer could not write a table.
    #[error("{}: {message}", path.display())]
    Parquet {
        /// The file.
        path: PathBuf,
        /// The writer's message.
        message: String,
    },
    /// The manifest could not be serialised.
    #[error("{}: cannot serialise the manifest: {message}", path.display())]
    Manifest {
        /// The file.
        path: PathBuf,
        /// The serialiser's message.
        message: String,
    },
    /// The columns of a table differ in length.
    #[error("{}: column `{column}` has {rows} rows, expected {expected}", path.display())]
    RaggedTable {
        /// The file.
        path: PathBuf,
        /// The column.
        column: String,
        /// Its rows.
        rows: usize,
        /// The table's rows.
        expected: usize,
    },
    /// Two columns share a name.
    #[error("{}: column `{column}` appears twice", path.display())]
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// The name.
        column: String,
    },
    /// More rows than one parquet table can index (a file's rows are counted in `i64`, a
    /// string column's bytes in `i32` offsets).
    #[error("{}: more rows than one parquet table can index ({rows})", path.display())]
    TooManyRows {
        /// The file.
        path: PathBuf,
        /// The rows.
        rows: usize,
    },
}

/// Writes `campaign.toml` and the three tables under `dir` (created if needed). Existing
/// `*.parquet` files in the table folders are removed first, so that a rewrite with other
/// options never leaves stale files for the reader to pick up. No events: no `events/` files.
pub fn write_campaign(
    dir: &Path,
    manifest: &Manifest,
    tables: &CampaignTables,
    opts: &WriteOptions,
) -> Result<(), WriteError> {
    create_dir(dir)?;
    write_manifest(&dir.join(MANIFEST), manifest)?;
    let unit = opts.time_unit;
    let encoders = encoder_frame(&dir.join(ENCODERS), tables, opts)?;
    write_table_files(&dir.join(ENCODERS), ENCODERS, encoders, opts, 1)?;
    let temperatures = temperature_frame(&dir.join(TEMPERATURES), tables, opts)?;
    write_table_files(&dir.join(TEMPERATURES), TEMPERATURES, temperatures, opts, 2)?;
    clear_parquet(&dir.join(EVENTS))?;
    if !tables.events.is_empty() {
        let events = event_frame(tables, unit);
        write_table_files(&dir.join(EVENTS), EVENTS, events, opts, 3)?;
    }
    Ok(())
}

fn create_dir(dir: &Path) -> Result<(), WriteError> {
    std::fs::create_dir_all(dir).map_err(|e| WriteError::Io {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })
}

fn write_manifest(path: &Path, manifest: &Manifest) -> Result<(), WriteError> {
    let text = manifest
        .to_toml_string()
        .map_err(|e| WriteError::Manifest {
            path: path.to_path_buf(),
            message: one_line(e),
        })?;
    std::fs::write(path, text).map_err(|e| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

pub(crate) fn clear_parquet(folder: &Path) -> Result<(), WriteError> {
    let stale = parquet_files(folder).map_err(|e| WriteError::Io {
        path: folder.to_path_buf(),
        message: one_line(e),
    })?;
    for file in stale {
        std::fs::remove_file(&file).map_err(|e| WriteError::Io {
            path: file.clone(),
            message: e.to_string(),
        })?;
    }
    Ok(())
}

// ---------------------------------------------------------------- building frames

/// A table's columns plus each row's UTC day (for splitting).
struct Frame {
    columns: Columns,
    day: Vec<i64>,
}

const NS_PER_DAY: i64 = 86_400_000_000_000;

/// The `time` column (floored to `unit`) and each row's UTC day.
fn time_column(
    time_ns: impl Iterator<Item = i64>,
    unit: TimeUnit,
    rows: usize,
) -> ((String, ArrayRef), Vec<i64>) {
    let mut values = Vec::with_capacity(rows);
    let mut day = Vec::with_capacity(rows);
    let per = unit.ns_per_unit();
    for t in time_ns {
        values.push(Some(t.div_euclid(per)));
        day.push(t.div_euclid(NS_PER_DAY));
    }
    (("time".into(), timestamps(values, unit, None)), day)
}

/// An id column (`bar`, `sensor`) repeating each id for its rows; categorical when asked.
fn id_column<'a>(
    name: &str,
    ids: impl Iterator<Item = (&'a str, usize)>,
    dictionary: bool,
) -> (String, ArrayRef) {
    let values = ids.flat_map(|(id, n)| std::iter::repeat_n(id, n));
    if dictionary {
        super::kind_write::dictionary(name, values)
    } else {
        (
            name.into(),
            Arc::new(StringViewArray::from_iter_values(values)),
        )
    }
}

fn check_len(path: &Path, column: &str, rows: usize, expected: usize) -> Result<(), WriteError> {
    if rows == expected {
        Ok(())
    } else {
        Err(WriteError::RaggedTable {
            path: path.to_path_buf(),
            column: column.to_string(),
            rows,
            expected,
        })
    }
}

fn encoder_frame(
    path: &Path,
    tables: &CampaignTables,
    opts: &WriteOptions,
) -> Result<Frame, WriteError> {
    let logs = &tables.encoders;
    for (bar, log) in logs {
        check_len(
            path,
            &format!("counts of bar {bar}"),
            log.counts.len(),
            log.time_ns.len(),
        )?;
    }
    let rows: usize = logs.values().map(|l| l.time_ns.len()).sum();
    let times = logs.values().flat_map(|l| l.time_ns.iter().copied());
    let (time, day) = time_column(times, opts.time_unit, rows);
    let ids = logs.iter().map(|(id, l)| (id.as_str(), l.time_ns.len()));
    let bar = id_column("bar", ids, opts.dictionary_strings);
    let mut counts = Vec::with_capacity(rows);
    logs.values()
        .for_each(|l| counts.extend_from_slice(&l.counts));
    let counts = column("counts", counts);
    Ok(Frame {
        columns: vec![time, bar, counts],
        day,
    })
}

fn temperature_frame(
    path: &Path,
    tables: &CampaignTables,
    opts: &WriteOptions,
) -> Result<Frame, WriteError> {
    let logs = &tables.temperatures;
    for (sensor, log) in logs {
        check_len(
            path,
            &format!("celsius of sensor {sensor}"),
            log.celsius.len(),
            log.time_ns.len(),
        )?;
    }
    let rows: usize = logs.values().map(|l| l.time_ns.len()).sum();
    let times = logs.values().flat_map(|l| l.time_ns.iter().copied());
    let (time, day) = time_column(times, opts.time_unit, rows);
    let ids = logs.iter().map(|(id, l)| (id.as_str(), l.time_ns.len()));
    let sensor = id_column("sensor", ids, opts.dictionary_strings);
    let mut celsius = Vec::with_capacity(rows);
    logs.values()
        .for_each(|l| celsius.extend_from_slice(&l.celsius));
    let celsius = column("celsius", celsius);
    Ok(Frame {
        columns: vec![time, sensor, celsius],
        day,
    })
}

fn event_frame(tables: &CampaignTables, unit: TimeUnit) -> Frame {
    let events = &tables.events;
    let rows = events.len();
    let (time, day) = time_column(events.iter().map(|e| e.time_ns), unit, rows);
    let bar = column(
        "bar",
        events.iter().map(|e| e.bar.as_deref()).collect::<Vec<_>>(),
    );
    let kind = column(
        "kind",
        events.iter().map(|e| e.kind.as_str()).collect::<Vec<_>>(),
    );
    let value = column("value", events.iter().map(|e| e.value).collect::<Vec<_>>());
    Frame {
        columns: vec![time, bar, kind, value],
        day,
    }
}

// ---------------------------------------------------------------- files

/// Writes `frame` under `folder` as one file or one per day, rows shuffled if asked.
/// `salt` decorrelates the shuffles of the different tables.
fn write_table_files(
    folder: &Path,
    table: &str,
    frame: Frame,
    opts: &WriteOptions,
    salt: u64,
) -> Result<(), WriteError> {
    create_dir(folder)?;
    clear_parquet(folder)?;
    if !opts.split_by_day && !opts.shuffle_rows && !opts.interleave_rows {
        return write_parquet(&folder.join(format!("{table}.parquet")), frame.columns);
    }
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed.wrapping_mul(31).wrapping_add(salt));
    for (name, mut rows) in file_rows(&frame.day, opts.split_by_day, table) {
        let path = folder.join(format!("{name}.parquet"));
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        } else if opts.interleave_rows {
            interleave(&path, &frame.columns, &mut rows)?;
        }
        write_parquet(&path, take_rows(&path, &frame.columns, rows)?)?;
    }
    Ok(())
}

/// Sorts `rows` by time, ties by id (stable: rows of one time and id keep their order): the
/// first two columns, as [`time_column`] and [`id_column`] build them.
fn interleave(path: &Path, columns: &Columns, rows: &mut [usize]) -> Result<(), WriteError> {
    let failed = |e: arrow_schema::ArrowError| WriteError::Parquet {
        path: path.to_path_buf(),
        message: one_line(e),
    };
    let (Some(time), Some(id)) = (columns.first(), columns.get(1)) else {
        return Ok(());
    };
    let time = arrow_cast::cast(&time.1, &arrow_schema::DataType::Int64).map_err(failed)?;
    let id = arrow_cast::cast(&id.1, &arrow_schema::DataType::Utf8).map_err(failed)?;
    let (time, id) = (
        time.as_primitive::<arrow_array::types::Int64Type>(),
        id.as_string::<i32>(),
    );
    let key = |r: usize| {
        (
            time.is_valid(r).then(|| time.value(r)),
            id.is_valid(r).then(|| id.value(r)),
        )
    };
    rows.sort_by(|&a, &b| key(a).cmp(&key(b)));
    Ok(())
}

/// File name -> row indices: all rows in one file named after the table, or one file per UTC
/// day. Always at least one file, so an empty table still has its schema on disk.
fn file_rows(day: &[i64], split_by_day: bool, table: &str) -> BTreeMap<String, Vec<usize>> {
    if !split_by_day || day.is_empty() {
        return BTreeMap::from([(table.to_string(), (0..day.len()).collect())]);
    }
    let mut by_day: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (row, &d) in day.iter().enumerate() {
        by_day.entry(d).or_default().push(row);
    }
    by_day
        .into_iter()
        .map(|(d, rows)| (day_name(d), rows))
        .collect()
}

fn day_name(day: i64) -> String {
    chrono::DateTime::from_timestamp(day.saturating_mul(86_400), 0)
        .map_or_else(|| format!("day{day}"), |t| t.format("%Y-%m-%d").to_string())
}

fn take_rows(path: &Path, columns: &Columns, rows: Vec<usize>) -> Result<Columns, WriteError> {
    let n = rows.len();
    let in_order = rows.iter().enumerate().all(|(i, &r)| i == r);
    if in_order && columns.first().is_none_or(|c| c.1.len() == n) {
        return Ok(columns.clone());
    }
    let indices: Vec<u64> = rows.into_iter().map(|r| r as u64).collect();
    let indices = arrow_array::UInt64Array::from(indices);
    columns
        .iter()
        .map(|(name, values)| {
            let taken = arrow_select::take::take(values.as_ref(), &indices, None).map_err(|e| {
                WriteError::Parquet {
                    path: path.to_path_buf(),
                    message: one_line(e),
                }
            })?;
            Ok((name.clone(), taken))
        })
        .collect()
}

/// Writes one parquet file of `columns` (zstd, statistics on; the writer embeds no timestamp,
/// so the bytes depend only on the columns).
pub(crate) fn write_parquet(path: &Path, columns: Columns) -> Result<(), WriteError> {
    crate::pq::write_columns(path, columns)
}
