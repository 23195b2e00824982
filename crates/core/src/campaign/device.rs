//! `[[device]]` tables of `campaign.toml` and the legs of their mounts
//! (`docs/spec/device-format.md`, "campaign.toml: `[[device]]`").
//!
//! [`DeviceDecl`] is the table as declared; [`Device`] is its validated form (six joints per ring,
//! uncertainties per leg, defaults filled in). A mount on a declared hexapod names its `leg`
//! (1–6): required there, not allowed with `length` or on an undeclared device; at any time a leg
//! carries at most one bar (a bar sits in at most one place at a time already, as its mounts may
//! not overlap). Every message is one line naming the key, as the rest of the manifest's.

use super::{display_number, limits, CampaignError, Manifest, Mount, Validator};

/// The kind of a device (`device[].kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DeviceKind {
    /// A six-link parallel mechanism: six legs numbered 1–6.
    Hexapod,
}

/// Number of legs of a hexapod.
pub(crate) const HEXAPOD_LEGS: usize = 6;

/// A value for every leg: one for all, or one per leg (`u_base_um`, `u_platform_um`).
#[derive(Debug, Clone, PartialEq)]
pub enum PerLeg {
    /// The same value for every leg.
    All(f64),
    /// One value per leg, leg 1 first.
    Each(Vec<f64>),
}

/// `[[device]]` as declared (`docs/spec/device-format.md`), not yet validated.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceDecl {
    /// Device id, as in mounts and `positions`.
    pub id: String,
    /// `"hexapod"`.
    pub kind: DeviceKind,
    /// Base joint centres in frame B, mm, leg 1 first.
    pub base_mm: Vec<[f64; 3]>,
    /// Platform joint centres in frame P, mm, leg 1 first.
    pub platform_mm: Vec<[f64; 3]>,
    /// Standard uncertainty (k = 1) of each coordinate of a base joint centre, µm.
    pub u_base_um: PerLeg,
    /// The same for the platform joint centres, µm.
    pub u_platform_um: PerLeg,
    /// Pose of P in B at the datum: [x, y, z] mm, [rx, ry, rz] degrees.
    pub nominal_pose: [f64; 6],
    /// The point of P whose translational errors are reported, mm; default P's origin.
    pub tool_point_mm: Option<[f64; 3]>,
    /// Orientation of B in M, degrees; default [0, 0, 0].
    pub base_orientation_deg: Option<[f64; 3]>,
    /// The upward vertical in B; default [0, 0, 1].
    pub up: Option<[f64; 3]>,
    /// The commanded machine position whose first dwell is the datum, mm; default the first
    /// dwell in `positions`.
    pub reference_mm: Option<[f64; 3]>,
    /// Expansion of the base and platform bodies, ppm/K; default 0.
    pub cte_ppm_per_k: Option<f64>,
    /// Temperature sensor of those bodies; default the mean of the air sensors.
    pub sensor: Option<String>,
}

/// A validated device: six joints per ring, defaults filled in.
#[derive(Debug, Clone, PartialEq)]
pub struct Device {
    /// Device id.
    pub id: String,
    /// Its kind.
    pub kind: DeviceKind,
    /// Base joint centres in B at T0, mm, leg 1 first.
    pub base_mm: [[f64; 3]; HEXAPOD_LEGS],
    /// Platform joint centres in P at T0, mm, leg 1 first.
    pub platform_mm: [[f64; 3]; HEXAPOD_LEGS],
    /// u (k = 1) of each coordinate of each base joint, µm.
    pub u_base_um: [f64; HEXAPOD_LEGS],
    /// u (k = 1) of each coordinate of each platform joint, µm.
    pub u_platform_um: [f64; HEXAPOD_LEGS],
    /// Pose of P in B near the datum: mm and degrees.
    pub nominal_pose: [f64; 6],
    /// Tool point in P, mm.
    pub tool_point_mm: [f64; 3],
    /// Orientation of B in M, degrees.
    pub base_orientation_deg: [f64; 3],
    /// Upward vertical in B.
    pub up: [f64; 3],
    /// Commanded position of the datum, mm (`None`: the first dwell).
    pub reference_mm: Option<[f64; 3]>,
    /// Ring expansion, ppm/K.
    pub cte_ppm_per_k: f64,
    /// Sensor of the rings (`None`: mean of the air sensors).
    pub sensor: Option<String>,
}

/// Largest |coordinate| of a joint, tool point or pose translation, mm (10 m).
const COORDINATE_MM: f64 = 10_000.0;
/// An angle of the pose or of the base's orientation.
const ANGLE_DEG: crate::limits::Limit = crate::limits::Limit::closed(-180.0, 180.0, "degrees");

impl Validator<'_> {
    /// Validates every `[[device]]`.
    pub(super) fn devices(&self, m: &Manifest) -> Result<Vec<Device>, CampaignError> {
        self.unique_ids("device", m.device.iter().map(|d| d.id.as_str()))?;
        m.device
            .iter()
            .enumerate()
            .map(|(i, d)| self.device(i, d, m))
            .collect()
    }

    fn device(&self, i: usize, d: &DeviceDecl, m: &Manifest) -> Result<Device, CampaignError> {
        let key = format!("device[{i}] ({:?})", d.id);
        let joints = |name: &str, v: &[[f64; 3]]| -> Result<[[f64; 3]; 6], CampaignError> {
            let ring: [[f64; 3]; 6] = v.try_into().map_err(|_| {
                self.invalid(
                    key.clone(),
                    format!(
                        "{name} has {} joint centres; a hexapod has {HEXAPOD_LEGS} (leg 1 first)",
                        v.len()
                    ),
                )
            })?;
            for (leg, p) in ring.iter().enumerate() {
                self.coordinates(&key, &format!("{name}[{leg}]"), p)?;
            }
            for a in 0..6 {
                for b in 0..a {
                    let dist = (0..3)
                        .map(|k| (ring[a][k] - ring[b][k]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    if dist < 1e-6 {
                        return Err(self.invalid(
                            key.clone(),
                            format!(
                                "{name}: the joints of legs {} and {} coincide",
                                b + 1,
                                a + 1
                            ),
                        ));
                    }
                }
            }
            Ok(ring)
        };
        let base_mm = joints("base_mm", &d.base_mm)?;
        let platform_mm = joints("platform_mm", &d.platform_mm)?;
        let u_base_um = self.per_leg(&key, "u_base_um", &d.u_base_um)?;
        let u_platform_um = self.per_leg(&key, "u_platform_um", &d.u_platform_um)?;
        let [x, y, z, rx, ry, rz] = d.nominal_pose;
        self.coordinates(&key, "nominal_pose (x, y, z)", &[x, y, z])?;
        for (name, a) in [("rx", rx), ("ry", ry), ("rz", rz)] {
            self.in_range(&key, &format!("nominal_pose {name}"), a, ANGLE_DEG)?;
        }
        let tool_point_mm = d.tool_point_mm.unwrap_or([0.0; 3]);
        self.coordinates(&key, "tool_point_mm", &tool_point_mm)?;
        let base_orientation_deg = d.base_orientation_deg.unwrap_or([0.0; 3]);
        for (k, a) in base_orientation_deg.iter().enumerate() {
            self.in_range(&key, &format!("base_orientation_deg[{k}]"), *a, ANGLE_DEG)?;
        }
        let up = d.up.unwrap_or([0.0, 0.0, 1.0]);
        if up.iter().any(|v| !v.is_finite()) || up.iter().all(|v| *v == 0.0) {
            return Err(self.invalid(
                key,
                format!("up = {up:?} must be a finite, non-zero vector"),
            ));
        }
        if let Some(r) = &d.reference_mm {
            self.coordinates(&key, "reference_mm", r)?;
        }
        let cte_ppm_per_k = d.cte_ppm_per_k.unwrap_or(0.0);
        self.in_range(&key, "cte_ppm_per_k", cte_ppm_per_k, limits::CTE_PPM_PER_K)?;
        if let Some(s) = &d.sensor {
            let known: Vec<&str> = m.sensor.iter().map(|s| s.id.as_str()).collect();
            if !known.contains(&s.as_str()) {
                return Err(self.unknown(key, "sensor", s, "a declared sensor", &known));
            }
        }
        Ok(Device {
            id: d.id.clone(),
            kind: d.kind,
            base_mm,
            platform_mm,
            u_base_um,
            u_platform_um,
            nominal_pose: d.nominal_pose,
            tool_point_mm,
            base_orientation_deg,
            up,
            reference_mm: d.reference_mm,
            cte_ppm_per_k,
            sensor: d.sensor.clone(),
        })
    }

    fn coordinates(&self, key: &str, name: &str, p: &[f64]) -> Result<(), CampaignError> {
        for (k, v) in p.iter().enumerate() {
            if !(v.is_finite() && v.abs() <= COORDINATE_MM) {
                return Err(self.invalid(
                    key,
                    format!(
                        "{name}[{k}] = {} must be a finite number within ±{COORDINATE_MM} mm",
                        display_number(*v)
                    ),
                ));
            }
        }
        Ok(())
    }

    fn per_leg(&self, key: &str, name: &str, v: &PerLeg) -> Result<[f64; 6], CampaignError> {
        let values: [f64; 6] = match v {
            PerLeg::All(u) => [*u; 6],
            PerLeg::Each(each) => each.as_slice().try_into().map_err(|_| {
                self.invalid(
                    key,
                    format!(
                        "{name} has {} values; give one for all legs or {HEXAPOD_LEGS}",
                        each.len()
                    ),
                )
            })?,
        };
        for u in values {
            self.in_range(key, name, u, limits::U_UM)?;
        }
        Ok(values)
    }

    /// The leg of mount `i` on `device` (`None` off a device or on an undeclared one).
    pub(super) fn leg(
        &self,
        key: &str,
        leg: Option<u8>,
        device: Option<&str>,
        m: &Manifest,
    ) -> Result<Option<u8>, CampaignError> {
        let declared = device.and_then(|id| m.device.iter().find(|d| d.id == id));
        match (leg, declared) {
            (None, None) => Ok(None),
            (Some(_), None) if device.is_none() => Err(self.invalid(
                key,
                "gives leg with length: a leg is allowed only on a device",
            )),
            (Some(_), None) => Err(self.invalid(
                key,
                format!(
                    "gives leg, but device {:?} has no [[device]] table",
                    device.unwrap_or_default()
                ),
            )),
            (None, Some(d)) => Err(self.invalid(
                key,
                format!(
                    "is on {} {:?}: leg (1–{HEXAPOD_LEGS}) is required",
                    "hexapod", d.id
                ),
            )),
            (Some(l), Some(_)) if !(1..=HEXAPOD_LEGS as u8).contains(&l) => Err(self.invalid(
                key,
                format!("leg = {l} is out of range: a hexapod's legs are 1–{HEXAPOD_LEGS}"),
            )),
            (Some(l), Some(_)) => Ok(Some(l)),
        }
    }

    /// At any time a leg carries at most one bar. `mounts` are (manifest index, mount).
    pub(super) fn legs_hold_one_bar(
        &self,
        mounts: &[(usize, Mount)],
        m: &Manifest,
    ) -> Result<(), CampaignError> {
        let mut legs: Vec<(&str, u8, i64, i64, usize)> = mounts
            .iter()
            .filter_map(|(i, mount)| match (&mount.place, mount.leg) {
                (super::Place::Device(d), Some(l)) => {
                    Some((d.as_str(), l, mount.from_ns, mount.to_ns, *i))
                }
                _ => None,
            })
            .collect();
        legs.sort_by(|a, b| (a.0, a.1, a.2, a.4).cmp(&(b.0, b.1, b.2, b.4)));
        for pair in legs.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if a.0 == b.0 && a.1 == b.1 && b.2 < a.3 {
                return Err(self.invalid(
                    format!("mount[{}] (bar {:?})", b.4, m.mount[b.4].bar),
                    format!(
                        "leg {} of device {:?} already carries bar {:?} (mount[{}]) from {} to {}",
                        b.1, b.0, m.mount[a.4].bar, a.4, m.mount[a.4].from, m.mount[a.4].to
                    ),
                ));
            }
        }
        Ok(())
    }
}
