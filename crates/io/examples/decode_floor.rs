//! The floor under `dbbcal ingest`: how long this crate's parquet reader takes just to decode a
//! campaign's encoder files, the same columns `dbbcal` reads, with nothing done to the rows.
//!
//! Two ways, best of `--repeat` runs each:
//! * `collect`: every file decoded into memory (its batches kept until the file is done), row
//!   groups in parallel on every core, as `bench/bare_scan.py` does in Python;
//! * `stream`: as ingest reads the encoder files: two threads (`--threads N` to change it) each
//!   take the files' row groups in turn and decode them in batches (`time`, `bar` as a
//!   dictionary, `counts`), the batches dropped on arrival.
//!
//! The process allocates as the `dbbcal` binary does: mimalloc, freed memory kept for reuse,
//! no huge pages (`dbbcal_io::tune_memory`). `bench/decode_floor.py` is the same measurement in Python
//! polars.
//!
//! ```text
//! cargo run --release -p dbbcal-io --features bench-tools --example decode_floor -- bench/out/campaign-full \
//!     [--repeat 3] [--only collect|stream] [--threads 2] [--json FILE]
//! ```
//!
//! A benchmark tool (`bench/run.sh` runs it), built only with the `bench-tools` feature so that
//! `cargo test` does not link it.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use arrow_array::RecordBatch;
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::arrow_reader::{
    ArrowReaderMetadata, ArrowReaderOptions, ParquetRecordBatchReaderBuilder,
};
use parquet::arrow::ProjectionMask;
use rayon::prelude::*;

/// Rows of a batch, as ingest decodes them.
const BATCH_ROWS: usize = 64 * 1024;
/// Threads of the `stream` way, as ingest's consumers.
const STREAM_THREADS: usize = 2;

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

/// A file's footer with `bar` read as a dictionary (as ingest reads ids), and the mask of the
/// three columns.
struct Opened {
    path: PathBuf,
    meta: ArrowReaderMetadata,
    mask: ProjectionMask,
}

fn open(path: &Path) -> anyhow::Result<Opened> {
    let file = File::open(path).with_context(|| path.display().to_string())?;
    let plain = ArrowReaderMetadata::load(&file, ArrowReaderOptions::new())?;
    let fields: Vec<Field> = plain
        .schema()
        .fields()
        .iter()
        .map(|f| match f.name().as_str() {
            "bar" => f.as_ref().clone().with_data_type(DataType::Dictionary(
                Box::new(DataType::Int32),
                Box::new(DataType::Utf8),
            )),
            _ => f.as_ref().clone(),
        })
        .collect();
    let options = ArrowReaderOptions::new().with_schema(Arc::new(Schema::new(fields)));
    let meta = ArrowReaderMetadata::try_new(plain.metadata().clone(), options)?;
    let schema = meta.schema();
    let roots = ["time", "bar", "counts"]
        .iter()
        .map(|n| schema.index_of(n))
        .collect::<Result<Vec<_>, _>>()?;
    let descr = meta.metadata().file_metadata().schema_descr_ptr();
    let mask = ProjectionMask::roots(&descr, roots);
    Ok(Opened {
        path: path.to_path_buf(),
        meta,
        mask,
    })
}

/// The batches of row group `group`, each handed to `each`; the rows decoded.
fn decode_group(
    opened: &Opened,
    group: usize,
    each: &mut dyn FnMut(RecordBatch),
) -> anyhow::Result<usize> {
    // A file of its own: a clone would share its offset with another thread's reader.
    let reader = ParquetRecordBatchReaderBuilder::new_with_metadata(
        File::open(&opened.path)?,
        opened.meta.clone(),
    )
    .with_projection(opened.mask.clone())
    .with_batch_size(BATCH_ROWS)
    .with_row_groups(vec![group])
    .build()?;
    let mut rows = 0;
    for batch in reader {
        let batch = batch?;
        rows += batch.num_rows();
        each(batch);
    }
    Ok(rows)
}

/// Every (file, row group), in file order.
fn tasks(files: &[Opened]) -> Vec<(usize, usize)> {
    files
        .iter()
        .enumerate()
        .flat_map(|(f, o)| (0..o.meta.metadata().num_row_groups()).map(move |g| (f, g)))
        .collect()
}

/// Rows decoded by collecting every file into memory, its row groups in parallel (rayon's
/// threads: every core; `--threads` is the `stream` way's).
fn collect(paths: &[PathBuf], _threads: usize) -> anyhow::Result<usize> {
    let mut rows = 0;
    for path in paths {
        let opened = [open(path)?];
        let kept: Vec<Vec<RecordBatch>> = tasks(&opened)
            .par_iter()
            .map(|&(_, g)| {
                let mut batches = Vec::new();
                decode_group(&opened[0], g, &mut |b| batches.push(b))?;
                Ok(batches)
            })
            .collect::<anyhow::Result<_>>()?;
        rows += kept
            .iter()
            .flatten()
            .map(RecordBatch::num_rows)
            .sum::<usize>();
    }
    Ok(rows)
}

/// Rows decoded by streaming every file's row groups on `threads` threads, batches dropped.
fn stream(paths: &[PathBuf], threads: usize) -> anyhow::Result<usize> {
    let files = paths
        .iter()
        .map(|p| open(p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let work = tasks(&files);
    let (next, rows) = (AtomicUsize::new(0), AtomicUsize::new(0));
    std::thread::scope(|scope| -> anyhow::Result<()> {
        let threads: Vec<_> = (0..threads.max(1))
            .map(|_| {
                scope.spawn(|| -> anyhow::Result<()> {
                    while let Some(&(f, g)) = work.get(next.fetch_add(1, Ordering::Relaxed)) {
                        let n = decode_group(&files[f], g, &mut drop)?;
                        rows.fetch_add(n, Ordering::Relaxed);
                    }
                    Ok(())
                })
            })
            .collect();
        for t in threads {
            t.join()
                .map_err(|_| anyhow::anyhow!("a decoding thread panicked"))??;
        }
        Ok(())
    })?;
    Ok(rows.load(Ordering::Relaxed))
}

/// The binary's allocator (`src/main.rs`), so that the floor is measured as ingest allocates.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// One line on failure (no backtrace), exit code 2.
fn main() {
    dbbcal_io::tune_memory();
    if let Err(e) = run() {
        eprintln!("decode_floor: {e:#}");
        std::process::exit(2);
    }
}

fn run() -> anyhow::Result<()> {
    let usage =
        "usage: decode_floor CAMPAIGN_DIR [--repeat N] [--only collect|stream] [--threads N] [--json FILE]";
    let mut args = std::env::args().skip(1);
    let campaign = args.next().ok_or_else(|| anyhow::anyhow!(usage))?;
    let (mut repeat, mut json, mut only, mut threads) = (3, None, None, STREAM_THREADS);
    while let Some(flag) = args.next() {
        let value = args.next().ok_or_else(|| anyhow::anyhow!(usage))?;
        match flag.as_str() {
            "--repeat" => repeat = value.parse()?,
            "--json" => json = Some(value),
            "--threads" => threads = value.parse()?,
            "--only" if value == "collect" || value == "stream" => only = Some(value),
            _ => anyhow::bail!(usage),
        }
    }
    let files = encoder_files(&campaign)?;
    let mut record = serde_json::Map::new();
    for (name, decode) in [
        (
            "collect",
            collect as fn(&[PathBuf], usize) -> anyhow::Result<usize>,
        ),
        ("stream", stream),
    ] {
        if only.as_ref().is_some_and(|o| o != name) {
            continue;
        }
        let mut runs = Vec::new();
        let mut rows = 0;
        for _ in 0..repeat.max(1) {
            let start = Instant::now();
            rows = decode(&files, threads)?;
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
    record.insert("stream_threads".into(), threads.into());
    if let Some(path) = json {
        std::fs::write(path, serde_json::to_string_pretty(&record)? + "\n")?;
    }
    Ok(())
}
