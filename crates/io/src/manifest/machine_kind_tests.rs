//! The machine kinds' manifests (`volumetric`, `probe`, `roll`) read from `campaign.toml`: the
//! specs' examples, and refusals naming the key.

use dbbcal_core::probe_campaign::{ArtefactKind, ProbeCampaign};
use dbbcal_core::roll_campaign::{RollCampaign, RollManifest};
use dbbcal_core::volumetric_campaign::{TableValues, VolumetricCampaign};

use super::{TomlCampaign, TomlManifest};

// ---------------------------------------------------------------- volumetric

const VOLUMETRIC: &str = r#"
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
    let c = VolumetricCampaign::from_toml_str(VOLUMETRIC, "campaign.toml").unwrap();
    assert_eq!(c.grid.i, 3);
    assert_eq!(c.lengths_mm(), [1000.0, 600.0, 500.0]);
    assert_eq!(c.table.values, TableValues::Correction);
}

#[test]
fn a_grid_outside_the_workspace_is_refused_naming_the_key() {
    let text = VOLUMETRIC.replace(
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
    let text = VOLUMETRIC.replace("flat-mirror", "retroreflector");
    let c = VolumetricCampaign::from_toml_str(&text, "campaign.toml").unwrap();
    assert!(c.check_steps(false, "f").is_ok());
    let e = c.check_steps(true, "f").unwrap_err().to_string();
    assert!(e.contains("laser.target"), "{e}");
}

// ---------------------------------------------------------------- probe

#[test]
fn a_manifest_with_a_bad_tip_names_the_key() {
    let text = r#"
campaign = { kind = "probe", id = "p", reference_temperature_c = 20.0 }
probe = { model = "TP2-5" }
[[stylus]]
id = "S1"
tip_diameter_mm = -6.0
[[artefact]]
id = "ring"
kind = "ring"
diameter_mm = 50.0
u_um = 0.15
"#;
    let e = ProbeCampaign::from_toml_str(text, "campaign.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("stylus[0].tip_diameter_mm"), "{e}");
    let good = text.replace("-6.0", "6.0");
    let c = ProbeCampaign::from_toml_str(&good, "campaign.toml").unwrap();
    assert_eq!(c.same_direction_deg, 1.0);
    assert_eq!(c.artefacts[0].kind, ArtefactKind::Ring);
}

// ---------------------------------------------------------------- roll

const SEED_MANIFEST: &str = r#"
campaign = { kind = "roll", id = "xstage-roll-2027-03", reference_temperature_c = 20.0 }

[roll]
axis = "X"
L_mm = 80.0
d_mm = 40.0
s_mm = 40.0
b_to_a = -1
unit = "V"
dwell_min_s = 2.0
dwell_tol_um = 2.0

[[roll.probe]]
id = "A"
u_xy_um = 50.0
um_per_v = -10.0
[[roll.probe]]
id = "B"
u_xy_um = 50.0
um_per_v = -10.0
[[roll.probe]]
id = "C"
u_xy_um = 50.0
um_per_v = -10.0
[[roll.probe]]
id = "D"
u_xy_um = 50.0
um_per_v = -10.0
xy_mm = [40.0, 80.05]
"#;

#[test]
fn the_spec_example_reads_and_round_trips() {
    let c = RollCampaign::from_toml_str(SEED_MANIFEST, "campaign.toml").unwrap();
    assert_eq!(c.b_to_a, -1);
    assert_eq!(c.probes[0].um_per_unit, -10.0);
    assert_eq!(c.probes[3].xy_mm, [40.0, 80.05]);
    assert!(!c.probes[2].measured && c.probes[3].measured);
    let m = RollManifest::from_toml_str(SEED_MANIFEST, "x").unwrap();
    let again = RollManifest::from_toml_str(&m.to_toml_string().unwrap(), "x").unwrap();
    assert_eq!(m, again);
}

#[test]
fn s_unequal_d_is_refused_naming_the_key() {
    let text = SEED_MANIFEST.replace("s_mm = 40.0", "s_mm = 40.5");
    let e = RollCampaign::from_toml_str(&text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("c.toml") && e.contains("roll.s_mm") && e.contains("d_mm"),
        "{e}"
    );
}

#[test]
fn a_missing_or_repeated_probe_and_a_bad_sign_are_named() {
    let text = SEED_MANIFEST.replace("id = \"D\"", "id = \"C\"");
    let e = RollCampaign::from_toml_str(&text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("roll.probe") && e.contains("\"C\""), "{e}");
    let text = SEED_MANIFEST.replace("b_to_a = -1", "b_to_a = 2");
    let e = RollCampaign::from_toml_str(&text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("roll.b_to_a"), "{e}");
    let text = SEED_MANIFEST.replace(
        "um_per_v = -10.0\n[[roll.probe]]\nid = \"B\"",
        "um_per_v = 0.0\n[[roll.probe]]\nid = \"B\"",
    );
    let e = RollCampaign::from_toml_str(&text, "c.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("roll.probe[0].um_per_v"), "{e}");
}
