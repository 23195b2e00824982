//! Building a bar's [`BarSeries`](super::BarSeries) from its log or its bins: readings inside
//! the plate mounts, as thermal error up to each mount's zero, with the air temperatures and the
//! plate's expansion taken out.
//!
//! Separate from the series types because building is where the campaign's mounts, zeros and
//! events are applied; the fits only read the result.

use super::temperatures::{temperatures_at, with_knots_between};
use super::{BarBins, BinGrid, Readings};
use super::{BarLog, BarSeries, Event, EventKind, FleetContext, MountSpan, SeriesError};
use crate::campaign::Bar;
use crate::campaign::Campaign;
use crate::campaign::TimeNs;
use std::collections::BTreeMap;

impl BarSeries {
    /// Build bar `bar_id`'s series from its log, every reading a sample (taken by value: the
    /// series owns the data, so a large campaign is never held twice), with the temperatures
    /// the log carries ([`interpolate_temperatures`]) and the campaign's events.
    #[cfg(test)]
    pub(crate) fn build(
        campaign: &Campaign,
        events: &[Event],
        bar_id: &str,
        log: BarLog,
        t0_ns: TimeNs,
    ) -> Result<BarSeries, SeriesError> {
        let BarLog {
            time_ns,
            counts,
            celsius,
        } = log;
        let n = time_ns.len();
        let readings = Readings {
            time_ns,
            counts: counts.into_iter().map(|c| c as f64).collect(),
            weight: vec![1.0; n],
            line_rss_counts2: vec![0.0; n],
        };
        Self::from_readings(campaign, events, bar_id, readings, celsius, t0_ns)
    }

    /// Bar `bar_id`'s series from its log compressed into bins of `bin_s` seconds (`bins`:
    /// two weighted nodes a bin, exact for a model that is a straight line within each bin);
    /// `bin_s <= 0`: every reading, as `BarSeries::build`. Temperatures are interpolated from
    /// `sensors` at the samples' times here (`knots`: [`sensor_knots`](super::sensor_knots) of `sensors`, used with
    /// bins). The full-rate log lives only inside this call.
    pub(crate) fn build_binned(
        fleet: &FleetContext<'_>,
        bar_id: &str,
        mut log: BarLog,
        bin_s: f64,
    ) -> Result<BarSeries, SeriesError> {
        let FleetContext {
            campaign,
            events,
            sensors,
            knots,
            t0_ns,
        } = *fleet;
        if bin_s.is_nan() || bin_s <= 0.0 {
            let n = log.time_ns.len();
            let readings = with_knots_between(
                Readings {
                    time_ns: std::mem::take(&mut log.time_ns),
                    counts: log.counts.iter().map(|&c| c as f64).collect(),
                    weight: vec![1.0; n],
                    line_rss_counts2: vec![0.0; n],
                },
                knots,
            );
            drop(log);
            let celsius = temperatures_at(&readings.time_ns, sensors);
            return Self::from_readings(campaign, events, bar_id, readings, celsius, t0_ns);
        }
        let grid = BinGrid::new(campaign, events, bar_id, bin_s);
        let bins = BarBins::from_log(grid, &log.time_ns, &log.counts).map_err(|e| {
            SeriesError::Readings {
                bar: bar_id.to_string(),
                reason: e.to_string(),
            }
        })?;
        drop(log);
        Self::from_bins(fleet, bar_id, &bins)
    }

    /// Bar `bar_id`'s series from its compressed bins (ingest can make them while it streams the
    /// encoder files), temperatures interpolated from `sensors` at the nodes' times. `knots`:
    /// [`sensor_knots`](super::sensor_knots) of `sensors`.
    pub(crate) fn from_bins(
        fleet: &FleetContext<'_>,
        bar_id: &str,
        bins: &BarBins,
    ) -> Result<BarSeries, SeriesError> {
        let readings = with_knots_between(bins.readings(fleet.knots), fleet.knots);
        let celsius = temperatures_at(&readings.time_ns, fleet.sensors);
        Self::from_readings(
            fleet.campaign,
            fleet.events,
            bar_id,
            readings,
            celsius,
            fleet.t0_ns,
        )
    }

    /// The series of weighted readings with every sensor's temperature at their times.
    fn from_readings(
        campaign: &Campaign,
        events: &[Event],
        bar_id: &str,
        readings: Readings,
        celsius: BTreeMap<String, Vec<f64>>,
        t0_ns: TimeNs,
    ) -> Result<BarSeries, SeriesError> {
        let bar = campaign
            .bar(bar_id)
            .cloned()
            .ok_or_else(|| SeriesError::NoReadings {
                bar: bar_id.to_string(),
            })?;
        if readings.time_ns.is_empty() {
            return Err(SeriesError::NoReadings {
                bar: bar_id.to_string(),
            });
        }
        let to_s = |ns: TimeNs| (ns - t0_ns) as f64 * 1e-9;
        let t_s: Vec<f64> = readings.time_ns.iter().map(|&t| to_s(t)).collect();
        let mounts = mount_spans(campaign, &bar, &to_s);
        let mount_of = assign_mounts(&t_s, &mounts);
        let dropped_outside_mounts = mount_of
            .iter()
            .zip(&readings.weight)
            .filter(|(m, _)| m.is_none())
            .map(|(_, w)| w)
            .sum::<f64>()
            .round() as usize;
        let events: Vec<(f64, Event)> = events
            .iter()
            .filter(|e| e.bar.as_deref().is_none_or(|b| b == bar_id))
            .map(|e| (to_s(e.time_ns), e.clone()))
            .collect();
        let (zero_segment, n_zero_segments) = zero_segments(&t_s, &mount_of, &events);
        let air_c = air_temperature(campaign, &bar, &celsius, t_s.len())?;
        let um_per_count = bar.resolution_nm * 1e-3;
        let mut y_um: Vec<f64> = readings.counts.iter().map(|&c| c * um_per_count).collect();
        subtract_plate_expansion(campaign, &celsius, &t_s, &mount_of, &mounts, &mut y_um);
        let segment_offset_um = centre_segments(&mut y_um, &zero_segment, n_zero_segments);
        let fit_index: Vec<usize> = (0..t_s.len())
            .filter(|&i| {
                readings.weight[i] > 0.0
                    && mount_of[i].is_some_and(|m| mounts[m as usize].is_fitted())
            })
            .collect();
        if fit_index.is_empty() {
            return Err(SeriesError::NoMountedReadings {
                bar: bar_id.to_string(),
            });
        }
        let within_bin_rss_um2 = fit_index
            .iter()
            .map(|&i| readings.line_rss_counts2[i])
            .sum::<f64>()
            * um_per_count
            * um_per_count;
        // A node stands for `weight` readings and takes one degree of freedom of them.
        let within_bin_dof = fit_index
            .iter()
            .map(|&i| readings.weight[i] - 1.0)
            .sum::<f64>()
            .max(0.0);
        Ok(BarSeries {
            bar,
            reference_temperature_c: campaign.reference_temperature_c,
            t0_ns,
            t_s,
            y_um,
            mount_of,
            zero_segment,
            n_zero_segments,
            segment_offset_um,
            mounts,
            air_c,
            celsius,
            air_sensor_ids: campaign.air_sensors().map(|s| s.id.clone()).collect(),
            plate_sensor_id: campaign
                .sensors
                .iter()
                .find(|s| s.kind == crate::campaign::SensorKind::Plate)
                .map(|s| s.id.clone()),
            fit_index,
            weight: readings.weight,
            within_bin_rss_um2,
            within_bin_dof,
            dropped_outside_mounts,
            events,
        })
    }

    /// A series from plain vectors (no campaign files): for tests and tools that make their own
    /// data. Samples are assigned to `mounts` by time; `y_um` is taken as it is.
    #[cfg(test)]
    pub(crate) fn from_vectors(
        bar: Bar,
        reference_temperature_c: f64,
        t_s: Vec<f64>,
        y_um: Vec<f64>,
        air_c: Vec<f64>,
        mounts: Vec<MountSpan>,
    ) -> BarSeries {
        let n = t_s.len();
        let mount_of = assign_mounts(&t_s, &mounts);
        let dropped_outside_mounts = mount_of.iter().filter(|m| m.is_none()).count();
        let (zero_segment, n_zero_segments) = zero_segments(&t_s, &mount_of, &[]);
        let fit_index = (0..t_s.len())
            .filter(|&i| mount_of[i].is_some_and(|m| mounts[m as usize].is_fitted()))
            .collect();
        let celsius = BTreeMap::from([("T1".to_string(), air_c.clone())]);
        BarSeries {
            bar,
            reference_temperature_c,
            t0_ns: 0,
            t_s,
            y_um,
            mount_of,
            zero_segment,
            segment_offset_um: vec![0.0; n_zero_segments],
            n_zero_segments,
            mounts,
            air_c,
            celsius,
            air_sensor_ids: vec!["T1".into()],
            plate_sensor_id: None,
            fit_index,
            weight: vec![1.0; n],
            within_bin_rss_um2: 0.0,
            within_bin_dof: 0.0,
            dropped_outside_mounts,
            events: Vec::new(),
        }
    }
}

fn mount_spans(campaign: &Campaign, bar: &Bar, to_s: &dyn Fn(TimeNs) -> f64) -> Vec<MountSpan> {
    campaign
        .mounts
        .iter()
        .enumerate()
        .filter(|(_, m)| m.bar == bar.id)
        .map(|(i, m)| {
            let (length_id, length_mm, device) = match &m.place {
                crate::campaign::Place::Length(l) => (Some(l.id.clone()), Some(l.mm), None),
                crate::campaign::Place::Device(d) => (None, None, Some(d.clone())),
            };
            MountSpan {
                campaign_index: i,
                i_p_mm: length_mm.map_or(0.0, |mm| mm - bar.fixed_length_mm),
                length_id,
                length_mm,
                tilt_deg: m.tilt_deg,
                purpose: m.purpose,
                device,
                from_s: to_s(m.from_ns),
                to_s: to_s(m.to_ns),
            }
        })
        .collect()
}

/// Mount index of each sample (mounts of one bar never overlap, `Campaign` checks it;
/// intervals are `[from, to)`): one sweep over the mounts by start for sorted times, else a binary
/// search per sample; never O(samples × mounts).
pub(super) fn assign_mounts(t_s: &[f64], mounts: &[MountSpan]) -> Vec<Option<u32>> {
    let mut by_start: Vec<usize> = (0..mounts.len()).collect();
    by_start.sort_by(|&a, &b| {
        mounts[a]
            .from_s
            .total_cmp(&mounts[b].from_s)
            .then(a.cmp(&b))
    });
    // Sorted times (every series `build` makes) sweep the mounts once.
    let sorted = t_s.windows(2).all(|w| w[0] <= w[1]);
    let mut k = 0; // mounts starting at or before t
    t_s.iter()
        .map(|&t| {
            if sorted {
                while k < by_start.len() && mounts[by_start[k]].from_s <= t {
                    k += 1;
                }
            } else {
                k = by_start.partition_point(|&i| mounts[i].from_s <= t);
            }
            let i = *by_start.get(k.checked_sub(1)?)?;
            (t < mounts[i].to_s).then_some(i as u32)
        })
        .collect()
}

/// Zero segments: each mount, split again at every `rezero` event inside it.
fn zero_segments(
    t_s: &[f64],
    mount_of: &[Option<u32>],
    events: &[(f64, Event)],
) -> (Vec<Option<u32>>, usize) {
    let rezeros: Vec<f64> = events
        .iter()
        .filter(|(_, e)| e.kind == EventKind::Rezero)
        .map(|(t, _)| *t)
        .collect();
    let mut out = Vec::with_capacity(t_s.len());
    let mut next: u32 = 0;
    let mut last: Option<(u32, usize)> = None; // (mount, rezeros passed)
    let mut current: u32 = 0;
    for (i, m) in mount_of.iter().enumerate() {
        let Some(m) = m else {
            out.push(None);
            continue;
        };
        let passed = rezeros.partition_point(|&r| r <= t_s[i]);
        if last != Some((*m, passed)) {
            current = next;
            next += 1;
            last = Some((*m, passed));
        }
        out.push(Some(current));
    }
    (out, next as usize)
}

fn air_temperature(
    campaign: &Campaign,
    bar: &Bar,
    celsius: &BTreeMap<String, Vec<f64>>,
    n: usize,
) -> Result<Vec<f64>, SeriesError> {
    let ids: Vec<String> = match &bar.sensor {
        Some(s) => vec![s.clone()],
        None => campaign.air_sensors().map(|s| s.id.clone()).collect(),
    };
    if ids.is_empty() {
        return Err(SeriesError::NoAirSensor {
            bar: bar.id.clone(),
        });
    }
    let mut sum = vec![0.0; n];
    for id in &ids {
        let col = celsius
            .get(id)
            .filter(|c| c.len() == sum.len() && c.iter().all(|v| v.is_finite()))
            .ok_or_else(|| SeriesError::NoAirTemperature {
                bar: bar.id.clone(),
                sensor: id.clone(),
            })?;
        sum.iter_mut().zip(col).for_each(|(s, v)| *s += v);
    }
    let k = ids.len() as f64;
    Ok(sum.into_iter().map(|s| s / k).collect())
}

/// Remove the known plate expansion from the reading (only when the manifest gives a CTE and
/// a plate sensor exists), with the plate temperature the `plate_expansion` term uses
/// ([`crate::signal::plate_temperature`]: the sensor smoothed without delay).
fn subtract_plate_expansion(
    campaign: &Campaign,
    celsius: &BTreeMap<String, Vec<f64>>,
    t_s: &[f64],
    mount_of: &[Option<u32>],
    mounts: &[MountSpan],
    y_um: &mut [f64],
) {
    let cte = campaign.plate.cte_ppm_per_k;
    if cte == 0.0 {
        return;
    }
    let Some(plate) = campaign
        .sensors
        .iter()
        .find(|s| s.kind == crate::campaign::SensorKind::Plate)
    else {
        return;
    };
    let Some(tp) = celsius.get(&plate.id) else {
        return;
    };
    let tp = crate::signal::plate_temperature(t_s, tp);
    for (i, y) in y_um.iter_mut().enumerate() {
        if let Some(mm) = mount_of[i].and_then(|m| mounts[m as usize].length_mm) {
            *y -= cte * mm * 1e-3 * (tp[i] - campaign.reference_temperature_c);
        }
    }
}

/// Subtract each zero segment's median, so every segment reads near zero; returns the medians.
fn centre_segments(y_um: &mut [f64], segment: &[Option<u32>], n_segments: usize) -> Vec<f64> {
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); n_segments];
    for (y, s) in y_um.iter().zip(segment) {
        if let Some(s) = s {
            values[*s as usize].push(*y);
        }
    }
    let medians: Vec<f64> = values
        .iter_mut()
        .map(|v| {
            if v.is_empty() {
                return 0.0;
            }
            let mid = v.len() / 2;
            *v.select_nth_unstable_by(mid, f64::total_cmp).1
        })
        .collect();
    // Samples outside mounts are centred on the nearest earlier segment for plotting.
    let mut last = 0.0;
    for (y, s) in y_um.iter_mut().zip(segment) {
        if let Some(s) = s {
            last = medians[*s as usize];
        }
        *y -= last;
    }
    medians
}
