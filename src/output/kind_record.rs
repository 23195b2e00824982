//! The head every machine kind's JSON record (`axis.json`, `probe.json`, `roll.json`,
//! `volumetric.json`) starts with, written once so that a kind's record holds only its own
//! fields. Flattened into the record: the JSON keeps the same keys in the same order.

use serde::Serialize;

use dbbcal_core::series::InputFile;

use super::inputs::{input_records, InputRecord};

/// Tool version, kind, campaign, pipeline (name and sha256) and every input file.
#[derive(Debug, Serialize)]
pub(crate) struct KindRecordHead {
    dbbcal_version: &'static str,
    kind: &'static str,
    campaign: String,
    pipeline: String,
    pipeline_sha256: String,
    inputs: Vec<InputRecord>,
}

impl KindRecordHead {
    /// The head of a `kind` record for `campaign`, run by `pipeline` (name, sha256).
    pub(crate) fn new(
        kind: &'static str,
        campaign: &str,
        pipeline: (&str, &str),
        inputs: &[InputFile],
    ) -> KindRecordHead {
        KindRecordHead {
            dbbcal_version: env!("CARGO_PKG_VERSION"),
            kind,
            campaign: campaign.to_string(),
            pipeline: pipeline.0.to_string(),
            pipeline_sha256: pipeline.1.to_string(),
            inputs: input_records(inputs),
        }
    }
}
