//! The simulation TOML of a `volumetric` campaign (`kind = "volumetric"`). Every section has
//! defaults: a 1000 × 600 × 500 mm machine, four body and four step diagonals, no effect on,
//! no diagonal read by a bar (`[bar] diagonals` empty).

use serde::Deserialize;

use crate::SimError;
use dbbcal_core::axis_campaign::LaserCompensation;
use dbbcal_core::volumetric_campaign::DiagonalSign;

/// The whole configuration.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumetricSimConfig {
    /// `"volumetric"`.
    pub kind: String,
    /// Seed of every random stream.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// `[campaign]`.
    #[serde(default)]
    pub campaign: CampaignConfig,
    /// `[machine]`.
    #[serde(default)]
    pub machine: MachineConfig,
    /// `[grid]`.
    #[serde(default)]
    pub grid: GridConfig,
    /// `[test]`.
    #[serde(default)]
    pub test: TestConfig,
    /// `[errors]`.
    #[serde(default)]
    pub errors: ErrorsConfig,
    /// `[laser]`.
    #[serde(default)]
    pub laser: LaserConfig,
    /// `[environment]`.
    #[serde(default)]
    pub environment: EnvironmentConfig,
    /// `[effects]`.
    #[serde(default)]
    pub effects: VolumetricEffectsConfig,
    /// `[output]`.
    #[serde(default)]
    pub output: OutputConfig,
    /// `[bar]`: body diagonals read by a bar in re-seated segments.
    #[serde(default)]
    pub bar: BarConfig,
}

fn default_seed() -> u64 {
    1
}

/// `[campaign]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CampaignConfig {
    /// Campaign id.
    pub id: String,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Start, RFC 3339.
    pub start: String,
}

impl Default for CampaignConfig {
    fn default() -> Self {
        CampaignConfig {
            id: "sim-volumetric".into(),
            reference_temperature_c: 20.0,
            start: "2027-01-15T08:00:00Z".into(),
        }
    }
}

/// `[machine]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MachineConfig {
    /// Workspace min corner, mm.
    pub min_mm: [f64; 3],
    /// Workspace max corner, mm.
    pub max_mm: [f64; 3],
    /// Scales' expansion, ppm/K.
    pub cte_ppm_per_k: f64,
}

impl Default for MachineConfig {
    fn default() -> Self {
        MachineConfig {
            min_mm: [0.0, 0.0, -500.0],
            max_mm: [1000.0, 600.0, 0.0],
            cte_ppm_per_k: 11.5,
        }
    }
}

/// `[grid]`: I, J, K over the whole workspace.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GridConfig {
    /// I, J, K.
    pub counts: [usize; 3],
}

impl Default for GridConfig {
    fn default() -> Self {
        GridConfig { counts: [3, 4, 3] }
    }
}

/// `[test]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TestConfig {
    /// The diagonals measured.
    pub diagonals: Vec<String>,
    /// Body diagonals measured.
    pub body: bool,
    /// Targets per body diagonal (intervals).
    pub targets: usize,
    /// Runs of each direction on a body diagonal.
    pub runs: usize,
    /// Steps N per step diagonal (0: none).
    pub steps: usize,
    /// Runs of each step diagonal.
    pub step_runs: usize,
    /// Time per reading, s.
    pub seconds_per_reading: f64,
}

impl Default for TestConfig {
    fn default() -> Self {
        TestConfig {
            diagonals: DiagonalSign::ALL
                .iter()
                .map(|d| d.as_str().to_string())
                .collect(),
            body: true,
            targets: 10,
            runs: 5,
            steps: 10,
            step_runs: 2,
            seconds_per_reading: 10.0,
        }
    }
}

/// `[errors]`: the true machine.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ErrorsConfig {
    /// Scale ε_k of each axis, µm/m.
    pub scale_um_per_m: [f64; 3],
    /// S_xy, S_yz, S_zx, µrad.
    pub squareness_urad: [f64; 3],
    /// Amplitude of the random shapes, µm.
    pub shape_um: f64,
    /// Amplitude of the angular errors' linear part, µrad (matter only with `[effects] abbe`).
    pub angular_urad: f64,
    /// Amplitude of their non-linear shapes (a quadratic and a sine), µrad; absent: 0.3 ×
    /// `angular_urad`. The analysis' Abbe term is bilinear (the linear part only).
    pub angular_shape_urad: Option<f64>,
}

impl Default for ErrorsConfig {
    fn default() -> Self {
        ErrorsConfig {
            scale_um_per_m: [6.0, -4.0, 3.0],
            squareness_urad: [20.0, -12.0, 8.0],
            shape_um: 2.0,
            angular_urad: 20.0,
            angular_shape_urad: None,
        }
    }
}

/// `[laser]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LaserConfig {
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// What the readings include.
    #[serde(with = "dbbcal_io::manifest::as_written::laser_compensation")]
    pub compensation: LaserCompensation,
    /// White noise per reading, µm.
    pub noise_um: f64,
}

impl Default for LaserConfig {
    fn default() -> Self {
        LaserConfig {
            wavelength_nm: 632.990577,
            compensation: LaserCompensation::Air,
            noise_um: 0.05,
        }
    }
}

/// `[environment]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvironmentConfig {
    /// Air at the start, °C.
    pub air_c: f64,
    /// Air drift, K/h.
    pub air_drift_k_per_h: f64,
    /// Pressure, hPa.
    pub pressure_hpa: f64,
    /// Humidity, %.
    pub humidity_pct: f64,
    /// Material, °C.
    pub material_c: f64,
}

impl Default for EnvironmentConfig {
    fn default() -> Self {
        EnvironmentConfig {
            air_c: 20.5,
            air_drift_k_per_h: 0.3,
            pressure_hpa: 1005.0,
            humidity_pct: 45.0,
            material_c: 20.8,
        }
    }
}

/// `[effects]`: each off by default.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct VolumetricEffectsConfig {
    /// |β| per diagonal, µrad.
    pub pointing_urad: f64,
    /// Machine drift rate, µm/h.
    pub drift_um_per_h: f64,
    /// Angular errors act through offsets (Abbe).
    pub abbe: bool,
    /// The tool's offset from the Z carriage, mm.
    pub tool_offset_mm: [f64; 3],
    /// Sag of Z with X, µm.
    pub non_rigid_sag_um: f64,
    /// The air sensor's error, K.
    pub air_sensor_error_k: f64,
}

/// `[bar]`: the body diagonals a calibrated bar reads instead of the laser
/// (`docs/bar-diagonals.md`), its segments and what disturbs it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BarConfig {
    /// The body diagonals the bar reads (the laser then reads only their step diagonals).
    pub diagonals: Vec<String>,
    /// The bar's id.
    pub id: String,
    /// The bar's centre distance at a segment's first target, mm.
    pub length_mm: f64,
    /// Targets along the diagonal (intervals: the step is D / targets).
    pub targets: usize,
    /// Intervals per segment.
    pub segment_intervals: usize,
    /// Intervals consecutive segments share (≥ 1: they share that many + 1 targets).
    pub overlap_intervals: usize,
    /// Runs of each direction per segment.
    pub runs: usize,
    /// The bar's calibrated scale u (k = 1), ppm; its true scale error is drawn from it.
    pub scale_u_ppm: f64,
    /// A socket's placement along the line: uniform within ±this, mm.
    pub socket_along_mm: f64,
    /// A socket's distance from the line: uniform within 0 … this, mm (declared as the
    /// misalignment bound).
    pub socket_across_mm: f64,
    /// White noise per reading, µm.
    pub noise_um: f64,
    /// Residue of the bar's thermal compensation: a random walk with steps uniform within
    /// ±this per reading, µm.
    pub residue_step_um: f64,
    /// The u each reading states (`u_um`), µm; absent: √(noise² + (5 · residue step)²); 0:
    /// the column is written null (u not known).
    pub reading_u_um: Option<f64>,
    /// Seconds to re-seat the fixed ball in the next socket.
    pub reseat_s: f64,
}

impl Default for BarConfig {
    fn default() -> Self {
        BarConfig {
            diagonals: Vec::new(),
            id: "B07".into(),
            length_mm: 300.0,
            targets: 90,
            segment_intervals: 10,
            overlap_intervals: 1,
            runs: 2,
            scale_u_ppm: 0.5,
            socket_along_mm: 1.0,
            socket_across_mm: 0.1,
            noise_um: 0.03,
            residue_step_um: 0.003,
            reading_u_um: None,
            reseat_s: 300.0,
        }
    }
}

impl BarConfig {
    /// The u written with each reading, µm (`None`: not written).
    pub(crate) fn stated_u_um(&self) -> Option<f64> {
        match self.reading_u_um {
            Some(u) if u > 0.0 => Some(u),
            Some(_) => None,
            None => Some(self.noise_um.hypot(5.0 * self.residue_step_um)),
        }
    }
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct OutputConfig {
    /// One file per diagonal.
    pub split_by_diagonal: bool,
    /// Shuffle rows.
    pub shuffle_rows: bool,
    /// Leave out `direction`.
    pub omit_direction: bool,
}

impl VolumetricSimConfig {
    pub(crate) fn validate(&self) -> Result<(), SimError> {
        let bad = |key: &str, reason: String| SimError::Invalid {
            key: key.into(),
            reason,
        };
        if self.kind != "volumetric" {
            return Err(bad(
                "kind",
                format!("is {:?}, not \"volumetric\"", self.kind),
            ));
        }
        for k in 0..3 {
            if self.machine.max_mm[k].is_nan() || self.machine.max_mm[k] <= self.machine.min_mm[k] {
                return Err(bad(
                    "machine.max_mm",
                    "must exceed min_mm on every axis".into(),
                ));
            }
            if self.grid.counts[k] < 2 {
                return Err(bad("grid.counts", "needs at least 2 nodes per axis".into()));
            }
        }
        if !self.test.body && self.test.steps == 0 && self.bar.diagonals.is_empty() {
            return Err(bad(
                "test",
                "measures nothing: set body = true or steps > 0".into(),
            ));
        }
        if self.test.body && (self.test.targets < 1 || self.test.runs < 2) {
            return Err(bad(
                "test",
                "body diagonals need targets ≥ 1 and runs ≥ 2".into(),
            ));
        }
        if self.laser.noise_um.is_nan() || self.laser.noise_um < 0.0 {
            return Err(bad("laser.noise_um", "must be ≥ 0".into()));
        }
        self.diagonal_signs()?;
        self.validate_bar()
    }

    fn validate_bar(&self) -> Result<(), SimError> {
        let b = &self.bar;
        let bad = |key: &str, reason: &str| SimError::Invalid {
            key: format!("bar.{key}"),
            reason: reason.into(),
        };
        self.bar_signs()?;
        if b.diagonals.is_empty() {
            return Ok(());
        }
        if b.targets < 2 || b.segment_intervals < 2 {
            return Err(bad(
                "targets",
                "targets and segment_intervals must each be ≥ 2",
            ));
        }
        if b.overlap_intervals < 1 || b.overlap_intervals >= b.segment_intervals {
            return Err(bad(
                "overlap_intervals",
                "must be ≥ 1 (segments must share targets) and below segment_intervals",
            ));
        }
        if b.runs < 2 {
            return Err(bad("runs", "needs ≥ 2 runs per direction (ISO 230-2)"));
        }
        for (key, v) in [
            ("length_mm", b.length_mm),
            ("scale_u_ppm", b.scale_u_ppm),
            ("socket_along_mm", b.socket_along_mm),
            ("socket_across_mm", b.socket_across_mm),
            ("noise_um", b.noise_um),
            ("residue_step_um", b.residue_step_um),
            ("reseat_s", b.reseat_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(key, "must be a finite number ≥ 0"));
            }
        }
        if b.length_mm <= 2.0 * b.socket_along_mm {
            return Err(bad("length_mm", "must exceed twice socket_along_mm"));
        }
        Ok(())
    }

    pub(crate) fn bar_signs(&self) -> Result<Vec<DiagonalSign>, SimError> {
        self.bar
            .diagonals
            .iter()
            .map(|w| {
                DiagonalSign::parse(w).ok_or_else(|| SimError::Invalid {
                    key: "bar.diagonals".into(),
                    reason: format!("{w:?} is not +++, -++, +-+ or ++-"),
                })
            })
            .collect()
    }

    pub(crate) fn diagonal_signs(&self) -> Result<Vec<DiagonalSign>, SimError> {
        self.test
            .diagonals
            .iter()
            .map(|w| {
                DiagonalSign::parse(w).ok_or_else(|| SimError::Invalid {
                    key: "test.diagonals".into(),
                    reason: format!("{w:?} is not +++, -++, +-+ or ++-"),
                })
            })
            .collect()
    }

    pub(crate) fn start_ns(&self) -> i64 {
        chrono::DateTime::parse_from_rfc3339(&self.campaign.start)
            .map(|t| t.timestamp_nanos_opt().unwrap_or(0))
            .unwrap_or(1_800_000_000_000_000_000)
    }
}
