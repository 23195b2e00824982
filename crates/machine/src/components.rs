//! The six component errors of a linear axis and their ISO 230-1 names.
//!
//! `docs/spec/device-format.md`, "Names", and `docs/spec/machine-physics.md`, "Common model": a
//! linear axis J ∈ {X, Y, Z} at coordinate q has translational errors δ_J = (EXJ, EYJ, EZJ) µm
//! and angular errors ε_J = (EAJ, EBJ, ECJ) µrad, right-handed about +X, +Y, +Z of M; a point at
//! offset p (mm) from the reporting point moves by Δ(p) = δ + 10⁻³ ε × p (µm).

/// A linear axis of the machine under test: the one type of the format (`dbbcal-core`), with
/// its ISO 230-1 names, positioning and straightness indices.
pub use dbbcal_core::axis_campaign::{MachineAxis as Axis, UnknownAxis};

/// Six errors (or their uncertainties) of the tool side relative to the workpiece side, in M's
/// axes: translations in µm, rotations in µrad.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SixErrors {
    /// δx, µm.
    pub dx_um: f64,
    /// δy, µm.
    pub dy_um: f64,
    /// δz, µm.
    pub dz_um: f64,
    /// εx, µrad.
    pub ex_urad: f64,
    /// εy, µrad.
    pub ey_urad: f64,
    /// εz, µrad.
    pub ez_urad: f64,
}

impl SixErrors {
    /// From [δx, δy, δz, εx, εy, εz] (µm, µrad).
    pub fn from_array(v: [f64; 6]) -> Self {
        SixErrors {
            dx_um: v[0],
            dy_um: v[1],
            dz_um: v[2],
            ex_urad: v[3],
            ey_urad: v[4],
            ez_urad: v[5],
        }
    }

    /// As [δx, δy, δz, εx, εy, εz] (µm, µrad).
    pub fn to_array(self) -> [f64; 6] {
        [
            self.dx_um,
            self.dy_um,
            self.dz_um,
            self.ex_urad,
            self.ey_urad,
            self.ez_urad,
        ]
    }

    /// δ as a vector, µm.
    pub fn delta_um(self) -> [f64; 3] {
        [self.dx_um, self.dy_um, self.dz_um]
    }

    /// ε as a vector, µrad.
    pub fn epsilon_urad(self) -> [f64; 3] {
        [self.ex_urad, self.ey_urad, self.ez_urad]
    }

    /// The displacement Δ(p) = δ + 10⁻³ ε × p (µm) of a point at offset `p_mm` from the
    /// reporting point (machine-physics.md, "Common model", rigid-body rule).
    pub fn displacement_um(self, p_mm: [f64; 3]) -> [f64; 3] {
        let [ex, ey, ez] = self.epsilon_urad();
        let [px, py, pz] = p_mm;
        [
            self.dx_um + 1e-3 * (ey * pz - ez * py),
            self.dy_um + 1e-3 * (ez * px - ex * pz),
            self.dz_um + 1e-3 * (ex * py - ey * px),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_table() {
        assert_eq!(
            Axis::X.iso230_1_names(),
            ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"]
        );
        assert_eq!(
            Axis::Y.iso230_1_names(),
            ["EXY", "EYY", "EZY", "EAY", "EBY", "ECY"]
        );
        assert_eq!(
            Axis::Z.iso230_1_names(),
            ["EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ"]
        );
        assert_eq!("Y".parse::<Axis>(), Ok(Axis::Y));
        assert!("W".parse::<Axis>().is_err());
    }

    #[test]
    fn the_rigid_body_rule() {
        let e = SixErrors::from_array([1.0, 2.0, 3.0, 10.0, 20.0, 30.0]);
        // 10 µrad about x moves (0, 0, 100 mm) by −1 µm in y.
        let d = e.displacement_um([0.0, 0.0, 100.0]);
        assert_eq!(d, [1.0 + 2.0, 2.0 - 1.0, 3.0]);
        assert_eq!(SixErrors::from_array(e.to_array()), e);
    }
}
