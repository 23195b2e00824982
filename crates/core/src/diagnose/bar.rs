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
