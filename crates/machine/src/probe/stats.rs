//! Statistics of touches grouped by direction (`docs/spec/machine-physics.md`, "Kind `probe`";
//! seed 003, Tables 1 and 2): per direction the mean of touches 2… (the two-touch method's
//! pretravel), their 2σ, the first touch's offset from them, the ranges over all touches and
//! over touches 2…, and the seed's printed summary rows ("1~2": |touch 1 − touch 2|, "2~10":
//! the range of touches 2 to 10).

/// The values of one direction's visit, in touch order (touch 1 first).
pub(crate) fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.iter().sum::<f64>() / v.len() as f64
}

/// max − min; NaN when empty.
pub fn range(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    max - min
}

/// The seed's two summary rows of one column of touches (touch 1 first): "1~2" =
/// |touch 1 − touch 2| and "2~10" = the range of touches 2 … n (seed 003, Tables 1 and 2).
pub fn seed_summary_rows(touches: &[f64]) -> (f64, f64) {
    if touches.len() < 2 {
        return (f64::NAN, f64::NAN);
    }
    ((touches[0] - touches[1]).abs(), range(&touches[1..]))
}

/// All-touch against two-touch statistics of one direction's visits.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionSpread {
    /// Mean of touches 2… over every visit, µm (the two-touch pretravel).
    pub mean_2on_um: f64,
    /// Mean of every touch, µm.
    pub mean_all_um: f64,
    /// 2σ of touches 2… about their visit's mean, µm.
    pub two_sigma_2on_um: f64,
    /// 2σ of every touch about its visit's mean, µm.
    pub two_sigma_all_um: f64,
    /// Mean over visits of touch 1 − the mean of touches 2… of that visit, µm.
    pub first_touch_offset_um: f64,
    /// Mean over visits of the range of every touch, µm.
    pub range_all_um: f64,
    /// Mean over visits of the range of touches 2…, µm.
    pub range_2on_um: f64,
    /// Touches, and visits (runs of touches after a change).
    pub touches: usize,
    /// Visits.
    pub visits: usize,
}

/// The spread of one direction from its visits (each in touch order, touch 1 first).
pub fn direction_spread(visits: &[Vec<f64>]) -> DirectionSpread {
    let all: Vec<f64> = visits.iter().flatten().copied().collect();
    let two_on: Vec<f64> = visits
        .iter()
        .flat_map(|v| v.iter().skip(1))
        .copied()
        .collect();
    let pooled = |skip: usize| {
        let (mut ss, mut dof) = (0.0, 0usize);
        for v in visits {
            let part = &v[skip.min(v.len())..];
            if part.len() >= 2 {
                let m = mean(part);
                ss += part.iter().map(|x| (x - m).powi(2)).sum::<f64>();
                dof += part.len() - 1;
            }
        }
        if dof == 0 {
            f64::NAN
        } else {
            2.0 * (ss / dof as f64).sqrt()
        }
    };
    let offsets: Vec<f64> = visits
        .iter()
        .filter(|v| v.len() >= 2)
        .map(|v| v[0] - mean(&v[1..]))
        .collect();
    let ranges = |skip: usize| {
        let r: Vec<f64> = visits
            .iter()
            .filter(|v| v.len() > skip)
            .map(|v| range(&v[skip..]))
            .collect();
        mean(&r)
    };
    DirectionSpread {
        mean_2on_um: mean(&two_on),
        mean_all_um: mean(&all),
        two_sigma_2on_um: pooled(1),
        two_sigma_all_um: pooled(0),
        first_touch_offset_um: mean(&offsets),
        range_all_um: ranges(0),
        range_2on_um: ranges(1),
        touches: all.len(),
        visits: visits.len(),
    }
}

/// Campaign-wide all-touch against two-touch figures over the directions' spreads.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoTouchSummary {
    /// Mean over directions of the mean range over all touches, µm.
    pub mean_range_all_um: f64,
    /// Mean over directions of the mean range over touches 2…, µm.
    pub mean_range_2on_um: f64,
    /// Their ratio (the seed: 1.89).
    pub range_ratio: f64,
    /// Pooled 2σ within a direction over all touches, µm.
    pub two_sigma_all_um: f64,
    /// Pooled 2σ within a direction over touches 2…, µm.
    pub two_sigma_2on_um: f64,
    /// The smallest and largest first-touch offset over directions, µm.
    pub first_touch_offset_span_um: (f64, f64),
    /// Largest − smallest direction mean of touches 2…, µm (the seed: 3.41).
    pub means_spread_um: f64,
}

/// The summary of the directions' spreads.
pub fn two_touch_summary(spreads: &[DirectionSpread]) -> TwoTouchSummary {
    let col = |f: fn(&DirectionSpread) -> f64| -> Vec<f64> {
        spreads.iter().map(f).filter(|v| v.is_finite()).collect()
    };
    let rms = |v: Vec<f64>| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let all = mean(&col(|s| s.range_all_um));
    let two = mean(&col(|s| s.range_2on_um));
    let offsets = col(|s| s.first_touch_offset_um);
    TwoTouchSummary {
        mean_range_all_um: all,
        mean_range_2on_um: two,
        range_ratio: all / two,
        two_sigma_all_um: rms(col(|s| s.two_sigma_all_um)),
        two_sigma_2on_um: rms(col(|s| s.two_sigma_2on_um)),
        first_touch_offset_span_um: (
            offsets.iter().copied().fold(f64::INFINITY, f64::min),
            offsets.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ),
        means_spread_um: range(&col(|s| s.mean_2on_um)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_visit_of_three_gives_its_offset_and_ranges() {
        let s = direction_spread(&[vec![1.0, 2.0, 2.2], vec![0.0, 1.0, 1.0]]);
        assert!((s.first_touch_offset_um - (-1.05)).abs() < 1e-12);
        assert!((s.range_all_um - 1.1).abs() < 1e-12);
        assert!((s.range_2on_um - 0.1).abs() < 1e-12);
        assert!((s.mean_2on_um - 1.55).abs() < 1e-12);
        assert_eq!((s.touches, s.visits), (6, 2));
        let (one_two, two_on) = seed_summary_rows(&[0.8, 1.0, 1.1, 1.0]);
        assert!((one_two - 0.2).abs() < 1e-12 && (two_on - 0.1).abs() < 1e-12);
    }
}
