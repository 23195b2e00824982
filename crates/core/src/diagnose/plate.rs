//! The plate named where a generic term reads its sensor: the path with `plate_expansion` and
//! the same term of the other sensor, which the forward selection fits beside the path the beam
//! kept (`selection::CoarseFleet::with_the_plate_named`).
//!
//! Separate because it is a rule about sensors and terms, not about searching paths.

use super::bar::term_identity;
use super::Candidate;
use crate::model::Effect;
use crate::series::BarSeries;

/// The fleet's plate sensor, where `plate_expansion` is among the ranking's candidates.
pub(super) fn plate_named_in<'a>(
    series: &[&'a BarSeries],
    first_candidates: &[Candidate],
) -> Option<&'a str> {
    let offered = first_candidates
        .iter()
        .any(|c| c.effect == Effect::PlateExpansion);
    let plate = series.first()?.plate_sensor_id.as_deref()?;
    offered.then_some(plate)
}

/// `path` with its first generic term that reads the plate sensor `plate` (the sensor alone or
/// a difference with it) replaced by the same term of the other sensor, if any, then
/// `plate_expansion`, and its later terms on the plate sensor dropped (the plate is in the
/// model by then); at most `max_steps` steps. `None` when `path` names `plate_expansion` or
/// reads the plate through no generic term.
pub(super) fn plate_split_path(
    path: &[Effect],
    plate: &str,
    max_steps: usize,
) -> Option<Vec<Effect>> {
    if path.contains(&Effect::PlateExpansion) {
        return None;
    }
    let mut split = Vec::with_capacity(path.len() + 1);
    let mut named = false;
    for effect in path {
        match without_sensor(effect, plate) {
            None => split.push(effect.clone()),
            Some(_) if named => {}
            Some(rest) => {
                split.extend(rest);
                split.push(Effect::PlateExpansion);
                named = true;
            }
        }
    }
    let mut seen = std::collections::BTreeSet::new();
    split.retain(|e| seen.insert(term_identity(e)));
    split.truncate(max_steps.max(1));
    named.then_some(split)
}

/// For a generic term that reads `sensor` (the sensor alone, or a difference of two with it):
/// the same term of the other sensor (`None` for the sensor alone). `None` for any other term.
pub(super) fn without_sensor(effect: &Effect, sensor: &str) -> Option<Option<Effect>> {
    let Effect::Channel {
        transform, channel, ..
    } = effect
    else {
        return None;
    };
    if channel == sensor {
        return Some(None);
    }
    let other = match channel.split_once('-')? {
        (a, b) if a == sensor => b,
        (a, b) if b == sensor => a,
        _ => return None,
    };
    Some(Some(Effect::Channel {
        transform: *transform,
        channel: other.to_string(),
        tau0_s: None,
    }))
}

#[cfg(test)]
pub(super) mod tests {
    use super::plate_split_path;
    use crate::model::Effect;

    /// The effects of these names (a test's paths).
    pub(in crate::diagnose) fn effects(names: &[&str]) -> Vec<Effect> {
        names
            .iter()
            .map(|n| Effect::parse(n).expect("an effect name"))
            .collect()
    }

    #[test]
    fn a_generic_term_on_the_plate_sensor_splits_into_plate_expansion_and_its_other_sensor() {
        let split = |path: &[&str], steps| {
            plate_split_path(&effects(path), "P1", steps)
                .map(|p| p.iter().map(Effect::name).collect::<Vec<_>>())
        };
        // The second simulator's k = 3 case: the difference with the cabinet's sensor.
        assert_eq!(
            split(&["heat:P1-C1", "air_gradient"], 3),
            Some(vec![
                "heat:C1".into(),
                "plate_expansion".into(),
                "air_gradient".into()
            ])
        );
        // The plate on either side of the difference; a later term on the plate is dropped.
        assert_eq!(
            split(&["heat:H1-P1", "heat:T2-P1", "air_gradient"], 3),
            Some(vec![
                "heat:H1".into(),
                "plate_expansion".into(),
                "air_gradient".into()
            ])
        );
        // The plate sensor alone leaves no term of its own; the transform is kept.
        assert_eq!(
            split(&["lag:P1", "creep"], 3),
            Some(vec!["plate_expansion".into(), "creep".into()])
        );
        // No longer than the forward selection may go.
        assert_eq!(
            split(&["heat:P1-C1", "air_gradient", "creep"], 3),
            Some(vec![
                "heat:C1".into(),
                "plate_expansion".into(),
                "air_gradient".into()
            ])
        );
        // Nothing to split: the plate named already, or not read by a generic term.
        assert_eq!(split(&["heat:P1-C1", "plate_expansion"], 3), None);
        assert_eq!(split(&["heat:T1-C1", "air_gradient"], 3), None);
        assert_eq!(split(&["heat:P10-C1"], 3), None);
    }
}
