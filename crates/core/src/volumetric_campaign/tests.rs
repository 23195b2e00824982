use super::*;

const MANIFEST: &str = r#"
campaign = { kind = "volumetric", id = "hmc-vol-2027-01", reference_temperature_c = 20.0 }
machine = { cte_ppm_per_k = 11.5 }
workspace = { min_mm = [0.0, 0.0, -500.0], max_mm = [1000.0, 600.0, 0.0] }
laser = { wavelength_nm = 632.990577, compensation = "air+material", target = "flat-mirror" }
grid = { I = 3, J = 4, K = 3, origin_mm = [0.0, 0.0, -500.0], spacing_mm = [500.0, 200.0, 250.0] }

[table]
format = "fanuc-3d"
n_base = 100000
unit_um = 1.0
values = "correction"
"#;

#[test]
fn the_spec_example_manifest_validates() {
    let c = VolumetricCampaign::from_toml_str(MANIFEST, "campaign.toml").unwrap();
    assert_eq!(c.grid.i, 3);
    assert_eq!(c.lengths_mm(), [1000.0, 600.0, 500.0]);
    assert_eq!(c.table.values, TableValues::Correction);
}

#[test]
fn a_grid_outside_the_workspace_is_refused_naming_the_key() {
    let text = MANIFEST.replace(
        "spacing_mm = [500.0, 200.0, 250.0]",
        "spacing_mm = [600.0, 200.0, 250.0]",
    );
    let e = VolumetricCampaign::from_toml_str(&text, "campaign.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("grid") && e.contains("outside the workspace"),
        "{e}"
    );
}

#[test]
fn steps_with_a_retroreflector_are_refused() {
    let text = MANIFEST.replace("flat-mirror", "retroreflector");
    let c = VolumetricCampaign::from_toml_str(&text, "campaign.toml").unwrap();
    assert!(c.check_steps(false, "f").is_ok());
    let e = c.check_steps(true, "f").unwrap_err().to_string();
    assert!(e.contains("laser.target"), "{e}");
}

#[test]
fn diagonal_names_round_trip() {
    for d in DiagonalSign::ALL {
        assert_eq!(DiagonalSign::parse(d.as_str()), Some(d));
        assert_eq!(logs::diagonal_of_index(d.index() as i64), Some(d));
    }
}

#[test]
fn diagonal_directions_are_derived_and_rows_ordered() {
    let r = |t: i64, x: f64| DiagonalReading {
        time_ns: t,
        diagonal: DiagonalSign::Mpp,
        run: 1,
        direction: 0,
        target_mm: x,
        deviation_um: 0.0,
    };
    let rows = vec![r(3, 0.0), r(1, 0.0), r(2, 100.0)];
    let out = order_diagonal_readings(&rows, &[None, None, None]).unwrap();
    assert_eq!(out.iter().map(|r| r.time_ns).collect::<Vec<_>>(), [1, 2, 3]);
    assert_eq!(
        out.iter().map(|r| r.direction).collect::<Vec<_>>(),
        [1, 1, -1]
    );
}
