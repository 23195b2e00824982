//! Reading a `roll` campaign (`docs/spec/machine-formats.md`, "Kind roll") with the parquet crate and
//! handing it over as plain data ([`RollCampaignLogs`]).
//!
//! `probes/*.parquet` (required) and `levels/*.parquet` (optional): each file decoded whole
//! under [`crate::guard::guarded`], its columns normalised as the reader rules allow
//! (timestamps ns/us/ms, naive or zoned; integers int8 … int64 and unsigned; floats 32 or 64
//! bit), and checked row by row: a null or non-finite value where one is needed, a `pass` below
//! 1, a time outside 1980 … 2200 refuses the campaign with one line naming the file, the column
//! and the rows (counting from 0 in that file). Samples of every file are sorted by time (ties
//! by file and row), so files split by pass and rows in any order give the same logs; a sample
//! two files hold (equal in every column) is kept once. `station` and `pass` may be absent or
//! all null. Every input file is hashed (sha256) before the read and checked unchanged after.

use std::path::{Path, PathBuf};

use super::axis::{check_rows, finite, required, Decoded};
use super::inputs::{check_unchanged, parquet_files};
use super::kind_read::{kind_manifest_text, required_table, snapshot};
use super::IngestError;
use crate::manifest::TomlCampaign;
use dbbcal_core::axis_campaign::CampaignKind;
use dbbcal_core::roll_campaign::{LevelRow, ProbeSample, RollCampaign, RollCampaignLogs};

const PROBES: &str = "probes";
const LEVELS: &str = "levels";
const READINGS: [&str; 4] = ["m_a", "m_b", "m_c", "m_d"];

/// Reads a `roll` campaign directory: `campaign.toml` (`kind = "roll"`), `probes/*.parquet`
/// and the optional `levels/*.parquet`.
pub fn read_roll_campaign(dir: &Path) -> Result<RollCampaignLogs, IngestError> {
    let manifest = dir.join("campaign.toml");
    let campaign = read_roll_manifest(dir)?;
    let probe_files = required_table(dir, PROBES)?;
    let level_files = parquet_files(&dir.join(LEVELS))?;
    let (before, inputs) = snapshot(dir, &manifest, &[&probe_files, &level_files])?;
    let mut samples = Vec::new();
    let (mut has_station, mut has_pass) = (false, false);
    for (f, path) in probe_files.iter().enumerate() {
        let file = read_probes(path, f as u32)?;
        has_station |= file.has_station;
        has_pass |= file.has_pass;
        samples.extend(file.samples);
    }
    samples.sort_by(|a, b| a.time_ns.cmp(&b.time_ns).then(a.source.cmp(&b.source)));
    samples.dedup_by(|b, a| {
        a.time_ns == b.time_ns
            && a.x_mm.to_bits() == b.x_mm.to_bits()
            && a.m.map(f64::to_bits) == b.m.map(f64::to_bits)
            && a.station == b.station
            && a.pass == b.pass
    });
    if has_pass {
        if let Some(s) = samples.iter().find(|s| s.pass.is_none()) {
            return Err(IngestError::BadRows {
                path: probe_files[s.source.0 as usize].clone(),
                column: "pass",
                rows: 1,
                first_row: s.source.1,
                last_row: s.source.1,
                problem: "lack a pass while other files give one (the pass column must be in every probes file or in none)".into(),
                example: "absent".into(),
            });
        }
    }
    let mut levels = Vec::new();
    for (f, path) in level_files.iter().enumerate() {
        levels.extend(read_levels(path, f as u32)?);
    }
    levels.sort_by(|a, b| a.time_ns.cmp(&b.time_ns).then(a.source.cmp(&b.source)));
    check_unchanged(dir, &before, &inputs)?;
    let shown = |files: &[PathBuf]| {
        files
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
    };
    Ok(RollCampaignLogs {
        campaign,
        inputs,
        probe_files: shown(&probe_files),
        level_files: shown(&level_files),
        samples,
        has_station,
        has_pass,
        levels,
    })
}

/// Reads and validates the `campaign.toml` of a `roll` campaign; another kind is refused, named.
pub fn read_roll_manifest(dir: &Path) -> Result<RollCampaign, IngestError> {
    let (file, text) = kind_manifest_text(dir, CampaignKind::Roll, "a roll campaign")?;
    Ok(RollCampaign::from_toml_str(&text, &file)?)
}

struct ProbeFile {
    samples: Vec<ProbeSample>,
    has_station: bool,
    has_pass: bool,
}

fn read_probes(path: &Path, index: u32) -> Result<ProbeFile, IngestError> {
    let d = Decoded::read(path)?;
    let time = required(path, "time", d.time("time")?)?;
    let x = finite_values(&d, path, "x_mm")?;
    let mut m = Vec::new();
    for name in READINGS {
        m.push(finite_values(&d, path, name)?);
    }
    let station = optional_int(&d, "station")?;
    let pass = optional_int(&d, "pass")?;
    let has_station = station
        .as_ref()
        .is_some_and(|s| s.iter().any(Option::is_some));
    let has_pass = pass.as_ref().is_some_and(|s| s.iter().any(Option::is_some));
    if let Some(p) = pass.as_ref().filter(|_| has_pass) {
        check_rows(
            path,
            "pass",
            p,
            |v| v.is_some_and(|v| v >= 1),
            "are null or below 1 (passes count from 1)",
        )?;
    }
    if let Some(s) = &station {
        check_rows(
            path,
            "station",
            s,
            |v| v.is_none_or(|v| v >= 0),
            "are negative",
        )?;
    }
    let samples = (0..d.rows())
        .map(|i| ProbeSample {
            time_ns: time[i],
            x_mm: x[i],
            m: [m[0][i], m[1][i], m[2][i], m[3][i]],
            station: station.as_ref().and_then(|s| s[i]),
            pass: pass.as_ref().filter(|_| has_pass).and_then(|p| p[i]),
            source: (index, i as u64),
        })
        .collect();
    Ok(ProbeFile {
        samples,
        has_station,
        has_pass,
    })
}

fn read_levels(path: &Path, index: u32) -> Result<Vec<LevelRow>, IngestError> {
    let d = Decoded::read(path)?;
    let time = required(path, "time", d.time("time")?)?;
    let roll = finite_values(&d, path, "roll_urad")?;
    let u = d.optional("u_urad", Decoded::real)?;
    check_rows(
        path,
        "u_urad",
        &u,
        |v| v.is_none_or(|v| v.is_finite() && v > 0.0),
        "are not positive finite uncertainties (nor null)",
    )?;
    Ok((0..d.rows())
        .map(|i| LevelRow {
            time_ns: time[i],
            roll_urad: roll[i],
            u_urad: u[i],
            source: (index, i as u64),
        })
        .collect())
}

/// A float column with every value present and finite.
fn finite_values(
    d: &Decoded<'_>,
    path: &Path,
    name: &'static str,
) -> Result<Vec<f64>, IngestError> {
    let values = required(path, name, d.real(name)?)?;
    finite(path, name, &values)?;
    Ok(values)
}

/// An optional integer column: `None` when absent or of no type (all null).
fn optional_int(
    d: &Decoded<'_>,
    name: &'static str,
) -> Result<Option<Vec<Option<i64>>>, IngestError> {
    if !d.has(name) || d.is_null_typed(name) {
        return Ok(None);
    }
    d.int(name).map(Some)
}
