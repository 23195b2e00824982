//! The findings of the quality checks as data: a [`Flag`] (where, how many rows, how big) and its
//! [`FlagNote`] (what was found, with the numbers and names the application's sentence needs:
//! `src/narrative/quality.rs`), and why a bar is [`Unusable`].
//!
//! Separate from the checks (`series::quality`) because these are the types every reader of the
//! findings uses: ingest (`dbbcal-io`) raises the file-level ones, the application words them.

use super::format_ns;
use crate::campaign::TimeNs;
use std::path::PathBuf;

/// Why a bar has no usable signal: every mounted reading was left out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unusable {
    /// The encoder is dead: counts frozen in every mount.
    EncoderDead,
    /// Every mount holds a counter wrap.
    EveryMountWrapped,
    /// Every mounted reading is frozen or in a mount with a counter wrap.
    FrozenOrWrapped,
}

/// What was found, where and how big.
#[derive(Debug, Clone, PartialEq)]
pub struct Flag {
    /// RFC 3339 UTC, first affected reading (absent for file-level flags).
    pub from: Option<String>,
    /// RFC 3339 UTC, last affected reading (absent for file-level flags).
    pub to: Option<String>,
    /// Rows (or readings) concerned.
    pub rows: u64,
    /// Signed size of a jump or wrap, counts.
    pub size_counts: Option<f64>,
    /// The same, µm.
    pub size_um: Option<f64>,
    /// What was found, as data: its kind ([`FlagNote::kind`]) and the numbers and names that
    /// say it (the words are the application's).
    pub note: FlagNote,
}

/// What a [`Flag`] found, one variant per finding, with what it takes to say it besides the
/// flag's time range and `rows` (the readings, rows or files concerned).
#[derive(Debug, Clone, PartialEq)]
pub enum FlagNote {
    /// `missing_values`: null, NaN or ±infinite values of `table` dropped (`rows`: all of them).
    MissingValues {
        /// The table of the rows.
        table: LogTable,
        /// Null values.
        null: u64,
        /// NaN values.
        nan: u64,
        /// ±infinite values.
        inf: u64,
    },
    /// `duplicate_rows`: exact copies of rows of `table` (same time and value) counted once.
    DuplicateRows {
        /// The table of the rows.
        table: LogTable,
        /// The copies were taken out of the bins ingest compressed the bar into.
        out_of_bins: bool,
    },
    /// `duplicate_file`: a file byte-identical to another of its table (same sha256), read once.
    DuplicateFile {
        /// The file not read, relative to the campaign (`/`-separated).
        file: String,
        /// The file read in its place, relative to the campaign.
        same_as: String,
    },
    /// `mixed_time_zones`: files with naive (UTC) times and files with zoned ones.
    MixedTimeZones {
        /// Files with naive times.
        naive_files: usize,
        /// Files with zoned times.
        zoned_files: usize,
        /// The name of the first file with naive times.
        naive_example: String,
    },
    /// `stuck`: counts frozen while the air moved; the readings are left out of the fits.
    Stuck {
        /// The frozen value, counts.
        counts: i64,
        /// From the run's first reading to its last, ns.
        duration_ns: TimeNs,
    },
    /// `jump`: a jump far beyond the noise and the thermal drift; not removed.
    Jump {
        /// Between two pieces or inside one bin.
        place: JumpPlace,
    },
    /// `counter_wrap`: a jump of at least 2^31 counts (half [`WRAP_COUNTS`](super::WRAP_COUNTS)); the mount is left
    /// out of the fits.
    CounterWrap {
        /// Between two pieces or inside one bin.
        place: JumpPlace,
        /// Signed size of the jump, counts (as the flag's `size_counts`).
        size_counts: f64,
    },
    /// `far_outside_mounts`: readings more than [`FAR_OUTSIDE_MOUNTS_S`](super::FAR_OUTSIDE_MOUNTS_S) before the bar's first
    /// mount or after its last; never fitted.
    FarOutsideMounts,
    /// `overlapping_files`: readings of `bar` that more than one file holds with the same time
    /// and counts, counted once.
    OverlappingFiles {
        /// The bar.
        bar: String,
        /// The files' names, in the order ingest read them.
        files: Vec<String>,
        /// The copies were taken out of the bins (else: exact duplicates, in `duplicate_rows`).
        out_of_bins: bool,
    },
    /// `conflicting_readings`: readings of a bar's full-rate rows at one time with different
    /// counts; all kept.
    ConflictingRows,
    /// `conflicting_readings`: readings of `bar` at one time with different counts, found
    /// across its files while they streamed; all kept.
    ConflictingInFiles {
        /// The bar.
        bar: String,
        /// The names of the files that hold them.
        files: Vec<String>,
    },
    /// `gap`: no reading for longer than the bar's gap threshold inside a mount.
    Gap {
        /// From the reading before the gap to the one after, ns.
        gap_ns: TimeNs,
        /// The bar's threshold: [`GAP_INTERVAL_FACTOR`](super::GAP_INTERVAL_FACTOR) × the median interval, at least
        /// [`GAP_MIN_S`](super::GAP_MIN_S); ns.
        threshold_ns: TimeNs,
        /// The bar's median interval between readings, ns.
        median_interval_ns: f64,
    },
    /// `implausible_temperature`: temperatures outside [`PLAUSIBLE_MIN_C`](super::PLAUSIBLE_MIN_C) ..
    /// [`PLAUSIBLE_MAX_C`](super::PLAUSIBLE_MAX_C), or steps beyond [`PLAUSIBLE_STEP_K`](super::PLAUSIBLE_STEP_K) + [`PLAUSIBLE_STEP_K_PER_S`](super::PLAUSIBLE_STEP_K_PER_S) ×
    /// the time since the last kept reading, dropped (`rows`: all of them).
    ImplausibleTemperatures {
        /// Those outside the plausible range (the others are steps).
        outside_range: u64,
        /// The lowest value dropped, °C.
        lowest_c: f64,
        /// The highest value dropped, °C.
        highest_c: f64,
    },
    /// `unusable_rows`: rows of one file with one problem in one column, dropped.
    UnusableRows {
        /// The file.
        file: PathBuf,
        /// The column.
        column: String,
        /// What is wrong with the rows' values in it.
        problem: RowProblem,
        /// The first row, counting from 0.
        first_row: u64,
        /// The last row, counting from 0.
        last_row: u64,
        /// The first row's value as stored (with its time unit for a time).
        first_value: String,
    },
    /// `unusable_rows`: rows of one file whose id `campaign.toml` does not declare, dropped.
    UndeclaredId {
        /// The file.
        file: PathBuf,
        /// The id column (`bar`, `sensor`).
        column: String,
        /// The id, as stored.
        id: String,
        /// The rows' first time, ns.
        first_ns: TimeNs,
        /// Their last time, ns.
        last_ns: TimeNs,
        /// The ids `campaign.toml` declares, in order.
        declared: Vec<String>,
    },
}

impl FlagNote {
    /// The kind of flag this finding raises.
    pub fn kind(&self) -> FlagKind {
        match self {
            FlagNote::MissingValues { .. } => FlagKind::MissingValues,
            FlagNote::DuplicateRows { .. } => FlagKind::DuplicateRows,
            FlagNote::DuplicateFile { .. } => FlagKind::DuplicateFile,
            FlagNote::MixedTimeZones { .. } => FlagKind::MixedTimeZones,
            FlagNote::Stuck { .. } => FlagKind::Stuck,
            FlagNote::Jump { .. } => FlagKind::Jump,
            FlagNote::CounterWrap { .. } => FlagKind::CounterWrap,
            FlagNote::FarOutsideMounts => FlagKind::FarOutsideMounts,
            FlagNote::OverlappingFiles { .. } => FlagKind::OverlappingFiles,
            FlagNote::ConflictingRows | FlagNote::ConflictingInFiles { .. } => {
                FlagKind::ConflictingReadings
            }
            FlagNote::Gap { .. } => FlagKind::Gap,
            FlagNote::ImplausibleTemperatures { .. } => FlagKind::ImplausibleTemperature,
            FlagNote::UnusableRows { .. } | FlagNote::UndeclaredId { .. } => FlagKind::UnusableRows,
        }
    }
}

/// The table a flag's rows come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogTable {
    /// The encoder readings.
    Encoders,
    /// The temperature readings.
    Temperatures,
    /// The events.
    Events,
}

/// Where a jump (or a counter wrap) was seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JumpPlace {
    /// Inside one bin: its smallest and largest counts differ by the jump.
    InsideOneBin,
    /// Between two consecutive readings (or bins).
    BetweenTwoReadings,
}

/// What is wrong with rows of an `unusable_rows` flag. The flags of one file and column come
/// in this order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RowProblem {
    /// Null where the spec wants a value.
    Null,
    /// Counts beyond ±2^48.
    CountsBeyondRange,
    /// Counts that are not whole numbers.
    CountsNotWhole,
    /// Times outside 1980-01-01 .. 2200-01-01 (NaT, a clock reset, a far future, or a unit
    /// whose ns value overflows).
    TimeOutOfBounds,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
/// The kinds of [`Flag`] (their names in `summary.json`: snake case).
pub enum FlagKind {
    /// Null, NaN or infinite values dropped.
    MissingValues,
    /// Exact copies of a row (same time and value): counted once.
    DuplicateRows,
    /// A file byte-identical to another of its table: read once.
    DuplicateFile,
    /// Naive (UTC) and zoned time columns in one campaign.
    MixedTimeZones,
    /// Counts frozen while the air moved.
    Stuck,
    /// A step between consecutive readings far beyond the segment's steps.
    Jump,
    /// A jump of at least 2^31 counts (a 32-bit counter wrapping): the mount is left out.
    CounterWrap,
    /// Readings more than 24 h from every mount of the bar (never fitted).
    FarOutsideMounts,
    /// Rows of one bar that two files both hold (same time and counts): counted once.
    OverlappingFiles,
    /// One bar, one time, different counts (a logger clock set back, or two loggers): kept.
    ConflictingReadings,
    /// No reading for longer than `gap_threshold_ns` inside a mount (a logger down, or its
    /// clock jumped forward).
    Gap,
    /// Temperatures no sensor of a room reads (below `PLAUSIBLE_MIN_C` or above
    /// `PLAUSIBLE_MAX_C`: a disconnected thermocouple, a logger's error code) or steps no air
    /// makes between two readings (`plausible_step_k`): dropped.
    ImplausibleTemperature,
    /// Rows that cannot be used (a time outside the accepted bounds or null, a null id, an id
    /// `campaign.toml` does not declare, counts that are not whole numbers or beyond ±2^48):
    /// dropped, named by file, column and rows (`quality.files`).
    UnusableRows,
}

impl Flag {
    /// A flag over the readings from `from_ns` to `to_ns`.
    pub fn at(note: FlagNote, from_ns: TimeNs, to_ns: TimeNs, rows: u64) -> Flag {
        Flag {
            from: Some(format_ns(from_ns)),
            to: Some(format_ns(to_ns)),
            rows,
            size_counts: None,
            size_um: None,
            note,
        }
    }

    /// What was found.
    pub fn kind(&self) -> FlagKind {
        self.note.kind()
    }

    /// A flag on files, with no time range.
    pub fn file(note: FlagNote, rows: u64) -> Flag {
        Flag {
            from: None,
            to: None,
            rows,
            size_counts: None,
            size_um: None,
            note,
        }
    }

    pub(super) fn sized(mut self, counts: f64, resolution_nm: f64) -> Flag {
        self.size_counts = Some(counts);
        self.size_um = Some(counts * resolution_nm * 1e-3);
        self
    }
}
