//! Unit tests of the model terms that do more than one column per effect or share a time
//! constant (`air_gradient`), and of the plate term's input.

use std::collections::BTreeMap;

use super::channels::{Channel, ChannelError};
use super::columns::decay;
use super::identifiable::identifiable_effects;
use super::*;
use crate::campaign::Bar;
use crate::fit::Separable;
use crate::series::BarSeries;
use crate::series::MountSpan;
use crate::signal::lag;
use crate::signal::plate_temperature;

const I_MIN: f64 = 230.0;

/// Three days at 60 s on three one-day plate mounts (I_p 20, 170, 95 mm); T1 (the bar's own
/// sensor) and T2 (above it, a gradient with its own rhythm). `y_um`: the bar seeing
/// `T1 + w (T2 - T1)` through both paths (`docs/spec/physics.md`), noise-free.
fn gradient_bar(w: f64) -> BarSeries {
    let n = 3 * 1440;
    let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 60.0).collect();
    let tau = std::f64::consts::TAU;
    let t1: Vec<f64> = t_s
        .iter()
        .map(|t| 20.3 + 0.5 * (tau * t / 86400.0).sin() + 0.1 * (tau * t / 1500.0).sin())
        .collect();
    let t2: Vec<f64> = t1
        .iter()
        .zip(&t_s)
        .map(|(a, t)| a + 0.3 + 0.2 * (tau * t / 30000.0).cos() + 0.05 * (tau * t / 4000.0).sin())
        .collect();
    let mounts = daily_mounts(0.0, 0.0);
    let seen: Vec<f64> = t1
        .iter()
        .zip(&t2)
        .map(|(a, b)| a + w * (b - a) - 20.0)
        .collect();
    let (lr, _) = lag::lag(&t_s, &seen, 3000.0, false);
    let (ls, _) = lag::lag(&t_s, &seen, 1500.0, false);
    let y_um: Vec<f64> = (0..n)
        .map(|i| {
            let m = (i / 1440).min(2);
            -(2.0 * I_MIN * lr[i] + 0.6 * mounts[m].i_p_mm * ls[i]) * 1e-3 + 0.1 * m as f64
        })
        .collect();
    let bar = Bar {
        id: "G".into(),
        resolution_nm: 1.0,
        fixed_length_mm: I_MIN,
        sensor: Some("T1".into()),
    };
    let mut s = BarSeries::from_vectors(bar, 20.0, t_s, y_um, t1.clone(), mounts);
    s.celsius = BTreeMap::from([("T1".to_string(), t1), ("T2".to_string(), t2)]);
    s.air_sensor_ids = vec!["T1".into(), "T2".into()];
    s
}

fn effects(names: &[&str]) -> Vec<Effect> {
    names.iter().map(|n| Effect::parse(n).unwrap()).collect()
}

#[test]
fn air_gradient_has_two_gains_on_the_base_time_constants() {
    let s = gradient_bar(0.5);
    let p = ThermalProblem::new(&s, &effects(&["fixed_part", "scale", "air_gradient"])).unwrap();
    assert_eq!(
        p.gain_names(),
        [
            "alpha_ppm_per_k",
            INITIAL_FIXED,
            "beta_ppm_per_k",
            INITIAL_SCALE,
            "gradient_fixed_ppm_per_k",
            "gradient_scale_ppm_per_k"
        ]
    );
    assert_eq!(p.nonlinear_names(), ["ln_tau_r_s", "ln_tau_s_s"]);
    assert_eq!(Effect::AirGradient.tau_name(), None);
    assert_eq!(
        Effect::parse("air_gradient").unwrap().name(),
        "air_gradient"
    );

    // The shared time constants move the gradient's columns too: the derivative matches finite
    // differences in every column.
    let theta = [2500f64.ln(), 1800f64.ln()];
    let h = 1e-6;
    for k in 0..2 {
        let d = p.basis_derivative(&theta, k);
        let (mut tp, mut tm) = (theta, theta);
        tp[k] += h;
        tm[k] -= h;
        let fd = (p.basis(&tp) - p.basis(&tm)) / (2.0 * h);
        let scale = fd.amax().max(1e-12);
        assert!((d.clone() - &fd).amax() < 1e-5 * scale, "theta {k}");
        // The gradient column of this path depends on the time constant, the other does not.
        let (own, other) = if k == 0 { (4, 5) } else { (5, 4) };
        assert!(
            d.column(own).amax() > 1e-6 * scale,
            "theta {k}: column {own}"
        );
        assert_eq!(d.column(other).amax(), 0.0, "theta {k}: column {other}");
    }
}

#[test]
fn air_gradient_recovers_the_weight_through_both_paths() {
    let s = gradient_bar(0.5);
    let m =
        crate::identify::identify(&s, &effects(&["fixed_part", "scale", "air_gradient"])).unwrap();
    let v = |n: &str| m.value(n).unwrap();
    assert!(m.rms_um < 1e-5, "rms {}", m.rms_um);
    for (name, truth) in [
        ("alpha_ppm_per_k", 2.0),
        ("beta_ppm_per_k", 0.6),
        ("gradient_fixed_ppm_per_k", 2.0 * 0.5),
        ("gradient_scale_ppm_per_k", 0.6 * 0.5),
        ("tau_r_s", 3000.0),
        ("tau_s_s", 1500.0),
    ] {
        assert!((v(name) - truth).abs() < 1e-3 * truth, "{name} {}", v(name));
    }
}

/// [`gradient_bar`] with a heat source too: a cabinet `C1` whose excess over T1 (on for ten
/// hours a day, its own 40-min rise) reaches the bar through a lag of `tau_h` and acts through
/// both lengths, `-(a_h I_min + b_h I_p) lag(C1 - T1; tau_h)`.
fn heated_bar(a_h: f64, b_h: f64, tau_h: f64) -> BarSeries {
    let mut s = gradient_bar(0.0);
    let on: Vec<f64> = s
        .t_s
        .iter()
        .map(|t| {
            if (t / 3600.0).rem_euclid(24.0) < 10.0 {
                4.0
            } else {
                0.0
            }
        })
        .collect();
    let (excess, _) = lag::lag(&s.t_s, &on, 2400.0, false);
    let (heat, _) = lag::lag(&s.t_s, &excess, tau_h, false);
    let i_p = s.i_p_mm();
    for (i, y) in s.y_um.iter_mut().enumerate() {
        *y -= (a_h * I_MIN + b_h * i_p[i]) * heat[i] * 1e-3;
    }
    let c1: Vec<f64> = s.celsius["T1"]
        .iter()
        .zip(&excess)
        .map(|(a, e)| a + e)
        .collect();
    s.celsius.insert("C1".into(), c1);
    s
}

#[test]
fn heat_acts_through_both_lengths_with_one_time_constant() {
    let s = heated_bar(0.3, 0.2, 3600.0);
    let heat = Effect::parse("heat:C1-T1").unwrap();
    let mut model = base_effects();
    model.push(heat.clone());
    let p = ThermalProblem::new(&s, &model).unwrap();
    assert_eq!(
        &p.gain_names()[4..],
        [
            "heat_C1-T1_fixed_ppm_per_unit",
            "heat_C1-T1_scale_ppm_per_unit"
        ]
    );
    assert_eq!(
        p.nonlinear_names(),
        ["ln_tau_r_s", "ln_tau_s_s", "ln_heat_C1-T1_tau_s"]
    );
    check_derivatives(&p, &[2500f64.ln(), 1800f64.ln(), 3000f64.ln()]);

    let m = crate::identify::identify(&s, &model).unwrap();
    let v = |n: &str| m.value(n).unwrap();
    assert!(m.rms_um < 1e-5, "rms {}", m.rms_um);
    for (name, truth) in [
        ("alpha_ppm_per_k", 2.0),
        ("beta_ppm_per_k", 0.6),
        ("heat_C1-T1_fixed_ppm_per_unit", 0.3),
        ("heat_C1-T1_scale_ppm_per_unit", 0.2),
        ("heat_C1-T1_tau_s", 3600.0),
    ] {
        assert!((v(name) - truth).abs() < 1e-3 * truth, "{name} {}", v(name));
    }
    // A generic lag of the same channel has one gain per bar: it cannot follow a source whose
    // effect changes with I_p from mount to mount.
    let mut lagged = base_effects();
    lagged.push(Effect::parse("lag:C1-T1").unwrap());
    let l = crate::identify::identify(&s, &lagged).unwrap();
    assert!(
        l.rms_um > 100.0 * m.rms_um.max(1e-7),
        "lag rms {}",
        l.rms_um
    );
    // Events carry no temperature: refused with a reason.
    let err = ThermalProblem::new(&s, &effects(&["fixed_part", "heat:event:head_power"]));
    assert!(matches!(
        err,
        Err(ModelError::Channel {
            source: ChannelError::HeatNeedsSampled(_),
            ..
        })
    ));
}

/// `heat:` binds two terms that lag the same input on one time constant: their lag is run once
/// for both, and each column is still that lag times its own scale, bit for bit.
#[test]
fn a_heat_terms_lag_is_computed_once_for_both_lengths() {
    let s = heated_bar(0.3, 0.2, 3600.0);
    let mut model = base_effects();
    model.push(Effect::parse("heat:C1-T1").unwrap());
    let p = ThermalProblem::new(&s, &model).unwrap();
    let pair: Vec<usize> = (0..p.terms.len())
        .filter(|&j| p.lag_group[j].is_some())
        .collect();
    assert_eq!(pair.len(), 2, "groups {:?}", p.lag_group);
    assert_eq!(p.lag_group[pair[0]], Some(pair[0]));
    assert_eq!(p.lag_group[pair[1]], Some(pair[0]));
    let theta = [2500f64.ln(), 1800f64.ln(), 3000f64.ln()];
    let Channel::Sampled(input) = &p.terms[pair[0]].input else {
        panic!("heat's input is sampled");
    };
    let (lag_x, lag_d) = lag::lag(&s.t_s, input, 3000f64.ln().exp(), true);
    let lag_d = lag_d.unwrap();
    for &j in &pair {
        let (x, d) = p.term_column(j, &theta, true);
        let scale = p.terms[j].scale.as_ref().unwrap();
        let bits = |v: &mut dyn Iterator<Item = f64>| v.map(f64::to_bits).collect::<Vec<_>>();
        assert_eq!(
            bits(&mut x.iter().copied()),
            bits(&mut lag_x.iter().zip(scale).map(|(x, s)| x * s))
        );
        assert_eq!(
            bits(&mut d.unwrap().iter().copied()),
            bits(&mut lag_d.iter().zip(scale).map(|(d, s)| d * s))
        );
    }
    assert_eq!(p.lag_memo.filled(), 1);
}

#[test]
fn air_gradient_follows_the_base_paths_present() {
    let s = gradient_bar(0.5);
    let p = ThermalProblem::new(&s, &effects(&["fixed_part", "air_gradient"])).unwrap();
    assert_eq!(
        p.gain_names(),
        ["alpha_ppm_per_k", INITIAL_FIXED, "gradient_fixed_ppm_per_k"]
    );
    assert_eq!(p.nonlinear_names(), ["ln_tau_r_s"]);
    let err = ThermalProblem::new(&s, &effects(&["creep", "air_gradient"]))
        .err()
        .unwrap();
    assert_eq!(
        err,
        ModelError::NoBasePath {
            effect: "air_gradient".into()
        }
    );
    // Without a second air sensor there is no gradient: a typed error, not a panic.
    let mut lone = gradient_bar(0.5);
    lone.celsius.remove("T2");
    lone.air_sensor_ids = vec!["T1".into()];
    assert!(matches!(
        ThermalProblem::new(&lone, &effects(&["fixed_part", "scale", "air_gradient"])),
        Err(ModelError::Channel { .. })
    ));
}

#[test]
fn plate_temperature_is_smoothed_without_delay() {
    // A slow plate (daily swing) read with alternating sensor noise: the noise goes, the swing
    // stays where it was.
    let t: Vec<f64> = (0..4 * 2880).map(|i| i as f64 * 30.0).collect();
    let w = std::f64::consts::TAU / 86400.0;
    let truth: Vec<f64> = t.iter().map(|t| 20.0 + 0.4 * (w * t).sin()).collect();
    let sensor: Vec<f64> = truth
        .iter()
        .enumerate()
        .map(|(k, v)| v + if k % 2 == 0 { 0.01 } else { -0.01 })
        .collect();
    let plate = plate_temperature(&t, &sensor);
    for k in 100..t.len() - 100 {
        assert!((plate[k] - truth[k]).abs() < 2e-4, "k={k}");
    }
    // A gap in the readings is left alone rather than spread.
    let mut gappy = sensor.clone();
    gappy[10] = f64::NAN;
    let out = plate_temperature(&t, &gappy);
    assert!(out[10].is_nan() && out[11] == sensor[11]);
}

fn event(t_s: f64, kind: &str, value: f64) -> (f64, crate::series::Event) {
    (
        t_s,
        crate::series::Event {
            time_ns: 0,
            bar: None,
            kind: crate::series::EventKind::parse(kind),
            value: Some(value),
        },
    )
}

/// Held event inputs start where `docs/spec/campaign-format.md` says: an event marks a change (before the
/// first the state is the other one), a head that logs readings is powered, the plate stands at
/// the mount's tilt; a kind whose values cannot tell "the other state" gets a free level where
/// fitted readings precede its first event.
#[test]
fn held_events_start_from_the_other_state() {
    use channels::{held_event_channel, FreeLevel};
    let mut s = gradient_bar(0.0);
    let (t0, t_f) = (s.t_s[0], s.t_s[s.fit_index[0]]);
    s.events = vec![
        event(t0 + 3600.0, "head_power", 0.0),
        event(t0 + 7200.0, "tilt", 30.0),
        event(t0 + 7200.0, "spindle", 1500.0),
        event(t0 + 9000.0, "spindle", 0.0),
        event(t0 + 7200.0, "speed", 1500.0),
        event(t0 + 9000.0, "speed", 0.0),
        event(t0 + 9900.0, "speed", 3000.0),
        event(t0, "fan", 2.0),
        event(t0 + 9000.0, "fan", 1.0),
        event(t0 + 9900.0, "fan", 3.0),
    ];
    let start = |s: &BarSeries, kind: &str| {
        let (channel, start) = held_event_channel(s, kind).unwrap();
        (channel.level(s.t_s.len()), start)
    };
    // A first "off": powered before it, for a time no event gives (its heat is fitted).
    let (head, head_start) = start(&s, "head_power");
    assert_eq!((head[0], head[59], head[60]), (1.0, 1.0, 0.0));
    assert_eq!(head_start.free_deviation_from_s, Some(t_f));
    assert_eq!(head_start.free_level, None);
    let (tilt, tilt_start) = start(&s, "tilt");
    assert_eq!((tilt[0], tilt[200]), (s.mounts[0].tilt_deg, 30.0));
    assert_eq!(tilt_start, channels::HeldStart::default());
    // Two values: the other one.
    let (spindle, spindle_start) = start(&s, "spindle");
    assert_eq!((spindle[0], spindle[120], spindle[150]), (0.0, 1500.0, 0.0));
    assert_eq!(spindle_start, channels::HeldStart::default());
    // Three values, fitted readings before the first event: a free level until it.
    let (_, speed_start) = start(&s, "speed");
    assert_eq!(
        speed_start.free_level,
        Some(FreeLevel {
            until_s: t0 + 7200.0
        })
    );
    // ... no readings before the first event: nothing to fit, the first value holds.
    let (fan, fan_start) = start(&s, "fan");
    assert_eq!(fan[0], 2.0);
    assert_eq!(fan_start, channels::HeldStart::default());

    // A first "on" with no reading before it: off (and cold) before it.
    s.events = vec![
        event(t0, "head_power", 1.0),
        event(t0 + 3600.0, "head_power", 0.0),
    ];
    let (head, head_start) = start(&s, "head_power");
    assert_eq!((head[0], head[60]), (1.0, 0.0));
    let Channel::Held { values, .. } = held_event_channel(&s, "head_power").unwrap().0 else {
        panic!("held");
    };
    assert_eq!(values, [0.0, 1.0, 0.0]);
    assert_eq!(head_start, channels::HeldStart::default());
    // A first "on" after readings: the head that logged was powered, the event changes nothing.
    s.events = vec![event(t0 + 3600.0, "head_power", 1.0)];
    let (head, head_start) = start(&s, "head_power");
    assert!(head.iter().all(|v| *v == 1.0));
    assert_eq!(head_start.free_deviation_from_s, Some(t_f));
}

/// Held inputs start in steady state at the value before the first event, like the temperature
/// lags: before a first "off" the lag sits at 1, then decays from it.
#[test]
fn held_lag_starts_in_steady_state_at_the_value_before_the_first_event() {
    let mut s = gradient_bar(0.0);
    let t0 = s.t_s[0];
    s.events = vec![event(t0 + 3600.0, "head_power", 0.0)];
    let channel = channels::event_channel(&s, "head_power").unwrap();
    let tau = 900.0;
    let (x, _) = channel.lag(&s.t_s, tau, false);
    for (t, x) in s.t_s.iter().zip(&x) {
        let expected = if *t <= t0 + 3600.0 {
            1.0
        } else {
            (-(t - t0 - 3600.0) / tau).exp()
        };
        assert!((x - expected).abs() < 1e-12, "t {t}: {x} vs {expected}");
    }
}

/// Three one-day calibration mounts at 250, 400 and 325 mm, each from `start_s` after its day's
/// start to `end_trim_s` before its end.
fn daily_mounts(start_s: f64, end_trim_s: f64) -> Vec<MountSpan> {
    [250.0, 400.0, 325.0]
        .iter()
        .enumerate()
        .map(|(k, mm)| {
            let (from_s, to_s) = (
                start_s + k as f64 * 86400.0,
                (k + 1) as f64 * 86400.0 - end_trim_s,
            );
            MountSpan::calibration(k, *mm, I_MIN, from_s, to_s)
        })
        .collect()
}

/// The `tilt_deg` channel holds the last mount's tilt between mounts (the first mount's before
/// it): with every mount at one tilt it is constant (no step at each mount start for a lag of it
/// to mimic settling with, and not offered to the diagnosis); a change of tilt shows where the
/// next mount begins.
#[test]
fn the_tilt_channel_changes_only_where_the_tilt_does() {
    let mut s = gradient_bar(0.0);
    // Handling before the first mount and between the mounts.
    let mut mounts = daily_mounts(1800.0, 1800.0);
    let tilt = |s: &BarSeries| match channels::resolve(s, "tilt_deg").unwrap() {
        channels::Channel::Sampled(v) => v,
        _ => panic!("tilt_deg is sampled"),
    };
    s.mount_of = s
        .t_s
        .iter()
        .map(|&t| {
            mounts
                .iter()
                .position(|m| m.from_s <= t && t < m.to_s)
                .map(|k| k as u32)
        })
        .collect();
    assert!(
        s.mount_of[0].is_none() && s.mount_of[1440].is_none(),
        "handling samples"
    );
    s.mounts = mounts.clone();
    let same = tilt(&s);
    assert!(
        same.iter().all(|&v| v == mounts[0].tilt_deg),
        "one tilt: constant"
    );
    // Constant, it is not offered: its lag is a constant the mount zeros hold.
    let offered = |s: &BarSeries| channels::available(s).contains(&"tilt_deg".to_string());
    assert!(!offered(&s), "{:?}", channels::available(&s));
    mounts[1].tilt_deg = 30.0;
    s.mounts = mounts.clone();
    assert!(offered(&s), "{:?}", channels::available(&s));
    let changed = tilt(&s);
    let first_of_second = s.mount_of.iter().position(|m| *m == Some(1)).unwrap();
    assert_eq!(
        changed[first_of_second - 1],
        mounts[0].tilt_deg,
        "held through handling"
    );
    assert_eq!(changed[first_of_second], 30.0);
    assert_eq!(changed[s.t_s.len() - 1], mounts[2].tilt_deg);
}

/// Three days at 60 s, readings from 0, fitted mounts from 1800 s on; the head powered from the
/// first reading (cold, no event says so), off 3 h a day from `off_at_s`; the reading falls by
/// `amplitude_um` times the head's first-order heat (`tau_s`), noise-free.
fn head_bar(amplitude_um: f64, tau_s: f64, off_at_s: &[f64]) -> BarSeries {
    let n = 3 * 1440;
    let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 60.0).collect();
    let mounts = daily_mounts(1800.0, 600.0);
    let mut switch_s = vec![-1.0];
    let mut values = vec![1.0];
    for &t in off_at_s {
        switch_s.extend([t, t + 3.0 * 3600.0]);
        values.extend([0.0, 1.0]);
    }
    // The head's heat from cold at the first reading.
    let (warm, _) = lag::held_lag(&t_s, &switch_s, &values, tau_s, false);
    let cold: Vec<f64> = warm
        .iter()
        .zip(&t_s)
        .map(|(x, t)| x - (-t / tau_s).exp())
        .collect();
    let y_um = cold.iter().map(|x| -amplitude_um * x).collect();
    let bar = Bar {
        id: "H".into(),
        resolution_nm: 1.0,
        fixed_length_mm: I_MIN,
        sensor: Some("T1".into()),
    };
    let mut s = BarSeries::from_vectors(bar, 20.0, t_s, y_um, vec![20.0; n], mounts);
    s.events = off_at_s
        .iter()
        .flat_map(|&t| {
            [
                event(t, "head_power", 0.0),
                event(t + 3.0 * 3600.0, "head_power", 1.0),
            ]
        })
        .collect();
    s
}

/// The basis of `p` at `theta` against central finite differences in `theta[k]`.
fn check_derivatives(p: &ThermalProblem, theta: &[f64]) {
    for k in 0..theta.len() {
        let d = p.basis_derivative(theta, k);
        let h = 1e-6;
        let mut plus = theta.to_vec();
        plus[k] += h;
        let mut minus = theta.to_vec();
        minus[k] -= h;
        let fd = (p.basis(&plus) - p.basis(&minus)) / (2.0 * h);
        let scale = fd.amax().max(1e-12);
        assert!(
            (&d - &fd).amax() < 1e-6 * scale.max(1.0),
            "theta {k}: {} vs {}",
            d.amax(),
            fd.amax()
        );
    }
}

/// A head powered before its first event ("off") has an unknown heat when the fitted readings
/// begin: a decay column on the head's time constant fits it, with its `ln tau` derivative, and
/// the fit recovers the head's gain and time constant exactly from a cold start no event gives.
#[test]
fn head_heating_fits_the_heat_of_a_head_powered_before_its_first_event() {
    let (amplitude, tau) = (1.3, 700.0);
    let s = head_bar(amplitude, tau, &[30_000.0, 120_000.0, 200_000.0]);
    let p = ThermalProblem::new(&s, &effects(&["head_heating"])).unwrap();
    assert_eq!(p.gain_names(), ["head_growth_um", "head_initial_um"]);
    assert_eq!(p.nonlinear_names(), ["ln_tau_head_s"]);
    // The decay column: 1 up to the first fitted reading (1800 s), then exp(-(t - 1800)/tau).
    let (x, d) = decay(&s.t_s, 1800.0, tau, true);
    let d = d.unwrap();
    for k in 0..s.t_s.len() {
        let r = (s.t_s[k] - 1800.0).max(0.0) / tau;
        // By recursion over the samples (relative drift ~1e-16 a step), cut to exactly 0 below
        // 1e-13 (`model::decay`).
        assert!(
            (x[k] - (-r).exp()).abs() < 1e-12,
            "k={k}: {} vs {}",
            x[k],
            (-r).exp()
        );
        let h = 1e-6;
        let fd = (decay(&s.t_s[k..=k], 1800.0, (tau.ln() + h).exp(), false).0[0]
            - decay(&s.t_s[k..=k], 1800.0, (tau.ln() - h).exp(), false).0[0])
            / (2.0 * h);
        assert!((d[k] - fd).abs() < 1e-8, "k={k}: {} vs {fd}", d[k]);
    }
    check_derivatives(&p, &[tau.ln()]);
    check_derivatives(&p, &[300f64.ln()]);
    let fit = crate::fit::fit(&p, &p.theta0(), &crate::fit::FitOptions::default()).unwrap();
    let value = |name: &str| fit.values[fit.names.iter().position(|n| n == name).unwrap()];
    assert!(
        (value("head_growth_um") - amplitude).abs() < 1e-6,
        "{:?}",
        fit.values
    );
    assert!((value("ln_tau_head_s").exp() / tau - 1.0).abs() < 1e-6);
    // The head's growth at the first fitted reading, beyond the steady state assumed.
    let initial = -amplitude * (-1800.0 / tau).exp();
    assert!((value("head_initial_um") - initial).abs() < 1e-6);
    assert!(fit.rms() < 1e-6);
}

/// A kind with more than two values whose level before the first event is unknown: a free
/// level (the indicator of "before", through the same lag) is fitted beside the gain.
#[test]
fn a_free_level_before_the_first_event_is_fitted() {
    let mut s = head_bar(0.0, 700.0, &[]);
    let (gain, tau, before) = (0.002, 1500.0, 800.0);
    let first_s = 50_000.0;
    let changes = [(first_s, 1500.0), (120_000.0, 0.0), (180_000.0, 3000.0)];
    s.events = changes.iter().map(|&(t, v)| event(t, "speed", v)).collect();
    let mut switch_s = vec![-1.0];
    let mut values = vec![before];
    for (t, v) in changes {
        switch_s.push(t);
        values.push(v);
    }
    let (x, _) = lag::held_lag(&s.t_s, &switch_s, &values, tau, false);
    s.y_um = x.iter().map(|x| gain * x).collect();
    let p = ThermalProblem::new(&s, &effects(&["lag:event:speed"])).unwrap();
    assert_eq!(
        p.gain_names(),
        [
            "lag_event:speed_gain_um_per_unit",
            "lag_event:speed_before_first_event_um"
        ]
    );
    check_derivatives(&p, &[tau.ln()]);
    let fit = crate::fit::fit(&p, &p.theta0(), &crate::fit::FitOptions::default()).unwrap();
    // The channel holds the first value before the first event; the free level adds the rest.
    assert!((fit.values[0] - gain).abs() < 1e-9, "{:?}", fit.values);
    assert!(
        (fit.values[1] - gain * (before - 1500.0)).abs() < 1e-6,
        "{:?}",
        fit.values
    );
    assert!((fit.values[2].exp() / tau - 1.0).abs() < 1e-6);
}

/// [`gradient_bar`] with the bar's lags not in steady state at the first sample: each path's
/// state departs from the air by `delta_k` there (a room that drifted before the logging).
fn bar_out_of_steady_state(delta_k: f64) -> BarSeries {
    let mut s = gradient_bar(0.0);
    let t_ref = s.t_s[s.fit_index[0]];
    for (k, &t) in s.t_s.iter().enumerate() {
        let m = s.mount_of[k].map_or(0, |m| m as usize);
        let i_p = s.mounts[m].i_p_mm;
        let decay = |tau: f64| delta_k * (-(t - t_ref) / tau).exp();
        s.y_um[k] -= (2.0 * I_MIN * decay(3000.0) + 0.6 * i_p * decay(1500.0)) * 1e-3;
    }
    s
}

#[test]
fn initial_state_transients_are_fitted_on_the_base_paths() {
    let s = bar_out_of_steady_state(0.2);
    let p = ThermalProblem::new(&s, &base_effects()).unwrap();
    assert_eq!(
        p.gain_names(),
        [
            "alpha_ppm_per_k",
            INITIAL_FIXED,
            "beta_ppm_per_k",
            INITIAL_SCALE
        ]
    );
    assert_eq!(p.nuisance_gains(), [false, true, false, true]);
    // The transient columns move with their path's time constant: the derivative matches
    // finite differences.
    let theta = [2500f64.ln(), 1800f64.ln()];
    check_derivatives(&p, &theta);
    for k in 0..2 {
        let own = if k == 0 { 1 } else { 3 };
        let d = p.basis_derivative(&theta, k);
        assert!(d.column(own).amax() > 1e-6 * d.amax(), "theta {k}");
    }
    // The fit finds the truth and the departures (alpha and beta times 0.2 K).
    let m = crate::identify::identify(&s, &base_effects()).unwrap();
    assert!(m.rms_um < 1e-5, "rms {}", m.rms_um);
    for (name, truth) in [
        ("alpha_ppm_per_k", 2.0),
        ("beta_ppm_per_k", 0.6),
        ("tau_r_s", 3000.0),
        ("tau_s_s", 1500.0),
    ] {
        let v = m.value(name).unwrap();
        assert!((v - truth).abs() < 1e-3 * truth, "{name} {v}");
    }
    assert!(m.params.iter().all(|p| !p.name.starts_with("initial_")));
    let initial: Vec<(&str, f64)> = m
        .initial_state
        .iter()
        .map(|e| (e.name.as_str(), e.value))
        .collect();
    assert_eq!(initial.len(), 2);
    assert!((initial[0].1 - 2.0 * 0.2).abs() < 1e-3, "{initial:?}");
    assert!((initial[1].1 - 0.6 * 0.2).abs() < 1e-3, "{initial:?}");
}

#[test]
fn one_length_leaves_the_scale_out_and_says_why() {
    let mut s = gradient_bar(0.0);
    for m in &mut s.mounts {
        m.i_p_mm = 95.0;
        m.length_mm = Some(I_MIN + 95.0);
    }
    let p = ThermalProblem::new(&s, &effects(&["fixed_part", "scale", "air_gradient"])).unwrap();
    assert_eq!(
        p.gain_names(),
        ["alpha_ppm_per_k", INITIAL_FIXED, "gradient_fixed_ppm_per_k"]
    );
    assert_eq!(p.tau_names(), ["tau_r_s"]);
    let notes = p.not_identifiable();
    assert_eq!(notes.len(), 1);
    assert_eq!(
        notes[0].params,
        ["beta_ppm_per_k", "tau_s_s", "gradient_scale_ppm_per_k"]
    );
    assert!(
        matches!(notes[0].reason, super::WhyNotIdentifiable::OneLength { .. }),
        "{:?}",
        notes[0].reason
    );
    // The model keeps the effects asked for; the fit has what the data determine.
    let m = crate::identify::identify(&s, &base_effects()).unwrap();
    assert_eq!(m.effects, base_effects());
    assert!(m.param("beta_ppm_per_k").is_none() && m.param("tau_s_s").is_none());
    assert!(m.param("alpha_ppm_per_k").is_some());
    assert_eq!(m.not_identifiable.len(), 1);
    // Two lengths: nothing left out.
    let s = gradient_bar(0.0);
    let (kept, out) = identifiable_effects(&s, &base_effects());
    assert_eq!(kept, base_effects());
    assert!(out.is_empty());
}

#[test]
fn every_effect_name_round_trips_through_parse_name_and_display() {
    let mut names: Vec<String> = CATALOGUE.iter().map(|n| n.to_string()).collect();
    for transform in ["lag", "rate", "level", "heat"] {
        for channel in ["T1", "event:head_power", "t4-t1", "length_mm", "a:b"] {
            names.push(format!("{transform}:{channel}"));
            names.push(format!("{transform}:{channel}@1800"));
            names.push(format!("{transform}:{channel}@0.5"));
        }
    }
    for name in &names {
        let effect = Effect::parse(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(&effect.name(), name);
        assert_eq!(&effect.to_string(), name);
        assert_eq!(Effect::parse(&effect.name()).unwrap(), effect);
    }
    assert_eq!(
        CATALOGUE
            .iter()
            .map(|n| Effect::parse(n).unwrap())
            .filter(|e| matches!(e, Effect::Channel { .. }))
            .count(),
        0
    );
    for bad in [
        "",
        "lag",
        "lag:",
        "lag:T1@",
        "lag:T1@-3",
        "lag:T1@x",
        "warp:T1",
        "Scale",
    ] {
        assert!(Effect::parse(bad).is_err(), "{bad:?} parsed");
    }
}

/// `columns_on(k)` names exactly the columns that move with `θ_k` (the Brent start holds the
/// others fixed through a sweep of `θ_k`): `air_gradient`'s two gains sit on the base paths'
/// time constants, `settling` has a masked column a mount. Also `basis_columns_of` gives those
/// columns as the whole basis has them.
#[test]
fn columns_on_a_time_constant_are_the_columns_that_move_with_it() {
    let s = gradient_bar(0.5);
    let p = ThermalProblem::new(
        &s,
        &effects(&["fixed_part", "scale", "air_gradient", "settling"]),
    )
    .unwrap();
    let theta: Vec<f64> = [2500.0f64, 1800.0, 900.0].iter().map(|t| t.ln()).collect();
    assert_eq!(p.nonlinear_names().len(), theta.len());
    let phi = p.basis(&theta);
    for k in 0..theta.len() {
        let mut moved = theta.clone();
        moved[k] += 0.3;
        let other = p.basis(&moved);
        let changed: Vec<usize> = (0..phi.ncols())
            .filter(|&c| phi.column(c) != other.column(c))
            .collect();
        let named = p.columns_on(k).unwrap();
        assert_eq!(named, changed, "theta {k} ({:?})", p.nonlinear_names()[k]);
        assert_eq!(
            p.basis_columns_of(&moved, &named),
            other.select_columns(&named)
        );
    }
}

/// A time constant at the model's upper limit leaves it and the gains on its columns
/// undetermined (the scale's: `beta`, not the nuisance initial-state gain); at the lower limit
/// only the time constant; one a step inside either limit, nothing.
#[test]
fn time_constants_at_the_model_limit_are_named_with_their_gains() {
    let s = gradient_bar(0.5);
    let p = ThermalProblem::new(&s, &effects(&["fixed_part", "scale"])).unwrap();
    let (lo, hi) = ln_tau_bounds();
    let names = |theta: &[f64]| -> Vec<Vec<String>> {
        super::at_model_limit(&p, theta)
            .into_iter()
            .map(|n| n.params)
            .collect()
    };
    assert_eq!(
        names(&[2500f64.ln(), hi]),
        vec![vec!["beta_ppm_per_k".to_string(), "tau_s_s".to_string()]]
    );
    assert_eq!(
        names(&[hi + 3.0, 1800f64.ln()]),
        vec![vec!["alpha_ppm_per_k".to_string(), "tau_r_s".to_string()]]
    );
    assert_eq!(
        names(&[lo, 1800f64.ln()]),
        vec![vec!["tau_r_s".to_string()]]
    );
    assert!(names(&[hi - 1e-3, lo + 1e-3]).is_empty());
    // Run up to the limit, the lag is the air's integral: the predicted response is undetermined;
    // run down to 1 s, it follows the air whatever the time constant.
    let response = |theta: &[f64]| {
        super::at_model_limit(&p, theta)[0]
            .reason
            .leaves_the_response_undetermined()
    };
    assert!(response(&[2500f64.ln(), hi]));
    assert!(!response(&[lo, 1800f64.ln()]));
    let reason = &super::at_model_limit(&p, &[2500f64.ln(), hi])[0].reason;
    assert_eq!(
        *reason,
        WhyNotIdentifiable::AtModelLimit {
            tau: "tau_s_s".into(),
            limit_s: MAX_TAU_S
        }
    );
}
