//! `inputs.json`, and the `inputs` of every other record: each input file the run read, with its
//! hash.

use serde::Serialize;

use crate::series::InputFile;

/// One input file the run read (`series::InputFile`).
#[derive(Debug, Serialize)]
pub(crate) struct InputRecord {
    /// Path relative to the campaign directory, `/`-separated.
    pub(crate) path: String,
    pub(crate) sha256: String,
    pub(crate) bytes: u64,
    /// Another input file with the same bytes: this one was not read again.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) duplicate_of: Option<String>,
}

impl From<&InputFile> for InputRecord {
    fn from(f: &InputFile) -> Self {
        InputRecord {
            path: f.path.clone(),
            sha256: f.sha256.clone(),
            bytes: f.bytes,
            duplicate_of: f.duplicate_of.clone(),
        }
    }
}

/// The records of `files`, in their order.
pub(crate) fn input_records(files: &[InputFile]) -> Vec<InputRecord> {
    files.iter().map(InputRecord::from).collect()
}
