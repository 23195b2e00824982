//! Reading `positions/*.parquet` (`docs/spec/device-format.md`, "positions") into
//! [`dbbcal_core::positions::PositionsLog`].
//!
//! The reader rules of `campaign-format.md` hold: any number of files in any order, unsorted
//! rows, timestamps in ns/us/ms (naive = UTC), `device` as utf8 or dictionary, `station` and
//! `run` as int64 or int32, extra columns ignored; `a_deg`, `b_deg`, `c_deg` and `run` may be
//! absent or all null. A row without time, device or x, y, z, a time out of range, or a station
//! whose rows disagree refuses the campaign with one line naming the file, the column and the
//! rows (a commanded position cannot be guessed).

use super::*;
use dbbcal_core::positions::{PositionRow, PositionsLog};

/// Position rows with a time out of range refuse the campaign (an error, in words).
const TIME_PROBLEM: &str =
    "hold times outside 1980-01-01 .. 2200-01-01 (NaT, a clock reset, a far future, or a unit whose ns value overflows)";

const REQUIRED: [ColumnSpec; 6] = [
    spec("time", Kind::Time, false),
    spec("device", Kind::Text, false),
    spec("x_mm", Kind::Real, false),
    spec("y_mm", Kind::Real, false),
    spec("z_mm", Kind::Real, false),
    spec("station", Kind::Count, true),
];
const OPTIONAL: [ColumnSpec; 4] = [
    spec("a_deg", Kind::Real, true),
    spec("b_deg", Kind::Real, true),
    spec("c_deg", Kind::Real, true),
    spec("run", Kind::Count, true),
];
const INTEGER: &str = "int64 or int32";

/// Every file of the `positions` table, checked (`PositionsLog::check`).
pub(crate) fn read_positions_files(files: &[PathBuf]) -> Result<PositionsLog, IngestError> {
    let mut log = PositionsLog {
        files: files.iter().map(|p| p.display().to_string()).collect(),
        rows: Vec::new(),
    };
    for (index, path) in files.iter().enumerate() {
        let index = u32::try_from(index).unwrap_or(u32::MAX);
        let rows = guarded(path, || read_one(path, index))?;
        log.rows.extend(rows);
    }
    log.check()?;
    Ok(log)
}

fn integer_only(path: &Path, scan: &Scan, name: &'static str) -> Result<(), IngestError> {
    match scan.dtype(name) {
        Some(dtype) if !dtype.is_integer() && dtype != &DataType::Null => {
            Err(IngestError::WrongType {
                path: path.to_path_buf(),
                column: name,
                found: crate::pq::type_name(dtype),
                expected: INTEGER,
            })
        }
        _ => Ok(()),
    }
}

fn read_one(path: &Path, index: u32) -> Result<Vec<PositionRow>, IngestError> {
    let mut scan = checked_scan(path, &REQUIRED)?;
    integer_only(path, &scan, "station")?;
    integer_only(path, &scan, "run")?;
    let mut present = Vec::new();
    for c in &OPTIONAL {
        // An all-null column of no type is as good as an absent one.
        if scan.dtype(c.name).is_none_or(|t| t == &DataType::Null) {
            continue;
        }
        scan.add(path, c)?;
        present.push(c.name);
    }
    let unit = scan.time;
    let df = scan.decode_all(path)?;
    let err = |e: ArrowError| not_parquet(path, e);
    let n = df.rows;
    for c in REQUIRED.iter().filter(|c| !c.nullable) {
        let column = df.get(c.name).map_err(err)?;
        if column.null_count() > 0 {
            let mut bad = None;
            for row in 0..n {
                if column.is_null(row) {
                    BadRange::add(&mut bad, row as u64, || "null".into());
                }
            }
            let Some(b) = bad else { continue };
            return Err(IngestError::BadRows {
                path: path.to_path_buf(),
                column: c.name,
                rows: b.rows,
                first_row: b.first_row,
                last_row: b.last_row,
                problem: "are null (every position row needs time, device, x_mm, y_mm and z_mm)"
                    .into(),
                example: b.example,
            });
        }
    }
    let time = df.i64("time").map_err(err)?;
    let device = df.text("device").map_err(err)?;
    let real = |name: &str| df.f64(name).map_err(err);
    let (x, y, z) = (real("x_mm")?, real("y_mm")?, real("z_mm")?);
    let station = df.get("station").map_err(err)?;
    let station = int_values(station).map_err(err)?;
    let optional_real = |name: &str| -> Result<Option<&Float64Array>, IngestError> {
        if present.contains(&name) {
            Ok(Some(real(name)?))
        } else {
            Ok(None)
        }
    };
    let abc = [
        optional_real("a_deg")?,
        optional_real("b_deg")?,
        optional_real("c_deg")?,
    ];
    let run = if present.contains(&"run") {
        Some(int_values(df.get("run").map_err(err)?).map_err(err)?)
    } else {
        None
    };
    let get = |c: &Float64Array, i: usize| c.is_valid(i).then(|| c.value(i));
    let mut bad_time = None;
    let mut rows = Vec::with_capacity(n);
    for i in 0..n {
        let raw = time.value(i);
        let Some(time_ns) = unit.to_ns(raw) else {
            BadRange::add(&mut bad_time, i as u64, || format!("{raw} {}", unit.unit()));
            continue;
        };
        rows.push(PositionRow {
            time_ns,
            device: device.value(i).unwrap_or_default().to_string(),
            xyz_mm: [
                get(x, i).unwrap_or(f64::NAN),
                get(y, i).unwrap_or(f64::NAN),
                get(z, i).unwrap_or(f64::NAN),
            ],
            abc_deg: std::array::from_fn(|k| abc[k].and_then(|c| get(c, i))),
            station: station[i],
            run: run.as_ref().and_then(|c| c[i]),
            file: index,
            row: i as u64,
        });
    }
    if let Some(b) = bad_time {
        return Err(IngestError::BadRows {
            path: path.to_path_buf(),
            column: "time",
            rows: b.rows,
            first_row: b.first_row,
            last_row: b.last_row,
            problem: TIME_PROBLEM.into(),
            example: b.example,
        });
    }
    Ok(rows)
}

/// An integer column (the spec's `Count` kind, checked integer by [`integer_only`]) as values.
fn int_values(column: &ArrayRef) -> Result<Vec<Option<i64>>, ArrowError> {
    let ints = column
        .as_primitive_opt::<Int64Type>()
        .ok_or_else(|| ArrowError::CastError("not an integer column".into()))?;
    Ok(ints.iter().collect())
}
