//! A machine warming up: its drift levels off towards a steady state
//! (`docs/spec/machine-physics.md`: time constants 10 min–2 h). Shared by the kinds whose loop
//! offers `machine_warm_up` (the device and the axis).
//!
//! Two forms: the device adds the rate's departure J · [τ (1 − e^(−h/τ)) − h] beside a constant
//! rate ([`departure_h`]: the rate falls by J over a few τ); the axis gives its drift the
//! levelling shape D · τ (1 − e^(−h/τ)) ([`levelled_h`]: the rate falls from D to zero). τ is a
//! parameter of the fit, found on [`tau_grid_h`]; the search pays ln n in the BIC.

/// A warm-up's departure from a constant rate, h: τ (1 − e^(−h/τ)) − h (≈ −h²/2τ early on; the
/// drift levels off after a few τ).
pub fn departure_h(hours: f64, tau_h: f64) -> f64 {
    tau_h * (1.0 - (-hours / tau_h).exp()) - hours
}

/// A drift levelling off, in hours of its first rate: τ (1 − e^(−h/τ)) (→ h as τ → ∞).
pub fn levelled_h(hours: f64, tau_h: f64) -> f64 {
    tau_h * (1.0 - (-hours / tau_h).exp())
}

/// Time constants the warm-up's τ is searched over, h: 41 from 0.25 h to 48 h, even in ln τ.
pub fn tau_grid_h() -> Vec<f64> {
    (0..=40)
        .map(|k| 0.25 * (48.0f64 / 0.25).powf(k as f64 / 40.0))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_departure_starts_as_a_parabola_and_ends_as_a_lost_rate() {
        let tau = 2.0;
        let early = departure_h(0.01, tau);
        assert!((early - (-0.01f64.powi(2) / (2.0 * tau))).abs() < 1e-7);
        // After many τ the slope is −1 h/h: the whole rate J is gone.
        let slope = departure_h(40.0, tau) - departure_h(39.0, tau);
        assert!((slope + 1.0).abs() < 1e-6);
    }

    #[test]
    fn the_grid_spans_a_quarter_hour_to_two_days() {
        let g = tau_grid_h();
        assert_eq!(g.len(), 41);
        assert!((g[0] - 0.25).abs() < 1e-12 && (g[40] - 48.0).abs() < 1e-9);
    }
}
