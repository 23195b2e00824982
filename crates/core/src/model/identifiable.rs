//! Which effects a bar's data can determine: terms left out of its fit, with the reason
//! ([`NotIdentifiable`]), e.g. the scale's time constant on a bar measured at one length.
//!
//! Separate because it is decided from the series alone, before any term is bound.

use super::{Effect, Transform};
use crate::series::BarSeries;

/// A group of parameters of the effects asked for that one bar's data cannot determine, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct NotIdentifiable {
    /// The parameters' names.
    pub params: Vec<String>,
    /// Why the data cannot determine them.
    pub reason: WhyNotIdentifiable,
}

/// Why a bar's data cannot determine some parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum WhyNotIdentifiable {
    /// Every fitted mount of the bar is at one length: the scale's expansion (beta, tau_S)
    /// cannot be told from the fixed part's; alpha and tau_R describe the whole bar at this
    /// length (alpha + beta I_p / I_min when the time constants are close).
    OneLength {
        /// The one scale travel, mm.
        i_p_mm: f64,
    },
}

/// Travel spread (mm) below which a bar's fitted mounts are taken as one length.
const ONE_LENGTH_SPREAD_MM: f64 = 1e-6;

/// The effects whose terms `series` can determine, and what was left out.
///
/// One length: when every fitted sample of the bar has the same travel `I_p` (all its plate
/// mounts on one length, e.g. a bar on a machine tool's spindle), the scale's term
/// `-beta I_p lag(T; tau_S)` is a second lag of the air with a constant factor: nothing in the
/// data says which of two lags is the scale's, so `beta` and `tau_S` are not identifiable (and
/// with `I_p = 0` the column vanishes). The scale (and `air_gradient`'s scale path) is left out;
/// the fixed part's `alpha` and `tau_R` then describe the whole bar at that length (its
/// expansion referred to `I_min`: `alpha + beta I_p / I_min` when the taus are close). A second
/// time constant, if the data call for one, is the diagnosis' `second_path`.
pub(crate) fn identifiable_effects(
    series: &BarSeries,
    effects: &[Effect],
) -> (Vec<Effect>, Vec<NotIdentifiable>) {
    if !effects.contains(&Effect::Scale) {
        return (effects.to_vec(), Vec::new());
    }
    let travel =
        |i: usize| series.mount_of[i].map_or(f64::NAN, |m| series.mounts[m as usize].i_p_mm);
    let (lo, hi) = series
        .fit_index
        .iter()
        .map(|&i| travel(i))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let spread_mm = hi - lo;
    if spread_mm.is_nan() || spread_mm > ONE_LENGTH_SPREAD_MM {
        return (effects.to_vec(), Vec::new());
    }
    let mut params = vec![
        Effect::Scale.gain_name(),
        Effect::Scale.tau_name().unwrap_or_default(),
    ];
    for e in effects {
        if matches!(
            e,
            Effect::AirGradient
                | Effect::Channel {
                    transform: Transform::Heat,
                    ..
                }
        ) {
            params.push(e.gain_names()[1].clone());
        }
    }
    let reason = WhyNotIdentifiable::OneLength { i_p_mm: lo };
    let kept = effects
        .iter()
        .filter(|e| **e != Effect::Scale)
        .cloned()
        .collect();
    (kept, vec![NotIdentifiable { params, reason }])
}
