//! Dwells, station indices and passes of a `roll` campaign (`docs/spec/machine-formats.md`,
//! "Kind roll").
//!
//! - **Dwells.** With a `station` column, a dwell is a maximal run of consecutive samples (in
//!   time, within one `pass` when that column is given) sharing one non-null station value.
//!   Without it, a dwell is a maximal interval of at least `dwell_min_s` during which `x_mm`
//!   stays within a band of width 2 · `dwell_tol_um` ([`detect`]): scanning in time, a window
//!   grows while the band holds; a window long enough is a dwell, otherwise its first sample is
//!   a moving one. Samples outside dwells are kept by the reader and not used.
//! - **Station.** n = round(b_to_a · (x_dwell − x_ref)/s), x_dwell the mean `x_mm` of the dwell,
//!   x_ref the dwell position with the smallest b_to_a · x over the campaign. A dwell further
//!   than [`OFF_GRID`] of a step from its station is refused, named.
//! - **Passes.** With `pass`, the column says. Without it, a reversal of the stepping direction
//!   starts a new pass at the turning dwell, which ends one pass and starts the next
//!   *(ours: an out-and-back run has one dwell at its far end)*; a dwell at the same station
//!   as the one before it starts a new pass.

/// A dwell further than this fraction of a step from the station grid is refused.
pub const OFF_GRID: f64 = 0.25;

/// One dwell: samples `first ..= last` (indices into the time-ordered samples).
#[derive(Debug, Clone, PartialEq)]
pub struct Dwell {
    /// First sample.
    pub first: usize,
    /// Last sample.
    pub last: usize,
    /// Its pass (from the `pass` column, else 0 until [`passes`] numbers them).
    pub pass: i64,
    /// Mean stage position, mm.
    pub x_mm: f64,
    /// Station index n (set by [`station_indices`]).
    pub station: usize,
}

/// Dwells from the `station` column: maximal runs of consecutive samples with one non-null
/// value (and one pass). `station[i]`, `pass[i]` are the columns of sample i.
pub fn marked(station: &[Option<i64>], pass: &[Option<i64>], x_mm: &[f64]) -> Vec<Dwell> {
    let mut dwells = Vec::new();
    let mut start: Option<usize> = None;
    let key = |i: usize| station[i].map(|s| (s, pass[i]));
    for i in 0..=station.len() {
        let here = (i < station.len()).then(|| key(i)).flatten();
        if let Some(s) = start {
            if here != key(s) {
                dwells.push(dwell(s, i - 1, pass[s].unwrap_or(0), x_mm));
                start = None;
            }
        }
        if start.is_none() && here.is_some() {
            start = Some(i);
        }
    }
    dwells
}

/// Dwells detected from the stage position: see the module documentation. `time_s` ascending.
pub fn detect(
    time_s: &[f64],
    x_mm: &[f64],
    pass: &[Option<i64>],
    min_s: f64,
    tol_um: f64,
) -> Vec<Dwell> {
    let band_mm = 2.0 * tol_um * 1e-3;
    let n = time_s.len();
    let mut dwells = Vec::new();
    let mut i = 0;
    while i < n {
        let (mut lo, mut hi) = (x_mm[i], x_mm[i]);
        let mut j = i;
        while j + 1 < n && pass[j + 1] == pass[i] {
            let x = x_mm[j + 1];
            if x.max(hi) - x.min(lo) > band_mm {
                break;
            }
            lo = lo.min(x);
            hi = hi.max(x);
            j += 1;
        }
        if time_s[j] - time_s[i] >= min_s {
            dwells.push(dwell(i, j, pass[i].unwrap_or(0), x_mm));
            i = j + 1;
        } else {
            i += 1;
        }
    }
    dwells
}

fn dwell(first: usize, last: usize, pass: i64, x_mm: &[f64]) -> Dwell {
    let xs = &x_mm[first..=last];
    Dwell {
        first,
        last,
        pass,
        x_mm: xs.iter().sum::<f64>() / xs.len() as f64,
        station: 0,
    }
}

/// A dwell off the station grid: its index and how far (in steps) from the nearest station.
#[derive(Debug, Clone, PartialEq)]
pub struct OffGrid {
    /// Index of the dwell.
    pub dwell: usize,
    /// b_to_a · (x − x_ref)/s.
    pub steps: f64,
}

/// Sets every dwell's station index (module documentation); refuses a dwell off the grid.
pub fn station_indices(dwells: &mut [Dwell], b_to_a: i8, s_mm: f64) -> Result<(), OffGrid> {
    let sign = f64::from(b_to_a);
    let x_ref = dwells
        .iter()
        .map(|d| d.x_mm)
        .min_by(|a, b| (sign * a).total_cmp(&(sign * b)))
        .unwrap_or(0.0);
    for (k, d) in dwells.iter_mut().enumerate() {
        let steps = sign * (d.x_mm - x_ref) / s_mm;
        let n = steps.round();
        if (steps - n).abs() > OFF_GRID {
            return Err(OffGrid { dwell: k, steps });
        }
        d.station = n as usize;
    }
    Ok(())
}

/// Numbers the passes (module documentation) when the `pass` column is absent; with it, keeps
/// the column's passes. Returns, per pass in order, the indices of its dwells in time order (a
/// turning dwell appears in two passes).
pub fn passes(dwells: &[Dwell], from_column: bool) -> Vec<Vec<usize>> {
    if from_column {
        let mut ids: Vec<i64> = dwells.iter().map(|d| d.pass).collect();
        ids.sort_unstable();
        ids.dedup();
        return ids
            .iter()
            .map(|&p| (0..dwells.len()).filter(|&k| dwells[k].pass == p).collect())
            .collect();
    }
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut current: Vec<usize> = Vec::new();
    let mut direction = 0i64;
    for k in 0..dwells.len() {
        let Some(&prev) = current.last() else {
            current.push(k);
            continue;
        };
        let step = dwells[k].station as i64 - dwells[prev].station as i64;
        if step == 0 {
            out.push(std::mem::take(&mut current));
            current.push(k);
            direction = 0;
        } else if direction != 0 && step.signum() != direction {
            out.push(std::mem::replace(&mut current, vec![prev, k]));
            direction = step.signum();
        } else {
            current.push(k);
            direction = step.signum();
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stops at 0, 40, 80 mm (b_to_a = +1), 3 s each at 10 Hz, 1 s moves between.
    fn staircase(stops: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut t, mut x) = (Vec::new(), Vec::new());
        let mut now: f64 = 0.0;
        for (k, &stop) in stops.iter().enumerate() {
            for _ in 0..30 {
                t.push(now);
                x.push(stop + 1e-4 * (now * 7.0).sin());
                now += 0.1;
            }
            if let Some(&next) = stops.get(k + 1) {
                for j in 1..10 {
                    t.push(now);
                    x.push(stop + (next - stop) * f64::from(j) / 10.0);
                    now += 0.1;
                }
            }
        }
        (t, x)
    }

    #[test]
    fn detected_dwells_cover_each_stop_and_leave_the_moves_out() {
        let stops = [0.0, 40.0, 80.0, 40.0, 0.0];
        let (t, x) = staircase(&stops);
        let pass = vec![None; t.len()];
        let mut d = detect(&t, &x, &pass, 2.0, 2.0);
        assert_eq!(d.len(), 5);
        for (dw, &stop) in d.iter().zip(&stops) {
            assert!((dw.x_mm - stop).abs() < 1e-3);
            assert_eq!(dw.last - dw.first + 1, 30);
        }
        station_indices(&mut d, 1, 40.0).unwrap();
        assert_eq!(
            d.iter().map(|d| d.station).collect::<Vec<_>>(),
            [0, 1, 2, 1, 0]
        );
        // Out and back: the far dwell is the end of pass 1 and the start of pass 2.
        assert_eq!(passes(&d, false), vec![vec![0, 1, 2], vec![2, 3, 4]]);
    }

    #[test]
    fn negative_b_to_a_counts_stations_from_the_largest_x() {
        let (t, x) = staircase(&[-770.0, -730.0, -690.0]);
        let mut d = detect(&t, &x, &vec![None; t.len()], 2.0, 2.0);
        station_indices(&mut d, -1, 40.0).unwrap();
        assert_eq!(d.iter().map(|d| d.station).collect::<Vec<_>>(), [2, 1, 0]);
    }

    #[test]
    fn an_off_grid_dwell_and_a_short_stop_are_told() {
        let (t, x) = staircase(&[0.0, 40.0, 100.0]);
        let mut d = detect(&t, &x, &vec![None; t.len()], 2.0, 2.0);
        let e = station_indices(&mut d, 1, 40.0).unwrap_err();
        assert_eq!(e.dwell, 2);
        assert!((e.steps - 2.5).abs() < 1e-3);
        // A 3-s stop is no dwell when 4 s are asked for.
        assert!(detect(&t, &x, &vec![None; t.len()], 4.0, 2.0).is_empty());
    }

    #[test]
    fn marked_dwells_follow_the_station_column() {
        let station = [None, Some(0), Some(0), None, Some(1), Some(1), Some(2)];
        let pass = [Some(1); 7];
        let x = [0.0, 0.0, 0.0, 20.0, 40.0, 40.0, 80.0];
        let d = marked(&station, &pass, &x);
        assert_eq!(d.len(), 3);
        assert_eq!((d[0].first, d[0].last, d[1].first, d[2].last), (1, 2, 4, 6));
        assert_eq!(d[0].pass, 1);
    }
}
