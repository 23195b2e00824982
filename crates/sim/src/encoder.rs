//! One bar's encoder log: the thermal states integrated on the fine grid, the true distance,
//! the thermal error and the quantized, noisy counts (`docs/spec/physics.md`, first-order model).
//!
//! `counts = round(((D_true - D_zero) + e + noise) / k)` for an ideal bar, with the thermal error
//! `e = -dD + settling + creep`; with geometric terms (`geometry.rs`) the counts are those the
//! true map `D(n, A)` sends to `D_true + e + noise`. And `dD = alpha I_min lag(T - T0; tau_R) + beta I_p lag(T - T0;
//! tau_S)` plus the enabled growth terms (second path, head heating, hidden channel). Lengths
//! in mm, `alpha`/`beta` in ppm/K, so `ppm * mm * 1e-3` is micrometres.

use rand_distr::{Distribution, Normal};

use super::environment::{Environment, AIR_HIGH, AIR_LOW};
use super::lag::FirstOrderLag;
use super::schedule::{BarPlan, Place};
use super::truth::BarTruth;
use super::{stream_rng, streams, Grid};
use dbbcal_core::series::EncoderLog;

/// What one bar's simulation yields.
#[derive(Debug, Clone, Default)]
pub(crate) struct BarRun {
    pub(crate) log: EncoderLog,
    /// Noise-free thermal error (indicated − true), µm, per row of `log`; empty unless recorded.
    pub(crate) true_error_um: Vec<f64>,
}

/// Everything constant during one bar's run.
pub(crate) struct BarSetup<'a> {
    pub(crate) bar: &'a BarTruth,
    pub(crate) plan: &'a BarPlan,
    pub(crate) index: usize,
    pub(crate) lengths_mm: &'a [f64],
    pub(crate) seed: u64,
    pub(crate) start_ns: i64,
    pub(crate) reference_temperature_c: f64,
    pub(crate) noise_um: f64,
    /// True plate expansion, ppm/K (declared + undeclared).
    pub(crate) plate_cte_ppm_per_k: f64,
    pub(crate) record_true_error: bool,
    /// The bar is a leg of a simulated hexapod: its true length and tilt on the device over time.
    pub(crate) leg_track: Option<&'a crate::hexapod::LegTrack>,
}

/// The bar's lagged states: `x' = (u - x) / tau` for each path (`docs/spec/physics.md`).
struct ThermalState {
    /// Weights of T1 and T2 in the temperature the bar sees.
    w_low: f64,
    w_high: f64,
    t0_c: f64,
    /// The air is held over each grid step ([`Environment::air_held`]).
    air_held: bool,
    fixed: FirstOrderLag,
    scale: FirstOrderLag,
    second: Option<(FirstOrderLag, f64)>,
    head: Option<(FirstOrderLag, f64)>,
    hidden: Option<(FirstOrderLag, f64, f64)>,
    /// The heat source: the lag of the cabinet's excess, and its expansions through the fixed
    /// part and the scale (ppm/K).
    heat: Option<(FirstOrderLag, f64, f64)>,
}

impl ThermalState {
    /// All states in equilibrium with the first air (the head cold, as the power comes on, or
    /// warm when it has been powered for long before the start); with a pre-history
    /// ([`Environment::pre_t1_c`]) the air states start in equilibrium at its start and follow it
    /// up to the start of the logging.
    fn new(setup: &BarSetup, env: &Environment, step_s: f64) -> Self {
        let bar = setup.bar;
        let w_low = bar.seen_weights.get(AIR_LOW).copied().unwrap_or(0.0);
        let w_high = bar.seen_weights.get(AIR_HIGH).copied().unwrap_or(0.0);
        let t0_c = setup.reference_temperature_c;
        let with_pre = !env.pre_t1_c.is_empty();
        let (t1, t2) = if with_pre {
            (&env.pre_t1_c, &env.pre_t2_c)
        } else {
            (&env.t1_c, &env.t2_c)
        };
        let u0 = w_low * t1[0] + w_high * t2[0] - t0_c;
        let second = bar
            .second_path
            .as_ref()
            .map(|s| (FirstOrderLag::new(s.tau_s, step_s, u0), s.gain_ppm_per_k));
        let head = bar.head_heating.as_ref().map(|h| {
            let warm = if setup.plan.head_warm_at_start {
                1.0
            } else {
                0.0
            };
            (FirstOrderLag::new(h.tau_s, step_s, warm), h.amplitude_um)
        });
        let hidden_c = if with_pre {
            &env.pre_hidden_c
        } else {
            &env.hidden_c
        };
        let hidden = match (&bar.hidden_channel, hidden_c) {
            (Some(c), Some(h)) => Some((
                FirstOrderLag::new(c.tau_s, step_s, h[0] - c.base_c),
                c.gain_um_per_k,
                c.base_c,
            )),
            _ => None,
        };
        let excess = if with_pre {
            &env.pre_cabinet_excess_k
        } else {
            &env.cabinet_excess_k
        };
        let heat = match (&bar.heat_source, excess) {
            (Some(h), Some(e)) => Some((
                FirstOrderLag::new(h.tau_s, step_s, e[0]),
                h.fixed_ppm_per_k,
                h.scale_ppm_per_k,
            )),
            _ => None,
        };
        let mut state = Self {
            w_low,
            w_high,
            t0_c,
            air_held: env.air_held,
            fixed: FirstOrderLag::new(bar.tau_r_s, step_s, u0),
            scale: FirstOrderLag::new(bar.tau_s_s, step_s, u0),
            second,
            head,
            hidden,
            heat,
        };
        if with_pre {
            for i in 0..env.pre_t1_c.len() - 1 {
                let seen = |k: usize| w_low * t1[k] + w_high * t2[k] - t0_c;
                let hidden = env.pre_hidden_c.as_ref().map(|h| (h[i], h[i + 1]));
                state.step_air(seen(i), seen(i + 1), hidden);
                state.step_heat(env.pre_cabinet_excess_k.as_deref(), i);
            }
        }
        state
    }

    fn seen(&self, env: &Environment, i: usize) -> f64 {
        self.w_low * env.t1_c[i] + self.w_high * env.t2_c[i] - self.t0_c
    }

    /// Advance from grid point `i` to `i + 1`, the head powered (`1`) or not (`0`).
    fn advance(&mut self, env: &Environment, i: usize, head_power: f64) {
        let (u0, u1) = (self.seen(env, i), self.seen(env, i + 1));
        let hidden = env.hidden_c.as_ref().map(|h| (h[i], h[i + 1]));
        self.step_air(u0, u1, hidden);
        self.step_heat(env.cabinet_excess_k.as_deref(), i);
        if let Some((lag, _)) = &mut self.head {
            lag.step_held(head_power);
        }
    }

    /// Advance the states that follow the air (and the hidden channel) by one grid step, the
    /// air going from `u0` to `u1` (linearly, or held at `u0` when the air is held).
    fn step_air(&mut self, u0: f64, u1: f64, hidden: Option<(f64, f64)>) {
        let u1 = if self.air_held { u0 } else { u1 };
        self.fixed.step_linear(u0, u1);
        self.scale.step_linear(u0, u1);
        if let Some((lag, _)) = &mut self.second {
            lag.step_linear(u0, u1);
        }
        if let (Some((lag, _, base)), Some((h0, h1))) = (&mut self.hidden, hidden) {
            lag.step_linear(h0 - *base, h1 - *base);
        }
    }

    /// Advance the heat source's lag from grid point `i` to `i + 1` of `excess` (K).
    fn step_heat(&mut self, excess: Option<&[f64]>, i: usize) {
        if let (Some((lag, ..)), Some(e)) = (&mut self.heat, excess) {
            if self.air_held {
                lag.step_held(e[i]);
            } else {
                lag.step_linear(e[i], e[i + 1]);
            }
        }
    }

    /// Growth `dD` of the bar, µm, at scale travel `travel_mm` (`I_p`).
    fn growth_um(&self, bar: &BarTruth, travel_mm: f64) -> f64 {
        let i_min = bar.fixed_length_mm;
        let mut ppm_mm = bar.alpha_ppm_per_k * i_min * self.fixed.state
            + bar.beta_ppm_per_k * travel_mm * self.scale.state;
        if let Some((lag, gain)) = &self.second {
            ppm_mm += gain * i_min * lag.state;
        }
        if let Some((lag, fixed, scale)) = &self.heat {
            ppm_mm += (fixed * i_min + scale * travel_mm) * lag.state;
        }
        let mut um = ppm_mm * 1e-3;
        if let Some((lag, amplitude)) = &self.head {
            um += amplitude * lag.state;
        }
        if let Some((lag, gain, _)) = &self.hidden {
            um += gain * lag.state;
        }
        um
    }
}

/// Head power switches as grid indices, with the power state between them.
struct HeadPower {
    toggles: Vec<usize>,
    next: usize,
    on: bool,
}

impl HeadPower {
    fn new(plan: &BarPlan, grid: &Grid) -> Self {
        let toggles = plan
            .head_toggles_ns
            .iter()
            .map(|&t| (t / grid.sample_ns) as usize * grid.steps_per_sample)
            .collect();
        // Without the effect the head is always on; with it the first toggle (at 0) turns it on,
        // unless it was powered at the start.
        Self {
            toggles,
            next: 0,
            on: plan.head_toggles_ns.is_empty() || plan.head_powered_at_start,
        }
    }

    /// The power state from grid point `i` on.
    fn at(&mut self, i: usize) -> bool {
        while self.next < self.toggles.len() && self.toggles[self.next] <= i {
            self.on = !self.on;
            self.next += 1;
        }
        self.on
    }
}

/// Simulate one bar over the whole campaign (one encoder row per sample while its head is on,
/// or at every sample if it logs while off).
pub(crate) fn simulate_bar(setup: &BarSetup, env: &Environment, grid: &Grid) -> BarRun {
    let mut rng = stream_rng(setup.seed, streams::BAR_NOISE + setup.index as u64);
    let noise = Normal::new(0.0, setup.noise_um)
        .unwrap_or_else(|_| Normal::new(0.0, 0.0).expect("zero sd"));
    let mut state = ThermalState::new(setup, env, grid.step_s);
    let mut power = HeadPower::new(setup.plan, grid);
    let mut run = BarRun {
        log: EncoderLog {
            time_ns: Vec::with_capacity(grid.n_samples),
            counts: Vec::with_capacity(grid.n_samples),
        },
        true_error_um: Vec::with_capacity(if setup.record_true_error {
            grid.n_samples
        } else {
            0
        }),
    };
    let mut cursor = 0;
    let m = grid.steps_per_sample;
    for j in 0..grid.n_samples {
        let i = j * m;
        if j > 0 {
            for k in (i - m)..i {
                let p = if power.at(k) { 1.0 } else { 0.0 };
                state.advance(env, k, p);
            }
        }
        let noise_um = noise.sample(&mut rng); // drawn for every sample: streams stay aligned
        if !power.at(i) && !setup.plan.head_logs_while_off {
            continue;
        }
        let t_ns = j as i64 * grid.sample_ns;
        let place = setup.plan.place_at(t_ns, setup.lengths_mm, &mut cursor);
        let (true_mm, error_um, tilt_deg) = distance_and_error(setup, &state, env, i, t_ns, place);
        let reading_um = (true_mm - setup.bar.d_zero_mm) * 1e3 + error_um + noise_um;
        run.log.time_ns.push(setup.start_ns + t_ns);
        run.log
            .counts
            .push(counts_of(setup.bar, reading_um, tilt_deg));
        if setup.record_true_error {
            run.true_error_um.push(error_um);
        }
    }
    run
}

/// Quantized counts of an indicated distance `D_zero + reading_um` at tilt `tilt_deg`: ideal
/// bars keep the plain `reading / k`, others invert their true map `D(n, A)`.
fn counts_of(bar: &BarTruth, reading_um: f64, tilt_deg: f64) -> i64 {
    if bar.geometry.is_ideal() {
        return (reading_um * 1e3 / bar.resolution_nm).round() as i64;
    }
    let travel_mm = bar
        .geometry
        .indicated_travel_mm(reading_um * 1e-3, tilt_deg, bar.d_zero_mm);
    (travel_mm * 1e6 / bar.resolution_nm).round() as i64
}

/// True centre distance (mm), thermal error (µm) and tilt (degrees) at grid point `i`, time `t_ns`.
fn distance_and_error(
    setup: &BarSetup,
    state: &ThermalState,
    env: &Environment,
    i: usize,
    t_ns: i64,
    place: Place,
) -> (f64, f64, f64) {
    let bar = setup.bar;
    let (true_mm, nominal_mm, settling_um, tilt_deg) = match place {
        Place::Mounted {
            nominal_mm,
            on_plate,
            tilt_deg,
            from_ns,
            settling_um,
        } => {
            let plate_dt = env.plate_c[i] - setup.reference_temperature_c;
            let cte = if on_plate {
                setup.plate_cte_ppm_per_k
            } else {
                0.0
            };
            let true_mm = nominal_mm * (1.0 + cte * 1e-6 * plate_dt);
            if let (false, Some(track)) = (on_plate, setup.leg_track) {
                let (leg_mm, leg_tilt_deg) = track.at(t_ns);
                let settling = match bar.settling_tau_s {
                    Some(tau_s) => settling_um * (-((t_ns - from_ns) as f64 * 1e-9) / tau_s).exp(),
                    None => 0.0,
                };
                (leg_mm, leg_mm, settling, leg_tilt_deg)
            } else {
                let settling = match bar.settling_tau_s {
                    Some(tau_s) => settling_um * (-((t_ns - from_ns) as f64 * 1e-9) / tau_s).exp(),
                    None => 0.0,
                };
                (true_mm, nominal_mm, settling, tilt_deg)
            }
        }
        Place::Handling {
            position_mm,
            tilt_deg,
        } => (position_mm, position_mm, 0.0, tilt_deg),
    };
    let travel_mm = nominal_mm - bar.fixed_length_mm;
    let creep_um = bar
        .creep_um_per_day
        .map_or(0.0, |rate| rate * t_ns as f64 * 1e-9 / 86400.0);
    (
        true_mm,
        -state.growth_um(bar, travel_mm) + settling_um + creep_um,
        tilt_deg,
    )
}
