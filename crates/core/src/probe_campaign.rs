//! The `probe` campaign kind (`docs/spec/machine-formats.md`, "Kind `probe`"; seed 003):
//! touch-trigger probe touches on a ring or a sphere. Types only, no IO.
//!
//! [`ProbeManifest`] is its `campaign.toml` as declared, one field a key (the TOML text is
//! `dbbcal_io::manifest`'s);
//! [`ProbeCampaign`] is its validated form, every error one line naming the file and the key.
//! [`ProbeTouch`] is one row of `touches/*.parquet` as plain data; [`derive_directions`] is the
//! reader rule every reader applies, in `seq` order: when a touch *changes direction* and its
//! number within the direction (touch 1 is the first touch after a change).

use crate::axis_campaign::{CampaignKind, KindSection, MachineSensorKind};
use crate::campaign::{check_campaign_id, limits, CampaignError};
use crate::limits::display_number;
use crate::limits::Limit;

/// The limits of a `probe` manifest's numbers.
pub mod probe_limits {
    use crate::limits::Limit;
    /// `probe.same_direction_deg`.
    pub(crate) const SAME_DIRECTION_DEG: Limit = Limit::above(0.0, 45.0, "degrees");
    /// `stylus[].tip_diameter_mm`.
    pub(crate) const TIP_DIAMETER_MM: Limit = Limit::above(0.0, 100.0, "mm");
    /// `stylus[].length_mm`.
    pub(crate) const STYLUS_LENGTH_MM: Limit = Limit::above(0.0, 1_000.0, "mm");
    /// `artefact[].diameter_mm`.
    pub(crate) const ARTEFACT_DIAMETER_MM: Limit = Limit::above(0.0, 2_000.0, "mm");
    /// `artefact[].form_um`.
    pub(crate) const FORM_UM: Limit = Limit::closed(0.0, 1_000.0, "µm");
    /// Each coordinate of `artefact[].centre_mm`.
    pub const CENTRE_MM: Limit = Limit::closed(-10_000.0, 10_000.0, "mm");
}

/// `campaign.toml` of a `probe` campaign as declared, not yet validated.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeManifest {
    /// `[campaign]`: kind, id, T0.
    pub campaign: KindSection,
    /// `[probe]`: model (informative) and the same-direction tolerance.
    pub probe: ProbeSection,
    /// `[[stylus]]`.
    pub stylus: Vec<StylusDecl>,
    /// `[[artefact]]`.
    pub artefact: Vec<ArtefactDecl>,
    /// `[[sensor]]`: sensors of `temperatures/*.parquet`, if given (not analysed by this
    /// version).
    pub sensor: Vec<ProbeSensorDecl>,
}

/// A temperature sensor of a `probe` campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeSensorDecl {
    /// Sensor id.
    pub id: String,
    /// What it measures.
    pub kind: MachineSensorKind,
}

/// `[probe]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeSection {
    /// The probe's model (informative, e.g. `TP2-5`).
    pub model: Option<String>,
    /// Approach vectors within this angle are the same direction, degrees (default 1).
    pub same_direction_deg: f64,
}

/// `[[stylus]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct StylusDecl {
    /// Stylus id (the `stylus` column).
    pub id: String,
    /// Nominal tip-ball diameter, mm.
    pub tip_diameter_mm: f64,
    /// Stylus length, mm (informative).
    pub length_mm: Option<f64>,
}

/// What the artefact is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ArtefactKind {
    /// A ring gauge, axis along Z, probed from inside.
    Ring,
    /// A sphere, probed from outside.
    Sphere,
}

impl ArtefactKind {
    /// `ring` or `sphere`.
    pub fn as_str(self) -> &'static str {
        match self {
            ArtefactKind::Ring => "ring",
            ArtefactKind::Sphere => "sphere",
        }
    }
}

/// `[[artefact]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ArtefactDecl {
    /// Artefact id (the `artefact` column).
    pub id: String,
    /// Ring or sphere.
    pub kind: ArtefactKind,
    /// Certified diameter, mm.
    pub diameter_mm: f64,
    /// Standard uncertainty (k = 1) of the diameter, µm.
    pub u_um: f64,
    /// Certified form deviation, µm.
    pub form_um: Option<f64>,
    /// Known centre, mm; absent: fitted.
    pub centre_mm: Option<[f64; 3]>,
}

/// A validated `probe` campaign manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeCampaign {
    /// Campaign id.
    pub id: String,
    /// Reference temperature, °C.
    pub reference_temperature_c: f64,
    /// The probe's model, if given.
    pub probe_model: Option<String>,
    /// Same-direction tolerance, degrees.
    pub same_direction_deg: f64,
    /// The styli.
    pub styli: Vec<StylusDecl>,
    /// The artefacts.
    pub artefacts: Vec<ArtefactDecl>,
}

impl ProbeCampaign {
    /// The stylus `id`, if declared.
    pub fn stylus(&self, id: &str) -> Option<&StylusDecl> {
        self.styli.iter().find(|s| s.id == id)
    }

    /// The artefact `id`, if declared.
    pub fn artefact(&self, id: &str) -> Option<&ArtefactDecl> {
        self.artefacts.iter().find(|a| a.id == id)
    }

    /// Validates a manifest, naming `file` in messages.
    pub fn from_manifest_at(m: ProbeManifest, file: &str) -> Result<ProbeCampaign, CampaignError> {
        let invalid = |key: &str, problem: String| CampaignError::Invalid {
            file: file.to_string(),
            key: key.to_string(),
            problem,
        };
        let check = |key: &str, value: f64, limit: Limit| {
            limit
                .check(key.rsplit('.').next().unwrap_or(key), value)
                .map_err(|e| invalid(key, e.to_string()))
        };
        if m.campaign.kind != CampaignKind::Probe {
            return Err(invalid(
                "campaign.kind",
                format!(
                    "is {:?}, this manifest is read as \"probe\"",
                    m.campaign.kind.as_str()
                ),
            ));
        }
        check_campaign_id(&m.campaign.id).map_err(|p| invalid("campaign.id", p.to_string()))?;
        check(
            "campaign.reference_temperature_c",
            m.campaign.reference_temperature_c,
            limits::REFERENCE_TEMPERATURE_C,
        )?;
        check(
            "probe.same_direction_deg",
            m.probe.same_direction_deg,
            probe_limits::SAME_DIRECTION_DEG,
        )?;
        if m.stylus.is_empty() {
            return Err(invalid("stylus", "declares no stylus".into()));
        }
        if m.artefact.is_empty() {
            return Err(invalid("artefact", "declares no artefact".into()));
        }
        unique_ids(file, "stylus", m.stylus.iter().map(|s| s.id.as_str()))?;
        unique_ids(file, "artefact", m.artefact.iter().map(|a| a.id.as_str()))?;
        for (i, s) in m.stylus.iter().enumerate() {
            let key = format!("stylus[{i}]");
            check(
                &format!("{key}.tip_diameter_mm"),
                s.tip_diameter_mm,
                probe_limits::TIP_DIAMETER_MM,
            )?;
            if let Some(l) = s.length_mm {
                check(
                    &format!("{key}.length_mm"),
                    l,
                    probe_limits::STYLUS_LENGTH_MM,
                )?;
            }
        }
        for (i, a) in m.artefact.iter().enumerate() {
            let key = format!("artefact[{i}]");
            check(
                &format!("{key}.diameter_mm"),
                a.diameter_mm,
                probe_limits::ARTEFACT_DIAMETER_MM,
            )?;
            check(&format!("{key}.u_um"), a.u_um, limits::U_UM)?;
            if let Some(f) = a.form_um {
                check(&format!("{key}.form_um"), f, probe_limits::FORM_UM)?;
            }
            if let Some(c) = a.centre_mm {
                for (axis, v) in ["x", "y", "z"].iter().zip(c) {
                    check(
                        &format!("{key}.centre_mm ({axis})"),
                        v,
                        probe_limits::CENTRE_MM,
                    )?;
                }
            }
        }
        Ok(ProbeCampaign {
            id: m.campaign.id,
            reference_temperature_c: m.campaign.reference_temperature_c,
            probe_model: m.probe.model,
            same_direction_deg: m.probe.same_direction_deg,
            styli: m.stylus,
            artefacts: m.artefact,
        })
    }
}

fn unique_ids<'a>(
    file: &str,
    table: &'static str,
    ids: impl Iterator<Item = &'a str>,
) -> Result<(), CampaignError> {
    let mut seen = std::collections::BTreeMap::new();
    for (i, id) in ids.enumerate() {
        if id.trim().is_empty() || id.chars().any(char::is_control) {
            return Err(CampaignError::Invalid {
                file: file.to_string(),
                key: format!("{table}[{i}].id"),
                problem: format!("{id:?} is empty or holds a control character"),
            });
        }
        if let Some(first) = seen.insert(id.to_string(), i) {
            return Err(CampaignError::DuplicateId {
                file: file.to_string(),
                table,
                id: id.to_string(),
                first,
                second: i,
            });
        }
    }
    Ok(())
}

// ---------------------------------------------------------------- the touches

/// One row of `touches/*.parquet`, as the reader hands it over (directions already derived).
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeTouch {
    /// When the probe triggered, ns since the epoch (UTC).
    pub time_ns: i64,
    /// Touch number, strictly increasing in the order of touching.
    pub seq: i64,
    /// Approach direction, unit vector in M.
    pub approach: [f64; 3],
    /// Latched position of the nominal stylus-tip centre, mm, in M.
    pub position_mm: [f64; 3],
    /// Approach feed, mm/min.
    pub feed_mm_min: Option<f64>,
    /// Stylus id.
    pub stylus: String,
    /// Artefact id.
    pub artefact: String,
    /// Probe orientation about the spindle, degrees.
    pub spindle_deg: Option<f64>,
    /// Derived: the touch's number within its direction (1: first touch after a change).
    pub touch_in_direction: u32,
}

impl ProbeTouch {
    /// Whether this touch is the first after a change of direction.
    pub fn is_first(&self) -> bool {
        self.touch_in_direction == 1
    }

    /// The approach's azimuth φ, degrees in [0, 360).
    pub fn phi_deg(&self) -> f64 {
        let [i, j, _] = self.approach;
        j.atan2(i).to_degrees().rem_euclid(360.0)
    }

    /// The approach's elevation θ, degrees.
    pub fn theta_deg(&self) -> f64 {
        self.approach[2].clamp(-1.0, 1.0).asin().to_degrees()
    }
}

/// The approach vector of φ, θ (degrees): i = cos θ cos φ, j = cos θ sin φ, k = sin θ
/// (`machine-formats.md`, "Kind `probe`").
pub fn approach_of(phi_deg: f64, theta_deg: f64) -> [f64; 3] {
    let (p, t) = (phi_deg.to_radians(), theta_deg.to_radians());
    [t.cos() * p.cos(), t.cos() * p.sin(), t.sin()]
}

/// The angle between two approach vectors, degrees (they need not be unit length).
pub fn angle_between_deg(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    (dot / (na * nb)).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The reader rule (`machine-formats.md`, "Kind `probe`"): `touches` sorted by `seq`; sets each
/// touch's number within its direction. A touch changes direction when its approach differs
/// from the previous touch's by more than `same_direction_deg`, or its stylus, artefact or
/// `spindle_deg` differs; the first touch counts as a change.
pub fn derive_directions(touches: &mut [ProbeTouch], same_direction_deg: f64) {
    touches.sort_by_key(|t| t.seq);
    let mut number = 0u32;
    for i in 0..touches.len() {
        let change = i == 0 || {
            let (p, t) = (&touches[i - 1], &touches[i]);
            angle_between_deg(&p.approach, &t.approach) > same_direction_deg
                || p.stylus != t.stylus
                || p.artefact != t.artefact
                || p.spindle_deg != t.spindle_deg
        };
        number = if change { 1 } else { number + 1 };
        touches[i].touch_in_direction = number;
    }
}

/// The logs of a `probe` campaign as plain data.
#[derive(Debug, Clone)]
pub struct ProbeCampaignLogs {
    /// The validated manifest.
    pub campaign: ProbeCampaign,
    /// Every input file with its hash.
    pub inputs: Vec<crate::series::InputFile>,
    /// The touches, in `seq` order, directions derived.
    pub touches: Vec<ProbeTouch>,
}

/// What a writer needs: the manifest and the touches (their derived numbers are not written).
#[derive(Debug, Clone)]
pub struct ProbeCampaignTables {
    /// The manifest.
    pub manifest: ProbeManifest,
    /// The touches.
    pub touches: Vec<ProbeTouch>,
}

/// `value` as the manifest shows it (for messages).
pub fn shown(value: f64) -> String {
    display_number(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(seq: i64, phi: f64, spindle: Option<f64>) -> ProbeTouch {
        ProbeTouch {
            time_ns: seq * 1_000_000_000,
            seq,
            approach: approach_of(phi, 0.0),
            position_mm: [0.0; 3],
            feed_mm_min: None,
            stylus: "S1".into(),
            artefact: "A".into(),
            spindle_deg: spindle,
            touch_in_direction: 0,
        }
    }

    #[test]
    fn directions_are_numbered_in_seq_order_whatever_the_row_order() {
        let mut t = vec![
            touch(5, 60.0, None),
            touch(1, 0.0, None),
            touch(2, 0.5, None),
            touch(9, 60.2, Some(180.0)),
            touch(3, 0.0, None),
            touch(7, 60.0, None),
        ];
        derive_directions(&mut t, 1.0);
        let numbers: Vec<(i64, u32)> = t.iter().map(|t| (t.seq, t.touch_in_direction)).collect();
        assert_eq!(numbers, [(1, 1), (2, 2), (3, 3), (5, 1), (7, 2), (9, 1)]);
    }
}
