//! Writing a `probe` campaign (`docs/spec/machine-formats.md`, "Kind `probe`"):
//! `campaign.toml` and `touches/*.parquet`, split across files and shuffled as asked, the
//! approach as i, j, k or as φ, θ.

use crate::manifest::TomlManifest;

use std::path::Path;

use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::kind_write::{column, f64_column, prepare, time_column, write_manifest, Columns};
use super::write::{write_parquet, TimeUnit, WriteError};
use dbbcal_core::probe_campaign::{ProbeCampaignTables, ProbeTouch};

/// How a `probe` campaign is written.
#[derive(Debug, Clone)]
pub struct ProbeWriteOptions {
    /// Unit of the `time` column.
    pub time_unit: TimeUnit,
    /// Shuffle the rows of each file.
    pub shuffle_rows: bool,
    /// Files to split the touches into (round robin by `seq` blocks; at least 1).
    pub files: usize,
    /// Write `phi_deg`, `theta_deg` instead of `i`, `j`, `k`.
    pub angles: bool,
    /// Seed of the shuffles.
    pub seed: u64,
}

impl Default for ProbeWriteOptions {
    fn default() -> Self {
        ProbeWriteOptions {
            time_unit: TimeUnit::Us,
            shuffle_rows: false,
            files: 1,
            angles: false,
            seed: 0,
        }
    }
}

/// Writes `campaign.toml` and `touches/` under `dir` (created if needed; stale `*.parquet`
/// removed first).
pub fn write_probe_campaign(
    dir: &Path,
    tables: &ProbeCampaignTables,
    opts: &ProbeWriteOptions,
) -> Result<(), WriteError> {
    write_manifest(dir, tables.manifest.to_toml_string())?;
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed.wrapping_mul(37).wrapping_add(11));
    let folder = dir.join("touches");
    prepare(&folder)?;
    let files = opts.files.max(1);
    let block = tables.touches.len().div_ceil(files).max(1);
    for (f, chunk) in tables.touches.chunks(block).enumerate() {
        let mut rows: Vec<&ProbeTouch> = chunk.iter().collect();
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        }
        let path = folder.join(format!("touches-{:02}.parquet", files - f));
        write_parquet(&path, touches_frame(&rows, opts))?;
    }
    Ok(())
}

fn touches_frame(rows: &[&ProbeTouch], opts: &ProbeWriteOptions) -> Columns {
    let mut columns = vec![
        time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
        column("seq", rows.iter().map(|r| r.seq).collect::<Vec<_>>()),
    ];
    if opts.angles {
        columns.push(f64_column("phi_deg", rows.iter().map(|r| r.phi_deg())));
        columns.push(f64_column("theta_deg", rows.iter().map(|r| r.theta_deg())));
    } else {
        for (k, name) in ["i", "j", "k"].iter().enumerate() {
            columns.push(f64_column(name, rows.iter().map(|r| r.approach[k])));
        }
    }
    for (k, name) in ["x_mm", "y_mm", "z_mm"].iter().enumerate() {
        columns.push(f64_column(name, rows.iter().map(|r| r.position_mm[k])));
    }
    columns.push(column(
        "feed_mm_min",
        rows.iter().map(|r| r.feed_mm_min).collect::<Vec<_>>(),
    ));
    columns.push(column(
        "stylus",
        rows.iter().map(|r| r.stylus.as_str()).collect::<Vec<_>>(),
    ));
    columns.push(column(
        "artefact",
        rows.iter().map(|r| r.artefact.as_str()).collect::<Vec<_>>(),
    ));
    if rows.iter().any(|r| r.spindle_deg.is_some()) {
        columns.push(column(
            "spindle_deg",
            rows.iter().map(|r| r.spindle_deg).collect::<Vec<_>>(),
        ));
    }
    columns
}
