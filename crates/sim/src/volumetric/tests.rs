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
