//! The `roll` campaign kind (`docs/spec/machine-formats.md`, "Kind roll"; seed 004): four
//! probes A, B, C, D in a fixture above a sensing surface that rides on the stage. Types only,
//! no IO.
//!
//! [`RollManifest`] is its `campaign.toml` as declared, one field a key (the TOML text is
//! `dbbcal_io::manifest`'s);
//! [`RollCampaign`] is the validated form ([`RollCampaign::from_manifest_at`]), every error one
//! line naming the file and the key. The logs as plain data ([`ProbeSample`], [`LevelRow`],
//! [`RollCampaignLogs`]) are handed over by `dbbcal_io::read_roll_campaign`; what the analysis
//! derives from them (dwells, stations, passes) is in `dbbcal_machine::roll`.

use crate::axis_campaign::{CampaignKind, KindSection, MachineAxis};
use crate::campaign::{check_campaign_id, limits, CampaignError, TimeNs};
use crate::limits::Limit;
use crate::series::InputFile;

/// The probes, in the order of the spec (and of the `m_a` … `m_d` columns).
pub const PROBES: [&str; 4] = ["A", "B", "C", "D"];

/// `campaign.toml` of a `roll` campaign as declared, not yet validated.
#[derive(Debug, Clone, PartialEq)]
pub struct RollManifest {
    /// `[campaign]`: kind, id, T0.
    pub campaign: KindSection,
    /// `[roll]`: the rig.
    pub roll: RollSection,
}

/// The unit of the probe readings (`[roll] unit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadingUnit {
    /// Micrometres of surface rise.
    Um,
    /// Volts, times each probe's `um_per_v`.
    Volt,
}

/// `[roll]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RollSection {
    /// The machine axis the stage moves along.
    pub axis: MachineAxis,
    /// Across: A–C and B–D, mm.
    pub l_mm: f64,
    /// Along: A–B and C–D, mm.
    pub d_mm: f64,
    /// Step between stations, mm; must equal `d_mm`.
    pub s_mm: f64,
    /// Sign of the `x_mm` change that carries the surface from under B to under A.
    pub b_to_a: i64,
    /// Unit of `m_a` … `m_d`.
    pub unit: ReadingUnit,
    /// Dwell detection (without `station`): the shortest dwell, s.
    pub dwell_min_s: f64,
    /// Dwell detection: half the band `x_mm` stays within, µm.
    pub dwell_tol_um: f64,
    /// `[[roll.probe]]`, one per probe A, B, C, D.
    pub probe: Vec<ProbeDecl>,
}

/// `[[roll.probe]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeDecl {
    /// `A`, `B`, `C` or `D`.
    pub id: String,
    /// Standard uncertainty of each coordinate of the probe centre, µm.
    pub u_xy_um: f64,
    /// Signed surface rise per volt, µm/V (used when `unit = "V"`).
    pub um_per_v: f64,
    /// Measured position in R, mm; absent: the nominal one.
    pub xy_mm: Option<[f64; 2]>,
}

/// One validated probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// Standard uncertainty of each coordinate of its centre, µm.
    pub u_xy_um: f64,
    /// µm of surface rise per unit of reading (1 for `um`, `um_per_v` for `V`).
    pub um_per_unit: f64,
    /// Its centre in R, mm (measured if given, else nominal).
    pub xy_mm: [f64; 2],
    /// Whether `xy_mm` was measured.
    pub measured: bool,
}

/// A validated `roll` campaign manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct RollCampaign {
    /// The campaign's id.
    pub id: String,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// The axis the stage moves along.
    pub axis: MachineAxis,
    /// A–C and B–D, mm.
    pub l_mm: f64,
    /// A–B and C–D, mm.
    pub d_mm: f64,
    /// The step between stations, mm (= `d_mm`).
    pub s_mm: f64,
    /// +1 or −1.
    pub b_to_a: i8,
    /// Unit of the readings.
    pub unit: ReadingUnit,
    /// Shortest dwell, s.
    pub dwell_min_s: f64,
    /// Half band of a dwell, µm.
    pub dwell_tol_um: f64,
    /// A, B, C, D.
    pub probes: [Probe; 4],
}

/// Ranges of the `roll` manifest's numbers.
pub mod roll_limits {
    use crate::limits::Limit;
    /// `L_mm`, `d_mm`, `s_mm`.
    pub(crate) const SPACING_MM: Limit = Limit::above(0.0, 2_000.0, "mm");
    /// `dwell_min_s`.
    pub(crate) const DWELL_MIN_S: Limit = Limit::above(0.0, 3_600.0, "s");
    /// `dwell_tol_um`.
    pub(crate) const DWELL_TOL_UM: Limit = Limit::above(0.0, 10_000.0, "µm");
    /// `um_per_v`: a magnitude from 1 nm/V to 10 mm/V, either sign.
    pub(crate) const UM_PER_V_ABS: Limit = Limit::closed(1e-3, 1e4, "µm/V");
    /// `xy_mm` coordinates.
    pub(crate) const XY_MM: Limit = Limit::closed(-2_000.0, 2_000.0, "mm");
    /// How far `s_mm` may be from `d_mm` (rounding of a written number), mm.
    pub(crate) const S_EQUALS_D_MM: f64 = 1e-6;
}

impl RollCampaign {
    /// The nominal centre of probe `k` (A, B, C, D) in R, mm.
    pub(crate) fn nominal_xy_mm(k: usize, l_mm: f64, d_mm: f64) -> [f64; 2] {
        [[0.0, 0.0], [d_mm, 0.0], [0.0, l_mm], [d_mm, l_mm]][k]
    }

    /// Validates a manifest, naming `file` in messages.
    pub fn from_manifest_at(m: RollManifest, file: &str) -> Result<RollCampaign, CampaignError> {
        let invalid = |key: &str, problem: String| CampaignError::Invalid {
            file: file.to_string(),
            key: key.to_string(),
            problem,
        };
        let check = |key: &str, value: f64, limit: Limit| {
            let short = key.rsplit('.').next().unwrap_or(key);
            limit
                .check(short, value)
                .map_err(|e| invalid(key, e.to_string()))
        };
        if m.campaign.kind != CampaignKind::Roll {
            return Err(invalid(
                "campaign.kind",
                format!(
                    "is {:?}, this manifest is read as \"roll\"",
                    m.campaign.kind.as_str()
                ),
            ));
        }
        check_campaign_id(&m.campaign.id).map_err(|p| invalid("campaign.id", p.to_string()))?;
        check(
            "campaign.reference_temperature_c",
            m.campaign.reference_temperature_c,
            limits::REFERENCE_TEMPERATURE_C,
        )?;
        let r = &m.roll;
        check("roll.L_mm", r.l_mm, roll_limits::SPACING_MM)?;
        check("roll.d_mm", r.d_mm, roll_limits::SPACING_MM)?;
        check("roll.s_mm", r.s_mm, roll_limits::SPACING_MM)?;
        if (r.s_mm - r.d_mm).abs() > roll_limits::S_EQUALS_D_MM {
            return Err(invalid(
                "roll.s_mm",
                format!(
                    "= {} mm differs from d_mm = {} mm: the estimator needs the step between stations to equal the probe spacing along the axis (docs/spec/machine-formats.md, \"Kind roll\")",
                    r.s_mm, r.d_mm
                ),
            ));
        }
        if r.b_to_a != 1 && r.b_to_a != -1 {
            return Err(invalid(
                "roll.b_to_a",
                format!("= {} must be +1 or -1", r.b_to_a),
            ));
        }
        check("roll.dwell_min_s", r.dwell_min_s, roll_limits::DWELL_MIN_S)?;
        check(
            "roll.dwell_tol_um",
            r.dwell_tol_um,
            roll_limits::DWELL_TOL_UM,
        )?;
        let mut probes: [Option<Probe>; 4] = [None; 4];
        for (i, p) in r.probe.iter().enumerate() {
            let key = format!("roll.probe[{i}]");
            let Some(k) = PROBES.iter().position(|&id| id == p.id) else {
                return Err(invalid(
                    &format!("{key}.id"),
                    format!("{:?} is not a probe of the rig (A, B, C or D)", p.id),
                ));
            };
            if probes[k].is_some() {
                return Err(CampaignError::DuplicateId {
                    file: file.to_string(),
                    table: "roll.probe",
                    id: p.id.clone(),
                    first: r.probe.iter().position(|q| q.id == p.id).unwrap_or(0),
                    second: i,
                });
            }
            check(&format!("{key}.u_xy_um"), p.u_xy_um, limits::U_UM)?;
            if !roll_limits::UM_PER_V_ABS.contains(p.um_per_v.abs()) {
                return Err(invalid(
                    &format!("{key}.um_per_v"),
                    format!(
                        "= {} is out of range: its magnitude must be {} (either sign)",
                        p.um_per_v,
                        roll_limits::UM_PER_V_ABS.describe()
                    ),
                ));
            }
            let nominal = Self::nominal_xy_mm(k, r.l_mm, r.d_mm);
            let xy = p.xy_mm.unwrap_or(nominal);
            for v in xy {
                check(&format!("{key}.xy_mm"), v, roll_limits::XY_MM)?;
            }
            probes[k] = Some(Probe {
                u_xy_um: p.u_xy_um,
                um_per_unit: match r.unit {
                    ReadingUnit::Um => 1.0,
                    ReadingUnit::Volt => p.um_per_v,
                },
                xy_mm: xy,
                measured: p.xy_mm.is_some(),
            });
        }
        let missing: Vec<&str> = (0..4)
            .filter(|&k| probes[k].is_none())
            .map(|k| PROBES[k])
            .collect();
        if !missing.is_empty() {
            return Err(invalid(
                "roll.probe",
                format!(
                    "declares no probe {}: the rig needs one [[roll.probe]] for each of A, B, C, D",
                    missing.join(", ")
                ),
            ));
        }
        Ok(RollCampaign {
            id: m.campaign.id,
            reference_temperature_c: m.campaign.reference_temperature_c,
            axis: r.axis,
            l_mm: r.l_mm,
            d_mm: r.d_mm,
            s_mm: r.s_mm,
            b_to_a: r.b_to_a as i8,
            unit: r.unit,
            dwell_min_s: r.dwell_min_s,
            dwell_tol_um: r.dwell_tol_um,
            probes: probes.map(|p| p.expect("every probe checked above")),
        })
    }
}

/// One row of `probes/*.parquet`, as read (readings in the file's unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeSample {
    /// Sample time, ns since the epoch (UTC).
    pub time_ns: TimeNs,
    /// Stage position, mm.
    pub x_mm: f64,
    /// `m_a`, `m_b`, `m_c`, `m_d`, in `[roll] unit`.
    pub m: [f64; 4],
    /// `station`: marks a dwell (`None`: moving, or the column is absent).
    pub station: Option<i64>,
    /// `pass`, from 1 (`None`: the column is absent).
    pub pass: Option<i64>,
    /// Which file (index into the files read, in path order) and row it came from.
    pub source: (u32, u64),
}

/// One row of `levels/*.parquet`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelRow {
    /// When read, ns since the epoch.
    pub time_ns: TimeNs,
    /// Measuring level − reference level, µrad, signed as εx.
    pub roll_urad: f64,
    /// Its standard uncertainty, µrad (`None`: not stated).
    pub u_urad: Option<f64>,
    /// Which file and row it came from.
    pub source: (u32, u64),
}

/// Everything a `roll` campaign directory holds: what `dbbcal_io::read_roll_campaign` hands
/// over. Samples sorted by time (ties by file and row).
#[derive(Debug, Clone)]
pub struct RollCampaignLogs {
    /// The validated manifest.
    pub campaign: RollCampaign,
    /// Every file read (manifest first), with its hash, sorted by path.
    pub inputs: Vec<InputFile>,
    /// `probes/*.parquet` files, in the order of [`ProbeSample::source`]'s index.
    pub probe_files: Vec<String>,
    /// `levels/*.parquet` files, in the order of [`LevelRow::source`]'s index.
    pub level_files: Vec<String>,
    /// The samples, sorted by time.
    pub samples: Vec<ProbeSample>,
    /// Whether any file has a `station` column with a value.
    pub has_station: bool,
    /// Whether the files have a `pass` column.
    pub has_pass: bool,
    /// The level readings, sorted by time.
    pub levels: Vec<LevelRow>,
}

/// The tables of a `roll` campaign as plain rows: what the simulator produces and
/// `dbbcal_io::write_roll_campaign` writes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RollCampaignTables {
    /// `probes/*.parquet` rows.
    pub samples: Vec<ProbeSample>,
    /// Whether to write the `station` column.
    pub write_station: bool,
    /// Whether to write the `pass` column.
    pub write_pass: bool,
    /// `levels/*.parquet` rows (none: no levels folder).
    pub levels: Vec<LevelRow>,
}
