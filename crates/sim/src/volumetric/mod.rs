//! Simulated `volumetric` campaigns with known truth (`docs/spec/machine-physics.md`, "Kind
//! volumetric", "Common model"; `docs/spec/machine-formats.md`, "Kind volumetric"), written from
//! the spec independently of the analysis.
//!
//! **Truth.** Per axis J the three translational errors δ_J(q) (µm) are a scale (on the axis's
//! own component), squareness (all of S_xy in Dx(y), S_yz in Dy(z), S_zx in Dx(z): X is the
//! reference) and random shapes (a quadratic and a sine of random amplitude and phase, zero at
//! the min corner); the angular errors ε_J(q) (µrad) are random lines plus sines.
//! **Stacking** (stated, `machine-physics.md` asks it): workpiece → X → Y → Z → tool; the
//! functional point is at `tool_offset_mm` from the Z carriage, so the lever of axis J's angular
//! errors is a_J = tool offset + the coordinates of the axes it carries (X carries Y and Z, Y
//! carries Z): e(P) = Σ_J [δ_J(q_J) + 10⁻³ ε_J(q_J) × a_J(P)], switched on by
//! `[effects] abbe`; off, e(P) = Σ_J δ_J(q_J) (the additive model).
//! **Effects**: pointing β ⟂ u per diagonal (random direction, `pointing_urad`), machine drift
//! g(t) = rate · hours along a random unit vector, non-rigid sag Dz −= sag sin(π ξ) ζ,
//! an air-temperature sensor error. **Readings**: body Dr(d) = u·[e(P0 + d u, t) − e(P0, t_d)]
//! − β²/2 d (cosine); step r = u·[e(P, t) − e(P0, t_d)] + 10³ β·(P − P0); each as the laser
//! reads it under `compensation` (this crate's own Edlén), plus white noise.
//!
//! **Bar-read diagonals** (`[bar]`, [`BarConfig`], [`BarTruth`]; `bar.rs`): the body diagonals
//! a calibrated bar reads in re-seated segments instead of the laser, from the exact centre
//! distances.
//!
//! Written: the campaign, `truth.json` (the truth's squareness, scales, V1 … V3, the error at
//! each grid node, the true E of every diagonal measured and V_diag, and the bar's scale
//! error, sockets and true Dr) and `truth/volumetric_truth.parquet` (the grid's true errors).

mod bar;
mod config;
#[cfg(test)]
mod tests;

use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

pub use bar::{BarDiagonalTruth, BarTruth};
pub use config::{
    BarConfig, CampaignConfig, EnvironmentConfig, ErrorsConfig, GridConfig, LaserConfig,
    MachineConfig, OutputConfig, TestConfig, VolumetricEffectsConfig, VolumetricSimConfig,
};

use crate::axis::edlen::refractive_index;
use crate::{stream_rng, SimError};
use dbbcal_core::axis_campaign::{
    CampaignKind, EnvironmentRow, KindSection, LaserCompensation, MachineAxis,
};
use dbbcal_core::volumetric_campaign::{
    BarDiagonalSection, DiagonalReading, DiagonalSign, GridSection, LaserTarget, StepReading,
    TableSection, TableValues, VolumetricCampaignTables, VolumetricLaserSection,
    VolumetricMachineSection, VolumetricManifest, WorkspaceSection,
};

/// A simulated `volumetric` campaign.
#[derive(Debug, Clone)]
pub struct VolumetricSimulation {
    /// Its `campaign.toml`.
    pub manifest: VolumetricManifest,
    /// Its tables.
    pub tables: VolumetricCampaignTables,
    /// The truth.
    pub truth: VolumetricTruth,
}

/// What was simulated (`truth.json`).
#[derive(Debug, Clone, Serialize)]
pub struct VolumetricTruth {
    /// Scales ε_k = LS slope of D_k(k) over the step nodes, µm/m.
    pub scale_um_per_m: [f64; 3],
    /// S_xy, S_yz, S_zx as LS slopes over the step nodes, µrad.
    pub squareness_urad: [f64; 3],
    /// Σ L_k² ε_k / D², µm/m.
    pub mean_scale_um_per_m: f64,
    /// V1, V2, V3 of the true field on the grid (e = 0 at the min corner), µm.
    pub v1_um: f64,
    /// V2.
    pub v2_um: f64,
    /// V3.
    pub v3_um: f64,
    /// The true error vector at each grid node (line order), µm.
    pub grid_errors_um: Vec<[f64; 3]>,
    /// Pointing per diagonal, µrad (x, y, z components).
    pub pointing_urad: Vec<(String, [f64; 3])>,
    /// The effects switched on.
    pub effects: Vec<String>,
    /// The stacking order.
    pub stacking: &'static str,
    /// Per diagonal measured, the true E (max − min of the true Dr over the targets its
    /// instrument reads: the body targets, the bar's, or the step ends), µm.
    pub diagonal_e_um: Vec<(String, f64)>,
    /// The largest of them, µm.
    pub v_diag_um: Option<f64>,
    /// The bar, when `[bar] diagonals` names any.
    pub bar: Option<BarTruth>,
}

/// Whether a simulation TOML asks for a `volumetric` campaign (`kind = "volumetric"`).
pub fn is_volumetric_config(text: &str) -> bool {
    toml::from_str::<toml::Table>(text)
        .ok()
        .and_then(|t| {
            t.get("kind")
                .and_then(|k| k.as_str().map(|s| s == "volumetric"))
        })
        .unwrap_or(false)
}

/// Random streams of this simulator.
mod streams {
    pub(super) const TRUTH: u64 = 30_000;
    pub(super) const NOISE: u64 = 30_001;
    pub(super) const POINTING: u64 = 30_002;
    pub(super) const DRIFT: u64 = 30_003;
    pub(super) const BAR_SCALE: u64 = 30_004;
    pub(super) const BAR_SOCKETS: u64 = 30_005;
    pub(super) const BAR_NOISE: u64 = 30_006;
}

/// One error curve: a q + b q² + c (sin(ω q + φ) − sin φ), q normalised to 0 … 1.
#[derive(Debug, Clone, Copy)]
struct Curve {
    a: f64,
    b: f64,
    c: f64,
    w: f64,
    phi: f64,
}

impl Curve {
    fn at(&self, t: f64) -> f64 {
        self.a * t + self.b * t * t + self.c * ((self.w * t + self.phi).sin() - self.phi.sin())
    }

    fn random(rng: &mut impl Rng, line: f64, shape: f64) -> Curve {
        Curve {
            a: line * rng.gen_range(-1.0..1.0),
            b: shape * rng.gen_range(-1.0..1.0),
            c: shape * rng.gen_range(-1.0..1.0),
            w: rng.gen_range(2.0..7.0),
            phi: rng.gen_range(0.0..std::f64::consts::TAU),
        }
    }
}

/// The true machine.
struct Machine {
    min: [f64; 3],
    len: [f64; 3],
    /// δ: [J][k].
    delta: [[Curve; 3]; 3],
    /// Linear parts added on top: [J][k] µm/m.
    slope: [[f64; 3]; 3],
    /// ε: [J][r] µrad.
    eps: [[Curve; 3]; 3],
    abbe: bool,
    tool_mm: [f64; 3],
    sag_um: f64,
}

impl Machine {
    fn t(&self, j: usize, q: f64) -> f64 {
        (q - self.min[j]) / self.len[j]
    }

    fn error(&self, p: [f64; 3]) -> [f64; 3] {
        let mut e = [0.0; 3];
        for j in 0..3 {
            let t = self.t(j, p[j]);
            for (k, ek) in e.iter_mut().enumerate() {
                *ek += self.delta[j][k].at(t) + 1e-3 * self.slope[j][k] * (p[j] - self.min[j]);
            }
            if self.abbe {
                let mut lever = self.tool_mm;
                for m in (j + 1)..3 {
                    lever[m] += p[m] - self.min[m];
                }
                let eps = [0, 1, 2].map(|r| self.eps[j][r].at(t));
                let cross = [
                    eps[1] * lever[2] - eps[2] * lever[1],
                    eps[2] * lever[0] - eps[0] * lever[2],
                    eps[0] * lever[1] - eps[1] * lever[0],
                ];
                for (ek, c) in e.iter_mut().zip(cross) {
                    *ek += 1e-3 * c;
                }
            }
        }
        if self.sag_um != 0.0 {
            let xi = self.t(0, p[0]);
            let zeta = self.t(2, p[2]);
            e[2] -= self.sag_um * (std::f64::consts::PI * xi).sin() * zeta;
        }
        e
    }
}

fn diagonal(sign: DiagonalSign, min: [f64; 3], max: [f64; 3]) -> ([f64; 3], [f64; 3], f64) {
    let s = sign.signs();
    let p0 = [0, 1, 2].map(|k| if s[k] > 0.0 { min[k] } else { max[k] });
    let d = [0, 1, 2].map(|k| s[k] * (max[k] - min[k]));
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    (p0, d.map(|v| v / len), len)
}

/// Generates a campaign from `cfg`.
pub fn generate_volumetric(cfg: &VolumetricSimConfig) -> Result<VolumetricSimulation, SimError> {
    cfg.validate()?;
    let (min, max) = (cfg.machine.min_mm, cfg.machine.max_mm);
    let len = [0, 1, 2].map(|k| max[k] - min[k]);
    let mut rng = stream_rng(cfg.seed, streams::TRUTH);
    let e = &cfg.errors;
    let delta = [0, 1, 2].map(|_| [0, 1, 2].map(|_| Curve::random(&mut rng, 0.0, e.shape_um)));
    let eps_shape = e.angular_shape_urad.unwrap_or(0.3 * e.angular_urad);
    let eps =
        [0, 1, 2].map(|_| [0, 1, 2].map(|_| Curve::random(&mut rng, e.angular_urad, eps_shape)));
    let mut slope = [[0.0; 3]; 3];
    for (k, row) in slope.iter_mut().enumerate() {
        row[k] = e.scale_um_per_m[k];
    }
    slope[1][0] += e.squareness_urad[0]; // Dx(y)
    slope[2][1] += e.squareness_urad[1]; // Dy(z)
    slope[2][0] += e.squareness_urad[2]; // Dx(z)
    let fx = &cfg.effects;
    let machine = Machine {
        min,
        len,
        delta,
        slope,
        eps,
        abbe: fx.abbe,
        tool_mm: fx.tool_offset_mm,
        sag_um: fx.non_rigid_sag_um,
    };
    let mut prng = stream_rng(cfg.seed, streams::POINTING);
    let mut drng = stream_rng(cfg.seed, streams::DRIFT);
    let drift_dir = {
        let v = [0, 1, 2].map(|_| drng.gen_range(-1.0_f64..1.0));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
        v.map(|x| x / n)
    };
    let mut noise = stream_rng(cfg.seed, streams::NOISE);
    let normal = Normal::new(0.0, cfg.laser.noise_um.max(1e-12)).expect("σ > 0");
    let mut tables = VolumetricCampaignTables::default();
    let mut pointing = Vec::new();
    let start_ns = cfg.start_ns();
    let mut clock = 0.0_f64; // hours
    let dt_h = cfg.test.seconds_per_reading / 3600.0;
    let air = |hours: f64| cfg.environment.air_c + cfg.environment.air_drift_k_per_h * hours;
    let n_of = |hours: f64| {
        refractive_index(
            cfg.laser.wavelength_nm,
            air(hours),
            cfg.environment.pressure_hpa,
            cfg.environment.humidity_pct,
        )
    };
    let read = |true_mm: f64, hours: f64| -> f64 {
        let tm = cfg.environment.material_c;
        let alpha = cfg.machine.cte_ppm_per_k * 1e-6;
        let t0 = cfg.campaign.reference_temperature_c;
        let l_m = true_mm * (1.0 + alpha * (tm - t0));
        let opl = n_of(hours) * l_m;
        let n_s = refractive_index(
            cfg.laser.wavelength_nm,
            air(hours) + cfg.effects.air_sensor_error_k,
            cfg.environment.pressure_hpa,
            cfg.environment.humidity_pct,
        );
        match cfg.laser.compensation {
            LaserCompensation::None => opl,
            LaserCompensation::Air => opl / n_s,
            LaserCompensation::AirMaterial => opl / n_s / (1.0 + alpha * (tm - t0)),
        }
    };
    let g = |hours: f64| drift_dir.map(|v| v * fx.drift_um_per_h * hours);
    let bar_signs = cfg.bar_signs()?;
    for sign in cfg.diagonal_signs()? {
        let (p0, u, d_len) = diagonal(sign, min, max);
        let [a, b] = basis(u);
        let phi: f64 = prng.gen_range(0.0..std::f64::consts::TAU);
        let beta =
            [0, 1, 2].map(|k| fx.pointing_urad * 1e-6 * (phi.cos() * a[k] + phi.sin() * b[k]));
        pointing.push((sign.as_str().to_string(), beta.map(|v| v * 1e6)));
        let along = |p: [f64; 3], hours: f64, datum_h: f64| {
            let ep = machine.error(p);
            let e0 = machine.error(p0);
            let (gp, g0) = (g(hours), g(datum_h));
            (0..3)
                .map(|k| u[k] * (ep[k] + gp[k] - e0[k] - g0[k]))
                .sum::<f64>()
        };
        if cfg.test.body && !bar_signs.contains(&sign) {
            let datum_h = clock;
            for run in 1..=cfg.test.runs {
                for dir in [1i8, -1] {
                    for i in 0..=cfg.test.targets {
                        let i = if dir > 0 { i } else { cfg.test.targets - i };
                        let d = d_len * i as f64 / cfg.test.targets as f64;
                        let p = [0, 1, 2].map(|k| p0[k] + d * u[k]);
                        let beta2: f64 = beta.iter().map(|v| v * v).sum();
                        let true_dev = along(p, clock, datum_h) - beta2 / 2.0 * d * 1e3;
                        let dev = (read(d + true_dev * 1e-3, clock) - d) * 1e3
                            + normal.sample(&mut noise);
                        tables.diagonals.push(DiagonalReading {
                            time_ns: start_ns + (clock * 3.6e12) as i64,
                            diagonal: sign,
                            run: run as i64,
                            direction: dir,
                            target_mm: d,
                            deviation_um: dev,
                        });
                        clock += dt_h;
                    }
                }
            }
        }
        if cfg.test.steps > 0 {
            let datum_h = clock;
            let n = cfg.test.steps;
            for run in 1..=cfg.test.step_runs {
                let mut p = p0;
                let mut push =
                    |p: [f64; 3],
                     step: i64,
                     sub: Option<MachineAxis>,
                     clock: f64,
                     tables: &mut VolumetricCampaignTables| {
                        let rel = [0, 1, 2].map(|k| p[k] - p0[k]);
                        let c: f64 = (0..3).map(|k| u[k] * rel[k]).sum();
                        let b: f64 = (0..3).map(|k| beta[k] * rel[k]).sum::<f64>() * 1e3;
                        let true_dev = along(p, clock, datum_h) + b;
                        let dev = (read(c + true_dev * 1e-3, clock) - c) * 1e3
                            + normal.sample(&mut noise);
                        tables.steps.push(StepReading {
                            time_ns: start_ns + (clock * 3.6e12) as i64,
                            diagonal: sign,
                            run: run as i64,
                            step,
                            submove: sub,
                            position_mm: p,
                            deviation_um: dev,
                        });
                    };
                push(p, 0, None, clock, &mut tables);
                clock += dt_h;
                for s in 1..=n {
                    for j in 0..3 {
                        let end = p0[j] + u[j] * d_len;
                        p[j] = p0[j] + (end - p0[j]) * s as f64 / n as f64;
                        push(
                            p,
                            s as i64,
                            Some([MachineAxis::X, MachineAxis::Y, MachineAxis::Z][j]),
                            clock,
                            &mut tables,
                        );
                        clock += dt_h;
                    }
                }
            }
        }
    }
    let bar = if bar_signs.is_empty() {
        None
    } else {
        let b = &cfg.bar;
        let mut srng = stream_rng(cfg.seed, streams::BAR_SCALE);
        let scale_error_ppm = Normal::new(0.0, b.scale_u_ppm.max(1e-12))
            .expect("σ > 0")
            .sample(&mut srng);
        let mut bar_streams = bar::BarStreams {
            sockets: stream_rng(cfg.seed, streams::BAR_SOCKETS),
            noise: stream_rng(cfg.seed, streams::BAR_NOISE),
        };
        let mut bar_clock = bar::Clock {
            hours: clock,
            start_ns,
            drift: &g,
        };
        let diagonals = bar_signs
            .iter()
            .map(|sign| {
                bar::read_diagonal(
                    cfg,
                    &machine,
                    *sign,
                    scale_error_ppm * 1e-6,
                    &mut bar_streams,
                    &mut bar_clock,
                    &mut tables.bar_readings,
                )
            })
            .collect();
        clock = bar_clock.hours;
        Some(BarTruth {
            id: b.id.clone(),
            scale_error_ppm,
            scale_u_ppm: b.scale_u_ppm,
            diagonals,
        })
    };
    let end_h = clock;
    let steps = (end_h / 0.05).ceil().max(1.0) as usize;
    for i in 0..=steps {
        let h = end_h * i as f64 / steps as f64;
        tables.environment.push(EnvironmentRow {
            time_ns: start_ns + (h * 3.6e12) as i64,
            air_c: air(h) + cfg.effects.air_sensor_error_k,
            pressure_hpa: cfg.environment.pressure_hpa,
            humidity_pct: cfg.environment.humidity_pct,
            material_c: Some(cfg.environment.material_c),
            env_factor_ppm: None,
        });
    }
    let manifest = manifest(cfg, &tables);
    let truth = truth(cfg, &machine, pointing, bar)?;
    Ok(VolumetricSimulation {
        manifest,
        tables,
        truth,
    })
}

fn basis(u: [f64; 3]) -> [[f64; 3]; 2] {
    let a = [-u[1], u[0], 0.0];
    let n = (a[0] * a[0] + a[1] * a[1]).sqrt();
    let a = a.map(|v| v / n);
    let b = [
        u[1] * a[2] - u[2] * a[1],
        u[2] * a[0] - u[0] * a[2],
        u[0] * a[1] - u[1] * a[0],
    ];
    [a, b]
}

fn manifest(cfg: &VolumetricSimConfig, tables: &VolumetricCampaignTables) -> VolumetricManifest {
    let (min, max) = (cfg.machine.min_mm, cfg.machine.max_mm);
    let counts = cfg.grid.counts;
    VolumetricManifest {
        campaign: KindSection {
            kind: CampaignKind::Volumetric,
            id: cfg.campaign.id.clone(),
            reference_temperature_c: cfg.campaign.reference_temperature_c,
        },
        machine: VolumetricMachineSection {
            cte_ppm_per_k: cfg.machine.cte_ppm_per_k,
        },
        workspace: WorkspaceSection {
            min_mm: min,
            max_mm: max,
        },
        laser: (!tables.diagonals.is_empty() || !tables.steps.is_empty()).then_some(
            VolumetricLaserSection {
                wavelength_nm: cfg.laser.wavelength_nm,
                compensation: cfg.laser.compensation,
                dead_path_mm: None,
                target: LaserTarget::FlatMirror,
            },
        ),
        bar_diagonal: (!tables.bar_readings.is_empty()).then(|| BarDiagonalSection {
            bar: cfg.bar.id.clone(),
            scale_u_ppm: cfg.bar.scale_u_ppm,
            misalignment_mm: cfg.bar.socket_across_mm,
        }),
        grid: GridSection {
            i: counts[0],
            j: counts[1],
            k: counts[2],
            origin_mm: min,
            spacing_mm: [0, 1, 2].map(|k| (max[k] - min[k]) / (counts[k].max(2) - 1) as f64),
        },
        table: Some(TableSection {
            format: "fanuc-3d".into(),
            n_base: 100_000,
            unit_um: 1.0,
            values: TableValues::Correction,
        }),
        sensor: Vec::new(),
    }
}

fn ls_slope(q: &[f64], v: &[f64]) -> f64 {
    let n = q.len() as f64;
    let qm = q.iter().sum::<f64>() / n;
    let vm = v.iter().sum::<f64>() / n;
    let sxy: f64 = q.iter().zip(v).map(|(a, b)| (a - qm) * (b - vm)).sum();
    let sxx: f64 = q.iter().map(|a| (a - qm).powi(2)).sum();
    1e3 * sxy / sxx
}

/// The true E of each diagonal measured, on the targets its instrument reads.
fn diagonal_e(
    cfg: &VolumetricSimConfig,
    m: &Machine,
    bar: Option<&BarTruth>,
) -> Result<Vec<(String, f64)>, SimError> {
    let mut out = Vec::new();
    let laser = cfg.diagonal_signs()?;
    for sign in DiagonalSign::ALL {
        let by_bar = bar.and_then(|b| b.diagonals.iter().find(|d| d.diagonal == sign.as_str()));
        let intervals = if by_bar.is_some() {
            None
        } else if laser.contains(&sign) && cfg.test.body {
            Some(cfg.test.targets)
        } else if laser.contains(&sign) && cfg.test.steps > 0 {
            Some(cfg.test.steps)
        } else {
            None
        };
        let e = match (by_bar, intervals) {
            (Some(b), _) => b.e_um,
            (None, Some(n)) => {
                let (p0, u, d_len) = diagonal(sign, m.min, cfg.machine.max_mm);
                let e0 = m.error(p0);
                let dr: Vec<f64> = (0..=n)
                    .map(|i| {
                        let d = d_len * i as f64 / n as f64;
                        let e = m.error([0, 1, 2].map(|k| p0[k] + d * u[k]));
                        (0..3).map(|k| u[k] * (e[k] - e0[k])).sum()
                    })
                    .collect();
                dr.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                    - dr.iter().copied().fold(f64::INFINITY, f64::min)
            }
            (None, None) => continue,
        };
        out.push((sign.as_str().to_string(), e));
    }
    Ok(out)
}

fn truth(
    cfg: &VolumetricSimConfig,
    m: &Machine,
    pointing: Vec<(String, [f64; 3])>,
    bar: Option<BarTruth>,
) -> Result<VolumetricTruth, SimError> {
    let diagonal_e_um = diagonal_e(cfg, m, bar.as_ref())?;
    let v_diag_um = diagonal_e_um
        .iter()
        .map(|(_, e)| *e)
        .fold(None, |a: Option<f64>, e| Some(a.map_or(e, |a| a.max(e))));
    let n = cfg.test.steps.max(1);
    let slope = |k: usize, j: usize| {
        let q: Vec<f64> = (0..=n)
            .map(|i| m.min[j] + m.len[j] * i as f64 / n as f64)
            .collect();
        let v: Vec<f64> = q
            .iter()
            .map(|x| {
                let mut p = m.min;
                p[j] = *x;
                m.error(p)[k]
            })
            .collect();
        ls_slope(&q, &v)
    };
    let scale = [slope(0, 0), slope(1, 1), slope(2, 2)];
    let d2: f64 = m.len.iter().map(|l| l * l).sum();
    let counts = cfg.grid.counts;
    let mut grid = Vec::new();
    for k in 0..counts[2] {
        for j in 0..counts[1] {
            for i in 0..counts[0] {
                let idx = [i, j, k];
                let p = [0, 1, 2]
                    .map(|a| m.min[a] + m.len[a] * idx[a] as f64 / (counts[a].max(2) - 1) as f64);
                grid.push(m.error(p));
            }
        }
    }
    let range = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
            (l.min(x), h.max(x))
        });
        hi - lo
    };
    let v1 = (0..3)
        .map(|k| {
            range(&mut (0..=n).map(|i| {
                let mut p = m.min;
                p[k] += m.len[k] * i as f64 / n as f64;
                m.error(p)[k]
            }))
            .powi(2)
        })
        .sum::<f64>()
        .sqrt();
    let v2 = (0..3)
        .map(|k| range(&mut grid.iter().map(|e| e[k])).powi(2))
        .sum::<f64>()
        .sqrt();
    let v3 = grid
        .iter()
        .map(|e| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
        .fold(0.0, f64::max);
    let fx = &cfg.effects;
    let mut effects = Vec::new();
    for (on, name) in [
        (fx.pointing_urad != 0.0, "pointing"),
        (fx.drift_um_per_h != 0.0, "machine_drift"),
        (fx.abbe, "abbe"),
        (fx.non_rigid_sag_um != 0.0, "non_rigid"),
        (fx.air_sensor_error_k != 0.0, "air_sensor_error"),
    ] {
        if on {
            effects.push(name.to_string());
        }
    }
    Ok(VolumetricTruth {
        scale_um_per_m: scale,
        squareness_urad: [
            slope(1, 0) + slope(0, 1),
            slope(2, 1) + slope(1, 2),
            slope(0, 2) + slope(2, 0),
        ],
        mean_scale_um_per_m: (0..3).map(|k| m.len[k] * m.len[k] * scale[k]).sum::<f64>() / d2,
        v1_um: v1,
        v2_um: v2,
        v3_um: v3,
        grid_errors_um: grid,
        pointing_urad: pointing,
        effects,
        stacking: "workpiece -> X -> Y -> Z -> tool",
        diagonal_e_um,
        v_diag_um,
        bar,
    })
}

/// Writes the campaign and the truth into `dir`.
pub fn write_volumetric(
    sim: &VolumetricSimulation,
    dir: &std::path::Path,
    cfg: &VolumetricSimConfig,
) -> Result<(), SimError> {
    let opts = dbbcal_io::VolumetricWriteOptions {
        split_by_diagonal: cfg.output.split_by_diagonal,
        shuffle_rows: cfg.output.shuffle_rows,
        omit_direction: cfg.output.omit_direction,
        seed: cfg.seed,
    };
    dbbcal_io::write_volumetric_campaign(dir, &sim.manifest, &sim.tables, &opts)?;
    let folder = dir.join("truth");
    std::fs::create_dir_all(&folder).map_err(|source| SimError::Io {
        path: folder.display().to_string(),
        source,
    })?;
    let t = &sim.truth;
    let table = dbbcal_io::Table::new()
        .with(
            "line",
            dbbcal_io::Column::F64((1..=t.grid_errors_um.len()).map(|l| l as f64).collect()),
        )
        .with(
            "ex_um",
            dbbcal_io::Column::F64(t.grid_errors_um.iter().map(|e| e[0]).collect()),
        )
        .with(
            "ey_um",
            dbbcal_io::Column::F64(t.grid_errors_um.iter().map(|e| e[1]).collect()),
        )
        .with(
            "ez_um",
            dbbcal_io::Column::F64(t.grid_errors_um.iter().map(|e| e[2]).collect()),
        );
    dbbcal_io::write_table(&folder.join("volumetric_truth.parquet"), &table)?;
    let path = dir.join("truth.json");
    let mut json = serde_json::to_string_pretty(&serde_json::json!({ "volumetric": t }))?;
    json.push('\n');
    std::fs::write(&path, json).map_err(|source| SimError::Io {
        path: path.display().to_string(),
        source,
    })
}
