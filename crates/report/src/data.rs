//! Small numeric helpers on plain slices: finite ranges, RMS, and min/max decimation so a
//! 100k-point trace is drawn with a few points per pixel column without hiding its extremes.

/// Min and max of the finite values, `None` if there are none.
pub(crate) fn finite_minmax<I: IntoIterator<Item = f64>>(values: I) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// Root mean square of the finite values, `None` if there are none.
pub(crate) fn rms(values: &[f64]) -> Option<f64> {
    let (n, ss) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((0usize, 0.0), |(n, ss), v| (n + 1, ss + v * v));
    (n > 0).then(|| (ss / n as f64).sqrt())
}

/// A polyline in plot coordinates.
pub(crate) type Polyline = Vec<(f64, f64)>;

/// Splits `(x, y)` pairs (`None` = gap) into polylines and keeps, per pixel column of
/// `[lo, hi]` split into `columns`, the first, lowest, highest and last point in drawing order
/// (the M4 scheme): the rendered line is the same as drawing every point.
pub(crate) fn decimate<I>(points: I, lo: f64, hi: f64, columns: usize) -> Vec<Polyline>
where
    I: IntoIterator<Item = Option<(f64, f64)>>,
{
    let scale = columns.max(1) as f64 / (hi - lo).max(f64::MIN_POSITIVE);
    let mut out = Vec::new();
    let mut line = Polyline::new();
    let mut bucket = Bucket::default();
    for p in points {
        match p {
            Some((x, y)) => {
                let col = ((x - lo) * scale).floor() as i64;
                if bucket.col != Some(col) {
                    bucket.flush_into(&mut line);
                    bucket = Bucket {
                        col: Some(col),
                        ..Bucket::default()
                    };
                }
                bucket.push((x, y));
            }
            None => {
                bucket.flush_into(&mut line);
                bucket = Bucket::default();
                if !line.is_empty() {
                    out.push(std::mem::take(&mut line));
                }
            }
        }
    }
    bucket.flush_into(&mut line);
    if !line.is_empty() {
        out.push(line);
    }
    out
}

/// The points of one pixel column seen so far, reduced to first/min/max/last.
#[derive(Default)]
struct Bucket {
    col: Option<i64>,
    count: usize,
    first: (usize, (f64, f64)),
    min: (usize, (f64, f64)),
    max: (usize, (f64, f64)),
    last: (usize, (f64, f64)),
}

impl Bucket {
    fn push(&mut self, p: (f64, f64)) {
        let item = (self.count, p);
        if self.count == 0 {
            (self.first, self.min, self.max) = (item, item, item);
        } else if p.1 < self.min.1 .1 {
            self.min = item;
        } else if p.1 > self.max.1 .1 {
            self.max = item;
        }
        self.last = item;
        self.count += 1;
    }

    /// Appends the kept points in their original order, each once.
    fn flush_into(&self, line: &mut Polyline) {
        if self.count == 0 {
            return;
        }
        let mut kept = [self.first, self.min, self.max, self.last];
        kept.sort_by_key(|k| k.0);
        let mut prev = None;
        for (i, p) in kept {
            if prev != Some(i) {
                line.push(p);
                prev = Some(i);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_extremes_and_splits_at_gaps() {
        let pts: Vec<_> = (0..10_000)
            .map(|i| {
                if i == 5000 {
                    None
                } else {
                    Some((i as f64, ((i * 7919) % 101) as f64))
                }
            })
            .collect();
        let lines = decimate(pts, 0.0, 10_000.0, 100);
        assert_eq!(lines.len(), 2);
        let n: usize = lines.iter().map(Vec::len).sum();
        assert!(n <= 4 * 101 + 4, "{n}");
        let ymax = lines.iter().flatten().map(|p| p.1).fold(f64::MIN, f64::max);
        assert_eq!(ymax, 100.0);
    }

    #[test]
    fn rms_and_minmax_skip_nan() {
        assert_eq!(rms(&[3.0, f64::NAN, -3.0]), Some(3.0));
        assert_eq!(rms(&[]), None);
        assert_eq!(finite_minmax([f64::NAN, 2.0, -1.0]), Some((-1.0, 2.0)));
    }
}
