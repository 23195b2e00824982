//! Issue 13, item 3 (model side): on base-only campaigns the base model fits to the noise,
//! whatever the truth does where the logs cannot tell — the air between two temperature readings
//! held or interpolated, the bars not in steady state when the logging starts.
//!
//! "The noise" is the noise each campaign actually drew (white reading noise and quantization,
//! `support::noisy_campaign`): a model that contains the truth fits a little below it, so the
//! ratio measures model mismatch alone, free of the ±0.4 % (at 10 s, 3 bars, 4 days) by which a
//! sample RMS scatters about the nominal 0.020 µm.

use dbbcal::fit::{self, FitOptions, Start};
use dbbcal::model::{base_effects, ThermalProblem};
use dbbcal::pipeline::Stage;
use dbbcal::simulate::AirBetweenReadings;

use crate::support::{
    analyse_campaign, base_only_campaign, base_only_config, noisy_campaign, NoisyCampaign,
};

/// One campaign's base fit against its noise: fleet RMS / noise, the same for the fit started
/// at the true time constants, and each base parameter's worst error in its own u.
struct Outcome {
    rms_ratio: f64,
    /// The worst bar's RMS over its own noise.
    worst_bar_ratio: f64,
    true_start_ratio: f64,
    worst_u: [f64; 4],
    /// Every bar's (estimate − truth) / u of each base parameter.
    z: Vec<[f64; 4]>,
    line: String,
}

const PARAMS: [&str; 4] = ["alpha_ppm_per_k", "beta_ppm_per_k", "tau_r_s", "tau_s_s"];

fn evaluate(c: &NoisyCampaign, label: &str) -> Outcome {
    // (Match keeps the series: an identify-only run drops its samples.)
    let results = analyse_campaign(&c.dir, Stage::Match, &["fixed_part", "scale"]);
    assert!(results.failed.is_empty(), "{label}: {:?}", results.failed);
    let (mut ss, mut ss_true, mut n) = (0.0, 0.0, 0usize);
    let mut worst_u = [0.0f64; 4];
    let mut zs = Vec::new();
    let mut worst_bar_ratio = 0.0f64;
    for o in &results.bars {
        let m = &o.model;
        worst_bar_ratio = worst_bar_ratio.max(m.rms_um / c.noise_rms_um[&m.bar]);
        ss += m.rms_um.powi(2) * m.n_samples as f64;
        n += m.n_samples;
        let t = c.truth.bars.iter().find(|b| b.id == m.bar).unwrap();
        let truths = [t.alpha_ppm_per_k, t.beta_ppm_per_k, t.tau_r_s, t.tau_s_s];
        let mut z_bar = [0.0; 4];
        for (k, name) in PARAMS.iter().enumerate() {
            let p = m.param(name).unwrap();
            let z = (p.value - truths[k]) / p.u;
            z_bar[k] = z;
            if z.abs() > worst_u[k].abs() {
                worst_u[k] = z;
            }
        }
        zs.push(z_bar);
        // The same model fitted from the true time constants (no Brent start): tells model
        // mismatch (both high) from an optimiser that stopped short (only the first high).
        let problem = ThermalProblem::new(&o.series, &base_effects()).unwrap();
        let theta = [t.tau_r_s.ln(), t.tau_s_s.ln()];
        let options = FitOptions {
            start: Start::Given,
            absorbed_params: problem.n_zeros(),
            ..FitOptions::default()
        };
        let f = fit::fit(&problem, &theta, &options).unwrap();
        ss_true += f.rss;
    }
    let rms = (ss / n as f64).sqrt();
    let rms_true = (ss_true / n as f64).sqrt();
    let out = Outcome {
        rms_ratio: rms / c.fleet_noise_rms_um,
        worst_bar_ratio,
        true_start_ratio: rms_true / c.fleet_noise_rms_um,
        worst_u,
        z: zs,
        line: String::new(),
    };
    let line = format!(
        "{label}: rms {rms:.6} µm, noise {:.6} µm (nominal 0.020): rms/noise {:.5} (worst bar {:.5}), true start {:.5}; worst (est-truth)/u alpha {:+.2} beta {:+.2} tau_r {:+.2} tau_s {:+.2}",
        c.fleet_noise_rms_um, out.rms_ratio, out.worst_bar_ratio, out.true_start_ratio, worst_u[0], worst_u[1], worst_u[2], worst_u[3]
    );
    Outcome { line, ..out }
}

/// The must-show, in the time a warm test suite allows: seeds × both truths of the air
/// between readings × encoder/temperature periods, each bar out of steady state when the
/// logging starts (the room ran a day before): the base RMS within 0.5 % of the noise on every
/// campaign and every bar. Before the initial-state transients were fitted such campaigns gave
/// up to 1.027 (`base_noise_study`, `docs/model.md`). And alpha and beta stay unbiased: the mean of
/// (estimate − truth) / u over the campaigns' bars within 3 standard errors of 0. (Single bars
/// are not held to 3 u: on these short campaigns u is about 15-25 % small, so |z| reaches 3.2-3.6
/// over 80 bars even with the truth the model assumes; `base_noise_study` prints it.)
#[test]
fn base_model_fits_held_and_interpolated_air_to_the_noise() {
    let tmp = tempfile::tempdir().unwrap();
    let mut report = String::new();
    let mut failures = Vec::new();
    let mut zs: Vec<[f64; 4]> = Vec::new();
    for (seed, (sample_s, temperature_s)) in
        [(1u64, (10.0, 30.0)), (2, (60.0, 60.0)), (3, (1.0, 1.0))]
    {
        for air in [AirBetweenReadings::Held, AirBetweenReadings::Interpolated] {
            let c = base_only_campaign(tmp.path(), seed, air, 24.0, sample_s, temperature_s);
            let label = format!("seed {seed} {air:?} {sample_s}/{temperature_s} s");
            let o = evaluate(&c, &label);
            report += &o.line;
            report += "\n";
            if o.rms_ratio > 1.005 || o.worst_bar_ratio > 1.005 {
                failures.push(format!(
                    "{label}: rms/noise {:.5}, worst bar {:.5}",
                    o.rms_ratio, o.worst_bar_ratio
                ));
            }
            zs.extend(o.z.iter().copied());
            std::fs::remove_dir_all(&c.dir).ok();
        }
    }
    for k in 0..2 {
        let n = zs.len() as f64;
        let mean = zs.iter().map(|z| z[k]).sum::<f64>() / n;
        let sd = (zs.iter().map(|z| (z[k] - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        report += &format!(
            "{}: mean (est-truth)/u {mean:+.2} over {n} bars (sd {sd:.2})\n",
            PARAMS[k]
        );
        if mean.abs() > 3.0 * sd / n.sqrt() {
            failures.push(format!("{} biased: mean z {mean:+.2}", PARAMS[k]));
        }
    }
    eprintln!("{report}");
    assert!(failures.is_empty(), "{failures:?}\n{report}");
}

/// The measurement behind the table in `docs/model.md` (not part of the suite: minutes): every truth
/// variant over seeds and samplings. `DBBCAL_STUDY_SEEDS=1-20`, `DBBCAL_STUDY_SAMPLING=10/30,60/60`
/// (encoder/temperature periods, s), `DBBCAL_STUDY_BARS=4`, `DBBCAL_STUDY_DAYS=5`,
/// `DBBCAL_STUDY_TRUTHS=continuous,held,interpolated,prehistory`.
///
/// `cargo test --release --test e2e base_noise_study -- --ignored --nocapture`
#[test]
#[ignore]
fn base_noise_study() {
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or_else(|_| d.to_string());
    let seeds: Vec<u64> = {
        let s = env("DBBCAL_STUDY_SEEDS", "1-5");
        match s.split_once('-') {
            Some((a, b)) => (a.parse().unwrap()..=b.parse().unwrap()).collect(),
            None => s.split(',').map(|v| v.parse().unwrap()).collect(),
        }
    };
    let sampling: Vec<(f64, f64)> = env("DBBCAL_STUDY_SAMPLING", "10/30")
        .split(',')
        .map(|p| {
            let (a, b) = p.split_once('/').unwrap();
            (a.parse().unwrap(), b.parse().unwrap())
        })
        .collect();
    let bars: usize = env("DBBCAL_STUDY_BARS", "4").parse().unwrap();
    let days: f64 = env("DBBCAL_STUDY_DAYS", "5").parse().unwrap();
    let truths: Vec<String> = env(
        "DBBCAL_STUDY_TRUTHS",
        "continuous,held,interpolated,prehistory",
    )
    .split(',')
    .map(String::from)
    .collect();
    let tmp = tempfile::tempdir().unwrap();
    println!("truth enc/temp seeds: rms/noise mean max | true-start mean max | (est-truth)/u mean/rms/max|.| of alpha beta tau_r tau_s over bars");
    for truth in &truths {
        let (air, pre) = match truth.as_str() {
            "continuous" => (AirBetweenReadings::Continuous, 0.0),
            "held" => (AirBetweenReadings::Held, 0.0),
            "interpolated" => (AirBetweenReadings::Interpolated, 0.0),
            "prehistory" => (AirBetweenReadings::Continuous, 24.0),
            "held+prehistory" => (AirBetweenReadings::Held, 24.0),
            "interpolated+prehistory" => (AirBetweenReadings::Interpolated, 24.0),
            other => panic!("truth {other}"),
        };
        for &(sample_s, temperature_s) in &sampling {
            let mut ratios = Vec::new();
            let mut true_ratios = Vec::new();
            let mut worst = [0.0f64; 4];
            let mut zs: Vec<[f64; 4]> = Vec::new();
            for &seed in &seeds {
                let cfg = base_only_config(seed, air, pre, sample_s, temperature_s, bars, days);
                let c = noisy_campaign(tmp.path(), &format!("s{seed}"), &cfg);
                let o = evaluate(
                    &c,
                    &format!("{truth} {sample_s}/{temperature_s} seed {seed}"),
                );
                if std::env::var("DBBCAL_STUDY_VERBOSE").is_ok() {
                    println!("  {}", o.line);
                }
                ratios.push(o.rms_ratio);
                true_ratios.push(o.true_start_ratio);
                for (w, u) in worst.iter_mut().zip(&o.worst_u) {
                    *w = w.max(u.abs());
                }
                zs.extend(o.z.iter().copied());
                std::fs::remove_dir_all(&c.dir).ok();
            }
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let z_col = |k: usize| zs.iter().map(|z| z[k]).collect::<Vec<f64>>();
            let z_stats: Vec<String> = (0..4)
                .map(|k| {
                    let z = z_col(k);
                    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
                    format!("{:+.2}/{:.2}/{:.2}", mean(&z), rms, worst[k])
                })
                .collect();
            println!(
                "{truth} {sample_s}/{temperature_s} s {}: {:.5} {:.5} | {:.5} {:.5} | {}",
                seeds.len(),
                mean(&ratios),
                max(&ratios),
                mean(&true_ratios),
                max(&true_ratios),
                z_stats.join(" ")
            );
        }
    }
}
