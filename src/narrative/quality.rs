//! What ingest found in the inputs, in words: each quality flag's note (`summary.json` →
//! `quality`, the headline's "rows dropped"), why a bar has no usable signal, and a failed bar's
//! reason. Core and the reader hand over the findings as data (`series::quality::FlagNote`,
//! `Unusable`, `stage::FailureReason`); the thresholds quoted are core's constants.

use std::borrow::Cow;

use crate::pipeline::{BarFailure, FailureReason};
use crate::series::quality::{
    format_ns, Flag, FlagNote, JumpPlace, LogTable, RowProblem, Unusable, FAR_OUTSIDE_MOUNTS_S,
    GAP_INTERVAL_FACTOR, GAP_MIN_S, PLAUSIBLE_MAX_C, PLAUSIBLE_MIN_C, PLAUSIBLE_STEP_K,
    PLAUSIBLE_STEP_K_PER_S, WRAP_COUNTS,
};

/// What `flag` found, in one line (its `rows` are the readings, rows or files counted).
pub fn note(flag: &Flag) -> String {
    let rows = flag.rows;
    match &flag.note {
        FlagNote::MissingValues {
            table,
            null,
            nan,
            inf,
        } => format!(
            "{rows} {} dropped as missing readings ({null} null, {nan} NaN, {inf} infinite)",
            rows_of(*table)
        ),
        FlagNote::DuplicateRows { table, out_of_bins } => format!(
            "{rows} exact duplicate {} (same time and value) counted once{}",
            rows_of(*table),
            if *out_of_bins {
                " (the copies taken out of the bins)"
            } else {
                ""
            }
        ),
        FlagNote::DuplicateFile { file, same_as } => {
            format!("{file} is byte-identical to {same_as} (same sha256): read once")
        }
        FlagNote::MixedTimeZones {
            naive_files,
            zoned_files,
            naive_example,
        } => format!(
            "{naive_files} files have naive times (taken as UTC, e.g. {naive_example}) and \
             {zoned_files} zoned ones: check the naive ones are not local time"
        ),
        FlagNote::Stuck {
            counts,
            duration_ns,
        } => format!(
            "counts frozen at {counts} for {:.2} h while the air moved: readings left out of \
             the fits",
            *duration_ns as f64 / 3.6e12
        ),
        FlagNote::Jump { place } => format!(
            "jump {}, far beyond the noise and the thermal drift; not removed",
            place_words(*place)
        ),
        FlagNote::CounterWrap { place, size_counts } => format!(
            "counter wrap {}: a jump of {size_counts:+.0} counts ({:+.3} × 2^32); the mount is \
             left out of the fits",
            place_words(*place),
            size_counts / WRAP_COUNTS as f64
        ),
        FlagNote::FarOutsideMounts => format!(
            "{rows} readings more than {:.0} h before the bar's first mount or after its last \
             (a clock reset?); handling time, not fitted",
            FAR_OUTSIDE_MOUNTS_S / 3600.0
        ),
        FlagNote::OverlappingFiles {
            bar,
            files,
            out_of_bins,
        } => format!(
            "{rows} readings of bar {bar} held by more than one file ({}) with the same time and \
             counts: counted once ({})",
            files.join(", "),
            if *out_of_bins {
                "the copies taken out of the bins"
            } else {
                "exact duplicates, in duplicate_rows"
            }
        ),
        FlagNote::ConflictingRows => conflicting(rows, "", "full-rate rows"),
        FlagNote::ConflictingInFiles { bar, files } => {
            conflicting(rows, &format!(" of bar {bar}"), &files.join(", "))
        }
        FlagNote::Gap {
            gap_ns,
            threshold_ns,
            median_interval_ns,
        } => format!(
            "no reading for {:.2} h inside a mount (threshold {:.0} s: max({GAP_INTERVAL_FACTOR} \
             × the median interval {:.1} s, {GAP_MIN_S} s)): a logger down or its clock jumped \
             forward; the fits go on",
            *gap_ns as f64 / 3.6e12,
            *threshold_ns as f64 * 1e-9,
            median_interval_ns * 1e-9
        ),
        FlagNote::ImplausibleTemperatures {
            outside_range,
            lowest_c,
            highest_c,
        } => format!(
            "{rows} temperature readings dropped ({outside_range} outside {PLAUSIBLE_MIN_C} .. \
             {PLAUSIBLE_MAX_C} °C, {} a step no air makes: more than {PLAUSIBLE_STEP_K} K + \
             {PLAUSIBLE_STEP_K_PER_S} K/s); values {lowest_c} .. {highest_c} °C",
            rows - outside_range
        ),
        FlagNote::UnusableRows {
            file,
            column,
            problem,
            first_row,
            last_row,
            first_value,
        } => format!(
            "{}: column `{column}`: {rows} rows (rows {first_row} .. {last_row}, counting from \
             0) {} (first: {first_value}): dropped",
            file.display(),
            problem_words(*problem)
        ),
        FlagNote::UndeclaredId {
            file,
            column,
            id,
            first_ns,
            last_ns,
            declared,
        } => format!(
            "{}: {rows} rows ({} .. {}) have {column} {id:?}, which campaign.toml does not \
             declare (known: {}): dropped",
            file.display(),
            format_ns(*first_ns),
            format_ns(*last_ns),
            declared.join(", ")
        ),
    }
}

/// Why bar `bar` has no usable signal (`summary.json` → `quality.bars.BAR.unusable`, and the
/// bar's failure).
pub fn unusable(bar: &str, why: Unusable) -> String {
    let why = match why {
        Unusable::EncoderDead => "the encoder is dead (counts frozen in every mount)",
        Unusable::EveryMountWrapped => "every mount holds a counter wrap",
        Unusable::FrozenOrWrapped => {
            "every mounted reading is frozen or in a mount with a counter wrap"
        }
    };
    format!("bar {bar}: no usable signal: {why} (see quality.bars.{bar}.flags)")
}

/// Why a bar failed, in one line (`failed_bars` → `error`).
pub fn failure(f: &BarFailure) -> Cow<'_, str> {
    match &f.reason {
        FailureReason::Unusable(why) => Cow::Owned(unusable(&f.bar, *why)),
        FailureReason::Error(message) => Cow::Borrowed(message),
    }
}

/// The rows of a table, as a count names them.
fn rows_of(table: LogTable) -> &'static str {
    match table {
        LogTable::Encoders => "encoder rows",
        LogTable::Temperatures => "temperature readings",
        LogTable::Events => "event rows",
    }
}

fn place_words(place: JumpPlace) -> &'static str {
    match place {
        JumpPlace::InsideOneBin => "inside one bin",
        JumpPlace::BetweenTwoReadings => "between two readings",
    }
}

/// What is wrong with the rows, after "N rows (rows A .. B)".
fn problem_words(problem: RowProblem) -> &'static str {
    match problem {
        RowProblem::Null => "are null",
        RowProblem::CountsBeyondRange => "hold counts beyond ±2^48",
        RowProblem::CountsNotWhole => "hold counts that are not whole numbers",
        RowProblem::TimeOutOfBounds => {
            "hold times outside 1980-01-01 .. 2200-01-01 (NaT, a clock reset, a far future, or a \
             unit whose ns value overflows)"
        }
    }
}

/// `rows` readings (`of_bar`: " of bar B01", or nothing) at one time with different counts, in
/// `among`.
fn conflicting(rows: u64, of_bar: &str, among: &str) -> String {
    format!(
        "{rows} readings{of_bar} share their time with a reading of other counts ({among}): a \
         logger clock set back, or two loggers; all kept"
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::series::quality::FlagKind;

    const T0_NS: i64 = 1_793_491_200_000_000_000;

    fn at(note: FlagNote, rows: u64) -> Flag {
        Flag::at(note, T0_NS, T0_NS + 3_600_000_000_000, rows)
    }

    #[test]
    fn a_gap_quotes_its_length_and_threshold() {
        let flag = at(
            FlagNote::Gap {
                gap_ns: 7_260_000_000_000,
                threshold_ns: 600_000_000_000,
                median_interval_ns: 60e9,
            },
            0,
        );
        assert_eq!(flag.kind(), FlagKind::Gap);
        assert_eq!(
            note(&flag),
            "no reading for 2.02 h inside a mount (threshold 600 s: max(10 × the median interval \
             60.0 s, 600 s)): a logger down or its clock jumped forward; the fits go on"
        );
    }

    #[test]
    fn a_counter_wrap_gives_its_size_in_counts_and_periods() {
        let flag = at(
            FlagNote::CounterWrap {
                place: JumpPlace::BetweenTwoReadings,
                size_counts: -4_294_967_296.0,
            },
            2,
        );
        assert_eq!(
            note(&flag),
            "counter wrap between two readings: a jump of -4294967296 counts (-1.000 × 2^32); the \
             mount is left out of the fits"
        );
    }

    #[test]
    fn missing_values_and_duplicates_name_their_table() {
        let missing = FlagNote::MissingValues {
            table: LogTable::Temperatures,
            null: 1,
            nan: 1,
            inf: 2,
        };
        assert_eq!(
            note(&at(missing, 4)),
            "4 temperature readings dropped as missing readings (1 null, 1 NaN, 2 infinite)"
        );
        let binned = FlagNote::DuplicateRows {
            table: LogTable::Encoders,
            out_of_bins: true,
        };
        assert_eq!(
            note(&at(binned, 31)),
            "31 exact duplicate encoder rows (same time and value) counted once (the copies \
             taken out of the bins)"
        );
    }

    #[test]
    fn implausible_temperatures_quote_the_limits() {
        let flag = at(
            FlagNote::ImplausibleTemperatures {
                outside_range: 2,
                lowest_c: -999.0,
                highest_c: 60.0,
            },
            3,
        );
        assert_eq!(
            note(&flag),
            "3 temperature readings dropped (2 outside -60 .. 150 °C, 1 a step no air makes: \
             more than 5 K + 0.05 K/s); values -999 .. 60 °C"
        );
    }

    #[test]
    fn unusable_rows_name_file_column_and_rows() {
        let rows = FlagNote::UnusableRows {
            file: "/c/encoders/float.parquet".into(),
            column: "counts".into(),
            problem: RowProblem::CountsNotWhole,
            first_row: 3,
            last_row: 9,
            first_value: "1.5".into(),
        };
        assert_eq!(
            note(&Flag::file(rows, 2)),
            "/c/encoders/float.parquet: column `counts`: 2 rows (rows 3 .. 9, counting from 0) \
             hold counts that are not whole numbers (first: 1.5): dropped"
        );
        let id = FlagNote::UndeclaredId {
            file: "/c/encoders/b.parquet".into(),
            column: "bar".into(),
            id: "B99".into(),
            first_ns: T0_NS + 1_000_000_000,
            last_ns: T0_NS + 2_000_000_000,
            declared: vec!["B01".into(), "B02".into()],
        };
        assert_eq!(
            note(&Flag::file(id, 2)),
            "/c/encoders/b.parquet: 2 rows (2026-11-01T00:00:01Z .. 2026-11-01T00:00:02Z) have \
             bar \"B99\", which campaign.toml does not declare (known: B01, B02): dropped"
        );
    }

    #[test]
    fn conflicts_and_overlaps_name_the_bar_and_files() {
        let files = vec!["a.parquet".to_string(), "b.parquet".to_string()];
        let conflicts = FlagNote::ConflictingInFiles {
            bar: "B01".into(),
            files: files.clone(),
        };
        assert_eq!(
            note(&at(conflicts, 20)),
            "20 readings of bar B01 share their time with a reading of other counts (a.parquet, \
             b.parquet): a logger clock set back, or two loggers; all kept"
        );
        assert_eq!(
            note(&at(FlagNote::ConflictingRows, 20)),
            "20 readings share their time with a reading of other counts (full-rate rows): a \
             logger clock set back, or two loggers; all kept"
        );
        let overlap = FlagNote::OverlappingFiles {
            bar: "B01".into(),
            files,
            out_of_bins: false,
        };
        assert_eq!(
            note(&at(overlap, 300)),
            "300 readings of bar B01 held by more than one file (a.parquet, b.parquet) with the \
             same time and counts: counted once (exact duplicates, in duplicate_rows)"
        );
    }

    #[test]
    fn a_dead_bar_fails_with_the_reason_quality_gives() {
        let failed = BarFailure {
            bar: "B03".into(),
            reason: FailureReason::Unusable(Unusable::EncoderDead),
        };
        let why = "bar B03: no usable signal: the encoder is dead (counts frozen in every mount) \
                   (see quality.bars.B03.flags)";
        assert_eq!(failure(&failed), why);
        assert_eq!(unusable("B03", Unusable::EncoderDead), why);
        let error = BarFailure {
            bar: "B01".into(),
            reason: FailureReason::Error("bar B01: no mount".into()),
        };
        assert_eq!(failure(&error), "bar B01: no mount");
    }
}
