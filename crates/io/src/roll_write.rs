//! Writing a `roll` campaign directory (what the simulator produces), with options that
//! exercise the reader's tolerance: probes split by pass, coarser time units, shuffled rows,
//! int32 `station`/`pass` columns.

use std::path::Path;

use polars::prelude::*;
use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::kind_write::{f64_column, polars_err, prepare, time_column, write_manifest};
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
        let mut df = probes_frame(&rows, tables, opts).map_err(polars_err(&path))?;
        write_parquet(&path, &mut df)?;
    }
    let folder = dir.join("levels");
    prepare(&folder)?;
    if !tables.levels.is_empty() {
        let path = folder.join("levels.parquet");
        let rows = &tables.levels;
        let columns = vec![
            time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
            f64_column("roll_urad", rows.iter().map(|r| r.roll_urad)),
            Series::new(
                "u_urad".into(),
                rows.iter().map(|r| r.u_urad).collect::<Vec<_>>(),
            )
            .into_column(),
        ];
        let mut df = DataFrame::new(rows.len(), columns).map_err(polars_err(&path))?;
        write_parquet(&path, &mut df)?;
    }
    Ok(())
}

fn probes_frame(
    rows: &[&ProbeSample],
    tables: &RollCampaignTables,
    opts: &RollWriteOptions,
) -> PolarsResult<DataFrame> {
    let mut columns = vec![
        time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
        f64_column("x_mm", rows.iter().map(|r| r.x_mm)),
    ];
    for (k, name) in ["m_a", "m_b", "m_c", "m_d"].iter().enumerate() {
        columns.push(f64_column(name, rows.iter().map(|r| r.m[k])));
    }
    let int = |name: &str, v: Vec<Option<i64>>| -> PolarsResult<Column> {
        let c = Series::new(name.into(), v).into_column();
        if opts.int32 {
            c.cast(&DataType::Int32)
        } else {
            Ok(c)
        }
    };
    if tables.write_station {
        columns.push(int("station", rows.iter().map(|r| r.station).collect())?);
    }
    if tables.write_pass {
        columns.push(int("pass", rows.iter().map(|r| r.pass).collect())?);
    }
    DataFrame::new(rows.len(), columns)
}
