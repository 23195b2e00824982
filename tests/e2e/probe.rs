//! The `probe` machine kind end to end (issue 31): seed 003's Table 1 as a campaign through
//! `dbbcal run pipelines/probe.toml` (the real data: `tests/data/seed003_tables.csv`, transcribed
//! from seed 003, Table 1), the simulator's 24-direction campaign through the loop, and bad
//! input answered in one line.

use std::path::Path;

use dbbcal::probe_campaign::{
    approach_of, ArtefactDecl, ArtefactKind, ProbeCampaignTables, ProbeManifest, ProbeSection,
    ProbeTouch, StylusDecl,
};
use serde_json::Value;

use crate::support::{root, run_cli, simulate_ok};

/// Touches 1 … 10 at 0°, 60°, … 300° of seed 003's Table 1 (µm).
fn seed_table_1() -> Vec<[f64; 6]> {
    let text = std::fs::read_to_string(root().join("tests/data/seed003_tables.csv")).unwrap();
    text.lines()
        .filter(|l| l.starts_with("1,") && !l.contains('~'))
        .map(|l| {
            let v: Vec<f64> = l.split(',').skip(2).map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4], v[5]]
        })
        .collect()
}

fn manifest(id: &str, centre: Option<[f64; 3]>) -> ProbeManifest {
    ProbeManifest {
        campaign: dbbcal::axis_campaign::KindSection {
            kind: dbbcal::axis_campaign::CampaignKind::Probe,
            id: id.into(),
            reference_temperature_c: 20.0,
        },
        probe: ProbeSection {
            model: Some("TP2-5".into()),
            same_direction_deg: 1.0,
        },
        stylus: vec![StylusDecl {
            id: "S1".into(),
            tip_diameter_mm: 6.0,
            length_mm: None,
        }],
        artefact: vec![ArtefactDecl {
            id: "ring-50".into(),
            kind: ArtefactKind::Ring,
            diameter_mm: 50.0,
            u_um: 0.05,
            form_um: Some(0.05),
            centre_mm: centre,
        }],
        sensor: Vec::new(),
    }
}

/// Seed Table 1 as touches on a ring whose centre is declared: each value is the touch's
/// pretravel (δ = (x − C)·a − (R − r)), directions in the table's order, ten touches each.
fn write_table_1_campaign(dir: &Path, stylus: &str) {
    let centre = [250.0, 150.0, -80.0];
    let rows = seed_table_1();
    assert_eq!(rows.len(), 10);
    let mut touches = Vec::new();
    for d in 0..6 {
        let a = approach_of(60.0 * d as f64, 0.0);
        for (k, row) in rows.iter().enumerate() {
            let seq = (d * 10 + k + 1) as i64;
            let reach = 25.0 - 3.0 + 1e-3 * row[d];
            touches.push(ProbeTouch {
                time_ns: 1_800_000_000_000_000_000 + seq * 5_000_000_000,
                seq,
                approach: a,
                position_mm: std::array::from_fn(|c| centre[c] + reach * a[c]),
                feed_mm_min: Some(100.0),
                stylus: stylus.into(),
                artefact: "ring-50".into(),
                spindle_deg: None,
                touch_in_direction: 0,
            });
        }
    }
    let tables = ProbeCampaignTables {
        manifest: manifest("seed003-table1", Some(centre)),
        touches,
    };
    let opts = dbbcal::io::ProbeWriteOptions {
        files: 2,
        shuffle_rows: true,
        ..Default::default()
    };
    dbbcal::io::write_probe_campaign(dir, &tables, &opts).unwrap();
}

/// `dbbcal run pipelines/probe.toml` on `campaign` into `out`, asserted to succeed: its
/// `probe.json` and what it printed.
pub(super) fn run(campaign: &Path, out: &Path, extra: &[&str]) -> (Value, String) {
    let (code, said) = crate::support::run_on("pipelines/probe.toml", campaign, out, extra);
    assert_eq!(code, 0, "{said}");
    (json(&out.join("probe.json")), said)
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

#[test]
fn seed_table_1_through_the_cli_says_what_six_directions_cannot_tell() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("table1");
    write_table_1_campaign(&campaign, "S1");
    let out = tmp.path().join("out");
    let (j, _) = run(&campaign, &out, &[]);
    let s = &j["setups"][0];
    let t = &s["two_touch"];
    assert!((f(&t["mean_range_all_um"]) - 0.2833).abs() < 5e-4, "{t}");
    assert!((f(&t["mean_range_2on_um"]) - 0.150).abs() < 1e-6, "{t}");
    assert!((f(&t["range_ratio"]) - 1.89).abs() < 5e-3, "{t}");
    assert!(
        (f(&t["direction_means_spread_um"]) - 3.41).abs() < 5e-3,
        "{t}"
    );
    assert!(
        (f(&t["first_touch_offset_min_um"]) - (-0.478)).abs() < 1e-3,
        "{t}"
    );
    // The 2~10 range at 180° is 0.3 (the seed prints 0.2).
    let d180 = &s["directions"][3];
    assert!((f(&d180["phi_deg"]) - 180.0).abs() < 1e-6);
    assert!((f(&d180["range_2on_um"]) - 0.3).abs() < 1e-9, "{d180}");
    // The 1st harmonic is 1.43 µm; sin 3φ is lost by name.
    let h1 = &s["harmonics"][1];
    assert!((f(&h1["amplitude_um"]) - 1.43).abs() < 5e-3, "{h1}");
    assert!(s["harmonics_lost"].to_string().contains("h3_sin_um"));
    let names: Vec<String> = s["not_identifiable"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["name"].as_str().unwrap().to_string())
        .collect();
    for name in [
        "0th harmonic ≡ tip radius",
        "1st harmonic ≡ centre offset",
        "6 directions: sin 3φ unseen",
    ] {
        assert!(names.iter().any(|n| n == name), "{name} not in {names:?}");
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let page = std::fs::read_to_string(out.join("index.html")).unwrap();
    for text in [&md, &page] {
        assert!(text.contains("6 directions: sin 3φ unseen"));
        assert!(text.contains("1st harmonic ≡ centre offset"));
        assert!(text.contains("0th harmonic ≡ tip radius"));
        assert!(
            text.contains("1st harmonic of 1.43 µm"),
            "the 1st harmonic named with its size"
        );
        assert!(text.contains("not pretravel"));
        assert!(text.contains("lobes' phase is not fixed"));
    }
    assert!(out.join("figures/probe-polar-S1-ring-50.png").is_file());
    assert!(page.contains("figures/probe-polar-S1-ring-50.png"));
    assert!(out.join("probe_directions.parquet").is_file());
    // MPE 1 µm against P and its U: the decision is written.
    assert!(s["form"]["decision"].is_string(), "{}", s["form"]);
}

#[test]
fn simulated_24_directions_separate_lobes_centre_and_first_touch_and_the_loop_names_it() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("sim");
    let c = campaign.to_str().unwrap();
    simulate_ok("pipelines/sim-probe.toml", c);
    let truth = json(&campaign.join("truth.json"));
    let logs = dbbcal::io::read_probe_campaign(&campaign).unwrap();
    assert_eq!(logs.touches.len(), 240);
    assert!(logs.inputs.iter().all(|f| !f.path.starts_with("truth")));

    let out1 = tmp.path().join("out1");
    let (j, said) = run(&campaign, &out1, &[]);
    assert_eq!(
        j["setups"][0]["diagnosis"]["proposal"], "first_touch",
        "{}",
        j["setups"][0]["diagnosis"]
    );
    assert!(said.contains("--add-effect first_touch"), "{said}");

    let out2 = tmp.path().join("out2");
    let (j, _) = run(&campaign, &out2, &["--add-effect", "first_touch"]);
    let s = &j["setups"][0];
    assert_ne!(s["diagnosis"]["proposal"], "first_touch");
    // Tri-lobe: δ_min and the seat phase within U.
    let l = &s["lobing"];
    let (d, ud) = (f(&l["size_um"]["value"]), f(&l["size_um"]["u_k2"]));
    assert!(
        (d - f(&truth["delta_min_um"])).abs() <= ud,
        "δ_min {d} ± {ud}"
    );
    let (p, up) = (f(&l["phase_deg"]["value"]), f(&l["phase_deg"]["u_k2"]));
    assert!(
        (p - f(&truth["seat_phase_deg"])).abs() <= up,
        "φ₀ {p} ± {up}"
    );
    // Centre (1.4 µm off the programme's) within U.
    let a = &s["artefact_fit"];
    for k in 0..2 {
        let err_um = 1e3 * (f(&a["centre_mm"][k]) - f(&truth["centre_mm"][k]));
        let u = f(&a["centre_offset_um"][k][2]);
        assert!(err_um.abs() <= u, "centre {k}: {err_um} µm, U {u}");
    }
    // First-touch errors per direction: their U is judged over many directions, not on one
    // draw (the shipped seed has 19 of 24 within U; 24 directions share one noise estimate, so
    // one seed's count scatters far more than a binomial's).
    let z = first_touch_errors_in_u(&s["directions"], &truth["directions"]);
    assert_eq!(z.len(), 24);
}

/// `(fit − truth) / (U/2)` of every direction's first-touch error (U at k = 2).
fn first_touch_errors_in_u(directions: &Value, truth: &Value) -> Vec<f64> {
    let truths = truth.as_array().unwrap();
    directions
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            let phi = f(&d["phi_deg"]);
            let t = truths
                .iter()
                .find(|t| ((f(&t["phi_deg"]) - phi + 180.0).rem_euclid(360.0) - 180.0).abs() < 0.1)
                .unwrap();
            let fit = &d["first_touch_fit"];
            (f(&fit["value"]) - f(&t["first_touch_error_um"])) / (f(&fit["u_k2"]) / 2.0)
        })
        .collect()
}

/// The first-touch errors' U over ten simulated campaigns (seeds 1-10 of
/// `pipelines/sim-probe.toml`, 240 directions): at k = 2 about 95 % lie within U; at least 90 %
/// must (3 standard deviations of the count below 95 %), and the scatter of the errors in units
/// of U/2 must be 1 within 15 % (U neither too small nor too large). Measured: 221 of 240 (92.1 %),
/// RMS 1.045.
#[test]
fn the_first_touch_errors_u_holds_over_ten_simulated_campaigns() {
    let tmp = tempfile::tempdir().unwrap();
    let config = std::fs::read_to_string(root().join("pipelines/sim-probe.toml")).unwrap();
    let mut z = Vec::new();
    for seed in 1..=10 {
        let cfg = tmp.path().join(format!("sim{seed}.toml"));
        std::fs::write(
            &cfg,
            config.replace("seed = 3\n", &format!("seed = {seed}\n")),
        )
        .unwrap();
        let campaign = tmp.path().join(format!("sim{seed}"));
        let out = tmp.path().join(format!("out{seed}"));
        simulate_ok(cfg.to_str().unwrap(), campaign.to_str().unwrap());
        let (j, _) = run(&campaign, &out, &["--add-effect", "first_touch"]);
        let truth = json(&campaign.join("truth.json"));
        z.extend(first_touch_errors_in_u(
            &j["setups"][0]["directions"],
            &truth["directions"],
        ));
    }
    assert_eq!(z.len(), 240);
    let inside = z.iter().filter(|z| z.abs() <= 2.0).count();
    let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt();
    eprintln!(
        "first-touch errors over ten campaigns: {inside} of 240 within U, RMS {rms:.3} in U/2"
    );
    assert!(inside >= 216, "{inside} of 240 first-touch errors within U");
    assert!(
        (0.85..=1.15).contains(&rms),
        "RMS of the errors in U/2: {rms}"
    );
}

#[test]
fn bad_touches_and_a_bad_mpe_are_one_line_naming_file_column_and_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("bad");
    write_table_1_campaign(&campaign, "S9");
    let out = tmp.path().join("out");
    let (code, _, stderr) = run_cli(&[
        "run",
        "pipelines/probe.toml",
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    let line = stderr.trim();
    assert_eq!(line.lines().count(), 1, "{stderr}");
    assert!(
        line.contains("touches-0") && line.contains("`stylus`") && line.contains("rows"),
        "{line}"
    );
    assert!(!out.exists());

    let pipeline = tmp.path().join("p.toml");
    let text = std::fs::read_to_string(root().join("pipelines/probe.toml"))
        .unwrap()
        .replace("mpe_um = 1.0", "mpe_um = -1.0");
    std::fs::write(&pipeline, text).unwrap();
    let good = tmp.path().join("good");
    write_table_1_campaign(&good, "S1");
    let (code, _, stderr) = run_cli(&[
        "run",
        pipeline.to_str().unwrap(),
        "--campaign",
        good.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(
        stderr.contains("probe.mpe_um") && stderr.trim().lines().count() == 1,
        "{stderr}"
    );
}
