//! Opening a table's parquet files: the spec columns found and checked in the footer's schema,
//! their batches decoded in canonical types, whole small files, footers.

use super::*;

/// One spec column found in a file.
pub(super) struct Found {
    pub(super) name: &'static str,
    pub(super) kind: Kind,
    /// Top-level index in the file.
    pub(super) index: usize,
    /// The type to decode it as (`None`: the file's own).
    pub(super) read_as: Option<DataType>,
}

/// A file whose footer is read and whose schema has every spec column in an accepted form.
pub(super) struct Scan {
    pub(super) file: ParquetFile,
    pub(super) columns: Vec<Found>,
    pub(super) time: TimeColumn,
}

/// One decoded batch: the spec columns in canonical types ([`Kind::canonical`]), by name.
pub(super) struct Canonical {
    pub(super) columns: Vec<(&'static str, ArrayRef)>,
    pub(super) rows: usize,
}

impl Canonical {
    pub(super) fn get(&self, name: &str) -> Result<&ArrayRef, ArrowError> {
        self.columns
            .iter()
            .find(|c| c.0 == name)
            .map(|c| &c.1)
            .ok_or_else(|| ArrowError::SchemaError(format!("no column `{name}` decoded")))
    }

    pub(super) fn i64(&self, name: &str) -> Result<&Int64Array, ArrowError> {
        self.get(name)?
            .as_primitive_opt::<Int64Type>()
            .ok_or_else(|| ArrowError::CastError(format!("`{name}` is not int64")))
    }

    pub(super) fn f64(&self, name: &str) -> Result<&Float64Array, ArrowError> {
        self.get(name)?
            .as_primitive_opt::<Float64Type>()
            .ok_or_else(|| ArrowError::CastError(format!("`{name}` is not float64")))
    }

    pub(super) fn text(&self, name: &str) -> Result<Ids<'_>, ArrowError> {
        let ids = self
            .get(name)?
            .as_dictionary_opt::<Int32Type>()
            .ok_or_else(|| ArrowError::CastError(format!("`{name}` is not a utf8 dictionary")))?;
        let values = ids
            .values()
            .as_string_opt::<i32>()
            .ok_or_else(|| ArrowError::CastError(format!("`{name}` holds no utf8 values")))?;
        Ok(Ids { ids, values })
    }

    /// The rows where `keep` is true.
    pub(super) fn filter(&self, keep: &BooleanArray) -> Result<Canonical, ArrowError> {
        let columns = self
            .columns
            .iter()
            .map(|(n, a)| Ok((*n, arrow_select::filter::filter(a.as_ref(), keep)?)))
            .collect::<Result<Vec<_>, ArrowError>>()?;
        let rows = keep.true_count();
        Ok(Canonical { columns, rows })
    }
}

/// An id column of a batch: each row's key into the distinct `values`.
#[derive(Clone, Copy)]
pub(super) struct Ids<'a> {
    pub(super) ids: &'a DictionaryArray<Int32Type>,
    pub(super) values: &'a StringArray,
}

impl<'a> Ids<'a> {
    pub(super) fn len(&self) -> usize {
        self.ids.len()
    }

    pub(super) fn null_count(&self) -> usize {
        self.ids.null_count()
    }

    pub(super) fn is_valid(&self, row: usize) -> bool {
        self.ids.is_valid(row)
    }

    pub(super) fn is_null(&self, row: usize) -> bool {
        self.ids.is_null(row)
    }

    /// Each row's key into [`Ids::values`] (a null row's key is meaningless).
    pub(super) fn keys(&self) -> &'a [i32] {
        self.ids.keys().values()
    }

    /// The id of row `row` (`None`: null).
    pub(super) fn value(&self, row: usize) -> Option<&'a str> {
        if self.ids.is_null(row) {
            return None;
        }
        let key = usize::try_from(*self.keys().get(row)?).ok()?;
        (key < self.values.len() && self.values.is_valid(key)).then(|| self.values.value(key))
    }
}

impl Scan {
    /// The names of every column of the file, comma-separated (for a missing column's message).
    fn names(&self) -> String {
        self.file
            .schema()
            .fields()
            .iter()
            .map(|f| f.name().as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The file's type of column `name`, if it has one.
    pub(super) fn dtype(&self, name: &str) -> Option<&DataType> {
        self.file
            .schema()
            .field_with_name(name)
            .ok()
            .map(|f| f.data_type())
    }

    /// Adds spec column `spec` to the columns decoded; absent: [`IngestError::MissingColumn`],
    /// of another type: [`IngestError::WrongType`].
    pub(super) fn add(&mut self, path: &Path, spec: &ColumnSpec) -> Result<(), IngestError> {
        let Ok(index) = self.file.schema().index_of(spec.name) else {
            return Err(IngestError::MissingColumn {
                path: path.to_path_buf(),
                column: spec.name,
                found: self.names(),
            });
        };
        let dtype = self.file.schema().field(index).data_type();
        let Some(read_as) = spec.kind.read_as(dtype) else {
            return Err(IngestError::WrongType {
                path: path.to_path_buf(),
                column: spec.name,
                found: crate::pq::type_name(dtype),
                expected: spec.kind.expected(),
            });
        };
        self.columns.push(Found {
            name: spec.name,
            kind: spec.kind,
            index,
            read_as,
        });
        Ok(())
    }

    /// A reader of the spec columns of row groups `groups` (`None`: all).
    pub(super) fn reader(
        &self,
        path: &Path,
        groups: Option<Vec<usize>>,
    ) -> Result<ParquetRecordBatchReader, IngestError> {
        let columns: Vec<(usize, Option<DataType>)> = self
            .columns
            .iter()
            .map(|c| (c.index, c.read_as.clone()))
            .collect();
        self.file.reader(path, &columns, groups)
    }

    /// One decoded batch of the reader, its spec columns in canonical types.
    pub(super) fn canonical(&self, batch: &RecordBatch) -> Result<Canonical, ArrowError> {
        let columns = self
            .columns
            .iter()
            .map(|c| {
                let column = batch.column_by_name(c.name).ok_or_else(|| {
                    ArrowError::SchemaError(format!("column `{}` was not decoded", c.name))
                })?;
                Ok((c.name, c.kind.canonical(column)?))
            })
            .collect::<Result<Vec<_>, ArrowError>>()?;
        Ok(Canonical {
            columns,
            rows: batch.num_rows(),
        })
    }

    /// Every row of the spec columns, as one batch.
    pub(super) fn decode_all(&self, path: &Path) -> Result<Canonical, IngestError> {
        let mut parts = Vec::new();
        for batch in self.reader(path, None)? {
            let batch = batch.map_err(|e| not_parquet(path, e))?;
            parts.push(self.canonical(&batch).map_err(|e| not_parquet(path, e))?);
        }
        concat(parts).map_err(|e| not_parquet(path, e))
    }
}

/// Batches of the same columns as one.
fn concat(mut parts: Vec<Canonical>) -> Result<Canonical, ArrowError> {
    if parts.len() == 1 {
        return Ok(parts.remove(0));
    }
    let Some(first) = parts.first() else {
        return Ok(Canonical {
            columns: Vec::new(),
            rows: 0,
        });
    };
    let names: Vec<&'static str> = first.columns.iter().map(|c| c.0).collect();
    let rows = parts.iter().map(|p| p.rows).sum();
    let columns = names
        .iter()
        .enumerate()
        .map(|(k, &name)| {
            let arrays: Vec<&dyn Array> = parts.iter().map(|p| p.columns[k].1.as_ref()).collect();
            Ok((name, arrow_select::concat::concat(&arrays)?))
        })
        .collect::<Result<Vec<_>, ArrowError>>()?;
    Ok(Canonical { columns, rows })
}

/// One file's footer, its schema checked against `columns` (missing column, wrong type).
pub(super) fn checked_scan(path: &Path, columns: &[ColumnSpec]) -> Result<Scan, IngestError> {
    let file = ParquetFile::open(path)?;
    let time = TimeColumn::of(
        file.schema()
            .field_with_name("time")
            .ok()
            .map(|f| f.data_type()),
    );
    let mut scan = Scan {
        file,
        columns: Vec::with_capacity(columns.len()),
        time,
    };
    for spec in columns {
        scan.add(path, spec)?;
    }
    Ok(scan)
}

/// Every file of one table, normalised and stacked with each row's file. Rows that cannot be
/// used (a null in a column that must hold a value, a time out of range) are dropped and
/// flagged in `dropped`. `zones`: each file's path and whether its times are zoned.
pub(super) fn read_table(
    files: &[PathBuf],
    columns: &[ColumnSpec],
    zones: &mut Vec<(PathBuf, bool)>,
    dropped: &mut Vec<Flag>,
) -> Result<TableRows, IngestError> {
    let mut table = TableRows::new(columns);
    for (index, path) in files.iter().enumerate() {
        let time = guarded(path, || {
            read_file(path, columns, index, &mut table, dropped)
        })?;
        zones.push((path.clone(), time.zoned));
    }
    Ok(table)
}

/// One file's spec columns appended to `table` in canonical types, times in ns; rows with a
/// null where the spec wants a value, or a time out of range, are dropped and flagged in
/// `dropped` with their rows.
pub(super) fn read_file(
    path: &Path,
    columns: &[ColumnSpec],
    index: usize,
    table: &mut TableRows,
    dropped: &mut Vec<Flag>,
) -> Result<TimeColumn, IngestError> {
    let index = u32::try_from(index).unwrap_or(u32::MAX);
    let scan = checked_scan(path, columns)?;
    let rows = scan.decode_all(path)?;
    let mut keep = vec![true; rows.rows];
    for spec in columns.iter().filter(|c| !c.nullable) {
        let column = rows.get(spec.name).map_err(|e| not_parquet(path, e))?;
        if column.null_count() == 0 {
            continue;
        }
        let mut bad = None;
        for (row, kept) in keep.iter_mut().enumerate() {
            if column.is_null(row) {
                BadRange::add(&mut bad, row as u64, || "null".into());
                *kept = false;
            }
        }
        if let Some(b) = bad {
            dropped.push(b.flag(path, spec.name, RowProblem::Null));
        }
    }
    let raw = rows.i64("time").map_err(|e| not_parquet(path, e))?;
    let ns = times_ns(raw, scan.time, &mut keep, path, dropped);
    table
        .append(index, &ns, &rows, &keep)
        .map_err(|e| not_parquet(path, e))?;
    Ok(scan.time)
}

/// The stored times `raw` as ns; a time that is no accepted reading time
/// ([`TimeColumn::to_ns`]) becomes 0, its row is marked in `keep` and flagged in `dropped`.
fn times_ns(
    raw: &Int64Array,
    unit: TimeColumn,
    keep: &mut [bool],
    path: &Path,
    dropped: &mut Vec<Flag>,
) -> Vec<i64> {
    let values = raw.values();
    // Every time accepted (the usual file; the check is an interval): one multiplication of the
    // column instead of a pass of per-row checks.
    let all_ok = raw.null_count() == 0
        && values.iter().min().and_then(|&t| unit.to_ns(t)).is_some()
        && values.iter().max().and_then(|&t| unit.to_ns(t)).is_some();
    if all_ok {
        return values.iter().map(|&t| t * unit.ns_per_unit).collect();
    }
    let mut bad = None;
    let ns = values
        .iter()
        .enumerate()
        .map(|(row, &t)| {
            if raw.is_null(row) {
                return 0; // dropped above
            }
            unit.to_ns(t).unwrap_or_else(|| {
                BadRange::add(&mut bad, row as u64, || format!("{t} {}", unit.unit()));
                keep[row] = false;
                0
            })
        })
        .collect();
    if let Some(b) = bad {
        dropped.push(b.flag(path, "time", RowProblem::TimeOutOfBounds));
    }
    ns
}

/// The rows the files' parquet footers announce (no data page is read).
pub(crate) fn footer_rows(files: &[PathBuf]) -> Result<u64, IngestError> {
    Ok(footer_rows_each(files)?
        .into_iter()
        .fold(0u64, u64::saturating_add))
}

/// The rows each file's parquet footer announces, in the order of `files`.
pub(super) fn footer_rows_each(files: &[PathBuf]) -> Result<Vec<u64>, IngestError> {
    files
        .iter()
        .map(|path| guarded(path, || Ok(ParquetFile::open(path)?.rows())))
        .collect()
}
