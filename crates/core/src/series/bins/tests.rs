use super::grid::BinKey;
use super::moments::BinMoments;
use super::reorder::Divide;
use super::*;

/// Moments of readings given as (µs after the bin's start, counts).
fn moments(samples: &[(i64, i64)]) -> BinMoments {
    let (time, counts): (Vec<TimeNs>, Vec<i64>) =
        samples.iter().map(|&(u, c)| (u * NS_PER_US, c)).unzip();
    let mut m = BinMoments::default();
    m.add_run(0, &time, &counts);
    m
}

/// Σ w_k p(s_k) = Σ_i p(u_i) for polynomials of degree ≤ 3, and Σ (c - f)² over the readings
/// equals the nodes' weighted RSS plus the line scatter for any straight line f.
#[test]
fn nodes_keep_every_moment_a_straight_line_model_sees() {
    let samples: Vec<(i64, i64)> = [0, 1_000_000, 2_500_000, 2_600_000, 7_000_000, 9_900_000]
        .iter()
        .zip([100, 103, 98, 120, 111, 95])
        .map(|(&u, c)| (u, c))
        .collect();
    let (nodes, line_rss) = moments(&samples).nodes();
    assert_eq!(nodes.len(), 2);
    for degree in 0..=3 {
        let exact: f64 = samples.iter().map(|&(u, _)| (u as f64).powi(degree)).sum();
        let quad: f64 = nodes
            .iter()
            .map(|n| n.weight * n.offset_us.powi(degree))
            .sum();
        assert!(
            (quad - exact).abs() <= 1e-9 * exact.abs().max(1.0),
            "degree {degree}"
        );
    }
    for (a, b) in [(100.0, 0.0), (90.0, 3e-6), (120.0, -1e-5)] {
        let f = |u: f64| a + b * u;
        let full: f64 = samples
            .iter()
            .map(|&(u, c)| (c as f64 - f(u as f64)).powi(2))
            .sum();
        let compressed: f64 = nodes
            .iter()
            .map(|n| n.weight * (n.counts - f(n.offset_us)).powi(2))
            .sum::<f64>()
            + line_rss;
        assert!(
            (full - compressed).abs() < 1e-9 * full,
            "{full} vs {compressed}"
        );
    }
}

#[test]
fn a_bin_of_one_time_is_one_node_with_the_mean() {
    let (nodes, rss) = moments(&[(5, 10), (5, 14)]).nodes();
    assert_eq!(nodes.len(), 1);
    assert_eq!((nodes[0].weight, nodes[0].counts), (2.0, 12.0));
    assert!((rss - 8.0).abs() < 1e-12);
    let (two, rss) = moments(&[(0, 1), (10, 5)]).nodes();
    assert_eq!(two.len(), 2);
    assert!((two[0].offset_us - 0.0).abs() < 1e-9 && (two[1].offset_us - 10.0).abs() < 1e-9);
    assert!((two[0].counts - 1.0).abs() < 1e-9 && (two[1].counts - 5.0).abs() < 1e-9);
    assert!(rss.abs() < 1e-9);
}

/// The integer sums are exact up to the longest bin: times near an hour (u² > i64::MAX)
/// and counts near the i64 range, against sums done one reading at a time in i128.
#[test]
fn bin_sums_are_exact_up_to_an_hour() {
    let us = [0, 1, 3_037_000_499, 3_037_000_500, 3_599_999_999];
    // Σc² of these is 2¹²⁷ − 2⁶⁵ + 2⁶⁴ + 51, just inside i128 (with 1 << 40 it overflowed:
    // found by overflow-checks, issue 14).
    let counts = [i64::MAX, i64::MIN + 1, -7, 0, 1 << 32];
    let samples: Vec<(i64, i64)> = us.iter().copied().zip(counts).collect();
    let m = moments(&samples);
    let sum = |f: &dyn Fn(i128, i128) -> i128| -> i128 {
        samples.iter().map(|&(u, c)| f(u as i128, c as i128)).sum()
    };
    assert_eq!(m.su, sum(&|u, _| u));
    assert_eq!(m.suu, sum(&|u, _| u * u));
    assert_eq!(m.suuu, sum(&|u, _| u * u * u));
    assert_eq!(m.sc, sum(&|_, c| c));
    assert_eq!(m.suc, sum(&|u, c| u * c));
    assert_eq!(m.scc, sum(&|_, c| c * c));
    assert_eq!((m.n, m.first_us, m.last_us), (5, 0, 3_599_999_999));
}

/// 2027-01-15: an accepted reading time (`reading_time_ok`).
const B: TimeNs = 1_800_000_000_000_000_000;

/// 500 readings a second apart from [`B`], on a grid of 60-s bins with one mount and one
/// rezero.
fn five_hundred_readings() -> (BinGrid, Vec<TimeNs>, Vec<i64>) {
    let time: Vec<TimeNs> = (0..500).map(|i| B + 1_000_000_000 * i + 7).collect();
    let counts: Vec<i64> = (0..500).map(|i| (i * 37) % 101 - 50).collect();
    let grid = BinGrid {
        bin_ns: 60_000_000_000,
        mounts: vec![(B + 100_000_000_000, B + 400_000_000_000, 0)],
        rezeros: vec![B + 250_000_000_000],
        edges: vec![],
    };
    (grid, time, counts)
}

#[test]
fn the_order_of_the_readings_does_not_change_the_bins() {
    let (grid, time, counts) = five_hundred_readings();
    let sorted = BarBins::from_log(grid.clone(), &time, &counts).unwrap();
    let mut order: Vec<usize> = (0..500).collect();
    order.reverse();
    order.swap(3, 400);
    let (t2, c2): (Vec<_>, Vec<_>) = order.iter().map(|&i| (time[i], counts[i])).unzip();
    assert_eq!(BarBins::from_log(grid, &t2, &c2).unwrap(), sorted);
    assert_eq!(sorted.n_readings(), 500);
    // Bins never cross the mount start/end or the rezero, and start on their region's grid.
    let starts: Vec<(TimeNs, Region)> = sorted
        .bins
        .iter()
        .map(|(k, _)| (k.start_ns, k.region))
        .collect();
    assert!(starts.contains(&(
        B + 100_000_000_000,
        Region::Segment {
            mount: 0,
            rezeros: 0
        }
    )));
    assert!(starts.contains(&(
        B + 250_000_000_000,
        Region::Segment {
            mount: 0,
            rezeros: 1
        }
    )));
    assert!(starts.contains(&(B + 400_000_000_000, Region::Outside)));
    assert!(sorted.bins.windows(2).all(|w| w[0].0 < w[1].0));
}

/// `add_all_then` hands over every row's time once, in the order the bins took them: as given
/// when in time order, grouped by bin (each bin's times together, bins in time order) when a
/// shuffled batch was sorted; and its bins are `add_all`'s.
#[test]
fn add_all_then_hands_over_the_rows_in_the_order_they_were_added() {
    let (grid, time, counts) = five_hundred_readings();
    let mut plain = BinAccumulator::new(grid.clone());
    plain.add_all(&time, &counts).unwrap();
    let mut seen = Vec::new();
    let mut then = BinAccumulator::new(grid.clone());
    then.add_all_then(&time, &counts, |rows| seen.extend_from_slice(rows))
        .unwrap();
    assert_eq!(seen, time, "rows in time order are handed over as given");
    // The 300 rows inside the mount, shuffled (a fixed permutation: i * 7 mod 300).
    let order: Vec<usize> = (0..300).map(|i| 100 + (i * 7) % 300).collect();
    let (t2, c2): (Vec<_>, Vec<_>) = order.iter().map(|&i| (time[i], counts[i])).unzip();
    let mut shuffled = BinAccumulator::new(grid.clone());
    let mut handed = Vec::new();
    shuffled
        .add_all_then(&t2, &c2, |rows| handed.extend_from_slice(rows))
        .unwrap();
    assert_ne!(handed, t2, "a shuffled batch is sorted before it is added");
    // Grouped by bin, bins in time order: never back by a bin's length or more.
    assert!(handed.windows(2).all(|w| w[1] > w[0] - grid.bin_ns));
    let mut sorted_handed = handed.clone();
    sorted_handed.sort_unstable();
    assert_eq!(sorted_handed, time[100..400], "every row once");
    let mut inside = BinAccumulator::new(grid.clone());
    inside.add_all(&time[100..400], &counts[100..400]).unwrap();
    assert_eq!(shuffled.finish(), inside.finish());
    assert_eq!(then.finish(), plain.finish());
    // Refused rows: nothing added, `then` not called.
    let mut refused = BinAccumulator::new(grid);
    let mut called = false;
    assert!(refused
        .add_all_then(&[i64::MIN], &[0], |_| called = true)
        .is_err());
    assert!(!called);
}

#[test]
fn accumulators_of_other_grids_are_not_merged() {
    let (grid, time, counts) = five_hundred_readings();
    let mut acc = BinAccumulator::new(grid.clone());
    acc.add_all(&time, &counts).unwrap();
    let coarser = BinGrid {
        bin_ns: 2 * grid.bin_ns,
        ..grid.clone()
    };
    let mut other = BinAccumulator::new(coarser);
    other.add_all(&time, &counts).unwrap();
    assert_eq!(acc.clone().merge(other), Err(BinError::OtherGrid));
    let mut doubled = acc.clone();
    doubled.merge(acc).unwrap();
    assert_eq!(doubled.finish().n_readings(), 1000);
}

#[test]
fn removing_readings_gives_back_the_bins_without_them() {
    let (grid, time, counts) = five_hundred_readings();
    let clean = BarBins::from_log(grid.clone(), &time, &counts).unwrap();
    // Add then remove everything: no bin left.
    let mut acc = BinAccumulator::new(grid.clone());
    acc.add_all(&time, &counts).unwrap();
    acc.remove_all(&time, &counts).unwrap();
    assert!(acc.finish().bins.is_empty());
    // The log plus copies of some of its rows (another file, another order), the copies
    // removed: exactly the bins of the log, bit for bit (first/last, min/max included).
    let mut acc = BinAccumulator::new(grid.clone());
    acc.add_all(&time, &counts).unwrap();
    let copies: Vec<usize> = (120..340).rev().chain([0, 499]).collect();
    let (ct, cc): (Vec<_>, Vec<_>) = copies.iter().map(|&i| (time[i], counts[i])).unzip();
    acc.add_all(&ct, &cc).unwrap();
    assert_ne!(acc.clone().finish(), clean);
    acc.remove_all(&ct, &cc).unwrap();
    let back = acc.finish();
    assert_eq!(back, clean);
    assert_eq!(back.n_readings(), 500);
    // A reading where no bin holds one is refused.
    let mut acc = BinAccumulator::new(grid);
    assert_eq!(
        acc.remove_all(&[B + 7], &[1]),
        Err(BinError::NotAdded { time_ns: B + 7 })
    );
}

/// Bins by the definition: each reading's bin from [`BinGrid::locate`], equal bins merged.
fn reference_bins(grid: &BinGrid, time: &[TimeNs], counts: &[i64]) -> BarBins {
    let mut runs: Vec<(BinKey, BinMoments)> = time
        .iter()
        .zip(counts)
        .map(|(&t, &c)| {
            let (key, end) = grid.locate(t);
            assert!(key.start_ns <= t && t < end);
            let mut m = BinMoments::default();
            m.add_run(key.start_ns, &[t], &[c]);
            (key, m)
        })
        .collect();
    runs.sort_by_key(|(key, _)| *key);
    let mut bins: Vec<(BinKey, BinMoments)> = Vec::new();
    for (key, moments) in runs {
        match bins.last_mut() {
            Some((last, sum)) if *last == key => sum.merge(&moments),
            _ => bins.push((key, moments)),
        }
    }
    BarBins {
        bin_ns: grid.bin_ns,
        bins,
    }
}

/// The paged accumulator gives the bins of the definition for readings in any order:
/// before, between and after mounts, across rezeros (two at one instant, one at a mount
/// start, one outside), far from every mount, and for bins so short that a span's pages
/// overflow its dense table.
#[test]
fn the_accumulator_gives_the_bins_of_the_definition_in_any_order() {
    use rand::seq::SliceRandom;
    use rand::{Rng, SeedableRng};
    const S: i64 = 1_000_000_000;
    // Times from 2027-01-15 (accepted reading times, `reading_time_ok`).
    const B: TimeNs = 1_800_000_000 * S;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
    let mounts = vec![
        (B + 1_000 * S, B + 5_000 * S, 0),
        (B + 5_000 * S, B + 9_000 * S + 7, 2),
        (B + 20_000 * S, B + 30_000 * S, 1),
    ];
    let rezeros: Vec<TimeNs> = [
        500 * S,
        3_000 * S,
        3_000 * S,
        5_000 * S,
        12_000 * S,
        25_000 * S + 3,
    ]
    .iter()
    .map(|&t| B + t)
    .collect();
    // Event edges: inside segments, on a rezero, on a mount's end, in handling time.
    let edges: Vec<TimeNs> = [
        2_000 * S + 1,
        3_000 * S,
        4_999 * S,
        9_000 * S + 7,
        15_000 * S,
    ]
    .iter()
    .map(|&t| B + t)
    .collect();
    let mut time: Vec<TimeNs> = (0..20_000)
        .map(|_| B + rng.gen_range(-2_000 * S..40_000 * S))
        .collect();
    time.extend([
        EARLIEST_READING_NS,
        B - 1,
        B,
        B + 1_000 * S,
        B + 5_000 * S - 1,
        B + 3_000 * S,
        B + 9_000 * S + 7,
        LATEST_READING_NS - 1,
    ]);
    let counts: Vec<i64> = (0..time.len())
        .map(|_| rng.gen_range(-1000..1000))
        .collect();
    for bin_ns in [60 * S, 7 * S + 3, 1_000, 1 << 20] {
        let grid = BinGrid {
            bin_ns,
            mounts: mounts.clone(),
            rezeros: rezeros.clone(),
            edges: edges.clone(),
        };
        let want = reference_bins(&grid, &time, &counts);
        let mut order: Vec<usize> = (0..time.len()).collect();
        for pass in 0..3 {
            match pass {
                0 => order.sort_by_key(|&i| time[i]),
                1 => order.reverse(),
                _ => order.shuffle(&mut rng),
            }
            let (t, c): (Vec<_>, Vec<_>) = order.iter().map(|&i| (time[i], counts[i])).unzip();
            let mut acc = BinAccumulator::new(grid.clone());
            for (tc, cc) in t.chunks(777).zip(c.chunks(777)) {
                acc.add_all(tc, cc).unwrap();
            }
            assert_eq!(acc.finish(), want, "bin {bin_ns} ns, pass {pass}");
        }
    }
}

#[test]
fn division_by_multiplication_is_exact() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let divisors = [
        1,
        2,
        3,
        7,
        1_000,
        60_000_000_000,
        (1 << 40) + 1,
        u64::MAX / 3,
        u64::MAX,
    ];
    for &d in &divisors {
        let divide = Divide::new(d);
        let edges = [0, 1, d - 1, d, d.saturating_add(1), u64::MAX - 1, u64::MAX];
        for n in edges
            .into_iter()
            .chain((0..10_000).map(|_| rng.gen::<u64>() >> rng.gen_range(0..64)))
        {
            assert_eq!(divide.quotient(n), n / d, "{n} / {d}");
        }
    }
}

/// The weight-0 samples: the first reading, sensor times between close nodes, and the last
/// reading before and first after a gap; none inside a gap.
#[test]
fn readings_carry_the_full_rate_grid_of_the_lags() {
    const S: i64 = 1_000_000_000;
    let grid = BinGrid {
        bin_ns: 60 * S,
        mounts: vec![],
        rezeros: vec![],
        edges: vec![],
    };
    // 1 Hz for 10 min, a 30-min gap, 1 Hz for 10 min again.
    const B: TimeNs = 1_800_000_000 * S;
    let time: Vec<TimeNs> = (0..600).chain(2400..3000).map(|i| B + i * S).collect();
    let counts: Vec<i64> = (0..time.len() as i64).map(|i| i % 7).collect();
    let bins = BarBins::from_log(grid, &time, &counts).unwrap();
    let knots: Vec<TimeNs> = (0..100).map(|i| B + i * 30 * S + 5 * S).collect();
    let r = bins.readings(&knots);
    assert!(r.time_ns.windows(2).all(|w| w[0] < w[1]), "sorted");
    let zero: Vec<TimeNs> = r
        .time_ns
        .iter()
        .zip(&r.weight)
        .filter(|(_, &w)| w == 0.0)
        .map(|(&t, _)| t)
        .collect();
    assert_eq!(zero[0], B, "the first reading");
    assert!(
        zero.contains(&(B + 599 * S)) && zero.contains(&(B + 2400 * S)),
        "gap edges"
    );
    assert!(
        zero.contains(&(B + 35 * S)) && zero.contains(&(B + 2435 * S)),
        "sensor times"
    );
    assert!(
        !zero.iter().any(|&t| t > B + 599 * S && t < B + 2400 * S),
        "nothing in the gap"
    );
    let total: f64 = r.weight.iter().sum();
    assert!((total - 1200.0).abs() < 1e-9);
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    const S: TimeNs = 1_000_000_000;
    const B: TimeNs = 1_800_000_000 * S;

    fn grid(bin_s: i64) -> BinGrid {
        BinGrid {
            bin_ns: bin_s * S,
            mounts: vec![
                (B + 1_000 * S, B + 50_000 * S, 0),
                (B + 60_000 * S, B + 90_000 * S, 1),
            ],
            rezeros: vec![B + 20_000 * S],
            // Events: inside a segment, on a mount's start, in handling time.
            edges: vec![
                B + 7_777 * S + 3,
                B + 33_333 * S,
                B + 55_000 * S,
                B + 60_000 * S,
            ],
        }
    }

    /// The rows shuffled by `keys`, added in one call, give the bins of the definition.
    fn check_shuffled(
        time: &[TimeNs],
        counts: &[i64],
        keys: &[u32],
        bin_s: i64,
    ) -> Result<(), TestCaseError> {
        let want = reference_bins(&grid(bin_s), time, counts);
        let mut order: Vec<usize> = (0..time.len()).collect();
        order.sort_by_key(|&i| keys[i % keys.len()]);
        let t: Vec<TimeNs> = order.iter().map(|&i| time[i]).collect();
        let c: Vec<i64> = order.iter().map(|&i| counts[i]).collect();
        let mut acc = BinAccumulator::new(grid(bin_s));
        acc.add_all(&t, &c).unwrap();
        prop_assert_eq!(acc.finish(), want);
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Any row order and any split into batches gives the same bins.
        #[test]
        fn any_order_or_batch_split_gives_the_same_bins(
            rows in prop::collection::vec((-5_000i64..100_000, -100_000i64..100_000), 1..600),
            keys in prop::collection::vec(any::<u32>(), 600),
            batch in 1usize..300,
            bin_s in 1i64..3600,
        ) {
            let time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
            let counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
            let want = BarBins::from_log(grid(bin_s), &time, &counts).unwrap();
            let mut order: Vec<usize> = (0..rows.len()).collect();
            order.sort_by_key(|&i| keys[i]);
            let t: Vec<TimeNs> = order.iter().map(|&i| time[i]).collect();
            let c: Vec<i64> = order.iter().map(|&i| counts[i]).collect();
            let mut acc = BinAccumulator::new(grid(bin_s));
            for (tc, cc) in t.chunks(batch).zip(c.chunks(batch)) {
                acc.add_all(tc, cc).unwrap();
            }
            prop_assert_eq!(acc.finish(), want);
        }

        /// Shuffled rows within one zero segment (a shuffled day file: the per-bin counting
        /// sort) give the bins of the definition, with or without a few rows beyond it.
        #[test]
        fn shuffled_rows_of_one_segment_give_the_same_bins(
            rows in prop::collection::vec((1_000i64..20_000, -100_000i64..100_000), 256..1200),
            keys in prop::collection::vec(any::<u32>(), 1200),
            outside in 0usize..3,
            bin_s in 1i64..600,
        ) {
            let mut time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
            let mut counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
            for k in 0..outside {
                time.push(B + 30_000 * S + k as i64); // after the rezero: another span
                counts.push(k as i64);
            }
            check_shuffled(&time, &counts, &keys, bin_s)?;
        }

        /// Shuffled rows over both mounts, the rezero and the handling time between them (a
        /// day file crossing a mount's end: split by span, then sorted by bin) give the bins
        /// of the definition.
        #[test]
        fn shuffled_rows_over_several_spans_give_the_same_bins(
            rows in prop::collection::vec((1_000i64..90_000, -100_000i64..100_000), 256..1500),
            keys in prop::collection::vec(any::<u32>(), 1500),
            bin_s in 300i64..3600,
        ) {
            let time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
            let counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
            check_shuffled(&time, &counts, &keys, bin_s)?;
        }

        /// Batches dealt between two accumulators (as ingest's two consumers take them) and
        /// merged give the bins of one accumulator given every row.
        #[test]
        fn batches_dealt_to_two_accumulators_merge_to_the_same_bins(
            rows in prop::collection::vec((-5_000i64..100_000, -100_000i64..100_000), 1..600),
            deal in prop::collection::vec(any::<bool>(), 600),
            batch in 1usize..300,
            bin_s in 1i64..3600,
        ) {
            let time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
            let counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
            let want = reference_bins(&grid(bin_s), &time, &counts);
            let mut two = [BinAccumulator::new(grid(bin_s)), BinAccumulator::new(grid(bin_s))];
            for (k, (tc, cc)) in time.chunks(batch).zip(counts.chunks(batch)).enumerate() {
                two[usize::from(deal[k])].add_all(tc, cc).unwrap();
            }
            let [mut first, second] = two;
            first.merge(second).unwrap();
            prop_assert_eq!(first.finish(), want);
        }

        /// Extreme times and counts are refused (an error, nothing added), never a panic,
        /// a hang or a wrapped sum; accepted ones are summed exactly.
        #[test]
        fn extreme_values_are_refused_not_wrapped(
            t in prop_oneof![
                Just(i64::MIN), Just(i64::MAX), Just(0i64), Just(-1i64),
                Just(EARLIEST_READING_NS - 1), Just(EARLIEST_READING_NS),
                Just(LATEST_READING_NS - 1), Just(LATEST_READING_NS), any::<i64>()
            ],
            c in prop_oneof![
                Just(i64::MIN), Just(i64::MAX), Just(MAX_ABS_COUNTS),
                Just(-MAX_ABS_COUNTS), Just(MAX_ABS_COUNTS + 1), any::<i64>()
            ],
        ) {
            let mut acc = BinAccumulator::new(grid(60));
            let ok = reading_time_ok(t) && c.unsigned_abs() <= MAX_ABS_COUNTS as u64;
            let r = acc.add_all(&[t, t], &[c, c]);
            prop_assert_eq!(r.is_ok(), ok);
            let bins = acc.finish();
            if ok {
                prop_assert_eq!(bins.n_readings(), 2);
                let m = bins.bins[0].1;
                prop_assert_eq!(m.sc, 2 * c as i128);
                prop_assert_eq!(m.scc, 2 * (c as i128) * (c as i128));
            } else {
                prop_assert_eq!(bins.n_readings(), 0);
            }
        }
    }
}

/// A time constant the bins cannot hold re-reads the campaign only when the data determine it:
/// short, and its interval short too (`too_short_for_bins`).
#[test]
fn only_a_determined_short_time_constant_is_too_short_for_the_bins() {
    // 60-s bins hold time constants from 120 s.
    assert!(
        too_short_for_bins(100.0, 115.0, 60.0),
        "determined and short"
    );
    assert!(
        !too_short_for_bins(145.0, 194.0, 60.0),
        "2.4 bins: long enough"
    );
    assert!(
        !too_short_for_bins(1.0, 3.0e8, 60.0),
        "run to its 1-s search bound, its interval reaching 3e8 s: not determined"
    );
    assert!(
        !too_short_for_bins(100.0, 150.0, 60.0),
        "its interval reaches 2 bins"
    );
    assert!(
        too_short_for_bins(100.0, f64::NAN, 60.0),
        "no interval: counted short"
    );
    assert!(
        !too_short_for_bins(1.0, 2.0, 0.0),
        "every reading: never too short"
    );
    // Bins longer than the automatic 60 s hold time constants from 10 of them.
    assert!(too_short_for_bins(2000.0, 2300.0, 240.0), "8 bins of 240 s");
    assert!(!too_short_for_bins(2000.0, 2300.0, 60.0), "33 bins of 60 s");
}
