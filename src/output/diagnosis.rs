//! `diagnosis.json`: where the model fails per bar, and the ranked candidate effects.

use serde::Serialize;

use crate::diagnose::{self, Candidate, LedgerStep};
use crate::model::Effect;
use crate::pipeline::{Diagnosis, RunPlan, RunResults};
use crate::series::InputFile;

use super::summary::ModelRecord;

/// `diagnosis.json`: per bar where the model fails, and the ranked candidate effects (every
/// `effect` string is accepted verbatim by `--add-effect`).
#[derive(Debug, Serialize)]
pub struct DiagnosisRecord<'a> {
    pub campaign: &'a str,
    pub model: ModelRecord,
    pub inputs: &'a [InputFile],
    pub bars: Vec<BarDiagnosisRecord<'a>>,
    /// What each temperature sensor plausibly measures, judged from its signal.
    pub sensors: &'a [diagnose::sensors::SensorProfile],
    /// When a candidate is proposed: significant and removing at least `min_gain_um` of the
    /// fleet RMS.
    pub criteria: &'a diagnose::Criteria,
    /// Every candidate: `verdict` proposed / immaterial / not_significant / screened_out, with
    /// its `reason`.
    pub candidates: &'a [Candidate],
    /// Candidates that could not be fitted on any bar, with the reason.
    pub unavailable: &'a [diagnose::Unavailable],
    /// Fleet-wide forward selection: one model for every bar.
    pub ledger: &'a [LedgerStep],
    /// Each bar's own forward selection.
    pub bar_ledgers: &'a [diagnose::BarLedger],
}

#[derive(Debug, Serialize)]
pub struct BarDiagnosisRecord<'a> {
    pub bar: &'a str,
    pub rms_um: f64,
    pub peak_to_valley_um: f64,
    pub fit_percent: f64,
    pub whiteness_p: f64,
    pub ljung_box_q: f64,
    pub residual_correlation_time_samples: f64,
    pub channels: Vec<ChannelRecord<'a>>,
}

#[derive(Debug, Serialize)]
pub struct ChannelRecord<'a> {
    pub channel: &'a str,
    pub explained_fraction: f64,
    pub tau_s: f64,
    pub description: String,
}

pub fn diagnosis_record<'a>(
    plan: &RunPlan,
    r: &'a RunResults,
    d: &'a Diagnosis,
) -> DiagnosisRecord<'a> {
    DiagnosisRecord {
        campaign: &r.campaign.id,
        model: ModelRecord {
            effects: plan.effects.iter().map(Effect::name).collect(),
            bin_s: plan.bin_s,
        },
        inputs: &r.inputs,
        bars: d
            .bars
            .iter()
            .map(|b| BarDiagnosisRecord {
                bar: &b.bar,
                rms_um: b.rms_um,
                peak_to_valley_um: b.stats.peak_to_valley_um,
                fit_percent: b.stats.fit_percent,
                whiteness_p: b.whiteness_p,
                ljung_box_q: b.stats.ljung_box_q,
                residual_correlation_time_samples: b.stats.correlation_time_samples,
                channels: b
                    .channels
                    .iter()
                    .map(|c| ChannelRecord {
                        channel: &c.channel,
                        explained_fraction: c.explained_fraction,
                        tau_s: c.tau_s,
                        description: diagnose::sensors::describe_channel_with(
                            &c.channel, &d.sensors,
                        ),
                    })
                    .collect(),
            })
            .collect(),
        sensors: &d.sensors,
        criteria: &d.criteria,
        candidates: &d.candidates,
        unavailable: &d.unavailable,
        ledger: &d.ledger,
        bar_ledgers: &d.bar_ledgers,
    }
}
