//! One bar's diagnosis: the screening base of its model, its residual statistics and the
//! ranking of the campaign's channels by what their first-order response would remove.
//!
//! Separate because it looks at one bar alone; fleet-level candidates are built from these.

use super::residual::residual_stats;
use super::screen::ScreenBase;
use super::{BarDiagnosis, ChannelScore};
use crate::identify::BarModel;
use crate::model::channels;
use crate::model::Effect;
use crate::model::Transform;
use crate::series::BarSeries;
use rayon::prelude::*;

/// Each bar's model linearised for screening (`ScreenBase`); `None` where it cannot be.
pub(crate) fn screen_bases(bars: &[(&BarSeries, &BarModel)]) -> Vec<Option<ScreenBase>> {
    bars.par_iter()
        .map(|(s, m)| ScreenBase::new(s, m))
        .collect()
}

/// Diagnose one bar's fit: residual statistics and the channel ranking (`base`: the model
/// linearised, [`screen_bases`]; without it no channel is ranked).
pub(crate) fn diagnose_bar(
    series: &BarSeries,
    model: &BarModel,
    base: Option<&ScreenBase>,
) -> BarDiagnosis {
    let y: Vec<f64> = series.fit_index.iter().map(|&i| series.y_um[i]).collect();
    let stats = residual_stats(&y, &model.residuals_um, model.n_params);
    let mut channels: Vec<ChannelScore> = match base {
        Some(base) => channels::available(series)
            .into_iter()
            .filter_map(|ch| score_channel(base, ch))
            .collect(),
        None => Vec::new(),
    };
    channels.sort_by(|a, b| {
        b.explained_fraction
            .total_cmp(&a.explained_fraction)
            .then_with(|| a.channel.cmp(&b.channel))
    });
    BarDiagnosis {
        bar: model.bar.clone(),
        effects: model.effects.clone(),
        rms_um: model.rms_um,
        whiteness_p: stats.whiteness_p,
        stats,
        channels,
    }
}

/// Fraction of the residual's RSS removed by the channel's best lag when the model is refitted
/// with it (the linearised refit of [`screen`]).
fn score_channel(base: &ScreenBase, channel: String) -> Option<ChannelScore> {
    let effect = Effect::Channel {
        transform: Transform::Lag,
        channel: channel.clone(),
        tau0_s: None,
    };
    let s = base.screen(&effect).ok()?;
    let rss = base.rss_um2();
    Some(ChannelScore {
        channel,
        explained_fraction: if rss > 0.0 {
            s.delta_rss_um2 / rss
        } else {
            0.0
        },
        tau_s: s.tau_s.unwrap_or(f64::NAN),
    })
}

/// The term an effect adds, whatever it is called: `head_heating` is the lag of the
/// `head_power` events, the same term as `lag:event:head_power` (one must not be offered once
/// the other is in the model, nor both as rival candidates).
pub(super) fn term_identity(e: &Effect) -> String {
    match e {
        Effect::HeadHeating => "lag:event:head_power".into(),
        Effect::Channel {
            transform, channel, ..
        } => Effect::Channel {
            transform: *transform,
            channel: channel.clone(),
            tau0_s: None,
        }
        .name(),
        other => other.name(),
    }
}

/// The family of terms one channel's response belongs to: `lag:CH` and `heat:CH` are one family
/// (`heat:CH` nests `lag:CH`: with `I_p` constant over a bar's mounts the two are one term,
/// `physics.md`'s first-order model), and so is a catalogue effect that is one of them
/// (`head_heating` is `lag:event:head_power`, [`term_identity`]); any other effect is its own.
pub(super) fn response_family(e: &Effect) -> String {
    let identity = term_identity(e);
    match identity.split_once(':') {
        Some(("lag" | "heat", channel)) => format!("response:{channel}"),
        _ => identity,
    }
}

/// The source a channel's response reads, whatever air sensor it is referred to: with `air` the
/// campaign's air sensors, `heat:C1`, `heat:T1-C1` and `lag:C1-T2` read one source, `source:C1`
/// (`air` holds T1 and T2, not C1). A difference of two air sensors or of two other sensors, and
/// any other effect, is its own [`response_family`].
///
/// Why: the base model already carries the air through each bar's own lags, so a heat source
/// referred to one air sensor or another, or to none, is nearly the same term: what those lags
/// take back. The beam lets one such reference go on once the others add the same next effect
/// (`selection::beam_paths`).
pub(super) fn source_family(e: &Effect, air: &[String]) -> String {
    let family = response_family(e);
    let Some(channel) = family.strip_prefix("response:") else {
        return family;
    };
    let is_air = |s: &str| air.iter().any(|a| a == s);
    let source = match channel.split_once('-') {
        Some((a, b)) if is_air(a) && !is_air(b) => b,
        Some((a, b)) if is_air(b) && !is_air(a) => a,
        Some(_) => return family,
        None if is_air(channel) || channel.starts_with("event:") => return family,
        None => channel,
    };
    format!("source:{source}")
}

/// The campaign's air sensors, as the fleet's first bar reads them (its plate sensor is not
/// one: a term referred to the plate reads the plate, [`super::plate`]); none for no bar.
pub(super) fn air_references(fleet: &[&BarSeries]) -> Vec<String> {
    let Some(series) = fleet.first() else {
        return Vec::new();
    };
    series
        .air_sensor_ids
        .iter()
        .filter(|s| series.plate_sensor_id.as_deref() != Some(s.as_str()))
        .cloned()
        .collect()
}
