//! Heidenhain KinematicsComp compensation table, `*.COM`: one row per compensation point, the
//! axis position and the six component errors of the axis in columns `C1` … `C6`.
//!
//! Sources (public fragments only; `docs/controller-tables.md` says what is assumed):
//! - iTNC 530 HSCI Technical Manual (07/2013), 6.4 "Axis-error compensation", KinematicsComp,
//!   "Recommendation for COM file" (p. 680): for a linear axis X, column C1 = EXX, C2 = EYX,
//!   C3 = EZX, C4 = EAX, C5 = EBX, C6 = ECX; the transformation chain's `COMPTAB` entries
//!   (`Trans Y A..C2`, p. 684) describe the actual machine, so the columns hold errors.
//! - MANUALplus 620 Technical Manual (p. 716): the `*.COM` position column `AXISPOS`, positions
//!   from the machine datum.
//! - TNC 407 Technical Manual 1.6.3 (p. 151): "The error is positive if the table travel is too
//!   long", i.e. Heidenhain enters errors, measured − commanded.
//! - The TNC table file layout (`BEGIN <name> .<ext> MM`, a header line naming fixed-width
//!   columns, `NR` first, `[END]` last) as the control's `TOOL.T` has it.

use super::{
    check_decimals, decimal, urad_to_deg, AxisErrors, LineEnding, Lines, NumberStyle, TableError,
    TableMeta, TableSign,
};

/// Width of the `NR` column.
const NR_WIDTH: usize = 8;
/// Width of the position and value columns.
const VALUE_WIDTH: usize = 16;

/// The options of [`heidenhain_com`]; every one explicit.
#[derive(Debug, Clone, PartialEq)]
pub struct HeidenhainComOptions {
    /// Error or correction; the control wants [`TableSign::Error`] (see the module's sources).
    pub sign: TableSign,
    /// The table's name in the `BEGIN` line (`X` for `X.COM`): 1 to 8 letters, digits, `_`.
    pub table_name: String,
    /// The position column's name: `AXISPOS` on the TNC 6xx family (MANUALplus 620 manual);
    /// check it on the control, the iTNC 530 KinematicsComp manual pages reachable do not name it.
    pub position_column: String,
    /// Decimals of positions and displacements, mm (4 = 0.1 µm).
    pub linear_decimals: u8,
    /// Decimals of rotations, degrees (7 ≈ 0.002 µrad).
    pub angular_decimals: u8,
    /// The control's tables end lines with `\r\n` as transferred ([`LineEnding::CrLf`]).
    pub line_ending: LineEnding,
    /// The most rows the control accepts (TNC 407: 256 per `.COM`; see the machine's manual).
    pub max_points: usize,
}

impl HeidenhainComOptions {
    /// What the file holds: sign and units in one sentence (the format has no comments).
    pub fn meta(&self) -> TableMeta {
        TableMeta {
            format: "heidenhain-com",
            sign: self.sign,
            linear_unit: "mm".to_string(),
            angular_unit: Some("degree".to_string()),
            statement: format!(
                "{}.COM columns C1-C6 are {}: displacements in mm ({} decimals), rotations in degrees ({} decimals)",
                self.table_name,
                self.sign.describe(),
                self.linear_decimals,
                self.angular_decimals
            ),
        }
    }
}

fn column_name_ok(name: &str, max: usize) -> bool {
    !name.is_empty()
        && name.len() <= max
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Writes the `*.COM` table: `NR`, the position column, then `C1` … `C6` for the components the
/// input has (C1 EXX, C2 EYX, C3 EZX, C4 EAX, C5 EBX, C6 ECX for the X axis; likewise for Y and
/// Z), displacements in mm, rotations in degrees, every number signed (`+0.0050`), fixed decimals.
///
/// Refused: more rows than [`HeidenhainComOptions::max_points`], a bad table or column name, a
/// value too large to write exactly, an input without components, any input
/// [`AxisErrors::validate`] refuses.
pub fn heidenhain_com(
    errors: &AxisErrors,
    options: &HeidenhainComOptions,
) -> Result<String, TableError> {
    const FORMAT: &str = "heidenhain-com";
    errors.validate()?;
    check_decimals("linear_decimals", options.linear_decimals)?;
    check_decimals("angular_decimals", options.angular_decimals)?;
    if !column_name_ok(&options.table_name, 8) {
        return Err(TableError::BadOption {
            option: "table_name",
            value: options.table_name.clone(),
            why: "1 to 8 letters, digits or _",
        });
    }
    if !column_name_ok(&options.position_column, VALUE_WIDTH - 1) {
        return Err(TableError::BadOption {
            option: "position_column",
            value: options.position_column.clone(),
            why: "1 to 15 letters, digits or _",
        });
    }
    let n = errors.positions_mm.len();
    if n > options.max_points {
        return Err(TableError::TooManyPoints {
            format: FORMAT,
            count: n,
            limit: options.max_points,
            why: "max_points of this control",
        });
    }
    let present = errors.in_iso_order();
    if present.is_empty() {
        return Err(TableError::NothingToWrite { format: FORMAT });
    }

    let mut out = Lines::new(options.line_ending);
    out.push(format!("BEGIN {:<8} {:<6} MM", options.table_name, ".COM"));
    let mut header = format!(
        "{:<NR_WIDTH$}{:<VALUE_WIDTH$}",
        "NR", options.position_column
    );
    for series in &present {
        header.push_str(&format!(
            "{:<VALUE_WIDTH$}",
            format!("C{}", series.component.index() + 1)
        ));
    }
    out.push(header.trim_end());
    for (row, &position) in errors.positions_mm.iter().enumerate() {
        let what = || format!("{} row {row}", options.position_column);
        let mut line = format!(
            "{:<NR_WIDTH$}{:<VALUE_WIDTH$}",
            row,
            decimal(
                position,
                options.linear_decimals,
                NumberStyle::Fixed,
                true,
                what
            )?
        );
        for series in &present {
            let error = series.values[row];
            let (value, places) = if series.component.is_angular() {
                (
                    urad_to_deg(options.sign.apply(error)),
                    options.angular_decimals,
                )
            } else {
                (options.sign.apply(error) / 1000.0, options.linear_decimals)
            };
            let what = || format!("{} row {row}", series.component.iso_name(errors.axis));
            let text = decimal(value, places, NumberStyle::Fixed, true, what)?;
            line.push_str(&format!("{text:<VALUE_WIDTH$}"));
        }
        out.push(line.trim_end());
    }
    out.push("[END]");
    Ok(out.finish())
}

#[cfg(test)]
mod tests {
    use super::super::test_support::axis;
    use super::super::{Component, LinearAxis};
    use super::*;

    fn options(sign: TableSign) -> HeidenhainComOptions {
        HeidenhainComOptions {
            sign,
            table_name: "X".to_string(),
            position_column: "AXISPOS".to_string(),
            linear_decimals: 4,
            angular_decimals: 6,
            line_ending: LineEnding::CrLf,
            max_points: 256,
        }
    }

    /// Field for field against the published fragment (iTNC 530 HSCI manual p. 680: the column
    /// each ISO 230-1 error of a linear axis goes to): each component carries a distinct value,
    /// and each must come out in its column, converted to mm or degrees, with the error's sign.
    /// The whole file is compared byte for byte with the layout we assume.
    #[test]
    fn columns_follow_the_published_assignment() {
        let input = axis(
            LinearAxis::X,
            vec![-100.0, 0.0, 250.0],
            vec![
                (Component::Ec, vec![6.0, 0.0, 0.0]),
                (Component::Ex, vec![1.0, 0.0, -12.5]),
                (Component::Ey, vec![2.0, 0.0, 0.0]),
                (Component::Ez, vec![3.0, 0.0, 0.0]),
                (Component::Ea, vec![4.0, 0.0, 0.0]),
                (Component::Eb, vec![5.0, 0.0, 0.0]),
            ],
        );
        let text = heidenhain_com(&input, &options(TableSign::Error)).unwrap();
        let expected = "BEGIN X        .COM   MM\r\n\
NR      AXISPOS         C1              C2              C3              C4              C5              C6\r\n\
0       -100.0000       +0.0010         +0.0020         +0.0030         +0.000229       +0.000286       +0.000344\r\n\
1       +0.0000         +0.0000         +0.0000         +0.0000         +0.000000       +0.000000       +0.000000\r\n\
2       +250.0000       -0.0125         +0.0000         +0.0000         +0.000000       +0.000000       +0.000000\r\n\
[END]\r\n";
        assert_eq!(text, expected);
        // Field for field: split the header and each row on whitespace.
        let rows: Vec<Vec<&str>> = text
            .lines()
            .map(|l| l.split_whitespace().collect())
            .collect();
        let header = &rows[1];
        let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
        let value = |row: usize, name: &str| rows[2 + row][column(name)].parse::<f64>().unwrap();
        assert_eq!(value(0, "C1"), 0.001); // EXX, mm
        assert_eq!(value(0, "C2"), 0.002); // EYX
        assert_eq!(value(0, "C3"), 0.003); // EZX
        for (name, urad) in [("C4", 4.0), ("C5", 5.0), ("C6", 6.0)] {
            let degrees = urad * 1e-6 * 180.0 / std::f64::consts::PI;
            assert!((value(0, name) - degrees).abs() < 5e-7, "{name}"); // EAX, EBX, ECX, degrees
        }
        assert_eq!(value(2, "AXISPOS"), 250.0);
    }

    #[test]
    fn only_present_components_get_columns() {
        let input = axis(
            LinearAxis::Z,
            vec![0.0, 5.0],
            vec![
                (Component::Eb, vec![0.0, 1.0]),
                (Component::Ez, vec![0.0, 2.0]),
            ],
        );
        let text = heidenhain_com(&input, &options(TableSign::Error)).unwrap();
        let header = text.lines().nth(1).unwrap();
        assert_eq!(
            header.split_whitespace().collect::<Vec<_>>(),
            ["NR", "AXISPOS", "C3", "C5"]
        );
    }

    #[test]
    fn sign_five_micrometres() {
        let input = axis(
            LinearAxis::Y,
            vec![0.0, 10.0, 20.0],
            vec![(Component::Ey, vec![0.0, 5.0, 0.0])],
        );
        let correction = heidenhain_com(&input, &options(TableSign::Correction)).unwrap();
        let row = correction.lines().nth(3).unwrap();
        assert_eq!(
            row.split_whitespace().collect::<Vec<_>>(),
            ["1", "+10.0000", "-0.0050"]
        );
        let error = heidenhain_com(&input, &options(TableSign::Error)).unwrap();
        let row = error.lines().nth(3).unwrap();
        assert_eq!(
            row.split_whitespace().collect::<Vec<_>>(),
            ["1", "+10.0000", "+0.0050"]
        );
        assert_eq!(
            error.lines().nth(1).unwrap().split_whitespace().nth(2),
            Some("C2")
        );
        assert!(options(TableSign::Correction)
            .meta()
            .statement
            .contains("correction = -error"));
    }

    #[test]
    fn bad_inputs_are_refused() {
        let o = options(TableSign::Error);
        let none = axis(LinearAxis::X, vec![0.0, 1.0], vec![]);
        assert!(matches!(
            heidenhain_com(&none, &o),
            Err(TableError::NothingToWrite { .. })
        ));
        let many = axis(
            LinearAxis::X,
            (0..257).map(f64::from).collect(),
            vec![(Component::Ex, vec![0.0; 257])],
        );
        assert!(matches!(
            heidenhain_com(&many, &o),
            Err(TableError::TooManyPoints { count: 257, .. })
        ));
        let ok = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![0.0; 2])],
        );
        let mut long = o.clone();
        long.table_name = "NINECHARS".into();
        assert!(matches!(
            heidenhain_com(&ok, &long),
            Err(TableError::BadOption {
                option: "table_name",
                ..
            })
        ));
        let mut spaced = o.clone();
        spaced.position_column = "AXIS POS".into();
        assert!(matches!(
            heidenhain_com(&ok, &spaced),
            Err(TableError::BadOption {
                option: "position_column",
                ..
            })
        ));
        let back = axis(
            LinearAxis::X,
            vec![1.0, 0.0],
            vec![(Component::Ex, vec![0.0; 2])],
        );
        assert!(matches!(
            heidenhain_com(&back, &o),
            Err(TableError::NotIncreasing { .. })
        ));
        let huge = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![0.0, 1e16])],
        );
        assert!(matches!(
            heidenhain_com(&huge, &o),
            Err(TableError::ValueOutOfRange { .. })
        ));
    }
}
