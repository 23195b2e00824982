//! The ballbar manifest's parser, writer and validation: every message names the file and the key.

use dbbcal_core::campaign::*;

use super::campaign::{ns_to_toml_datetime, toml_datetime_to_ns};
use super::TomlManifest;

pub(super) const GOOD: &str = r#"
[campaign]
id = "lab"
reference_temperature_c = 20.0

[plate]
material = "zerodur"
tilt_deg = 60.0
[[plate.length]]
id = "min"
mm = 250.0
u_um = 0.15
[[plate.length]]
id = "max"
mm = 400.0
u_um = 0.2

[[sensor]]
id = "T1"
kind = "air"

[[bar]]
id = "B02"
resolution_nm = 5.0
fixed_length_mm = 230.0
[[bar]]
id = "B01"
resolution_nm = 5.0
fixed_length_mm = 230.0
sensor = "T1"

[[mount]]
bar = "B02"
length = "max"
from = 2026-11-02T00:00:00Z
to = 2026-11-03T00:00:00Z
[[mount]]
bar = "B01"
device = "hexapod-1"
purpose = "check"
tilt_deg = 10.0
from = 2026-11-04T01:00:00+01:00
to = 2026-11-06T00:00:00
[[mount]]
bar = "B01"
length = "min"
from = 2026-11-01T00:00:00Z
to = 2026-11-04T00:00:00Z
"#;

const DAY_NS: i64 = 86_400 * 1_000_000_000;
const NOV1: i64 = 1_793_491_200 * 1_000_000_000;

fn validate(text: &str) -> Result<Campaign, CampaignError> {
    Campaign::from_manifest(Manifest::from_toml_str(text, "campaign.toml")?)
}

fn error(text: &str) -> String {
    let msg = validate(text).expect_err("should fail").to_string();
    assert!(!msg.contains('\n'), "not one line: {msg}");
    msg
}

#[test]
fn resolves_sorts_and_fills_in() {
    let c = validate(GOOD).expect("valid");
    let order: Vec<(&str, i64)> = c
        .mounts
        .iter()
        .map(|m| (m.bar.as_str(), m.from_ns))
        .collect();
    // Sorted by (bar, from); +01:00 offset and local (= UTC) datetimes converted.
    assert_eq!(
        order,
        vec![
            ("B01", NOV1),
            ("B01", NOV1 + 3 * DAY_NS),
            ("B02", NOV1 + DAY_NS)
        ]
    );
    assert_eq!(c.mounts[1].to_ns, NOV1 + 5 * DAY_NS);
    assert_eq!(
        c.mounts[0].tilt_deg, 60.0,
        "plate tilt when the mount has none"
    );
    assert_eq!(c.mounts[1].tilt_deg, 10.0);
    assert_eq!(c.mounts[1].place, Place::Device("hexapod-1".into()));
    assert_eq!(c.mounts[1].purpose, Purpose::Check);
    assert_eq!(c.mounts[0].purpose, Purpose::Calibration);
    assert!(matches!(&c.mounts[2].place, Place::Length(l) if l.id == "max" && l.mm == 400.0));
    assert_eq!(c.bar("B01").and_then(|b| b.sensor.as_deref()), Some("T1"));
}

#[test]
fn manifest_round_trips_through_toml() {
    let m = Manifest::from_toml_str(GOOD, "campaign.toml").expect("parse");
    let text = m.to_toml_string().expect("serialise");
    assert_eq!(Manifest::from_toml_str(&text, "x").expect("reparse"), m);
}

#[test]
fn time_conversion_round_trips() {
    for ns in [
        0,
        NOV1,
        NOV1 + 123_456_789,
        NOV1 + 500_000_000,
        -5_000_000_001,
    ] {
        assert_eq!(toml_datetime_to_ns(&ns_to_toml_datetime(ns)), Ok(ns));
        // What the simulators declare is what TOML writes.
        assert_eq!(
            DeclaredTime::at(ns).text,
            ns_to_toml_datetime(ns).to_string()
        );
    }
}

#[test]
fn syntax_errors_name_file_and_line() {
    let msg = error(&GOOD.replace(
        "resolution_nm = 5.0\nfixed_length_mm = 230.0\nsensor",
        "resolution = 5.0\nfixed_length_mm = 230.0\nsensor",
    ));
    assert!(msg.starts_with("campaign.toml:"), "{msg}");
    assert!(msg.contains("resolution"), "{msg}");
    let msg = error("[campaign\nid = 1");
    assert!(msg.starts_with("campaign.toml:1:"), "{msg}");
}

#[test]
fn duplicate_ids_are_named() {
    let msg = error(
        &GOOD
            .replace("id = \"B02\"", "id = \"B01\"")
            .replace("bar = \"B02\"", "bar = \"B01\""),
    );
    assert!(
        msg.contains("campaign.toml: bar[1]: id \"B01\" is already used by bar[0]"),
        "{msg}"
    );
    let msg = error(&GOOD.replace("id = \"max\"", "id = \"min\""));
    assert!(
        msg.contains("plate.length[1]: id \"min\" is already used by plate.length[0]"),
        "{msg}"
    );
    let msg = error(&format!(
        "{GOOD}\n[[sensor]]\nid = \"T1\"\nkind = \"bar\"\n"
    ));
    assert!(msg.contains("sensor[1]: id \"T1\""), "{msg}");
}

#[test]
fn unknown_references_are_named() {
    let msg = error(&GOOD.replace("length = \"max\"", "length = \"huge\""));
    assert_eq!(msg, "campaign.toml: mount[0] (bar \"B02\"): length \"huge\" is not a plate length (known: min, max)");
    let msg = error(&GOOD.replace("bar = \"B02\"", "bar = \"B03\""));
    assert!(
        msg.contains("mount[0]: bar \"B03\" is not a declared bar (known: B02, B01)"),
        "{msg}"
    );
    let msg = error(&GOOD.replace("sensor = \"T1\"", "sensor = \"T7\""));
    assert!(
        msg.contains("bar[1] (\"B01\"): sensor \"T7\" is not a declared sensor (known: T1)"),
        "{msg}"
    );
}

#[test]
fn place_must_be_length_xor_device() {
    let msg = error(&GOOD.replace(
        "device = \"hexapod-1\"",
        "device = \"hexapod-1\"\nlength = \"min\"",
    ));
    assert!(
        msg.contains("mount[1] (bar \"B01\"): gives both length and device"),
        "{msg}"
    );
    let msg = error(&GOOD.replace("device = \"hexapod-1\"\n", ""));
    assert!(
        msg.contains("mount[1] (bar \"B01\"): gives neither length nor device"),
        "{msg}"
    );
}

#[test]
fn bad_intervals_are_named() {
    let msg = error(&GOOD.replace("to = 2026-11-03T00:00:00Z", "to = 2026-11-02T00:00:00Z"));
    assert!(
        msg.contains("mount[0] (bar \"B02\"): from = 2026-11-02T00:00:00Z is not before to"),
        "{msg}"
    );
    // The device mount starts (01:00+01:00 = 00:00Z) when the plate mount ends: touching is
    // fine. One hour earlier overlaps.
    let msg = error(&GOOD.replace(
        "from = 2026-11-04T01:00:00+01:00",
        "from = 2026-11-04T00:00:00+01:00",
    ));
    assert!(
        msg.contains("mount[1] (bar \"B01\"): interval") && msg.contains("overlaps mount[2]"),
        "{msg}"
    );
    let msg = error(&GOOD.replace("from = 2026-11-01T00:00:00Z", "from = 2026-11-01"));
    assert!(
        msg.contains("mount[2] (bar \"B01\"): from: 2026-11-01 is not a date-time"),
        "{msg}"
    );
}

#[test]
fn bad_numbers_are_named() {
    let msg = error(&GOOD.replacen("resolution_nm = 5.0", "resolution_nm = 0.0", 1));
    assert!(
        msg.contains("bar[0] (\"B02\"): resolution_nm = 0 is out of range: it must be a finite number above 0 and at most 1000000 nm"),
        "{msg}"
    );
    let msg = error(&GOOD.replacen("fixed_length_mm = 230.0", "fixed_length_mm = -1.0", 1));
    assert!(
        msg.contains("bar[0] (\"B02\"): fixed_length_mm = -1"),
        "{msg}"
    );
    let msg = error(&GOOD.replace(
        "fixed_length_mm = 230.0\nsensor",
        "fixed_length_mm = 260.0\nsensor",
    ));
    assert!(msg.contains("mount[2] (bar \"B01\"): bar fixed_length_mm = 260 exceeds plate length \"min\" = 250 mm"), "{msg}");
}

#[test]
fn campaign_ids_name_a_folder() {
    for ok in ["lab", "lab-a-2026-11", "a.b_c-D9", "x..y", &"a".repeat(100)] {
        let text = GOOD.replace("id = \"lab\"", &format!("id = {ok:?}"));
        validate(&text).unwrap_or_else(|e| panic!("{ok}: {e}"));
    }
    for (bad, why) in [
        ("", "is empty"),
        (".hidden", "starts with a dot"),
        ("..", "starts with a dot"),
        ("../../etc", "contains '/'"),
        ("a/b", "contains '/'"),
        ("a\\b", "contains '\\\\'"),
        ("lab 1", "contains ' '"),
        ("lab\n1", "contains '\\n'"),
        ("läb", "contains 'ä'"),
        (&"a".repeat(101), "101 characters long"),
    ] {
        let text = GOOD.replace("id = \"lab\"", &format!("id = {bad:?}"));
        let msg = error(&text);
        assert!(
            msg.contains("campaign.toml: campaign.id: "),
            "{bad:?}: {msg}"
        );
        assert!(msg.contains(why), "{bad:?}: {msg}");
    }
}

#[test]
fn bar_and_sensor_ids_refuse_control_characters() {
    let msg = error(
        &GOOD
            .replace("id = \"B02\"", "id = \"B\\u0007\"")
            .replace("bar = \"B02\"", "bar = \"B\\u0007\""),
    );
    assert!(
        msg.contains("bar[0]: id \"B\\u{7}\" contains a control character"),
        "{msg}"
    );
    let msg = error(&GOOD.replace("id = \"T1\"", "id = \"T\\t1\""));
    assert!(
        msg.contains("sensor[0]: id \"T\\t1\" contains a control character"),
        "{msg}"
    );
    let msg = error(&GOOD.replace("id = \"T1\"", "id = \"\""));
    assert!(msg.contains("sensor[0]: id is empty"), "{msg}");
    // Path-like bar ids are not refused here (the report makes file names safe).
    let text = GOOD
        .replace("id = \"B02\"", "id = \"../B 02\"")
        .replace("bar = \"B02\"", "bar = \"../B 02\"");
    validate(&text).expect("a path-like bar id is allowed");
    // An unknown reference with a newline stays on one line.
    let msg = error(&GOOD.replace("bar = \"B02\"", "bar = \"B\\n03\""));
    assert!(
        msg.contains("bar \"B\\n03\" is not a declared bar"),
        "{msg}"
    );
}

#[test]
fn every_number_is_range_checked() {
    let cases: &[(&str, &str, &str)] = &[
            ("reference_temperature_c = 20.0", "reference_temperature_c = nan", "campaign: reference_temperature_c = NaN is out of range"),
            ("reference_temperature_c = 20.0", "reference_temperature_c = 2000.0", "reference_temperature_c = 2000 is out of range: it must be a finite number from -100 to 200 °C"),
            ("material = \"zerodur\"", "material = \"zerodur\"\ncte_ppm_per_k = inf", "plate: cte_ppm_per_k = inf is out of range"),
            ("tilt_deg = 60.0\n[[plate", "tilt_deg = 400.0\n[[plate", "plate: tilt_deg = 400 is out of range: it must be a finite number from -90 to 90 degrees"),
            ("tilt_deg = 10.0", "tilt_deg = -inf", "mount[1] (bar \"B01\"): tilt_deg = -inf is out of range"),
            ("mm = 250.0", "mm = 1e9", "plate.length[0] (\"min\"): mm = 1000000000 is out of range"),
            ("mm = 250.0", "mm = nan", "plate.length[0] (\"min\"): mm = NaN is out of range: it must be a finite number above 0"),
            ("u_um = 0.15", "u_um = 5000.0", "plate.length[0] (\"min\"): u_um = 5000 is out of range"),
            ("u_um = 0.15", "u_um = -inf", "u_um = -inf is out of range: it must be a finite number from 0 to 1000 µm"),
            ("resolution_nm = 5.0", "resolution_nm = 1e300", "bar[0] (\"B02\"): resolution_nm = 1e300 is out of range"),
            ("resolution_nm = 5.0", "resolution_nm = nan", "bar[0] (\"B02\"): resolution_nm = NaN is out of range: it must be a finite number above 0"),
            ("fixed_length_mm = 230.0", "fixed_length_mm = 1e5", "bar[0] (\"B02\"): fixed_length_mm = 100000 is out of range"),
            ("from = 2026-11-02T00:00:00Z", "from = 1900-11-02T00:00:00Z", "mount[0] (bar \"B02\"): from = 1900-11-02T00:00:00Z is outside 1970-01-01T00:00:00Z .. 2200-01-01T00:00:00Z"),
            ("to = 2026-11-03T00:00:00Z", "to = 2250-11-03T00:00:00Z", "mount[0] (bar \"B02\"): to = 2250-11-03T00:00:00Z is outside"),
            ("to = 2026-11-03T00:00:00Z", "to = 9999-12-31T23:59:59-23:59", "mount[0] (bar \"B02\"): to: 9999-12-31T23:59:59-23:59 is outside 1677..2262"),
            ("to = 2026-11-03T00:00:00Z", "to = 2262-04-11T23:47:16.854775807-01:00", "mount[0] (bar \"B02\"): to: 2262-04-11T23:47:16.854775807-01:00 is outside 1677..2262"),
        ];
    for (from, to, needle) in cases {
        assert!(GOOD.contains(from), "{from}");
        let msg = error(&GOOD.replacen(from, to, 1));
        assert!(msg.contains(needle), "{to}: {msg}");
    }
}
