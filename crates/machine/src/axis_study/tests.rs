//! The study on a small synthetic X axis: three lines as in the patent, 5 runs each way, white
//! noise, and a machine drift hidden in the readings. (The end-to-end check against the
//! simulator, which shares no code with this crate, is `tests/e2e/axis_campaign.rs`.)

use std::collections::BTreeMap;

use dbbcal_core::axis_campaign::{
    AxisCampaign, AxisCampaignLogs, AxisMachineSection, AxisManifest, AxisReading as LogReading,
    CampaignKind, Channel as LogChannel, KindSection, LaserCompensation, LaserSection, LineDecl,
    MachineAxis,
};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::*;

/// Axis X, three lines: `{id 1 at [0, 0, 0]}`, `{2 at [0, 0, 100]}`, `{3 at [0, 100, 100]}` (mm),
/// readings with air and material compensation.
fn axis_campaign() -> AxisCampaign {
    let line = |id, reflector_mm| LineDecl { id, reflector_mm };
    let manifest = AxisManifest {
        campaign: KindSection {
            kind: CampaignKind::Axis,
            id: "t".into(),
            reference_temperature_c: 20.0,
        },
        machine: AxisMachineSection {
            axis: MachineAxis::X,
            cte_ppm_per_k: 11.5,
        },
        laser: LaserSection {
            wavelength_nm: 632.990577,
            compensation: LaserCompensation::AirMaterial,
            dead_path_mm: None,
        },
        line: vec![
            line(1, [0.0, 0.0, 0.0]),
            line(2, [0.0, 0.0, 100.0]),
            line(3, [0.0, 100.0, 100.0]),
        ],
        fixture: None,
        sensor: Vec::new(),
    };
    AxisCampaign::from_manifest_at(manifest, "campaign.toml").unwrap()
}

/// True errors at x (mm): δ µm, ε µrad, zero at x = 0.
fn truth(x: f64) -> [f64; 6] {
    let u = x / 1000.0;
    [
        8.0 * u + 1.5 * (6.0 * u).sin(),
        3.0 * u * u,
        -2.0 * u + 0.8 * (4.0 * u).sin(),
        12.0 * u,
        -15.0 * u * u + 5.0 * (3.0 * u).sin(),
        7.0 * u,
    ]
}

/// Readings Δ = δ + 10⁻³ ε × p, plus `drift_um_per_h` on every channel, plus noise.
fn campaign(drift_um_per_h: f64, seed: u64) -> AxisCampaignLogs {
    let campaign = axis_campaign();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let along = Normal::new(0.0, 0.02).unwrap();
    let lateral = Normal::new(0.0, 0.2).unwrap();
    let lines: [(i64, [f64; 3], &[LogChannel]); 3] = [
        (
            1,
            [0.0, 0.0, 0.0],
            &[LogChannel::Dx, LogChannel::Dy, LogChannel::Dz],
        ),
        (2, [0.0, 0.0, 100.0], &[LogChannel::Dx, LogChannel::Dy]),
        (3, [0.0, 100.0, 100.0], &[LogChannel::Dx]),
    ];
    let targets: Vec<f64> = (0..11).map(|j| 50.0 * j as f64).collect();
    let mut readings = Vec::new();
    let mut t: i64 = 0;
    for (line, p, channels) in lines {
        for run in 1..=5 {
            let visits = targets
                .iter()
                .map(|&x| (x, 1i8))
                .chain(targets.iter().rev().map(|&x| (x, -1i8)));
            for (x, direction) in visits {
                let e = truth(x);
                let d = crate::components::SixErrors::from_array(e).displacement_um(p);
                let hours = t as f64 / 3.6e12;
                for &c in channels {
                    let k = c.index();
                    let noise = if k == 0 {
                        along.sample(&mut rng)
                    } else {
                        lateral.sample(&mut rng)
                    };
                    readings.push(LogReading {
                        time_ns: t,
                        line,
                        run,
                        direction,
                        target_mm: x,
                        channel: c,
                        deviation_um: d[k] + drift_um_per_h * hours + noise,
                    });
                }
                t += 20_000_000_000; // 20 s a target
            }
        }
    }
    AxisCampaignLogs {
        campaign,
        inputs: Vec::new(),
        readings,
        extra: BTreeMap::new(),
        duplicate_readings: 0,
        fixture: Vec::new(),
        environment: Vec::new(),
        temperatures: BTreeMap::new(),
        events: Vec::new(),
    }
}

fn worst_over_u(s: &AxisStudy) -> f64 {
    s.targets
        .iter()
        .flat_map(|t| {
            let e = truth(t.target_mm);
            (0..6).map(move |k| (t.errors[k] - e[k]).abs() / t.u_k2[k].max(1e-12))
        })
        .fold(0.0, f64::max)
}

#[test]
fn a_clean_axis_is_recovered_within_u_and_nothing_is_proposed() {
    let s = study(&campaign(0.0, 1), &AxisStudyOptions::default()).unwrap();
    assert_eq!(s.rank, 6);
    assert!(s.lost.is_empty(), "{:?}", s.lost);
    assert_eq!(s.names[0], "EXX");
    assert_eq!(s.targets.len(), 22);
    let worst = worst_over_u(&s);
    assert!(worst < 1.5, "worst |error − truth| / U = {worst}");
    assert_eq!(s.diagnosis.proposal, None, "{:?}", s.diagnosis.candidates);
    let iso = s.iso230_2.as_ref().expect("5 runs each way");
    assert!(iso.repeatability_r_um.unwrap() < 0.2, "{iso:?}");
    assert_eq!(s.straightness.len(), 2);
    assert_eq!(s.straightness[0].name, "EYX");
    let choice = s.point_choice.as_ref().unwrap();
    assert!(choice.best.as_ref().unwrap().trace.unwrap() > 0.0);
    assert!(
        s.sigma_um[0] > 0.01 && s.sigma_um[0] < 0.03,
        "{:?}",
        s.sigma_um
    );
}

#[test]
fn a_machine_drift_is_named_added_and_the_error_falls() {
    let logs = campaign(1.5, 2);
    let base = study(&logs, &AxisStudyOptions::default()).unwrap();
    assert_eq!(
        base.diagnosis.proposal,
        Some(AxisEffect::MachineDrift),
        "{:?}",
        base.diagnosis.candidates
    );
    let added = study(
        &logs,
        &AxisStudyOptions {
            effects: vec![AxisEffect::MachineDrift],
            ..AxisStudyOptions::default()
        },
    )
    .unwrap();
    assert!(
        added.rms_um[0] < 0.5 * base.rms_um[0],
        "{:?} → {:?}",
        base.rms_um,
        added.rms_um
    );
    assert!(added.rms_um[0] < 0.03, "{:?}", added.rms_um);
    let drift = &added.effects[0].parameters[0];
    assert!((drift.1 - 1.5).abs() < drift.2.max(0.02), "{drift:?}");
    assert_eq!(added.diagnosis.proposal, None);
    assert!(worst_over_u(&added) < 1.5);
}

#[test]
fn lines_at_one_height_lose_the_roll_by_name() {
    let mut logs = campaign(0.0, 3);
    // Line 2's reflector at line 1's height (z₁ = z₂), the three points still not collinear:
    // Δy₁ − Δy₂ no longer sees EAX.
    logs.campaign.lines[1].reflector_mm = [0.0, 50.0, 0.0];
    let s = study(&logs, &AxisStudyOptions::default()).unwrap();
    assert_eq!(s.rank, 5);
    assert!(
        s.lost.iter().any(|l| l.contains("EAX")),
        "lost: {:?}",
        s.lost
    );
}

#[test]
fn a_levelling_drift_holds_the_constant_rate_but_not_the_reverse() {
    use effects::AxisEffect::{MachineDrift, MachineWarmUp};
    assert!(MachineDrift.is_within(&[MachineWarmUp]));
    assert!(!MachineWarmUp.is_within(&[MachineDrift]));
    // With both, the drift's three columns take the levelling shape and the warm-up adds none.
    let both = effects::columns_of(&[MachineDrift, MachineWarmUp]);
    assert_eq!(both.len(), 3);
    assert!(both
        .iter()
        .all(|c| c.effect == MachineDrift && c.regressor == effects::WARM_UP));
    assert_eq!(effects::columns_of(&[MachineWarmUp]).len(), 3);
}
