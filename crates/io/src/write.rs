//! Writing a campaign directory (what `simulate` produces), with options that exercise the
//! reader's tolerance: files split by day, coarser time units, shuffled rows, dictionary ids.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use polars::prelude::*;
use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::inputs::{parquet_files, ENCODERS, EVENTS, MANIFEST, TEMPERATURES};
use super::one_line;
use dbbcal_core::campaign::Manifest;
use dbbcal_core::series::CampaignTables;

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
    fn ns_per_unit(self) -> i64 {
        match self {
            TimeUnit::Ns => 1,
            TimeUnit::Us => 1_000,
            TimeUnit::Ms => 1_000_000,
        }
    }

    fn polars(self) -> polars::prelude::TimeUnit {
        match self {
            TimeUnit::Ns => polars::prelude::TimeUnit::Nanoseconds,
            TimeUnit::Us => polars::prelude::TimeUnit::Microseconds,
            TimeUnit::Ms => polars::prelude::TimeUnit::Milliseconds,
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
    /// polars could not write a table.
    #[error("{}: {message}", path.display())]
    Polars {
        /// The file.
        path: PathBuf,
        /// polars' message.
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
    /// More rows than polars can index.
    #[error("{}: more rows than polars can index ({rows})", path.display())]
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
        let events = event_frame(&dir.join(EVENTS), tables, unit)?;
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
    let text = toml::to_string(manifest).map_err(|e| WriteError::Manifest {
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

/// A table's frame plus each row's UTC day (for splitting).
struct Frame {
    df: DataFrame,
    day: Vec<i64>,
}

const NS_PER_DAY: i64 = 86_400_000_000_000;

fn polars_err(path: &Path) -> impl Fn(PolarsError) -> WriteError + '_ {
    move |e| WriteError::Polars {
        path: path.to_path_buf(),
        message: one_line(e),
    }
}

fn time_column(
    time_ns: impl Iterator<Item = i64>,
    unit: TimeUnit,
    rows: usize,
) -> (Column, Vec<i64>) {
    let mut values = Vec::with_capacity(rows);
    let mut day = Vec::with_capacity(rows);
    let per = unit.ns_per_unit();
    for t in time_ns {
        values.push(t.div_euclid(per));
        day.push(t.div_euclid(NS_PER_DAY));
    }
    let column = Int64Chunked::from_vec("time".into(), values)
        .into_datetime(unit.polars(), None)
        .into_column();
    (column, day)
}

/// An id column (`bar`, `sensor`) repeating each id for its rows; categorical when asked.
fn id_column<'a>(
    name: &str,
    ids: impl Iterator<Item = (&'a str, usize)>,
    dictionary: bool,
) -> PolarsResult<Column> {
    let values = ids.flat_map(|(id, n)| std::iter::repeat_n(id, n));
    let column = StringChunked::from_iter_values(name.into(), values).into_column();
    if dictionary {
        column.cast(&DataType::from_categories(Categories::global()))
    } else {
        Ok(column)
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
    let bar = id_column("bar", ids, opts.dictionary_strings).map_err(polars_err(path))?;
    let mut counts = Vec::with_capacity(rows);
    logs.values()
        .for_each(|l| counts.extend_from_slice(&l.counts));
    let counts = Int64Chunked::from_vec("counts".into(), counts).into_column();
    let df = DataFrame::new(rows, vec![time, bar, counts]).map_err(polars_err(path))?;
    Ok(Frame { df, day })
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
    let sensor = id_column("sensor", ids, opts.dictionary_strings).map_err(polars_err(path))?;
    let mut celsius = Vec::with_capacity(rows);
    logs.values()
        .for_each(|l| celsius.extend_from_slice(&l.celsius));
    let celsius = Float64Chunked::from_vec("celsius".into(), celsius).into_column();
    let df = DataFrame::new(rows, vec![time, sensor, celsius]).map_err(polars_err(path))?;
    Ok(Frame { df, day })
}

fn event_frame(path: &Path, tables: &CampaignTables, unit: TimeUnit) -> Result<Frame, WriteError> {
    let events = &tables.events;
    let rows = events.len();
    let (time, day) = time_column(events.iter().map(|e| e.time_ns), unit, rows);
    let bar =
        StringChunked::from_iter_options("bar".into(), events.iter().map(|e| e.bar.as_deref()))
            .into_column();
    let kind =
        StringChunked::from_iter_values("kind".into(), events.iter().map(|e| e.kind.as_str()))
            .into_column();
    let value = Float64Chunked::from_iter_options("value".into(), events.iter().map(|e| e.value))
        .into_column();
    let df = DataFrame::new(rows, vec![time, bar, kind, value]).map_err(polars_err(path))?;
    Ok(Frame { df, day })
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
        let mut df = frame.df;
        return write_parquet(&folder.join(format!("{table}.parquet")), &mut df);
    }
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed.wrapping_mul(31).wrapping_add(salt));
    for (name, mut rows) in file_rows(&frame.day, opts.split_by_day, table) {
        let path = folder.join(format!("{name}.parquet"));
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        }
        let mut df = take_rows(&path, &frame.df, rows)?;
        if opts.interleave_rows && !opts.shuffle_rows {
            let by: Vec<PlSmallStr> = df.get_column_names_owned().into_iter().take(2).collect();
            df = df
                .sort(by, SortMultipleOptions::default().with_maintain_order(true))
                .map_err(polars_err(&path))?;
        }
        write_parquet(&path, &mut df)?;
    }
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

fn take_rows(path: &Path, df: &DataFrame, rows: Vec<usize>) -> Result<DataFrame, WriteError> {
    let in_order = rows.iter().enumerate().all(|(i, &r)| i == r);
    if in_order && rows.len() == df.height() {
        return Ok(df.clone());
    }
    let n = rows.len();
    let idx: Vec<IdxSize> = rows
        .into_iter()
        .map(IdxSize::try_from)
        .collect::<Result<_, _>>()
        .map_err(|_| WriteError::TooManyRows {
            path: path.to_path_buf(),
            rows: n,
        })?;
    df.take(&IdxCa::from_vec("idx".into(), idx))
        .map_err(polars_err(path))
}

/// Writes one parquet file (zstd, statistics on; polars embeds no timestamp, so the bytes
/// depend only on the frame).
pub(crate) fn write_parquet(path: &Path, df: &mut DataFrame) -> Result<(), WriteError> {
    let file = std::fs::File::create(path).map_err(|e| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut writer = std::io::BufWriter::new(file);
    ParquetWriter::new(&mut writer)
        .finish(df)
        .map_err(polars_err(path))?;
    use std::io::Write;
    writer.flush().map_err(|e| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
