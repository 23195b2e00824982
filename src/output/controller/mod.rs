//! Controller compensation tables: the text files a machine tool's control loads to compensate
//! the errors dbbcal measured (`docs/controller-tables.md` gives each format's source, columns,
//! sign, unit, limits and what is assumed).
//!
//! One input, [`AxisErrors`]: a linear axis, its positions (mm) and, per position, the error of
//! each ISO 230-1 component the caller has (µm for the linear components, µrad for the angular
//! ones), with dbbcal's sign, error = measured − commanded. The volumetric table takes
//! [`GridErrors`], the error vector at each node of a lattice.
//!
//! Nothing about sign or unit is silent: every writer takes a [`TableSign`] (the error as measured,
//! or the correction = −error) and the number of decimals of its values; the unit is the one the
//! vendor's format fixes, named in each writer's documentation, in [`TableMeta::statement`], and
//! in a comment at the head of the file where the format has comments. Each writer returns the
//! whole file as text, byte for byte deterministic (fixed decimals, the vendor's line ending), or
//! a [`TableError`] naming what is wrong with the input.
//!
//! | writer | format | vendor's sign | unit |
//! |---|---|---|---|
//! | [`heidenhain_com`] | Heidenhain KinematicsComp `*.COM` (columns `C1`…`C6`) | error | mm, ° (assumed) |
//! | [`siemens_lec`] | Siemens SINUMERIK 840D LEC, `$AA_ENC_COMP` | error | mm |
//! | [`isg_csv`] | ISG kernel / Beckhoff TwinCAT CNC volumetric compensation, ISG CSV | error | mm, rad |
//! | [`fanuc_3d`] | Fanuc-style 3-D error table (`docs/spec/machine-physics.md`) | per `[table] values` | `unit_um` |

mod fanuc;
mod heidenhain;
mod isg;
mod siemens;

pub use fanuc::{fanuc_3d, line_number, node_of_line, Fanuc3dOptions, GridErrors};
pub use heidenhain::{heidenhain_com, HeidenhainComOptions};
pub use isg::{isg_csv, IsgCsvOptions};
pub use siemens::{siemens_lec, SiemensLecOptions, SIEMENS_LEC_MAX_POINTS_CEILING};

use std::fmt;

/// Which quantity a table holds: the error as dbbcal measures it, or the correction.
///
/// dbbcal's errors are measured − commanded (`docs/spec/machine-formats.md`, "Conventions"). A
/// control either wants that error (and subtracts it itself) or the correction it adds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TableSign {
    /// The value written is the error, measured − commanded.
    Error,
    /// The value written is the correction, −error = commanded − measured.
    Correction,
}

impl TableSign {
    /// The value to write for an error `error` (same unit). A zero error gives +0, never -0.
    pub fn apply(self, error: f64) -> f64 {
        match self {
            TableSign::Error => error + 0.0,
            TableSign::Correction => 0.0 - error,
        }
    }

    /// The sign in words, for a file's header comment and the output records.
    pub fn describe(self) -> &'static str {
        match self {
            TableSign::Error => "error = measured - commanded",
            TableSign::Correction => "correction = -error = commanded - measured",
        }
    }
}

/// How a line ends: the vendor's convention, chosen explicitly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineEnding {
    /// `\n`.
    Lf,
    /// `\r\n`.
    CrLf,
}

impl LineEnding {
    /// The characters that end a line.
    pub fn as_str(self) -> &'static str {
        match self {
            LineEnding::Lf => "\n",
            LineEnding::CrLf => "\r\n",
        }
    }
}

/// How a decimal number is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumberStyle {
    /// Exactly the given number of decimals: `0.0100`.
    Fixed,
    /// Rounded to the given number of decimals, trailing zeros removed but one decimal kept:
    /// `0.01`, `1.0` (the style of Siemens' published example).
    Trimmed,
}

/// The most decimals any writer accepts (1 fm in mm: finer than any control resolves).
pub const MAX_DECIMALS: u8 = 12;

/// A linear machine axis, the subject of a table (its letter names the ISO 230-1 components).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum LinearAxis {
    /// The X axis.
    X,
    /// The Y axis.
    Y,
    /// The Z axis.
    Z,
}

impl LinearAxis {
    /// The axis letter.
    pub fn letter(self) -> char {
        match self {
            LinearAxis::X => 'X',
            LinearAxis::Y => 'Y',
            LinearAxis::Z => 'Z',
        }
    }

    /// The component along the axis itself (EXX for X): the positioning error.
    pub fn positioning(self) -> Component {
        match self {
            LinearAxis::X => Component::Ex,
            LinearAxis::Y => Component::Ey,
            LinearAxis::Z => Component::Ez,
        }
    }
}

/// An ISO 230-1 component error of a linear axis, by its direction: with the axis it names
/// `E{direction}{axis}` (for the X axis: EXX positioning, EYX and EZX straightness, EAX roll,
/// EBX pitch, ECX yaw, in dbbcal's frame M).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Component {
    /// Displacement along X, µm.
    Ex,
    /// Displacement along Y, µm.
    Ey,
    /// Displacement along Z, µm.
    Ez,
    /// Rotation about X, µrad.
    Ea,
    /// Rotation about Y, µrad.
    Eb,
    /// Rotation about Z, µrad.
    Ec,
}

impl Component {
    /// All six, in ISO order (X, Y, Z, A, B, C).
    pub const ALL: [Component; 6] = [
        Component::Ex,
        Component::Ey,
        Component::Ez,
        Component::Ea,
        Component::Eb,
        Component::Ec,
    ];

    /// The direction letter (X, Y, Z, A, B or C).
    pub fn direction(self) -> char {
        match self {
            Component::Ex => 'X',
            Component::Ey => 'Y',
            Component::Ez => 'Z',
            Component::Ea => 'A',
            Component::Eb => 'B',
            Component::Ec => 'C',
        }
    }

    /// True for a rotation (EA*, EB*, EC*: µrad), false for a displacement (µm).
    pub fn is_angular(self) -> bool {
        matches!(self, Component::Ea | Component::Eb | Component::Ec)
    }

    /// The ISO 230-1 name for the given axis: `EYX` for [`Component::Ey`] of X.
    pub fn iso_name(self, axis: LinearAxis) -> String {
        format!("E{}{}", self.direction(), axis.letter())
    }

    /// Position in [`Component::ALL`] (0 for Ex … 5 for Ec).
    pub fn index(self) -> usize {
        self as usize
    }
}

/// The errors of one component at each position of an [`AxisErrors`].
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentErrors {
    /// Which component.
    pub component: Component,
    /// One value per position: µm for a displacement, µrad for a rotation; error = measured −
    /// commanded.
    pub values: Vec<f64>,
}

/// The input of every axis table: one linear axis, its positions and the errors there.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisErrors {
    /// The axis moved.
    pub axis: LinearAxis,
    /// The commanded axis positions, mm, in the control's machine coordinates; strictly
    /// increasing.
    pub positions_mm: Vec<f64>,
    /// The components measured, each once, each with one value per position.
    pub components: Vec<ComponentErrors>,
}

impl AxisErrors {
    /// The values of a component, if the input has it.
    pub fn values(&self, component: Component) -> Option<&[f64]> {
        self.components
            .iter()
            .find(|c| c.component == component)
            .map(|c| c.values.as_slice())
    }

    /// The components present, in ISO order (X, Y, Z, A, B, C), with their values.
    pub(crate) fn in_iso_order(&self) -> Vec<&ComponentErrors> {
        let mut present: Vec<&ComponentErrors> = self.components.iter().collect();
        present.sort_by_key(|c| c.component);
        present
    }

    /// Refuses what no table can hold: fewer than two positions, a position that is not finite
    /// or not above the previous one, a component given twice, a component whose length differs
    /// from the positions', a value that is not finite.
    pub fn validate(&self) -> Result<(), TableError> {
        if self.positions_mm.len() < 2 {
            return Err(TableError::TooFewPositions {
                count: self.positions_mm.len(),
            });
        }
        for (index, &position) in self.positions_mm.iter().enumerate() {
            if !position.is_finite() {
                return Err(TableError::NonFinitePosition { index, position });
            }
            if index > 0 && position <= self.positions_mm[index - 1] {
                return Err(TableError::NotIncreasing {
                    index,
                    previous_mm: self.positions_mm[index - 1],
                    position_mm: position,
                });
            }
        }
        for (n, series) in self.components.iter().enumerate() {
            let name = series.component.iso_name(self.axis);
            if self.components[..n]
                .iter()
                .any(|c| c.component == series.component)
            {
                return Err(TableError::DuplicateComponent { component: name });
            }
            if series.values.len() != self.positions_mm.len() {
                return Err(TableError::LengthMismatch {
                    component: name,
                    values: series.values.len(),
                    positions: self.positions_mm.len(),
                });
            }
            if let Some(index) = series.values.iter().position(|v| !v.is_finite()) {
                return Err(TableError::NonFiniteValue {
                    component: name,
                    index,
                    value: series.values[index],
                });
            }
        }
        Ok(())
    }

    /// The equal spacing a table with implied positions needs (Siemens LEC): the step, or the
    /// first position off the line `first + i · step` by more than `tolerance_mm`.
    pub(crate) fn equal_step(&self, tolerance_mm: f64) -> Result<f64, TableError> {
        let n = self.positions_mm.len();
        let first = self.positions_mm[0];
        let step = (self.positions_mm[n - 1] - first) / (n - 1) as f64;
        for (index, &position) in self.positions_mm.iter().enumerate() {
            let expected = first + index as f64 * step;
            if (position - expected).abs() > tolerance_mm {
                return Err(TableError::NotEquallySpaced {
                    index,
                    expected_mm: expected,
                    position_mm: position,
                });
            }
        }
        Ok(step)
    }
}

/// What a written table holds, for the output records (`compensation.json` and the like) and for
/// formats without comments.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TableMeta {
    /// The format's name (`siemens-lec`, `heidenhain-com`, `isg-csv`, `fanuc-3d`).
    pub format: &'static str,
    /// The sign of the values.
    pub sign: TableSign,
    /// The unit of displacements.
    pub linear_unit: String,
    /// The unit of rotations, when the table has any.
    pub angular_unit: Option<String>,
    /// The sign and units in one sentence, as a header comment states them.
    pub statement: String,
}

/// Why a table cannot be written from this input: each names the position, component or option
/// at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TableError {
    /// A table needs at least two positions.
    #[error("a table needs at least 2 positions, got {count}")]
    TooFewPositions {
        /// How many were given.
        count: usize,
    },
    /// A position is NaN or infinite.
    #[error("position {index} is {position}: positions must be finite")]
    NonFinitePosition {
        /// Its index.
        index: usize,
        /// The value.
        position: f64,
    },
    /// Positions must be strictly increasing.
    #[error("position {index} ({position_mm} mm) is not above position {} ({previous_mm} mm): positions must be strictly increasing", index - 1)]
    NotIncreasing {
        /// The index of the position that is not above its predecessor.
        index: usize,
        /// The previous position, mm.
        previous_mm: f64,
        /// This position, mm.
        position_mm: f64,
    },
    /// The format implies positions from a start and a step; this one is off that line.
    #[error("position {index} is {position_mm} mm, the equal spacing puts it at {expected_mm} mm: this format needs equally spaced positions")]
    NotEquallySpaced {
        /// The index of the position.
        index: usize,
        /// Where equal spacing puts it, mm.
        expected_mm: f64,
        /// Where it is, mm.
        position_mm: f64,
    },
    /// A component was given twice.
    #[error("component {component} is given twice")]
    DuplicateComponent {
        /// Its ISO 230-1 name.
        component: String,
    },
    /// A component has a different number of values than there are positions.
    #[error("component {component} has {values} values for {positions} positions")]
    LengthMismatch {
        /// Its ISO 230-1 name.
        component: String,
        /// Its number of values.
        values: usize,
        /// The number of positions.
        positions: usize,
    },
    /// A value is NaN or infinite.
    #[error("component {component}, position {index}: value {value} is not finite")]
    NonFiniteValue {
        /// Its ISO 230-1 name (or the grid node for the 3-D table).
        component: String,
        /// The index of the position (or line).
        index: usize,
        /// The value.
        value: f64,
    },
    /// The format needs a component the input lacks.
    #[error("{format} needs component {component}, which the input does not have")]
    MissingComponent {
        /// The format.
        format: &'static str,
        /// The ISO 230-1 name of the component.
        component: String,
    },
    /// The input has no component this format can carry.
    #[error("{format}: the input has no component this format carries")]
    NothingToWrite {
        /// The format.
        format: &'static str,
    },
    /// More points than the control (or the format) holds.
    #[error("{format}: {count} points, the limit is {limit} ({why})")]
    TooManyPoints {
        /// The format.
        format: &'static str,
        /// Points in the input.
        count: usize,
        /// The limit.
        limit: usize,
        /// Where the limit comes from.
        why: &'static str,
    },
    /// A value does not fit the format once converted and rounded.
    #[error("{what}: {value} does not fit the format (limit ±{limit})")]
    ValueOutOfRange {
        /// What the value is (component and position, or line).
        what: String,
        /// The value in the file's unit.
        value: f64,
        /// The largest magnitude the format holds, in the file's unit.
        limit: f64,
    },
    /// A position cannot be written exactly with the decimals chosen (a table whose positions are
    /// implied by start and step would be misplaced).
    #[error("{what} = {value_mm} mm cannot be written with {decimals} decimals")]
    NotRepresentable {
        /// Which position (start, step, end).
        what: &'static str,
        /// Its value, mm.
        value_mm: f64,
        /// The decimals chosen.
        decimals: u8,
    },
    /// An option is out of its range.
    #[error("option {option} = {value}: {why}")]
    BadOption {
        /// The option's name.
        option: &'static str,
        /// Its value, as text.
        value: String,
        /// What the format accepts.
        why: &'static str,
    },
}

/// Checks the number of decimals an option asks for.
pub(crate) fn check_decimals(option: &'static str, places: u8) -> Result<(), TableError> {
    if places > MAX_DECIMALS {
        return Err(TableError::BadOption {
            option,
            value: places.to_string(),
            why: "at most 12 decimals",
        });
    }
    Ok(())
}

/// The largest magnitude of a decimal written with `places` decimals: beyond it the scaled value
/// is no longer an exact integer in an f64, so the last digits would be noise.
pub(crate) fn decimal_limit(places: u8) -> f64 {
    const EXACT: f64 = 9_007_199_254_740_992.0; // 2^53
    EXACT / 10f64.powi(i32::from(places))
}

/// Writes `value` with `places` decimals in `style`, with a leading `+` when `plus`; refuses a
/// value too large to write exactly (`what` names it in the error).
///
/// Rounding is Rust's (the exact binary value, ties to even), the same as C's `printf`: a small
/// negative value rounds to `-0.000`, as the `-0.0` of Siemens' published example.
pub(crate) fn decimal(
    value: f64,
    places: u8,
    style: NumberStyle,
    plus: bool,
    what: impl FnOnce() -> String,
) -> Result<String, TableError> {
    let limit = decimal_limit(places);
    if !value.is_finite() || value.abs() >= limit {
        return Err(TableError::ValueOutOfRange {
            what: what(),
            value,
            limit,
        });
    }
    let places = usize::from(places);
    let mut text = if plus {
        format!("{value:+.places$}")
    } else {
        format!("{value:.places$}")
    };
    if style == NumberStyle::Trimmed {
        if text.contains('.') {
            while text.ends_with('0') {
                text.pop();
            }
            if text.ends_with('.') {
                text.push('0');
            }
        } else {
            text.push_str(".0");
        }
    }
    Ok(text)
}

/// Checks that a position written with `places` decimals is the position itself (within 1 pm).
pub(crate) fn representable(
    what: &'static str,
    value_mm: f64,
    places: u8,
) -> Result<(), TableError> {
    let scale = 10f64.powi(i32::from(places));
    let written = (value_mm * scale).round() / scale;
    if (written - value_mm).abs() > 1e-9 {
        return Err(TableError::NotRepresentable {
            what,
            value_mm,
            decimals: places,
        });
    }
    Ok(())
}

/// µrad to degrees.
pub(crate) fn urad_to_deg(urad: f64) -> f64 {
    urad * 1e-6 * (180.0 / std::f64::consts::PI)
}

/// Builds a file line by line with one line ending.
pub(crate) struct Lines {
    text: String,
    ending: LineEnding,
}

impl Lines {
    pub(crate) fn new(ending: LineEnding) -> Self {
        Lines {
            text: String::new(),
            ending,
        }
    }

    pub(crate) fn push(&mut self, line: impl fmt::Display) {
        use fmt::Write;
        let _ = write!(self.text, "{line}");
        self.text.push_str(self.ending.as_str());
    }

    pub(crate) fn finish(self) -> String {
        self.text
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    use super::*;

    /// An axis with the given positions and one component.
    pub(crate) fn axis(
        axis: LinearAxis,
        positions_mm: Vec<f64>,
        components: Vec<(Component, Vec<f64>)>,
    ) -> AxisErrors {
        AxisErrors {
            axis,
            positions_mm,
            components: components
                .into_iter()
                .map(|(component, values)| ComponentErrors { component, values })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::axis;
    use super::*;

    #[test]
    fn sign_negates_only_for_corrections() {
        assert_eq!(TableSign::Error.apply(5.0), 5.0);
        assert_eq!(TableSign::Correction.apply(5.0), -5.0);
        assert!(TableSign::Correction.apply(0.0).is_sign_positive());
        assert!(TableSign::Error.apply(-0.0).is_sign_positive());
    }

    #[test]
    fn numbers_are_fixed_or_trimmed() {
        let w = || String::new();
        assert_eq!(
            decimal(0.01, 4, NumberStyle::Fixed, false, w).unwrap(),
            "0.0100"
        );
        assert_eq!(
            decimal(0.01, 4, NumberStyle::Trimmed, false, w).unwrap(),
            "0.01"
        );
        assert_eq!(
            decimal(1.0, 3, NumberStyle::Trimmed, false, w).unwrap(),
            "1.0"
        );
        assert_eq!(
            decimal(-200.0, 3, NumberStyle::Trimmed, false, w).unwrap(),
            "-200.0"
        );
        assert_eq!(
            decimal(-0.00002, 3, NumberStyle::Trimmed, false, w).unwrap(),
            "-0.0"
        );
        assert_eq!(
            decimal(0.005, 4, NumberStyle::Fixed, true, w).unwrap(),
            "+0.0050"
        );
        assert_eq!(
            decimal(7.0, 0, NumberStyle::Trimmed, false, w).unwrap(),
            "7.0"
        );
        assert!(matches!(
            decimal(1e12, 6, NumberStyle::Fixed, false, w),
            Err(TableError::ValueOutOfRange { .. })
        ));
    }

    #[test]
    fn bad_axes_are_refused() {
        let ok = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![(Component::Ex, vec![1.0, 2.0])],
        );
        assert_eq!(ok.validate(), Ok(()));
        let one = axis(LinearAxis::X, vec![0.0], vec![(Component::Ex, vec![1.0])]);
        assert!(matches!(
            one.validate(),
            Err(TableError::TooFewPositions { count: 1 })
        ));
        let down = axis(LinearAxis::X, vec![0.0, 1.0, 1.0], vec![]);
        assert!(matches!(
            down.validate(),
            Err(TableError::NotIncreasing { index: 2, .. })
        ));
        let nan = axis(LinearAxis::X, vec![0.0, f64::NAN], vec![]);
        assert!(matches!(
            nan.validate(),
            Err(TableError::NonFinitePosition { index: 1, .. })
        ));
        let short = axis(
            LinearAxis::Y,
            vec![0.0, 1.0],
            vec![(Component::Ez, vec![1.0])],
        );
        assert!(matches!(
            short.validate(),
            Err(TableError::LengthMismatch { ref component, .. }) if component == "EZY"
        ));
        let inf = axis(
            LinearAxis::Z,
            vec![0.0, 1.0],
            vec![(Component::Ea, vec![1.0, f64::INFINITY])],
        );
        assert!(matches!(
            inf.validate(),
            Err(TableError::NonFiniteValue { ref component, index: 1, .. }) if component == "EAZ"
        ));
        let twice = axis(
            LinearAxis::X,
            vec![0.0, 1.0],
            vec![
                (Component::Ex, vec![1.0, 2.0]),
                (Component::Ex, vec![1.0, 2.0]),
            ],
        );
        assert!(matches!(
            twice.validate(),
            Err(TableError::DuplicateComponent { .. })
        ));
    }

    #[test]
    fn iso_names() {
        assert_eq!(Component::Ey.iso_name(LinearAxis::X), "EYX");
        assert_eq!(LinearAxis::Z.positioning().iso_name(LinearAxis::Z), "EZZ");
    }
}
