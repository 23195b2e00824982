//! `summary.json`'s `quality`: what ingest dropped, counted and flagged, per bar, sensor, the
//! events and the files (`docs/guarantees.md`, "Inputs").

use std::collections::BTreeMap;

use serde::Serialize;

use crate::narrative::quality::{note, unusable};
use crate::series::quality::{ChannelQuality, Flag, FlagKind};
use crate::series::Quality;

/// Everything ingest found (`series::Quality`).
#[derive(Debug, Serialize)]
pub(crate) struct QualityRecord<'a> {
    pub(crate) bars: BTreeMap<&'a str, ChannelQualityRecord<'a>>,
    pub(crate) sensors: BTreeMap<&'a str, ChannelQualityRecord<'a>>,
    pub(crate) events: ChannelQualityRecord<'a>,
    pub(crate) files: Vec<FlagRecord<'a>>,
}

impl<'a> From<&'a Quality> for QualityRecord<'a> {
    fn from(q: &'a Quality) -> Self {
        let channels = |m: &'a BTreeMap<String, ChannelQuality>| {
            m.iter()
                .map(|(k, v)| (k.as_str(), ChannelQualityRecord::new(k, v)))
                .collect()
        };
        QualityRecord {
            bars: channels(&q.bars),
            sensors: channels(&q.sensors),
            events: ChannelQualityRecord::new("events", &q.events),
            files: q.files.iter().map(FlagRecord::from).collect(),
        }
    }
}

/// Counts of one bar's, sensor's or the events' rows, and the flags raised on them.
#[derive(Debug, Serialize)]
pub(crate) struct ChannelQualityRecord<'a> {
    pub(crate) rows: u64,
    pub(crate) null: u64,
    pub(crate) nan: u64,
    pub(crate) inf: u64,
    pub(crate) duplicate_rows: u64,
    pub(crate) fault_rows: u64,
    pub(crate) dropped_rows: u64,
    pub(crate) flags: Vec<FlagRecord<'a>>,
    /// Set when no usable reading is left: the bar fails alone for this reason.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) unusable: Option<String>,
}

impl<'a> ChannelQualityRecord<'a> {
    /// The record of `q`, the quality of the bar, sensor or events `name` (a bar's `unusable`
    /// names it).
    fn new(name: &str, q: &'a ChannelQuality) -> Self {
        ChannelQualityRecord {
            rows: q.rows,
            null: q.null,
            nan: q.nan,
            inf: q.inf,
            duplicate_rows: q.duplicate_rows,
            fault_rows: q.fault_rows,
            dropped_rows: q.dropped_rows,
            flags: q.flags.iter().map(FlagRecord::from).collect(),
            unusable: q.unusable.map(|why| unusable(name, why)),
        }
    }
}

/// What was found, where and how big.
#[derive(Debug, Serialize)]
pub(crate) struct FlagRecord<'a> {
    pub(crate) kind: &'static str,
    /// RFC 3339 UTC, first and last affected reading (absent for file-level flags).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) from: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) to: Option<&'a str>,
    pub(crate) rows: u64,
    /// Signed size of a jump or wrap, counts and µm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) size_counts: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) size_um: Option<f64>,
    pub(crate) note: String,
}

impl<'a> From<&'a Flag> for FlagRecord<'a> {
    fn from(f: &'a Flag) -> Self {
        FlagRecord {
            kind: flag_kind_word(f.kind()),
            from: f.from.as_deref(),
            to: f.to.as_deref(),
            rows: f.rows,
            size_counts: f.size_counts,
            size_um: f.size_um,
            note: note(f),
        }
    }
}

/// A flag kind's name in `summary.json` (snake case), e.g. `counter_wrap`.
pub(crate) fn flag_kind_word(kind: FlagKind) -> &'static str {
    match kind {
        FlagKind::MissingValues => "missing_values",
        FlagKind::DuplicateRows => "duplicate_rows",
        FlagKind::DuplicateFile => "duplicate_file",
        FlagKind::MixedTimeZones => "mixed_time_zones",
        FlagKind::Stuck => "stuck",
        FlagKind::Jump => "jump",
        FlagKind::CounterWrap => "counter_wrap",
        FlagKind::FarOutsideMounts => "far_outside_mounts",
        FlagKind::OverlappingFiles => "overlapping_files",
        FlagKind::ConflictingReadings => "conflicting_readings",
        FlagKind::Gap => "gap",
        FlagKind::ImplausibleTemperature => "implausible_temperature",
        FlagKind::UnusableRows => "unusable_rows",
    }
}
