//! `[[device]]` tables and the legs of their mounts, read from `campaign.toml`: the spec's
//! example with its defaults, and every refusal one line naming the key.

use dbbcal_core::campaign::{Campaign, Manifest};

use super::TomlManifest;

/// The spec's example device with two bars in legs 1 and 2 (others unused).
fn manifest(extra_mount: &str, device_extra: &str) -> String {
    format!(
        r#"
[campaign]
id = "dev"
reference_temperature_c = 20.0
[plate]
material = "zerodur"
tilt_deg = 60.0
[[plate.length]]
id = "min"
mm = 250.0
u_um = 0.15
[[sensor]]
id = "T1"
kind = "air"
[[bar]]
id = "B01"
resolution_nm = 5.0
fixed_length_mm = 230.0
[[bar]]
id = "B02"
resolution_nm = 5.0
fixed_length_mm = 230.0
[[device]]
id = "hexapod-1"
kind = "hexapod"
base_mm = [[196.962, -34.730, 0.0], [196.962, 34.730, 0.0], [-68.404, 187.939, 0.0],
       [-128.558, 153.209, 0.0], [-128.558, -153.209, 0.0], [-68.404, -187.939, 0.0]]
platform_mm = [[64.279, -76.604, 0.0], [64.279, 76.604, 0.0], [34.202, 93.969, 0.0],
           [-98.481, 17.365, 0.0], [-98.481, -17.365, 0.0], [34.202, -93.969, 0.0]]
u_base_um = 2.0
u_platform_um = [1.0, 1.0, 1.0, 1.0, 1.0, 2.0]
nominal_pose = [0.0, 0.0, 260.0, 0.0, 0.0, 0.0]
reference_mm = [400.0, 300.0, -200.0]
cte_ppm_per_k = 11.5
sensor = "T1"
{device_extra}
[[mount]]
bar = "B01"
device = "hexapod-1"
leg = 1
from = 2026-11-04T01:00:00Z
to   = 2026-11-06T00:00:00Z
{extra_mount}
"#
    )
}

fn check(text: &str) -> Result<Campaign, String> {
    let m = Manifest::from_toml_str(text, "campaign.toml").map_err(|e| e.to_string())?;
    Campaign::from_manifest(m).map_err(|e| e.to_string())
}

fn refused(text: &str, words: &[&str]) {
    let e = check(text).expect_err("refused");
    assert!(!e.contains('\n'), "{e}");
    for w in words {
        assert!(e.contains(w), "{e:?} lacks {w:?}");
    }
}

#[test]
fn the_specs_example_device_is_read_with_its_defaults() {
    let c = check(&manifest("", "")).unwrap();
    let d = &c.devices[0];
    assert_eq!(d.id, "hexapod-1");
    assert_eq!(d.u_base_um, [2.0; 6]);
    assert_eq!(d.u_platform_um[5], 2.0);
    assert_eq!(d.tool_point_mm, [0.0; 3]);
    assert_eq!(d.up, [0.0, 0.0, 1.0]);
    assert_eq!(d.reference_mm, Some([400.0, 300.0, -200.0]));
    assert_eq!(c.mounts[0].leg, Some(1));
    // Written back and read again: the same campaign.
    let m = Manifest::from_toml_str(&manifest("", ""), "x").unwrap();
    let again = check(&m.to_toml_string().unwrap()).unwrap();
    assert_eq!(again, c);
}

#[test]
fn leg_mounts_and_device_tables_are_checked_with_one_line_naming_the_key() {
    let second = |leg: &str, from: &str, place: &str| {
        format!(
            "[[mount]]\nbar = \"B02\"\n{place}\n{leg}\nfrom = {from}\nto = 2026-11-07T00:00:00Z\n"
        )
    };
    let dev = "device = \"hexapod-1\"";
    refused(
        &manifest(&second("", "2026-11-04T01:00:00Z", dev), ""),
        &["mount[1]", "leg (1–6) is required"],
    );
    refused(
        &manifest(&second("leg = 7", "2026-11-04T01:00:00Z", dev), ""),
        &["mount[1]", "leg = 7"],
    );
    refused(
        &manifest(
            &second("leg = 2", "2026-11-04T01:00:00Z", "length = \"min\""),
            "",
        ),
        &["mount[1]", "leg with length"],
    );
    refused(
        &manifest(
            &second("leg = 2", "2026-11-04T01:00:00Z", "device = \"other\""),
            "",
        ),
        &["mount[1]", "no [[device]] table"],
    );
    refused(
        &manifest(&second("leg = 1", "2026-11-05T00:00:00Z", dev), ""),
        &["mount[1]", "leg 1", "already carries bar \"B01\""],
    );
    // After the first bar left leg 1, another may take it.
    check(&manifest(
        &second("leg = 1", "2026-11-06T00:00:00Z", dev),
        "",
    ))
    .unwrap();
    // An undeclared device keeps the old meaning: no leg.
    check(&manifest(
        &second("", "2026-11-04T01:00:00Z", "device = \"other\""),
        "",
    ))
    .unwrap();
    let bad_ring = manifest("", "").replace("[-68.404, -187.939, 0.0]]\nplatform", "]\nplatform");
    let bad_ring = bad_ring.replace(", ]", "]");
    refused(&bad_ring, &["device[0]", "base_mm has 5 joint centres"]);
    refused(
        &manifest("", "").replace("u_base_um = 2.0", "u_base_um = [2.0, 2.0]"),
        &["device[0]", "u_base_um has 2 values"],
    );
    refused(
        &manifest("", "").replace("sensor = \"T1\"\n", "sensor = \"T9\"\n"),
        &["device[0]", "sensor", "T9"],
    );
    refused(
        &manifest("", "").replace("kind = \"hexapod\"", "kind = \"tripod\""),
        &["campaign.toml", "tripod"],
    );
    refused(
        &manifest("", "").replace("cte_ppm_per_k = 11.5", "cte_ppm_per_k = 1e9"),
        &["device[0]", "cte_ppm_per_k"],
    );
}
