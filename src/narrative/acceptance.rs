//! Acceptance in words: the ISO 14253-1 decision rule as every output prints it, and what each
//! term of an uncertainty budget is made of.

use crate::acceptance::BudgetSource;

/// The ISO 14253-1 decision rule, as printed in every output.
pub(crate) const DECISION_RULE: &str = "ISO 14253-1: pass only when max|error| + U <= tolerance (conformance proven); fail only when max|error| - U > tolerance (non-conformance proven); otherwise no decision. U is the expanded uncertainty (k = 2).";

/// The rule in one short line, for figures.
pub(crate) const DECISION_RULE_SHORT: &str = "ISO 14253-1: pass only if max|e| + U ≤ tolerance, fail only if max|e| − U > tolerance, otherwise no decision.";

/// What a budget term is made of, with its numbers (`acceptance.json`'s `note`).
pub(crate) fn budget_note(source: &BudgetSource) -> String {
    match source {
        BudgetSource::PlateLength {
            check_u_um,
            calibration_u_um,
        } => format!(
            "check length {check_u_um:.3} µm (k=1) and the calibration lengths propagated through D(n, A) ({calibration_u_um:.3} µm)"
        ),
        BudgetSource::Resolution { resolution_nm } => {
            format!("k = {resolution_nm} nm, rectangular")
        }
        BudgetSource::CalibrationFunction { form } => {
            format!("leave-one-point-out RMS of the form {}", form.name())
        }
        BudgetSource::ThermalModelResidual { mode } => format!("mode {mode}"),
        BudgetSource::ThermalModelParameters => {
            "parameter uncertainties (HAC) times the temperature excursion".into()
        }
        BudgetSource::TemperatureMeasurement {
            sensitivity_um_per_k,
            u_temperature_k,
        } => format!("{sensitivity_um_per_k:.3} µm/K × {u_temperature_k} K"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_notes_quote_their_numbers() {
        assert_eq!(
            budget_note(&BudgetSource::PlateLength {
                check_u_um: 0.15,
                calibration_u_um: 0.0123
            }),
            "check length 0.150 µm (k=1) and the calibration lengths propagated through D(n, A) (0.012 µm)"
        );
        assert_eq!(
            budget_note(&BudgetSource::TemperatureMeasurement {
                sensitivity_um_per_k: 0.5,
                u_temperature_k: 0.05
            }),
            "0.500 µm/K × 0.05 K"
        );
        assert_eq!(
            budget_note(&BudgetSource::Resolution { resolution_nm: 5.0 }),
            "k = 5 nm, rectangular"
        );
    }
}
