//! Identification against simulated truth (issue 2: 10 bars, 15 days, 10 s, noise 0.02 µm, base
//! effects only: alpha and beta within 0.5 %, taus within 3 %, RMS within 5 % of the noise), and
//! compressed bins against the full-rate fit.

use dbbcal::pipeline::Stage;
use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::support::{
    analyse_campaign, analyse_campaign_binned, rel, sim_config, simulate_campaign,
};

/// The issue's identification campaign (`pipelines/sim-identification.toml`: 10 bars, 15 days,
/// 10 s, noise 0.02 µm, base effects; the room at the top of docs/spec/physics.md's typical range plus the
/// patent's set-point steps) meets every limit on every bar: alpha and beta within 0.5 %, taus
/// within 3 %, RMS within 5 % of the noise.
#[test]
fn base_model_recovers_truth_ten_bars_fifteen_days() {
    let cfg = sim_config("pipelines/sim-identification.toml");
    check_identification(&cfg, ISSUE_LIMITS);
}

/// The same campaign in a passive room (no set-point steps) carries about 4× less information
/// on tau_S: u(tau_S) is about 2 % a bar, so beta and tau_S are asserted only to lie within
/// 3 u of the truth (noise-limited, not biased); alpha, tau_R and the RMS still meet the issue.
#[test]
fn passive_room_identification_is_noise_limited() {
    let mut cfg = sim_config("pipelines/sim-identification.toml");
    cfg.room.setpoint_step_k = 0.0;
    check_identification(&cfg, [Some(0.005), None, Some(0.03), None]);
}

/// Relative limits of the issue on alpha, beta, tau_R and tau_S.
const ISSUE_LIMITS: [Option<f64>; 4] = [Some(0.005), Some(0.005), Some(0.03), Some(0.03)];
const PARAMS: [&str; 4] = ["alpha_ppm_per_k", "beta_ppm_per_k", "tau_r_s", "tau_s_s"];

/// Simulate `cfg`, identify the base model, and check every bar against its truth: each
/// parameter within 3 of its own standard uncertainties, within `limits` (relative; `None`: not
/// asserted) where given, and the RMS within 5 % of the noise. Prints per bar the errors in % and
/// in u, and the chance that all bars meet each issue limit given their u (a property of the
/// campaign's design, not of the estimator).
fn check_identification(cfg: &SimConfig, limits: [Option<f64>; 4]) {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, truth) = simulate_campaign(tmp.path(), "c", cfg);
    let results = analyse_campaign(&dir, Stage::Identify, &["fixed_part", "scale"]);
    assert!(
        results.failed.is_empty(),
        "failed bars: {:?}",
        results.failed
    );
    assert_eq!(results.bars.len(), truth.bars.len());
    let normal = statrs::distribution::Normal::new(0.0, 1.0).unwrap();
    let mut report = String::new();
    let mut worst = [0.0f64; 4];
    let mut worst_z = [0.0f64; 4];
    let mut worst_rms = 0.0f64;
    let mut p_all = [1.0f64; 4];
    for o in &results.bars {
        let t = truth
            .bars
            .iter()
            .find(|b| b.id == o.model.bar)
            .expect("truth for bar");
        let truths = [t.alpha_ppm_per_k, t.beta_ppm_per_k, t.tau_r_s, t.tau_s_s];
        report += &o.model.bar;
        for (k, name) in PARAMS.iter().enumerate() {
            let p = o.model.param(name).unwrap();
            let (err, z, u_rel) = (
                rel(p.value, truths[k]),
                (p.value - truths[k]).abs() / p.u,
                p.u / truths[k],
            );
            worst[k] = worst[k].max(err);
            worst_z[k] = worst_z[k].max(z);
            let limit = ISSUE_LIMITS[k].unwrap();
            p_all[k] *=
                2.0 * statrs::distribution::ContinuousCDF::cdf(&normal, limit / u_rel) - 1.0;
            report += &format!(
                " {name} {:.3}% ({:.1} u, u {:.2}%)",
                err * 100.0,
                z,
                u_rel * 100.0
            );
        }
        let rms = rel(o.model.rms_um, cfg.noise_um);
        worst_rms = worst_rms.max(rms);
        report += &format!(" rms {:.5} µm\n", o.model.rms_um);
    }
    let summary = format!(
        "worst: alpha {:.3} %, beta {:.3} %, tau_r {:.2} %, tau_s {:.2} % (issue 0.5, 0.5, 3, 3); \
         chance all bars meet the issue's limits from their u: {:.3}, {:.3}, {:.3}, {:.3}",
        worst[0] * 100.0,
        worst[1] * 100.0,
        worst[2] * 100.0,
        worst[3] * 100.0,
        p_all[0],
        p_all[1],
        p_all[2],
        p_all[3]
    );
    eprintln!("{}\n{report}{summary}", cfg.campaign_id);
    for (k, name) in PARAMS.iter().enumerate() {
        assert!(
            worst_z[k] < 3.0,
            "{name} is {:.1} u from the truth\n{report}",
            worst_z[k]
        );
        if let Some(limit) = limits[k] {
            assert!(
                worst[k] < limit,
                "{name} worst {:.3} % (limit {} %)\n{report}",
                worst[k] * 100.0,
                limit * 100.0
            );
        }
    }
    assert!(
        worst_rms < 0.05,
        "rms worst {:.2} % off the noise\n{report}",
        worst_rms * 100.0
    );
}

/// Bins compressed into two weighted nodes ([`dbbcal::series::BarBins`], `[model] bin_s`) give
/// the fit of every reading: on a 1 Hz campaign the estimates of 2-60 s compressions equal the
/// full-rate fit's to 0.002 of their uncertainty (measured), the RMS to 1e-6 relative, and the
/// sample count is the full-rate one. The HAC uncertainties differ by up to 18 % (measured): the
/// automatic batches are cut on different grids (a bandwidth choice, not an error of the
/// compression).
#[test]
fn compressed_bins_reproduce_the_full_rate_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = SimConfig {
        seed: 77,
        campaign_id: "bins-1hz".into(),
        duration_days: 3.0,
        sample_s: 1.0,
        noise_um: 0.02,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    };
    let (dir, _) = simulate_campaign(tmp.path(), "c", &cfg);
    // With no bin length set, a 1 Hz log is compressed into 60-s bins (`io::automatic_bin_s`).
    assert_eq!(dbbcal::io::automatic_bin_s(&dir).unwrap(), 60.0);
    let full = compressed(&dir, 0.0, false);
    let mut report = String::new();
    for bin_s in [2.0, 10.0, 30.0, 60.0] {
        let binned = compressed(&dir, bin_s, false);
        assert_eq!(binned.bars.len(), full.bars.len());
        for (f, b) in full.bars.iter().zip(&binned.bars) {
            let (f, b) = (&f.model, &b.model);
            assert_eq!(f.n_samples, b.n_samples, "{} bin {bin_s}", f.bar);
            assert!(
                b.n_samples as f64 > (bin_s - 1.0) * b.residuals_um.len() as f64 / 2.0,
                "{}: {} readings in {} nodes",
                f.bar,
                b.n_samples,
                b.residuals_um.len()
            );
            let rms = rel(b.rms_um, f.rms_um);
            report += &format!("{} bin {bin_s} s: rms {:.2e} rel", f.bar, rms);
            assert!(
                rms < 1e-5,
                "{} bin {bin_s}: rms {} vs {}",
                f.bar,
                b.rms_um,
                f.rms_um
            );
            for p in &f.params {
                let q = b.param(&p.name).unwrap();
                let shift_u = (q.value - p.value).abs() / p.u;
                report += &format!(
                    ", {} {:.3} u (u {:+.1} %)",
                    p.name,
                    shift_u,
                    100.0 * (q.u / p.u - 1.0)
                );
                assert!(
                    shift_u < 0.01,
                    "{} bin {bin_s}: {} moved {shift_u} u",
                    f.bar,
                    p.name
                );
                assert!(
                    rel(q.u, p.u) < 0.25,
                    "{} bin {bin_s}: u({}) {} vs {}",
                    f.bar,
                    p.name,
                    q.u,
                    p.u
                );
            }
            report += "\n";
        }
    }
    println!("{report}");
    // Ingest that bins while it streams gives the same bits as binning a log read whole.
    let streamed = compressed(&dir, 60.0, true);
    let whole = compressed(&dir, 60.0, false);
    for (a, b) in streamed.bars.iter().zip(&whole.bars) {
        assert_eq!(a.model.params, b.model.params, "{}", a.model.bar);
        assert_eq!(a.model.rms_um.to_bits(), b.model.rms_um.to_bits());
    }
}

fn compressed(dir: &std::path::Path, bin_s: f64, streamed: bool) -> dbbcal::pipeline::RunResults {
    analyse_campaign_binned(
        dir,
        Stage::Identify,
        &["fixed_part", "scale"],
        bin_s,
        streamed,
    )
}

/// With no bin length set, a fitted time constant shorter than 2 bins of the automatic 60 s
/// makes the run read the campaign again with bins a quarter of it, and one of 4 bins does not;
/// either way the estimates are the full-rate fit's (settling with tau 50 s and 240 s, 2-s
/// readings).
#[test]
fn automatic_bins_shorten_for_a_short_fitted_time_constant() {
    for (tau_settling_s, reread) in [(50.0, true), (240.0, false)] {
        check_automatic_bins_against_every_reading(tau_settling_s, reread);
    }
}

fn check_automatic_bins_against_every_reading(tau_settling_s: f64, reread: bool) {
    let tmp = tempfile::tempdir().unwrap();
    let mut cfg: SimConfig = sim_config("pipelines/sim-sample.toml");
    cfg.campaign_id = "short-tau".into();
    cfg.duration_days = 2.0;
    cfg.sample_s = 2.0;
    cfg.fleet = Some(FleetConfig {
        n_bars: 2,
        ..FleetConfig::default()
    });
    cfg.effects.settling.enabled = true;
    cfg.effects.settling.tau_s = tau_settling_s;
    let (dir, _) = simulate_campaign(tmp.path(), "short-tau", &cfg);
    let summary = |bin: Option<&str>| {
        let out = tmp.path().join(format!("out-{bin:?}"));
        let mut args = vec![
            "-q",
            "identify",
            "--campaign",
            dir.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--add-effect",
            "settling",
        ];
        if let Some(b) = bin {
            args.extend(["--bin-s", b]);
        }
        let (code, _, stderr) = crate::support::run_cli(&args);
        assert_eq!(code, 0, "{stderr}");
        let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()
    };
    let auto = summary(None);
    let full = summary(Some("0"));
    let bin_s = auto["model"]["bin_s"].as_f64().unwrap();
    if reread {
        assert!(
            bin_s > 0.0 && bin_s <= tau_settling_s / 3.0,
            "tau {tau_settling_s} s: bins of {bin_s} s"
        );
    } else {
        assert_eq!(bin_s, 60.0, "tau {tau_settling_s} s: bins of {bin_s} s");
    }
    for (a, f) in auto["bars"]
        .as_array()
        .unwrap()
        .iter()
        .zip(full["bars"].as_array().unwrap())
    {
        for p in ["alpha_ppm_per_k", "tau_settling_s"] {
            let (va, vf) = (
                a["params"][p]["value"].as_f64().unwrap(),
                f["params"][p]["value"].as_f64().unwrap(),
            );
            let u = f["params"][p]["u"].as_f64().unwrap();
            assert!(
                (va - vf).abs() < 0.1 * u,
                "tau {tau_settling_s} s, {p}: {va} vs {vf} (u {u})"
            );
        }
    }
}
