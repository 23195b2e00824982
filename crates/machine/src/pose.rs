//! Poses of the device's platform frame P in its base frame B, and the rotation helpers.
//!
//! Convention: `docs/spec/device-format.md`, "Conventions", **Pose**: (x, y, z, rx, ry, rz) is
//! P expressed in B; a point q in P is t + R q in B, t in mm, R = Rz(rz) · Ry(ry) · Rx(rx),
//! right-hand rotations about B's fixed axes (first rx about x, then ry about y, then rz about
//! z), angles in degrees. `base_orientation_deg` uses the same convention (R_MB).
//! **Small angles**: an error rotation ε (rad) is R(ε) = I + \[ε\]× to first order; here the
//! exact rotation exp(\[ε\]×) and the exact rotation vector (its inverse) are used, which agree
//! with the spec's to second order.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// A pose of P in B: translation in mm, rotation angles in degrees (R = Rz · Ry · Rx).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    /// x, mm.
    pub x_mm: f64,
    /// y, mm.
    pub y_mm: f64,
    /// z, mm.
    pub z_mm: f64,
    /// rx, degrees (about B's x, applied first).
    pub rx_deg: f64,
    /// ry, degrees (about B's y, second).
    pub ry_deg: f64,
    /// rz, degrees (about B's z, last).
    pub rz_deg: f64,
}

impl Pose {
    /// From [x, y, z, rx, ry, rz] (mm, deg), the manifest's `nominal_pose` order.
    pub fn from_array(v: [f64; 6]) -> Self {
        Pose {
            x_mm: v[0],
            y_mm: v[1],
            z_mm: v[2],
            rx_deg: v[3],
            ry_deg: v[4],
            rz_deg: v[5],
        }
    }

    /// As [x, y, z, rx, ry, rz] (mm, deg).
    pub fn to_array(self) -> [f64; 6] {
        [
            self.x_mm,
            self.y_mm,
            self.z_mm,
            self.rx_deg,
            self.ry_deg,
            self.rz_deg,
        ]
    }

    /// Translation t, mm.
    pub fn translation_mm(&self) -> Vector3<f64> {
        Vector3::new(self.x_mm, self.y_mm, self.z_mm)
    }

    /// Rotation R = Rz(rz) · Ry(ry) · Rx(rx).
    pub fn rotation(&self) -> Matrix3<f64> {
        rotation_from_deg([self.rx_deg, self.ry_deg, self.rz_deg])
    }

    /// The pose of translation `t_mm` and rotation `r` (angles with ry in [−90°, 90°]).
    pub fn from_parts(t_mm: &Vector3<f64>, r: &Matrix3<f64>) -> Self {
        let [rx, ry, rz] = angles_deg(r);
        Pose {
            x_mm: t_mm.x,
            y_mm: t_mm.y,
            z_mm: t_mm.z,
            rx_deg: rx,
            ry_deg: ry,
            rz_deg: rz,
        }
    }
}

/// R = Rz(rz) · Ry(ry) · Rx(rx) from [rx, ry, rz] in degrees.
pub fn rotation_from_deg(angles_deg: [f64; 3]) -> Matrix3<f64> {
    let [rx, ry, rz] = angles_deg.map(f64::to_radians);
    // nalgebra's from_euler_angles(roll, pitch, yaw) is Rz(yaw) · Ry(pitch) · Rx(roll).
    Rotation3::from_euler_angles(rx, ry, rz).into_inner()
}

/// [rx, ry, rz] in degrees of a rotation R = Rz · Ry · Rx (ry in [−90°, 90°]).
pub fn angles_deg(r: &Matrix3<f64>) -> [f64; 3] {
    let (rx, ry, rz) = Rotation3::from_matrix_unchecked(*r).euler_angles();
    [rx.to_degrees(), ry.to_degrees(), rz.to_degrees()]
}

/// The skew matrix \[v\]×, \[v\]× q = v × q.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    v.cross_matrix()
}

/// The rotation exp(\[ε\]×) of rotation vector ε (rad).
pub fn rotation_from_vector(eps_rad: &Vector3<f64>) -> Matrix3<f64> {
    Rotation3::new(*eps_rad).into_inner()
}

/// The rotation vector (rad) of a rotation matrix: the ε with exp(\[ε\]×) = R, |ε| ≤ π.
///
/// θ = atan2(|w|, (tr R − 1)/2), ε = w θ / |w| with w = vee(R − Rᵀ)/2: exact to rounding for
/// the small rotations of error evaluation (an arccos of the trace would lose half the
/// digits); near θ = π nalgebra's axis-angle is used.
pub fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    let w = 0.5
        * Vector3::new(
            r[(2, 1)] - r[(1, 2)],
            r[(0, 2)] - r[(2, 0)],
            r[(1, 0)] - r[(0, 1)],
        );
    let s = w.norm();
    let c = 0.5 * (r.trace() - 1.0);
    let theta = s.atan2(c);
    if s == 0.0 && c > 0.0 {
        Vector3::zeros()
    } else if theta < 3.0 {
        w * (theta / s)
    } else {
        Rotation3::from_matrix_unchecked(*r).scaled_axis()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rx(a: f64) -> Matrix3<f64> {
        let (s, c) = a.to_radians().sin_cos();
        Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
    }
    fn ry(a: f64) -> Matrix3<f64> {
        let (s, c) = a.to_radians().sin_cos();
        Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
    }
    fn rz(a: f64) -> Matrix3<f64> {
        let (s, c) = a.to_radians().sin_cos();
        Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    }

    #[test]
    fn the_rotation_is_rz_ry_rx() {
        let (a, b, c) = (12.0, -31.0, 47.0);
        let by_hand = rz(c) * ry(b) * rx(a);
        let r = rotation_from_deg([a, b, c]);
        assert!((r - by_hand).norm() < 1e-14);
        // Right-hand: +90° about z takes x to y.
        let q = rotation_from_deg([0.0, 0.0, 90.0]) * Vector3::x();
        assert!((q - Vector3::y()).norm() < 1e-15);
        let back = angles_deg(&r);
        assert!((back[0] - a).abs() < 1e-12 && (back[1] - b).abs() < 1e-12);
        assert!((back[2] - c).abs() < 1e-12);
        let p = Pose::from_array([1.0, 2.0, 3.0, a, b, c]);
        let q = Pose::from_parts(&p.translation_mm(), &p.rotation());
        for (u, v) in p.to_array().iter().zip(q.to_array()) {
            assert!((u - v).abs() < 1e-12);
        }
    }

    #[test]
    fn small_rotations_are_i_plus_skew() {
        let e = Vector3::new(3e-5, -7e-5, 5e-5);
        let r = rotation_from_vector(&e);
        let first = Matrix3::identity() + skew(&e);
        // Second order: |ε|²/2 ≈ 4e-9.
        assert!((r - first).norm() < 1e-8);
        assert!((rotation_vector(&r) - e).norm() < 1e-18);
    }
}
