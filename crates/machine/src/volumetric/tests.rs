//! The spec's checks (`docs/spec/machine-physics.md`, "Kind volumetric"), with a forward model
//! written here from the spec's formulas (not the analysis' design rows).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::grid::{self, Grid};
use super::model::{Observation, Place, VolumetricEffect};
use super::study::{analyse, Frame, VolumetricStudyOptions};
use super::{Diagonal, DiagonalSign};

/// A true error field: e(P) µm from P mm.
type Field = dyn Fn([f64; 3]) -> [f64; 3];

fn frame(min: [f64; 3], max: [f64; 3], counts: [usize; 3]) -> Frame {
    Frame {
        min_mm: min,
        max_mm: max,
        grid: Grid {
            counts,
            origin_mm: min,
            spacing_mm: [0, 1, 2].map(|k| (max[k] - min[k]) / (counts[k] - 1) as f64),
        },
        cte_ppm_per_k: 11.5,
    }
}

/// Body-diagonal readings Dr(d) = u·[e(P0 + d u) − e(P0)], `runs` runs each way, 10 targets.
fn body_readings(
    f: &Frame,
    e: &Field,
    runs: i64,
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Observation> {
    let mut out = Vec::new();
    let normal = Normal::new(0.0, noise.max(1e-300)).unwrap();
    for sign in DiagonalSign::ALL {
        let d = Diagonal::new(sign, f.min_mm, f.max_mm);
        let e0 = e(d.p0_mm);
        for run in 1..=runs {
            for dir in [1i8, -1] {
                for t in 0..=10 {
                    let t = if dir > 0 { t } else { 10 - t };
                    let dist = d.length_mm * t as f64 / 10.0;
                    let ep = e(d.point_at(dist));
                    let v: f64 = (0..3).map(|k| d.u[k] * (ep[k] - e0[k])).sum();
                    out.push(Observation {
                        diagonal: sign,
                        run,
                        direction: dir,
                        place: Place::Body { d_mm: dist },
                        hours: 0.0,
                        deviation_um: v + if noise > 0.0 { normal.sample(rng) } else { 0.0 },
                        bar: false,
                    });
                }
            }
        }
    }
    out
}

/// Step-diagonal readings r = u·[e(P) − e(P0)] + 10³ β·(P − P0) (β in rad), sub-moves X, Y, Z.
fn step_readings(
    f: &Frame,
    e: &Field,
    n: usize,
    beta_rad: &[[f64; 3]; 4],
    runs: i64,
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Observation> {
    let normal = Normal::new(0.0, noise.max(1e-300)).unwrap();
    let mut out = Vec::new();
    for sign in DiagonalSign::ALL {
        let d = Diagonal::new(sign, f.min_mm, f.max_mm);
        let e0 = e(d.p0_mm);
        let end = d.point_at(d.length_mm);
        for run in 1..=runs {
            let mut p = d.p0_mm;
            let mut push = |p: [f64; 3], step: i64, sub: Option<usize>, rng: &mut ChaCha8Rng| {
                let ep = e(p);
                let mut v: f64 = (0..3).map(|k| d.u[k] * (ep[k] - e0[k])).sum();
                v += 1e3
                    * (0..3)
                        .map(|k| beta_rad[sign.index()][k] * (p[k] - d.p0_mm[k]))
                        .sum::<f64>();
                out.push(Observation {
                    diagonal: sign,
                    run,
                    direction: 1,
                    place: Place::Step {
                        position_mm: p,
                        step,
                        submove: sub,
                    },
                    hours: 0.0,
                    deviation_um: v + if noise > 0.0 { normal.sample(rng) } else { 0.0 },
                    bar: false,
                });
            };
            push(p, 0, None, rng);
            for s in 1..=n {
                for j in 0..3 {
                    p[j] = d.p0_mm[j] + (end[j] - d.p0_mm[j]) * s as f64 / n as f64;
                    push(p, s as i64, Some(j), rng);
                }
            }
        }
    }
    out
}

#[test]
fn table_numbering_follows_the_spec() {
    let g = Grid {
        counts: [3, 4, 3],
        origin_mm: [0.0; 3],
        spacing_mm: [1.0; 3],
    };
    assert_eq!(g.line(1, 2, 1), Some(4));
    assert_eq!(g.line(1, 1, 2), Some(13));
    assert_eq!(g.line(3, 4, 3), Some(36));
    assert_eq!(g.node(13), Some([1, 1, 2]));
    assert_eq!(g.node(34), Some([1, 4, 3]));
    assert_eq!(g.line(4, 1, 1), None);
    for l in 1..=36 {
        let [i, j, k] = g.node(l).unwrap();
        assert_eq!(g.line(i, j, k), Some(l));
    }
}

#[test]
fn trilinear_reads_vertices_cell_centres_and_linear_fields() {
    let g = Grid {
        counts: [3, 4, 3],
        origin_mm: [0.0, 0.0, -500.0],
        spacing_mm: [500.0, 200.0, 250.0],
    };
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let values: Vec<f64> = (0..36).map(|_| rng.gen_range(-5.0..5.0)).collect();
    for (l, p) in g.positions().iter().enumerate() {
        assert!((g.trilinear(&values, *p).unwrap() - values[l]).abs() < 1e-12);
    }
    // Centre of the cell with lower node (2, 3, 1): the mean of its 8 vertices.
    let lower = [2, 3, 1];
    let centre = [0, 1, 2].map(|a| g.position(lower)[a] + g.spacing_mm[a] / 2.0);
    let mut mean = 0.0;
    for c in 0..2 {
        for b in 0..2 {
            for a in 0..2 {
                mean += values[g.line(lower[0] + a, lower[1] + b, lower[2] + c).unwrap() - 1] / 8.0;
            }
        }
    }
    assert!((g.trilinear(&values, centre).unwrap() - mean).abs() < 1e-12);
    let lin = |p: [f64; 3]| 0.3 + 0.01 * p[0] - 0.02 * p[1] + 0.005 * p[2];
    let field: Vec<f64> = g.positions().into_iter().map(lin).collect();
    for _ in 0..50 {
        let p = [
            rng.gen_range(0.0..1000.0),
            rng.gen_range(0.0..600.0),
            rng.gen_range(-500.0..0.0),
        ];
        assert!((g.trilinear(&field, p).unwrap() - lin(p)).abs() < 1e-9);
    }
    assert_eq!(g.trilinear(&values, [1000.1, 0.0, -500.0]), None);
}

#[test]
fn scale_errors_that_cancel_on_the_diagonals_are_14_um_and_invisible_to_them() {
    let f = frame([0.0; 3], [1000.0; 3], [3, 3, 3]);
    let e = |p: [f64; 3]| [10e-3 * p[0], -10e-3 * p[1], 0.0];
    // Truth figures.
    let errors: Vec<[f64; 3]> = f.grid.positions().into_iter().map(e).collect();
    let positioning = [0, 1, 2].map(|k| {
        (0..=10)
            .map(|i| e([0, 1, 2].map(|a| if a == k { i as f64 * 100.0 } else { 0.0 }))[k])
            .collect::<Vec<_>>()
    });
    assert!((grid::v1_um(&positioning) - 14.142).abs() < 1e-3);
    assert!((grid::v2_um(&errors) - 14.142).abs() < 1e-3);
    assert!((grid::v3_um(&errors) - 14.142).abs() < 1e-3);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let obs = body_readings(&f, &e, 2, 0.0, &mut rng);
    let s = analyse(obs, &f, &VolumetricStudyOptions::default()).unwrap();
    assert_eq!(s.curves.len(), 4);
    for c in &s.curves {
        assert!(c.e_um.unwrap().abs() < 0.005, "{:?}", c.e_um);
    }
    assert!(s.v_diag.unwrap().value_um < 0.005);
    assert!(s
        .invisible
        .iter()
        .any(|l| l.contains("per-axis scale differences are invisible")));
    assert!(s
        .invisible
        .iter()
        .any(|l| l.contains("4 of 9 linear terms")));
    assert!(!s.figures_identifiable);
    // The slopes of Dx(x), Dy(y) are not seen; the mean scale is, and is 0.
    assert!(!s.slopes[0][0].identifiable && !s.slopes[1][1].identifiable);
    assert!(s.mean_scale.identifiable && s.mean_scale.value.abs() < 1e-6);
}

#[test]
fn squareness_of_20_urad_gives_v2_v3_20_and_v_diag_11_55() {
    let f = frame([0.0; 3], [1000.0; 3], [3, 3, 3]);
    let e = |p: [f64; 3]| [20e-3 * p[1], 0.0, 0.0];
    let errors: Vec<[f64; 3]> = f.grid.positions().into_iter().map(e).collect();
    assert!((grid::v2_um(&errors) - 20.0).abs() < 1e-9);
    assert!((grid::v3_um(&errors) - 20.0).abs() < 1e-9);
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let s = analyse(
        body_readings(&f, &e, 2, 0.0, &mut rng),
        &f,
        &VolumetricStudyOptions::default(),
    )
    .unwrap();
    let v = s.v_diag.unwrap().value_um;
    assert!((v - 11.547).abs() < 0.005, "{v}");
    assert!((s.squareness[0].value - 20.0).abs() < 1e-6 && s.squareness[0].identifiable);
    assert!(s.squareness[1].value.abs() < 1e-6 && s.squareness[2].value.abs() < 1e-6);
}

/// Random smooth truth: scales, squareness and cubic shapes, zero at the min corner.
fn random_field(
    rng: &mut ChaCha8Rng,
    min: [f64; 3],
    len: [f64; 3],
) -> impl Fn([f64; 3]) -> [f64; 3] {
    let mut c = [[[0.0; 3]; 3]; 3]; // [j][k][power-1]
    for value in c.iter_mut().flatten().flatten() {
        *value = rng.gen_range(-4.0..4.0);
    }
    move |p: [f64; 3]| {
        let mut e = [0.0; 3];
        for j in 0..3 {
            let t = (p[j] - min[j]) / len[j];
            for k in 0..3 {
                e[k] += c[j][k][0] * t + c[j][k][1] * t * t + c[j][k][2] * (3.0 * t).sin();
            }
        }
        e
    }
}

fn ls_slope_of(e: &Field, k: usize, j: usize, min: [f64; 3], len: [f64; 3], n: usize) -> f64 {
    let q: Vec<f64> = (0..=n)
        .map(|i| min[j] + len[j] * i as f64 / n as f64)
        .collect();
    let v: Vec<f64> = q
        .iter()
        .map(|x| {
            let mut p = min;
            p[j] = *x;
            e(p)[k]
        })
        .collect();
    super::solve::ls_slope(&q, &v)
}

/// β ⟂ u of 50 µrad in a random direction.
fn pointing(rng: &mut ChaCha8Rng, d: &Diagonal) -> [f64; 3] {
    let [a, b] = d.pointing_basis();
    let phi: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
    [0, 1, 2].map(|k| 50e-6 * (phi.cos() * a[k] + phi.sin() * b[k]))
}

#[test]
fn the_joint_fit_finds_squareness_under_pointing_where_the_naive_inversion_scatters() {
    let (min, max) = ([0.0, 0.0, -500.0], [1000.0, 600.0, 0.0]);
    let len = [1000.0, 600.0, 500.0];
    let f = frame(min, max, [3, 4, 3]);
    let n = 10;
    let mut within = 0;
    let (mut joint_err, mut naive_err, mut u_sum) = (0.0_f64, 0.0_f64, 0.0);
    for draw in 0..20 {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + draw);
        let e = random_field(&mut rng, min, len);
        let beta = DiagonalSign::ALL.map(|s| pointing(&mut rng, &Diagonal::new(s, min, max)));
        let obs = step_readings(&f, &e, n, &beta, 2, 0.05, &mut rng);
        let s = analyse(
            obs,
            &f,
            &VolumetricStudyOptions {
                forward_steps: 0,
                ..Default::default()
            },
        )
        .unwrap();
        let truth = [(0, 1), (1, 2), (2, 0)]
            .map(|(a, b)| ls_slope_of(&e, b, a, min, len, n) + ls_slope_of(&e, a, b, min, len, n));
        let naive = s.naive.as_ref().unwrap();
        for (i, (q, t)) in s.squareness.iter().zip(truth).enumerate() {
            assert!(q.identifiable);
            let err = (q.value - t).abs();
            within += usize::from(err <= q.u_k2);
            joint_err = joint_err.max(err);
            naive_err = naive_err.max((naive.squareness_urad[i] - t).abs());
            u_sum += q.u_k2 / 60.0;
        }
        // Pointing confounds the per-axis scales: five slope combinations are lost.
        assert!(!s.slopes[0][0].identifiable);
        assert!(s.invisible.iter().any(|l| l.contains("unknown pointing")));
        // Pointing adds straight lines only: every function's shape stays seen, with U.
        let shapes = s.fit.shapes();
        assert!(shapes
            .iter()
            .flatten()
            .flatten()
            .all(|(_, q)| q.identifiable && q.u_k2.is_finite()));
    }
    eprintln!("joint max |err| {joint_err:.3} µrad, mean U {u_sum:.3} µrad, naive max |err| {naive_err:.2} µrad, within U {within}/60");
    // U is k = 2 (95 %): if it is right, 60 draws fall within it 51 times or more with
    // probability 0.999 (binomial); the naive inversion misses by far more than U.
    assert!(within >= 51, "{within} of 60 within U");
    assert!(naive_err > 10.0 * u_sum, "naive {naive_err} vs U {u_sum}");
}

#[test]
fn without_pointing_step_diagonals_see_all_nine_slopes_and_the_fourth_pattern_is_zero() {
    let (min, max) = ([0.0; 3], [800.0, 600.0, 400.0]);
    let f = frame(min, max, [3, 3, 3]);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let e = random_field(&mut rng, min, [800.0, 600.0, 400.0]);
    let obs = step_readings(&f, &e, 8, &[[0.0; 3]; 4], 1, 0.0, &mut rng);
    let opts = VolumetricStudyOptions {
        effects: vec![],
        forward_steps: 0,
        ..Default::default()
    };
    let s = analyse(obs, &f, &opts).unwrap();
    assert!(s.fit.lost.is_empty(), "{:?}", s.fit.lost);
    assert!(s.slopes.iter().flatten().all(|q| q.identifiable));
    let (data, _) = s.fourth_rms_um.unwrap();
    assert!(data < 1e-9, "{data}");
    // The naive inversion and the joint fit agree with the truth at every node.
    for j in 0..3 {
        for k in 0..3 {
            for (q, v) in s.fit.functions()[j][k].iter() {
                let mut p = min;
                p[j] = *q;
                assert!((v.value - e(p)[k]).abs() < 1e-6, "D{k}({j}) at {q}");
            }
        }
    }
}

#[test]
fn pointing_shows_in_the_fourth_pattern_and_the_loop_names_it() {
    let (min, max) = ([0.0; 3], [1000.0, 600.0, 500.0]);
    let f = frame(min, max, [3, 3, 3]);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let e = random_field(&mut rng, min, [1000.0, 600.0, 500.0]);
    let beta = DiagonalSign::ALL.map(|s| pointing(&mut rng, &Diagonal::new(s, min, max)));
    let obs = step_readings(&f, &e, 10, &beta, 2, 0.05, &mut rng);
    let opts = VolumetricStudyOptions {
        effects: vec![],
        forward_steps: 1,
        ..Default::default()
    };
    let s = analyse(obs, &f, &opts).unwrap();
    assert_eq!(s.diagnosis.proposal, Some(VolumetricEffect::Pointing));
    let best = &s.diagnosis.candidates[0];
    assert!(best.rms_after_um < 0.5 * s.diagnosis.base_rms_um);
}
