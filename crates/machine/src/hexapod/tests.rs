use super::*;
use crate::components::SixErrors;
use crate::pose_errors::axis_of_test;
use crate::straightness::remove_line;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The `[[device]]` example of device-format.md.
pub(crate) fn example() -> Hexapod {
    Hexapod {
        base_mm: [
            [196.962, -34.730, 0.0],
            [196.962, 34.730, 0.0],
            [-68.404, 187.939, 0.0],
            [-128.558, 153.209, 0.0],
            [-128.558, -153.209, 0.0],
            [-68.404, -187.939, 0.0],
        ],
        platform_mm: [
            [64.279, -76.604, 0.0],
            [64.279, 76.604, 0.0],
            [34.202, 93.969, 0.0],
            [-98.481, 17.365, 0.0],
            [-98.481, -17.365, 0.0],
            [34.202, -93.969, 0.0],
        ],
        u_base_um: [2.0; 6],
        u_platform_um: [2.0; 6],
        nominal_pose: Pose::from_array([0.0, 0.0, 260.0, 0.0, 0.0, 0.0]),
        tool_point_mm: [0.0, 0.0, 0.0],
        base_orientation_deg: [0.0, 0.0, 0.0],
        up: [0.0, 0.0, 1.0],
        cte_ppm_per_k: 11.5,
    }
}

#[test]
fn the_spec_example_lengths_and_tilts() {
    let d = example();
    d.validate().unwrap();
    let l = d.leg_lengths_mm(&d.nominal_pose);
    let a = d.leg_tilts_deg(&d.nominal_pose);
    println!("legs {l:.5?} mm, tilts {a:.4?} deg");
    for (l, a) in l.iter().zip(a) {
        assert!((l - 294.887).abs() < 5e-4, "{l}");
        assert!((a - 61.85).abs() < 5e-3, "{a}");
    }
    let c = d.condition_number(&d.nominal_pose);
    assert!((c - 2.937).abs() < 1e-3, "{c}");
}

fn random_pose(rng: &mut ChaCha8Rng) -> Pose {
    Pose::from_array([
        rng.gen_range(-20.0..20.0),
        rng.gen_range(-20.0..20.0),
        260.0 + rng.gen_range(-20.0..20.0),
        rng.gen_range(-3.0..3.0),
        rng.gen_range(-3.0..3.0),
        rng.gen_range(-3.0..3.0),
    ])
}

#[test]
fn forward_inverts_inverse_kinematics() {
    let d = example();
    let mut rng = ChaCha8Rng::seed_from_u64(29_005);
    let (mut worst_mm, mut worst_urad, mut worst_iter) = (0.0f64, 0.0f64, 0);
    for _ in 0..500 {
        let truth = random_pose(&mut rng);
        let f = d.forward(&d.leg_lengths_mm(&truth)).unwrap();
        assert!(f.residual_mm <= 1e-12);
        let e = d.pose_errors(&f.pose, &truth).to_array();
        worst_mm = worst_mm.max(e[..3].iter().fold(0.0f64, |a, v| a.max(v.abs())) * 1e-3);
        worst_urad = worst_urad.max(e[3..].iter().fold(0.0f64, |a, v| a.max(v.abs())));
        worst_iter = worst_iter.max(f.iterations);
    }
    println!("round trip: worst {worst_mm:.2e} mm, {worst_urad:.2e} µrad, {worst_iter} iterations");
    assert!(worst_mm < 1e-6, "{worst_mm} mm");
    // 1 nm at the platform's 100 mm radius is 0.01 µrad.
    assert!(worst_urad < 1e-2, "{worst_urad} µrad");
}

const SPEC_ONE_UM: [f64; 6] = [1.3, 1.3, 0.46, 7.1, 7.1, 9.4];

#[test]
fn one_micrometre_per_leg_analytic() {
    let d = example();
    let c = d
        .pose_covariance(&d.nominal_pose, &[1.0; 6], false)
        .unwrap();
    let u: Vec<f64> = (0..6).map(|k| c[(k, k)].sqrt()).collect();
    println!("1 µm per leg, analytic: {u:.4?}");
    for (k, (a, b)) in u.iter().zip(SPEC_ONE_UM).enumerate() {
        assert!((a / b - 1.0).abs() < 0.05, "{k}: {a} vs {b}");
    }
}

#[test]
fn one_micrometre_per_leg_monte_carlo() {
    let d = example();
    let l0 = d.leg_lengths_mm(&d.nominal_pose);
    let n = 20_000;
    let mut rng = ChaCha8Rng::seed_from_u64(29_006);
    let normal = Normal::new(0.0, 1e-3).unwrap(); // mm
    let mut sum2 = [0.0; 6];
    for _ in 0..n {
        let l: [f64; 6] = std::array::from_fn(|i| l0[i] + normal.sample(&mut rng));
        let f = d.forward(&l).unwrap();
        let e = d.pose_errors(&f.pose, &d.nominal_pose).to_array();
        for k in 0..6 {
            sum2[k] += e[k] * e[k];
        }
    }
    let sd: Vec<f64> = sum2.iter().map(|s| (s / n as f64).sqrt()).collect();
    println!("1 µm per leg, MC (n = {n}): {sd:.4?}");
    let c = d
        .pose_covariance(&d.nominal_pose, &[1.0; 6], false)
        .unwrap();
    for k in 0..6 {
        assert!(
            (sd[k] / SPEC_ONE_UM[k] - 1.0).abs() < 0.05,
            "{k}: {}",
            sd[k]
        );
        assert!(
            (sd[k] / c[(k, k)].sqrt() - 1.0).abs() < 0.03,
            "{k}: {}",
            sd[k]
        );
    }
}

#[test]
fn a_near_singular_pose_is_refused() {
    // The platform 0.1 mm above the base plane: the legs are nearly horizontal, z unseen.
    let d = Hexapod {
        nominal_pose: Pose::from_array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
        ..example()
    };
    let flat = Pose::from_array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0]);
    let c = d.condition_number(&flat);
    println!("condition at z = 0.1 mm: {c:.1}");
    match d.forward(&d.leg_lengths_mm(&flat)) {
        Err(HexapodError::NearSingular {
            condition,
            threshold,
            pose,
        }) => {
            assert!(condition > threshold && threshold == DEFAULT_MAX_CONDITION);
            assert!((pose.z_mm - 0.1).abs() < 1e-6);
        }
        other => panic!("{other:?}"),
    }
    // The same pose with a looser threshold is accepted and flagged by its number.
    let f = d
        .forward_with(
            &d.leg_lengths_mm(&flat),
            ForwardOptions {
                max_condition: 1e4,
                ..ForwardOptions::default()
            },
        )
        .unwrap();
    assert!(f.condition > DEFAULT_MAX_CONDITION);
}

#[test]
fn bad_lengths_and_devices_are_refused() {
    let d = example();
    assert!(matches!(
        d.forward(&[0.0; 6]),
        Err(HexapodError::BadInput(_))
    ));
    // Lengths no pose can take.
    assert!(matches!(
        d.forward(&[10.0; 6]),
        Err(HexapodError::NotConverged { .. }) | Err(HexapodError::NearSingular { .. })
    ));
    let mut bad = example();
    bad.base_mm[1] = bad.base_mm[0];
    assert!(matches!(bad.validate(), Err(HexapodError::BadDevice(_))));
    let mut bad = example();
    bad.up = [0.0; 3];
    assert!(matches!(bad.validate(), Err(HexapodError::BadDevice(_))));
}

#[test]
fn rings_expand_about_their_centroids() {
    let mut d = example();
    // Move B's origin 40 mm under the base ring: the ring still expands about its centre.
    for b in &mut d.base_mm {
        b[2] += 40.0;
    }
    let hot = d.at_temperature(21.0, 20.0);
    for i in 0..6 {
        for k in 0..2 {
            let want = d.base_mm[i][k] * (1.0 + 11.5e-6);
            assert!((hot.base_mm[i][k] - want).abs() < 1e-12);
        }
        assert!((hot.base_mm[i][2] - 40.0).abs() < 1e-12);
    }
    // 11.5 ppm/K on a 200 mm radius: 2.3 µm/K (machine-physics.md, "Hexapod").
    let r0 = (d.base_mm[0][0].powi(2) + d.base_mm[0][1].powi(2)).sqrt();
    let r1 = (hot.base_mm[0][0].powi(2) + hot.base_mm[0][1].powi(2)).sqrt();
    assert!(((r1 - r0) * 1e3 - 2.3).abs() < 0.01);
    assert_eq!(d.at_temperature(20.0, 20.0), d);
}

#[test]
fn commanded_poses_and_errors() {
    let d = Hexapod {
        base_orientation_deg: [0.4, -0.7, 30.0],
        tool_point_mm: [10.0, -5.0, 60.0],
        ..example()
    };
    let datum = Pose::from_array([1.0, -2.0, 258.0, 0.3, -0.2, 0.5]);
    let c0 = [400.0, 300.0, -200.0];
    let c = [430.0, 300.0, -200.0];
    let cmd = d.commanded_pose(&datum, c0, c);
    // The tool moves by R_MBᵀ (c − c₀) in B, and 30 mm along M's X.
    let moved = d.base_orientation() * (cmd.translation_mm() - datum.translation_mm());
    assert!((moved - Vector3::new(30.0, 0.0, 0.0)).norm() < 1e-12);
    assert_eq!(
        d.pose_errors(&datum, &d.commanded_pose(&datum, c0, c0)),
        SixErrors::default()
    );
    let e = SixErrors::from_array([12.0, -7.5, 3.0, 25.0, -40.0, 15.0]);
    let back = d.pose_errors(&d.apply_errors(&cmd, &e), &cmd).to_array();
    for (a, b) in back.iter().zip(e.to_array()) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
}

/// Truth of a simulated X axis, zero at the datum (x₀): tens of µm and µrad.
fn truth_x(x: f64, x0: f64) -> SixErrors {
    let f = |x: f64| {
        let u = x / 50.0;
        [
            15.0 * u + 4.0 * (1.5 * u).sin(), // EXX: positioning, 15 µm / 50 mm
            8.0 * u * u - 3.0 * u,            // EYX: straightness with a slope
            -6.0 * u * u + 2.0 * (2.0 * u).cos(), // EZX
            12.0 * u,                         // EAX: roll
            -20.0 * u + 5.0 * u * u,          // EBX: pitch
            10.0 * (1.2 * u).sin(),           // ECX: yaw
        ]
    };
    let (a, b) = (f(x), f(x0));
    SixErrors::from_array(std::array::from_fn(|k| a[k] - b[k]))
}

#[test]
fn a_simulated_axis_is_recovered_within_u() {
    let manifest = Hexapod {
        base_orientation_deg: [0.2, -0.1, 0.5],
        ..example()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(29_007);
    // The true device differs from the manifest within the joints' u.
    let ju = Normal::new(0.0, 2e-3).unwrap(); // mm
    let mut real = manifest.clone();
    for j in real.base_mm.iter_mut().chain(real.platform_mm.iter_mut()) {
        for v in j.iter_mut() {
            *v += ju.sample(&mut rng);
        }
    }
    let leg_u_k2 = [1.0; 6]; // µm, U (k = 2) per leg
    let leg_noise = Normal::new(0.0, 0.5e-3).unwrap(); // mm, = U / 2
    let c0 = [400.0, 300.0, -200.0];
    let positions: Vec<[f64; 3]> = (-5..=5)
        .map(|k| [c0[0] + 10.0 * k as f64, c0[1], c0[2]])
        .collect();
    assert_eq!(
        axis_of_test(&positions, 1e-3),
        Some(crate::components::Axis::X)
    );
    // The true datum pose, and every station's true pose.
    let datum_true = Pose::from_array([0.4, -0.3, 259.0, 0.05, -0.03, 0.1]);
    let noisy = |truth: &Pose, rng: &mut ChaCha8Rng| -> [f64; 6] {
        let l = real.leg_lengths_mm(truth);
        std::array::from_fn(|i| l[i] + leg_noise.sample(rng))
    };
    let datum = manifest
        .forward(&noisy(&datum_true, &mut rng))
        .unwrap()
        .pose;
    let (mut inside, mut total, mut worst) = (0, 0, 0.0f64);
    let mut ey = Vec::new();
    for c in &positions {
        let e_true = truth_x(c[0], c0[0]);
        let cmd_true = manifest.commanded_pose(&datum_true, c0, *c);
        let pose_true = manifest.apply_errors(&cmd_true, &e_true);
        let measured = manifest.forward(&noisy(&pose_true, &mut rng)).unwrap().pose;
        let cmd = manifest.commanded_pose(&datum, c0, *c);
        let e = manifest.pose_errors(&measured, &cmd).to_array();
        let u = manifest
            .error_uncertainty(&datum, &measured, &leg_u_k2)
            .unwrap()
            .to_array();
        let t = e_true.to_array();
        for k in 0..6 {
            let z = (e[k] - t[k]).abs() / u[k];
            worst = worst.max(z);
            total += 1;
            if z <= 1.0 {
                inside += 1;
            }
        }
        ey.push(e[1]);
        println!(
            "x {:6.1}: EXX {:7.3} (true {:7.3}, U {:.2}) EAX {:7.2} (true {:7.2}, U {:.2})",
            c[0], e[0], t[0], u[0], e[3], t[3], u[3]
        );
    }
    println!("{inside} of {total} inside U (k = 2); worst |error|/U {worst:.2}");
    // U at k = 2 covers ~95 % of components; none beyond 2 U.
    assert!(inside as f64 >= 0.9 * total as f64, "{inside} of {total}");
    assert!(worst < 2.0, "{worst}");
    // Straightness: the line removed takes out the slope of EYX, the bow stays.
    let x: Vec<f64> = positions.iter().map(|c| c[0]).collect();
    let s = remove_line(&x, &ey).unwrap();
    assert!(s.detrended_range_um() < 8.0 + 1.0 && s.detrended_range_um() > 8.0 - 2.0);
}

#[test]
fn without_noise_the_simulated_axis_is_exact() {
    let d = Hexapod {
        base_orientation_deg: [0.2, -0.1, 0.5],
        tool_point_mm: [0.0, 0.0, 50.0],
        ..example()
    };
    let c0 = [400.0, 300.0, -200.0];
    let datum = Pose::from_array([0.4, -0.3, 259.0, 0.05, -0.03, 0.1]);
    for k in -5..=5 {
        let c = [c0[0] + 10.0 * k as f64, c0[1], c0[2]];
        let truth = truth_x(c[0], c0[0]);
        let cmd = d.commanded_pose(&datum, c0, c);
        let pose = d.apply_errors(&cmd, &truth);
        let measured = d.forward(&d.leg_lengths_mm(&pose)).unwrap().pose;
        let e = d.pose_errors(&measured, &cmd).to_array();
        for (a, b) in e.iter().zip(truth.to_array()) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
    }
}

#[test]
fn the_error_uncertainty_matches_monte_carlo() {
    // A station 50 mm along X from the datum; legs U = 1 µm (k = 2) independent at both
    // dwells, joints u = 2 µm per coordinate shared by both.
    let d = Hexapod {
        base_orientation_deg: [0.2, -0.1, 0.5],
        tool_point_mm: [0.0, 0.0, 40.0],
        ..example()
    };
    let c0 = [400.0, 300.0, -200.0];
    let c = [450.0, 300.0, -200.0];
    let datum = Pose::from_array([0.4, -0.3, 259.0, 0.05, -0.03, 0.1]);
    let station = d.commanded_pose(&datum, c0, c);
    let u = d.error_uncertainty(&datum, &station, &[1.0; 6]).unwrap();
    let legs_only = Hexapod {
        u_base_um: [0.0; 6],
        u_platform_um: [0.0; 6],
        ..d.clone()
    }
    .error_uncertainty(&datum, &station, &[1.0; 6])
    .unwrap();
    let n = 10_000;
    let mut rng = ChaCha8Rng::seed_from_u64(29_008);
    let leg = Normal::new(0.0, 0.5e-3).unwrap();
    let joint = Normal::new(0.0, 2e-3).unwrap();
    let mut sum2 = [0.0; 6];
    for _ in 0..n {
        let mut real = d.clone();
        for j in real.base_mm.iter_mut().chain(real.platform_mm.iter_mut()) {
            for v in j.iter_mut() {
                *v += joint.sample(&mut rng);
            }
        }
        let mut measure = |pose: &Pose| {
            let l = real.leg_lengths_mm(pose);
            d.forward(&std::array::from_fn(|i| l[i] + leg.sample(&mut rng)))
                .unwrap()
                .pose
        };
        let m0 = measure(&datum);
        let ms = measure(&station);
        let e = d.pose_errors(&ms, &d.commanded_pose(&m0, c0, c)).to_array();
        for k in 0..6 {
            sum2[k] += e[k] * e[k];
        }
    }
    let mc: Vec<f64> = sum2.iter().map(|s| 2.0 * (s / n as f64).sqrt()).collect();
    println!("error U (k = 2) at 50 mm: analytic {:.4?}", u.to_array());
    println!(
        "                     legs only {:.4?}",
        legs_only.to_array()
    );
    println!("                  MC (n = {n}) {mc:.4?}");
    for (k, (a, b)) in u.to_array().iter().zip(&mc).enumerate() {
        assert!((b / a - 1.0).abs() < 0.05, "{k}: MC {b} vs {a}");
    }
}
