//! The floor under `dbbcal ingest`: how long this crate's polars takes just to decode a
//! campaign's encoder files, the same columns `dbbcal` reads, with nothing done to the rows.
//!
//! Two ways, best of `--repeat` runs each:
//! * `collect`: `scan_parquet` + `collect` into memory, as `bench/bare_scan.py` does in Python;
//! * `stream`: the streaming engine handing over batches (`sink_batches`), as ingest reads the
//!   encoder files (one scan over all of them), the batches dropped on arrival.
//!
//! ```text
//! cargo run --release -p dbbcal-io --features bench-tools --example decode_floor -- bench/out/campaign-full \
//!     [--repeat 3] [--json FILE]
//! ```
//!
//! A benchmark tool (`bench/run.sh` runs it), built only with the `bench-tools` feature so that
//! `cargo test` does not link polars once more.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use polars::lazy::dsl::Engine;
use polars::prelude::*;

fn encoder_files(campaign: &str) -> anyhow::Result<Vec<PathBuf>> {
    let dir = PathBuf::from(campaign).join("encoders");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "parquet"))
        .collect();
    files.sort();
    anyhow::ensure!(!files.is_empty(), "no encoders/*.parquet in {campaign}");
    Ok(files)
}

fn scan(path: &std::path::Path) -> PolarsResult<LazyFrame> {
    let args = ScanArgsParquet {
        glob: false,
        ..Default::default()
    };
    let lazy = LazyFrame::scan_parquet(PlRefPath::try_from_path(path)?, args)?;
    Ok(lazy.select([
        col("time").cast(DataType::Int64),
        col("bar").cast(DataType::String),
        col("counts").cast(DataType::Int64),
    ]))
}

/// Rows decoded by collecting every file into memory.
fn collect(files: &[PathBuf]) -> PolarsResult<usize> {
    let mut rows = 0;
    for path in files {
        rows += scan(path)?.collect()?.height();
    }
    Ok(rows)
}

/// Rows decoded by streaming every file in batches, each dropped as it arrives: one scan over
/// all the files, as ingest reads files of one schema.
fn stream(files: &[PathBuf]) -> PolarsResult<usize> {
    let rows = Arc::new(AtomicUsize::new(0));
    let seen = rows.clone();
    let callback = PlanCallback::new(move |batch: DataFrame| {
        seen.fetch_add(batch.height(), Ordering::Relaxed);
        Ok(false)
    });
    let args = ScanArgsParquet {
        glob: false,
        ..Default::default()
    };
    let paths: Vec<PlRefPath> = files
        .iter()
        .map(|p| PlRefPath::try_from_path(p))
        .collect::<PolarsResult<_>>()?;
    LazyFrame::scan_parquet_files(paths.into(), args)?
        .select([
            col("time").cast(DataType::Int64),
            col("bar").cast(DataType::String),
            col("counts").cast(DataType::Int64),
        ])
        .sink_batches(callback, true, None)?
        .collect_with_engine(Engine::Streaming)?;
    Ok(rows.load(Ordering::Relaxed))
}

/// One line on failure (no backtrace), exit code 2.
fn main() {
    if let Err(e) = run() {
        eprintln!("decode_floor: {e:#}");
        std::process::exit(2);
    }
}

fn run() -> anyhow::Result<()> {
    let usage = "usage: decode_floor CAMPAIGN_DIR [--repeat N] [--json FILE]";
    let mut args = std::env::args().skip(1);
    let campaign = args.next().ok_or_else(|| anyhow::anyhow!(usage))?;
    let (mut repeat, mut json) = (3, None);
    while let Some(flag) = args.next() {
        let value = args.next().ok_or_else(|| anyhow::anyhow!(usage))?;
        match flag.as_str() {
            "--repeat" => repeat = value.parse()?,
            "--json" => json = Some(value),
            _ => anyhow::bail!(usage),
        }
    }
    let files = encoder_files(&campaign)?;
    let mut record = serde_json::Map::new();
    for (name, decode) in [
        ("collect", collect as fn(&[PathBuf]) -> PolarsResult<usize>),
        ("stream", stream),
    ] {
        let mut runs = Vec::new();
        let mut rows = 0;
        for _ in 0..repeat.max(1) {
            let start = Instant::now();
            rows = decode(&files)?;
            runs.push(start.elapsed().as_secs_f64());
        }
        let best = runs.iter().copied().fold(f64::INFINITY, f64::min);
        let shown: Vec<String> = runs.iter().map(|r| format!("{r:.3}")).collect();
        println!(
            "{name:8} {rows} rows  best of {} {best:.3} s  (runs: {})",
            runs.len(),
            shown.join(", ")
        );
        record.insert(format!("{name}_best_s"), best.into());
        record.insert(format!("{name}_runs_s"), runs.into());
        record.insert("encoder_rows".into(), rows.into());
    }
    if let Some(path) = json {
        std::fs::write(path, serde_json::to_string_pretty(&record)? + "\n")?;
    }
    Ok(())
}
