//! Air refraction by the modified Edlén equation and the normalisation of laser readings to a
//! true displacement at the reference temperature T0.
//!
//! Formulas: `docs/spec/machine-physics.md`, "Interferometer readings: `axis`, `volumetric`"
//! (Birch & Downs 1993, corrected 1994), with σ = 1/λ_vac in µm⁻¹, t in °C, p in Pa, f the
//! water-vapour partial pressure in Pa, f = RH/100 · p_sat(t), p_sat = 611.2 exp(17.62 t /
//! (243.12 + t)) (the spec's example, used here):
//!
//! ```text
//! (n − 1)_s  = [8342.54 + 2406147/(130 − σ²) + 15998/(38.9 − σ²)] · 1e-8
//! (n − 1)_tp = p (n − 1)_s [1 + 1e-8 (0.601 − 0.00972 t) p] / [96095.43 (1 + 0.003661 t)]
//! n          = 1 + (n − 1)_tp − f (3.7345 − 0.0401 σ²) · 1e-10
//! ```
//!
//! Readings, per `docs/spec/machine-formats.md` "Laser and environment" (`[laser]
//! compensation`) and machine-physics.md: a true displacement L of the machine at T_m reads
//! n L with `none`, L with `air`, L / (1 + α (T_m − T0)) with `air+material`. Dead path: after
//! air compensation a reading carries + L_dead (n(t) − n(t_datum)). The spec states that term
//! to first order (physically it is L_dead (n(t) − n(t_datum)) / n(t), 3e-4 relative of a
//! sub-micrometre term); this module takes the spec's form as the definition, so that
//! [`simulate_reading_mm`] and [`normalise_reading_mm`] are exact inverses *(ours)*:
//!
//! ```text
//! L_air  = r / n(t)           (none)     | r (air) | r (1 + α ΔT_m) (air+material)
//! L      = L_air − L_dead (n(t) − n(t_datum))
//! L_T0   = L / (1 + α ΔT_m),  ΔT_m = T_m − T0, α in ppm/K · 1e-6
//! ```

use std::fmt;
use std::str::FromStr;

/// Errors of the refraction and normalisation functions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EdlenError {
    /// An input is NaN or infinite.
    #[error("{0} is not finite")]
    NonFinite(&'static str),
    /// The vacuum wavelength is outside the equation's range (σ² must stay below 38.9 µm⁻²).
    #[error("wavelength {0} nm is outside the Edlén equation's range (> 161 nm)")]
    Wavelength(f64),
    /// Pressure must be positive.
    #[error("pressure {0} hPa is not positive")]
    Pressure(f64),
    /// Relative humidity must be in 0–100 %.
    #[error("relative humidity {0} % is not in 0..=100")]
    Humidity(f64),
    /// The compensation mode needs air data that were not given.
    #[error("compensation {compensation} needs {what}, which was not given")]
    Missing {
        /// The compensation mode.
        compensation: Compensation,
        /// What was missing.
        what: &'static str,
    },
    /// `[laser] compensation` is not one of `none`, `air`, `air+material`.
    #[error("unknown laser compensation {0:?} (none | air | air+material)")]
    UnknownCompensation(String),
}

/// What a laser reading already includes (`[laser] compensation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compensation {
    /// `"none"`: counted in vacuum wavelengths; the reading is n L.
    None,
    /// `"air"`: divided by the air's refractive index; the reading is L.
    Air,
    /// `"air+material"`: also normalised to T0; the reading is L / (1 + α (T_m − T0)).
    AirMaterial,
}

impl FromStr for Compensation {
    type Err = EdlenError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "none" => Ok(Compensation::None),
            "air" => Ok(Compensation::Air),
            "air+material" => Ok(Compensation::AirMaterial),
            other => Err(EdlenError::UnknownCompensation(other.to_string())),
        }
    }
}

impl fmt::Display for Compensation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Compensation::None => "none",
            Compensation::Air => "air",
            Compensation::AirMaterial => "air+material",
        })
    }
}

/// Air near the beam (one row of `environment`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Air {
    /// Air temperature, °C.
    pub temperature_c: f64,
    /// Air pressure, hPa.
    pub pressure_hpa: f64,
    /// Relative humidity, %.
    pub humidity_pct: f64,
}

/// Saturation vapour pressure of water over a plane water surface, Pa:
/// 611.2 exp(17.62 t / (243.12 + t)) (machine-physics.md's example formula).
pub fn saturation_vapour_pressure_pa(temperature_c: f64) -> f64 {
    611.2 * (17.62 * temperature_c / (243.12 + temperature_c)).exp()
}

/// Refractive index n of air by the modified Edlén equation (Birch & Downs 1993/1994).
pub fn refractive_index(air: &Air, wavelength_nm: f64) -> Result<f64, EdlenError> {
    let Air {
        temperature_c: t,
        pressure_hpa,
        humidity_pct,
    } = *air;
    for (v, what) in [
        (t, "temperature"),
        (pressure_hpa, "pressure"),
        (humidity_pct, "humidity"),
        (wavelength_nm, "wavelength"),
    ] {
        if !v.is_finite() {
            return Err(EdlenError::NonFinite(what));
        }
    }
    if pressure_hpa <= 0.0 {
        return Err(EdlenError::Pressure(pressure_hpa));
    }
    if !(0.0..=100.0).contains(&humidity_pct) {
        return Err(EdlenError::Humidity(humidity_pct));
    }
    let sigma = 1e3 / wavelength_nm; // µm⁻¹
    let s2 = sigma * sigma;
    if wavelength_nm <= 0.0 || s2 >= 38.9 {
        return Err(EdlenError::Wavelength(wavelength_nm));
    }
    let p = pressure_hpa * 100.0;
    let n_s = (8342.54 + 2_406_147.0 / (130.0 - s2) + 15998.0 / (38.9 - s2)) * 1e-8;
    let n_tp =
        p * n_s * (1.0 + 1e-8 * (0.601 - 0.00972 * t) * p) / (96095.43 * (1.0 + 0.003661 * t));
    let f = humidity_pct / 100.0 * saturation_vapour_pressure_pa(t);
    Ok(1.0 + n_tp - f * (3.7345 - 0.0401 * s2) * 1e-10)
}

/// The laser set-up of a campaign (`[laser]`, `[machine] cte_ppm_per_k`,
/// `reference_temperature_c`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserSetup {
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// What the readings already include.
    pub compensation: Compensation,
    /// Optics to reflector at the datum, mm; `None`: no dead-path correction.
    pub dead_path_mm: Option<f64>,
    /// Expansion coefficient of the machine's scales, ppm/K.
    pub cte_ppm_per_k: f64,
    /// T0, °C.
    pub reference_temperature_c: f64,
}

/// Conditions at one reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadingConditions {
    /// Air at the reading; needed unless `air+material` without dead path.
    pub air: Option<Air>,
    /// Air at the line's datum; needed for the dead-path correction.
    pub datum_air: Option<Air>,
    /// Machine (material) temperature T_m, °C; needed unless `air+material` without dead path.
    pub material_c: Option<f64>,
}

/// The parts of the model a reading needs: n(t), n(t_datum) (when a dead path is set) and
/// 1 + α (T_m − T0).
struct Factors {
    n: f64,
    dead_term_mm: f64,
    material: f64,
}

fn factors(setup: &LaserSetup, at: &ReadingConditions) -> Result<Factors, EdlenError> {
    let comp = setup.compensation;
    let need = |what| EdlenError::Missing {
        compensation: comp,
        what,
    };
    let n = match at.air {
        Some(a) => refractive_index(&a, setup.wavelength_nm)?,
        None => 1.0,
    };
    let dead_term_mm = match setup.dead_path_mm {
        Some(l) if l != 0.0 => {
            at.air
                .ok_or_else(|| need("air at the reading (dead path)"))?;
            let datum = at
                .datum_air
                .ok_or_else(|| need("air at the datum (dead path)"))?;
            l * (n - refractive_index(&datum, setup.wavelength_nm)?)
        }
        _ => 0.0,
    };
    if comp == Compensation::None && at.air.is_none() {
        return Err(need("air at the reading"));
    }
    let material = match at.material_c {
        Some(tm) => 1.0 + 1e-6 * setup.cte_ppm_per_k * (tm - setup.reference_temperature_c),
        None if comp == Compensation::AirMaterial && dead_term_mm == 0.0 => 1.0,
        None => return Err(need("the material temperature")),
    };
    if !(n.is_finite() && dead_term_mm.is_finite() && material.is_finite()) {
        return Err(EdlenError::NonFinite("reading conditions"));
    }
    Ok(Factors {
        n,
        dead_term_mm,
        material,
    })
}

/// The true displacement at T0 (mm) from a laser reading (mm, displacement since the line's
/// datum) taken with `setup.compensation`, removing the dead-path term when
/// `setup.dead_path_mm` is set.
pub fn normalise_reading_mm(
    reading_mm: f64,
    setup: &LaserSetup,
    at: &ReadingConditions,
) -> Result<f64, EdlenError> {
    let f = factors(setup, at)?;
    let air_compensated = match setup.compensation {
        Compensation::None => reading_mm / f.n,
        Compensation::Air => reading_mm,
        Compensation::AirMaterial => reading_mm * f.material,
    };
    Ok((air_compensated - f.dead_term_mm) / f.material)
}

/// What the laser reads (mm) for a true displacement at T0 (mm) under `setup` and `at`: the
/// forward model that [`normalise_reading_mm`] inverts (for simulators and tests).
pub fn simulate_reading_mm(
    true_displacement_t0_mm: f64,
    setup: &LaserSetup,
    at: &ReadingConditions,
) -> Result<f64, EdlenError> {
    let f = factors(setup, at)?;
    let air_compensated = true_displacement_t0_mm * f.material + f.dead_term_mm;
    Ok(match setup.compensation {
        Compensation::None => air_compensated * f.n,
        Compensation::Air => air_compensated,
        Compensation::AirMaterial => air_compensated / f.material,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HENE_NM: f64 = 632.990577;

    fn air(t: f64, p: f64, rh: f64) -> Air {
        Air {
            temperature_c: t,
            pressure_hpa: p,
            humidity_pct: rh,
        }
    }

    fn n(t: f64, p: f64, rh: f64) -> f64 {
        refractive_index(&air(t, p, rh), HENE_NM).unwrap()
    }

    #[test]
    fn the_spec_check_value() {
        let nm1 = (n(20.0, 1013.25, 50.0) - 1.0) * 1e6;
        // 271.375e-6 to the printed digits (computed 271.37521).
        assert!((nm1 - 271.375).abs() < 5e-4, "{nm1}");
    }

    #[test]
    fn the_spec_sensitivities() {
        let h = 1e-3;
        let dt = (n(20.0 + h, 1013.25, 50.0) - n(20.0 - h, 1013.25, 50.0)) / (2.0 * h) * 1e6;
        let dp = (n(20.0, 1013.25 + h, 50.0) - n(20.0, 1013.25 - h, 50.0)) / (2.0 * h) * 1e6;
        let dh = (n(20.0, 1013.25, 50.0 + h) - n(20.0, 1013.25, 50.0 - h)) / (2.0 * h) * 1e6;
        // Spec: −0.95 ppm/K at constant RH. Computed −0.9561: it agrees with the printed
        // digits truncated (rounded it would print −0.96; at constant vapour pressure −0.930).
        assert!((-0.96..-0.95).contains(&dt), "{dt}");
        assert!((dp - 0.27).abs() < 0.005, "{dp}");
        assert!((dh - (-0.0085)).abs() < 0.00005, "{dh}");
    }

    #[test]
    fn bad_air_is_refused() {
        assert_eq!(
            refractive_index(&air(20.0, 0.0, 50.0), HENE_NM),
            Err(EdlenError::Pressure(0.0))
        );
        assert_eq!(
            refractive_index(&air(20.0, 1000.0, 120.0), HENE_NM),
            Err(EdlenError::Humidity(120.0))
        );
        assert!(matches!(
            refractive_index(&air(20.0, 1000.0, 50.0), 100.0),
            Err(EdlenError::Wavelength(_))
        ));
        assert!(matches!(
            refractive_index(&air(f64::NAN, 1000.0, 50.0), HENE_NM),
            Err(EdlenError::NonFinite(_))
        ));
        assert!("vacuum".parse::<Compensation>().is_err());
    }

    #[test]
    fn every_compensation_mode_round_trips() {
        let at = ReadingConditions {
            air: Some(air(21.3, 987.0, 38.0)),
            datum_air: Some(air(20.6, 988.5, 41.0)),
            material_c: Some(23.1),
        };
        for mode in ["none", "air", "air+material"] {
            let compensation: Compensation = mode.parse().unwrap();
            assert_eq!(compensation.to_string(), mode);
            for dead_path_mm in [None, Some(150.0)] {
                let setup = LaserSetup {
                    wavelength_nm: HENE_NM,
                    compensation,
                    dead_path_mm,
                    cte_ppm_per_k: 11.5,
                    reference_temperature_c: 20.0,
                };
                for l in [-400.0, 0.0, 0.001, 250.0, 1000.0] {
                    let r = simulate_reading_mm(l, &setup, &at).unwrap();
                    let back = normalise_reading_mm(r, &setup, &at).unwrap();
                    assert!(
                        (back - l).abs() < 1e-12,
                        "{mode} {dead_path_mm:?} {l}: {back}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_reading_models_are_the_specs() {
        let a = air(20.0, 1013.25, 50.0);
        let at = ReadingConditions {
            air: Some(a),
            datum_air: None,
            material_c: Some(21.0),
        };
        let setup = |compensation| LaserSetup {
            wavelength_nm: HENE_NM,
            compensation,
            dead_path_mm: None,
            cte_ppm_per_k: 11.5,
            reference_temperature_c: 20.0,
        };
        let nn = n(20.0, 1013.25, 50.0);
        // A true 1000 mm at T_m = 21 °C is 1000 / (1 + 11.5e-6) mm at T0.
        let l_t0 = 1000.0 / (1.0 + 11.5e-6);
        let none = simulate_reading_mm(l_t0, &setup(Compensation::None), &at).unwrap();
        assert!((none - nn * 1000.0).abs() < 1e-9);
        let airc = simulate_reading_mm(l_t0, &setup(Compensation::Air), &at).unwrap();
        assert!((airc - 1000.0).abs() < 1e-9);
        let am = simulate_reading_mm(l_t0, &setup(Compensation::AirMaterial), &at).unwrap();
        assert!((am - l_t0).abs() < 1e-9);
        // 1 K of steel: 11.5 µm/m.
        assert!(((1000.0 - l_t0) * 1e3 - 11.5).abs() < 1e-3);
        // air+material without dead path needs no environment.
        let bare = ReadingConditions {
            air: None,
            datum_air: None,
            material_c: None,
        };
        assert_eq!(
            normalise_reading_mm(5.0, &setup(Compensation::AirMaterial), &bare),
            Ok(5.0)
        );
        assert!(matches!(
            normalise_reading_mm(5.0, &setup(Compensation::None), &bare),
            Err(EdlenError::Missing { .. })
        ));
    }

    #[test]
    fn dead_path_of_the_spec_table() {
        // 0.5 K over 0.2 m ≈ 0.1 µm (machine-physics.md, "Kind axis").
        let setup = LaserSetup {
            wavelength_nm: HENE_NM,
            compensation: Compensation::Air,
            dead_path_mm: Some(200.0),
            cte_ppm_per_k: 0.0,
            reference_temperature_c: 20.0,
        };
        let at = ReadingConditions {
            air: Some(air(20.5, 1013.25, 50.0)),
            datum_air: Some(air(20.0, 1013.25, 50.0)),
            material_c: Some(20.0),
        };
        let r = simulate_reading_mm(0.0, &setup, &at).unwrap();
        assert!((r * 1e3 - (-0.0956)).abs() < 0.001, "{}", r * 1e3);
    }
}
