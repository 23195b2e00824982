//! Reading a `volumetric` campaign (`docs/spec/machine-formats.md`, "Kind volumetric") with
//! the parquet crate and handing it over as plain data ([`VolumetricCampaignLogs`]), on the column readers
//! and row checks of the `axis` reader (`super::axis`): timestamps ns/us/ms, integers int8 …
//! int64, strings utf8 or dictionary, optional columns absent or all null, one line naming the
//! file, the column and the rows. `diagonals/`, `steps/` and/or `bar_diagonals/` (at least
//! one; the last is our extension, `docs/bar-diagonals.md`), `environment/` (required with a
//! laser unless `compensation = "air+material"`), `events/`; files split in any way and
//! rows in any order give the same logs (`dbbcal_core::volumetric_campaign::logs`).

use std::path::{Path, PathBuf};

use super::axis::{
    check_rows, check_runs_and_directions, finite, read_environment, read_events, required, Decoded,
};
use super::inputs::{check_unchanged, parquet_files};
use super::kind_read::{kind_manifest_text, snapshot};
use super::IngestError;
use crate::manifest::TomlCampaign;
use dbbcal_core::axis_campaign::{CampaignKind, MachineAxis};
use dbbcal_core::volumetric_campaign::{
    logs::diagonal_of_index, order_bar_readings, order_diagonal_readings, order_step_readings,
    BarReading, DiagonalReading, DiagonalSign, StepReading, VolumetricCampaign,
    VolumetricCampaignLogs,
};

const DIAGONALS: &str = "diagonals";
const STEPS: &str = "steps";
const BAR_DIAGONALS: &str = "bar_diagonals";
const ENVIRONMENT: &str = "environment";
const EVENTS: &str = "events";

/// Reads and validates the `campaign.toml` of a `volumetric` campaign.
pub fn read_volumetric_manifest(dir: &Path) -> Result<VolumetricCampaign, IngestError> {
    let (file, text) = kind_manifest_text(dir, CampaignKind::Volumetric, "a volumetric campaign")?;
    Ok(VolumetricCampaign::from_toml_str(&text, &file)?)
}

/// Reads a `volumetric` campaign directory.
pub fn read_volumetric_campaign(dir: &Path) -> Result<VolumetricCampaignLogs, IngestError> {
    let manifest = dir.join("campaign.toml");
    let campaign = read_volumetric_manifest(dir)?;
    let diagonal_files = parquet_files(&dir.join(DIAGONALS))?;
    let step_files = parquet_files(&dir.join(STEPS))?;
    let bar_files = parquet_files(&dir.join(BAR_DIAGONALS))?;
    if diagonal_files.is_empty() && step_files.is_empty() && bar_files.is_empty() {
        return Err(IngestError::MissingTable {
            folder: dir.join(DIAGONALS),
            table: "diagonals (or steps, or bar_diagonals)",
        });
    }
    let environment_files = parquet_files(&dir.join(ENVIRONMENT))?;
    let event_files = parquet_files(&dir.join(EVENTS))?;
    let (before, inputs) = snapshot(
        dir,
        &manifest,
        &[
            &diagonal_files,
            &step_files,
            &bar_files,
            &environment_files,
            &event_files,
        ],
    )?;
    let diagonals = read_diagonals(&diagonal_files, &campaign)?;
    let steps = read_steps(&step_files)?;
    let bar_readings = read_bar_readings(&bar_files, &campaign, &diagonals)?;
    let file = manifest.display().to_string();
    campaign.check_instruments(
        !diagonals.is_empty() || !steps.is_empty(),
        !bar_readings.is_empty(),
        &file,
    )?;
    campaign.check_steps(!steps.is_empty(), &file)?;
    let environment = read_environment(&environment_files)?;
    campaign.check_environment(!environment.is_empty(), &file)?;
    let events = read_events(&event_files)?;
    check_unchanged(dir, &before, &inputs)?;
    Ok(VolumetricCampaignLogs {
        campaign,
        inputs,
        diagonals,
        steps,
        bar_readings,
        environment,
        temperatures: Default::default(),
        events,
    })
}

fn signs(path: &Path, words: &[String]) -> Result<Vec<DiagonalSign>, IngestError> {
    check_rows(
        path,
        "diagonal",
        words,
        |w| DiagonalSign::parse(w).is_some(),
        "are not a diagonal's sign vector (\"+++\", \"-++\", \"+-+\" or \"++-\")",
    )?;
    Ok(words
        .iter()
        .filter_map(|w| DiagonalSign::parse(w))
        .collect())
}

fn read_diagonals(
    files: &[PathBuf],
    campaign: &VolumetricCampaign,
) -> Result<Vec<DiagonalReading>, IngestError> {
    let mut rows = Vec::new();
    let mut given = Vec::new();
    let mut source: Vec<(usize, usize)> = Vec::new();
    for (f, path) in files.iter().enumerate() {
        let file = Decoded::read(path)?;
        let time = required(path, "time", file.time("time")?)?;
        let diagonal = signs(path, &required(path, "diagonal", file.text("diagonal")?)?)?;
        let run = required(path, "run", file.int("run")?)?;
        let direction = file.optional("direction", Decoded::int)?;
        check_runs_and_directions(path, &run, &direction)?;
        let target = required(path, "target_mm", file.real("target_mm")?)?;
        finite(path, "target_mm", &target)?;
        let d_len = diagonal_length_mm(campaign);
        check_rows(
            path,
            "target_mm",
            &target,
            |&t| (-1e-6..=d_len + 1e-6).contains(&t),
            &format!("are outside 0 … D = {d_len:.3} mm (the diagonal's length)"),
        )?;
        let deviation = required(path, "deviation_um", file.real("deviation_um")?)?;
        finite(path, "deviation_um", &deviation)?;
        for i in 0..file.rows() {
            rows.push(DiagonalReading {
                time_ns: time[i],
                diagonal: diagonal[i],
                run: run[i],
                direction: 0,
                target_mm: target[i],
                deviation_um: deviation[i],
            });
            given.push(direction[i].map(|d| d as i8));
            source.push((f, i));
        }
    }
    order_diagonal_readings(&rows, &given).map_err(|p| {
        let (f, first) = source[p.rows[0]];
        IngestError::BadRows {
            path: files[f].clone(),
            column: "direction",
            rows: p.rows.len() as u64,
            first_row: first as u64,
            last_row: p.rows.iter().map(|&r| source[r].1).max().unwrap_or(first) as u64,
            problem: format!(
                "diagonal {}, run {}: {}",
                diagonal_of_index(p.line).map_or("?", |d| d.as_str()),
                p.run,
                p.problem
            ),
            example: String::new(),
        }
    })
}

/// The diagonal's length D of the workspace, mm.
fn diagonal_length_mm(campaign: &VolumetricCampaign) -> f64 {
    campaign
        .lengths_mm()
        .iter()
        .map(|l| l * l)
        .sum::<f64>()
        .sqrt()
}

fn read_bar_readings(
    files: &[PathBuf],
    campaign: &VolumetricCampaign,
    laser: &[DiagonalReading],
) -> Result<Vec<BarReading>, IngestError> {
    let d_len = diagonal_length_mm(campaign);
    let mut rows = Vec::new();
    for path in files {
        let file = Decoded::read(path)?;
        let time = required(path, "time", file.time("time")?)?;
        let diagonal = signs(path, &required(path, "diagonal", file.text("diagonal")?)?)?;
        check_rows(
            path,
            "diagonal",
            &diagonal,
            |d| !laser.iter().any(|r| r.diagonal == *d),
            "are body diagonals diagonals/*.parquet also holds (read by the laser): one instrument per body diagonal",
        )?;
        let segment = required(path, "segment", file.int("segment")?)?;
        check_rows(
            path,
            "segment",
            &segment,
            |&s| (1..=100_000).contains(&s),
            "are not 1 … 100000 (segments count from 1)",
        )?;
        let run: Vec<i64> = file
            .optional("run", Decoded::int)?
            .into_iter()
            .map(|r| r.unwrap_or(1))
            .collect();
        let direction = file.optional("direction", Decoded::int)?;
        check_runs_and_directions(path, &run, &direction)?;
        let along = required(path, "distance_along_mm", file.real("distance_along_mm")?)?;
        check_rows(
            path,
            "distance_along_mm",
            &along,
            |&t| t.is_finite() && (-1e-6..=d_len + 1e-6).contains(&t),
            &format!("are not finite numbers within 0 … D = {d_len:.3} mm (the diagonal's length)"),
        )?;
        let centre = required(path, "centre_distance_mm", file.real("centre_distance_mm")?)?;
        check_rows(
            path,
            "centre_distance_mm",
            &centre,
            |&c| c.is_finite() && c > 0.0 && c <= 10_000.0,
            "are not finite centre distances within (0, 10000] mm",
        )?;
        let u = file.optional("u_um", Decoded::real)?;
        check_rows(
            path,
            "u_um",
            &u,
            |v| v.is_none_or(|v| v.is_finite() && v > 0.0 && v <= 1_000.0),
            "are not standard uncertainties within (0, 1000] µm (nor null)",
        )?;
        for i in 0..file.rows() {
            rows.push(BarReading {
                time_ns: time[i],
                diagonal: diagonal[i],
                segment: segment[i],
                run: run[i],
                direction: direction[i].map_or(1, |d| d as i8),
                distance_along_mm: along[i],
                centre_distance_mm: centre[i],
                u_um: u[i],
            });
        }
    }
    order_bar_readings(&mut rows);
    Ok(rows)
}

fn read_steps(files: &[PathBuf]) -> Result<Vec<StepReading>, IngestError> {
    let mut rows = Vec::new();
    for path in files {
        let file = Decoded::read(path)?;
        let time = required(path, "time", file.time("time")?)?;
        let diagonal = signs(path, &required(path, "diagonal", file.text("diagonal")?)?)?;
        let run: Vec<i64> = file
            .optional("run", Decoded::int)?
            .into_iter()
            .map(|r| r.unwrap_or(1))
            .collect();
        check_rows(
            path,
            "run",
            &run,
            |&r| r >= 1,
            "are below 1 (runs count from 1)",
        )?;
        let step = required(path, "step", file.int("step")?)?;
        check_rows(
            path,
            "step",
            &step,
            |&s| (0..=100_000).contains(&s),
            "are not 0 … 100000",
        )?;
        let submove = file.optional("submove", Decoded::text)?;
        check_rows(
            path,
            "submove",
            &submove,
            |s| s.as_deref().is_none_or(|s| ["X", "Y", "Z"].contains(&s)),
            "are not X, Y or Z (nor null)",
        )?;
        let mut xyz = Vec::new();
        for name in ["x_mm", "y_mm", "z_mm"] {
            let v = required(path, name, file.real(name)?)?;
            finite(path, name, &v)?;
            xyz.push(v);
        }
        let deviation = required(path, "deviation_um", file.real("deviation_um")?)?;
        finite(path, "deviation_um", &deviation)?;
        for i in 0..file.rows() {
            let axis = submove[i].as_deref().map(|s| match s {
                "X" => MachineAxis::X,
                "Y" => MachineAxis::Y,
                _ => MachineAxis::Z,
            });
            rows.push(StepReading {
                time_ns: time[i],
                diagonal: diagonal[i],
                run: run[i],
                step: step[i],
                submove: axis,
                position_mm: [xyz[0][i], xyz[1][i], xyz[2][i]],
                deviation_um: deviation[i],
            });
        }
    }
    order_step_readings(&mut rows);
    Ok(rows)
}
