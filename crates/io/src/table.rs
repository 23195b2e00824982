//! A small generic table for the pipeline's outputs, written as parquet.

use std::path::Path;

use arrow_array::ArrayRef;

use super::kind_write::{column, timestamps};
use super::write::{write_parquet, WriteError};

/// One output column: its values, all columns of a [`Table`] having the same length.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// Floats.
    F64(Vec<f64>),
    /// Nullable floats (`None` is written as a parquet null).
    OptF64(Vec<Option<f64>>),
    /// Integers.
    I64(Vec<i64>),
    /// Strings.
    Str(Vec<String>),
    /// Nullable strings (`None` is written as a parquet null).
    OptStr(Vec<Option<String>>),
    /// Timestamps, nanoseconds since the Unix epoch, written as a naive (= UTC) `Datetime(ns)`.
    TimeNs(Vec<i64>),
    /// Nullable integers.
    OptI64(Vec<Option<i64>>),
    /// Raw timestamps in `unit` (`None`: null), naive or in `zone` (e.g. `"UTC"`): how a
    /// logger may write them, for tests of odd inputs.
    Time {
        /// Values in `unit`; `None` is a null.
        raw: Vec<Option<i64>>,
        /// Unit of `raw`.
        unit: super::TimeUnit,
        /// Time zone of the column; `None`: naive.
        zone: Option<String>,
    },
}

impl Column {
    pub(crate) fn len(&self) -> usize {
        match self {
            Column::F64(v) => v.len(),
            Column::OptF64(v) => v.len(),
            Column::I64(v) => v.len(),
            Column::Str(v) => v.len(),
            Column::OptStr(v) => v.len(),
            Column::TimeNs(v) => v.len(),
            Column::OptI64(v) => v.len(),
            Column::Time { raw, .. } => raw.len(),
        }
    }

    /// Whether the column has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The column as arrow data, of the types the tables have always been written with
    /// (strings as string views, timestamps naive in ns unless `Time` says otherwise).
    fn to_arrow(&self, name: &str) -> (String, ArrayRef) {
        match self {
            Column::F64(v) => column(name, v.clone()),
            Column::OptF64(v) => column(name, v.clone()),
            Column::I64(v) => column(name, v.clone()),
            Column::Str(v) => column(name, v.clone()),
            Column::OptStr(v) => column(name, v.clone()),
            Column::TimeNs(v) => (
                name.to_string(),
                timestamps(
                    v.iter().map(|&t| Some(t)).collect(),
                    super::TimeUnit::Ns,
                    None,
                ),
            ),
            Column::OptI64(v) => column(name, v.clone()),
            Column::Time { raw, unit, zone } => (
                name.to_string(),
                timestamps(raw.clone(), *unit, zone.as_deref()),
            ),
        }
    }
}

/// Named columns, in output order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// Name and values of each column.
    pub columns: Vec<(String, Column)>,
}

impl Table {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a column (builder style).
    pub fn with(mut self, name: impl Into<String>, column: Column) -> Self {
        self.columns.push((name.into(), column));
        self
    }

    /// Rows of the table (of its first column; [`write_table`] checks they all agree).
    pub(crate) fn height(&self) -> usize {
        self.columns.first().map_or(0, |(_, c)| c.len())
    }
}

/// Writes `table` as one parquet file. Same table, same bytes.
pub fn write_table(path: &Path, table: &Table) -> Result<(), WriteError> {
    let height = table.height();
    let mut names = std::collections::BTreeSet::new();
    for (name, column) in &table.columns {
        if column.len() != height {
            return Err(WriteError::RaggedTable {
                path: path.to_path_buf(),
                column: name.clone(),
                rows: column.len(),
                expected: height,
            });
        }
        if !names.insert(name.as_str()) {
            return Err(WriteError::DuplicateColumn {
                path: path.to_path_buf(),
                column: name.clone(),
            });
        }
    }
    let columns = table
        .columns
        .iter()
        .map(|(name, c)| c.to_arrow(name))
        .collect();
    write_parquet(path, columns)
}

/// Writes `table` as CSV (a header row, then one row per table row): floats in their shortest
/// exact decimal form, nulls empty, timestamps RFC 3339 UTC. Same table, same bytes.
pub fn write_table_csv(path: &Path, table: &Table) -> Result<(), WriteError> {
    let io_err = |e: std::io::Error| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let csv_err = |e: csv::Error| WriteError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut w = csv::Writer::from_path(path).map_err(csv_err)?;
    w.write_record(table.columns.iter().map(|(n, _)| n.as_str()))
        .map_err(csv_err)?;
    let cell = |c: &Column, i: usize| -> String {
        match c {
            Column::F64(v) => v[i].to_string(),
            Column::OptF64(v) => v[i].map(|x| x.to_string()).unwrap_or_default(),
            Column::I64(v) => v[i].to_string(),
            Column::OptI64(v) => v[i].map(|x| x.to_string()).unwrap_or_default(),
            Column::Str(v) => v[i].clone(),
            Column::OptStr(v) => v[i].clone().unwrap_or_default(),
            Column::TimeNs(v) => super::format_ns(v[i]),
            Column::Time { raw, .. } => raw[i].map(|x| x.to_string()).unwrap_or_default(),
        }
    };
    for i in 0..table.height() {
        w.write_record(table.columns.iter().map(|(_, c)| cell(c, i)))
            .map_err(csv_err)?;
    }
    w.flush().map_err(io_err)
}
