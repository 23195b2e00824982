//! Writing a `roll` campaign directory (what the simulator produces), with options that
//! exercise the reader's tolerance: probes split by pass, coarser time units, shuffled rows,
//! int32 `station`/`pass` columns.

use crate::manifest::TomlManifest;

use std::path::Path;

use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::kind_write::{column, f64_column, prepare, time_column, write_manifest, Columns};
use super::write::{write_parquet, TimeUnit, WriteError};
use dbbcal_core::roll_campaign::{ProbeSample, RollCampaignTables, RollManifest};

/// How [`write_roll_campaign`] lays out the tables. Default: one probes file, ns, rows in
/// time order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RollWriteOptions {
    /// One probes file per pass (`probes/pass-<k>.parquet`; needs the samples' `pass`).
    pub split_by_pass: bool,
    /// Unit of the timestamp columns.
    pub time_unit: TimeUnit,
    /// Shuffle the rows inside each file (seeded by `seed`).
    pub shuffle_rows: bool,
    /// Write `station` and `pass` as int32 instead of int64.
    pub int32: bool,
    /// Seed of the row shuffle.
    pub seed: u64,
}

/// Writes `campaign.toml`, `probes/` and, when it has rows, `levels/` under `dir` (created if
/// needed; stale `*.parquet` files in those folders removed first).
pub fn write_roll_campaign(
    dir: &Path,
    manifest: &RollManifest,
    tables: &RollCampaignTables,
    opts: &RollWriteOptions,
) -> Result<(), WriteError> {
    write_manifest(dir, manifest.to_toml_string())?;
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed.wrapping_mul(37).wrapping_add(11));
    let folder = dir.join("probes");
    prepare(&folder)?;
    let mut files: Vec<(String, Vec<&ProbeSample>)> = Vec::new();
    if opts.split_by_pass {
        let mut passes: Vec<Option<i64>> = tables.samples.iter().map(|s| s.pass).collect();
        passes.sort_unstable();
        passes.dedup();
        for p in passes {
            let rows = tables.samples.iter().filter(|s| s.pass == p).collect();
            files.push((format!("pass-{}", p.unwrap_or(0)), rows));
        }
    } else {
        files.push(("probes".into(), tables.samples.iter().collect()));
    }
    for (name, mut rows) in files {
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        }
        let path = folder.join(format!("{name}.parquet"));
        write_parquet(&path, probes_frame(&rows, tables, opts))?;
    }
    let folder = dir.join("levels");
    prepare(&folder)?;
    if !tables.levels.is_empty() {
        let path = folder.join("levels.parquet");
        let rows = &tables.levels;
        let columns = vec![
            time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
            f64_column("roll_urad", rows.iter().map(|r| r.roll_urad)),
            column("u_urad", rows.iter().map(|r| r.u_urad).collect::<Vec<_>>()),
        ];
        write_parquet(&path, columns)?;
    }
    Ok(())
}

fn probes_frame(
    rows: &[&ProbeSample],
    tables: &RollCampaignTables,
    opts: &RollWriteOptions,
) -> Columns {
    let mut columns = vec![
        time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
        f64_column("x_mm", rows.iter().map(|r| r.x_mm)),
    ];
    for (k, name) in ["m_a", "m_b", "m_c", "m_d"].iter().enumerate() {
        columns.push(f64_column(name, rows.iter().map(|r| r.m[k])));
    }
    // `int32`: the integers narrowed as a logger of 32-bit integers writes them (values that do
    // not fit become null, as polars' cast made them).
    let int = |name: &str, v: Vec<Option<i64>>| {
        if opts.int32 {
            let narrow: Vec<Option<i32>> = v
                .into_iter()
                .map(|x| x.and_then(|x| i32::try_from(x).ok()))
                .collect();
            column(name, narrow)
        } else {
            column(name, v)
        }
    };
    if tables.write_station {
        columns.push(int("station", rows.iter().map(|r| r.station).collect()));
    }
    if tables.write_pass {
        columns.push(int("pass", rows.iter().map(|r| r.pass).collect()));
    }
    columns
}
