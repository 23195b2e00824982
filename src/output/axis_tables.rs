//! The controller tables an `axis` run writes (`[tables]` of `pipelines/axis.toml`): the six
//! errors at each target, as the mean of the two directions of approach (ISO 230-2's x̄_j), in
//! the vendors' formats of [`super::controller`]. Each file states its sign and unit; a table the
//! format cannot hold (unequal steps for Siemens, too many points) is not written, and the
//! record says why, so the rest of the output stands.

use serde::Serialize;

use dbbcal_machine::axis_study::AxisStudy;
use dbbcal_machine::components::Axis;

use super::controller::{
    heidenhain_com, isg_csv, siemens_lec, AxisErrors, Component, ComponentErrors,
    HeidenhainComOptions, IsgCsvOptions, LineEnding, LinearAxis, NumberStyle, SiemensLecOptions,
    TableError, TableMeta, TableSign, SIEMENS_LEC_MAX_POINTS_CEILING,
};

/// A controller table format an `axis` run can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum AxisTableFormat {
    HeidenhainCom,
    SiemensLec,
    IsgCsv,
}

impl AxisTableFormat {
    pub(crate) const ALL: [AxisTableFormat; 3] = [
        AxisTableFormat::HeidenhainCom,
        AxisTableFormat::SiemensLec,
        AxisTableFormat::IsgCsv,
    ];

    pub(crate) fn name(self) -> &'static str {
        match self {
            AxisTableFormat::HeidenhainCom => "heidenhain-com",
            AxisTableFormat::SiemensLec => "siemens-lec",
            AxisTableFormat::IsgCsv => "isg-csv",
        }
    }

    pub(crate) fn parse(name: &str) -> Option<AxisTableFormat> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }
}

/// What the pipeline asks for: formats, sign, and the Siemens machine axis name.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AxisTablesPlan {
    pub(crate) formats: Vec<AxisTableFormat>,
    pub(crate) sign: TableSign,
    pub(crate) siemens_axis: String,
}

/// One table: written (its file in `tables/` and what it holds) or refused (why).
#[derive(Debug, Clone, Serialize)]
pub(crate) struct TableRecord {
    pub(crate) format: &'static str,
    /// `tables/<file>`, when written.
    pub(crate) file: Option<String>,
    pub(crate) meta: Option<TableMeta>,
    /// Why the table was not written.
    pub(crate) refused: Option<String>,
    #[serde(skip)]
    pub(crate) text: Option<String>,
}

fn linear_axis(axis: Axis) -> LinearAxis {
    match axis {
        Axis::X => LinearAxis::X,
        Axis::Y => LinearAxis::Y,
        Axis::Z => LinearAxis::Z,
    }
}

/// The errors at each target, the mean of the directions measured there, for every component
/// the readings determine at every target (a component lost at one target is left out: a
/// control table has no gaps).
pub(crate) fn axis_errors(study: &AxisStudy) -> AxisErrors {
    let mut positions: Vec<f64> = study.targets.iter().map(|t| t.target_mm).collect();
    positions.sort_by(f64::total_cmp);
    positions.dedup();
    let at = |x: f64, k: usize| -> f64 {
        let v: Vec<f64> = study
            .targets
            .iter()
            .filter(|t| t.target_mm == x)
            .map(|t| t.errors[k])
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let components = Component::ALL
        .into_iter()
        .filter_map(|c| {
            let values: Vec<f64> = positions.iter().map(|&x| at(x, c.index())).collect();
            values
                .iter()
                .all(|v| v.is_finite())
                .then_some(ComponentErrors {
                    component: c,
                    values,
                })
        })
        .collect();
    AxisErrors {
        axis: linear_axis(study.axis),
        positions_mm: positions,
        components,
    }
}

/// Every table the plan asks for, in its order.
pub(crate) fn axis_tables(study: &AxisStudy, plan: &AxisTablesPlan) -> Vec<TableRecord> {
    let errors = axis_errors(study);
    let letter = study.axis.letter();
    plan.formats
        .iter()
        .map(|&format| {
            let written: Result<(String, String, TableMeta), TableError> = match format {
                AxisTableFormat::HeidenhainCom => {
                    let o = HeidenhainComOptions {
                        sign: plan.sign,
                        table_name: letter.to_string(),
                        position_column: "AXISPOS".into(),
                        linear_decimals: 4,
                        angular_decimals: 7,
                        line_ending: LineEnding::CrLf,
                        max_points: 256,
                    };
                    heidenhain_com(&errors, &o).map(|t| (format!("{letter}.COM"), t, o.meta()))
                }
                AxisTableFormat::SiemensLec => {
                    let o = SiemensLecOptions {
                        sign: plan.sign,
                        machine_axis: plan.siemens_axis.clone(),
                        encoder: 0,
                        decimals: 4,
                        style: NumberStyle::Fixed,
                        max_points: SIEMENS_LEC_MAX_POINTS_CEILING,
                        line_ending: LineEnding::Lf,
                    };
                    siemens_lec(&errors, &o)
                        .map(|t| (format!("{}_EEC.INI", plan.siemens_axis), t, o.meta()))
                }
                AxisTableFormat::IsgCsv => {
                    let o = IsgCsvOptions {
                        sign: plan.sign,
                        linear_decimals: 4,
                        angular_decimals: 9,
                        style: NumberStyle::Fixed,
                        line_ending: LineEnding::Lf,
                    };
                    isg_csv(&errors, &o).map(|t| (format!("{letter}.csv"), t, o.meta()))
                }
            };
            match written {
                Ok((file, text, meta)) => TableRecord {
                    format: format.name(),
                    file: Some(format!("tables/{file}")),
                    meta: Some(meta),
                    refused: None,
                    text: Some(text),
                },
                Err(e) => TableRecord {
                    format: format.name(),
                    file: None,
                    meta: None,
                    refused: Some(e.to_string()),
                    text: None,
                },
            }
        })
        .collect()
}
