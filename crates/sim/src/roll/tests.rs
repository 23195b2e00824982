//! The roll simulator against the analysis of `dbbcal-machine` (a dev-dependency): noise-free
//! readings give the true roll back; a zero offset on C is the spec's ramp.

use super::*;
use dbbcal_core::roll_campaign::{RollCampaign, RollCampaignLogs};
use dbbcal_io::manifest::{TomlCampaign, TomlManifest};
use dbbcal_machine::roll::{study, RollOptions};

fn logs(sim: &RollSimulation, station: bool, pass: bool) -> RollCampaignLogs {
    let text = sim.manifest.to_toml_string().unwrap();
    let mut samples = sim.tables.samples.clone();
    for (i, s) in samples.iter_mut().enumerate() {
        s.source = (0, i as u64);
        if !station {
            s.station = None;
        }
        if !pass {
            s.pass = None;
        }
    }
    RollCampaignLogs {
        campaign: RollCampaign::from_toml_str(&text, "campaign.toml").unwrap(),
        inputs: Vec::new(),
        probe_files: vec!["probes/probes.parquet".into()],
        level_files: vec!["levels/levels.parquet".into()],
        samples,
        has_station: station,
        has_pass: pass,
        levels: sim.tables.levels.clone(),
    }
}

#[test]
fn noise_free_readings_give_the_true_roll_back_however_dwells_and_passes_are_found() {
    let mut cfg = RollSimConfig::default();
    cfg.sampling.noise_um = 0.0;
    cfg.sampling.passes = 2;
    cfg.truth.shape = "random".into();
    cfg.truth.roll_urad = 1000.0;
    cfg.truth.pitch_urad = 1000.0;
    cfg.truth.dz_um = 20.0;
    let sim = generate_roll(&cfg).unwrap();
    for (station, pass) in [(false, false), (true, true), (true, false)] {
        let s = study(&logs(&sim, station, pass), &RollOptions::default()).unwrap();
        assert_eq!(s.passes.len(), 2, "station {station} pass {pass}");
        for st in &s.stations {
            let err = (st.roll_urad - sim.truth.roll_urad[st.station]).abs();
            assert!(err * 1e-6 < 1e-12, "n {}: {err} µrad", st.station);
            assert!((st.x_mm - sim.truth.x_mm[st.station]).abs() < 1e-9);
            assert!((st.roll_error_urad - sim.truth.roll_error_urad[st.station]).abs() < 1e-6);
        }
    }
}

#[test]
fn a_5_um_offset_on_c_is_a_62_5_urad_ramp() {
    let mut cfg = RollSimConfig::default();
    cfg.sampling.noise_um = 0.0;
    let clean = generate_roll(&cfg).unwrap();
    cfg.effects.offset_um = [0.0, 0.0, 5.0, 0.0];
    let offset = generate_roll(&cfg).unwrap();
    let a = study(&logs(&clean, false, false), &RollOptions::default()).unwrap();
    let b = study(&logs(&offset, false, false), &RollOptions::default()).unwrap();
    for (x, y) in a.stations.iter().zip(&b.stations) {
        assert!((y.roll_urad - x.roll_urad - 62.5 * x.station as f64).abs() < 1e-9);
    }
}
