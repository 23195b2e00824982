//! `diagnosis.json`: where the model fails per bar, and the ranked candidate effects.

use serde::Serialize;

use crate::campaign::SensorKind;
use crate::diagnose::sensors::SensorProfile;
use crate::diagnose::{self, Candidate, CandidateOnBar, LedgerStep, Verdict};
use crate::model::Effect;
use crate::narrative::{diagnosis::reason, effects, sensors};
use crate::pipeline::{Diagnosis, RunPlan, RunResults};

use super::inputs::{input_records, InputRecord};
use super::summary::{effect_names, ModelRecord};

/// `diagnosis.json`: per bar where the model fails, and the ranked candidate effects (every
/// `effect` string is accepted verbatim by `--add-effect`).
#[derive(Debug, Serialize)]
pub(crate) struct DiagnosisRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) model: ModelRecord,
    pub(crate) inputs: Vec<InputRecord>,
    pub(crate) bars: Vec<BarDiagnosisRecord<'a>>,
    /// What each temperature sensor plausibly measures, judged from its signal.
    pub(crate) sensors: Vec<SensorProfileRecord<'a>>,
    /// When a candidate is proposed: significant and removing at least `min_gain_um` of the
    /// fleet RMS.
    pub(crate) criteria: CriteriaRecord,
    /// Every candidate: `verdict` proposed / immaterial / not_significant / screened_out, with
    /// its `reason`.
    pub(crate) candidates: Vec<CandidateRecord<'a>>,
    /// Candidates that could not be fitted on any bar, with the reason.
    pub(crate) unavailable: Vec<UnavailableRecord>,
    /// Fleet-wide forward selection: one model for every bar.
    pub(crate) ledger: Vec<LedgerStepRecord<'a>>,
    /// Each bar's own forward selection.
    pub(crate) bar_ledgers: Vec<BarLedgerRecord<'a>>,
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
        inputs: input_records(&r.inputs),
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
                        description: effects::describe_channel_with(&c.channel, &d.sensors),
                    })
                    .collect(),
            })
            .collect(),
        sensors: d.sensors.iter().map(SensorProfileRecord::from).collect(),
        criteria: CriteriaRecord::from(&d.criteria),
        candidates: d
            .candidates
            .iter()
            .map(|c| CandidateRecord::new(c, &d.sensors))
            .collect(),
        unavailable: d
            .unavailable
            .iter()
            .map(|u| UnavailableRecord {
                effect: u.effect.name(),
                reason: u
                    .reason
                    .as_ref()
                    .map(ToString::to_string)
                    .unwrap_or_default(),
            })
            .collect(),
        ledger: d.ledger.iter().map(LedgerStepRecord::from).collect(),
        bar_ledgers: d
            .bar_ledgers
            .iter()
            .map(|l| BarLedgerRecord {
                bar: &l.bar,
                steps: l.steps.iter().map(LedgerStepRecord::from).collect(),
                from_fleet: l.from_fleet,
            })
            .collect(),
    }
}

/// What a temperature sensor plausibly measures (`diagnose::sensors::SensorProfile`), with
/// its description and summary in words.
#[derive(Debug, Serialize)]
pub(crate) struct SensorProfileRecord<'a> {
    pub(crate) sensor: &'a str,
    pub(crate) declared_kind: &'static str,
    pub(crate) range_k: f64,
    pub(crate) fast_fluctuation_k: f64,
    pub(crate) air_share: Option<f64>,
    pub(crate) air_tau_s: f64,
    pub(crate) event: Option<&'a str>,
    pub(crate) event_tau_s: f64,
    pub(crate) event_share: f64,
    pub(crate) description: String,
    pub(crate) summary: String,
}

impl<'a> From<&'a SensorProfile> for SensorProfileRecord<'a> {
    fn from(p: &'a SensorProfile) -> Self {
        SensorProfileRecord {
            sensor: &p.sensor,
            declared_kind: sensor_kind_word(p.declared_kind),
            range_k: p.range_k,
            fast_fluctuation_k: p.fast_fluctuation_k,
            air_share: p.air_share,
            air_tau_s: p.air_tau_s,
            event: p.event.as_deref(),
            event_tau_s: p.event_tau_s,
            event_share: p.event_share,
            description: sensors::description(p),
            summary: sensors::summary(p),
        }
    }
}

/// `air`, `plate`, `bar`, `head` or `other`, as `campaign.toml` spells the kinds.
fn sensor_kind_word(kind: SensorKind) -> &'static str {
    match kind {
        SensorKind::Air => "air",
        SensorKind::Plate => "plate",
        SensorKind::Bar => "bar",
        SensorKind::Head => "head",
        SensorKind::Other => "other",
    }
}

/// When a candidate is proposed (`diagnose::Criteria`).
#[derive(Debug, Serialize)]
pub(crate) struct CriteriaRecord {
    pub(crate) noise_floor_um: f64,
    pub(crate) tolerance_um: f64,
    pub(crate) min_gain_um: f64,
    pub(crate) alpha: f64,
}

impl From<&diagnose::Criteria> for CriteriaRecord {
    fn from(c: &diagnose::Criteria) -> Self {
        CriteriaRecord {
            noise_floor_um: c.noise_floor_um,
            tolerance_um: c.tolerance_um,
            min_gain_um: c.min_gain_um,
            alpha: c.alpha,
        }
    }
}

/// One candidate effect fleet-wide, with its verdict's reason and its explanation in words.
#[derive(Debug, Serialize)]
pub(crate) struct CandidateRecord<'a> {
    /// Accepted verbatim by `--add-effect`.
    pub(crate) effect: String,
    pub(crate) verdict: &'static str,
    pub(crate) reason: String,
    pub(crate) rms_before_um: f64,
    pub(crate) screened_rms_after_um: f64,
    pub(crate) screened_shift_um: f64,
    pub(crate) rms_after_um: Option<f64>,
    pub(crate) delta_bic: Option<f64>,
    pub(crate) p_value: Option<f64>,
    pub(crate) bars_improved: usize,
    pub(crate) significant: bool,
    pub(crate) material: bool,
    pub(crate) explanation: String,
    pub(crate) per_bar: Vec<CandidateOnBarRecord<'a>>,
}

impl<'a> CandidateRecord<'a> {
    /// The record of `c`; channel terms' explanations quote the sensors' `profiles`.
    fn new(c: &'a Candidate, profiles: &[SensorProfile]) -> Self {
        CandidateRecord {
            effect: c.effect.name(),
            verdict: verdict_word(c.verdict),
            reason: reason(&c.reason),
            rms_before_um: c.rms_before_um,
            screened_rms_after_um: c.screened_rms_after_um,
            screened_shift_um: c.screened_shift_um,
            rms_after_um: c.rms_after_um,
            delta_bic: c.delta_bic,
            p_value: c.p_value,
            bars_improved: c.bars_improved,
            significant: c.significant,
            material: c.material,
            explanation: effects::explain_with(&c.effect, profiles),
            per_bar: c.per_bar.iter().map(CandidateOnBarRecord::from).collect(),
        }
    }
}

/// `proposed`, `immaterial`, `not_significant` or `screened_out`.
pub(crate) fn verdict_word(v: Verdict) -> &'static str {
    match v {
        Verdict::Proposed => "proposed",
        Verdict::Immaterial => "immaterial",
        Verdict::NotSignificant => "not_significant",
        Verdict::ScreenedOut => "screened_out",
    }
}

/// One candidate's result on one bar.
#[derive(Debug, Serialize)]
pub(crate) struct CandidateOnBarRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) rms_before_um: f64,
    pub(crate) screened_rms_after_um: f64,
    pub(crate) screened_shift_um: f64,
    pub(crate) rms_after_um: Option<f64>,
    pub(crate) delta_bic: Option<f64>,
    pub(crate) p_value: Option<f64>,
    pub(crate) significant: bool,
    pub(crate) error: Option<String>,
}

impl<'a> From<&'a CandidateOnBar> for CandidateOnBarRecord<'a> {
    fn from(c: &'a CandidateOnBar) -> Self {
        CandidateOnBarRecord {
            bar: &c.bar,
            rms_before_um: c.rms_before_um,
            screened_rms_after_um: c.screened_rms_after_um,
            screened_shift_um: c.screened_shift_um,
            rms_after_um: c.rms_after_um,
            delta_bic: c.delta_bic,
            p_value: c.p_value,
            significant: c.significant,
            error: c.error.as_ref().map(ToString::to_string),
        }
    }
}

/// A candidate no bar could fit, with the first bar's reason.
#[derive(Debug, Serialize)]
pub(crate) struct UnavailableRecord {
    pub(crate) effect: String,
    pub(crate) reason: String,
}

/// One step of a forward selection.
#[derive(Debug, Serialize)]
pub(crate) struct LedgerStepRecord<'a> {
    /// `"base"` for the starting model, else the effect's name.
    pub(crate) added: String,
    pub(crate) effects: Vec<String>,
    /// `[bar, µm]` pairs.
    pub(crate) rms_um: &'a [(String, f64)],
    pub(crate) fleet_rms_um: f64,
    pub(crate) delta_bic: Option<f64>,
    pub(crate) p_value: Option<f64>,
}

impl<'a> From<&'a LedgerStep> for LedgerStepRecord<'a> {
    fn from(s: &'a LedgerStep) -> Self {
        LedgerStepRecord {
            added: s.added.name(),
            effects: effect_names(&s.effects),
            rms_um: &s.rms_um,
            fleet_rms_um: s.fleet_rms_um,
            delta_bic: s.delta_bic,
            p_value: s.p_value,
        }
    }
}

/// One bar's own forward selection.
#[derive(Debug, Serialize)]
pub(crate) struct BarLedgerRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) steps: Vec<LedgerStepRecord<'a>>,
    pub(crate) from_fleet: bool,
}
