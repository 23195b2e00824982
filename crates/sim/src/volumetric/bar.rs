//! Body diagonals read by a calibrated bar in re-seated segments (`[bar]`;
//! `docs/bar-diagonals.md`), from the geometry alone: the fixed ball in a socket S on the table,
//! placed `length_mm` behind the segment's first target on the diagonal's line to within
//! ±`socket_along_mm` along it and up to `socket_across_mm` across it; the spindle's ball at the
//! true tool point P + 10⁻³ (e(P) + g(t)) (the truth's error field and drift); the bar reads the
//! *exact* centre distance |P_true − S| (so the lateral error's |e⊥|²/(2L) and the socket's
//! cosine are in it), stretched by the machine's expansion 1 + α (T_m − T0) as the laser's
//! readings are, through its own scale error (drawn once from N(0, `scale_u_ppm`)), plus the
//! residue of its thermal compensation (a random walk per segment) and white noise.

use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use super::{basis, diagonal, Machine, VolumetricSimConfig};
use dbbcal_core::volumetric_campaign::{BarReading, DiagonalSign};

/// What the bar did (`truth.json` → `volumetric.bar`).
#[derive(Debug, Clone, Serialize)]
pub struct BarTruth {
    /// The bar's id.
    pub id: String,
    /// Its true scale error, ppm (drawn within its calibration's u).
    pub scale_error_ppm: f64,
    /// The calibration's u it was drawn from, ppm.
    pub scale_u_ppm: f64,
    /// Per diagonal read.
    pub diagonals: Vec<BarDiagonalTruth>,
}

/// One bar-read diagonal's truth.
#[derive(Debug, Clone, Serialize)]
pub struct BarDiagonalTruth {
    /// Its sign vector.
    pub diagonal: String,
    /// The targets, mm from P0.
    pub target_mm: Vec<f64>,
    /// The true Dr = u · [e(P) − e(P0)] at each, µm (the machine's static error, no drift).
    pub dr_um: Vec<f64>,
    /// max − min of `dr_um`, µm: the E a noise-free test would read.
    pub e_um: f64,
    /// Each segment's socket, mm.
    pub sockets_mm: Vec<[f64; 3]>,
    /// Each socket's distance from the line, mm.
    pub socket_off_line_mm: Vec<f64>,
}

/// The random streams the bar draws from (none shared with the laser's).
pub(super) struct BarStreams<R: Rng> {
    /// Sockets.
    pub(super) sockets: R,
    /// Noise and residue.
    pub(super) noise: R,
}

/// The clock and the frame every reading shares.
pub(super) struct Clock<'a> {
    /// Hours since the start.
    pub(super) hours: f64,
    /// The campaign's start, ns.
    pub(super) start_ns: i64,
    /// The machine's drift at a time, µm.
    pub(super) drift: &'a dyn Fn(f64) -> [f64; 3],
}

fn add(a: [f64; 3], b: [f64; 3], f: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + f * b[k])
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The bar's readings of diagonal `sign`, appended to `out`; its truth.
#[allow(clippy::too_many_arguments)]
pub(super) fn read_diagonal<R: Rng>(
    cfg: &VolumetricSimConfig,
    machine: &Machine,
    sign: DiagonalSign,
    scale_error: f64,
    streams: &mut BarStreams<R>,
    clock: &mut Clock<'_>,
    out: &mut Vec<BarReading>,
) -> BarDiagonalTruth {
    let b = &cfg.bar;
    let (p0, u, d_len) = diagonal(sign, machine.min, cfg.machine.max_mm);
    let [across_a, across_b] = basis(u);
    let n = b.targets;
    let step_mm = d_len / n as f64;
    let expansion = 1.0
        + cfg.machine.cte_ppm_per_k
            * 1e-6
            * (cfg.environment.material_c - cfg.campaign.reference_temperature_c);
    let noise = Normal::new(0.0, b.noise_um.max(1e-12)).expect("σ > 0");
    let dt_h = cfg.test.seconds_per_reading / 3600.0;
    let e0 = machine.error(p0);
    let dr: Vec<f64> = (0..=n)
        .map(|i| {
            let e = machine.error(add(p0, u, i as f64 * step_mm));
            (0..3).map(|k| u[k] * (e[k] - e0[k])).sum()
        })
        .collect();
    let (mut sockets, mut off_line) = (Vec::new(), Vec::new());
    let (mut segment, mut first) = (1i64, 0usize);
    loop {
        let last = (first + b.segment_intervals).min(n);
        let along = streams
            .sockets
            .gen_range(-b.socket_along_mm..=b.socket_along_mm);
        let h = streams.sockets.gen_range(0.0..=b.socket_across_mm);
        let phi = streams.sockets.gen_range(0.0..std::f64::consts::TAU);
        let lateral = add(across_a.map(|v| v * h * phi.cos()), across_b, h * phi.sin());
        let socket = add(
            add(p0, u, first as f64 * step_mm - b.length_mm + along),
            lateral,
            1.0,
        );
        sockets.push(socket);
        off_line.push(h);
        let mut residue_um = 0.0;
        for run in 1..=b.runs {
            for direction in [1i8, -1] {
                for k in 0..=(last - first) {
                    let i = if direction > 0 { first + k } else { last - k };
                    let d = i as f64 * step_mm;
                    let p = add(p0, u, d);
                    let e = add(machine.error(p), (clock.drift)(clock.hours), 1.0);
                    let tool = add(p, e, 1e-3);
                    let true_mm = norm(add(tool, socket, -1.0)) * expansion;
                    let read_mm = true_mm * (1.0 + scale_error)
                        + 1e-3 * (residue_um + noise.sample(&mut streams.noise));
                    residue_um += streams
                        .noise
                        .gen_range(-b.residue_step_um..=b.residue_step_um);
                    out.push(BarReading {
                        time_ns: clock.start_ns + (clock.hours * 3.6e12) as i64,
                        diagonal: sign,
                        segment,
                        run: run as i64,
                        direction,
                        distance_along_mm: d,
                        centre_distance_mm: read_mm,
                        u_um: b.stated_u_um(),
                    });
                    clock.hours += dt_h;
                }
            }
        }
        clock.hours += b.reseat_s / 3600.0;
        if last == n {
            break;
        }
        first = last - b.overlap_intervals;
        segment += 1;
    }
    let e_um = dr.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - dr.iter().copied().fold(f64::INFINITY, f64::min);
    BarDiagonalTruth {
        diagonal: sign.as_str().to_string(),
        target_mm: (0..=n).map(|i| i as f64 * step_mm).collect(),
        dr_um: dr,
        e_um,
        sockets_mm: sockets,
        socket_off_line_mm: off_line,
    }
}
