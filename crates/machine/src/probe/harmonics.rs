//! The harmonic content of the directions' two-touch pretravel (`docs/spec/machine-physics.md`,
//! "Kind `probe`", "Not identifiable"): δ(φ) = h₀ + Σ_k [c_k cos kφ + s_k sin kφ], k = 1 … K,
//! solved by [`crate::linear`] so that what the directions cannot see is named (six equally
//! spaced directions: `h3_sin_um`, sin 3φ being zero at all six).

use crate::linear::{self, LinearError, LinearProblem};

/// One harmonic order.
#[derive(Debug, Clone, PartialEq)]
pub struct Harmonic {
    /// Order k (0: the mean).
    pub order: u32,
    /// Amplitude √(c² + s²), µm (h₀ for k = 0).
    pub amplitude_um: f64,
    /// U (k = 2) of the amplitude, µm; NaN where not determined.
    pub amplitude_u_k2_um: f64,
    /// Phase: δ_k = A cos k(φ − phase), degrees in [0, 360/k); NaN where not determined.
    pub phase_deg: f64,
    /// Whether both its cos and sin coefficients are determined.
    pub determined: bool,
}

/// The harmonic fit of the direction means.
#[derive(Debug, Clone, PartialEq)]
pub struct HarmonicFit {
    /// Orders 0 … K.
    pub harmonics: Vec<Harmonic>,
    /// What the directions cannot see, by name.
    pub lost: Vec<String>,
}

impl HarmonicFit {
    /// The harmonic of order `k`.
    pub fn order(&self, k: u32) -> Option<&Harmonic> {
        self.harmonics.iter().find(|h| h.order == k)
    }
}

/// Fit harmonics 0 … K to the values `v_um` (σ `u_um`, k = 1) at azimuths `phi_deg`;
/// K = (N − 1)/2 clamped to 3 … 6, so the 3rd harmonic is always asked for.
pub fn fit_harmonics(
    phi_deg: &[f64],
    v_um: &[f64],
    u_um: &[f64],
) -> Result<HarmonicFit, LinearError> {
    let max_order = (phi_deg.len().saturating_sub(1) / 2).clamp(3, 6) as u32;
    let mut names = vec!["h0_um".to_string()];
    for k in 1..=max_order {
        names.push(format!("h{k}_cos_um"));
        names.push(format!("h{k}_sin_um"));
    }
    let rows = phi_deg
        .iter()
        .map(|p| {
            let mut r = vec![1.0];
            for k in 1..=max_order {
                let a = f64::from(k) * p.to_radians();
                r.push(clean(a.cos()));
                r.push(clean(a.sin()));
            }
            r
        })
        .collect();
    let s = linear::solve(&LinearProblem {
        names,
        rows,
        observations: v_um.to_vec(),
        sigma: Some(u_um.iter().map(|u| u.max(1e-6)).collect()),
    })?;
    let cov = |i: usize, j: usize| s.covariance.as_ref().map_or(f64::NAN, |c| c[(i, j)]);
    let mut harmonics = vec![Harmonic {
        order: 0,
        amplitude_um: s.estimate[0],
        amplitude_u_k2_um: if s.determined[0] {
            2.0 * cov(0, 0).sqrt()
        } else {
            f64::NAN
        },
        phase_deg: f64::NAN,
        determined: s.determined[0],
    }];
    for k in 1..=max_order {
        let (ic, is) = (2 * k as usize - 1, 2 * k as usize);
        let determined = s.determined[ic] && s.determined[is];
        let (c, sn) = (s.estimate[ic], s.estimate[is]);
        let a = c.hypot(sn);
        let var = if a > 0.0 {
            (c * c * cov(ic, ic) + sn * sn * cov(is, is) + 2.0 * c * sn * cov(ic, is)) / (a * a)
        } else {
            0.5 * (cov(ic, ic) + cov(is, is))
        };
        let period = 360.0 / f64::from(k);
        harmonics.push(Harmonic {
            order: k,
            amplitude_um: if determined { a } else { f64::NAN },
            amplitude_u_k2_um: if determined {
                2.0 * var.sqrt()
            } else {
                f64::NAN
            },
            phase_deg: if determined {
                (sn.atan2(c).to_degrees() / f64::from(k)).rem_euclid(period)
            } else {
                f64::NAN
            },
            determined,
        });
    }
    Ok(HarmonicFit {
        harmonics,
        lost: s.lost.iter().map(|l| l.to_string()).collect(),
    })
}

/// A trigonometric value within 1e-12 of 0 is 0 (sin 180° is not 1.2e-16: six directions
/// must lose sin 3φ exactly).
fn clean(v: f64) -> f64 {
    if v.abs() < 1e-12 {
        0.0
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn six_directions_lose_sin_3phi_by_name_and_twelve_do_not() {
        let six: Vec<f64> = (0..6).map(|i| 60.0 * i as f64).collect();
        let v: Vec<f64> = six
            .iter()
            .map(|p| 1.0 + 0.5 * (3.0 * p.to_radians()).cos())
            .collect();
        let f = fit_harmonics(&six, &v, &[0.05; 6]).unwrap();
        assert!(
            f.lost.iter().any(|l| l.contains("h3_sin_um")),
            "{:?}",
            f.lost
        );
        assert!(!f.order(3).unwrap().determined);
        let twelve: Vec<f64> = (0..12).map(|i| 30.0 * i as f64).collect();
        let v: Vec<f64> = twelve
            .iter()
            .map(|p| {
                1.0 + 0.3 * (3.0 * (p - 20.0)).to_radians().cos()
                    + 1.4 * (p - 45.0).to_radians().cos()
            })
            .collect();
        let f = fit_harmonics(&twelve, &v, &[0.05; 12]).unwrap();
        let h3 = f.order(3).unwrap();
        assert!(h3.determined && (h3.amplitude_um - 0.3).abs() < 1e-9);
        assert!((h3.phase_deg - 20.0).abs() < 1e-6, "{}", h3.phase_deg);
        assert!((f.order(1).unwrap().amplitude_um - 1.4).abs() < 1e-9);
    }
}
