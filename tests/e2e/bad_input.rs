//! Bad input through the CLI: one clear line naming what and where, exit code 3, and no output
//! folder (not even a partial one).

use std::path::Path;

use dbbcal::io::{write_table, Column, Table};
use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::corpus::check_refused;
use crate::support::{run_cli, simulate_campaign};

fn small_campaign(root: &Path, name: &str) -> std::path::PathBuf {
    let cfg = SimConfig {
        seed: 5,
        campaign_id: name.into(),
        duration_days: 1.0,
        sample_s: 60.0,
        fleet: Some(FleetConfig {
            n_bars: 2,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    };
    simulate_campaign(root, name, &cfg).0
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
    check(&d, &["ghost.parquet", "B99"]);

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
fn a_bar_without_data_fails_alone_with_exit_code_2() {
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
    assert_eq!(code, 2, "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["bars"].as_array().unwrap().len(), 2);
    assert_eq!(summary["failed_bars"][0]["bar"], "B77");
}
