//! The true environment on the fine internal grid: air at bar height (T1) and above (T2), the
//! plate temperature, and the hidden channel; plus the door events and the logged sensor readings.
//!
//! The room is a daily swing, an air-conditioning triangle, Poisson door openings and, for
//! identification campaigns, programmed set-point steps. `[generation]` is applied here too: the
//! room runs `prehistory_hours` before the logging starts, and the air between two temperature
//! readings is the room's own, the last reading's held, or the readings' interpolated
//! (`air_between_readings`).

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use rand::Rng;
use rand_distr::{Distribution, Exp, Normal};

use super::config::{AirBetweenReadings, HiddenChannel, RoomConfig, SimConfig};
use super::lag::FirstOrderLag;
use super::{stream_rng, streams, Grid};
use dbbcal_core::series::SensorLog;
use dbbcal_core::signal::interpolate::{self, Knot};

// Sensor ids the simulator writes.
/// Id of the first air sensor.
pub const AIR_LOW: &str = "T1";
/// Id of the second air sensor.
pub const AIR_HIGH: &str = "T2";
/// Id of the plate sensor (kind plate).
pub const PLATE: &str = "P1";

const DAY_S: f64 = 86400.0;

/// True signals at every grid point `i` (time `i * step_s` after the start).
#[derive(Debug, Clone)]
pub(crate) struct Environment {
    /// Air at bar height, °C: what drives the bars (and what T1 reads at its reading times,
    /// before noise).
    pub(crate) t1_c: Vec<f64>,
    /// Air above the bars, °C (what T2 reads, before noise).
    pub(crate) t2_c: Vec<f64>,
    /// Plate temperature: T1 lagged by `plate.thermal_tau_s`.
    pub(crate) plate_c: Vec<f64>,
    /// The hidden channel's true value, °C, when the effect is on.
    pub(crate) hidden_c: Option<Vec<f64>>,
    /// Door openings, seconds after the start (whole seconds).
    pub(crate) door_times_s: Vec<f64>,
    /// The room before the logging starts (`generation.prehistory_hours`), on the same grid,
    /// ending at the start (its last point is the first of `t1_c`, `t2_c`); empty without one.
    pub(crate) pre_t1_c: Vec<f64>,
    pub(crate) pre_t2_c: Vec<f64>,
    pub(crate) pre_hidden_c: Option<Vec<f64>>,
    /// The heat source's excess over T1, K, when the effect is on (the cabinet's sensor reads
    /// T1 plus it), and its pre-history.
    pub(crate) cabinet_excess_k: Option<Vec<f64>>,
    pub(crate) pre_cabinet_excess_k: Option<Vec<f64>>,
    /// The air is constant over each grid step (`generation.air_between_readings = "held"`):
    /// the bars integrate it held, not linearly.
    pub(crate) air_held: bool,
}

/// A sum of sinusoids `sum a sin(w t + phi)`: the slow random wander of the room.
struct Sinusoids(Vec<(f64, f64, f64)>);

impl Sinusoids {
    fn random(rng: &mut impl Rng, n: usize, amplitude: f64, min_days: f64, max_days: f64) -> Self {
        let each = amplitude / (n as f64).sqrt();
        Self(
            (0..n)
                .map(|_| {
                    let period_s = rng.gen_range(min_days..max_days) * DAY_S;
                    (each, TAU / period_s, rng.gen_range(0.0..TAU))
                })
                .collect(),
        )
    }

    fn at(&self, t_s: f64) -> f64 {
        self.0
            .iter()
            .map(|&(a, w, phi)| a * (w * t_s + phi).sin())
            .sum()
    }
}

/// Triangle wave of amplitude 1 and period `period_s`, phase `phase` in cycles.
fn triangle(t_s: f64, period_s: f64, phase: f64) -> f64 {
    let x = (t_s / period_s + phase).rem_euclid(1.0);
    2.0 * (2.0 * x - 1.0).abs() - 1.0
}

/// Normalised door bump: `(exp(-t/decay) - exp(-t/rise)) / peak`, peak height 1.
fn door_bump(t_s: f64, rise_s: f64, decay_s: f64) -> f64 {
    let t_peak = rise_s * decay_s / (decay_s - rise_s) * (decay_s / rise_s).ln();
    let shape = |t: f64| (-t / decay_s).exp() - (-t / rise_s).exp();
    shape(t_s) / shape(t_peak)
}

impl Environment {
    pub(crate) fn build(cfg: &SimConfig, grid: &Grid) -> Self {
        let room = &cfg.room;
        let mut rng = stream_rng(cfg.seed, streams::ROOM);
        let wander = Sinusoids::random(&mut rng, 3, room.wander_k, 1.5, 6.0);
        let gradient_wander = Sinusoids::random(&mut rng, 2, room.gradient_wander_k, 0.3, 2.0);
        let ac_phase = rng.gen_range(0.0..1.0);
        let door_times_s = door_times(&mut rng, room, grid.duration_s());
        let day_offset_s = seconds_of_day(cfg);
        // Grid points before the start (the pre-history); the room's signals are functions of
        // time and run back unchanged; doors happen only while logging.
        let pre = prehistory_points(cfg, grid);
        let n = grid.n_points() + pre;
        let mut t1_c = Vec::with_capacity(n);
        let mut t2_c = Vec::with_capacity(n);
        for i in 0..n {
            let t = grid_time(i, pre, grid.step_s);
            let daily = (TAU * (t + day_offset_s - room.daily_peak_hour * 3600.0) / DAY_S).cos();
            let ac = triangle(t, room.ac_period_s, ac_phase);
            let low = room.mean_c
                + room.daily_amplitude_k * daily
                + room.ac_amplitude_k * ac
                + room.drift_k_per_day * t / DAY_S
                + wander.at(t);
            let gradient = room.gradient_k
                + room.gradient_daily_k * daily
                + room.gradient_ac_k * ac
                + gradient_wander.at(t);
            t1_c.push(low);
            t2_c.push(low + gradient);
        }
        add_doors(
            &mut t1_c[pre..],
            &mut t2_c[pre..],
            &door_times_s,
            room,
            grid.step_s,
        );
        add_setpoint_steps(&mut t1_c, &mut t2_c, room, grid.step_s, pre);
        let air_held = cfg.generation.air_between_readings == AirBetweenReadings::Held;
        if cfg.generation.air_between_readings != AirBetweenReadings::Continuous {
            let period = readings_period_points(cfg, grid);
            for series in [&mut t1_c, &mut t2_c] {
                *series = air_between_readings(series, period, pre, air_held);
            }
        }
        let plate_c = lagged(&t1_c, cfg.plate.thermal_tau_s, grid.step_s, air_held);
        let cabinet_excess_k = cfg
            .effects
            .heat_source
            .enabled
            .then(|| cabinet_excess(cfg, grid, pre));
        let hidden_c = cfg
            .effects
            .hidden_channel
            .enabled
            .then(|| hidden_signal(cfg.seed, &cfg.effects.hidden_channel, grid, pre));
        let split = |mut v: Vec<f64>| {
            let main = v.split_off(pre);
            if pre > 0 {
                v.push(main[0]);
            }
            (v, main)
        };
        let (pre_t1_c, t1_c) = split(t1_c);
        let (pre_t2_c, t2_c) = split(t2_c);
        let (_, plate_c) = split(plate_c);
        let (pre_hidden_c, hidden_c) = match hidden_c.map(split) {
            Some((p, h)) => (Some(p), Some(h)),
            None => (None, None),
        };
        let (pre_cabinet_excess_k, cabinet_excess_k) = match cabinet_excess_k.map(split) {
            Some((p, h)) => (Some(p), Some(h)),
            None => (None, None),
        };
        Self {
            t1_c,
            t2_c,
            plate_c,
            hidden_c,
            door_times_s,
            pre_t1_c,
            pre_t2_c,
            pre_hidden_c,
            cabinet_excess_k,
            pre_cabinet_excess_k,
            air_held,
        }
    }

    /// The logged temperature sensors: T1, T2, optionally P1 and the hidden channel, each with
    /// white Gaussian noise, sampled every `room.temperature_sample_s`.
    pub(crate) fn sensor_logs(
        &self,
        cfg: &SimConfig,
        grid: &Grid,
        start_ns: i64,
    ) -> BTreeMap<String, SensorLog> {
        let mut logs = BTreeMap::new();
        let noise = cfg.room.sensor_noise_k;
        let mut add = |id: &str, series: &[f64], noise_k: f64, stream: u64| {
            logs.insert(
                id.to_string(),
                sample_sensor(series, noise_k, cfg, grid, start_ns, stream),
            );
        };
        add(AIR_LOW, &self.t1_c, noise, streams::SENSOR);
        add(AIR_HIGH, &self.t2_c, noise, streams::SENSOR + 1);
        if logs_plate_sensor(cfg) {
            add(PLATE, &self.plate_c, noise, streams::SENSOR + 2);
        }
        if let Some(h) = &self.hidden_c {
            let hc = &cfg.effects.hidden_channel;
            add(&hc.sensor_id, h, hc.noise_k, streams::SENSOR + 3);
        }
        if let Some(excess) = &self.cabinet_excess_k {
            let hs = &cfg.effects.heat_source;
            let cabinet: Vec<f64> = self.t1_c.iter().zip(excess).map(|(a, e)| a + e).collect();
            add(&hs.sensor_id, &cabinet, hs.noise_k, streams::SENSOR + 4);
        }
        logs
    }
}

/// Whether a plate sensor is logged.
pub(crate) fn logs_plate_sensor(cfg: &SimConfig) -> bool {
    cfg.room.plate_sensor || cfg.effects.plate_expansion.enabled || cfg.plate.cte_ppm_per_k != 0.0
}

fn seconds_of_day(cfg: &SimConfig) -> f64 {
    let ts = cfg.start.timestamp();
    ts.rem_euclid(86400) as f64 + f64::from(cfg.start.timestamp_subsec_nanos()) * 1e-9
}

/// Poisson door openings over the campaign, at whole seconds.
fn door_times(rng: &mut impl Rng, room: &RoomConfig, duration_s: f64) -> Vec<f64> {
    let mut times = Vec::new();
    if room.door_rate_per_day <= 0.0 {
        return times;
    }
    let Ok(gap) = Exp::new(room.door_rate_per_day / DAY_S) else {
        return times;
    };
    let mut t = gap.sample(rng);
    while t < duration_s {
        times.push(t.round());
        t += gap.sample(rng);
    }
    times
}

/// Add every door bump to both air heights (the door air mixes the room).
fn add_doors(t1: &mut [f64], t2: &mut [f64], doors_s: &[f64], room: &RoomConfig, step_s: f64) {
    let window_s = 12.0 * room.door_decay_s;
    for &door in doors_s {
        let first = (door / step_s).ceil() as usize;
        let last = (((door + window_s) / step_s) as usize).min(t1.len().saturating_sub(1));
        for i in first..=last {
            let bump = room.door_amplitude_k
                * door_bump(
                    i as f64 * step_s - door,
                    room.door_rise_s,
                    room.door_decay_s,
                );
            t1[i] += bump;
            t2[i] += bump;
        }
    }
}

/// The programmed set-point steps ([`RoomConfig::setpoint_step_k`]): a square wave of
/// `±step / 2` starting high at the start of the logging, followed by the air with the
/// first-order settle of the air-conditioning loop, added to both air levels (`pre` grid points
/// of pre-history come first).
fn add_setpoint_steps(t1: &mut [f64], t2: &mut [f64], room: &RoomConfig, step_s: f64, pre: usize) {
    if room.setpoint_step_k == 0.0 {
        return;
    }
    let half = room.setpoint_step_k / 2.0;
    let square: Vec<f64> = (0..t1.len())
        .map(|i| {
            let t = grid_time(i, pre, step_s);
            let phase = (t / room.setpoint_half_period_s).floor() as i64;
            if phase.rem_euclid(2) == 0 {
                half
            } else {
                -half
            }
        })
        .collect();
    let air = lagged(&square, room.setpoint_settle_s, step_s, false);
    for ((a, b), d) in t1.iter_mut().zip(t2.iter_mut()).zip(air) {
        *a += d;
        *b += d;
    }
}

/// `series` lagged by `tau_s`, starting in equilibrium; the input linear over each step, or
/// held at its value at the step's start (`held`).
fn lagged(series: &[f64], tau_s: f64, step_s: f64, held: bool) -> Vec<f64> {
    let Some(&first) = series.first() else {
        return Vec::new();
    };
    let mut lag = FirstOrderLag::new(tau_s, step_s, first);
    let mut out = Vec::with_capacity(series.len());
    out.push(first);
    out.extend(series.windows(2).map(|w| {
        if held {
            lag.step_held(w[0])
        } else {
            lag.step_linear(w[0], w[1])
        }
    }));
    out
}

/// Time (s after the start of the logging) of grid point `i` of a grid with `pre` points of
/// pre-history.
fn grid_time(i: usize, pre: usize, step_s: f64) -> f64 {
    if pre == 0 {
        i as f64 * step_s
    } else {
        (i as f64 - pre as f64) * step_s
    }
}

/// Grid points of pre-history (`generation.prehistory_hours`, whole steps).
pub(crate) fn prehistory_points(cfg: &SimConfig, grid: &Grid) -> usize {
    (cfg.generation.prehistory_hours * 3600.0 / grid.step_s).round() as usize
}

/// Grid steps between two temperature readings (validated to be whole:
/// [`SimConfig::validate`]).
fn readings_period_points(cfg: &SimConfig, grid: &Grid) -> usize {
    ((cfg.room.temperature_sample_s / grid.step_s).round() as usize).max(1)
}

/// The air rebuilt from its values at the reading times (every `period` grid points from the
/// start of the logging, `pre` points into `series`; readings go on back into the
/// pre-history): held from each reading to the next (`held`), or linear between them. At a
/// reading time the value is the air's own.
fn air_between_readings(series: &[f64], period: usize, pre: usize, held: bool) -> Vec<f64> {
    let last = series.len() - 1;
    // Grid index of reading `k` (k counts from the first reading at or before grid point 0).
    let first = pre % period;
    let reading = |i: usize| -> (usize, usize) {
        let k = if i < first { 0 } else { (i - first) / period };
        let at = if i < first { i } else { first + k * period };
        (at, (at + period).min(last))
    };
    (0..series.len())
        .map(|i| {
            let (a, b) = reading(i);
            if held || b == a {
                series[a]
            } else {
                let index = |k: usize| k as i64;
                i64::lerp(index(a), index(b), series[a], series[b], index(i))
            }
        })
        .collect()
}

/// The machine's temperature: base + amplitude * lag(on/off), on and off for exponential
/// durations, starting off and cold.
fn hidden_signal(seed: u64, h: &HiddenChannel, grid: &Grid, pre: usize) -> Vec<f64> {
    let mut rng = stream_rng(seed, streams::HIDDEN);
    let toggles = on_off_toggles(&mut rng, h.mean_off_h, h.mean_on_h, grid.duration_s());
    let mut lag = FirstOrderLag::new(h.signal_tau_s, grid.step_s, 0.0);
    let mut on = false;
    let mut next = toggles.iter().peekable();
    (0..grid.n_points() + pre)
        .map(|i| {
            let value = h.base_c + h.amplitude_k * lag.state;
            let t = grid_time(i, pre, grid.step_s);
            while next.next_if(|&&toggle| toggle <= t).is_some() {
                on = !on;
            }
            lag.step_held(if on { 1.0 } else { 0.0 });
            value
        })
        .collect()
}

/// The heat source's excess over T1 (K) on the grid, pre-history first
/// ([`crate::HeatSource`]): `excess_k` times the lag of its running state, on from `on_hour`
/// to `off_hour` (UTC) on working days (Monday to Friday), off and cold before the grid starts.
fn cabinet_excess(cfg: &SimConfig, grid: &Grid, pre: usize) -> Vec<f64> {
    let h = &cfg.effects.heat_source;
    let start_s =
        cfg.start.timestamp() as f64 + f64::from(cfg.start.timestamp_subsec_nanos()) * 1e-9;
    let running = |t: f64| {
        let abs = start_s + t;
        let day = (abs / DAY_S).floor();
        // 1970-01-01 was a Thursday: Monday is 0.
        let weekday = (day as i64 + 3).rem_euclid(7);
        let hour = (abs - day * DAY_S) / 3600.0;
        weekday < 5 && hour >= h.on_hour && hour < h.off_hour
    };
    let mut lag = FirstOrderLag::new(h.signal_tau_s, grid.step_s, 0.0);
    (0..grid.n_points() + pre)
        .map(|i| {
            let value = h.excess_k * lag.state;
            lag.step_held(if running(grid_time(i, pre, grid.step_s)) {
                1.0
            } else {
                0.0
            });
            value
        })
        .collect()
}

/// Alternating durations (first `first_mean_h`, then `second_mean_h`, ...), exponential with a
/// floor of 5 minutes: the toggle times in seconds, below `duration_s`.
pub(crate) fn on_off_toggles(
    rng: &mut impl Rng,
    first_mean_h: f64,
    second_mean_h: f64,
    duration_s: f64,
) -> Vec<f64> {
    let mut toggles = Vec::new();
    let mut t = 0.0;
    let mut first = true;
    loop {
        let mean_s = if first { first_mean_h } else { second_mean_h } * 3600.0;
        let unit: f64 = rng.sample(rand_distr::Exp1);
        t += (mean_s * unit).max(300.0);
        if t >= duration_s {
            return toggles;
        }
        toggles.push(t);
        first = !first;
    }
}

/// A sensor's readings: `series` interpolated at each logging time, plus noise.
fn sample_sensor(
    series: &[f64],
    noise_k: f64,
    cfg: &SimConfig,
    grid: &Grid,
    start_ns: i64,
    stream: u64,
) -> SensorLog {
    let mut rng = stream_rng(cfg.seed, stream);
    let normal =
        Normal::new(0.0, noise_k).unwrap_or_else(|_| Normal::new(0.0, 0.0).expect("zero sd"));
    let period_ns = (cfg.room.temperature_sample_s * 1e9).round().max(1.0) as i64;
    let n = ((grid.duration_ns + period_ns - 1) / period_ns) as usize;
    let mut log = SensorLog {
        time_ns: Vec::with_capacity(n),
        celsius: Vec::with_capacity(n),
    };
    for k in 0..n as i64 {
        let offset_ns = k * period_ns;
        let value = interpolate::on_grid(series, offset_ns as f64 * 1e-9 / grid.step_s);
        log.time_ns.push(start_ns + offset_ns);
        log.celsius.push(value + normal.sample(&mut rng));
    }
    log
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn door_bump_peaks_at_one() {
        let (rise, decay) = (60.0, 600.0);
        let peak = (0..20000)
            .map(|i| door_bump(i as f64 * 0.1, rise, decay))
            .fold(0.0, f64::max);
        assert!((peak - 1.0).abs() < 1e-6);
        assert_eq!(door_bump(0.0, rise, decay), 0.0);
    }

    #[test]
    fn triangle_spans_minus_one_to_one() {
        let v: Vec<f64> = (0..1200).map(|t| triangle(t as f64, 1200.0, 0.0)).collect();
        assert_eq!(v[0], 1.0);
        assert_eq!(v[600], -1.0);
    }
}
