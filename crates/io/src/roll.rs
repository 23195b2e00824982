//! Reading a `roll` campaign (`docs/spec/machine-formats.md`, "Kind roll") with polars and
//! handing it over as plain data ([`RollCampaignLogs`]).
//!
//! `probes/*.parquet` (required) and `levels/*.parquet` (optional): each file decoded whole
//! under [`crate::guard::guarded`], its columns normalised as the reader rules allow
//! (timestamps ns/us/ms, naive or zoned; integers int8 … int64 and unsigned; floats 32 or 64
//! bit), and checked row by row: a null or non-finite value where one is needed, a `pass` below
//! 1, a time outside 1980 … 2200 refuses the campaign with one line naming the file, the column
//! and the rows (counting from 0 in that file). Samples of every file are sorted by time (ties
//! by file and row), so files split by pass and rows in any order give the same logs; a sample
//! two files hold (equal in every column) is kept once. `station` and `pass` may be absent or
//! all null. Every input file is hashed (sha256) before the read and checked unchanged after.

use std::path::{Path, PathBuf};

use polars::prelude::*;

use super::guard::guarded;
use super::inputs::{check_unchanged, parquet_files};
use super::kind_read::{kind_manifest_text, required_table, snapshot};
use super::{one_line, IngestError};
use dbbcal_core::axis_campaign::CampaignKind;
use dbbcal_core::roll_campaign::{LevelRow, ProbeSample, RollCampaign, RollCampaignLogs};
use dbbcal_core::series::reading_time_ok;

const PROBES: &str = "probes";
const LEVELS: &str = "levels";
const READINGS: [&str; 4] = ["m_a", "m_b", "m_c", "m_d"];

/// Reads a `roll` campaign directory: `campaign.toml` (`kind = "roll"`), `probes/*.parquet`
/// and the optional `levels/*.parquet`.
pub fn read_roll_campaign(dir: &Path) -> Result<RollCampaignLogs, IngestError> {
    let manifest = dir.join("campaign.toml");
    let campaign = read_roll_manifest(dir)?;
    let probe_files = required_table(dir, PROBES)?;
    let level_files = parquet_files(&dir.join(LEVELS))?;
    let (before, inputs) = snapshot(dir, &manifest, &[&probe_files, &level_files])?;
    let mut samples = Vec::new();
    let (mut has_station, mut has_pass) = (false, false);
    for (f, path) in probe_files.iter().enumerate() {
        let file = read_probes(path, f as u32)?;
        has_station |= file.has_station;
        has_pass |= file.has_pass;
        samples.extend(file.samples);
    }
    samples.sort_by(|a, b| a.time_ns.cmp(&b.time_ns).then(a.source.cmp(&b.source)));
    samples.dedup_by(|b, a| {
        a.time_ns == b.time_ns
            && a.x_mm.to_bits() == b.x_mm.to_bits()
            && a.m.map(f64::to_bits) == b.m.map(f64::to_bits)
            && a.station == b.station
            && a.pass == b.pass
    });
    if has_pass {
        if let Some(s) = samples.iter().find(|s| s.pass.is_none()) {
            return Err(IngestError::BadRows {
                path: probe_files[s.source.0 as usize].clone(),
                column: "pass",
                rows: 1,
                first_row: s.source.1,
                last_row: s.source.1,
                problem: "lack a pass while other files give one (the pass column must be in every probes file or in none)".into(),
                example: "absent".into(),
            });
        }
    }
    let mut levels = Vec::new();
    for (f, path) in level_files.iter().enumerate() {
        levels.extend(read_levels(path, f as u32)?);
    }
    levels.sort_by(|a, b| a.time_ns.cmp(&b.time_ns).then(a.source.cmp(&b.source)));
    check_unchanged(dir, &before, &inputs)?;
    let shown = |files: &[PathBuf]| {
        files
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
    };
    Ok(RollCampaignLogs {
        campaign,
        inputs,
        probe_files: shown(&probe_files),
        level_files: shown(&level_files),
        samples,
        has_station,
        has_pass,
        levels,
    })
}

/// Reads and validates the `campaign.toml` of a `roll` campaign; another kind is refused, named.
pub fn read_roll_manifest(dir: &Path) -> Result<RollCampaign, IngestError> {
    let (file, text) = kind_manifest_text(dir, CampaignKind::Roll, "a roll campaign")?;
    Ok(RollCampaign::from_toml_str(&text, &file)?)
}

struct ProbeFile {
    samples: Vec<ProbeSample>,
    has_station: bool,
    has_pass: bool,
}

fn read_probes(path: &Path, index: u32) -> Result<ProbeFile, IngestError> {
    let df = decode(path)?;
    let cols = Columns { path, df: &df };
    let time = cols.required("time", cols.time("time")?)?;
    let x = cols.finite("x_mm", cols.real("x_mm")?)?;
    let mut m = Vec::new();
    for name in READINGS {
        m.push(cols.finite(name, cols.real(name)?)?);
    }
    let station = cols.optional_int("station")?;
    let pass = cols.optional_int("pass")?;
    let has_station = station
        .as_ref()
        .is_some_and(|s| s.iter().any(Option::is_some));
    let has_pass = pass.as_ref().is_some_and(|s| s.iter().any(Option::is_some));
    if let Some(p) = pass.as_ref().filter(|_| has_pass) {
        cols.bad_rows(
            "pass",
            p,
            |v| v.is_none_or(|v| v < 1),
            "are null or below 1 (passes count from 1)",
        )?;
    }
    if let Some(s) = &station {
        cols.bad_rows("station", s, |v| v.is_some_and(|v| v < 0), "are negative")?;
    }
    let samples = (0..df.height())
        .map(|i| ProbeSample {
            time_ns: time[i],
            x_mm: x[i],
            m: [m[0][i], m[1][i], m[2][i], m[3][i]],
            station: station.as_ref().and_then(|s| s[i]),
            pass: pass.as_ref().filter(|_| has_pass).and_then(|p| p[i]),
            source: (index, i as u64),
        })
        .collect();
    Ok(ProbeFile {
        samples,
        has_station,
        has_pass,
    })
}

fn read_levels(path: &Path, index: u32) -> Result<Vec<LevelRow>, IngestError> {
    let df = decode(path)?;
    let cols = Columns { path, df: &df };
    let time = cols.required("time", cols.time("time")?)?;
    let roll = cols.finite("roll_urad", cols.real("roll_urad")?)?;
    let u = if cols.has("u_urad") {
        cols.real("u_urad")?
    } else {
        vec![None; df.height()]
    };
    cols.bad_rows(
        "u_urad",
        &u,
        |v| v.is_some_and(|v| !(v.is_finite() && v > 0.0)),
        "are not positive finite uncertainties (nor null)",
    )?;
    Ok((0..df.height())
        .map(|i| LevelRow {
            time_ns: time[i],
            roll_urad: roll[i],
            u_urad: u[i],
            source: (index, i as u64),
        })
        .collect())
}

fn decode(path: &Path) -> Result<DataFrame, IngestError> {
    guarded(path, || {
        let file = std::fs::File::open(path).map_err(|e| IngestError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        ParquetReader::new(file)
            .finish()
            .map_err(|e| IngestError::NotParquet {
                path: path.to_path_buf(),
                reason: one_line(e),
            })
    })
}

/// One decoded file's columns, checked.
struct Columns<'a> {
    path: &'a Path,
    df: &'a DataFrame,
}

impl Columns<'_> {
    fn has(&self, name: &str) -> bool {
        self.df
            .get_column_names()
            .iter()
            .any(|n| n.as_str() == name)
    }

    fn polars(&self) -> impl Fn(PolarsError) -> IngestError + '_ {
        move |e| IngestError::NotParquet {
            path: self.path.to_path_buf(),
            reason: one_line(e),
        }
    }

    fn column(&self, name: &'static str) -> Result<&Column, IngestError> {
        self.df
            .column(name)
            .map_err(|_| IngestError::MissingColumn {
                path: self.path.to_path_buf(),
                column: name,
                found: self
                    .df
                    .get_column_names()
                    .iter()
                    .map(|n| n.to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
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
            found: found.to_string(),
            expected,
        }
    }

    fn time(&self, name: &'static str) -> Result<Vec<Option<i64>>, IngestError> {
        let column = self.column(name)?;
        let DataType::Datetime(unit, _) = column.dtype() else {
            return Err(self.wrong_type(
                name,
                column.dtype(),
                "a timestamp (ns, us or ms; naive or zoned)",
            ));
        };
        let per: i64 = match unit {
            TimeUnit::Nanoseconds => 1,
            TimeUnit::Microseconds => 1_000,
            TimeUnit::Milliseconds => 1_000_000,
        };
        let raw = column.cast(&DataType::Int64).map_err(self.polars())?;
        let raw: Vec<Option<i64>> = raw.i64().map_err(self.polars())?.iter().collect();
        let ns: Vec<Option<Option<i64>>> = raw
            .iter()
            .map(|t| t.map(|t| t.checked_mul(per).filter(|&ns| reading_time_ok(ns))))
            .collect();
        self.bad_rows(
            name,
            &ns,
            |v| matches!(v, Some(None)),
            "hold times outside 1980-01-01 .. 2200-01-01 (NaT, a clock reset, or a unit whose ns value overflows)",
        )?;
        Ok(ns.into_iter().map(Option::flatten).collect())
    }

    fn real(&self, name: &'static str) -> Result<Vec<Option<f64>>, IngestError> {
        let column = self.column(name)?;
        if !column.dtype().is_float() {
            return Err(self.wrong_type(name, column.dtype(), "float64"));
        }
        let cast = column.cast(&DataType::Float64).map_err(self.polars())?;
        Ok(cast.f64().map_err(self.polars())?.iter().collect())
    }

    /// An optional integer column: `None` when absent or of no type (all null).
    fn optional_int(&self, name: &'static str) -> Result<Option<Vec<Option<i64>>>, IngestError> {
        if !self.has(name) {
            return Ok(None);
        }
        let column = self.column(name)?;
        if column.dtype().is_null() {
            return Ok(None);
        }
        if !column.dtype().is_integer() {
            return Err(self.wrong_type(name, column.dtype(), "an integer (int8 .. int64)"));
        }
        let cast = column
            .strict_cast(&DataType::Int64)
            .map_err(self.polars())?;
        Ok(Some(cast.i64().map_err(self.polars())?.iter().collect()))
    }

    /// Every value present.
    fn required<T: Copy + std::fmt::Debug>(
        &self,
        name: &'static str,
        values: Vec<Option<T>>,
    ) -> Result<Vec<T>, IngestError> {
        self.bad_rows(name, &values, Option::is_none, "are null")?;
        Ok(values.into_iter().flatten().collect())
    }

    /// Every value present and finite.
    fn finite(
        &self,
        name: &'static str,
        values: Vec<Option<f64>>,
    ) -> Result<Vec<f64>, IngestError> {
        self.bad_rows(
            name,
            &values,
            |v| v.is_none_or(|v| !v.is_finite()),
            "are null or not finite numbers (NaN or infinite)",
        )?;
        Ok(values.into_iter().flatten().collect())
    }

    /// Refuses the rows where `bad` holds: one line with the file, the column, the rows.
    fn bad_rows<T: std::fmt::Debug>(
        &self,
        column: &'static str,
        values: &[T],
        bad: impl Fn(&T) -> bool,
        problem: &str,
    ) -> Result<(), IngestError> {
        let rows: Vec<usize> = (0..values.len()).filter(|&i| bad(&values[i])).collect();
        let (Some(&first), Some(&last)) = (rows.first(), rows.last()) else {
            return Ok(());
        };
        Err(IngestError::BadRows {
            path: self.path.to_path_buf(),
            column,
            rows: rows.len() as u64,
            first_row: first as u64,
            last_row: last as u64,
            problem: problem.to_string(),
            example: format!("{:?}", values[first]),
        })
    }
}
