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
pub(crate) struct DiagnosisRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) model: ModelRecord,
    pub(crate) inputs: &'a [InputFile],
    pub(crate) bars: Vec<BarDiagnosisRecord<'a>>,
    /// What each temperature sensor plausibly measures, judged from its signal.
    pub(crate) sensors: &'a [diagnose::sensors::SensorProfile],
    /// When a candidate is proposed: significant and removing at least `min_gain_um` of the
    /// fleet RMS.
    pub(crate) criteria: &'a diagnose::Criteria,
    /// Every candidate: `verdict` proposed / immaterial / not_significant / screened_out, with
    /// its `reason`.
    pub(crate) candidates: &'a [Candidate],
    /// Candidates that could not be fitted on any bar, with the reason.
    pub(crate) unavailable: &'a [diagnose::Unavailable],
    /// Fleet-wide forward selection: one model for every bar.
    pub(crate) ledger: &'a [LedgerStep],
    /// Each bar's own forward selection.
    pub(crate) bar_ledgers: &'a [diagnose::BarLedger],
}

#[derive(Debug, Serialize)]
pub(crate) struct BarDiagnosisRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) rms_um: f64,
    pub(crate) peak_to_valley_um: f64,
    pub(crate) fit_percent: f64,
    pub(crate) whiteness_p: f64,
    pub(crate) ljung_box_q: f64,
    pub(crate) residual_correlation_time_samples: f64,
    pub(crate) channels: Vec<ChannelRecord<'a>>,
}

#[derive(Debug, Serialize)]
pub(crate) struct ChannelRecord<'a> {
    pub(crate) channel: &'a str,
    pub(crate) explained_fraction: f64,
    pub(crate) tau_s: f64,
    pub(crate) description: String,
}

pub(crate) fn diagnosis_record<'a>(
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
                        description: diagnose::explain::describe_channel_with(
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
