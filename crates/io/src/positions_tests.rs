//! `positions/*.parquet` (`docs/spec/device-format.md`): every form the reader must accept, and
//! the broken forms it must name in one line (file, column, rows).

use crate::test_frames::{col, df, dict_col, raw_time_col, write_df, Col, Unit};

use super::{read_positions, IngestError};

const S: i64 = 1_000_000_000;
const T0: i64 = 1_793_491_200 * S;

fn time_col(ns: &[i64], unit: Unit) -> Col {
    let per = match unit {
        Unit::Nanoseconds => 1,
        Unit::Microseconds => 1_000,
        Unit::Milliseconds => 1_000_000,
    };
    raw_time_col(
        "time",
        ns.iter().map(|t| Some(t / per)).collect(),
        unit,
        None,
    )
}

fn frame(times: &[i64], unit: Unit, x: &[f64], station: &[Option<i64>]) -> Vec<Col> {
    let n = times.len();
    let station: Vec<Option<i32>> = station
        .iter()
        .map(|s| s.map(|v| i32::try_from(v).expect("int32")))
        .collect();
    vec![
        time_col(times, unit),
        dict_col("device", &vec!["hexapod-1"; n]),
        col("x_mm", x),
        col("y_mm", vec![300.0; n]),
        col("z_mm", vec![-200.0; n]),
        col("station", station),
    ]
}

#[test]
fn split_unsorted_files_in_any_unit_with_optional_columns_absent_or_present_are_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    assert!(read_positions(dir.path()).expect("no folder").is_none());
    // File b (ms, no optional columns) holds the later rows, unsorted; file a (us) has `run` and
    // an all-null `c_deg`.
    write_df(
        &dir.path().join("positions/b.parquet"),
        df(frame(
            &[T0 + 40 * S, T0 + 30 * S, T0 + 50 * S],
            Unit::Milliseconds,
            &[405.0, 410.0, 400.0],
            &[None, Some(2), Some(1)],
        )),
    );
    let mut a = frame(
        &[T0 + 10 * S, T0, T0 + 20 * S],
        Unit::Microseconds,
        &[400.0, 400.0, 400.0],
        &[Some(1), Some(1), None],
    );
    a.push(col("run", [1i64, 1, 1]));
    a.push(col("c_deg", [None::<f64>, None, None]));
    a.push(col("extra", ["x", "y", "z"]));
    write_df(&dir.path().join("positions/a.parquet"), df(a));
    let (log, hashes) = read_positions(dir.path()).expect("read").expect("some");
    assert_eq!(hashes.len(), 2);
    assert_eq!(hashes[0].path, "positions/a.parquet");
    let dwells = log.dwells("hexapod-1");
    let got: Vec<(i64, i64, Option<i64>, Option<i64>)> = dwells
        .iter()
        .map(|d| {
            (
                d.station,
                (d.from_ns - T0) / S,
                d.to_ns.map(|t| (t - T0) / S),
                d.run,
            )
        })
        .collect();
    assert_eq!(
        got,
        vec![
            (1, 0, Some(20), Some(1)),
            (2, 30, Some(40), None),
            (1, 50, None, None)
        ]
    );
    assert_eq!(dwells[1].approach, [1, 0, 0]);
    assert_eq!(dwells[0].rotary_deg, [None; 3]);
}

fn refused(columns: Vec<Col>, words: &[&str]) {
    let dir = tempfile::tempdir().expect("tempdir");
    write_df(&dir.path().join("positions/p.parquet"), df(columns));
    let e: IngestError = read_positions(dir.path()).expect_err("refused");
    let m = e.to_string();
    assert!(!m.contains('\n'), "{m}");
    assert!(m.contains("p.parquet"), "{m}");
    for w in words {
        assert!(m.contains(w), "{m:?} lacks {w:?}");
    }
}

#[test]
fn broken_positions_files_are_named_by_file_column_and_rows() {
    let good = || {
        frame(
            &[T0, T0 + S, T0 + 2 * S],
            Unit::Nanoseconds,
            &[400.0, 400.0, 410.0],
            &[Some(1), None, Some(2)],
        )
    };
    let mut missing = good();
    missing.remove(3); // y_mm
    refused(missing, &["missing column `y_mm`"]);
    let mut wrong = good();
    wrong[5] = col("station", ["1", "", "2"]);
    refused(wrong, &["column `station`", "int64 or int32"]);
    let mut nulls = good();
    nulls[2] = col("x_mm", [Some(400.0), None, None]);
    refused(nulls, &["column `x_mm`", "rows 1 .. 2", "null"]);
    refused(
        frame(
            &[T0, T0 + S, T0 + 2 * S],
            Unit::Nanoseconds,
            &[400.0, 410.0, 400.01],
            &[Some(1), Some(2), Some(1)],
        ),
        &["column `x_mm`", "station 1", "row 2", "row 0"],
    );
}
