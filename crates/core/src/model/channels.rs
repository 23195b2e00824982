//! Channels: every logged signal a term or the diagnosis can use, at a bar's sample times.
//!
//! Names (the strings users type after `lag:`, `rate:`, `level:`):
//! - a sensor id (`T1`), or a difference of two (`T2-T1`);
//! - `event:KIND`: events with values as a held (step) series (`head_power`, `tilt`, …),
//!   events without values as unit impulses (`door`, `handling`, …);
//! - `time_since_mount_h`, `time_of_day_h`, `length_mm` (`I_p`), `tilt_deg`.

use crate::series::BarSeries;

use crate::signal::lag;

/// A channel's samples at the bar's times, or impulse times.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Channel {
    Sampled(Vec<f64>),
    /// Times (s, sorted) of unit impulses.
    Impulses(Vec<f64>),
    /// A piecewise-constant input switching to `values[j]` at `switch_s[j]` (from events that
    /// carry values), held between switches even where no sample was logged.
    Held {
        switch_s: Vec<f64>,
        values: Vec<f64>,
        at_samples: Vec<f64>,
    },
}

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ChannelError {
    #[error("no channel {0:?} in this campaign for this bar")]
    Unknown(String),
    #[error("no {0} events for this bar")]
    NoEvents(String),
    #[error("needs two air sensors and a bar with its own `sensor`")]
    NoGradient,
    #[error("needs a sensor of kind \"plate\"")]
    NoPlateSensor,
    #[error("heat acts through a logged quantity: {0:?} is an event channel; use a sensor or a difference of two (heat:C1, heat:C1-T1)")]
    HeatNeedsSampled(String),
}

impl Channel {
    /// First-order lag of the channel (impulses: their unit responses).
    pub(crate) fn lag(
        &self,
        t_s: &[f64],
        tau_s: f64,
        with_derivative: bool,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        match self {
            Channel::Sampled(u) => lag::lag(t_s, u, tau_s, with_derivative),
            Channel::Impulses(e) => lag::impulse_lag(t_s, e, tau_s, with_derivative),
            Channel::Held {
                switch_s, values, ..
            } => lag::held_lag(t_s, switch_s, values, tau_s, with_derivative),
        }
    }

    /// Whether the channel holds one value over the whole timeline: its lag is then that value
    /// too, a constant the mount zeros already hold.
    pub(crate) fn is_constant(&self) -> bool {
        fn all_equal<'v>(mut v: impl Iterator<Item = &'v f64>) -> bool {
            let first = v.next().copied();
            v.all(|x| Some(*x) == first)
        }
        match self {
            Channel::Sampled(u) => all_equal(u.iter()),
            Channel::Impulses(e) => e.is_empty(),
            Channel::Held {
                values, at_samples, ..
            } => all_equal(values.iter().chain(at_samples)),
        }
    }

    /// The channel's level (impulses: 1 at the first sample at or after each impulse).
    pub(crate) fn level(&self, n: usize) -> Vec<f64> {
        match self {
            Channel::Sampled(u) => u.clone(),
            Channel::Impulses(_) => vec![0.0; n],
            Channel::Held { at_samples, .. } => at_samples.clone(),
        }
    }
}

/// Resolve a channel name for a bar.
pub(crate) fn resolve(series: &BarSeries, name: &str) -> Result<Channel, ChannelError> {
    if let Some(c) = series.celsius.get(name) {
        return Ok(Channel::Sampled(c.clone()));
    }
    if let Some((a, b)) = name.split_once('-') {
        if let (Some(a), Some(b)) = (series.celsius.get(a), series.celsius.get(b)) {
            return Ok(Channel::Sampled(
                a.iter().zip(b).map(|(a, b)| a - b).collect(),
            ));
        }
    }
    if let Some(kind) = name.strip_prefix("event:") {
        return event_channel(series, kind);
    }
    let t = &series.t_s;
    match name {
        "time_since_mount_h" => Ok(Channel::Sampled(
            t.iter()
                .zip(&series.mount_of)
                .map(|(t, m)| m.map_or(0.0, |m| (t - series.mounts[m as usize].from_s) / 3600.0))
                .collect(),
        )),
        "time_of_day_h" => {
            let t0_s = series.t0_ns as f64 * 1e-9;
            Ok(Channel::Sampled(
                t.iter()
                    .map(|t| ((t0_s + t) / 3600.0).rem_euclid(24.0))
                    .collect(),
            ))
        }
        "length_mm" => Ok(Channel::Sampled(series.i_p_mm())),
        "tilt_deg" => Ok(Channel::Sampled(mount_tilt_held(series))),
        _ => Err(ChannelError::Unknown(name.to_string())),
    }
}

/// The tilt of the bar's mount at each sample, degrees. Between mounts (handling) the bar's tilt
/// is not known: the last mount's is held (the first mount's before it), so the channel changes
/// only where the tilt does. A 0 there made a step at every mount start even on a campaign
/// whose mounts all share one tilt, and `lag:tilt_deg` then mimicked settling: on the second
/// simulator's settling campaigns (`bench/foreign_check.py`, seeds 2 and 3) it ranked above
/// `settling` itself.
fn mount_tilt_held(series: &BarSeries) -> Vec<f64> {
    let tilt_of = |m: u32| series.mounts[m as usize].tilt_deg;
    let mut held = series
        .mount_of
        .iter()
        .flatten()
        .next()
        .map_or(0.0, |&m| tilt_of(m));
    series
        .mount_of
        .iter()
        .map(|m| {
            if let Some(&m) = m.as_ref() {
                held = tilt_of(m);
            }
            held
        })
        .collect()
}

/// Events of one kind for the bar: a held series when they carry values, impulses otherwise.
/// The held series' value before the first event follows [`held_start`]'s rules.
pub(crate) fn event_channel(series: &BarSeries, kind: &str) -> Result<Channel, ChannelError> {
    held_event_channel(series, kind).map(|(channel, _)| channel)
}

/// [`event_channel`], and for a held series what the data leave unknown about its start.
pub(crate) fn held_event_channel(
    series: &BarSeries,
    kind: &str,
) -> Result<(Channel, HeldStart), ChannelError> {
    let events: Vec<(f64, Option<f64>)> = series
        .events
        .iter()
        .filter(|(_, e)| e.kind.as_str() == kind)
        .map(|(t, e)| (*t, e.value))
        .collect();
    if events.is_empty() {
        return Err(ChannelError::NoEvents(kind.to_string()));
    }
    if events.iter().all(|(_, v)| v.is_none()) {
        return Ok((
            Channel::Impulses(events.iter().map(|(t, _)| *t).collect()),
            HeldStart::default(),
        ));
    }
    // Valueless events of a kind that otherwise carries values keep the value they find.
    let mut switch_s = Vec::with_capacity(events.len() + 1);
    let mut values = Vec::with_capacity(events.len() + 1);
    let mut value = 0.0;
    for (t, v) in &events {
        value = v.unwrap_or(value);
        switch_s.push(*t);
        values.push(value);
    }
    let (before, start) = held_start(series, kind, switch_s[0], &values);
    // The lag starts here, in steady state at the value before the first event.
    switch_s.insert(
        0,
        series.t_s.first().copied().unwrap_or(0.0).min(switch_s[0]) - 1.0,
    );
    values.insert(0, before);
    let at_samples = held_at(&series.t_s, &switch_s, &values);
    Ok((
        Channel::Held {
            switch_s,
            values,
            at_samples,
        },
        start,
    ))
}

/// A held input's value at each sample time.
fn held_at(t_s: &[f64], switch_s: &[f64], values: &[f64]) -> Vec<f64> {
    let mut at_samples = Vec::with_capacity(t_s.len());
    let mut next = 0;
    let mut current = 0.0;
    for &t in t_s {
        while next < switch_s.len() && switch_s[next] <= t {
            current = values[next];
            next += 1;
        }
        at_samples.push(current);
    }
    at_samples
}

/// What the data leave unknown about a held event series' start, to be fitted by the model
/// (see [`held_start`]). The default: nothing.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct HeldStart {
    /// The value before the first event cannot be told (a free level, fitted from the fitted
    /// readings before the first event). Its placeholder in the channel is the first value.
    pub(crate) free_level: Option<FreeLevel>,
    /// The first-order state at the first fitted reading is not known to be steady: its
    /// deviation, decaying with the term's time constant from that reading on, is fitted.
    pub(crate) free_deviation_from_s: Option<f64>,
}

/// The samples before a kind's first event, whose level is fitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FreeLevel {
    /// The first event's time, s: the level holds before it.
    pub(crate) until_s: f64,
}

impl HeldStart {
    /// The indicator of the free level (1 before the first event, 0 from it on), as a held
    /// input on `t_s`, or `None`.
    pub(crate) fn level_channel(&self, t_s: &[f64]) -> Option<Channel> {
        let until_s = self.free_level?.until_s;
        let switch_s = vec![
            t_s.first().copied().unwrap_or(0.0).min(until_s) - 1.0,
            until_s,
        ];
        let values = vec![1.0, 0.0];
        let at_samples = held_at(t_s, &switch_s, &values);
        Some(Channel::Held {
            switch_s,
            values,
            at_samples,
        })
    }
}

/// The value of a held event series before its first event (at `first_s`, values `values`), and
/// what the data cannot tell about that start (`docs/spec/campaign-format.md`, events):
///
/// - An event marks a change: before the first one the state is the other one. `head_power`
///   (1 powered, 0 off): off before a first "on", powered before a first "off". A kind whose
///   events carry exactly two values: the other value.
/// - A head that logs readings is powered: readings before the first `head_power` event mean a
///   powered head, whatever that event says.
/// - A lag starts in steady state at the value before the first event, like the temperature
///   lags. A cold (unpowered) head is at rest; a powered head was switched on at a time no
///   event gives, so its heat when the fitted readings begin is fitted (`free_deviation`).
/// - `tilt`: the first mount's tilt (its own, else the plate's).
/// - Any other kind (one value, or more than two): the level before the first event cannot be
///   told; where fitted readings precede the first event it is fitted (`free_level`), else the
///   first value is kept (the readings begin after the first event).
fn held_start(series: &BarSeries, kind: &str, first_s: f64, values: &[f64]) -> (f64, HeldStart) {
    let first_value = values[0];
    let first_fitted_s = series.fit_index.first().map(|&i| series.t_s[i]);
    match kind {
        "head_power" => {
            let logged_before = series.t_s.first().is_some_and(|&t| t < first_s);
            let powered = logged_before || first_value.is_nan() || first_value <= 0.0;
            if powered {
                (
                    1.0,
                    HeldStart {
                        free_deviation_from_s: first_fitted_s,
                        ..HeldStart::default()
                    },
                )
            } else {
                (0.0, HeldStart::default())
            }
        }
        "tilt" => (
            series.mounts.first().map_or(first_value, |m| m.tilt_deg),
            HeldStart::default(),
        ),
        _ => {
            let mut distinct: Vec<f64> = values.to_vec();
            distinct.sort_by(f64::total_cmp);
            distinct.dedup();
            if let [a, b] = distinct[..] {
                return (if first_value == a { b } else { a }, HeldStart::default());
            }
            let free_level = first_fitted_s
                .filter(|&t| t < first_s)
                .map(|_| FreeLevel { until_s: first_s });
            (
                first_value,
                HeldStart {
                    free_level,
                    ..HeldStart::default()
                },
            )
        }
    }
}

/// Mean of the other air sensors minus the bar's own.
pub(crate) fn air_gradient(series: &BarSeries) -> Result<Channel, ChannelError> {
    let own = series.bar.sensor.as_ref().ok_or(ChannelError::NoGradient)?;
    let own_c = series.celsius.get(own).ok_or(ChannelError::NoGradient)?;
    let others: Vec<&Vec<f64>> = series
        .air_sensor_ids
        .iter()
        .filter(|id| *id != own)
        .filter_map(|id| series.celsius.get(id))
        .collect();
    if others.is_empty() {
        return Err(ChannelError::NoGradient);
    }
    let k = others.len() as f64;
    Ok(Channel::Sampled(
        (0..own_c.len())
            .map(|i| others.iter().map(|c| c[i]).sum::<f64>() / k - own_c[i])
            .collect(),
    ))
}

/// The plate sensor's temperature.
pub(crate) fn plate_temperature(series: &BarSeries) -> Result<Vec<f64>, ChannelError> {
    series
        .plate_sensor_id
        .as_ref()
        .and_then(|id| series.celsius.get(id))
        .cloned()
        .ok_or(ChannelError::NoPlateSensor)
}

/// Every channel the diagnosis can offer for this bar (names accepted by [`resolve`]), but those
/// constant over its timeline ([`Channel::is_constant`]).
///
/// Why: the lag of a constant channel is the same constant, which the mount zeros hold; the
/// column the screen fits is then rounding noise, and fitted scale-free it "explained" up to a
/// tenth of a residual at time constants a factor of 1.2 apart (`tilt_deg` on every bar of the
/// loop matrix, whose plate has one tilt: `bench/README.md`).
pub(crate) fn available(series: &BarSeries) -> Vec<String> {
    let mut names = all_channels(series);
    names.retain(|name| !resolve(series, name).is_ok_and(|c| c.is_constant()));
    names
}

/// Every channel name of the bar, constant or not.
fn all_channels(series: &BarSeries) -> Vec<String> {
    let mut names: Vec<String> = series.celsius.keys().cloned().collect();
    let sensors: Vec<String> = series.celsius.keys().cloned().collect();
    for (i, a) in sensors.iter().enumerate() {
        for b in &sensors[i + 1..] {
            names.push(format!("{b}-{a}"));
        }
    }
    let mut kinds: Vec<String> = series
        .events
        .iter()
        .map(|(_, e)| e.kind.to_string())
        .collect();
    kinds.sort();
    kinds.dedup();
    names.extend(kinds.into_iter().map(|k| format!("event:{k}")));
    names.extend(BUILT_IN.map(String::from));
    names
}

/// The channels every bar has, computed from its timeline and mounts ([`resolve`]).
const BUILT_IN: [&str; 4] = [
    "time_since_mount_h",
    "time_of_day_h",
    "length_mm",
    "tilt_deg",
];

/// Whether a channel name is a logged sensor or a difference of two (a temperature a heat
/// term can act through), not an event series or a built-in channel.
pub(crate) fn is_sensor_channel(name: &str) -> bool {
    !name.starts_with("event:") && !BUILT_IN.contains(&name)
}
