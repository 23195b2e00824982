//! Reading a campaign's tables with polars and handing them over as plain series.
//!
//! Each file is scanned lazily on its own (so every error can name its file), projected to the
//! columns the spec defines and normalised: timestamps in any unit and zone become `i64` ns UTC,
//! dictionary/categorical ids become strings, integer counts become `i64`. The per-file frames
//! are stacked, validated (nulls, unknown ids), then split per bar / sensor and sorted by time.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use polars::prelude::*;

use super::inputs::{CampaignFiles, MANIFEST};
use super::{format_ns, one_line, IngestError};
use crate::campaign::{Campaign, Manifest};
use crate::series::{BarLog, Event, SensorLog};

/// Index of the source file of each row, added while scanning, for error messages.
const FILE_COL: &str = "__source_file";

/// The accepted physical forms of one spec column.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Timestamp, ns/us/ms, any zone or none -> i64 ns UTC.
    Time,
    /// utf8 or dictionary(utf8) -> String.
    Text,
    /// Integer -> i64.
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
    spec("counts", Kind::Count, false),
];
const TEMPERATURE_COLUMNS: [ColumnSpec; 3] = [
    spec("time", Kind::Time, false),
    spec("sensor", Kind::Text, false),
    spec("celsius", Kind::Real, false),
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
            Kind::Count => "int64 or int32",
            Kind::Real => "float64",
        }
    }

    /// The expression turning column `name` of type `dtype` into the canonical type, or `None`
    /// when `dtype` is not an accepted form.
    fn normalise(self, name: &str, dtype: &DataType) -> Option<Expr> {
        let c = col(name);
        match (self, dtype) {
            // The physical value of a polars datetime is UTC epoch in its unit, zone or not.
            (Kind::Time, DataType::Datetime(unit, _)) => {
                let ns_per_unit: i64 = match unit {
                    TimeUnit::Nanoseconds => 1,
                    TimeUnit::Microseconds => 1_000,
                    TimeUnit::Milliseconds => 1_000_000,
                };
                Some(c.cast(DataType::Int64) * lit(ns_per_unit))
            }
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
            (Kind::Real, DataType::Float64 | DataType::Float32) => Some(c.cast(DataType::Float64)),
            _ => None,
        }
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
    let text = std::fs::read_to_string(&path).map_err(|e| IngestError::Io {
        path: path.clone(),
        message: e.to_string(),
    })?;
    let file = path.display().to_string();
    let manifest = Manifest::from_toml_str(&text, &file)?;
    Ok(Campaign::from_manifest_at(manifest, &file)?)
}

/// The three tables, split per bar / sensor and sorted.
pub(crate) struct Tables {
    pub bars: BTreeMap<String, BarLog>,
    pub sensors: BTreeMap<String, SensorLog>,
    pub events: Vec<Event>,
}

pub(crate) fn read_tables(
    files: &CampaignFiles,
    campaign: &Campaign,
) -> Result<Tables, IngestError> {
    let bar_ids: BTreeSet<&str> = campaign.bars.iter().map(|b| b.id.as_str()).collect();
    let sensor_ids: BTreeSet<&str> = campaign.sensors.iter().map(|s| s.id.as_str()).collect();

    let clock = std::time::Instant::now();
    let temperatures = read_table(&files.temperatures, &TEMPERATURE_COLUMNS)?;
    let readings =
        sensor_readings(&temperatures, &sensor_ids).map_err(polars_error("temperatures"))?;
    let matched = readings.values().map(DataFrame::height).sum();
    check_all_rows_known(
        &temperatures,
        matched,
        &files.temperatures,
        "sensor",
        &sensor_ids,
    )?;
    drop(temperatures);
    tracing::debug!(elapsed = ?clock.elapsed(), "temperatures read");

    let encoders = read_table(&files.encoders, &ENCODER_COLUMNS)?;
    tracing::debug!(elapsed = ?clock.elapsed(), rows = encoders.height(), "encoders scanned");
    let mut bars = BTreeMap::new();
    for bar in &bar_ids {
        let log = bar_log(&encoders, bar, &readings)
            .map_err(polars_error(&format!("encoders of bar \"{bar}\"")))?;
        bars.insert(bar.to_string(), log);
    }
    let matched = bars.values().map(|b: &BarLog| b.time_ns.len()).sum();
    check_all_rows_known(&encoders, matched, &files.encoders, "bar", &bar_ids)?;
    drop(encoders);
    tracing::debug!(elapsed = ?clock.elapsed(), "bar logs built");

    let sensors: BTreeMap<String, SensorLog> = readings
        .iter()
        .map(|(id, df)| Ok((id.clone(), sensor_log(df)?)))
        .collect::<PolarsResult<_>>()
        .map_err(polars_error("temperatures"))?;
    Ok(Tables {
        bars,
        sensors,
        events: read_events(&files.events, &bar_ids)?,
    })
}

/// The rows of known ids were extracted (`matched` of them); if that is not every row, some id
/// is unknown and [`check_ids`] finds and names it. This keeps the costly per-file summary off
/// the path of a good campaign.
fn check_all_rows_known(
    df: &DataFrame,
    matched: usize,
    files: &[PathBuf],
    id_column: &'static str,
    known: &BTreeSet<&str>,
) -> Result<(), IngestError> {
    if matched == df.height() {
        return Ok(());
    }
    check_ids(df, files, id_column, known)?;
    Err(IngestError::Polars {
        context: id_column.to_string(),
        message: format!(
            "{matched} of {} rows have a declared id, but no undeclared id was found",
            df.height()
        ),
    })
}

fn polars_error(context: &str) -> impl Fn(PolarsError) -> IngestError + '_ {
    move |e| IngestError::Polars {
        context: context.to_string(),
        message: one_line(e),
    }
}

// ---------------------------------------------------------------- scanning

/// Scans, normalises and stacks every file of one table; adds [`FILE_COL`] and checks nulls.
fn read_table(files: &[PathBuf], columns: &[ColumnSpec]) -> Result<DataFrame, IngestError> {
    let mut stacked: Option<DataFrame> = None;
    for (index, path) in files.iter().enumerate() {
        let df = read_file(path, columns, index)?;
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

/// One file, projected to the spec's columns in canonical types.
fn read_file(path: &Path, columns: &[ColumnSpec], index: usize) -> Result<DataFrame, IngestError> {
    let source = PlRefPath::try_from_path(path).map_err(|e| not_parquet(path, e))?;
    let args = ScanArgsParquet {
        glob: false,
        ..Default::default()
    };
    let mut lazy = LazyFrame::scan_parquet(source, args).map_err(|e| not_parquet(path, e))?;
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
    let index = u32::try_from(index).unwrap_or(u32::MAX);
    exprs.push(lit(index).cast(DataType::UInt32).alias(FILE_COL));
    lazy.select(exprs)
        .collect()
        .map_err(|e| not_parquet(path, e))
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

fn file_path(files: &[PathBuf], index: u32) -> PathBuf {
    files.get(index as usize).cloned().unwrap_or_default()
}

/// Rejects ids (bar or sensor) the manifest does not declare, naming file, id, row count and
/// time range. Null ids are skipped (they are either checked by [`check_nulls`] or allowed).
fn check_ids(
    df: &DataFrame,
    files: &[PathBuf],
    id_column: &'static str,
    known: &BTreeSet<&str>,
) -> Result<(), IngestError> {
    let summary = id_summary(df, id_column).map_err(polars_error(id_column))?;
    for row in summary {
        if known.contains(row.id.as_str()) {
            continue;
        }
        return Err(IngestError::UnknownId {
            path: file_path(files, row.file),
            column: id_column,
            id: row.id,
            rows: row.rows,
            first: format_ns(row.first_ns),
            last: format_ns(row.last_ns),
            known: known.iter().copied().collect::<Vec<_>>().join(", "),
        });
    }
    Ok(())
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

fn sensor_log(readings: &DataFrame) -> PolarsResult<SensorLog> {
    Ok(SensorLog {
        time_ns: i64_values(readings, "time")?,
        celsius: f64_values(readings, "celsius")?,
    })
}

fn bar_log(
    encoders: &DataFrame,
    bar: &str,
    readings: &BTreeMap<String, DataFrame>,
) -> PolarsResult<BarLog> {
    let rows = rows_of(encoders, "bar", bar, ["time", "counts"])?;
    let times = rows.select(["time"])?;
    let mut celsius = BTreeMap::new();
    for (sensor, sensor_rows) in readings {
        if sensor_rows.height() == 0 {
            continue;
        }
        celsius.insert(sensor.clone(), celsius_at(&times, sensor_rows)?);
    }
    Ok(BarLog {
        time_ns: i64_values(&rows, "time")?,
        counts: i64_values(&rows, "counts")?,
        celsius,
    })
}

/// A sensor's temperature at each of `times` (sorted): backward as-of join (latest reading at
/// or before), then a backward fill so times before the first reading get the first reading.
fn celsius_at(times: &DataFrame, sensor_rows: &DataFrame) -> PolarsResult<Vec<f64>> {
    let options = AsOfOptions {
        strategy: AsofStrategy::Backward,
        allow_eq: true,
        check_sortedness: true,
        ..Default::default()
    };
    let joined = times
        .clone()
        .lazy()
        .join_builder()
        .with(sensor_rows.clone().lazy())
        .left_on([col("time")])
        .right_on([col("time")])
        .how(JoinType::AsOf(Box::new(options)))
        .finish()
        .select([col("celsius").fill_null_with_strategy(FillNullStrategy::Backward(None))])
        .collect()?;
    f64_values(&joined, "celsius")
}

/// Values of a column checked free of nulls (a null, which cannot occur here, would read NaN).
fn f64_values(df: &DataFrame, name: &str) -> PolarsResult<Vec<f64>> {
    Ok(df
        .column(name)?
        .f64()?
        .iter()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect())
}

/// Values of a column checked free of nulls by [`check_nulls`].
fn i64_values(df: &DataFrame, name: &str) -> PolarsResult<Vec<i64>> {
    Ok(df.column(name)?.i64()?.into_no_null_iter().collect())
}

// ---------------------------------------------------------------- events

fn read_events(files: &[PathBuf], bar_ids: &BTreeSet<&str>) -> Result<Vec<Event>, IngestError> {
    if files.is_empty() {
        return Ok(Vec::new());
    }
    let table = read_table(files, &EVENT_COLUMNS)?;
    check_ids(&table, files, "bar", bar_ids)?;
    events_sorted(table).map_err(polars_error("events"))
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
            kind: kind.get(i).unwrap_or_default().to_string(),
            value: value.get(i),
        })
        .collect())
}
