//! The residuals' autocorrelation and the HAC batch length chosen from it (integrated
//! autocorrelation time, variance-time plateau, batch-edge bias).
//!
//! Separate because it works on a plain residual series, not on a problem: the batch length is
//! also asked for by callers outside the engine ([`hac_batch_length`]).

use super::hac::dot;

/// Batch length for the HAC estimate: ten times the residuals' integrated autocorrelation time
/// (at least `n^(1/3)`), lengthened where the residuals' variance-time curve shows a slow part
/// (`variance_time_plateau`), and no more than `n / 20` so that about twenty batches remain.
pub fn hac_batch_length(residuals: &[f64]) -> usize {
    batch_length_from(residuals, &initial_autocorrelation(residuals))
}

/// [`hac_batch_length`] with the residuals' autocorrelation `acf` given (its initial positive
/// part at least: [`initial_autocorrelation`]).
pub(super) fn batch_length_from(residuals: &[f64], acf: &[f64]) -> usize {
    let n = residuals.len();
    if n < 40 {
        return 1;
    }
    let (tau_int, _) = initial_positive_sums(acf);
    let lower = (n as f64).cbrt();
    let upper = (n / 20) as f64;
    let short = (10.0 * tau_int).max(lower).min(upper).max(1.0).round() as usize;
    variance_time_plateau(residuals, short, n / 20)
}

/// The batch length, from `short` doubling up to `longest`, whose variance-time ratio is largest
/// by its lower three-standard-error bound, if that bound is above the ratio at `short`.
///
/// Why: a slow residual far below the white noise (at 1 Hz, sensor noise carried through the
/// lags: 0.4 nm under 20 nm of reading noise, correlated over an hour) has autocorrelations of
/// 1e-4 a lag, lost in the sample ACF's noise, so [`integrated_autocorrelation_time`] sees white
/// noise and the batches stay short. Yet summed over thousands of lags it carries much of the
/// residual's power at the thermal signal's frequencies, where the estimates take their
/// information: the benchmark's errors were 1.6-1.75 times their u.
///
/// Batch means see it directly: `R(L) = L Var(batch means) / Var(r)` is flat for white
/// residuals and rises towards the integrated autocorrelation time as `L` spans the slow part's
/// correlation time; it falls again once batches span whole mounts, whose zeros were fitted.
/// `R` is estimated from overlapping batch means (Meketon and Schmeiser, 1984), standard error
/// `R √(4 / (3B))` with `B = n / L`, a fifth less than from disjoint batches. A longer batch
/// counts only when `R − 3 se` exceeds `R(short)`: significantly more variance per sample, so
/// white residuals keep the short batch. Among those, the lower bound peaks at the batch that
/// holds the slow part while keeping enough batches.
fn variance_time_plateau(residuals: &[f64], short: usize, longest: usize) -> usize {
    let n = residuals.len();
    let mean = residuals.iter().sum::<f64>() / n as f64;
    let var = residuals.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n as f64;
    if var.is_nan() || var <= 0.0 || short >= longest {
        return short;
    }
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for r in residuals {
        acc += r - mean;
        prefix.push(acc);
    }
    let mut best = (short, f64::NEG_INFINITY);
    let mut short_ratio = None;
    let mut len = short.max(1);
    while len <= longest && len < n {
        let windows = n - len + 1;
        let sum_sq: f64 = (0..windows)
            .map(|i| ((prefix[i + len] - prefix[i]) / len as f64).powi(2))
            .sum();
        let ratio = len as f64 * n as f64 * sum_sq / (windows as f64 * (n - len) as f64) / var;
        let se = ratio * (4.0 / (3.0 * (n / len) as f64)).sqrt();
        let floor = *short_ratio.get_or_insert(ratio);
        if ratio - 3.0 * se > floor.max(best.1) {
            best = (len, ratio - 3.0 * se);
        }
        len *= 2;
    }
    best.0
}

/// Relative downward bias of batch-means variance with batches of `batch_len` samples:
/// `2 Σ k ρ_k / (L (1 + 2 Σ ρ_k))`, sums over the initial positive autocorrelations.
/// `acf`: the residuals' autocorrelation.
pub(super) fn batch_edge_bias(acf: &[f64], batch_len: usize) -> f64 {
    let (tau, first_moment) = initial_positive_sums(acf);
    2.0 * first_moment / (batch_len.max(1) as f64 * tau)
}

/// `(1 + 2 Σ ρ_k, Σ k ρ_k)` over the initial positive autocorrelations `ρ_1, ρ_2, …` of `acf`
/// (summed until the ACF first drops to zero or below: Geyer's initial positive sequence,
/// simplified).
pub(super) fn initial_positive_sums(acf: &[f64]) -> (f64, f64) {
    let (mut tau, mut first_moment) = (1.0, 0.0);
    for (k, rho) in acf.iter().enumerate().skip(1) {
        if *rho <= 0.0 {
            break;
        }
        first_moment += k as f64 * rho;
        tau += 2.0 * rho;
    }
    (tau, first_moment)
}

/// Integrated autocorrelation time `1 + 2 Σ ρ_k`, summed until the ACF first drops below zero
/// (Geyer's initial positive sequence, simplified), in samples.
pub(crate) fn integrated_autocorrelation_time(x: &[f64]) -> f64 {
    initial_positive_sums(&initial_autocorrelation(x)).0
}

/// Lags beyond which [`initial_autocorrelation`] leaves direct sums for the FFT.
pub(super) const DIRECT_ACF_MAX_LAG: usize = 32;

/// The sample autocorrelation of `x` up to and including its first lag at or below zero: all
/// that [`initial_positive_sums`] reads. By direct sums, O(n) a lag: residuals of a fit are
/// mostly a few lags from white, where this costs a few passes instead of two FFTs of twice the
/// series (padded to a power of two). A series still positive at lag
/// [`DIRECT_ACF_MAX_LAG`] gets the FFT's autocorrelation to lag `n/2`. Same estimator as
/// [`autocorrelation`] (biased: sums over `n`), up to rounding.
pub(super) fn initial_autocorrelation(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let centred: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let c0 = dot(&centred, &centred);
    if c0.is_nan() || c0 <= 0.0 {
        return vec![1.0];
    }
    let mut acf = vec![1.0];
    for k in 1..n.min(DIRECT_ACF_MAX_LAG + 1) {
        let rho = dot(&centred[..n - k], &centred[k..]) / c0;
        acf.push(rho);
        if rho <= 0.0 {
            return acf;
        }
    }
    if n <= DIRECT_ACF_MAX_LAG + 1 {
        return acf;
    }
    autocorrelation(x, n / 2)
}

/// Sample autocorrelation for lags `0..=max_lag` (biased estimator, FFT-based).
pub(crate) fn autocorrelation(x: &[f64], max_lag: usize) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let len = (2 * n).next_power_of_two();
    // Plans (twiddle tables) are kept per thread: every fit asks for the autocorrelation of its
    // residual, and planning cost as much as the transform.
    thread_local! {
        static PLANNER: std::cell::RefCell<realfft::RealFftPlanner<f64>> =
            std::cell::RefCell::new(realfft::RealFftPlanner::new());
    }
    let (fwd, inv) = PLANNER.with(|p| {
        let mut p = p.borrow_mut();
        (p.plan_fft_forward(len), p.plan_fft_inverse(len))
    });
    let mut buf = vec![0.0; len];
    for (b, v) in buf.iter_mut().zip(x) {
        *b = v - mean;
    }
    let mut spec = fwd.make_output_vec();
    if fwd.process(&mut buf, &mut spec).is_err() {
        return vec![1.0];
    }
    for c in spec.iter_mut() {
        *c = realfft::num_complex::Complex::new(c.norm_sqr(), 0.0);
    }
    let mut out = inv.make_output_vec();
    if inv.process(&mut spec, &mut out).is_err() {
        return vec![1.0];
    }
    let c0 = out[0];
    if c0 <= 0.0 {
        return vec![1.0];
    }
    out.iter()
        .take(max_lag.min(n - 1) + 1)
        .map(|c| c / c0)
        .collect()
}
