//! The first-order lag of `docs/spec/physics.md` (`x' = (u - x) / tau`), integrated exactly over a fixed
//! step for an input that is linear (first-order hold) or constant over the step.
//!
//! Written independently of any fitting code: the simulator is the "truth".

/// Exact discretisation of `x' = (u - x) / tau` over a step `h`.
///
/// With `e = exp(-h / tau)` and `g = 1 - tau (1 - e) / h`, an input going linearly from `u0` to
/// `u1` gives `x1 = e x0 + (1 - e - g) u0 + g u1` (exact: the solution for a ramp input is
/// `u(t) - s tau + (x0 - u0 + s tau) exp(-t / tau)`, `s` the slope).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FirstOrderLag {
    decay: f64,
    gain_u0: f64,
    gain_u1: f64,
    /// The lagged value.
    pub(crate) state: f64,
}

impl FirstOrderLag {
    /// A lag of time constant `tau_s` on the step `step_s`, starting in equilibrium with `input`.
    pub(crate) fn new(tau_s: f64, step_s: f64, input: f64) -> Self {
        let ratio = step_s / tau_s;
        let decay = (-ratio).exp();
        // 1 - e, accurate for small ratios.
        let one_minus_decay = -(-ratio).exp_m1();
        let g = if ratio < 1e-6 {
            0.5 * ratio
        } else {
            1.0 - one_minus_decay / ratio
        };
        Self {
            decay,
            gain_u0: one_minus_decay - g,
            gain_u1: g,
            state: input,
        }
    }

    /// Advance one step with the input going linearly from `u0` to `u1`.
    #[inline]
    pub(crate) fn step_linear(&mut self, u0: f64, u1: f64) -> f64 {
        self.state = self.decay * self.state + self.gain_u0 * u0 + self.gain_u1 * u1;
        self.state
    }

    /// Advance one step with the input held at `u`.
    #[inline]
    pub(crate) fn step_held(&mut self, u: f64) -> f64 {
        self.step_linear(u, u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_matches_closed_form() {
        let (tau, h) = (900.0, 1.0);
        let mut lag = FirstOrderLag::new(tau, h, 0.0);
        for i in 1..=5000 {
            let x = lag.step_held(1.0);
            let t = i as f64 * h;
            let exact = 1.0 - (-t / tau).exp();
            assert!((x - exact).abs() < 1e-12, "t={t}: {x} vs {exact}");
        }
    }

    #[test]
    fn ramp_response_matches_closed_form() {
        let (tau, h, slope) = (1800.0, 7.0, 1e-3);
        let mut lag = FirstOrderLag::new(tau, h, 0.0);
        for i in 1..=3000 {
            let t = i as f64 * h;
            let x = lag.step_linear(slope * (t - h), slope * t);
            let exact = slope * (t - tau * (1.0 - (-t / tau).exp()));
            assert!((x - exact).abs() < 1e-11, "t={t}: {x} vs {exact}");
        }
    }

    #[test]
    fn equilibrium_is_kept() {
        let mut lag = FirstOrderLag::new(60.0, 1e-9, 3.5);
        assert!((lag.step_held(3.5) - 3.5).abs() < 1e-15);
        let mut lag = FirstOrderLag::new(1e-3, 10.0, 0.0);
        assert!((lag.step_linear(2.0, 2.0) - 2.0).abs() < 1e-15);
    }
}
