//! Straightness raw and with its least-squares line removed.
//!
//! `docs/spec/device-format.md`, "Straightness line": B's alignment to M is known only to
//! set-up accuracy; a misalignment φ adds φ × (c − c₀), a linear term, to the straightness
//! errors, so straightness is reported both raw and with its least-squares line removed (ISO
//! 230-1). The line is fitted by [`crate::linear`] (parameters `intercept`, `slope`).

use crate::linear::{self, LinearError, LinearProblem};

/// A straightness error along the axis, raw and without its least-squares line.
#[derive(Debug, Clone, PartialEq)]
pub struct Straightness {
    /// Raw values, µm, as given.
    pub raw_um: Vec<f64>,
    /// Values minus the least-squares line, µm.
    pub detrended_um: Vec<f64>,
    /// The line's value at position 0, µm.
    pub intercept_um: f64,
    /// The line's slope, µm/mm (= mrad; × 1000 for µrad).
    pub slope_um_per_mm: f64,
}

impl Straightness {
    /// Range (max − min) of the detrended values, µm.
    pub fn detrended_range_um(&self) -> f64 {
        let max = self
            .detrended_um
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        let min = self
            .detrended_um
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        max - min
    }
}

/// Fit and remove the least-squares line through (position, value). Needs at least two
/// distinct positions; the engine's error otherwise (e.g. rank 1 names what is lost).
pub fn remove_line(
    positions_mm: &[f64],
    values_um: &[f64],
) -> Result<Straightness, StraightnessError> {
    let problem = LinearProblem {
        names: vec!["intercept".into(), "slope".into()],
        rows: positions_mm.iter().map(|&x| vec![1.0, x]).collect(),
        observations: values_um.to_vec(),
        sigma: None,
    };
    let s = linear::solve(&problem)?;
    if !s.full_rank() {
        return Err(StraightnessError::NoLine(
            s.lost
                .iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(", "),
        ));
    }
    Ok(Straightness {
        raw_um: values_um.to_vec(),
        detrended_um: s.residuals.clone(),
        intercept_um: s.estimate[0],
        slope_um_per_mm: s.estimate[1],
    })
}

/// Errors of [`remove_line`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StraightnessError {
    /// The input is empty or ill-shaped.
    #[error(transparent)]
    Linear(#[from] LinearError),
    /// Fewer than two distinct positions: no line.
    #[error("no line through the positions: {0} not determined")]
    NoLine(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_misalignment_is_a_line() {
        let x: Vec<f64> = (0..11).map(|k| -50.0 + 10.0 * k as f64).collect();
        let bow: Vec<f64> = x
            .iter()
            .map(|x| 2.0 * (1.0 - (x / 50.0f64).powi(2)))
            .collect();
        // 20 µrad of misalignment: 0.02 µm/mm.
        let raw: Vec<f64> = x
            .iter()
            .zip(&bow)
            .map(|(x, b)| b + 0.02 * x + 0.5)
            .collect();
        let s = remove_line(&x, &raw).unwrap();
        let again = remove_line(&x, &bow).unwrap();
        for (a, b) in s.detrended_um.iter().zip(&again.detrended_um) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!((s.slope_um_per_mm - 0.02).abs() < 1e-12);
        assert!((s.detrended_range_um() - again.detrended_range_um()).abs() < 1e-12);
        assert_eq!(s.raw_um, raw);
        assert!(matches!(
            remove_line(&[5.0, 5.0], &[1.0, 2.0]),
            Err(StraightnessError::NoLine(_))
        ));
        assert!(matches!(
            remove_line(&[], &[]),
            Err(StraightnessError::Linear(LinearError::NoRows))
        ));
    }
}
