//! Scanning parquet files: one guarded scan per table, footers, the scan arguments.

use super::*;

// ---------------------------------------------------------------- scanning

/// Scans, normalises and stacks every file of one table; adds [`FILE_COL`]. Rows that cannot
/// be used (a null in a column that must hold a value, a time out of range) are dropped and
/// flagged in `dropped`.
/// `zones`: each file's path and whether its times are zoned.
pub(super) fn read_table(
    files: &[PathBuf],
    columns: &[ColumnSpec],
    zones: &mut Vec<(PathBuf, bool)>,
    dropped: &mut Vec<Flag>,
) -> Result<DataFrame, IngestError> {
    let mut stacked: Option<DataFrame> = None;
    for (index, path) in files.iter().enumerate() {
        let (df, time) = guarded(path, || read_file(path, columns, index, dropped))?;
        zones.push((path.clone(), time.zoned));
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

pub(super) fn not_parquet(path: &Path, e: PolarsError) -> IngestError {
    IngestError::NotParquet {
        path: path.to_path_buf(),
        reason: one_line(e),
    }
}

/// One file, projected to the spec's columns in canonical types, times in ns; rows with a null
/// where the spec wants a value, or a time out of range, are dropped and flagged in `dropped`
/// with their rows.
pub(super) fn read_file(
    path: &Path,
    columns: &[ColumnSpec],
    index: usize,
    dropped: &mut Vec<Flag>,
) -> Result<(DataFrame, TimeColumn), IngestError> {
    let index = u32::try_from(index).unwrap_or(u32::MAX);
    let (lazy, schema, exprs) = checked_scan(path, columns)?;
    let unit = TimeColumn::of(schema.get("time"));
    let mut df = lazy
        .select(exprs)
        .with_column(lit(index).cast(DataType::UInt32).alias(FILE_COL))
        .collect()
        .map_err(|e| not_parquet(path, e))?;
    let mut keep: Option<Vec<bool>> = None;
    for spec in columns.iter().filter(|c| !c.nullable) {
        let column = df.column(spec.name).map_err(|e| not_parquet(path, e))?;
        if column.null_count() == 0 {
            continue;
        }
        let is_null = column.is_null();
        let mut bad = None;
        let keep = keep.get_or_insert_with(|| vec![true; df.height()]);
        for (row, null) in is_null.iter().enumerate() {
            if null == Some(true) {
                BadRange::add(&mut bad, row as u64, || "null".into());
                keep[row] = false;
            }
        }
        if let Some(b) = bad {
            dropped.push(b.flag(path, spec.name, NULL_PROBLEM));
        }
    }
    let raw = df
        .column("time")
        .and_then(|c| c.i64().cloned())
        .map_err(|e| not_parquet(path, e))?;
    let ns = times_ns(&raw, unit, &mut keep, path, dropped);
    df.with_column(ns.into_series().with_name("time".into()).into_column())
        .map_err(|e| not_parquet(path, e))?;
    if let Some(keep) = keep {
        let mask: BooleanChunked = keep.into_iter().map(Some).collect();
        df = df.filter(&mask).map_err(|e| not_parquet(path, e))?;
    }
    Ok((df, unit))
}

/// The stored times `raw` as ns; a time that is no accepted reading time
/// ([`TimeColumn::to_ns`]) becomes 0, its row is marked in `keep` and flagged in `dropped`.
fn times_ns(
    raw: &Int64Chunked,
    unit: TimeColumn,
    keep: &mut Option<Vec<bool>>,
    path: &Path,
    dropped: &mut Vec<Flag>,
) -> Int64Chunked {
    // Every time accepted (the usual file; the check is an interval): one multiplication of the
    // column instead of a pass of per-row checks (a fifth of a second per 5 M rows).
    let all_ok = raw.null_count() == 0
        && raw.min().and_then(|t| unit.to_ns(t)).is_some()
        && raw.max().and_then(|t| unit.to_ns(t)).is_some();
    if all_ok {
        return raw * unit.ns_per_unit;
    }
    let mut bad = None;
    let ns: Int64Chunked = raw
        .iter()
        .enumerate()
        .map(|(row, t)| {
            let Some(t) = t else {
                return Some(0); // dropped above
            };
            let ns = unit.to_ns(t);
            if ns.is_none() {
                BadRange::add(&mut bad, row as u64, || format!("{t} {}", unit.unit()));
                keep.get_or_insert_with(|| vec![true; raw.len()])[row] = false;
            }
            ns.or(Some(0))
        })
        .collect();
    if let Some(b) = bad {
        dropped.push(b.flag(path, "time", TIME_PROBLEM));
    }
    ns
}

/// One file's lazy scan, its whole schema, and the expressions that project it to the spec's
/// columns in canonical types; schema errors (missing column, wrong type) are raised here.
pub(super) fn checked_scan(
    path: &Path,
    columns: &[ColumnSpec],
) -> Result<(LazyFrame, SchemaRef, Vec<Expr>), IngestError> {
    let source = PlRefPath::try_from_path(path).map_err(|e| not_parquet(path, e))?;
    let mut lazy =
        LazyFrame::scan_parquet(source, scan_args()).map_err(|e| not_parquet(path, e))?;
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
    Ok((lazy, schema, exprs))
}

pub(super) fn scan_args() -> ScanArgsParquet {
    ScanArgsParquet {
        glob: false,
        ..Default::default()
    }
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
        .map(|path| {
            guarded(path, || {
                let file = std::fs::File::open(path).map_err(|e| IngestError::Io {
                    path: path.clone(),
                    message: e.to_string(),
                })?;
                ParquetReader::new(file)
                    .num_rows()
                    .map(|n| n as u64)
                    .map_err(|e| not_parquet(path, e))
            })
        })
        .collect()
}
