//! `before_after.json`: what the model's added effects bought, each bar's base-model refit
//! beside the model (`identify::BeforeAfter`).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::identify::{BarBeforeAfter, BeforeAfter};

/// `before_after.json`.
#[derive(Debug, Serialize)]
pub(crate) struct BeforeAfterRecord<'a> {
    pub(crate) before_effects: &'a [String],
    pub(crate) after_effects: &'a [String],
    pub(crate) bars: Vec<BarBeforeAfterRecord<'a>>,
    pub(crate) fleet_rms_before_um: f64,
    pub(crate) fleet_rms_after_um: f64,
}

impl<'a> From<&'a BeforeAfter> for BeforeAfterRecord<'a> {
    fn from(b: &'a BeforeAfter) -> Self {
        BeforeAfterRecord {
            before_effects: &b.before_effects,
            after_effects: &b.after_effects,
            bars: b.bars.iter().map(BarBeforeAfterRecord::from).collect(),
            fleet_rms_before_um: b.fleet_rms_before_um,
            fleet_rms_after_um: b.fleet_rms_after_um,
        }
    }
}

/// One bar with the base model and with the model.
#[derive(Debug, Serialize)]
pub(crate) struct BarBeforeAfterRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) rms_before_um: f64,
    pub(crate) rms_after_um: f64,
    pub(crate) params_before: &'a BTreeMap<String, f64>,
    pub(crate) params_after: &'a BTreeMap<String, f64>,
}

impl<'a> From<&'a BarBeforeAfter> for BarBeforeAfterRecord<'a> {
    fn from(b: &'a BarBeforeAfter) -> Self {
        BarBeforeAfterRecord {
            bar: &b.bar,
            rms_before_um: b.rms_before_um,
            rms_after_um: b.rms_after_um,
            params_before: &b.params_before,
            params_after: &b.params_after,
        }
    }
}
