//! Bad input through the CLI: one clear line naming what and where, exit code 3, and no output
//! folder (not even a partial one).

use std::path::{Path, PathBuf};

use dbbcal::io::{write_campaign, write_table, Column, Table, TimeUnit, WriteOptions};
use dbbcal::series::CampaignTables;
use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::corpus::check_refused;
use crate::support::{run_cli, simulate_campaign};

/// One day, `n_bars` bars, a reading a minute.
fn small_config(name: &str, n_bars: usize) -> SimConfig {
    SimConfig {
        seed: 5,
        campaign_id: name.into(),
        duration_days: 1.0,
        sample_s: 60.0,
        fleet: Some(FleetConfig {
            n_bars,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    }
}

fn small_campaign(root: &Path, name: &str) -> PathBuf {
    simulate_campaign(root, name, &small_config(name, 2)).0
}

fn encoder_table(bar: &str, counts: Column) -> Table {
    Table::new()
        .with(
            "time",
            Column::TimeNs(vec![1_793_491_200_000_000_000, 1_793_491_260_000_000_000]),
        )
        .with("bar", Column::Str(vec![bar.into(), bar.into()]))
        .with("counts", counts)
}

/// Run the nightly pipeline on `dir`, then `identify` with bins accumulated while ingest streams
/// (a second reading path); expect exit 3, one line containing every `needles`, and the earlier
/// output untouched by either.
fn check(dir: &Path, needles: &[&str]) {
    check_refused(dir, &["run", "pipelines/nightly.toml"], 3, needles);
    check_refused(dir, &["identify", "--bin-s", "60"], 3, needles);
}

/// Rows that cannot be used are dropped, counted and flagged, and the night goes on (issue 27):
/// the nightly pipeline, `identify` with bins and at full rate exit 0; `summary.json` →
/// `quality.files` holds an `unusable_rows` flag whose note has every `needles` (file, column,
/// rows), and the terminal block and the page say it too.
fn check_dropped(dir: &Path, needles: &[&str]) {
    let runs: [&[&str]; 3] = [
        &["run", "pipelines/nightly.toml"],
        &["identify", "--bin-s", "60"],
        &["identify", "--bin-s", "0"],
    ];
    for (k, command) in runs.into_iter().enumerate() {
        let out = dir.with_extension(format!("dropped-{k}"));
        let _ = std::fs::remove_dir_all(&out);
        let mut args = command.to_vec();
        args.extend([
            "--campaign",
            dir.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let (code, _, stderr) = run_cli(&args);
        let what = format!("{command:?} on {}", dir.display());
        assert_eq!(code, 0, "{what}: {stderr}");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let notes: Vec<&str> = summary["quality"]["files"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["kind"] == "unusable_rows")
            .map(|f| f["note"].as_str().unwrap())
            .collect();
        assert!(
            notes.iter().any(|n| needles.iter().all(|x| n.contains(x))),
            "{what}: {needles:?} not in {notes:?}"
        );
        let said = stderr
            .lines()
            .any(|l| l.contains("rows dropped") && l.contains(needles[0]));
        assert!(said, "{what}: the terminal block does not say it: {stderr}");
        let page = std::fs::read_to_string(out.join("index.html")).unwrap();
        assert!(page.contains("rows dropped"), "{what}: not on the page");
    }
}

#[test]
fn bad_inputs_give_one_clear_line_and_no_output() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();

    let d = small_campaign(root, "missing-column");
    write_table(
        &d.join("encoders/extra.parquet"),
        &Table::new()
            .with("time", Column::TimeNs(vec![1_793_491_200_000_000_000]))
            .with("bar", Column::Str(vec!["B01".into()])),
    )
    .unwrap();
    check(&d, &["extra.parquet", "counts"]);

    let d = small_campaign(root, "wrong-type");
    write_table(
        &d.join("encoders/strings.parquet"),
        &encoder_table("B01", Column::Str(vec!["12".into(), "13".into()])),
    )
    .unwrap();
    check(&d, &["strings.parquet", "counts"]);

    let d = small_campaign(root, "unknown-bar");
    write_table(
        &d.join("encoders/ghost.parquet"),
        &encoder_table("B99", Column::I64(vec![1, 2])),
    )
    .unwrap();
    check_dropped(&d, &["ghost.parquet", "B99", "does not declare"]);

    let d = small_campaign(root, "corrupt");
    std::fs::write(
        d.join("encoders/broken.parquet"),
        b"PAR1 this is not a parquet file",
    )
    .unwrap();
    check(&d, &["broken.parquet"]);

    let d = small_campaign(root, "empty-folder");
    for f in std::fs::read_dir(d.join("encoders")).unwrap() {
        std::fs::remove_file(f.unwrap().path()).unwrap();
    }
    check(&d, &["encoders"]);

    let d = small_campaign(root, "unknown-length");
    let manifest = std::fs::read_to_string(d.join("campaign.toml")).unwrap();
    let first = manifest
        .find("length = \"")
        .expect("a mount on a plate length");
    let end = first + manifest[first + 10..].find('"').unwrap() + 10;
    let broken = format!("{}length = \"huge{}", &manifest[..first], &manifest[end..]);
    std::fs::write(d.join("campaign.toml"), broken).unwrap();
    check(&d, &["campaign.toml", "huge"]);

    let d = small_campaign(root, "bin-too-long");
    check_refused(
        &d,
        &["identify", "--bin-s", "7200"],
        3,
        &["--bin-s", "3600"],
    );
}

#[test]
fn a_bar_without_data_fails_alone_with_exit_code_4() {
    let tmp = tempfile::tempdir().unwrap();
    let d = small_campaign(tmp.path(), "one-bad-bar");
    // Declare a third bar that never logged anything.
    let mut manifest = std::fs::read_to_string(d.join("campaign.toml")).unwrap();
    manifest.push_str("\n[[bar]]\nid = \"B77\"\nresolution_nm = 5.0\nfixed_length_mm = 230.0\n");
    std::fs::write(d.join("campaign.toml"), manifest).unwrap();
    let out = tmp.path().join("out");
    let (code, _, stderr) = run_cli(&[
        "run",
        "pipelines/nightly.toml",
        "--campaign",
        d.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 4, "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["bars"].as_array().unwrap().len(), 2);
    assert_eq!(summary["failed_bars"][0]["bar"], "B77");
}

// ---------------------------------------------------------------- issue 14: never lose a byte

/// The small campaign's tables, changed by `edit`, written to `root/name` (one file a table).
fn edited_campaign(root: &Path, name: &str, edit: impl FnOnce(&mut CampaignTables)) -> PathBuf {
    let mut sim = dbbcal::simulate::generate(&small_config(name, 3)).unwrap();
    edit(&mut sim.tables);
    let dir = root.join(name);
    write_campaign(&dir, &sim.manifest, &sim.tables, &WriteOptions::default()).unwrap();
    dir
}

/// A campaign directory with `campaign.toml` rewritten by `edit`.
fn with_manifest(root: &Path, name: &str, edit: impl Fn(&str) -> String) -> PathBuf {
    let d = small_campaign(root, name);
    let text = std::fs::read_to_string(d.join("campaign.toml")).unwrap();
    std::fs::write(d.join("campaign.toml"), edit(&text)).unwrap();
    d
}

/// `text` without its `[[header]]` sections.
fn without_sections(text: &str, header: &str) -> String {
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        if line.starts_with('[') {
            skipping = line.trim() == format!("[[{header}]]");
        }
        if !skipping {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// Runs `identify` (rows binned while they stream with `bin_s` > 0, else every reading) on a
/// campaign that must be processed; returns summary.json. The exit code agrees with
/// `failed_bars`.
fn identify(dir: &Path, bin_s: &str) -> serde_json::Value {
    let out = dir.with_extension(format!("out-{bin_s}"));
    let (code, _, stderr) = run_cli(&[
        "identify",
        "--bin-s",
        bin_s,
        "--campaign",
        dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let failed = summary["failed_bars"].as_array().unwrap().len();
    assert_eq!(code == 0, failed == 0, "exit {code}, {stderr}");
    // What was dropped or flagged is said in words too, per bar, in report.md and on the page.
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    let page = std::fs::read_to_string(out.join("index.html")).unwrap();
    for bar in summary["bars"].as_array().unwrap() {
        let q = &summary["quality"]["bars"][bar["bar"].as_str().unwrap()];
        let dropped = q["dropped_rows"].as_u64().unwrap_or(0);
        let flagged = q["flags"].as_array().is_some_and(|f| !f.is_empty());
        if dropped > 0 || flagged {
            let line = format!("data: {dropped} of {} readings dropped", q["rows"]);
            assert!(report.contains(&line), "{line:?} not in report.md");
            assert!(page.contains(&line), "{line:?} not on the page");
        }
    }
    summary
}

fn time_column(raw: Vec<Option<i64>>, unit: TimeUnit, zone: Option<&str>) -> Column {
    Column::Time {
        raw,
        unit,
        zone: zone.map(str::to_string),
    }
}

const T0_NS: i64 = 1_793_491_200_000_000_000 + 3_600_000_000_000;

fn encoder_rows(time: Column, counts: Column) -> Table {
    Table::new()
        .with("time", time)
        .with("bar", Column::Str(vec!["B01".into(), "B01".into()]))
        .with("counts", counts)
}

#[test]
fn unusable_rows_are_dropped_and_named_and_unreadable_files_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let ns = |t: Vec<Option<i64>>| time_column(t, TimeUnit::Ns, None);
    let cases: Vec<(&str, Table, Vec<&str>)> = vec![
        (
            "nat",
            encoder_rows(
                ns(vec![Some(T0_NS), Some(i64::MIN)]),
                Column::I64(vec![1, 2]),
            ),
            vec![
                "nat.parquet",
                "`time`",
                "rows 1 .. 1",
                "-9223372036854775808",
            ],
        ),
        (
            "max-time",
            encoder_rows(
                ns(vec![Some(i64::MAX), Some(T0_NS)]),
                Column::I64(vec![1, 2]),
            ),
            vec!["max-time.parquet", "rows 0 .. 0", "9223372036854775807"],
        ),
        (
            "clock-reset",
            encoder_rows(
                ns(vec![Some(5_000_000_000), Some(6_000_000_000)]),
                Column::I64(vec![1, 2]),
            ),
            vec!["clock-reset.parquet", "2 rows", "rows 0 .. 1"],
        ),
        (
            "ms-overflow",
            encoder_rows(
                time_column(
                    vec![Some(T0_NS / 1_000_000), Some(i64::MAX / 1000)],
                    TimeUnit::Ms,
                    None,
                ),
                Column::I64(vec![1, 2]),
            ),
            vec!["ms-overflow.parquet", "rows 1 .. 1", "ms"],
        ),
        (
            "us-far-future",
            encoder_rows(
                // Year 2300 in µs: its ns value overflows i64.
                time_column(
                    vec![Some(10_413_792_000_000_000), Some(T0_NS / 1000)],
                    TimeUnit::Us,
                    None,
                ),
                Column::I64(vec![1, 2]),
            ),
            vec!["us-far-future.parquet", "rows 0 .. 0", "us"],
        ),
        (
            "fraction",
            encoder_rows(
                ns(vec![Some(T0_NS), Some(T0_NS + 60_000_000_000)]),
                Column::F64(vec![3.0, 3.25]),
            ),
            vec![
                "fraction.parquet",
                "`counts`",
                "rows 1 .. 1",
                "not whole",
                "3.25",
            ],
        ),
        (
            "huge-counts",
            encoder_rows(
                ns(vec![Some(T0_NS), Some(T0_NS + 60_000_000_000)]),
                Column::F64(vec![1e300, 1.0]),
            ),
            vec!["huge-counts.parquet", "`counts`", "rows 0 .. 0", "2^48"],
        ),
    ];
    for (name, table, needles) in cases {
        let d = small_campaign(root, name);
        write_table(&d.join(format!("encoders/{name}.parquet")), &table).unwrap();
        check_dropped(&d, &needles);
    }

    // A temperature time out of range is named the same way.
    let d = small_campaign(root, "temperature-nat");
    write_table(
        &d.join("temperatures/nat.parquet"),
        &Table::new()
            .with("time", ns(vec![Some(T0_NS), Some(i64::MIN)]))
            .with("sensor", Column::Str(vec!["T1".into(), "T1".into()]))
            .with("celsius", Column::F64(vec![20.0, 20.1])),
    )
    .unwrap();
    check_dropped(&d, &["nat.parquet", "`time`", "rows 1 .. 1"]);

    // Null times, undeclared sensors and event bars: dropped and named.
    let d = small_campaign(root, "null-times");
    write_table(
        &d.join("encoders/nulltime.parquet"),
        &encoder_rows(ns(vec![Some(T0_NS), None]), Column::I64(vec![1, 2])),
    )
    .unwrap();
    check_dropped(&d, &["nulltime.parquet", "`time`", "rows 1 .. 1", "null"]);
    let d = small_campaign(root, "unknown-sensor");
    write_table(
        &d.join("temperatures/t9.parquet"),
        &Table::new()
            .with("time", ns(vec![Some(T0_NS)]))
            .with("sensor", Column::Str(vec!["T9".into()]))
            .with("celsius", Column::F64(vec![20.0])),
    )
    .unwrap();
    check_dropped(&d, &["t9.parquet", "sensor \"T9\"", "1 rows"]);
    let d = small_campaign(root, "unknown-event-bar");
    std::fs::create_dir_all(d.join("events")).unwrap();
    write_table(
        &d.join("events/ghost.parquet"),
        &Table::new()
            .with("time", ns(vec![Some(T0_NS)]))
            .with("bar", Column::Str(vec!["B42".into()]))
            .with("kind", Column::Str(vec!["door".into()]))
            .with("value", Column::OptF64(vec![None])),
    )
    .unwrap();
    check_dropped(&d, &["ghost.parquet", "bar \"B42\""]);

    // Zero bytes, a truncated file, corrupt data pages: one line naming the file.
    let d = small_campaign(root, "zero-bytes");
    std::fs::write(d.join("encoders/empty.parquet"), b"").unwrap();
    check(&d, &["empty.parquet"]);
    let d = small_campaign(root, "truncated");
    let whole = std::fs::read(d.join("encoders/encoders.parquet")).unwrap();
    std::fs::write(
        d.join("encoders/encoders.parquet"),
        &whole[..whole.len() / 2],
    )
    .unwrap();
    check(&d, &["encoders.parquet"]);
    let d = small_campaign(root, "corrupt-pages");
    let mut bytes = whole.clone();
    for b in &mut bytes[64..whole.len() / 2] {
        *b ^= 0x5a;
    }
    std::fs::write(d.join("encoders/encoders.parquet"), &bytes).unwrap();
    check(&d, &["encoders.parquet"]);
}

#[test]
fn campaigns_without_bars_mounts_or_air_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let d = with_manifest(root, "no-mounts", |t| without_sections(t, "mount"));
    check_refused(&d, &["identify"], 3, &["campaign.toml", "no mount"]);
    let d = with_manifest(root, "no-bars", |t| {
        without_sections(&without_sections(t, "mount"), "bar")
    });
    check_refused(&d, &["identify"], 3, &["campaign.toml", "no bar"]);
    let d = with_manifest(root, "no-air", |t| {
        t.replace("kind = \"air\"", "kind = \"other\"")
            .lines()
            .filter(|l| !l.starts_with("sensor = "))
            .collect::<Vec<_>>()
            .join("\n")
    });
    check_refused(&d, &["identify"], 3, &["campaign.toml", "no air sensor"]);
}

fn bar_quality<'a>(summary: &'a serde_json::Value, bar: &str) -> &'a serde_json::Value {
    &summary["quality"]["bars"][bar]
}

fn flags<'a>(q: &'a serde_json::Value, kind: &str) -> Vec<&'a serde_json::Value> {
    q["flags"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["kind"] == kind)
        .collect()
}

#[test]
fn missing_values_are_dropped_counted_and_flagged() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let d = edited_campaign(root, "nan-inf-null", |t| {
        let t1 = t.temperatures.get_mut("T1").unwrap();
        t1.celsius[10] = f64::NAN;
        t1.celsius[11] = f64::INFINITY;
        t1.celsius[12] = f64::NEG_INFINITY;
        t.events.push(dbbcal::series::Event {
            time_ns: T0_NS,
            bar: None,
            kind: dbbcal::series::EventKind::parse("door"),
            value: Some(f64::NAN),
        });
    });
    // Null temperatures and counts, and whole float counts, in extra files.
    write_table(
        &d.join("temperatures/nulls.parquet"),
        &Table::new()
            .with("time", Column::TimeNs(vec![T0_NS + 1, T0_NS + 2]))
            .with("sensor", Column::Str(vec!["T2".into(), "T2".into()]))
            .with("celsius", Column::OptF64(vec![None, Some(f64::NAN)])),
    )
    .unwrap();
    write_table(
        &d.join("encoders/nulls.parquet"),
        &encoder_rows(
            Column::TimeNs(vec![T0_NS + 1, T0_NS + 2]),
            Column::OptI64(vec![None, None]),
        ),
    )
    .unwrap();
    write_table(
        &d.join("encoders/floats.parquet"),
        &Table::new()
            .with(
                "time",
                Column::TimeNs(vec![T0_NS + 5, T0_NS + 6, T0_NS + 7]),
            )
            .with("bar", Column::Str(vec!["B02".into(); 3]))
            .with(
                "counts",
                Column::OptF64(vec![Some(f64::NAN), Some(f64::INFINITY), None]),
            ),
    )
    .unwrap();
    for bin_s in ["0", "60"] {
        let s = identify(&d, bin_s);
        assert!(s["failed_bars"].as_array().unwrap().is_empty(), "{s}");
        let t1 = &s["quality"]["sensors"]["T1"];
        assert_eq!(
            (t1["nan"].as_u64(), t1["inf"].as_u64()),
            (Some(1), Some(2)),
            "{t1}"
        );
        let t2 = &s["quality"]["sensors"]["T2"];
        assert_eq!(
            (t2["null"].as_u64(), t2["nan"].as_u64()),
            (Some(1), Some(1)),
            "{t2}"
        );
        assert_eq!(t2["dropped_rows"], 2);
        let b1 = bar_quality(&s, "B01");
        assert_eq!(
            (b1["null"].as_u64(), b1["dropped_rows"].as_u64()),
            (Some(2), Some(2))
        );
        let missing = flags(b1, "missing_values");
        assert_eq!(missing[0]["from"], "2026-11-01T01:00:00.000000001Z");
        let b2 = bar_quality(&s, "B02");
        assert_eq!(
            (b2["null"].as_u64(), b2["nan"].as_u64(), b2["inf"].as_u64()),
            (Some(1), Some(1), Some(1))
        );
        assert_eq!(
            s["quality"]["events"]["nan"], 1,
            "{}",
            s["quality"]["events"]
        );
        assert_eq!(s["bars"].as_array().unwrap().len(), 3);
    }
}

#[test]
fn duplicates_and_mixed_zones_are_counted_once_and_flagged() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let d = edited_campaign(root, "duplicates", |_| {});
    std::fs::copy(
        d.join("encoders/encoders.parquet"),
        d.join("encoders/copy.parquet"),
    )
    .unwrap();
    // Overlapping identical rows from another file, in zoned ms (the others are naive ns).
    let logs = dbbcal::io::read_campaign(&d).unwrap();
    let b1 = &logs.bars["B01"];
    let n = 30;
    write_table(
        &d.join("encoders/overlap.parquet"),
        &Table::new()
            .with(
                "time",
                time_column(
                    b1.time_ns[100..100 + n]
                        .iter()
                        .rev()
                        .map(|&t| Some(t / 1_000_000))
                        .collect(),
                    TimeUnit::Ms,
                    Some("UTC"),
                ),
            )
            .with("bar", Column::Str(vec!["B01".into(); n]))
            .with(
                "counts",
                Column::I64(b1.counts[100..100 + n].iter().rev().copied().collect()),
            ),
    )
    .unwrap();
    let s = identify(&d, "0");
    let files: Vec<&str> = s["quality"]["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["kind"].as_str().unwrap())
        .collect();
    assert!(
        files.contains(&"duplicate_file") && files.contains(&"mixed_time_zones"),
        "{files:?}"
    );
    let inputs = s["inputs"].as_array().unwrap();
    let copy = inputs
        .iter()
        .find(|f| f["path"] == "encoders/encoders.parquet")
        .unwrap();
    // Files are taken in path order: the copy is read, the original marked as its duplicate.
    assert_eq!(copy["duplicate_of"], "encoders/copy.parquet");
    let q = bar_quality(&s, "B01");
    assert_eq!(q["duplicate_rows"], n as u64, "{q}");
    let dup = flags(q, "duplicate_rows");
    assert_eq!(dup.len(), 1);
    let n_samples_b1 = s["bars"][0]["n_samples"].as_u64().unwrap();
    let clean = identify(&edited_campaign(root, "clean", |_| {}), "0");
    assert_eq!(
        clean["bars"][0]["n_samples"].as_u64().unwrap(),
        n_samples_b1
    );
    assert_eq!(bar_quality(&clean, "B01")["dropped_rows"], 0);
}

#[test]
fn encoder_faults_are_flagged_and_a_dead_bar_fails_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    // Out of order (reversed) rows and a spike in B01, a 32-bit wrap in B02, B03 frozen.
    let mut spike_at = 0;
    let mut wrap_at = 0;
    let d = edited_campaign(root, "faults", |t| {
        let b1 = t.encoders.get_mut("B01").unwrap();
        spike_at = b1.time_ns[200];
        b1.counts[200] += 4000; // 20 µm for one reading
        b1.time_ns.reverse();
        b1.counts.reverse();
        let b2 = t.encoders.get_mut("B02").unwrap();
        let late = b2.time_ns.len() * 3 / 4;
        wrap_at = b2.time_ns[late];
        for c in &mut b2.counts[late..] {
            *c -= 1 << 32;
        }
        let b3 = t.encoders.get_mut("B03").unwrap();
        let frozen = b3.counts[0];
        b3.counts.iter_mut().for_each(|c| *c = frozen);
    });
    for bin_s in ["0", "60"] {
        let s = identify(&d, bin_s);
        let q = bar_quality(&s, "B01");
        let jumps = flags(q, "jump");
        assert!(!jumps.is_empty(), "{q}");
        let spike = dbbcal::series::quality::format_ns(spike_at);
        let at_spike = |f: &&serde_json::Value| {
            f["from"].as_str().unwrap() <= spike.as_str()
                && f["to"].as_str().unwrap() >= spike.as_str()
        };
        assert!(jumps.iter().any(at_spike), "{spike}: {q}");
        let q2 = bar_quality(&s, "B02");
        let wraps = flags(q2, "counter_wrap");
        assert_eq!(wraps.len(), 1, "{q2}");
        let size = wraps[0]["size_counts"].as_f64().unwrap();
        assert!((size + 4_294_967_296.0).abs() < 1e3, "{size}");
        let wrap = dbbcal::series::quality::format_ns(wrap_at);
        assert!(wraps[0]["from"].as_str().unwrap() <= wrap.as_str());
        assert!(wraps[0]["to"].as_str().unwrap() >= wrap.as_str());
        assert!(q2["fault_rows"].as_u64().unwrap() > 0);
        let failed = s["failed_bars"].as_array().unwrap();
        assert_eq!(failed.len(), 2, "{s}");
        assert_eq!(failed[0]["bar"], "B02");
        assert!(failed[0]["error"]
            .as_str()
            .unwrap()
            .contains("counter wrap"));
        assert_eq!(failed[1]["bar"], "B03");
        assert!(
            failed[1]["error"].as_str().unwrap().contains("dead"),
            "{}",
            failed[1]
        );
        assert!(!flags(bar_quality(&s, "B03"), "stuck").is_empty());
        assert_eq!(s["bars"][0]["bar"], "B01");
        assert_eq!(s["bars"].as_array().unwrap().len(), 1);
    }
}

/// Each bar's fitted parameters (values) and RMS: what must not change when rows are
/// duplicated across files.
fn fit_results(s: &serde_json::Value) -> Vec<(String, String, String)> {
    s["bars"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            (
                b["bar"].as_str().unwrap().to_string(),
                b["params"].to_string(),
                b["rms_um"].to_string(),
            )
        })
        .collect()
}

/// Rows `range` of `bar`'s full-rate log as an encoder file in zoned ms, in reverse order (other
/// bytes than the campaign's own naive-ns file), counts changed by `shift`.
fn rows_of_bar(
    d: &Path,
    bar: &str,
    range: std::ops::Range<usize>,
    shift: i64,
) -> (Table, i64, i64) {
    rows_of_bar_as(d, bar, range, shift, true)
}

/// [`rows_of_bar`]; `zoned_ms: false`: naive ns, the campaign's own schema (its files then
/// share one scan), still reversed.
fn rows_of_bar_as(
    d: &Path,
    bar: &str,
    range: std::ops::Range<usize>,
    shift: i64,
    zoned_ms: bool,
) -> (Table, i64, i64) {
    let logs = dbbcal::io::read_campaign(d).unwrap();
    let log = &logs.bars[bar];
    let n = range.len();
    let times = log.time_ns[range.clone()].iter().rev();
    let time = if zoned_ms {
        time_column(
            times.map(|&t| Some(t / 1_000_000)).collect(),
            TimeUnit::Ms,
            Some("UTC"),
        )
    } else {
        Column::TimeNs(times.copied().collect())
    };
    let table = Table::new()
        .with("time", time)
        .with("bar", Column::Str(vec![bar.into(); n]))
        .with(
            "counts",
            Column::I64(
                log.counts[range.clone()]
                    .iter()
                    .rev()
                    .map(|c| c + shift)
                    .collect(),
            ),
        );
    (table, log.time_ns[range.start], log.time_ns[range.end - 1])
}

#[test]
fn rows_two_files_both_hold_are_flagged_and_counted_once_on_both_paths() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let clean = edited_campaign(root, "clean", |_| {});
    // A re-export overlapping the day file by 5 h for B01 (300 rows at 60 s) and 50 rows of
    // B02: other bytes (reversed; zoned ms, or naive ns as the day file: one shared scan),
    // the same readings.
    for (name, zoned_ms) in [("overlap-ms", true), ("overlap-ns", false)] {
        let d = edited_campaign(root, name, |_| {});
        let (b1, from, to) = rows_of_bar_as(&d, "B01", 100..400, 0, zoned_ms);
        write_table(&d.join("encoders/reexport-b01.parquet"), &b1).unwrap();
        let (b2, _, _) = rows_of_bar_as(&d, "B02", 0..50, 0, zoned_ms);
        write_table(&d.join("encoders/reexport-b02.parquet"), &b2).unwrap();
        overlap_counted_once(&d, &clean, from, to);
    }
}

fn overlap_counted_once(d: &Path, clean: &Path, from: i64, to: i64) {
    for bin_s in ["60", "0"] {
        let s = identify(d, bin_s);
        let reference = identify(clean, bin_s);
        assert_eq!(fit_results(&s), fit_results(&reference), "bin_s {bin_s}");
        let q = bar_quality(&s, "B01");
        assert_eq!(q["duplicate_rows"], 300, "{q}");
        let overlap = flags(q, "overlapping_files");
        assert_eq!(overlap.len(), 1, "{q}");
        assert_eq!(overlap[0]["rows"], 300);
        assert_eq!(overlap[0]["from"], dbbcal::series::quality::format_ns(from));
        assert_eq!(overlap[0]["to"], dbbcal::series::quality::format_ns(to));
        let note = overlap[0]["note"].as_str().unwrap();
        assert!(
            note.contains("reexport-b01.parquet") && note.contains("encoders.parquet"),
            "{note}"
        );
        assert_eq!(bar_quality(&s, "B02")["duplicate_rows"], 50);
        assert_eq!(bar_quality(&s, "B03")["duplicate_rows"], 0);
        assert!(flags(q, "conflicting_readings").is_empty(), "{q}");
    }
}

#[test]
fn conflicting_readings_are_flagged_and_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let d = edited_campaign(tmp.path(), "conflicts", |_| {});
    // Ten readings of B01 again at the same times with other counts (a second logger, or a
    // clock set back over them).
    let (b1, from, to) = rows_of_bar(&d, "B01", 200..210, 40);
    write_table(&d.join("encoders/second-logger.parquet"), &b1).unwrap();
    for bin_s in ["60", "0"] {
        let s = identify(&d, bin_s);
        let q = bar_quality(&s, "B01");
        let conflicts = flags(q, "conflicting_readings");
        assert_eq!(conflicts.len(), 1, "bin_s {bin_s}: {q}");
        assert_eq!(conflicts[0]["rows"], 20);
        assert_eq!(
            conflicts[0]["from"],
            dbbcal::series::quality::format_ns(from)
        );
        assert_eq!(conflicts[0]["to"], dbbcal::series::quality::format_ns(to));
        assert_eq!(q["duplicate_rows"], 0, "{q}");
        assert_eq!(q["dropped_rows"], 0, "{q}");
        assert!(flags(bar_quality(&s, "B02"), "conflicting_readings").is_empty());
    }
}

#[test]
fn a_two_hour_gap_inside_a_mount_is_flagged_on_both_paths() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let probe = edited_campaign(root, "probe", |_| {});
    let campaign = dbbcal::io::read_manifest(&probe).unwrap();
    let mount = campaign
        .mounts
        .iter()
        .filter(|m| m.bar == "B01")
        .max_by_key(|m| m.to_ns - m.from_ns)
        .unwrap();
    assert!(mount.to_ns - mount.from_ns > 4 * 3_600_000_000_000);
    let mid = mount.from_ns + (mount.to_ns - mount.from_ns) / 2;
    let (cut_from, cut_to) = (mid - 3_600_000_000_000, mid + 3_600_000_000_000);
    let mut edges = (0, 0);
    let d = edited_campaign(root, "gap", |t| {
        let b1 = t.encoders.get_mut("B01").unwrap();
        let keep: Vec<bool> = b1
            .time_ns
            .iter()
            .map(|&t| t < cut_from || t >= cut_to)
            .collect();
        let before = b1.time_ns.iter().filter(|&&t| t < cut_from).max().unwrap();
        let after = b1.time_ns.iter().filter(|&&t| t >= cut_to).min().unwrap();
        edges = (*before, *after);
        let mut k = keep.iter();
        b1.time_ns.retain(|_| *k.next().unwrap());
        let mut k = keep.iter();
        b1.counts.retain(|_| *k.next().unwrap());
    });
    for bin_s in ["60", "0"] {
        let s = identify(&d, bin_s);
        let q = bar_quality(&s, "B01");
        let gaps = flags(q, "gap");
        assert_eq!(gaps.len(), 1, "bin_s {bin_s}: {q}");
        assert_eq!(gaps[0]["from"], dbbcal::series::quality::format_ns(edges.0));
        assert_eq!(gaps[0]["to"], dbbcal::series::quality::format_ns(edges.1));
        assert!(flags(bar_quality(&s, "B02"), "gap").is_empty(), "{s}");
        // Flags only: the bar is fitted.
        assert_eq!(s["bars"][0]["bar"], "B01");
    }
}

#[test]
fn repeated_rows_inside_one_file_are_counted_once_and_conflicts_flagged_on_both_paths() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let clean = edited_campaign(root, "clean-one-file", |_| {});
    let mut times = (0, 0, 0, 0);
    // In the campaign's own encoder file: 30 rows of B01 written twice (the copies at the end,
    // out of time order, one of them three times), and 10 more of its times again with other
    // counts (a logger clock set back).
    let d = edited_campaign(root, "repeats-one-file", |t| {
        let b1 = t.encoders.get_mut("B01").unwrap();
        times = (
            b1.time_ns[100],
            b1.time_ns[129],
            b1.time_ns[200],
            b1.time_ns[209],
        );
        for i in (100..130).rev().chain([115]) {
            let (t, c) = (b1.time_ns[i], b1.counts[i]);
            b1.time_ns.push(t);
            b1.counts.push(c);
        }
        for i in 200..210 {
            let (t, c) = (b1.time_ns[i], b1.counts[i] + 40);
            b1.time_ns.push(t);
            b1.counts.push(c);
        }
    });
    let encoder_files = std::fs::read_dir(d.join("encoders")).unwrap().count();
    assert_eq!(encoder_files, 1, "the repeats are inside one file");
    let (dup_from, dup_to, conflict_from, conflict_to) = times;
    for bin_s in ["60", "0"] {
        let s = identify(&d, bin_s);
        let q = bar_quality(&s, "B01");
        assert_eq!(q["duplicate_rows"], 31, "bin_s {bin_s}: {q}");
        let dups = flags(q, "duplicate_rows");
        assert_eq!(dups.len(), 1, "bin_s {bin_s}: {q}");
        assert_eq!(dups[0]["rows"], 31);
        assert_eq!(
            dups[0]["from"],
            dbbcal::series::quality::format_ns(dup_from)
        );
        assert_eq!(dups[0]["to"], dbbcal::series::quality::format_ns(dup_to));
        let conflicts = flags(q, "conflicting_readings");
        assert_eq!(conflicts.len(), 1, "bin_s {bin_s}: {q}");
        assert_eq!(conflicts[0]["rows"], 20);
        assert_eq!(
            conflicts[0]["from"],
            dbbcal::series::quality::format_ns(conflict_from)
        );
        assert_eq!(
            conflicts[0]["to"],
            dbbcal::series::quality::format_ns(conflict_to)
        );
        assert!(flags(q, "overlapping_files").is_empty(), "{q}");
        for bar in ["B02", "B03"] {
            assert_eq!(bar_quality(&s, bar)["duplicate_rows"], 0, "{bar}");
        }
        // Without the conflicting readings, the fit is that of the clean campaign: the copies
        // weigh nothing (taken out of the bins exactly).
        if bin_s == "60" {
            let only_dups = edited_campaign(root, "dups-one-file", |t| {
                let b1 = t.encoders.get_mut("B01").unwrap();
                for i in (100..130).rev().chain([115]) {
                    let (t, c) = (b1.time_ns[i], b1.counts[i]);
                    b1.time_ns.push(t);
                    b1.counts.push(c);
                }
            });
            assert_eq!(
                fit_results(&identify(&only_dups, bin_s)),
                fit_results(&identify(&clean, bin_s)),
                "bin_s {bin_s}"
            );
        }
    }
}

/// A page that made polars abort the process (an allocation of ~2.3e18 bytes while decoding its
/// validity; `tests/data/page-validity-abort.parquet` is the fuzz's seed-14 case, see
/// `crates/io/src/fuzz_tests.rs`). The parquet crate refuses it with an error: `dbbcal` names
/// the file in one line, exit 3, the earlier output unchanged and nothing left beside it. Alone,
/// and beside a valid file of the same schema (only the corrupt one is named).
#[test]
fn a_page_that_aborted_the_old_parquet_decoder_is_named_in_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("abort");
    for sub in ["encoders", "temperatures"] {
        std::fs::create_dir_all(d.join(sub)).unwrap();
    }
    std::fs::copy("data/sample/campaign.toml", d.join("campaign.toml")).unwrap();
    std::fs::copy(
        "data/sample/temperatures/temperatures.parquet",
        d.join("temperatures/temperatures.parquet"),
    )
    .unwrap();
    std::fs::copy(
        "tests/data/page-validity-abort.parquet",
        d.join("encoders/corrupt.parquet"),
    )
    .unwrap();
    let corrupt = d.join("encoders/corrupt.parquet");
    let named = format!("{}: not a valid parquet file", corrupt.display());
    let needles = [named.as_str()];
    check_refused(&d, &["run", "pipelines/nightly.toml"], 3, &needles);
    check_refused(&d, &["identify", "--bin-s", "0", "-q"], 3, &needles);
    check_refused(
        &d,
        &["ingest", "--bin-s", "60", "--color", "never"],
        3,
        &needles,
    );
    // `a.parquet` is read first, beside the corrupt file.
    std::fs::copy(
        "data/sample/encoders/encoders.parquet",
        d.join("encoders/a.parquet"),
    )
    .unwrap();
    check_refused(&d, &["identify", "--bin-s", "60"], 3, &needles);
}

// ---------------------------------------------------------------- issue 27: round 2

/// W1: an entry named `*.parquet` that is not a regular file (a link to an unmounted share, a
/// FIFO, a folder) is refused by name; it was skipped, and a quarter of the rows never read.
#[test]
fn a_parquet_entry_that_is_not_a_regular_file_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let d = small_campaign(root, "dangling-link");
    std::os::unix::fs::symlink(
        "/mnt/unmounted-share/day2.parquet",
        d.join("encoders/day2.parquet"),
    )
    .unwrap();
    check(
        &d,
        &["day2.parquet", "symbolic link", "/mnt/unmounted-share"],
    );
    let d = small_campaign(root, "fifo");
    let status = std::process::Command::new("mkfifo")
        .arg(d.join("temperatures/day3.parquet"))
        .status()
        .unwrap();
    assert!(status.success());
    check(&d, &["day3.parquet", "not a regular file"]);
    let d = small_campaign(root, "folder");
    std::fs::create_dir(d.join("encoders/day4.parquet")).unwrap();
    check(&d, &["day4.parquet", "a folder"]);
}

/// W2: temperatures no room has (below absolute zero, a logger's −999, 1e300) and a spike no air
/// makes are dropped, counted and flagged `implausible_temperature`, and the fits are those of
/// the campaign without them (a −300 °C reading moved every bar's alpha and beta).
#[test]
fn impossible_temperatures_are_dropped_counted_and_flagged() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let clean = edited_campaign(root, "clean-air", |_| {});
    for (name, values) in [
        ("minus-300", vec![(10, -300.0)]),
        ("error-code", vec![(10, -999.0), (400, -999.0)]),
        ("huge", vec![(20, 1e300)]),
        ("spike", vec![(30, 60.0)]),
    ] {
        let edits = values.clone();
        let d = edited_campaign(root, name, move |t| {
            let t1 = t.temperatures.get_mut("T1").unwrap();
            for &(i, v) in &edits {
                t1.celsius[i] = v;
            }
        });
        // The same readings left out: what the fits must equal.
        let edits = values.clone();
        let without = edited_campaign(root, &format!("{name}-without"), move |t| {
            let t1 = t.temperatures.get_mut("T1").unwrap();
            let mut idx: Vec<usize> = edits.iter().map(|e| e.0).collect();
            idx.sort_unstable();
            for &i in idx.iter().rev() {
                t1.time_ns.remove(i);
                t1.celsius.remove(i);
            }
        });
        for bin_s in ["0", "60"] {
            let s = identify(&d, bin_s);
            let q = &s["quality"]["sensors"]["T1"];
            let f = flags(q, "implausible_temperature");
            assert_eq!(f.len(), 1, "{name}: {q}");
            assert_eq!(f[0]["rows"], values.len() as u64, "{name}: {q}");
            assert_eq!(q["dropped_rows"], values.len() as u64, "{name}: {q}");
            assert_eq!(
                fit_results(&s),
                fit_results(&identify(&without, bin_s)),
                "{name}, bins {bin_s}: the fits differ from the campaign without the readings"
            );
            assert!(s["failed_bars"].as_array().unwrap().is_empty(), "{name}");
        }
    }
    // The clean campaign flags nothing.
    let s = identify(&clean, "0");
    assert!(flags(&s["quality"]["sensors"]["T1"], "implausible_temperature").is_empty());
}

/// W3: a byte-identical copy of a day file is read once, so it changes nothing: not the
/// automatic bins (it switched them from every reading to 60 s), not the fits.
#[test]
fn a_byte_identical_copy_of_a_file_changes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let clean = tmp.path().join("sample");
    crate::corpus::copy_dir(Path::new("data/sample"), &clean);
    let copied = tmp.path().join("sample-copied");
    crate::corpus::copy_dir(Path::new("data/sample"), &copied);
    std::fs::copy(
        copied.join("encoders/encoders.parquet"),
        copied.join("encoders/encoders-copy.parquet"),
    )
    .unwrap();
    let summary = |d: &Path| {
        let out = d.with_extension("out");
        let (code, _, stderr) = run_cli(&[
            "identify",
            "--campaign",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{stderr}");
        let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()
    };
    let (a, b) = (summary(&clean), summary(&copied));
    assert_eq!(a["model"]["bin_s"], b["model"]["bin_s"]);
    assert_eq!(fit_results(&a), fit_results(&b));
}

/// Peak resident memory (bytes) of `dbbcal args` and the process it supervises (`wait4`'s
/// usage of the child covers the grandchildren it waited for).
fn peak_rss_bytes(args: &[&str]) -> u64 {
    // Waited for by `wait4` below, which also gives its usage.
    #[allow(clippy::zombie_processes)]
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(args)
        .current_dir(crate::support::root())
        .env("CI", "1")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut status = 0;
    // SAFETY: zeroed plain data, filled by the kernel.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: waiting for our own child, with valid pointers.
    let pid = unsafe { libc::wait4(child.id() as i32, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as i32);
    assert!(
        libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0,
        "{args:?}: status {status}"
    );
    usage.ru_maxrss as u64 * 1024
}

/// H2: memory follows the rows, not the time span: the sample with one air reading in 2199 and
/// one in 1981 (both inside the accepted bounds) runs the nightly within 1.2x the sample's own
/// peak (it took 4.46 GB against 0.18 GB: a 60-s air history over 220 years).
#[test]
fn air_readings_decades_apart_cost_no_memory_by_time_span() {
    let tmp = tempfile::tempdir().unwrap();
    let clean = tmp.path().join("sample");
    crate::corpus::copy_dir(Path::new("data/sample"), &clean);
    let far = tmp.path().join("far");
    crate::corpus::copy_dir(Path::new("data/sample"), &far);
    let ns = |rfc: &str| {
        chrono::DateTime::parse_from_rfc3339(rfc)
            .unwrap()
            .timestamp_nanos_opt()
            .unwrap()
    };
    write_table(
        &far.join("temperatures/far.parquet"),
        &Table::new()
            .with(
                "time",
                Column::TimeNs(vec![ns("1981-01-01T00:00:00Z"), ns("2199-12-31T00:00:00Z")]),
            )
            .with("sensor", Column::Str(vec!["T1".into(), "T1".into()]))
            .with("celsius", Column::F64(vec![20.0, 20.0])),
    )
    .unwrap();
    let peak = |d: &Path| {
        let out = d.with_extension("out");
        peak_rss_bytes(&[
            "run",
            "pipelines/nightly.toml",
            "--campaign",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let (base, with_far) = (peak(&clean), peak(&far));
    assert!(
        (with_far as f64) <= 1.2 * base as f64,
        "peak {with_far} bytes against the sample's {base}"
    );
}
