//! Residual statistics: how far from white noise a fit's residual is.
//!
//! Fit % is MATLAB `compare`'s normalised RMSE fit; the whiteness test is Ljung-Box on the
//! residual autocorrelation (as in System Identification's `resid`); the cumulative periodogram
//! with its Kolmogorov-Smirnov band is Box & Jenkins' test for periodic structure.

use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::fit::autocorrelation;

#[derive(Debug, Clone, PartialEq)]
pub struct ResidualStats {
    pub rms_um: f64,
    pub peak_to_valley_um: f64,
    /// `100 (1 - ‖y - ŷ‖ / ‖y - ȳ‖)`.
    pub fit_percent: f64,
    /// Autocorrelation at lags `0..=acf.len()-1` (in samples).
    pub acf: Vec<f64>,
    /// 95 % band for a white residual: `±1.96/√n`.
    pub(crate) acf_band: f64,
    pub ljung_box_q: f64,
    pub ljung_box_lags: usize,
    pub(crate) ljung_box_dof: usize,
    /// p-value of the Ljung-Box test (small = not white).
    pub(crate) whiteness_p: f64,
    /// Integrated autocorrelation time, samples.
    pub correlation_time_samples: f64,
    /// Cumulative periodogram (thinned to ≤ 512 points) at `periodogram_freq_per_sample`.
    pub cumulative_periodogram: Vec<f64>,
    /// Frequencies of `cumulative_periodogram`, cycles per sample (`k / n`).
    pub periodogram_freq_per_sample: Vec<f64>,
    /// 95 % Kolmogorov band half-width around the white-noise diagonal.
    pub(crate) periodogram_band: f64,
}

/// Statistics of residual `r` of a fit to `y` with `n_params` parameters.
pub(crate) fn residual_stats(y: &[f64], r: &[f64], n_params: usize) -> ResidualStats {
    let n = r.len().max(1);
    let rms_um = (r.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let (lo, hi) = r
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    let mean_y = y.iter().sum::<f64>() / y.len().max(1) as f64;
    let norm_dev = y.iter().map(|v| (v - mean_y).powi(2)).sum::<f64>().sqrt();
    let norm_r = r.iter().map(|v| v * v).sum::<f64>().sqrt();
    let fit_percent = if norm_dev > 0.0 {
        100.0 * (1.0 - norm_r / norm_dev)
    } else {
        f64::NAN
    };
    let lags = 20.min(n / 4).max(1);
    let acf = autocorrelation(r, 200.min(n.saturating_sub(1)));
    let q: f64 = (1..=lags.min(acf.len().saturating_sub(1)))
        .map(|k| acf[k] * acf[k] / (n - k) as f64)
        .sum::<f64>()
        * (n as f64)
        * (n as f64 + 2.0);
    let dof = lags.saturating_sub(n_params.min(lags - 1)).max(1);
    let whiteness_p = ChiSquared::new(dof as f64)
        .map(|d| 1.0 - d.cdf(q))
        .unwrap_or(f64::NAN);
    let (cumulative_periodogram, periodogram_freq_per_sample, periodogram_band) =
        cumulative_periodogram(r);
    ResidualStats {
        rms_um,
        peak_to_valley_um: if hi >= lo { hi - lo } else { 0.0 },
        fit_percent,
        acf_band: 1.96 / (n as f64).sqrt(),
        acf,
        ljung_box_q: q,
        ljung_box_lags: lags,
        ljung_box_dof: dof,
        whiteness_p,
        correlation_time_samples: crate::fit::integrated_autocorrelation_time(r),
        cumulative_periodogram,
        periodogram_freq_per_sample,
        periodogram_band,
    }
}

/// Normalised cumulative periodogram (thinned to at most 512 points), its frequencies (cycles
/// per sample) and the 95 % KS band.
fn cumulative_periodogram(r: &[f64]) -> (Vec<f64>, Vec<f64>, f64) {
    let n = r.len();
    if n < 4 {
        return (Vec::new(), Vec::new(), f64::NAN);
    }
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mean = r.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<f64> = r.iter().map(|v| v - mean).collect();
    let mut spec = fft.make_output_vec();
    if fft.process(&mut buf, &mut spec).is_err() {
        return (Vec::new(), Vec::new(), f64::NAN);
    }
    let power: Vec<f64> = spec
        .iter()
        .skip(1)
        .take(n / 2)
        .map(|c| c.norm_sqr())
        .collect();
    let total: f64 = power.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return (Vec::new(), Vec::new(), f64::NAN);
    }
    let mut acc = 0.0;
    let cum: Vec<f64> = power
        .iter()
        .map(|p| {
            acc += p;
            acc / total
        })
        .collect();
    let stride = cum.len().div_ceil(512).max(1);
    let thinned = cum.iter().step_by(stride).copied().collect();
    let freqs = (0..cum.len())
        .step_by(stride)
        .map(|k| (k + 1) as f64 / n as f64)
        .collect();
    (
        thinned,
        freqs,
        1.36 / ((power.len() as f64 - 1.0).max(1.0)).sqrt(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                // Sum of uniforms: close enough to Gaussian for a whiteness test.
                (0..12)
                    .map(|_| {
                        s = s
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        (s >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum::<f64>()
                    - 6.0
            })
            .collect()
    }

    #[test]
    fn white_noise_passes_and_a_sine_fails() {
        let r = noise(5000, 7);
        let st = residual_stats(&r, &r, 0);
        assert!(
            st.whiteness_p > 0.01,
            "white noise rejected: p = {}",
            st.whiteness_p
        );
        let sine: Vec<f64> = r
            .iter()
            .enumerate()
            .map(|(i, v)| v * 0.1 + (i as f64 / 50.0).sin())
            .collect();
        let st = residual_stats(&sine, &sine, 0);
        assert!(st.whiteness_p < 1e-6);
        assert!(st.correlation_time_samples > 10.0);
    }

    #[test]
    fn fit_percent_is_100_for_a_perfect_fit_and_0_for_the_mean() {
        let y = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
        assert!((residual_stats(&y, &[0.0; 8], 1).fit_percent - 100.0).abs() < 1e-12);
        let r: Vec<f64> = y.iter().map(|v| v - 4.5).collect();
        assert!(residual_stats(&y, &r, 1).fit_percent.abs() < 1e-12);
    }
}
