//! The `probe` simulator (`docs/spec/machine-physics.md`, "Kind `probe`", forward model;
//! written from the spec, sharing nothing with the analysis but the format types): a stylus
//! touching a ring (from inside) or a sphere (from outside) in equally spaced directions, each
//! touch's latched tip centre
//!
//! ```text
//! x_k = c_k + 10⁻³ [δ(φ_k) + v τ + noise] a_k − 10⁻³ O_{k−1} − 10⁻³ g(t_k)
//! ```
//!
//! with c_k the tip centre at first contact on the true artefact (the true centre is the
//! programme's centre plus the offset; true radius with its lobed form; true tip radius), δ the seed's tri-lobe
//! (eqs. 10–11: δ_min / cos(60° − φ'), φ' = (φ − φ₀ − spindle) mod 120°), v τ feed × latency,
//! O the pendulum's rest offset after the previous touch (O(a) = rest (cos(φ_a + twist),
//! sin(φ_a + twist), 0)), g the machine's drift. The truth is written beside the campaign
//! (`truth.json`, `truth/probe_truth.parquet`), never read by the analysis.

mod config;

use std::path::Path;

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use dbbcal_core::axis_campaign::{CampaignKind, KindSection};
use dbbcal_core::probe_campaign::{
    ArtefactDecl, ArtefactKind, ProbeCampaignTables, ProbeManifest, ProbeSection, ProbeTouch,
    StylusDecl,
};

pub use config::{
    ProbeSimArtefact, ProbeSimConfig, ProbeSimOutput, ProbeSimPretravel, ProbeSimReversal,
    ProbeSimStylus, ProbeSimTouches,
};

use crate::SimError;

/// What was simulated: the campaign and its truth.
#[derive(Debug, Clone)]
pub struct ProbeSimulation {
    /// Manifest and touches.
    pub tables: ProbeCampaignTables,
    /// The truth.
    pub truth: ProbeTruth,
}

/// The truth of a simulated `probe` campaign (`truth.json`).
#[derive(Debug, Clone, Serialize)]
pub struct ProbeTruth {
    /// True centre, mm.
    pub centre_mm: [f64; 3],
    /// Its offset from the programme's centre, µm.
    pub centre_offset_um: [f64; 3],
    /// True tip diameter, mm.
    pub tip_diameter_mm: f64,
    /// δ_min, µm.
    pub delta_min_um: f64,
    /// φ₀, degrees.
    pub seat_phase_deg: f64,
    /// feed × τ, µm.
    pub latency_um: f64,
    /// Per direction (in φ order): φ, the pretravel δ(φ) at spindle 0 (µm), and the reversal
    /// error of its first touch (µm; the first of each visit, averaged over visits).
    pub directions: Vec<TruthDirection>,
    /// Per touch, in seq order.
    #[serde(skip)]
    pub touches: Vec<TruthTouch>,
}

/// One direction's truth.
#[derive(Debug, Clone, Serialize)]
pub struct TruthDirection {
    /// Azimuth, degrees.
    pub phi_deg: f64,
    /// Spindle, degrees.
    pub spindle_deg: f64,
    /// δ, µm.
    pub pretravel_um: f64,
    /// e of touch 1, µm.
    pub first_touch_error_um: f64,
}

/// One touch's truth.
#[derive(Debug, Clone)]
pub struct TruthTouch {
    /// seq.
    pub seq: i64,
    /// δ, µm.
    pub pretravel_um: f64,
    /// Reversal error (touch 1 only), µm.
    pub reversal_um: f64,
    /// Drift along the approach, µm.
    pub drift_um: f64,
    /// Noise, µm.
    pub noise_um: f64,
}

/// Whether a simulation TOML asks for a `probe` campaign (top-level `kind = "probe"`).
pub fn is_probe_config(text: &str) -> Result<bool, SimError> {
    let table: toml::Table = toml::from_str(text)?;
    Ok(matches!(table.get("kind"), Some(toml::Value::String(s)) if s == "probe"))
}

/// The seed's tri-lobe relative to δ_min (eqs. 10–11).
fn tri_lobe(phi_prime_deg: f64) -> f64 {
    let p = phi_prime_deg.rem_euclid(120.0);
    1.0 / (60.0 - p).to_radians().cos()
}

fn rest_offset_um(c: &ProbeSimConfig, phi_deg: f64) -> [f64; 3] {
    let p = (phi_deg + c.reversal.twist_deg).to_radians();
    [
        c.reversal.rest_um * p.cos(),
        c.reversal.rest_um * p.sin(),
        0.0,
    ]
}

/// Simulate a `probe` campaign.
pub fn generate_probe(c: &ProbeSimConfig) -> Result<ProbeSimulation, SimError> {
    c.validate()?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(c.seed);
    let noise =
        Normal::new(0.0, c.pretravel.noise_um.max(1e-12)).map_err(|e| SimError::Invalid {
            key: "pretravel.noise_um".into(),
            reason: e.to_string(),
        })?;
    let a_cfg = &c.artefact;
    let true_centre: [f64; 3] =
        std::array::from_fn(|k| a_cfg.centre_mm[k] + 1e-3 * a_cfg.centre_offset_um[k]);
    let tip_r = (c.stylus.tip_diameter_mm + 1e-3 * c.stylus.tip_error_um) / 2.0;
    let latency_um = c.touches.feed_mm_min / 60.0 * c.pretravel.latency_ms;
    let spindles = if c.touches.spindle_deg.is_empty() {
        vec![None]
    } else {
        c.touches.spindle_deg.iter().map(|s| Some(*s)).collect()
    };
    let n = c.touches.directions;
    let theta = c.touches.elevation_deg.to_radians();
    let mut touches = Vec::new();
    let mut truth_touches = Vec::new();
    let mut first_errors: Vec<(f64, f64, f64, f64, usize)> = Vec::new();
    let mut prev_phi: Option<f64> = None;
    let mut seq = 0i64;
    let t0 = c.start.timestamp_nanos_opt().ok_or(SimError::Time(0))?;
    for spindle in &spindles {
        let mut order: Vec<usize> = (0..n).collect();
        if c.touches.order == "shuffled" {
            order.shuffle(&mut rng);
        }
        for d in order {
            let phi = c.touches.first_phi_deg + 360.0 * d as f64 / n as f64;
            let (pr, tr) = (phi.to_radians(), theta);
            let a = [tr.cos() * pr.cos(), tr.cos() * pr.sin(), tr.sin()];
            // Contact normal from the centre: a ring is touched moving outwards, a sphere inwards.
            let normal = match a_cfg.kind {
                ArtefactKind::Ring => a,
                ArtefactKind::Sphere => a.map(|v| -v),
            };
            let form = a_cfg.form_um
                * (f64::from(a_cfg.form_lobes) * (phi - a_cfg.form_phase_deg))
                    .to_radians()
                    .cos();
            let big_r = a_cfg.diameter_mm / 2.0 + 1e-3 * form;
            let reach = match a_cfg.kind {
                ArtefactKind::Ring => big_r - tip_r,
                ArtefactKind::Sphere => big_r + tip_r,
            };
            let phi_prime = phi - c.pretravel.seat_phase_deg - spindle.unwrap_or(0.0);
            let delta = c.pretravel.delta_min_um * tri_lobe(phi_prime);
            let o_now = rest_offset_um(c, phi);
            let o_before = rest_offset_um(c, prev_phi.unwrap_or(phi));
            let e_first = -(0..3).map(|k| (o_before[k] - o_now[k]) * a[k]).sum::<f64>();
            first_errors.push((phi, spindle.unwrap_or(0.0), delta, e_first, d));
            for k in 0..c.touches.per_direction {
                seq += 1;
                let t_ns = t0 + (seq - 1) * (c.touches.interval_s * 1e9) as i64;
                let hours = (t_ns - t0) as f64 / 3.6e12;
                let g = c.drift_um_per_h.map(|v| v * hours);
                let o = if k == 0 { o_before } else { o_now };
                let e = noise.sample(&mut rng) * f64::from(u8::from(c.pretravel.noise_um > 0.0));
                let along = delta + latency_um + e;
                let x: [f64; 3] = std::array::from_fn(|j| {
                    true_centre[j] + reach * normal[j] + 1e-3 * along * a[j]
                        - 1e-3 * o[j]
                        - 1e-3 * g[j]
                });
                touches.push(ProbeTouch {
                    time_ns: t_ns,
                    seq: seq * 10,
                    approach: a,
                    position_mm: x,
                    feed_mm_min: Some(c.touches.feed_mm_min),
                    stylus: c.stylus.id.clone(),
                    artefact: a_cfg.id.clone(),
                    spindle_deg: *spindle,
                    touch_in_direction: 0,
                });
                truth_touches.push(TruthTouch {
                    seq: seq * 10,
                    pretravel_um: delta,
                    reversal_um: if k == 0 { e_first } else { 0.0 },
                    drift_um: -(0..3).map(|j| g[j] * a[j]).sum::<f64>(),
                    noise_um: e,
                });
            }
            prev_phi = Some(phi);
        }
    }
    first_errors.sort_by(|x, y| x.1.total_cmp(&y.1).then(x.4.cmp(&y.4)));
    let manifest = ProbeManifest {
        campaign: KindSection {
            kind: CampaignKind::Probe,
            id: c.campaign_id.clone(),
            reference_temperature_c: c.reference_temperature_c,
        },
        probe: ProbeSection {
            model: Some(c.probe_model.clone()),
            same_direction_deg: 1.0,
        },
        stylus: vec![StylusDecl {
            id: c.stylus.id.clone(),
            tip_diameter_mm: c.stylus.tip_diameter_mm,
            length_mm: Some(c.stylus.length_mm),
        }],
        artefact: vec![ArtefactDecl {
            id: a_cfg.id.clone(),
            kind: a_cfg.kind,
            diameter_mm: a_cfg.diameter_mm,
            u_um: a_cfg.u_um,
            form_um: (a_cfg.form_um > 0.0).then_some(a_cfg.form_um),
            centre_mm: a_cfg.declare_centre.then_some(a_cfg.centre_mm),
        }],
        sensor: Vec::new(),
    };
    Ok(ProbeSimulation {
        tables: ProbeCampaignTables { manifest, touches },
        truth: ProbeTruth {
            centre_mm: true_centre,
            centre_offset_um: a_cfg.centre_offset_um,
            tip_diameter_mm: 2.0 * tip_r,
            delta_min_um: c.pretravel.delta_min_um,
            seat_phase_deg: c.pretravel.seat_phase_deg,
            latency_um,
            directions: first_errors
                .into_iter()
                .map(|(phi, spindle, delta, e, _)| TruthDirection {
                    phi_deg: phi.rem_euclid(360.0),
                    spindle_deg: spindle,
                    pretravel_um: delta,
                    first_touch_error_um: e,
                })
                .collect(),
            touches: truth_touches,
        },
    })
}

/// Writes the campaign (`campaign.toml`, `touches/`) and its truth under `dir`.
pub fn write_probe(sim: &ProbeSimulation, dir: &Path, c: &ProbeSimConfig) -> Result<(), SimError> {
    let opts = dbbcal_io::ProbeWriteOptions {
        files: c.output.files,
        shuffle_rows: c.output.shuffle_rows,
        angles: c.output.angles,
        seed: c.seed,
        ..Default::default()
    };
    dbbcal_io::write_probe_campaign(dir, &sim.tables, &opts)?;
    let folder = dir.join("truth");
    std::fs::create_dir_all(&folder).map_err(|source| SimError::Io {
        path: folder.display().to_string(),
        source,
    })?;
    let t = &sim.truth.touches;
    let table = dbbcal_io::Table::new()
        .with(
            "seq",
            dbbcal_io::Column::I64(t.iter().map(|x| x.seq).collect()),
        )
        .with(
            "pretravel_um",
            dbbcal_io::Column::F64(t.iter().map(|x| x.pretravel_um).collect()),
        )
        .with(
            "reversal_um",
            dbbcal_io::Column::F64(t.iter().map(|x| x.reversal_um).collect()),
        )
        .with(
            "drift_um",
            dbbcal_io::Column::F64(t.iter().map(|x| x.drift_um).collect()),
        )
        .with(
            "noise_um",
            dbbcal_io::Column::F64(t.iter().map(|x| x.noise_um).collect()),
        );
    dbbcal_io::write_table(&folder.join("probe_truth.parquet"), &table)?;
    let path = dir.join("truth.json");
    let text = serde_json::to_string_pretty(&sim.truth)?;
    std::fs::write(&path, text).map_err(|source| SimError::Io {
        path: path.display().to_string(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quiet_ring_reads_the_seeds_tri_lobe_and_touch_one_its_reversal() {
        let mut c = ProbeSimConfig::default();
        c.pretravel.noise_um = 0.0;
        c.pretravel.latency_ms = 0.0;
        c.reversal.rest_um = 0.4;
        c.artefact.centre_offset_um = [1.0, -2.0, 0.0];
        let sim = generate_probe(&c).unwrap();
        let t = &sim.truth;
        let r_reach = c.artefact.diameter_mm / 2.0 - c.stylus.tip_diameter_mm / 2.0;
        let mut firsts = 0;
        for (touch, truth) in sim.tables.touches.iter().zip(&t.touches) {
            let a = touch.approach;
            let along: f64 = (0..3)
                .map(|k| (touch.position_mm[k] - t.centre_mm[k]) * a[k])
                .sum();
            let seen_um = 1e3 * (along - r_reach);
            let phi = a[1].atan2(a[0]).to_degrees();
            let psi = (phi - 20.0).rem_euclid(120.0);
            let delta = 0.3 / (60.0 - psi).to_radians().cos();
            assert!((truth.pretravel_um - delta).abs() < 1e-9);
            // Touches 2… carry −O(a)·a = −rest cos(twist) = 0 (twist 90°); touch 1 its e.
            assert!(
                (seen_um - delta - truth.reversal_um).abs() < 1e-6,
                "{seen_um} {delta}"
            );
            if truth.reversal_um.abs() > 0.05 {
                firsts += 1;
            }
        }
        assert!(
            firsts > 10,
            "{firsts} first touches with a visible reversal"
        );
        assert_eq!(sim.tables.touches.len(), 240);
        assert!(sim.tables.manifest.artefact[0].centre_mm.is_none());
    }
}
