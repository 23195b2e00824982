//! A noise model for the residuals of a thermal fit, so that likelihood-ratio tests see
//! autocorrelated residuals for what they are.
//!
//! The residual is modelled as a slow first-order (AR(1)) wander plus white measurement noise,
//! `r_t = w_t + v_t`, `w_t = φ w_{t−1} + η_t`, `v ~ N(0, σ²)`, `η ~ N(0, λσ²)`: an ARMA(1,1)
//! process, the smallest state-space noise model that holds both a slow wander and sample noise
//! (the system noise plus measurement noise of CTSM-R's stochastic differential equation
//! models). Its exact Gaussian likelihood comes from a scalar Kalman filter, with `σ²`
//! concentrated out and `(φ, λ)` found by nested 1-D Brent searches (argmin).
//!
//! Samples are taken in order as one sequence (gaps between mounts are not modelled).
//! With `λ → 0` the model is white noise and the likelihood the textbook `−n/2 ln(RSS/n)`
//! plus constants, so on white residuals the likelihood-ratio test is the usual one.

use argmin::core::{CostFunction, Executor};
use argmin::solver::brent::BrentOpt;

/// Search range of `log10(1 − φ)`: φ from 0 to 0.99997.
const LOG_ONE_MINUS_PHI: (f64, f64) = (-4.5, 0.0);
/// Search range of `ln λ`, the wander's innovation variance over the white-noise variance.
const LN_LAMBDA: (f64, f64) = (-25.0, 8.0);

/// The maximum-likelihood noise model of one residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NoiseFit {
    /// AR coefficient of the wander, per sample.
    pub(crate) phi: f64,
    /// Innovation variance of the wander over the white-noise variance.
    pub(crate) lambda: f64,
    /// White-noise variance (concentrated), in the residual's unit squared.
    pub(crate) white_variance: f64,
    /// Maximised Gaussian log-likelihood of the residual.
    pub(crate) log_likelihood: f64,
}

/// Fit the AR(1)-plus-white-noise model to residual `r` by maximum likelihood.
pub(crate) fn fit_noise(r: &[f64]) -> NoiseFit {
    let outer = OuterCost { r };
    let best_u = brent_min(outer, LOG_ONE_MINUS_PHI, -2.0);
    let phi = 1.0 - 10f64.powf(best_u);
    let ln_lambda = best_ln_lambda(r, phi);
    let mut fit = kalman_likelihood(r, phi, ln_lambda.exp());
    // λ → 0 is white noise; keep it when it is at least as likely (the searches stop short of
    // the boundary).
    let white = kalman_likelihood(r, 0.0, 0.0);
    if white.log_likelihood >= fit.log_likelihood {
        fit = white;
    }
    fit
}

/// Exact Gaussian log-likelihood of `r` for given `φ`, `λ` (σ² concentrated out).
pub(crate) fn kalman_likelihood(r: &[f64], phi: f64, lambda: f64) -> NoiseFit {
    let n = r.len();
    // Stationary prior of the wander, in units of σ².
    let mut p = if lambda > 0.0 {
        lambda / (1.0 - phi * phi).max(1e-12)
    } else {
        0.0
    };
    let mut w = 0.0;
    let (mut weighted_ss, mut sum_ln_f) = (0.0, 0.0);
    let mut k = 0;
    while k < r.len() {
        let f = p + 1.0;
        let e = r[k] - w;
        weighted_ss += e * e / f;
        let ln_f = f.ln();
        sum_ln_f += ln_f;
        let gain = p / f;
        w += gain * e;
        let p_filtered = p - gain * p;
        // Predict the next sample.
        w *= phi;
        let p_next = phi * phi * p_filtered + lambda;
        k += 1;
        if p_next == p {
            // The Riccati recursion reached its fixed point (to the bit): every later step has
            // the same `f`, `ln f` and gain, so the filter is the linear recursion
            // `w ← a w + b y` (`a = φ (1 − gain)`, `b = φ gain`), taken two samples a step so
            // that the dependency chain is one multiply-add per two samples (the fit of the
            // noise model runs this over every residual some hundreds of times).
            let rest = &r[k..];
            let (a, b) = (phi * (1.0 - gain), phi * gain);
            let (a2, ab) = (a * a, a * b);
            let (mut ss0, mut ss1) = (0.0, 0.0);
            let mut pairs = rest.chunks_exact(2);
            for pair in &mut pairs {
                let (y0, y1) = (pair[0], pair[1]);
                let e0 = y0 - w;
                let e1 = y1 - (a * w + b * y0);
                ss0 += e0 * e0;
                ss1 += e1 * e1;
                w = a2 * w + (ab * y0 + b * y1);
            }
            for &y in pairs.remainder() {
                let e = y - w;
                ss0 += e * e;
                w = a * w + b * y;
            }
            weighted_ss += (ss0 + ss1) / f;
            sum_ln_f += ln_f * rest.len() as f64;
            break;
        }
        p = p_next;
    }
    let nf = n.max(1) as f64;
    let white_variance = weighted_ss / nf;
    let log_likelihood = if white_variance > 0.0 {
        -0.5 * nf * ((2.0 * std::f64::consts::PI * white_variance).ln() + 1.0) - 0.5 * sum_ln_f
    } else {
        f64::INFINITY
    };
    NoiseFit {
        phi,
        lambda,
        white_variance,
        log_likelihood,
    }
}

/// Likelihood-ratio statistic `2 (ℓ₁ − ℓ₀)` of two residuals of the same samples, each under
/// its own maximum-likelihood noise model; 0 when the second is not more likely.
#[cfg(test)]
pub(crate) fn likelihood_ratio(base: &[f64], extended: &[f64]) -> f64 {
    let l0 = fit_noise(base).log_likelihood;
    let l1 = fit_noise(extended).log_likelihood;
    (2.0 * (l1 - l0)).max(0.0)
}

fn best_ln_lambda(r: &[f64], phi: f64) -> f64 {
    brent_min(InnerCost { r, phi }, LN_LAMBDA, -5.0)
}

fn brent_min<C>(cost: C, (lo, hi): (f64, f64), start: f64) -> f64
where
    C: CostFunction<Param = f64, Output = f64>,
{
    // Relative tolerance 1 %: the log-likelihood is flat (quadratic) at its maximum, so the
    // likelihood-ratio statistics move by far less than their own sampling spread.
    let solver = BrentOpt::new(lo, hi).set_tolerance(1e-2, 1e-6);
    Executor::new(cost, solver)
        .configure(|state| state.param(start).max_iters(60))
        .run()
        .ok()
        .and_then(|res| res.state().best_param)
        .unwrap_or(start)
}

/// Negative log-likelihood over `ln λ` at fixed `φ`.
struct InnerCost<'a> {
    r: &'a [f64],
    phi: f64,
}

impl CostFunction for InnerCost<'_> {
    type Param = f64;
    type Output = f64;
    fn cost(&self, ln_lambda: &f64) -> Result<f64, argmin::core::Error> {
        Ok(-kalman_likelihood(self.r, self.phi, ln_lambda.exp()).log_likelihood)
    }
}

/// Negative profile log-likelihood over `u = log10(1 − φ)`.
struct OuterCost<'a> {
    r: &'a [f64],
}

impl CostFunction for OuterCost<'_> {
    type Param = f64;
    type Output = f64;
    fn cost(&self, u: &f64) -> Result<f64, argmin::core::Error> {
        let phi = 1.0 - 10f64.powf(*u);
        let ln_lambda = best_ln_lambda(self.r, phi);
        Ok(-kalman_likelihood(self.r, phi, ln_lambda.exp()).log_likelihood)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn ar1_plus_noise(n: usize, phi: f64, sd_eta: f64, sd_v: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let z = Normal::new(0.0, 1.0).unwrap();
        let mut w = 0.0;
        (0..n)
            .map(|_| {
                w = phi * w + sd_eta * z.sample(&mut rng);
                w + sd_v * z.sample(&mut rng)
            })
            .collect()
    }

    #[test]
    fn white_noise_likelihood_is_the_textbook_one() {
        let r = ar1_plus_noise(5000, 0.0, 0.0, 0.3, 1);
        let fit = fit_noise(&r);
        let n = r.len() as f64;
        let rss = r.iter().map(|v| v * v).sum::<f64>();
        let textbook = -0.5 * n * ((2.0 * std::f64::consts::PI * rss / n).ln() + 1.0);
        assert!(
            (fit.log_likelihood - textbook).abs() < 3.0,
            "{} vs {textbook}",
            fit.log_likelihood
        );
    }

    #[test]
    fn recovers_a_slow_wander_under_white_noise() {
        // φ = 0.995, wander innovations 0.02, white noise 0.05: λ = 0.16.
        let r = ar1_plus_noise(20_000, 0.995, 0.02, 0.05, 2);
        let fit = fit_noise(&r);
        assert!((fit.phi - 0.995).abs() < 0.004, "phi {}", fit.phi);
        assert!(
            (fit.lambda / 0.16).ln().abs() < 0.5,
            "lambda {} against 0.16",
            fit.lambda
        );
        assert!(
            (fit.white_variance.sqrt() / 0.05 - 1.0).abs() < 0.1,
            "white sd {}",
            fit.white_variance.sqrt()
        );
    }

    /// The test's size: a smooth regressor with no effect, fitted by least squares to a residual
    /// that wanders, is found significant at 5 % no more often than 5 % of the time. (Least
    /// squares makes the statistic smaller than the noise model's own generalised least squares
    /// would, so the test is conservative.)
    #[test]
    fn an_irrelevant_smooth_regressor_is_rarely_significant() {
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        let reps = 200;
        let mut rejected = 0;
        for rep in 0..reps {
            let r = ar1_plus_noise(4000, 0.99, 0.05, 0.05, 100 + rep);
            // An unrelated smooth signal: another slow wander, noise-free.
            let x = ar1_plus_noise(4000, 0.998, 1.0, 0.0, 10_000 + rep);
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let (mx, mr) = (mean(&x), mean(&r));
            let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
            let sxr: f64 = x.iter().zip(&r).map(|(a, b)| (a - mx) * (b - mr)).sum();
            let b = sxr / sxx;
            let base: Vec<f64> = r.iter().map(|v| v - mr).collect();
            let extended: Vec<f64> = x.iter().zip(&base).map(|(a, e)| e - b * (a - mx)).collect();
            let lr = likelihood_ratio(&base, &extended);
            if 1.0 - ChiSquared::new(1.0).unwrap().cdf(lr) < 0.05 {
                rejected += 1;
            }
        }
        let rate = rejected as f64 / reps as f64;
        eprintln!("irrelevant smooth regressor: rejected {rate:.3} at 5 %");
        assert!(rate <= 0.07, "rejection rate {rate}");
    }
}
