//! `volumetric.json`, `volumetric_grid.parquet`, `volumetric_functions.parquet`,
//! `volumetric_bar.parquet` (the bar-read diagonals' stitched Dr) and the controller tables of a `volumetric` campaign (`docs/spec/machine-formats.md`, "Kind
//! volumetric"): the results as files, the record this module's own.

use serde::Serialize;

use crate::io::{Column, Table};
use crate::kinds::volumetric::Tolerances;
use crate::output::controller::{
    fanuc_3d, isg_csv, AxisErrors, Component, ComponentErrors, Fanuc3dOptions, GridErrors,
    IsgCsvOptions, LineEnding, LinearAxis, NumberStyle, TableSign,
};
use dbbcal_core::acceptance::{decide, Decision};
use dbbcal_core::series::InputFile;

use super::kind_record::KindRecordHead;
use dbbcal_core::volumetric_campaign::{TableValues, VolumetricCampaign};
use dbbcal_machine::volumetric::solve::Quantity;
use dbbcal_machine::volumetric::study::{
    BarCurve, Figure, ScaleTerms, VDiagBudget, VolumetricStudy,
};

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// One ISO 14253-1 decision: a figure against the user's tolerance.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct DecisionRecord {
    /// What is judged (`V2`, `S_xy` …).
    pub(crate) quantity: String,
    /// Its value, µm or µrad.
    pub(crate) value: Option<f64>,
    /// U (k = 2).
    pub(crate) u_k2: Option<f64>,
    /// The tolerance.
    pub(crate) tolerance: f64,
    /// pass / fail / no decision.
    pub(crate) decision: &'static str,
    /// Why, when the figure cannot be judged as measured.
    pub(crate) note: Option<String>,
}

/// The decisions for the tolerances given.
pub(crate) fn decisions(s: &VolumetricStudy, t: &Tolerances) -> Vec<DecisionRecord> {
    let mut out = Vec::new();
    let mut judge = |name: &str, f: Option<Figure>, tol: Option<f64>, seen: bool| {
        let Some(tol) = tol else { return };
        let (v, u) = f.map_or((f64::NAN, f64::NAN), |f| (f.value_um.abs(), f.u_k2_um));
        let d = if seen {
            decide(v, u, tol)
        } else {
            Decision::NoDecision
        };
        out.push(DecisionRecord {
            quantity: name.to_string(),
            value: finite(v),
            u_k2: finite(u),
            tolerance: tol,
            decision: d.as_str(),
            note: (!seen).then(|| {
                "depends on terms the readings cannot see (given in the stated gauge): no decision".to_string()
            }),
        });
    };
    judge("V_diag", s.v_diag, t.v_diag_um, true);
    judge("V1", Some(s.v1), t.v1_um, s.figures_identifiable);
    judge("V2", Some(s.v2), t.v2_um, s.figures_identifiable);
    judge("V3", Some(s.v3), t.v3_um, s.figures_identifiable);
    for q in &s.squareness {
        let f = Figure {
            value_um: q.value,
            u_k2_um: q.u_k2,
        };
        judge(
            &format!("|{}|", q.name),
            Some(f),
            t.squareness_urad,
            q.identifiable,
        );
    }
    out
}

/// The controller tables written, with what each states.
#[derive(Debug, Clone, Default)]
pub(crate) struct ControllerTables {
    /// (file name, text).
    pub(crate) files: Vec<(String, String)>,
    /// (file name, sign and unit in one sentence).
    pub(crate) statements: Vec<(String, String)>,
}

/// The FANUC 3-D table of the grid errors and the ISG CSV of each axis's three translational
/// functions.
pub(crate) fn controller_tables(
    c: &VolumetricCampaign,
    s: &VolumetricStudy,
) -> anyhow::Result<ControllerTables> {
    let mut t = ControllerTables::default();
    let grid = GridErrors {
        counts: s.grid.counts,
        errors_um: s
            .nodes
            .iter()
            .map(|n| n.error.clone().map(|q| q.value))
            .collect(),
    };
    let fanuc = Fanuc3dOptions {
        sign: match c.table.values {
            TableValues::Correction => TableSign::Correction,
            TableValues::Error => TableSign::Error,
        },
        n_base: c.table.n_base,
        unit_um: c.table.unit_um,
        max_abs_units: 99_999,
        line_ending: LineEnding::Lf,
    };
    t.files
        .push(("table_fanuc_3d.txt".into(), fanuc_3d(&grid, &fanuc)?));
    let unseen = if s.figures_identifiable {
        String::new()
    } else {
        "; WARNING: the grid's errors hold terms these readings cannot see, set by the stated gauge, not measured: do not load this table without measurements that see them".to_string()
    };
    t.statements.push((
        "table_fanuc_3d.txt".into(),
        format!("{}{unseen}", fanuc.meta().statement),
    ));
    let f = s.fit.functions();
    let isg = IsgCsvOptions {
        sign: TableSign::Error,
        linear_decimals: 5,
        angular_decimals: 9,
        style: NumberStyle::Fixed,
        line_ending: LineEnding::Lf,
    };
    for (j, axis) in [LinearAxis::X, LinearAxis::Y, LinearAxis::Z]
        .into_iter()
        .enumerate()
    {
        let errors = AxisErrors {
            axis,
            positions_mm: f[j][0].iter().map(|(q, _)| *q).collect(),
            components: [Component::Ex, Component::Ey, Component::Ez]
                .into_iter()
                .enumerate()
                .map(|(k, component)| ComponentErrors {
                    component,
                    values: f[j][k].iter().map(|(_, q)| q.value).collect(),
                })
                .collect(),
        };
        let name = format!("table_isg_{}.csv", axis.letter().to_ascii_lowercase());
        t.files.push((name.clone(), isg_csv(&errors, &isg)?));
        t.statements.push((
            name,
            format!(
                "{}; translational errors D_k({}) of the additive model at the step nodes, squareness inside the straightness slopes in the stated gauge",
                isg.meta().statement,
                axis.letter()
            ),
        ));
    }
    Ok(t)
}

#[derive(Debug, Serialize)]
struct QuantityRecord {
    name: String,
    value: Option<f64>,
    u_k2: Option<f64>,
    identifiable: bool,
}

impl From<&Quantity> for QuantityRecord {
    fn from(q: &Quantity) -> Self {
        QuantityRecord {
            name: q.name.clone(),
            value: finite(q.value),
            u_k2: finite(q.u_k2),
            identifiable: q.identifiable,
        }
    }
}

#[derive(Debug, Serialize)]
struct FigureRecord {
    value_um: Option<f64>,
    u_k2_um: Option<f64>,
}

impl From<Figure> for FigureRecord {
    fn from(f: Figure) -> Self {
        FigureRecord {
            value_um: finite(f.value_um),
            u_k2_um: finite(f.u_k2_um),
        }
    }
}

#[derive(Debug, Serialize)]
struct DiagonalRecord {
    diagonal: &'static str,
    source: &'static str,
    length_mm: f64,
    accuracy_a_um: Option<f64>,
    reversal_b_um: Option<f64>,
    repeatability_r_um: Option<f64>,
    systematic_e_um: Option<f64>,
    mean_range_m_um: Option<f64>,
    e_um: Option<f64>,
    undefined: Vec<String>,
    not_evaluated: Option<String>,
}

/// A body diagonal read by the bar (`docs/bar-diagonals.md`).
#[derive(Debug, Serialize)]
struct BarDiagonalRecord {
    diagonal: &'static str,
    bar: String,
    segments: usize,
    targets: usize,
    readings: usize,
    /// Whether every reading stated its u (else the covariance is the residuals').
    weighted: bool,
    weighted_rms: f64,
    dof: usize,
    normalised_to_t0: bool,
    scale_u_ppm: f64,
    max_misalignment_rad: f64,
    /// U (k = 2) of Dr at the far corner, µm, and its parts (k = 1).
    u_k2_far_corner_um: f64,
    far_corner_random_um: f64,
    far_corner_bar_scale_um: f64,
    far_corner_misalignment_um: f64,
    /// The bar's share (scale and misalignment) of U² at the far corner.
    bar_share_far_corner: f64,
    segment_constant_um: Vec<(i64, f64)>,
    /// The stitched curve: targets (mm from P0), Dr (µm) and its U (k = 2, µm).
    target_mm: Vec<f64>,
    dr_um: Vec<f64>,
    u_k2_um: Vec<f64>,
}

impl From<&BarCurve> for BarDiagonalRecord {
    fn from(b: &BarCurve) -> Self {
        let st = &b.stitched;
        let far = st.target_mm.len() - 1;
        let [random, scale, cosine] = st.difference_u_um(0, far);
        let all = random.powi(2) + scale.powi(2) + cosine.powi(2);
        BarDiagonalRecord {
            diagonal: b.sign.as_str(),
            bar: b.bar.clone(),
            segments: b.segments(),
            targets: st.target_mm.len(),
            readings: b.observations.len(),
            weighted: st.weighted,
            weighted_rms: st.weighted_rms,
            dof: st.dof,
            normalised_to_t0: b.normalised,
            scale_u_ppm: st.budget.scale_u_ppm,
            max_misalignment_rad: st.budget.max_misalignment_rad,
            u_k2_far_corner_um: st.u_k2_um[far],
            far_corner_random_um: random,
            far_corner_bar_scale_um: scale,
            far_corner_misalignment_um: cosine,
            bar_share_far_corner: if all > 0.0 {
                (scale.powi(2) + cosine.powi(2)) / all
            } else {
                0.0
            },
            segment_constant_um: st
                .segments
                .iter()
                .copied()
                .zip(st.segment_constant_um.iter().copied())
                .collect(),
            target_mm: st.target_mm.clone(),
            dr_um: st.dr_um.clone(),
            u_k2_um: st.u_k2_um.clone(),
        }
    }
}

/// Where V_diag's E lies and what its U (k = 1 parts) holds.
#[derive(Debug, Serialize)]
struct VDiagBudgetRecord {
    diagonal: &'static str,
    source: &'static str,
    d_max_mm: f64,
    d_min_mm: f64,
    span_mm: f64,
    random_um: f64,
    scale_um: f64,
    scale_u_ppm: f64,
    misalignment_um: f64,
    instrument_share: f64,
}

impl From<&VDiagBudget> for VDiagBudgetRecord {
    fn from(b: &VDiagBudget) -> Self {
        VDiagBudgetRecord {
            diagonal: b.diagonal.as_str(),
            source: b.source,
            d_max_mm: b.d_max_mm,
            d_min_mm: b.d_min_mm,
            span_mm: (b.d_max_mm - b.d_min_mm).abs(),
            random_um: b.random_um,
            scale_um: b.scale_um,
            scale_u_ppm: b.scale_u_ppm,
            misalignment_um: b.cosine_um,
            instrument_share: b.instrument_share(),
        }
    }
}

/// How the instruments' scales enter the mean scale and the squareness values.
#[derive(Debug, Serialize)]
struct ScaleTermsRecord {
    laser_u_ppm: f64,
    bar_u_ppm: f64,
    mean_scale_per_laser_ppm: f64,
    mean_scale_per_bar_ppm: f64,
    squareness_per_laser_ppm: [f64; 3],
    squareness_per_bar_ppm: [f64; 3],
}

impl From<&ScaleTerms> for ScaleTermsRecord {
    fn from(t: &ScaleTerms) -> Self {
        // A sensitivity of 1e-17 is the solve's rounding: written as 0 so that the bytes do
        // not depend on it.
        let clean = |v: f64| if v.abs() < 1e-9 { 0.0 } else { v };
        ScaleTermsRecord {
            laser_u_ppm: t.laser_u_ppm,
            bar_u_ppm: t.bar_u_ppm,
            mean_scale_per_laser_ppm: clean(t.mean_scale_per_laser_ppm),
            mean_scale_per_bar_ppm: clean(t.mean_scale_per_bar_ppm),
            squareness_per_laser_ppm: t.squareness_per_laser_ppm.map(clean),
            squareness_per_bar_ppm: t.squareness_per_bar_ppm.map(clean),
        }
    }
}

#[derive(Debug, Serialize)]
struct NaiveRecord {
    squareness_urad: Option<[f64; 3]>,
    scale_um_per_m: Option<[f64; 3]>,
    not_available: Option<String>,
}

#[derive(Debug, Serialize)]
struct CandidateRecord {
    effect: &'static str,
    physics: &'static str,
    delta_bic: f64,
    rms_after_um: f64,
    fourth_pattern_rms_after_um: Option<f64>,
}

/// `volumetric.json`.
#[derive(Debug, Serialize)]
pub(crate) struct VolumetricRecord {
    #[serde(flatten)]
    head: KindRecordHead,
    conventions: &'static str,
    readings: usize,
    model_effects: Vec<&'static str>,
    parameters: usize,
    rank: usize,
    lost: Vec<String>,
    gauge: Vec<String>,
    cannot_see: Vec<String>,
    diagonals: Vec<DiagonalRecord>,
    bar_diagonals: Vec<BarDiagonalRecord>,
    v_diag: Option<FigureRecord>,
    v_diag_budget: Option<VDiagBudgetRecord>,
    scale_terms: ScaleTermsRecord,
    bar_scale_vs_laser_ppm: Option<QuantityRecord>,
    squareness_urad: Vec<QuantityRecord>,
    mean_scale_um_per_m: QuantityRecord,
    slopes_um_per_m: Vec<QuantityRecord>,
    naive_inversion: NaiveRecord,
    fourth_pattern_rms_um: Option<(f64, f64)>,
    residual_rms_um: f64,
    residual_sigma_um: Option<f64>,
    v1: FigureRecord,
    v2: FigureRecord,
    v3: FigureRecord,
    figures_identifiable: bool,
    decisions: Vec<DecisionRecord>,
    tables: Vec<(String, String)>,
    diagnosis_proposal: Option<&'static str>,
    diagnosis_candidates: Vec<CandidateRecord>,
    diagnosis_path: Vec<(&'static str, f64)>,
}

impl VolumetricRecord {
    pub(crate) fn new(
        campaign: &str,
        (pipeline, sha): (&str, &str),
        inputs: &[InputFile],
        s: &VolumetricStudy,
        decisions: &[DecisionRecord],
        tables: &ControllerTables,
    ) -> VolumetricRecord {
        let diagonals = s
            .curves
            .iter()
            .map(|c| {
                let i = c.iso.as_ref().ok();
                DiagonalRecord {
                    diagonal: c.sign.as_str(),
                    source: c.source,
                    length_mm: c.length_mm,
                    accuracy_a_um: i.and_then(|i| i.accuracy_a_um),
                    reversal_b_um: i.and_then(|i| i.reversal_b_um),
                    repeatability_r_um: i.and_then(|i| i.repeatability_r_um),
                    systematic_e_um: i.and_then(|i| i.systematic_e_um),
                    mean_range_m_um: i.and_then(|i| i.mean_range_m_um),
                    e_um: c.e_um,
                    undefined: i.map(|i| i.undefined.clone()).unwrap_or_default(),
                    not_evaluated: c.iso.as_ref().err().map(ToString::to_string),
                }
            })
            .collect();
        VolumetricRecord {
            head: KindRecordHead::new("volumetric", campaign, (pipeline, sha), inputs),
            conventions: "error = measured - commanded, µm (displacements), µrad (squareness, slopes = µm/m); the tool relative to the workpiece in the machine frame M; e = 0 at the workspace's min corner",
            readings: s.observations.len(),
            model_effects: s.fit.layout.effects.iter().map(|e| e.name()).collect(),
            parameters: s.fit.layout.len(),
            rank: s.fit.rank,
            lost: s.fit.lost.clone(),
            gauge: s.fit.gauge.clone(),
            cannot_see: s.invisible.clone(),
            diagonals,
            bar_diagonals: s.bars.iter().map(BarDiagonalRecord::from).collect(),
            v_diag: s.v_diag.map(FigureRecord::from),
            v_diag_budget: s.v_diag_budget.as_ref().map(VDiagBudgetRecord::from),
            scale_terms: (&s.scale_terms).into(),
            bar_scale_vs_laser_ppm: s.bar_scale_vs_laser.as_ref().map(QuantityRecord::from),
            squareness_urad: s.squareness.iter().map(QuantityRecord::from).collect(),
            mean_scale_um_per_m: (&s.mean_scale).into(),
            slopes_um_per_m: s.slopes.iter().flatten().map(QuantityRecord::from).collect(),
            naive_inversion: match &s.naive {
                Ok(n) => NaiveRecord {
                    squareness_urad: Some(n.squareness_urad),
                    scale_um_per_m: Some(n.scale_um_per_m),
                    not_available: None,
                },
                Err(e) => NaiveRecord {
                    squareness_urad: None,
                    scale_um_per_m: None,
                    not_available: Some(e.to_string()),
                },
            },
            fourth_pattern_rms_um: s.fourth_rms_um,
            residual_rms_um: s.fit.rms_um,
            residual_sigma_um: finite(s.fit.sigma_um),
            v1: s.v1.into(),
            v2: s.v2.into(),
            v3: s.v3.into(),
            figures_identifiable: s.figures_identifiable,
            decisions: decisions.to_vec(),
            tables: tables.statements.clone(),
            diagnosis_proposal: s.diagnosis.proposal.map(|e| e.name()),
            diagnosis_candidates: s
                .diagnosis
                .candidates
                .iter()
                .map(|c| CandidateRecord {
                    effect: c.effect.name(),
                    physics: c.effect.physics(),
                    delta_bic: c.delta_bic,
                    rms_after_um: c.rms_after_um,
                    fourth_pattern_rms_after_um: c.fourth_rms_after_um,
                })
                .collect(),
            diagnosis_path: s.diagnosis.path.iter().map(|(e, r)| (e.name(), *r)).collect(),
        }
    }
}

/// `volumetric_grid.parquet`: one row per grid node (line order).
pub(crate) fn grid_table(s: &VolumetricStudy) -> Table {
    let n = &s.nodes;
    let mut t = Table::new()
        .with(
            "line",
            Column::I64(n.iter().map(|x| x.line as i64).collect()),
        )
        .with(
            "i",
            Column::I64(n.iter().map(|x| x.node[0] as i64).collect()),
        )
        .with(
            "j",
            Column::I64(n.iter().map(|x| x.node[1] as i64).collect()),
        )
        .with(
            "k",
            Column::I64(n.iter().map(|x| x.node[2] as i64).collect()),
        );
    for (a, name) in ["x_mm", "y_mm", "z_mm"].iter().enumerate() {
        t = t.with(
            *name,
            Column::F64(n.iter().map(|x| x.position_mm[a]).collect()),
        );
    }
    for (k, c) in ["x", "y", "z"].iter().enumerate() {
        t = t
            .with(
                format!("e{c}_um"),
                Column::F64(n.iter().map(|x| x.error[k].value).collect()),
            )
            .with(
                format!("e{c}_u_k2_um"),
                Column::F64(n.iter().map(|x| x.error[k].u_k2).collect()),
            );
    }
    t
}

/// `volumetric_functions.parquet`: D_k(j) at the nodes of axis j, with U (NaN where the value
/// is in the gauge), and its shape (less its least-squares line) with U.
pub(crate) fn functions_table(s: &VolumetricStudy) -> Table {
    let f = s.fit.functions();
    let shapes = s.fit.shapes();
    let (mut shape, mut shape_u) = (Vec::new(), Vec::new());
    for row in &shapes {
        for series in row {
            for (_, quantity) in series {
                shape.push(quantity.value);
                shape_u.push(quantity.u_k2);
            }
        }
    }
    let (mut name, mut axis, mut q, mut v, mut u, mut seen) = (
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
    );
    for (j, row) in f.iter().enumerate() {
        for (k, series) in row.iter().enumerate() {
            for (pos, quantity) in series {
                name.push(format!("D{}({})", ["x", "y", "z"][k], ["x", "y", "z"][j]));
                axis.push(["X", "Y", "Z"][j].to_string());
                q.push(*pos);
                v.push(quantity.value);
                u.push(quantity.u_k2);
                seen.push(i64::from(quantity.identifiable));
            }
        }
    }
    Table::new()
        .with("function", Column::Str(name))
        .with("axis", Column::Str(axis))
        .with("position_mm", Column::F64(q))
        .with("error_um", Column::F64(v))
        .with("u_k2_um", Column::F64(u))
        .with("identifiable", Column::I64(seen))
        .with("shape_um", Column::F64(shape))
        .with("shape_u_k2_um", Column::F64(shape_u))
}

/// `volumetric_bar.parquet`: one row per bar-read diagonal and target: the stitched Dr and its
/// U (k = 2).
pub(crate) fn bar_table(s: &VolumetricStudy) -> Table {
    let (mut diagonal, mut bar, mut d, mut dr, mut u) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for b in &s.bars {
        let st = &b.stitched;
        for j in 0..st.target_mm.len() {
            diagonal.push(b.sign.as_str().to_string());
            bar.push(b.bar.clone());
            d.push(st.target_mm[j]);
            dr.push(st.dr_um[j]);
            u.push(st.u_k2_um[j]);
        }
    }
    Table::new()
        .with("diagonal", Column::Str(diagonal))
        .with("bar", Column::Str(bar))
        .with("distance_along_mm", Column::F64(d))
        .with("dr_um", Column::F64(dr))
        .with("u_k2_um", Column::F64(u))
}
