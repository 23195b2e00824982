//! Binding effects to a bar's data: each effect's terms with their input channel, column scale,
//! kind and shared time constant, and the start of each term's time constant.
//!
//! Separate because it is where the effect vocabulary meets one campaign's channels, apart from
//! how the bound terms are then evaluated.

use super::channels;
use super::channels::Channel;
use super::channels::ChannelError;
use super::problem::{BoundTerm, TermKind};
use super::{Effect, Transform, INITIAL_FIXED, INITIAL_SCALE};
use crate::series::BarSeries;
use crate::signal::plate_temperature;

/// Bind an effect to a bar's data: its input channel and per-sample scale, one term per column
/// (`air_gradient`: one per base path of `model`, none when the model has neither).
pub(super) fn bind(
    series: &BarSeries,
    effect: &Effect,
    model: &[Effect],
) -> Result<Vec<BoundTerm>, ChannelError> {
    let t0 = series.reference_temperature_c;
    let minus_i_min = || Some(vec![-series.bar.fixed_length_mm * 1e-3; series.t_s.len()]);
    let minus_i_p = || Some(series.i_p_mm().iter().map(|ip| -ip * 1e-3).collect());
    let air = || Channel::Sampled(series.air_c.iter().map(|t| t - t0).collect());
    let term = |input, scale, kind| BoundTerm {
        effect: effect.clone(),
        gain_name: effect.gain_name(),
        input,
        scale,
        kind,
        shares_tau_of: None,
    };
    // A base path: its lag of the air and the decay of its initial departure from steady
    // state ([`initial_state`]), on the same length and time constant.
    let base_path = |scale: Option<Vec<f64>>, initial_name: &str| {
        vec![
            term(air(), scale.clone(), TermKind::Lag),
            BoundTerm {
                gain_name: initial_name.to_string(),
                shares_tau_of: Some(effect.clone()),
                ..term(Channel::Sampled(Vec::new()), scale, TermKind::InitialState)
            },
        ]
    };
    let single = match effect {
        Effect::FixedPart => return Ok(base_path(minus_i_min(), INITIAL_FIXED)),
        Effect::Scale => return Ok(base_path(minus_i_p(), INITIAL_SCALE)),
        Effect::SecondPath => term(air(), minus_i_min(), TermKind::Lag),
        Effect::HeadHeating => {
            let (input, start) = channels::held_event_channel(series, "head_power")?;
            let scale = Some(vec![-1.0; series.t_s.len()]);
            let mut terms = vec![term(input, scale.clone(), TermKind::Lag)];
            terms.extend(start_terms(series, effect, &start, scale, TermKind::Lag));
            return Ok(terms);
        }
        Effect::AirGradient => {
            // `docs/spec/physics.md` model with `T = T_own + w dT_grad`: the gradient's share through each
            // base path, on that path's length and with that path's time constant.
            let gradient = channels::air_gradient(series)?;
            let names = effect.gain_names();
            let paths = [
                (Effect::FixedPart, minus_i_min(), &names[0]),
                (Effect::Scale, minus_i_p(), &names[1]),
            ];
            return Ok(paths
                .into_iter()
                .filter(|(path, ..)| model.contains(path))
                .map(|(path, scale, name)| BoundTerm {
                    gain_name: name.clone(),
                    shares_tau_of: Some(path),
                    ..term(gradient.clone(), scale, TermKind::Lag)
                })
                .collect());
        }
        Effect::PlateExpansion => {
            // `docs/spec/campaign-format.md`: the true distance is `mm (1 + cte (T_plate - T0))`, so an
            // undeclared expansion raises the reading by `cte L (T_plate - T0)` (µm: mm · ppm/K ·
            // K · 1e-3).
            let plate = plate_temperature(&series.t_s, &channels::plate_temperature(series)?);
            let length: Vec<f64> = series
                .mount_of
                .iter()
                .map(|m| {
                    m.and_then(|m| series.mounts[m as usize].length_mm)
                        .unwrap_or(0.0)
                        * 1e-3
                })
                .collect();
            term(
                Channel::Sampled(plate.iter().map(|t| t - t0).collect()),
                Some(length),
                TermKind::Level,
            )
        }
        Effect::Settling => term(
            Channel::Sampled(vec![0.0; series.t_s.len()]),
            None,
            TermKind::Settling,
        ),
        Effect::Creep => term(
            Channel::Sampled(series.t_s.iter().map(|t| t / 86400.0).collect()),
            None,
            TermKind::Level,
        ),
        Effect::Channel {
            transform: Transform::Heat,
            channel,
            ..
        } => {
            // Heat from the channel reaches both of the bar's lengths through one lag of its
            // own: the fixed part's share on `I_min`, the scale's on `I_p` (left out when the
            // model has no scale: one length cannot tell the two apart, as for `air_gradient`).
            if channel.starts_with("event:") {
                return Err(ChannelError::HeatNeedsSampled(channel.clone()));
            }
            let input = channels::resolve(series, channel)?;
            let names = effect.gain_names();
            let mut terms = vec![BoundTerm {
                gain_name: names[0].clone(),
                ..term(input.clone(), minus_i_min(), TermKind::Lag)
            }];
            if model.contains(&Effect::Scale) {
                terms.push(BoundTerm {
                    gain_name: names[1].clone(),
                    shares_tau_of: Some(effect.clone()),
                    ..term(input, minus_i_p(), TermKind::Lag)
                });
            }
            return Ok(terms);
        }
        Effect::Channel {
            transform, channel, ..
        } => {
            let kind = match transform {
                // (`heat:` is bound above, as lags.)
                Transform::Lag | Transform::Heat => TermKind::Lag,
                Transform::Rate => TermKind::Rate,
                Transform::Level => TermKind::Level,
            };
            if let Some(event_kind) = channel.strip_prefix("event:") {
                let (input, start) = channels::held_event_channel(series, event_kind)?;
                let mut terms = vec![term(input, None, kind)];
                terms.extend(start_terms(series, effect, &start, None, kind));
                return Ok(terms);
            }
            term(channels::resolve(series, channel)?, None, kind)
        }
    };
    Ok(vec![single])
}

/// The extra terms that fit what the data leave unknown about a held event input's start
/// ([`channels::HeldStart`]), on the time constant of `effect`'s own term: a free level before
/// the first event (the indicator of "before", transformed as the effect's input is), and the
/// decay of an unknown initial deviation of its lag ([`TermKind::Decay`]; a level has no lag).
fn start_terms(
    series: &BarSeries,
    effect: &Effect,
    start: &channels::HeldStart,
    scale: Option<Vec<f64>>,
    kind: TermKind,
) -> Vec<BoundTerm> {
    let (level_name, deviation_name) = effect.start_gain_names();
    let shares_tau_of = (kind != TermKind::Level).then(|| effect.clone());
    let mut terms = Vec::new();
    if let Some(indicator) = start.level_channel(&series.t_s) {
        terms.push(BoundTerm {
            effect: effect.clone(),
            gain_name: level_name,
            input: indicator,
            scale: scale.clone(),
            kind,
            shares_tau_of: shares_tau_of.clone(),
        });
    }
    if let (Some(from_s), Some(_)) = (start.free_deviation_from_s, &shares_tau_of) {
        terms.push(BoundTerm {
            effect: effect.clone(),
            gain_name: deviation_name,
            input: Channel::Sampled(Vec::new()),
            scale,
            kind: TermKind::Decay { from_s },
            shares_tau_of,
        });
    }
    terms
}
