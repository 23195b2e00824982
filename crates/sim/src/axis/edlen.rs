//! The refractive index of air by the modified Edlén equation (Birch & Downs 1993, corrected
//! 1994), written from `docs/spec/machine-physics.md` ("Interferometer readings") for the
//! simulator alone: the analysis has its own implementation, so that the two check each other.

/// Saturation vapour pressure of water over a plane surface at `t_c` (°C), Pa (Magnus form of
/// the spec: 611.2 exp(17.62 t / (243.12 + t))).
pub(crate) fn saturation_pressure_pa(t_c: f64) -> f64 {
    611.2 * (17.62 * t_c / (243.12 + t_c)).exp()
}

/// n of air for vacuum wavelength `wavelength_nm`, air temperature `t_c` (°C), pressure
/// `pressure_hpa` and relative humidity `humidity_pct`.
pub(crate) fn refractive_index(
    wavelength_nm: f64,
    t_c: f64,
    pressure_hpa: f64,
    humidity_pct: f64,
) -> f64 {
    let sigma = 1e3 / wavelength_nm; // µm⁻¹
    let s2 = sigma * sigma;
    let n_s = (8342.54 + 2_406_147.0 / (130.0 - s2) + 15_998.0 / (38.9 - s2)) * 1e-8;
    let p = pressure_hpa * 100.0;
    let n_tp =
        p * n_s * (1.0 + 1e-8 * (0.601 - 0.00972 * t_c) * p) / (96_095.43 * (1.0 + 0.003661 * t_c));
    let f = humidity_pct / 100.0 * saturation_pressure_pa(t_c);
    1.0 + n_tp - f * (3.7345 - 0.0401 * s2) * 1e-10
}

#[cfg(test)]
mod tests {
    use super::*;

    const HENE_NM: f64 = 632.990577;

    #[test]
    fn the_spec_s_check_values_hold() {
        let n = refractive_index(HENE_NM, 20.0, 1013.25, 50.0);
        assert!(
            ((n - 1.0) - 271.375e-6).abs() < 0.002e-6,
            "n - 1 = {:e}",
            n - 1.0
        );
        let d = |dn: f64| dn * 1e6; // ppm
        let per_k = d(refractive_index(HENE_NM, 20.5, 1013.25, 50.0)
            - refractive_index(HENE_NM, 19.5, 1013.25, 50.0));
        assert!((per_k + 0.95).abs() < 0.01, "{per_k} ppm/K");
        let per_hpa = d(refractive_index(HENE_NM, 20.0, 1013.75, 50.0)
            - refractive_index(HENE_NM, 20.0, 1012.75, 50.0));
        assert!((per_hpa - 0.27).abs() < 0.005, "{per_hpa} ppm/hPa");
        let per_rh = d(refractive_index(HENE_NM, 20.0, 1013.25, 55.0)
            - refractive_index(HENE_NM, 20.0, 1013.25, 45.0))
            / 10.0;
        assert!((per_rh + 0.0085).abs() < 0.0005, "{per_rh} ppm/%RH");
    }
}
