//! The simulator's truth against the spec's worked figures (`docs/spec/machine-physics.md`,
//! "Kind volumetric"), computed by this crate alone; and its random streams.

use super::*;

fn cube(errors: &str, effects: &str) -> VolumetricSimConfig {
    let text = format!(
        "kind = \"volumetric\"\nseed = 5\n[machine]\nmin_mm = [0.0, 0.0, 0.0]\nmax_mm = [1000.0, 1000.0, 1000.0]\n[grid]\ncounts = [3, 3, 3]\n[errors]\n{errors}\n[effects]\n{effects}\n"
    );
    toml::from_str(&text).unwrap()
}

#[test]
fn scale_errors_of_plus_minus_10_um_per_m_give_v1_v2_v3_of_14_14_um() {
    let cfg = cube(
        "scale_um_per_m = [10.0, -10.0, 0.0]\nsquareness_urad = [0.0, 0.0, 0.0]\nshape_um = 0.0",
        "",
    );
    let t = generate_volumetric(&cfg).unwrap().truth;
    for v in [t.v1_um, t.v2_um, t.v3_um] {
        assert!((v - 200f64.sqrt()).abs() < 1e-9, "{v}");
    }
    assert!(t.mean_scale_um_per_m.abs() < 1e-9);
}

#[test]
fn a_squareness_of_20_urad_alone_gives_v2_v3_of_20_um_and_zero_v1() {
    let cfg = cube(
        "scale_um_per_m = [0.0, 0.0, 0.0]\nsquareness_urad = [20.0, 0.0, 0.0]\nshape_um = 0.0",
        "",
    );
    let t = generate_volumetric(&cfg).unwrap().truth;
    assert!((t.v2_um - 20.0).abs() < 1e-9 && (t.v3_um - 20.0).abs() < 1e-9);
    assert!(t.v1_um.abs() < 1e-9);
    assert!((t.squareness_urad[0] - 20.0).abs() < 1e-9);
}

#[test]
fn the_readings_follow_the_seed_and_an_effect_leaves_the_other_draws_alone() {
    let a = generate_volumetric(&cube("", "")).unwrap();
    let b = generate_volumetric(&cube("", "")).unwrap();
    assert_eq!(a.tables, b.tables);
    // Pointing on: the machine (truth stream) is the same, the step readings differ.
    let c = generate_volumetric(&cube("", "pointing_urad = 50.0")).unwrap();
    assert_eq!(a.truth.grid_errors_um, c.truth.grid_errors_um);
    assert_ne!(a.tables.steps, c.tables.steps);
    // Body readings see pointing only through its cosine term, −β²/2 · d: about 1.6 nm at
    // D = 1.7 m and 50 µrad.
    let worst = a
        .tables
        .diagonals
        .iter()
        .zip(&c.tables.diagonals)
        .map(|(x, y)| (x.deviation_um - y.deviation_um).abs())
        .fold(0.0, f64::max);
    assert!(worst > 1e-4 && worst < 0.01, "{worst}");
    let mut cfg = cube("", "");
    cfg.seed = 6;
    let d = generate_volumetric(&cfg).unwrap();
    assert_ne!(a.truth.grid_errors_um, d.truth.grid_errors_um);
}

#[test]
fn a_retroreflector_layout_is_never_written_for_step_diagonals() {
    let m = generate_volumetric(&cube("", "")).unwrap().manifest;
    assert_eq!(m.laser.unwrap().target, LaserTarget::FlatMirror);
    assert_eq!(m.grid.spacing_mm, [500.0, 500.0, 500.0]);
}

#[test]
fn a_bar_on_a_perfect_machine_reads_its_travel_short_by_the_socket_s_cosine_only() {
    // No machine error, no noise, no residue, the bar's scale exact: within a segment the
    // centre distance is √((L₀ + x)² + h²) (the machine at T0), so each reading less the
    // segment's first is x less a shortfall of at most h²/(2 L₀) · x/(L₀ + x) ≤ θ²/2 · x.
    let mut cfg = cube(
        "scale_um_per_m = [0.0, 0.0, 0.0]\nsquareness_urad = [0.0, 0.0, 0.0]\nshape_um = 0.0",
        "",
    );
    cfg.environment.material_c = cfg.campaign.reference_temperature_c;
    cfg.bar = toml::from_str(
        "diagonals = [\"+-+\"]\nnoise_um = 0.0\nresidue_step_um = 0.0\nscale_u_ppm = 0.0\nsocket_across_mm = 0.1",
    )
    .unwrap();
    let sim = generate_volumetric(&cfg).unwrap();
    let rows = &sim.tables.bar_readings;
    assert!(!rows.is_empty());
    let theta = 0.1 / cfg.bar.length_mm;
    let mut worst = 0.0f64;
    for s in 1..=rows.iter().map(|r| r.segment).max().unwrap() {
        let seg: Vec<_> = rows
            .iter()
            .filter(|r| r.segment == s && r.run == 1 && r.direction == 1)
            .collect();
        for r in &seg {
            let x = r.distance_along_mm - seg[0].distance_along_mm;
            let short = x - (r.centre_distance_mm - seg[0].centre_distance_mm);
            assert!(
                short >= -1e-9 && short <= theta * theta / 2.0 * x + 1e-9,
                "{short} at {x}"
            );
            worst = worst.max(short);
        }
    }
    assert!(worst > 0.0);
    let truth = sim.truth.bar.unwrap();
    assert_eq!(truth.diagonals.len(), 1);
    assert!(truth.diagonals[0].e_um.abs() < 1e-12);
    // Body diagonal "+-+" by bar: the laser reads the other three.
    assert!(sim
        .tables
        .diagonals
        .iter()
        .all(|r| r.diagonal != DiagonalSign::Pmp));
    assert!(sim.manifest.bar_diagonal.is_some() && sim.manifest.laser.is_some());
}
