//! The sensors' temperatures at the encoder's times: linear interpolation of each sensor's log,
//! the sensors' reading times as extra samples between a bar's readings, and the campaign's
//! time origin.
//!
//! Separate because it joins two logs of different rates, a question of its own (why linear
//! and not as-of is said on [`interpolate_temperatures`]).

use super::Readings;
use super::{BarBins, BarLog, CampaignLogs, SensorLog};
use crate::campaign::TimeNs;
use crate::signal::interpolate;
use std::collections::BTreeMap;

/// Every sensor's temperature at the encoder times of `log`, by linear interpolation of the
/// sensor's own log (replacing any column already there). Linear, not as-of: a backward as-of
/// join holds each reading until the next one, a delay of half the sensor period on average
/// (15 s at 30 s) that would bias every fitted time constant by about that much. Outside a
/// sensor's log the nearest reading is used; a sensor without readings gets no column.
pub fn interpolate_temperatures(log: &mut BarLog, sensors: &BTreeMap<String, SensorLog>) {
    log.celsius = temperatures_at(&log.time_ns, sensors);
}

/// `readings` (sorted) with a weight-0 sample at every sensor reading time (`knots`, sorted)
/// that falls strictly between two consecutive readings.
///
/// Why: lags are computed along the series' own times, the input held linear between them
/// (`signal::lag`). Where a bar logs nothing for a while (a read head switched off for hours: no
/// encoder rows, `docs/spec/campaign-format.md`) the air went on changing and the sensors went on logging;
/// bridged by a straight line, the lags enter every later reading with the wrong state (measured:
/// 2.4-4 nm RMS noise-free and tau_S off by up to 50 % on a 5-day campaign with a head off 1.5-4 h
/// a day). Where the sensors log on the encoder's grid nothing is added (compressed bins already
/// keep the knots between close nodes: only longer gaps gain samples). Counts there are
/// interpolated (for plots only); samples of weight 0 are never fitted.
pub(super) fn with_knots_between(readings: Readings, knots: &[TimeNs]) -> Readings {
    let t = &readings.time_ns;
    // The knots strictly inside (t[k], t[k + 1]), for each k in turn (one walk).
    let mut j = 0;
    let mut inside = |k: usize| {
        while knots.get(j).is_some_and(|&x| x <= t[k]) {
            j += 1;
        }
        let from = j;
        while knots.get(j).is_some_and(|&x| x < t[k + 1]) {
            j += 1;
        }
        from..j
    };
    let added: usize = (0..t.len().saturating_sub(1))
        .map(|k| inside(k).len())
        .sum();
    if added == 0 {
        return readings;
    }
    let n = t.len() + added;
    let mut out = Readings {
        time_ns: Vec::with_capacity(n),
        counts: Vec::with_capacity(n),
        weight: Vec::with_capacity(n),
        line_rss_counts2: Vec::with_capacity(n),
    };
    let mut j = 0;
    for k in 0..t.len() {
        out.time_ns.push(t[k]);
        out.counts.push(readings.counts[k]);
        out.weight.push(readings.weight[k]);
        out.line_rss_counts2.push(readings.line_rss_counts2[k]);
        if k + 1 == t.len() {
            break;
        }
        while knots.get(j).is_some_and(|&x| x <= t[k]) {
            j += 1;
        }
        while let Some(&x) = knots.get(j).filter(|&&x| x < t[k + 1]) {
            let f = (x - t[k]) as f64 / (t[k + 1] - t[k]) as f64;
            let (c0, c1) = (readings.counts[k], readings.counts[k + 1]);
            out.time_ns.push(x);
            out.counts.push(c0 + f * (c1 - c0));
            out.weight.push(0.0);
            out.line_rss_counts2.push(0.0);
            j += 1;
        }
    }
    out
}

/// Every sensor's reading times, sorted and deduplicated: the knots of the temperature
/// interpolation, which a compressed series keeps as samples (`BarSeries::from_bins`(super::BarSeries::from_bins)). The
/// same for every bar, so made once per campaign.
pub fn sensor_knots(sensors: &BTreeMap<String, SensorLog>) -> Vec<TimeNs> {
    let mut knots: Vec<TimeNs> = sensors
        .values()
        .flat_map(|s| s.time_ns.iter().copied())
        .collect();
    knots.sort_unstable();
    knots.dedup();
    knots
}

/// The sensor logs a series compressed into `bin_s` bins is built from (`bin_s` ≤ 0: every
/// reading, the logs as they are): each log that reads at least twice per half bin (the
/// spacing of a bin's two nodes) on average replaced by its means over consecutive half-bin
/// blocks, each at the mean time of its readings (a steady drift is not delayed); slower
/// logs as they are.
///
/// Why: a compressed series keeps every sensor reading between close nodes as a sample
/// ([`sensor_knots`]), so the lags see the interpolated temperature's every kink. A sensor
/// logging at 1 Hz would put 30 samples between a 60-s bin's nodes: on a 30-day 1 Hz campaign a
/// bar's series holds 86 k samples with block means and would hold 2.6 M with every sensor
/// reading, and the campaign's identify takes about 2 s and 0.5 GB where it would take 10 s and
/// 2 GB, for nothing the lags can see: inside a block the mean's error
/// enters a lag of time constant `tau` weighted by `(t − t_mid)/tau` (`docs/spec/physics.md`:
/// `tau` ≥ 15 min against 30-s blocks), so what the block means lose is of order `(block/tau)²`
/// of the fluctuation, far below the readings' noise. Slower logs are unchanged, so their
/// campaigns give the same fits to the bit.
pub(crate) fn knot_logs(
    sensors: &BTreeMap<String, SensorLog>,
    bin_s: f64,
) -> BTreeMap<String, SensorLog> {
    let block_ns = if bin_s > 0.0 {
        (bin_s * 0.5e9).round() as TimeNs
    } else {
        0
    };
    sensors
        .iter()
        .map(|(id, log)| {
            let n = log.time_ns.len();
            let fast = block_ns > 0
                && n > 2
                && (log.time_ns[n - 1] - log.time_ns[0]) / (n as TimeNs - 1) * 2 <= block_ns;
            let log = if fast {
                block_means(log, block_ns)
            } else {
                log.clone()
            };
            (id.clone(), log)
        })
        .collect()
}

/// `log` (sorted) as the means of its readings over consecutive `block_ns` blocks of the time
/// axis, each at the mean time of the block's readings.
fn block_means(log: &SensorLog, block_ns: TimeNs) -> SensorLog {
    let mut out = SensorLog::default();
    let mut start = 0;
    while start < log.time_ns.len() {
        let block = log.time_ns[start].div_euclid(block_ns);
        let end = start
            + log.time_ns[start..]
                .iter()
                .take_while(|t| t.div_euclid(block_ns) == block)
                .count();
        let first = log.time_ns[start];
        let n = (end - start) as f64;
        let offset_ns: f64 = log.time_ns[start..end]
            .iter()
            .map(|&t| (t - first) as f64)
            .sum::<f64>()
            / n;
        out.time_ns.push(first + offset_ns.round() as TimeNs);
        out.celsius
            .push(log.celsius[start..end].iter().sum::<f64>() / n);
        start = end;
    }
    out
}

/// Every sensor's temperature at the sorted times `time_ns` (see [`interpolate_temperatures`]).
pub(crate) fn temperatures_at(
    time_ns: &[TimeNs],
    sensors: &BTreeMap<String, SensorLog>,
) -> BTreeMap<String, Vec<f64>> {
    let mut out = BTreeMap::new();
    for (id, sensor) in sensors {
        if sensor.time_ns.is_empty() {
            continue;
        }
        let column = interpolate::linear_ascending(&sensor.time_ns, &sensor.celsius, time_ns);
        out.insert(id.clone(), column);
    }
    out
}

/// Campaign time origin: the earliest mount start (else the earliest reading, of the bars' logs
/// and of the bins ingest compressed readings into; 0 without any).
pub fn campaign_origin_ns(logs: &CampaignLogs) -> TimeNs {
    let first_mount = logs.campaign.mounts.iter().map(|m| m.from_ns).min();
    let first_reading = || {
        logs.bars
            .values()
            .filter_map(|l| l.time_ns.first().copied())
            .chain(logs.bins.values().filter_map(BarBins::first_reading_ns))
            .min()
    };
    first_mount.or_else(first_reading).unwrap_or(0)
}
