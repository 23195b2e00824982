//! Acceptance of working bars on known lengths: error statistics before and after compensation,
//! an uncertainty budget with expanded uncertainty `U` (k = 2), and a decision against a
//! tolerance by the ISO 14253-1 rule: conformance is proven only when `|error| + U` lies inside
//! the tolerance, non-conformance only when `|error| − U` lies outside; otherwise no decision.
//!
//! Pure computation: no IO.

use crate::calibrate::{u_from_lengths_um, BarCalibration, Form};
use crate::campaign::Campaign;
use crate::compensate::{CompensationMode, WorkingSeries};

/// What acceptance judges against: the tolerance and the temperature uncertainty.
#[derive(Debug, Clone)]
pub struct AcceptanceOptions {
    /// Tolerance on the centre-distance error, ± µm (the patent's ±1 µm by default).
    pub tolerance_um: f64,
    /// Standard uncertainty of the temperature measurement, K.
    pub u_temperature_k: f64,
}

impl Default for AcceptanceOptions {
    fn default() -> Self {
        Self {
            tolerance_um: 1.0,
            u_temperature_k: 0.05,
        }
    }
}

/// The ISO 14253-1 decision on a working bar: its worst error against the tolerance, with U.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Conformance proven: worst error + U is within the tolerance.
    Pass,
    /// Non-conformance proven: worst error − U exceeds the tolerance.
    Fail,
    /// Neither proven (the error is within U of the tolerance, or not finite).
    NoDecision,
}

impl Decision {
    /// The decision as written in `summary.json`: `pass`, `fail` or `no decision`.
    pub fn as_str(self) -> &'static str {
        match self {
            Decision::Pass => "pass",
            Decision::Fail => "fail",
            Decision::NoDecision => "no decision",
        }
    }
}

/// Max |e|, peak-to-valley and RMS of an error series, µm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Largest absolute error, µm.
    pub max_abs_um: f64,
    /// Peak-to-valley, µm.
    pub pv_um: f64,
    /// RMS, µm.
    pub rms_um: f64,
}

impl ErrorStats {
    pub(crate) fn of(e: &[f64]) -> ErrorStats {
        let finite: Vec<f64> = e.iter().copied().filter(|v| v.is_finite()).collect();
        if finite.is_empty() {
            return ErrorStats {
                max_abs_um: f64::NAN,
                pv_um: f64::NAN,
                rms_um: f64::NAN,
            };
        }
        let (lo, hi) = finite
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        ErrorStats {
            max_abs_um: lo.abs().max(hi.abs()),
            pv_um: hi - lo,
            rms_um: (finite.iter().map(|v| v * v).sum::<f64>() / finite.len() as f64).sqrt(),
        }
    }
}

/// One term of the budget: a standard uncertainty (k = 1), µm, and what it is made of.
#[derive(Debug, Clone, PartialEq)]
pub struct BudgetTerm {
    /// Standard uncertainty (k = 1), µm.
    pub u_um: f64,
    /// Which term it is, with the numbers it is made of.
    pub source: BudgetSource,
}

/// What a budget term is, with the numbers it is made of.
#[derive(Debug, Clone, PartialEq)]
pub enum BudgetSource {
    /// The check length's uncertainty and the calibration lengths' propagated through
    /// `D(n, A)`.
    PlateLength {
        /// The check length's standard uncertainty, µm.
        check_u_um: f64,
        /// The calibration lengths' through `D(n, A)`, µm.
        calibration_u_um: f64,
    },
    /// One encoder count, rectangular.
    Resolution {
        /// The count, nm.
        resolution_nm: f64,
    },
    /// The leave-one-point-out RMS of the chosen form of `D(n, A)`.
    CalibrationFunction {
        /// The form.
        form: Form,
    },
    /// The thermal model's residual in the way the mount was compensated.
    ThermalModelResidual {
        /// How the mount was compensated.
        mode: CompensationMode,
    },
    /// The parameters' uncertainties (HAC) times the temperature excursion.
    ThermalModelParameters,
    /// The temperature sensitivity times the temperature measurement's uncertainty.
    TemperatureMeasurement {
        /// Sensitivity of the compensated distance to the temperature, µm/K.
        sensitivity_um_per_k: f64,
        /// Standard uncertainty of the temperature measurement, K.
        u_temperature_k: f64,
    },
}

impl BudgetSource {
    /// The term's name in every output, e.g. `plate_length`.
    pub fn name(&self) -> &'static str {
        match self {
            BudgetSource::PlateLength { .. } => "plate_length",
            BudgetSource::Resolution { .. } => "resolution",
            BudgetSource::CalibrationFunction { .. } => "calibration_function",
            BudgetSource::ThermalModelResidual { .. } => "thermal_model_residual",
            BudgetSource::ThermalModelParameters => "thermal_model_parameters",
            BudgetSource::TemperatureMeasurement { .. } => "temperature_measurement",
        }
    }
}

/// One working bar's acceptance on one known length.
#[derive(Debug, Clone)]
pub struct BarAcceptance {
    /// Working bar id.
    pub bar: String,
    /// The plate length's id.
    pub length_id: String,
    /// The plate length's calibrated centre distance, mm.
    pub length_mm: f64,
    /// How it was compensated: `two_references`, `one_reference` or `model`, with
    /// `+model_difference` when the modelled reference-to-working difference was added.
    pub mode: CompensationMode,
    /// Ids of the reference bars used.
    pub references: Vec<String>,
    /// Samples judged.
    pub n_samples: usize,
    /// Largest absolute error after compensation, µm.
    pub max_abs_error_um: f64,
    /// Peak-to-valley of the error after compensation, µm.
    pub pv_um: f64,
    /// RMS of the error after compensation, µm.
    pub rms_um: f64,
    /// The same statistics before compensation.
    pub before: ErrorStats,
    /// The uncertainty budget, term by term.
    pub budget: Vec<BudgetTerm>,
    /// Combined standard uncertainty (k = 1), µm.
    pub u_c_um: f64,
    /// Expanded uncertainty U (k = 2), µm.
    pub u_k2_um: f64,
    /// The tolerance judged against, ± µm.
    pub tolerance_um: f64,
    /// The ISO 14253-1 decision against the tolerance.
    pub decision: Decision,
    /// Time (s since campaign start) and errors after / before compensation, µm.
    pub t_s: Vec<f64>,
    /// Error after compensation at `t_s`, µm.
    pub error_um: Vec<f64>,
    /// Error before compensation at `t_s`, µm.
    pub error_before_um: Vec<f64>,
}

/// The ISO 14253-1 decision for a worst error `max_abs_um` with expanded uncertainty `u_k2_um`.
pub fn decide(max_abs_um: f64, u_k2_um: f64, tolerance_um: f64) -> Decision {
    if !(max_abs_um.is_finite() && u_k2_um.is_finite()) {
        return Decision::NoDecision;
    }
    if max_abs_um + u_k2_um <= tolerance_um {
        Decision::Pass
    } else if max_abs_um - u_k2_um > tolerance_um {
        Decision::Fail
    } else {
        Decision::NoDecision
    }
}

/// The uncertainty budget (standard uncertainties, k = 1) of a compensated working series.
pub(crate) fn budget(
    w: &WorkingSeries,
    cal: &BarCalibration,
    resolution_nm: f64,
    options: &AcceptanceOptions,
) -> Vec<BudgetTerm> {
    let x_mm = representative_reading_mm(w, cal);
    let u_cal_lengths = u_from_lengths_um(cal, x_mm, w.tilt_deg);
    let term = |u_um: f64, source: BudgetSource| BudgetTerm { u_um, source };
    let sensitivity_um_per_k = w.temperature_sensitivity_um_per_k;
    vec![
        term(
            (w.u_length_um.powi(2) + u_cal_lengths.powi(2)).sqrt(),
            BudgetSource::PlateLength {
                check_u_um: w.u_length_um,
                calibration_u_um: u_cal_lengths,
            },
        ),
        term(
            resolution_nm * 1e-3 / 12f64.sqrt(),
            BudgetSource::Resolution { resolution_nm },
        ),
        term(
            cal.cv_rms_um,
            BudgetSource::CalibrationFunction {
                form: cal.chosen.form,
            },
        ),
        term(
            w.u_thermal_residual_um,
            BudgetSource::ThermalModelResidual { mode: w.mode },
        ),
        term(w.u_thermal_params_um, BudgetSource::ThermalModelParameters),
        term(
            sensitivity_um_per_k * options.u_temperature_k,
            BudgetSource::TemperatureMeasurement {
                sensitivity_um_per_k,
                u_temperature_k: options.u_temperature_k,
            },
        ),
    ]
}

/// Expanded uncertainty U (k = 2), µm, of a working bar's compensated centre distance: the
/// budget of `accept` (calibration lengths, resolution, calibration function, thermal terms),
/// without a check length. What a device's leg takes (`docs/spec/device-format.md`).
pub fn compensated_u_k2_um(
    w: &WorkingSeries,
    cal: &BarCalibration,
    resolution_nm: f64,
    options: &AcceptanceOptions,
) -> f64 {
    2.0 * budget(w, cal, resolution_nm, options)
        .iter()
        .map(|t| t.u_um * t.u_um)
        .sum::<f64>()
        .sqrt()
}

/// A reading (mm) whose calibrated distance is the working distance: invert `D` by fixed point.
fn representative_reading_mm(w: &WorkingSeries, cal: &BarCalibration) -> f64 {
    let target = w.distance_for_weights_mm;
    let mut x = target - cal.chosen.distance_mm(0.0, w.tilt_deg);
    for _ in 0..20 {
        x += target - cal.chosen.distance_mm(x, w.tilt_deg);
    }
    x
}

/// The acceptance stage: accept every compensated working series on a known length whose bar
/// was calibrated (`resolution_nm` from the campaign's bar, 0 for a bar it does not list), in
/// the order of `working`. Nothing without calibrations or working series.
pub fn accept_fleet(
    working: &[WorkingSeries],
    calibrations: &[BarCalibration],
    campaign: &Campaign,
    options: &AcceptanceOptions,
) -> Vec<BarAcceptance> {
    working
        .iter()
        .filter_map(|w| {
            let c = calibrations.iter().find(|c| c.bar == w.bar)?;
            let resolution_nm = campaign.bar(&w.bar).map_or(0.0, |b| b.resolution_nm);
            accept(w, c, resolution_nm, options)
        })
        .collect()
}

/// Accept one working series on a known length.
pub(crate) fn accept(
    w: &WorkingSeries,
    cal: &BarCalibration,
    resolution_nm: f64,
    options: &AcceptanceOptions,
) -> Option<BarAcceptance> {
    let (after, before) = w.errors_um()?;
    let stats = ErrorStats::of(&after);
    let budget = budget(w, cal, resolution_nm, options);
    let u_c_um = budget.iter().map(|t| t.u_um * t.u_um).sum::<f64>().sqrt();
    let u_k2_um = 2.0 * u_c_um;
    Some(BarAcceptance {
        bar: w.bar.clone(),
        length_id: w.length_id.clone()?,
        length_mm: w.length_mm?,
        mode: w.mode,
        references: w.references.iter().map(|r| r.bar.clone()).collect(),
        n_samples: after.len(),
        max_abs_error_um: stats.max_abs_um,
        pv_um: stats.pv_um,
        rms_um: stats.rms_um,
        before: ErrorStats::of(&before),
        decision: decide(stats.max_abs_um, u_k2_um, options.tolerance_um),
        budget,
        u_c_um,
        u_k2_um,
        tolerance_um: options.tolerance_um,
        t_s: w.t_s.clone(),
        error_um: after,
        error_before_um: before,
    })
}

/// The fleet's acceptance at a glance.
#[derive(Debug, Clone)]
pub struct FleetAcceptance {
    /// Bars judged.
    pub n_bars: usize,
    /// Bars proven within tolerance.
    pub n_pass: usize,
    /// Bars proven out of tolerance.
    pub n_fail: usize,
    /// Bars the uncertainty leaves undecided.
    pub n_no_decision: usize,
    /// Largest absolute error after compensation over the fleet, µm.
    pub max_abs_error_um: f64,
    /// The same before compensation, µm.
    pub max_abs_error_before_um: f64,
    /// RMS error after compensation over the fleet, µm.
    pub rms_um: f64,
    /// The same before compensation, µm.
    pub rms_before_um: f64,
    /// Largest expanded uncertainty U (k = 2) of any bar, µm.
    pub max_u_k2_um: f64,
    /// Every compensation mode that ran.
    pub modes: Vec<CompensationMode>,
}

/// Summarise the fleet: counts of decisions, worst errors, RMS over all samples.
pub fn fleet(bars: &[BarAcceptance]) -> FleetAcceptance {
    let count = |d: Decision| bars.iter().filter(|b| b.decision == d).count();
    let all = |f: &dyn Fn(&BarAcceptance) -> &Vec<f64>| {
        ErrorStats::of(
            &bars
                .iter()
                .flat_map(|b| f(b).iter().copied())
                .collect::<Vec<_>>(),
        )
    };
    let after = all(&|b| &b.error_um);
    let before = all(&|b| &b.error_before_um);
    let mut modes: Vec<CompensationMode> = bars.iter().map(|b| b.mode).collect();
    modes.sort_by_key(|m| m.name());
    modes.dedup();
    FleetAcceptance {
        n_bars: bars.len(),
        n_pass: count(Decision::Pass),
        n_fail: count(Decision::Fail),
        n_no_decision: count(Decision::NoDecision),
        max_abs_error_um: after.max_abs_um,
        max_abs_error_before_um: before.max_abs_um,
        rms_um: after.rms_um,
        rms_before_um: before.rms_um,
        max_u_k2_um: bars.iter().map(|b| b.u_k2_um).fold(0.0, f64::max),
        modes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_14253_decisions() {
        assert_eq!(decide(0.3, 0.4, 1.0), Decision::Pass);
        assert_eq!(decide(0.7, 0.4, 1.0), Decision::NoDecision);
        assert_eq!(decide(1.2, 0.4, 1.0), Decision::NoDecision);
        assert_eq!(decide(1.5, 0.4, 1.0), Decision::Fail);
        assert_eq!(decide(f64::NAN, 0.4, 1.0), Decision::NoDecision);
        assert_eq!(Decision::NoDecision.as_str(), "no decision");
    }

    #[test]
    fn error_statistics() {
        let s = ErrorStats::of(&[0.1, -0.3, 0.2, f64::NAN]);
        assert!((s.max_abs_um - 0.3).abs() < 1e-12);
        assert!((s.pv_um - 0.5).abs() < 1e-12);
        assert!((s.rms_um - (0.14f64 / 3.0).sqrt()).abs() < 1e-12);
    }
}
