//! The `positions` log of a device campaign as plain data, and its rules
//! (`docs/spec/device-format.md`, "positions"): dwells, stations, approach directions, the datum,
//! which bar readings fall in a dwell.
//!
//! - A *dwell* is a maximal run of a device's rows (in time order) with the same non-null
//!   `station`; it begins at its first row and ends at the next row of that device with another
//!   station or null (open at the end of the log).
//! - Within one device a station means one commanded position in the whole campaign: all its rows
//!   agree to `STATION_TOLERANCE_MM` and [`STATION_TOLERANCE_DEG`], else the campaign is
//!   rejected ([`PositionsError::StationDisagrees`], naming the station, the files and rows).
//! - The approach direction of a dwell, per axis, is the sign of that coordinate's change since
//!   the previous dwell (0 for the first).
//! - The datum is the first dwell at `reference_mm` (to `STATION_TOLERANCE_MM`), or the first
//!   dwell when the device gives none.
//!
//! No IO: `dbbcal-io` reads the files into a [`PositionsLog`].

/// Rows of one station agree to this, mm (1 µm).
pub(crate) const STATION_TOLERANCE_MM: f64 = 1e-3;
/// Rows of one station agree to this, degrees.
pub const STATION_TOLERANCE_DEG: f64 = 1e-4;

/// One row of `positions/*.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct PositionRow {
    /// ns since the epoch, UTC.
    pub time_ns: i64,
    /// The device on the machine that was commanded.
    pub device: String,
    /// Commanded x, y, z, mm.
    pub xyz_mm: [f64; 3],
    /// Commanded a, b, c, degrees (`None`: no such axis, or null).
    pub abc_deg: [Option<f64>; 3],
    /// The programmed stop; `None` while the machine moves.
    pub station: Option<i64>,
    /// Pass of a bidirectional test, from 1.
    pub run: Option<i64>,
    /// Index of the file in [`PositionsLog::files`].
    pub file: u32,
    /// Row in that file, from 0.
    pub row: u64,
}

/// The `positions` log: every row of every file, any order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PositionsLog {
    /// The files read (as named in messages).
    pub files: Vec<String>,
    /// Their rows.
    pub rows: Vec<PositionRow>,
}

/// A maximal interval during which a device dwelt at one station.
#[derive(Debug, Clone, PartialEq)]
pub struct Dwell {
    /// The station.
    pub station: i64,
    /// Its run (of the first row), if logged.
    pub run: Option<i64>,
    /// First row's time, ns.
    pub from_ns: i64,
    /// The next row's time with another station or null, ns; `None`: open at the log's end.
    pub to_ns: Option<i64>,
    /// Commanded x, y, z, mm.
    pub position_mm: [f64; 3],
    /// Commanded rotary axes, degrees.
    pub rotary_deg: [Option<f64>; 3],
    /// Sign of each coordinate's change since the previous dwell (+1, −1, 0).
    pub approach: [i8; 3],
}

impl Dwell {
    /// Whether `t_ns` lies inside the dwell, `margin_ns` in from both ends.
    pub fn contains(&self, t_ns: i64, margin_ns: i64) -> bool {
        t_ns >= self.from_ns.saturating_add(margin_ns)
            && self
                .to_ns
                .is_none_or(|end| t_ns < end.saturating_sub(margin_ns))
    }
}

/// A `positions` log that breaks the format's rules.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PositionsError {
    /// Two rows of one station command different positions.
    #[error("{0}")]
    StationDisagrees(Box<Disagreement>),
    /// A commanded coordinate is NaN or infinite.
    #[error("{file}: column `{column}`: row {row} holds {value}, not a finite number")]
    NotFinite {
        /// The file.
        file: String,
        /// The column.
        column: &'static str,
        /// The row.
        row: u64,
        /// The value.
        value: f64,
    },
}

/// Two rows of one station that command different positions.
#[derive(Debug, Clone, PartialEq)]
pub struct Disagreement {
    /// The device.
    pub device: String,
    /// The station.
    pub station: i64,
    /// The column that differs.
    pub column: &'static str,
    /// The file of the disagreeing row.
    pub file: String,
    /// Its row.
    pub row: u64,
    /// Its value.
    pub value: String,
    /// The file of the station's first row.
    pub first_file: String,
    /// That row.
    pub first_row: u64,
    /// Its value.
    pub(crate) first_value: String,
}

impl std::fmt::Display for Disagreement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: column `{}`: device {:?}, station {}: row {} says {} but {} row {} says {} \
             (a station's rows must agree to 1 µm and 1e-4°)",
            self.file,
            self.column,
            self.device,
            self.station,
            self.row,
            self.value,
            self.first_file,
            self.first_row,
            self.first_value
        )
    }
}

const LINEAR: [&str; 3] = ["x_mm", "y_mm", "z_mm"];
const ROTARY: [&str; 3] = ["a_deg", "b_deg", "c_deg"];

impl PositionsLog {
    fn file(&self, i: u32) -> String {
        self.files
            .get(i as usize)
            .cloned()
            .unwrap_or_else(|| format!("file {i}"))
    }

    /// The devices named, sorted.
    pub fn devices(&self) -> Vec<String> {
        let mut d: Vec<String> = self.rows.iter().map(|r| r.device.clone()).collect();
        d.sort();
        d.dedup();
        d
    }

    /// Checks the rules that hold for the whole log: finite coordinates, and every station's
    /// rows agreeing (per device).
    pub fn check(&self) -> Result<(), PositionsError> {
        for r in &self.rows {
            let coords = r.xyz_mm.iter().zip(LINEAR).map(|(v, c)| (Some(*v), c));
            let rot = r.abc_deg.iter().zip(ROTARY).map(|(v, c)| (*v, c));
            for (v, column) in coords.chain(rot) {
                if let Some(v) = v.filter(|v| !v.is_finite()) {
                    return Err(PositionsError::NotFinite {
                        file: self.file(r.file),
                        column,
                        row: r.row,
                        value: v,
                    });
                }
            }
        }
        let mut first: std::collections::BTreeMap<(&str, i64), &PositionRow> =
            std::collections::BTreeMap::new();
        for r in self.sorted_rows(None) {
            let Some(s) = r.station else { continue };
            let Some(f) = first.get(&(r.device.as_str(), s)) else {
                first.insert((r.device.as_str(), s), r);
                continue;
            };
            let differs = |column: &'static str, a: String, b: String| {
                PositionsError::StationDisagrees(Box::new(Disagreement {
                    device: r.device.clone(),
                    station: s,
                    column,
                    file: self.file(r.file),
                    row: r.row,
                    value: a,
                    first_file: self.file(f.file),
                    first_row: f.row,
                    first_value: b,
                }))
            };
            for k in 0..3 {
                if (r.xyz_mm[k] - f.xyz_mm[k]).abs() > STATION_TOLERANCE_MM {
                    return Err(differs(
                        LINEAR[k],
                        r.xyz_mm[k].to_string(),
                        f.xyz_mm[k].to_string(),
                    ));
                }
                let agree = match (r.abc_deg[k], f.abc_deg[k]) {
                    (None, None) => true,
                    (Some(a), Some(b)) => (a - b).abs() <= STATION_TOLERANCE_DEG,
                    _ => false,
                };
                if !agree {
                    let show = |v: Option<f64>| v.map_or("null".to_string(), |v| v.to_string());
                    return Err(differs(ROTARY[k], show(r.abc_deg[k]), show(f.abc_deg[k])));
                }
            }
        }
        Ok(())
    }

    /// The rows (of `device`, or all), in time order (ties by file and row).
    fn sorted_rows(&self, device: Option<&str>) -> Vec<&PositionRow> {
        let mut rows: Vec<&PositionRow> = self
            .rows
            .iter()
            .filter(|r| device.is_none_or(|d| r.device == d))
            .collect();
        rows.sort_by_key(|r| (r.time_ns, r.file, r.row));
        rows
    }

    /// The dwells of `device`, in time order, with their approach directions.
    pub fn dwells(&self, device: &str) -> Vec<Dwell> {
        let mut out: Vec<Dwell> = Vec::new();
        let mut open: Option<Dwell> = None;
        for r in self.sorted_rows(Some(device)) {
            if let Some(d) = &open {
                if r.station == Some(d.station) {
                    continue;
                }
                let mut d = open.take().expect("open");
                d.to_ns = Some(r.time_ns);
                out.push(d);
            }
            if let Some(station) = r.station {
                let approach = match out.last() {
                    None => [0; 3],
                    Some(prev) => std::array::from_fn(|k| {
                        let dc = r.xyz_mm[k] - prev.position_mm[k];
                        if dc > STATION_TOLERANCE_MM {
                            1
                        } else if dc < -STATION_TOLERANCE_MM {
                            -1
                        } else {
                            0
                        }
                    }),
                };
                open = Some(Dwell {
                    station,
                    run: r.run,
                    from_ns: r.time_ns,
                    to_ns: None,
                    position_mm: r.xyz_mm,
                    rotary_deg: r.abc_deg,
                    approach,
                });
            }
        }
        out.extend(open);
        out
    }
}

/// The datum: the first dwell at `reference_mm` (to `STATION_TOLERANCE_MM`), or the first dwell
/// when `reference_mm` is `None`. `None` when no dwell is at the reference.
pub fn datum_index(dwells: &[Dwell], reference_mm: Option<[f64; 3]>) -> Option<usize> {
    match reference_mm {
        None => (!dwells.is_empty()).then_some(0),
        Some(r) => dwells
            .iter()
            .position(|d| (0..3).all(|k| (d.position_mm[k] - r[k]).abs() <= STATION_TOLERANCE_MM)),
    }
}

/// Mean and number of the `values` whose `times_ns` (sorted) fall inside `dwell`, `margin_ns`
/// in from both ends; `None` when none do.
pub fn mean_in_dwell(
    times_ns: &[i64],
    values: &[f64],
    dwell: &Dwell,
    margin_ns: i64,
) -> Option<(f64, usize)> {
    let lo = times_ns.partition_point(|&t| t < dwell.from_ns.saturating_add(margin_ns));
    let hi = match dwell.to_ns {
        Some(end) => times_ns.partition_point(|&t| t < end.saturating_sub(margin_ns)),
        None => times_ns.len(),
    };
    let picked: Vec<f64> = (lo..hi.max(lo))
        .map(|i| values[i])
        .filter(|v| v.is_finite())
        .collect();
    (!picked.is_empty()).then(|| {
        (
            picked.iter().sum::<f64>() / picked.len() as f64,
            picked.len(),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t: i64, x: f64, station: Option<i64>, file: u32, r: u64) -> PositionRow {
        PositionRow {
            time_ns: t,
            device: "hexapod-1".into(),
            xyz_mm: [x, 300.0, -200.0],
            abc_deg: [None; 3],
            station,
            run: Some(1),
            file,
            row: r,
        }
    }

    fn log(rows: Vec<PositionRow>) -> PositionsLog {
        PositionsLog {
            files: vec!["positions/a.parquet".into(), "positions/b.parquet".into()],
            rows,
        }
    }

    #[test]
    fn dwells_are_maximal_runs_of_one_station_whatever_the_row_order() {
        // A logger sampling while dwelling, a null while moving, a station revisited, split
        // over two files and shuffled.
        let rows = vec![
            row(50, 400.0, Some(1), 1, 3),
            row(0, 400.0, Some(1), 0, 0),
            row(10, 400.0, Some(1), 0, 1),
            row(20, 400.0, None, 0, 2),
            row(30, 410.0, Some(2), 1, 0),
            row(35, 410.0, Some(2), 1, 1),
            row(40, 405.0, None, 1, 2),
        ];
        let l = log(rows);
        l.check().unwrap();
        let d = l.dwells("hexapod-1");
        let got: Vec<(i64, i64, Option<i64>, [i8; 3])> = d
            .iter()
            .map(|d| (d.station, d.from_ns, d.to_ns, d.approach))
            .collect();
        assert_eq!(
            got,
            vec![
                (1, 0, Some(20), [0, 0, 0]),
                (2, 30, Some(40), [1, 0, 0]),
                (1, 50, None, [-1, 0, 0]),
            ]
        );
        assert_eq!(datum_index(&d, Some([410.0, 300.0, -200.0])), Some(1));
        assert_eq!(datum_index(&d, None), Some(0));
        assert_eq!(datum_index(&d, Some([1.0, 2.0, 3.0])), None);
        assert!(l.dwells("other").is_empty());
        // Readings in a dwell: [from + margin, to − margin).
        let t = [0, 5, 10, 19, 20, 31, 39, 55];
        let v = [1.0, 2.0, 3.0, 4.0, 99.0, 7.0, 9.0, 5.0];
        assert_eq!(mean_in_dwell(&t, &v, &d[0], 0), Some((2.5, 4)));
        assert_eq!(mean_in_dwell(&t, &v, &d[0], 2), Some((2.5, 2)));
        assert_eq!(mean_in_dwell(&t, &v, &d[1], 0), Some((8.0, 2)));
        assert_eq!(mean_in_dwell(&t, &v, &d[2], 0), Some((5.0, 1)));
        assert_eq!(mean_in_dwell(&t, &v, &d[1], 10), None);
    }

    #[test]
    fn a_station_whose_rows_disagree_rejects_the_log_naming_station_files_and_rows() {
        let l = log(vec![
            row(0, 400.0, Some(1), 0, 0),
            row(10, 410.0, Some(2), 0, 1),
            row(20, 400.0005, Some(1), 1, 7),
        ]);
        l.check().unwrap(); // within 1 µm
        let l = log(vec![
            row(0, 400.0, Some(1), 0, 0),
            row(10, 410.0, Some(2), 0, 1),
            row(20, 400.002, Some(1), 1, 7),
        ]);
        let e = l.check().unwrap_err().to_string();
        assert!(!e.contains('\n'));
        for w in [
            "positions/b.parquet",
            "x_mm",
            "station 1",
            "row 7",
            "positions/a.parquet row 0",
        ] {
            assert!(e.contains(w), "{e} lacks {w}");
        }
        let mut r = row(30, 400.0, Some(1), 1, 9);
        r.abc_deg[2] = Some(0.001);
        let e = log(vec![row(0, 400.0, Some(1), 0, 0), r])
            .check()
            .unwrap_err()
            .to_string();
        assert!(e.contains("c_deg") && e.contains("row 9"), "{e}");
        let e = log(vec![row(0, f64::NAN, Some(1), 0, 4)])
            .check()
            .unwrap_err()
            .to_string();
        assert!(e.contains("x_mm") && e.contains("row 4"), "{e}");
    }
}
