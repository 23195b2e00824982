//! How candidates are compared: named effects preferred to equally good channel terms, the
//! ΔBIC of competing candidates, pairs of parameters the data cannot tell apart, and the
//! likelihood-ratio p-value.
//!
//! Separate because these are the decision rules, kept apart from the machinery that produces
//! the numbers they compare.

use super::{Candidate, Criteria};
use crate::identify::BarModel;
use crate::model::Effect;
use statrs::distribution::ChiSquared;
use statrs::distribution::ContinuousCDF;

/// When a generic channel term and a catalogue effect fit equally well and share a verdict, the
/// named physical effect goes first: `lag:event:head_power` and `head_heating` are the same
/// model, and the user should be told the physics. Equally well: ΔBIC within 2 ("not worth more
/// than a bare mention" on Kass & Raftery's scale), or fleet RMS after within the materiality
/// threshold ([`equally_good`]: on a long campaign a generic term with more freedom wins the
/// ΔBIC by hundreds for an immaterial fraction of a nanometre; `heat:P1` against
/// `plate_expansion` on a 10-bar, 15-day campaign).
pub(super) fn prefer_named_effects(ranked: &mut [Candidate], criteria: &Criteria) {
    let generic = |c: &Candidate| matches!(c.effect, Effect::Channel { .. });
    let close = |a: &Candidate, b: &Candidate| match (a.delta_bic, b.delta_bic) {
        (Some(x), Some(y)) => {
            a.verdict == b.verdict && ((x - y).abs() < 2.0 || equally_good(a, b, criteria))
        }
        _ => false,
    };
    for i in 1..ranked.len() {
        let mut j = i;
        while j > 0
            && generic(&ranked[j - 1])
            && !generic(&ranked[j])
            && close(&ranked[j], &ranked[j - 1])
        {
            ranked.swap(j - 1, j);
            j -= 1;
        }
    }
}

/// Whether two refitted candidates leave fleet RMS values within the materiality threshold of
/// each other: what one removes beyond the other does not matter.
fn equally_good(a: &Candidate, b: &Candidate, criteria: &Criteria) -> bool {
    match (a.rms_after_um, b.rms_after_um) {
        (Some(x), Some(y)) => (x - y).abs() < criteria.min_gain_um,
        _ => false,
    }
}

/// Per candidate of one path's `proposed` list (in ranking order, a named effect before the
/// generic terms it fits equally well, [`prefer_named_effects`]): the ΔBIC it competes with in
/// the beam, the best of its own and that of any later candidate it fits equally well. So a
/// named effect is not pushed out of the beam by a generic alias that wins the ΔBIC by an
/// immaterial difference.
pub(super) fn competing_delta_bic(proposed: &[Candidate], criteria: &Criteria) -> Vec<f64> {
    proposed
        .iter()
        .enumerate()
        .map(|(i, c)| {
            proposed[i..]
                .iter()
                .filter(|later| later.effect == c.effect || equally_good(c, later, criteria))
                .filter_map(|later| later.delta_bic)
                .fold(c.delta_bic.unwrap_or(0.0), f64::min)
        })
        .collect()
}

/// Correlation beyond which two estimates are taken as one combination the data cannot split
/// (e.g. two equal time constants with huge, cancelling gains: a derivative in disguise).
pub(crate) const MAX_PARAM_CORRELATION: f64 = 0.9999;

/// The first pair of parameters of `model`, one of them new relative to `base`, whose
/// estimates correlate beyond [`MAX_PARAM_CORRELATION`].
pub(super) fn unidentifiable_pair(
    base: &BarModel,
    model: &BarModel,
) -> Option<(String, String, f64)> {
    let is_new = |k: usize| base.param(&model.params[k].name).is_none();
    for (i, row) in model.correlation.iter().enumerate() {
        for (j, r) in row.iter().enumerate().skip(i + 1) {
            if (is_new(i) || is_new(j)) && r.abs() > MAX_PARAM_CORRELATION {
                return Some((
                    model.params[i].name.clone(),
                    model.params[j].name.clone(),
                    *r,
                ));
            }
        }
    }
    None
}

/// Likelihood-ratio test of nested fits, each residual under its own maximum-likelihood
/// AR(1)-plus-white-noise model ([`noise`]; `base_log_likelihood` is the base model's),
/// `χ²` with the added parameters' degrees of freedom. The fits are least squares, not the
/// noise model's generalised least squares, which makes the statistic smaller: the test errs on
/// the side of "not significant". A term that lowers the RMS but makes the residual less
/// predictable (it adds its channel's sensor noise, or fits a slow wander with a smooth curve
/// that jumps elsewhere) gets `p = 1`. Residuals are weighed by the square root of their
/// samples' weights ([`BarSeries::weighted_residuals`]).
pub(crate) fn lr_p_value(
    base_log_likelihood: f64,
    extended_log_likelihood: f64,
    added_params: usize,
) -> f64 {
    let lr = 2.0 * (extended_log_likelihood - base_log_likelihood);
    if lr.is_nan() || lr <= 0.0 {
        return 1.0;
    }
    ChiSquared::new(added_params as f64)
        .map(|d| 1.0 - d.cdf(lr))
        .unwrap_or(f64::NAN)
}
