//! The bars as the diagonal instrument: a body-diagonal test (ISO 230-6) read by a calibrated
//! double ballbar instead of a laser. A `volumetric` campaign carries it as
//! `bar_diagonals/*.parquet` and `[bar_diagonal]` (`docs/bar-diagonals.md`); [`super::study::bar`]
//! turns each diagonal's readings into [`BarDiagonalReading`]s (normalised to T0), stitches them
//! here, and hands Dr with its U to the same ISO 230-2, V_diag and joint fit as a laser body
//! diagonal.
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
//! target's Dr and every segment's constant, weighted by each reading's standard uncertainty
//! (when every reading states one; else unweighted, the covariance scaled by the residuals).
//! The segments must chain (overlap): a segment that shares no target with the chain holding
//! the datum is named, with the combination the engine loses.
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

use std::collections::BTreeSet;

use nalgebra::DMatrix;

use crate::linear::{self, LinearError, LinearProblem};

/// One compensated bar reading on a segment of a diagonal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarDiagonalReading {
    /// The segment (socket set-up), as the campaign numbers it.
    pub segment: i64,
    /// Commanded distance from the diagonal's start corner along u, mm.
    pub target_mm: f64,
    /// The bar's compensated centre distance minus the commanded distance from its socket,
    /// µm (any constant per segment is allowed: it is solved for).
    pub reading_um: f64,
    /// Standard uncertainty of the reading's random part, µm; NaN when not known (then the
    /// readings' scatter about the solution sets it).
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
    /// The segments, as numbered, in the order of `segment_constant_um`.
    pub segments: Vec<i64>,
    /// Each segment's constant, µm.
    pub segment_constant_um: Vec<f64>,
    /// RMS of the weighted residuals (1 when the readings scatter as their u says; the
    /// residual RMS in µm when no u was given).
    pub weighted_rms: f64,
    /// Residual degrees of freedom.
    pub dof: usize,
    /// Whether every reading stated its u (else the covariance is scaled by the residuals).
    pub weighted: bool,
    /// Covariance of Dr over the targets (the datum's row and column zero), µm²: the
    /// readings' random part and the segments' constants, without the bar's scale.
    pub covariance_um2: DMatrix<f64>,
    /// The budget the U includes.
    pub budget: BarDiagonalBudget,
}

impl StitchedDiagonal {
    /// The target nearest `d_mm`.
    pub fn index_of(&self, d_mm: f64) -> usize {
        (0..self.target_mm.len())
            .min_by(|&a, &b| {
                (self.target_mm[a] - d_mm)
                    .abs()
                    .total_cmp(&(self.target_mm[b] - d_mm).abs())
            })
            .unwrap_or(0)
    }

    /// The standard uncertainty (k = 1) of Dr(b) − Dr(a), µm, as its three parts: the
    /// stitching's random part (covariance of the two targets), the bar's scale over |b − a|
    /// (fully correlated), and the misalignment's cosine shortfall over |b − a| (rectangular).
    pub fn difference_u_um(&self, a: usize, b: usize) -> [f64; 3] {
        let c = &self.covariance_um2;
        let random = (c[(a, a)] + c[(b, b)] - 2.0 * c[(a, b)]).max(0.0).sqrt();
        let span = (self.target_mm[b] - self.target_mm[a]).abs();
        [
            random,
            self.budget.scale_um(span),
            self.budget.cosine_um(span),
        ]
    }
}

/// Targets closer than this are one target, mm.
const SAME_TARGET_MM: f64 = 1e-6;

/// Why the readings cannot be stitched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BarDiagonalError {
    /// No reading at the start corner (d = 0): the datum is missing.
    #[error("no reading at the diagonal's start corner (distance 0 mm): Dr has no datum; the nearest segment, segment {first_segment}, starts at {first_mm:.3} mm")]
    NoDatum {
        /// The segment whose readings start nearest the corner.
        first_segment: i64,
        /// Its first distance along the diagonal, mm.
        first_mm: f64,
    },
    /// The segments do not chain: the segments cut off from the datum's chain, and what the
    /// engine loses.
    #[error("segment{} {} share{} no target with the chain of segments holding the datum ({}): the segments do not overlap into one chain; lost: {lost}", plural(.cut_off), list(.cut_off), if .cut_off.len() == 1 { "s" } else { "" }, list(.chained))]
    NotChained {
        /// The segments that share no target with the datum's chain.
        cut_off: Vec<i64>,
        /// The segments chained to the datum.
        chained: Vec<i64>,
        /// The lost combinations, by name.
        lost: String,
    },
    /// The engine refused the problem.
    #[error(transparent)]
    Linear(#[from] LinearError),
}

fn plural(v: &[i64]) -> &'static str {
    if v.len() == 1 {
        ""
    } else {
        "s"
    }
}

fn list(v: &[i64]) -> String {
    v.iter()
        .map(|s| s.to_string())
        .collect::<Vec<_>>()
        .join(", ")
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

impl BarDiagonalBudget {
    /// The bar's scale over a span of `span_mm`, µm (k = 1).
    pub fn scale_um(&self, span_mm: f64) -> f64 {
        self.scale_u_ppm * 1e-3 * span_mm
    }

    /// The misalignment's shortfall over `span_mm`, µm (k = 1, rectangular of half-width
    /// θ²/2 · span).
    pub fn cosine_um(&self, span_mm: f64) -> f64 {
        self.max_misalignment_rad.powi(2) / 2.0 * 1e3 * span_mm / 3f64.sqrt()
    }

    /// The misalignment's shortfall as a scale, ppm (k = 1).
    pub fn cosine_ppm(&self) -> f64 {
        self.max_misalignment_rad.powi(2) / 2.0 * 1e6 / 3f64.sqrt()
    }
}

/// Dr along the diagonal from the bars' segments (see the module documentation).
pub fn stitch(
    readings: &[BarDiagonalReading],
    budget: BarDiagonalBudget,
) -> Result<StitchedDiagonal, BarDiagonalError> {
    let mut targets: Vec<f64> = readings.iter().map(|r| r.target_mm).collect();
    targets.sort_by(f64::total_cmp);
    targets.dedup_by(|a, b| (*a - *b).abs() <= SAME_TARGET_MM);
    let segments: Vec<i64> = readings
        .iter()
        .map(|r| r.segment)
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    if targets.first().is_none_or(|t| t.abs() > SAME_TARGET_MM) {
        let first = readings
            .iter()
            .min_by(|a, b| a.target_mm.total_cmp(&b.target_mm));
        return Err(BarDiagonalError::NoDatum {
            first_segment: first.map_or(0, |r| r.segment),
            first_mm: first.map_or(f64::NAN, |r| r.target_mm),
        });
    }
    let index = |t: f64| {
        targets
            .iter()
            .position(|x| (x - t).abs() <= SAME_TARGET_MM)
            .unwrap_or(0)
    };
    let seg_index = |s: i64| segments.binary_search(&s).unwrap_or(0);
    check_chain(readings, &segments, &index)?;
    // Unknowns: Dr at every target but the datum, then every segment's constant.
    let n_dr = targets.len() - 1;
    let mut names: Vec<String> = targets[1..]
        .iter()
        .map(|t| format!("Dr({t:.3} mm)"))
        .collect();
    names.extend(segments.iter().map(|s| format!("segment {s} constant")));
    let rows: Vec<Vec<f64>> = readings
        .iter()
        .map(|r| {
            let mut row = vec![0.0; n_dr + segments.len()];
            let j = index(r.target_mm);
            if j > 0 {
                row[j - 1] = 1.0;
            }
            row[n_dr + seg_index(r.segment)] = 1.0;
            row
        })
        .collect();
    let weighted = readings.iter().all(|r| r.u_um.is_finite() && r.u_um > 0.0);
    let solution = linear::solve(&LinearProblem {
        names,
        rows,
        observations: readings.iter().map(|r| r.reading_um).collect(),
        sigma: weighted.then(|| readings.iter().map(|r| r.u_um).collect()),
    })?;
    if !solution.lost.is_empty() {
        // The chain check above catches what overlap can: this is what it cannot.
        let lost: Vec<String> = solution.lost.iter().map(|l| l.to_string()).collect();
        return Err(BarDiagonalError::NotChained {
            cut_off: Vec::new(),
            chained: segments.clone(),
            lost: lost.join("; "),
        });
    }
    // Given u: the covariance from it, not rescaled by a residual that a few overlaps estimate
    // poorly. No u: the residuals' scatter.
    let cov = if weighted {
        solution.covariance_given.clone()
    } else {
        solution.covariance.clone()
    };
    let n = targets.len();
    let covariance_um2 = DMatrix::from_fn(n, n, |a, b| {
        if a == 0 || b == 0 {
            0.0
        } else {
            cov.as_ref().map_or(f64::NAN, |c| c[(a - 1, b - 1)])
        }
    });
    let mut dr_um = vec![0.0];
    let mut u_k2_um = vec![0.0];
    for (j, t) in targets.iter().enumerate().skip(1) {
        dr_um.push(solution.estimate[j - 1]);
        let (scale, cosine) = (budget.scale_um(*t), budget.cosine_um(*t));
        u_k2_um.push(2.0 * (covariance_um2[(j, j)] + scale * scale + cosine * cosine).sqrt());
    }
    let weighted_rms = (solution.rss_weighted / readings.len().max(1) as f64).sqrt();
    Ok(StitchedDiagonal {
        target_mm: targets,
        dr_um,
        u_k2_um,
        segment_constant_um: solution.estimate[n_dr..].to_vec(),
        segments,
        weighted_rms,
        dof: solution.dof,
        weighted,
        covariance_um2,
        budget,
    })
}

/// The segments reachable from the datum through shared targets; the others are named.
fn check_chain(
    readings: &[BarDiagonalReading],
    segments: &[i64],
    index: &dyn Fn(f64) -> usize,
) -> Result<(), BarDiagonalError> {
    let targets_of = |s: i64| -> BTreeSet<usize> {
        readings
            .iter()
            .filter(|r| r.segment == s)
            .map(|r| index(r.target_mm))
            .collect()
    };
    let sets: Vec<BTreeSet<usize>> = segments.iter().map(|&s| targets_of(s)).collect();
    let mut reached: BTreeSet<usize> = BTreeSet::from([0]);
    let mut chained = vec![false; segments.len()];
    loop {
        let mut grew = false;
        for (i, set) in sets.iter().enumerate() {
            if !chained[i] && !set.is_disjoint(&reached) {
                chained[i] = true;
                reached.extend(set.iter().copied());
                grew = true;
            }
        }
        if !grew {
            break;
        }
    }
    let pick = |want: bool| -> Vec<i64> {
        segments
            .iter()
            .zip(&chained)
            .filter(|(_, c)| **c == want)
            .map(|(s, _)| *s)
            .collect()
    };
    let cut_off = pick(false);
    if cut_off.is_empty() {
        return Ok(());
    }
    let first = cut_off[0];
    let span = |s: i64| {
        let d: Vec<f64> = readings
            .iter()
            .filter(|r| r.segment == s)
            .map(|r| r.target_mm)
            .collect();
        (
            d.iter().copied().fold(f64::INFINITY, f64::min),
            d.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    };
    let (lo, hi) = span(first);
    Err(BarDiagonalError::NotChained {
        cut_off,
        chained: pick(true),
        lost: format!(
            "segment {first} constant against Dr at its targets ({lo:.3} … {hi:.3} mm): only their difference is read"
        ),
    })
}

#[cfg(test)]
mod tests;
