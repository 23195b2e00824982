//! For the tests: small tables built column by column as arrow arrays and written as parquet
//! directly (not through the crate's writers), in every form the spec allows and in broken ones.

use std::path::Path;
use std::sync::Arc;

use arrow_array::types::UInt32Type;
use arrow_array::{
    Array, ArrayRef, BooleanArray, DictionaryArray, Float64Array, Int32Array, Int64Array,
    Int8Array, RecordBatch, StringViewArray, TimestampMicrosecondArray, TimestampMillisecondArray,
    TimestampNanosecondArray,
};
use arrow_schema::{Field, Schema};

/// A named column.
pub(crate) struct Col(pub(crate) String, pub(crate) ArrayRef);

impl Col {
    pub(crate) fn name(&self) -> &str {
        &self.0
    }
}

/// The unit of a test's timestamp column.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Unit {
    Nanoseconds,
    Microseconds,
    Milliseconds,
}

impl Unit {
    fn ns(self) -> i64 {
        match self {
            Unit::Nanoseconds => 1,
            Unit::Microseconds => 1_000,
            Unit::Milliseconds => 1_000_000,
        }
    }
}

/// Values a test column is built from.
pub(crate) trait Values {
    fn array(self) -> ArrayRef;
}

macro_rules! values {
    ($($t:ty => $array:ty),* $(,)?) => {$(
        impl Values for Vec<$t> {
            fn array(self) -> ArrayRef {
                Arc::new(<$array>::from(self))
            }
        }
        impl Values for Vec<Option<$t>> {
            fn array(self) -> ArrayRef {
                Arc::new(<$array>::from(self))
            }
        }
        impl<const N: usize> Values for [$t; N] {
            fn array(self) -> ArrayRef {
                Arc::new(<$array>::from(self.to_vec()))
            }
        }
        impl<const N: usize> Values for [Option<$t>; N] {
            fn array(self) -> ArrayRef {
                Arc::new(<$array>::from(self.to_vec()))
            }
        }
        impl Values for &[$t] {
            fn array(self) -> ArrayRef {
                Arc::new(<$array>::from(self.to_vec()))
            }
        }
        impl Values for &[Option<$t>] {
            fn array(self) -> ArrayRef {
                Arc::new(<$array>::from(self.to_vec()))
            }
        }
    )*};
}

values!(
    f64 => Float64Array,
    i64 => Int64Array,
    i32 => Int32Array,
    i8 => Int8Array,
    u32 => arrow_array::UInt32Array,
    f32 => arrow_array::Float32Array,
    bool => BooleanArray,
);

macro_rules! text_values {
    ($($t:ty),* $(,)?) => {$(
        impl Values for $t {
            fn array(self) -> ArrayRef {
                Arc::new(self.into_iter().map(|s| Some(s.to_string())).collect::<StringViewArray>())
            }
        }
    )*};
}

text_values!(Vec<&str>, Vec<String>, &[&str], &Vec<&str>);

impl<const N: usize> Values for [&str; N] {
    fn array(self) -> ArrayRef {
        Arc::new(StringViewArray::from_iter_values(self))
    }
}

impl<const N: usize> Values for [Option<&str>; N] {
    fn array(self) -> ArrayRef {
        Arc::new(StringViewArray::from(self.to_vec()))
    }
}

impl Values for Vec<Option<&str>> {
    fn array(self) -> ArrayRef {
        Arc::new(StringViewArray::from(self))
    }
}

impl Values for &[Option<&str>] {
    fn array(self) -> ArrayRef {
        Arc::new(StringViewArray::from(self.to_vec()))
    }
}

/// A column named `name` of `values`.
pub(crate) fn col(name: &str, values: impl Values) -> Col {
    Col(name.to_string(), values.array())
}

/// A timestamp column `time` of raw values in `unit` (`None`: null), naive or in zone `tz`.
pub(crate) fn raw_time_col(name: &str, raw: Vec<Option<i64>>, unit: Unit, tz: Option<&str>) -> Col {
    let tz: Option<Arc<str>> = tz.map(Arc::from);
    let array: ArrayRef = match unit {
        Unit::Nanoseconds => Arc::new(TimestampNanosecondArray::from(raw).with_timezone_opt(tz)),
        Unit::Microseconds => Arc::new(TimestampMicrosecondArray::from(raw).with_timezone_opt(tz)),
        Unit::Milliseconds => Arc::new(TimestampMillisecondArray::from(raw).with_timezone_opt(tz)),
    };
    Col(name.to_string(), array)
}

/// A timestamp column `time` from ns values, in `unit` (floored) and zone `tz`.
pub(crate) fn time_col(ns: &[i64], unit: Unit, tz: Option<&str>) -> Col {
    let raw = ns.iter().map(|t| Some(t.div_euclid(unit.ns()))).collect();
    raw_time_col("time", raw, unit, tz)
}

pub(crate) fn str_col(name: &str, values: &[&str]) -> Col {
    col(name, values)
}

/// A dictionary (categorical) column: `u32` keys into utf8 values.
pub(crate) fn dict_col(name: &str, values: &[&str]) -> Col {
    let array: DictionaryArray<UInt32Type> = values.iter().copied().collect();
    Col(name.to_string(), Arc::new(array))
}

/// The columns as one batch (every field nullable).
pub(crate) fn df(columns: Vec<Col>) -> RecordBatch {
    let fields: Vec<Field> = columns
        .iter()
        .map(|c| Field::new(&c.0, c.1.data_type().clone(), true))
        .collect();
    let arrays: Vec<ArrayRef> = columns.into_iter().map(|c| c.1).collect();
    RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays).expect("frame")
}

/// Writes `batch` as a parquet file (zstd), creating its folder.
pub(crate) fn write_df(path: &Path, batch: RecordBatch) {
    write_df_in_groups(path, batch, 1024 * 1024);
}

/// [`write_df`] with row groups of at most `group_rows` rows.
pub(crate) fn write_df_in_groups(path: &Path, batch: RecordBatch, group_rows: usize) {
    use parquet::basic::{Compression, ZstdLevel};
    use parquet::file::properties::WriterProperties;
    std::fs::create_dir_all(path.parent().expect("parent")).expect("mkdir");
    let file = std::fs::File::create(path).expect("create");
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_max_row_group_row_count(Some(group_rows))
        .build();
    let mut writer =
        parquet::arrow::ArrowWriter::try_new(file, batch.schema(), Some(props)).expect("writer");
    writer.write(&batch).expect("write parquet");
    writer.close().expect("close parquet");
}

/// Every column and row of a parquet file.
pub(crate) fn read_df(path: &Path) -> RecordBatch {
    let file = std::fs::File::open(path).expect("open");
    let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .expect("parquet")
        .build()
        .expect("reader");
    let batches: Vec<RecordBatch> = reader.map(|b| b.expect("batch")).collect();
    let schema = batches.first().map(|b| b.schema()).expect("a batch");
    arrow_select::concat::concat_batches(&schema, &batches).expect("concat")
}
