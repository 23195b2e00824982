//! `positions/*.parquet` (`docs/spec/device-format.md`): every form the reader must accept, and
//! the broken forms it must name in one line (file, column, rows).

use std::path::Path;

use polars::prelude as pl;
use polars::prelude::{DataType, IntoColumn, TimeZone};

use super::{read_positions, IngestError};

const S: i64 = 1_000_000_000;
const T0: i64 = 1_793_491_200 * S;

fn write_df(path: &Path, mut df: pl::DataFrame) {
    std::fs::create_dir_all(path.parent().expect("parent")).expect("mkdir");
    let file = std::fs::File::create(path).expect("create");
    pl::ParquetWriter::new(file)
        .finish(&mut df)
        .expect("write parquet");
}

fn time_col(ns: &[i64], unit: pl::TimeUnit) -> pl::Column {
    let per = match unit {
        pl::TimeUnit::Nanoseconds => 1,
        pl::TimeUnit::Microseconds => 1_000,
        pl::TimeUnit::Milliseconds => 1_000_000,
    };
    let values: Vec<i64> = ns.iter().map(|t| t / per).collect();
    pl::Int64Chunked::from_vec("time".into(), values)
        .into_datetime(unit, TimeZone::opt_try_new(None::<&str>).expect("zone"))
        .into_column()
}

fn frame(times: &[i64], unit: pl::TimeUnit, x: &[f64], station: &[Option<i64>]) -> Vec<pl::Column> {
    let n = times.len();
    vec![
        time_col(times, unit),
        pl::Column::new("device".into(), vec!["hexapod-1"; n])
            .cast(&DataType::from_categories(pl::Categories::global()))
            .expect("dictionary"),
        pl::Column::new("x_mm".into(), x),
        pl::Column::new("y_mm".into(), vec![300.0; n]),
        pl::Column::new("z_mm".into(), vec![-200.0; n]),
        pl::Column::new("station".into(), station)
            .cast(&DataType::Int32)
            .expect("int32"),
    ]
}

fn df(columns: Vec<pl::Column>) -> pl::DataFrame {
    pl::DataFrame::new_infer_height(columns).expect("frame")
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
            pl::TimeUnit::Milliseconds,
            &[405.0, 410.0, 400.0],
            &[None, Some(2), Some(1)],
        )),
    );
    let mut a = frame(
        &[T0 + 10 * S, T0, T0 + 20 * S],
        pl::TimeUnit::Microseconds,
        &[400.0, 400.0, 400.0],
        &[Some(1), Some(1), None],
    );
    a.push(pl::Column::new("run".into(), [1i64, 1, 1]));
    a.push(pl::Column::new("c_deg".into(), [None::<f64>, None, None]));
    a.push(pl::Column::new("extra".into(), ["x", "y", "z"]));
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

fn refused(columns: Vec<pl::Column>, words: &[&str]) {
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
            pl::TimeUnit::Nanoseconds,
            &[400.0, 400.0, 410.0],
            &[Some(1), None, Some(2)],
        )
    };
    let mut missing = good();
    missing.remove(3); // y_mm
    refused(missing, &["missing column `y_mm`"]);
    let mut wrong = good();
    wrong[5] = pl::Column::new("station".into(), ["1", "", "2"]);
    refused(wrong, &["column `station`", "int64 or int32"]);
    let mut nulls = good();
    nulls[2] = pl::Column::new("x_mm".into(), [Some(400.0), None, None]);
    refused(nulls, &["column `x_mm`", "rows 1 .. 2", "null"]);
    refused(
        frame(
            &[T0, T0 + S, T0 + 2 * S],
            pl::TimeUnit::Nanoseconds,
            &[400.0, 410.0, 400.01],
            &[Some(1), Some(2), Some(1)],
        ),
        &["column `x_mm`", "station 1", "row 2", "row 0"],
    );
}
