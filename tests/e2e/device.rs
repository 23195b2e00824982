//! The six-bar measuring device end to end (issue 29, `docs/spec/device-format.md`):
//! `dbbcal simulate --config pipelines/sim-device.toml` then `dbbcal run pipelines/device.toml`
//! recovers the simulated axis's six true errors within U at every station (the simulator's own
//! inverse kinematics against `dbbcal-machine`'s forward kinematics), and broken `positions`
//! files are refused with one line naming file, column and rows (exit 3).

use std::path::{Path, PathBuf};

use dbbcal::io::{write_table, Column, Table};

use crate::support::{run_cli, simulate_ok};

fn run_device(campaign: &Path, out: &Path) -> (i32, String) {
    let (code, _, err) = run_cli(&[
        "run",
        "pipelines/device.toml",
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    (code, err)
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// Each evaluated dwell's six errors against the truth of its station: (worst |e − t| / U,
/// share of components within U, components beyond 2U, components compared).
fn recovery(device: &serde_json::Value, truth: &serde_json::Value) -> (f64, f64, usize, usize) {
    let stations = truth["device"]["stations"]
        .as_array()
        .expect("truth stations");
    let (mut worst, mut inside, mut beyond, mut n) = (0.0f64, 0usize, 0usize, 0usize);
    for d in device["dwells"].as_array().expect("dwells") {
        let errors = d["errors"].as_array().unwrap();
        if errors.is_empty() || d["flag"].as_str().is_some_and(|f| f.starts_with("datum")) {
            continue;
        }
        let station = d["station"].as_i64().unwrap();
        let t = stations
            .iter()
            .find(|s| s["station"].as_i64() == Some(station))
            .expect("station in truth");
        for (c, e) in errors.iter().enumerate() {
            assert_eq!(e["name"], t["names"][c], "names agree");
            let (v, u) = (e["value"].as_f64().unwrap(), e["u_k2"].as_f64().unwrap());
            let r = (v - t["errors"][c].as_f64().unwrap()).abs() / u;
            worst = worst.max(r);
            inside += usize::from(r <= 1.0);
            beyond += usize::from(r > 2.0);
            n += 1;
        }
    }
    (worst, inside as f64 / n.max(1) as f64, beyond, n)
}

/// `dbbcal simulate --config pipelines/sim-device.toml [--seed S]` and `dbbcal run
/// pipelines/device.toml` on it: the output folder and the campaign.
fn simulate_and_run(root: &Path, seed: Option<u64>) -> (PathBuf, PathBuf) {
    let name = seed.map_or("default".to_string(), |s| format!("seed-{s}"));
    let campaign = root.join(format!("campaign-{name}"));
    let seed_text = seed.map(|s| s.to_string());
    let mut args = vec![
        "simulate",
        "--config",
        "pipelines/sim-device.toml",
        "--out",
        campaign.to_str().unwrap(),
    ];
    if let Some(s) = &seed_text {
        args.extend(["--seed", s.as_str()]);
    }
    let (code, _, err) = run_cli(&args);
    assert_eq!(code, 0, "simulate: {err}");
    let out = root.join(format!("out-{name}"));
    let (code, err) = run_device(&campaign, &out);
    assert_eq!(code, 0, "run: {err}");
    (campaign, out)
}

/// The six true errors are recovered within U: the joint-centre offsets are one draw per
/// campaign, the same at every station, so the coverage is pooled over four campaigns (the
/// config's seed and three more); no component of any may lie beyond 2U.
#[test]
fn a_simulated_hexapod_axis_is_recovered_within_u_at_every_station() {
    let tmp = tempfile::tempdir().unwrap();
    let (mut inside, mut total, mut worst_all) = (0.0, 0usize, 0.0f64);
    for seed in [None, Some(1), Some(2), Some(3)] {
        let (campaign, out) = simulate_and_run(tmp.path(), seed);
        let device = json(&out.join("device.json"));
        let truth = json(&campaign.join("truth.json"));
        assert_eq!(device["axis"], "X");
        assert_eq!(device["names"][0], "EXX");
        assert!(
            device["not_evaluated"].is_null(),
            "{}",
            device["not_evaluated"]
        );
        assert!(
            device["loop"]["proposal"].is_null(),
            "a clean test: {}",
            device["loop"]
        );
        let (worst, coverage, beyond, n) = recovery(&device, &truth);
        eprintln!(
            "device recovery, seed {seed:?}: {n} components, worst |error − truth| / U = \
             {worst:.3}, {:.1} % within U, {beyond} beyond 2U",
            100.0 * coverage
        );
        assert!(n >= 6 * 40, "{n} components compared");
        assert_eq!(beyond, 0, "seed {seed:?}: worst {worst}");
        inside += coverage * n as f64;
        total += n;
        worst_all = worst_all.max(worst);
        if seed.is_some() {
            continue;
        }
        // The other outputs: the table, the figure, the sections, the inputs' hashes.
        assert!(out.join("device_errors.parquet").is_file());
        assert!(out.join("figures/device-errors.png").is_file());
        assert!(out.join("figures/device-poses.png").is_file());
        let page = std::fs::read_to_string(out.join("index.html")).unwrap();
        assert!(page.contains("id=\"device\"") && page.contains("device-errors.png"));
        assert!(page.contains("device-poses.png"));
        assert!(
            device["iso230_2"]["error"] == "EXX",
            "{}",
            device["iso230_2"]
        );
        let report = std::fs::read_to_string(out.join("report.md")).unwrap();
        assert!(report.contains("## Device") && report.contains("EYX"));
        let inputs = device["inputs"].as_array().unwrap();
        assert!(inputs
            .iter()
            .any(|i| i["path"] == "positions/positions.parquet"));
    }
    let pooled = inside / total as f64;
    eprintln!(
        "device recovery, pooled: {total} components, {:.1} % within U, worst {worst_all:.3} U",
        100.0 * pooled
    );
    assert!(pooled >= 0.9, "pooled coverage {pooled}");
}

/// The device's loop (`dbbcal_machine::device_study`): each effect of the catalogue hidden in
/// the simulator in turn is named from the legs across repeated dwells; added, the legs agree
/// to their noise again, nothing more is proposed, and the six errors are recovered as on a
/// clean test (none beyond 2U).
#[test]
fn the_device_loop_names_each_hidden_effect_and_adding_it_restores_the_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let base =
        std::fs::read_to_string(crate::support::root().join("pipelines/sim-device.toml")).unwrap();
    for (effect, hidden) in [
        ("machine_drift", "drift_um_per_h = [0.5, -0.3, 0.4]"),
        ("body_expansion", "body_cte_ppm_per_k = 11.5"),
        (
            "reseated_leg",
            "reseat = { leg = 3, from_dwell = 30, step_um = 0.8 }",
        ),
    ] {
        let (campaign, truth) = simulate_hidden(tmp.path(), &base, effect, hidden);
        let before = tmp.path().join(format!("{effect}-out"));
        let (code, err) = run_device(&campaign, &before);
        assert_eq!(code, 0, "{effect}: {err}");
        assert!(
            err.contains(&format!("--add-effect {effect}")),
            "{effect}: {err}"
        );
        let device = json(&before.join("device.json"));
        assert_eq!(device["loop"]["proposal"], effect, "{}", device["loop"]);
        let rms_before = device["loop"]["rms_um"].as_f64().unwrap();
        let (worst_before, ..) = recovery(&device, &truth);
        let after = tmp.path().join(format!("{effect}-added"));
        let (code, _, err) = run_cli(&[
            "run",
            "pipelines/device.toml",
            "--campaign",
            campaign.to_str().unwrap(),
            "--out",
            after.to_str().unwrap(),
            "--add-effect",
            effect,
        ]);
        assert_eq!(code, 0, "{effect}: {err}");
        let device = json(&after.join("device.json"));
        assert!(device["loop"]["proposal"].is_null(), "{}", device["loop"]);
        assert_eq!(device["loop"]["effects"][0]["effect"], effect);
        let rms_after = device["loop"]["rms_um"].as_f64().unwrap();
        let (worst, coverage, beyond, n) = recovery(&device, &truth);
        eprintln!(
            "device loop, {effect}: legs' RMS {rms_before:.4} → {rms_after:.4} µm; worst \
             |error − truth| / U {worst_before:.2} → {worst:.2}, {:.1} % of {n} within U",
            100.0 * coverage
        );
        assert!(
            rms_after < rms_before / 5.0,
            "{effect}: {rms_before} → {rms_after}"
        );
        assert!(worst < worst_before, "{effect}: {worst_before} → {worst}");
        assert_eq!(beyond, 0, "{effect}: worst {worst}");
    }
}

/// A machine warming up during the test (the drift slowing with a 1-h time constant) is named
/// `machine_drift`, then `machine_warm_up`; with both the legs agree across repeats and the six
/// errors are recovered as on a clean test.
#[test]
fn a_machine_warming_up_is_named_drift_then_warm_up() {
    let tmp = tempfile::tempdir().unwrap();
    let base =
        std::fs::read_to_string(crate::support::root().join("pipelines/sim-device.toml")).unwrap();
    let hidden = "drift_um_per_h = [0.4, -0.3, 1.5]\ndrift_tau_h = 1.0";
    let (campaign, truth) = simulate_hidden(tmp.path(), &base, "warm", hidden);
    let mut added: Vec<&str> = Vec::new();
    let mut rms = Vec::new();
    for expected in ["machine_drift", "machine_warm_up", ""] {
        let out = tmp.path().join(format!("out-{}", added.len()));
        let extra: Vec<&str> = added.iter().flat_map(|e| ["--add-effect", *e]).collect();
        let (device, _) = crate::support::run_record(
            "pipelines/device.toml",
            &campaign,
            &out,
            &extra,
            "device.json",
        );
        let (worst, coverage, beyond, n) = recovery(&device, &truth);
        let r = device["loop"]["rms_um"].as_f64().unwrap();
        eprintln!(
            "device loop, warm-up, with {added:?}: legs' RMS {r:.4} µm, worst {worst:.2} U, {:.1} % of {n} within U, {beyond} beyond 2U; proposed {}",
            100.0 * coverage,
            device["loop"]["proposal"]
        );
        assert_eq!(
            device["loop"]["proposal"].as_str().unwrap_or(""),
            expected,
            "{}",
            device["loop"]
        );
        rms.push((r, beyond));
        added.push(expected);
    }
    assert!(rms[2].0 < rms[0].0 / 5.0 && rms[2].0 < rms[1].0, "{rms:?}");
    assert_eq!(rms[2].1, 0, "{rms:?}");
}

/// `pipelines/sim-device.toml` (`base`) with `hidden` as its hexapod's effects, simulated into
/// `dir/name`: the campaign and its truth.
fn simulate_hidden(
    dir: &Path,
    base: &str,
    name: &str,
    hidden: &str,
) -> (PathBuf, serde_json::Value) {
    let config = dir.join(format!("{name}.toml"));
    std::fs::write(
        &config,
        format!("{base}\n[schedule.working.device.hexapod.effects]\n{hidden}\n"),
    )
    .unwrap();
    let campaign = dir.join(name);
    simulate_ok(config.to_str().unwrap(), campaign.to_str().unwrap());
    let truth = json(&campaign.join("truth.json"));
    (campaign, truth)
}

fn write_positions(campaign: &Path, columns: Vec<(&str, Column)>) {
    let folder = campaign.join("positions");
    let _ = std::fs::remove_dir_all(&folder);
    std::fs::create_dir_all(&folder).unwrap();
    let table = Table {
        columns: columns
            .into_iter()
            .map(|(n, c)| (n.to_string(), c))
            .collect(),
    };
    write_table(&folder.join("bad.parquet"), &table).unwrap();
}

/// A bad `positions` file is refused with exit 3 and one line naming file, column and rows.
fn check(campaign: &Path, out: &Path, columns: Vec<(&str, Column)>, words: &[&str]) {
    write_positions(campaign, columns);
    let (code, err) = run_device(campaign, out);
    assert_eq!(code, 3, "{err}");
    let line = err.trim();
    assert!(!line.contains('\n'), "one line: {line}");
    assert!(line.contains("bad.parquet"), "{line}");
    for w in words {
        assert!(line.contains(w), "{line:?} lacks {w:?}");
    }
}

#[test]
fn bad_positions_files_are_named_in_one_line_and_exit_3() {
    let tmp = tempfile::tempdir().unwrap();
    let (campaign, _) = simulate_and_run(tmp.path(), Some(1));
    let out = tmp.path().join("out-bad");
    let t0 = 1_793_491_200i64 * 1_000_000_000 + 23 * 3_600_000_000_000;
    let times: Vec<i64> = (0..4).map(|i| t0 + i * 60_000_000_000).collect();
    let good = |x: [f64; 4], station: [Option<i64>; 4]| {
        vec![
            ("time", Column::TimeNs(times.clone())),
            ("device", Column::Str(vec!["hexapod-1".into(); 4])),
            ("x_mm", Column::F64(x.to_vec())),
            ("y_mm", Column::F64(vec![300.0; 4])),
            ("z_mm", Column::F64(vec![-200.0; 4])),
            ("station", Column::OptI64(station.to_vec())),
        ]
    };
    // A station whose rows disagree.
    check(
        &campaign,
        &out,
        good(
            [400.0, 406.0, 400.01, 406.0],
            [Some(1), Some(2), Some(1), Some(2)],
        ),
        &["column `x_mm`", "station 1", "row 2", "row 0"],
    );
    // A missing column.
    let mut missing = good([400.0; 4], [Some(1); 4]);
    missing.remove(4);
    check(&campaign, &out, missing, &["missing column `z_mm`"]);
    // A wrong type.
    let mut wrong = good([400.0; 4], [Some(1); 4]);
    wrong[5].1 = Column::F64(vec![1.0, 1.0, 2.0, 2.0]);
    check(
        &campaign,
        &out,
        wrong,
        &["column `station`", "int64 or int32"],
    );
}
