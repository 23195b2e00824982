//! The `volumetric` reader and writer: round trip under every layout (split by diagonal,
//! shuffled rows, `direction` left out and derived), bad rows named, a retroreflector on a step
//! diagonal refused.

use super::*;
use dbbcal_core::axis_campaign::{
    CampaignKind, EnvironmentRow, KindSection, LaserCompensation, MachineAxis,
};
use dbbcal_core::volumetric_campaign::{
    order_bar_readings, BarDiagonalSection, BarReading, DiagonalReading, DiagonalSign, GridSection,
    LaserTarget, StepReading, VolumetricCampaignTables, VolumetricLaserSection,
    VolumetricMachineSection, VolumetricManifest, WorkspaceSection,
};

const T0: i64 = 1_800_000_000_000_000_000;

fn manifest(target: LaserTarget) -> VolumetricManifest {
    VolumetricManifest {
        campaign: KindSection {
            kind: CampaignKind::Volumetric,
            id: "v".into(),
            reference_temperature_c: 20.0,
        },
        machine: VolumetricMachineSection {
            cte_ppm_per_k: 11.5,
        },
        workspace: WorkspaceSection {
            min_mm: [0.0, 0.0, 0.0],
            max_mm: [300.0, 200.0, 100.0],
        },
        laser: Some(VolumetricLaserSection {
            wavelength_nm: 632.99,
            compensation: LaserCompensation::AirMaterial,
            dead_path_mm: None,
            target,
        }),
        bar_diagonal: None,
        grid: GridSection {
            i: 2,
            j: 2,
            k: 2,
            origin_mm: [0.0, 0.0, 0.0],
            spacing_mm: [300.0, 200.0, 100.0],
        },
        table: None,
        sensor: Vec::new(),
    }
}

/// Two diagonals, two runs up and down of 4 targets; one step diagonal of 2 steps.
fn tables() -> VolumetricCampaignTables {
    let d_len = (300.0f64 * 300.0 + 200.0 * 200.0 + 100.0 * 100.0).sqrt();
    let mut t = VolumetricCampaignTables::default();
    let mut clock = T0;
    for sign in [DiagonalSign::Ppp, DiagonalSign::Mpp] {
        for run in 1..=2 {
            for dir in [1i8, -1] {
                for i in 0..=3 {
                    let i = if dir > 0 { i } else { 3 - i };
                    t.diagonals.push(DiagonalReading {
                        time_ns: clock,
                        diagonal: sign,
                        run,
                        direction: dir,
                        target_mm: d_len * i as f64 / 3.0,
                        deviation_um: 0.1 * i as f64 + 0.01 * run as f64 + 0.003 * dir as f64,
                    });
                    clock += 1_000_000_000;
                }
            }
        }
    }
    let mut p = [0.0, 0.0, 0.0];
    let mut push = |p: [f64; 3], step: i64, submove: Option<MachineAxis>, clock: i64| {
        t.steps.push(StepReading {
            time_ns: clock,
            diagonal: DiagonalSign::Ppp,
            run: 1,
            step,
            submove,
            position_mm: p,
            deviation_um: 0.01 * (step as f64) + p[0] * 1e-4,
        })
    };
    push(p, 0, None, clock);
    for s in 1..=2 {
        for (j, axis) in [MachineAxis::X, MachineAxis::Y, MachineAxis::Z]
            .into_iter()
            .enumerate()
        {
            p[j] = [300.0, 200.0, 100.0][j] * s as f64 / 2.0;
            clock += 1_000_000_000;
            // Sub-moves of one step logged at the same time: read back in the order X, Y, Z.
            push(p, s, Some(axis), clock - (j as i64) * 1_000_000_000);
        }
    }
    t.environment.push(EnvironmentRow {
        time_ns: T0,
        air_c: 20.0,
        pressure_hpa: 1013.25,
        humidity_pct: 50.0,
        material_c: None,
        env_factor_ppm: None,
    });
    t
}

#[test]
fn any_layout_reads_back_the_same_readings() {
    let t = tables();
    let mut read = Vec::new();
    for (k, opts) in [
        VolumetricWriteOptions::default(),
        VolumetricWriteOptions {
            split_by_diagonal: true,
            shuffle_rows: true,
            omit_direction: true,
            seed: 7,
        },
    ]
    .iter()
    .enumerate()
    {
        let dir = tempfile::tempdir().unwrap();
        write_volumetric_campaign(dir.path(), &manifest(LaserTarget::FlatMirror), &t, opts)
            .unwrap();
        let logs = read_volumetric_campaign(dir.path()).unwrap();
        assert_eq!(logs.diagonals.len(), 32, "layout {k}");
        assert_eq!(logs.steps.len(), 7, "layout {k}");
        // Derived directions equal the written ones.
        let mut written = t.diagonals.clone();
        written.sort_by_key(|r| (r.diagonal, r.run, r.time_ns));
        assert_eq!(logs.diagonals, written, "layout {k}");
        let order: Vec<(i64, Option<MachineAxis>)> =
            logs.steps.iter().map(|s| (s.step, s.submove)).collect();
        assert_eq!(order[0], (0, None));
        assert_eq!(order[1], (1, Some(MachineAxis::X)));
        assert_eq!(order[3], (1, Some(MachineAxis::Z)));
        read.push((logs.diagonals.clone(), logs.steps.clone()));
    }
    assert_eq!(read[0], read[1]);
}

#[test]
fn a_bad_submove_is_refused_naming_file_column_and_rows() {
    use crate::test_frames::{col, raw_time_col, Unit};
    let dir = tempfile::tempdir().unwrap();
    let mut t = tables();
    t.steps.clear();
    write_volumetric_campaign(
        dir.path(),
        &manifest(LaserTarget::FlatMirror),
        &t,
        &VolumetricWriteOptions::default(),
    )
    .unwrap();
    let steps = dir.path().join("steps");
    std::fs::create_dir_all(&steps).unwrap();
    let n = 4;
    let time = raw_time_col(
        "time",
        (0..n).map(|i| Some(T0 + i)).collect(),
        Unit::Nanoseconds,
        None,
    );
    let f = |name: &str, v: Vec<f64>| col(name, v);
    let columns: Vec<_> = vec![
        time,
        col("diagonal", vec!["+++"; 4]),
        col("step", vec![0i64, 1, 1, 1]),
        col("submove", vec![None, Some("X"), Some("W"), Some("W")]),
        f("x_mm", vec![0.0, 150.0, 150.0, 150.0]),
        f("y_mm", vec![0.0, 0.0, 100.0, 100.0]),
        f("z_mm", vec![0.0, 0.0, 0.0, 50.0]),
        f("deviation_um", vec![0.0; 4]),
    ]
    .into_iter()
    .map(|c| (c.0, c.1))
    .collect();
    crate::write::write_parquet(&steps.join("steps-bad.parquet"), columns).unwrap();
    let e = read_volumetric_campaign(dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("steps-bad.parquet") && e.contains("submove") && e.contains("2 .. 3"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn a_retroreflector_on_a_step_diagonal_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    write_volumetric_campaign(
        dir.path(),
        &manifest(LaserTarget::Retroreflector),
        &tables(),
        &VolumetricWriteOptions::default(),
    )
    .unwrap();
    let e = read_volumetric_campaign(dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("laser.target") && e.contains("flat-mirror"),
        "{e}"
    );
}

/// Two segments of a bar on "-++" (sharing one target), up and down, rows as given.
fn bar_readings() -> Vec<BarReading> {
    let mut out = Vec::new();
    let mut clock = T0;
    for (segment, targets) in [(1i64, [0.0, 50.0, 100.0]), (2, [100.0, 150.0, 200.0])] {
        for direction in [1i8, -1] {
            for (i, d) in targets.iter().enumerate() {
                out.push(BarReading {
                    time_ns: clock,
                    diagonal: DiagonalSign::Mpp,
                    segment,
                    run: 1,
                    direction,
                    distance_along_mm: *d,
                    centre_distance_mm: 300.0 + d + 1e-4 * i as f64,
                    u_um: (segment == 1).then_some(0.03),
                });
                clock += 1_000_000_000;
            }
        }
    }
    out
}

#[test]
fn bar_readings_read_back_under_any_layout_and_a_bar_only_campaign_needs_no_laser() {
    let mut m = manifest(LaserTarget::FlatMirror);
    m.laser = None;
    m.bar_diagonal = Some(BarDiagonalSection {
        bar: "B07".into(),
        scale_u_ppm: 0.5,
        misalignment_mm: 0.1,
    });
    let t = VolumetricCampaignTables {
        bar_readings: bar_readings(),
        ..Default::default()
    };
    for opts in [
        VolumetricWriteOptions::default(),
        VolumetricWriteOptions {
            split_by_diagonal: true,
            shuffle_rows: true,
            omit_direction: true,
            seed: 3,
        },
    ] {
        let dir = tempfile::tempdir().unwrap();
        write_volumetric_campaign(dir.path(), &m, &t, &opts).unwrap();
        let logs = read_volumetric_campaign(dir.path()).unwrap();
        let mut written = t.bar_readings.clone();
        order_bar_readings(&mut written);
        assert_eq!(logs.bar_readings, written);
        assert!(logs.campaign.laser.is_none());
    }
}

#[test]
fn bar_readings_without_their_section_and_a_diagonal_read_twice_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut t = tables();
    t.bar_readings = bar_readings();
    write_volumetric_campaign(
        dir.path(),
        &manifest(LaserTarget::FlatMirror),
        &t,
        &VolumetricWriteOptions::default(),
    )
    .unwrap();
    // "-++" is in diagonals/ too: one instrument per body diagonal.
    let e = read_volumetric_campaign(dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bar-all.parquet") && e.contains("diagonal") && e.contains("one instrument"),
        "{e}"
    );
    t.diagonals.retain(|r| r.diagonal != DiagonalSign::Mpp);
    let dir = tempfile::tempdir().unwrap();
    write_volumetric_campaign(
        dir.path(),
        &manifest(LaserTarget::FlatMirror),
        &t,
        &VolumetricWriteOptions::default(),
    )
    .unwrap();
    let e = read_volumetric_campaign(dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bar_diagonal") && e.contains("is missing"),
        "{e}"
    );
}
