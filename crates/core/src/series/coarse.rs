//! A series' coarse copy: weighted means over consecutive bins, for fit starts and profile
//! shapes on long series.
//!
//! Separate because it is a derived, approximate series, never what a result is fitted to.

use super::BarSeries;
use crate::campaign::TimeNs;

impl BarSeries {
    /// The series averaged over consecutive bins of at most `bin_s` seconds that never cross a
    /// mount or zero-segment boundary (nor a gap longer than `bin_s`): weighted means, each bin
    /// weighing the readings it stands for. A coarse copy to start a fit's time constants on
    /// and to trace the shape of its profiles; unlike [`BarSeries::build_binned`] it is not
    /// exact, and its [`BarSeries::within_bin_rss_um2`] is the source's, so only RSS
    /// *differences* of fits to it mean anything. `bin_s <= 0`: a copy.
    ///
    /// Bin edges are decided on integer nanoseconds (`t_s` rounded to ns), so a 1 Hz log gives
    /// bins of exactly `bin_s` samples.
    pub(crate) fn binned_copy(&self, bin_s: f64) -> BarSeries {
        if bin_s.is_nan() || bin_s <= 0.0 || self.t_s.len() < 2 {
            return self.clone();
        }
        let time_ns: Vec<TimeNs> = self
            .t_s
            .iter()
            .map(|&t| (t * 1e9).round() as TimeNs)
            .collect();
        let bin_ns = (bin_s * 1e9).round() as TimeNs;
        self.averaged(&bin_groups(
            &time_ns,
            &self.mount_of,
            &self.zero_segment,
            bin_ns,
        ))
    }

    /// Weighted means over the sample ranges `groups` (see [`bin_groups`]).
    fn averaged(&self, groups: &[(usize, usize)]) -> BarSeries {
        let w = &self.weight;
        let weight: Vec<f64> = groups.iter().map(|&(a, b)| w[a..b].iter().sum()).collect();
        let mean = |v: &[f64]| -> Vec<f64> {
            groups
                .iter()
                .zip(&weight)
                .map(|(&(a, b), &total)| {
                    if total > 0.0 {
                        v[a..b]
                            .iter()
                            .zip(&w[a..b])
                            .map(|(x, w)| x * w)
                            .sum::<f64>()
                            / total
                    } else {
                        v[a..b].iter().sum::<f64>() / (b - a) as f64
                    }
                })
                .collect()
        };
        let pick =
            |v: &[Option<u32>]| -> Vec<Option<u32>> { groups.iter().map(|&(a, _)| v[a]).collect() };
        let mount_of = pick(&self.mount_of);
        let fit_index = (0..groups.len())
            .filter(|&i| {
                weight[i] > 0.0 && mount_of[i].is_some_and(|m| self.mounts[m as usize].is_fitted())
            })
            .collect();
        BarSeries {
            bar: self.bar.clone(),
            reference_temperature_c: self.reference_temperature_c,
            t0_ns: self.t0_ns,
            t_s: mean(&self.t_s),
            y_um: mean(&self.y_um),
            zero_segment: pick(&self.zero_segment),
            n_zero_segments: self.n_zero_segments,
            segment_offset_um: self.segment_offset_um.clone(),
            mounts: self.mounts.clone(),
            air_c: mean(&self.air_c),
            celsius: self
                .celsius
                .iter()
                .map(|(k, v)| (k.clone(), mean(v)))
                .collect(),
            air_sensor_ids: self.air_sensor_ids.clone(),
            plate_sensor_id: self.plate_sensor_id.clone(),
            mount_of,
            fit_index,
            weight,
            within_bin_rss_um2: self.within_bin_rss_um2,
            within_bin_dof: self.within_bin_dof,
            dropped_outside_mounts: self.dropped_outside_mounts,
            events: self.events.clone(),
        }
    }
}

/// Sample ranges `[a, b)` of the bins of [`BarSeries::binned_copy`]: a bin starts at a sample and
/// takes the following ones while they are in the same mount and zero segment and less than
/// `bin_ns` after its first sample (integer ns: no rounding decides a bin edge).
pub(super) fn bin_groups(
    time_ns: &[TimeNs],
    mount_of: &[Option<u32>],
    segment: &[Option<u32>],
    bin_ns: TimeNs,
) -> Vec<(usize, usize)> {
    let mut groups = Vec::with_capacity(time_ns.len() / 4 + 1);
    let mut start = 0;
    for i in 1..=time_ns.len() {
        let closes = i == time_ns.len()
            || mount_of[i] != mount_of[start]
            || segment[i] != segment[start]
            || time_ns[i] - time_ns[start] >= bin_ns;
        if closes {
            groups.push((start, i));
            start = i;
        }
    }
    groups
}
