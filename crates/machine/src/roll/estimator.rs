//! The seed's estimator (seed 004, eq. 10; `docs/spec/machine-physics.md`, "Kind roll",
//! "Estimator") on one pass of station means, and its uncertainty law.
//!
//! p(n+1) = 10³ {[m_C(n+1) − m_D(n)] − [m_A(n+1) − m_B(n)]} / L = εx(n+1) − εx(n) µrad, exact to
//! first order: the profiles f₁, f₂ (the surface under B at n is under A at n + 1), δz and εy
//! cancel. εx(n) = Σ_{i=1..n} p(i), εx(0) := 0. Consecutive p share no reading, so with u_m per
//! reading u(εx(n)) = 2·10³ u_m √n / L *(ours)*.
//!
//! The analysis (`roll::model`) solves the same equations as one weighted least-squares
//! problem over every pass (and the levels, and the effects); this explicit form is the
//! reference it is tested against.

/// The step p(i), µrad, from the means `m[k][probe]` (µm) at stations i − 1 and i.
pub fn step_urad(before: &[f64; 4], after: &[f64; 4], l_mm: f64) -> f64 {
    1e3 * ((after[2] - before[3]) - (after[0] - before[1])) / l_mm
}

/// εx(n), µrad, for n = 0 … N from the station means of one pass at consecutive stations
/// 0 … N (`means[n][probe]`, µm).
pub fn roll_urad(means: &[[f64; 4]], l_mm: f64) -> Vec<f64> {
    let mut eps = vec![0.0];
    for w in means.windows(2) {
        let last = *eps.last().unwrap_or(&0.0);
        eps.push(last + step_urad(&w[0], &w[1], l_mm));
    }
    eps
}

/// u(εx(n)) = 2·10³ u_m √n / L, µrad: the law of the estimator with u_m (µm) per reading.
pub fn u_law_urad(u_m_um: f64, n: usize, l_mm: f64) -> f64 {
    2e3 * u_m_um * (n as f64).sqrt() / l_mm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seed_experiment_gives_30_6_urad_at_station_18() {
        // 1 µm resolution: u_m = 1/√12 µm; L = 80 mm; 19 stations (seed §4.2).
        let u = u_law_urad(1.0 / 12f64.sqrt(), 18, 80.0);
        assert!((u - 30.6).abs() < 0.05, "{u}");
        assert!(
            (u - 30.0).abs() / 30.0 < 0.03,
            "the seed reports σ = 30 µrad"
        );
    }

    #[test]
    fn a_5_um_offset_on_c_adds_62_5_urad_per_station() {
        let flat = [[0.0; 4]; 19];
        let mut offset = flat;
        for m in &mut offset {
            m[2] += 5.0;
        }
        let e0 = roll_urad(&flat, 80.0);
        let e = roll_urad(&offset, 80.0);
        for n in 0..19 {
            assert_eq!(e[n] - e0[n], 62.5 * n as f64);
        }
    }
}
