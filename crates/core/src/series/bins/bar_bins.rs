//! A bar's finished bins ([`BarBins`]) and the samples the fits see from them: the nodes plus
//! weight-0 samples at the sensors' reading times ([`Readings`]).
//!
//! Separate because it is the result of binning, read by series building, while the other files
//! produce it.

use super::accumulator::BinAccumulator;
use super::grid::{BinGrid, BinKey};
use super::moments::BinMoments;
use super::{BinError, NS_PER_US};
use crate::campaign::TimeNs;

/// One bar's readings as bins, in time order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarBins {
    pub(crate) bin_ns: TimeNs,
    pub(crate) bins: Vec<(BinKey, BinMoments)>,
}

/// Weighted pseudo-readings: what a series is built from (`BarBins::readings`; a full-rate
/// log is the case of unit weights and no scatter).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Readings {
    /// Node times, ns (rounded), sorted.
    pub(crate) time_ns: Vec<TimeNs>,
    pub(crate) counts: Vec<f64>,
    pub(crate) weight: Vec<f64>,
    /// Scatter of each bin's counts about its line, counts², carried by the bin's first node
    /// (0 on the others).
    pub(crate) line_rss_counts2: Vec<f64>,
}

impl BarBins {
    /// Bins of a log held in memory (the same sums as streaming it through a
    /// [`BinAccumulator`]).
    pub(crate) fn from_log(
        grid: BinGrid,
        time_ns: &[TimeNs],
        counts: &[i64],
    ) -> Result<BarBins, BinError> {
        let mut acc = BinAccumulator::new(grid);
        acc.add_all(time_ns, counts)?;
        Ok(acc.finish())
    }

    /// Time of the first reading.
    pub fn first_reading_ns(&self) -> Option<TimeNs> {
        self.bins
            .first()
            .map(|(k, m)| k.start_ns + m.first_us * NS_PER_US)
    }

    /// Number of readings.
    pub(crate) fn n_readings(&self) -> u64 {
        self.bins.iter().map(|(_, m)| m.n).sum()
    }

    /// The nodes of every bin, in time order, with weight-0 samples (never fitted) that give a
    /// model's lags the full-rate grid's input:
    ///
    /// * `knots` (sorted times: the temperature sensors' readings) between consecutive nodes at
    ///   most two bins apart;
    /// * the first reading, and the last reading before and the first after every longer gap.
    ///
    /// Why: lags are computed along the series' own times, the input held linear between them
    /// (`signal::lag`). At full rate every sensor reading lies on the encoder's grid, so the
    /// lag sees each kink of the interpolated temperature, starts at the first reading and
    /// bridges a gap from its last reading to its next; along the nodes alone it would see a
    /// coarser line (mostly sensor noise, smoothed) and start and bridge elsewhere, which
    /// moved gains by up to two standard uncertainties on a 1 Hz campaign. With these samples
    /// the lag at the nodes is the full-rate one. Counts of a weight-0 sample are interpolated
    /// between its nodes (for plots only).
    pub(crate) fn readings(&self, knots: &[TimeNs]) -> Readings {
        let mut out = Readings::default();
        // Previous node (time, counts) and the last reading of its bin.
        let mut last: Option<(TimeNs, f64, TimeNs)> = None;
        // Knots before this one lie before the previous node.
        let mut next_knot = 0;
        for (key, moments) in &self.bins {
            let (nodes, line_rss) = moments.nodes();
            let first_reading = key.start_ns + moments.first_us * NS_PER_US;
            let last_reading = key.start_ns + moments.last_us * NS_PER_US;
            for (k, node) in nodes.iter().enumerate() {
                let time = key.start_ns + (node.offset_us * NS_PER_US as f64).round() as TimeNs;
                match last {
                    None => {
                        if first_reading < time {
                            out.push(first_reading, node.counts, 0.0, 0.0);
                        }
                    }
                    Some((t_prev, c_prev, prev_reading)) if time - t_prev > 2 * self.bin_ns => {
                        if prev_reading > t_prev {
                            out.push(prev_reading, c_prev, 0.0, 0.0);
                        }
                        if k == 0 && first_reading < time {
                            out.push(first_reading, node.counts, 0.0, 0.0);
                        }
                    }
                    Some((t_prev, c_prev, _)) => {
                        // Nodes come in time order: one walk over the knots, not a search each.
                        while knots.get(next_knot).is_some_and(|&t| t <= t_prev) {
                            next_knot += 1;
                        }
                        let from = next_knot;
                        while knots.get(next_knot).is_some_and(|&t| t < time) {
                            next_knot += 1;
                        }
                        for &t in &knots[from..next_knot] {
                            let f = (t - t_prev) as f64 / (time - t_prev) as f64;
                            out.push(t, c_prev + f * (node.counts - c_prev), 0.0, 0.0);
                        }
                    }
                }
                out.push(
                    time,
                    node.counts,
                    node.weight,
                    if k == 0 { line_rss } else { 0.0 },
                );
                last = Some((time, node.counts, last_reading));
            }
        }
        out
    }
}

impl Readings {
    fn push(&mut self, time_ns: TimeNs, counts: f64, weight: f64, line_rss_counts2: f64) {
        self.time_ns.push(time_ns);
        self.counts.push(counts);
        self.weight.push(weight);
        self.line_rss_counts2.push(line_rss_counts2);
    }
}
