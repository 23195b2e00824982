//! The effects a `roll` model may miss (`docs/spec/machine-physics.md`, "Kind roll", the table
//! of effects): those the global model can add as columns, and those it cannot tell from the
//! roll itself (said, with their size, not fitted).

/// An effect the model can add (a pipeline's `[roll] effects`, `--add-effect`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RollEffect {
    /// Constant zero offsets of the probes: 10³ (o_C − o_D − o_A + o_B)/L on every step, a
    /// linear ramp in n. Seen only against a level datum at two stations.
    ProbeZeroOffset,
    /// The stage's roll drifting in time: ω (t_n − t_{n−1}) on every step, of opposite sign in
    /// passes run the other way; the levels read it as ω t.
    RollDrift,
    /// The probes' zeros drifting in time: 10³ ρ t/L on a step at mean time t (ρ the combined
    /// drift of o_C − o_D − o_A + o_B), told from a roll by passes at other times.
    ProbeZeroDrift,
}

impl RollEffect {
    /// Every effect, in the order candidates are listed.
    pub const ALL: [RollEffect; 3] = [
        RollEffect::ProbeZeroOffset,
        RollEffect::RollDrift,
        RollEffect::ProbeZeroDrift,
    ];

    /// The name a pipeline's `[roll] effects` and `--add-effect` take.
    pub fn name(self) -> &'static str {
        match self {
            RollEffect::ProbeZeroOffset => "probe_zero_offset",
            RollEffect::RollDrift => "roll_drift",
            RollEffect::ProbeZeroDrift => "probe_zero_drift",
        }
    }

    /// The effect called `name`.
    pub fn parse(name: &str) -> Option<RollEffect> {
        RollEffect::ALL.into_iter().find(|e| e.name() == name)
    }

    /// The physical effect in the spec's words.
    pub fn physics(self) -> &'static str {
        match self {
            RollEffect::ProbeZeroOffset => "probe zero offset",
            RollEffect::RollDrift => "roll drifting in time",
            RollEffect::ProbeZeroDrift => "probe zero drift",
        }
    }

    /// Its parameter's name, with the unit.
    pub fn parameter_name(self) -> &'static str {
        match self {
            RollEffect::ProbeZeroOffset => "combined_offset_um",
            RollEffect::RollDrift => "roll_drift_urad_per_h",
            RollEffect::ProbeZeroDrift => "combined_zero_drift_um_per_h",
        }
    }

    /// Its column on a step row (µrad per unit of the parameter): `l_mm` the nominal L,
    /// `(k_now, k_before)` the row's coefficients of εx(n) and εx(n − 1), times in hours.
    pub(crate) fn step_column(self, l_mm: f64, k: (f64, f64), t_h: (f64, f64)) -> f64 {
        match self {
            RollEffect::ProbeZeroOffset => 1e3 / l_mm,
            RollEffect::RollDrift => k.0 * t_h.0 + k.1 * t_h.1,
            RollEffect::ProbeZeroDrift => 1e3 / l_mm * 0.5 * (t_h.0 + t_h.1),
        }
    }

    /// Its column on a level row at time `t_h`.
    pub(crate) fn level_column(self, t_h: f64) -> f64 {
        match self {
            RollEffect::RollDrift => t_h,
            RollEffect::ProbeZeroOffset | RollEffect::ProbeZeroDrift => 0.0,
        }
    }
}

/// An effect of the spec's table these data cannot tell from the roll: its signature is a
/// function of the station alone, which the roll free at every station absorbs.
#[derive(Debug, Clone, PartialEq)]
pub struct Unseen {
    /// The effect in the spec's words.
    pub effect: &'static str,
    /// What it turns into, and its size here.
    pub becomes: String,
}

/// What the catalogue's unseen effects amount to in this campaign: `reading_span_um` the
/// largest range of a probe's station means, `l_mm`, `u_xy_um` the largest probe position
/// uncertainty, `max_roll_urad` the largest |εx|, `step_error_um` the measured mean step minus
/// d (µm), `levels`: whether a level datum was read.
pub fn unseen(
    reading_span_um: f64,
    l_mm: f64,
    u_xy_um: f64,
    max_roll_urad: f64,
    step_error_um: f64,
    levels: bool,
) -> Vec<Unseen> {
    let gain_leak = 1e3 * 1e-3 * reading_span_um / l_mm;
    let scale = 2f64.sqrt() * u_xy_um / (l_mm * 1e3);
    let mut out = Vec::new();
    if !levels {
        out.push(Unseen {
            effect: "probe zero offset",
            becomes: format!(
                "a linear ramp in n, 10³ (o_C − o_D − o_A + o_B)/L per station ({:.1} µrad per µm here): read as roll; only an end-level datum (levels/) separates it",
                1e3 / l_mm
            ),
        });
    }
    out.push(Unseen {
        effect: "gain mismatch",
        becomes: format!(
            "m' = (1 + g) m leaks δz and the profile into each step: g = 1e-3 on readings spanning {reading_span_um:.1} µm gives up to {gain_leak:.2} µrad per step; calibrate the probes' gains"
        ),
    });
    out.push(Unseen {
        effect: "lateral probe position error",
        becomes: format!(
            "a scale error of εx, u = √2 u_xy/L = {:.1e} ({:.2} µrad at the largest |εx| = {max_roll_urad:.1} µrad, included in U), plus a profile-slope leak",
            scale,
            scale * max_roll_urad
        ),
    });
    out.push(Unseen {
        effect: "s ≠ d",
        becomes: format!(
            "the profile slope × (s − d)/L per step; the dwells' mean step differs from d by {step_error_um:.1} µm: a 1 µm/mm profile slope gives {:.3} µrad per step",
            1e3 * 1e-3 * step_error_um / l_mm
        ),
    });
    out.push(Unseen {
        effect: "probe tilt",
        becomes: format!(
            "0.1° → ≤ 10 nm reading error (seed §3.2): ≤ {:.2} µrad per step, within the noise",
            1e3 * 2.0 * 0.01 / l_mm
        ),
    });
    out
}
