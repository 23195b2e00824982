//! Property tests of the manifest parser (issue 14): arbitrary and mutated `campaign.toml` texts
//! never panic; each is a validated campaign whose every number is in range, or one typed error
//! on one line. `PROPTEST_CASES=20000 cargo test --release -p dbbcal-io campaign_prop_tests` for a longer run.

use proptest::prelude::*;

use dbbcal_core::campaign::*;
use dbbcal_core::limits::Limit;
use dbbcal_testkit::{apply, cases, edit};

use super::TomlManifest;

/// The shipped sample's manifest and the unit tests' (devices, offsets, purposes).
const SAMPLE: &str = include_str!("../../../../data/sample/campaign.toml");
const OTHER: &str = super::campaign_tests::GOOD;

/// What a validated campaign promises.
fn check_valid(c: &Campaign) {
    assert!(check_campaign_id(&c.id).is_ok(), "{:?}", c.id);
    let within = |v: f64, limit: Limit| limit.contains(v);
    assert!(within(
        c.reference_temperature_c,
        limits::REFERENCE_TEMPERATURE_C
    ));
    assert!(within(c.plate.cte_ppm_per_k, limits::CTE_PPM_PER_K));
    assert!(within(c.plate.tilt_deg, limits::TILT_DEG));
    for l in &c.plate.lengths {
        assert!(l.mm > 0.0 && within(l.mm, limits::LENGTH_MM), "{l:?}");
        assert!(within(l.u_um, limits::U_UM), "{l:?}");
    }
    for b in &c.bars {
        assert!(b.resolution_nm > 0.0 && within(b.resolution_nm, limits::RESOLUTION_NM));
        assert!(b.fixed_length_mm > 0.0 && within(b.fixed_length_mm, limits::LENGTH_MM));
        assert!(!b.id.trim().is_empty() && !b.id.chars().any(char::is_control));
    }
    for s in &c.sensors {
        assert!(!s.id.trim().is_empty() && !s.id.chars().any(char::is_control));
    }
    for m in &c.mounts {
        assert!(m.from_ns < m.to_ns);
        assert!(limits::MOUNT_TIME_NS.0 <= m.from_ns && m.to_ns < limits::MOUNT_TIME_NS.1);
        assert!(within(m.tilt_deg, limits::TILT_DEG));
        assert!(c.bar(&m.bar).is_some());
    }
}

fn parse(text: &str) {
    match Manifest::from_toml_str(text, "campaign.toml").and_then(Campaign::from_manifest) {
        Ok(c) => check_valid(&c),
        Err(e) => {
            let msg = e.to_string();
            assert!(
                !msg.contains('\n') && !msg.contains('\r'),
                "not one line: {msg:?}"
            );
        }
    }
}

proptest! {
    #![proptest_config(cases(256))]

    #[test]
    fn mutated_manifests_parse_or_fail_cleanly(
        base in prop::sample::select(vec![SAMPLE, OTHER]),
        edits in prop::collection::vec(edit(), 1..6),
    ) {
        parse(&apply(base, &edits));
    }

    #[test]
    fn arbitrary_text_parses_or_fails_cleanly(text in any::<String>()) {
        parse(&text);
    }
}
