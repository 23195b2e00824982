//! Bad configuration through the CLI (issue 14): a pipeline file, an effect name or a manifest
//! with a number out of range, a NaN or an infinity, or a name the campaign does not declare, is
//! refused with exit code 3 and one line naming the key, before any parquet file is read, and an
//! earlier output stays byte for byte as it was.

use std::path::{Path, PathBuf};

use crate::corpus::{check_refused, copy_dir};

/// A copy of the shipped sample under `root/name` whose encoder files are garbage: a run that
/// got as far as reading them would report them, so a refusal naming the key shows that the
/// plan was refused first.
fn poisoned_sample(root: &Path, name: &str) -> PathBuf {
    let d = root.join(name);
    copy_dir(Path::new("data/sample"), &d);
    for f in std::fs::read_dir(d.join("encoders")).unwrap().flatten() {
        std::fs::write(f.path(), b"not parquet").unwrap();
    }
    d
}

const NIGHTLY: &str = include_str!("../../pipelines/nightly.toml");

/// `pipelines/nightly.toml` with `from` replaced by `to`, written to `root/<name>.toml`.
fn pipeline(root: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    assert!(NIGHTLY.contains(from), "{from}");
    let path = root.join(format!("{name}.toml"));
    std::fs::write(&path, NIGHTLY.replacen(from, to, 1)).unwrap();
    path
}

#[test]
fn bad_pipeline_numbers_and_names_are_refused_before_any_data_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let cases: &[(&str, &str, &str, &[&str])] = &[
        (
            "study-nan",
            "[match]\n",
            "[match]\nstudy_step_s = nan\n",
            &[
                "match.study_step_s = NaN is out of range",
                "from 1 to 86400 s",
            ],
        ),
        (
            "limit-inf",
            "limit_um = 1.0",
            "limit_um = inf",
            &["match.limit_um = inf", "µm"],
        ),
        (
            "tolerance-negative",
            "# tolerance_um = 1.0",
            "tolerance_um = -1.0",
            &["diagnose.tolerance_um = -1"],
        ),
        (
            "beam-zero",
            "beam = 3",
            "beam = 0",
            &["diagnose.beam = 0", "from 1 to 10"],
        ),
        (
            "steps-huge",
            "forward_steps = 3",
            "forward_steps = 100000",
            &["diagnose.forward_steps = 100000", "from 0 to 10"],
        ),
        (
            "bin-nan",
            "# bin_s = 60",
            "bin_s = nan",
            &["model.bin_s = NaN", "from 0 to 3600 s"],
        ),
        (
            "bin-tiny",
            "# bin_s = 60",
            "bin_s = 0.001",
            &[
                "model.bin_s = 0.001",
                "0 (every reading) or from 1 to 3600 s",
            ],
        ),
        (
            "selection-rounds",
            "forward_steps = 3",
            "forward_steps = 5",
            &[
                "diagnose.forward_steps × diagnose.beam = 5 × 3",
                "at most 12",
            ],
        ),
        (
            "effect-unknown",
            "effects = [\"fixed_part\", \"scale\"]",
            "effects = [\"fixed_part\", \"scale\", \"air_gradent\"]",
            &[
                "effect-unknown.toml: model.effects[2]",
                "unknown effect \"air_gradent\"",
            ],
        ),
        (
            "effect-tau-zero",
            "effects = [\"fixed_part\", \"scale\"]",
            "effects = [\"fixed_part\", \"scale\", \"lag:T1@0\"]",
            &[
                "model.effects[2]",
                "@TAU_S = 0 is out of range",
                "from 1 to 1000000000 s",
            ],
        ),
        (
            "tau-suffix-inf",
            "effects = [\"fixed_part\", \"scale\"]",
            "effects = [\"fixed_part\", \"scale\", \"rate:T1@inf\"]",
            &[
                "model.effects[2]",
                "\"rate:T1@inf\"",
                "@TAU_S = inf is out of range",
                "from 1 to 1000000000 s",
            ],
        ),
        (
            "term-tau-zero",
            "[match]",
            "[[model.term]]\nchannel = \"T1\"\ntransform = \"lag\"\ntau_s = 0.0\n\n[match]",
            &["model.term[0].tau_s = 0 is out of range"],
        ),
        (
            "acceptance-gap",
            "[diagnose]",
            "[acceptance]\nmax_gap_s = -inf\n\n[diagnose]",
            &["acceptance.max_gap_s = -inf"],
        ),
        (
            "u-temperature",
            "[diagnose]",
            "[acceptance]\nu_temperature_k = 1e300\n\n[diagnose]",
            &["acceptance.u_temperature_k = 1e300", "from 0 to 10 K"],
        ),
        (
            "at-length",
            "# at_length = \"mid\"",
            "at_length = \"middle\"",
            &[
                "match.at_length = \"middle\" is not a plate length",
                "campaign.toml",
                "known: min, mid, max",
            ],
        ),
        (
            "channel",
            "effects = [\"fixed_part\", \"scale\"]",
            "effects = [\"fixed_part\", \"scale\", \"lag:T9\"]",
            &[
                "model.effects[2]",
                "\"lag:T9\"",
                "no channel \"T9\"",
                "sensors: T1, T2",
            ],
        ),
        (
            "difference",
            "effects = [\"fixed_part\", \"scale\"]",
            "effects = [\"fixed_part\", \"scale\", \"level:T2-T5\"]",
            &["model.effects[2]", "no channel \"T2-T5\""],
        ),
    ];
    for (name, from, to, needles) in cases {
        let campaign = poisoned_sample(root, name);
        let file = pipeline(root, name, from, to);
        check_refused(&campaign, &["run", file.to_str().unwrap()], 3, needles);
    }
    // Effects added on the command line, and the stage commands' numeric flag.
    let campaign = poisoned_sample(root, "cli");
    check_refused(
        &campaign,
        &[
            "run",
            "pipelines/nightly.toml",
            "--add-effect",
            "rate:T1@1e-9",
        ],
        3,
        &[
            "--add-effect",
            "\"rate:T1@0.000000001\"",
            "@TAU_S = 1e-9 is out of range",
        ],
    );
    check_refused(
        &campaign,
        &["run", "pipelines/nightly.toml", "--add-effect", "lag:H1"],
        3,
        &["--add-effect", "no channel \"H1\""],
    );
    check_refused(
        &campaign,
        &["identify", "--add-effect", "level:nope@600"],
        3,
        &["--effects/--add-effect", "no channel \"nope\""],
    );
    for bin in ["NaN", "inf", "7200", "0.001"] {
        check_refused(&campaign, &["identify", "--bin-s", bin], 3, &["--bin-s"]);
    }
    // A pipeline file that is a link to /dev/urandom is refused, not read until killed; so is
    // one larger than any pipeline file.
    let endless = root.join("endless.toml");
    std::os::unix::fs::symlink("/dev/urandom", &endless).unwrap();
    check_refused(
        &campaign,
        &["run", endless.to_str().unwrap()],
        3,
        &["endless.toml", "not a regular file"],
    );
    let huge = root.join("huge.toml");
    std::fs::write(&huge, format!("{NIGHTLY}\n{}", "#".repeat(2 << 20))).unwrap();
    check_refused(
        &campaign,
        &["run", huge.to_str().unwrap()],
        3,
        &["huge.toml", "larger than"],
    );
}

#[test]
fn bad_manifests_are_refused_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let cases: &[(&str, &str, &str, &[&str])] = &[
        (
            "id-escape",
            "id = \"sim-sample\"",
            "id = \"../../escape\"",
            &["campaign.toml: campaign.id:", "contains '/'"],
        ),
        (
            "id-dot",
            "id = \"sim-sample\"",
            "id = \".hidden\"",
            &["campaign.id:", "starts with a dot"],
        ),
        (
            "id-space",
            "id = \"sim-sample\"",
            "id = \"sim sample\"",
            &["campaign.id:", "contains ' '"],
        ),
        (
            "id-long",
            "id = \"sim-sample\"",
            &format!("id = \"{}\"", "x".repeat(101)),
            &["campaign.id:", "101 characters long", "at most 100"],
        ),
        (
            "bar-control",
            "id = \"B01\"",
            "id = \"B\\u0001\"",
            &["bar[0]:", "contains a control character"],
        ),
        (
            "resolution-nan",
            "resolution_nm = 5.0",
            "resolution_nm = nan",
            &["bar[0] (\"B01\"): resolution_nm = NaN"],
        ),
        (
            "reference-inf",
            "reference_temperature_c = 20.0",
            "reference_temperature_c = inf",
            &["campaign: reference_temperature_c = inf is out of range"],
        ),
        (
            "tilt",
            "tilt_deg = 60.0",
            "tilt_deg = 600.0",
            &["plate: tilt_deg = 600 is out of range", "degrees"],
        ),
        (
            "length-huge",
            "mm = 250.0006",
            "mm = 1e12",
            &["plate.length[0] (\"min\"): mm = 1000000000000 is out of range"],
        ),
        (
            "year",
            "from = 2026-",
            "from = 1900-",
            &[
                "mount[0]",
                "from = 1900-",
                "outside 1970-01-01T00:00:00Z .. 2200-01-01T00:00:00Z",
            ],
        ),
    ];
    for (name, from, to, needles) in cases {
        let campaign = poisoned_sample(root, name);
        let manifest = std::fs::read_to_string(campaign.join("campaign.toml")).unwrap();
        assert!(manifest.contains(from), "{from}");
        std::fs::write(
            campaign.join("campaign.toml"),
            manifest.replacen(from, to, 1),
        )
        .unwrap();
        check_refused(&campaign, &["run", "pipelines/nightly.toml"], 3, needles);
        check_refused(&campaign, &["ingest"], 3, needles);
    }
}
