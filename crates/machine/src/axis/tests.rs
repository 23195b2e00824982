use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The patent's three lines of an X axis: line 1 reads Δx, Δy, Δz at p1, line 2 Δx, Δy at
/// p2, line 3 Δx at p3.
const PATTERN: [(u32, Channel); 6] = [
    (1, Channel::Dx),
    (1, Channel::Dy),
    (1, Channel::Dz),
    (2, Channel::Dx),
    (2, Channel::Dy),
    (3, Channel::Dx),
];

const SPEC_POINTS: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [0.0, 0.0, 100.0], [0.0, 100.0, 100.0]];

/// The X-axis pattern carried to `axis` by the cyclic permutation x → y → z → x (which keeps
/// handedness): for Y, an X-axis point (a, b, c) becomes (c, a, b) and dx becomes dy.
fn permute(axis: Axis, p: [f64; 3], ch: Channel) -> ([f64; 3], Channel) {
    let shift = axis.index();
    let mut q = [0.0; 3];
    for k in 0..3 {
        q[(k + shift) % 3] = p[k];
    }
    let c = match (ch.index() + shift) % 3 {
        0 => Channel::Dx,
        1 => Channel::Dy,
        _ => Channel::Dz,
    };
    (q, c)
}

fn readings(
    axis: Axis,
    points: [[f64; 3]; 3],
    truth: SixErrors,
    sigma_um: f64,
    noise: &mut dyn FnMut() -> f64,
) -> Vec<AxisReading> {
    PATTERN
        .iter()
        .map(|&(line, ch)| {
            let (p, c) = permute(axis, points[line as usize - 1], ch);
            AxisReading {
                line,
                channel: c,
                reflector_mm: p,
                deviation_um: truth.displacement_um(p)[c.index()] + noise(),
                sigma_um,
            }
        })
        .collect()
}

fn truth() -> SixErrors {
    SixErrors::from_array([3.2, -1.7, 0.8, 12.5, -23.0, 7.75])
}

#[test]
fn the_spec_check_analytic() {
    let r = readings(Axis::X, SPEC_POINTS, truth(), 0.1, &mut || 0.0);
    let t = solve_target(Axis::X, &r, &Fixture::default()).unwrap();
    assert_eq!(t.rank, 6);
    let u = t.u.to_array();
    for (k, &v) in u.iter().enumerate().take(3) {
        assert!((v - 0.1).abs() < 1e-12, "σ(δ{k}) = {v}");
    }
    for &v in &u[3..] {
        assert!((v - 0.1 * 2f64.sqrt() * 10.0).abs() < 1e-9, "σ(ε) = {v}");
    }
    println!("σ(δ) analytic {:.4} {:.4} {:.4} µm", u[0], u[1], u[2]);
    println!("σ(ε) analytic {:.4} {:.4} {:.4} µrad", u[3], u[4], u[5]);
}

#[test]
fn the_spec_check_monte_carlo() {
    let n = 20_000;
    let mut rng = ChaCha8Rng::seed_from_u64(29_002);
    let normal = Normal::new(0.0, 0.1).unwrap();
    let mut sum = [0.0; 6];
    let mut sum2 = [0.0; 6];
    let fixture = Fixture::default();
    let t0 = truth().to_array();
    for _ in 0..n {
        let r = readings(Axis::X, SPEC_POINTS, truth(), 0.1, &mut || {
            normal.sample(&mut rng)
        });
        let e = solve_target(Axis::X, &r, &fixture)
            .unwrap()
            .errors
            .to_array();
        for k in 0..6 {
            let d = e[k] - t0[k];
            sum[k] += d;
            sum2[k] += d * d;
        }
    }
    let sd: Vec<f64> = (0..6)
        .map(|k| ((sum2[k] - sum[k] * sum[k] / n as f64) / (n as f64 - 1.0)).sqrt())
        .collect();
    println!("σ MC (n = {n}): {sd:.4?}");
    for (k, &v) in sd.iter().enumerate() {
        let expected = if k < 3 { 0.1 } else { 2f64.sqrt() };
        assert!((v / expected - 1.0).abs() < 0.03, "{k}: {v} vs {expected}");
    }
}

#[test]
fn known_errors_are_recovered_on_every_axis() {
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        let r = readings(axis, SPEC_POINTS, truth(), 0.1, &mut || 0.0);
        let t = solve_target(axis, &r, &Fixture::default()).unwrap();
        assert_eq!(t.rank, 6, "{axis}");
        assert!(t.lost.is_empty());
        for (k, (a, b)) in t
            .errors
            .to_array()
            .iter()
            .zip(truth().to_array())
            .enumerate()
        {
            assert!((a - b).abs() < 1e-9, "{axis} {}: {a} vs {b}", t.names[k]);
        }
        assert_eq!(t.names[0], format!("EX{axis}"));
        assert!(t.residuals_um.iter().all(|r| r.abs() < 1e-9));
    }
}

#[test]
fn redundant_readings_are_least_squares_with_residuals() {
    let mut r = readings(Axis::X, SPEC_POINTS, truth(), 0.1, &mut || 0.0);
    // A fourth line at (0, 100, 0) reading Δx, Δy, Δz, one reading off by 0.3 µm.
    for (c, off) in [(Channel::Dx, 0.3), (Channel::Dy, 0.0), (Channel::Dz, 0.0)] {
        let p = [0.0, 100.0, 0.0];
        r.push(AxisReading {
            line: 4,
            channel: c,
            reflector_mm: p,
            deviation_um: truth().displacement_um(p)[c.index()] + off,
            sigma_um: 0.1,
        });
    }
    let t = solve_target(Axis::X, &r, &Fixture::default()).unwrap();
    assert_eq!(t.rank, 6);
    assert_eq!(t.solution.dof, 3);
    assert!(t.residuals_um.iter().any(|r| r.abs() > 0.01));
    // Clean readings: exact recovery, zero residuals.
    let clean: Vec<AxisReading> = r
        .iter()
        .map(|x| AxisReading {
            deviation_um: truth().displacement_um(x.reflector_mm)[x.channel.index()],
            ..*x
        })
        .collect();
    let t = solve_target(Axis::X, &clean, &Fixture::default()).unwrap();
    for (a, b) in t.errors.to_array().iter().zip(truth().to_array()) {
        assert!((a - b).abs() < 1e-9);
    }
    assert!(t.residuals_um.iter().all(|r| r.abs() < 1e-9));
}

#[test]
fn equal_heights_lose_the_roll() {
    // Lines 1 and 2 at one height (z₁ = z₂ = 0), the three Δx points still not collinear.
    let points = [[0.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]];
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        let r = readings(axis, points, truth(), 0.1, &mut || 0.0);
        let t = solve_target(axis, &r, &Fixture::default()).unwrap();
        assert_eq!(t.rank, 5);
        let roll = ["EAX", "EBY", "ECZ"][axis.index()];
        assert_eq!(t.lost.len(), 1);
        assert_eq!(t.lost[0].single(), Some(roll), "{axis}: {}", t.lost[0]);
        assert!(t.errors.to_array()[3 + axis.index()].is_nan());
        assert!(t.u.to_array()[3 + axis.index()].is_nan());
        // The five others are still recovered.
        for k in (0..6).filter(|&k| k != 3 + axis.index()) {
            assert!((t.errors.to_array()[k] - truth().to_array()[k]).abs() < 1e-9);
        }
    }
}

#[test]
fn equal_heights_away_from_the_report_point_lose_straightness_with_the_roll() {
    // z₁ = z₂ = 100 mm: Δy₁ and Δy₂ both read δy − 0.1 εx, so EYX at the report point is lost
    // with EAX: the lost direction is EYX + 10 EAX (µm per µrad: 100 mm lever).
    let points = [[0.0, 0.0, 100.0], [0.0, 100.0, 100.0], [0.0, 0.0, 0.0]];
    let t = solve_target(
        Axis::X,
        &readings(Axis::X, points, truth(), 0.1, &mut || 0.0),
        &Fixture::default(),
    )
    .unwrap();
    assert_eq!(t.rank, 5);
    assert_eq!(t.lost[0].to_string(), "EYX + 10 EAX");
    assert_eq!(t.solution.undetermined_names(), vec!["EYX", "EAX"]);
    // Reported at the lines' height instead, only the roll is lost.
    let high = Fixture {
        report_point_mm: [0.0, 0.0, 100.0],
        u_um: 0.0,
    };
    let t = solve_target(
        Axis::X,
        &readings(Axis::X, points, truth(), 0.1, &mut || 0.0),
        &high,
    )
    .unwrap();
    assert_eq!(t.lost[0].to_string(), "EAX");
}

#[test]
fn collinear_points_lose_the_named_error() {
    // All on the z axis: ECX (yaw) has no lever.
    let on_z = [[0.0, 0.0, 0.0], [0.0, 0.0, 100.0], [0.0, 0.0, 200.0]];
    let t = solve_target(
        Axis::X,
        &readings(Axis::X, on_z, truth(), 0.1, &mut || 0.0),
        &Fixture::default(),
    )
    .unwrap();
    assert_eq!(t.rank, 5);
    assert_eq!(t.lost[0].to_string(), "ECX");
    // On the diagonal y = z: only EBX − ECX is seen, EBX + ECX is lost.
    let diag = [[0.0, 0.0, 0.0], [0.0, 50.0, 50.0], [0.0, 100.0, 100.0]];
    let t = solve_target(
        Axis::X,
        &readings(Axis::X, diag, truth(), 0.1, &mut || 0.0),
        &Fixture::default(),
    )
    .unwrap();
    assert_eq!(t.rank, 5);
    assert_eq!(t.lost[0].to_string(), "EBX + ECX");
    assert_eq!(&t.solution.undetermined_names(), &["EBX", "ECX"]);
}

#[test]
fn the_fixture_enters_only_through_epsilon() {
    let fixture = Fixture {
        report_point_mm: [0.0; 3],
        u_um: 5.0,
    };
    // ε = 0: the fixture adds nothing.
    let zero_eps = SixErrors::from_array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
    let t = solve_target(
        Axis::X,
        &readings(Axis::X, SPEC_POINTS, zero_eps, 0.1, &mut || 0.0),
        &fixture,
    )
    .unwrap();
    assert!((t.u.dx_um - 0.1).abs() < 1e-12);
    // 20 µrad and 5 µm: 0.1 nm per reading, nothing visible at 0.1 µm.
    let t = solve_target(
        Axis::X,
        &readings(Axis::X, SPEC_POINTS, truth(), 0.1, &mut || 0.0),
        &fixture,
    )
    .unwrap();
    assert!((t.u.dx_um / 0.1 - 1.0).abs() < 1e-4);
}

#[test]
fn the_fixture_propagation_matches_monte_carlo() {
    // Exaggerated so that it shows: ε of a few mrad, u = 0.3 mm per coordinate.
    let big = SixErrors::from_array([1.0, -2.0, 0.5, 2000.0, -1500.0, 2500.0]);
    let fixture = Fixture {
        report_point_mm: [0.0; 3],
        u_um: 300.0,
    };
    let sigma = 0.1;
    let nominal = readings(Axis::X, SPEC_POINTS, big, sigma, &mut || 0.0);
    let analytic = solve_target(Axis::X, &nominal, &fixture)
        .unwrap()
        .u
        .to_array();
    let n = 20_000;
    let mut rng = ChaCha8Rng::seed_from_u64(29_003);
    let read = Normal::new(0.0, sigma).unwrap();
    let fix = Normal::new(0.0, 0.3).unwrap(); // mm
    let mut sum2 = [0.0; 6];
    let t0 = big.to_array();
    for _ in 0..n {
        let dp: Vec<[f64; 3]> = (0..3)
            .map(|_| [0.0; 3].map(|_| fix.sample(&mut rng)))
            .collect();
        let r: Vec<AxisReading> = nominal
            .iter()
            .map(|x| {
                let d = dp[x.line as usize - 1];
                let q = [
                    x.reflector_mm[0] + d[0],
                    x.reflector_mm[1] + d[1],
                    x.reflector_mm[2] + d[2],
                ];
                AxisReading {
                    deviation_um: big.displacement_um(q)[x.channel.index()] + read.sample(&mut rng),
                    ..*x
                }
            })
            .collect();
        let e = solve_target(Axis::X, &r, &Fixture::default())
            .unwrap()
            .errors
            .to_array();
        for k in 0..6 {
            sum2[k] += (e[k] - t0[k]).powi(2);
        }
    }
    let sd: Vec<f64> = sum2.iter().map(|s| (s / n as f64).sqrt()).collect();
    println!("fixture: analytic {analytic:.4?}, MC (n = {n}) {sd:.4?}");
    for k in 0..6 {
        assert!(
            (sd[k] / analytic[k] - 1.0).abs() < 0.03,
            "{k}: {} vs {}",
            sd[k],
            analytic[k]
        );
    }
    // And it is larger than the readings' σ alone.
    assert!(analytic[0] > 0.11);
}

#[test]
fn the_triplet_with_least_noise_amplification_is_chosen() {
    let lines = vec![
        LineCandidates {
            line: 1,
            channels: vec![Channel::Dx, Channel::Dy, Channel::Dz],
            candidates_mm: vec![[0.0, 0.0, 0.0]],
        },
        LineCandidates {
            line: 2,
            channels: vec![Channel::Dx, Channel::Dy],
            candidates_mm: vec![[0.0, 0.0, 0.0], [0.0, 0.0, 50.0], [0.0, 0.0, 100.0]],
        },
        LineCandidates {
            line: 3,
            channels: vec![Channel::Dx],
            candidates_mm: vec![[0.0, 50.0, 100.0], [0.0, 100.0, 100.0]],
        },
    ];
    let c = choose_points(&lines).unwrap();
    assert_eq!(c.all.len(), 6);
    for comb in &c.all {
        println!("choice {:?}: trace {:?}", comb.choice, comb.trace);
    }
    // z2 = z1 = 0: rank 5, no criterion.
    assert!(c.all[0].trace.is_none() && c.all[1].trace.is_none());
    let best = c.best.unwrap();
    assert_eq!(best.choice, vec![0, 2, 1]);
    // At the spec's points with unit σ: 3 · 1 + 3 · 200 (µrad/µm)² = 603.
    assert!(
        (best.trace.unwrap() - 603.0).abs() < 1e-6,
        "{:?}",
        best.trace
    );
}

#[test]
fn bad_input_is_refused() {
    assert_eq!(
        solve_target(Axis::X, &[], &Fixture::default()),
        Err(AxisError::NoReadings)
    );
    let mut r = readings(Axis::X, SPEC_POINTS, truth(), 0.1, &mut || 0.0);
    r[0].sigma_um = -1.0;
    assert!(matches!(
        solve_target(Axis::X, &r, &Fixture::default()),
        Err(AxisError::Linear(LinearError::BadSigma { row: 0, .. }))
    ));
    r[0].sigma_um = 0.1;
    r[1].reflector_mm[0] = f64::NAN;
    assert!(matches!(
        solve_target(Axis::X, &r, &Fixture::default()),
        Err(AxisError::BadInput(_))
    ));
}
