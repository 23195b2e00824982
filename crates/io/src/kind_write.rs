//! What every machine kind's campaign writer (`axis_write`, `probe_write`, `roll_write`,
//! `volumetric_write`) shares, so that a kind's writer holds only its own tables: the
//! manifest, folders cleared of stale parquet files, and the time and `f64` columns.

use std::path::Path;

use polars::prelude::*;

use super::one_line;
use super::write::{TimeUnit, WriteError};

/// `dir` created (if needed) with its `campaign.toml` holding `manifest` (the manifest's
/// `to_toml_string()`).
pub(crate) fn write_manifest(
    dir: &Path,
    manifest: Result<String, toml::ser::Error>,
) -> Result<(), WriteError> {
    create_dir(dir)?;
    let path = dir.join("campaign.toml");
    let text = manifest.map_err(|e| WriteError::Manifest {
        path: path.clone(),
        message: one_line(e),
    })?;
    std::fs::write(&path, text).map_err(|e| WriteError::Io {
        path: path.clone(),
        message: e.to_string(),
    })
}

/// The `time` column of `ns` nanosecond instants, stored in `unit`.
pub(crate) fn time_column(ns: impl Iterator<Item = i64>, unit: TimeUnit) -> Column {
    let (per, polars_unit) = match unit {
        TimeUnit::Ns => (1, polars::prelude::TimeUnit::Nanoseconds),
        TimeUnit::Us => (1_000, polars::prelude::TimeUnit::Microseconds),
        TimeUnit::Ms => (1_000_000, polars::prelude::TimeUnit::Milliseconds),
    };
    Int64Chunked::from_vec("time".into(), ns.map(|t: i64| t.div_euclid(per)).collect())
        .into_datetime(polars_unit, None)
        .into_column()
}

pub(crate) fn f64_column(name: &str, values: impl Iterator<Item = f64>) -> Column {
    Float64Chunked::from_vec(name.into(), values.collect()).into_column()
}

pub(crate) fn polars_err(path: &Path) -> impl Fn(PolarsError) -> WriteError + '_ {
    move |e| WriteError::Polars {
        path: path.to_path_buf(),
        message: one_line(e),
    }
}

pub(crate) fn create_dir(dir: &Path) -> Result<(), WriteError> {
    std::fs::create_dir_all(dir).map_err(|e| WriteError::Io {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })
}

/// Creates `folder` and removes its `*.parquet` files.
pub(crate) fn prepare(folder: &Path) -> Result<(), WriteError> {
    create_dir(folder)?;
    crate::write::clear_parquet(folder)
}
