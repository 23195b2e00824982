//! The diagnostics loop on real data nobody here wrote: the machine-tool thermal-drift run in
//! `../shared/external/fl-thermal-machine-tool/` (README there: MIT, CAIVIAC/FL_THERMAL).
//!
//! Converted to a campaign as a test fixture: the five displacement channels are bars on one
//! fixed plate length, `t1` is the air sensor, `t2..t16` are sensors of kind `other`, spindle
//! speed changes are events of kind `spindle` (value = rpm). The yardstick: the base
//! model fails badly (RMS near 9 µm on ch3); a lag-of-channel term for the best channel cuts that
//! at least 3x, and forward selection at least 5x within three terms.

use std::path::Path;

use dbbcal::campaign::*;
use dbbcal::narrative::sensors::description;
use dbbcal::pipeline::{analyse, RunPlan, Stage};
use dbbcal::series::{CampaignTables, EncoderLog, Event, SensorLog};

const START_NS: i64 = 1_700_000_000_000_000_000;
const RESOLUTION_NM: f64 = 1.0;

/// The whole second at or before `ns`, as a mount's time.
fn datetime(ns: i64) -> DeclaredTime {
    DeclaredTime::at(ns.div_euclid(1_000_000_000) * 1_000_000_000)
}

/// Read `data.csv` into a campaign directory.
fn convert(dir: &Path) {
    let csv = std::fs::read_to_string(
        crate::support::root().join("../shared/external/fl-thermal-machine-tool/data.csv"),
    )
    .unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let time_ns: Vec<i64> = rows
        .iter()
        .map(|r| START_NS + (r[col("time_s")] * 1e9) as i64)
        .collect();
    let bars: Vec<String> = (1..=5).map(|k| format!("ch{k}")).collect();
    let sensors: Vec<String> = (1..=16).map(|k| format!("t{k}")).collect();
    let mut tables = CampaignTables::default();
    for b in &bars {
        let c = col(&format!("{b}_um"));
        let counts = rows
            .iter()
            .map(|r| (r[c] * 1000.0 / RESOLUTION_NM).round() as i64)
            .collect();
        tables.encoders.insert(
            b.clone(),
            EncoderLog {
                time_ns: time_ns.clone(),
                counts,
            },
        );
    }
    for s in &sensors {
        let c = col(&format!("{s}_C"));
        tables.temperatures.insert(
            s.clone(),
            SensorLog {
                time_ns: time_ns.clone(),
                celsius: rows.iter().map(|r| r[c]).collect(),
            },
        );
    }
    let rpm = col("spindle_rpm");
    let mut last = f64::NAN;
    for (r, t) in rows.iter().zip(&time_ns) {
        if r[rpm] != last {
            tables.events.push(Event {
                time_ns: *t,
                bar: None,
                kind: dbbcal::series::EventKind::parse("spindle"),
                value: Some(r[rpm]),
            });
            last = r[rpm];
        }
    }
    let end = *time_ns.last().unwrap() + 1_000_000_000;
    let manifest = Manifest {
        campaign: CampaignSection {
            id: "fl-thermal-machine-tool".into(),
            reference_temperature_c: 26.0,
        },
        plate: PlateSection {
            material: "machine".into(),
            cte_ppm_per_k: 0.0,
            tilt_deg: 0.0,
            length: vec![PlateLength {
                id: "spindle".into(),
                mm: 300.0,
                u_um: 1.0,
            }],
        },
        sensor: sensors
            .iter()
            .map(|s| SensorDecl {
                id: s.clone(),
                kind: if s == "t1" {
                    SensorKind::Air
                } else {
                    SensorKind::Other
                },
            })
            .collect(),
        bar: bars
            .iter()
            .map(|b| BarDecl {
                id: b.clone(),
                resolution_nm: RESOLUTION_NM,
                fixed_length_mm: 200.0,
                sensor: Some("t1".into()),
            })
            .collect(),
        mount: bars
            .iter()
            .map(|b| MountDecl {
                bar: b.clone(),
                length: Some("spindle".into()),
                device: None,
                leg: None,
                tilt_deg: None,
                purpose: None,
                from: datetime(START_NS),
                to: datetime(end),
            })
            .collect(),
        device: Vec::new(),
    };
    dbbcal::io::write_campaign(
        dir,
        &manifest,
        &tables,
        &dbbcal::io::WriteOptions::default(),
    )
    .unwrap();
}

#[test]
fn machine_tool_run_base_fails_channel_terms_fix_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("fl");
    convert(&dir);
    // To look at the reports: DBB_FL_CAMPAIGN=DIR keeps a copy of the converted campaign there.
    if let Ok(keep) = std::env::var("DBB_FL_CAMPAIGN") {
        convert(Path::new(&keep));
    }
    let plan = RunPlan::for_stage(Stage::Diagnose, dir.clone(), None, &[])
        .and_then(|p| p.with_forward_steps(3))
        .unwrap();
    let results = analyse(&plan, dbbcal::io::read_campaign(&dir).unwrap());
    assert!(results.failed.is_empty(), "{:?}", results.failed);
    let d = results.diagnosis.as_ref().unwrap();
    let ch3 = results.bars.iter().find(|o| o.model.bar == "ch3").unwrap();
    let base_rms = ch3.model.rms_um;
    let diag3 = d.bars.iter().find(|b| b.bar == "ch3").unwrap();
    eprintln!(
        "ch3 base RMS {base_rms:.2} µm; best channels: {:?}",
        diag3
            .channels
            .iter()
            .take(5)
            .map(|c| (&c.channel, (c.explained_fraction * 1000.0).round() / 10.0))
            .collect::<Vec<_>>()
    );
    for c in d.candidates.iter().take(6) {
        let on3 = c.per_bar.iter().find(|b| b.bar == "ch3").unwrap();
        eprintln!(
            "  candidate {:<22} {:?} fleet {:.2} -> {:.2} µm, ch3 {:.2} -> {:.2} µm — {}",
            c.effect,
            c.verdict,
            c.rms_before_um,
            c.rms_after_um.unwrap_or(c.screened_rms_after_um),
            on3.rms_before_um,
            on3.rms_after_um.unwrap_or(on3.screened_rms_after_um),
            dbbcal::narrative::effects::explain_with(&c.effect, &d.sensors)
        );
    }
    for s in &d.ledger {
        eprintln!(
            "  ledger {:<22} fleet {:.3} µm, ch3 {:.3} µm",
            s.added,
            s.fleet_rms_um,
            s.rms_um.iter().find(|(b, _)| b == "ch3").unwrap().1
        );
    }
    // What the sensors plausibly are, against the data's README (its authors' inspection): t5 is
    // the fastest, hottest sensor near the spindle; t4 has fast fluctuations of about ±1 °C.
    for p in &d.sensors {
        eprintln!(
            "  sensor {}: {} (fast {:.3} K)",
            p.sensor,
            description(p),
            p.fast_fluctuation_k
        );
    }
    let sensor = |s: &str| d.sensors.iter().find(|p| p.sensor == s).unwrap();
    assert!(
        description(sensor("t5")).contains("heated by 'spindle' events"),
        "{:?}",
        sensor("t5")
    );
    assert!(
        description(sensor("t4")).contains("fast fluctuations"),
        "{:?}",
        sensor("t4")
    );
    assert!(description(sensor("t1")).starts_with("air sensor"));
    assert!(
        base_rms > 5.0,
        "the base model should fail badly on ch3, RMS {base_rms:.2} µm"
    );
    // The best single lag-of-channel term on ch3.
    let best_channel_term = d
        .candidates
        .iter()
        .filter(|c| c.effect.name().starts_with("lag:"))
        .filter_map(|c| {
            c.per_bar
                .iter()
                .find(|b| b.bar == "ch3")
                .and_then(|b| b.rms_after_um)
        })
        .fold(f64::INFINITY, f64::min);
    assert!(
        base_rms / best_channel_term >= 3.0,
        "best lag-of-channel term: {base_rms:.2} -> {best_channel_term:.2} µm"
    );
    for bl in &d.bar_ledgers {
        let steps: Vec<String> = bl
            .steps
            .iter()
            .map(|s| format!("{} {:.3}", s.added, s.fleet_rms_um))
            .collect();
        eprintln!("  {} alone: {}", bl.bar, steps.join(" -> "));
    }
    let fleet3 = d
        .ledger
        .last()
        .unwrap()
        .rms_um
        .iter()
        .find(|(b, _)| b == "ch3")
        .unwrap()
        .1;
    eprintln!(
        "fleet-wide forward selection on ch3: {base_rms:.2} -> {fleet3:.2} µm = {:.2}x in {} steps",
        base_rms / fleet3,
        d.ledger.len() - 1
    );
    assert!(d.ledger.len() <= 4);
    assert!(
        fleet3 < best_channel_term,
        "fleet forward selection should beat the single best term on ch3"
    );
    // The issue asks 5x on ch3 within three terms. ch3's own selection (beam of 3, innovations
    // likelihood-ratio tests) measured 7.47 -> 1.34 µm (5.56x: lag:t4-t1, lag:t8-t5,
    // lag:t8-t4). The fleet's selection serves five different axes at once: ch3 7.47 -> 1.59 µm
    // (4.69x), the fleet 6.34 -> 1.47 µm (4.3x); asserted as measured, so a regression shows.
    let fleet_base = d.ledger[0].fleet_rms_um;
    let fleet_end = d.ledger.last().unwrap().fleet_rms_um;
    assert!(
        fleet_base / fleet_end >= 4.3,
        "fleet forward selection: {fleet_base:.2} -> {fleet_end:.2} µm"
    );
    assert!(
        base_rms / fleet3 >= 4.5,
        "fleet forward selection on ch3: {base_rms:.2} -> {fleet3:.2} µm"
    );
    let own = &d.bar_ledgers.iter().find(|b| b.bar == "ch3").unwrap().steps;
    let own_end = own.last().unwrap().fleet_rms_um;
    eprintln!(
        "ch3's own forward selection: {base_rms:.2} -> {own_end:.2} µm = {:.2}x in {} steps",
        base_rms / own_end,
        own.len() - 1
    );
    assert!(own.len() <= 4);
    assert!(
        base_rms / own_end >= 5.0,
        "ch3's own forward selection: {base_rms:.2} -> {own_end:.2} µm"
    );
}
