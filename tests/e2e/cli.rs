//! The README's first command and the CLI contract: exit codes, outputs, byte-identical JSON,
//! adding an effect with one flag and seeing the error fall.

use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::support::{run_cli, run_pipeline_ok, simulate_campaign};

fn read_json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(
        &std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
    )
    .unwrap()
}

#[test]
fn sample_pipeline_runs_and_is_byte_reproducible() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    for out in [&a, &b] {
        let (code, _, stderr) = run_cli(&[
            "run",
            "pipelines/reference-match.toml",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{stderr}");
    }
    for f in [
        "summary.json",
        "inputs.json",
        "match_study.json",
        "models.parquet",
    ] {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(x == y, "{f} differs between two identical runs");
    }
    let s = read_json(&a.join("summary.json"));
    assert_eq!(s["campaign"], "sim-sample");
    assert_eq!(
        s["model"]["effects"],
        serde_json::json!(["fixed_part", "scale"])
    );
    let bars = s["bars"].as_array().unwrap();
    assert_eq!(bars.len(), 6);
    for bar in bars {
        for p in ["alpha_ppm_per_k", "beta_ppm_per_k", "tau_r_s", "tau_s_s"] {
            assert!(
                bar["params"][p]["value"].as_f64().unwrap() > 0.0,
                "{p} of {}",
                bar["bar"]
            );
            assert!(bar["params"][p]["u"].as_f64().unwrap() > 0.0);
        }
        assert!(bar["rms_um"].as_f64().unwrap() < 0.03);
    }
    let reference = s["reference"]["bar"].as_str().unwrap();
    assert_eq!(s["reference"]["mismatch_um"].as_object().unwrap().len(), 5);
    assert!(!s["reference"]["mismatch_um"]
        .as_object()
        .unwrap()
        .contains_key(reference));
    assert!(s["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .all(|f| f["sha256"].as_str().unwrap().len() == 64));
    for fig in ["fleet.png", "match-study.png", "bar-B01.png"] {
        assert!(a.join("figures").join(fig).is_file(), "{fig}");
    }
    let study = read_json(&a.join("match_study.json"));
    assert_eq!(study["nearest_mean"], reference);
}

#[test]
fn adding_an_effect_on_the_command_line_makes_the_error_fall() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = SimConfig {
        seed: 41,
        campaign_id: "cli-head".into(),
        duration_days: 4.0,
        sample_s: 30.0,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        effects: dbbcal::simulate::EffectsConfig {
            head_heating: dbbcal::simulate::HeadHeating {
                enabled: true,
                ..Default::default()
            },
            ..Default::default()
        },
        ..SimConfig::default()
    };
    let (dir, _) = simulate_campaign(tmp.path(), "c", &cfg);
    let out = tmp.path().join("out");
    let (code, _, stderr) = run_cli(&[
        "identify",
        "--campaign",
        dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--add-effect",
        "head_heating",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let ba = read_json(&out.join("before_after.json"));
    let before = ba["fleet_rms_before_um"].as_f64().unwrap();
    let after = ba["fleet_rms_after_um"].as_f64().unwrap();
    assert!(after < 0.5 * before, "fleet RMS {before} -> {after}");
    assert!(after < 1.2 * cfg.noise_um, "fleet RMS after {after}");
    let s = read_json(&out.join("summary.json"));
    assert_eq!(
        s["model"]["effects"],
        serde_json::json!(["fixed_part", "scale", "head_heating"])
    );
    assert!(
        s["bars"][0]["params"]["head_growth_um"]["value"]
            .as_f64()
            .unwrap()
            > 0.3
    );

    let (code, _, stderr) = run_cli(&[
        "identify",
        "--campaign",
        dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--add-effect",
        "warp_drive",
    ]);
    assert_eq!(code, 3);
    assert!(
        stderr.contains("warp_drive") && stderr.lines().count() == 1,
        "{stderr}"
    );
}

#[test]
fn run_takes_the_stage_overrides_and_writes_csv_when_asked() {
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string("pipelines/nightly.toml").unwrap();
    let pipeline = tmp.path().join("csv.toml");
    std::fs::write(&pipeline, format!("{text}\n[output]\ncsv = true\n")).unwrap();
    let out = tmp.path().join("out");
    let (code, _, stderr) = run_cli(&[
        "run",
        pipeline.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--bin-s",
        "600",
        "--effects",
        "fixed_part,scale",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let csv = std::fs::read_to_string(out.join("models.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "campaign,bar,param,value,u,u_naive,ci95_low,ci95_high,rms_um,n_samples"
    );
    let s = read_json(&out.join("summary.json"));
    let rows = s["bars"].as_array().unwrap().len() * 4;
    assert_eq!(lines.count(), rows, "one CSV row per bar and parameter");
    // An effect naming a channel the campaign lacks is refused before any data is read.
    let (code, _, stderr) = run_cli(&[
        "run",
        "pipelines/nightly.toml",
        "--out",
        out.to_str().unwrap(),
        "--effects",
        "fixed_part,scale,lag:T9",
    ]);
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stderr.contains("--effects") && stderr.contains("T9"),
        "{stderr}"
    );
}

/// The README's `summary.json` row is the contract: every key the sample run writes, at the top
/// level, per bar, per parameter and in `reference`, is named there in backticks.
#[test]
fn the_readme_names_every_field_of_summary_json() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    run_pipeline_ok("pipelines/nightly.toml", &out);
    let s = read_json(&out.join("summary.json"));
    let readme = std::fs::read_to_string(crate::support::root().join("README.md")).unwrap();
    let row = readme
        .lines()
        .find(|l| l.starts_with("| `summary.json` |"))
        .expect("the README's output table has a summary.json row");
    let keys =
        |v: &serde_json::Value| -> Vec<String> { v.as_object().unwrap().keys().cloned().collect() };
    let bar = &s["bars"][0];
    let param = bar["params"].as_object().unwrap().values().next().unwrap();
    let mut missing = Vec::new();
    for (part, names) in [
        ("top level", keys(&s)),
        ("bars[]", keys(bar)),
        ("params", keys(param)),
        ("reference", keys(&s["reference"])),
        ("model", keys(&s["model"])),
        ("pipeline", keys(&s["pipeline"])),
    ] {
        for name in names {
            let mentioned = row.contains(&format!("`{name}`"))
                || row.contains(&format!("{{{name},"))
                || row.contains(&format!(" {name},"))
                || row.contains(&format!(" {name}}}"))
                || row.contains(&format!("({name},"))
                || row.contains(&format!("`{name} "))
                || row.contains(&format!("`{name}."))
                || row.contains(&format!(".{name}`"))
                || row.contains(&format!("({name}, "))
                || row.contains(&format!(" {name})"))
                || row.contains(&format!("{{{name}: "))
                || row.contains(&format!(" {name}: "));
            if !mentioned {
                missing.push(format!("{part}: {name}"));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "not in the README's summary.json row: {missing:?}"
    );
}

/// The exit codes have one definition (`dbbcal::exit`): the README's table is it word for word,
/// and `dbbcal --help` prints it.
#[test]
fn the_readme_and_help_list_the_exit_codes_main_uses() {
    let readme = std::fs::read_to_string(crate::support::root().join("README.md")).unwrap();
    let table = dbbcal::exit::markdown_table();
    assert!(
        readme.contains(&table),
        "the README's exit-code table is not dbbcal::exit::markdown_table():\n{table}"
    );
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        help.contains(dbbcal::exit::help_text().trim_end()),
        "{help}"
    );
}
