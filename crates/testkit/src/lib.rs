//! Test fixtures shared by the workspace's unit tests (a dev-dependency only; it depends on no
//! dbbcal crate, so every crate's tests can use it): the property tests' configuration and a
//! small campaign manifest; random edits of TOML texts for the parsers' property tests.

use proptest::prelude::*;
use proptest::test_runner::Config as ProptestConfig;

/// Cases per property: `PROPTEST_CASES` when set, else `default` (kept short for CI). The
/// random stream is seeded with [`CI_SEED`] unless `PROPTEST_RNG_SEED` gives another, so every
/// `cargo test` runs the same cases (a failure in CI is reproducible, and CI is not flaky);
/// longer runs with other seeds are in `docs/guarantees.md` ("Property tests").
pub fn cases(default: u32) -> ProptestConfig {
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
pub const CI_SEED: u64 = 1;

/// A one-bar campaign: B01 (5 nm, 230 mm fixed length) on the plate's `min` (250 mm) and `max`
/// (400 mm) lengths and a hexapod, mounted on 2026-11-01 from 00:00 to 04:00 (UTC); air sensors T1
/// and T2.
pub const ONE_BAR_MANIFEST: &str = r#"
[campaign]
id = "series"
reference_temperature_c = 20.0

[plate]
material = "zerodur"
tilt_deg = 60.0
[[plate.length]]
id = "min"
mm = 250.0
u_um = 0.1
[[plate.length]]
id = "max"
mm = 400.0
u_um = 0.2

[[sensor]]
id = "T1"
kind = "air"
[[sensor]]
id = "T2"
kind = "air"

[[bar]]
id = "B01"
resolution_nm = 5.0
fixed_length_mm = 230.0

[[mount]]
bar = "B01"
length = "min"
from = 2026-11-01T00:00:00Z
to = 2026-11-01T01:00:00Z
[[mount]]
bar = "B01"
length = "max"
from = 2026-11-01T01:10:00Z
to = 2026-11-01T03:00:00Z
[[mount]]
bar = "B01"
device = "hexapod"
from = 2026-11-01T03:00:00Z
to = 2026-11-01T04:00:00Z
"#;

/// Values a number or string in a TOML file may be replaced by.
pub fn nasty_value() -> impl Strategy<Value = String> {
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
pub enum Edit {
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

/// One random edit of a TOML text, values mostly from [`nasty_value`].
pub fn edit() -> impl Strategy<Value = Edit> {
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
pub fn apply(text: &str, edits: &[Edit]) -> String {
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

/// `rel` under the workspace's root: a member's tests run in the member's own folder, and the
/// shipped sample, the pipelines and the test data live at the root. Found at run time (the
/// nearest folder above the tested crate's `CARGO_MANIFEST_DIR` that holds `Cargo.lock`), not
/// baked in when this crate is compiled: checkouts sharing one target directory share this
/// crate's build, and a baked path would point into whichever checkout built it.
pub fn repo_path(rel: &str) -> std::path::PathBuf {
    let start = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::current_dir().expect("the tests' working directory"));
    let root = start
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .unwrap_or(&start);
    root.join(rel)
}
