//! Writing an `axis` campaign directory (what the simulator produces), with options that
//! exercise the reader's tolerance: readings split by line, coarser time units, shuffled rows,
//! dictionary channels, no `direction` column.

use crate::manifest::TomlManifest;

use std::path::Path;

use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::kind_write::{
    column, dictionary, f64_column, prepare, time_column, write_manifest, Columns,
};
use super::write::{write_parquet, TimeUnit, WriteError};
use dbbcal_core::axis_campaign::{AxisCampaignTables, AxisManifest, AxisReading};

/// How [`write_axis_campaign`] lays out the tables. The default: one file per table, ns, rows
/// in the given order, plain strings, `direction` written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AxisWriteOptions {
    /// One readings file per line (`readings/line-<id>.parquet`) instead of one.
    pub split_by_line: bool,
    /// Unit of the timestamp columns.
    pub time_unit: TimeUnit,
    /// Shuffle the rows inside each file (seeded by `seed`).
    pub shuffle_rows: bool,
    /// Write `channel` as a dictionary (categorical) column.
    pub dictionary_strings: bool,
    /// Write the optional `direction` column (else the reader derives it).
    pub write_direction: bool,
    /// Seed of the row shuffle.
    pub seed: u64,
}

impl Default for AxisWriteOptions {
    fn default() -> Self {
        Self {
            split_by_line: false,
            time_unit: TimeUnit::Ns,
            shuffle_rows: false,
            dictionary_strings: false,
            write_direction: true,
            seed: 0,
        }
    }
}

/// Writes `campaign.toml`, `readings/`, and `fixture/` and `environment/` when they have rows,
/// under `dir` (created if needed). Existing `*.parquet` files in those folders are removed
/// first, so a rewrite never leaves stale files for the reader.
pub fn write_axis_campaign(
    dir: &Path,
    manifest: &AxisManifest,
    tables: &AxisCampaignTables,
    opts: &AxisWriteOptions,
) -> Result<(), WriteError> {
    write_manifest(dir, manifest.to_toml_string())?;
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed.wrapping_mul(31).wrapping_add(7));

    let folder = dir.join("readings");
    prepare(&folder)?;
    let mut files: Vec<(String, Vec<&AxisReading>)> = Vec::new();
    if opts.split_by_line {
        let mut lines: Vec<i64> = tables.readings.iter().map(|r| r.line).collect();
        lines.sort_unstable();
        lines.dedup();
        for line in lines {
            let rows = tables.readings.iter().filter(|r| r.line == line).collect();
            files.push((format!("line-{line}"), rows));
        }
    } else {
        files.push(("readings".into(), tables.readings.iter().collect()));
    }
    for (name, mut rows) in files {
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        }
        let path = folder.join(format!("{name}.parquet"));
        write_parquet(&path, readings_frame(&rows, opts))?;
    }

    let folder = dir.join("fixture");
    prepare(&folder)?;
    if !tables.fixture.is_empty() {
        let mut rows: Vec<_> = tables.fixture.iter().collect();
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        }
        let path = folder.join("fixture.parquet");
        let columns = vec![
            time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
            column("line", rows.iter().map(|r| r.line).collect::<Vec<_>>()),
            f64_column("x_mm", rows.iter().map(|r| r.reflector_mm[0])),
            f64_column("y_mm", rows.iter().map(|r| r.reflector_mm[1])),
            f64_column("z_mm", rows.iter().map(|r| r.reflector_mm[2])),
        ];
        write_parquet(&path, columns)?;
    }

    let folder = dir.join("environment");
    prepare(&folder)?;
    if !tables.environment.is_empty() {
        let mut rows: Vec<_> = tables.environment.iter().collect();
        if opts.shuffle_rows {
            rows.shuffle(&mut rng);
        }
        let path = folder.join("environment.parquet");
        let columns = vec![
            time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
            f64_column("air_c", rows.iter().map(|r| r.air_c)),
            f64_column("pressure_hpa", rows.iter().map(|r| r.pressure_hpa)),
            f64_column("humidity_pct", rows.iter().map(|r| r.humidity_pct)),
            column(
                "material_c",
                rows.iter().map(|r| r.material_c).collect::<Vec<_>>(),
            ),
            column(
                "env_factor_ppm",
                rows.iter().map(|r| r.env_factor_ppm).collect::<Vec<_>>(),
            ),
        ];
        write_parquet(&path, columns)?;
    }
    Ok(())
}

fn readings_frame(rows: &[&AxisReading], opts: &AxisWriteOptions) -> Columns {
    let mut columns = vec![
        time_column(rows.iter().map(|r| r.time_ns), opts.time_unit),
        column("line", rows.iter().map(|r| r.line).collect::<Vec<_>>()),
        column("run", rows.iter().map(|r| r.run).collect::<Vec<_>>()),
    ];
    if opts.write_direction {
        columns.push(column(
            "direction",
            rows.iter().map(|r| r.direction).collect::<Vec<i8>>(),
        ));
    }
    columns.push(f64_column("target_mm", rows.iter().map(|r| r.target_mm)));
    let channel = rows.iter().map(|r| r.channel.as_str());
    columns.push(if opts.dictionary_strings {
        dictionary("channel", channel)
    } else {
        column("channel", channel.collect::<Vec<_>>())
    });
    columns.push(f64_column(
        "deviation_um",
        rows.iter().map(|r| r.deviation_um),
    ));
    columns
}
