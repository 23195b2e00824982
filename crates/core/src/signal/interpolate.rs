//! The one piecewise-linear interpolator: sensor logs at a bar's sample times, the matching
//! study's air history, calibration tables, reference tracks in compensation and the
//! simulator's fine grid all go through it.
//!
//! Knots are `(x[i], y[i])` with `x` ascending; equal abscissae are allowed (a value held and
//! then changed at one instant): at such an `x` the last of them wins. Between two knots the
//! value is the straight line through them, at a knot its value exactly. What happens beyond
//! the first and last knots is the caller's choice ([`Beyond`]); a caller that must not bridge
//! long gaps asks [`within`].

/// A knot abscissa: nanosecond times (`i64`, differences exact) or any `f64` coordinate.
pub trait Knot: Copy + PartialOrd {
    /// The value at `at` on the line from `(x0, y0)` to `(x1, y1)`, `x0 < x1`.
    fn lerp(x0: Self, x1: Self, y0: f64, y1: f64, at: Self) -> f64;
}

impl Knot for i64 {
    /// The fraction from the exact integer differences, then the line; a knot's own time gives
    /// its value whatever the next one holds.
    fn lerp(x0: i64, x1: i64, y0: f64, y1: f64, at: i64) -> f64 {
        if at == x0 {
            return y0;
        }
        let w = (at - x0) as f64 / (x1 - x0) as f64;
        y0 + w * (y1 - y0)
    }
}

impl Knot for f64 {
    fn lerp(x0: f64, x1: f64, y0: f64, y1: f64, at: f64) -> f64 {
        y0 + (y1 - y0) * (at - x0) / (x1 - x0)
    }
}

/// What the interpolation gives beyond the first and last knots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Beyond {
    /// The nearest end knot's value (a sensor before its first reading, a history's ends).
    Hold,
    /// The end segment's line continued (a calibration table read past its rows).
    Extend,
}

/// The value at `at` through the knots `(x, y)`; NaN without knots.
pub fn linear<X: Knot>(x: &[X], y: &[f64], at: X, beyond: Beyond) -> f64 {
    debug_assert_eq!(x.len(), y.len());
    let n = x.len();
    match n {
        0 => return f64::NAN,
        1 => return y[0],
        _ => {}
    }
    // Knots at or before `at`: the segment is (after - 1, after).
    let after = x.partition_point(|v| *v <= at);
    match (after, beyond) {
        (0, Beyond::Hold) => y[0],
        (a, Beyond::Hold) if a == n => y[n - 1],
        (a, Beyond::Hold) => X::lerp(x[a - 1], x[a], y[a - 1], y[a], at),
        (a, Beyond::Extend) => {
            let k = a.clamp(1, n - 1);
            if x[k - 1] < x[k] {
                X::lerp(x[k - 1], x[k], y[k - 1], y[k], at)
            } else {
                // Two knots at one abscissa at an end: no slope to continue.
                0.5 * (y[k - 1] + y[k])
            }
        }
    }
}

/// The value at `at` when a knot lies within `max_gap` of it: the line between the two
/// neighbours when both do, else the one that does; `None` when neither does (a gap in the
/// track is not bridged).
pub fn within(x: &[f64], y: &[f64], at: f64, max_gap: f64) -> Option<f64> {
    debug_assert_eq!(x.len(), y.len());
    let after = x.partition_point(|v| *v <= at);
    let before = after.checked_sub(1).map(|j| (x[j], y[j]));
    let next = x.get(after).map(|v| (*v, y[after]));
    match (before, next) {
        (Some((x0, y0)), Some((x1, y1))) if at - x0 <= max_gap && x1 - at <= max_gap => {
            Some(f64::lerp(x0, x1, y0, y1, at))
        }
        (Some((x0, y0)), _) if at - x0 <= max_gap => Some(y0),
        (_, Some((x1, y1))) if x1 - at <= max_gap => Some(y1),
        _ => None,
    }
}

/// Values at many ascending abscissae, walking the knots once ([`Beyond::Hold`]): the same
/// values as [`linear`] at each, in O(knots + queries).
pub(crate) fn linear_ascending<X: Knot>(x: &[X], y: &[f64], at: &[X]) -> Vec<f64> {
    debug_assert_eq!(x.len(), y.len());
    if x.is_empty() {
        return vec![f64::NAN; at.len()];
    }
    let mut after = 0;
    at.iter()
        .map(|&t| {
            debug_assert!(after == 0 || x[after - 1] <= t, "queries not ascending");
            while after < x.len() && x[after] <= t {
                after += 1;
            }
            match after {
                0 => y[0],
                a if a == x.len() => y[a - 1],
                a => X::lerp(x[a - 1], x[a], y[a - 1], y[a], t),
            }
        })
        .collect()
}

/// The value at fractional index `index` of samples on a uniform grid (knots at 0, 1, 2, …;
/// [`Beyond::Hold`]).
pub fn on_grid(y: &[f64], index: f64) -> f64 {
    let Some(last) = y.len().checked_sub(1) else {
        return f64::NAN;
    };
    if index <= 0.0 {
        return y[0];
    }
    let i = index.floor() as usize;
    if i >= last {
        return y[last];
    }
    f64::lerp(i as f64, (i + 1) as f64, y[i], y[i + 1], index)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_knot_gives_its_value_and_a_segment_its_line() {
        let (x, y) = ([0.0, 1.0, 3.0], [1.0, 3.0, -1.0]);
        for beyond in [Beyond::Hold, Beyond::Extend] {
            for (at, want) in [(0.0, 1.0), (0.5, 2.0), (1.0, 3.0), (2.0, 1.0), (3.0, -1.0)] {
                assert_eq!(linear(&x, &y, at, beyond), want, "{at} {beyond:?}");
            }
        }
        assert_eq!(linear(&x, &y, -1.0, Beyond::Hold), 1.0);
        assert_eq!(linear(&x, &y, 4.0, Beyond::Hold), -1.0);
        assert_eq!(linear(&x, &y, -1.0, Beyond::Extend), -1.0);
        assert_eq!(linear(&x, &y, 4.0, Beyond::Extend), -3.0);
        assert!(linear::<f64>(&[], &[], 0.0, Beyond::Hold).is_nan());
        assert_eq!(linear(&[2.0], &[5.0], 9.0, Beyond::Extend), 5.0);
    }

    #[test]
    fn equal_abscissae_are_a_step_the_last_knot_wins() {
        let (x, y) = ([0_i64, 10, 10, 20], [0.0, 1.0, 5.0, 7.0]);
        assert_eq!(linear(&x, &y, 5, Beyond::Hold), 0.5);
        assert_eq!(linear(&x, &y, 10, Beyond::Hold), 5.0);
        assert_eq!(linear(&x, &y, 15, Beyond::Hold), 6.0);
        let (xs, ys) = ([0.0, 1.0, 1.0], [0.0, 2.0, 4.0]);
        assert_eq!(
            linear(&xs, &ys, 2.0, Beyond::Extend),
            3.0,
            "no slope: the mean"
        );
    }

    #[test]
    fn the_ascending_walk_equals_one_search_per_query() {
        let x: Vec<i64> = vec![-5, 0, 0, 7, 30, 31];
        let y = [2.0, -1.0, 4.0, 0.25, 9.0, -3.5];
        let at: Vec<i64> = (-10..40).collect();
        let walked = linear_ascending(&x, &y, &at);
        for (t, v) in at.iter().zip(&walked) {
            assert_eq!(
                v.to_bits(),
                linear(&x, &y, *t, Beyond::Hold).to_bits(),
                "at {t}"
            );
        }
        assert!(linear_ascending::<i64>(&[], &[], &[1])[0].is_nan());
    }

    #[test]
    fn a_gap_wider_than_allowed_is_not_bridged() {
        let (x, y) = ([0.0, 10.0, 100.0], [0.0, 10.0, 100.0]);
        assert_eq!(within(&x, &y, 5.0, 6.0), Some(5.0));
        assert_eq!(
            within(&x, &y, 12.0, 6.0),
            Some(10.0),
            "only the one before is near"
        );
        assert_eq!(
            within(&x, &y, 97.0, 6.0),
            Some(100.0),
            "only the one after is near"
        );
        assert_eq!(within(&x, &y, 50.0, 6.0), None);
        assert_eq!(within(&x, &y, 100.0, 0.0), Some(100.0));
    }

    #[test]
    fn a_uniform_grid_is_read_by_fractional_index() {
        let y = [1.0, 2.0, 4.0];
        assert_eq!(on_grid(&y, 0.5), 1.5);
        assert_eq!(on_grid(&y, 1.25), 2.5);
        assert_eq!(on_grid(&y, -3.0), 1.0);
        assert_eq!(on_grid(&y, 2.0), 4.0);
        assert_eq!(on_grid(&y, 7.5), 4.0);
        for k in 0..20 {
            let index = k as f64 * 0.1;
            assert_eq!(
                on_grid(&y, index),
                linear(&[0.0, 1.0, 2.0], &y, index, Beyond::Hold)
            );
        }
    }
}
