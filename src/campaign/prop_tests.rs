//! Property tests of the manifest parser (issue 14): arbitrary and mutated `campaign.toml` texts
//! never panic; each is a validated campaign whose every number is in range, or one typed error
//! on one line. `PROPTEST_CASES=20000 cargo test --release --lib prop_tests` for a longer run.

use proptest::prelude::*;

use super::*;

/// The shipped sample's manifest and the unit tests' (devices, offsets, purposes).
const SAMPLE: &str = include_str!("../../data/sample/campaign.toml");
const OTHER: &str = super::tests::GOOD;

/// Cases per property: `PROPTEST_CASES` when set, else `default` (kept short for CI). The
/// random stream is seeded with [`CI_SEED`] unless `PROPTEST_RNG_SEED` gives another, so every
/// `cargo test` runs the same cases (a failure in CI is reproducible, and CI is not flaky);
/// longer runs with other seeds are in the README.
pub(crate) fn cases(default: u32) -> ProptestConfig {
    let n = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default);
    let mut config = ProptestConfig {
        cases: n,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        config.rng_seed = proptest::test_runner::RngSeed::Fixed(CI_SEED);
    }
    config
}

/// The seed of the property tests' cases in `cargo test`.
pub(crate) const CI_SEED: u64 = 1;

/// Values a number or string in a TOML file may be replaced by.
pub(crate) fn nasty_value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("nan".to_string()),
        Just("+inf".to_string()),
        Just("-inf".to_string()),
        Just("0".to_string()),
        Just("-0.0".to_string()),
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("5e-324".to_string()),
        Just("9223372036854775807".to_string()),
        Just("-9223372036854775808".to_string()),
        Just("99999999999999999999".to_string()),
        Just("\"\"".to_string()),
        Just("\"..\"".to_string()),
        Just("\"a/b\"".to_string()),
        Just("\"\\u0000\"".to_string()),
        Just("\"\\n\"".to_string()),
        Just("true".to_string()),
        Just("[]".to_string()),
        Just("{}".to_string()),
        Just("1970-01-01T00:00:00Z".to_string()),
        Just("0001-01-01T00:00:00Z".to_string()),
        Just("9999-12-31T23:59:59.999999999-23:59".to_string()),
        Just("2262-04-11T23:47:16.854775807Z".to_string()),
        Just("2026-11-01".to_string()),
        Just("00:00:00".to_string()),
        any::<f64>().prop_map(|v| format!("{v:?}")),
        any::<i64>().prop_map(|v| v.to_string()),
        "[a-zA-Z0-9 ./_-]{0,12}".prop_map(|s| format!("{s:?}")),
    ]
}

/// One edit of a TOML text.
#[derive(Debug, Clone)]
pub(crate) enum Edit {
    /// Replace the value of the `n`-th `key = value` line.
    Value(usize, String),
    /// Delete the `n`-th line.
    DeleteLine(usize),
    /// Duplicate the `n`-th line.
    DuplicateLine(usize),
    /// Insert a string at a byte offset (as a fraction of the length).
    Insert(f64, String),
    /// Truncate at a fraction of the length.
    Truncate(f64),
}

pub(crate) fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<usize>(), nasty_value()).prop_map(|(n, v)| Edit::Value(n, v)),
        1 => any::<usize>().prop_map(Edit::DeleteLine),
        1 => any::<usize>().prop_map(Edit::DuplicateLine),
        1 => (0.0..1.0f64, any::<String>()).prop_map(|(at, s)| Edit::Insert(at, s)),
        1 => (0.0..1.0f64, prop::sample::select(vec![
            "[", "]", "=", "\"", "\n", "[[mount]]\n", "[[bar]]\n", "[plate]\n", "#", "\u{feff}", "é",
        ]))
        .prop_map(|(at, s)| Edit::Insert(at, s.to_string())),
        1 => (0.0..1.0f64).prop_map(Edit::Truncate),
    ]
}

fn floor_boundary(s: &str, at: f64) -> usize {
    let mut i = ((s.len() as f64) * at) as usize;
    i = i.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// `text` with `edits` applied in order.
pub(crate) fn apply(text: &str, edits: &[Edit]) -> String {
    let mut s = text.to_string();
    for e in edits {
        let mut lines: Vec<String> = s.lines().map(str::to_string).collect();
        match e {
            Edit::Value(n, v) => {
                let assignments: Vec<usize> = (0..lines.len())
                    .filter(|&i| {
                        lines[i].contains(" = ") && !lines[i].trim_start().starts_with('#')
                    })
                    .collect();
                if let Some(&i) = assignments.get(n % assignments.len().max(1)) {
                    let key = lines[i].split(" = ").next().unwrap_or("").to_string();
                    lines[i] = format!("{key} = {v}");
                }
                s = lines.join("\n");
            }
            Edit::DeleteLine(n) if !lines.is_empty() => {
                lines.remove(n % lines.len());
                s = lines.join("\n");
            }
            Edit::DuplicateLine(n) if !lines.is_empty() => {
                let i = n % lines.len();
                lines.insert(i, lines[i].clone());
                s = lines.join("\n");
            }
            Edit::Insert(at, ins) => {
                let i = floor_boundary(&s, *at);
                s.insert_str(i, ins);
            }
            Edit::Truncate(at) => {
                let i = floor_boundary(&s, *at);
                s.truncate(i);
            }
            _ => {}
        }
    }
    s
}

/// What a validated campaign promises.
fn check_valid(c: &Campaign) {
    assert!(check_campaign_id(&c.id).is_ok(), "{:?}", c.id);
    let within = |v: f64, (lo, hi): (f64, f64)| v.is_finite() && lo <= v && v <= hi;
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
