//! ISG kernel (Beckhoff TwinCAT CNC, TF5280 Volumetric Compensation) error parameter file in
//! the ISG CSV format: a header naming the argument (the axis) and the ISO 230-1 component
//! errors, one record per axis position.
//!
//! Sources (Beckhoff Information System, TF5280 Volumetric Compensation):
//! - "ISG CSV format" (infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296429067.html):
//!   columns named in a header line, records below, `//` starts a comment line, `#` a file break;
//!   the example "Component errors of the X axis": header `X EXX EYX EZX EAX EBX ECX`, records
//!   `0.0 0.02 0.01 0.07 0.00 0.0042 0.003` and `10.0 0.00 -0.1 0.01 0.00 0.0011 0.002`.
//! - "Units of measure" (…/296426379.html): parameter values in millimetres for offsets and rad
//!   for angles; the arguments X, Y, Z in millimetres.
//! - "List of parameters supported" (…/296423819.html): EXX … ECX are the DIN ISO 230 component
//!   errors; the configuration's `negate` (P-VOLC-00009) negates the compensation per axis, so
//!   the file holds the errors themselves.

use super::{
    check_decimals, decimal, AxisErrors, LineEnding, Lines, NumberStyle, TableError, TableMeta,
    TableSign,
};

/// The options of [`isg_csv`]; every one explicit.
#[derive(Debug, Clone, PartialEq)]
pub struct IsgCsvOptions {
    /// Error or correction; the ISO 230-1 parameters the control reads are errors
    /// ([`TableSign::Error`]).
    pub sign: TableSign,
    /// Decimals of the positions and displacements, mm (4 = 0.1 µm).
    pub linear_decimals: u8,
    /// Decimals of the rotations, rad (9 = 1 nrad).
    pub angular_decimals: u8,
    /// Fixed decimals, or trimmed as in the published example.
    pub style: NumberStyle,
    /// The control runs on Windows; its example files do not say. Choose explicitly.
    pub line_ending: LineEnding,
}

impl IsgCsvOptions {
    /// What the file holds: sign and units in one sentence.
    pub fn meta(&self) -> TableMeta {
        TableMeta {
            format: "isg-csv",
            sign: self.sign,
            linear_unit: "mm".to_string(),
            angular_unit: Some("rad".to_string()),
            statement: format!(
                "dbbcal: values are {}; positions and displacements in mm ({} decimals), rotations in rad ({} decimals)",
                self.sign.describe(),
                self.linear_decimals,
                self.angular_decimals
            ),
        }
    }
}

/// Writes the ISG CSV error parameter file of one axis: two `//` comment lines stating sign and
/// units, the header (the axis letter, then the ISO 230-1 names of the components present, in
/// ISO order), then one record per position, fields separated by one space.
///
/// Refused: an input without components, a value too large to write exactly, any input
/// [`AxisErrors::validate`] refuses.
pub fn isg_csv(errors: &AxisErrors, options: &IsgCsvOptions) -> Result<String, TableError> {
    const FORMAT: &str = "isg-csv";
    errors.validate()?;
    check_decimals("linear_decimals", options.linear_decimals)?;
    check_decimals("angular_decimals", options.angular_decimals)?;
    let present = errors.in_iso_order();
    if present.is_empty() {
        return Err(TableError::NothingToWrite { format: FORMAT });
    }
    let axis = errors.axis.letter();
    let mut out = Lines::new(options.line_ending);
    out.push(format!("// {}", options.meta().statement));
    out.push(format!(
        "// component errors of the {axis} axis against {axis} (ISO 230-1 names)"
    ));
    let mut header = axis.to_string();
    for series in &present {
        header.push(' ');
        header.push_str(&series.component.iso_name(errors.axis));
    }
    out.push(header);
    for (row, &position) in errors.positions_mm.iter().enumerate() {
        let what = || format!("{axis} row {row}");
        let mut line = decimal(
            position,
            options.linear_decimals,
            options.style,
            false,
            what,
        )?;
        for series in &present {
            let signed = options.sign.apply(series.values[row]);
            let (value, places) = if series.component.is_angular() {
                (signed * 1e-6, options.angular_decimals)
            } else {
                (signed / 1000.0, options.linear_decimals)
            };
            let what = || format!("{} row {row}", series.component.iso_name(errors.axis));
            line.push(' ');
            line.push_str(&decimal(value, places, options.style, false, what)?);
        }
        out.push(line);
    }
    Ok(out.finish())
}

#[cfg(test)]
mod tests {
    use super::super::test_support::axis;
    use super::super::{Component, LinearAxis};
    use super::*;

    fn options(sign: TableSign) -> IsgCsvOptions {
        IsgCsvOptions {
            sign,
            linear_decimals: 4,
            angular_decimals: 6,
            style: NumberStyle::Trimmed,
            line_ending: LineEnding::CrLf,
        }
    }

    /// The published example "Component errors of the X axis": the header byte for byte, the
    /// two records field for field (the example writes zero both as `0.00` and `0.0`, so no
    /// single number style reproduces it byte for byte), from the errors in dbbcal's units.
    #[test]
    fn reproduces_the_published_example() {
        let input = axis(
            LinearAxis::X,
            vec![0.0, 10.0],
            vec![
                (Component::Ex, vec![20.0, 0.0]),
                (Component::Ey, vec![10.0, -100.0]),
                (Component::Ez, vec![70.0, 10.0]),
                (Component::Ea, vec![0.0, 0.0]),
                (Component::Eb, vec![4200.0, 1100.0]),
                (Component::Ec, vec![3000.0, 2000.0]),
            ],
        );
        let text = isg_csv(&input, &options(TableSign::Error)).unwrap();
        let lines: Vec<&str> = text.split("\r\n").collect();
        assert_eq!(lines.len(), 6, "{text:?}");
        assert!(lines[0].starts_with("//") && lines[1].starts_with("//"));
        assert_eq!(lines[2], "X EXX EYX EZX EAX EBX ECX");
        let published = [
            "0.0 0.02 0.01 0.07 0.00 0.0042 0.003",
            "10.0 0.00 -0.1 0.01 0.00 0.0011 0.002",
        ];
        for (ours, theirs) in lines[3..5].iter().zip(published) {
            let ours: Vec<f64> = ours.split(' ').map(|f| f.parse().unwrap()).collect();
            let theirs: Vec<f64> = theirs.split(' ').map(|f| f.parse().unwrap()).collect();
            assert_eq!(ours, theirs);
        }
        assert_eq!(lines[3], "0.0 0.02 0.01 0.07 0.0 0.0042 0.003");
        assert_eq!(lines[5], "");
    }

    #[test]
    fn sign_five_micrometres() {
        let input = axis(
            LinearAxis::Z,
            vec![0.0, 100.0, 200.0],
            vec![
                (Component::Ex, vec![0.0; 3]),
                (Component::Ez, vec![0.0, 5.0, 0.0]),
            ],
        );
        let mut o = options(TableSign::Correction);
        o.style = NumberStyle::Fixed;
        o.line_ending = LineEnding::Lf;
        let text = isg_csv(&input, &o).unwrap();
        assert!(text.contains("\nZ EXZ EZZ\n"), "{text}");
        assert!(text.contains("\n100.0000 0.0000 -0.0050\n"), "{text}");
        assert!(text.starts_with("// dbbcal: values are correction = -error"));
        o.sign = TableSign::Error;
        let text = isg_csv(&input, &o).unwrap();
        assert!(text.contains("\n100.0000 0.0000 0.0050\n"), "{text}");
    }

    #[test]
    fn bad_inputs_are_refused() {
        let o = options(TableSign::Error);
        let none = axis(LinearAxis::X, vec![0.0, 1.0], vec![]);
        assert!(matches!(
            isg_csv(&none, &o),
            Err(TableError::NothingToWrite { .. })
        ));
        let back = axis(
            LinearAxis::X,
            vec![0.0, 0.0],
            vec![(Component::Ex, vec![0.0; 2])],
        );
        assert!(matches!(
            isg_csv(&back, &o),
            Err(TableError::NotIncreasing { .. })
        ));
        let nan = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Eb, vec![0.0, f64::NAN])],
        );
        assert!(matches!(
            isg_csv(&nan, &o),
            Err(TableError::NonFiniteValue { .. })
        ));
        let huge = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ea, vec![0.0, 1e16])],
        );
        assert!(matches!(
            isg_csv(&huge, &o),
            Err(TableError::ValueOutOfRange { .. })
        ));
        let mut many = o;
        many.angular_decimals = 13;
        let ok = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![0.0; 2])],
        );
        assert!(matches!(
            isg_csv(&ok, &many),
            Err(TableError::BadOption { .. })
        ));
    }
}
