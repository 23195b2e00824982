//! The `axis` manifest's parser and validation, the kind dispatch, and the reader rules.

use super::logs::reflector_at;
use super::*;

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

// ---------------------------------------------------------------- rules

fn key(
    time_s: i64,
    run: i64,
    target_mm: f64,
    channel: Channel,
    direction: Option<i8>,
) -> ReadingKey {
    ReadingKey {
        time_ns: time_s * 1_000_000_000,
        line: 1,
        run,
        target_mm,
        channel,
        deviation_um: 0.0,
        direction,
    }
}

#[test]
fn directions_are_the_sign_of_the_change_and_a_run_s_first_target_takes_its_second_s() {
    // A pendulum run: up 0, 100, 200, the turn read twice at 200, down 100, 0; then run 2 down.
    let targets = [0.0, 100.0, 200.0, 200.0, 100.0, 0.0];
    let mut keys: Vec<ReadingKey> = targets
        .iter()
        .enumerate()
        .map(|(i, &x)| key(i as i64, 1, x, Channel::Dx, None))
        .collect();
    keys.extend(
        [500.0, 400.0, 300.0]
            .iter()
            .enumerate()
            .map(|(i, &x)| key(100 + i as i64, 2, x, Channel::Dx, None)),
    );
    let o = derive_order(&keys).unwrap();
    assert_eq!(o.order, (0..9).collect::<Vec<_>>());
    assert_eq!(o.direction, [1, 1, 1, -1, -1, -1, -1, -1, -1]);
    // Rows in any order (and channels of one target) give the same.
    let mut shuffled = keys.clone();
    shuffled.reverse();
    let r = derive_order(&shuffled).unwrap();
    let directions: Vec<i8> = r.order.iter().map(|&i| r.direction[i]).collect();
    assert_eq!(directions, [1, 1, 1, -1, -1, -1, -1, -1, -1]);
    // A given direction wins, null ones are derived.
    keys[1].direction = Some(-1);
    let o = derive_order(&keys).unwrap();
    assert_eq!(o.direction[..3], [1, -1, 1]);
}

#[test]
fn the_channels_of_one_target_are_one_visit() {
    let keys = vec![
        key(0, 1, 0.0, Channel::Dy, None),
        key(0, 1, 0.0, Channel::Dx, None),
        key(5, 1, -50.0, Channel::Dx, None),
        key(5, 1, -50.0, Channel::Dy, None),
        key(6, 1, -50.0, Channel::Dz, None),
    ];
    let o = derive_order(&keys).unwrap();
    assert_eq!(o.order, [1, 0, 2, 3, 4]);
    assert_eq!(o.direction, [-1; 5]);
}

#[test]
fn repeated_times_are_ordered_by_target_in_the_run_s_direction() {
    let down = [300.0, 100.0, 200.0].map(|x| key(7, 1, x, Channel::Dx, Some(-1)));
    let o = derive_order(&down).unwrap();
    assert_eq!(o.order, [0, 2, 1]);
    let up = [300.0, 100.0, 200.0].map(|x| key(7, 1, x, Channel::Dx, Some(1)));
    assert_eq!(derive_order(&up).unwrap().order, [1, 2, 0]);
    // Without direction: refused, naming the rows.
    let mut bad = up;
    bad[2].direction = None;
    let e = derive_order(&bad).unwrap_err();
    assert_eq!(e.rows, [0, 1, 2]);
    assert!(e.to_string().contains("line 1, run 1") && e.problem.contains("`direction`"));
    let mut mixed = up;
    mixed[0].direction = Some(-1);
    assert!(derive_order(&mixed)
        .unwrap_err()
        .problem
        .contains("both directions"));
}

#[test]
fn a_run_at_one_target_or_a_bad_direction_is_refused() {
    let keys = [
        key(0, 3, 10.0, Channel::Dx, None),
        key(1, 3, 10.0, Channel::Dx, None),
    ];
    let e = derive_order(&keys).unwrap_err();
    assert_eq!((e.run, e.rows.clone()), (3, vec![0, 1]));
    assert!(e.problem.contains("cannot be derived"), "{e}");
    let keys = [key(0, 3, 10.0, Channel::Dx, Some(2))];
    assert!(derive_order(&keys)
        .unwrap_err()
        .problem
        .contains("+1 nor -1"));
    // Given: fine.
    assert!(derive_order(&[key(0, 3, 10.0, Channel::Dx, Some(1))]).is_ok());
}

#[test]
fn a_reading_takes_the_latest_fixture_row_of_its_line_else_the_first_else_the_manifest() {
    let row = |line, t, z| FixtureRow {
        time_ns: t,
        line,
        reflector_mm: [0.0, 0.0, z],
    };
    let fixture = [row(1, 10, 1.0), row(1, 20, 2.0), row(2, 5, 9.0)];
    let default = [7.0, 7.0, 7.0];
    assert_eq!(reflector_at(&fixture, 1, 15, default)[2], 1.0);
    assert_eq!(reflector_at(&fixture, 1, 20, default)[2], 2.0);
    assert_eq!(reflector_at(&fixture, 1, 99, default)[2], 2.0);
    assert_eq!(reflector_at(&fixture, 1, 0, default)[2], 1.0);
    assert_eq!(reflector_at(&fixture, 2, 0, default)[2], 9.0);
    assert_eq!(reflector_at(&fixture, 3, 50, default), default);
    let env = |t, air_c| EnvironmentRow {
        time_ns: t,
        air_c,
        pressure_hpa: 1000.0,
        humidity_pct: 50.0,
        material_c: None,
        env_factor_ppm: None,
    };
    let rows = [env(10, 20.0), env(20, 21.0)];
    assert_eq!(environment_at(&rows, 5).unwrap().air_c, 20.0);
    assert_eq!(environment_at(&rows, 19).unwrap().air_c, 20.0);
    assert_eq!(environment_at(&rows, 20).unwrap().air_c, 21.0);
    assert!(environment_at(&[], 20).is_none());
}

#[test]
fn channels_round_trip() {
    for c in Channel::ALL {
        assert_eq!(Channel::parse(c.as_str()), Some(c));
        assert_eq!(Channel::of_axis(MachineAxis::from_index(c.index())), c);
    }
    assert_eq!(Channel::parse("DX"), None);
}
