//! Everything that touches files and parquet: reading a campaign directory into plain typed
//! series ([`read_campaign`]), writing one ([`write_campaign`], used by `simulate` and the tests),
//! and writing the pipeline's output tables ([`write_table`]). The `axis` machine kind has its
//! own reader and writer ([`read_axis_campaign`], [`write_axis_campaign`]).
//!
//! INVARIANT: this crate is the only code in the workspace that uses parquet and arrow. Its
//! public API speaks only in the crate's own types (`campaign`, `series`, [`Table`]), so a
//! parquet/arrow upgrade touches `crates/io/` alone.

mod alloc;
mod axis;
mod axis_write;
mod guard;
mod inputs;
mod kind_read;
mod kind_write;
pub mod manifest;
mod pq;
mod probe;
mod probe_write;
mod read;
mod repeats;
mod roll;
mod roll_write;
mod table;
mod volumetric;
mod volumetric_write;
mod write;

#[cfg(test)]
mod axis_tests;
#[cfg(test)]
mod fuzz_tests;
#[cfg(test)]
mod positions_tests;
#[cfg(test)]
mod roll_tests;
#[cfg(test)]
mod test_frames;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod volumetric_tests;

use std::path::{Path, PathBuf};

use dbbcal_core::campaign::CampaignError;
use dbbcal_core::series::CampaignLogs;

pub use alloc::tune_memory;
pub use axis::{read_axis_campaign, read_axis_manifest};
pub use axis_write::{write_axis_campaign, AxisWriteOptions};
pub use guard::decode_whole_file;
pub use probe::{read_probe_campaign, read_probe_manifest};
pub use probe_write::{write_probe_campaign, ProbeWriteOptions};
pub use roll::{read_roll_campaign, read_roll_manifest};
pub use roll_write::{write_roll_campaign, RollWriteOptions};
pub use table::{write_table, write_table_csv, Column, Table};
pub use volumetric::{read_volumetric_campaign, read_volumetric_manifest};
pub use volumetric_write::{write_volumetric_campaign, VolumetricWriteOptions};
pub use write::{write_campaign, TimeUnit, WriteError, WriteOptions};

/// Why a campaign directory could not be read. Every message is one line naming the file (and
/// column, id or key) that is wrong.
#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    /// No `campaign.toml` in the directory.
    #[error("{}: no campaign.toml here (not a campaign directory?)", dir.display())]
    MissingManifest {
        /// The directory given.
        dir: PathBuf,
    },
    /// A file could not be read.
    #[error("{}: cannot read: {message}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        message: String,
    },
    /// `campaign.toml` is invalid.
    #[error(transparent)]
    Manifest(#[from] CampaignError),
    /// A required table has no parquet files.
    #[error("{}: no *.parquet files (the {table} table is required)", folder.display())]
    MissingTable {
        /// The table's folder.
        folder: PathBuf,
        /// The table (`encoders`, `temperatures`).
        table: &'static str,
    },
    /// A file is not valid parquet.
    #[error("{}: not a valid parquet file: {reason}", path.display())]
    NotParquet {
        /// The file.
        path: PathBuf,
        /// The reader's message.
        reason: String,
    },
    /// A required column is missing.
    #[error("{}: missing column `{column}` (found: {found})", path.display())]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column required.
        column: &'static str,
        /// The columns the file has.
        found: String,
    },
    /// A column has the wrong type.
    #[error("{}: column `{column}` has type {found}, expected {expected}", path.display())]
    WrongType {
        /// The file.
        path: PathBuf,
        /// The column.
        column: &'static str,
        /// Its type.
        found: String,
        /// The type required.
        expected: &'static str,
    },
    /// Rows name a bar or sensor that `campaign.toml` does not declare.
    #[error(
        "{}: {rows} rows ({} .. {}) have {column} \"{id}\", which campaign.toml does not declare (known: {known})",
        path.display(), format_ns(*first_ns), format_ns(*last_ns)
    )]
    UnknownId {
        /// The file.
        path: PathBuf,
        /// `bar` or `sensor`.
        column: &'static str,
        /// The undeclared id.
        id: String,
        /// How many rows have it.
        rows: u64,
        /// Time of the first of those rows, ns since the epoch (UTC).
        first_ns: i64,
        /// Time of the last of those rows, ns since the epoch (UTC).
        last_ns: i64,
        /// The declared ids, comma-separated.
        known: String,
    },
    /// A column has null values.
    #[error("{}: column `{column}` has {count} null values", path.display())]
    Nulls {
        /// The file.
        path: PathBuf,
        /// The column.
        column: &'static str,
        /// How many nulls.
        count: u64,
    },
    /// A parquet/arrow failure that none of the checks above predicted (e.g. a corrupt data
    /// page).
    #[error("{context}: {message}")]
    Parquet {
        /// What was being read.
        context: String,
        /// The reader's message.
        message: String,
    },
    /// Rows whose value cannot be read as what the spec says (a time out of range, counts that
    /// are not whole numbers): named by file, column and row range (counting from 0).
    #[error(
        "{}: column `{column}`: {rows} rows (rows {first_row} .. {last_row}, counting from 0) {problem} (first: {example})",
        path.display()
    )]
    BadRows {
        /// The file.
        path: PathBuf,
        /// The column.
        column: &'static str,
        /// How many rows.
        rows: u64,
        /// The first of them (from 0).
        first_row: u64,
        /// The last of them (from 0).
        last_row: u64,
        /// What is wrong with them.
        problem: String,
        /// The first bad value.
        example: String,
    },
    /// A dependency panicked while reading the file (caught at the read, `io::guard`).
    #[error("{}: the parquet reader failed on this file (corrupt?): {message}", path.display())]
    Panicked {
        /// The file.
        path: PathBuf,
        /// The panic's message.
        message: String,
    },
    /// The file's size or modification time changed between hashing and the end of the read:
    /// the hash recorded would not be of the bytes analysed.
    #[error("{}: changed while it was being read ({what}); run again on a stable copy", path.display())]
    ChangedDuringRun {
        /// The file.
        path: PathBuf,
        /// What changed.
        what: String,
    },
    /// The `positions` log breaks a rule of `docs/spec/device-format.md` (a station's rows
    /// disagree, a coordinate is not finite).
    #[error(transparent)]
    Positions(#[from] dbbcal_core::positions::PositionsError),
    /// A campaign that cannot give any result (no bars, no mounts, no air for a bar).
    #[error("{}: {problem}", path.display())]
    UnusableCampaign {
        /// The campaign's directory or file concerned.
        path: PathBuf,
        /// Why no result is possible.
        problem: String,
    },
}

/// Reads `positions/*.parquet` of a device campaign (`docs/spec/device-format.md`): `None` when
/// the campaign has none. The files' hashes come with the log, for `inputs.json`. Every error is
/// one line naming the file, the column and the rows.
pub fn read_positions(
    dir: &Path,
) -> Result<
    Option<(
        dbbcal_core::positions::PositionsLog,
        Vec<dbbcal_core::series::InputFile>,
    )>,
    IngestError,
> {
    let files = inputs::parquet_files(&dir.join("positions"))?;
    if files.is_empty() {
        return Ok(None);
    }
    let hashes = inputs::hash_inputs(dir, &files)?;
    let log = read::read_positions_files(&files)?;
    Ok(Some((log, hashes)))
}

/// Reads a campaign directory (see `docs/spec/campaign-format.md`): the manifest, every
/// `encoders/*.parquet` and `temperatures/*.parquet`, and `events/*.parquet` if present.
///
/// Files may be split in any way and rows may be in any order; the result is sorted by time
/// (ties by value). Bar logs come with an empty [`dbbcal_core::series::BarLog::celsius`]:
/// [`dbbcal_core::series::interpolate_temperatures`] puts each sensor's log onto a bar's encoder
/// times when that bar is processed, so the temperatures of every bar at every encoder time
/// are never held at once.
pub fn read_campaign(dir: &Path) -> Result<CampaignLogs, IngestError> {
    read_campaign_binned(dir, 0.0)
}

/// [`read_campaign`], with every bar's encoder rows compressed into bins of `bin_s` seconds
/// while they stream in ([`dbbcal_core::series::BarBins`], [`CampaignLogs::bins`]; the bar logs stay
/// empty): a campaign at 1 Hz is never held at full rate. `bin_s <= 0`: [`read_campaign`].
///
/// Every file is hashed (`inputs.json`): those sharing their size with another file of their
/// table before the read, so that a file byte-identical to an earlier one of its table is read
/// once and flagged (`quality.files`), the others beside the read; after it every file's size and
/// modification time are checked against those taken before hashing, so the hashes recorded
/// are of the bytes analysed ([`IngestError::ChangedDuringRun`] otherwise).
pub fn read_campaign_binned(dir: &Path, bin_s: f64) -> Result<CampaignLogs, IngestError> {
    let campaign = read::read_manifest(dir)?;
    let mut files = inputs::CampaignFiles::list(dir)?;
    let stamps = inputs::stamps(&files.all())?;
    let (hash_first, hash_beside) = inputs::split_by_shared_size(&files, &stamps);
    let mut inputs = inputs::hash_inputs(dir, &hash_first)?;
    let mut quality = dbbcal_core::series::Quality::default();
    inputs::skip_duplicate_files(dir, &mut files, &mut inputs, &mut quality);
    let (tables, hashed_beside) = std::thread::scope(|scope| {
        let hashing = scope.spawn(|| inputs::hash_inputs(dir, &hash_beside));
        let tables = read::read_tables(&files, &campaign, bin_s, &mut quality);
        let hashed = hashing.join().unwrap_or_else(|_| {
            Err(IngestError::Io {
                path: dir.to_path_buf(),
                message: "the input hashing thread panicked".into(),
            })
        });
        (tables, hashed)
    });
    let tables = tables?;
    inputs.extend(hashed_beside?);
    inputs.sort_by(|a, b| a.path.cmp(&b.path));
    inputs::check_unchanged(dir, &stamps, &inputs)?;
    Ok(CampaignLogs {
        campaign,
        inputs,
        bars: tables.bars,
        bins: tables.bins,
        sensors: tables.sensors,
        events: tables.events,
        quality,
    })
}

/// The campaign's manifest (`campaign.toml`) alone, read and validated: what a run needs to know
/// before any parquet is read (its id names the default output folder).
pub fn read_manifest(dir: &Path) -> Result<dbbcal_core::campaign::Campaign, IngestError> {
    read::read_manifest(dir)
}

/// The bin length to compress a campaign with when none is set
/// ([`dbbcal_core::series::automatic_bin_s`]): decided from `campaign.toml` and the encoder files'
/// parquet footers, before any row is read, so ingest can bin while it streams.
pub fn automatic_bin_s(dir: &Path) -> Result<f64, IngestError> {
    let campaign = read::read_manifest(dir)?;
    let mut files = inputs::CampaignFiles::list(dir)?;
    // A byte-identical copy of a file is read once, so its rows do not count twice here either
    // (only files sharing their size with another can be one: those are hashed).
    let stamps = inputs::stamps(&files.all())?;
    let (hash_first, _) = inputs::split_by_shared_size(&files, &stamps);
    let mut hashed = inputs::hash_inputs(dir, &hash_first)?;
    inputs::skip_duplicate_files(
        dir,
        &mut files,
        &mut hashed,
        &mut dbbcal_core::series::Quality::default(),
    );
    let rows = read::footer_rows(&files.encoders)?;
    Ok(dbbcal_core::series::automatic_bin_s(&campaign, rows))
}

/// The text of a small configuration file (`campaign.toml`, a pipeline file): a regular file
/// (links followed) of at most `max_bytes`, read with that bound whatever it claims to be (a link
/// to `/dev/urandom` or a FIFO is refused, never read until killed). The error is the reason,
/// for a message that names the file.
pub fn read_small_text(path: &Path, max_bytes: u64) -> Result<String, SmallTextError> {
    use std::io::Read;
    let fail = |why| SmallTextError { why };
    let meta = std::fs::metadata(path).map_err(|e| fail(Unreadable::Io(e)))?;
    if !meta.is_file() {
        return Err(fail(if meta.is_dir() {
            Unreadable::Folder
        } else {
            Unreadable::NotRegular
        }));
    }
    let file = std::fs::File::open(path).map_err(|e| fail(Unreadable::Io(e)))?;
    let mut bytes = Vec::new();
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(Unreadable::Io(e)))?;
    if bytes.len() as u64 > max_bytes {
        return Err(fail(Unreadable::TooLarge { max_bytes }));
    }
    String::from_utf8(bytes).map_err(|e| fail(Unreadable::NotUtf8(e)))
}

/// A small configuration file that could not be read: `cannot read: WHY`.
#[derive(Debug, thiserror::Error)]
#[error("cannot read: {why}")]
pub struct SmallTextError {
    /// Why.
    pub why: Unreadable,
}

/// Why a small configuration file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum Unreadable {
    /// The OS refused (no such file, no permission, …).
    #[error("{0}")]
    Io(std::io::Error),
    /// The path is a folder.
    #[error("it is a folder")]
    Folder,
    /// The path is a FIFO or a device.
    #[error("it is not a regular file (a FIFO or device)")]
    NotRegular,
    /// Larger than the bound.
    #[error("larger than {max_bytes} bytes, more than any such file holds")]
    TooLarge {
        /// The bound, bytes.
        max_bytes: u64,
    },
    /// Not UTF-8.
    #[error("not UTF-8 text ({0})")]
    NotUtf8(std::string::FromUtf8Error),
}

/// The largest `campaign.toml` read (bytes).
pub const MAX_MANIFEST_BYTES: u64 = 16 << 20;
/// The largest pipeline file read (bytes).
pub const MAX_PIPELINE_BYTES: u64 = 1 << 20;

/// Flattens a (possibly multi-line) message to one line.
pub(crate) fn one_line(s: impl std::fmt::Display) -> String {
    s.to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

/// An RFC 3339 UTC rendering of nanoseconds since the epoch, for messages.
pub fn format_ns(ns: i64) -> String {
    chrono::DateTime::from_timestamp_nanos(ns).to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true)
}
