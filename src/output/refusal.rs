//! Why an output location is refused (`OutputError::Refused`'s `why`): what overlaps the
//! campaign, a folder holding what dbbcal did not write, a parent it cannot write in, a mount
//! point.

use super::{escape, shown, MARKER};
use std::path::PathBuf;

/// Why dbbcal may not write, replace or remove an output location (one line; paths shown with
/// control characters escaped).
#[derive(Debug, thiserror::Error)]
pub(crate) enum Refusal {
    /// `OUT` is the campaign folder.
    #[error("it is the campaign folder {}", shown(.campaign))]
    IsCampaign { campaign: PathBuf },
    /// `OUT` lies inside the campaign folder.
    #[error("it is inside the campaign folder {}", shown(.campaign))]
    InsideCampaign { campaign: PathBuf },
    /// `OUT` holds the campaign folder.
    #[error("it holds the campaign folder {}", shown(.campaign))]
    HoldsCampaign { campaign: PathBuf },
    /// `OUT` lies inside the campaign folder through another path (a bind mount).
    #[error("it is inside the campaign folder {} (the same folder as {}, e.g. through a mount)", shown(.campaign), shown(.same))]
    InsideCampaignThrough { campaign: PathBuf, same: PathBuf },
    /// What a run would replace or remove holds the campaign folder.
    #[error("{} (which the run would replace or remove) holds the campaign folder {}", shown(.removable), shown(.campaign))]
    RemovableHoldsCampaign {
        removable: PathBuf,
        campaign: PathBuf,
    },
    /// What a run would replace or remove holds a file or folder of the campaign (same device
    /// and inode).
    #[error("{} (which the run would replace or remove) holds {} of the campaign (the same file or folder)", shown(.path), shown(.part))]
    RemovableHoldsCampaignPart { path: PathBuf, part: PathBuf },
    /// A folder without dbbcal's marker.
    #[error("holds files dbbcal did not write (no {MARKER})")]
    NoMarker,
    /// More files than any output holds (not listed further).
    #[error("holds more files than any dbbcal output")]
    TooManyFiles,
    /// The folder cannot be listed.
    #[error("cannot list it: {0}")]
    Unlistable(std::io::Error),
    /// A file the marker does not list.
    #[error("holds {}, which dbbcal did not write (it replaces only the files it wrote: move that elsewhere, or choose another folder)", escape(.file.trim_end_matches('/')))]
    NotWritten { file: String },
    /// A path with a NUL byte (no system call takes it).
    #[error("{0}")]
    NulInPath(std::ffi::NulError),
    /// The parent folder takes no new entries.
    #[error("cannot write in {}: {error}", shown(.parent))]
    NotWritable {
        parent: PathBuf,
        error: std::io::Error,
    },
    /// `OUT` is a mount point: it cannot be renamed.
    #[error("it is a mount point (dbbcal replaces an output by renaming it, which a mount point does not allow); give a folder inside it")]
    MountPoint,
}
