//! Finding a campaign's input files and hashing them for the provenance record.

use std::io::Read;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::IngestError;
use dbbcal_core::series::quality::{Flag, FlagNote};
use dbbcal_core::series::{InputFile, Quality};

pub(crate) const MANIFEST: &str = "campaign.toml";
pub(crate) const ENCODERS: &str = "encoders";
pub(crate) const TEMPERATURES: &str = "temperatures";
pub(crate) const EVENTS: &str = "events";

/// The files of one campaign directory, each list sorted by path.
pub(crate) struct CampaignFiles {
    pub(crate) manifest: PathBuf,
    pub(crate) encoders: Vec<PathBuf>,
    pub(crate) temperatures: Vec<PathBuf>,
    pub(crate) events: Vec<PathBuf>,
}

impl CampaignFiles {
    /// Lists the table files; encoders and temperatures must have at least one file each.
    pub(crate) fn list(dir: &Path) -> Result<Self, IngestError> {
        Ok(Self {
            manifest: dir.join(MANIFEST),
            encoders: required_table(dir, ENCODERS)?,
            temperatures: required_table(dir, TEMPERATURES)?,
            events: parquet_files(&dir.join(EVENTS))?,
        })
    }

    pub(crate) fn all(&self) -> Vec<PathBuf> {
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
        if !name.ends_with(".parquet") || name.starts_with('.') {
            continue;
        }
        // A `*.parquet` that is not a regular file (a link to an unmounted share, a FIFO, a
        // folder) is refused by name: skipping it would analyse part of the campaign silently.
        match std::fs::metadata(&path) {
            Ok(m) if m.is_file() => files.push(path),
            other => {
                let what = match other {
                    Ok(m) if m.is_dir() => "a folder".to_string(),
                    Ok(_) => "not a regular file (a FIFO, socket or device)".to_string(),
                    Err(e) => match std::fs::read_link(&path) {
                        Ok(target) => format!(
                            "a symbolic link to {}, which cannot be read ({e})",
                            target.display()
                        ),
                        Err(_) => format!("cannot be read ({e})"),
                    },
                };
                return Err(IngestError::Io {
                    path,
                    message: format!("{what}; every *.parquet file of a table is read, so the campaign is refused (move it out of the folder, or make it readable)"),
                });
            }
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
        duplicate_of: None,
    })
}

fn relative_slash_path(dir: &Path, path: &Path) -> String {
    let rel = path.strip_prefix(dir).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// The files to hash before the read, and those whose hashes can wait until it ends: a file
/// can be byte-identical to another of its table ([`skip_duplicate_files`]) only if it has the
/// same size, so only files sharing their size with another of their table are hashed first;
/// the others are hashed on a thread beside the read (the manifest among them).
pub(crate) fn split_by_shared_size(
    files: &CampaignFiles,
    stamps: &[Stamp],
) -> (Vec<PathBuf>, Vec<PathBuf>) {
    let size: std::collections::HashMap<&Path, u64> =
        stamps.iter().map(|s| (s.path.as_path(), s.bytes)).collect();
    let (mut first, mut later) = (Vec::new(), vec![files.manifest.clone()]);
    for table in [&files.encoders, &files.temperatures, &files.events] {
        let mut files_of_size = std::collections::HashMap::<Option<u64>, usize>::new();
        for path in table {
            *files_of_size
                .entry(size.get(path.as_path()).copied())
                .or_default() += 1;
        }
        for path in table {
            let bytes = size.get(path.as_path()).copied();
            // A file without a stamp (cannot happen: every file is stamped) is hashed first.
            if bytes.is_none() || files_of_size[&bytes] > 1 {
                first.push(path.clone());
            } else {
                later.push(path.clone());
            }
        }
    }
    (first, later)
}

/// Size and modification time of a file, taken before it is hashed.
pub(crate) struct Stamp {
    path: PathBuf,
    bytes: u64,
    modified: Option<std::time::SystemTime>,
}

fn stamp(path: &Path) -> Result<Stamp, IngestError> {
    let meta = std::fs::metadata(path).map_err(|e| IngestError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(Stamp {
        path: path.to_path_buf(),
        bytes: meta.len(),
        modified: meta.modified().ok(),
    })
}

/// [`Stamp`]s of `files`, in order.
pub(crate) fn stamps(files: &[PathBuf]) -> Result<Vec<Stamp>, IngestError> {
    files.iter().map(|p| stamp(p)).collect()
}

/// The hashes are of the bytes analysed: each file kept the size and modification time it had
/// before hashing until the read ended, and the hash covered exactly that many bytes.
pub(crate) fn check_unchanged(
    dir: &Path,
    before: &[Stamp],
    hashed: &[InputFile],
) -> Result<(), IngestError> {
    for old in before {
        let now = stamp(&old.path)?;
        let changed = |what: String| IngestError::ChangedDuringRun {
            path: old.path.clone(),
            what,
        };
        if now.bytes != old.bytes {
            return Err(changed(format!("{} bytes, then {}", old.bytes, now.bytes)));
        }
        if now.modified != old.modified {
            return Err(changed("modification time moved".into()));
        }
        let rel = relative_slash_path(dir, &old.path);
        let hashed_bytes = hashed.iter().find(|f| f.path == rel).map(|f| f.bytes);
        if let Some(b) = hashed_bytes.filter(|&b| b != old.bytes) {
            return Err(changed(format!("{} bytes, {b} hashed", old.bytes)));
        }
    }
    Ok(())
}

/// A file byte-identical to an earlier one (by path) of its table is not read again: it is
/// dropped from `files`, marked `duplicate_of` in `inputs` and flagged in `quality.files`.
/// Files absent from `inputs` (not hashed: see [`split_by_shared_size`]) are kept.
pub(crate) fn skip_duplicate_files(
    dir: &Path,
    files: &mut CampaignFiles,
    inputs: &mut [InputFile],
    quality: &mut Quality,
) {
    let hash_of = |inputs: &[InputFile], path: &Path| {
        let rel = relative_slash_path(dir, path);
        inputs
            .iter()
            .find(|f| f.path == rel)
            .map(|f| f.sha256.clone())
    };
    for table in [
        &mut files.encoders,
        &mut files.temperatures,
        &mut files.events,
    ] {
        let mut seen: Vec<(String, String)> = Vec::new();
        let mut kept = Vec::new();
        for path in table.drain(..) {
            let rel = relative_slash_path(dir, &path);
            // Not hashed yet: its size is its table's alone, so it has no byte-identical twin.
            let Some(hash) = hash_of(inputs, &path) else {
                kept.push(path);
                continue;
            };
            match seen.iter().find(|(h, _)| *h == hash) {
                Some((_, first)) => {
                    if let Some(f) = inputs.iter_mut().find(|f| f.path == rel) {
                        f.duplicate_of = Some(first.clone());
                    }
                    let note = FlagNote::DuplicateFile {
                        file: rel,
                        same_as: first.clone(),
                    };
                    quality.files.push(Flag::file(note, 0));
                }
                None => {
                    seen.push((hash, rel));
                    kept.push(path);
                }
            }
        }
        *table = kept;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_files_sharing_a_size_are_hashed_before_the_read_and_twins_are_found_among_them() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join(ENCODERS)).unwrap();
        std::fs::create_dir(d.join(TEMPERATURES)).unwrap();
        std::fs::write(d.join(MANIFEST), "manifest").unwrap();
        for (name, bytes) in [("a", "xxxx"), ("b", "xxxx"), ("c", "yyyyy"), ("d", "zzzz")] {
            std::fs::write(d.join(ENCODERS).join(format!("{name}.parquet")), bytes).unwrap();
        }
        // A temperature file of an encoder file's size: sizes are compared within a table.
        std::fs::write(d.join(TEMPERATURES).join("t.parquet"), "wwwww").unwrap();
        let mut files = CampaignFiles::list(d).unwrap();
        let stamps = stamps(&files.all()).unwrap();
        let (first, later) = split_by_shared_size(&files, &stamps);
        let names = |paths: &[PathBuf]| -> Vec<String> {
            paths.iter().map(|p| relative_slash_path(d, p)).collect()
        };
        assert_eq!(
            names(&first),
            [
                "encoders/a.parquet",
                "encoders/b.parquet",
                "encoders/d.parquet"
            ]
        );
        assert_eq!(
            names(&later),
            [
                "campaign.toml",
                "encoders/c.parquet",
                "temperatures/t.parquet"
            ]
        );
        let mut inputs = hash_inputs(d, &first).unwrap();
        let mut quality = Quality::default();
        skip_duplicate_files(d, &mut files, &mut inputs, &mut quality);
        assert_eq!(
            names(&files.encoders),
            [
                "encoders/a.parquet",
                "encoders/c.parquet",
                "encoders/d.parquet"
            ]
        );
        assert_eq!(quality.files.len(), 1);
        let b = inputs
            .iter()
            .find(|f| f.path == "encoders/b.parquet")
            .unwrap();
        assert_eq!(b.duplicate_of.as_deref(), Some("encoders/a.parquet"));
        assert!(inputs
            .iter()
            .all(|f| f.path == "encoders/b.parquet" || f.duplicate_of.is_none()));
    }
}
