//! The diagnostics loop on data with a hidden effect (issue: the diagnosis ranks the true effect
//! — or the right channel — first; after adding it the RMS falls to within 1.2x the simulated
//! noise and the base parameters lose their bias, i.e. alpha, beta, tau_R and tau_S lie within
//! 3 standard uncertainties of the truth; on the base-only campaign no candidate is proposed,
//! i.e. significant and material).

use dbbcal::identify::identify;
use dbbcal::model::Effect;
use dbbcal::narrative::diagnosis::reason;
use dbbcal::pipeline::{analyse, RunPlan, RunResults, Stage};
use dbbcal::simulate::{FleetConfig, SimConfig, Truth};

use crate::support::simulate_campaign;

/// A small campaign: 3 bars, 6 days, 30 s, noise 0.02 µm; `switch` turns one effect on.
fn config(seed: u64, switch: impl FnOnce(&mut SimConfig)) -> SimConfig {
    let mut cfg = SimConfig {
        seed,
        campaign_id: format!("hidden-{seed}"),
        duration_days: 6.0,
        sample_s: 30.0,
        noise_um: 0.02,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    };
    switch(&mut cfg);
    cfg
}

/// Simulate `cfg` (as `name`), then ingest, identify and rank the candidates (no forward
/// selection): the results, with the diagnosis, and the simulator's truth.
fn ranked(name: &str, cfg: &SimConfig) -> (RunResults, Truth) {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, truth) = simulate_campaign(tmp.path(), name, cfg);
    let plan = RunPlan::for_stage(Stage::Diagnose, dir.clone(), None, &[])
        .and_then(|p| p.with_forward_steps(0))
        .unwrap();
    let results = analyse(&plan, dbbcal::io::read_campaign(&dir).unwrap());
    (results, truth)
}

/// Why each proposed candidate was proposed (empty: the model is adequate).
fn proposed_reasons(diagnosis: &dbbcal::pipeline::Diagnosis) -> Vec<String> {
    diagnosis
        .candidates
        .iter()
        .filter(|c| c.proposed())
        .map(|c| reason(&c.reason))
        .collect()
}

/// Simulate, diagnose (no forward selection), and check the ranking and the fix: `expected`
/// (the effect string the diagnosis prints) first and proposed; after adding it, per bar, the
/// RMS within 1.2x the noise and each base parameter within 3 standard uncertainties (HAC) of
/// the truth. Prints, per bar, the rank, RMS/noise and the base parameters' errors before and
/// after.
fn check(name: &str, cfg: SimConfig, expected: &str) {
    let (results, truth) = ranked(name, &cfg);
    let diagnosis = results.diagnosis.as_ref().expect("diagnosis");
    let ranking: Vec<String> = diagnosis
        .candidates
        .iter()
        .map(|c| {
            format!(
                "{} ({:?}, ΔRMS {:.2e} µm, shift {:.2e} µm, ΔBIC {:.0}, p {:.1e}, {} bars)",
                c.effect,
                c.verdict,
                c.gain_um(),
                c.screened_shift_um,
                c.delta_bic.unwrap_or(f64::NAN),
                c.p_value.unwrap_or(f64::NAN),
                c.bars_improved
            )
        })
        .collect();
    eprintln!("{name}: {}", ranking.join("; "));
    for c in &diagnosis.candidates {
        let errors: Vec<String> = c
            .per_bar
            .iter()
            .filter_map(|b| b.error.as_ref().map(ToString::to_string))
            .collect();
        eprintln!("  {}: {} {errors:?}", c.effect, reason(&c.reason));
    }
    let rank = diagnosis
        .candidates
        .iter()
        .position(|c| c.effect.name() == expected)
        .map_or("-".to_string(), |r| (r + 1).to_string());
    let first = &diagnosis.candidates[0];

    // Add the true effect (exactly the string the diagnosis prints) and refit; the numbers are
    // printed before the assertions so that a failure still shows them.
    let mut effects = dbbcal::model::base_effects();
    effects.push(Effect::parse(expected).unwrap());
    let mut failures = Vec::new();
    for o in &results.bars {
        let after = identify(&o.series, &effects).unwrap();
        let t = truth.bars.iter().find(|b| b.id == o.model.bar).unwrap();
        let base_truth = [
            ("alpha_ppm_per_k", t.alpha_ppm_per_k),
            ("beta_ppm_per_k", t.beta_ppm_per_k),
            ("tau_r_s", t.tau_r_s),
            ("tau_s_s", t.tau_s_s),
        ];
        let errors = |m: &dbbcal::identify::BarModel| -> Vec<String> {
            base_truth
                .iter()
                .map(|(param, truth)| {
                    let p = m.param(param).unwrap();
                    format!(
                        "{param} {:+.2}% ({:+.1} u)",
                        (p.value - truth) / truth.abs() * 100.0,
                        (p.value - truth) / p.u
                    )
                })
                .collect()
        };
        eprintln!(
            "{name} {}: rank of {expected} {rank}; rms/noise {:.2} -> {:.2}\n  before: {}\n  after:  {}",
            o.model.bar,
            o.model.rms_um / cfg.noise_um,
            after.rms_um / cfg.noise_um,
            errors(&o.model).join(", "),
            errors(&after).join(", "),
        );
        if after.rms_um > 1.2 * cfg.noise_um {
            failures.push(format!("{}: rms after {:.4} µm", o.model.bar, after.rms_um));
        }
        // "Lose their bias": after the fix the truth lies within 3 standard uncertainties (HAC).
        for (param, truth) in base_truth {
            let p = after.param(param).unwrap();
            let z = (p.value - truth).abs() / p.u;
            if z.is_nan() || z >= 3.0 {
                failures.push(format!(
                    "{}: {param} {:.4} ± {:.4} vs truth {truth:.4} ({z:.1} u) after adding",
                    o.model.bar, p.value, p.u
                ));
            }
        }
    }
    assert_eq!(
        first.effect.name(),
        expected,
        "{name}: expected {expected} first, ranking {ranking:?}"
    );
    assert!(
        first.proposed(),
        "{name}: the true effect is not proposed: {}",
        reason(&first.reason)
    );
    assert!(failures.is_empty(), "{name}: {failures:#?}");
}

#[test]
fn head_heating_is_found() {
    check(
        "head",
        config(31, |c| c.effects.head_heating.enabled = true),
        "head_heating",
    );
}

#[test]
fn second_thermal_path_is_found() {
    check(
        "second-path",
        config(32, |c| c.effects.second_path.enabled = true),
        "second_path",
    );
}

#[test]
fn air_gradient_is_found() {
    // The bar sees T1 + w (T2 - T1) on both of its paths; `air_gradient` carries the gradient
    // through both (I_min with tau_R, I_p with tau_S).
    check(
        "gradient",
        config(33, |c| c.effects.sensor_gradient.enabled = true),
        "air_gradient",
    );
}

#[test]
fn settling_after_mounting_is_found() {
    check(
        "settling",
        config(34, |c| c.effects.settling.enabled = true),
        "settling",
    );
}

#[test]
fn plate_expansion_is_found() {
    // The plate follows the air with a 3 h lag, its sensor P1 reads it with white noise; the
    // term uses P1 smoothed without delay (a raw noisy level biased alpha and beta by ~5 u).
    check(
        "plate",
        config(35, |c| c.effects.plate_expansion.enabled = true),
        "plate_expansion",
    );
}

#[test]
fn an_effect_outside_the_catalogue_is_caught_by_a_channel_term() {
    check(
        "hidden-channel",
        config(36, |c| c.effects.hidden_channel.enabled = true),
        "lag:H1",
    );
}

/// A heat source no catalogue names (an electronics cabinet beside the plate, logged by a sensor
/// of kind `other`, running on working days): its excess over the air warms every bar through
/// a lag of its own and through both lengths, so a generic `lag:` term (one gain a bar) cannot
/// follow it from mount to mount; `heat:` can.
#[test]
fn a_heat_source_outside_the_catalogue_is_caught_by_a_heat_term() {
    check(
        "heat-source",
        config(38, |c| c.effects.heat_source.enabled = true),
        "heat:T1-C1",
    );
}

/// Three hidden effects at once (head heating, an air gradient, settling): the fleet's forward
/// selection names each of them and reaches the noise within three steps. Before the refits
/// searched the defaults' basin and the path was chosen by its total ΔBIC, such a campaign
/// stalled several times above the noise.
#[test]
fn three_hidden_effects_at_once_are_all_named_and_removed() {
    let cfg = config(39, |c| {
        c.effects.head_heating.enabled = true;
        c.effects.sensor_gradient.enabled = true;
        c.effects.settling.enabled = true;
    });
    check_ledger(
        "three",
        &cfg,
        &[
            ("head_heating", |e| e == "head_heating"),
            AIR_GRADIENT,
            ("settling", |e| e == "settling"),
        ],
    );
}

/// The plate's expansion and a heat source no catalogue names (a cabinet logged by C1) at once,
/// alone and with an air gradient: a generic term of C1's difference with the plate sensor
/// (`heat:P1-C1`) carries much of both with one gain a bar, so the forward selection must name
/// the plate as well as a term of C1. On these small campaigns (3 bars, 6 days) the ledgers are
/// the same without the plate split of `diagnose::selection` (seeds 40-45 tried); at 10 bars and
/// 15 days it decides (`bench/loop_check.py`, k = 3, seed 1), at about 13 s a run.
#[test]
fn the_plate_and_a_heat_source_at_once_are_both_named_and_removed() {
    let cfg = config(40, |c| {
        c.effects.plate_expansion.enabled = true;
        c.effects.heat_source.enabled = true;
    });
    check_ledger("plate-heat", &cfg, &[PLATE, HEAT_SOURCE]);
}

#[test]
fn the_plate_a_heat_source_and_an_air_gradient_at_once_are_all_named_and_removed() {
    let cfg = config(40, |c| {
        c.effects.plate_expansion.enabled = true;
        c.effects.heat_source.enabled = true;
        c.effects.sensor_gradient.enabled = true;
    });
    check_ledger("plate-heat-air", &cfg, &[PLATE, HEAT_SOURCE, AIR_GRADIENT]);
}

/// What a ledger step must add (printed when it is missing) and which effect names count.
type Named = (&'static str, fn(&str) -> bool);
const PLATE: Named = ("plate_expansion", |e| e == "plate_expansion");
const AIR_GRADIENT: Named = ("air_gradient", |e| e == "air_gradient");
/// The cabinet counts as named by any term of its sensor C1 (`heat:C1`, `heat:T1-C1`, `lag:C1`...).
const HEAT_SOURCE: Named = ("a term of C1", |e| e.contains("C1"));

/// Simulate `cfg`, run the fleet forward selection for as many steps as `named` has entries
/// and check the ledger: each `(what, is)` matched by an added effect's name, and the fleet RMS
/// after the last step within 1.2 × the noise. Prints the ledger first.
fn check_ledger(name: &str, cfg: &SimConfig, named: &[Named]) {
    let (steps, added, end) = fleet_ledger(name, cfg, Some(named.len()));
    eprintln!("{name}: {}", steps.join(" -> "));
    for (what, is) in named {
        assert!(
            added.iter().any(|a| is(a)),
            "{name}: {what} not named: {steps:?}"
        );
    }
    assert!(
        end <= 1.2 * cfg.noise_um,
        "{name}: stalled at {end:.4} µm ({:.2}x the noise): {steps:?}",
        end / cfg.noise_um
    );
}

/// Simulate `cfg` (as `name`) and run the diagnosis with `forward_steps` (the default when
/// `None`): the fleet ledger's steps as "effect RMS", the effects it adds, and its last RMS (µm).
fn fleet_ledger(
    name: &str,
    cfg: &SimConfig,
    forward_steps: Option<usize>,
) -> (Vec<String>, Vec<String>, f64) {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, _) = simulate_campaign(tmp.path(), name, cfg);
    let mut plan = RunPlan::for_stage(Stage::Diagnose, dir.clone(), None, &[]).unwrap();
    if let Some(steps) = forward_steps {
        plan = plan.with_forward_steps(steps).unwrap();
    }
    let results = analyse(&plan, dbbcal::io::read_campaign(&dir).unwrap());
    let ledger = &results.diagnosis.as_ref().unwrap().ledger;
    let steps = ledger
        .iter()
        .map(|s| format!("{} {:.4}", s.added, s.fleet_rms_um))
        .collect();
    let added = ledger.iter().skip(1).map(|s| s.added.name()).collect();
    (steps, added, ledger.last().unwrap().fleet_rms_um)
}

#[test]
fn base_only_campaign_raises_no_false_alarm() {
    let (results, _) = ranked("clean", &config(37, |_| {}));
    let alarms = proposed_reasons(results.diagnosis.as_ref().unwrap());
    assert!(alarms.is_empty(), "false alarms: {alarms:?}");
}

/// A weak air gradient (T2 − T1 wandering by ±0.015 K; the bars feel 40 % of it): the base model
/// is 0.5 % above the noise, and `lag:T2`, `air_gradient` and `lag:T2-T1` each remove about
/// 0.11 nm of the fleet RMS. `lag:T2` does it by trading its gain against the base paths (it
/// moves the model's own terms by 0.08 µm, alpha by −45 %); `air_gradient`, the truth, leaves
/// them in place. A generic channel term counts only for the RMS it removes, so nothing is
/// proposed; before this rule `lag:T2` was proposed as the missing effect.
#[test]
fn a_generic_channel_term_is_not_proposed_for_its_shift_alone() {
    let cfg = sample_campaign_with(
        |table| {
            let room = table["room"].as_table_mut().unwrap();
            for key in [
                "gradient_k",
                "gradient_daily_k",
                "gradient_ac_k",
                "gradient_wander_k",
            ] {
                room.insert(key.into(), toml::Value::Float(0.015));
            }
        },
        "sensor_gradient = { enabled = true, weight_t2 = 0.4 }",
    );
    let (results, truth) = ranked("weak-gradient", &cfg);
    let diagnosis = results.diagnosis.as_ref().unwrap();
    for c in &diagnosis.candidates {
        eprintln!("{}: {:?}: {}", c.effect, c.verdict, reason(&c.reason));
    }
    let proposed = proposed_reasons(diagnosis);
    assert!(proposed.is_empty(), "proposed: {proposed:?}");
    // The alias: shifting the model by more than the threshold, its gain below it, so screened
    // out (or, refitted, immaterial) as a channel term.
    let min_gain = diagnosis.criteria.min_gain_um;
    let alias = diagnosis
        .candidates
        .iter()
        .find(|c| c.effect.name() == "lag:T2")
        .unwrap();
    let why = reason(&alias.reason);
    assert!(!alias.proposed(), "{why}");
    assert!(alias.screened_shift_um >= min_gain, "{why}");
    assert!(
        why.contains("a channel term counts only for what it removes"),
        "{why}"
    );
    // Why it must not be proposed: added, it takes alpha far from the truth on every bar.
    let mut effects = dbbcal::model::base_effects();
    effects.push(Effect::parse("lag:T2").unwrap());
    for o in &results.bars {
        let with_alias = identify(&o.series, &effects).unwrap();
        let t = truth.bars.iter().find(|b| b.id == o.model.bar).unwrap();
        let alpha = with_alias.param("alpha_ppm_per_k").unwrap();
        let z = (alpha.value - t.alpha_ppm_per_k) / alpha.u;
        eprintln!(
            "{}: alpha with lag:T2 {:.3} ± {:.3}, truth {:.3} ({z:.1} u)",
            o.model.bar, alpha.value, alpha.u, t.alpha_ppm_per_k
        );
        assert!(
            z.abs() > 5.0,
            "{}: lag:T2 left alpha within 5 u",
            o.model.bar
        );
    }
}

/// The shipped sample's simulation (`pipelines/sim-sample.toml`) cut to 4 bars and 5 days,
/// changed by `edit`, with the `[effects]` table `effects` (TOML).
fn sample_campaign_with(edit: impl FnOnce(&mut toml::Table), effects: &str) -> SimConfig {
    let text = std::fs::read_to_string("pipelines/sim-sample.toml").unwrap();
    let mut table: toml::Table = toml::from_str(&text).unwrap();
    table["fleet"]
        .as_table_mut()
        .unwrap()
        .insert("n_bars".into(), toml::Value::Integer(4));
    table.insert("duration_days".into(), toml::Value::Float(5.0));
    table.insert("effects".into(), toml::from_str(effects).unwrap());
    edit(&mut table);
    table.try_into().unwrap()
}

/// A plate expansion the base model bends its time constants to mimic: the refit with
/// `plate_expansion` started from the base's time constants alone stopped short of the fit made
/// afresh (seed 13 at 10 s, bar B03: 20.58 nm against 20.05; seed 1 at 30 s: fleet 20.32 nm
/// against 20.00), and forward selection then added a spurious `second_path`. The diagnosis's
/// refits also search the defaults' basin (`identify::defaults_basin`, on the series' 300-s
/// copy), so each bar's refit is as good as the fit made afresh.
#[test]
fn a_refit_from_a_bent_base_is_as_good_as_the_fit_made_afresh() {
    for (seed, sample_s) in [(13, 10.0), (1, 30.0)] {
        let cfg = sample_campaign_with(
            |table| {
                table.insert("seed".into(), toml::Value::Integer(seed));
                table.insert("sample_s".into(), toml::Value::Float(sample_s));
            },
            "plate_expansion = { enabled = true }",
        );
        let (results, _) = ranked("bent-base", &cfg);
        let diagnosis = results.diagnosis.as_ref().unwrap();
        let first = &diagnosis.candidates[0];
        assert_eq!(
            first.effect.name(),
            "plate_expansion",
            "{}",
            reason(&first.reason)
        );
        assert!(first.proposed(), "{}", reason(&first.reason));
        let mut effects = dbbcal::model::base_effects();
        effects.push(Effect::PlateExpansion);
        for (o, refit) in results.bars.iter().zip(&first.per_bar) {
            let afresh = identify(&o.series, &effects).unwrap().rms_um;
            let from_base = refit.rms_after_um.unwrap();
            let bar = &o.model.bar;
            eprintln!(
                "seed {seed}, {sample_s} s, {bar}: refit from the base {from_base:.6} µm, \
                 afresh {afresh:.6} µm"
            );
            assert!(
                from_base <= afresh * (1.0 + 1e-6),
                "seed {seed}, {sample_s} s, {bar}: the refit from the base stopped at \
                 {from_base:.6} µm, afresh {afresh:.6} µm"
            );
        }
    }
}

/// A base model that bends a time constant to the model's limit to mimic a missing effect names
/// it, is left out of matching with a note, and is whole again once the effect is added: seed
/// 34's settling drives bar B02's `tau_s_s` to 1e9 s (a lag that slow is the integral of the
/// air; only `beta / tau_S` is determined), and with `settling` B02 is matched.
#[test]
fn a_time_constant_run_to_the_limit_is_named_and_the_bar_left_out_of_matching() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = config(34, |c| c.effects.settling.enabled = true);
    let (dir, _) = simulate_campaign(tmp.path(), "settling-limit", &cfg);
    let pipeline = crate::support::root().join("pipelines/reference-match.toml");
    let run = |out: &str, extra: &[&str]| {
        let out = tmp.path().join(out);
        let (summary, said) = crate::support::run_record(
            pipeline.to_str().unwrap(),
            &dir,
            &out,
            extra,
            "summary.json",
        );
        let report = std::fs::read_to_string(out.join("report.md")).unwrap();
        (summary, said, report)
    };
    let bar = |summary: &serde_json::Value, id: &str| {
        summary["bars"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["bar"] == id)
            .cloned()
            .unwrap()
    };
    let (base, said, report) = run("base", &[]);
    let b02 = bar(&base, "B02");
    let named = &b02["not_identifiable"][0];
    assert_eq!(
        named["params"],
        serde_json::json!(["beta_ppm_per_k", "tau_s_s"]),
        "{b02}"
    );
    let reason = named["reason"].as_str().unwrap();
    assert!(
        reason.starts_with("the fit ran tau_s_s to the model's limit (1e9 s"),
        "{reason}"
    );
    assert!(
        b02["params"]["tau_s_s"]["value"].as_f64().unwrap() > 9.99e8,
        "{b02}"
    );
    let mismatch = &base["reference"]["mismatch_um"];
    assert!(
        mismatch.get("B02").is_none() && base["reference"]["bar"] != "B02",
        "{mismatch}"
    );
    let note = "B02 left out of matching: its data do not determine beta_ppm_per_k, tau_s_s";
    assert!(said.contains(note), "{said}");
    assert!(report.contains(note), "{report}");
    assert!(report.contains("tau_s_s          1.0e9 ± "), "{report}");

    let (fixed, said, _) = run("settling", &["--add-effect", "settling"]);
    let b02 = bar(&fixed, "B02");
    assert_eq!(b02["not_identifiable"], serde_json::json!([]), "{b02}");
    let matched = fixed["reference"]["bar"] == "B02"
        || fixed["reference"]["mismatch_um"].get("B02").is_some();
    assert!(matched, "{}", fixed["reference"]);
    assert!(!said.contains("left out of matching"), "{said}");
}

/// Settling and a second thermal path at once, on our simulator's identification campaign cut
/// to 4 bars, 8 days and 30-s readings (seed 1): the coarse beam kept a path with a channel term
/// between the two (`settling` 31.1 → `lag:T2` 22.9 → `second_path` 20.0 nm), a step the
/// readings do not support once both effects are in. The readings' order of that ledger
/// (`selection::in_readings_order`) stops short of it, and its shorter ledger, lower in BIC, is
/// kept: the two hidden effects in two steps, at the noise.
#[test]
fn a_step_the_readings_do_not_support_after_the_others_is_left_out() {
    let path = crate::support::root().join("pipelines/sim-identification.toml");
    let mut cfg = crate::support::sim_config(path.to_str().unwrap());
    cfg.seed = 1;
    cfg.campaign_id = "settling-second-path".into();
    cfg.duration_days = 8.0;
    cfg.sample_s = 30.0;
    cfg.fleet.as_mut().unwrap().n_bars = 4;
    cfg.effects.second_path.enabled = true;
    cfg.effects.settling.enabled = true;
    let (steps, added, end) = fleet_ledger("settling-second-path", &cfg, None);
    assert_eq!(added, ["settling", "second_path"], "{steps:?}");
    assert!(end <= 1.2 * cfg.noise_um, "{steps:?}");
}
