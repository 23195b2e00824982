//! `summary.json`: the stable contract for cron jobs and dashboards (README, "What the output folder holds").

use std::collections::BTreeMap;

use serde::Serialize;

use crate::identify::Estimate;
use crate::model::{Effect, NotIdentifiable};
use crate::narrative::model::not_identifiable_reason;
use crate::pipeline::{RunPlan, RunResults, Stage};

use super::inputs::{input_records, InputRecord};
use super::quality::QualityRecord;
use super::stage_records::{failure_records, FailureRecord};

/// `summary.json`: the stable contract for cron jobs and dashboards.
#[derive(Debug, Serialize)]
pub(crate) struct Summary<'a> {
    pub(crate) dbbcal_version: String,
    pub(crate) campaign: String,
    pub(crate) pipeline: PipelineRecord,
    pub(crate) inputs: Vec<InputRecord>,
    pub(crate) model: ModelRecord,
    pub(crate) bars: Vec<BarSummary>,
    pub(crate) failed_bars: Vec<FailureRecord<'a>>,
    pub(crate) reference: Option<ReferenceSummary>,
    /// What ingest dropped, counted and flagged, per bar, sensor, events and files.
    pub(crate) quality: QualityRecord<'a>,
}

#[derive(Debug, Serialize)]
pub(crate) struct PipelineRecord {
    pub(crate) name: String,
    pub(crate) path: Option<String>,
    pub(crate) sha256: Option<String>,
    pub(crate) stages: Vec<Stage>,
}

#[derive(Debug, Serialize)]
pub(crate) struct ModelRecord {
    pub(crate) effects: Vec<String>,
    /// Bin length of the compressed readings, s (0: every reading). The fits, RMS and sample
    /// counts are those of every reading either way (`series::bins`); residual statistics and
    /// figures then show the bins' nodes.
    pub(crate) bin_s: f64,
}

#[derive(Debug, Serialize)]
pub(crate) struct ParamValue {
    pub(crate) value: f64,
    pub(crate) u: f64,
    pub(crate) u_naive: f64,
    pub(crate) ci95: [f64; 2],
    /// Per end of `ci95`: the end is the time constants' search bound, not a limit set by the
    /// data ([`Estimate::ci95_at_search_bound`]).
    pub(crate) ci95_at_search_bound: [bool; 2],
}

#[derive(Debug, Serialize)]
pub(crate) struct BarSummary {
    pub(crate) bar: String,
    pub(crate) effects: Vec<String>,
    pub(crate) params: BTreeMap<String, ParamValue>,
    pub(crate) correlation: CorrelationRecord,
    pub(crate) rms_um: f64,
    pub(crate) n_samples: usize,
    pub(crate) dropped_outside_mounts: usize,
    pub(crate) hac_batch_samples: usize,
    /// The base paths' initial-state gains (nuisance parameters like the zeros: each lag's
    /// departure from steady state at the bar's first fitted sample times its expansion, ppm).
    pub(crate) initial_state: BTreeMap<String, ParamValue>,
    /// Parameters of the model's effects that this bar's data cannot determine (left out of its
    /// fit), with the reason: e.g. `beta_ppm_per_k` and `tau_s_s` of a bar mounted on one length.
    pub(crate) not_identifiable: Vec<NotIdentifiableRecord>,
}

/// Parameters a bar's data cannot determine, and why in words.
#[derive(Debug, Serialize)]
pub(crate) struct NotIdentifiableRecord {
    pub(crate) params: Vec<String>,
    pub(crate) reason: String,
}

impl From<&NotIdentifiable> for NotIdentifiableRecord {
    fn from(n: &NotIdentifiable) -> Self {
        NotIdentifiableRecord {
            params: n.params.clone(),
            reason: not_identifiable_reason(&n.reason),
        }
    }
}

/// The effects' names, as `--add-effect` accepts them.
pub(crate) fn effect_names(effects: &[Effect]) -> Vec<String> {
    effects.iter().map(Effect::name).collect()
}

#[derive(Debug, Serialize)]
pub(crate) struct CorrelationRecord {
    pub(crate) names: Vec<String>,
    pub(crate) matrix: Vec<Vec<f64>>,
}

#[derive(Debug, Serialize)]
pub(crate) struct ReferenceSummary {
    pub(crate) bar: String,
    pub(crate) rule: &'static str,
    pub(crate) compared_at_mm: f64,
    pub(crate) limit_um: f64,
    pub(crate) mismatch_um: BTreeMap<String, f64>,
    pub(crate) flagged: Vec<String>,
    pub(crate) scaled_distance_to_mean: BTreeMap<String, f64>,
}

fn param_value(e: &Estimate) -> ParamValue {
    ParamValue {
        value: e.value,
        u: e.u,
        u_naive: e.u_naive,
        ci95: e.ci95,
        ci95_at_search_bound: e.ci95_at_search_bound,
    }
}

pub(crate) fn summary<'a>(plan: &RunPlan, r: &'a RunResults) -> Summary<'a> {
    let bars = r
        .bars
        .iter()
        .map(|o| BarSummary {
            bar: o.model.bar.clone(),
            effects: o.model.effect_names(),
            params: o
                .model
                .params
                .iter()
                .map(|p| (p.name.clone(), param_value(p)))
                .collect(),
            correlation: CorrelationRecord {
                names: o.model.params.iter().map(|p| p.name.clone()).collect(),
                matrix: o.model.correlation.clone(),
            },
            rms_um: o.model.rms_um,
            n_samples: o.model.n_samples,
            dropped_outside_mounts: o.series.dropped_outside_mounts,
            hac_batch_samples: o.model.hac_batch_len,
            initial_state: o
                .model
                .initial_state
                .iter()
                .map(|p| (p.name.clone(), param_value(p)))
                .collect(),
            not_identifiable: o
                .model
                .not_identifiable
                .iter()
                .map(NotIdentifiableRecord::from)
                .collect(),
        })
        .collect();
    let reference = r.reference.as_ref().map(|rr| ReferenceSummary {
        bar: rr.choice.bar.clone(),
        rule: if rr.choice.fleet_mean.iter().all(|v| v.is_finite()) {
            "nearest the fleet mean in (alpha, beta, tau_R, tau_S) scaled by the fleet standard deviation"
        } else {
            "nearest the fleet mean in (alpha, tau_R) scaled by the fleet standard deviation (beta and tau_S are not identifiable: every bar on one length)"
        },
        compared_at_mm: rr.distance_mm,
        limit_um: rr.limit_um,
        mismatch_um: rr.mismatches.iter().map(|m| (m.bar.clone(), m.max_abs_um)).collect(),
        flagged: rr.mismatches.iter().filter(|m| m.flagged).map(|m| m.bar.clone()).collect(),
        scaled_distance_to_mean: rr.choice.distance.iter().cloned().collect(),
    });
    Summary {
        dbbcal_version: env!("CARGO_PKG_VERSION").to_string(),
        campaign: r.campaign.id.clone(),
        pipeline: PipelineRecord {
            name: plan.pipeline_name.clone(),
            path: plan
                .pipeline_source
                .as_ref()
                .map(|(p, _)| p.display().to_string()),
            sha256: plan.pipeline_source.as_ref().map(|(_, h)| h.clone()),
            stages: plan.stages.clone(),
        },
        inputs: input_records(&r.inputs),
        model: ModelRecord {
            effects: effect_names(&plan.effects),
            bin_s: plan.bin_s,
        },
        bars,
        failed_bars: failure_records(&r.failed),
        reference,
        quality: QualityRecord::from(&r.quality),
    }
}
