//! The controller tables an `axis` run writes (`[tables]` of `pipelines/axis.toml`): the six
//! errors at each target, as the mean of the two directions of approach (ISO 230-2's x̄_j), in
//! the vendors' formats of [`super::controller`]. Each file states its sign and unit; a table the
//! format cannot hold (unequal steps for Siemens, too many points) is not written, and the
//! record says why, so the rest of the output stands.

use serde::{Deserialize, Serialize};

use dbbcal_machine::axis_study::AxisStudy;
use dbbcal_machine::components::Axis;
use dbbcal_machine::device_test::DeviceTestResult;

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

/// No table.
impl Default for AxisTablesPlan {
    fn default() -> Self {
        AxisTablesPlan {
            formats: Vec::new(),
            sign: TableSign::Error,
            siemens_axis: default_siemens_axis(),
        }
    }
}

/// `[tables]`: controller compensation tables (`docs/controller-tables.md`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TablesSection {
    /// Format names of `AxisTableFormat`; empty: none.
    #[serde(default)]
    formats: Vec<String>,
    /// `error` or `correction` (= −error). No default: a table's sign is never silent.
    sign: Option<String>,
    /// The Siemens machine axis name (`$AA_ENC_COMP[0,N,<name>]`).
    #[serde(default = "default_siemens_axis")]
    siemens_axis: String,
}

impl Default for TablesSection {
    fn default() -> Self {
        TablesSection {
            formats: Vec::new(),
            sign: None,
            siemens_axis: default_siemens_axis(),
        }
    }
}

fn default_siemens_axis() -> String {
    "X1".into()
}

/// Why `[tables]` cannot be used: one line naming the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum TablesError {
    /// A format no controller table has.
    #[error("tables.formats[{index}]: {name:?} is not a controller table format (known: {})", AxisTableFormat::ALL.map(|f| f.name()).join(", "))]
    UnknownFormat { index: usize, name: String },
    /// A format listed twice.
    #[error("tables.formats[{index}]: {name:?} is listed twice")]
    Twice { index: usize, name: String },
    /// A sign that is neither `error` nor `correction`.
    #[error("tables.sign = {sign:?}: \"error\" (the value is measured − commanded) or \"correction\" (−error)")]
    UnknownSign { sign: String },
    /// Tables asked for without a sign.
    #[error("tables.sign is missing: say whether the tables hold the error (\"error\") or the correction (\"correction\"); the controls listed in docs/controller-tables.md want the error")]
    NoSign,
    /// A Siemens axis name that is not 1 to 16 letters, digits or `_`.
    #[error("tables.siemens_axis = {name:?}: 1 to 16 letters, digits or _")]
    SiemensAxis { name: String },
}

/// `[tables]` validated: known formats, each once, and a sign whenever a table is asked for.
pub(crate) fn tables_plan(t: &TablesSection) -> Result<AxisTablesPlan, TablesError> {
    let mut formats = Vec::new();
    for (index, name) in t.formats.iter().enumerate() {
        let f = AxisTableFormat::parse(name).ok_or_else(|| TablesError::UnknownFormat {
            index,
            name: name.clone(),
        })?;
        if formats.contains(&f) {
            return Err(TablesError::Twice {
                index,
                name: name.clone(),
            });
        }
        formats.push(f);
    }
    let sign = match (t.sign.as_deref(), formats.is_empty()) {
        (Some("error"), _) => TableSign::Error,
        (Some("correction"), _) => TableSign::Correction,
        (Some(other), _) => {
            return Err(TablesError::UnknownSign {
                sign: other.to_string(),
            })
        }
        (None, true) => TableSign::Error,
        (None, false) => return Err(TablesError::NoSign),
    };
    let name_ok = !t.siemens_axis.is_empty()
        && t.siemens_axis.len() <= 16
        && t.siemens_axis
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !name_ok {
        return Err(TablesError::SiemensAxis {
            name: t.siemens_axis.clone(),
        });
    }
    Ok(AxisTablesPlan {
        formats,
        sign,
        siemens_axis: t.siemens_axis.clone(),
    })
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
    let measured: Vec<(f64, [f64; 6])> = study
        .targets
        .iter()
        .map(|t| (t.target_mm, t.errors))
        .collect();
    mean_at_each_position(study.axis, &measured)
}

/// The six errors at each commanded position of `axis`, the mean of every measurement there
/// (positions within [`POSITION_TOLERANCE_MM`] are one), keeping only the components finite at
/// every position: a control table has no gaps.
fn mean_at_each_position(axis: Axis, measured: &[(f64, [f64; 6])]) -> AxisErrors {
    let mut positions: Vec<f64> = measured.iter().map(|(x, _)| *x).collect();
    positions.sort_by(f64::total_cmp);
    positions.dedup_by(|a, b| (*a - *b).abs() <= POSITION_TOLERANCE_MM);
    let mean = |x: f64, k: usize| -> f64 {
        let at: Vec<f64> = measured
            .iter()
            .filter(|(p, _)| (p - x).abs() <= POSITION_TOLERANCE_MM)
            .map(|(_, e)| e[k])
            .collect();
        at.iter().sum::<f64>() / at.len() as f64
    };
    let components = Component::ALL
        .into_iter()
        .filter_map(|c| {
            let values: Vec<f64> = positions.iter().map(|&x| mean(x, c.index())).collect();
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
        axis: linear_axis(axis),
        positions_mm: positions,
        components,
    }
}

/// Every table the plan asks for, in its order.
pub(crate) fn axis_tables(study: &AxisStudy, plan: &AxisTablesPlan) -> Vec<TableRecord> {
    tables_from(&axis_errors(study), plan)
}

/// The tables of a device test (`pipelines/device.toml`): the six errors at each station of the
/// moved axis, the mean of its evaluated dwells there (both directions, every run; the datum's
/// zeros are the datum station's measurement). A test that moved no single linear axis has no
/// table, and each record says so.
pub(crate) fn device_tables(test: &DeviceTestResult, plan: &AxisTablesPlan) -> Vec<TableRecord> {
    let Some(axis) = test.axis else {
        return plan
            .formats
            .iter()
            .map(|f| refused(*f, "the test moved no single linear axis".into()))
            .collect();
    };
    let evaluated: Vec<(f64, [f64; 6])> = test
        .dwells
        .iter()
        .filter_map(|d| Some((d.input.position_mm[axis.index()], d.errors?.to_array())))
        .collect();
    tables_from(&mean_at_each_position(axis, &evaluated), plan)
}

/// Commanded positions this close are one target or station (`device-format.md`: a station's
/// rows agree to 1 µm).
const POSITION_TOLERANCE_MM: f64 = 1e-3;

fn refused(format: AxisTableFormat, why: String) -> TableRecord {
    TableRecord {
        format: format.name(),
        file: None,
        meta: None,
        refused: Some(why),
        text: None,
    }
}

/// Every table the plan asks for, from `errors`, in the plan's order.
fn tables_from(errors: &AxisErrors, plan: &AxisTablesPlan) -> Vec<TableRecord> {
    let letter = errors.axis.letter();
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
                    heidenhain_com(errors, &o).map(|t| (format!("{letter}.COM"), t, o.meta()))
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
                    siemens_lec(errors, &o)
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
                    isg_csv(errors, &o).map(|t| (format!("{letter}.csv"), t, o.meta()))
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
                Err(e) => refused(format, e.to_string()),
            }
        })
        .collect()
}

/// The written tables' files, in `dir/tables/` (created when there is one).
pub(crate) fn write_tables(
    dir: &std::path::Path,
    tables: &[TableRecord],
) -> Result<(), super::OutputError> {
    let written: Vec<_> = tables
        .iter()
        .filter_map(|t| Some((t.file.as_ref()?, t.text.as_ref()?)))
        .collect();
    if !written.is_empty() {
        super::create_dir(&dir.join("tables"))?;
    }
    for (file, text) in written {
        super::write_file(&dir.join(file), text.as_bytes())?;
    }
    Ok(())
}
