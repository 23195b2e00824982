//! What every machine kind's campaign reader (`axis`, `probe`, `roll`, `volumetric`) shares, so
//! that a kind's reader holds only its own tables: its manifest refused when it is of another
//! kind, and the input files stamped and hashed before any table is read.

use std::path::{Path, PathBuf};

use super::inputs::{hash_inputs, parquet_files, stamps, Stamp};
use super::IngestError;
use crate::manifest::campaign_kind;
use dbbcal_core::axis_campaign::CampaignKind;
use dbbcal_core::series::InputFile;

/// The shown path and text of `dir/campaign.toml`, refused unless its `[campaign] kind` is
/// `kind` (`a_campaign`: the kind with its article, as the message says it).
pub(crate) fn kind_manifest_text(
    dir: &Path,
    kind: CampaignKind,
    a_campaign: &str,
) -> Result<(String, String), IngestError> {
    let (path, text) = crate::read::read_manifest_text(dir)?;
    let file = path.display().to_string();
    let found = campaign_kind(&text, &file)?;
    if found != kind {
        return Err(IngestError::UnusableCampaign {
            path,
            problem: format!("is a {found} campaign ([campaign] kind), not {a_campaign}"),
        });
    }
    Ok((file, text))
}

/// The stamps and hashes of `manifest` then every file of `tables`, in that order (checked
/// again by `check_unchanged` when the read ends).
pub(crate) fn snapshot(
    dir: &Path,
    manifest: &Path,
    tables: &[&[PathBuf]],
) -> Result<(Vec<Stamp>, Vec<InputFile>), IngestError> {
    let mut all = vec![manifest.to_path_buf()];
    for files in tables {
        all.extend(files.iter().cloned());
    }
    let before = stamps(&all)?;
    let inputs = hash_inputs(dir, &all)?;
    Ok((before, inputs))
}

/// The parquet files of `dir/folder`, refused when there are none (a table the kind needs).
pub(crate) fn required_table(
    dir: &Path,
    folder: &'static str,
) -> Result<Vec<PathBuf>, IngestError> {
    let files = parquet_files(&dir.join(folder))?;
    if files.is_empty() {
        return Err(IngestError::MissingTable {
            folder: dir.join(folder),
            table: folder,
        });
    }
    Ok(files)
}
