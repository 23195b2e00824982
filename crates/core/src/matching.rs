//! Reference-bar matching (`docs/spec/physics.md`, "Matching"; the patent's rule).
//!
//! 1. `choose_reference`: the bar whose parameters (alpha, beta, tau_R, tau_S, each scaled by
//!    the fleet's spread) are nearest the fleet mean becomes the reference.
//! 2. `predicted_mismatch`: for every other bar, the difference of the two identified models'
//!    thermal errors over this campaign's actual temperature history, both evaluated at the same
//!    centre distance; flagged beyond the limit (±1 µm, the patent's figure).
//! 3. `measured_mismatch_matrix`: the matching study — every bar as a candidate reference
//!    against every other bar on the *measured* drifts, to check whether the nearest-the-mean
//!    rule picked the bar that is actually best.
//!
//! [`match_fleet`] runs the three on a fleet's identified bars (`fleet`); the history the models
//! are compared on is the campaign's mean air ([`air_history`], `history`).

use crate::signal::lag::lag;

mod fleet;
mod history;

pub use fleet::{match_fleet, FleetMatch, MatchOptions, ReferenceReport};
pub use history::air_history;

/// The air history's grid step, s ([`air_history`]).
pub const AIR_HISTORY_STEP_S: f64 = 60.0;

/// The four base parameters used for matching, in the order of `docs/spec/physics.md`.
pub const MATCH_PARAMS: [&str; 4] = ["alpha_ppm_per_k", "beta_ppm_per_k", "tau_r_s", "tau_s_s"];

/// What matching needs of one identified bar.
#[derive(Debug, Clone)]
pub(crate) struct MatchInput {
    /// Bar id.
    pub(crate) bar: String,
    /// The bar's fixed length, mm.
    pub(crate) fixed_length_mm: f64,
    /// Values of [`MATCH_PARAMS`], in order; NaN for a parameter the bar's data cannot
    /// determine (`beta` and `tau_S` of a bar mounted on one length: its `alpha` and `tau_R`
    /// then describe the whole bar at that length).
    pub(crate) params: [f64; 4],
    /// Measured thermal error (reading minus the fitted zero), µm, at `t_s` (fitted samples).
    pub(crate) t_s: Vec<f64>,
    /// Measured thermal error at `t_s`, µm.
    pub(crate) measured_um: Vec<f64>,
}

/// The reference bar: the one nearest the fleet mean.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceChoice {
    /// Its id.
    pub bar: String,
    /// Scaled distance of every bar to the fleet mean, same order as the input.
    pub distance: Vec<(String, f64)>,
    /// The fleet's mean of each of `MATCH_PARAMS`.
    pub fleet_mean: [f64; 4],
    pub(crate) fleet_spread: [f64; 4],
}

/// Pick the bar nearest the fleet mean in parameters scaled by the fleet's standard deviation,
/// over the parameters every bar has (a parameter some bar lacks has NaN mean and spread).
/// `None` for an empty fleet.
pub(crate) fn choose_reference(bars: &[MatchInput]) -> Option<ReferenceChoice> {
    if bars.is_empty() {
        return None;
    }
    let n = bars.len() as f64;
    let mut mean = [0.0; 4];
    let mut spread = [0.0; 4];
    for k in 0..4 {
        mean[k] = bars.iter().map(|b| b.params[k]).sum::<f64>() / n;
        let var = bars
            .iter()
            .map(|b| (b.params[k] - mean[k]).powi(2))
            .sum::<f64>()
            / (n - 1.0).max(1.0);
        spread[k] = var.sqrt();
    }
    let distance: Vec<(String, f64)> = bars
        .iter()
        .map(|b| {
            let d2: f64 = (0..4)
                .filter(|&k| spread[k] > 0.0 && mean[k].is_finite())
                .map(|k| ((b.params[k] - mean[k]) / spread[k]).powi(2))
                .sum();
            (b.bar.clone(), d2.sqrt())
        })
        .collect();
    let best = distance
        .iter()
        .min_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)))?;
    Some(ReferenceChoice {
        bar: best.0.clone(),
        distance: distance.clone(),
        fleet_mean: mean,
        fleet_spread: spread,
    })
}

/// A temperature history to evaluate models on.
#[derive(Debug, Clone)]
pub struct TemperatureHistory {
    /// Times, s.
    pub t_s: Vec<f64>,
    /// Air temperature minus the reference temperature, K.
    pub delta_c: Vec<f64>,
}

/// Base-model thermal error (µm) of a bar at centre distance `distance_mm` over `history`
/// (`docs/spec/physics.md`: `-(alpha I_min lag(T; tau_R) + beta I_p lag(T; tau_S))`). A bar without
/// `beta` (identified on one length) has only its fixed part: its error at its own length,
/// whatever `distance_mm` is.
pub(crate) fn predicted_error_um(
    bar: &MatchInput,
    history: &TemperatureHistory,
    distance_mm: f64,
) -> Vec<f64> {
    let [alpha, beta, tau_r, tau_s] = bar.params;
    let (beta, tau_s) = if beta.is_finite() && tau_s.is_finite() {
        (beta, tau_s)
    } else {
        (0.0, tau_r)
    };
    let i_min = bar.fixed_length_mm;
    let i_p = (distance_mm - i_min).max(0.0);
    let (lr, _) = lag(&history.t_s, &history.delta_c, tau_r, false);
    let (ls, _) = lag(&history.t_s, &history.delta_c, tau_s, false);
    lr.iter()
        .zip(&ls)
        .map(|(r, s)| -(alpha * i_min * r + beta * i_p * s) * 1e-3)
        .collect()
}

/// How far one bar's thermal error is from the reference's.
#[derive(Debug, Clone, PartialEq)]
pub struct Mismatch {
    /// Bar id.
    pub bar: String,
    /// max |e_bar(t) - e_reference(t)| over the history, µm.
    pub max_abs_um: f64,
    /// Whether `max_abs_um` exceeds the match limit.
    pub flagged: bool,
}

/// Predicted mismatch of every bar against `reference` (the reference itself is left out).
pub(crate) fn predicted_mismatch(
    bars: &[MatchInput],
    reference: &str,
    history: &TemperatureHistory,
    distance_mm: f64,
    limit_um: f64,
) -> Vec<Mismatch> {
    let Some(r) = bars.iter().find(|b| b.bar == reference) else {
        return Vec::new();
    };
    let er = predicted_error_um(r, history, distance_mm);
    bars.iter()
        .filter(|b| b.bar != reference)
        .map(|b| {
            let eb = predicted_error_um(b, history, distance_mm);
            let max_abs_um = eb
                .iter()
                .zip(&er)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            Mismatch {
                bar: b.bar.clone(),
                max_abs_um,
                flagged: max_abs_um > limit_um,
            }
        })
        .collect()
}

/// The matching study's result: `matrix[r][w]` = max |measured drift of w - of r| over the
/// times both were measured (µm); NaN where they never overlap, and on the diagonal.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchStudy {
    /// The bars, in the matrix's row and column order.
    pub bars: Vec<String>,
    /// The mismatch matrix, µm (see the type's doc).
    pub matrix_um: Vec<Vec<f64>>,
    /// Each candidate's worst mismatch against the others.
    pub worst_um: Vec<f64>,
    /// The bar nearest the fleet mean (the reference chosen).
    pub nearest_mean: String,
    /// The candidate with the smallest worst mismatch.
    pub best: String,
    /// How much worse the nearest-the-mean pick is than the best candidate (µm, ≥ 0).
    pub excess_um: f64,
}

/// Evaluate every bar as a reference against all others on the measured drifts, on a common
/// grid of `step_s` (each bar's nearest sample within `step_s / 2`).
pub(crate) fn measured_mismatch_matrix(
    bars: &[MatchInput],
    nearest_mean: &str,
    step_s: f64,
) -> Option<MatchStudy> {
    let t_start = bars
        .iter()
        .filter_map(|b| b.t_s.first())
        .copied()
        .reduce(f64::min)?;
    let t_end = bars
        .iter()
        .filter_map(|b| b.t_s.last())
        .copied()
        .reduce(f64::max)?;
    let n_grid = ((t_end - t_start) / step_s).floor() as usize + 1;
    let grid: Vec<Vec<f64>> = bars
        .iter()
        .map(|b| on_grid(b, t_start, step_s, n_grid))
        .collect();
    let k = bars.len();
    let mut matrix = vec![vec![f64::NAN; k]; k];
    for r in 0..k {
        for w in 0..k {
            if r != w {
                matrix[r][w] = max_abs_diff(&grid[r], &grid[w]);
            }
        }
    }
    let worst: Vec<f64> = matrix
        .iter()
        .map(|row| {
            row.iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max)
        })
        .collect();
    let best_i = (0..k).min_by(|&a, &b| worst[a].total_cmp(&worst[b]))?;
    let picked_i = bars.iter().position(|b| b.bar == nearest_mean)?;
    Some(MatchStudy {
        bars: bars.iter().map(|b| b.bar.clone()).collect(),
        excess_um: worst[picked_i] - worst[best_i],
        matrix_um: matrix,
        worst_um: worst,
        nearest_mean: nearest_mean.to_string(),
        best: bars[best_i].bar.clone(),
    })
}

fn on_grid(bar: &MatchInput, t_start: f64, step_s: f64, n: usize) -> Vec<f64> {
    let mut out = vec![f64::NAN; n];
    for (t, v) in bar.t_s.iter().zip(&bar.measured_um) {
        let g = ((t - t_start) / step_s).round();
        if g >= 0.0
            && (g as usize) < n
            && (t - t_start - g * step_s).abs() <= step_s / 2.0
            && out[g as usize].is_nan()
        {
            out[g as usize] = *v;
        }
    }
    out
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    let mut best = f64::NAN;
    for (x, y) in a.iter().zip(b) {
        let d = (x - y).abs();
        if d.is_finite() && (best.is_nan() || d > best) {
            best = d;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bar(id: &str, params: [f64; 4]) -> MatchInput {
        MatchInput {
            bar: id.into(),
            fixed_length_mm: 230.0,
            params,
            t_s: vec![],
            measured_um: vec![],
        }
    }

    #[test]
    fn nearest_the_mean_is_the_middle_bar() {
        let bars = [
            bar("A", [1.0, 0.5, 1000.0, 2000.0]),
            bar("B", [2.0, 0.6, 1500.0, 2500.0]),
            bar("C", [3.0, 0.7, 2000.0, 3000.0]),
        ];
        let c = choose_reference(&bars).unwrap();
        assert_eq!(c.bar, "B");
        assert!(c.distance[1].1 < 1e-12);
    }

    #[test]
    fn bars_without_beta_are_matched_on_what_they_have() {
        let nan = f64::NAN;
        let bars = [
            bar("A", [1.0, nan, 1000.0, nan]),
            bar("B", [2.0, nan, 1500.0, nan]),
            bar("C", [3.0, nan, 2100.0, nan]),
        ];
        let c = choose_reference(&bars).unwrap();
        assert_eq!(c.bar, "B");
        assert!(c.distance.iter().all(|(_, d)| d.is_finite()));
        let history = TemperatureHistory {
            t_s: (0..100).map(|i| i as f64 * 60.0).collect(),
            delta_c: vec![1.0; 100],
        };
        let e = predicted_error_um(&bars[0], &history, 400.0);
        assert!(e.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn identical_bars_have_no_mismatch_and_a_step_gives_alpha_i_min_dt() {
        let history = TemperatureHistory {
            t_s: (0..1000).map(|i| i as f64 * 60.0).collect(),
            delta_c: vec![1.0; 1000],
        };
        let a = bar("A", [2.0, 0.0, 600.0, 600.0]);
        let b = bar("B", [3.0, 0.0, 600.0, 600.0]);
        let m = predicted_mismatch(&[a.clone(), b], "A", &history, 300.0, 1.0);
        // Steady state difference: 1 ppm/K * 230 mm * 1 K = 0.23 µm.
        assert!((m[0].max_abs_um - 0.23).abs() < 1e-9, "{m:?}");
        assert!(!m[0].flagged);
        assert!(predicted_mismatch(&[a.clone(), a.clone()], "A", &history, 300.0, 1.0).is_empty());
    }
}
