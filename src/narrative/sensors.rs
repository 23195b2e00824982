//! What each temperature sensor plausibly is, in words: the diagnosis' sensor profiles
//! (`diagnose::sensors`) as `diagnosis.json`, the channel explanations and the ledger figures
//! quote them.

use crate::campaign::SensorKind;
use crate::diagnose::sensors::SensorProfile;

/// The profile in words, for reports and explanations: "air sensor, range 1.2 K; follows the
/// air (95 % of its variation, tau 16 min): probably in the air or on a light part".
pub fn description(p: &SensorProfile) -> String {
    let mut parts = vec![match p.declared_kind {
        SensorKind::Air => format!("air sensor, range {:.1} K", p.range_k),
        SensorKind::Plate => format!("plate sensor, range {:.1} K", p.range_k),
        _ => format!("range {:.1} K", p.range_k),
    }];
    if let Some(share) = p.air_share.filter(|_| p.follows_air()) {
        let minutes = p.air_tau_s / 60.0;
        let place = if minutes <= 10.0 {
            "in the air or on a light part"
        } else {
            "on a part that follows the room slowly"
        };
        parts.push(format!(
            "follows the air ({:.0} % of its variation, tau {minutes:.0} min): probably {place}",
            100.0 * share
        ));
    }
    match p.heated_by() {
        Some(kind) => {
            let minutes = p.event_tau_s / 60.0;
            let place = if p.near_source() {
                "near the heat source those events switch (a motor, bearing or head)"
            } else {
                "in the structure that source heats"
            };
            let of = if p.air_share.is_some() {
                "of what the air leaves"
            } else {
                "of its variation"
            };
            parts.push(format!(
                "heated by {} ({:.0} % {of}, tau {minutes:.0} min): probably {place}",
                event_words(kind),
                100.0 * p.event_share
            ));
        }
        None if !p.follows_air() && p.declared_kind != SensorKind::Air => parts.push(
            "moves mostly on its own: a slow part of the structure or a heat source nobody logs"
                .into(),
        ),
        None => {}
    }
    if p.fluctuates_fast() {
        parts.push(format!(
            "fast fluctuations of ±{:.1} K (air-conditioning or draughts)",
            2.0 * p.fast_fluctuation_k
        ));
    }
    parts.join("; ")
}

/// The profile in a few words, for figure captions: "t5: follows the air (16 min), heated by
/// 'spindle' events (on/off) (32 min, near the source)".
pub fn summary(p: &SensorProfile) -> String {
    let mut parts = Vec::new();
    match p.declared_kind {
        SensorKind::Air => parts.push("air sensor".to_string()),
        SensorKind::Plate => parts.push("plate sensor".to_string()),
        _ => {}
    }
    if p.follows_air() {
        parts.push(format!("follows the air ({:.0} min)", p.air_tau_s / 60.0));
    }
    if let Some(kind) = p.heated_by() {
        let near = if p.near_source() {
            ", near the source"
        } else {
            ""
        };
        parts.push(format!(
            "heated by {} ({:.0} min{near})",
            event_words(kind),
            p.event_tau_s / 60.0
        ));
    }
    if parts.is_empty() {
        parts.push("moves on its own".into());
    }
    if p.fluctuates_fast() {
        parts.push(format!("fast ±{:.1} K", 2.0 * p.fast_fluctuation_k));
    }
    format!("{}: {}", p.sensor, parts.join(", "))
}

/// The sensors a channel term reads, in a few words each (empty for other channels).
pub fn channel_sensor_summaries(channel: &str, profiles: &[SensorProfile]) -> Vec<String> {
    let names: Vec<&str> = match channel.split_once('-') {
        Some((a, b)) => vec![a, b],
        None => vec![channel],
    };
    names
        .into_iter()
        .filter_map(|n| profiles.iter().find(|p| p.sensor == n))
        .map(summary)
        .collect()
}

/// `spindle` → `'spindle' events`, `spindle (on/off)` → `'spindle' events (on/off)`.
fn event_words(label: &str) -> String {
    match label.strip_suffix(" (on/off)") {
        Some(kind) => format!("'{kind}' events (on/off)"),
        None => format!("'{label}' events"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> SensorProfile {
        SensorProfile {
            sensor: "t5".into(),
            declared_kind: SensorKind::Other,
            range_k: 3.0,
            fast_fluctuation_k: 0.01,
            air_share: Some(0.6),
            air_tau_s: 960.0,
            event: Some("spindle (on/off)".into()),
            event_tau_s: 1920.0,
            event_share: 0.92,
        }
    }

    #[test]
    fn a_sensor_heated_by_events_is_named_by_them() {
        let p = motor();
        assert_eq!(
            description(&p),
            "range 3.0 K; follows the air (60 % of its variation, tau 16 min): probably on a part \
             that follows the room slowly; heated by 'spindle' events (on/off) (92 % of what the \
             air leaves, tau 32 min): probably near the heat source those events switch (a \
             motor, bearing or head)"
        );
        assert_eq!(
            summary(&p),
            "t5: follows the air (16 min), heated by 'spindle' events (on/off) (32 min, near the source)"
        );
    }

    #[test]
    fn a_channel_of_two_sensors_quotes_both() {
        let mut air = motor();
        air.sensor = "T1".into();
        air.declared_kind = SensorKind::Air;
        air.air_share = None;
        air.event = None;
        air.event_share = 0.0;
        air.fast_fluctuation_k = 0.2;
        assert_eq!(
            channel_sensor_summaries("t5-T1", &[motor(), air]),
            [
                "t5: follows the air (16 min), heated by 'spindle' events (on/off) (32 min, near the source)",
                "T1: air sensor, fast ±0.4 K"
            ]
        );
        assert!(channel_sensor_summaries("time_of_day_h", &[motor()]).is_empty());
    }
}
