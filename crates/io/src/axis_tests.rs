//! Tests of the `axis` reader and writer: small parquet files written with the parquet crate directly, in
//! the forms the reader rules allow and in the broken forms it must name.

use crate::manifest::TomlManifest;

use std::path::Path;

use crate::test_frames::{col, df, dict_col, raw_time_col, write_df, Col, Unit};

use super::{read_axis_campaign, write_axis_campaign, AxisWriteOptions, TimeUnit};
use dbbcal_core::axis_campaign::{
    AxisCampaignTables, AxisManifest, AxisReading, Channel, EnvironmentRow, ExtraColumn, FixtureRow,
};

const S: i64 = 1_000_000_000;
/// 2026-12-01T00:00:00Z in ns.
const T0: i64 = 1_796_083_200 * S;

const MANIFEST: &str = r#"
campaign = { kind = "axis", id = "vmc-x", reference_temperature_c = 20.0 }
machine = { axis = "X", cte_ppm_per_k = 11.5 }
laser = { wavelength_nm = 632.990577, compensation = "air", dead_path_mm = 150.0 }
line = [ { id = 1, reflector_mm = [0.0, 0.0, 0.0] },
         { id = 2, reflector_mm = [0.0, 0.0, 100.0] },
         { id = 3, reflector_mm = [0.0, 100.0, 100.0] } ]

[fixture]
u_um = 5.0
"#;

/// Two runs (up, then down) of 4 targets on lines 1 (dx, dy) and 2 (dx): a deviation that
/// tells every row apart.
fn readings() -> Vec<AxisReading> {
    let mut rows = Vec::new();
    let mut t = T0;
    for (line, channels) in [(1, vec![Channel::Dx, Channel::Dy]), (2, vec![Channel::Dx])] {
        for run in 1..=2 {
            let mut targets = vec![0.0, 100.0, 200.0, 300.0];
            let direction = if run == 1 { 1 } else { -1 };
            if direction < 0 {
                targets.reverse();
            }
            for x in targets {
                t += 5 * S;
                for &c in &channels {
                    rows.push(AxisReading {
                        time_ns: t,
                        line,
                        run,
                        direction,
                        target_mm: x,
                        channel: c,
                        deviation_um: x * 0.001
                            + line as f64
                            + 0.1 * run as f64
                            + 0.01 * c.index() as f64,
                    });
                }
            }
        }
    }
    rows
}

fn tables() -> AxisCampaignTables {
    AxisCampaignTables {
        readings: readings(),
        fixture: vec![
            FixtureRow {
                time_ns: T0,
                line: 1,
                reflector_mm: [0.0, 0.0, 0.5],
            },
            FixtureRow {
                time_ns: T0 + 12 * S,
                line: 1,
                reflector_mm: [0.0, 0.0, 0.7],
            },
        ],
        environment: (0..10)
            .map(|i| EnvironmentRow {
                time_ns: T0 + i * 10 * S,
                air_c: 20.0 + 0.01 * i as f64,
                pressure_hpa: 1013.0,
                humidity_pct: 45.0,
                material_c: if i == 3 { None } else { Some(20.5) },
                env_factor_ppm: None,
            })
            .collect(),
    }
}

fn manifest() -> AxisManifest {
    AxisManifest::from_toml_str(MANIFEST, "campaign.toml").unwrap()
}

fn write(dir: &Path, opts: &AxisWriteOptions) {
    write_axis_campaign(dir, &manifest(), &tables(), opts).unwrap();
}

fn time_col(ns: &[i64]) -> Col {
    raw_time_col(
        "time",
        ns.iter().map(|&t| Some(t)).collect(),
        Unit::Nanoseconds,
        None,
    )
}

/// A readings file of `n` rows with the standard columns: line 1, run 1, targets 0, 10, ….
fn readings_df(n: usize) -> Vec<Col> {
    let times: Vec<i64> = (0..n as i64).map(|i| T0 + i * S).collect();
    vec![
        time_col(&times),
        col("line", vec![1i64; n]),
        col("run", vec![1i64; n]),
        col(
            "target_mm",
            (0..n).map(|i| i as f64 * 10.0).collect::<Vec<_>>(),
        ),
        col("channel", vec!["dx"; n]),
        col("deviation_um", vec![0.5f64; n]),
    ]
}

fn replace(mut columns: Vec<Col>, column: Col) -> Vec<Col> {
    match columns.iter().position(|c| c.name() == column.name()) {
        Some(i) => columns[i] = column,
        None => columns.push(column),
    }
    columns
}

/// A campaign of the manifest (compensation = air) with one readings file of `columns` and a
/// good environment; the reader's error, one line.
fn error_with(columns: Vec<Col>) -> String {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &AxisWriteOptions::default());
    std::fs::remove_file(dir.path().join("readings/readings.parquet")).unwrap();
    write_df(&dir.path().join("readings/bad.parquet"), df(columns));
    let e = read_axis_campaign(dir.path())
        .expect_err("should fail")
        .to_string();
    assert!(!e.contains('\n'), "not one line: {e}");
    e
}

#[test]
fn a_written_campaign_reads_back_whole_and_hashed() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &AxisWriteOptions::default());
    let logs = read_axis_campaign(dir.path()).unwrap();
    assert_eq!(logs.readings, readings());
    assert_eq!(logs.fixture, tables().fixture);
    assert_eq!(logs.environment, tables().environment);
    assert_eq!(logs.campaign.line_ids(), [1, 2, 3]);
    let paths: Vec<&str> = logs.inputs.iter().map(|f| f.path.as_str()).collect();
    assert_eq!(
        paths,
        [
            "campaign.toml",
            "environment/environment.parquet",
            "fixture/fixture.parquet",
            "readings/readings.parquet"
        ]
    );
    assert!(logs
        .inputs
        .iter()
        .all(|f| f.sha256.len() == 64 && f.bytes > 0));
    // The fixture rule: before line 1's second row its first; line 2 has none: the manifest's.
    let r = logs.readings[0];
    assert_eq!(logs.reflector_mm(&r), [0.0, 0.0, 0.5]);
    let late = logs
        .readings
        .iter()
        .find(|r| r.line == 1 && r.run == 2)
        .unwrap();
    assert_eq!(logs.reflector_mm(late), [0.0, 0.0, 0.7]);
    let line2 = logs.readings.iter().find(|r| r.line == 2).unwrap();
    assert_eq!(logs.reflector_mm(line2), [0.0, 0.0, 100.0]);
}

#[test]
fn split_files_in_any_order_and_unsorted_rows_give_the_same_logs() {
    let reference = {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), &AxisWriteOptions::default());
        read_axis_campaign(dir.path()).unwrap()
    };
    for (seed, unit, dictionary, direction) in [
        (1, TimeUnit::Us, true, true),
        (2, TimeUnit::Ms, false, false),
        (3, TimeUnit::Ns, true, false),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let opts = AxisWriteOptions {
            split_by_line: true,
            time_unit: unit,
            shuffle_rows: true,
            dictionary_strings: dictionary,
            write_direction: direction,
            seed,
        };
        write(dir.path(), &opts);
        let logs = read_axis_campaign(dir.path()).unwrap();
        assert_eq!(logs.readings, reference.readings, "seed {seed}");
        assert_eq!(logs.environment, reference.environment);
        assert_eq!(logs.fixture, reference.fixture);
    }
}

#[test]
fn narrow_integers_zoned_times_and_extra_columns_are_read() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &AxisWriteOptions::default());
    std::fs::remove_file(dir.path().join("readings/readings.parquet")).unwrap();
    let n = 4;
    let times: Vec<i64> = (0..n as i64).map(|i| (T0 + i * S) / 1000).collect();
    let zoned = raw_time_col(
        "time",
        times.into_iter().map(Some).collect(),
        Unit::Microseconds,
        Some("Europe/Berlin"),
    );
    let mut columns = replace(readings_df(n), zoned);
    columns = replace(columns, col("line", vec![1i8; n]));
    columns = replace(columns, col("run", vec![1u32; n]));
    columns.push(col("laser_temp_c", vec![21.5f32; n]));
    columns.push(col("operator", vec!["ann"; n]));
    write_df(&dir.path().join("readings/r.parquet"), df(columns));
    let logs = read_axis_campaign(dir.path()).unwrap();
    assert_eq!(logs.readings.len(), n);
    assert_eq!(logs.readings[1].time_ns, T0 + S);
    assert!(logs.readings.iter().all(|r| r.direction == 1));
    assert_eq!(
        logs.extra["laser_temp_c"],
        ExtraColumn::Real(vec![Some(21.5); n])
    );
    assert_eq!(
        logs.extra["operator"],
        ExtraColumn::Text(vec![Some("ann".to_string()); n])
    );
}

#[test]
fn every_bad_input_is_named_by_file_column_and_rows() {
    let n = 5;
    let cases: Vec<(Vec<Col>, &[&str])> = vec![
        (
            readings_df(n)
                .into_iter()
                .filter(|c| c.name() != "channel")
                .collect(),
            &["bad.parquet: missing column `channel`"],
        ),
        (
            replace(readings_df(n), col("target_mm", vec!["0"; n])),
            &[
                "bad.parquet: column `target_mm` has type",
                "expected float64",
            ],
        ),
        (
            replace(
                readings_df(n),
                col("channel", ["dx", "dx", "dw", "dx", "x"]),
            ),
            &[
                "column `channel`: 2 rows (rows 2 .. 4",
                "not dx, dy or dz",
                "\"dw\"",
            ],
        ),
        (
            replace(readings_df(n), col("line", [1i64, 7, 7, 1, 1])),
            &["bad.parquet: 2 rows", "have line \"7\"", "known: 1, 2, 3"],
        ),
        (
            replace(
                readings_df(n),
                col("deviation_um", [0.5, 0.5, 0.5, f64::NAN, 0.5]),
            ),
            &["column `deviation_um`: 1 rows (rows 3 .. 3", "NaN"],
        ),
        (
            replace(
                readings_df(n),
                col("run", [Some(1i64), None, Some(1), Some(1), Some(1)]),
            ),
            &["column `run`: 1 rows (rows 1 .. 1", "are null"],
        ),
        (
            replace(readings_df(n), col("run", [1i64, 1, 0, 1, 1])),
            &["column `run`", "runs count from 1"],
        ),
        (
            replace(readings_df(n), col("direction", [1i64, 1, 3, 1, 1])),
            &[
                "column `direction`: 1 rows (rows 2 .. 2",
                "neither +1 nor -1",
            ],
        ),
        (
            replace(readings_df(n), time_col(&[T0; 5])),
            &[
                "column `direction`: 5 rows (rows 0 .. 4",
                "of line 1, run 1",
                "share one time at different targets",
                "give `direction`",
            ],
        ),
        (
            replace(readings_df(n), col("target_mm", vec![10.0; n])),
            &["of line 1, run 1", "cannot be derived"],
        ),
        (
            replace(readings_df(n), time_col(&[T0, T0, T0, 0, 0])),
            &["column `time`: 2 rows (rows 3 .. 4", "outside 1980"],
        ),
    ];
    for (columns, needles) in cases {
        let e = error_with(columns);
        for needle in needles {
            assert!(e.contains(needle), "{needle:?} not in: {e}");
        }
    }
}

#[test]
fn the_environment_is_required_and_checked() {
    // compensation = "air": no environment → refused, naming the key.
    let dir = tempfile::tempdir().unwrap();
    let mut t = tables();
    t.environment.clear();
    write_axis_campaign(dir.path(), &manifest(), &t, &AxisWriteOptions::default()).unwrap();
    let e = read_axis_campaign(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("laser.compensation") && e.contains("environment"),
        "{e}"
    );
    // With air+material it is not.
    let m =
        AxisManifest::from_toml_str(&MANIFEST.replace("\"air\"", "\"air+material\""), "c").unwrap();
    write_axis_campaign(dir.path(), &m, &t, &AxisWriteOptions::default()).unwrap();
    assert!(read_axis_campaign(dir.path())
        .unwrap()
        .environment
        .is_empty());
    // Pressure in Pa: refused by rows.
    let mut t = tables();
    t.environment[4].pressure_hpa = 101_300.0;
    write_axis_campaign(dir.path(), &manifest(), &t, &AxisWriteOptions::default()).unwrap();
    let e = read_axis_campaign(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("environment.parquet: column `pressure_hpa`: 1 rows (rows 4 .. 4"),
        "{e}"
    );
    // A fixture row of an undeclared line.
    let mut t = tables();
    t.fixture[1].line = 9;
    write_axis_campaign(dir.path(), &manifest(), &t, &AxisWriteOptions::default()).unwrap();
    let e = read_axis_campaign(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("fixture.parquet") && e.contains("line \"9\""),
        "{e}"
    );
    // Another kind's manifest.
    std::fs::write(
        dir.path().join("campaign.toml"),
        "[campaign]\nid = \"x\"\nreference_temperature_c = 20.0\n",
    )
    .unwrap();
    let e = read_axis_campaign(dir.path()).unwrap_err().to_string();
    assert!(e.contains("is a ballbar campaign"), "{e}");
}

#[test]
fn dictionary_channels_and_categorical_casts_stay_strings() {
    let columns = replace(readings_df(3), dict_col("channel", &["dx", "dy", "dz"]));
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &AxisWriteOptions::default());
    std::fs::remove_file(dir.path().join("readings/readings.parquet")).unwrap();
    write_df(&dir.path().join("readings/r.parquet"), df(columns));
    let logs = read_axis_campaign(dir.path()).unwrap();
    let channels: Vec<Channel> = logs.readings.iter().map(|r| r.channel).collect();
    assert_eq!(channels, [Channel::Dx, Channel::Dy, Channel::Dz]);
}

#[test]
fn a_reading_two_files_hold_is_kept_once() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &AxisWriteOptions::default());
    let once = read_axis_campaign(dir.path()).unwrap();
    assert_eq!(once.duplicate_readings, 0);
    std::fs::copy(
        dir.path().join("readings/readings.parquet"),
        dir.path().join("readings/copy.parquet"),
    )
    .unwrap();
    let twice = read_axis_campaign(dir.path()).unwrap();
    assert_eq!(twice.readings, once.readings);
    assert_eq!(twice.duplicate_readings, once.readings.len() as u64);
    assert_eq!(twice.inputs.len(), once.inputs.len() + 1);
}

#[test]
fn extra_columns_follow_their_rows_through_any_order() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &AxisWriteOptions::default());
    std::fs::remove_file(dir.path().join("readings/readings.parquet")).unwrap();
    // Rows in reverse, split over two files, the second without the extra column.
    let rows: Vec<AxisReading> = readings().into_iter().rev().collect();
    let (a, b) = rows.split_at(rows.len() / 2);
    for (name, part, with_extra) in [("a", a, true), ("b", b, false)] {
        let times: Vec<i64> = part.iter().map(|r| r.time_ns).collect();
        let mut columns = vec![
            time_col(&times),
            col("line", part.iter().map(|r| r.line).collect::<Vec<_>>()),
            col("run", part.iter().map(|r| r.run).collect::<Vec<_>>()),
            col(
                "target_mm",
                part.iter().map(|r| r.target_mm).collect::<Vec<_>>(),
            ),
            col(
                "channel",
                part.iter().map(|r| r.channel.as_str()).collect::<Vec<_>>(),
            ),
            col(
                "deviation_um",
                part.iter().map(|r| r.deviation_um).collect::<Vec<_>>(),
            ),
        ];
        if with_extra {
            columns.push(col(
                "copy",
                part.iter().map(|r| r.deviation_um).collect::<Vec<_>>(),
            ));
        }
        write_df(
            &dir.path().join(format!("readings/{name}.parquet")),
            df(columns),
        );
    }
    let logs = read_axis_campaign(dir.path()).unwrap();
    assert_eq!(logs.readings, readings());
    let ExtraColumn::Real(copy) = &logs.extra["copy"] else {
        panic!("not numbers")
    };
    let in_a: Vec<(i64, f64)> = a.iter().map(|r| (r.time_ns, r.deviation_um)).collect();
    for (r, c) in logs.readings.iter().zip(copy) {
        let expected = in_a
            .iter()
            .any(|&(t, d)| t == r.time_ns && d == r.deviation_um)
            .then_some(r.deviation_um);
        assert_eq!(*c, expected);
    }
}
