//! A station's mean reading per probe and its standard uncertainty (`docs/spec/machine-physics.md`,
//! "Kind roll"; the seed samples at 20 Hz).
//!
//! **Type A of a mean of correlated samples** *(ours)*. Samples 50 ms apart are not independent
//! (probe electronics, stage settling, floor vibration), so s/√N would understate the
//! uncertainty of their mean. The variance of the mean is s² τ / N with the integrated
//! autocorrelation time τ = 1 + 2 Σ_{k=1}^{K} ρ̂_k, the sample autocorrelations summed from lag 1
//! while they are significantly positive (ρ̂_k > 2/√N); τ is at least 1 (negative correlations are
//! not credited). White noise gives τ = 1 in about 98 % of dwells; a strongly correlated noise is
//! somewhat understated by the truncation (AR(1) with ρ = 0.8 and N = 100: about 10 % in u),
//! which the passes' scatter (the Birge ratio of the global fit) then shows.
//!
//! **Resolution** *(ours)*. A probe read with resolution q (the seed's 1 µm) gives the same value
//! at every sample of a steady dwell: s = 0, while the mean is uncertain by the rounding,
//! q/√12 (0.289 µm for 1 µm), which averaging does not reduce. So u² = s² τ / N + q²/12. q is the
//! pipeline's `resolution_um`, else the grid the readings lie on ([`detect_resolution`]).
//!
//! A floor of [`U_FLOOR_UM`] keeps noise-free readings usable as weights.

/// The smallest standard uncertainty of a station mean, µm (noise-free, continuous readings).
pub const U_FLOOR_UM: f64 = 1e-6;

/// The mean of `values` and its Type A standard uncertainty with τ (module documentation):
/// (mean, u_A, τ). Fewer than 2 values: u_A = 0.
pub fn mean_type_a(values: &[f64]) -> (f64, f64, f64) {
    let n = values.len();
    if n == 0 {
        return (f64::NAN, f64::NAN, 1.0);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, 0.0, 1.0);
    }
    let dev: Vec<f64> = values.iter().map(|v| v - mean).collect();
    let c0 = dev.iter().map(|d| d * d).sum::<f64>() / n as f64;
    let s2 = c0 * n as f64 / (n - 1) as f64;
    if c0 <= 0.0 {
        return (mean, 0.0, 1.0);
    }
    let threshold = 2.0 / (n as f64).sqrt();
    let mut tau = 1.0;
    for k in 1..n / 2 {
        let ck = dev[..n - k]
            .iter()
            .zip(&dev[k..])
            .map(|(a, b)| a * b)
            .sum::<f64>()
            / n as f64;
        let rho = ck / c0;
        if rho <= threshold {
            break;
        }
        tau += 2.0 * rho;
    }
    let tau: f64 = tau.max(1.0);
    (mean, (s2 * tau / n as f64).sqrt(), tau)
}

/// The grid step the readings lie on, µm, if they are visibly quantised: at most half as many
/// distinct values as readings, every value within 1e-3 of a step of a multiple of q, q the
/// smallest gap between distinct values divided by 1 … 10 (the largest that fits). `None`: continuous readings.
pub fn detect_resolution(values_um: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values_um
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * a.abs().max(1.0));
    if v.len() < 2 || 2 * v.len() > values_um.len() {
        return None;
    }
    let gap = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if gap <= 0.0 || !gap.is_finite() {
        return None;
    }
    // The smallest gap may span several steps (few distinct values): the largest q = gap/k,
    // k = 1 … 10, on whose grid every value lies.
    (1..=10).map(|k| gap / f64::from(k)).find(|&q| {
        v.iter().all(|x| {
            let k = (x - v[0]) / q;
            (k - k.round()).abs() < 1e-3
        })
    })
}

/// A station mean of one probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeMean {
    /// Mean reading, µm.
    pub mean_um: f64,
    /// Its standard uncertainty, µm: Type A with τ, resolution and floor combined.
    pub u_um: f64,
    /// The Type A part alone, µm.
    pub u_a_um: f64,
    /// τ of the Type A part.
    pub tau: f64,
}

/// The station mean of `values_um` with resolution `resolution_um` (0: none).
pub fn probe_mean(values_um: &[f64], resolution_um: f64) -> ProbeMean {
    let (mean_um, u_a_um, tau) = mean_type_a(values_um);
    let u_res = resolution_um / 12f64.sqrt();
    ProbeMean {
        mean_um,
        u_um: (u_a_um * u_a_um + u_res * u_res).sqrt().max(U_FLOOR_UM),
        u_a_um,
        tau,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn white_noise_gives_s_over_root_n_and_correlated_noise_more() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let n = 400;
        let (mut ratio_white, mut ratio_ar) = (0.0, 0.0);
        let trials = 200;
        for _ in 0..trials {
            let white: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
            let (_, u, _) = mean_type_a(&white);
            ratio_white += u / (1.0 / (n as f64).sqrt());
            let mut x = 0.0;
            let ar: Vec<f64> = (0..n)
                .map(|_| {
                    x = 0.8 * x + 0.6 * normal.sample(&mut rng);
                    x
                })
                .collect();
            // True u of the mean of AR(1), ρ = 0.8, unit variance: √(τ/N), τ = (1+ρ)/(1−ρ) = 9.
            let (_, u, tau) = mean_type_a(&ar);
            assert!(tau > 3.0, "τ = {tau}");
            ratio_ar += u / (9.0 / n as f64).sqrt();
        }
        let (white, ar) = (ratio_white / trials as f64, ratio_ar / trials as f64);
        assert!((white - 1.0).abs() < 0.03, "white: {white}");
        assert!(ar > 0.8 && ar < 1.05, "AR(1): {ar}");
    }

    #[test]
    fn a_quantised_steady_dwell_is_uncertain_by_q_over_root_12() {
        let values = vec![3.0; 100];
        let m = probe_mean(&values, 1.0);
        assert_eq!(m.u_a_um, 0.0);
        assert!((m.u_um - 0.288_675).abs() < 1e-6);
        let mut readings: Vec<f64> = (0..60).map(|i| f64::from(i % 3) - 7.0).collect();
        readings.extend(vec![12.0; 40]);
        assert_eq!(detect_resolution(&readings), Some(1.0));
        let volts: Vec<f64> = (0..50).map(|i| f64::from(i % 5) * 0.1 * -10.0).collect();
        assert!((detect_resolution(&volts).unwrap() - 1.0).abs() < 1e-9);
        let continuous: Vec<f64> = (0..50).map(|i| (f64::from(i) * 0.37).sin()).collect();
        assert_eq!(detect_resolution(&continuous), None);
        // Few distinct values whose smallest gap is two steps.
        let sparse: Vec<f64> = [0.0, 2.0, 5.0, 9.0]
            .iter()
            .flat_map(|&v| vec![v; 10])
            .collect();
        assert_eq!(detect_resolution(&sparse), Some(1.0));
    }
}
