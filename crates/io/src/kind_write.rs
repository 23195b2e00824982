//! What every machine kind's campaign writer (`axis_write`, `probe_write`, `roll_write`,
//! `volumetric_write`) shares, so that a kind's writer holds only its own tables: the
//! manifest, folders cleared of stale parquet files, and the time and `f64` columns.

use std::path::Path;

use std::sync::Arc;

use arrow_array::types::UInt32Type;
use arrow_array::{ArrayRef, DictionaryArray, StringViewArray};

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

/// A table's columns in output order: each name and its values.
pub(crate) type Columns = Vec<(String, ArrayRef)>;

/// The `time` column of `ns` nanosecond instants, stored in `unit` (floored), naive (= UTC).
pub(crate) fn time_column(ns: impl Iterator<Item = i64>, unit: TimeUnit) -> (String, ArrayRef) {
    let values: Vec<Option<i64>> = ns.map(|t| Some(t.div_euclid(unit.ns_per_unit()))).collect();
    ("time".into(), timestamps(values, unit, None))
}

/// A timestamp array of `values` in `unit` (`None`: null), naive or in `zone`.
pub(crate) fn timestamps(values: Vec<Option<i64>>, unit: TimeUnit, zone: Option<&str>) -> ArrayRef {
    use arrow_array::{
        TimestampMicrosecondArray, TimestampMillisecondArray, TimestampNanosecondArray,
    };
    let zone: Option<Arc<str>> = zone.map(Arc::from);
    match unit {
        TimeUnit::Ns => Arc::new(TimestampNanosecondArray::from(values).with_timezone_opt(zone)),
        TimeUnit::Us => Arc::new(TimestampMicrosecondArray::from(values).with_timezone_opt(zone)),
        TimeUnit::Ms => Arc::new(TimestampMillisecondArray::from(values).with_timezone_opt(zone)),
    }
}

pub(crate) fn f64_column(name: &str, values: impl Iterator<Item = f64>) -> (String, ArrayRef) {
    column(name, values.collect::<Vec<f64>>())
}

/// Values that make an arrow array of the type polars gave them (strings as string views).
pub(crate) trait IntoArray {
    fn into_array(self) -> ArrayRef;
}

macro_rules! primitive_into_array {
    ($($t:ty => $array:ty),* $(,)?) => {$(
        impl IntoArray for Vec<$t> {
            fn into_array(self) -> ArrayRef {
                Arc::new(<$array>::from(self))
            }
        }
        impl IntoArray for Vec<Option<$t>> {
            fn into_array(self) -> ArrayRef {
                Arc::new(<$array>::from(self))
            }
        }
    )*};
}

primitive_into_array!(
    f64 => arrow_array::Float64Array,
    i64 => arrow_array::Int64Array,
    i32 => arrow_array::Int32Array,
    i8 => arrow_array::Int8Array,
    u32 => arrow_array::UInt32Array,
    bool => arrow_array::BooleanArray,
);

impl IntoArray for Vec<&str> {
    fn into_array(self) -> ArrayRef {
        Arc::new(StringViewArray::from_iter_values(self))
    }
}

impl IntoArray for Vec<Option<&str>> {
    fn into_array(self) -> ArrayRef {
        Arc::new(StringViewArray::from(self))
    }
}

impl IntoArray for Vec<String> {
    fn into_array(self) -> ArrayRef {
        Arc::new(StringViewArray::from_iter_values(self))
    }
}

impl IntoArray for Vec<Option<String>> {
    fn into_array(self) -> ArrayRef {
        Arc::new(self.into_iter().collect::<StringViewArray>())
    }
}

/// A named column of `values`.
pub(crate) fn column(name: &str, values: impl IntoArray) -> (String, ArrayRef) {
    (name.to_string(), values.into_array())
}

/// Strings as a dictionary (categorical) column: `u32` keys into the distinct strings.
pub(crate) fn dictionary<'a>(
    name: &str,
    values: impl Iterator<Item = &'a str>,
) -> (String, ArrayRef) {
    let array: DictionaryArray<UInt32Type> = values.collect();
    (name.to_string(), Arc::new(array))
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
