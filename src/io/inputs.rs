//! Finding a campaign's input files and hashing them for the provenance record.

use std::io::Read;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::IngestError;
use crate::series::InputFile;

pub(crate) const MANIFEST: &str = "campaign.toml";
pub(crate) const ENCODERS: &str = "encoders";
pub(crate) const TEMPERATURES: &str = "temperatures";
pub(crate) const EVENTS: &str = "events";

/// The files of one campaign directory, each list sorted by path.
pub(crate) struct CampaignFiles {
    pub manifest: PathBuf,
    pub encoders: Vec<PathBuf>,
    pub temperatures: Vec<PathBuf>,
    pub events: Vec<PathBuf>,
}

impl CampaignFiles {
    /// Lists the table files; encoders and temperatures must have at least one file each.
    pub fn list(dir: &Path) -> Result<Self, IngestError> {
        Ok(Self {
            manifest: dir.join(MANIFEST),
            encoders: required_table(dir, ENCODERS)?,
            temperatures: required_table(dir, TEMPERATURES)?,
            events: parquet_files(&dir.join(EVENTS))?,
        })
    }

    pub fn all(&self) -> Vec<PathBuf> {
        let mut all = vec![self.manifest.clone()];
        all.extend(self.encoders.iter().cloned());
        all.extend(self.temperatures.iter().cloned());
        all.extend(self.events.iter().cloned());
        all
    }
}

fn required_table(dir: &Path, table: &'static str) -> Result<Vec<PathBuf>, IngestError> {
    let folder = dir.join(table);
    let files = parquet_files(&folder)?;
    if files.is_empty() {
        return Err(IngestError::MissingTable { folder, table });
    }
    Ok(files)
}

/// `folder/*.parquet`, sorted; hidden files are skipped and a missing folder is empty.
pub(crate) fn parquet_files(folder: &Path) -> Result<Vec<PathBuf>, IngestError> {
    if !folder.is_dir() {
        return Ok(Vec::new());
    }
    let io_err = |e: std::io::Error| IngestError::Io {
        path: folder.to_path_buf(),
        message: e.to_string(),
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(folder).map_err(io_err)? {
        let path = entry.map_err(io_err)?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if path.is_file() && name.ends_with(".parquet") && !name.starts_with('.') {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// SHA-256 of every file, paths relative to `dir` and `/`-separated, sorted by path.
pub(crate) fn hash_inputs(dir: &Path, files: &[PathBuf]) -> Result<Vec<InputFile>, IngestError> {
    let mut inputs = files
        .par_iter()
        .map(|path| hash_file(dir, path))
        .collect::<Result<Vec<_>, _>>()?;
    inputs.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(inputs)
}

fn hash_file(dir: &Path, path: &Path) -> Result<InputFile, IngestError> {
    let io_err = |e: std::io::Error| IngestError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut file = std::fs::File::open(path).map_err(io_err)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = file.read(&mut buf).map_err(io_err)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        bytes += n as u64;
    }
    let hex = hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<String>();
    Ok(InputFile {
        path: relative_slash_path(dir, path),
        sha256: hex,
        bytes,
    })
}

fn relative_slash_path(dir: &Path, path: &Path) -> String {
    let rel = path.strip_prefix(dir).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}
