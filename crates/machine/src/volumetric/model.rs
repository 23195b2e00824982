//! The parameters of a `volumetric` fit and one design row per reading
//! (`docs/spec/machine-physics.md`, "Kind volumetric" and "Common model").
//!
//! **Error functions** *(ours, the seed's additive model §IV)*: e(P) = Σ_j D(j)(q_j), each of the
//! nine D_k(j) (component k, axis j moved) zero at the workspace's min corner and written as
//! D_k(j)(q) = 10⁻³ m_kj (q − min_j) + Σ_n w_kjn φ_n(q): a slope m_kj (µm/m = µrad) and a shape
//! on the N − 1 inner step nodes (hat functions φ_n, zero at both ends), so that pointing, which
//! adds only straight lines, can never take a shape.
//!
//! **Rows.** A body-diagonal reading at distance d: u·[e(P0 + d u) − e(P0)]. A step reading at
//! P: u·[e(P) − e(P0)] + 10⁻³ β·(P − P0) (β ⟂ u in µrad, two components per diagonal in the
//! basis of [`crate::volumetric::Diagonal::pointing_basis`]). Every (diagonal, run) has a
//! datum offset (the laser's zero of that run).
//!
//! **Effects** a model may add ([`VolumetricEffect`]): pointing, machine drift (a rate along u
//! per diagonal, µm/h), Abbe terms through offsets (the nine bilinear cross terms
//! 10⁻⁶ c (q_a − min_a)(q_b − min_b) that angular errors acting on carried coordinates make,
//! µm/m²) and a non-rigid cross term (the sag D_k(x, z) = c_k 4ξ(1 − ξ) ζ, ξ, ζ the normalised
//! x and z, µm).
//!
//! **Two instruments** *(ours)*: when a campaign's body diagonals are read by a bar and other
//! readings by the laser, each has its own scale; one nuisance parameter, the bar's scale less
//! the laser's (ppm, 10⁻³ µm per mm of travel on every bar reading), keeps the bar's
//! calibration error out of the error field (Σ L_k² ε_k / D² is then the laser's), and is
//! reported as a check of the bar's calibration.

use super::{dot, Diagonal, DiagonalSign};

/// An effect the model can hold beyond the additive error functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum VolumetricEffect {
    /// Beam and mirror mis-pointing β ⟂ u, two components per step diagonal (nuisance).
    Pointing,
    /// Machine drift during the test: a rate along u per diagonal.
    MachineDrift,
    /// Angular errors acting through offsets (Abbe): bilinear cross terms.
    Abbe,
    /// Non-rigid, load-dependent error: D_k(x, z) sag.
    NonRigid,
}

impl VolumetricEffect {
    /// Every effect, in the order candidates are listed.
    pub const ALL: [VolumetricEffect; 4] = [
        VolumetricEffect::Pointing,
        VolumetricEffect::MachineDrift,
        VolumetricEffect::Abbe,
        VolumetricEffect::NonRigid,
    ];

    /// The name `[volumetric] effects` and `--add-effect` take.
    pub fn name(self) -> &'static str {
        match self {
            VolumetricEffect::Pointing => "pointing",
            VolumetricEffect::MachineDrift => "machine_drift",
            VolumetricEffect::Abbe => "abbe",
            VolumetricEffect::NonRigid => "non_rigid",
        }
    }

    /// The effect a name gives; `parse(e.name()) == Some(e)`.
    pub fn parse(word: &str) -> Option<VolumetricEffect> {
        Self::ALL.into_iter().find(|e| e.name() == word)
    }

    /// The spec's words for it (`machine-physics.md`, the table of effects).
    pub fn physics(self) -> &'static str {
        match self {
            VolumetricEffect::Pointing => "beam and mirror mis-pointing β: a line along each sub-moved axis, per step diagonal",
            VolumetricEffect::MachineDrift => "machine thermal drift during the test: a trend in time along each diagonal",
            VolumetricEffect::Abbe => "Abbe / angular errors through offsets: cross terms q_a·q_b outside the additive model",
            VolumetricEffect::NonRigid => "non-rigid, load-dependent error (Z sag with X): a cross term D_k(x, z)",
        }
    }
}

/// Where a reading was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Place {
    /// On a body diagonal, at distance `d_mm` from P0.
    Body {
        /// Commanded distance from P0, mm.
        d_mm: f64,
    },
    /// On a step diagonal, after a sub-move, at commanded `position_mm`.
    Step {
        /// Commanded P, mm.
        position_mm: [f64; 3],
        /// The step (0 = datum).
        step: i64,
        /// The axis just moved (0, 1, 2), `None` at step 0.
        submove: Option<usize>,
    },
}

/// One reading, normalised to T0 (µm along u).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Which diagonal.
    pub diagonal: DiagonalSign,
    /// Run.
    pub run: i64,
    /// +1 / −1 (body diagonals), +1 for steps.
    pub direction: i8,
    /// Where.
    pub place: Place,
    /// Hours since the campaign's first reading.
    pub hours: f64,
    /// Measured − commanded along u, µm.
    pub deviation_um: f64,
    /// Read by a bar (a stitched body diagonal), not by the laser.
    pub bar: bool,
}

impl Observation {
    /// Whether it is a step-diagonal reading.
    pub fn is_step(&self) -> bool {
        matches!(self.place, Place::Step { .. })
    }

    /// The commanded point, mm.
    pub fn position_mm(&self, diagonal: &Diagonal) -> [f64; 3] {
        match self.place {
            Place::Body { d_mm } => diagonal.point_at(d_mm),
            Place::Step { position_mm, .. } => position_mm,
        }
    }
}

/// The name of the bar's scale less the laser's, ppm.
pub const BAR_SCALE: &str = "bar scale − laser scale (ppm)";

/// The letters of the axes and components.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// The pairs (a, b) of the bilinear Abbe terms.
const PAIRS: [(usize, usize); 3] = [(0, 1), (1, 2), (2, 0)];

/// The parameters of one fit: their names and where each block starts.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Parameter names, in column order.
    pub names: Vec<String>,
    /// Workspace min corner, mm.
    pub min_mm: [f64; 3],
    /// Workspace extent, mm.
    pub lengths_mm: [f64; 3],
    /// N: the step nodes per axis are min + n L/N, n = 0 … N (0: no shapes, body diagonals only).
    pub intervals: usize,
    /// The effects held.
    pub effects: Vec<VolumetricEffect>,
    /// The diagonals, by index of [`DiagonalSign::ALL`].
    pub diagonals: [Diagonal; 4],
    pointing: Vec<(DiagonalSign, usize)>,
    drift: Vec<(DiagonalSign, usize)>,
    abbe: Option<usize>,
    non_rigid: Option<usize>,
    offsets: Vec<((DiagonalSign, i64, bool), usize)>,
    bar_scale: Option<usize>,
}

/// Column of slope m_kj.
pub fn slope_index(k: usize, j: usize) -> usize {
    3 * j + k
}

impl Layout {
    /// The parameters for readings `obs` on the workspace `min_mm` … `max_mm`, with `intervals`
    /// step intervals per axis and `effects`.
    // The axes k, j index several arrays at once (error k along axis j: the spec's D_k(j)).
    #[allow(clippy::needless_range_loop)]
    pub fn new(
        min_mm: [f64; 3],
        max_mm: [f64; 3],
        intervals: usize,
        effects: &[VolumetricEffect],
        obs: &[Observation],
    ) -> Layout {
        let diagonals = DiagonalSign::ALL.map(|s| Diagonal::new(s, min_mm, max_mm));
        let lengths_mm = [0, 1, 2].map(|k| max_mm[k] - min_mm[k]);
        let mut names = Vec::new();
        for j in 0..3 {
            for k in 0..3 {
                names.push(format!("slope D{}({})", AXES[k], AXES[j]));
            }
        }
        for j in 0..3 {
            for k in 0..3 {
                for n in 1..intervals {
                    let q = min_mm[j] + n as f64 * lengths_mm[j] / intervals as f64;
                    names.push(format!("D{}({})@{}mm", AXES[k], AXES[j], trim(q)));
                }
            }
        }
        let mut diags: Vec<DiagonalSign> = obs.iter().map(|o| o.diagonal).collect();
        diags.sort();
        diags.dedup();
        let mut step_diags: Vec<DiagonalSign> = obs
            .iter()
            .filter(|o| matches!(o.place, Place::Step { .. }))
            .map(|o| o.diagonal)
            .collect();
        step_diags.sort();
        step_diags.dedup();
        let mut effects = effects.to_vec();
        effects.sort();
        effects.dedup();
        let mut pointing = Vec::new();
        let mut drift = Vec::new();
        let (mut abbe, mut non_rigid) = (None, None);
        for e in &effects {
            match e {
                VolumetricEffect::Pointing => {
                    for d in &step_diags {
                        pointing.push((*d, names.len()));
                        names.push(format!("pointing {d} a"));
                        names.push(format!("pointing {d} b"));
                    }
                }
                VolumetricEffect::MachineDrift => {
                    for d in &diags {
                        drift.push((*d, names.len()));
                        names.push(format!("drift {d}"));
                    }
                }
                VolumetricEffect::Abbe => {
                    abbe = Some(names.len());
                    for (a, b) in PAIRS {
                        for k in 0..3 {
                            names.push(format!("abbe D{}·{}{}", AXES[k], AXES[a], AXES[b]));
                        }
                    }
                }
                VolumetricEffect::NonRigid => {
                    non_rigid = Some(names.len());
                    for k in 0..3 {
                        names.push(format!("sag D{}(x,z)", AXES[k]));
                    }
                }
            }
        }
        let mut runs: Vec<(DiagonalSign, i64, bool)> = obs
            .iter()
            .map(|o| (o.diagonal, o.run, o.is_step()))
            .collect();
        runs.sort();
        runs.dedup();
        let offsets = runs
            .into_iter()
            .map(|(d, r, step)| {
                let what = if step { "step" } else { "body" };
                names.push(format!("datum {what} {d} run {r}"));
                ((d, r, step), names.len() - 1)
            })
            .collect();
        let bar_scale = (obs.iter().any(|o| o.bar) && obs.iter().any(|o| !o.bar)).then(|| {
            names.push(BAR_SCALE.to_string());
            names.len() - 1
        });
        Layout {
            names,
            min_mm,
            lengths_mm,
            intervals,
            effects,
            diagonals,
            pointing,
            drift,
            abbe,
            non_rigid,
            offsets,
            bar_scale,
        }
    }

    /// The column of the bar's scale less the laser's (campaigns with both instruments).
    pub fn bar_scale_index(&self) -> Option<usize> {
        self.bar_scale
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are none (never: the nine slopes are always there).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The diagonal of `sign`.
    pub fn diagonal(&self, sign: DiagonalSign) -> &Diagonal {
        &self.diagonals[sign.index()]
    }

    /// The node coordinates of axis `j`, mm (min … max, N + 1 of them; 2 without shapes).
    pub fn nodes(&self, j: usize) -> Vec<f64> {
        let n = self.intervals.max(1);
        (0..=n)
            .map(|i| self.min_mm[j] + i as f64 * self.lengths_mm[j] / n as f64)
            .collect()
    }

    fn shape_index(&self, k: usize, j: usize, n: usize) -> usize {
        9 + (3 * j + k) * (self.intervals - 1) + (n - 1)
    }

    /// Adds c · D_k(j)(q) to the coefficients `row`.
    fn add_function(&self, row: &mut [f64], k: usize, j: usize, q: f64, c: f64) {
        row[slope_index(k, j)] += c * 1e-3 * (q - self.min_mm[j]);
        if self.intervals < 2 {
            return;
        }
        let h = self.lengths_mm[j] / self.intervals as f64;
        let t = (q - self.min_mm[j]) / h;
        let lo = t.floor();
        for n in [lo as i64, lo as i64 + 1] {
            if n >= 1 && (n as usize) < self.intervals {
                let phi = 1.0 - (t - n as f64).abs();
                if phi > 0.0 {
                    row[self.shape_index(k, j, n as usize)] += c * phi;
                }
            }
        }
    }

    /// Adds c · e_k(P) (the model's error field, nuisance excluded) to `row`.
    fn add_error(&self, row: &mut [f64], k: usize, p: [f64; 3], c: f64) {
        for (j, q) in p.into_iter().enumerate() {
            self.add_function(row, k, j, q, c);
        }
        let rel = [0, 1, 2].map(|a| p[a] - self.min_mm[a]);
        if let Some(start) = self.abbe {
            for (i, (a, b)) in PAIRS.iter().enumerate() {
                row[start + 3 * i + k] += c * 1e-6 * rel[*a] * rel[*b];
            }
        }
        if let Some(start) = self.non_rigid {
            let xi = rel[0] / self.lengths_mm[0];
            let zeta = rel[2] / self.lengths_mm[2];
            row[start + k] += c * 4.0 * xi * (1.0 - xi) * zeta;
        }
    }

    /// The coefficients of e_k(P): e_k = c · θ.
    pub fn error_coefficients(&self, k: usize, p_mm: [f64; 3]) -> Vec<f64> {
        let mut row = vec![0.0; self.len()];
        self.add_error(&mut row, k, p_mm, 1.0);
        row
    }

    /// The coefficients of D_k(j)(q).
    pub fn function_coefficients(&self, k: usize, j: usize, q_mm: f64) -> Vec<f64> {
        let mut row = vec![0.0; self.len()];
        self.add_function(&mut row, k, j, q_mm, 1.0);
        row
    }

    /// The coefficients of the least-squares slope of D_k(j) over the nodes, µm/m (= µrad).
    pub fn ls_slope_coefficients(&self, k: usize, j: usize) -> Vec<f64> {
        let q = self.nodes(j);
        let mean = q.iter().sum::<f64>() / q.len() as f64;
        let sxx: f64 = q.iter().map(|v| (v - mean).powi(2)).sum();
        let mut row = vec![0.0; self.len()];
        for v in &q {
            self.add_function(&mut row, k, j, *v, 1e3 * (v - mean) / sxx);
        }
        row
    }

    /// The design row of a reading.
    pub fn row(&self, o: &Observation) -> Vec<f64> {
        let diag = self.diagonal(o.diagonal);
        let p = o.position_mm(diag);
        let mut row = vec![0.0; self.len()];
        for k in 0..3 {
            self.add_error(&mut row, k, p, diag.u[k]);
            self.add_error(&mut row, k, diag.p0_mm, -diag.u[k]);
        }
        if matches!(o.place, Place::Step { .. }) {
            if let Some((_, start)) = self.pointing.iter().find(|(d, _)| *d == o.diagonal) {
                let rel = [0, 1, 2].map(|a| p[a] - diag.p0_mm[a]);
                let [a, b] = diag.pointing_basis();
                row[*start] = 1e-3 * dot(a, rel);
                row[start + 1] = 1e-3 * dot(b, rel);
            }
        }
        if let Some((_, i)) = self.drift.iter().find(|(d, _)| *d == o.diagonal) {
            row[*i] = o.hours;
        }
        if let (Some(i), true) = (self.bar_scale, o.bar) {
            let rel = [0, 1, 2].map(|a| p[a] - diag.p0_mm[a]);
            row[i] = 1e-3 * dot(diag.u, rel);
        }
        let key = (o.diagonal, o.run, o.is_step());
        if let Some((_, i)) = self.offsets.iter().find(|(dr, _)| *dr == key) {
            row[*i] = 1.0;
        }
        row
    }

    /// The columns of nuisance parameters (pointing, drift, datum offsets), which the error
    /// field never uses.
    pub fn is_nuisance(&self, index: usize) -> bool {
        self.pointing
            .iter()
            .any(|(_, s)| index == *s || index == s + 1)
            || self.drift.iter().any(|(_, i)| *i == index)
            || self.offsets.iter().any(|(_, i)| *i == index)
            || self.bar_scale == Some(index)
    }
}

/// A coordinate for a name: integer mm when whole, else 3 decimals.
fn trim(q: f64) -> String {
    if (q - q.round()).abs() < 1e-9 {
        format!("{}", q.round() as i64)
    } else {
        format!("{q:.3}")
    }
}
