//! Plan validation (issue 14): every number of a pipeline file in range, and what the plan names
//! in the campaign (plate length, channels) declared by its manifest, all before any parquet file
//! is read. Property test: arbitrary and mutated pipeline files never panic.

use std::path::{Path, PathBuf};

use proptest::prelude::*;

use super::*;
use crate::model::Effect;
use dbbcal_testkit::{apply, cases, edit};

/// Every key of a pipeline file, at valid values, on the shipped sample.
const FULL: &str = r#"
[pipeline]
name = "full"
stages = ["ingest", "identify", "match", "match_study", "diagnose", "calibrate", "compensate", "acceptance", "report"]
campaign = "data/sample"

[model]
effects = ["fixed_part", "scale", "rate:T1@600", "lag:T2-T1"]
bin_s = 60.0
[[model.term]]
channel = "T2"
transform = "level"
tau_s = 1800.0

[match]
limit_um = 1.0
at_length = "mid"
study_step_s = 60.0

[diagnose]
forward_steps = 3
beam = 3
tolerance_um = 1.0

[acceptance]
tolerance_um = 1.0
u_temperature_k = 0.05
model_difference = false
max_gap_s = 300.0
"#;

fn write(dir: &Path, text: &str) -> PathBuf {
    let path = dir.join("p.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn plan(text: &str, add: &[&str]) -> Result<RunPlan, String> {
    let dir = tempfile::tempdir().unwrap();
    let add: Vec<String> = add.iter().map(|s| s.to_string()).collect();
    RunPlan::from_pipeline_file(&write(dir.path(), text), None, None, &add).map_err(|e| {
        let msg = e.to_string();
        assert!(!msg.contains('\n'), "not one line: {msg}");
        msg
    })
}

fn refused(text: &str, add: &[&str], needles: &[&str]) {
    let msg = plan(text, add)
        .err()
        .unwrap_or_else(|| panic!("accepted: {text}"));
    for n in needles {
        assert!(msg.contains(n), "{n:?} missing from: {msg}");
    }
}

#[test]
fn the_full_file_and_the_shipped_pipelines_are_accepted() {
    let p = plan(FULL, &[]).expect("full");
    assert_eq!(p.matching.at_length.as_deref(), Some("mid"));
    assert_eq!(p.effects.len(), 5);
    for f in ["nightly", "acceptance", "reference-match"] {
        let text = std::fs::read_to_string(format!("pipelines/{f}.toml")).unwrap();
        plan(
            &text,
            &["rate:T1@600", "level:time_of_day_h", "lag:event:door"],
        )
        .expect(f);
    }
}

#[test]
fn every_number_is_range_checked_with_its_key() {
    let cases: &[(&str, &str, &[&str])] = &[
        ("study_step_s = 60.0", "study_step_s = nan", &["match.study_step_s = NaN is out of range", "from 1 to 86400 s"]),
        ("study_step_s = 60.0", "study_step_s = 0.001", &["match.study_step_s = 0.001"]),
        ("limit_um = 1.0", "limit_um = inf", &["match.limit_um = inf", "from 0.000001 to 1000 µm"]),
        ("limit_um = 1.0", "limit_um = -1.0", &["match.limit_um = -1"]),
        ("tau_s = 1800.0", "tau_s = inf", &["model.term[0].tau_s = inf", "from 1 to 1000000000 s"]),
        ("tau_s = 1800.0", "tau_s = -5.0", &["model.term[0].tau_s = -5"]),
        ("forward_steps = 3", "forward_steps = 1000000", &["diagnose.forward_steps = 1000000", "from 0 to 10"]),
        ("beam = 3", "beam = 0", &["diagnose.beam = 0", "from 1 to 10"]),
        ("beam = 3", "beam = -1", &["beam"]),
        ("tolerance_um = 1.0\n\n[acceptance]", "tolerance_um = nan\n\n[acceptance]", &["diagnose.tolerance_um = NaN"]),
        ("tolerance_um = 1.0\nu_temperature_k", "tolerance_um = 0.0\nu_temperature_k", &["acceptance.tolerance_um = 0"]),
        ("u_temperature_k = 0.05", "u_temperature_k = -inf", &["acceptance.u_temperature_k = -inf", "from 0 to 10 K"]),
        ("max_gap_s = 300.0", "max_gap_s = 1e300", &["acceptance.max_gap_s = 1e300"]),
        ("bin_s = 60.0", "bin_s = nan", &["model.bin_s = NaN", "from 0 to 3600 s"]),
        ("bin_s = 60.0", "bin_s = 7200", &["model.bin_s = 7200"]),
        ("rate:T1@600", "rate:T1@inf", &["model.effects[2]: \"rate:T1@inf\": the starting time constant @TAU_S = inf is out of range"]),
        ("rate:T1@600", "rate:T1@1e-3", &["model.effects[2]", "@TAU_S = 0.001"]),
        ("rate:T1@600", "rate:T1@nan", &["model.effects[2]: \"rate:T1@nan\": the starting time constant @TAU_S = NaN is out of range", "from 1 to 1000000000 s"]),
        ("rate:T1@600", "rate:T1@0", &["model.effects[2]: \"rate:T1@0\": the starting time constant @TAU_S = 0 is out of range"]),
        ("rate:T1@600", "rate_of:T1", &["model.effects[2]: unknown effect \"rate_of:T1\""]),
    ];
    for (from, to, needles) in cases {
        assert!(FULL.contains(from), "{from}");
        refused(&FULL.replacen(from, to, 1), &[], needles);
    }
    refused(
        FULL,
        &["lag:T1@1e12"],
        &[
            "--add-effect: \"lag:T1@1000000000000\"",
            "@TAU_S = 1000000000000 is out of range",
        ],
    );
}

#[test]
fn numbers_are_checked_before_the_campaign_is_looked_at() {
    // A missing campaign directory: the bad number is still what is reported.
    let text = FULL
        .replace(
            "campaign = \"data/sample\"",
            "campaign = \"/nonexistent/campaign\"",
        )
        .replace("beam = 3", "beam = 0");
    refused(&text, &[], &["diagnose.beam = 0"]);
}

#[test]
fn names_the_campaign_does_not_declare_are_refused_at_plan_time() {
    refused(
        &FULL.replace("at_length = \"mid\"", "at_length = \"huge\""),
        &[],
        &["match.at_length = \"huge\" is not a plate length of data/sample/campaign.toml (known: min, mid, max)"],
    );
    refused(
        &FULL.replace("rate:T1@600", "rate:T9@600"),
        &[],
        &["model.effects[2]: \"rate:T9@600\": no channel \"T9\" in data/sample/campaign.toml (sensors: T1, T2"],
    );
    refused(
        &FULL.replace("lag:T2-T1", "lag:T2-T7"),
        &[],
        &["model.effects[3]: \"lag:T2-T7\": no channel \"T2-T7\""],
    );
    refused(
        &FULL.replace("channel = \"T2\"", "channel = \"H1\""),
        &[],
        &["model.term[0]: \"level:H1@1800\": no channel \"H1\""],
    );
    refused(
        FULL,
        &["level:nothing"],
        &["--add-effect: \"level:nothing\": no channel \"nothing\""],
    );
    // Stage subcommands check theirs too.
    let e = RunPlan::for_stage(
        Stage::Identify,
        PathBuf::from("data/sample"),
        None,
        &["fixed_part".into(), "lag:T3".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("--effects/--add-effect: \"lag:T3\": no channel \"T3\""),
        "{e}"
    );
    let e = RunPlan::for_stage(
        Stage::Identify,
        PathBuf::from("data/sample"),
        None,
        &["rate:T1@inf".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("--effects/--add-effect: \"rate:T1@inf\""), "{e}");
}

#[test]
fn a_bad_manifest_is_refused_at_plan_time() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string("data/sample/campaign.toml")
        .unwrap()
        .replace("id = \"sim-sample\"", "id = \"../escape\"");
    std::fs::write(dir.path().join("campaign.toml"), text).unwrap();
    let e = RunPlan::for_stage(Stage::Ingest, dir.path().to_path_buf(), None, &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("campaign.toml: campaign.id: \"../escape\" contains '/'"),
        "{e}"
    );
}

/// What an accepted plan promises.
fn check_plan(p: &RunPlan) {
    let within = |v: f64, limit: dbbcal_core::limits::Limit| limit.contains(v);
    assert!(within(p.matching.limit_um, limits::TOLERANCE_UM));
    assert!(within(p.matching.study_step_s, limits::STUDY_STEP_S));
    assert!(within(p.acceptance.tolerance_um, limits::TOLERANCE_UM));
    assert!(within(
        p.acceptance.u_temperature_k,
        limits::U_TEMPERATURE_K
    ));
    assert!(within(p.acceptance.max_gap_s, limits::MAX_GAP_S));
    assert!(p
        .diagnose
        .tolerance_um
        .is_none_or(|t| within(t, limits::TOLERANCE_UM)));
    assert!((1..=10).contains(&p.diagnose.beam) && p.diagnose.forward_steps <= 10);
    assert!(within(p.bin_s, limits::BIN_S));
    for e in &p.effects {
        if let Effect::Channel {
            tau0_s: Some(t), ..
        } = e
        {
            assert!(within(*t, limits::TAU_S), "{e:?}");
        }
    }
}

proptest! {
    #![proptest_config(cases(128))]

    #[test]
    fn mutated_pipeline_files_plan_or_fail_cleanly(
        edits in prop::collection::vec(edit(), 1..5),
    ) {
        if let Ok(p) = plan(&apply(FULL, &edits), &[]) {
            check_plan(&p);
        }
    }

    #[test]
    fn arbitrary_pipeline_text_plans_or_fails_cleanly(text in any::<String>()) {
        if let Ok(p) = plan(&text, &[]) {
            check_plan(&p);
        }
    }

    #[test]
    fn arbitrary_effect_names_plan_or_fail_cleanly(
        name in prop_oneof![
            any::<String>(),
            ("(lag|rate|level):", "[A-Za-z0-9:_-]{0,8}", "(@[-+0-9.einfa]{0,8})?")
                .prop_map(|(a, b, c)| format!("{a}{b}{c}")),
        ],
    ) {
        if let Ok(p) = plan(FULL, &[name.as_str()]) {
            check_plan(&p);
        }
    }
}

#[test]
fn bin_s_takes_seconds_or_auto() {
    let with = |v: &str| FULL.replace("bin_s = 60.0", &format!("bin_s = {v}"));
    let p = plan(&with("\"auto\""), &[]).unwrap();
    assert!(p.automatic_bins);
    let p = plan(&with("30"), &[]).unwrap();
    assert_eq!((p.bin_s, p.automatic_bins), (30.0, false));
    refused(&with("\"fast\""), &[], &["\"auto\"", "fast"]);
}
