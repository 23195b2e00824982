//! The true, time-invariant mapping counts -> centre distance of a bar at a tilt
//! (`docs/spec/physics.md`, "The instrument": Abbe offset, cosine error, scale nonlinearity, gravity sag),
//! and its inverse, which the simulator uses to turn a distance into counts.
//!
//! With `x = k n` (mm, indicated travel from the counter zero):
//!
//! `D(x, A) = D_zero + (x (1 + s 1e-6) + q 1e-6 x^2) / cos(theta) - sag_um(A, D_zero + x) 1e-3`
//!
//! `sag_um(A, L) = s0 f(A) (L / L_ref)^p`, `f = cos` or `cos^2`. All terms zero gives the ideal
//! `D = D_zero + x` (then the simulator keeps its original exact arithmetic).

use serde::{Deserialize, Serialize};

use super::config::SagForm;

/// A bar's true geometric terms (see the module doc for the formula).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(default)]
pub struct BarGeometry {
    /// Linear scale error `s`, ppm.
    pub(crate) scale_ppm: f64,
    /// Quadratic nonlinearity `q`, ppm per mm of travel.
    pub(crate) nonlinearity_ppm_per_mm: f64,
    /// Scale misalignment `theta`, mrad.
    pub(crate) cosine_mrad: f64,
    /// `D_zero - I_min`, µm (already included in `BarTruth::d_zero_mm`).
    pub(crate) zero_offset_um: f64,
    /// Sag `s0` at horizontal and `L = sag_ref_mm`, µm; positive = the reading is long.
    pub(crate) sag_um: f64,
    pub(crate) sag_form: SagForm,
    pub(crate) sag_ref_mm: f64,
    pub(crate) sag_exponent: f64,
}

/// Newton iterations of the inverse: quadratic convergence from `x = y`, a few suffice.
const MAX_NEWTON: usize = 12;
const NEWTON_TOL_MM: f64 = 1e-13;

impl BarGeometry {
    /// No term at all: `D = D_zero + k n` exactly.
    pub(crate) fn is_ideal(&self) -> bool {
        self.scale_ppm == 0.0
            && self.nonlinearity_ppm_per_mm == 0.0
            && self.cosine_mrad == 0.0
            && self.sag_um == 0.0
    }

    /// Sag at tilt `tilt_deg` and centre distance `length_mm`, µm (reading long by this).
    pub(crate) fn sag_at_um(&self, tilt_deg: f64, length_mm: f64) -> f64 {
        if self.sag_um == 0.0 {
            return 0.0;
        }
        self.sag_um
            * self.sag_form.factor(tilt_deg)
            * (length_mm / self.sag_ref_mm).powf(self.sag_exponent)
    }

    /// `D(x, A) - D_zero`, mm, for the indicated travel `travel_mm = k n`.
    pub(crate) fn true_travel_mm(&self, travel_mm: f64, tilt_deg: f64, d_zero_mm: f64) -> f64 {
        let scale = travel_mm * (1.0 + self.scale_ppm * 1e-6)
            + self.nonlinearity_ppm_per_mm * 1e-6 * travel_mm * travel_mm;
        scale / self.cos_theta() - self.sag_at_um(tilt_deg, d_zero_mm + travel_mm) * 1e-3
    }

    /// The indicated travel `x` (mm) at which `D(x, A) - D_zero = true_travel_mm` (Newton).
    pub(crate) fn indicated_travel_mm(
        &self,
        true_travel_mm: f64,
        tilt_deg: f64,
        d_zero_mm: f64,
    ) -> f64 {
        if self.is_ideal() {
            return true_travel_mm;
        }
        let mut x = true_travel_mm;
        for _ in 0..MAX_NEWTON {
            let f = self.true_travel_mm(x, tilt_deg, d_zero_mm) - true_travel_mm;
            let dx = f / self.slope(x, tilt_deg, d_zero_mm);
            x -= dx;
            if dx.abs() < NEWTON_TOL_MM {
                break;
            }
        }
        x
    }

    /// `dD/dx` at `x`.
    fn slope(&self, x: f64, tilt_deg: f64, d_zero_mm: f64) -> f64 {
        let scale = 1.0 + self.scale_ppm * 1e-6 + 2.0 * self.nonlinearity_ppm_per_mm * 1e-6 * x;
        let length_mm = d_zero_mm + x;
        let sag = if length_mm > 0.0 {
            self.sag_at_um(tilt_deg, length_mm) * 1e-3 * self.sag_exponent / length_mm
        } else {
            0.0
        };
        scale / self.cos_theta() - sag
    }

    fn cos_theta(&self) -> f64 {
        (self.cosine_mrad * 1e-3).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rough() -> BarGeometry {
        BarGeometry {
            scale_ppm: 3.0,
            nonlinearity_ppm_per_mm: 0.01,
            cosine_mrad: 2.0,
            zero_offset_um: 5.0,
            sag_um: 1.0,
            sag_form: SagForm::Cos,
            sag_ref_mm: 400.0,
            sag_exponent: 2.0,
        }
    }

    #[test]
    fn inverse_reproduces_the_forward_map() {
        let g = rough();
        for tilt in [0.0, 30.0, 60.0, 90.0] {
            for y in [0.0, 20.0, 95.0, 170.0] {
                let x = g.indicated_travel_mm(y, tilt, 230.0);
                assert!(
                    (g.true_travel_mm(x, tilt, 230.0) - y).abs() < 1e-12,
                    "tilt {tilt} y {y}"
                );
            }
        }
    }

    #[test]
    fn sag_is_largest_horizontal_and_zero_vertical() {
        let g = rough();
        assert!((g.sag_at_um(0.0, 400.0) - 1.0).abs() < 1e-15);
        assert!((g.sag_at_um(60.0, 400.0) - 0.5).abs() < 1e-12);
        assert!(g.sag_at_um(90.0, 400.0).abs() < 1e-15);
        assert!(
            (g.sag_at_um(0.0, 200.0) - 0.25).abs() < 1e-15,
            "(L / L_ref)^2"
        );
        let cos2 = BarGeometry {
            sag_form: SagForm::Cos2,
            ..g
        };
        assert!((cos2.sag_at_um(60.0, 400.0) - 0.25).abs() < 1e-12);
        // Sag makes the reading long: at a fixed true distance the indicated travel grows.
        let (flat, upright) = (
            g.indicated_travel_mm(170.0, 0.0, 230.0),
            g.indicated_travel_mm(170.0, 90.0, 230.0),
        );
        assert!(
            ((flat - upright) * 1e3 - 1.0).abs() < 0.01,
            "{}",
            (flat - upright) * 1e3
        );
    }

    #[test]
    fn ideal_geometry_is_the_identity() {
        let g = BarGeometry::default();
        assert!(g.is_ideal());
        assert_eq!(g.indicated_travel_mm(123.456, 30.0, 230.0), 123.456);
        assert_eq!(g.true_travel_mm(123.456, 30.0, 230.0), 123.456);
    }
}
