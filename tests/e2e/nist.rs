//! NIST StRD nonlinear regressions (`../shared/external/nist-strd/`, README there) through the
//! one fitting engine, from both NIST starts, against the certified values.
//!
//! The engine is separable (variable projection), so each model is written as linear
//! coefficients times basis functions of the nonlinear parameters; only the nonlinear part of
//! a NIST start is used (the linear part is solved exactly at every step).

use std::path::PathBuf;

use dbbcal::fit::{fit, FitOptions, Start, Stop};

use crate::support::{BasisFn, ClosedForm};

struct Certified {
    start1: Vec<f64>,
    start2: Vec<f64>,
    value: Vec<f64>,
    sd: Vec<f64>,
    rss: f64,
    x: Vec<f64>,
    y: Vec<f64>,
}

fn nist_dir() -> PathBuf {
    crate::support::root().join("../shared/external/nist-strd")
}

/// Parse a NIST `.dat` file: `bK = start1 start2 certified sd` lines, the certified RSS, and the
/// data block after `Data:` (columns `y x`).
fn load(name: &str) -> Certified {
    let text = std::fs::read_to_string(nist_dir().join(format!("{name}.dat"))).expect("NIST file");
    let mut c = Certified {
        start1: vec![],
        start2: vec![],
        value: vec![],
        sd: vec![],
        rss: f64::NAN,
        x: vec![],
        y: vec![],
    };
    let mut in_data = false;
    for line in text.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        if in_data {
            if f.len() >= 2 {
                c.y.push(f[0].parse().unwrap());
                c.x.push(f[1].parse().unwrap());
            }
            continue;
        }
        if f.first() == Some(&"Data:") && f.get(1) == Some(&"y") {
            in_data = true;
        } else if f.len() == 6 && f[0].starts_with('b') && f[1] == "=" {
            let v: Vec<f64> = f[2..].iter().map(|s| s.parse().unwrap()).collect();
            c.start1.push(v[0]);
            c.start2.push(v[1]);
            c.value.push(v[2]);
            c.sd.push(v[3]);
        } else if line.trim_start().starts_with("Residual Sum of Squares:") {
            c.rss = f.last().unwrap().parse().unwrap();
        }
    }
    c
}

/// Fit `name` from both NIST starts; `linear` and `nonlinear` are the indices of the certified
/// parameters in the engine's order (linear coefficients first, then nonlinear).
fn check(name: &str, linear: &[usize], nonlinear: &[usize], basis: BasisFn) {
    let c = load(name);
    for (label, start) in [("start 1", &c.start1), ("start 2", &c.start2)] {
        let problem = ClosedForm {
            x: c.x.clone(),
            y: c.y.clone(),
            n_nonlinear: nonlinear.len(),
            n_linear: linear.len(),
            basis,
        };
        let theta0: Vec<f64> = nonlinear.iter().map(|&i| start[i]).collect();
        let options = FitOptions {
            start: Start::Given,
            hac_batch_len: Some(1),
            absorbed_params: 0,
            // The certified digits, not the statistical resolution.
            stop: Stop::Numerical,
        };
        let f = fit(&problem, &theta0, &options).unwrap_or_else(|e| panic!("{name} {label}: {e}"));
        let order: Vec<usize> = linear.iter().chain(nonlinear).copied().collect();
        for (slot, &b) in order.iter().enumerate() {
            let rel = (f.values[slot] - c.value[b]).abs() / c.value[b].abs();
            assert!(
                rel < 1e-6,
                "{name} {label}: b{} = {:.10e}, certified {:.10e} (rel {rel:.1e})",
                b + 1,
                f.values[slot],
                c.value[b]
            );
            let rel_sd = (f.se_naive(slot) - c.sd[b]).abs() / c.sd[b];
            assert!(
                rel_sd < 1e-4,
                "{name} {label}: sd(b{}) = {:.6e}, certified {:.6e}",
                b + 1,
                f.se_naive(slot),
                c.sd[b]
            );
        }
        let rel_rss = (f.rss - c.rss).abs() / c.rss;
        assert!(
            rel_rss < 1e-8,
            "{name} {label}: RSS {:.10e} vs certified {:.10e}",
            f.rss,
            c.rss
        );
    }
}

#[test]
fn misra1a_first_order_step() {
    check("Misra1a", &[0], &[1], |x, t| vec![1.0 - (-t[0] * x).exp()]);
}

#[test]
fn boxbod_first_order_step_higher_difficulty() {
    check("BoxBOD", &[0], &[1], |x, t| vec![1.0 - (-t[0] * x).exp()]);
}

#[test]
fn misra1b() {
    check("Misra1b", &[0], &[1], |x, t| {
        vec![1.0 - (1.0 + t[0] * x / 2.0).powi(-2)]
    });
}

#[test]
fn misra1c_and_misra1d() {
    check("Misra1c", &[0], &[1], |x, t| {
        vec![1.0 - (1.0 + 2.0 * t[0] * x).powf(-0.5)]
    });
    check("Misra1d", &[0], &[1], |x, t| {
        vec![t[0] * x / (1.0 + t[0] * x)]
    });
}

#[test]
fn danwood_and_rat42() {
    check("DanWood", &[0], &[1], |x, t| vec![x.powf(t[0])]);
    check("Rat42", &[0], &[1, 2], |x, t| {
        vec![1.0 / (1.0 + (t[0] - t[1] * x).exp())]
    });
}

#[test]
fn lanczos3_three_exponentials() {
    check("Lanczos3", &[0, 2, 4], &[1, 3, 5], |x, t| {
        vec![(-t[0] * x).exp(), (-t[1] * x).exp(), (-t[2] * x).exp()]
    });
}
