//! The `roll` machine kind end to end (issue 31): `dbbcal simulate` with `pipelines/sim-roll.toml`
//! and variants, `dbbcal run pipelines/roll.toml`: εx against the simulator's truth within U,
//! the files and the figure, a probe zero offset named and removed by the end-level datum, bad
//! input answered in one line.

use std::path::{Path, PathBuf};

use crate::support::{run_cli, simulate_ok};
use dbbcal::io::manifest::TomlManifest;

/// `pipelines/sim-roll.toml` with `edits` (whole-line replacements `from` → `to`), simulated
/// into `root/name`.
fn simulate(root: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text =
        std::fs::read_to_string(crate::support::root().join("pipelines/sim-roll.toml")).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    let config = root.join(format!("{name}.toml"));
    std::fs::write(&config, text).unwrap();
    let out = root.join(name);
    simulate_ok(config.to_str().unwrap(), out.to_str().unwrap());
    out
}

/// `dbbcal run pipelines/roll.toml` on `campaign` into `out`: (exit code, stdout+stderr).
pub(super) fn run(campaign: &Path, out: &Path, extra: &[&str]) -> (i32, String) {
    crate::support::run_on("pipelines/roll.toml", campaign, out, extra)
}

pub(super) fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn truth(campaign: &Path) -> Vec<f64> {
    json(&campaign.join("truth.json"))["roll_urad"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

/// |εx − truth| ≤ U (k = 2) at every station, and EAX = −b_to_a εx = +εx here.
fn assert_within_u(record: &serde_json::Value, truth: &[f64]) {
    let stations = record["stations"].as_array().unwrap();
    assert_eq!(stations.len(), truth.len());
    for (s, t) in stations.iter().zip(truth) {
        let (e, u) = (
            s["roll_urad"].as_f64().unwrap(),
            s["u_k2_urad"].as_f64().unwrap(),
        );
        assert!(
            (e - t).abs() <= u,
            "station {}: {e} vs {t} ± {u}",
            s["station"]
        );
        assert_eq!(s["roll_error_urad"].as_f64().unwrap(), e);
    }
}

#[test]
fn simulate_and_run_give_the_true_roll_within_u_with_every_file() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = simulate(tmp.path(), "roll", &[]);
    for file in [
        "campaign.toml",
        "probes/probes.parquet",
        "levels/levels.parquet",
        "truth.json",
        "truth/roll_truth.parquet",
    ] {
        assert!(campaign.join(file).is_file(), "{file} missing");
    }
    let out = tmp.path().join("out");
    let (code, said) = run(&campaign, &out, &[]);
    assert_eq!(code, 0, "{said}");
    for file in [
        "roll.json",
        "roll_stations.parquet",
        "roll_dwells.parquet",
        "figures/roll.png",
        "report.md",
        "index.html",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let record = json(&out.join("roll.json"));
    assert_eq!(record["roll_error"], "EAX");
    assert_eq!(record["roll_error_sign"], 1);
    assert_eq!(record["level_datum"], true);
    assert_eq!(record["passes"].as_array().unwrap().len(), 2);
    assert!(record["implausible"].is_null());
    assert_within_u(&record, &truth(&campaign));
    let page = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(page.contains("src=\"figures/roll.png\""));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## εx per station") && md.contains("## The loop"));
    // Same inputs, same bytes.
    let again = tmp.path().join("again");
    assert_eq!(run(&campaign, &again, &[]).0, 0);
    assert_eq!(
        std::fs::read(out.join("roll.json")).unwrap(),
        std::fs::read(again.join("roll.json")).unwrap()
    );
}

#[test]
fn a_5_um_offset_on_c_is_named_as_a_probe_zero_offset_and_a_level_datum_removes_its_ramp() {
    let tmp = tempfile::tempdir().unwrap();
    let offset = (
        "offset_um = [0.0, 0.0, 0.0, 0.0]",
        "offset_um = [0.0, 0.0, 5.0, 0.0]",
    );
    let no_levels = ("write = true", "write = false");
    let one_pass = ("passes = 2", "passes = 1");
    let bare = simulate(tmp.path(), "bare", &[offset, no_levels, one_pass]);
    let out = tmp.path().join("bare-out");
    let (code, said) = run(&bare, &out, &[]);
    assert_eq!(code, 0, "{said}");
    assert!(
        said.contains("implausibly large for a machine table"),
        "{said}"
    );
    assert!(
        said.contains("missing probe_zero_offset (probe zero offset)"),
        "{said}"
    );
    let record = json(&out.join("roll.json"));
    assert_eq!(record["diagnosis"]["missing"], "probe_zero_offset");
    let t = truth(&bare);
    for s in record["stations"].as_array().unwrap() {
        let n = s["station"].as_u64().unwrap() as usize;
        let ramp = s["roll_urad"].as_f64().unwrap() - t[n];
        assert!(
            (ramp - 62.5 * n as f64).abs() <= s["u_k2_urad"].as_f64().unwrap(),
            "n {n}: {ramp}"
        );
    }
    // The slope through the datum also takes the true roll's (±20 µrad: at most
    // 20 Σn/Σn² = 1.6 µrad per station, 0.13 µm of equivalent offset).
    let equivalent = record["implausible"]["equivalent_offset_um"]
        .as_f64()
        .unwrap();
    assert!((equivalent - 5.0).abs() < 0.15, "{equivalent}");

    let datum = simulate(tmp.path(), "datum", &[offset, one_pass]);
    let out = tmp.path().join("datum-out");
    let (code, said) = run(&datum, &out, &[]);
    assert_eq!(code, 0, "{said}");
    let record = json(&out.join("roll.json"));
    assert_eq!(record["level_datum"], true);
    assert!(record["implausible"].is_null());
    let effect = &record["effects"][0];
    assert_eq!(effect["effect"], "probe_zero_offset");
    let (v, u) = (
        effect["value"].as_f64().unwrap(),
        effect["u_k2"].as_f64().unwrap(),
    );
    assert!((v - 5.0).abs() <= u.max(0.02), "{v} ± {u}");
    assert_within_u(&record, &truth(&datum));
}

#[test]
fn a_bad_sample_is_answered_in_one_line_naming_file_column_and_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = simulate(tmp.path(), "roll", &[]);
    let logs = dbbcal::io::read_roll_campaign(&campaign).unwrap();
    let mut samples = logs.samples.clone();
    for s in &mut samples[100..104] {
        s.m[1] = f64::NAN;
    }
    let text = std::fs::read_to_string(campaign.join("campaign.toml")).unwrap();
    let manifest =
        dbbcal_core::roll_campaign::RollManifest::from_toml_str(&text, "campaign.toml").unwrap();
    let tables = dbbcal_core::roll_campaign::RollCampaignTables {
        samples,
        write_station: false,
        write_pass: false,
        levels: logs.levels.clone(),
    };
    dbbcal::io::write_roll_campaign(&campaign, &manifest, &tables, &Default::default()).unwrap();
    let (code, said) = run(&campaign, &tmp.path().join("out"), &[]);
    assert_ne!(code, 0);
    let line = said
        .lines()
        .find(|l| l.contains("m_b"))
        .unwrap_or_else(|| panic!("{said}"));
    assert!(
        line.contains("probes.parquet") && line.contains("rows 100 .. 103"),
        "{line}"
    );
    assert!(!tmp.path().join("out").join("roll.json").exists());
    // A bad simulation key is one line naming it.
    let config = tmp.path().join("bad.toml");
    let text =
        std::fs::read_to_string(crate::support::root().join("pipelines/sim-roll.toml")).unwrap();
    std::fs::write(&config, text.replace("stations = 19", "stations = 1")).unwrap();
    let (code, _, stderr) = run_cli(&[
        "simulate",
        "--config",
        config.to_str().unwrap(),
        "--out",
        tmp.path().join("bad").to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(
        stderr.contains("rig.stations") && stderr.contains("bad.toml"),
        "{stderr}"
    );
    // An unknown effect is refused before any parquet is read, naming the known ones.
    let (code, said) = run(
        &campaign,
        &tmp.path().join("out2"),
        &["--add-effect", "gravity"],
    );
    assert_ne!(code, 0);
    assert!(
        said.contains("--add-effect") && said.contains("probe_zero_offset"),
        "{said}"
    );
}
