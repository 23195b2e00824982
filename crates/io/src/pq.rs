//! Parquet files as arrow data (the `parquet` crate's arrow reader and writer): opening a file
//! (its footer only), decoding chosen columns of chosen row groups in batches, whole small
//! files, the type names the messages use, and writing one table.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use arrow_array::{Array, ArrayRef, RecordBatch};
use arrow_schema::{DataType, Field, Schema, SchemaRef, TimeUnit};
use parquet::arrow::arrow_reader::{
    ArrowReaderMetadata, ArrowReaderOptions, ParquetRecordBatchReader,
    ParquetRecordBatchReaderBuilder,
};
use parquet::arrow::{ArrowWriter, ProjectionMask};
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::properties::WriterProperties;

use super::write::WriteError;
use super::{one_line, IngestError};

/// Rows of one decoded batch at most: large enough that the per-batch work (a channel send, a
/// sink's bookkeeping) is negligible, small enough that a batch of three columns stays in the
/// L2 cache's neighbourhood (~1.5 MB).
pub(crate) const BATCH_ROWS: usize = 64 * 1024;

/// Rows of one written row group (polars' default, so our files' row groups are those of the
/// campaigns polars writes).
const ROW_GROUP_ROWS: usize = 512 * 512;

/// `path` is no parquet file the reader can decode: its message, on one line.
pub(crate) fn not_parquet(path: &Path, e: impl std::fmt::Display) -> IngestError {
    IngestError::NotParquet {
        path: path.to_path_buf(),
        reason: one_line(e),
    }
}

/// A parquet file whose footer has been read (row groups, row counts, arrow schema); no data
/// page is read until a [`ParquetFile::reader`] is built.
pub(crate) struct ParquetFile {
    meta: ArrowReaderMetadata,
}

impl ParquetFile {
    /// Opens `path` and reads its footer.
    pub(crate) fn open(path: &Path) -> Result<ParquetFile, IngestError> {
        let file = File::open(path).map_err(|e| IngestError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let meta = ArrowReaderMetadata::load(&file, ArrowReaderOptions::new())
            .map_err(|e| not_parquet(path, e))?;
        Ok(ParquetFile { meta })
    }

    /// The file's arrow schema (from its embedded arrow schema where there is one, else from
    /// the parquet types).
    pub(crate) fn schema(&self) -> &SchemaRef {
        self.meta.schema()
    }

    /// The rows the footer announces.
    pub(crate) fn rows(&self) -> u64 {
        u64::try_from(self.meta.metadata().file_metadata().num_rows()).unwrap_or(0)
    }

    /// Rows of each row group, in order.
    pub(crate) fn row_group_rows(&self) -> Vec<u64> {
        self.meta
            .metadata()
            .row_groups()
            .iter()
            .map(|g| u64::try_from(g.num_rows()).unwrap_or(0))
            .collect()
    }

    /// The `(min, max)` the footer records for top-level column `column` in row group `group`,
    /// when it records both as 64-bit integers (a timestamp's stored values).
    pub(crate) fn int64_range(&self, group: usize, column: usize) -> Option<(i64, i64)> {
        use parquet::file::statistics::Statistics;
        let leaf = self.leaf_of(column)?;
        let chunk = self.meta.metadata().row_groups().get(group)?.column(leaf);
        match chunk.statistics()? {
            Statistics::Int64(s) => Some((*s.min_opt()?, *s.max_opt()?)),
            _ => None,
        }
    }

    /// The parquet leaf column of top-level field `column`, when it is a primitive column.
    fn leaf_of(&self, column: usize) -> Option<usize> {
        let descr = self.meta.metadata().file_metadata().schema_descr();
        let leaves: Vec<usize> = (0..descr.num_columns())
            .filter(|&i| descr.get_column_root_idx(i) == column)
            .collect();
        (leaves.len() == 1).then(|| leaves[0])
    }

    /// A reader of the top-level columns `columns` (in the file's order), each decoded as its
    /// type in `types` (`None`: the file's own), of the row groups `groups` (`None`: all), in
    /// batches of at most [`BATCH_ROWS`] rows. A type must be one the parquet reader can decode
    /// the column as (a string column as `Utf8View`, a timestamp in its unit).
    pub(crate) fn reader(
        &self,
        path: &Path,
        columns: &[(usize, Option<DataType>)],
        groups: Option<Vec<usize>>,
    ) -> Result<ParquetRecordBatchReader, IngestError> {
        let meta = self.hinted(path, columns)?;
        // A file of its own (not a clone of `self.file`, which would share its offset): the
        // reader seeks, and two readers of one file run on two threads at once.
        let file = File::open(path).map_err(|e| IngestError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let descr = meta.metadata().file_metadata().schema_descr_ptr();
        let mask = ProjectionMask::roots(&descr, columns.iter().map(|c| c.0));
        let mut builder = ParquetRecordBatchReaderBuilder::new_with_metadata(file, meta)
            .with_projection(mask)
            .with_batch_size(BATCH_ROWS);
        if let Some(groups) = groups {
            builder = builder.with_row_groups(groups);
        }
        builder.build().map_err(|e| not_parquet(path, e))
    }

    /// The footer with the arrow schema changed to the types asked for.
    fn hinted(
        &self,
        path: &Path,
        columns: &[(usize, Option<DataType>)],
    ) -> Result<ArrowReaderMetadata, IngestError> {
        if columns.iter().all(|c| c.1.is_none()) {
            return Ok(self.meta.clone());
        }
        let fields: Vec<Field> = self
            .schema()
            .fields()
            .iter()
            .enumerate()
            .map(|(i, f)| match columns.iter().find(|c| c.0 == i) {
                Some((_, Some(t))) => f.as_ref().clone().with_data_type(t.clone()),
                _ => f.as_ref().clone(),
            })
            .collect();
        let schema = Arc::new(Schema::new(fields));
        let options = ArrowReaderOptions::new().with_schema(schema);
        ArrowReaderMetadata::try_new(self.meta.metadata().clone(), options)
            .map_err(|e| not_parquet(path, e))
    }
}

/// Every column and row of a (small) file, as one batch.
pub(crate) fn read_whole(path: &Path) -> Result<RecordBatch, IngestError> {
    let file = ParquetFile::open(path)?;
    let columns: Vec<(usize, Option<DataType>)> = (0..file.schema().fields().len())
        .map(|i| (i, None))
        .collect();
    let schema = file.schema().clone();
    let batches = file
        .reader(path, &columns, None)?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| not_parquet(path, e))?;
    arrow_select_concat(&schema, &batches).map_err(|e| not_parquet(path, e))
}

/// The batches as one (the reader's schema may differ from the footer's in metadata only).
fn arrow_select_concat(
    schema: &SchemaRef,
    batches: &[RecordBatch],
) -> Result<RecordBatch, arrow_schema::ArrowError> {
    match batches {
        [] => Ok(RecordBatch::new_empty(schema.clone())),
        [one] => Ok(one.clone()),
        _ => arrow_select::concat::concat_batches(&batches[0].schema(), batches),
    }
}

/// The short type names messages use (`i64`, `f64`, `str`, `datetime[ns, UTC]`, …), the
/// names the messages have always given.
pub(crate) fn type_name(dtype: &DataType) -> String {
    let unit = |u: &TimeUnit| match u {
        TimeUnit::Second => "s",
        TimeUnit::Millisecond => "ms",
        TimeUnit::Microsecond => "μs",
        TimeUnit::Nanosecond => "ns",
    };
    match dtype {
        DataType::Null => "null".into(),
        DataType::Boolean => "bool".into(),
        DataType::Int8 => "i8".into(),
        DataType::Int16 => "i16".into(),
        DataType::Int32 => "i32".into(),
        DataType::Int64 => "i64".into(),
        DataType::UInt8 => "u8".into(),
        DataType::UInt16 => "u16".into(),
        DataType::UInt32 => "u32".into(),
        DataType::UInt64 => "u64".into(),
        DataType::Float16 => "f16".into(),
        DataType::Float32 => "f32".into(),
        DataType::Float64 => "f64".into(),
        DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View => "str".into(),
        DataType::Binary
        | DataType::LargeBinary
        | DataType::BinaryView
        | DataType::FixedSizeBinary(_) => "binary".into(),
        DataType::Date32 | DataType::Date64 => "date".into(),
        DataType::Time32(_) | DataType::Time64(_) => "time".into(),
        DataType::Timestamp(u, None) => format!("datetime[{}]", unit(u)),
        DataType::Timestamp(u, Some(zone)) => format!("datetime[{}, {zone}]", unit(u)),
        DataType::Duration(u) => format!("duration[{}]", unit(u)),
        DataType::Dictionary(_, value) if is_text(value) => "cat".into(),
        DataType::Dictionary(_, value) => format!("dictionary[{}]", type_name(value)),
        DataType::List(f) | DataType::LargeList(f) | DataType::ListView(f) => {
            format!("list[{}]", type_name(f.data_type()))
        }
        DataType::FixedSizeList(f, n) => format!("array[{}, {n}]", type_name(f.data_type())),
        DataType::Struct(fields) => format!("struct[{}]", fields.len()),
        DataType::Decimal128(p, s) | DataType::Decimal256(p, s) => format!("decimal[{p},{s}]"),
        other => other.to_string().to_lowercase(),
    }
}

/// A string type (utf8, large or view).
pub(crate) fn is_text(dtype: &DataType) -> bool {
    matches!(
        dtype,
        DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View
    )
}

/// A string column, or a dictionary of strings (a categorical).
pub(crate) fn is_text_or_dictionary(dtype: &DataType) -> bool {
    match dtype {
        DataType::Dictionary(_, value) => is_text(value),
        other => is_text(other),
    }
}

/// Writes one parquet file holding `columns` (all nullable): zstd, statistics, dictionary pages
/// where they pay, row groups of 512² rows. The writer records no time, so the bytes depend
/// only on the columns.
pub(crate) fn write_columns(
    path: &Path,
    columns: Vec<(String, ArrayRef)>,
) -> Result<(), WriteError> {
    let failed = |e: &dyn std::fmt::Display| WriteError::Parquet {
        path: path.to_path_buf(),
        message: one_line(e),
    };
    let fields: Vec<Field> = columns
        .iter()
        .map(|(name, a)| Field::new(name, a.data_type().clone(), true))
        .collect();
    let schema = Arc::new(Schema::new(fields));
    let arrays: Vec<ArrayRef> = columns.into_iter().map(|(_, a)| a).collect();
    let batch = if arrays.is_empty() {
        RecordBatch::new_empty(schema.clone())
    } else {
        RecordBatch::try_new(schema.clone(), arrays).map_err(|e| failed(&e))?
    };
    let file = File::create(path).map_err(|e| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_max_row_group_row_count(Some(ROW_GROUP_ROWS))
        .build();
    let mut writer = ArrowWriter::try_new(std::io::BufWriter::new(file), schema, Some(props))
        .map_err(|e| failed(&e))?;
    writer.write(&batch).map_err(|e| failed(&e))?;
    let mut file = writer.into_inner().map_err(|e| failed(&e))?;
    use std::io::Write;
    file.flush().map_err(|e| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
