//! Kind `volumetric` (`docs/spec/machine-physics.md`, "Kind volumetric"; seed 001): body and
//! step diagonals measured by a laser, read through the additive model of the seed's §IV.
//!
//! - [`Diagonal`]: a diagonal's start corner P0, direction u and length D
//!   (`docs/spec/machine-formats.md`, "Kind volumetric");
//! - [`grid`]: the lattice of V2, V3 and the 3-D table (numbering l = i + I(j − 1) + IJ(k − 1),
//!   trilinear read-back) and the volumetric figures V1, V2, V3;
//! - [`model`]: the parameters (the nine error functions D_k(j) as a least-squares slope plus
//!   a shape on the step nodes, the beams' pointing, the effects a model may add) and one
//!   design row per reading;
//! - [`solve`]: every reading in one least-squares problem on the engine of [`crate::linear`]
//!   (rank, lost combinations by name), the gauge the report states for what cannot be seen,
//!   the identifiable squareness values and mean scale with U; and, for comparison, the naive
//!   closed-form inversion of the four step diagonals with the fourth sign pattern's
//!   consistency residual;
//! - [`study`]: a campaign's readings analysed (Edlén normalisation, ISO 230-2 per diagonal,
//!   V_diag, the joint fit, V1 … V3 on the grid, what cannot be seen, and the loop: candidate
//!   effects by BIC, the missing one named).

pub mod bar_diagonal;
pub mod grid;
pub mod model;
pub mod solve;
pub mod study;
#[cfg(test)]
mod tests;

pub use dbbcal_core::volumetric_campaign::DiagonalSign;

/// A diagonal of the workspace: start corner, unit direction, length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Diagonal {
    /// Its sign vector.
    pub sign: DiagonalSign,
    /// Start corner P0, mm: coordinate k is `min_mm[k]` where s_k is +, `max_mm[k]` where −.
    pub p0_mm: [f64; 3],
    /// u = (P_end − P0)/D.
    pub u: [f64; 3],
    /// D, mm.
    pub length_mm: f64,
}

impl Diagonal {
    /// The diagonal `sign` of the workspace `min_mm` … `max_mm`.
    pub fn new(sign: DiagonalSign, min_mm: [f64; 3], max_mm: [f64; 3]) -> Diagonal {
        let s = sign.signs();
        let p0_mm = [0, 1, 2].map(|k| if s[k] > 0.0 { min_mm[k] } else { max_mm[k] });
        let delta = [0, 1, 2].map(|k| s[k] * (max_mm[k] - min_mm[k]));
        let length_mm = norm(delta);
        Diagonal {
            sign,
            p0_mm,
            u: delta.map(|v| v / length_mm),
            length_mm,
        }
    }

    /// P0 + d u, mm.
    pub fn point_at(&self, d_mm: f64) -> [f64; 3] {
        [0, 1, 2].map(|k| self.p0_mm[k] + d_mm * self.u[k])
    }

    /// Two unit vectors perpendicular to u (and to each other): the directions of the
    /// pointing error β, which the spec takes ⟂ u. a = u × e_z normalised, b = u × a.
    pub fn pointing_basis(&self) -> [[f64; 3]; 2] {
        let u = self.u;
        let a = [u[1], -u[0], 0.0];
        let n = norm(a);
        let a = a.map(|v| v / n);
        let b = [
            u[1] * a[2] - u[2] * a[1],
            u[2] * a[0] - u[0] * a[2],
            u[0] * a[1] - u[1] * a[0],
        ];
        [a, b]
    }
}

pub(crate) fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
