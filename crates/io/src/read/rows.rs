//! The small tables (temperatures, events) stacked across their files as plain columns: each
//! row's file and time (ns), ids as small indices, values as `Option<f64>`.

use super::*;

/// A row whose id is null.
pub(super) const NULL_ID: u32 = u32::MAX;

/// An id column: each row's index into `ids.names` ([`NULL_ID`]: null).
pub(super) struct TextColumn {
    pub(super) index: Vec<u32>,
    pub(super) ids: IdIndex,
}

impl TextColumn {
    /// The id of row `row` (`None`: null).
    pub(super) fn get(&self, row: usize) -> Option<&str> {
        let index = *self.index.get(row)?;
        self.ids.names.get(index as usize).map(String::as_str)
    }
}

/// Rows of one table from all its files.
pub(super) struct TableRows {
    pub(super) file: Vec<u32>,
    pub(super) time: Vec<i64>,
    pub(super) text: Vec<(&'static str, TextColumn)>,
    pub(super) real: Vec<(&'static str, Vec<Option<f64>>)>,
}

impl TableRows {
    /// An empty table of the spec's columns (`time` is the time column; counts are not used in
    /// these tables).
    pub(super) fn new(columns: &[ColumnSpec]) -> TableRows {
        let of = |kind: Kind| columns.iter().filter(move |c| c.kind == kind);
        TableRows {
            file: Vec::new(),
            time: Vec::new(),
            text: of(Kind::Text)
                .map(|c| {
                    let column = TextColumn {
                        index: Vec::new(),
                        ids: IdIndex::new(std::iter::empty()),
                    };
                    (c.name, column)
                })
                .collect(),
            real: of(Kind::Real).map(|c| (c.name, Vec::new())).collect(),
        }
    }

    pub(super) fn height(&self) -> usize {
        self.time.len()
    }

    pub(super) fn text(&self, name: &str) -> Option<&TextColumn> {
        self.text.iter().find(|c| c.0 == name).map(|c| &c.1)
    }

    pub(super) fn real(&self, name: &str) -> Option<&[Option<f64>]> {
        self.real
            .iter()
            .find(|c| c.0 == name)
            .map(|c| c.1.as_slice())
    }

    /// Appends the rows of `rows` where `keep` holds, from file `file`, their times `ns`.
    pub(super) fn append(
        &mut self,
        file: u32,
        ns: &[i64],
        rows: &Canonical,
        keep: &[bool],
    ) -> Result<(), ArrowError> {
        let kept = |i: &usize| keep[*i];
        let n = keep.iter().filter(|&&k| k).count();
        self.file.extend(std::iter::repeat_n(file, n));
        self.time.extend((0..ns.len()).filter(kept).map(|i| ns[i]));
        let mut scratch = Vec::new();
        for (name, column) in &mut self.text {
            let values = rows.text(name)?;
            column.ids.indices(values, &mut scratch);
            column.index.extend((0..values.len()).filter(kept).map(|i| {
                if values.is_null(i) {
                    NULL_ID
                } else {
                    scratch[i]
                }
            }));
        }
        for (name, column) in &mut self.real {
            let values = rows.f64(name)?;
            column.extend(
                (0..values.len())
                    .filter(kept)
                    .map(|i| values.is_valid(i).then(|| values.value(i))),
            );
        }
        Ok(())
    }
}

/// Rows and time range per (file, id), sorted by file then id (null ids skipped).
pub(super) fn id_summary(table: &TableRows, id_column: &str) -> Vec<IdSummary> {
    let Some(ids) = table.text(id_column) else {
        return Vec::new();
    };
    let mut ranges: BTreeMap<(u32, u32), FileRange> = BTreeMap::new();
    for (row, &index) in ids.index.iter().enumerate() {
        if index == NULL_ID {
            continue;
        }
        let t = table.time[row];
        let range = FileRange {
            first_ns: t,
            last_ns: t,
            rows: 1,
        };
        FileRange::add_to(&mut ranges, (table.file[row], index), range);
    }
    let mut out: Vec<IdSummary> = ranges
        .into_iter()
        .map(|((file, index), r)| IdSummary {
            file,
            id: ids.ids.names[index as usize].clone(),
            rows: r.rows,
            first_ns: r.first_ns,
            last_ns: r.last_ns,
        })
        .collect();
    out.sort_by(|a, b| (a.file, &a.id).cmp(&(b.file, &b.id)));
    out
}
