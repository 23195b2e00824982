use super::*;

#[test]
fn diagonal_names_round_trip() {
    for d in DiagonalSign::ALL {
        assert_eq!(DiagonalSign::parse(d.as_str()), Some(d));
        assert_eq!(logs::diagonal_of_index(d.index() as i64), Some(d));
    }
}

#[test]
fn diagonal_directions_are_derived_and_rows_ordered() {
    let r = |t: i64, x: f64| DiagonalReading {
        time_ns: t,
        diagonal: DiagonalSign::Mpp,
        run: 1,
        direction: 0,
        target_mm: x,
        deviation_um: 0.0,
    };
    let rows = vec![r(3, 0.0), r(1, 0.0), r(2, 100.0)];
    let out = order_diagonal_readings(&rows, &[None, None, None]).unwrap();
    assert_eq!(out.iter().map(|r| r.time_ns).collect::<Vec<_>>(), [1, 2, 3]);
    assert_eq!(
        out.iter().map(|r| r.direction).collect::<Vec<_>>(),
        [1, 1, -1]
    );
}
