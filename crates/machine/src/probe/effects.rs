//! The effects a `probe` model may miss (`docs/spec/machine-physics.md`, "Kind `probe`", the
//! table of effects), as columns the global model can add.

/// An effect the model can add.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ProbeEffect {
    /// First-touch reversal error: touch 1 after a change carries the previous rest offset; one
    /// offset per direction (µm).
    FirstTouch,
    /// Trigger latency: pretravel ∝ feed, feed × τ (ms).
    TriggerLatency,
    /// Machine drift during the cycle: the functional point moves linearly in time (µm/h per
    /// axis of M).
    MachineDrift,
    /// Artefact form: a 2nd harmonic of the radius in M (an oval ring or sphere), µm.
    ArtefactForm,
    /// Higher lobing: a 6th harmonic of the pretravel in the probe's frame (seats, stylus), µm.
    HigherLobing,
}

impl ProbeEffect {
    /// Every effect, in the order candidates are listed.
    pub const ALL: [ProbeEffect; 5] = [
        ProbeEffect::FirstTouch,
        ProbeEffect::TriggerLatency,
        ProbeEffect::MachineDrift,
        ProbeEffect::ArtefactForm,
        ProbeEffect::HigherLobing,
    ];

    /// The name a pipeline's `[probe] effects` and `--add-effect` take.
    pub fn name(self) -> &'static str {
        match self {
            ProbeEffect::FirstTouch => "first_touch",
            ProbeEffect::TriggerLatency => "trigger_latency",
            ProbeEffect::MachineDrift => "machine_drift",
            ProbeEffect::ArtefactForm => "artefact_form",
            ProbeEffect::HigherLobing => "higher_lobing",
        }
    }

    /// The effect called `name`.
    pub fn parse(name: &str) -> Option<ProbeEffect> {
        ProbeEffect::ALL.into_iter().find(|e| e.name() == name)
    }

    /// The physical effect in the spec's words.
    pub fn physics(self) -> &'static str {
        match self {
            ProbeEffect::FirstTouch => {
                "first-touch reversal error (touch 1 after a change re-seated at the previous direction's rest offset)"
            }
            ProbeEffect::TriggerLatency => "trigger latency (pretravel ∝ feed)",
            ProbeEffect::MachineDrift => "machine drift during the cycle",
            ProbeEffect::ArtefactForm => "artefact form (2nd harmonic of the radius)",
            ProbeEffect::HigherLobing => "higher lobing (6th harmonic in the probe's frame)",
        }
    }
}

/// What a touch needs for the effects' columns.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TouchInputs {
    /// Approach vector.
    pub(crate) a: [f64; 3],
    /// Approach azimuth in M, degrees.
    pub(crate) phi_deg: f64,
    /// Spindle orientation, degrees (0 when not given).
    pub(crate) spindle_deg: f64,
    /// Whether the touch is first after a change.
    pub(crate) first: bool,
    /// Its direction's index.
    pub(crate) direction: usize,
    /// Hours since the setup's first touch.
    pub(crate) hours: f64,
    /// Feed, mm/min.
    pub(crate) feed_mm_min: Option<f64>,
}

/// The names of an effect's columns (`directions`: how many directions the setup has).
pub(crate) fn column_names(e: ProbeEffect, directions: usize) -> Vec<String> {
    match e {
        ProbeEffect::FirstTouch => (0..directions)
            .map(|d| format!("first_touch_d{:02}_um", d + 1))
            .collect(),
        ProbeEffect::TriggerLatency => vec!["latency_ms".into()],
        ProbeEffect::MachineDrift => vec![
            "drift_x_um_per_h".into(),
            "drift_y_um_per_h".into(),
            "drift_z_um_per_h".into(),
        ],
        ProbeEffect::ArtefactForm => vec!["form2_cos_um".into(), "form2_sin_um".into()],
        ProbeEffect::HigherLobing => vec!["lobe6_cos_um".into(), "lobe6_sin_um".into()],
    }
}

/// An effect's columns for one touch (same order as [`column_names`]).
pub(crate) fn columns(e: ProbeEffect, t: &TouchInputs, directions: usize) -> Vec<f64> {
    match e {
        ProbeEffect::FirstTouch => (0..directions)
            .map(|d| f64::from(u8::from(t.first && t.direction == d)))
            .collect(),
        // feed (mm/min) / 60 → mm/s; × τ (ms) → µm.
        ProbeEffect::TriggerLatency => vec![t.feed_mm_min.unwrap_or(0.0) / 60.0],
        ProbeEffect::MachineDrift => t.a.iter().map(|c| c * t.hours).collect(),
        ProbeEffect::ArtefactForm => {
            let p = 2.0 * t.phi_deg.to_radians();
            vec![p.cos(), p.sin()]
        }
        ProbeEffect::HigherLobing => {
            let p = 6.0 * (t.phi_deg - t.spindle_deg).to_radians();
            vec![p.cos(), p.sin()]
        }
    }
}
