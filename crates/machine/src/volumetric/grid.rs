//! The lattice of the 3-D table and the volumetric figures (`docs/spec/machine-physics.md`,
//! "Kind volumetric": V1, V2, V3 and "3-D table").

/// The lattice: I × J × K nodes, node (1, 1, 1) at `origin_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// I, J, K.
    pub counts: [usize; 3],
    /// Node (1, 1, 1), mm.
    pub origin_mm: [f64; 3],
    /// Δx, Δy, Δz, mm.
    pub spacing_mm: [f64; 3],
}

impl Grid {
    /// The line of node (i, j, k), 1-based: l = i + I(j − 1) + IJ(k − 1); `None` outside.
    pub fn line(&self, i: usize, j: usize, k: usize) -> Option<usize> {
        let [ni, nj, nk] = self.counts;
        let inside = (1..=ni).contains(&i) && (1..=nj).contains(&j) && (1..=nk).contains(&k);
        inside.then(|| i + ni * (j - 1) + ni * nj * (k - 1))
    }

    /// The node (i, j, k) of line l (1 … IJK).
    pub fn node(&self, l: usize) -> Option<[usize; 3]> {
        let [ni, nj, nk] = self.counts;
        if l == 0 || l > ni * nj * nk {
            return None;
        }
        let z = l - 1;
        Some([z % ni + 1, (z / ni) % nj + 1, z / (ni * nj) + 1])
    }

    /// The position of node (i, j, k), mm.
    pub fn position(&self, node: [usize; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin_mm[a] + (node[a] as f64 - 1.0) * self.spacing_mm[a])
    }

    /// Every node's position, in line order (l = 1 … IJK).
    pub fn positions(&self) -> Vec<[f64; 3]> {
        let n: usize = self.counts.iter().product();
        (1..=n)
            .filter_map(|l| self.node(l))
            .map(|node| self.position(node))
            .collect()
    }

    /// Trilinear interpolation of node values `values` (line order) at `p_mm`; `None` outside
    /// the lattice (the table is undefined there). In the cell with lower node (i, j, k):
    /// f = Σ f(i+a, j+b, k+c) ξ^a (1−ξ)^(1−a) η^b (1−η)^(1−b) ζ^c (1−ζ)^(1−c).
    pub fn trilinear(&self, values: &[f64], p_mm: [f64; 3]) -> Option<f64> {
        let mut lower = [1usize; 3];
        let mut frac = [0.0; 3];
        for a in 0..3 {
            let t = (p_mm[a] - self.origin_mm[a]) / self.spacing_mm[a];
            let last = (self.counts[a] - 1) as f64;
            if t.is_nan() || t < -1e-9 || t > last + 1e-9 {
                return None;
            }
            let t = t.clamp(0.0, last);
            let cell = (t.floor() as usize).min(self.counts[a].saturating_sub(2));
            lower[a] = cell + 1;
            frac[a] = if self.counts[a] == 1 {
                0.0
            } else {
                t - cell as f64
            };
        }
        let mut f = 0.0;
        for c in 0..2 {
            for b in 0..2 {
                for a in 0..2 {
                    let off = [a, b, c];
                    let w: f64 = (0..3)
                        .map(|d| if off[d] == 1 { frac[d] } else { 1.0 - frac[d] })
                        .product();
                    if w == 0.0 {
                        continue;
                    }
                    let n = [0, 1, 2].map(|d| lower[d] + off[d]);
                    f += w * values[self.line(n[0], n[1], n[2])? - 1];
                }
            }
        }
        Some(f)
    }
}

/// Range (max − min) of values; 0 for none.
pub fn range(values: impl IntoIterator<Item = f64>) -> f64 {
    let (lo, hi) = values
        .into_iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    if lo.is_finite() {
        hi - lo
    } else {
        0.0
    }
}

/// V1 = √Σ_k [max D_k(k) − min D_k(k)]²: `positioning[k]` holds D_k(k) along axis k.
pub fn v1_um(positioning: &[Vec<f64>; 3]) -> f64 {
    positioning
        .iter()
        .map(|v| range(v.iter().copied()).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// V2 = √Σ_k [max D_k − min D_k]² over the grid's error vectors.
pub fn v2_um(errors: &[[f64; 3]]) -> f64 {
    (0..3)
        .map(|k| range(errors.iter().map(|e| e[k])).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// V3 = max over the grid of |e|.
pub fn v3_um(errors: &[[f64; 3]]) -> f64 {
    errors
        .iter()
        .map(|e| crate::volumetric::norm(*e))
        .fold(0.0, f64::max)
}
