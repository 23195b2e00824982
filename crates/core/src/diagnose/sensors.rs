//! What each temperature sensor plausibly measures, judged from its own signal.
//!
//! A campaign declares sensors as `air`, `plate` or `other` (`docs/spec/campaign-format.md`); an `other`
//! sensor may sit on a motor, in a structure or in a draught, and the diagnosis must say what a
//! channel it ranks plausibly is. Each sensor is explained by a first-order response to the
//! bar's air (the share of its variance the best time constant explains, on a grid of time
//! constants), then what the air leaves by a first-order response to each event kind (beside
//! the air), and by its fast fluctuations (what a 10-min zero-phase smoothing removes). The
//! drivers name it; the application words them (`src/narrative/sensors.rs`: "follows the air …;
//! heated by 'spindle' events (92 % of what the air leaves, tau 16 min)").

use crate::campaign::SensorKind;
use crate::model::channels;
use crate::series::BarSeries;
use crate::signal::lag;

/// At most this many samples are used (the series is thinned evenly); the drivers are slow.
const MAX_SAMPLES: usize = 20_000;
/// Time constants tried for each driver, s (2 min to 4.3 h, factors of 2).
const TAU_GRID_S: [f64; 8] = [120.0, 240.0, 480.0, 960.0, 1920.0, 3840.0, 7680.0, 15360.0];
/// A driver "explains" a sensor when its best response removes at least this share of the
/// sensor's variance.
pub const DRIVEN_SHARE: f64 = 0.5;
/// Zero-phase smoothing that separates fast fluctuations (air-conditioning, draughts) from the
/// slow signal, s.
const FAST_SMOOTHING_S: f64 = 600.0;

/// One sensor's profile.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorProfile {
    /// Sensor id.
    pub sensor: String,
    /// `air`, `plate` or `other`: the bar's air sensor(s) and the plate sensor as
    /// `campaign.toml` declares them, every other sensor `other`.
    pub declared_kind: SensorKind,
    /// Max − min over the bar's log, K.
    pub range_k: f64,
    /// RMS of what a 10-min zero-phase smoothing removes (fluctuations faster than about an
    /// hour), K.
    pub fast_fluctuation_k: f64,
    /// Share of the sensor's variance its best first-order response to the air explains
    /// (`None` for the air sensors themselves).
    pub air_share: Option<f64>,
    /// The time constant of that response, s.
    pub air_tau_s: f64,
    /// The event kind whose first-order response explains most of what the air leaves; `KIND
    /// (on/off)` when the on/off state of valued events explains more than their value.
    pub event: Option<String>,
    /// The time constant of that response, s.
    pub event_tau_s: f64,
    /// Share of what the air leaves (of the whole variance for air sensors) that it explains.
    pub event_share: f64,
}

impl SensorProfile {
    /// The air explains it: its response removes at least [`DRIVEN_SHARE`] of its variance.
    pub fn follows_air(&self) -> bool {
        self.air_share.is_some_and(|s| s >= DRIVEN_SHARE)
    }

    /// The event kind that explains it (at least [`DRIVEN_SHARE`] of what the air leaves).
    pub fn heated_by(&self) -> Option<&str> {
        self.event
            .as_deref()
            .filter(|_| self.event_share >= DRIVEN_SHARE)
    }

    /// A fast response that explains most of what the air leaves: the sensor sits near the
    /// source.
    pub fn near_source(&self) -> bool {
        self.event_share >= 0.7 && self.event_tau_s <= 3600.0
    }

    /// Its fast fluctuations matter: above 0.1 K RMS and 3 % of its range.
    pub fn fluctuates_fast(&self) -> bool {
        self.fast_fluctuation_k > 0.1 && self.fast_fluctuation_k > 0.03 * self.range_k
    }
}

/// Profiles of every sensor of `series`' campaign, by sensor name.
pub(crate) fn sensor_profiles(series: &BarSeries) -> Vec<SensorProfile> {
    let step = series.t_s.len().div_ceil(MAX_SAMPLES).max(1);
    let t: Vec<f64> = series.t_s.iter().step_by(step).copied().collect();
    let thin = |v: &[f64]| -> Vec<f64> { v.iter().step_by(step).copied().collect() };
    let mut kinds: Vec<String> = series
        .events
        .iter()
        .map(|(_, e)| e.kind.to_string())
        .collect();
    kinds.sort();
    kinds.dedup();
    let mut events: Vec<(String, channels::Channel)> = Vec::new();
    for kind in kinds {
        match channels::event_channel(series, &kind) {
            Ok(channels::Channel::Held {
                switch_s, values, ..
            }) => {
                // Heat need not grow in proportion to the logged value (a spindle's speed):
                // try the value and the on/off state.
                let on_off = values
                    .iter()
                    .map(|v| f64::from(u8::from(*v != 0.0)))
                    .collect();
                events.push((
                    format!("{kind} (on/off)"),
                    channels::Channel::Held {
                        switch_s: switch_s.clone(),
                        values: on_off,
                        at_samples: Vec::new(),
                    },
                ));
                events.push((
                    kind,
                    channels::Channel::Held {
                        switch_s,
                        values,
                        at_samples: Vec::new(),
                    },
                ));
            }
            Ok(channels::Channel::Sampled(v)) => {
                events.push((kind, channels::Channel::Sampled(thin(&v))))
            }
            Ok(impulses) => events.push((kind, impulses)),
            Err(_) => {}
        }
    }
    let air = channels::Channel::Sampled(thin(&series.air_c));
    series
        .celsius
        .iter()
        .map(|(name, celsius)| {
            let kind = declared_kind(series, name);
            let own_air = kind == SensorKind::Air || series.air_c == *celsius;
            profile(
                name,
                kind,
                &t,
                &thin(celsius),
                (!own_air).then_some(&air),
                &events,
            )
        })
        .collect()
}

fn declared_kind(series: &BarSeries, name: &str) -> SensorKind {
    if series.air_sensor_ids.iter().any(|s| s == name) {
        SensorKind::Air
    } else if series.plate_sensor_id.as_deref() == Some(name) {
        SensorKind::Plate
    } else {
        SensorKind::Other
    }
}

/// Profile sensor `x`: its best response to the air (if given), then the event kind whose best
/// response explains most of what the air leaves.
fn profile(
    name: &str,
    declared_kind: SensorKind,
    t: &[f64],
    x: &[f64],
    air: Option<&channels::Channel>,
    events: &[(String, channels::Channel)],
) -> SensorProfile {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    let smooth = lag::zero_phase_lag(t, x, FAST_SMOOTHING_S);
    let fast_fluctuation_k = rms(x.iter().zip(&smooth).map(|(a, b)| a - b));
    let air_responses: Vec<(f64, Vec<f64>)> = match air {
        Some(air) => TAU_GRID_S
            .iter()
            .map(|&tau| (tau, air.lag(t, tau, false).0))
            .collect(),
        None => Vec::new(),
    };
    let total = centred_ss(x);
    // The air alone: its best time constant.
    let (air_tau_s, air_rss) = air_responses
        .iter()
        .map(|(tau, u)| (*tau, least_squares_rss(x, &[u])))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((f64::NAN, total));
    let air_share = air.map(|_| 1.0 - air_rss / total);
    // Each event kind beside the air (both time constants on the grid): the share of what the
    // air leaves that it explains.
    let best_event = events
        .iter()
        .map(|(kind, ch)| {
            let (tau, rss) = TAU_GRID_S
                .iter()
                .map(|&tau| {
                    let e = ch.lag(t, tau, false).0;
                    let rss = if air_responses.is_empty() {
                        least_squares_rss(x, &[&e])
                    } else {
                        air_responses
                            .iter()
                            .map(|(_, u)| least_squares_rss(x, &[u, &e]))
                            .fold(f64::INFINITY, f64::min)
                    };
                    (tau, rss)
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((f64::NAN, air_rss));
            (kind.clone(), tau, 1.0 - rss / air_rss)
        })
        .filter(|(_, _, share)| share.is_finite())
        .max_by(|a, b| a.2.total_cmp(&b.2));
    let (event, event_tau_s, event_share) = match best_event {
        Some((k, tau, share)) => (Some(k), tau, share),
        None => (None, f64::NAN, 0.0),
    };
    SensorProfile {
        sensor: name.to_string(),
        declared_kind,
        range_k: hi - lo,
        fast_fluctuation_k,
        air_share,
        air_tau_s,
        event,
        event_tau_s,
        event_share,
    }
}

fn centred_ss(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len().max(1) as f64;
    x.iter().map(|v| (v - m).powi(2)).sum()
}

/// Residual sum of squares of `x` regressed on an offset and `columns` (normal equations; a
/// singular fit leaves `x`'s own centred sum of squares).
fn least_squares_rss(x: &[f64], columns: &[&Vec<f64>]) -> f64 {
    let n = x.len();
    let k = columns.len() + 1;
    let design =
        nalgebra::DMatrix::from_fn(n, k, |i, j| if j == 0 { 1.0 } else { columns[j - 1][i] });
    let y = nalgebra::DVector::from_column_slice(x);
    let gram = design.tr_mul(&design);
    let rhs = design.tr_mul(&y);
    match gram.cholesky() {
        Some(c) => {
            let b = c.solve(&rhs);
            (y.norm_squared() - b.dot(&rhs)).max(0.0)
        }
        None => centred_ss(x),
    }
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x * x;
        n += 1;
    }
    (s / n.max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sensor_heated_by_events_is_named_by_them() {
        // A motor sensor: the air (wandering slowly) plus a first-order response (tau 16 min)
        // to a switched power.
        let t: Vec<f64> = (0..20_000).map(|k| k as f64 * 15.0).collect();
        let air: Vec<f64> = t.iter().map(|t| 20.0 + (t / 40_000.0).sin()).collect();
        let power = channels::Channel::Held {
            switch_s: vec![-1.0, 10_000.0, 60_000.0, 120_000.0, 200_000.0],
            values: vec![0.0, 3000.0, 0.0, 5000.0, 0.0],
            at_samples: Vec::new(),
        };
        let (heat, _) = power.lag(&t, 960.0, false);
        let motor: Vec<f64> = heat.iter().zip(&air).map(|(h, a)| a + 0.002 * h).collect();
        let air_channel = channels::Channel::Sampled(air.clone());
        let events = vec![("spindle".to_string(), power)];
        let p = profile(
            "t5",
            SensorKind::Other,
            &t,
            &motor,
            Some(&air_channel),
            &events,
        );
        assert_eq!(p.event.as_deref(), Some("spindle"), "{p:?}");
        assert_eq!(p.event_tau_s, 960.0);
        assert!(p.event_share > 0.99, "{p:?}");
        assert_eq!(p.heated_by(), Some("spindle"), "{p:?}");
        assert!(p.near_source(), "{p:?}");

        // A sensor in the air: follows it, nothing left for the events.
        let p = profile(
            "t2",
            SensorKind::Other,
            &t,
            &air,
            Some(&air_channel),
            &events,
        );
        assert!(p.follows_air(), "{p:?}");
        assert_eq!(p.heated_by(), None, "{p:?}");
    }
}
