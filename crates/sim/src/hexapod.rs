//! A hexapod measuring device on a machine under test, with known truth
//! (`docs/spec/device-format.md`, `docs/spec/machine-physics.md`, "Hexapod").
//!
//! Six working bars sit in the six legs of the device; the machine moves one linear axis through
//! `stations` stops `step_mm` apart from `reference_mm` and back, `runs` times, dwelling
//! `dwell_s` at each stop (`positions` log: a row at each dwell start, one mid-dwell, a null row
//! at each move start). The moved axis carries six true errors, smooth functions of the position
//! whose shape follows the seed, zero at the datum; they act on the commanded pose by the spec's
//! forward model (R = exp(\[ε\]×) R_cmd, t = t_cmd + R_cmd r + δ − R r), and the legs take the
//! lengths of that pose between the *true* joint centres (the manifest's plus offsets drawn with
//! `u_base_um`, `u_platform_um`). During a move the leg lengths go linearly from stop to stop.
//!
//! The kinematics here are the simulator's own (written from the spec, sharing no code with
//! `dbbcal-machine`), so that a bug in either shows as a recovery failure.

use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use super::{stream_rng, SimError};

/// `[schedule.working.device.hexapod]`: the device and the test the machine runs.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HexapodSim {
    /// Base joint centres in B, mm, leg 1 first (the manifest's, nominal).
    pub(crate) base_mm: Vec<[f64; 3]>,
    /// Platform joint centres in P, mm, leg 1 first.
    pub(crate) platform_mm: Vec<[f64; 3]>,
    /// u (k = 1) of each joint coordinate, µm: declared, and the spread of the true offsets.
    pub(crate) u_base_um: f64,
    /// The same for the platform joints, µm.
    pub(crate) u_platform_um: f64,
    /// Pose of P in B at the datum (mm, degrees).
    pub(crate) nominal_pose: [f64; 6],
    /// Tool point in P, mm.
    #[serde(default)]
    pub(crate) tool_point_mm: [f64; 3],
    /// Commanded machine position of the datum, mm (the first station).
    pub(crate) reference_mm: [f64; 3],
    /// The axis moved: "X", "Y" or "Z".
    pub(crate) axis: String,
    /// Number of stops (the first at `reference_mm`).
    pub(crate) stations: usize,
    /// Distance between stops, mm (negative: towards −).
    pub(crate) step_mm: f64,
    /// Bidirectional runs (each up then down).
    pub(crate) runs: usize,
    /// Dwell at each stop, s.
    pub(crate) dwell_s: f64,
    /// Move between stops, s.
    pub(crate) move_s: f64,
    /// The test starts this long after the last leg's mount began, h.
    pub(crate) settle_hours: f64,
    /// Scale of the true positioning error at the end of the travel, µm.
    pub(crate) positioning_um: f64,
    /// Scale of the true straightness errors, µm.
    pub(crate) straightness_um: f64,
    /// Scale of the true angular errors, µrad.
    pub(crate) angular_urad: f64,
    /// Multiplies the drawn joint-centre offsets (1: drawn with the declared u; 0: none).
    #[serde(default = "one")]
    pub(crate) joint_error_scale: f64,
    /// Effects the analysis' model may miss (`machine-physics.md`, "Hexapod"); all off by
    /// default.
    #[serde(default)]
    pub(crate) effects: HexapodEffects,
}

/// `[schedule.working.device.hexapod.effects]`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct HexapodEffects {
    /// Machine thermal drift during the test: the tool point moves by this much per hour in
    /// x, y, z (µm/h), from the datum dwell's start.
    #[serde(default)]
    pub(crate) drift_um_per_h: [f64; 3],
    /// The drift's time constant (h): a machine warming up, the tool point moving by
    /// `drift_um_per_h · τ (1 − e^(−t/τ))` (its initial rate `drift_um_per_h`); absent: a
    /// constant rate.
    #[serde(default)]
    pub(crate) drift_tau_h: Option<f64>,
    /// True expansion of the base and platform bodies (ppm/K) about their frames' origins, at
    /// the mean air temperature; the manifest declares `declared_cte_ppm_per_k`.
    #[serde(default)]
    pub(crate) body_cte_ppm_per_k: f64,
    /// The expansion the manifest declares (`[[device]] cte_ppm_per_k`); absent: none declared.
    #[serde(default)]
    pub(crate) declared_cte_ppm_per_k: Option<f64>,
    /// A leg's socket re-seated during the test: its length steps.
    #[serde(default)]
    pub(crate) reseat: Option<Reseat>,
}

/// A re-seated socket: leg `leg` (1-6) is `step_um` longer from dwell `from_dwell` on (dwells
/// counted from 0 in the test's order, the datum first).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Reseat {
    pub(crate) leg: usize,
    pub(crate) from_dwell: usize,
    pub(crate) step_um: f64,
}

fn one() -> f64 {
    1.0
}

/// Random stream of the device (errors' shape, joint offsets).
const STREAM: u64 = 7_000;

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

fn mat_vec(m: &M3, v: &V3) -> V3 {
    std::array::from_fn(|i| (0..3).map(|k| m[i][k] * v[k]).sum())
}

fn mat_mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn add(a: &V3, b: &V3) -> V3 {
    std::array::from_fn(|k| a[k] + b[k])
}

fn sub(a: &V3, b: &V3) -> V3 {
    std::array::from_fn(|k| a[k] - b[k])
}

fn norm(a: &V3) -> f64 {
    a.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// R = Rz(rz) Ry(ry) Rx(rx), angles in degrees (device-format.md, "Pose").
fn rotation_deg(rx: f64, ry: f64, rz: f64) -> M3 {
    let (a, b, c) = (rx.to_radians(), ry.to_radians(), rz.to_radians());
    let rx_m = [
        [1.0, 0.0, 0.0],
        [0.0, a.cos(), -a.sin()],
        [0.0, a.sin(), a.cos()],
    ];
    let ry_m = [
        [b.cos(), 0.0, b.sin()],
        [0.0, 1.0, 0.0],
        [-b.sin(), 0.0, b.cos()],
    ];
    let rz_m = [
        [c.cos(), -c.sin(), 0.0],
        [c.sin(), c.cos(), 0.0],
        [0.0, 0.0, 1.0],
    ];
    mat_mul(&rz_m, &mat_mul(&ry_m, &rx_m))
}

/// exp([w]×) by Rodrigues' formula, w in rad.
fn rotation_of_vector(w: &V3) -> M3 {
    let theta = norm(w);
    let k: M3 = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let k2 = mat_mul(&k, &k);
    let (s, c) = if theta < 1e-12 {
        (1.0, 0.5)
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / (theta * theta))
    };
    std::array::from_fn(|i| {
        std::array::from_fn(|j| (if i == j { 1.0 } else { 0.0 }) + s * k[i][j] + c * k2[i][j])
    })
}

/// A leg's true length and tilt over time: knots (ns after the campaign start), linear between
/// them, held beyond the ends.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct LegTrack {
    pub(crate) times_ns: Vec<i64>,
    pub(crate) lengths_mm: Vec<f64>,
    pub(crate) tilts_deg: Vec<f64>,
}

impl LegTrack {
    /// (length mm, tilt degrees) at `t_ns`.
    pub(crate) fn at(&self, t_ns: i64) -> (f64, f64) {
        let t = &self.times_ns;
        let k = t.partition_point(|&x| x <= t_ns);
        if k == 0 {
            return (self.lengths_mm[0], self.tilts_deg[0]);
        }
        if k == t.len() {
            return (self.lengths_mm[k - 1], self.tilts_deg[k - 1]);
        }
        let w = (t_ns - t[k - 1]) as f64 / (t[k] - t[k - 1]) as f64;
        let lerp = |v: &[f64]| v[k - 1] + w * (v[k] - v[k - 1]);
        (lerp(&self.lengths_mm), lerp(&self.tilts_deg))
    }
}

/// The true errors at one station.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct StationTruth {
    /// Station number (1 = the datum).
    pub station: i64,
    /// Commanded machine position, mm.
    pub position_mm: [f64; 3],
    /// True errors in M's axes at the tool point: δx, δy, δz µm, εx, εy, εz µrad.
    pub errors: [f64; 6],
    /// Their ISO 230-1 names, in the same order.
    pub names: [String; 6],
    /// True leg lengths there, mm.
    pub leg_lengths_mm: [f64; 6],
    /// True leg tilts there, degrees.
    pub leg_tilts_deg: [f64; 6],
}

/// What was simulated of the device (in `truth.json`; the analysis never reads it).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct DeviceTruth {
    /// Device id.
    pub device: String,
    /// The axis moved.
    pub axis: String,
    /// True joint-centre offsets from the manifest's, µm: base then platform, leg 1 first.
    pub joint_offsets_um: Vec<[f64; 3]>,
    /// Every station once, in station order.
    pub stations: Vec<StationTruth>,
}

/// One row of the simulated `positions` log.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PositionRowSim {
    pub(crate) t_ns: i64,
    pub(crate) xyz_mm: V3,
    pub(crate) station: Option<i64>,
    pub(crate) run: i64,
}

/// The device as simulated: leg tracks (per leg), the positions log, the truth.
#[derive(Debug, Clone)]
pub(crate) struct HexapodRun {
    pub(crate) legs: Vec<LegTrack>,
    pub(crate) positions: Vec<PositionRowSim>,
    pub(crate) truth: DeviceTruth,
}

impl HexapodSim {
    /// Checks of the section; `key` is its TOML path.
    pub(crate) fn validate(&self, key: &str) -> Result<(), SimError> {
        let bad = |k: &str, reason: &str| {
            Err(SimError::Invalid {
                key: format!("{key}.{k}"),
                reason: reason.into(),
            })
        };
        if self.base_mm.len() != 6 || self.platform_mm.len() != 6 {
            return bad("base_mm", "a hexapod has six base and six platform joints");
        }
        if !["X", "Y", "Z"].contains(&self.axis.as_str()) {
            return bad("axis", "must be \"X\", \"Y\" or \"Z\"");
        }
        if !(2..=100).contains(&self.stations) || !(1..=20).contains(&self.runs) {
            return bad("stations", "2..=100 stations and 1..=20 runs");
        }
        let finite = [
            self.step_mm,
            self.dwell_s,
            self.move_s,
            self.settle_hours,
            self.positioning_um,
            self.straightness_um,
            self.angular_urad,
            self.u_base_um,
            self.u_platform_um,
            self.joint_error_scale,
        ];
        if finite.iter().any(|v| !v.is_finite()) || self.step_mm == 0.0 {
            return bad("step_mm", "every number must be finite, step_mm non-zero");
        }
        if self.dwell_s < 10.0 || self.move_s < 1.0 || self.settle_hours < 0.0 {
            return bad("dwell_s", "dwell_s ≥ 10, move_s ≥ 1, settle_hours ≥ 0");
        }
        let e = &self.effects;
        let effect_numbers = [
            e.drift_um_per_h[0],
            e.drift_um_per_h[1],
            e.drift_um_per_h[2],
            e.body_cte_ppm_per_k,
            e.declared_cte_ppm_per_k.unwrap_or(0.0),
            e.drift_tau_h.unwrap_or(1.0),
        ];
        if effect_numbers
            .iter()
            .any(|v| !v.is_finite() || v.abs() > 1e3)
        {
            return bad(
                "effects",
                "drift and expansion must be finite and below 1000",
            );
        }
        if e.drift_tau_h.is_some_and(|t| t <= 0.0) {
            return bad("effects.drift_tau_h", "must be above 0 h");
        }
        if let Some(r) = &e.reseat {
            let dwells = 2 * self.stations * self.runs;
            if !(1..=6).contains(&r.leg) || !(1..dwells).contains(&r.from_dwell) {
                return bad(
                    "effects.reseat",
                    "leg is 1-6 and from_dwell a dwell after the datum, before the test ends",
                );
            }
            if !r.step_um.is_finite() || r.step_um.abs() > 1e3 {
                return bad("effects.reseat.step_um", "must be finite and below 1000 µm");
            }
        }
        Ok(())
    }

    fn axis_index(&self) -> usize {
        match self.axis.as_str() {
            "X" => 0,
            "Y" => 1,
            _ => 2,
        }
    }

    /// ISO 230-1 names of the six errors of the moved axis.
    fn names(&self) -> [String; 6] {
        let a = &self.axis;
        ["X", "Y", "Z", "A", "B", "C"].map(|c| format!("E{c}{a}"))
    }

    /// The duration of the test, ns.
    pub(crate) fn duration_ns(&self) -> i64 {
        let visits = (2 * self.stations * self.runs) as f64;
        ((visits * (self.dwell_s + self.move_s) + self.settle_hours * 3600.0) * 1e9) as i64
    }

    /// Simulate the device: the legs' true lengths over time from `mount_start_ns` (the last
    /// leg's mount start), the positions log and the truth. `body_excess_k(t_ns)` is the bodies'
    /// temperature above T0 at a time (used by `effects.body_cte_ppm_per_k`).
    pub(crate) fn run(
        &self,
        device: &str,
        seed: u64,
        mount_start_ns: i64,
        body_excess_k: &dyn Fn(i64) -> f64,
    ) -> HexapodRun {
        let mut rng = stream_rng(seed, STREAM);
        let unit = Normal::new(0.0, 1.0).expect("unit normal");
        // True joints: manifest + offsets.
        let mut draw = |u: f64| -> V3 {
            std::array::from_fn(|_| unit.sample(&mut rng) * u * self.joint_error_scale)
        };
        let base_off: Vec<V3> = (0..6).map(|_| draw(self.u_base_um)).collect();
        let platform_off: Vec<V3> = (0..6).map(|_| draw(self.u_platform_um)).collect();
        let base: Vec<V3> = (0..6)
            .map(|i| add(&self.base_mm[i], &base_off[i].map(|v| v * 1e-3)))
            .collect();
        let platform: Vec<V3> = (0..6)
            .map(|i| add(&self.platform_mm[i], &platform_off[i].map(|v| v * 1e-3)))
            .collect();
        // The errors' shape: per component a line, a parabola and a wave, zero at the datum.
        let shape: Vec<[f64; 4]> = (0..6)
            .map(|_| {
                [
                    unit.sample(&mut rng),
                    unit.sample(&mut rng),
                    0.5 * unit.sample(&mut rng),
                    std::f64::consts::PI * unit.sample(&mut rng),
                ]
            })
            .collect();
        let k_axis = self.axis_index();
        let travel = self.step_mm.abs() * (self.stations - 1) as f64;
        let scale = |k: usize| {
            if k == k_axis {
                self.positioning_um
            } else if k < 3 {
                self.straightness_um
            } else {
                self.angular_urad
            }
        };
        let errors_at = |q: f64| -> [f64; 6] {
            let s = (q - self.reference_mm[k_axis]).abs() / travel;
            std::array::from_fn(|k| {
                let [a, b, c, phi] = shape[k];
                let wave = c * ((2.5 * std::f64::consts::PI * s + phi).sin() - phi.sin());
                scale(k) * (0.6 * a * s + 0.4 * b * s * s + wave) / 1.5
            })
        };
        let [x0, y0, z0, rx, ry, rz] = self.nominal_pose;
        let r_cmd = rotation_deg(rx, ry, rz);
        let t0 = [x0, y0, z0];
        let r = self.tool_point_mm;
        // `at`: the time effects at a dwell (hours since the datum, body strain, dwell index).
        let legs_with = |c: &V3, at: Option<(f64, f64, usize)>| -> ([f64; 6], [f64; 6], [f64; 6]) {
            let mut e = errors_at(c[k_axis]);
            let (hours, strain, dwell) = at.unwrap_or((0.0, 0.0, 0));
            let drift_hours = match self.effects.drift_tau_h {
                Some(tau) => tau * (1.0 - (-hours / tau).exp()),
                None => hours,
            };
            for (k, g) in self.effects.drift_um_per_h.iter().enumerate() {
                e[k] += g * drift_hours;
            }
            let t_cmd = add(&t0, &sub(c, &self.reference_mm));
            let eps = [e[3] * 1e-6, e[4] * 1e-6, e[5] * 1e-6];
            let rot = mat_mul(&rotation_of_vector(&eps), &r_cmd);
            let delta = [e[0] * 1e-3, e[1] * 1e-3, e[2] * 1e-3];
            let t = sub(
                &add(&add(&t_cmd, &mat_vec(&r_cmd, &r)), &delta),
                &mat_vec(&rot, &r),
            );
            let mut l = [0.0; 6];
            let mut a = [0.0; 6];
            let grown = |v: &V3| v.map(|x| x * (1.0 + strain));
            for i in 0..6 {
                let p = grown(&platform[i]);
                let v = sub(&add(&t, &mat_vec(&rot, &p)), &grown(&base[i]));
                l[i] = norm(&v);
                a[i] = (v[2].abs() / l[i]).asin().to_degrees();
            }
            if let Some(r) = self
                .effects
                .reseat
                .as_ref()
                .filter(|r| dwell >= r.from_dwell)
            {
                l[r.leg - 1] += r.step_um * 1e-3;
            }
            (l, a, e)
        };
        let legs_at = |c: &V3| legs_with(c, None);
        let position = |station: usize| -> V3 {
            let mut c = self.reference_mm;
            c[k_axis] += self.step_mm * station as f64;
            c
        };
        let names = self.names();
        let stations: Vec<StationTruth> = (0..self.stations)
            .map(|s| {
                let c = position(s);
                let (l, a, e) = legs_at(&c);
                StationTruth {
                    station: s as i64 + 1,
                    position_mm: c,
                    errors: e,
                    names: names.clone(),
                    leg_lengths_mm: l,
                    leg_tilts_deg: a,
                }
            })
            .collect();
        let mut legs = vec![LegTrack::default(); 6];
        let dwell_ns = (self.dwell_s * 1e9) as i64;
        let move_ns = (self.move_s * 1e9) as i64;
        let mut t = mount_start_ns + (self.settle_hours * 3600.0 * 1e9) as i64;
        let datum_ns = t;
        let mut knot = |t_ns: i64, s: usize, dwell: usize| {
            let hours = (t_ns - datum_ns).max(0) as f64 / 3600e9;
            let strain = 1e-6 * self.effects.body_cte_ppm_per_k * body_excess_k(t_ns);
            let (l, a, _) = legs_with(&position(s), Some((hours, strain, dwell)));
            for (i, leg) in legs.iter_mut().enumerate() {
                leg.times_ns.push(t_ns);
                leg.lengths_mm.push(l[i]);
                leg.tilts_deg.push(a[i]);
            }
        };
        knot(0, 0, 0);
        let mut dwell = 0;
        let mut positions = Vec::new();
        for run in 1..=self.runs as i64 {
            let up = 0..self.stations;
            let down = (0..self.stations).rev();
            for s in up.chain(down) {
                let c = position(s);
                let row = |t_ns, station| PositionRowSim {
                    t_ns,
                    xyz_mm: c,
                    station,
                    run,
                };
                knot(t, s, dwell);
                positions.push(row(t, Some(s as i64 + 1)));
                positions.push(row(t + dwell_ns / 2, Some(s as i64 + 1)));
                t += dwell_ns;
                knot(t, s, dwell);
                dwell += 1;
                positions.push(row(t, None));
                t += move_ns;
            }
        }
        HexapodRun {
            legs,
            positions,
            truth: DeviceTruth {
                device: device.to_string(),
                axis: self.axis.clone(),
                joint_offsets_um: base_off.into_iter().chain(platform_off).collect(),
                stations,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> HexapodSim {
        HexapodSim {
            base_mm: vec![
                [196.962, -34.730, 0.0],
                [196.962, 34.730, 0.0],
                [-68.404, 187.939, 0.0],
                [-128.558, 153.209, 0.0],
                [-128.558, -153.209, 0.0],
                [-68.404, -187.939, 0.0],
            ],
            platform_mm: vec![
                [64.279, -76.604, 0.0],
                [64.279, 76.604, 0.0],
                [34.202, 93.969, 0.0],
                [-98.481, 17.365, 0.0],
                [-98.481, -17.365, 0.0],
                [34.202, -93.969, 0.0],
            ],
            u_base_um: 2.0,
            u_platform_um: 2.0,
            nominal_pose: [0.0, 0.0, 260.0, 0.0, 0.0, 0.0],
            tool_point_mm: [0.0; 3],
            reference_mm: [400.0, 300.0, -200.0],
            axis: "X".into(),
            stations: 11,
            step_mm: 5.0,
            runs: 2,
            dwell_s: 300.0,
            move_s: 60.0,
            settle_hours: 1.0,
            positioning_um: 3.0,
            straightness_um: 2.0,
            angular_urad: 15.0,
            joint_error_scale: 0.0,
            effects: HexapodEffects::default(),
        }
    }

    #[test]
    fn the_specs_example_device_has_legs_of_294_887_mm_at_61_85_degrees() {
        let run = example().run("hexapod-1", 1, 0, &|_| 0.0);
        let s = &run.truth.stations[0];
        for i in 0..6 {
            assert!((s.leg_lengths_mm[i] - 294.887).abs() < 1e-3, "{s:?}");
            assert!((s.leg_tilts_deg[i] - 61.85).abs() < 0.01, "{s:?}");
        }
        // Zero at the datum, of the configured size at the far end.
        assert!(s.errors.iter().all(|e| e.abs() < 1e-12));
        assert_eq!(s.names[1], "EYX");
        let far = &run.truth.stations[10].errors;
        assert!(far.iter().any(|e| e.abs() > 0.1), "{far:?}");
        // 2 runs × 2 directions × 11 stops, three rows each.
        assert_eq!(run.positions.len(), 2 * 2 * 11 * 3);
        // Leg tracks: the datum lengths before the test, a stop's lengths mid-dwell.
        let (l, _) = run.legs[0].at(10);
        assert!((l - 294.887).abs() < 1e-3);
        let mid = run.positions[3 * 5 + 1].t_ns;
        assert_eq!(
            run.legs[2].at(mid).0,
            run.truth.stations[5].leg_lengths_mm[2]
        );
    }

    #[test]
    fn rotations_follow_the_specs_convention() {
        // Rz(90°) takes x to y; exp of a small rotation vector is I + [w]× to first order.
        let r = rotation_deg(0.0, 0.0, 90.0);
        let v = mat_vec(&r, &[1.0, 0.0, 0.0]);
        assert!((v[1] - 1.0).abs() < 1e-12 && v[0].abs() < 1e-12);
        let e = rotation_of_vector(&[0.0, 0.0, 1e-6]);
        assert!((e[1][0] - 1e-6).abs() < 1e-15 && (e[0][1] + 1e-6).abs() < 1e-15);
    }
}
