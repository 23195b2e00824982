//! The bars as the diagonal instrument (issue 30, ★): a body-diagonal test (ISO 230-6) read by
//! a calibrated double ballbar instead of a laser. Designed and simulated here; the campaign
//! format that would carry it (a bar's device mounts along a diagonal, the `positions` log) is
//! not built yet.
//!
//! # The measurement *(ours)*
//!
//! One ball sits in a socket S fixed on the table on the diagonal's line, the other in a socket on
//! the spindle. The machine is commanded along the diagonal's unit vector u, P = S + (L₀ + d) u.
//! The bar's compensated centre distance (`physics.md`: D(n, A) plus the reference bars'
//! thermal compensation) is
//!
//! ```text
//! L = |P + 10⁻³ e(P) − S| = L₀ + d + 10⁻³ u · e(P) + 10⁻⁶ |e⊥(P)|² / (2 L) + …   (mm, e in µm)
//! ```
//!
//! so its change along the diagonal is u · e, what a laser reads on a body diagonal (Dr of
//! `machine-physics.md`, "Kind volumetric"), to first order; the lateral part enters as
//! |e⊥|²/(2L): 20 µm off the line at L = 300 mm is 0.7 nm. The bar's travel (100–200 mm) is a
//! fraction of a diagonal (1.27 m on 1000 × 600 × 500 mm), so the fixed ball is re-seated at
//! sockets along the diagonal, one *segment* each, consecutive segments sharing at least one
//! target. A socket's place along u is known only to set-up accuracy (millimetres): each
//! segment's readings carry an unknown constant c_s. [`stitch`] solves
//!
//! ```text
//! r_{s,i} = Dr(d_i) + c_s + noise,   Dr(0) = 0 (the datum: the diagonal's start corner)
//! ```
//!
//! as one least-squares problem on the machine kinds' linear engine ([`crate::linear`]): every
//! target's Dr and every segment's constant, weighted by each reading's standard uncertainty.
//! The segments must chain (overlap); otherwise the constants and the targets are not
//! separable, and the engine names the lost combination.
//!
//! # What the bars bring to U
//!
//! - each reading's random part: the compensated reading's scatter and the residual of the
//!   reference bars' thermal compensation over the segment (`acceptance`'s budget without its
//!   constant terms): the weights;
//! - what is constant over a segment (the calibrated plate length's u, a mount's zero) falls into
//!   c_s and leaves Dr;
//! - the bar's scale: the calibration function's slope uncertainty, one value for every segment
//!   (the same bar), so it is added fully correlated: u_scale · d
//!   ([`BarDiagonalBudget::scale_u_ppm`]);
//! - the bar's alignment with the diagonal: a socket h off the line at bar length L tilts the bar
//!   by θ = h/L, and each segment reads its travel short by θ²/2 · x; the shortfalls add along the
//!   chain (0.1 mm at 300 mm: 0.017 µm per 150-mm segment), a one-sided bias taken as a
//!   rectangular term ([`BarDiagonalBudget::max_misalignment_rad`]): set the sockets on the line
//!   by touching them with the spindle, to a tenth of a millimetre;
//! - the stitching's own propagation: each overlap adds its readings' noise to every target
//!   beyond it (a random walk of segment constants), which the covariance of the joint solve
//!   carries.

use crate::linear::{self, LinearError, LinearProblem};

/// One compensated bar reading on a segment of a diagonal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarDiagonalReading {
    /// The segment (socket set-up), from 0.
    pub segment: usize,
    /// Commanded distance from the diagonal's start corner along u, mm.
    pub target_mm: f64,
    /// The bar's compensated centre distance minus the commanded distance from its socket,
    /// µm (any constant per segment is allowed: it is solved for).
    pub reading_um: f64,
    /// Standard uncertainty of the reading's random part, µm.
    pub u_um: f64,
}

/// The diagonal read by the bars: Dr at each target with its U.
#[derive(Debug, Clone, PartialEq)]
pub struct StitchedDiagonal {
    /// The targets, mm from the start corner, increasing; the first is the datum (0).
    pub target_mm: Vec<f64>,
    /// Dr = u · [e(P) − e(P₀)], µm.
    pub dr_um: Vec<f64>,
    /// Its expanded uncertainty (k = 2), µm: the joint solve's covariance and the bar's scale.
    pub u_k2_um: Vec<f64>,
    /// Each segment's constant, µm.
    pub segment_constant_um: Vec<f64>,
    /// RMS of the weighted residuals (1 when the readings scatter as their u says).
    pub weighted_rms: f64,
    /// Residual degrees of freedom.
    pub dof: usize,
}

/// Targets closer than this are one target, mm.
const SAME_TARGET_MM: f64 = 1e-6;

/// Why the readings cannot be stitched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BarDiagonalError {
    /// No reading at the start corner (d = 0): the datum is missing.
    #[error("no reading at the diagonal's start corner (target 0 mm): Dr has no datum")]
    NoDatum,
    /// The segments do not chain: the engine names what is lost.
    #[error("the segments do not overlap into one chain: {0}")]
    NotChained(String),
    /// The engine refused the problem.
    #[error(transparent)]
    Linear(#[from] LinearError),
}

/// What the bar and its set-up add to every segment alike.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarDiagonalBudget {
    /// The bar's scale standard uncertainty (the calibration function's slope), ppm.
    pub scale_u_ppm: f64,
    /// The largest angle between the bar and the diagonal (a socket off the line by h at bar
    /// length L: h / L), rad. A segment reads its travel x short by θ²/2 · x (a cosine error),
    /// and the segments' shortfalls add up along the chain; taken as a rectangular bias of
    /// half-width θ²/2 · d.
    pub max_misalignment_rad: f64,
}

/// Dr along the diagonal from the bars' segments (see the module documentation).
pub fn stitch(
    readings: &[BarDiagonalReading],
    budget: BarDiagonalBudget,
) -> Result<StitchedDiagonal, BarDiagonalError> {
    let mut targets: Vec<f64> = readings.iter().map(|r| r.target_mm).collect();
    targets.sort_by(f64::total_cmp);
    targets.dedup_by(|a, b| (*a - *b).abs() <= SAME_TARGET_MM);
    if targets.first().is_none_or(|t| t.abs() > SAME_TARGET_MM) {
        return Err(BarDiagonalError::NoDatum);
    }
    let segments = readings.iter().map(|r| r.segment + 1).max().unwrap_or(0);
    let index = |t: f64| {
        targets
            .iter()
            .position(|x| (x - t).abs() <= SAME_TARGET_MM)
            .unwrap_or(0)
    };
    // Unknowns: Dr at every target but the datum, then every segment's constant.
    let n_dr = targets.len() - 1;
    let mut names: Vec<String> = targets[1..].iter().map(|t| format!("Dr({t} mm)")).collect();
    names.extend((0..segments).map(|s| format!("segment {s} constant")));
    let rows: Vec<Vec<f64>> = readings
        .iter()
        .map(|r| {
            let mut row = vec![0.0; n_dr + segments];
            let j = index(r.target_mm);
            if j > 0 {
                row[j - 1] = 1.0;
            }
            row[n_dr + r.segment] = 1.0;
            row
        })
        .collect();
    let solution = linear::solve(&LinearProblem {
        names,
        rows,
        observations: readings.iter().map(|r| r.reading_um).collect(),
        sigma: Some(readings.iter().map(|r| r.u_um).collect()),
    })?;
    if !solution.lost.is_empty() {
        let lost: Vec<String> = solution
            .lost
            .iter()
            .map(|l| {
                l.terms
                    .iter()
                    .map(|(n, c)| format!("{c:+.3} {n}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect();
        return Err(BarDiagonalError::NotChained(lost.join("; ")));
    }
    // The readings' u is their stated random part: the covariance from it, not rescaled by a
    // residual that a few overlaps estimate poorly.
    let cov = solution.covariance_given.clone();
    let variance = |j: usize| cov.as_ref().map_or(f64::NAN, |c| c[(j, j)]);
    let mut dr_um = vec![0.0];
    let mut u_k2_um = vec![0.0];
    for (j, t) in targets.iter().enumerate().skip(1) {
        dr_um.push(solution.estimate[j - 1]);
        let scale = budget.scale_u_ppm * 1e-3 * t;
        let cosine = budget.max_misalignment_rad.powi(2) / 2.0 * 1e3 * t / 3f64.sqrt();
        u_k2_um.push(2.0 * (variance(j - 1) + scale * scale + cosine * cosine).sqrt());
    }
    let weighted_rms = (solution.rss_weighted / readings.len().max(1) as f64).sqrt();
    Ok(StitchedDiagonal {
        target_mm: targets,
        dr_um,
        u_k2_um,
        segment_constant_um: solution.estimate[n_dr..].to_vec(),
        weighted_rms,
        dof: solution.dof,
    })
}

#[cfg(test)]
mod tests;
