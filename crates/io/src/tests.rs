//! Tests of the io module: small parquet files written with the parquet crate directly, in every form the
//! spec allows and in every broken form the reader must name.

use crate::manifest::TomlManifest;

use std::collections::BTreeMap;
use std::path::Path;

use arrow_array::cast::AsArray;
use arrow_array::types::Float64Type;
use arrow_array::RecordBatch;

use crate::test_frames::*;

use super::{
    read_campaign, write_campaign, write_table, Column, IngestError, Table, TimeUnit, WriteOptions,
};
use dbbcal_core::campaign::{Campaign, Manifest};
use dbbcal_core::series::quality::{FlagKind, FlagNote, RowProblem};
use dbbcal_core::series::{CampaignTables, EncoderLog, Event, SensorLog};

const S: i64 = 1_000_000_000;
/// 2026-11-01T00:00:00Z in ns.
const T0: i64 = 1_793_491_200 * S;

const MANIFEST: &str = r#"
[campaign]
id = "test"
reference_temperature_c = 20.0

[plate]
material = "zerodur"
tilt_deg = 60.0
[[plate.length]]
id = "min"
mm = 250.0
u_um = 0.1
[[plate.length]]
id = "max"
mm = 400.0
u_um = 0.2

[[sensor]]
id = "T1"
kind = "air"
[[sensor]]
id = "T2"
kind = "plate"

[[bar]]
id = "B01"
resolution_nm = 5.0
fixed_length_mm = 230.0
sensor = "T1"
[[bar]]
id = "B02"
resolution_nm = 5.0
fixed_length_mm = 230.0

[[mount]]
bar = "B01"
length = "min"
from = 2026-11-01T00:00:00Z
to = 2026-11-02T00:00:00Z
"#;

// ---------------------------------------------------------------- helpers

fn campaign_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("campaign.toml"), MANIFEST).expect("write manifest");
    std::fs::create_dir_all(dir.path().join("encoders")).expect("mkdir");
    std::fs::create_dir_all(dir.path().join("temperatures")).expect("mkdir");
    dir
}

/// The standard T1 log: one reading per second from T0 - 1 s to T0 + 10 s, value = 20 + i/10.
fn write_t1(dir: &Path) {
    let times: Vec<i64> = (-1..=10).map(|i| T0 + i * S).collect();
    let celsius: Vec<f64> = (-1..=10).map(|i| 20.0 + i as f64 / 10.0).collect();
    let sensors = vec!["T1"; times.len()];
    write_df(
        &dir.join("temperatures/t1.parquet"),
        df(vec![
            time_col(&times, Unit::Nanoseconds, None),
            str_col("sensor", &sensors),
            col("celsius", celsius),
        ]),
    );
}

fn encoders(times: &[i64], bars: &[&str], counts: &[i64]) -> RecordBatch {
    df(vec![
        time_col(times, Unit::Nanoseconds, None),
        str_col("bar", bars),
        col("counts", counts),
    ])
}

/// Rows of one file dropped, as an `unusable_rows` flag says them (the words are the
/// application's): the file's name, the column, rows, first and last row (or time), the problem
/// (or the undeclared id) and the first value.
#[derive(Debug, Clone, PartialEq)]
struct Dropped {
    file: String,
    column: String,
    rows: u64,
    first: String,
    last: String,
    what: String,
}

/// The campaign is read (rows that cannot be used are dropped, issue 27): its `unusable_rows`
/// flags.
fn read_dropped(dir: &Path) -> Vec<Dropped> {
    let logs = read_campaign(dir).unwrap_or_else(|e| panic!("refused: {e}"));
    let name = |p: &Path| p.file_name().unwrap().to_string_lossy().into_owned();
    let dropped: Vec<Dropped> = logs
        .quality
        .files
        .iter()
        .filter(|f| f.kind() == FlagKind::UnusableRows)
        .map(|f| match &f.note {
            FlagNote::UnusableRows {
                file,
                column,
                problem,
                first_row,
                last_row,
                first_value,
            } => Dropped {
                file: name(file),
                column: column.clone(),
                rows: f.rows,
                first: first_row.to_string(),
                last: last_row.to_string(),
                what: format!("{problem:?} {first_value}"),
            },
            FlagNote::UndeclaredId {
                file,
                column,
                id,
                first_ns,
                last_ns,
                declared,
            } => Dropped {
                file: name(file),
                column: column.clone(),
                rows: f.rows,
                first: crate::format_ns(*first_ns),
                last: crate::format_ns(*last_ns),
                what: format!("{id} of {}", declared.join(", ")),
            },
            other => panic!("not a note of unusable rows: {other:?}"),
        })
        .collect();
    assert!(!dropped.is_empty(), "nothing dropped");
    dropped
}

/// `Dropped` from its parts.
fn dropped(file: &str, column: &str, rows: u64, first: &str, last: &str, what: &str) -> Dropped {
    Dropped {
        file: file.into(),
        column: column.into(),
        rows,
        first: first.into(),
        last: last.into(),
        what: what.into(),
    }
}

fn read_err(dir: &Path) -> String {
    match read_campaign(dir) {
        Ok(_) => panic!("expected an error"),
        Err(e) => {
            let msg = e.to_string();
            eprintln!("{msg}");
            assert!(!msg.contains('\n'), "message is not one line: {msg}");
            msg
        }
    }
}

// ---------------------------------------------------------------- tolerant reading

#[test]
fn reads_any_unit_zone_dictionary_int32_over_unsorted_files() {
    let dir = campaign_dir();
    let d = dir.path();
    write_t1(d);
    // ns, naive, plain strings, int64, rows out of order.
    write_df(
        &d.join("encoders/a.parquet"),
        encoders(
            &[T0 + 3 * S, T0 + S, T0 + 2 * S],
            &["B01", "B01", "B02"],
            &[30, 10, 200],
        ),
    );
    // us, UTC, dictionary strings, int32, an extra column.
    write_df(
        &d.join("encoders/b.parquet"),
        df(vec![
            col("junk", [1.0f64, 2.0]),
            time_col(&[T0 + 2 * S, T0 + S], Unit::Microseconds, Some("UTC")),
            dict_col("bar", &["B01", "B02"]),
            col("counts", vec![20i32, 100]),
        ]),
    );
    // ms, a non-UTC zone (the stored instant is still UTC).
    write_df(
        &d.join("encoders/c.parquet"),
        df(vec![
            time_col(
                &[T0 + 4 * S + 5_000_000],
                Unit::Milliseconds,
                Some("Europe/Berlin"),
            ),
            str_col("bar", &["B01"]),
            col("counts", [40i64]),
        ]),
    );
    let logs = read_campaign(d).expect("read");
    let b01 = &logs.bars["B01"];
    assert_eq!(
        b01.time_ns,
        vec![T0 + S, T0 + 2 * S, T0 + 3 * S, T0 + 4 * S + 5_000_000]
    );
    assert_eq!(b01.counts, vec![10, 20, 30, 40]);
    assert!(b01.celsius.is_empty(), "ingest joins no temperatures");
    let mut b01 = b01.clone();
    dbbcal_core::series::interpolate_temperatures(&mut b01, &logs.sensors);
    let t1_at: Vec<f64> = (1..=4).map(|i| 20.0 + i as f64 / 10.0).collect();
    assert_eq!(b01.celsius["T1"][..3], t1_at[..3]);
    assert!(
        (b01.celsius["T1"][3] - 20.4005).abs() < 1e-12,
        "between readings"
    );
    let b02 = &logs.bars["B02"];
    assert_eq!(b02.time_ns, vec![T0 + S, T0 + 2 * S]);
    assert_eq!(b02.counts, vec![100, 200]);
    // T2 has no readings: present (empty) as a sensor, absent from the bar logs.
    assert!(logs.sensors["T2"].time_ns.is_empty());
    assert!(!b01.celsius.contains_key("T2"));
    assert_eq!(logs.sensors["T1"].time_ns.len(), 12);
}

#[test]
fn temperatures_interpolate_between_readings_and_hold_the_nearest_outside() {
    let dir = campaign_dir();
    let d = dir.path();
    let sensor_times = [T0 + 30 * S, T0 + 10 * S, T0 + 20 * S];
    write_df(
        &d.join("temperatures/t.parquet"),
        df(vec![
            time_col(&sensor_times, Unit::Nanoseconds, None),
            str_col("sensor", &["T2", "T2", "T2"]),
            col("celsius", [3.0f64, 1.0, 2.0]),
        ]),
    );
    let times = [
        T0 + 35 * S,
        T0 + 5 * S,
        T0 + 10 * S,
        T0 + 15 * S,
        T0 + 25 * S,
        T0 + 30 * S,
    ];
    write_df(
        &d.join("encoders/e.parquet"),
        encoders(&times, &["B02"; 6], &[6, 1, 2, 3, 4, 5]),
    );
    let logs = read_campaign(d).expect("read");
    let b02 = &logs.bars["B02"];
    assert_eq!(b02.counts, vec![1, 2, 3, 4, 5, 6]);
    let mut b02 = b02.clone();
    dbbcal_core::series::interpolate_temperatures(&mut b02, &logs.sensors);
    assert_eq!(b02.celsius["T2"], vec![1.0, 1.0, 1.5, 2.5, 3.0, 3.0]);
    assert_eq!(logs.sensors["T2"].celsius, vec![1.0, 2.0, 3.0]);
    assert!(
        logs.bars["B01"].time_ns.is_empty(),
        "every manifest bar has an entry"
    );
    assert!(
        logs.sensors["T1"].time_ns.is_empty(),
        "every manifest sensor has an entry"
    );
}

#[test]
fn reads_events_sorted_keeping_unknown_kinds_and_hashes_inputs() {
    let dir = campaign_dir();
    let d = dir.path();
    write_t1(d);
    write_df(
        &d.join("encoders/e.parquet"),
        encoders(&[T0], &["B01"], &[0]),
    );
    write_df(
        &d.join("events/ev.parquet"),
        df(vec![
            time_col(&[T0 + 2 * S, T0 + S], Unit::Milliseconds, None),
            col("bar", [Some("B01"), None]),
            str_col("kind", &["door_opened", "head_power"]),
            col("value", [None, Some(1.0f64)]),
        ]),
    );
    let logs = read_campaign(d).expect("read");
    assert_eq!(
        logs.events,
        vec![
            Event {
                time_ns: T0 + S,
                bar: None,
                kind: dbbcal_core::series::EventKind::parse("head_power"),
                value: Some(1.0)
            },
            Event {
                time_ns: T0 + 2 * S,
                bar: Some("B01".into()),
                kind: dbbcal_core::series::EventKind::parse("door_opened"),
                value: None
            },
        ]
    );
    let paths: Vec<&str> = logs.inputs.iter().map(|f| f.path.as_str()).collect();
    assert_eq!(
        paths,
        vec![
            "campaign.toml",
            "encoders/e.parquet",
            "events/ev.parquet",
            "temperatures/t1.parquet"
        ]
    );
    use sha2::Digest;
    let expected = sha2::Sha256::digest(MANIFEST.as_bytes());
    let hex: String = expected.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(logs.inputs[0].sha256, hex);
    assert_eq!(logs.inputs[0].bytes, MANIFEST.len() as u64);
    assert_eq!(
        logs.campaign,
        Campaign::from_manifest(Manifest::from_toml_str(MANIFEST, "m").expect("toml"))
            .expect("valid")
    );
}

#[test]
fn equal_times_are_ordered_by_value_whatever_the_file_order() {
    let dir = campaign_dir();
    let d = dir.path();
    write_t1(d);
    write_df(
        &d.join("encoders/a.parquet"),
        encoders(&[T0 + S, T0], &["B01", "B01"], &[7, 0]),
    );
    write_df(
        &d.join("encoders/b.parquet"),
        encoders(&[T0 + S, T0 + 2 * S], &["B01", "B01"], &[3, 9]),
    );
    let b01 = &read_campaign(d).expect("read").bars["B01"];
    assert_eq!(b01.time_ns, vec![T0, T0 + S, T0 + S, T0 + 2 * S]);
    assert_eq!(b01.counts, vec![0, 3, 7, 9]);
}

#[test]
fn interleaved_bars_over_many_batches_are_split_and_sorted() {
    let dir = campaign_dir();
    let d = dir.path();
    write_t1(d);
    // 300 000 rows alternating between the bars, times descending: several streamed batches,
    // a run of one row each, every bar's rows out of order.
    let n = 300_000i64;
    let times: Vec<i64> = (0..n).map(|i| T0 + (n - i / 2) * S).collect();
    let bars: Vec<&str> = (0..n)
        .map(|i| if i % 2 == 0 { "B01" } else { "B02" })
        .collect();
    let counts: Vec<i64> = (0..n).map(|i| i % 2 * 1_000_000 + (n - i / 2)).collect();
    write_df(
        &d.join("encoders/a.parquet"),
        encoders(&times, &bars, &counts),
    );
    let logs = read_campaign(d).expect("read");
    for (bar, offset) in [("B01", 0), ("B02", 1_000_000)] {
        let log = &logs.bars[bar];
        let expected: Vec<i64> = (n / 2 + 1..=n).map(|k| T0 + k * S).collect();
        assert_eq!(log.time_ns, expected, "{bar}");
        assert!(log
            .counts
            .iter()
            .zip(&expected)
            .all(|(&c, &t)| c == offset + (t - T0) / S));
    }
}

/// Bad rows in batches that the two consumers share out are still reported as one range of the
/// file's rows, whichever consumer saw which.
#[test]
fn bad_rows_over_many_batches_are_one_range_of_the_files_rows() {
    let dir = campaign_dir();
    let d = dir.path();
    write_t1(d);
    let n = 400_000i64;
    let times: Vec<i64> = (0..n).map(|i| T0 + i * S / 1000).collect();
    let bars = vec!["B01"; n as usize];
    let mut counts: Vec<i64> = (0..n).collect();
    for row in [5, 150_000, 350_000] {
        counts[row] = 1 << 50;
    }
    write_df(
        &d.join("encoders/a.parquet"),
        encoders(&times, &bars, &counts),
    );
    let found = read_dropped(d);
    let expected = dropped(
        "a.parquet",
        "counts",
        3,
        "5",
        "350000",
        &format!("{:?} {}", RowProblem::CountsBeyondRange, 1i64 << 50),
    );
    assert_eq!(found, vec![expected]);
}

// ---------------------------------------------------------------- bad input

#[test]
fn missing_manifest_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let msg = read_err(dir.path());
    assert!(msg.contains("no campaign.toml"), "{msg}");
}

#[test]
fn manifest_errors_name_file_and_key() {
    let dir = campaign_dir();
    let text = MANIFEST.replace("length = \"min\"", "length = \"huge\"");
    std::fs::write(dir.path().join("campaign.toml"), text).expect("write");
    let msg = read_err(dir.path());
    assert!(msg.contains("campaign.toml: mount[0] (bar \"B01\"): length \"huge\" is not a plate length (known: min, max)"), "{msg}");
    assert!(matches!(
        read_campaign(dir.path()),
        Err(IngestError::Manifest(_))
    ));
}

#[test]
fn missing_or_empty_table_folders_are_named() {
    let dir = campaign_dir();
    write_t1(dir.path());
    let msg = read_err(dir.path());
    assert!(
        msg.contains("encoders") && msg.contains("no *.parquet"),
        "{msg}"
    );
    std::fs::remove_dir_all(dir.path().join("temperatures")).expect("rm");
    write_df(
        &dir.path().join("encoders/e.parquet"),
        encoders(&[T0], &["B01"], &[0]),
    );
    let msg = read_err(dir.path());
    assert!(
        msg.contains("temperatures") && msg.contains("the temperatures table is required"),
        "{msg}"
    );
}

#[test]
fn a_file_that_is_not_parquet_is_named() {
    let dir = campaign_dir();
    write_t1(dir.path());
    std::fs::write(
        dir.path().join("encoders/broken.parquet"),
        b"time,bar,counts\n1,B01,2\n",
    )
    .expect("write");
    let msg = read_err(dir.path());
    assert!(
        msg.contains("broken.parquet") && msg.contains("not a valid parquet file"),
        "{msg}"
    );
}

#[test]
fn missing_column_is_named() {
    let dir = campaign_dir();
    write_t1(dir.path());
    write_df(
        &dir.path().join("encoders/nocounts.parquet"),
        df(vec![
            time_col(&[T0], Unit::Nanoseconds, None),
            str_col("bar", &["B01"]),
        ]),
    );
    let msg = read_err(dir.path());
    assert!(
        msg.contains("nocounts.parquet: missing column `counts` (found: time, bar)"),
        "{msg}"
    );
}

#[test]
fn wrong_column_types_are_named() {
    let dir = campaign_dir();
    write_t1(dir.path());
    write_df(
        &dir.path().join("encoders/float.parquet"),
        df(vec![
            time_col(&[T0], Unit::Nanoseconds, None),
            str_col("bar", &["B01"]),
            col("counts", [1.5f64]),
        ]),
    );
    // Float counts are accepted when whole; a fraction is refused with file, column and row.
    let found = read_dropped(dir.path());
    let expected = dropped("float.parquet", "counts", 1, "0", "0", "CountsNotWhole 1.5");
    assert_eq!(found, vec![expected]);
    write_df(
        &dir.path().join("encoders/float.parquet"),
        df(vec![
            time_col(&[T0, T0 + S, T0 + 2 * S], Unit::Nanoseconds, None),
            str_col("bar", &["B01", "B01", "B01"]),
            col("counts", [Some(-7.0f64), None, Some(f64::NAN)]),
        ]),
    );
    let logs = read_campaign(dir.path()).expect("whole float counts");
    assert_eq!(logs.bars["B01"].counts, vec![-7]);
    let q = &logs.quality.bars["B01"];
    assert_eq!((q.rows, q.null, q.nan, q.dropped_rows), (3, 1, 1, 2));
    std::fs::remove_file(dir.path().join("encoders/float.parquet")).expect("rm");

    write_df(
        &dir.path().join("encoders/float.parquet"),
        df(vec![
            col("time", [T0]),
            str_col("bar", &["B01"]),
            col("counts", [1i64]),
        ]),
    );
    let msg = read_err(dir.path());
    assert!(
        msg.contains("float.parquet: column `time` has type i64, expected a timestamp"),
        "{msg}"
    );
}

#[test]
fn unknown_bar_is_named_with_file_rows_and_times() {
    let dir = campaign_dir();
    write_t1(dir.path());
    write_df(
        &dir.path().join("encoders/a.parquet"),
        encoders(&[T0], &["B01"], &[0]),
    );
    write_df(
        &dir.path().join("encoders/b.parquet"),
        encoders(
            &[T0 + S, T0, T0 + 2 * S],
            &["B99", "B01", "B99"],
            &[1, 2, 3],
        ),
    );
    let found = read_dropped(dir.path());
    let expected = dropped(
        "b.parquet",
        "bar",
        2,
        "2026-11-01T00:00:01Z",
        "2026-11-01T00:00:02Z",
        "B99 of B01, B02",
    );
    assert_eq!(found, vec![expected]);
}

#[test]
fn unknown_sensor_is_named() {
    let dir = campaign_dir();
    write_df(
        &dir.path().join("encoders/a.parquet"),
        encoders(&[T0], &["B01"], &[0]),
    );
    write_df(
        &dir.path().join("temperatures/t.parquet"),
        df(vec![
            time_col(&[T0], Unit::Nanoseconds, None),
            str_col("sensor", &["T9"]),
            col("celsius", [20.0f64]),
        ]),
    );
    let found = read_dropped(dir.path());
    assert!(
        found
            .iter()
            .any(|d| d.file == "t.parquet" && d.rows == 1 && d.what.starts_with("T9 of ")),
        "{found:?}"
    );
}

#[test]
fn null_times_and_counts_are_named() {
    let dir = campaign_dir();
    write_t1(dir.path());
    // A clean file of the same schema first: the two share a scan, and the nulls are still
    // attributed to their file.
    write_df(
        &dir.path().join("encoders/a.parquet"),
        encoders(&[T0 + 9 * S], &["B01"], &[0]),
    );
    let times = raw_time_col("time", vec![Some(T0), None], Unit::Nanoseconds, None);
    write_df(
        &dir.path().join("encoders/nulltime.parquet"),
        df(vec![
            times,
            str_col("bar", &["B01", "B01"]),
            col("counts", [1i64, 2]),
        ]),
    );
    let found = read_dropped(dir.path());
    let expected = dropped("nulltime.parquet", "time", 1, "1", "1", "Null null");
    assert!(found.contains(&expected), "{found:?}");

    std::fs::remove_file(dir.path().join("encoders/nulltime.parquet")).expect("rm");
    write_df(
        &dir.path().join("encoders/nullcounts.parquet"),
        df(vec![
            time_col(&[T0, T0 + S], Unit::Nanoseconds, None),
            str_col("bar", &["B01", "B01"]),
            col("counts", [Some(1i64), None]),
        ]),
    );
    // Null counts are missing readings: dropped and counted for their bar.
    let logs = read_campaign(dir.path()).expect("null counts are dropped");
    assert_eq!(logs.bars["B01"].counts, vec![1, 0]);
    let q = &logs.quality.bars["B01"];
    assert_eq!((q.rows, q.null, q.dropped_rows), (3, 1, 1));
    assert_eq!(q.flags[0].kind(), FlagKind::MissingValues);
}

// ---------------------------------------------------------------- writing

fn sample_tables() -> CampaignTables {
    let mut encoders = BTreeMap::new();
    // Three days, irregular sub-millisecond times, descending counts for B02.
    let b01: Vec<i64> = (0..50).map(|i| T0 + i * 3_600 * S + i * 123_457).collect();
    encoders.insert(
        "B01".to_string(),
        EncoderLog {
            counts: (0..50).collect(),
            time_ns: b01,
        },
    );
    let b02: Vec<i64> = (0..30).map(|i| T0 + i * 7_000 * S + 999).collect();
    encoders.insert(
        "B02".to_string(),
        EncoderLog {
            counts: (0..30).map(|i| 1000 - i).collect(),
            time_ns: b02,
        },
    );
    let mut temperatures = BTreeMap::new();
    let t1: Vec<i64> = (0..80).map(|i| T0 - S + i * 3_000 * S).collect();
    temperatures.insert(
        "T1".to_string(),
        SensorLog {
            celsius: (0..80).map(|i| 20.0 + i as f64 * 0.01).collect(),
            time_ns: t1,
        },
    );
    temperatures.insert("T2".to_string(), SensorLog::default());
    let events = vec![
        Event {
            time_ns: T0 + 5 * S,
            bar: Some("B01".into()),
            kind: dbbcal_core::series::EventKind::parse("rezero"),
            value: None,
        },
        Event {
            time_ns: T0 + S,
            bar: None,
            kind: dbbcal_core::series::EventKind::parse("tilt"),
            value: Some(45.0),
        },
    ];
    CampaignTables {
        encoders,
        temperatures,
        events,
    }
}

fn floored(ns: &[i64], unit: TimeUnit) -> Vec<i64> {
    let per = match unit {
        TimeUnit::Ns => 1,
        TimeUnit::Us => 1_000,
        TimeUnit::Ms => 1_000_000,
    };
    ns.iter().map(|t| t.div_euclid(per) * per).collect()
}

fn all_files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for sub in ["", "encoders", "temperatures", "events"] {
        let Ok(entries) = std::fs::read_dir(dir.join(sub)) else {
            continue;
        };
        for entry in entries {
            let path = entry.expect("entry").path();
            if path.is_file() {
                let rel = path
                    .strip_prefix(dir)
                    .expect("prefix")
                    .to_string_lossy()
                    .into_owned();
                files.insert(rel, std::fs::read(&path).expect("read"));
            }
        }
    }
    files
}

#[test]
fn write_then_read_round_trips_under_every_layout() {
    let manifest = Manifest::from_toml_str(MANIFEST, "m").expect("toml");
    let tables = sample_tables();
    let layouts = [
        WriteOptions::default(),
        WriteOptions {
            split_by_day: true,
            time_unit: TimeUnit::Us,
            shuffle_rows: true,
            interleave_rows: false,
            dictionary_strings: true,
            seed: 7,
        },
        WriteOptions {
            split_by_day: true,
            time_unit: TimeUnit::Ms,
            shuffle_rows: false,
            interleave_rows: true,
            dictionary_strings: false,
            seed: 0,
        },
    ];
    for opts in layouts {
        let dir = tempfile::tempdir().expect("tempdir");
        write_campaign(dir.path(), &manifest, &tables, &opts).expect("write");
        let logs = read_campaign(dir.path()).expect("read");
        assert_eq!(
            logs.campaign,
            Campaign::from_manifest(manifest.clone()).expect("valid")
        );
        for (bar, written) in &tables.encoders {
            let read = &logs.bars[bar];
            assert_eq!(
                read.time_ns,
                floored(&written.time_ns, opts.time_unit),
                "{opts:?}"
            );
            assert_eq!(read.counts, written.counts, "{opts:?}");
            let mut read = read.clone();
            dbbcal_core::series::interpolate_temperatures(&mut read, &logs.sensors);
            assert_eq!(read.celsius["T1"].len(), written.time_ns.len());
        }
        for (sensor, written) in &tables.temperatures {
            assert_eq!(
                logs.sensors[sensor].time_ns,
                floored(&written.time_ns, opts.time_unit)
            );
            assert_eq!(logs.sensors[sensor].celsius, written.celsius);
        }
        assert_eq!(logs.events.len(), 2);
        assert_eq!(logs.events[0].kind, dbbcal_core::series::EventKind::Tilt);
        let n_encoder_files = logs
            .inputs
            .iter()
            .filter(|f| f.path.starts_with("encoders/"))
            .count();
        assert_eq!(
            n_encoder_files,
            if opts.split_by_day { 3 } else { 1 },
            "{opts:?}"
        );
    }
}

#[test]
fn writing_is_deterministic_and_leaves_no_stale_files() {
    let manifest = Manifest::from_toml_str(MANIFEST, "m").expect("toml");
    let tables = sample_tables();
    let opts = WriteOptions {
        split_by_day: true,
        time_unit: TimeUnit::Us,
        shuffle_rows: true,
        interleave_rows: false,
        dictionary_strings: true,
        seed: 3,
    };
    let a = tempfile::tempdir().expect("tempdir");
    let b = tempfile::tempdir().expect("tempdir");
    write_campaign(a.path(), &manifest, &tables, &opts).expect("write a");
    write_campaign(b.path(), &manifest, &tables, &opts).expect("write b");
    assert_eq!(all_files(a.path()), all_files(b.path()));

    write_campaign(a.path(), &manifest, &tables, &WriteOptions::default()).expect("rewrite");
    let names: Vec<String> = all_files(a.path()).into_keys().collect();
    assert_eq!(
        names,
        vec![
            "campaign.toml",
            "encoders/encoders.parquet",
            "events/events.parquet",
            "temperatures/temperatures.parquet"
        ]
    );
}

#[test]
fn write_table_is_readable_deterministic_and_checks_lengths() {
    let dir = tempfile::tempdir().expect("tempdir");
    let table = Table::new()
        .with("bar", Column::Str(vec!["B01".into(), "B02".into()]))
        .with("gain_um_per_k", Column::F64(vec![1.5, -2.0]))
        .with("tau_s", Column::OptF64(vec![Some(600.0), None]))
        .with("n", Column::I64(vec![10, 20]));
    let (p1, p2) = (dir.path().join("a.parquet"), dir.path().join("b.parquet"));
    write_table(&p1, &table).expect("write");
    write_table(&p2, &table).expect("write");
    assert_eq!(
        std::fs::read(&p1).expect("read"),
        std::fs::read(&p2).expect("read")
    );

    let back = read_df(&p1);
    let schema = back.schema();
    let names: Vec<&str> = schema.fields().iter().map(|f| f.name().as_str()).collect();
    assert_eq!(names, vec!["bar", "gain_um_per_k", "tau_s", "n"]);
    let tau: Vec<Option<f64>> = back
        .column_by_name("tau_s")
        .expect("col")
        .as_primitive_opt::<Float64Type>()
        .expect("f64")
        .iter()
        .collect();
    assert_eq!(tau, vec![Some(600.0), None]);

    let ragged = table.with("short", Column::I64(vec![1]));
    let err = write_table(&p1, &ragged).expect_err("ragged");
    assert!(
        err.to_string()
            .contains("column `short` has 1 rows, expected 2"),
        "{err}"
    );
}

/// Timing on a campaign of realistic size (~31 M encoder rows). Run by hand:
/// `cargo test --release -p dbbcal-io tests::large -- --ignored --nocapture`.
#[test]
#[ignore]
fn large_campaign_write_and_read_timing() {
    let _ = tracing_subscriber::fmt()
        .with_max_level(tracing::Level::DEBUG)
        .with_test_writer()
        .try_init();
    let manifest = Manifest::from_toml_str(MANIFEST, "m").expect("toml");
    let rows_per_bar = 15_500_000i64; // 2 bars: 31 M rows, one reading every ~170 ms over 30 days
    let step = 30 * 86_400 * S / rows_per_bar;
    let mut tables = CampaignTables::default();
    for bar in ["B01", "B02"] {
        tables.encoders.insert(
            bar.to_string(),
            EncoderLog {
                time_ns: (0..rows_per_bar).map(|i| T0 + i * step).collect(),
                counts: (0..rows_per_bar).collect(),
            },
        );
    }
    for sensor in ["T1", "T2"] {
        let n = 30 * 1440;
        tables.temperatures.insert(
            sensor.to_string(),
            SensorLog {
                time_ns: (0..n).map(|i| T0 + i * 60 * S).collect(),
                celsius: (0..n).map(|i| 20.0 + (i % 100) as f64 / 100.0).collect(),
            },
        );
    }
    let dir = tempfile::tempdir().expect("tempdir");
    for opts in [
        WriteOptions::default(),
        WriteOptions {
            split_by_day: true,
            shuffle_rows: true,
            dictionary_strings: true,
            ..Default::default()
        },
    ] {
        let t = std::time::Instant::now();
        write_campaign(dir.path(), &manifest, &tables, &opts).expect("write");
        let written = t.elapsed();
        let t = std::time::Instant::now();
        let logs = read_campaign(dir.path()).expect("read");
        eprintln!("{opts:?}: write {written:?}, read {:?}", t.elapsed());
        assert_eq!(logs.bars["B01"].time_ns.len() as i64, rows_per_bar);
        assert_eq!(logs.bars["B02"].counts, tables.encoders["B02"].counts);
    }
}

/// Issue 27: a row with a null kind (events) or a null id (temperatures) is dropped and named
/// by file, column and rows; the other rows are read.
#[test]
fn null_kinds_and_ids_are_dropped_and_named_by_rows() {
    let dir = campaign_dir();
    let d = dir.path();
    write_t1(d);
    write_df(
        &d.join("encoders/e.parquet"),
        encoders(&[T0], &["B01"], &[0]),
    );
    write_df(
        &d.join("events/ev.parquet"),
        df(vec![
            time_col(&[T0, T0 + S, T0 + 2 * S], Unit::Nanoseconds, None),
            col("bar", [Some("B01"), None, None]),
            col("kind", [Some("door"), None, Some("door")]),
            col("value", [None::<f64>, None, None]),
        ]),
    );
    write_df(
        &d.join("temperatures/nullid.parquet"),
        df(vec![
            time_col(&[T0, T0 + S], Unit::Nanoseconds, None),
            col("sensor", [None, Some("T1")]),
            col("celsius", [20.0f64, 20.1]),
        ]),
    );
    let found = read_dropped(d);
    let expected = [
        dropped("ev.parquet", "kind", 1, "1", "1", "Null null"),
        dropped("nullid.parquet", "sensor", 1, "0", "0", "Null null"),
    ];
    for e in &expected {
        assert!(found.contains(e), "{e:?} not in {found:?}");
    }
    let logs = read_campaign(d).expect("read");
    assert_eq!(logs.events.len(), 2);
}
