//! The campaign's air history ([`air_history`]): the mean of the air sensors minus the
//! reference temperature, on which the bars' models are compared (and the device's rings take
//! the air when they have no sensor of their own).
//!
//! Nothing is allocated by time span: the history is a regular grid only where the air sensors
//! log; across a stretch of more than [`HISTORY_MAX_FILLED_GAP_S`] without a reading it holds
//! the two readings around it (the lag follows a straight line exactly), so a reading dated
//! decades away costs two points.

use std::collections::BTreeMap;

use crate::campaign::{Campaign, TimeNs};
use crate::series::SensorLog;
use crate::signal::interpolate;

use super::TemperatureHistory;

/// The longest stretch without an air reading that the history fills with its regular grid, s;
/// a longer one (a logger down for days, a reading dated decades away) gets only its two ends:
/// the air is a straight line between them, which the lag follows exactly, so no grid point there
/// carries anything, and the grid's size follows the readings, not the time span.
pub(crate) const HISTORY_MAX_FILLED_GAP_S: f64 = 6.0 * 3600.0;

/// Mean air temperature minus the reference, on a regular grid of `step_s` from the campaign's
/// origin `t0_ns` (each air sensor interpolated); empty without air readings spanning time.
pub fn air_history(
    campaign: &Campaign,
    sensors: &BTreeMap<String, SensorLog>,
    t0_ns: TimeNs,
    step_s: f64,
) -> TemperatureHistory {
    let logs: Vec<&SensorLog> = campaign
        .air_sensors()
        .filter_map(|s| sensors.get(&s.id))
        .filter(|l| !l.time_ns.is_empty())
        .collect();
    let to_s = |ns: TimeNs| (ns - t0_ns) as f64 * 1e-9;
    let start = logs
        .iter()
        .map(|l| to_s(l.time_ns[0]))
        .fold(f64::INFINITY, f64::min);
    let end = logs
        .iter()
        .map(|l| to_s(*l.time_ns.last().unwrap_or(&0)))
        .fold(f64::NEG_INFINITY, f64::max);
    if logs.is_empty() || end.partial_cmp(&start) != Some(std::cmp::Ordering::Greater) {
        return TemperatureHistory {
            t_s: vec![],
            delta_c: vec![],
        };
    }
    let t_s = history_times(&logs, to_s, start, end, step_s);
    let mut sum = vec![0.0; t_s.len()];
    for l in &logs {
        let ts: Vec<f64> = l.time_ns.iter().map(|&t| to_s(t)).collect();
        let at_history = interpolate::linear_ascending(&ts, &l.celsius, &t_s);
        for (s, v) in sum.iter_mut().zip(at_history) {
            *s += v;
        }
    }
    let k = logs.len() as f64;
    TemperatureHistory {
        t_s,
        delta_c: sum
            .into_iter()
            .map(|s| s / k - campaign.reference_temperature_c)
            .collect(),
    }
}

/// The history's times: `start + i step_s` up to `end`, but inside a stretch of more than
/// [`HISTORY_MAX_FILLED_GAP_S`] without a reading only the readings on either side. At most
/// `HISTORY_MAX_FILLED_GAP_S / step_s + 2` points a reading.
fn history_times(
    logs: &[&SensorLog],
    to_s: impl Fn(TimeNs) -> f64,
    start: f64,
    end: f64,
    step_s: f64,
) -> Vec<f64> {
    let mut knots: Vec<f64> = logs
        .iter()
        .flat_map(|l| l.time_ns.iter().map(|&t| to_s(t)))
        .collect();
    knots.sort_by(f64::total_cmp);
    knots.dedup();
    let n = ((end - start) / step_s).floor() as usize + 1;
    let grid = |i: usize| start + i as f64 * step_s;
    let mut t_s: Vec<f64> = Vec::new();
    let mut i = 0usize;
    let push = |t_s: &mut Vec<f64>, t: f64| {
        if t_s.last().is_none_or(|&last| t > last) {
            t_s.push(t);
        }
    };
    for w in knots.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b - a <= HISTORY_MAX_FILLED_GAP_S {
            continue;
        }
        while i < n && grid(i) <= a {
            push(&mut t_s, grid(i));
            i += 1;
        }
        push(&mut t_s, a);
        push(&mut t_s, b);
        // The grid resumes at its first point after `b`.
        let resume = ((b - start) / step_s).floor() as usize + 1;
        i = i.max(resume);
    }
    while i < n {
        push(&mut t_s, grid(i));
        i += 1;
    }
    t_s
}
