//! Writing a `volumetric` campaign directory (what the simulator produces): readings split by
//! diagonal or not, rows shuffled or not, `direction` written or not.

use crate::manifest::TomlManifest;

use std::path::Path;

use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::kind_write::{column, f64_column, prepare, time_column, write_manifest};
use super::write::{write_parquet, TimeUnit, WriteError};
use dbbcal_core::volumetric_campaign::{VolumetricCampaignTables, VolumetricManifest};

/// How [`write_volumetric_campaign`] lays out the tables.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct VolumetricWriteOptions {
    /// One file per diagonal instead of one per table.
    pub split_by_diagonal: bool,
    /// Shuffle the rows inside each file.
    pub shuffle_rows: bool,
    /// Leave out the optional `direction` column of `diagonals/`.
    pub omit_direction: bool,
    /// Seed of the shuffle.
    pub seed: u64,
}

/// Writes `campaign.toml`, `diagonals/`, `steps/`, `bar_diagonals/` and `environment/` under
/// `dir`.
pub fn write_volumetric_campaign(
    dir: &Path,
    manifest: &VolumetricManifest,
    tables: &VolumetricCampaignTables,
    opts: &VolumetricWriteOptions,
) -> Result<(), WriteError> {
    write_manifest(dir, manifest.to_toml_string())?;
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed.wrapping_mul(17).wrapping_add(3));
    let groups = |n: usize, key: &dyn Fn(usize) -> &'static str| -> Vec<(String, Vec<usize>)> {
        if !opts.split_by_diagonal {
            return vec![("all".into(), (0..n).collect())];
        }
        let mut g: Vec<(String, Vec<usize>)> = Vec::new();
        for i in 0..n {
            let name = match key(i) {
                "+++" => "ppp",
                "-++" => "mpp",
                "+-+" => "pmp",
                _ => "ppm",
            };
            match g.iter_mut().find(|(k, _)| k == name) {
                Some((_, v)) => v.push(i),
                None => g.push((name.to_string(), vec![i])),
            }
        }
        g
    };
    if !tables.diagonals.is_empty() {
        let folder = dir.join("diagonals");
        prepare(&folder)?;
        let rows = &tables.diagonals;
        for (name, mut idx) in groups(rows.len(), &|i| rows[i].diagonal.as_str()) {
            if opts.shuffle_rows {
                idx.shuffle(&mut rng);
            }
            let path = folder.join(format!("diagonals-{name}.parquet"));
            let r: Vec<_> = idx.iter().map(|&i| rows[i]).collect();
            let mut columns = vec![
                time_column(r.iter().map(|x| x.time_ns), TimeUnit::Ns),
                column(
                    "diagonal",
                    r.iter().map(|x| x.diagonal.as_str()).collect::<Vec<_>>(),
                ),
                column("run", r.iter().map(|x| x.run).collect::<Vec<_>>()),
            ];
            if !opts.omit_direction {
                columns.push(column(
                    "direction",
                    r.iter().map(|x| x.direction).collect::<Vec<i8>>(),
                ));
            }
            columns.push(f64_column("target_mm", r.iter().map(|x| x.target_mm)));
            columns.push(f64_column("deviation_um", r.iter().map(|x| x.deviation_um)));
            write_parquet(&path, columns)?;
        }
    }
    if !tables.steps.is_empty() {
        let folder = dir.join("steps");
        prepare(&folder)?;
        let rows = &tables.steps;
        for (name, mut idx) in groups(rows.len(), &|i| rows[i].diagonal.as_str()) {
            if opts.shuffle_rows {
                idx.shuffle(&mut rng);
            }
            let path = folder.join(format!("steps-{name}.parquet"));
            let r: Vec<_> = idx.iter().map(|&i| rows[i]).collect();
            let columns = vec![
                time_column(r.iter().map(|x| x.time_ns), TimeUnit::Ns),
                column(
                    "diagonal",
                    r.iter().map(|x| x.diagonal.as_str()).collect::<Vec<_>>(),
                ),
                column("run", r.iter().map(|x| x.run).collect::<Vec<_>>()),
                column("step", r.iter().map(|x| x.step).collect::<Vec<_>>()),
                column(
                    "submove",
                    r.iter()
                        .map(|x| x.submove.map(|a| a.as_str()))
                        .collect::<Vec<_>>(),
                ),
                f64_column("x_mm", r.iter().map(|x| x.position_mm[0])),
                f64_column("y_mm", r.iter().map(|x| x.position_mm[1])),
                f64_column("z_mm", r.iter().map(|x| x.position_mm[2])),
                f64_column("deviation_um", r.iter().map(|x| x.deviation_um)),
            ];
            write_parquet(&path, columns)?;
        }
    }
    if !tables.bar_readings.is_empty() {
        let folder = dir.join("bar_diagonals");
        prepare(&folder)?;
        let rows = &tables.bar_readings;
        for (name, mut idx) in groups(rows.len(), &|i| rows[i].diagonal.as_str()) {
            if opts.shuffle_rows {
                idx.shuffle(&mut rng);
            }
            let path = folder.join(format!("bar-{name}.parquet"));
            let r: Vec<_> = idx.iter().map(|&i| rows[i]).collect();
            let mut columns = vec![
                time_column(r.iter().map(|x| x.time_ns), TimeUnit::Ns),
                column(
                    "diagonal",
                    r.iter().map(|x| x.diagonal.as_str()).collect::<Vec<_>>(),
                ),
                column("segment", r.iter().map(|x| x.segment).collect::<Vec<_>>()),
                column("run", r.iter().map(|x| x.run).collect::<Vec<_>>()),
                // Always written: a bar reading's direction is not derived (default +1).
                column(
                    "direction",
                    r.iter().map(|x| x.direction).collect::<Vec<i8>>(),
                ),
            ];
            columns.push(f64_column(
                "distance_along_mm",
                r.iter().map(|x| x.distance_along_mm),
            ));
            columns.push(f64_column(
                "centre_distance_mm",
                r.iter().map(|x| x.centre_distance_mm),
            ));
            columns.push(column("u_um", r.iter().map(|x| x.u_um).collect::<Vec<_>>()));
            write_parquet(&path, columns)?;
        }
    }
    if !tables.environment.is_empty() {
        let folder = dir.join("environment");
        prepare(&folder)?;
        let rows = &tables.environment;
        let path = folder.join("environment.parquet");
        let columns = vec![
            time_column(rows.iter().map(|r| r.time_ns), TimeUnit::Ns),
            f64_column("air_c", rows.iter().map(|r| r.air_c)),
            f64_column("pressure_hpa", rows.iter().map(|r| r.pressure_hpa)),
            f64_column("humidity_pct", rows.iter().map(|r| r.humidity_pct)),
            column(
                "material_c",
                rows.iter().map(|r| r.material_c).collect::<Vec<_>>(),
            ),
        ];
        write_parquet(&path, columns)?;
    }
    Ok(())
}
