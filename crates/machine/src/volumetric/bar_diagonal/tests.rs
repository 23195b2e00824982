//! The bars as the diagonal instrument, simulated: a machine with rigid-body errors of the
//! typical sizes (`machine-physics.md`), a body diagonal of a 1000 × 600 × 500 mm workspace read
//! by one bar in ten re-seated segments, each reading the *exact* centre distance
//! |P + 10⁻³ e(P) − S| (second-order terms included), with the socket off the line by up to
//! 0.1 mm, the bar's scale off by its calibration's u, a slow residue of the thermal
//! compensation and reading noise; against the laser's quantity Dr = u · [e(P) − e(P₀)].

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use super::*;

const L_MM: [f64; 3] = [1000.0, 600.0, 500.0];
/// Steps along the diagonal, and per segment (consecutive segments share one step: two targets).
const STEPS: usize = 90;
const SEGMENT_STEPS: usize = 10;
const BAR_MM: f64 = 300.0;
const NOISE_UM: f64 = 0.03;
const SCALE_U_PPM: f64 = 0.5;
const SOCKET_OFF_LINE_MM: f64 = 0.1;

/// e(P) µm: per axis a slope (scale, straightness with squareness) and a smooth shape, each
/// D_k(j) zero at the min corner.
struct Machine {
    slope: [[f64; 3]; 3],
    wave: [[(f64, f64); 3]; 3],
}

impl Machine {
    fn draw(rng: &mut impl Rng) -> Machine {
        Machine {
            slope: std::array::from_fn(|_| std::array::from_fn(|_| rng.gen_range(-0.015..0.015))),
            wave: std::array::from_fn(|_| {
                std::array::from_fn(|_| (rng.gen_range(-2.0..2.0), rng.gen_range(0.5..2.0)))
            }),
        }
    }

    fn error_um(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| {
            (0..3)
                .map(|j| {
                    let (a, cycles) = self.wave[k][j];
                    let s = p[j] / L_MM[j];
                    self.slope[k][j] * p[j] + a * (std::f64::consts::TAU * cycles * s).sin()
                })
                .sum()
        })
    }
}

fn add(a: [f64; 3], b: [f64; 3], f: f64) -> [f64; 3] {
    std::array::from_fn(|k| a[k] + f * b[k])
}

fn norm(a: [f64; 3]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// One draw: the readings, the true Dr at every target, and the budget.
fn simulate(seed: u64) -> (Vec<BarDiagonalReading>, Vec<f64>, BarDiagonalBudget) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let machine = Machine::draw(&mut rng);
    let d_mm = norm(L_MM);
    let u = L_MM.map(|l| l / d_mm);
    let step_mm = d_mm / STEPS as f64;
    let noise = Normal::new(0.0, NOISE_UM).unwrap();
    let scale = Normal::new(0.0, SCALE_U_PPM).unwrap().sample(&mut rng) * 1e-6;
    let e0 = machine.error_um([0.0; 3]);
    let truth: Vec<f64> = (0..=STEPS)
        .map(|n| {
            let e = machine.error_um(u.map(|c| c * n as f64 * step_mm));
            (0..3).map(|k| u[k] * (e[k] - e0[k])).sum()
        })
        .collect();
    // Two directions across u, for the socket's lateral offset.
    let a = {
        let c = [u[1], -u[0], 0.0];
        c.map(|x| x / norm(c))
    };
    let b = [
        u[1] * a[2] - u[2] * a[1],
        u[2] * a[0] - u[0] * a[2],
        u[0] * a[1] - u[1] * a[0],
    ];
    let mut readings = Vec::new();
    let mut segment = 0;
    let mut first = 0;
    while first < STEPS {
        let start_mm = first as f64 * step_mm;
        // The socket: BAR_MM behind the segment's first target on the line, placed to ±1 mm
        // along it and 0.1 mm across.
        let along = rng.gen_range(-1.0..1.0);
        let (ha, hb) = (
            rng.gen_range(-SOCKET_OFF_LINE_MM..SOCKET_OFF_LINE_MM) / 2f64.sqrt(),
            rng.gen_range(-SOCKET_OFF_LINE_MM..SOCKET_OFF_LINE_MM) / 2f64.sqrt(),
        );
        let nominal = u.map(|c| c * (start_mm - BAR_MM));
        let socket = add(add(add(nominal, u, along), a, ha), b, hb);
        // The residue of the thermal compensation: a slow walk over the segment.
        let mut residue = 0.0;
        let last = (first + SEGMENT_STEPS).min(STEPS);
        for n in first..=last {
            let p_cmd = u.map(|c| c * n as f64 * step_mm);
            let p = add(p_cmd, machine.error_um(p_cmd), 1e-3);
            let true_mm = norm(add(p, socket, -1.0));
            // The bar reads its length through its own scale error.
            let read_mm = true_mm * (1.0 + scale);
            residue += rng.gen_range(-0.005..0.005);
            let commanded_mm = BAR_MM + (n - first) as f64 * step_mm;
            readings.push(BarDiagonalReading {
                segment,
                target_mm: n as f64 * step_mm,
                reading_um: 1e3 * (read_mm - commanded_mm) + residue + noise.sample(&mut rng),
                u_um: (NOISE_UM * NOISE_UM + 0.01f64.powi(2)).sqrt(),
            });
        }
        segment += 1;
        first = last - 1;
        if last == STEPS {
            break;
        }
    }
    let budget = BarDiagonalBudget {
        scale_u_ppm: SCALE_U_PPM,
        max_misalignment_rad: SOCKET_OFF_LINE_MM / BAR_MM,
    };
    (readings, truth, budget)
}

#[test]
fn a_bar_in_re_seated_segments_reads_the_body_diagonal_within_u() {
    let (mut inside, mut total, mut worst, mut z2) = (0, 0, 0.0f64, 0.0);
    let mut u_end = Vec::new();
    for seed in 1..=20 {
        let (readings, truth, budget) = simulate(seed);
        let s = stitch(&readings, budget).unwrap();
        assert_eq!(s.target_mm.len(), STEPS + 1);
        assert!(s.segment_constant_um.len() >= 10);
        for (j, t) in truth.iter().enumerate().skip(1) {
            let r = (s.dr_um[j] - t).abs() / s.u_k2_um[j];
            inside += usize::from(r <= 1.0);
            worst = worst.max(r);
            z2 += (2.0 * r).powi(2);
            total += 1;
        }
        u_end.push(*s.u_k2_um.last().unwrap());
    }
    let rms_z = (z2 / total as f64).sqrt();
    eprintln!(
        "bar diagonal: {inside}/{total} targets within U, worst {worst:.2} U, RMS z {rms_z:.2}, \
         U at the far corner {:.3}-{:.3} µm",
        u_end.iter().copied().fold(f64::INFINITY, f64::min),
        u_end.iter().copied().fold(0.0, f64::max)
    );
    assert!(inside as f64 >= 0.9 * total as f64, "{inside}/{total}");
    assert!(worst <= 2.0, "worst {worst}");
    // U neither too small nor inflated out of use.
    assert!((0.6..=1.4).contains(&rms_z), "RMS z {rms_z}");
    // At the far corner the bar's scale dominates: 2 · 0.5 ppm · 1269 mm = 1.27 µm.
    let scale_k2 = 2.0 * SCALE_U_PPM * 1e-3 * norm(L_MM);
    assert!(
        u_end.iter().all(|u| *u >= scale_k2 && *u < 1.1 * scale_k2),
        "{u_end:?}"
    );
}

#[test]
fn segments_that_do_not_overlap_are_refused_by_name() {
    let (readings, _, budget) = simulate(1);
    // Drop the targets the first two segments share.
    let shared: Vec<f64> = readings
        .iter()
        .filter(|r| r.segment == 1)
        .map(|r| r.target_mm)
        .take(2)
        .collect();
    let cut: Vec<BarDiagonalReading> = readings
        .into_iter()
        .filter(|r| !shared.contains(&r.target_mm))
        .collect();
    let e = stitch(&cut, budget).unwrap_err();
    assert!(matches!(e, BarDiagonalError::NotChained { .. }), "{e}");
    let m = e.to_string();
    assert!(
        m.contains("segments 1, 2") && m.contains("share no target") && m.contains("(0)"),
        "{m}"
    );
}

#[test]
fn without_a_reading_at_the_start_corner_there_is_no_datum() {
    let (readings, _, budget) = simulate(2);
    let cut: Vec<BarDiagonalReading> = readings.into_iter().filter(|r| r.target_mm > 0.0).collect();
    let e = stitch(&cut, budget).unwrap_err();
    assert!(
        matches!(
            e,
            BarDiagonalError::NoDatum {
                first_segment: 0,
                ..
            }
        ),
        "{e}"
    );
}
