//! Siemens SINUMERIK 840D (sl) leadscrew / measuring-system error compensation (LEC, MSEC):
//! `$AA_ENC_COMP[e,N,AX]`, `_STEP`, `_MIN`, `_MAX`, `_IS_MODULO` in a `%_N_AX_EEC_INI` file.
//!
//! Source: SINUMERIK 840D sl Function Manual Extended Functions, K3 Compensations, 4.4.2
//! (03/2013, 6FC5397-1BP40-3BA1; 5.4.2 in 09/2009, 6FC5397-1BP20-0BA0): the example table of
//! machine axis X1 and the rule "A positive compensation value causes the corresponding machine
//! axis to move in the negative direction", i.e. the control adds the value to the actual
//! position: the value it wants is the error, measured − commanded, in mm.

use super::{
    check_decimals, decimal, representable, AxisErrors, LineEnding, Lines, NumberStyle, TableError,
    TableMeta, TableSign,
};

/// The most interpolation points dbbcal writes into one table. Not from Siemens' public
/// material (which ties the count to the machine's `MD38000 $MA_MM_ENC_COMP_MAX_POINTS` and the
/// static user memory, 8 bytes a point): a ceiling against a mistaken input, which
/// [`SiemensLecOptions::max_points`] (the machine's own MD38000) must not exceed.
pub const SIEMENS_LEC_MAX_POINTS_CEILING: usize = 125_000;

/// Positions further than this from `MIN + N · STEP` are refused (1 nm).
const SPACING_TOLERANCE_MM: f64 = 1e-6;

/// The options of [`siemens_lec`]; every one explicit.
#[derive(Debug, Clone, PartialEq)]
pub struct SiemensLecOptions {
    /// Error or correction. The control wants [`TableSign::Error`] (see the module's source).
    pub sign: TableSign,
    /// The machine axis name in the brackets, e.g. `X1`.
    pub machine_axis: String,
    /// The measuring system (encoder) index, 0 or 1.
    pub encoder: u8,
    /// Decimals of the values and of `MIN`, `STEP`, `MAX`, in mm (3 = µm, as the manual's
    /// example).
    pub decimals: u8,
    /// Fixed decimals, or trimmed as in the manual's example.
    pub style: NumberStyle,
    /// The machine's `MD38000 $MA_MM_ENC_COMP_MAX_POINTS`: the points the table may hold.
    pub max_points: usize,
    /// Siemens' files end lines with `\n` ([`LineEnding::Lf`]).
    pub line_ending: LineEnding,
}

impl SiemensLecOptions {
    /// What the file holds: sign and unit in one sentence.
    pub fn meta(&self) -> TableMeta {
        TableMeta {
            format: "siemens-lec",
            sign: self.sign,
            linear_unit: "mm".to_string(),
            angular_unit: None,
            statement: format!(
                "dbbcal: $AA_ENC_COMP values are {} in mm, {} decimals",
                self.sign.describe(),
                self.decimals
            ),
        }
    }
}

/// Writes the `%_N_AX_EEC_INI` table of one axis: its positioning error (EXX for X) at equally
/// spaced positions, `MIN` the first position, `MAX` the last, `STEP` their spacing, no modulo.
///
/// Refused: positions not equally spaced (within 1 nm), more points than
/// [`SiemensLecOptions::max_points`] or [`SIEMENS_LEC_MAX_POINTS_CEILING`], a start, step or end
/// not exactly writable with the decimals, a value too large to write exactly, the positioning
/// component missing, a bad axis name or encoder index.
pub fn siemens_lec(errors: &AxisErrors, options: &SiemensLecOptions) -> Result<String, TableError> {
    const FORMAT: &str = "siemens-lec";
    errors.validate()?;
    check_decimals("decimals", options.decimals)?;
    if options.encoder > 1 {
        return Err(TableError::BadOption {
            option: "encoder",
            value: options.encoder.to_string(),
            why: "the measuring system is 0 or 1",
        });
    }
    let axis_name = &options.machine_axis;
    let name_ok = axis_name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic())
        && axis_name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !name_ok {
        return Err(TableError::BadOption {
            option: "machine_axis",
            value: axis_name.clone(),
            why: "a machine axis name: a letter, then letters, digits or _",
        });
    }
    if options.max_points > SIEMENS_LEC_MAX_POINTS_CEILING {
        return Err(TableError::BadOption {
            option: "max_points",
            value: options.max_points.to_string(),
            why: "above dbbcal's ceiling of 125000 points",
        });
    }
    let n = errors.positions_mm.len();
    if n > options.max_points {
        return Err(TableError::TooManyPoints {
            format: FORMAT,
            count: n,
            limit: options.max_points,
            why: "MD38000 $MA_MM_ENC_COMP_MAX_POINTS of this machine",
        });
    }
    let component = errors.axis.positioning();
    let values = errors
        .values(component)
        .ok_or_else(|| TableError::MissingComponent {
            format: FORMAT,
            component: component.iso_name(errors.axis),
        })?;
    let step = errors.equal_step(SPACING_TOLERANCE_MM)?;
    let min = errors.positions_mm[0];
    let max = errors.positions_mm[n - 1];
    representable("MIN", min, options.decimals)?;
    representable("STEP", step, options.decimals)?;
    representable("MAX", max, options.decimals)?;

    let places = options.decimals;
    let style = options.style;
    let mm = |value: f64, what: &dyn Fn() -> String| decimal(value, places, style, false, what);
    let e = options.encoder;
    let mut out = Lines::new(options.line_ending);
    out.push("%_N_AX_EEC_INI");
    out.push("CHANDATA(1)");
    out.push(format!("; {}", options.meta().statement));
    out.push(format!(
        "; axis {axis_name}: {} at {n} points",
        component.iso_name(errors.axis)
    ));
    for (index, &error_um) in values.iter().enumerate() {
        let value = options.sign.apply(error_um) / 1000.0;
        let what = || format!("{axis_name} point {index}");
        out.push(format!(
            "$AA_ENC_COMP[{e},{index},{axis_name}]={}",
            mm(value, &what)?
        ));
    }
    let what = || "STEP".to_string();
    out.push(format!(
        "$AA_ENC_COMP_STEP[{e},{axis_name}]={}",
        mm(step, &what)?
    ));
    let what = || "MIN".to_string();
    out.push(format!(
        "$AA_ENC_COMP_MIN[{e},{axis_name}]={}",
        mm(min, &what)?
    ));
    let what = || "MAX".to_string();
    out.push(format!(
        "$AA_ENC_COMP_MAX[{e},{axis_name}]={}",
        mm(max, &what)?
    ));
    out.push(format!("$AA_ENC_COMP_IS_MODULO[{e},{axis_name}]=0"));
    out.push("M17");
    Ok(out.finish())
}

#[cfg(test)]
mod tests {
    use super::super::test_support::axis;
    use super::super::{Component, LinearAxis};
    use super::*;

    fn options(sign: TableSign) -> SiemensLecOptions {
        SiemensLecOptions {
            sign,
            machine_axis: "X1".to_string(),
            encoder: 0,
            decimals: 3,
            style: NumberStyle::Trimmed,
            max_points: 801,
            line_ending: LineEnding::Lf,
        }
    }

    /// The manual's example: X1 from -200 mm to 600 mm in 1 mm steps (801 points), +3, +10,
    /// +12 µm at points 0, 1, 2 and "-0.0" at point 800 (a small negative value, -0.02 µm,
    /// written with 3 decimals as C's printf writes it). The manual elides points 3 … 799 ("...")
    /// and annotates each line with a comment; every line it prints, without its annotation, is
    /// in our file at the same place, byte for byte, and our file has no other lines than the
    /// elided points and our two header comments.
    #[test]
    fn reproduces_the_function_manual_example() {
        let positions: Vec<f64> = (0..=800).map(|i| -200.0 + f64::from(i)).collect();
        let mut exx = vec![0.0; 801];
        exx[0] = 3.0;
        exx[1] = 10.0;
        exx[2] = 12.0;
        exx[800] = -0.02;
        let input = axis(LinearAxis::X, positions, vec![(Component::Ex, exx)]);
        let text = siemens_lec(&input, &options(TableSign::Error)).unwrap();
        let lines: Vec<&str> = text.split('\n').collect();
        assert_eq!(lines.last(), Some(&""), "the file ends with a line ending");
        let statements: Vec<&str> = lines[..lines.len() - 1]
            .iter()
            .copied()
            .filter(|l| !l.starts_with(';'))
            .collect();
        let published_head = [
            "%_N_AX_EEC_INI",
            "CHANDATA(1)",
            "$AA_ENC_COMP[0,0,X1]=0.003",
            "$AA_ENC_COMP[0,1,X1]=0.01",
            "$AA_ENC_COMP[0,2,X1]=0.012",
        ];
        let published_tail = [
            "$AA_ENC_COMP[0,800,X1]=-0.0",
            "$AA_ENC_COMP_STEP[0,X1]=1.0",
            "$AA_ENC_COMP_MIN[0,X1]=-200.0",
            "$AA_ENC_COMP_MAX[0,X1]=600.0",
            "$AA_ENC_COMP_IS_MODULO[0,X1]=0",
            "M17",
        ];
        assert_eq!(&statements[..5], &published_head);
        assert_eq!(&statements[statements.len() - 6..], &published_tail);
        assert_eq!(statements.len(), 2 + 801 + 5);
        for (index, line) in statements[2..2 + 801].iter().enumerate() {
            assert!(
                line.starts_with(&format!("$AA_ENC_COMP[0,{index},X1]=")),
                "{line}"
            );
        }
        // The header comments come right after CHANDATA(1) and state sign and unit.
        assert_eq!(
            lines[2],
            "; dbbcal: $AA_ENC_COMP values are error = measured - commanded in mm, 3 decimals"
        );
    }

    #[test]
    fn sign_five_micrometres() {
        let mut exx = vec![0.0; 5];
        exx[2] = 5.0;
        let input = axis(
            LinearAxis::X,
            vec![0.0, 10.0, 20.0, 30.0, 40.0],
            vec![(Component::Ex, exx)],
        );
        let mut o = options(TableSign::Correction);
        o.style = NumberStyle::Fixed;
        let text = siemens_lec(&input, &o).unwrap();
        assert!(text.contains("\n$AA_ENC_COMP[0,2,X1]=-0.005\n"), "{text}");
        assert!(text.contains("\n$AA_ENC_COMP[0,1,X1]=0.000\n"));
        o.sign = TableSign::Error;
        let text = siemens_lec(&input, &o).unwrap();
        assert!(text.contains("\n$AA_ENC_COMP[0,2,X1]=0.005\n"), "{text}");
        assert!(text.contains("values are error = measured - commanded in mm"));
    }

    #[test]
    fn the_y_axis_takes_eyy_and_ignores_straightness() {
        let input = axis(
            LinearAxis::Y,
            vec![0.0, 50.0],
            vec![
                (Component::Ez, vec![9.0, 9.0]),
                (Component::Ey, vec![1.0, -2.0]),
            ],
        );
        let mut o = options(TableSign::Error);
        o.machine_axis = "Y1".into();
        let text = siemens_lec(&input, &o).unwrap();
        assert!(
            text.contains("$AA_ENC_COMP[0,0,Y1]=0.001\n$AA_ENC_COMP[0,1,Y1]=-0.002\n"),
            "{text}"
        );
        assert!(text.contains("$AA_ENC_COMP_STEP[0,Y1]=50.0\n"));
    }

    #[test]
    fn bad_inputs_are_refused() {
        let o = options(TableSign::Error);
        let uneven = axis(
            LinearAxis::X,
            vec![0.0, 1.0, 2.5],
            vec![(Component::Ex, vec![0.0; 3])],
        );
        assert!(matches!(
            siemens_lec(&uneven, &o),
            Err(TableError::NotEquallySpaced { index: 1, .. })
        ));
        let no_exx = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ey, vec![0.0; 2])],
        );
        assert!(matches!(
            siemens_lec(&no_exx, &o),
            Err(TableError::MissingComponent { .. })
        ));
        let many = axis(
            LinearAxis::X,
            (0..802).map(f64::from).collect(),
            vec![(Component::Ex, vec![0.0; 802])],
        );
        assert!(matches!(
            siemens_lec(&many, &o),
            Err(TableError::TooManyPoints {
                count: 802,
                limit: 801,
                ..
            })
        ));
        let mut big = o.clone();
        big.max_points = 200_000;
        assert!(matches!(
            siemens_lec(&many, &big),
            Err(TableError::BadOption {
                option: "max_points",
                ..
            })
        ));
        let fine = axis(
            LinearAxis::X,
            vec![0.0, 0.0005],
            vec![(Component::Ex, vec![0.0; 2])],
        );
        assert!(matches!(
            siemens_lec(&fine, &o),
            Err(TableError::NotRepresentable { what: "STEP", .. })
        ));
        let huge = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![0.0, 1e16])],
        );
        assert!(matches!(
            siemens_lec(&huge, &o),
            Err(TableError::ValueOutOfRange { .. })
        ));
        let nan = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![0.0, f64::NAN])],
        );
        assert!(matches!(
            siemens_lec(&nan, &o),
            Err(TableError::NonFiniteValue { .. })
        ));
        let mut bad_name = o.clone();
        bad_name.machine_axis = "X1]=0".into();
        let ok = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![0.0; 2])],
        );
        assert!(matches!(
            siemens_lec(&ok, &bad_name),
            Err(TableError::BadOption {
                option: "machine_axis",
                ..
            })
        ));
        let mut bad_encoder = o;
        bad_encoder.encoder = 2;
        assert!(matches!(
            siemens_lec(&ok, &bad_encoder),
            Err(TableError::BadOption {
                option: "encoder",
                ..
            })
        ));
    }
}
