//! The spec columns of a table: their accepted physical forms, the time column in any unit, and
//! the ranges of rows that cannot be used.

use super::*;

/// The accepted physical forms of one spec column.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    /// Timestamp, ns/us/ms, any zone or none -> i64 ns UTC.
    Time,
    /// utf8 or dictionary(utf8) -> String.
    Text,
    /// Integer -> i64; float -> f64 (whole numbers accepted, checked row by row).
    Count,
    /// Float -> f64.
    Real,
}

pub(super) struct ColumnSpec {
    pub(super) name: &'static str,
    pub(super) kind: Kind,
    pub(super) nullable: bool,
}

pub(super) const fn spec(name: &'static str, kind: Kind, nullable: bool) -> ColumnSpec {
    ColumnSpec {
        name,
        kind,
        nullable,
    }
}

pub(super) const ENCODER_COLUMNS: [ColumnSpec; 3] = [
    spec("time", Kind::Time, false),
    spec("bar", Kind::Text, false),
    // Null counts are missing readings: dropped and counted per bar (`EncoderSink::push`).
    spec("counts", Kind::Count, true),
];
pub(super) const TEMPERATURE_COLUMNS: [ColumnSpec; 3] = [
    spec("time", Kind::Time, false),
    spec("sensor", Kind::Text, false),
    // Null, NaN, ±inf: missing readings, dropped and counted per sensor (`sensor_log`).
    spec("celsius", Kind::Real, true),
];
pub(super) const EVENT_COLUMNS: [ColumnSpec; 4] = [
    spec("time", Kind::Time, false),
    spec("bar", Kind::Text, true),
    spec("kind", Kind::Text, false),
    spec("value", Kind::Real, true),
];

impl Kind {
    pub(super) fn expected(self) -> &'static str {
        match self {
            Kind::Time => "a timestamp (ns, us or ms; naive or zoned)",
            Kind::Text => "utf8 or dictionary(utf8)",
            Kind::Count => "int64 or int32 (or float64 holding whole numbers)",
            Kind::Real => "float64",
        }
    }

    /// How a column of file type `dtype` is decoded: `Some(None)` as the file's own type,
    /// `Some(Some(t))` as `t` (ids as a dictionary, whatever their encoding), `None` when
    /// `dtype` is not an accepted form.
    pub(super) fn read_as(self, dtype: &DataType) -> Option<Option<DataType>> {
        match (self, dtype) {
            // The stored value of a timestamp is the UTC epoch in its unit, zone or not; it is
            // scaled to ns in Rust with checked arithmetic (`to_ns`), never wrapped.
            (Kind::Time, DataType::Timestamp(..)) => Some(None),
            (Kind::Text, t) if crate::pq::is_text_or_dictionary(t) => Some(Some(text_type())),
            (
                Kind::Count,
                DataType::Int64
                | DataType::Int32
                | DataType::Int16
                | DataType::Int8
                | DataType::UInt32
                | DataType::UInt16
                | DataType::UInt8
                | DataType::Float64
                | DataType::Float32,
            ) => Some(None),
            (Kind::Real, DataType::Float64 | DataType::Float32) => Some(None),
            _ => None,
        }
    }

    /// A decoded column in the canonical type of its kind: times as their stored `i64`
    /// values, ids as a dictionary ([`text_type`]), counts as `i64` (integers) or `f64` (floats), reals as
    /// `f64`.
    pub(super) fn canonical(self, column: &ArrayRef) -> Result<ArrayRef, ArrowError> {
        let target = match (self, column.data_type()) {
            (Kind::Time, _) => DataType::Int64,
            (Kind::Text, _) => text_type(),
            (Kind::Count, DataType::Float32 | DataType::Float64) => DataType::Float64,
            (Kind::Count, _) => DataType::Int64,
            (Kind::Real, _) => DataType::Float64,
        };
        if column.data_type() == &target {
            Ok(column.clone())
        } else {
            arrow_cast::cast(column, &target)
        }
    }
}

/// The type ids are decoded as: a dictionary of `i32` keys into utf8 values. Parquet writers
/// store ids dictionary-encoded; decoded so, the keys come straight from the pages (no string is
/// materialised per row) and an id's index is looked up once per distinct value and batch.
pub(super) fn text_type() -> DataType {
    DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8))
}

/// How a file stores its `time` column: ns per stored unit, and whether it names a zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct TimeColumn {
    pub(super) ns_per_unit: i64,
    pub(super) zoned: bool,
}

impl TimeColumn {
    pub(super) fn of(dtype: Option<&DataType>) -> TimeColumn {
        match dtype {
            Some(DataType::Timestamp(unit, zone)) => TimeColumn {
                ns_per_unit: match unit {
                    TimeUnit::Nanosecond => 1,
                    TimeUnit::Microsecond => 1_000,
                    TimeUnit::Millisecond => 1_000_000,
                    TimeUnit::Second => 1_000_000_000,
                },
                zoned: zone.is_some(),
            },
            _ => TimeColumn {
                ns_per_unit: 1,
                zoned: false,
            },
        }
    }

    pub(super) fn unit(self) -> &'static str {
        match self.ns_per_unit {
            1 => "ns",
            1_000 => "us",
            1_000_000 => "ms",
            _ => "s",
        }
    }

    /// A stored value as ns, when it is an accepted reading time: `None` for an overflow of
    /// the ns range (µs/ms far out) or a time outside 1980 .. 2200 (NaT = `i64::MIN`, a 1970
    /// clock reset, a far future).
    pub(super) fn to_ns(self, raw: i64) -> Option<i64> {
        raw.checked_mul(self.ns_per_unit)
            .filter(|&t| reading_time_ok(t))
    }
}

/// Rows of one file with one problem: how many, the first and last row, the first value.
#[derive(Debug, Clone)]
pub(super) struct BadRange {
    pub(super) rows: u64,
    pub(super) first_row: u64,
    pub(super) last_row: u64,
    pub(super) example: String,
}

impl BadRange {
    pub(super) fn add(slot: &mut Option<BadRange>, row: u64, example: impl FnOnce() -> String) {
        match slot {
            Some(b) => {
                b.rows += 1;
                b.first_row = b.first_row.min(row);
                b.last_row = b.last_row.max(row);
            }
            None => {
                *slot = Some(BadRange {
                    rows: 1,
                    first_row: row,
                    last_row: row,
                    example: example(),
                })
            }
        }
    }

    /// Adds `other` to the range kept under `key` (file, column, problem); the example is the
    /// first row's.
    pub(super) fn merge_into<K: Ord>(ranges: &mut BTreeMap<K, BadRange>, key: K, other: BadRange) {
        let Some(mine) = ranges.get_mut(&key) else {
            ranges.insert(key, other);
            return;
        };
        if other.first_row < mine.first_row {
            mine.example = other.example;
        }
        mine.rows += other.rows;
        mine.first_row = mine.first_row.min(other.first_row);
        mine.last_row = mine.last_row.max(other.last_row);
    }

    /// The rows dropped, as an `unusable_rows` flag of the files (`quality.files`).
    pub(super) fn flag(self, path: &Path, column: &str, problem: RowProblem) -> Flag {
        let note = FlagNote::UnusableRows {
            file: path.to_path_buf(),
            column: column.to_string(),
            problem,
            first_row: self.first_row,
            last_row: self.last_row,
            first_value: self.example,
        };
        Flag::file(note, self.rows)
    }
}
