//! The Fanuc-style 3-D error table of kind `volumetric` (`docs/spec/machine-formats.md`,
//! `[table] format = "fanuc-3d"`; numbering in `docs/spec/machine-physics.md`, "3-D table"):
//! line l = i + I(j − 1) + IJ(k − 1), i fastest, is `N{n_base+l}A1P{dx}A2P{dy}A3P{dz}` with
//! values round(v / unit_um), v = −e for `correction`, e for `error`.
//!
//! Source of the layout: Optodyne's note on 3-D positioning accuracy (seed 001, §VII, "the
//! format obtained from Fanuc"): `N100001A1P[dx]A2P[dy]A3P[dz]` for i = j = k = 1, l = 1, up to
//! `N100036…` for I = 3, J = 4, K = 3; A1, A2, A3 the x, y, z axes, the number after P the error
//! value. The note prints no values, no unit and no sign: the spec fixes them (`unit_um`,
//! `values`), and the file has no comment to state them, so [`Fanuc3dOptions::meta`] does.

use super::{LineEnding, Lines, TableError, TableMeta, TableSign};

/// The largest sequence number written: eight digits (`N99999999`). An assumption: the seed
/// prints six-digit numbers, Fanuc's public material reachable here gives no limit.
const MAX_SEQUENCE_NUMBER: u64 = 99_999_999;

/// The error vectors at the nodes of a lattice: node (i, j, k), 1-based, i fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct GridErrors {
    /// I, J, K: the nodes along x, y, z (each ≥ 1).
    pub counts: [usize; 3],
    /// (ex, ey, ez) at each node, µm, error = measured − commanded; node (i, j, k) at index
    /// `line_number(counts, i, j, k) − 1`.
    pub errors_um: Vec<[f64; 3]>,
}

/// The options of [`fanuc_3d`]; every one explicit (the spec's `[table]` section).
#[derive(Debug, Clone, PartialEq)]
pub struct Fanuc3dOptions {
    /// `values`: error or correction (= −error).
    pub sign: TableSign,
    /// `n_base`: line l is written `N{n_base + l}`.
    pub n_base: u64,
    /// `unit_um`: one detection unit, µm (> 0).
    pub unit_um: f64,
    /// The largest |value| the control accepts, in detection units (the machine's manual; no
    /// public Fanuc source was reachable, see `docs/controller-tables.md`).
    pub max_abs_units: i64,
    /// `\n` ([`LineEnding::Lf`]) unless the control's transfer wants `\r\n`.
    pub line_ending: LineEnding,
}

impl Fanuc3dOptions {
    /// What the file holds: sign and unit in one sentence (the format has no comments).
    pub fn meta(&self) -> TableMeta {
        TableMeta {
            format: "fanuc-3d",
            sign: self.sign,
            linear_unit: format!("{} um (one detection unit)", self.unit_um),
            angular_unit: None,
            statement: format!(
                "fanuc-3d: A1P, A2P, A3P are the {} along x, y, z in detection units of {} um, N = {} + l",
                self.sign.describe(),
                self.unit_um,
                self.n_base
            ),
        }
    }
}

/// The line of node (i, j, k), 1-based: l = i + I(j − 1) + IJ(k − 1); `None` outside the lattice.
pub fn line_number(counts: [usize; 3], i: usize, j: usize, k: usize) -> Option<usize> {
    let [ni, nj, nk] = counts;
    if !(1..=ni).contains(&i) || !(1..=nj).contains(&j) || !(1..=nk).contains(&k) {
        return None;
    }
    Some(i + ni * (j - 1) + ni * nj * (k - 1))
}

/// The node (i, j, k) of line l, 1-based; `None` outside 1 … IJK.
pub fn node_of_line(counts: [usize; 3], l: usize) -> Option<(usize, usize, usize)> {
    let [ni, nj, nk] = counts;
    if l == 0 || ni == 0 || nj == 0 || l > ni * nj * nk {
        return None;
    }
    let z = l - 1;
    Some((z % ni + 1, (z / ni) % nj + 1, z / (ni * nj) + 1))
}

/// Writes the table: IJK lines `N{n_base+l}A1P{dx}A2P{dy}A3P{dz}` in order of l, integers in
/// detection units, rounded half away from zero.
///
/// Refused: a count of 0, a number of vectors other than IJK, a value that is not finite, a value
/// beyond [`Fanuc3dOptions::max_abs_units`] once rounded, a sequence number beyond eight digits,
/// `unit_um` not finite and positive.
pub fn fanuc_3d(grid: &GridErrors, options: &Fanuc3dOptions) -> Result<String, TableError> {
    const FORMAT: &str = "fanuc-3d";
    if !(options.unit_um.is_finite() && options.unit_um > 0.0) {
        return Err(TableError::BadOption {
            option: "unit_um",
            value: options.unit_um.to_string(),
            why: "a detection unit is finite and > 0 µm",
        });
    }
    if options.max_abs_units < 0 {
        return Err(TableError::BadOption {
            option: "max_abs_units",
            value: options.max_abs_units.to_string(),
            why: "a magnitude, ≥ 0",
        });
    }
    let [ni, nj, nk] = grid.counts;
    if ni == 0 || nj == 0 || nk == 0 {
        return Err(TableError::BadOption {
            option: "counts",
            value: format!("{ni} x {nj} x {nk}"),
            why: "I, J and K are at least 1",
        });
    }
    let lines =
        ni.checked_mul(nj)
            .and_then(|n| n.checked_mul(nk))
            .ok_or(TableError::TooManyPoints {
                format: FORMAT,
                count: usize::MAX,
                limit: MAX_SEQUENCE_NUMBER as usize,
                why: "I·J·K overflows",
            })?;
    if grid.errors_um.len() != lines {
        return Err(TableError::LengthMismatch {
            component: "error vectors".to_string(),
            values: grid.errors_um.len(),
            positions: lines,
        });
    }
    let last = options.n_base.checked_add(lines as u64);
    if last.is_none_or(|n| n > MAX_SEQUENCE_NUMBER) {
        return Err(TableError::TooManyPoints {
            format: FORMAT,
            count: lines,
            limit: MAX_SEQUENCE_NUMBER.saturating_sub(options.n_base) as usize,
            why: "n_base + I·J·K must stay within eight digits (N99999999)",
        });
    }
    let limit = options.max_abs_units as f64;
    let mut out = Lines::new(options.line_ending);
    for (index, vector) in grid.errors_um.iter().enumerate() {
        let l = index + 1;
        let mut units = [0i64; 3];
        for (axis, (&error, unit)) in vector.iter().zip(units.iter_mut()).enumerate() {
            let (i, j, k) = node_of_line(grid.counts, l).unwrap_or_default();
            let what = || format!("line {l}, node ({i}, {j}, {k}), A{}", axis + 1);
            if !error.is_finite() {
                return Err(TableError::NonFiniteValue {
                    component: what(),
                    index,
                    value: error,
                });
            }
            let rounded = (options.sign.apply(error) / options.unit_um).round();
            if rounded.abs() > limit {
                return Err(TableError::ValueOutOfRange {
                    what: what(),
                    value: rounded,
                    limit,
                });
            }
            *unit = rounded as i64;
        }
        out.push(format!(
            "N{}A1P{}A2P{}A3P{}",
            options.n_base + l as u64,
            units[0],
            units[1],
            units[2]
        ));
    }
    Ok(out.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEED_COUNTS: [usize; 3] = [3, 4, 3];

    fn options(sign: TableSign) -> Fanuc3dOptions {
        Fanuc3dOptions {
            sign,
            n_base: 100_000,
            unit_um: 1.0,
            max_abs_units: 32_767,
            line_ending: LineEnding::Lf,
        }
    }

    /// A grid whose error at node (i, j, k) is (i, 10 j, 100 k) µm: each line shows its node.
    fn marked_grid() -> GridErrors {
        let mut errors_um = Vec::new();
        for l in 1..=36 {
            let (i, j, k) = node_of_line(SEED_COUNTS, l).unwrap();
            errors_um.push([i as f64, 10.0 * j as f64, 100.0 * k as f64]);
        }
        GridErrors {
            counts: SEED_COUNTS,
            errors_um,
        }
    }

    /// The spec's checks (machine-physics.md and issue 30): l(1,2,1) = 4, l(1,1,2) = 13,
    /// l(1,4,3) = 34, l(3,4,3) = 36 for I, J, K = 3, 4, 3, and back.
    #[test]
    fn numbering_follows_the_spec() {
        assert_eq!(line_number(SEED_COUNTS, 1, 1, 1), Some(1));
        assert_eq!(line_number(SEED_COUNTS, 1, 2, 1), Some(4));
        assert_eq!(line_number(SEED_COUNTS, 1, 1, 2), Some(13));
        assert_eq!(line_number(SEED_COUNTS, 1, 4, 3), Some(34));
        assert_eq!(line_number(SEED_COUNTS, 3, 4, 3), Some(36));
        assert_eq!(node_of_line(SEED_COUNTS, 13), Some((1, 1, 2)));
        assert_eq!(node_of_line(SEED_COUNTS, 34), Some((1, 4, 3)));
        assert_eq!(node_of_line(SEED_COUNTS, 36), Some((3, 4, 3)));
        assert_eq!(line_number(SEED_COUNTS, 4, 1, 1), None);
        assert_eq!(line_number(SEED_COUNTS, 0, 1, 1), None);
        assert_eq!(node_of_line(SEED_COUNTS, 37), None);
        assert_eq!(node_of_line(SEED_COUNTS, 0), None);
        for l in 1..=36 {
            let (i, j, k) = node_of_line(SEED_COUNTS, l).unwrap();
            assert_eq!(line_number(SEED_COUNTS, i, j, k), Some(l));
        }
    }

    /// The seed's table (§VII) field for field: it prints the sequence numbers and the node of
    /// lines 1 … 15 and 34 … 36 with placeholders for the values. Each of our lines carries that
    /// number and the values of that node.
    #[test]
    fn reproduces_the_seed_layout() {
        let published: [(u64, (usize, usize, usize)); 18] = [
            (100001, (1, 1, 1)),
            (100002, (2, 1, 1)),
            (100003, (3, 1, 1)),
            (100004, (1, 2, 1)),
            (100005, (2, 2, 1)),
            (100006, (3, 2, 1)),
            (100007, (1, 3, 1)),
            (100008, (2, 3, 1)),
            (100009, (3, 3, 1)),
            (100010, (1, 4, 1)),
            (100011, (2, 4, 1)),
            (100012, (3, 4, 1)),
            (100013, (1, 1, 2)),
            (100014, (2, 1, 2)),
            (100015, (3, 1, 2)),
            (100034, (1, 4, 3)),
            (100035, (2, 4, 3)),
            (100036, (3, 4, 3)),
        ];
        let text = fanuc_3d(&marked_grid(), &options(TableSign::Error)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 36);
        for (n, (i, j, k)) in published {
            let line = lines[(n - 100_001) as usize];
            assert_eq!(line, format!("N{n}A1P{i}A2P{}A3P{}", 10 * j, 100 * k));
        }
        assert!(text.ends_with("N100036A1P3A2P40A3P300\n"));
    }

    #[test]
    fn sign_five_micrometres() {
        let mut errors_um = vec![[0.0; 3]; 36];
        errors_um[12] = [0.0, 5.0, 0.0]; // node (1, 1, 2), line 13
        let grid = GridErrors {
            counts: SEED_COUNTS,
            errors_um,
        };
        let correction = fanuc_3d(&grid, &options(TableSign::Correction)).unwrap();
        assert_eq!(correction.lines().nth(12), Some("N100013A1P0A2P-5A3P0"));
        let error = fanuc_3d(&grid, &options(TableSign::Error)).unwrap();
        assert_eq!(error.lines().nth(12), Some("N100013A1P0A2P5A3P0"));
        // In 0.1 µm detection units the same error is 50 units; 1.26 µm rounds to 13.
        let mut fine = options(TableSign::Error);
        fine.unit_um = 0.1;
        let mut grid = grid;
        grid.errors_um[0] = [1.26, -1.26, 0.0];
        let text = fanuc_3d(&grid, &fine).unwrap();
        assert_eq!(text.lines().next(), Some("N100001A1P13A2P-13A3P0"));
        assert_eq!(text.lines().nth(12), Some("N100013A1P0A2P50A3P0"));
        assert!(options(TableSign::Correction)
            .meta()
            .statement
            .contains("correction = -error"));
    }

    #[test]
    fn bad_inputs_are_refused() {
        let o = options(TableSign::Error);
        let short = GridErrors {
            counts: SEED_COUNTS,
            errors_um: vec![[0.0; 3]; 35],
        };
        assert!(matches!(
            fanuc_3d(&short, &o),
            Err(TableError::LengthMismatch {
                values: 35,
                positions: 36,
                ..
            })
        ));
        let empty = GridErrors {
            counts: [3, 0, 3],
            errors_um: vec![],
        };
        assert!(matches!(
            fanuc_3d(&empty, &o),
            Err(TableError::BadOption {
                option: "counts",
                ..
            })
        ));
        let mut nan = marked_grid();
        nan.errors_um[33][2] = f64::NAN;
        let refused = fanuc_3d(&nan, &o).unwrap_err();
        assert!(
            refused.to_string().contains("line 34, node (1, 4, 3), A3"),
            "{refused}"
        );
        let mut big = marked_grid();
        big.errors_um[0][0] = 40_000.0;
        assert!(matches!(
            fanuc_3d(&big, &o),
            Err(TableError::ValueOutOfRange { .. })
        ));
        let mut zero_unit = o.clone();
        zero_unit.unit_um = 0.0;
        assert!(matches!(
            fanuc_3d(&marked_grid(), &zero_unit),
            Err(TableError::BadOption {
                option: "unit_um",
                ..
            })
        ));
        let mut high = o;
        high.n_base = 99_999_990;
        assert!(matches!(
            fanuc_3d(&marked_grid(), &high),
            Err(TableError::TooManyPoints { .. })
        ));
    }
}
