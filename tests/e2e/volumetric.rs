//! The `volumetric` kind end to end (issue 30): `dbbcal simulate` writes body and step
//! diagonals (the simulator shares no code with the analysis), `dbbcal run
//! pipelines/volumetric.toml` reads them back and writes the record, tables, figures and page;
//! what the readings cannot see is said by name; each effect of the spec's catalogue hidden in
//! turn is named by the loop, and adding it makes the residual fall.

use std::path::{Path, PathBuf};

use crate::support::{root, run_cli, simulate_ok};

/// White noise per reading in [`config`], µm.
const NOISE_UM: f64 = 0.05;

/// A simulation config: the shipped one's sections with `test`, `errors` and `effects` given.
fn config(seed: u64, machine: &str, test: &str, errors: &str, effects: &str) -> String {
    format!(
        "kind = \"volumetric\"\nseed = {seed}\n[campaign]\nid = \"vol-e2e\"\n[machine]\n{machine}\n[grid]\ncounts = [3, 4, 3]\n[test]\n{test}\n[errors]\n{errors}\n[laser]\ncompensation = \"air\"\nnoise_um = 0.05\n[effects]\n{effects}\n"
    )
}

fn simulate(dir: &Path, name: &str, text: &str) -> PathBuf {
    let cfg = dir.join(format!("{name}.toml"));
    std::fs::write(&cfg, text).unwrap();
    let out = dir.join(name);
    simulate_ok(&cfg.display().to_string(), &out.display().to_string());
    out
}

fn run(
    dir: &Path,
    campaign: &Path,
    name: &str,
    pipeline: &Path,
    add: &[&str],
) -> serde_json::Value {
    let out = dir.join(name);
    let mut args = vec![
        "run".to_string(),
        pipeline.display().to_string(),
        "--campaign".into(),
        campaign.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    for a in add {
        args.push("--add-effect".into());
        args.push(a.to_string());
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let (code, o, e) = run_cli(&refs);
    assert_eq!(code, 0, "{o}\n{e}");
    serde_json::from_str(&std::fs::read_to_string(out.join("volumetric.json")).unwrap()).unwrap()
}

fn truth(campaign: &Path) -> serde_json::Value {
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(campaign.join("truth.json")).unwrap())
            .unwrap();
    t["volumetric"].clone()
}

#[test]
fn the_shipped_pipeline_runs_a_simulated_campaign_and_says_what_it_cannot_see() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("vol");
    simulate_ok("pipelines/sim-volumetric.toml", &out.display().to_string());
    let rec = run(
        tmp.path(),
        &out,
        "vol-out",
        &root().join("pipelines/volumetric.toml"),
        &[],
    );
    let t = truth(&out);
    // Squareness: the joint fit finds the truth within U; the naive inversion does not.
    for i in 0..3 {
        let q = &rec["squareness_urad"][i];
        let (v, u) = (q["value"].as_f64().unwrap(), q["u_k2"].as_f64().unwrap());
        let truth = t["squareness_urad"][i].as_f64().unwrap();
        // k = 3 (1.5 U): one fixed seed, three values, not a 95 % coin toss each.
        assert!((v - truth).abs() <= 1.5 * u, "S{i}: {v} ± {u} vs {truth}");
    }
    let naive = rec["naive_inversion"]["squareness_urad"]
        .as_array()
        .unwrap();
    let naive_err = (0..3)
        .map(|i| (naive[i].as_f64().unwrap() - t["squareness_urad"][i].as_f64().unwrap()).abs())
        .fold(0.0, f64::max);
    assert!(
        naive_err > 3.0,
        "the naive inversion's error under 50 µrad pointing: {naive_err}"
    );
    let cannot: Vec<String> = rec["cannot_see"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    assert!(
        cannot
            .iter()
            .any(|l| l.contains("unknown pointing") && l.contains("slope Dx(x)")),
        "{cannot:?}"
    );
    let out_dir = tmp.path().join("vol-out");
    let md = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    assert!(md.contains("confounded with the beams' pointing"));
    let page = std::fs::read_to_string(out_dir.join("index.html")).unwrap();
    assert!(
        page.contains("confounded with the beams&#39;")
            || page.contains("confounded with the beams'")
    );
    for f in [
        "figures/diagonals.png",
        "figures/residuals.png",
        "figures/fourth_pattern.png",
        "figures/grid_vectors_xy.png",
        "figures/grid_vectors_xz.png",
    ] {
        assert!(out_dir.join(f).is_file(), "{f}");
        assert!(page.contains(f), "{f} not on the page");
    }
    // The FANUC 3-D table: 36 lines, N100001 … N100036, sign and unit stated in the record.
    let fanuc = std::fs::read_to_string(out_dir.join("table_fanuc_3d.txt")).unwrap();
    let lines: Vec<&str> = fanuc.lines().collect();
    assert_eq!(lines.len(), 36);
    assert!(lines[0].starts_with("N100001A1P") && lines[35].starts_with("N100036A1P"));
    let tables = rec["tables"].to_string();
    assert!(
        tables.contains("correction") && tables.contains("detection units"),
        "{tables}"
    );
    assert!(std::fs::read_to_string(out_dir.join("table_isg_x.csv"))
        .unwrap()
        .contains("EXX"));
    // ISO 230-2 per diagonal (body) and V_diag.
    assert_eq!(rec["diagonals"].as_array().unwrap().len(), 4);
    assert!(rec["v_diag"]["value_um"].as_f64().unwrap() > 0.0);
    assert!(!rec["decisions"].as_array().unwrap().is_empty());
}

#[test]
fn body_diagonals_cannot_see_scale_errors_that_cancel() {
    let tmp = tempfile::tempdir().unwrap();
    let text = config(
        4,
        "min_mm = [0.0, 0.0, 0.0]\nmax_mm = [1000.0, 1000.0, 1000.0]",
        "steps = 0\nruns = 3",
        "scale_um_per_m = [10.0, -10.0, 0.0]\nsquareness_urad = [0.0, 0.0, 0.0]\nshape_um = 0.0",
        "",
    );
    let campaign = simulate(tmp.path(), "cube", &text);
    let t = truth(&campaign);
    assert!((t["v1_um"].as_f64().unwrap() - 14.142).abs() < 0.01);
    assert!((t["v2_um"].as_f64().unwrap() - 14.142).abs() < 0.01);
    assert!((t["v3_um"].as_f64().unwrap() - 14.142).abs() < 0.01);
    let rec = run(
        tmp.path(),
        &campaign,
        "cube-out",
        &root().join("pipelines/volumetric.toml"),
        &[],
    );
    for d in rec["diagonals"].as_array().unwrap() {
        assert!(d["e_um"].as_f64().unwrap() < 0.2, "{d}");
    }
    let cannot = rec["cannot_see"].to_string();
    assert!(cannot.contains("4 of 9 linear terms: Σ L_k² ε_k / D² and three squareness values; per-axis scale differences are invisible"), "{cannot}");
    let md = std::fs::read_to_string(tmp.path().join("cube-out/report.md")).unwrap();
    assert!(md.contains("per-axis scale differences are invisible"));
    assert_eq!(rec["figures_identifiable"], false);
    // V1 … V3 (14.14 µm in truth) are said not determined, and the 3-D table carries a warning.
    assert!(
        md.contains("V1, V2, V3: not determined by these readings"),
        "{md}"
    );
    assert!(rec["tables"].to_string().contains("WARNING"));
    let decisions = rec["decisions"].to_string();
    assert!(decisions.contains("\"quantity\":\"V2\"") && decisions.contains("no decision"));
}

/// Each effect hidden in turn: the loop names it, and adding it makes the residual fall.
#[test]
fn the_loop_names_each_hidden_effect_and_adding_it_lowers_the_residual() {
    let tmp = tempfile::tempdir().unwrap();
    let machine = "min_mm = [0.0, 0.0, -500.0]\nmax_mm = [1000.0, 600.0, 0.0]";
    let base = tmp.path().join("base.toml");
    std::fs::write(
        &base,
        "[pipeline]\nname = \"volumetric\"\nstages = [\"volumetric\"]\n[volumetric]\neffects = []\nforward_steps = 0\n",
    )
    .unwrap();
    let pointing = root().join("pipelines/volumetric.toml");
    // Step diagonals alone, evenly timed, make the time a linear function of P: a machine
    // drift linear in time is then one more linear field, confounded with the slopes and the
    // pointing (the run says so, see below); body diagonals run up and down separate it.
    let steps_only = "body = false\nsteps = 10\nstep_runs = 2";
    let with_body = "body = true\nruns = 2\nsteps = 10\nstep_runs = 2";
    let cases: [(&str, &str, &str, &Path, &[&str]); 4] = [
        ("pointing", "pointing_urad = 50.0", steps_only, &base, &[]),
        (
            "machine_drift",
            "drift_um_per_h = 4.0",
            with_body,
            &pointing,
            &[],
        ),
        // The analysis' Abbe term is bilinear: the angular errors' linear part (the
        // simulator's non-linear angular shapes are switched off here; with them the residual
        // falls but not to the noise, see the report of issue 30).
        (
            "abbe",
            "abbe = true\ntool_offset_mm = [0.0, 0.0, 150.0]",
            steps_only,
            &pointing,
            &[],
        ),
        // Along the four diagonals a sag D_z(x, z) is nearly an additive field: the step
        // diagonals see it only through each staircase cell's mixed difference, so it takes a
        // sag of some 20 µm to be named at 0.05 µm noise (5 µm is absorbed unseen).
        (
            "non_rigid",
            "non_rigid_sag_um = 30.0",
            steps_only,
            &pointing,
            &[],
        ),
    ];
    for (i, (name, effects, test, pipeline, add)) in cases.iter().enumerate() {
        let text = config(
            10 + i as u64,
            machine,
            test,
            "shape_um = 2.0\nangular_urad = 20.0\nangular_shape_urad = 0.0",
            effects,
        );
        let campaign = simulate(tmp.path(), name, &text);
        let before = run(tmp.path(), &campaign, &format!("{name}-1"), pipeline, add);
        assert_eq!(
            before["diagnosis_proposal"].as_str(),
            Some(*name),
            "{name}: {}",
            before["diagnosis_candidates"]
        );
        let mut with: Vec<&str> = add.to_vec();
        with.push(name);
        let after = run(tmp.path(), &campaign, &format!("{name}-2"), pipeline, &with);
        let (r0, r1) = (
            before["residual_rms_um"].as_f64().unwrap(),
            after["residual_rms_um"].as_f64().unwrap(),
        );
        let t = truth(&campaign);
        let sq_err = |rec: &serde_json::Value| {
            (0..3)
                .map(|i| {
                    (rec["squareness_urad"][i]["value"].as_f64().unwrap()
                        - t["squareness_urad"][i].as_f64().unwrap())
                    .abs()
                })
                .fold(0.0, f64::max)
        };
        // Squareness against the truth: (seen and within U, seen).
        let within = |rec: &serde_json::Value| {
            let (mut ok, mut seen) = (0, 0);
            for i in 0..3 {
                let q = &rec["squareness_urad"][i];
                if q["identifiable"] == true {
                    seen += 1;
                    let err = (q["value"].as_f64().unwrap()
                        - t["squareness_urad"][i].as_f64().unwrap())
                    .abs();
                    ok += usize::from(err <= q["u_k2"].as_f64().unwrap());
                }
            }
            (ok, seen)
        };
        let (w0, w1) = (within(&before), within(&after));
        eprintln!(
            "{name}: residual RMS {r0:.4} -> {r1:.4} µm; largest squareness error {:.3} -> {:.3} µrad; squareness within U: {}/{} seen -> {}/{} seen",
            sq_err(&before),
            sq_err(&after),
            w0.0,
            w0.1,
            w1.0,
            w1.1
        );
        // The effect explains the excess: the residual falls to the simulated noise (0.05 µm
        // per reading) from clearly above it.
        assert!(r1 <= 1.15 * NOISE_UM, "{name}: {r0} -> {r1}");
        // With the effect in the model, every squareness the readings still see is the truth
        // within its U (fixed seeds; Abbe's cross terms leave none seen, and the run says so).
        assert_eq!(w1.0, w1.1, "{name}: squareness within U after");
        assert!(r0 >= 1.2 * r1, "{name}: {r0} -> {r1}");
    }
}

/// Machine drift on step diagonals alone (evenly timed sub-moves): the run says it cannot be
/// separated, by name, instead of naming it or claiming it absent.
#[test]
fn drift_on_step_diagonals_alone_is_named_as_unseparable() {
    let tmp = tempfile::tempdir().unwrap();
    let text = config(
        21,
        "min_mm = [0.0, 0.0, -500.0]\nmax_mm = [1000.0, 600.0, 0.0]",
        "body = false\nsteps = 10\nstep_runs = 2",
        "shape_um = 2.0",
        "drift_um_per_h = 4.0",
    );
    let campaign = simulate(tmp.path(), "drift", &text);
    let rec = run(
        tmp.path(),
        &campaign,
        "drift-out",
        &root().join("pipelines/volumetric.toml"),
        &[],
    );
    assert_ne!(rec["diagnosis_proposal"].as_str(), Some("machine_drift"));
    let cannot = rec["cannot_see"].to_string();
    assert!(
        cannot.contains("machine_drift") && cannot.contains("confounded"),
        "{cannot}"
    );
}

/// The plan is checked before any parquet is read: a wrong effect or an axis pipeline on a
/// volumetric campaign is one line naming the pipeline, and no output folder appears.
#[test]
fn a_bad_pipeline_is_refused_in_one_line_before_reading() {
    let tmp = tempfile::tempdir().unwrap();
    // A campaign folder with only a manifest: the plan must not need the tables.
    let campaign = tmp.path().join("c");
    std::fs::create_dir_all(&campaign).unwrap();
    std::fs::write(
        campaign.join("campaign.toml"),
        "[campaign]\nkind = \"volumetric\"\nid = \"c\"\nreference_temperature_c = 20.0\n",
    )
    .unwrap();
    let out = tmp.path().join("out");
    for (pipeline, add, words) in [
        (
            "pipelines/volumetric.toml",
            "foo",
            "\"foo\" is not an effect of a volumetric campaign",
        ),
        (
            "pipelines/axis.toml",
            "pointing",
            "is a volumetric campaign (run it with pipelines/volumetric.toml)",
        ),
    ] {
        let (code, _o, e) = run_cli(&[
            "run",
            &root().join(pipeline).display().to_string(),
            "--campaign",
            &campaign.display().to_string(),
            "--out",
            &out.display().to_string(),
            "--add-effect",
            add,
        ]);
        assert_ne!(code, 0);
        assert!(e.contains(words), "{e}");
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(!out.exists());
    }
    // A scale budget out of range, named by its key.
    let text = std::fs::read_to_string(root().join("pipelines/volumetric.toml")).unwrap();
    let bad = tmp.path().join("bad-budget.toml");
    std::fs::write(
        &bad,
        text.replace("material_k = 0.0577", "material_k = -1.0"),
    )
    .unwrap();
    let (code, _o, e) = run_cli(&[
        "run",
        bad.to_str().unwrap(),
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(e.contains("volumetric.scale_budget.material_k"), "{e}");
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(!out.exists());
}
