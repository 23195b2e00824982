//! Reading an `axis` campaign (`docs/spec/machine-formats.md`, "Kind axis") with the parquet crate and
//! handing it over as plain data ([`AxisCampaignLogs`]).
//!
//! Small tables (a few thousand readings): each file is decoded whole under
//! [`crate::guard::guarded`] (a panic is one line naming the file), its columns normalised as
//! the reader rules allow — timestamps ns/us/ms, naive (= UTC) or zoned, scaled to ns with
//! checked arithmetic; integers int8 … int64 (and unsigned); strings utf8 or dictionary — and
//! checked row by row. Unlike the ballbar reader nothing is dropped: a row that cannot be used
//! (a null where a value is needed, a NaN deviation, a channel that is not `dx`/`dy`/`dz`, a
//! line the manifest does not declare, a time out of 1980 … 2200) refuses the campaign with one
//! line naming the file, the column and the rows (counting from 0 in that file). The order and
//! the directions follow `dbbcal_core::axis_campaign::derive_order`, so files split in any way
//! and rows in any order give the same logs; a reading several files hold (equal in every
//! spec column) is kept once and counted (`AxisCampaignLogs::duplicate_readings`). Extra columns of `readings/` are kept by name
//! (numbers and booleans as f64, anything else as text); extra columns of the other tables are
//! ignored. Every input file is hashed (sha256) before the read and checked unchanged after it,
//! as `read_campaign` does. Temperatures with a non-finite `celsius` are missing readings and
//! left out of the sensor's log.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use arrow_array::cast::AsArray;
use arrow_array::types::{Float64Type, Int64Type};
use arrow_array::{ArrayRef, RecordBatch};
use arrow_cast::CastOptions;
use arrow_schema::{DataType, TimeUnit};

use super::guard::guarded;
use super::inputs::{check_unchanged, parquet_files};
use super::kind_read::{kind_manifest_text, required_table, snapshot};
use super::IngestError;
use crate::manifest::TomlCampaign;
use dbbcal_core::axis_campaign::{
    derive_order, AxisCampaign, AxisCampaignLogs, AxisReading, CampaignKind, Channel,
    EnvironmentRow, ExtraColumn, FixtureRow, ReadingKey,
};
use dbbcal_core::series::{reading_time_ok, Event, EventKind, SensorLog};

/// The folders of an `axis` campaign.
const READINGS: &str = "readings";
const FIXTURE: &str = "fixture";
const ENVIRONMENT: &str = "environment";
const TEMPERATURES: &str = "temperatures";
const EVENTS: &str = "events";
const MANIFEST: &str = "campaign.toml";

/// The columns `readings/*.parquet` defines (the rest are kept as extra columns).
const READING_COLUMNS: [&str; 7] = [
    "time",
    "line",
    "run",
    "direction",
    "target_mm",
    "channel",
    "deviation_um",
];

/// Plausible environment values (both ends included): what no laser's sensors read is a unit
/// mix-up (pressure in Pa, humidity as a fraction read as %), refused by rows.
const AIR_C: (f64, f64) = (-50.0, 100.0);
const PRESSURE_HPA: (f64, f64) = (500.0, 1_200.0);
const HUMIDITY_PCT: (f64, f64) = (0.0, 100.0);
const MATERIAL_C: (f64, f64) = (-50.0, 150.0);

/// Reads an `axis` campaign directory: `campaign.toml` (`[campaign] kind = "axis"`),
/// `readings/*.parquet` (required), `fixture/*.parquet`, `environment/*.parquet` (required
/// unless `compensation = "air+material"`), `temperatures/*.parquet` (sensors declared in
/// `[[sensor]]`) and `events/*.parquet`, all optional otherwise.
pub fn read_axis_campaign(dir: &Path) -> Result<AxisCampaignLogs, IngestError> {
    let manifest = dir.join(MANIFEST);
    let campaign = read_axis_manifest(dir)?;
    let readings_files = required_table(dir, READINGS)?;
    let fixture_files = parquet_files(&dir.join(FIXTURE))?;
    let environment_files = parquet_files(&dir.join(ENVIRONMENT))?;
    let temperature_files = parquet_files(&dir.join(TEMPERATURES))?;
    let event_files = parquet_files(&dir.join(EVENTS))?;
    let (before, inputs) = snapshot(
        dir,
        &manifest,
        &[
            &readings_files,
            &fixture_files,
            &environment_files,
            &temperature_files,
            &event_files,
        ],
    )?;

    let Readings {
        readings,
        extra,
        duplicates,
    } = read_readings(&readings_files, &campaign)?;
    let fixture = read_fixture(&fixture_files, &campaign)?;
    let environment = read_environment(&environment_files)?;
    campaign.check_environment(!environment.is_empty(), &manifest.display().to_string())?;
    let temperatures = read_temperatures(&temperature_files, &campaign)?;
    let events = read_events(&event_files)?;
    check_unchanged(dir, &before, &inputs)?;
    Ok(AxisCampaignLogs {
        campaign,
        inputs,
        readings,
        extra,
        duplicate_readings: duplicates,
        fixture,
        environment,
        temperatures,
        events,
    })
}

/// Reads and validates the `campaign.toml` of an `axis` campaign; another kind is refused, named.
pub fn read_axis_manifest(dir: &Path) -> Result<AxisCampaign, IngestError> {
    let (file, text) = kind_manifest_text(dir, CampaignKind::Axis, "an axis campaign")?;
    Ok(AxisCampaign::from_toml_str(&text, &file)?)
}

// ---------------------------------------------------------------- one file's columns

/// One decoded file.
pub(crate) struct Decoded<'a> {
    path: &'a Path,
    batch: RecordBatch,
}

/// A cast that refuses a value it cannot hold (a `u64` beyond `i64`) instead of nulling it.
const STRICT: CastOptions<'static> = CastOptions {
    safe: false,
    format_options: arrow_cast::display::FormatOptions::new(),
};

impl<'a> Decoded<'a> {
    pub(crate) fn read(path: &'a Path) -> Result<Decoded<'a>, IngestError> {
        let batch = guarded(path, || crate::pq::read_whole(path))?;
        Ok(Decoded { path, batch })
    }

    pub(crate) fn rows(&self) -> usize {
        self.batch.num_rows()
    }

    pub(crate) fn has(&self, name: &str) -> bool {
        self.batch.schema().index_of(name).is_ok()
    }

    /// The names of the file's columns, in order.
    pub(crate) fn names(&self) -> Vec<String> {
        self.batch
            .schema()
            .fields()
            .iter()
            .map(|f| f.name().to_string())
            .collect()
    }

    /// Whether column `name` is present with no type (every value null).
    pub(crate) fn is_null_typed(&self, name: &str) -> bool {
        self.batch
            .column_by_name(name)
            .is_some_and(|c| c.data_type() == &DataType::Null)
    }

    pub(crate) fn column(&self, name: &'static str) -> Result<&ArrayRef, IngestError> {
        self.batch
            .column_by_name(name)
            .ok_or_else(|| IngestError::MissingColumn {
                path: self.path.to_path_buf(),
                column: name,
                found: self.names().join(", "),
            })
    }

    fn wrong_type(
        &self,
        name: &'static str,
        found: &DataType,
        expected: &'static str,
    ) -> IngestError {
        IngestError::WrongType {
            path: self.path.to_path_buf(),
            column: name,
            found: crate::pq::type_name(found),
            expected,
        }
    }

    /// `column` cast to `to`, refusing values it cannot hold.
    fn cast(&self, column: &ArrayRef, to: &DataType) -> Result<ArrayRef, IngestError> {
        arrow_cast::cast_with_options(column, to, &STRICT)
            .map_err(|e| crate::pq::not_parquet(self.path, e))
    }

    /// A timestamp column as ns UTC (`None`: null); a time that overflows ns or lies outside
    /// 1980 … 2200 refuses the rows.
    pub(crate) fn time(&self, name: &'static str) -> Result<Vec<Option<i64>>, IngestError> {
        let column = self.column(name)?;
        let DataType::Timestamp(unit, _) = column.data_type() else {
            return Err(self.wrong_type(
                name,
                column.data_type(),
                "a timestamp (ns, us or ms; naive or zoned)",
            ));
        };
        let per: i64 = match unit {
            TimeUnit::Nanosecond => 1,
            TimeUnit::Microsecond => 1_000,
            TimeUnit::Millisecond => 1_000_000,
            TimeUnit::Second => 1_000_000_000,
        };
        let raw = self.cast(column, &DataType::Int64)?;
        let raw = raw.as_primitive::<Int64Type>();
        let mut bad = Bad::default();
        let values: Vec<Option<i64>> = raw
            .iter()
            .enumerate()
            .map(|(row, t)| {
                t.map(|t| {
                    let ns = t.checked_mul(per).filter(|&ns| reading_time_ok(ns));
                    if ns.is_none() {
                        bad.add(row, || format!("{t} (x {per} ns)"));
                    }
                    ns.unwrap_or(0)
                })
            })
            .collect();
        bad.check(
            self.path,
            name,
            "hold times outside 1980-01-01 .. 2200-01-01 (NaT, a clock reset, or a unit whose ns value overflows)",
        )?;
        Ok(values)
    }

    /// An integer column (int8 … int64, uint8 … uint64) as i64.
    pub(crate) fn int(&self, name: &'static str) -> Result<Vec<Option<i64>>, IngestError> {
        let column = self.column(name)?;
        if !column.data_type().is_integer() {
            return Err(self.wrong_type(name, column.data_type(), "an integer (int8 .. int64)"));
        }
        let cast = self.cast(column, &DataType::Int64)?;
        Ok(cast.as_primitive::<Int64Type>().iter().collect())
    }

    /// A float column (float32 or float64) as f64.
    pub(crate) fn real(&self, name: &'static str) -> Result<Vec<Option<f64>>, IngestError> {
        let column = self.column(name)?;
        if !column.data_type().is_floating() {
            return Err(self.wrong_type(name, column.data_type(), "float64"));
        }
        let cast = self.cast(column, &DataType::Float64)?;
        Ok(cast.as_primitive::<Float64Type>().iter().collect())
    }

    /// A utf8 or dictionary(utf8) column as strings.
    pub(crate) fn text(&self, name: &'static str) -> Result<Vec<Option<String>>, IngestError> {
        let column = self.column(name)?;
        if !crate::pq::is_text_or_dictionary(column.data_type()) {
            return Err(self.wrong_type(name, column.data_type(), "utf8 or dictionary(utf8)"));
        }
        let cast = self.cast(column, &DataType::Utf8)?;
        Ok(cast
            .as_string::<i32>()
            .iter()
            .map(|s| s.map(str::to_string))
            .collect())
    }

    /// An optional column: absent is all null.
    pub(crate) fn optional<T: Clone>(
        &self,
        name: &'static str,
        read: impl Fn(&Self, &'static str) -> Result<Vec<Option<T>>, IngestError>,
    ) -> Result<Vec<Option<T>>, IngestError> {
        if self.has(name) {
            read(self, name)
        } else {
            Ok(vec![None; self.rows()])
        }
    }

    /// An extra column kept by name: numbers and booleans as f64, anything else as text
    /// (`None`: a type that has no text form, left out).
    fn extra(&self, name: &str) -> Option<ExtraColumn> {
        let column = self.batch.column_by_name(name)?;
        let dtype = column.data_type();
        if dtype.is_numeric() || dtype == &DataType::Boolean {
            let cast = arrow_cast::cast(column, &DataType::Float64).ok()?;
            return Some(ExtraColumn::Real(
                cast.as_primitive::<Float64Type>().iter().collect(),
            ));
        }
        let cast = arrow_cast::cast(column, &DataType::Utf8).ok()?;
        Some(ExtraColumn::Text(
            cast.as_string::<i32>()
                .iter()
                .map(|s| s.map(str::to_string))
                .collect(),
        ))
    }
}

/// Rows of one column with one problem.
#[derive(Default)]
struct Bad {
    rows: u64,
    first: u64,
    last: u64,
    example: String,
}

impl Bad {
    fn add(&mut self, row: usize, example: impl FnOnce() -> String) {
        let row = row as u64;
        if self.rows == 0 {
            self.first = row;
            self.example = example();
        }
        self.rows += 1;
        self.first = self.first.min(row);
        self.last = self.last.max(row);
    }

    fn check(self, path: &Path, column: &'static str, problem: &str) -> Result<(), IngestError> {
        if self.rows == 0 {
            return Ok(());
        }
        Err(IngestError::BadRows {
            path: path.to_path_buf(),
            column,
            rows: self.rows,
            first_row: self.first,
            last_row: self.last,
            problem: problem.to_string(),
            example: self.example,
        })
    }
}

/// Every value present; nulls refuse their rows.
pub(crate) fn required<T>(
    path: &Path,
    column: &'static str,
    values: Vec<Option<T>>,
) -> Result<Vec<T>, IngestError> {
    let mut bad = Bad::default();
    for (row, v) in values.iter().enumerate() {
        if v.is_none() {
            bad.add(row, || "null".into());
        }
    }
    bad.check(path, column, "are null")?;
    Ok(values.into_iter().flatten().collect())
}

/// The `run` column counts from 1 and `direction` is +1, −1 or null: the rows that are not,
/// named by file and column (an axis's lines, a volumetric campaign's laser and bar diagonals alike).
pub(crate) fn check_runs_and_directions(
    path: &Path,
    run: &[i64],
    direction: &[Option<i64>],
) -> Result<(), IngestError> {
    check_rows(
        path,
        "run",
        run,
        |&r| r >= 1,
        "are below 1 (runs count from 1)",
    )?;
    check_rows(
        path,
        "direction",
        direction,
        |d| d.is_none_or(|d| d == 1 || d == -1),
        "are neither +1 nor -1 (nor null)",
    )
}

/// Refuses the rows where `ok` fails, showing the first value.
pub(crate) fn check_rows<T: std::fmt::Debug>(
    path: &Path,
    column: &'static str,
    values: &[T],
    ok: impl Fn(&T) -> bool,
    problem: &str,
) -> Result<(), IngestError> {
    let mut bad = Bad::default();
    for (row, v) in values.iter().enumerate() {
        if !ok(v) {
            bad.add(row, || format!("{v:?}"));
        }
    }
    bad.check(path, column, problem)
}

fn finite_within(
    path: &Path,
    column: &'static str,
    values: &[f64],
    (lo, hi): (f64, f64),
    unit: &str,
) -> Result<(), IngestError> {
    check_rows(
        path,
        column,
        values,
        |v| v.is_finite() && (lo..=hi).contains(v),
        &format!("are not finite numbers within {lo} .. {hi} {unit}"),
    )
}

pub(crate) fn finite(path: &Path, column: &'static str, values: &[f64]) -> Result<(), IngestError> {
    check_rows(
        path,
        column,
        values,
        |v| v.is_finite(),
        "are not finite numbers (NaN or infinite)",
    )
}

/// Rows whose `line` the manifest does not declare: the first such line, by file.
fn check_lines(
    path: &Path,
    lines: &[i64],
    times: &[i64],
    campaign: &AxisCampaign,
) -> Result<(), IngestError> {
    let Some(&unknown) = lines.iter().find(|&&l| campaign.line(l).is_none()) else {
        return Ok(());
    };
    let of_it: Vec<usize> = (0..lines.len()).filter(|&i| lines[i] == unknown).collect();
    let first_ns = of_it.iter().map(|&i| times[i]).min().unwrap_or(0);
    let last_ns = of_it.iter().map(|&i| times[i]).max().unwrap_or(0);
    Err(IngestError::UnknownId {
        path: path.to_path_buf(),
        column: "line",
        id: unknown.to_string(),
        rows: of_it.len() as u64,
        first_ns,
        last_ns,
        known: campaign
            .line_ids()
            .iter()
            .map(i64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
    })
}

// ---------------------------------------------------------------- readings

/// The readings of every file, checked, ordered and with directions; their extra columns.
fn read_readings(files: &[PathBuf], campaign: &AxisCampaign) -> Result<Readings, IngestError> {
    let mut keys: Vec<ReadingKey> = Vec::new();
    let mut source: Vec<(usize, u64)> = Vec::new();
    // Extra columns, per name: one piece per file (`None`: the file lacks it).
    let mut extra_pieces: BTreeMap<String, Vec<(usize, usize, Option<ExtraColumn>)>> =
        BTreeMap::new();
    let mut offsets = Vec::new();
    for (f, path) in files.iter().enumerate() {
        let file = Decoded::read(path)?;
        for name in [
            "time",
            "line",
            "run",
            "target_mm",
            "channel",
            "deviation_um",
        ] {
            file.column(name)?;
        }
        let time = required(path, "time", file.time("time")?)?;
        let line = required(path, "line", file.int("line")?)?;
        let run = required(path, "run", file.int("run")?)?;
        let direction = file.optional("direction", Decoded::int)?;
        let target = required(path, "target_mm", file.real("target_mm")?)?;
        let channel = required(path, "channel", file.text("channel")?)?;
        let deviation = required(path, "deviation_um", file.real("deviation_um")?)?;
        check_lines(path, &line, &time, campaign)?;
        check_runs_and_directions(path, &run, &direction)?;
        finite(path, "target_mm", &target)?;
        finite(path, "deviation_um", &deviation)?;
        check_rows(
            path,
            "channel",
            &channel,
            |c| Channel::parse(c).is_some(),
            "hold a channel that is not dx, dy or dz",
        )?;
        offsets.push(keys.len());
        for row in 0..file.rows() {
            keys.push(ReadingKey {
                time_ns: time[row],
                line: line[row],
                run: run[row],
                target_mm: target[row],
                channel: Channel::parse(&channel[row]).unwrap_or(Channel::Dx),
                deviation_um: deviation[row],
                direction: direction[row].map(|d| d as i8),
            });
            source.push((f, row as u64));
        }
        let names: Vec<String> = file
            .names()
            .into_iter()
            .filter(|n| !READING_COLUMNS.contains(&n.as_str()))
            .collect();
        for name in names {
            let piece = file.extra(&name);
            extra_pieces
                .entry(name)
                .or_default()
                .push((f, file.rows(), piece));
        }
    }
    let order = derive_order(&keys).map_err(|p| {
        let (f, _) = source[p.rows[0]];
        let in_file: Vec<u64> = p
            .rows
            .iter()
            .filter(|&&i| source[i].0 == f)
            .map(|&i| source[i].1)
            .collect();
        let elsewhere = p.rows.len() - in_file.len();
        let k = &keys[p.rows[0]];
        IngestError::BadRows {
            path: files[f].clone(),
            column: "direction",
            rows: in_file.len() as u64,
            first_row: in_file.iter().copied().min().unwrap_or(0),
            last_row: in_file.iter().copied().max().unwrap_or(0),
            problem: format!(
                "of line {}, run {}{}: {}",
                p.line,
                p.run,
                if elsewhere > 0 {
                    format!(" (and {elsewhere} rows of other files)")
                } else {
                    String::new()
                },
                p.problem
            ),
            example: format!(
                "time {}, target_mm {}",
                crate::format_ns(k.time_ns),
                k.target_mm
            ),
        }
    })?;
    // A reading held by two files (an overlapping export, a copied file) is kept once: rows
    // equal in every spec column are adjacent in the order.
    let mut readings: Vec<AxisReading> = Vec::with_capacity(keys.len());
    let mut kept: Vec<usize> = Vec::with_capacity(keys.len());
    for &i in &order.order {
        let k = &keys[i];
        let reading = AxisReading {
            time_ns: k.time_ns,
            line: k.line,
            run: k.run,
            direction: order.direction[i],
            target_mm: k.target_mm,
            channel: k.channel,
            deviation_um: k.deviation_um,
        };
        if readings.last() != Some(&reading) {
            readings.push(reading);
            kept.push(i);
        }
    }
    let duplicates = (keys.len() - kept.len()) as u64;
    let total = keys.len();
    let extra = extra_pieces
        .into_iter()
        .filter_map(|(name, pieces)| {
            let whole = join_pieces(&pieces, &offsets, total)?;
            Some((name, whole.reordered(&kept)))
        })
        .collect();
    Ok(Readings {
        readings,
        extra,
        duplicates,
    })
}

/// The readings, ordered, with directions; their extra columns; the copies left out.
struct Readings {
    readings: Vec<AxisReading>,
    extra: BTreeMap<String, ExtraColumn>,
    duplicates: u64,
}

/// One extra column over every file (rows of files without it are null): numbers where every
/// file has numbers, text otherwise. `None` when no file could give it.
fn join_pieces(
    pieces: &[(usize, usize, Option<ExtraColumn>)],
    offsets: &[usize],
    total: usize,
) -> Option<ExtraColumn> {
    if pieces.iter().all(|p| p.2.is_none()) {
        return None;
    }
    let all_real = pieces
        .iter()
        .all(|p| matches!(p.2, None | Some(ExtraColumn::Real(_))));
    if all_real {
        let mut v = vec![None; total];
        for (f, _, piece) in pieces {
            if let Some(ExtraColumn::Real(values)) = piece {
                v[offsets[*f]..offsets[*f] + values.len()].copy_from_slice(values);
            }
        }
        return Some(ExtraColumn::Real(v));
    }
    let mut v: Vec<Option<String>> = vec![None; total];
    for (f, _, piece) in pieces {
        let texts: Vec<Option<String>> = match piece {
            Some(ExtraColumn::Real(values)) => {
                values.iter().map(|x| x.map(|x| x.to_string())).collect()
            }
            Some(ExtraColumn::Text(values)) => values.clone(),
            None => continue,
        };
        for (i, t) in texts.into_iter().enumerate() {
            v[offsets[*f] + i] = t;
        }
    }
    Some(ExtraColumn::Text(v))
}

// ---------------------------------------------------------------- the other tables

fn read_fixture(
    files: &[PathBuf],
    campaign: &AxisCampaign,
) -> Result<Vec<FixtureRow>, IngestError> {
    let mut rows = Vec::new();
    for path in files {
        let file = Decoded::read(path)?;
        for name in ["time", "line", "x_mm", "y_mm", "z_mm"] {
            file.column(name)?;
        }
        let time = required(path, "time", file.time("time")?)?;
        let line = required(path, "line", file.int("line")?)?;
        check_lines(path, &line, &time, campaign)?;
        let mut xyz = Vec::new();
        for name in ["x_mm", "y_mm", "z_mm"] {
            let v = required(path, name, file.real(name)?)?;
            finite(path, name, &v)?;
            xyz.push(v);
        }
        rows.extend((0..file.rows()).map(|i| FixtureRow {
            time_ns: time[i],
            line: line[i],
            reflector_mm: [xyz[0][i], xyz[1][i], xyz[2][i]],
        }));
    }
    rows.sort_by(|a, b| {
        (a.line, a.time_ns).cmp(&(b.line, b.time_ns)).then_with(|| {
            a.reflector_mm
                .iter()
                .zip(&b.reflector_mm)
                .map(|(x, y)| x.total_cmp(y))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        })
    });
    Ok(rows)
}

pub(crate) fn read_environment(files: &[PathBuf]) -> Result<Vec<EnvironmentRow>, IngestError> {
    let mut rows = Vec::new();
    for path in files {
        let file = Decoded::read(path)?;
        for name in [
            "time",
            "air_c",
            "pressure_hpa",
            "humidity_pct",
            "material_c",
        ] {
            file.column(name)?;
        }
        let time = required(path, "time", file.time("time")?)?;
        let air = required(path, "air_c", file.real("air_c")?)?;
        finite_within(path, "air_c", &air, AIR_C, "°C")?;
        let pressure = required(path, "pressure_hpa", file.real("pressure_hpa")?)?;
        finite_within(path, "pressure_hpa", &pressure, PRESSURE_HPA, "hPa")?;
        let humidity = required(path, "humidity_pct", file.real("humidity_pct")?)?;
        finite_within(path, "humidity_pct", &humidity, HUMIDITY_PCT, "%")?;
        let material = file.real("material_c")?;
        check_rows(
            path,
            "material_c",
            &material,
            |m| m.is_none_or(|m| m.is_finite() && (MATERIAL_C.0..=MATERIAL_C.1).contains(&m)),
            &format!(
                "are not finite numbers within {} .. {} °C (nor null)",
                MATERIAL_C.0, MATERIAL_C.1
            ),
        )?;
        let factor = file.optional("env_factor_ppm", Decoded::real)?;
        check_rows(
            path,
            "env_factor_ppm",
            &factor,
            |f| f.is_none_or(f64::is_finite),
            "are not finite numbers (nor null)",
        )?;
        rows.extend((0..file.rows()).map(|i| EnvironmentRow {
            time_ns: time[i],
            air_c: air[i],
            pressure_hpa: pressure[i],
            humidity_pct: humidity[i],
            material_c: material[i],
            env_factor_ppm: factor[i],
        }));
    }
    rows.sort_by(|a, b| {
        a.time_ns
            .cmp(&b.time_ns)
            .then(a.air_c.total_cmp(&b.air_c))
            .then(a.pressure_hpa.total_cmp(&b.pressure_hpa))
            .then(a.humidity_pct.total_cmp(&b.humidity_pct))
    });
    Ok(rows)
}

fn read_temperatures(
    files: &[PathBuf],
    campaign: &AxisCampaign,
) -> Result<BTreeMap<String, SensorLog>, IngestError> {
    let mut by_sensor: BTreeMap<String, Vec<(i64, f64)>> = campaign
        .sensors
        .iter()
        .map(|s| (s.id.clone(), Vec::new()))
        .collect();
    for path in files {
        let file = Decoded::read(path)?;
        for name in ["time", "sensor", "celsius"] {
            file.column(name)?;
        }
        let time = required(path, "time", file.time("time")?)?;
        let sensor = required(path, "sensor", file.text("sensor")?)?;
        let celsius = file.real("celsius")?;
        if let Some(unknown) = sensor.iter().find(|s| !by_sensor.contains_key(*s)) {
            let of_it: Vec<usize> = (0..sensor.len())
                .filter(|&i| &sensor[i] == unknown)
                .collect();
            let known = campaign
                .sensors
                .iter()
                .map(|s| s.id.as_str())
                .collect::<Vec<_>>()
                .join(", ");
            return Err(IngestError::UnknownId {
                path: path.clone(),
                column: "sensor",
                id: unknown.clone(),
                rows: of_it.len() as u64,
                first_ns: of_it.iter().map(|&i| time[i]).min().unwrap_or(0),
                last_ns: of_it.iter().map(|&i| time[i]).max().unwrap_or(0),
                known: if known.is_empty() {
                    "none".into()
                } else {
                    known
                },
            });
        }
        for i in 0..file.rows() {
            if let Some(c) = celsius[i].filter(|c| c.is_finite()) {
                if let Some(log) = by_sensor.get_mut(&sensor[i]) {
                    log.push((time[i], c));
                }
            }
        }
    }
    Ok(by_sensor
        .into_iter()
        .map(|(id, mut rows)| {
            rows.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
            let log = SensorLog {
                time_ns: rows.iter().map(|r| r.0).collect(),
                celsius: rows.iter().map(|r| r.1).collect(),
            };
            (id, log)
        })
        .collect())
}

pub(crate) fn read_events(files: &[PathBuf]) -> Result<Vec<Event>, IngestError> {
    let mut events = Vec::new();
    for path in files {
        let file = Decoded::read(path)?;
        for name in ["time", "kind"] {
            file.column(name)?;
        }
        let time = required(path, "time", file.time("time")?)?;
        let kind = required(path, "kind", file.text("kind")?)?;
        let bar = file.optional("bar", Decoded::text)?;
        let value = file.optional("value", Decoded::real)?;
        events.extend((0..file.rows()).map(|i| Event {
            time_ns: time[i],
            bar: bar[i].clone(),
            kind: EventKind::parse(&kind[i]),
            value: value[i].filter(|v| v.is_finite()),
        }));
    }
    events.sort_by(|a, b| {
        a.time_ns
            .cmp(&b.time_ns)
            .then_with(|| a.kind.cmp(&b.kind))
            .then_with(|| a.bar.cmp(&b.bar))
            .then_with(|| {
                a.value
                    .unwrap_or(f64::NAN)
                    .total_cmp(&b.value.unwrap_or(f64::NAN))
            })
    });
    Ok(events)
}
