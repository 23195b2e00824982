//! First-order lag (low-pass) of irregularly sampled inputs, with its derivative in `ln tau`.
//!
//! `docs/spec/physics.md`: the step response `1 - exp(-t/tau)` generalises to `dx/dt = (u - x) / tau`.
//! Between two samples the input is taken as linear (first-order hold), which makes the
//! discretisation exact for piecewise-linear inputs at any sample spacing:
//!
//! ```text
//! a = exp(-dt/tau),  m = (u1 - u0) / dt
//! x1 = a x0 + u1 - a u0 - m tau (1 - a)
//! ```
//!
//! Differentiating the recursion gives the Jacobian column for `theta = ln tau` at the same cost
//! (`b = a dt / tau`): `D1 = a D0 + b (x0 - u0) + m tau (b - (1 - a))`.
//! The state starts in equilibrium with the first input (`x0 = u0`).
//!
//! # How it works
//!
//! - `lag::lag` caches its step factors (`exp(-dt/tau)` and the hold factor) by the step's bits in
//!   a small open-addressed table per call: a binned bar's timeline repeats a few step lengths,
//!   and a hit returns the bits a fresh computation would (`lag::tests::cached_step_factors_give_the_same_bits`).

/// The lag `x` of `u` sampled at `t_s`, and optionally `dx/d ln tau`.
pub(crate) fn lag(
    t_s: &[f64],
    u: &[f64],
    tau_s: f64,
    with_derivative: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let n = t_s.len().min(u.len());
    if with_derivative {
        let (x, d) = lag_steps::<true>(&t_s[..n], &u[..n], tau_s);
        (x, Some(d))
    } else {
        (lag_steps::<false>(&t_s[..n], &u[..n], tau_s).0, None)
    }
}

/// [`lag`]'s recursion, with the derivative when `DERIVATIVE` (else an empty one).
///
/// Why this shape: the outputs are written into zeroed vectors through iterators. Pushing
/// each step kept the vectors' lengths in memory, a load and a store on every step's path,
/// and made the recursion about 1.6 times slower (130 k steps: 1.15 against 0.71 ms).
fn lag_steps<const DERIVATIVE: bool>(t_s: &[f64], u: &[f64], tau_s: f64) -> (Vec<f64>, Vec<f64>) {
    let n = t_s.len();
    let mut x = vec![0.0; n];
    let mut d = vec![0.0; if DERIVATIVE { n } else { 0 }];
    let Some(&u0) = u.first() else {
        return (x, d);
    };
    let (mut xs, mut ds) = (u0, 0.0);
    x[0] = xs;
    let mut factors = StepFactorCache::new(tau_s);
    let steps = t_s.windows(2).zip(u.windows(2));
    if DERIVATIVE {
        for ((t, u), (x, d)) in steps.zip(x[1..].iter_mut().zip(&mut d[1..])) {
            let dt = t[1] - t[0];
            if dt > 0.0 {
                let StepFactors { r, a, hold, .. } = *factors.at(dt);
                let du = u[1] - u[0];
                let x_next = a * xs + u[1] - a * u[0] - du * hold;
                let b = a * r;
                ds = a * ds + b * (xs - u[0]) + du * (a - hold);
                xs = x_next;
            }
            *x = xs;
            *d = ds;
        }
    } else {
        for ((t, u), x) in steps.zip(&mut x[1..]) {
            let dt = t[1] - t[0];
            if dt > 0.0 {
                let StepFactors { a, hold, .. } = *factors.at(dt);
                let du = u[1] - u[0];
                xs = a * xs + u[1] - a * u[0] - du * hold;
            }
            *x = xs;
        }
    }
    (x, d)
}

/// The per-step factors of [`lag`] for one time step `dt`, with a small cache.
///
/// Why: the exponential is most of a lag's cost, and a bar's timeline repeats a handful of
/// steps (sensor period, the bin nodes' fixed offsets between sensor samples: on the 30-day
/// benchmark 4 step lengths make 83 % of 172 800 steps). A small open-addressed table keyed by the
/// step's bits returns the very bits a fresh computation would, so results do not change.
#[derive(Clone, Copy)]
struct StepFactors {
    dt_bits: u64,
    /// `dt / tau`.
    r: f64,
    /// `exp(-dt/tau)`.
    a: f64,
    /// `(1 - a) / r`: the first-order-hold factor, finite as `tau -> infinity` (`r -> 0`).
    hold: f64,
}

struct StepFactorCache {
    tau_s: f64,
    slots: [StepFactors; CACHE_SLOTS],
}

const CACHE_SLOTS: usize = 64;
/// Slots tried after a step's home slot before one is overwritten (open addressing).
const CACHE_PROBES: usize = 4;

impl StepFactorCache {
    fn new(tau_s: f64) -> StepFactorCache {
        let empty = StepFactors {
            dt_bits: u64::MAX,
            r: f64::NAN,
            a: f64::NAN,
            hold: f64::NAN,
        };
        StepFactorCache {
            tau_s,
            slots: [empty; CACHE_SLOTS],
        }
    }

    fn at(&mut self, dt: f64) -> &StepFactors {
        let bits = dt.to_bits();
        // Fibonacci hashing: round steps (7.5 s, 30 s) differ only in their high bits.
        let home = (bits.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 58) as usize;
        let mut slot = home;
        for probe in 0..CACHE_PROBES {
            slot = (home + probe) % CACHE_SLOTS;
            if self.slots[slot].dt_bits == bits {
                return &self.slots[slot];
            }
            if self.slots[slot].dt_bits == u64::MAX {
                break;
            }
        }
        let r = dt / self.tau_s;
        let one_minus_a = -(-r).exp_m1();
        self.slots[slot] = StepFactors {
            dt_bits: bits,
            r,
            a: 1.0 - one_minus_a,
            hold: if r > 1e-300 { one_minus_a / r } else { 1.0 },
        };
        &self.slots[slot]
    }
}

/// Zero-phase smoothing of `u` sampled at `t_s`: the first-order lag run forward, then backward
/// in time over the result (same time constant).
///
/// Used for a slow body's temperature read by a noisy sensor (the plate): a causal lag would
/// delay the signal by `tau`, the forward-backward pair does not (a ramp comes out unchanged; a
/// sinusoid of angular frequency `w` is scaled by `1 / (1 + (w tau)^2)` with no phase shift),
/// while white sensor noise is cut by about `dt / (2 tau)` in variance.
pub(crate) fn zero_phase_lag(t_s: &[f64], u: &[f64], tau_s: f64) -> Vec<f64> {
    let (forward, _) = lag(t_s, u, tau_s, false);
    let t_rev: Vec<f64> = t_s.iter().rev().map(|t| -t).collect();
    let f_rev: Vec<f64> = forward.into_iter().rev().collect();
    let (mut out, _) = lag(&t_rev, &f_rev, tau_s, false);
    out.reverse();
    out
}

/// Response of a unit first-order system to unit impulses at `events_s` (sorted), sampled at
/// `t_s`: `x(t) = Σ_{e ≤ t} exp(-(t - e)/tau)`, and optionally `dx/d ln tau`.
pub(crate) fn impulse_lag(
    t_s: &[f64],
    events_s: &[f64],
    tau_s: f64,
    with_derivative: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let n = t_s.len();
    let mut x = Vec::with_capacity(n);
    let mut d = with_derivative.then(|| Vec::with_capacity(n));
    let (mut xs, mut ds) = (0.0, 0.0);
    let mut next_event = 0;
    let mut t_prev = t_s.first().copied().unwrap_or(0.0);
    // Events before the first sample still decay into it.
    for &t in t_s {
        let dt = (t - t_prev).max(0.0);
        let a = (-dt / tau_s).exp();
        ds = a * ds + a * dt / tau_s * xs;
        xs *= a;
        while next_event < events_s.len() && events_s[next_event] <= t {
            let s = t - events_s[next_event];
            let e = (-s / tau_s).exp();
            xs += e;
            ds += e * s / tau_s;
            next_event += 1;
        }
        x.push(xs);
        if let Some(d) = d.as_mut() {
            d.push(ds);
        }
        t_prev = t;
    }
    (x, d)
}

/// Response of a unit first-order system to a piecewise-constant input that switches to
/// `values[j]` at `switch_s[j]` (sorted; the input before the first switch is `values[0]`),
/// sampled at `t_s`, and optionally `dx/d ln tau`. Exact at any sampling: the switches are
/// integrated at their own times, so an input that changes while no sample is logged (a read
/// head switched off between readings) is still seen. Starts in equilibrium.
pub(crate) fn held_lag(
    t_s: &[f64],
    switch_s: &[f64],
    values: &[f64],
    tau_s: f64,
    with_derivative: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let n = t_s.len();
    let mut x = Vec::with_capacity(n);
    let mut d = with_derivative.then(|| Vec::with_capacity(n));
    let Some(&u0) = values.first() else {
        return (vec![0.0; n], d.map(|_| vec![0.0; n]));
    };
    let (mut xs, mut ds, mut u) = (u0, 0.0, u0);
    let mut t_prev = t_s
        .first()
        .copied()
        .unwrap_or(0.0)
        .min(switch_s.first().copied().unwrap_or(f64::INFINITY));
    let mut next = 0;
    let advance = |to: f64, xs: &mut f64, ds: &mut f64, u: f64, t_prev: &mut f64| {
        let dt = (to - *t_prev).max(0.0);
        let a = (-dt / tau_s).exp();
        *ds = a * *ds + a * dt / tau_s * (*xs - u);
        *xs = u + (*xs - u) * a;
        *t_prev = to;
    };
    for &t in t_s {
        while next < switch_s.len() && switch_s[next] <= t {
            advance(switch_s[next], &mut xs, &mut ds, u, &mut t_prev);
            u = values[next];
            next += 1;
        }
        advance(t, &mut xs, &mut ds, u, &mut t_prev);
        x.push(xs);
        if let Some(d) = d.as_mut() {
            d.push(ds);
        }
    }
    (x, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The recursion of [`lag`] with its factors computed afresh at every step.
    fn lag_uncached(t: &[f64], u: &[f64], tau: f64) -> (Vec<f64>, Vec<f64>) {
        let (mut xs, mut ds) = (u[0], 0.0);
        let (mut x, mut d) = (vec![xs], vec![ds]);
        for k in 1..t.len() {
            let dt = t[k] - t[k - 1];
            if dt > 0.0 {
                let r = dt / tau;
                let one_minus_a = -(-r).exp_m1();
                let a = 1.0 - one_minus_a;
                let hold = if r > 1e-300 { one_minus_a / r } else { 1.0 };
                let du = u[k] - u[k - 1];
                let x_next = a * xs + u[k] - a * u[k - 1] - du * hold;
                ds = a * ds + a * r * (xs - u[k - 1]) + du * (a - hold);
                xs = x_next;
            }
            x.push(xs);
            d.push(ds);
        }
        (x, d)
    }

    #[test]
    fn cached_step_factors_give_the_same_bits() {
        // A timeline like a binned bar's: a few steps repeating (more than the cache probes
        // can hold at one home slot), irregular ones between them, and repeated times.
        let pattern = [7.5, 22.5, 15.25, 14.75, 30.0, 0.0];
        let mut t = vec![0.0];
        for k in 1..5000usize {
            let step = if k % 7 == 0 {
                1.0 + (k as f64 * 0.618).fract() * 40.0
            } else {
                pattern[k % pattern.len()]
            };
            t.push(t[k - 1] + step);
        }
        let u: Vec<f64> = t
            .iter()
            .map(|t| (t / 700.0).sin() + 0.01 * (t / 13.0).cos())
            .collect();
        for tau in [1.0, 900.0, 3000.0, 1e9] {
            let (x, d) = lag(&t, &u, tau, true);
            let (x_ref, d_ref) = lag_uncached(&t, &u, tau);
            let bits = |v: &[f64]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&x), bits(&x_ref), "tau {tau}");
            assert_eq!(bits(&d.unwrap()), bits(&d_ref), "tau {tau}");
            let (x_alone, none) = lag(&t, &u, tau, false);
            assert_eq!(
                bits(&x_alone),
                bits(&x_ref),
                "tau {tau}, without the derivative"
            );
            assert!(none.is_none());
        }
    }

    #[test]
    fn step_response_is_exact_at_any_spacing() {
        // A ramp-free step: u = 0 at t=0, 1 afterwards (sample right after the step at 1e-9 s).
        let mut t = vec![0.0, 1e-9];
        let mut u = vec![0.0, 1.0];
        let mut s = 1e-9;
        for i in 1..200 {
            s += 7.0 + (i % 5) as f64 * 13.0; // irregular spacing
            t.push(s);
            u.push(1.0);
        }
        let tau = 300.0;
        let (x, _) = lag(&t, &u, tau, false);
        for (ti, xi) in t.iter().zip(&x).skip(2) {
            let exact = 1.0 - (-(ti - 1e-9) / tau).exp();
            assert!((xi - exact).abs() < 1e-9, "t={ti} x={xi} exact={exact}");
        }
    }

    #[test]
    fn ramp_response_is_exact() {
        // u = t: x = t - tau (1 - exp(-t/tau)) from equilibrium x(0)=0.
        let t: Vec<f64> = (0..100).map(|i| (i * i) as f64 * 0.5).collect();
        let (x, _) = lag(&t, &t, 250.0, false);
        for (ti, xi) in t.iter().zip(&x) {
            let exact = ti - 250.0 * (1.0 - (-ti / 250.0).exp());
            assert!((xi - exact).abs() < 1e-8 * (1.0 + ti), "{ti}");
        }
    }

    #[test]
    fn derivative_matches_finite_difference() {
        let t: Vec<f64> = (0..300)
            .map(|i| i as f64 * 10.0 + ((i * 7) % 3) as f64)
            .collect();
        let u: Vec<f64> = t
            .iter()
            .map(|t| (t / 500.0).sin() + 0.3 * (t / 77.0).cos())
            .collect();
        let tau: f64 = 420.0;
        let (_, d) = lag(&t, &u, tau, true);
        let h = 1e-6;
        let (xp, _) = lag(&t, &u, (tau.ln() + h).exp(), false);
        let (xm, _) = lag(&t, &u, (tau.ln() - h).exp(), false);
        for k in 0..t.len() {
            let fd = (xp[k] - xm[k]) / (2.0 * h);
            assert!((d.as_ref().unwrap()[k] - fd).abs() < 1e-6, "k={k}");
        }
    }

    #[test]
    fn held_input_switching_between_samples_is_seen() {
        // Samples only while the input is 1; it is 0 between t = 100 and 1000 with no sample.
        let t = [0.0, 50.0, 100.0, 1000.0, 1100.0];
        let (x, d) = held_lag(&t, &[0.0, 100.0, 1000.0], &[1.0, 0.0, 1.0], 300.0, true);
        let off = (-900.0f64 / 300.0).exp(); // state left after 900 s off
        assert!((x[3] - off).abs() < 1e-12, "{x:?}");
        assert!((x[4] - (1.0 - (1.0 - off) * (-100.0f64 / 300.0).exp())).abs() < 1e-12);
        let h = 1e-6;
        let (xp, _) = held_lag(
            &t,
            &[0.0, 100.0, 1000.0],
            &[1.0, 0.0, 1.0],
            (300f64.ln() + h).exp(),
            false,
        );
        let (xm, _) = held_lag(
            &t,
            &[0.0, 100.0, 1000.0],
            &[1.0, 0.0, 1.0],
            (300f64.ln() - h).exp(),
            false,
        );
        for k in 0..t.len() {
            assert!(
                (d.as_ref().unwrap()[k] - (xp[k] - xm[k]) / (2.0 * h)).abs() < 1e-6,
                "k={k}"
            );
        }
    }

    #[test]
    fn zero_phase_lag_keeps_ramps_and_phase_and_cuts_noise() {
        let t: Vec<f64> = (0..20_000).map(|i| i as f64 * 30.0).collect();
        // A ramp comes out unchanged away from the ends (no delay).
        let ramp: Vec<f64> = t.iter().map(|t| 1e-5 * t).collect();
        let x = zero_phase_lag(&t, &ramp, 300.0);
        for k in 200..t.len() - 200 {
            assert!(
                (x[k] - ramp[k]).abs() < 1e-9,
                "k={k}: {} vs {}",
                x[k],
                ramp[k]
            );
        }
        // A daily sinusoid keeps its phase and (almost) its amplitude.
        let w = std::f64::consts::TAU / 86400.0;
        let sine: Vec<f64> = t.iter().map(|t| (w * t).sin()).collect();
        let x = zero_phase_lag(&t, &sine, 300.0);
        let gain = 1.0 / (1.0 + (w * 300.0).powi(2));
        for k in 200..t.len() - 200 {
            assert!((x[k] - gain * sine[k]).abs() < 1e-6, "k={k}");
        }
        // Alternating +-1 (the fastest noise the sampling allows) nearly vanishes.
        let alt: Vec<f64> = (0..t.len())
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let x = zero_phase_lag(&t, &alt, 300.0);
        assert!(x[200..t.len() - 200].iter().all(|v| v.abs() < 0.01));
    }

    #[test]
    fn impulse_derivative_matches_finite_difference() {
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 15.0).collect();
        let ev = [100.0, 1234.5, 2000.0];
        let tau: f64 = 600.0;
        let (x, d) = impulse_lag(&t, &ev, tau, true);
        assert!((x[10] - (-(150.0 - 100.0) / tau).exp()).abs() < 1e-12);
        let h = 1e-6;
        let (xp, _) = impulse_lag(&t, &ev, (tau.ln() + h).exp(), false);
        let (xm, _) = impulse_lag(&t, &ev, (tau.ln() - h).exp(), false);
        for k in 0..t.len() {
            assert!((d.as_ref().unwrap()[k] - (xp[k] - xm[k]) / (2.0 * h)).abs() < 1e-6);
        }
    }
}
