//! A candidate's summary over the fleet: its verdict (proposed, immaterial, not significant,
//! screened out) and the one-line reason the report prints.
//!
//! Separate because it turns the per-bar numbers into the verdict and words users read.

use super::explain;
use super::{
    may_be_proposed_for_its_shift, Candidate, CandidateOnBar, Criteria, Verdict, CHANNEL_SHIFT,
    SCREEN_SHARE,
};
use crate::model::Effect;
use statrs::distribution::ChiSquared;
use statrs::distribution::ContinuousCDF;

pub(super) fn summarise_candidate(
    effect: &Effect,
    per_bar: Vec<CandidateOnBar>,
    threshold: f64,
    criteria: &Criteria,
) -> Candidate {
    let fitted: Vec<&CandidateOnBar> = per_bar.iter().filter(|c| c.error.is_none()).collect();
    let fleet_rms = |f: &dyn Fn(&CandidateOnBar) -> f64| {
        if fitted.is_empty() {
            return f64::NAN;
        }
        (fitted.iter().map(|c| f(c).powi(2)).sum::<f64>() / fitted.len() as f64).sqrt()
    };
    let rms_before_um = fleet_rms(&|c| c.rms_before_um);
    let screened_rms_after_um = fleet_rms(&|c| c.screened_rms_after_um);
    let screened_shift_um = fleet_rms(&|c| c.screened_shift_um);
    let refitted = !fitted.is_empty() && fitted.iter().all(|c| c.rms_after_um.is_some());
    let mut candidate = Candidate {
        effect: effect.clone(),
        verdict: Verdict::ScreenedOut,
        reason: String::new(),
        rms_before_um,
        screened_rms_after_um,
        screened_shift_um,
        rms_after_um: None,
        delta_bic: None,
        p_value: None,
        bars_improved: 0,
        significant: false,
        material: false,
        explanation: explain::explain(effect),
        per_bar: Vec::new(),
    };
    if !refitted {
        let gain = rms_before_um - screened_rms_after_um;
        candidate.reason = if screened_shift_um >= SCREEN_SHARE * criteria.min_gain_um {
            let why_not = if may_be_proposed_for_its_shift(effect) {
                "its score test does not find the term or it leaves no trace in the fit (a reparametrisation the data do not determine)"
            } else {
                CHANNEL_SHIFT
            };
            format!(
                "screened out: the linearised refit removes {} µm of the fleet RMS, below {} of the materiality threshold {} µm; it would move the model's own terms by {} µm, but {why_not}",
                fmt_um(gain),
                SCREEN_SHARE,
                fmt_um(criteria.min_gain_um),
                fmt_um(screened_shift_um)
            )
        } else {
            format!(
                "screened out: the linearised refit removes {} µm of the fleet RMS and moves the model's own terms by {} µm, both below {} of the materiality threshold {} µm",
                fmt_um(gain),
                fmt_um(screened_shift_um),
                SCREEN_SHARE,
                fmt_um(criteria.min_gain_um)
            )
        };
        candidate.per_bar = per_bar;
        return candidate;
    }
    let rms_after_um = fleet_rms(&|c| c.rms_after_um.unwrap_or(c.rms_before_um));
    let delta_bic: f64 = fitted.iter().filter_map(|c| c.delta_bic).sum();
    // Fisher's method combines the bars' p-values into one fleet-wide test.
    let x2: f64 = fitted
        .iter()
        .map(|c| -2.0 * c.p_value.unwrap_or(1.0).max(1e-300).ln())
        .sum();
    let p_value = ChiSquared::new(2.0 * fitted.len() as f64)
        .map(|d| 1.0 - d.cdf(x2))
        .unwrap_or(f64::NAN);
    let bars_improved = fitted.iter().filter(|c| c.significant).count();
    let significant = p_value < threshold && delta_bic < 0.0 && bars_improved > 0;
    let gain = rms_before_um - rms_after_um;
    let material = criteria.is_material(effect, gain, screened_shift_um);
    let (verdict, reason) = match (significant, material) {
        (true, true) => (
            Verdict::Proposed,
            format!(
                "significant (p = {p_value:.1e} < {threshold:.1e}) and material: removes {} µm of the fleet RMS and moves the model's own terms by {} µm (threshold {} µm)",
                fmt_um(gain),
                fmt_um(screened_shift_um),
                fmt_um(criteria.min_gain_um)
            ),
        ),
        (true, false)
            if screened_shift_um >= criteria.min_gain_um
                && !may_be_proposed_for_its_shift(effect) =>
        {
            (
                Verdict::Immaterial,
                format!(
                    "detectable but immaterial: significant (p = {p_value:.1e}), but it removes only {} µm of the fleet RMS, below the materiality threshold {} µm; it would move the model's own terms by {} µm, but {CHANNEL_SHIFT}",
                    fmt_um(gain),
                    fmt_um(criteria.min_gain_um),
                    fmt_um(screened_shift_um)
                ),
            )
        }
        (true, false) => (
            Verdict::Immaterial,
            format!(
                "detectable but immaterial: significant (p = {p_value:.1e}), but it removes only {} µm of the fleet RMS and moves the model's own terms by {} µm, below the materiality threshold {} µm",
                fmt_um(gain),
                fmt_um(screened_shift_um),
                fmt_um(criteria.min_gain_um)
            ),
        ),
        (false, _) => (
            Verdict::NotSignificant,
            format!(
                "not significant: p = {p_value:.1e} against {threshold:.1e} (5 % family-wise), ΔBIC {delta_bic:.1}"
            ),
        ),
    };
    Candidate {
        verdict,
        reason,
        rms_after_um: Some(rms_after_um),
        delta_bic: Some(delta_bic),
        p_value: Some(p_value),
        bars_improved,
        significant,
        material,
        per_bar,
        ..candidate
    }
}

/// A length in µm with four significant digits (a reason's numbers).
pub(super) fn fmt_um(v: f64) -> String {
    format!("{v:.3e}")
        .parse::<f64>()
        .map_or_else(|_| format!("{v}"), |x| format!("{x}"))
}
