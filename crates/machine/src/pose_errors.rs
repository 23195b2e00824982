//! The errors of the machine under test from the device's poses: the commanded pose from the
//! datum, the six errors (measured − commanded) in M's axes, their forward model, the axis that
//! moved, and the uncertainty of the errors from the legs and joints.
//!
//! Sources: `docs/spec/device-format.md`, "Conventions": **Commanded pose** (R_cmd = R₀,
//! t_cmd = t₀ + R_MBᵀ (c − c₀)); **Errors** (δ = 1000 · R_MB [(t + R r) − (t_cmd + R_cmd r)] µm,
//! ε = 10⁶ · R_MB ε_B µrad, ε_B the rotation vector of R · R_cmdᵀ); **Names**. The forward
//! model is `docs/spec/machine-physics.md`, "Hexapod": R = (I + \[10⁻⁶ ε\]×) R_cmd,
//! t = t_cmd + R_cmd r + 10⁻³ δ − R r with (δ, ε) in B's axes; here with the exact rotation
//! exp(\[10⁻⁶ ε\]×), so that [`Hexapod::pose_errors`] inverts [`Hexapod::apply_errors`] exactly
//! (the two differ by second-order terms, < 2 nm at 300 mm for |ε| ≤ 1e-4 rad).
//!
//! Uncertainty *(ours, first order)*, in µm and µrad: a leg error dl moves the pose by J⁻¹ dl
//! (J in µm per µm and µrad, [`Hexapod::jacobian_um_urad`]); a joint error moves it by
//! −J⁻¹ G dj with ∂l_i/∂b_i = −n_i and ∂l_i/∂p_i = Rᵀ n_i (p_i in P). For one measured pose
//! ([`Hexapod::pose_covariance`]) both are independent per leg, Σ_i = σ_leg,i² + u_b,i² +
//! u_p,i² (n_i and Rᵀ n_i are unit vectors). For an error (a station against the datum,
//! [`Hexapod::error_uncertainty`]) the leg readings of the two dwells are independent, while
//! the joints are the same at both, so they enter through J_s⁻¹ G_s − J₀⁻¹ G₀: zero at the
//! datum, growing with the displacement (machine-physics.md: "constant leg or joint errors
//! cancel at the datum except through the change of J⁻¹").

use crate::components::{Axis, SixErrors};
use crate::hexapod::{Hexapod, HexapodError};
use crate::pose::{rotation_from_vector, rotation_vector, Pose};
use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3};

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

/// The one linear axis whose commanded coordinate differs from the datum's by more than
/// `tolerance_mm` (ISO 230-1 names apply only then); `None` when none or several moved.
pub fn moved_axis(datum_mm: [f64; 3], position_mm: [f64; 3], tolerance_mm: f64) -> Option<Axis> {
    let moved: Vec<usize> = (0..3)
        .filter(|&k| (position_mm[k] - datum_mm[k]).abs() > tolerance_mm)
        .collect();
    match moved.as_slice() {
        [0] => Some(Axis::X),
        [1] => Some(Axis::Y),
        [2] => Some(Axis::Z),
        _ => None,
    }
}

/// The one linear axis a test moves: the only coordinate that varies over the commanded
/// positions by more than `tolerance_mm` (device-format.md, "Names": 1 µm, 1e-3 mm).
pub fn axis_of_test(positions_mm: &[[f64; 3]], tolerance_mm: f64) -> Option<Axis> {
    let first = *positions_mm.first()?;
    let varies: Vec<usize> = (0..3)
        .filter(|&k| {
            positions_mm
                .iter()
                .any(|p| (p[k] - first[k]).abs() > tolerance_mm)
        })
        .collect();
    match varies.as_slice() {
        [k] => Some([Axis::X, Axis::Y, Axis::Z][*k]),
        _ => None,
    }
}

impl Hexapod {
    /// The commanded pose at commanded machine coordinates `position_mm`, from the measured
    /// pose at the datum and the datum's coordinates: R_cmd = R₀, t_cmd = t₀ + R_MBᵀ (c − c₀).
    pub fn commanded_pose(
        &self,
        datum_pose: &Pose,
        datum_position_mm: [f64; 3],
        position_mm: [f64; 3],
    ) -> Pose {
        let dc = v3(position_mm) - v3(datum_position_mm);
        let t = datum_pose.translation_mm() + self.base_orientation().transpose() * dc;
        Pose::from_parts(&t, &datum_pose.rotation())
    }

    /// The six errors (measured − commanded) at the tool point, in M's axes: δ µm, ε µrad.
    pub fn pose_errors(&self, measured: &Pose, commanded: &Pose) -> SixErrors {
        let r_mb = self.base_orientation();
        let r = v3(self.tool_point_mm);
        let (t, rot) = (measured.translation_mm(), measured.rotation());
        let (tc, rc) = (commanded.translation_mm(), commanded.rotation());
        let delta = 1e3 * r_mb * ((t + rot * r) - (tc + rc * r));
        let eps = 1e6 * r_mb * rotation_vector(&(rot * rc.transpose()));
        SixErrors::from_array([delta.x, delta.y, delta.z, eps.x, eps.y, eps.z])
    }

    /// The pose that errors (in M's axes, µm and µrad, at the tool point) make of a commanded
    /// pose: the forward model of machine-physics.md "Hexapod" (exact rotation).
    pub fn apply_errors(&self, commanded: &Pose, errors: &SixErrors) -> Pose {
        let r_bm = self.base_orientation().transpose();
        let r = v3(self.tool_point_mm);
        let delta_b = r_bm * v3(errors.delta_um());
        let eps_b = r_bm * v3(errors.epsilon_urad());
        let rc = commanded.rotation();
        let rot = rotation_from_vector(&(1e-6 * eps_b)) * rc;
        let t = commanded.translation_mm() + rc * r + 1e-3 * delta_b - rot * r;
        Pose::from_parts(&t, &rot)
    }

    fn inverse_jacobian(&self, pose: &Pose) -> Result<Matrix6<f64>, HexapodError> {
        self.jacobian_um_urad(pose)
            .try_inverse()
            .ok_or(HexapodError::NearSingular {
                pose: *pose,
                condition: f64::INFINITY,
                threshold: crate::hexapod::DEFAULT_MAX_CONDITION,
            })
    }

    /// ∂l/∂(joints), 6 × 36 (µm per µm): leg i, base joint i (3) then platform joint i (3).
    fn joint_derivative(&self, pose: &Pose) -> DMatrix<f64> {
        let rot = pose.rotation();
        let mut g = DMatrix::zeros(6, 36);
        for (i, v) in self.leg_vectors_mm(pose).iter().enumerate() {
            let n = v / v.norm();
            let np = rot.transpose() * n;
            for k in 0..3 {
                g[(i, 6 * i + k)] = -n[k];
                g[(i, 6 * i + 3 + k)] = np[k];
            }
        }
        g
    }

    fn joint_variances_um2(&self) -> DMatrix<f64> {
        DMatrix::from_diagonal(&nalgebra::DVector::from_fn(36, |c, _| {
            let (leg, part) = (c / 6, (c % 6) / 3);
            if part == 0 {
                self.u_base_um[leg].powi(2)
            } else {
                self.u_platform_um[leg].powi(2)
            }
        }))
    }

    fn to_machine_axes(&self, cov_b: &Matrix6<f64>) -> Matrix6<f64> {
        let r_mb: Matrix3<f64> = self.base_orientation();
        let mut t = Matrix6::zeros();
        t.fixed_view_mut::<3, 3>(0, 0).copy_from(&r_mb);
        t.fixed_view_mut::<3, 3>(3, 3).copy_from(&r_mb);
        t * cov_b * t.transpose()
    }

    /// Covariance (k = 1) of one measured pose's six values at the tool point, in M's axes
    /// (µm, µrad), from independent leg errors of standard uncertainty `leg_u_um` (k = 1) and,
    /// when `with_joints`, the joints' `u_base_um` and `u_platform_um`.
    pub fn pose_covariance(
        &self,
        pose: &Pose,
        leg_u_um: &[f64; 6],
        with_joints: bool,
    ) -> Result<Matrix6<f64>, HexapodError> {
        let ji = self.inverse_jacobian(pose)?;
        let var = Matrix6::from_diagonal(&nalgebra::Vector6::from_fn(|i, _| {
            let j = if with_joints {
                self.u_base_um[i].powi(2) + self.u_platform_um[i].powi(2)
            } else {
                0.0
            };
            leg_u_um[i].powi(2) + j
        }));
        Ok(self.to_machine_axes(&(ji * var * ji.transpose())))
    }

    /// Expanded uncertainty U (k = 2) of the six errors at a station against the datum, in M's
    /// axes (µm, µrad), from the legs' U (k = 2, per leg, independent between the two dwells)
    /// and the joints' u (the same joints at both dwells). Call it for stations other than the
    /// datum dwell itself, whose errors are zero by definition.
    pub fn error_uncertainty(
        &self,
        datum: &Pose,
        station: &Pose,
        leg_expanded_um: &[f64; 6],
    ) -> Result<SixErrors, HexapodError> {
        let (j0, js) = (
            self.inverse_jacobian(datum)?,
            self.inverse_jacobian(station)?,
        );
        let legs = Matrix6::from_diagonal(&nalgebra::Vector6::from_fn(|i, _| {
            (0.5 * leg_expanded_um[i]).powi(2)
        }));
        let mut cov = js * legs * js.transpose() + j0 * legs * j0.transpose();
        let to_dyn = |m: &Matrix6<f64>| DMatrix::from_fn(6, 6, |r, c| m[(r, c)]);
        let d = to_dyn(&js) * self.joint_derivative(station)
            - to_dyn(&j0) * self.joint_derivative(datum);
        let cj = &d * self.joint_variances_um2() * d.transpose();
        cov += Matrix6::from_fn(|r, c| cj[(r, c)]);
        let cov_m = self.to_machine_axes(&cov);
        Ok(SixErrors::from_array(std::array::from_fn(|k| {
            2.0 * cov_m[(k, k)].max(0.0).sqrt()
        })))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_axis_moved_names_the_errors() {
        let c0 = [400.0, 300.0, -200.0];
        assert_eq!(moved_axis(c0, [420.0, 300.0, -200.0], 1e-3), Some(Axis::X));
        assert_eq!(
            moved_axis(c0, [400.0, 300.0005, -150.0], 1e-3),
            Some(Axis::Z)
        );
        assert_eq!(moved_axis(c0, c0, 1e-3), None);
        assert_eq!(moved_axis(c0, [401.0, 301.0, -200.0], 1e-3), None);
        let test = [c0, [410.0, 300.0, -200.0], [420.0, 300.0, -200.0]];
        assert_eq!(axis_of_test(&test, 1e-3), Some(Axis::X));
        assert_eq!(
            axis_of_test(&test, 1e-3).unwrap().iso230_1_names()[1],
            "EYX"
        );
    }
}
