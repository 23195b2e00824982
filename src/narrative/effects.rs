//! One line per effect, in physical words: what the effect means and what to check on the
//! bench. These strings go verbatim into `diagnosis.json` and the reports.

use super::sensors::description;
use crate::diagnose::sensors::SensorProfile;
use crate::model::{Effect, Transform};

/// What an effect means physically and what to check; channel terms name what their sensors
/// plausibly are (`profiles`, see [`super::sensors`]).
pub fn explain_with(effect: &Effect, profiles: &[SensorProfile]) -> String {
    match effect {
        Effect::Channel {
            transform, channel, ..
        } => channel_explanation(*transform, &describe_channel_with(channel, profiles)),
        other => explain(other),
    }
}

/// A channel name in words, with what its sensors plausibly are.
pub fn describe_channel_with(channel: &str, profiles: &[SensorProfile]) -> String {
    let generic = describe_channel(channel);
    let of = |s: &str| profiles.iter().find(|p| p.sensor == s);
    if let Some(p) = of(channel) {
        return format!("{generic} ({})", description(p));
    }
    if let Some((a, b)) = channel.split_once('-') {
        if let (Some(pa), Some(pb)) = (of(a), of(b)) {
            return format!(
                "{generic}: {a} {}; {b} {}",
                description(pa),
                description(pb)
            );
        }
    }
    generic
}

/// What an effect means physically and what to check.
pub fn explain(effect: &Effect) -> String {
    match effect {
        Effect::FixedPart => "Expansion of the fixed part (balls, bases, tubes) with its own time constant: the patent's alpha, tau_R.".into(),
        Effect::Scale => "Expansion of the scale between its start and the read head, growing with the travel I_p: the patent's beta, tau_S. Check: bars on different plate lengths drift differently.".into(),
        Effect::HeadHeating => "Read-head self-heating: the reading steps after head_power events and settles with its own time constant. Check: power the head long before measuring, or log head power.".into(),
        Effect::SecondPath => "A second thermal path with a slower or faster time constant (e.g. tube and end caps heat at different rates): the residual follows the rate of temperature change. Check: where heat enters the bar, insulation of the tubes.".into(),
        Effect::AirGradient => "A temperature gradient between the air sensors that the bar sees differently from its own sensor (e.g. vertical stratification): the bar's air is its sensor plus a share of the difference to the other air sensors, reaching the fixed part and the scale with their own time constants. Check: sensor placement; move the sensor closer to the bar or add one.".into(),
        Effect::PlateExpansion => "The plate expands with its temperature: the true centre distance grows with plate temperature (its sensor) times length. Check: the plate material and its CTE in campaign.toml, the plate sensor.".into(),
        Effect::Settling => "Settling after each mount: the bar creeps into its sockets or warms from handling, decaying after the mount. Check: wait longer after mounting, use gloves, check the magnetic sockets.".into(),
        Effect::Creep => "Slow monotonic drift independent of temperature (creep, ageing, encoder drift). Check: the bar's history, mechanical stress, the logger's reference mark.".into(),
        // Without sensor profiles the channel is described by its name alone.
        Effect::Channel { .. } => explain_with(effect, &[]),
    }
}

fn channel_explanation(transform: Transform, what: &str) -> String {
    let how = match transform {
        Transform::Lag => "a first-order response (gain and time constant) to",
        Transform::Rate => "the rate of change of",
        Transform::Level => "the level of",
        Transform::Heat => {
            return format!("Heat from {what} reaches the bar through a first-order lag of its own and expands both its lengths (I_min and I_p, like the air does); no catalogue effect explains it as well. Check what this source is (a cabinet, a lamp, a machine) and shield the bars from it or log it beside them.");
        }
    };
    format!("The reading follows {how} {what}; no catalogue effect explains it as well. Check what this channel measures and how it reaches the bar.")
}

/// A channel name in words.
fn describe_channel(channel: &str) -> String {
    if let Some(kind) = channel.strip_prefix("event:") {
        return match kind {
            "head_power" => "read-head power (head_power events)".into(),
            "tilt" => "plate tilt changes (tilt events)".into(),
            "handling" => "handling events (someone touched the bar)".into(),
            "door" => "door openings (door events): a draught reaches the bar".into(),
            other => format!("'{other}' events"),
        };
    }
    match channel {
        "time_since_mount_h" => "the time since mounting".into(),
        "time_of_day_h" => "the time of day (a daily cycle not seen by the sensors)".into(),
        "length_mm" => "the scale travel I_p (plate length)".into(),
        "tilt_deg" => "the tilt of the bar".into(),
        _ if channel.contains('-') => {
            format!("the temperature difference {channel} (a gradient between sensors)")
        }
        _ => format!("sensor {channel}"),
    }
}
