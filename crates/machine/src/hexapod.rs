//! The hexapod device: six legs between base joints (frame B) and platform joints (frame P);
//! inverse and forward kinematics, leg tilts, the Jacobian, thermal scaling of the rings.
//!
//! Sources: `docs/spec/device-format.md` ("`[[device]]`", "Conventions": **Leg length**
//! l_i = |t + R p_i − b_i|, **Tilt** A_i = asin(|(t + R p_i − b_i) · up| / l_i), **Measured
//! pose**: the pose near `nominal_pose` whose six leg lengths equal the legs' distances) and
//! `docs/spec/machine-physics.md`, "Hexapod": to first order dl_i = n_i · dδ + (q_i × n_i) · dε
//! (mm, rad), n_i the unit vector from b_i to the platform joint, q_i = R (p_i − r); J is the
//! 6 × 6 matrix of these rows.
//!
//! Thermal scaling: joint centres hold at T0 and are scaled by 1 + cte (T − T0) about *each
//! ring's centroid* ([`Hexapod::at_temperature`]). The spec scales about the frame's origin and
//! asks that origin to be put at the ring's centre; the two agree then (they do for the spec's
//! example) *(ours: the centroid, so that a frame origin elsewhere does not move the ring)*.
//!
//! Forward kinematics *(standard)*: Newton's method from `nominal_pose` on the six lengths,
//! t ← t + dδ, R ← exp(\[dε\]×) R, until every length agrees to [`ForwardOptions::tolerance_mm`]
//! (default 1e-12 mm). A pose whose Jacobian is near-singular is refused: its condition number
//! (rotation columns divided by the RMS distance ρ of the platform joints from the tool point,
//! so that it has no unit, *ours*) is reported with the threshold
//! ([`ForwardOptions::max_condition`], default [`DEFAULT_MAX_CONDITION`]). The spec's example
//! has 2.94 at its nominal pose, 197 with the platform 1 mm above the base plane.

use crate::pose::{rotation_from_vector, Pose};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// Default largest condition number of a pose's Jacobian (rotation columns per ρ) accepted by
/// [`Hexapod::forward`]: beyond it leg noise is amplified a thousandfold in some direction.
pub const DEFAULT_MAX_CONDITION: f64 = 1000.0;

/// Errors of the device's kinematics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HexapodError {
    /// The device description is not usable.
    #[error("device: {0}")]
    BadDevice(String),
    /// A leg length or pose value is NaN, infinite or not positive.
    #[error("{0}")]
    BadInput(String),
    /// Newton's method did not reach the tolerance.
    #[error(
        "forward kinematics did not converge from the nominal pose after {iterations} \
         iterations: largest leg-length residual {residual_mm:.3e} mm"
    )]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Largest |l_i − l_i(pose)| at the end, mm.
        residual_mm: f64,
    },
    /// The pose found is too close to a singular configuration.
    #[error(
        "near-singular pose {pose:?}: condition number {condition:.3e} of the Jacobian exceeds \
         {threshold:.3e}"
    )]
    NearSingular {
        /// The pose that matches the lengths.
        pose: Pose,
        /// Its Jacobian's condition number (rotation columns per ρ).
        condition: f64,
        /// The threshold.
        threshold: f64,
    },
}

/// A hexapod device (`[[device]]` with `kind = "hexapod"`), joint centres at T0.
#[derive(Debug, Clone, PartialEq)]
pub struct Hexapod {
    /// Base joint centres in B, mm, leg 1 first.
    pub base_mm: [[f64; 3]; 6],
    /// Platform joint centres in P, mm, leg 1 first.
    pub platform_mm: [[f64; 3]; 6],
    /// Standard uncertainty (k = 1) of each coordinate of each base joint centre, µm.
    pub u_base_um: [f64; 6],
    /// Standard uncertainty (k = 1) of each coordinate of each platform joint centre, µm.
    pub u_platform_um: [f64; 6],
    /// Pose of P in B near the datum: selects the assembly.
    pub nominal_pose: Pose,
    /// The point of P whose translational errors are reported, mm.
    pub tool_point_mm: [f64; 3],
    /// Orientation of B in M, degrees (same convention as a pose).
    pub base_orientation_deg: [f64; 3],
    /// The upward vertical in B (any length), for leg tilts.
    pub up: [f64; 3],
    /// Expansion of the base and platform bodies, ppm/K.
    pub cte_ppm_per_k: f64,
}

/// Options of [`Hexapod::forward_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForwardOptions {
    /// Convergence: every leg length within this of its target, mm.
    pub tolerance_mm: f64,
    /// Most Newton iterations.
    pub max_iterations: usize,
    /// Largest condition number accepted (rotation columns per ρ).
    pub max_condition: f64,
}

impl Default for ForwardOptions {
    fn default() -> Self {
        ForwardOptions {
            tolerance_mm: 1e-12,
            max_iterations: 100,
            max_condition: DEFAULT_MAX_CONDITION,
        }
    }
}

/// A pose from six leg lengths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForwardSolution {
    /// The measured pose.
    pub pose: Pose,
    /// Newton iterations used.
    pub iterations: usize,
    /// Largest leg-length residual at the end, mm.
    pub residual_mm: f64,
    /// Condition number of the Jacobian at the pose (rotation columns per ρ).
    pub condition: f64,
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

impl Hexapod {
    /// Check that the description is usable: finite values, non-negative uncertainties, a
    /// non-zero `up`, and six distinct joints per ring.
    pub fn validate(&self) -> Result<(), HexapodError> {
        let bad = |m: String| Err(HexapodError::BadDevice(m));
        let finite = self
            .base_mm
            .iter()
            .chain(&self.platform_mm)
            .flatten()
            .chain(&self.nominal_pose.to_array())
            .chain(&self.tool_point_mm)
            .chain(&self.base_orientation_deg)
            .chain(&self.up)
            .chain(std::iter::once(&self.cte_ppm_per_k))
            .all(|v| v.is_finite());
        if !finite {
            return bad("a coordinate, angle or coefficient is not finite".into());
        }
        if self
            .u_base_um
            .iter()
            .chain(&self.u_platform_um)
            .any(|u| !(u.is_finite() && *u >= 0.0))
        {
            return bad("joint uncertainties must be finite and ≥ 0".into());
        }
        if v3(self.up).norm() == 0.0 {
            return bad("`up` is the zero vector".into());
        }
        for (ring, joints) in [("base", &self.base_mm), ("platform", &self.platform_mm)] {
            for i in 0..6 {
                for j in 0..i {
                    if (v3(joints[i]) - v3(joints[j])).norm() < 1e-9 {
                        return bad(format!("{ring} joints {} and {} coincide", j + 1, i + 1));
                    }
                }
            }
        }
        Ok(())
    }

    /// The device with its joint centres at body temperature `temperature_c`: each ring scaled
    /// by 1 + cte (T − T0) about its centroid (see the module documentation).
    pub fn at_temperature(&self, temperature_c: f64, reference_temperature_c: f64) -> Hexapod {
        let s = 1.0 + 1e-6 * self.cte_ppm_per_k * (temperature_c - reference_temperature_c);
        if s == 1.0 {
            return self.clone();
        }
        let scale = |ring: &[[f64; 3]; 6]| {
            let c = ring.iter().fold([0.0; 3], |a, p| {
                [a[0] + p[0] / 6.0, a[1] + p[1] / 6.0, a[2] + p[2] / 6.0]
            });
            ring.map(|p| std::array::from_fn(|k| c[k] + s * (p[k] - c[k])))
        };
        Hexapod {
            base_mm: scale(&self.base_mm),
            platform_mm: scale(&self.platform_mm),
            ..self.clone()
        }
    }

    /// Leg vectors t + R p_i − b_i in B, mm.
    pub fn leg_vectors_mm(&self, pose: &Pose) -> [Vector3<f64>; 6] {
        let (t, r) = (pose.translation_mm(), pose.rotation());
        std::array::from_fn(|i| t + r * v3(self.platform_mm[i]) - v3(self.base_mm[i]))
    }

    /// Leg lengths l_i = |t + R p_i − b_i|, mm (inverse kinematics).
    pub fn leg_lengths_mm(&self, pose: &Pose) -> [f64; 6] {
        self.leg_vectors_mm(pose).map(|v| v.norm())
    }

    /// Leg tilts A_i = asin(|(t + R p_i − b_i) · up| / l_i), degrees from horizontal.
    pub fn leg_tilts_deg(&self, pose: &Pose) -> [f64; 6] {
        let up = v3(self.up).normalize();
        self.leg_vectors_mm(pose)
            .map(|v| (v.dot(&up).abs() / v.norm()).min(1.0).asin().to_degrees())
    }

    /// The Jacobian at `pose` for errors at the tool point: row i = [n_i, q_i × n_i],
    /// q_i = R (p_i − r); dl (mm) = J (dδ mm, dε rad).
    pub fn jacobian(&self, pose: &Pose) -> Matrix6<f64> {
        self.jacobian_about(pose, &v3(self.tool_point_mm))
    }

    fn jacobian_about(&self, pose: &Pose, r_mm: &Vector3<f64>) -> Matrix6<f64> {
        let rot = pose.rotation();
        let legs = self.leg_vectors_mm(pose);
        let mut j = Matrix6::zeros();
        for (i, v) in legs.iter().enumerate() {
            let n = v / v.norm();
            let q = rot * (v3(self.platform_mm[i]) - r_mm);
            let m = q.cross(&n);
            j.fixed_view_mut::<1, 3>(i, 0).copy_from(&n.transpose());
            j.fixed_view_mut::<1, 3>(i, 3).copy_from(&m.transpose());
        }
        j
    }

    /// The Jacobian in µm per (µm, µrad): J with its rotation columns × 10⁻³.
    pub fn jacobian_um_urad(&self, pose: &Pose) -> Matrix6<f64> {
        let mut j = self.jacobian(pose);
        for c in 3..6 {
            j.column_mut(c).scale_mut(1e-3);
        }
        j
    }

    /// ρ: RMS distance of the platform joints from the tool point, mm.
    fn rho_mm(&self) -> f64 {
        let r = v3(self.tool_point_mm);
        let s: f64 = self
            .platform_mm
            .iter()
            .map(|p| (v3(*p) - r).norm_squared())
            .sum();
        (s / 6.0).sqrt()
    }

    /// Condition number of the Jacobian at `pose` with its rotation columns divided by ρ (the
    /// RMS distance of the platform joints from the tool point), so that it has no unit.
    pub fn condition_number(&self, pose: &Pose) -> f64 {
        let mut j = self.jacobian(pose);
        let rho = self.rho_mm();
        for c in 3..6 {
            j.column_mut(c).scale_mut(1.0 / rho);
        }
        let s = j.singular_values();
        if s.min() == 0.0 {
            f64::INFINITY
        } else {
            s.max() / s.min()
        }
    }

    /// The measured pose from six leg lengths (mm), with the default options.
    pub fn forward(&self, lengths_mm: &[f64; 6]) -> Result<ForwardSolution, HexapodError> {
        self.forward_with(lengths_mm, ForwardOptions::default())
    }

    /// The measured pose from six leg lengths (mm): Newton from `nominal_pose`.
    pub fn forward_with(
        &self,
        lengths_mm: &[f64; 6],
        options: ForwardOptions,
    ) -> Result<ForwardSolution, HexapodError> {
        self.validate()?;
        if let Some(l) = lengths_mm.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
            return Err(HexapodError::BadInput(format!(
                "leg length {l} mm is not positive and finite"
            )));
        }
        let origin = Vector3::zeros();
        let mut t = self.nominal_pose.translation_mm();
        let mut rot = self.nominal_pose.rotation();
        let mut residual = f64::INFINITY;
        for iteration in 0..=options.max_iterations {
            let pose = Pose::from_parts(&t, &rot);
            let now = self.leg_lengths_mm(&pose);
            let res = Vector6::from_fn(|i, _| lengths_mm[i] - now[i]);
            residual = res.amax();
            if residual <= options.tolerance_mm {
                let condition = self.condition_number(&pose);
                // NaN (a singular Jacobian) is refused too.
                if condition.is_nan() || condition > options.max_condition {
                    return Err(HexapodError::NearSingular {
                        pose,
                        condition,
                        threshold: options.max_condition,
                    });
                }
                return Ok(ForwardSolution {
                    pose,
                    iterations: iteration,
                    residual_mm: residual,
                    condition,
                });
            }
            if iteration == options.max_iterations || !residual.is_finite() {
                break;
            }
            // Steps about P's origin: dl = J (dt, dε).
            let j = self.jacobian_about(&pose, &origin);
            let Some(step) = j.lu().solve(&res) else {
                break;
            };
            t += step.fixed_rows::<3>(0);
            rot = rotation_from_vector(&step.fixed_rows::<3>(3).into_owned()) * rot;
        }
        Err(HexapodError::NotConverged {
            iterations: options.max_iterations,
            residual_mm: residual,
        })
    }

    /// Orientation of B in M, R_MB.
    pub fn base_orientation(&self) -> Matrix3<f64> {
        crate::pose::rotation_from_deg(self.base_orientation_deg)
    }
}

#[cfg(test)]
pub(crate) mod tests;
