//! ISO 230-2 evaluation of a positioning test: deviations x_ij of run i at target j, approached
//! in the positive (↑) or negative (↓) direction.
//!
//! Bidirectional quantities exactly as in `docs/spec/machine-physics.md`, "ISO 230-2 quantities
//! (standard)"; x̄ and s (n − 1 in the denominator) per target and direction:
//!
//! ```text
//! B_j = x̄↑_j − x̄↓_j, B = max|B_j|;   x̄_j = (x̄↑_j + x̄↓_j)/2, M = max x̄_j − min x̄_j
//! R_j = max(2 s↑_j + 2 s↓_j + |B_j|, 4 s↑_j, 4 s↓_j), R = max R_j
//! E = max − min over all x̄↑_j, x̄↓_j
//! A = max(x̄↑_j + 2 s↑_j, x̄↓_j + 2 s↓_j) − min(x̄↑_j − 2 s↑_j, x̄↓_j − 2 s↓_j)
//! ```
//!
//! Unidirectional quantities per measured direction, from ISO 230-2 itself (the spec does not
//! print them; *standard*): A↑ = max(x̄↑_j + 2 s↑_j) − min(x̄↑_j − 2 s↑_j), R↑ = max 4 s↑_j,
//! E↑ = max x̄↑_j − min x̄↑_j, likewise ↓.
//!
//! When only one direction was measured, B, M and the bidirectional A, R, E are *undefined*:
//! they are returned as `None` and named in [`Iso230_2::undefined`], never filled in from the
//! one direction.

/// Errors of the ISO 230-2 evaluation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Iso230Error {
    /// No targets.
    #[error("no targets")]
    NoTargets,
    /// Neither direction has readings.
    #[error("no direction has readings")]
    NoDirection,
    /// A target lacks a direction that another target has.
    #[error(
        "target {target} ({position_mm} mm) has no {direction} runs, but other targets do: \
         every target must be approached in the same directions"
    )]
    MissingDirection {
        /// Target index, from 0.
        target: usize,
        /// Its commanded position, mm.
        position_mm: f64,
        /// `"↑"` or `"↓"`.
        direction: &'static str,
    },
    /// Fewer than two runs: no standard deviation.
    #[error("target {target} ({position_mm} mm): {runs} {direction} run(s), at least 2 are needed for s")]
    TooFewRuns {
        /// Target index, from 0.
        target: usize,
        /// Its commanded position, mm.
        position_mm: f64,
        /// `"↑"` or `"↓"`.
        direction: &'static str,
        /// Runs given.
        runs: usize,
    },
    /// A deviation is NaN or infinite.
    #[error("target {target}: non-finite deviation")]
    NonFinite {
        /// Target index, from 0.
        target: usize,
    },
}

/// The deviations of one target: one value per run and direction, µm.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetDeviations {
    /// Commanded position of the target, mm.
    pub position_mm: f64,
    /// Deviations of the runs approaching in the positive direction (↑), µm.
    pub up_um: Vec<f64>,
    /// Deviations of the runs approaching in the negative direction (↓), µm.
    pub down_um: Vec<f64>,
}

/// Mean and standard deviation of one direction at one target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionStats {
    /// Mean unidirectional positional deviation x̄, µm.
    pub mean_um: f64,
    /// Estimator of the unidirectional standard uncertainty s (n − 1), µm.
    pub s_um: f64,
    /// Number of runs.
    pub runs: usize,
}

/// Per-target results.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetStats {
    /// Commanded position, mm.
    pub position_mm: f64,
    /// ↑ statistics, `None` when ↑ was not measured.
    pub up: Option<DirectionStats>,
    /// ↓ statistics, `None` when ↓ was not measured.
    pub down: Option<DirectionStats>,
    /// Reversal value B_j = x̄↑_j − x̄↓_j, µm (bidirectional only).
    pub reversal_um: Option<f64>,
    /// Mean bidirectional positional deviation x̄_j, µm (bidirectional only).
    pub mean_um: Option<f64>,
    /// Bidirectional repeatability R_j, µm (bidirectional only).
    pub repeatability_um: Option<f64>,
}

/// Unidirectional quantities of one direction (ISO 230-2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unidirectional {
    /// Unidirectional accuracy A↑ (or A↓), µm.
    pub accuracy_um: f64,
    /// Unidirectional repeatability R↑ = max 4 s↑_j, µm.
    pub repeatability_um: f64,
    /// Unidirectional systematic positional deviation E↑ = max x̄↑_j − min x̄↑_j, µm.
    pub systematic_um: f64,
}

/// The evaluation of a positioning test.
#[derive(Debug, Clone, PartialEq)]
pub struct Iso230_2 {
    /// Per-target statistics, in the order given.
    pub targets: Vec<TargetStats>,
    /// Bidirectional accuracy A, µm.
    pub accuracy_a_um: Option<f64>,
    /// Reversal value B = max |B_j|, µm.
    pub reversal_b_um: Option<f64>,
    /// Bidirectional repeatability R = max R_j, µm.
    pub repeatability_r_um: Option<f64>,
    /// Bidirectional systematic positional deviation E, µm.
    pub systematic_e_um: Option<f64>,
    /// Range of the mean bidirectional positional deviation M, µm.
    pub mean_range_m_um: Option<f64>,
    /// Unidirectional quantities of ↑, when measured.
    pub up: Option<Unidirectional>,
    /// Unidirectional quantities of ↓, when measured.
    pub down: Option<Unidirectional>,
    /// Quantities that are undefined for this test, with the reason (e.g. `"B: only ↑
    /// measured"`).
    pub undefined: Vec<String>,
}

fn stats(values: &[f64]) -> DirectionStats {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let ss: f64 = values.iter().map(|v| (v - mean).powi(2)).sum();
    DirectionStats {
        mean_um: mean,
        s_um: (ss / (n - 1.0)).sqrt(),
        runs: values.len(),
    }
}

fn range(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let max = values.clone().fold(f64::NEG_INFINITY, f64::max);
    let min = values.fold(f64::INFINITY, f64::min);
    max - min
}

fn unidirectional(stats: &[DirectionStats]) -> Unidirectional {
    let hi = stats
        .iter()
        .map(|s| s.mean_um + 2.0 * s.s_um)
        .fold(f64::NEG_INFINITY, f64::max);
    let lo = stats
        .iter()
        .map(|s| s.mean_um - 2.0 * s.s_um)
        .fold(f64::INFINITY, f64::min);
    Unidirectional {
        accuracy_um: hi - lo,
        repeatability_um: stats.iter().map(|s| 4.0 * s.s_um).fold(0.0, f64::max),
        systematic_um: range(stats.iter().map(|s| s.mean_um)),
    }
}

/// Evaluate a positioning test per ISO 230-2 (see the module documentation).
pub fn evaluate(targets: &[TargetDeviations]) -> Result<Iso230_2, Iso230Error> {
    if targets.is_empty() {
        return Err(Iso230Error::NoTargets);
    }
    let has_up = targets.iter().any(|t| !t.up_um.is_empty());
    let has_down = targets.iter().any(|t| !t.down_um.is_empty());
    if !has_up && !has_down {
        return Err(Iso230Error::NoDirection);
    }
    for (j, t) in targets.iter().enumerate() {
        if !(t.position_mm.is_finite() && t.up_um.iter().chain(&t.down_um).all(|v| v.is_finite())) {
            return Err(Iso230Error::NonFinite { target: j });
        }
        for (measured, values, direction) in [(has_up, &t.up_um, "↑"), (has_down, &t.down_um, "↓")]
        {
            if !measured {
                continue;
            }
            if values.is_empty() {
                return Err(Iso230Error::MissingDirection {
                    target: j,
                    position_mm: t.position_mm,
                    direction,
                });
            }
            if values.len() < 2 {
                return Err(Iso230Error::TooFewRuns {
                    target: j,
                    position_mm: t.position_mm,
                    direction,
                    runs: values.len(),
                });
            }
        }
    }
    let per_target: Vec<TargetStats> = targets
        .iter()
        .map(|t| {
            let up = has_up.then(|| stats(&t.up_um));
            let down = has_down.then(|| stats(&t.down_um));
            let (reversal_um, mean_um, repeatability_um) = match (up, down) {
                (Some(u), Some(d)) => {
                    let b = u.mean_um - d.mean_um;
                    let r = (2.0 * u.s_um + 2.0 * d.s_um + b.abs())
                        .max(4.0 * u.s_um)
                        .max(4.0 * d.s_um);
                    (Some(b), Some(0.5 * (u.mean_um + d.mean_um)), Some(r))
                }
                _ => (None, None, None),
            };
            TargetStats {
                position_mm: t.position_mm,
                up,
                down,
                reversal_um,
                mean_um,
                repeatability_um,
            }
        })
        .collect();
    let ups: Vec<DirectionStats> = per_target.iter().filter_map(|t| t.up).collect();
    let downs: Vec<DirectionStats> = per_target.iter().filter_map(|t| t.down).collect();
    let up = has_up.then(|| unidirectional(&ups));
    let down = has_down.then(|| unidirectional(&downs));
    let mut result = Iso230_2 {
        targets: per_target,
        accuracy_a_um: None,
        reversal_b_um: None,
        repeatability_r_um: None,
        systematic_e_um: None,
        mean_range_m_um: None,
        up,
        down,
        undefined: Vec::new(),
    };
    if has_up && has_down {
        let t = &result.targets;
        result.reversal_b_um = Some(
            t.iter()
                .filter_map(|t| t.reversal_um)
                .fold(0.0, |a, b| a.max(b.abs())),
        );
        result.mean_range_m_um = Some(range(t.iter().filter_map(|t| t.mean_um)));
        result.repeatability_r_um = Some(
            t.iter()
                .filter_map(|t| t.repeatability_um)
                .fold(0.0, f64::max),
        );
        let both = ups.iter().chain(&downs);
        result.systematic_e_um = Some(range(both.clone().map(|s| s.mean_um)));
        let hi = both
            .clone()
            .map(|s| s.mean_um + 2.0 * s.s_um)
            .fold(f64::NEG_INFINITY, f64::max);
        let lo = both
            .map(|s| s.mean_um - 2.0 * s.s_um)
            .fold(f64::INFINITY, f64::min);
        result.accuracy_a_um = Some(hi - lo);
    } else {
        let (only, missing) = if has_up {
            ("↑", "↓")
        } else {
            ("↓", "↑")
        };
        for q in ["A", "B", "R", "E", "M", "B_j", "x̄_j", "R_j"] {
            result.undefined.push(format!(
                "{q}: bidirectional, only {only} measured (no {missing} runs)"
            ));
        }
        let missing_uni = if has_up {
            "A↓, R↓, E↓"
        } else {
            "A↑, R↑, E↑"
        };
        result
            .undefined
            .push(format!("{missing_uni}: no {missing} runs"));
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn example() -> Vec<TargetDeviations> {
        vec![
            TargetDeviations {
                position_mm: 0.0,
                up_um: vec![1.0, 2.0, 3.0],
                down_um: vec![-1.0, 0.0, 1.0],
            },
            TargetDeviations {
                position_mm: 100.0,
                up_um: vec![4.0, 5.0, 6.0],
                down_um: vec![2.0, 4.0, 6.0],
            },
        ]
    }

    #[test]
    fn a_hand_computed_bidirectional_test() {
        // Target 1: x̄↑ 2, s↑ 1, x̄↓ 0, s↓ 1; target 2: x̄↑ 5, s↑ 1, x̄↓ 4, s↓ 2.
        let r = evaluate(&example()).unwrap();
        let t = &r.targets;
        assert_eq!(t[0].reversal_um, Some(2.0));
        assert_eq!(t[1].reversal_um, Some(1.0));
        assert_eq!(t[0].mean_um, Some(1.0));
        assert_eq!(t[1].mean_um, Some(4.5));
        assert_eq!(t[0].repeatability_um, Some(6.0)); // 2 + 2 + 2
        assert_eq!(t[1].repeatability_um, Some(8.0)); // max(2 + 4 + 1, 4, 8)
        assert_eq!(t[1].down.unwrap().s_um, 2.0);
        assert_eq!(r.reversal_b_um, Some(2.0));
        assert_eq!(r.mean_range_m_um, Some(3.5));
        assert_eq!(r.repeatability_r_um, Some(8.0));
        assert_eq!(r.systematic_e_um, Some(5.0)); // 5 − 0
        assert_eq!(r.accuracy_a_um, Some(10.0)); // (4 + 2·2) − (0 − 2·1)
        let up = r.up.unwrap();
        assert_eq!(
            (up.accuracy_um, up.repeatability_um, up.systematic_um),
            (7.0, 4.0, 3.0)
        );
        let down = r.down.unwrap();
        assert_eq!(
            (down.accuracy_um, down.repeatability_um, down.systematic_um),
            (10.0, 8.0, 4.0)
        );
        assert!(r.undefined.is_empty());
    }

    #[test]
    fn one_direction_names_what_is_undefined() {
        let only_up: Vec<TargetDeviations> = example()
            .into_iter()
            .map(|t| TargetDeviations {
                down_um: vec![],
                ..t
            })
            .collect();
        let r = evaluate(&only_up).unwrap();
        assert_eq!(r.accuracy_a_um, None);
        assert_eq!(r.reversal_b_um, None);
        assert_eq!(r.repeatability_r_um, None);
        assert_eq!(r.systematic_e_um, None);
        assert_eq!(r.mean_range_m_um, None);
        assert!(r.down.is_none());
        assert_eq!(r.up.unwrap().accuracy_um, 7.0);
        assert!(r.undefined.iter().any(|u| u.starts_with("B: ")));
        assert!(r.undefined.iter().any(|u| u.starts_with("M: ")));
        assert!(r.undefined.iter().any(|u| u.starts_with("A↓, R↓, E↓")));
        assert!(r.targets.iter().all(|t| t.reversal_um.is_none()));
    }

    #[test]
    fn bad_tests_are_typed_errors() {
        assert_eq!(evaluate(&[]), Err(Iso230Error::NoTargets));
        let mut t = example();
        t[1].down_um.clear();
        assert!(matches!(
            evaluate(&t),
            Err(Iso230Error::MissingDirection { target: 1, .. })
        ));
        let mut t = example();
        t[0].up_um.truncate(1);
        assert!(matches!(
            evaluate(&t),
            Err(Iso230Error::TooFewRuns {
                target: 0,
                runs: 1,
                ..
            })
        ));
        let mut t = example();
        t[0].up_um[0] = f64::NAN;
        assert_eq!(evaluate(&t), Err(Iso230Error::NonFinite { target: 0 }));
        let empty = vec![TargetDeviations {
            position_mm: 0.0,
            up_um: vec![],
            down_um: vec![],
        }];
        assert_eq!(evaluate(&empty), Err(Iso230Error::NoDirection));
    }

    #[test]
    fn a_constant_offset_changes_none_of_a_b_r_e_m() {
        let mut rng = ChaCha8Rng::seed_from_u64(2302);
        for _ in 0..200 {
            let targets: Vec<TargetDeviations> = (0..rng.gen_range(1..12))
                .map(|j| TargetDeviations {
                    position_mm: 50.0 * j as f64,
                    up_um: (0..rng.gen_range(2..7))
                        .map(|_| rng.gen_range(-20.0..20.0))
                        .collect(),
                    down_um: (0..rng.gen_range(2..7))
                        .map(|_| rng.gen_range(-20.0..20.0))
                        .collect(),
                })
                .collect();
            let c = rng.gen_range(-1000.0..1000.0);
            let shifted: Vec<TargetDeviations> = targets
                .iter()
                .map(|t| TargetDeviations {
                    position_mm: t.position_mm,
                    up_um: t.up_um.iter().map(|v| v + c).collect(),
                    down_um: t.down_um.iter().map(|v| v + c).collect(),
                })
                .collect();
            let a = evaluate(&targets).unwrap();
            let b = evaluate(&shifted).unwrap();
            let q = |r: &Iso230_2| {
                [
                    r.accuracy_a_um,
                    r.reversal_b_um,
                    r.repeatability_r_um,
                    r.systematic_e_um,
                    r.mean_range_m_um,
                ]
            };
            for (x, y) in q(&a).iter().zip(q(&b)) {
                assert!((x.unwrap() - y.unwrap()).abs() < 1e-9, "{x:?} {y:?} c={c}");
            }
        }
    }
}
