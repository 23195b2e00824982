use super::*;
use crate::components::SixErrors;
use crate::hexapod::tests::example;

/// What a hidden effect adds to the legs (µm) at dwell k, from (k, hours, body excess, dwell).
type Hidden = Box<dyn Fn(usize, f64, f64, &DwellLegs) -> [f64; 6]>;

/// Noise of a leg's dwell mean, µm.
const NOISE_UM: f64 = 0.02;

/// A test like the simulator's: 9 stations 8 mm apart along X, up and down, `runs` runs, 5 min
/// a dwell; the axis's own errors repeat at each station, `hidden` adds to the legs (µm) at
/// dwell k (hours, body excess). Noise from a fixed LCG (deterministic).
fn campaign(
    runs: usize,
    hidden: impl Fn(usize, f64, f64, &DwellLegs) -> [f64; 6],
) -> (Vec<DwellLegs>, Vec<[f64; 6]>) {
    let device = example();
    let c0 = [400.0, 300.0, -200.0];
    let truth = |q: f64| {
        let s = (q - 400.0) / 64.0;
        SixErrors::from_array([3.0 * s, 2.0 * s * s, -s, 10.0 * s, -5.0 * s * s, 8.0 * s])
    };
    let mut state = 12345u64;
    let mut noise = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        // Sum of 4 uniforms, scaled to unit variance.
        let u: f64 = (0..4)
            .map(|j| ((state >> (16 * j)) & 0xffff) as f64 / 65536.0 - 0.5)
            .sum();
        u * 3f64.sqrt()
    };
    let mut dwells = Vec::new();
    let mut hidden_um = Vec::new();
    let mut k = 0;
    for _run in 0..runs {
        let up: Vec<(usize, i8)> = (0..9).map(|s| (s, if s == 0 { 0 } else { 1 })).collect();
        let down: Vec<(usize, i8)> = (0..9).rev().map(|s| (s, -1)).collect();
        for (s, dir) in up.into_iter().chain(down) {
            let q = 400.0 + 8.0 * s as f64;
            let cmd = device.commanded_pose(&device.nominal_pose, c0, [q, 300.0, -200.0]);
            let pose = device.apply_errors(&cmd, &truth(q));
            let hours = k as f64 * 6.0 / 60.0;
            let excess = 0.3 * (hours / 2.0).sin();
            let exact = device.leg_lengths_mm(&pose);
            let mut d = DwellLegs::at_pose(&device, &pose, hours, (s as i64, dir), exact, excess);
            let h = hidden(k, hours, excess, &d);
            for (l, h) in d.lengths_mm.iter_mut().zip(h) {
                *l += (h + NOISE_UM * noise()) * 1e-3;
            }
            hidden_um.push(h);
            dwells.push(d);
            k += 1;
        }
    }
    (dwells, hidden_um)
}

fn run(dwells: &[DwellLegs], effects: &[DeviceEffect]) -> DeviceStudy {
    study(
        dwells,
        &DeviceStudyOptions {
            effects: effects.to_vec(),
            ..Default::default()
        },
    )
    .unwrap()
}

#[test]
fn a_clean_test_proposes_nothing_and_its_residual_is_the_noise() {
    let (dwells, _) = campaign(3, |_, _, _, _| [0.0; 6]);
    let s = run(&dwells, &[]);
    assert_eq!(s.proposal, None, "{:?}", s.candidates);
    // Residuals about group means of 3 dwells: sqrt(2/3) of the noise.
    let expected = NOISE_UM * (2.0f64 / 3.0).sqrt();
    assert!(
        (s.rms_um / expected - 1.0).abs() < 0.2,
        "{} vs {expected}",
        s.rms_um
    );
    assert!(s.corrections_um.iter().all(|c| c.iter().all(|v| *v == 0.0)));
}

#[test]
fn each_hidden_effect_is_named_and_adding_it_brings_the_legs_to_the_noise() {
    let drift = [0.8, -0.5, 0.3, 2.0, 0.0, -1.5];
    let cases: [(DeviceEffect, Hidden); 3] = [
        (
            DeviceEffect::MachineDrift,
            Box::new(move |_, h, _, d: &DwellLegs| {
                std::array::from_fn(|i| (0..6).map(|c| d.jacobian_um[i][c] * drift[c] * h).sum())
            }),
        ),
        (
            DeviceEffect::BodyExpansion,
            Box::new(|_, _, t, d: &DwellLegs| {
                std::array::from_fn(|i| d.strain_um_per_ppm[i] * 11.5 * t)
            }),
        ),
        (
            DeviceEffect::ReseatedLeg,
            Box::new(|k, _, _, _| {
                std::array::from_fn(|i| if i == 2 && k >= 23 { 0.6 } else { 0.0 })
            }),
        ),
    ];
    for (effect, hidden) in cases {
        let (dwells, truth) = campaign(3, hidden);
        let before = run(&dwells, &[]);
        assert_eq!(
            before.proposal,
            Some(effect),
            "{effect:?}: {:?}",
            before.candidates
        );
        assert!(
            before.rms_um > 2.0 * NOISE_UM,
            "{effect:?}: {}",
            before.rms_um
        );
        let after = run(&dwells, &[effect]);
        assert_eq!(after.proposal, None, "{effect:?}: {:?}", after.candidates);
        assert!(
            after.rms_um < 1.2 * NOISE_UM,
            "{effect:?}: {}",
            after.rms_um
        );
        // The corrections are the hidden effect, up to what group means absorb: compare the
        // worst leg at the dwell where the effect is largest.
        let worst = truth
            .iter()
            .zip(&after.corrections_um)
            .map(|(t, c)| (0..6).map(|i| (t[i] - c[i]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        assert!(worst < 0.05, "{effect:?}: correction off by {worst} µm");
        if effect == DeviceEffect::ReseatedLeg {
            assert_eq!(after.effects[0].parameters[0].0, "leg3_step_um");
            let (_, v, u) = &after.effects[0].parameters[0];
            assert!((v - 0.6).abs() < u.max(0.01), "step {v} ± {u}");
        }
    }
}

#[test]
fn without_repeats_the_loop_says_so() {
    let (dwells, _) = campaign(1, |_, _, _, _| [0.0; 6]);
    let single: Vec<DwellLegs> = dwells.into_iter().take(9).collect();
    assert_eq!(
        study(&single, &DeviceStudyOptions::default()),
        Err(DeviceStudyError::NoRepeats)
    );
}

#[test]
fn the_strain_sensitivity_is_the_legs_change_when_the_rings_grow() {
    let mut device = example();
    device.cte_ppm_per_k = 0.0;
    let pose = device.nominal_pose;
    let d = DwellLegs::at_pose(&device, &pose, 0.0, (0, 0), [0.0; 6], 0.0);
    let grown = device.at_temperature(21.0, 20.0);
    let mut hot = device.clone();
    hot.cte_ppm_per_k = 100.0;
    let hot = hot.at_temperature(21.0, 20.0);
    let (l0, l1) = (device.leg_lengths_mm(&pose), hot.leg_lengths_mm(&pose));
    for i in 0..6 {
        let per_ppm_um = (l1[i] - l0[i]) * 1e3 / 100.0;
        assert!((per_ppm_um - d.strain_um_per_ppm[i]).abs() < 1e-4, "{i}");
    }
    assert_eq!(grown, device, "cte 0: no growth");
}
