//! A candidate's summary over the fleet: its verdict (proposed, immaterial, not significant,
//! screened out) and the reason, as the numbers it rests on.
//!
//! Separate because it turns the per-bar numbers into the verdict users read.

use super::{
    may_be_proposed_for_its_shift, Candidate, CandidateOnBar, Criteria, Reason, Verdict,
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
    let gain = rms_before_um - screened_rms_after_um;
    let screened_reason = if screened_shift_um >= SCREEN_SHARE * criteria.min_gain_um {
        Reason::ScreenedOutShiftIgnored {
            gain_um: gain,
            share: SCREEN_SHARE,
            min_gain_um: criteria.min_gain_um,
            shift_um: screened_shift_um,
            channel_term: !may_be_proposed_for_its_shift(effect),
        }
    } else {
        Reason::ScreenedOut {
            gain_um: gain,
            shift_um: screened_shift_um,
            share: SCREEN_SHARE,
            min_gain_um: criteria.min_gain_um,
        }
    };
    let candidate = Candidate {
        effect: effect.clone(),
        verdict: Verdict::ScreenedOut,
        reason: screened_reason,
        rms_before_um,
        screened_rms_after_um,
        screened_shift_um,
        rms_after_um: None,
        delta_bic: None,
        p_value: None,
        bars_improved: 0,
        significant: false,
        material: false,
        per_bar: Vec::new(),
    };
    if !refitted {
        let first_failure = per_bar
            .iter()
            .find_map(|c| Some((c.bar.clone(), c.error.clone()?)));
        let reason = match first_failure {
            Some((first_bar, error)) if fitted.is_empty() => Reason::NotFittedOnAnyBar {
                bars: per_bar.len(),
                first_bar,
                error,
            },
            _ => candidate.reason.clone(),
        };
        return Candidate {
            reason,
            per_bar,
            ..candidate
        };
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
            Reason::Proposed {
                p_value,
                threshold,
                gain_um: gain,
                shift_um: screened_shift_um,
                min_gain_um: criteria.min_gain_um,
            },
        ),
        (true, false)
            if screened_shift_um >= criteria.min_gain_um
                && !may_be_proposed_for_its_shift(effect) =>
        {
            (
                Verdict::Immaterial,
                Reason::ImmaterialShiftIgnored {
                    p_value,
                    gain_um: gain,
                    min_gain_um: criteria.min_gain_um,
                    shift_um: screened_shift_um,
                },
            )
        }
        (true, false) => (
            Verdict::Immaterial,
            Reason::Immaterial {
                p_value,
                gain_um: gain,
                shift_um: screened_shift_um,
                min_gain_um: criteria.min_gain_um,
            },
        ),
        (false, _) => (
            Verdict::NotSignificant,
            Reason::NotSignificant {
                p_value,
                threshold,
                delta_bic,
            },
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
