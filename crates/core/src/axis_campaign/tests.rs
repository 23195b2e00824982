//! The `axis` campaign's reader rules.

use super::logs::reflector_at;
use super::*;

// ---------------------------------------------------------------- rules

fn key(
    time_s: i64,
    run: i64,
    target_mm: f64,
    channel: Channel,
    direction: Option<i8>,
) -> ReadingKey {
    ReadingKey {
        time_ns: time_s * 1_000_000_000,
        line: 1,
        run,
        target_mm,
        channel,
        deviation_um: 0.0,
        direction,
    }
}

#[test]
fn directions_are_the_sign_of_the_change_and_a_run_s_first_target_takes_its_second_s() {
    // A pendulum run: up 0, 100, 200, the turn read twice at 200, down 100, 0; then run 2 down.
    let targets = [0.0, 100.0, 200.0, 200.0, 100.0, 0.0];
    let mut keys: Vec<ReadingKey> = targets
        .iter()
        .enumerate()
        .map(|(i, &x)| key(i as i64, 1, x, Channel::Dx, None))
        .collect();
    keys.extend(
        [500.0, 400.0, 300.0]
            .iter()
            .enumerate()
            .map(|(i, &x)| key(100 + i as i64, 2, x, Channel::Dx, None)),
    );
    let o = derive_order(&keys).unwrap();
    assert_eq!(o.order, (0..9).collect::<Vec<_>>());
    assert_eq!(o.direction, [1, 1, 1, -1, -1, -1, -1, -1, -1]);
    // Rows in any order (and channels of one target) give the same.
    let mut shuffled = keys.clone();
    shuffled.reverse();
    let r = derive_order(&shuffled).unwrap();
    let directions: Vec<i8> = r.order.iter().map(|&i| r.direction[i]).collect();
    assert_eq!(directions, [1, 1, 1, -1, -1, -1, -1, -1, -1]);
    // A given direction wins, null ones are derived.
    keys[1].direction = Some(-1);
    let o = derive_order(&keys).unwrap();
    assert_eq!(o.direction[..3], [1, -1, 1]);
}

#[test]
fn the_channels_of_one_target_are_one_visit() {
    let keys = vec![
        key(0, 1, 0.0, Channel::Dy, None),
        key(0, 1, 0.0, Channel::Dx, None),
        key(5, 1, -50.0, Channel::Dx, None),
        key(5, 1, -50.0, Channel::Dy, None),
        key(6, 1, -50.0, Channel::Dz, None),
    ];
    let o = derive_order(&keys).unwrap();
    assert_eq!(o.order, [1, 0, 2, 3, 4]);
    assert_eq!(o.direction, [-1; 5]);
}

#[test]
fn repeated_times_are_ordered_by_target_in_the_run_s_direction() {
    let down = [300.0, 100.0, 200.0].map(|x| key(7, 1, x, Channel::Dx, Some(-1)));
    let o = derive_order(&down).unwrap();
    assert_eq!(o.order, [0, 2, 1]);
    let up = [300.0, 100.0, 200.0].map(|x| key(7, 1, x, Channel::Dx, Some(1)));
    assert_eq!(derive_order(&up).unwrap().order, [1, 2, 0]);
    // Without direction: refused, naming the rows.
    let mut bad = up;
    bad[2].direction = None;
    let e = derive_order(&bad).unwrap_err();
    assert_eq!(e.rows, [0, 1, 2]);
    assert!(e.to_string().contains("line 1, run 1") && e.problem.contains("`direction`"));
    let mut mixed = up;
    mixed[0].direction = Some(-1);
    assert!(derive_order(&mixed)
        .unwrap_err()
        .problem
        .contains("both directions"));
}

#[test]
fn a_run_at_one_target_or_a_bad_direction_is_refused() {
    let keys = [
        key(0, 3, 10.0, Channel::Dx, None),
        key(1, 3, 10.0, Channel::Dx, None),
    ];
    let e = derive_order(&keys).unwrap_err();
    assert_eq!((e.run, e.rows.clone()), (3, vec![0, 1]));
    assert!(e.problem.contains("cannot be derived"), "{e}");
    let keys = [key(0, 3, 10.0, Channel::Dx, Some(2))];
    assert!(derive_order(&keys)
        .unwrap_err()
        .problem
        .contains("+1 nor -1"));
    // Given: fine.
    assert!(derive_order(&[key(0, 3, 10.0, Channel::Dx, Some(1))]).is_ok());
}

#[test]
fn a_reading_takes_the_latest_fixture_row_of_its_line_else_the_first_else_the_manifest() {
    let row = |line, t, z| FixtureRow {
        time_ns: t,
        line,
        reflector_mm: [0.0, 0.0, z],
    };
    let fixture = [row(1, 10, 1.0), row(1, 20, 2.0), row(2, 5, 9.0)];
    let default = [7.0, 7.0, 7.0];
    assert_eq!(reflector_at(&fixture, 1, 15, default)[2], 1.0);
    assert_eq!(reflector_at(&fixture, 1, 20, default)[2], 2.0);
    assert_eq!(reflector_at(&fixture, 1, 99, default)[2], 2.0);
    assert_eq!(reflector_at(&fixture, 1, 0, default)[2], 1.0);
    assert_eq!(reflector_at(&fixture, 2, 0, default)[2], 9.0);
    assert_eq!(reflector_at(&fixture, 3, 50, default), default);
    let env = |t, air_c| EnvironmentRow {
        time_ns: t,
        air_c,
        pressure_hpa: 1000.0,
        humidity_pct: 50.0,
        material_c: None,
        env_factor_ppm: None,
    };
    let rows = [env(10, 20.0), env(20, 21.0)];
    assert_eq!(environment_at(&rows, 5).unwrap().air_c, 20.0);
    assert_eq!(environment_at(&rows, 19).unwrap().air_c, 20.0);
    assert_eq!(environment_at(&rows, 20).unwrap().air_c, 21.0);
    assert!(environment_at(&[], 20).is_none());
}

#[test]
fn channels_round_trip() {
    for c in Channel::ALL {
        assert_eq!(Channel::parse(c.as_str()), Some(c));
        assert_eq!(Channel::of_axis(MachineAxis::from_index(c.index())), c);
    }
    assert_eq!(Channel::parse("DX"), None);
}
