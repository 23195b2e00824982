//! The `roll` reader and writer: round trip under every layout, bad rows named.

use super::*;
use dbbcal_core::axis_campaign::{CampaignKind, KindSection, MachineAxis};
use dbbcal_core::roll_campaign::{
    LevelRow, ProbeDecl, ProbeSample, ReadingUnit, RollCampaignTables, RollManifest, RollSection,
};

fn manifest() -> RollManifest {
    RollManifest {
        campaign: KindSection {
            kind: CampaignKind::Roll,
            id: "r".into(),
            reference_temperature_c: 20.0,
        },
        roll: RollSection {
            axis: MachineAxis::X,
            l_mm: 80.0,
            d_mm: 40.0,
            s_mm: 40.0,
            b_to_a: -1,
            unit: ReadingUnit::Volt,
            dwell_min_s: 2.0,
            dwell_tol_um: 2.0,
            probe: ["A", "B", "C", "D"]
                .iter()
                .map(|id| ProbeDecl {
                    id: id.to_string(),
                    u_xy_um: 50.0,
                    um_per_v: -10.0,
                    xy_mm: None,
                })
                .collect(),
        },
    }
}

fn tables() -> RollCampaignTables {
    let samples = (0..200)
        .map(|i| ProbeSample {
            time_ns: 1_800_000_000_000_000_000 + i * 50_000_000,
            x_mm: -50.0 - 40.0 * (i / 50) as f64,
            m: [0.1 * i as f64, 0.2, -0.3, 0.4],
            station: (i % 50 < 45).then_some(i / 50),
            pass: Some(1 + i / 100),
            source: (0, 0),
        })
        .collect();
    RollCampaignTables {
        samples,
        write_station: true,
        write_pass: true,
        levels: vec![LevelRow {
            time_ns: 1_800_000_000_000_000_000 + 1_000_000_000,
            roll_urad: 3.0,
            u_urad: None,
            source: (0, 0),
        }],
    }
}

#[test]
fn any_layout_reads_back_the_same_samples() {
    let t = tables();
    let mut read = Vec::new();
    for (k, opts) in [
        RollWriteOptions::default(),
        RollWriteOptions {
            split_by_pass: true,
            time_unit: TimeUnit::Ms,
            shuffle_rows: true,
            int32: true,
            seed: 3,
        },
    ]
    .iter()
    .enumerate()
    {
        let dir = tempfile::tempdir().unwrap();
        write_roll_campaign(dir.path(), &manifest(), &t, opts).unwrap();
        let logs = read_roll_campaign(dir.path()).unwrap();
        assert!(logs.has_station && logs.has_pass, "layout {k}");
        assert_eq!(logs.samples.len(), 200);
        assert_eq!(logs.levels.len(), 1);
        assert_eq!(logs.levels[0].u_urad, None);
        assert_eq!(logs.campaign.probes[2].um_per_unit, -10.0);
        read.push(
            logs.samples
                .iter()
                .map(|s| (s.time_ns, s.x_mm, s.m, s.station, s.pass))
                .collect::<Vec<_>>(),
        );
    }
    assert_eq!(read[0], read[1]);
}

#[test]
fn a_nan_reading_is_refused_naming_file_column_and_rows() {
    let mut t = tables();
    for s in &mut t.samples[10..13] {
        s.m[2] = f64::NAN;
    }
    let dir = tempfile::tempdir().unwrap();
    write_roll_campaign(dir.path(), &manifest(), &t, &RollWriteOptions::default()).unwrap();
    let e = read_roll_campaign(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("probes.parquet") && e.contains("`m_c`") && e.contains("rows 10 .. 12"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1);
}
