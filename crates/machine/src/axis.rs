//! Kind `axis` (seed 002): the six errors of one linear axis at one target from interferometer
//! channels read at reflector points on a fixture.
//!
//! Model: `docs/spec/machine-physics.md`, "Kind `axis`" and "Common model": a reading on line l
//! is one channel (dx, dy, dz) of Δ(p_l) = δ + 10⁻³ ε × p_l (µm), p_l the reflector relative to
//! the reporting point (mm). For the patent's three lines of an X axis this is the 6 × 6 matrix
//! E_x of the spec's table *(standard)*; here any number of channels and lines give one row each,
//! solved at each target by [`crate::linear`] (six readings: exactly determined; more: least
//! squares with residuals). The same rows serve Y and Z: only the ISO 230-1 names change
//! (`docs/spec/device-format.md`, "Names"; `docs/spec/machine-formats.md`, "Kind `axis`": the
//! line pattern is permuted, the rigid-body rule is not).
//!
//! Rank 6 needs two points differing in the roll lever (z₁ ≠ z₂ for X) and three non-collinear
//! points; otherwise the linear engine names the lost error or combination. With z₁ = z₂ = h
//! relative to the reporting point the lost direction is EYX + 10⁻³ h EAX (both undetermined):
//! the spec's "EAX lost" is that case at h = 0 *(ours)*.
//!
//! Uncertainty *(ours, first order)*: readings carry their σ; a fixture coordinate error δp
//! (standard uncertainty u per coordinate, shared by all channels of one line) adds
//! 10⁻³ (ε × δp)_c to channel c. The estimate is x̂ = K y with K = (AᵀWA)⁺AᵀW, W = diag(σ⁻²), so
//! cov(x̂) = K (diag σ² + G u² Gᵀ) Kᵀ, G the derivative of the readings by the lines' points,
//! evaluated at the estimated ε.
//!
//! Point choice *(ours)*: machine-physics.md says that the patent's "position-error sensitivity
//! matrix" is garbled and that what matters is noise amplification: from candidate reflector
//! points per line, [`choose_points`] picks one per line minimising trace((EᵀE)⁻¹), the sum of
//! the six errors' variances per unit reading variance ((µm² + µrad²)/µm²).

use crate::components::{Axis, SixErrors};
use crate::linear::{self, LinearError, LinearProblem, LinearSolution, LostCombination};
use nalgebra::DMatrix;

/// Errors of the axis evaluation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxisError {
    /// The linear engine refused the rows.
    #[error(transparent)]
    Linear(#[from] LinearError),
    /// No readings at this target.
    #[error("no readings")]
    NoReadings,
    /// A reflector coordinate, σ or u is not finite, or σ/u is negative.
    #[error("{0}")]
    BadInput(String),
    /// Too many candidate combinations to search exhaustively.
    #[error("{0} candidate combinations: more than the limit of {1}")]
    TooManyCombinations(u128, usize),
}

/// A channel of the laser system: the component of the displacement read, in M.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    /// Δx.
    Dx,
    /// Δy.
    Dy,
    /// Δz.
    Dz,
}

impl Channel {
    /// Index (0, 1, 2).
    pub fn index(self) -> usize {
        match self {
            Channel::Dx => 0,
            Channel::Dy => 1,
            Channel::Dz => 2,
        }
    }
}

/// One reading at one target: a channel of Δ at a reflector point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisReading {
    /// Line id: readings of one line share one reflector point and its fixture error.
    pub line: u32,
    /// The displacement component read.
    pub channel: Channel,
    /// The reflector's measuring point in the fixture frame F, mm.
    pub reflector_mm: [f64; 3],
    /// Measured − commanded displacement along the channel, µm.
    pub deviation_um: f64,
    /// Standard uncertainty of the reading, µm.
    pub sigma_um: f64,
}

/// The fixture of an `axis` campaign (`[fixture]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fixture {
    /// Where translational errors are reported, in F, mm.
    pub report_point_mm: [f64; 3],
    /// Standard uncertainty of each reflector coordinate from the scales, µm.
    pub u_um: f64,
}

impl Default for Fixture {
    fn default() -> Self {
        Fixture {
            report_point_mm: [0.0; 3],
            u_um: 0.0,
        }
    }
}

/// The six errors of the axis at one target.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTarget {
    /// The axis under test.
    pub axis: Axis,
    /// ISO 230-1 names, in the order of [`SixErrors::to_array`].
    pub names: [String; 6],
    /// The six errors; NaN where not determined.
    pub errors: SixErrors,
    /// Whether each error (δx … εz) is determined.
    pub determined: [bool; 6],
    /// Standard uncertainty (k = 1) of each error from the readings' σ and the fixture's u,
    /// propagated to first order; NaN where not determined.
    pub u: SixErrors,
    /// Rank of the rows (6 = all determined).
    pub rank: usize,
    /// What the rows do not see, by name (empty at rank 6).
    pub lost: Vec<LostCombination>,
    /// Residual of each reading, µm (all zero when exactly determined).
    pub residuals_um: Vec<f64>,
    /// The engine's full answer (covariance scaled by the residuals when redundant).
    pub solution: LinearSolution,
}

/// Design row of one channel at offset `p` (mm) from the reporting point: coefficients of
/// (δx, δy, δz, εx, εy, εz) in Δ_c (µm per µm and per µrad).
pub fn design_row(channel: Channel, p_mm: [f64; 3]) -> [f64; 6] {
    let [px, py, pz] = p_mm.map(|v| 1e-3 * v);
    match channel {
        Channel::Dx => [1.0, 0.0, 0.0, 0.0, pz, -py],
        Channel::Dy => [0.0, 1.0, 0.0, -pz, 0.0, px],
        Channel::Dz => [0.0, 0.0, 1.0, py, -px, 0.0],
    }
}

/// ∂Δ_c/∂p (per mm of reflector coordinate), at rotation ε (µrad): 10⁻³ ∂(ε × p)_c/∂p.
fn point_derivative(channel: Channel, eps_urad: [f64; 3]) -> [f64; 3] {
    let [ex, ey, ez] = eps_urad.map(|v| 1e-3 * v);
    match channel {
        Channel::Dx => [0.0, -ez, ey],
        Channel::Dy => [ez, 0.0, -ex],
        Channel::Dz => [-ey, ex, 0.0],
    }
}

fn offset(reading: &AxisReading, fixture: &Fixture) -> [f64; 3] {
    let r = fixture.report_point_mm;
    [
        reading.reflector_mm[0] - r[0],
        reading.reflector_mm[1] - r[1],
        reading.reflector_mm[2] - r[2],
    ]
}

/// Solve the six errors of `axis` at one target from its readings.
pub fn solve_target(
    axis: Axis,
    readings: &[AxisReading],
    fixture: &Fixture,
) -> Result<AxisTarget, AxisError> {
    if readings.is_empty() {
        return Err(AxisError::NoReadings);
    }
    let fixture_ok = fixture.u_um.is_finite()
        && fixture.u_um >= 0.0
        && fixture.report_point_mm.iter().all(|v| v.is_finite());
    if !fixture_ok {
        return Err(AxisError::BadInput(format!(
            "fixture u {} µm or report point {:?} mm is not valid",
            fixture.u_um, fixture.report_point_mm
        )));
    }
    if let Some(r) = readings
        .iter()
        .find(|r| !r.reflector_mm.iter().all(|v| v.is_finite()))
    {
        return Err(AxisError::BadInput(format!(
            "line {}: reflector {:?} mm is not finite",
            r.line, r.reflector_mm
        )));
    }
    let names = axis.iso230_1_names();
    let problem = LinearProblem {
        names: names.to_vec(),
        rows: readings
            .iter()
            .map(|r| design_row(r.channel, offset(r, fixture)).to_vec())
            .collect(),
        observations: readings.iter().map(|r| r.deviation_um).collect(),
        sigma: Some(readings.iter().map(|r| r.sigma_um).collect()),
    };
    let solution = linear::solve(&problem)?;
    let determined: [bool; 6] = std::array::from_fn(|k| solution.determined[k]);
    let est: [f64; 6] = std::array::from_fn(|k| {
        if determined[k] {
            solution.estimate[k]
        } else {
            f64::NAN
        }
    });

    // First-order propagation: cov = K (Σ_y + G Σ_p Gᵀ) Kᵀ, K = (AᵀWA)⁺ AᵀW.
    let n = readings.len();
    let cov_given = solution
        .covariance_given
        .as_ref()
        .expect("σ was given to the engine");
    let mut a_w = DMatrix::<f64>::zeros(n, 6); // AᵀW as its transpose: rows aᵢ/σᵢ²
    for (i, row) in problem.rows.iter().enumerate() {
        let w = 1.0 / readings[i].sigma_um.powi(2);
        for j in 0..6 {
            a_w[(i, j)] = row[j] * w;
        }
    }
    let k = cov_given * a_w.transpose(); // 6 × n
    let mut sigma_y = DMatrix::<f64>::from_diagonal(&nalgebra::DVector::from_iterator(
        n,
        readings.iter().map(|r| r.sigma_um.powi(2)),
    ));
    if fixture.u_um > 0.0 {
        let eps = [est[3], est[4], est[5]].map(|v| if v.is_finite() { v } else { 0.0 });
        let u_mm2 = (1e-3 * fixture.u_um).powi(2);
        for (i, ri) in readings.iter().enumerate() {
            let gi = point_derivative(ri.channel, eps);
            for (j, rj) in readings.iter().enumerate() {
                if ri.line == rj.line {
                    let gj = point_derivative(rj.channel, eps);
                    let c: f64 = gi.iter().zip(gj).map(|(a, b)| a * b).sum();
                    sigma_y[(i, j)] += u_mm2 * c;
                }
            }
        }
    }
    let cov = &k * sigma_y * k.transpose();
    let u: [f64; 6] = std::array::from_fn(|j| {
        if determined[j] {
            cov[(j, j)].max(0.0).sqrt()
        } else {
            f64::NAN
        }
    });
    Ok(AxisTarget {
        axis,
        names,
        errors: SixErrors::from_array(est),
        determined,
        u: SixErrors::from_array(u),
        rank: solution.rank,
        lost: solution.lost.clone(),
        residuals_um: solution.residuals.clone(),
        solution,
    })
}

/// Candidate reflector points of one line and the channels it reads.
#[derive(Debug, Clone, PartialEq)]
pub struct LineCandidates {
    /// Line id.
    pub line: u32,
    /// Channels read on this line.
    pub channels: Vec<Channel>,
    /// Candidate reflector points, in F, mm (relative to the reporting point).
    pub candidates_mm: Vec<[f64; 3]>,
}

/// One combination of candidates (one per line) and its criterion.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCombination {
    /// Index of the chosen candidate of each line, in the order of the lines.
    pub choice: Vec<usize>,
    /// trace((EᵀE)⁻¹), (µm² + µrad²) per µm² of reading variance; `None` when rank < 6.
    pub trace: Option<f64>,
}

/// The result of [`choose_points`].
#[derive(Debug, Clone, PartialEq)]
pub struct PointChoice {
    /// The best combination (smallest trace), `None` when no combination has rank 6.
    pub best: Option<PointCombination>,
    /// Every combination with its criterion, in enumeration order (last line fastest).
    pub all: Vec<PointCombination>,
}

/// Most combinations [`choose_points`] enumerates.
pub const MAX_COMBINATIONS: usize = 1_000_000;

/// Pick one reflector point per line minimising trace((EᵀE)⁻¹) (noise amplification; the
/// patent's "sensitivity matrix", *ours*), over all combinations.
pub fn choose_points(lines: &[LineCandidates]) -> Result<PointChoice, AxisError> {
    if lines.is_empty() || lines.iter().any(|l| l.candidates_mm.is_empty()) {
        return Err(AxisError::NoReadings);
    }
    let total: u128 = lines
        .iter()
        .map(|l| l.candidates_mm.len() as u128)
        .product();
    if total > MAX_COMBINATIONS as u128 {
        return Err(AxisError::TooManyCombinations(total, MAX_COMBINATIONS));
    }
    let mut all = Vec::with_capacity(total as usize);
    let mut choice = vec![0usize; lines.len()];
    loop {
        let rows: Vec<[f64; 6]> = lines
            .iter()
            .zip(&choice)
            .flat_map(|(l, &c)| {
                l.channels
                    .iter()
                    .map(move |&ch| design_row(ch, l.candidates_mm[c]))
            })
            .collect();
        let e = DMatrix::<f64>::from_fn(rows.len().max(6), 6, |i, j| {
            rows.get(i).map_or(0.0, |r| r[j])
        });
        let s = e.singular_values();
        let smax = s.max();
        // trace((EᵀE)⁻¹) = Σ 1/s_k², at full rank (the engine's tolerance).
        let trace = (s.min() > linear::DEFAULT_RANK_RTOL * smax)
            .then(|| s.iter().map(|v| 1.0 / (v * v)).sum());
        all.push(PointCombination {
            choice: choice.clone(),
            trace,
        });
        // Next combination, last line fastest.
        let mut k = lines.len();
        loop {
            if k == 0 {
                let best = all
                    .iter()
                    .filter(|c| c.trace.is_some())
                    .min_by(|a, b| a.trace.unwrap().total_cmp(&b.trace.unwrap()))
                    .cloned();
                return Ok(PointChoice { best, all });
            }
            k -= 1;
            choice[k] += 1;
            if choice[k] < lines[k].candidates_mm.len() {
                break;
            }
            choice[k] = 0;
        }
    }
}

#[cfg(test)]
mod tests;
