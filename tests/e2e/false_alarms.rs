//! Issue 13, item 3: no false alarms. Over 20 base-only campaigns — the truth generated with the
//! air held and with it interpolated between temperature readings, the bars out of steady state
//! when the logging starts, encoder and temperature periods from 1 to 60 s — the nightly
//! diagnosis (ranking, fleet-wide and per-bar forward selection at their defaults, the readings
//! compressed as `dbbcal run` does: 60-s bins for the 1, 5 and 10 s logs) proposes no
//! effect on at least 19 of 20 (5 % family-wise), and the base model fits each campaign to
//! within 0.5 % of the noise it drew. Where the readings are compressed (60-s bins) the
//! diagnosis's noise floor is that noise within 0.5 % too: it pools the readings' scatter
//! about their bins' lines (nearly every reading's degree of freedom); from the nodes alone
//! it came out 0.4-0.7 % low on the 1 s seeds (0.99345-0.99559, -0.4 to +0.4 % on the 5 s
//! ones), more than the RMS it is read against.

use dbbcal::diagnose::Verdict;
use dbbcal::pipeline::Stage;
use dbbcal::simulate::AirBetweenReadings;

use crate::support::{analyse_campaign_binned, base_only_config, noisy_campaign};

/// (encoder period, temperature period), s: cycled over the seeds.
const SAMPLINGS: [(f64, f64); 5] = [
    (1.0, 1.0),
    (5.0, 10.0),
    (10.0, 30.0),
    (30.0, 30.0),
    (60.0, 60.0),
];

#[test]
fn base_only_campaigns_raise_no_alarm_and_fit_to_the_noise() {
    let tmp = tempfile::tempdir().unwrap();
    let mut alarms = Vec::new();
    let mut misfits = Vec::new();
    let mut floors = Vec::new();
    let mut report = String::new();
    for seed in 1..=20u64 {
        let air = if seed % 2 == 0 {
            AirBetweenReadings::Held
        } else {
            AirBetweenReadings::Interpolated
        };
        let (sample_s, temperature_s) = SAMPLINGS[(seed as usize - 1) % SAMPLINGS.len()];
        let days = if sample_s < 5.0 { 1.5 } else { 3.0 };
        let cfg = base_only_config(seed, air, 24.0, sample_s, temperature_s, 3, days);
        let campaign = noisy_campaign(tmp.path(), &format!("clean-{seed}"), &cfg);
        // As `dbbcal run` reads it: logs of 12 s or faster compressed into 60-s bins, the others not.
        let bin_s = dbbcal::io::automatic_bin_s(&campaign.dir).unwrap();
        assert_eq!(bin_s > 0.0, sample_s <= 12.0, "seed {seed}: bins {bin_s} s");
        let results = analyse_campaign_binned(&campaign.dir, Stage::Diagnose, &[], bin_s, true);
        let d = results.diagnosis.as_ref().expect("diagnosis");
        let (ss, n) = results.bars.iter().fold((0.0, 0usize), |(ss, n), o| {
            (
                ss + o.model.rms_um.powi(2) * o.model.n_samples as f64,
                n + o.model.n_samples,
            )
        });
        let ratio = (ss / n as f64).sqrt() / campaign.fleet_noise_rms_um;
        let floor_ratio = d.criteria.noise_floor_um / campaign.fleet_noise_rms_um;
        let proposed: Vec<String> = d
            .candidates
            .iter()
            .filter(|c| c.verdict == Verdict::Proposed)
            .map(|c| {
                format!(
                    "{}: {}",
                    c.effect,
                    dbbcal::narrative::diagnosis::reason(&c.reason)
                )
            })
            .chain(
                d.ledger
                    .iter()
                    .skip(1)
                    .map(|s| format!("fleet ledger adds {}", s.added)),
            )
            .chain(d.bar_ledgers.iter().flat_map(|b| {
                b.steps
                    .iter()
                    .skip(1)
                    .map(move |s| format!("{} ledger adds {}", b.bar, s.added))
            }))
            .collect();
        let immaterial = d
            .candidates
            .iter()
            .filter(|c| c.verdict == Verdict::Immaterial)
            .count();
        report += &format!(
            "seed {seed:2} {air:?} {sample_s}/{temperature_s} s: rms/noise {ratio:.5}, floor/noise {floor_ratio:.5}, {} proposed, {immaterial} detectable but immaterial, threshold {:.4} µm\n",
            proposed.len(),
            d.criteria.min_gain_um
        );
        if !proposed.is_empty() {
            alarms.push(format!("seed {seed}: {proposed:?}"));
        }
        if ratio > 1.005 {
            misfits.push(format!("seed {seed}: rms/noise {ratio:.5}"));
        }
        if bin_s > 0.0 && (floor_ratio - 1.0).abs() > 0.005 {
            floors.push(format!("seed {seed}: floor/noise {floor_ratio:.5}"));
        }
        std::fs::remove_dir_all(&campaign.dir).ok();
    }
    eprintln!("{report}{alarms:#?}");
    assert!(
        alarms.len() <= 1,
        "false alarms on {} of 20: {alarms:#?}",
        alarms.len()
    );
    assert!(misfits.is_empty(), "{misfits:?}\n{report}");
    assert!(floors.is_empty(), "{floors:?}\n{report}");
}
