//! The match stage over a fleet ([`match_fleet`]): who is matched (`matched_inputs`), the
//! reference nearest the fleet mean, every other bar's predicted mismatch against it at the
//! comparison distance, and (on request) the measured-mismatch study.

use crate::campaign::{Campaign, Place};
use crate::identify::BarOutcome;

use super::{
    choose_reference, measured_mismatch_matrix, predicted_mismatch, MatchInput, MatchStudy,
    Mismatch, ReferenceChoice, TemperatureHistory, MATCH_PARAMS,
};

/// How the fleet is matched.
#[derive(Debug, Clone)]
pub struct MatchOptions {
    /// Flag bars whose predicted mismatch exceeds this, µm (the patent's ±1 µm).
    pub limit_um: f64,
    /// Plate length id at which bars are compared; the middle plate length when absent.
    pub at_length: Option<String>,
    /// Grid step of the measured-drift matching study, s; `None`: no study.
    pub study_step_s: Option<f64>,
}

/// The reference bar and the mismatches against it.
#[derive(Debug, Clone)]
pub struct ReferenceReport {
    /// The reference bar, nearest the fleet mean, and every bar's distance to that mean.
    pub choice: ReferenceChoice,
    /// The centre distance the bars are compared at, mm.
    pub distance_mm: f64,
    /// The mismatch limit, µm.
    pub limit_um: f64,
    /// Each bar's predicted mismatch against the reference.
    pub mismatches: Vec<Mismatch>,
}

/// The match stage's result.
#[derive(Debug, Clone)]
pub struct FleetMatch {
    /// The reference and the predicted mismatches.
    pub reference: ReferenceReport,
    /// The measured-mismatch study, when asked for and the bars' drifts give one.
    pub study: Option<MatchStudy>,
}

/// Match the fleet: the bars `matched_inputs` keeps, the reference nearest their mean, each
/// other bar's predicted mismatch over `history` at the comparison distance (the plate length
/// `options.at_length`, else the middle one), and the study when `options.study_step_s` asks
/// for it. `None` when no bar can be matched.
pub fn match_fleet(
    bars: &[BarOutcome],
    campaign: &Campaign,
    history: &TemperatureHistory,
    options: &MatchOptions,
) -> Option<FleetMatch> {
    let inputs = matched_inputs(bars);
    let choice = choose_reference(&inputs)?;
    let distance_mm = comparison_distance_mm(campaign, options.at_length.as_deref());
    let mismatches =
        predicted_mismatch(&inputs, &choice.bar, history, distance_mm, options.limit_um);
    let study = options
        .study_step_s
        .and_then(|step_s| measured_mismatch_matrix(&inputs, &choice.bar, step_s));
    Some(FleetMatch {
        reference: ReferenceReport {
            choice,
            distance_mm,
            limit_um: options.limit_um,
            mismatches,
        },
        study,
    })
}

/// What matching needs of an identified bar: `None` when its model lacks `alpha` or `tau_R`
/// or its data leave them, and with them its response, undetermined; `beta` and `tau_S` are NaN
/// when they are absent or so undetermined (one length, `crate::model::identifiable_effects`;
/// a time constant run up to the model's limit, `crate::model::at_model_limit`). See
/// [`matched_inputs`] for who is matched.
pub(crate) fn match_input(o: &BarOutcome) -> Option<MatchInput> {
    let p = |name: &str| {
        o.model
            .value(name)
            .filter(|_| !o.model.response_undetermined(name))
    };
    let q = |name: &str| p(name).unwrap_or(f64::NAN);
    let params = [
        p(MATCH_PARAMS[0])?,
        q(MATCH_PARAMS[1]),
        p(MATCH_PARAMS[2])?,
        q(MATCH_PARAMS[3]),
    ];
    let (t_s, measured_um) = o
        .series
        .fit_index
        .iter()
        .map(|&i| {
            let zero = o.series.zero_segment[i].map_or(0.0, |s| o.model.zeros_um[s as usize]);
            (o.series.t_s[i], o.series.y_um[i] - zero)
        })
        .unzip();
    Some(MatchInput {
        bar: o.model.bar.clone(),
        fixed_length_mm: o.series.bar.fixed_length_mm,
        params,
        t_s,
        measured_um,
    })
}

/// The bars matched: those with all four base parameters; when no bar has them all (a
/// one-length campaign, where `beta` cannot be identified), every bar on `alpha` and `tau_R`
/// (each bar's predicted error is then the one at its own length). A bar lacking `beta` in a
/// fleet where others have it is left out: its `alpha` describes the whole bar at its one length
/// and is not comparable with theirs.
pub(crate) fn matched_inputs(bars: &[BarOutcome]) -> Vec<MatchInput> {
    let inputs: Vec<MatchInput> = bars.iter().filter_map(match_input).collect();
    let complete = |m: &MatchInput| m.params.iter().all(|v| v.is_finite());
    if inputs.iter().any(complete) {
        inputs.into_iter().filter(complete).collect()
    } else {
        inputs
    }
}

/// The centre distance at which bars are compared, mm: the named plate length, else the middle
/// one, else the first plate mount's length (0 without any).
fn comparison_distance_mm(campaign: &Campaign, at_length: Option<&str>) -> f64 {
    let mut lengths: Vec<f64> = campaign.plate.lengths.iter().map(|l| l.mm).collect();
    if let Some(l) = at_length.and_then(|id| campaign.plate.lengths.iter().find(|l| l.id == id)) {
        return l.mm;
    }
    lengths.sort_by(f64::total_cmp);
    lengths.get(lengths.len() / 2).copied().unwrap_or_else(|| {
        campaign
            .mounts
            .iter()
            .find_map(|m| match &m.place {
                Place::Length(l) => Some(l.mm),
                Place::Device(_) => None,
            })
            .unwrap_or(0.0)
    })
}
