#!/usr/bin/env python3
"""The diagnosis loop done plainly in Python: the peer of issue 13's "dbbcal >= 20x faster".

What a competent metrologist would write with polars + numpy + scipy to answer "which effect is
my model missing?" on a campaign (``../shared/spec/physics.md``, ``campaign-format.md``), with no
clever tricks (no score tests, no screening, no compression, one process) and no gratuitous waste
(the mount zeros projected out, the last lag columns remembered):

1. **read** ``campaign.toml`` and ``encoders/`` / ``temperatures/`` / ``events/*.parquet`` with
   polars, as ``bench/python_equivalent.py`` does (its reading and lag code are imported);
2. **series**: per bar, every sensor linearly interpolated onto the encoder times
   (``numpy.interp``), air = the bar's own sensor (else the mean of the air sensors), readings in
   µm centred on each zero segment (a mount, split again at ``rezero`` events), readings outside
   calibration / reference mounts on plate lengths dropped from the fit while the lags run over
   the bar's whole timeline; where the encoder log has a gap (more than 3 median steps: a head
   switched off, no rows), the sensors' reading times inside it join the timeline as unfitted
   points, so the air is not taken as a straight line across the gap (without them the
   head-heating campaign stopped at 0.0208 µm instead of the 0.020 noise);
3. **base fit** per bar: ``-(alpha I_min lag(T - T0; tau_R) + beta I_p lag(T - T0; tau_S))
   + g_R I_min d(tau_R) + g_S I_p d(tau_S) + zero``, ``d(tau)`` the decay of each base path's
   initial departure from steady state (``exp(-(t - t_ref)/tau)``, 1 before ``t_ref``, the first
   fitted sample; dbbcal's ``initial_fixed_ppm``/``initial_scale_ppm``)
   by variable projection: ``scipy.optimize.least_squares`` (trf, finite-difference Jacobian)
   over ``ln tau`` within [60 s, 30 days], and at every trial the linear parameters by
   ``numpy.linalg.lstsq``. The zeros are projected out (each column and the readings demeaned
   within each zero segment, Frisch-Waugh-Lovell: the same estimates and residuals as a one-hot
   design, ``--dense`` uses the one-hot design instead);
4. **candidate ranking**: for each candidate, base + candidate refitted on every bar, from two
   starts (the base's fitted time constants, and the defaults), the better kept; a new time
   constant starts at the best of a 7-point grid from 2 min to 2 days with the others held. Per bar ``ΔBIC = n ln(RSS1/RSS0) + Δk ln n`` (Gaussian,
   k counts gains, time constants and zeros) and ``LR = n ln(RSS0/RSS1)``; fleet-wide the sums,
   the p-value ``chi2.sf(ΣLR, ΣΔk)`` (white-noise likelihood), ΔRMS of the fleet RMS
   (root mean square of the bars' RMS, as dbbcal), bars with a significant own test;
5. **forward selection**, fleet-wide and greedy: add the candidate with the most negative fleet
   ΔBIC if it is significant (``p < 5 % / number of candidates``, Bonferroni, and ΔBIC < 0), then
   refit every remaining candidate on every bar on top of it, up to ``--max-steps`` (3) steps.
   The first step reuses the ranking of 4.

Candidates (as dbbcal's ``crates/core/src/model/mod.rs`` and ``channels.rs``, roughly):

- ``second_path``: ``-alpha2 I_min lag(T - T0; tau_2)`` (start 3 h);
- ``air_gradient``: ``dT_grad`` = mean of the other air sensors - the bar's own sensor;
  ``-(g_R I_min lag(dT_grad; tau_R) + g_S I_p lag(dT_grad; tau_S))``, two gains, the base taus
  (only for bars with their own ``sensor`` and a campaign with >= 2 air sensors);
- ``settling``: ``exp(-(t - mount start)/tau)`` within each zero segment, one amplitude per
  segment, one shared tau (start 1 h);
- ``creep``: ``t / 1 day``, one gain (µm/day), no tau;
- ``head_heating`` (if the campaign has ``head_power`` events): ``-h lag(P; tau_head)`` of the
  held power P (start 15 min). The switches are integrated at their own times (the sample grid
  is merged with the switch times, zero-order hold between them, so a switch between two
  readings is exact). Before a bar's first event the power is the other state (issue 13's rule:
  an event marks a change; a head that logs is powered), and the lag starts in steady state;
- ``plate_expansion`` (if a sensor has kind ``plate``): ``+cte L (T_plate - T0)`` on plate
  mounts, the plate sensor smoothed forward and backward with a 300-s lag, no tau;
- ``lag:CH`` for every temperature sensor CH and every difference ``CH2-CH1`` of two sensors:
  ``g lag(CH; tau)`` (start 30 min), raw °C, no scale. ``--extra-channels`` adds
  ``lag:time_since_mount_h``, ``lag:time_of_day_h``, ``lag:length_mm`` and ``lag:event:KIND``
  for every event kind (held steps when the events carry values, unit impulses otherwise).

Simplifications against dbbcal (it is a peer, not a reimplementation):

- the likelihood-ratio test takes the residuals as white (Gaussian, ``n ln RSS``), not dbbcal's
  per-residual AR(1)-plus-white-noise model; the fleet test sums the bars' LR statistics and
  their degrees of freedom (dbbcal combines the bars' p-values by Fisher's method);
- every candidate is offered (dbbcal offers the catalogue plus the 10 channels that explain the
  most residual variance in a linearised screening); no channel screening, no beam (greedy,
  dbbcal's ``beam = 1``), no per-bar forward selection, no refusal of unidentifiable pairs
  (correlation > 0.9999); dbbcal's tie rule is kept (a named effect before a ``lag:`` term
  within ΔBIC 2);
- candidate fits start from the current model and from the defaults (``--starts``), a new time
  constant from a 7-point grid, then least squares with a finite-difference Jacobian (dbbcal:
  Brent on a 300-s coarse copy, then Levenberg-Marquardt with analytic ``ln tau`` derivatives);
- no uncertainties (HAC, profiles), no figures, no JSON contract: timings and the ledger only;
- the head_power state before the first event follows issue 13 (the other state), which dbbcal
  at the time of writing does not (it takes "off").

Usage (from the repository root)::

    python3 bench/python_loop.py CAMPAIGN [--bars N] [--max-steps 3] [--extra-channels]
                                 [--starts both|warm|cold] [--dense] [--json OUT] [--quiet]

``--bars N`` fits only the first N bars of the manifest and prints, beside the measured times, an
extrapolation to all bars (read as measured; the per-bar stages scaled by bars/N).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time

# One BLAS thread unless the environment says otherwise: on the 2 shared cores of the benchmark VM,
# OpenBLAS's threads made a 128 000 x 18 lstsq 5-10x slower (they spin against each other and
# against everything else running).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import polars as pl  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402
from scipy.signal import lfilter  # noqa: E402
from scipy.stats import chi2  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from python_equivalent import constant_step_runs, lag, read_manifest, scan, to_ns  # noqa: E402

LN_TAU_LO, LN_TAU_HI = np.log(60.0), np.log(30 * 86400.0)  # dbbcal's search interval
TAU0 = {"tau_r": 1800.0, "tau_s": 3600.0, "second_path": 10800.0, "settling": 3600.0, "head_heating": 900.0}
TAU0_CHANNEL = 1800.0
START_GRID_S = np.geomspace(120.0, 2 * 86400.0, 7)  # starting grid of a candidate's new time constant
PLATE_SMOOTHING_S = 300.0
ALPHA = 0.05
GAIN_NAMES = {
    "fixed_part": ["alpha_ppm_per_k", "initial_fixed_ppm"],
    "scale": ["beta_ppm_per_k", "initial_scale_ppm"],
    "second_path": ["alpha2_ppm_per_k"],
    "air_gradient": ["gradient_fixed_ppm_per_k", "gradient_scale_ppm_per_k"],
    "creep": ["creep_um_per_day"],
    "head_heating": ["head_growth_um"],
    "plate_expansion": ["plate_cte_ppm_per_k"],
}
LSQ = dict(method="trf", ftol=1e-10, xtol=1e-10, gtol=1e-10)


# ----------------------------------------------------------------------------- lags


def recurse(a: np.ndarray, b: np.ndarray, x0: float, runs) -> np.ndarray:
    """x_0 = x0, x_k = a_k x_{k-1} + b_k (a, b of length n-1), one lfilter call per run of equal a."""
    x = np.empty(b.size + 1)
    x[0] = x0
    for s, e in runs:
        x[s + 1 : e + 1] = lfilter([1.0], [1.0, -a[s]], b[s:e], zi=[a[s] * x[s]])[0]
    return x


def held_lag(t_ns: np.ndarray, switch_ns: np.ndarray, values: np.ndarray, before: float, tau: float) -> np.ndarray:
    """Lag of a piecewise-constant input (``before`` until ``switch_ns[0]``, then ``values[j]`` from
    ``switch_ns[j]``), exact: the sample grid is merged with the switch times (zero-order hold on
    each merged interval). Starts in steady state at ``before``. Sampled at ``t_ns``."""
    grid = np.union1d(t_ns, switch_ns)
    idx = np.searchsorted(switch_ns, grid, side="right") - 1
    u = np.where(idx >= 0, values[np.maximum(idx, 0)], before)
    dt = np.diff(grid)
    a = np.exp(-dt * (1e-9 / tau))
    x = recurse(a, (1.0 - a) * u[:-1], before, constant_step_runs(dt))
    return x[np.searchsorted(grid, t_ns)]


def impulse_lag(t_ns: np.ndarray, event_ns: np.ndarray, tau: float) -> np.ndarray:
    """Sum of unit responses exp(-(t - e)/tau) of the impulses at ``event_ns``, sampled at ``t_ns``."""
    grid = np.union1d(t_ns, event_ns)
    kick = np.zeros(grid.size)
    np.add.at(kick, np.searchsorted(grid, event_ns), 1.0)
    dt = np.diff(grid)
    a = np.exp(-dt * (1e-9 / tau))
    x = recurse(a, kick[1:], kick[0], constant_step_runs(dt))
    return x[np.searchsorted(grid, t_ns)]


# ----------------------------------------------------------------------------- one bar


class Bar:
    """One bar's series (dbbcal's BarSeries, roughly) and a small memo of lag columns."""

    def __init__(self, man, bar, t_ns, counts, sensor_logs, events, mounts, t0_ns, extra_channels):
        self.id = bar["id"]
        self.T0 = man["campaign"]["reference_temperature_c"]
        lengths = {l["id"]: l["mm"] for l in man["plate"]["length"]}
        kinds = {s["id"]: s.get("kind", "other") for s in man.get("sensor", [])}
        air_ids = [s for s, k in kinds.items() if k == "air" and s in sensor_logs]
        plate_ids = [s for s, k in kinds.items() if k == "plate" and s in sensor_logs]
        self.i_min_mm = bar["fixed_length_mm"]
        # The lags run on the encoder times; where the encoder log has a gap (a head switched off,
        # a logger restart), the sensors' own reading times inside it are added as unfitted points,
        # so the air is not taken as a straight line across hours it was not.
        n_read = t_ns.size
        step = np.diff(t_ns)
        gaps = np.flatnonzero(step > 3 * np.median(step)) if step.size else np.array([], dtype=np.int64)
        extra = np.array([], dtype=np.int64)
        if gaps.size:
            s_t = np.unique(np.concatenate([lt for lt, _ in sensor_logs.values()]))
            i = np.searchsorted(t_ns, s_t)
            inside = (i > 0) & (i < n_read)
            i_c = np.clip(i, 1, max(n_read - 1, 1))
            inside &= np.isin(i_c - 1, gaps) & (s_t > t_ns[i_c - 1]) & (s_t < t_ns[i_c])
            extra = s_t[inside]
        order = np.argsort(np.concatenate([t_ns, extra]), kind="stable")
        is_reading = order < n_read
        t_ns = np.concatenate([t_ns, extra])[order]
        self.n_gap_points = int(extra.size)
        self.t_ns = t_ns - t0_ns
        self.t_s = self.t_ns * 1e-9
        self.dt_ns = np.diff(self.t_ns)
        self.runs = constant_step_runs(self.dt_ns)
        tf = self.t_ns.astype(np.float64)
        self.celsius = {s: np.interp(tf, (lt - t0_ns).astype(np.float64), lc) for s, (lt, lc) in sensor_logs.items()}
        own = bar.get("sensor")
        self.air = self.celsius[own] if own in self.celsius else np.mean([self.celsius[s] for s in air_ids], axis=0)

        # mounts, zero segments, what is fitted
        mount_of = np.full(t_ns.size, -1)
        self.mount_from_s = np.array([(m["from_ns"] - t0_ns) * 1e-9 for m in mounts] + [0.0])
        for k, m in enumerate(mounts):
            lo, hi = np.searchsorted(self.t_ns, [m["from_ns"] - t0_ns, m["to_ns"] - t0_ns], side="left")
            mount_of[lo:hi] = k
        self.mount_of = mount_of
        length_mm = np.array([lengths[m["length"]] if "length" in m else np.nan for m in mounts] + [np.nan])
        fitted_mount = np.array([("length" in m) and m.get("purpose", "calibration") != "check" for m in mounts] + [False])
        rezero = np.sort(np.asarray([e[0] for e in events if e[1] == "rezero"], dtype=np.int64)) - t0_ns
        passed = np.searchsorted(rezero, self.t_ns, side="right")
        seg_full = np.where(mount_of >= 0, mount_of.astype(np.int64) * (rezero.size + 1) + passed, -1)
        self.length_mm = np.nan_to_num(length_mm[mount_of], nan=0.0)
        self.i_p_mm = np.where(mount_of >= 0, self.length_mm - self.i_min_mm, 0.0)
        self.i_p_mm[~np.isfinite(length_mm[mount_of])] = 0.0  # device mounts
        self.fit = np.flatnonzero(fitted_mount[mount_of] & is_reading)
        _, self.segment = np.unique(seg_full[self.fit], return_inverse=True)
        self.n_seg = int(self.segment.max()) + 1 if self.segment.size else 0
        self.seg_counts = np.bincount(self.segment, minlength=self.n_seg).astype(np.float64)
        # fitted rows are in time order and segments are time intervals: each segment is one block
        assert np.all(np.diff(self.segment) >= 0)
        self.seg_starts = np.concatenate(([0], np.flatnonzero(np.diff(self.segment)) + 1))

        y = np.zeros(t_ns.size)
        y[is_reading] = counts.astype(np.float64) * (bar["resolution_nm"] * 1e-3)
        cte = man["plate"].get("cte_ppm_per_k", 0.0)
        self.plate = None
        if plate_ids:
            self.plate = self.zero_phase(self.celsius[plate_ids[0]]) - self.T0
            if cte != 0.0:
                y = y - cte * self.length_mm * 1e-3 * self.plate
        self.y = y[self.fit]
        for k in range(self.n_seg):  # centre on the median (rounding: raw readings are ~1e5 µm)
            s = slice(self.seg_starts[k], self.seg_starts[k + 1] if k + 1 < self.n_seg else self.y.size)
            self.y[s] -= np.median(self.y[s])
        self.n = int(self.y.size)
        self.y_proj = self.project(self.y[:, None])[:, 0]

        # events: (time ns, kind, value) for this bar or the whole setup
        self.events = {}
        for t, kind, value in events:
            self.events.setdefault(kind, []).append((t - t0_ns, value))

        self.channels = {s: v for s, v in self.celsius.items()}
        ids = sorted(self.celsius)
        for i, a in enumerate(ids):
            for b in ids[i + 1 :]:
                self.channels[f"{b}-{a}"] = self.celsius[b] - self.celsius[a]
        if extra_channels:
            since = np.where(mount_of >= 0, (self.t_s - self.mount_from_s[mount_of]) / 3600.0, 0.0)
            self.channels["time_since_mount_h"] = since
            self.channels["time_of_day_h"] = np.mod((t0_ns * 1e-9 + self.t_s) / 3600.0, 24.0)
            self.channels["length_mm"] = self.i_p_mm
        self.memo = {}

    # --- helpers

    def zero_phase(self, u):
        fwd = lag(self.dt_ns, u, PLATE_SMOOTHING_S, self.runs)
        back = lag(self.dt_ns[::-1].copy(), fwd[::-1].copy(), PLATE_SMOOTHING_S, constant_step_runs(self.dt_ns[::-1]))
        return back[::-1]

    def project(self, X):
        """Demean the columns of X (fitted rows) within each zero segment (the zeros projected out)."""
        means = np.add.reduceat(X, self.seg_starts, axis=0) / self.seg_counts[:, None]
        return X - means[self.segment]

    def lagged(self, key, tau):
        """Lag (whole timeline) of input ``key``, remembered by (key, tau): a finite-difference
        Jacobian moves one time constant at a time, the other columns are repeats."""
        k = (key, float(tau))
        hit = self.memo.get(k)
        if hit is not None:
            return hit
        if key == "air":
            x = lag(self.dt_ns, self.air - self.T0, tau, self.runs)
        elif key == "gradient":
            x = lag(self.dt_ns, self.gradient(), tau, self.runs)
        elif key.startswith("event:"):
            x = self.event_lag(key[6:], tau)
        else:
            x = lag(self.dt_ns, self.channels[key], tau, self.runs)
        if len(self.memo) >= 12:
            self.memo.pop(next(iter(self.memo)))
        self.memo[k] = x
        return x

    def gradient(self):
        g = getattr(self, "_gradient", None)
        if g is None:
            g = self._gradient = np.mean([self.celsius[s] for s in self.others], axis=0) - self.celsius[self.own]
        return g

    def event_lag(self, kind, tau):
        ev = sorted(self.events[kind], key=lambda e: e[0])
        t = np.array([e[0] for e in ev], dtype=np.int64)
        vals = [e[1] for e in ev]
        if all(v is None for v in vals):
            return impulse_lag(self.t_ns, t, tau)
        held, v = [], None
        for x in vals:  # a valueless event of a valued kind keeps the value it finds
            v = x if x is not None else v
            held.append(v)
        first = next(x for x in held if x is not None)
        held = np.array([first if x is None else x for x in held])
        before = 1.0 - held[0] if kind == "head_power" and held[0] in (0.0, 1.0) else held[0]
        return held_lag(self.t_ns, t, held, before, tau)


# ----------------------------------------------------------------------------- models


def effect_spec(effect: str, bar: Bar, man) -> dict | None:
    """Columns of one effect on one bar: list of (input key or callable, scale, tau name or None),
    own tau name (or None). None when the bar's campaign cannot support the effect."""
    mi = -bar.i_min_mm * 1e-3
    mp = -bar.i_p_mm * 1e-3
    if effect == "fixed_part":
        return {"cols": [("air", mi, "tau_r"), ("initial", mi, "tau_r")], "tau": "tau_r", "tau0": TAU0["tau_r"]}
    if effect == "scale":
        return {"cols": [("air", mp, "tau_s"), ("initial", mp, "tau_s")], "tau": "tau_s", "tau0": TAU0["tau_s"]}
    if effect == "second_path":
        return {"cols": [("air", mi, "second_path")], "tau": "second_path", "tau0": TAU0["second_path"]}
    if effect == "air_gradient":
        kinds = {s["id"]: s.get("kind", "other") for s in man.get("sensor", [])}
        own = next(b.get("sensor") for b in man["bar"] if b["id"] == bar.id)
        others = [s for s, k in kinds.items() if k == "air" and s != own and s in bar.celsius]
        if own not in bar.celsius or not others:
            return None
        bar.own, bar.others = own, others
        return {"cols": [("gradient", mi, "tau_r"), ("gradient", mp, "tau_s")], "tau": None}
    if effect == "settling":
        return {"cols": [("settling", None, "settling")], "tau": "settling", "tau0": TAU0["settling"]}
    if effect == "creep":
        return {"cols": [("creep", None, None)], "tau": None}
    if effect == "head_heating":
        if "head_power" not in bar.events:
            return None
        return {"cols": [("event:head_power", -1.0, "head_heating")], "tau": "head_heating", "tau0": TAU0["head_heating"]}
    if effect == "plate_expansion":
        if bar.plate is None:
            return None
        return {"cols": [("plate", None, None)], "tau": None}
    if effect.startswith("lag:"):
        ch = effect[4:]
        if ch.startswith("event:"):
            if ch[6:] not in bar.events:
                return None
        elif ch not in bar.channels:
            return None
        return {"cols": [(ch, None, effect)], "tau": effect, "tau0": TAU0_CHANNEL}
    raise ValueError(f"unknown effect {effect}")


class Model:
    """One bar's model (a list of effects) for variable projection."""

    def __init__(self, bar: Bar, effects: list[str], man, dense=False):
        self.bar, self.effects, self.dense = bar, effects, dense
        self.specs = []
        for e in effects:
            s = effect_spec(e, bar, man)
            if s is None:
                raise LookupError(f"{e}: not supported by this campaign/bar")
            self.specs.append(s)
        self.tau_names = [s["tau"] for s in self.specs if s["tau"] is not None]
        self.tau0 = [s["tau0"] for s in self.specs if s["tau"] is not None]
        self.gain_names = []
        for e, s in zip(effects, self.specs):
            names = GAIN_NAMES.get(e, [f"{e.replace(':', '_')}_gain_um_per_unit"])
            if e == "settling":
                names = [f"settling_{k}_um" for k in range(bar.n_seg)]
            self.gain_names += names
        self.n_gains = len(self.gain_names)
        self.k = self.n_gains + len(self.tau_names) + bar.n_seg  # gains, time constants, zeros

    def design(self, theta):
        b = self.bar
        tau = dict(zip(self.tau_names, np.exp(theta)))
        cols = []
        for s in self.specs:
            for key, scale, tname in s["cols"]:
                if key == "settling":
                    since = np.maximum(b.t_s[b.fit] - b.mount_from_s[b.mount_of[b.fit]], 0.0)
                    e = np.exp(-since / tau[tname])
                    for k in range(b.n_seg):
                        cols.append(np.where(b.segment == k, e, 0.0))
                    continue
                if key == "initial":
                    since = np.maximum(b.t_s[b.fit] - b.t_s[b.fit[0]], 0.0)
                    e = np.exp(-since / tau[tname])
                    x = np.where(e < 1e-13, 0.0, e)
                elif key == "creep":
                    x = b.t_s[b.fit] / 86400.0
                elif key == "plate":
                    x = (b.length_mm * 1e-3 * b.plate)[b.fit]
                else:
                    x = b.lagged(key, tau[tname])[b.fit]
                cols.append(x * (scale[b.fit] if isinstance(scale, np.ndarray) else (1.0 if scale is None else scale)))
        return np.column_stack(cols)

    def solve(self, theta):
        X = self.design(theta)
        b = self.bar
        if self.dense:
            D = np.zeros((b.n, X.shape[1] + b.n_seg))
            D[:, : X.shape[1]] = X
            D[np.arange(b.n), X.shape[1] + b.segment] = 1.0
            coef = np.linalg.lstsq(D, b.y, rcond=None)[0]
            return coef, b.y - D @ coef
        Xp = b.project(X)
        coef = np.linalg.lstsq(Xp, b.y_proj, rcond=None)[0]
        return coef, b.y_proj - Xp @ coef

    def rss(self, theta):
        r = self.solve(theta)[1]
        return float(r @ r)


def tau_param(name: str) -> str:
    """dbbcal's parameter name of a time constant."""
    fixed = {"tau_r": "tau_r_s", "tau_s": "tau_s_s", "second_path": "tau_2_s", "settling": "tau_settling_s", "head_heating": "tau_head_s"}
    return fixed.get(name, f"{name.replace(':', '_')}_tau_s")


def fit(model: Model, theta0) -> dict:
    theta0 = np.clip(np.asarray(theta0, dtype=float), LN_TAU_LO, LN_TAU_HI)
    if theta0.size:
        res = least_squares(lambda th: model.solve(th)[1], theta0, bounds=(LN_TAU_LO, LN_TAU_HI), **LSQ)
        theta, nfev = res.x, res.nfev
    else:
        theta, nfev = theta0, 0
    coef, resid = model.solve(theta)
    rss = float(resid @ resid)
    n = model.bar.n
    return {
        "effects": model.effects,
        "theta": theta,
        "taus_s": dict(zip(model.tau_names, np.exp(theta).tolist())),
        "gains": coef[: model.n_gains].tolist(),
        "params": dict(zip(model.gain_names, coef[: model.n_gains].tolist()), **{tau_param(k): float(v) for k, v in zip(model.tau_names, np.exp(theta))}),
        "rss": rss,
        "rms_um": float(np.sqrt(rss / n)),
        "n": n,
        "k": model.k,
        "bic": n * np.log(rss / n) + model.k * np.log(n),
        "nfev": nfev,
    }


def extend(bar: Bar, current: dict, effect: str, man, opts) -> dict | None:
    """Fit current model + effect on a bar. Warm start: the current model's time constants; cold
    start: every time constant at its default (the base model's 1800 s and 3600 s, ...). A new time
    constant starts at the best point of START_GRID_S with the others held. ``--starts both``
    (default) fits from both and keeps the lower RSS: a base model distorted by the missing effect
    can hold the warm start in a wrong basin (plate expansion: tau_S at 30 days, RMS 50 % above the
    cold start's)."""
    try:
        model = Model(bar, current["effects"] + [effect], man, opts.dense)
    except LookupError:
        return None
    warm = list(current["theta"])
    cold = list(np.log(model.tau0[: len(warm)]))
    starts = {"warm": [warm], "cold": [cold], "both": [warm] + ([cold] if not np.allclose(cold, warm) else [])}[opts.starts]
    best = None
    for theta0 in starts:
        if len(model.tau_names) > len(theta0):
            grid = np.log(START_GRID_S)
            theta0 = theta0 + [min(grid, key=lambda g: model.rss(np.array(theta0 + [g])))]
        f = fit(model, theta0)
        if best is None or f["rss"] < best["rss"]:
            best = f
    return best


def fleet_rms(fits) -> float:
    return float(np.sqrt(np.mean([f["rms_um"] ** 2 for f in fits])))


def rank(bars, currents, candidates, man, opts, log) -> list[dict]:
    """Every candidate refitted on every bar on top of ``currents``; ranked by fleet ΔBIC. The
    Bonferroni threshold divides 5 % by the number of candidates the campaign supports."""
    out = []
    for c in candidates:
        t = time.perf_counter()
        fits = [extend(bar, cur, c, man, opts) for bar, cur in zip(bars, currents)]
        per_bar = [
            (f["bic"] - cur["bic"], max(cur["n"] * np.log(cur["rss"] / f["rss"]), 0.0), f["k"] - cur["k"])
            for cur, f in zip(currents, fits)
            if f is not None
        ]
        if not per_bar:
            log(f"  {c:<28} not supported by this campaign")
            continue
        d_bic, lr, dk = (sum(v[i] for v in per_bar) for i in range(3))
        before = fleet_rms([cur for cur, f in zip(currents, fits) if f is not None])
        after = fleet_rms([f for f in fits if f is not None])
        p = float(chi2.sf(lr, dk)) if dk > 0 else 1.0
        out.append({
            "effect": c,
            "rms_before_um": before,
            "rms_after_um": after,
            "delta_rms_um": after - before,
            "delta_bic": float(d_bic),
            "lr": float(lr),
            "df": int(dk),
            "p_value": p,
            "bars_fitted": len(per_bar),
            "per_bar": per_bar,
            "seconds": time.perf_counter() - t,
            "fits": fits,
        })
        nfev = np.mean([f["nfev"] for f in fits if f is not None])
        log(f"  {c:<28} rms {before:.5f} -> {after:.5f} um  dBIC {d_bic:12.1f}  p {p:9.2e}  ({out[-1]['seconds']:.1f} s, {nfev:.0f} evals a bar)")
    threshold = ALPHA / max(len(out), 1)
    for r in out:
        r["threshold"] = threshold
        r["significant"] = bool(r["p_value"] < threshold and r["delta_bic"] < 0)
        r["bars_improved"] = sum(bool(db < 0 and chi2.sf(l, k) < threshold) for db, l, k in r.pop("per_bar"))
    out.sort(key=lambda r: r["delta_bic"])
    # dbbcal's tie rule: a named effect goes before a generic ``lag:`` term within ΔBIC 2
    # (``second_path`` and ``lag:OWN_SENSOR`` are the same model).
    for i in range(1, len(out)):
        j = i
        while j > 0 and ":" in out[j - 1]["effect"] and ":" not in out[j]["effect"] \
                and abs(out[j]["delta_bic"] - out[j - 1]["delta_bic"]) < 2.0:
            out[j - 1], out[j] = out[j], out[j - 1]
            j -= 1
    return out


def candidate_list(man, bars, extra_channels) -> list[str]:
    names = ["head_heating", "second_path", "air_gradient", "plate_expansion", "settling", "creep"]
    channels = []
    for b in bars:
        for ch in b.channels:
            if ch not in channels:
                channels.append(ch)
        if extra_channels:
            for kind in sorted(b.events):
                if f"event:{kind}" not in channels and kind != "rezero":
                    channels.append(f"event:{kind}")
    return names + [f"lag:{c}" for c in channels]


# ----------------------------------------------------------------------------- pipeline


def read(campaign, n_bars, extra_channels):
    man = read_manifest(campaign)
    enc = scan(campaign, "encoders", {"time": "time", "bar": "str", "counts": "i64"})
    tmp = scan(campaign, "temperatures", {"time": "time", "sensor": "str", "celsius": "f64"})
    ev = scan(campaign, "events", {"time": "time", "bar": "str", "kind": "str", "value": "f64"})
    t_read = time.perf_counter()
    mounts_ns = [dict(m, from_ns=to_ns(m["from"]), to_ns=to_ns(m["to"])) for m in man.get("mount", [])]
    t0_ns = min(m["from_ns"] for m in mounts_ns)
    logs = {}
    for (s,), df in tmp.partition_by("sensor", as_dict=True).items():
        df = df.sort("time")
        logs[s] = (df["time"].to_numpy(), df["celsius"].to_numpy())
    per_bar = {b: df for (b,), df in enc.partition_by("bar", as_dict=True).items()}
    del enc
    bars = []
    for bar in man["bar"][:n_bars]:
        df = per_bar.pop(bar["id"], None)
        if df is None or df.height == 0:
            print(f"{bar['id']}: no readings, skipped")
            continue
        df = df.sort(["time", "counts"])
        events = []
        if ev is not None:
            e = ev.filter(pl.col("bar").is_null() | (pl.col("bar") == bar["id"])).sort("time")
            events = list(zip(e["time"].to_list(), e["kind"].to_list(), e["value"].to_list()))
        mounts = sorted((m for m in mounts_ns if m["bar"] == bar["id"]), key=lambda m: m["from_ns"])
        bars.append(Bar(man, bar, df["time"].to_numpy(), df["counts"].to_numpy(), logs, events, mounts, t0_ns, extra_channels))
    return man, bars, t_read


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaign")
    ap.add_argument("--bars", type=int, default=0, help="only the first N bars of the manifest (0: all); times extrapolated")
    ap.add_argument("--max-steps", type=int, default=3, help="forward-selection steps (default 3)")
    ap.add_argument("--extra-channels", action="store_true", help="also lag: of time_since_mount_h, time_of_day_h, length_mm, event:KIND")
    ap.add_argument("--starts", choices=["both", "warm", "cold"], default="both",
                    help="candidate fits from the current model's taus (warm), from the defaults (cold), or both, the better kept (default)")
    ap.add_argument("--dense", action="store_true", help="one-hot zeros in the lstsq design instead of projecting them out")
    ap.add_argument("--json", help="write the ranking, ledger and timings here")
    ap.add_argument("--quiet", action="store_true", help="no per-candidate lines")
    args = ap.parse_args()
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    cpu0 = time.process_time()
    t0 = time.perf_counter()

    man, bars, t_scan = read(args.campaign, args.bars or None, args.extra_channels)
    n_all = len(man["bar"])
    timings = {"read_s": t_scan - t0, "series_s": time.perf_counter() - t_scan}
    print(f"read {sum(b.t_ns.size for b in bars)} encoder rows of {len(bars)} bars in {timings['read_s']:.2f} s, "
          f"series {timings['series_s']:.2f} s")

    # base fit
    t = time.perf_counter()
    base = []
    for b in bars:
        m = Model(b, ["fixed_part", "scale"], man, args.dense)
        f = fit(m, np.log(m.tau0))
        base.append(f)
        log(f"{b.id}: alpha {f['gains'][0]:.5f} ppm/K  beta {f['gains'][1]:.5f} ppm/K  "
            f"tau_R {f['taus_s']['tau_r']:.1f} s  tau_S {f['taus_s']['tau_s']:.1f} s  rms {f['rms_um']:.5f} um  "
            f"n {f['n']}  evals {f['nfev']}")
    timings["base_fit_s"] = time.perf_counter() - t

    # candidate ranking: base + each candidate
    candidates = candidate_list(man, bars, args.extra_channels)
    t = time.perf_counter()
    log(f"ranking {len(candidates)} candidates on the base model")
    ranking = rank(bars, base, candidates, man, args, log)
    timings["ranking_s"] = time.perf_counter() - t

    # greedy forward selection
    t = time.perf_counter()
    ledger = [{"added": "base", "effects": ["fixed_part", "scale"], "fleet_rms_um": fleet_rms(base),
               "rms_um": {b.id: f["rms_um"] for b, f in zip(bars, base)}, "delta_bic": 0.0, "p_value": None}]
    currents, ranked, remaining = base, ranking, [r["effect"] for r in ranking]
    for step in range(args.max_steps):
        if step > 0:
            log(f"step {step + 1}: {len(remaining)} candidates on {currents[0]['effects']}")
            ranked = rank(bars, currents, remaining, man, args, log)
        best = ranked[0] if ranked else None
        if best is None or not best["significant"]:
            break
        # bars where the effect cannot be fitted keep their model
        currents = [f if f is not None else cur for cur, f in zip(currents, best["fits"])]
        remaining = [r["effect"] for r in ranked[1:]]
        ledger.append({"added": best["effect"], "effects": currents[0]["effects"], "fleet_rms_um": fleet_rms(currents),
                       "rms_um": {b.id: f["rms_um"] for b, f in zip(bars, currents)},
                       "delta_bic": best["delta_bic"], "p_value": best["p_value"],
                       "params": {b.id: f["params"] for b, f in zip(bars, currents)}})
    timings["forward_selection_s"] = time.perf_counter() - t
    timings["total_s"] = time.perf_counter() - t0
    timings["cpu_s"] = time.process_time() - cpu0
    timings["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    print(f"\nranking on the base model ({len(ranking)} candidates, fleet of {len(bars)} bars; "
          f"significant: p < {ALPHA:g}/{len(ranking)} and dBIC < 0)")
    print(f"{'candidate':<28} {'rms before':>10} {'rms after':>10} {'dRMS %':>8} {'dBIC':>12} {'p':>9} {'df':>4} bars")
    for r in ranking:
        print(f"{r['effect']:<28} {r['rms_before_um']:10.5f} {r['rms_after_um']:10.5f} {100 * r['delta_rms_um'] / r['rms_before_um']:8.3f} "
              f"{r['delta_bic']:12.1f} {r['p_value']:9.2e} {r['df']:4d} {r['bars_improved']}/{r['bars_fitted']}"
              f"{'  *' if r['significant'] else ''}")
    if len(ledger) > 1:
        print(f"\nfinal model per bar ({', '.join(ledger[-1]['effects'])}; settling amplitudes left out)")
        for b, params in ledger[-1]["params"].items():
            new = {k: v for k, v in params.items() if not (k.startswith("settling_") and k.endswith("_um"))}
            print(f"  {b}: rms {ledger[-1]['rms_um'][b]:.5f}  " + "  ".join(f"{k} {v:.4g}" for k, v in new.items()))
    print("\nledger (greedy forward selection, fleet-wide)")
    for i, s in enumerate(ledger):
        p = "" if s["p_value"] is None else f"  dBIC {s['delta_bic']:.1f}  p {s['p_value']:.2e}"
        print(f"  {i}: {s['added']:<26} fleet rms {s['fleet_rms_um']:.5f} um{p}")
    if len(ledger) == 1:
        print("  no candidate significant: nothing added")
    print("\ntimings (wall, s): " + "  ".join(f"{k[:-2]} {v:.2f}" for k, v in timings.items() if k.endswith("_s") and k != "cpu_s"))
    print(f"cpu {timings['cpu_s']:.1f} s, peak RSS {timings['peak_rss_mb']:.0f} MB, load {os.getloadavg()[0]:.2f}")
    if len(bars) < n_all:
        scale = n_all / len(bars)
        per_bar = sum(timings[k] for k in ("series_s", "base_fit_s", "ranking_s", "forward_selection_s"))
        timings["extrapolated_total_s"] = timings["read_s"] + per_bar * scale
        print(f"extrapolated to {n_all} bars (read as measured, per-bar stages x {scale:.2f}): "
              f"total ~{timings['extrapolated_total_s']:.1f} s (the ledger itself may differ with all bars)")
    if args.json:
        for r in ranking:
            r.pop("fits", None)
        clean = lambda s: {k: v for k, v in s.items()}
        with open(args.json, "w") as f:
            json.dump({"campaign": man["campaign"]["id"], "bars": [b.id for b in bars], "timings": timings,
                       "ranking": ranking, "ledger": [clean(s) for s in ledger],
                       "base": [{"bar": b.id, **{k: v for k, v in f.items() if k != "theta"}} for b, f in zip(bars, base)]},
                      f, indent=2, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
