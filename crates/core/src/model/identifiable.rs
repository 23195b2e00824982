//! Which parameters a bar's data cannot determine, with the reason ([`NotIdentifiable`]): terms
//! left out of its fit, decided from the series alone before any term is bound (the scale's
//! time constant on a bar measured at one length, [`identifiable_effects`]), and time constants
//! a fit ran to the end of the model's range ([`at_model_limit`]).

use super::{ln_tau_bounds, Effect, ThermalProblem, Transform, MAX_TAU_S};
use crate::fit::Separable;
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
    /// The fit ran a time constant to the end of the range the model allows
    /// (`model::at_model_limit`); the parameters stay in the fit, but their values mean nothing apart.
    AtModelLimit {
        /// The time constant's name.
        tau: String,
        /// The limit it ran to, s: `MAX_TAU_S` (the lag has become its input's running integral
        /// over the campaign, so only the gains' ratio to `tau` is determined) or 1 s (the lag
        /// follows its input within the readings' spacing: the gains are determined, `tau` not).
        limit_s: f64,
    },
}

impl WhyNotIdentifiable {
    /// Whether the parameters named for this reason leave the bar's predicted response
    /// undetermined: not for a time constant run down to 1 s, whose lag follows its input on any
    /// grid the predictions use (`matching::AIR_HISTORY_STEP_S`) whatever its value.
    pub fn leaves_the_response_undetermined(&self) -> bool {
        match self {
            WhyNotIdentifiable::OneLength { .. } => true,
            WhyNotIdentifiable::AtModelLimit { limit_s, .. } => *limit_s > 1.0,
        }
    }
}

/// How close (in `ln tau`) a fitted time constant must be to the model's limit
/// ([`ln_tau_bounds`]) to count as run to it: the minimisers hold a time constant they push
/// beyond the limit there, and one that ends that close was pushed.
const AT_LIMIT_LN_TAU: f64 = 1e-6;

/// The time constants of `problem` that a fit ending at `theta` ran to the model's limit, each
/// with the parameters it leaves undetermined ([`WhyNotIdentifiable::AtModelLimit`]).
///
/// Why: a base model bends its terms to mimic an effect it lacks. On the second simulator's
/// air-gradient campaign at 1-s readings (`bench/foreign_sim.py --effect air_gradient --seed 11
/// --sample-s 1 --temp-s 30 --files day`) bar F05's `tau_s_s` ran to 1e9 s with `beta_ppm_per_k`
/// at -2.1e4 ± 6.3e7: a lag that slow is the running integral of its input, and only
/// `beta / tau_S` is determined (their correlation -1.000). Taken at face value those numbers
/// predicted a 55-µm mismatch against the reference and moved the fleet mean it is chosen by.
pub(crate) fn at_model_limit(problem: &ThermalProblem, theta: &[f64]) -> Vec<NotIdentifiable> {
    let (lo, hi) = ln_tau_bounds();
    let inside = |ln_tau: f64| ln_tau > lo + AT_LIMIT_LN_TAU && ln_tau < hi - AT_LIMIT_LN_TAU;
    // Every refit of the diagnosis asks; the names are built only for a fit that ran off.
    if theta.iter().all(|&t| inside(t)) {
        return Vec::new();
    }
    let tau_names = problem.tau_names();
    let gain_names = problem.gain_names();
    let nuisance = problem.nuisance_gains();
    let mut out = Vec::new();
    for (k, &ln_tau) in theta.iter().enumerate() {
        if inside(ln_tau) {
            continue;
        }
        let upper = ln_tau >= hi - AT_LIMIT_LN_TAU;
        let Some(tau) = tau_names.get(k) else {
            continue;
        };
        let mut params: Vec<String> = if upper {
            problem
                .columns_on(k)
                .unwrap_or_default()
                .into_iter()
                .filter(|&c| !nuisance.get(c).copied().unwrap_or(true))
                .filter_map(|c| gain_names.get(c).cloned())
                .collect()
        } else {
            Vec::new()
        };
        params.push(tau.clone());
        out.push(NotIdentifiable {
            params,
            reason: WhyNotIdentifiable::AtModelLimit {
                tau: tau.clone(),
                limit_s: if upper { MAX_TAU_S } else { lo.exp() },
            },
        });
    }
    out
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
