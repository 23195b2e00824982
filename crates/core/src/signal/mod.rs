//! Signal processing on sampled series, with no knowledge of bars, campaigns or models: the
//! first-order lag along irregular times (`lag`), the one piecewise-linear interpolator
//! (`interpolate`), and the plate sensor's zero-phase smoothing.
//! A leaf: `series`, `model`, `diagnose` and `matching` use it; it uses none of them.

pub mod interpolate;
pub(crate) mod lag;

/// Time constant of the zero-phase smoothing of the plate sensor, seconds.
pub(crate) const PLATE_SMOOTHING_S: f64 = 300.0;

/// The plate temperature the expansion follows: its sensor smoothed forward and backward with
/// [`PLATE_SMOOTHING_S`] ([`lag::zero_phase_lag`]; `docs/spec/physics.md`, "plate expansion").
///
/// The plate is a massive, slow body (hours), its sensor noisy. Taken raw, the sensor's white
/// noise is an error in the regressor: it biases the expansion gain towards zero, and with it
/// every gain correlated with it (the plate follows the same air as the bar's lags, so alpha and
/// beta take several standard uncertainties of bias). A causal lag would delay the plate by its
/// time constant and is not separable from the bar's own lags; smoothing both ways removes the
/// noise without delay (a daily cycle keeps 99.98 % of its amplitude).
/// A gap in the readings (non-finite values) is left as it is: smoothing would spread it.
pub(crate) fn plate_temperature(t_s: &[f64], sensor_c: &[f64]) -> Vec<f64> {
    if sensor_c.iter().any(|v| !v.is_finite()) {
        return sensor_c.to_vec();
    }
    lag::zero_phase_lag(t_s, sensor_c, PLATE_SMOOTHING_S)
}
