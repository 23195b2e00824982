//! The `axis` manifest's parser and validation, and the kind dispatch.

use dbbcal_core::axis_campaign::*;
use dbbcal_core::campaign::CampaignError;

use super::{campaign_kind, TomlCampaign, TomlManifest};

const GOOD: &str = r#"
campaign = { kind = "axis", id = "vmc-x-2026-12", reference_temperature_c = 20.0 }
machine = { axis = "X", cte_ppm_per_k = 11.5 }
laser = { wavelength_nm = 632.990577, compensation = "air+material", dead_path_mm = 150.0 }
line = [ { id = 1, reflector_mm = [0.0, 0.0, 0.0] },
         { id = 2, reflector_mm = [0.0, 0.0, 100.0] },
         { id = 3, reflector_mm = [0.0, 100.0, 100.0] } ]

[fixture]
u_um = 5.0
report_point_mm = [0.0, 0.0, 0.0]
"#;

fn validate(text: &str) -> Result<AxisCampaign, CampaignError> {
    AxisCampaign::from_toml_str(text, "campaign.toml")
}

fn error(text: &str) -> String {
    let msg = validate(text).expect_err("should fail").to_string();
    assert!(!msg.contains('\n'), "not one line: {msg}");
    msg
}

#[test]
fn the_spec_example_parses_and_validates() {
    let c = validate(GOOD).unwrap();
    assert_eq!(c.id, "vmc-x-2026-12");
    assert_eq!(c.axis, MachineAxis::X);
    assert_eq!(c.compensation, LaserCompensation::AirMaterial);
    assert_eq!(c.dead_path_mm, Some(150.0));
    assert_eq!(c.line_ids(), [1, 2, 3]);
    assert_eq!(c.line(3).unwrap().reflector_mm, [0.0, 100.0, 100.0]);
    assert_eq!(c.fixture_u_um, 5.0);
    assert_eq!(MachineAxis::Y.error_names()[0], "EXY");
    assert_eq!(MachineAxis::X.error_names()[5], "ECX");
    assert_eq!(MachineAxis::Z.along(), Channel::Dz);
}

#[test]
fn the_manifest_round_trips_through_toml() {
    let m = AxisManifest::from_toml_str(GOOD, "campaign.toml").unwrap();
    let text = m.to_toml_string().unwrap();
    assert_eq!(AxisManifest::from_toml_str(&text, "x").unwrap(), m);
    assert_eq!(campaign_kind(&text, "x").unwrap(), CampaignKind::Axis);
}

#[test]
fn the_kind_is_read_from_any_manifest_and_absent_means_ballbar() {
    assert_eq!(campaign_kind(GOOD, "c").unwrap(), CampaignKind::Axis);
    let ballbar = "[campaign]\nid = \"lab\"\nreference_temperature_c = 20.0\n";
    assert_eq!(campaign_kind(ballbar, "c").unwrap(), CampaignKind::Ballbar);
    assert_eq!(campaign_kind("", "c").unwrap(), CampaignKind::Ballbar);
    assert_eq!(
        campaign_kind("[campaign]\nkind = \"roll\"\n", "c").unwrap(),
        CampaignKind::Roll
    );
    let e = campaign_kind("[campaign]\nkind = \"laser\"\n", "campaign.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("campaign.toml") && e.contains("kind") && e.contains("\"laser\""));
    assert!(e.contains("ballbar, axis, volumetric, probe, roll"), "{e}");
    let e = campaign_kind("[campaign]\nkind = 3\n", "c")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("campaign.kind") && e.contains("must be a string"),
        "{e}"
    );
    let e = campaign_kind("[campaign\n", "c").unwrap_err().to_string();
    assert!(e.starts_with("c:1:"), "{e}");
    for k in CampaignKind::ALL {
        assert_eq!(CampaignKind::parse(k.as_str()), Some(k));
    }
}

#[test]
fn every_bad_value_names_its_key() {
    let cases: &[(&str, &str, &str)] = &[
        ("kind = \"axis\"", "kind = \"probe\"", "campaign.kind"),
        ("id = \"vmc-x-2026-12\"", "id = \"a/b\"", "campaign.id"),
        (
            "reference_temperature_c = 20.0",
            "reference_temperature_c = nan",
            "campaign.reference_temperature_c",
        ),
        (
            "cte_ppm_per_k = 11.5",
            "cte_ppm_per_k = 1e9",
            "machine.cte_ppm_per_k",
        ),
        (
            "wavelength_nm = 632.990577",
            "wavelength_nm = 0.63",
            "laser.wavelength_nm",
        ),
        (
            "dead_path_mm = 150.0",
            "dead_path_mm = -1.0",
            "laser.dead_path_mm",
        ),
        (
            "[0.0, 0.0, 100.0]",
            "[0.0, 0.0, inf]",
            "line[1].reflector_mm",
        ),
        ("u_um = 5.0", "u_um = -5.0", "fixture.u_um"),
        (
            "report_point_mm = [0.0, 0.0, 0.0]",
            "report_point_mm = [0.0, 1e6, 0.0]",
            "fixture.report_point_mm",
        ),
    ];
    for (from, to, key) in cases {
        let text = GOOD.replacen(from, to, 1);
        assert_ne!(text, GOOD, "{from}");
        let e = error(&text);
        assert!(
            e.starts_with("campaign.toml: ") && e.contains(key),
            "{key}: {e}"
        );
    }
    let e = error(&GOOD.replacen("id = 2,", "id = 1,", 1));
    assert!(e.contains("line[1]") && e.contains("line[0]"), "{e}");
    let e = error(&GOOD.replacen("axis = \"X\"", "axis = \"W\"", 1));
    assert!(e.starts_with("campaign.toml:3:"), "{e}");
    let e = error(&GOOD.replacen("\"air+material\"", "\"material\"", 1));
    assert!(e.contains("campaign.toml:4:"), "{e}");
    let e = error(&GOOD.replacen("u_um = 5.0", "u_um = 5.0\nsigma = 1", 1));
    assert!(e.contains("sigma"), "{e}");
    let no_lines: String = GOOD
        .lines()
        .filter(|l| !l.contains("reflector_mm"))
        .map(|l| format!("{l}\n"))
        .collect::<String>()
        .replacen("[fixture]", "line = []\n[fixture]", 1);
    let e = error(&no_lines);
    assert!(e.contains("line: declares no line"), "{e}");
}

#[test]
fn the_environment_is_required_unless_the_readings_include_air_and_material() {
    let c = validate(GOOD).unwrap();
    assert!(c.check_environment(false, "campaign.toml").is_ok());
    let air = validate(&GOOD.replacen("\"air+material\"", "\"air\"", 1)).unwrap();
    assert!(air.check_environment(true, "campaign.toml").is_ok());
    let e = air
        .check_environment(false, "campaign.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("campaign.toml: laser.compensation: ") && e.contains("environment"),
        "{e}"
    );
    let none = validate(&GOOD.replacen("\"air+material\"", "\"none\"", 1)).unwrap();
    assert!(none.check_environment(false, "c").is_err());
    // Without [fixture]: no uncertainty, report point at F's origin.
    let bare = GOOD.split("[fixture]").next().unwrap();
    let c = validate(bare).unwrap();
    assert_eq!((c.fixture_u_um, c.report_point_mm), (0.0, [0.0; 3]));
}
