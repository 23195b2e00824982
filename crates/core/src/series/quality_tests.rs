use super::*;

const S: TimeNs = 1_000_000_000;
const B: TimeNs = 1_800_000_000 * S;

fn reading(t_s: i64, c: i64) -> (Region, Piece) {
    let seg = Region::Segment {
        mount: 0,
        rezeros: 0,
    };
    (seg, Piece::reading(B + t_s * S, c))
}

fn segments() -> Segments {
    Segments {
        mounts: vec![(B, B + 100_000 * S, 0)],
        rezeros: vec![],
        edges: vec![],
    }
}

/// Noise of a few counts every 60 s for a day, with a jump, a frozen hour and a wrap.
#[test]
fn jumps_wraps_and_frozen_runs_are_flagged_with_time_and_size() {
    let noise = |i: i64| (i * 7919) % 9 - 4;
    let mut pieces: Vec<(Region, Piece)> = (0..1440).map(|i| reading(i * 60, noise(i))).collect();
    pieces[100].1.mean += 5000.0; // a single-sample spike of 5000 counts (25 µm at 5 nm)
    pieces[100].1.min += 5000;
    pieces[100].1.max += 5000;
    for p in &mut pieces[300..400] {
        (p.1.min, p.1.max, p.1.mean) = (17, 17, 17.0); // frozen 99 min
    }
    let mut q = ChannelQuality::default();
    let leave = check_pieces(&pieces, &segments(), 5.0, &[], &mut q);
    let kinds: Vec<FlagKind> = q.flags.iter().map(|f| f.kind()).collect();
    assert_eq!(
        kinds.iter().filter(|&&k| k == FlagKind::Jump).count(),
        2,
        "{q:?}"
    );
    let stuck: Vec<&Flag> = q
        .flags
        .iter()
        .filter(|f| f.kind() == FlagKind::Stuck)
        .collect();
    assert_eq!(stuck.len(), 1);
    assert_eq!(stuck[0].rows, 100);
    assert_eq!(
        stuck[0].from.as_deref(),
        Some(format_ns(B + 300 * 60 * S).as_str())
    );
    assert_eq!(leave.ranges, vec![(B + 300 * 60 * S, B + 399 * 60 * S)]);
    assert!(leave.mounts.is_empty());
    let jump = q.flags.iter().find(|f| f.kind() == FlagKind::Jump).unwrap();
    assert!((jump.size_counts.unwrap() - 5000.0).abs() < 10.0);
    assert!((jump.size_um.unwrap() - 25.0).abs() < 0.1);

    // A wrap: every reading after #700 is 2^32 lower.
    for p in &mut pieces[700..] {
        p.1.min -= WRAP_COUNTS;
        p.1.max -= WRAP_COUNTS;
        p.1.mean -= WRAP_COUNTS as f64;
    }
    let mut q = ChannelQuality::default();
    let leave = check_pieces(&pieces, &segments(), 5.0, &[], &mut q);
    let wrap: Vec<&Flag> = q
        .flags
        .iter()
        .filter(|f| f.kind() == FlagKind::CounterWrap)
        .collect();
    assert_eq!(wrap.len(), 1, "{q:?}");
    assert_eq!(
        wrap[0].size_counts,
        Some(-(WRAP_COUNTS as f64)).map(|w| w + (noise(700) - noise(699)) as f64)
    );
    assert_eq!(leave.mounts, vec![0]);
}

/// A live encoder is not frozen: an hour of equal counts while the air stood still is kept.
#[test]
fn equal_counts_while_the_air_stands_still_are_not_frozen() {
    let pieces: Vec<(Region, Piece)> = (0..120).map(|i| reading(i * 60, 3)).collect();
    let still = SensorLog {
        time_ns: (0..120).map(|i| B + i * 60 * S).collect(),
        celsius: vec![20.0; 120],
    };
    let mut q = ChannelQuality::default();
    let leave = check_pieces(&pieces, &segments(), 5.0, &[&still], &mut q);
    assert!(leave.ranges.is_empty() && q.flags.is_empty(), "{q:?}");
    let moving = SensorLog {
        celsius: (0..120).map(|i| 20.0 + 0.01 * i as f64).collect(),
        ..still
    };
    let leave = check_pieces(&pieces, &segments(), 5.0, &[&moving], &mut q);
    assert_eq!(leave.ranges.len(), 1);
}

#[test]
fn exact_duplicates_are_counted_once() {
    let mut t = vec![1, 1, 2, 2, 2, 3];
    let mut c = vec![5, 5, 6, 7, 7, 8];
    let (n, range) = dedup_sorted(&mut t, &mut c);
    assert_eq!((n, range), (2, Some((1, 2))));
    assert_eq!((t, c), (vec![1, 2, 2, 3], vec![5, 6, 7, 8]));
}

/// Issue 27 (W2): out-of-range temperatures and steps no air makes are dropped and counted; a
/// bad first reading is no yardstick; a real step is followed again once the allowance covers it.
#[test]
fn implausible_temperatures_are_dropped_and_a_real_step_is_followed_again() {
    let mut t: Vec<TimeNs> = (0..100).map(|i| B + i * 60 * S).collect();
    let mut c = vec![20.0; 100];
    c[0] = 80.0; // a bad first reading
    c[10] = -300.0; // below absolute zero
    c[20] = 1e300;
    for v in &mut c[60..] {
        *v = 30.0; // the sensor really moves on: 10 K, more than 5 + 0.05 x 60 = 8 K at once
    }
    let mut q = ChannelQuality::default();
    drop_implausible_temperatures(&mut t, &mut c, &mut q);
    assert_eq!(q.dropped_rows, 4);
    assert_eq!(q.fault_rows, 4);
    assert_eq!(t.len(), 96);
    assert!(!t.contains(&B) && !t.contains(&(B + 10 * 60 * S)) && !t.contains(&(B + 60 * 60 * S)));
    assert!(
        t.contains(&(B + 61 * 60 * S)),
        "the new level is followed again"
    );
    assert_eq!(q.flags.len(), 1);
    assert_eq!(q.flags[0].kind(), FlagKind::ImplausibleTemperature);
    assert_eq!(q.flags[0].rows, 4);
    // Plausible readings are left alone.
    let mut t2: Vec<TimeNs> = (0..10).map(|i| B + i * S).collect();
    let mut c2: Vec<f64> = (0..10).map(|i| 20.0 + 0.01 * i as f64).collect();
    let mut q2 = ChannelQuality::default();
    drop_implausible_temperatures(&mut t2, &mut c2, &mut q2);
    assert_eq!((t2.len(), q2.dropped_rows, q2.flags.len()), (10, 0, 0));
}
