//! The bars' true parameters: the explicit list or a seeded fleet, plus the per-bar parameters
//! of each extra effect (drawn whether or not the effect is on, so switching one effect changes
//! nothing else), the geometric terms (own random stream) and the deliberate mismatches.

use std::collections::BTreeMap;

use rand::Rng;
use rand_distr::StandardNormal;

use super::config::{FleetConfig, SimConfig};
use super::environment::{AIR_HIGH, AIR_LOW};
use super::geometry::BarGeometry;
use super::truth::{BarTruth, ChannelTruth, HeadTruth, HeatTruth, SecondPathTruth};
use super::{stream_rng, streams};

/// Every bar's truth, in configuration order.
pub(crate) fn bar_truths(cfg: &SimConfig) -> Vec<BarTruth> {
    let base = if cfg.bars.is_empty() {
        fleet_bars(cfg.seed, &cfg.fleet_or_default())
    } else {
        explicit_bars(cfg)
    };
    base.into_iter()
        .enumerate()
        .map(|(i, bar)| with_mismatch(cfg, with_geometry(cfg, i, with_effects(cfg, i, bar))))
        .collect()
}

fn plain_bar(
    cfg: &SimConfig,
    id: String,
    fixed_length_mm: f64,
    alpha: f64,
    beta: f64,
    tau_r_s: f64,
    tau_s_s: f64,
) -> BarTruth {
    BarTruth {
        id,
        fixed_length_mm,
        d_zero_mm: fixed_length_mm,
        resolution_nm: cfg.resolution_nm,
        alpha_ppm_per_k: alpha,
        beta_ppm_per_k: beta,
        tau_r_s,
        tau_s_s,
        declared_sensor: AIR_LOW.into(),
        seen_weights: BTreeMap::from([(AIR_LOW.to_string(), 1.0)]),
        head_heating: None,
        second_path: None,
        creep_um_per_day: None,
        hidden_channel: None,
        settling_tau_s: None,
        heat_source: None,
        geometry: BarGeometry::default(),
        mismatch: None,
    }
}

fn explicit_bars(cfg: &SimConfig) -> Vec<BarTruth> {
    cfg.bars
        .iter()
        .map(|b| {
            plain_bar(
                cfg,
                b.id.clone(),
                b.fixed_length_mm,
                b.alpha_ppm_per_k,
                b.beta_ppm_per_k,
                b.tau_r_s,
                b.tau_s_s,
            )
        })
        .collect()
}

/// `n_bars` bars around the fleet mean: lengths and expansions normal, taus log-normal.
fn fleet_bars(seed: u64, f: &FleetConfig) -> Vec<BarTruth> {
    let mut rng = stream_rng(seed, streams::FLEET);
    let cfg = SimConfig {
        resolution_nm: 0.0,
        ..SimConfig::default()
    };
    (0..f.n_bars)
        .map(|i| {
            let z: [f64; 5] = std::array::from_fn(|_| rng.sample(StandardNormal));
            let mut bar = plain_bar(
                &cfg,
                format!("{}{:02}", f.id_prefix, i + 1),
                f.fixed_length_mm + f.fixed_length_sd_mm * z[0],
                f.alpha_ppm_per_k + f.alpha_sd_ppm_per_k * z[1],
                f.beta_ppm_per_k + f.beta_sd_ppm_per_k * z[2],
                f.tau_r_s * (f.tau_rel_sd * z[3]).exp(),
                f.tau_s_s * (f.tau_rel_sd * z[4]).exp(),
            );
            bar.fixed_length_mm = round_to_decimals(bar.fixed_length_mm, 4);
            bar.d_zero_mm = bar.fixed_length_mm;
            bar
        })
        .collect()
}

/// `x` rounded to `decimals` decimals (nearest f64, so it prints short in the manifest).
fn round_to_decimals(x: f64, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    (x * scale).round() / scale
}

/// Add the enabled effects' per-bar terms (log-normal spread around the configured values).
fn with_effects(cfg: &SimConfig, index: usize, mut bar: BarTruth) -> BarTruth {
    let mut rng = stream_rng(cfg.seed, streams::BAR_EFFECTS + index as u64);
    let z: [f64; 7] = std::array::from_fn(|_| rng.sample(StandardNormal));
    let e = &cfg.effects;
    bar.resolution_nm = cfg.resolution_nm;
    let h = &e.head_heating;
    if h.enabled {
        bar.head_heating = Some(HeadTruth {
            amplitude_um: h.amplitude_um * (h.spread * z[0]).exp(),
            tau_s: h.tau_s * (h.spread * z[1]).exp(),
        });
    }
    let s = &e.second_path;
    if s.enabled {
        bar.second_path = Some(SecondPathTruth {
            gain_ppm_per_k: s.gain_ppm_per_k * (s.spread * z[2]).exp(),
            tau_s: s.tau_s * (s.spread * z[3]).exp(),
        });
    }
    if e.creep.enabled {
        bar.creep_um_per_day = Some(e.creep.rate_um_per_day * (e.creep.spread * z[4]).exp());
    }
    let c = &e.hidden_channel;
    if c.enabled {
        bar.hidden_channel = Some(ChannelTruth {
            sensor: c.sensor_id.clone(),
            base_c: c.base_c,
            gain_um_per_k: c.gain_um_per_k * (c.spread * z[5]).exp(),
            tau_s: c.tau_s * (c.spread * z[6]).exp(),
        });
    }
    if e.sensor_gradient.enabled {
        let w = e.sensor_gradient.weight_t2;
        bar.seen_weights =
            BTreeMap::from([(AIR_LOW.to_string(), 1.0 - w), (AIR_HIGH.to_string(), w)]);
    }
    if e.settling.enabled {
        bar.settling_tau_s = Some(e.settling.tau_s);
    }
    let h = &e.heat_source;
    if h.enabled {
        // A stream of its own: the other effects' draws stay what they were.
        let mut rng = stream_rng(cfg.seed, streams::HEAT_SOURCE + index as u64);
        let z: [f64; 3] = std::array::from_fn(|_| rng.sample(StandardNormal));
        bar.heat_source = Some(HeatTruth {
            sensor: h.sensor_id.clone(),
            fixed_ppm_per_k: h.fixed_ppm_per_k * (h.spread * z[0]).exp(),
            scale_ppm_per_k: h.scale_ppm_per_k * (h.spread * z[1]).exp(),
            tau_s: h.tau_s * (h.spread * z[2]).exp(),
        });
    }
    bar
}

/// The bar's geometric terms around the `[geometry]` fleet mean (normal; sag log-normal), and
/// the counter zero moved by the zero offset.
fn with_geometry(cfg: &SimConfig, index: usize, mut bar: BarTruth) -> BarTruth {
    let mut rng = stream_rng(cfg.seed, streams::GEOMETRY + index as u64);
    let z: [f64; 5] = std::array::from_fn(|_| rng.sample(StandardNormal));
    let g = &cfg.geometry;
    bar.geometry = BarGeometry {
        scale_ppm: g.scale_ppm + g.scale_sd_ppm * z[0],
        nonlinearity_ppm_per_mm: g.nonlinearity_ppm_per_mm + g.nonlinearity_sd_ppm_per_mm * z[1],
        cosine_mrad: g.cosine_mrad + g.cosine_sd_mrad * z[2],
        zero_offset_um: g.zero_offset_um + g.zero_offset_sd_um * z[3],
        sag_um: g.sag.amplitude_um * (g.sag.spread * z[4]).exp(),
        sag_form: g.sag.form,
        sag_ref_mm: g.sag.ref_mm,
        sag_exponent: g.sag.exponent,
    };
    bar.d_zero_mm = bar.fixed_length_mm + bar.geometry.zero_offset_um * 1e-3;
    bar
}

/// Apply the bar's `[[mismatch]]` factors, if it has one.
fn with_mismatch(cfg: &SimConfig, mut bar: BarTruth) -> BarTruth {
    let Some(m) = cfg.mismatch.iter().find(|m| m.bar == bar.id) else {
        return bar;
    };
    bar.alpha_ppm_per_k *= m.alpha_factor;
    bar.beta_ppm_per_k *= m.beta_factor;
    bar.tau_r_s *= m.tau_r_factor;
    bar.tau_s_s *= m.tau_s_factor;
    bar.geometry.sag_um *= m.sag_factor;
    bar.mismatch = Some(m.clone());
    bar
}
