#!/usr/bin/env python3
"""The straightforward Python equivalent of ``dbbcal identify`` (base model): the benchmark's yardstick.

What a scientist would write with polars + numpy + scipy, doing the same computation as dbbcal's
ingest + identify for the base model (``../shared/spec/physics.md``, ``ARCHITECTURE.md``):

1. read ``campaign.toml`` (tomllib) and ``encoders/*.parquet`` / ``temperatures/*.parquet`` /
   ``events/*.parquet`` (polars, lazily, only the spec's columns; timestamps -> int ns UTC);
2. per bar: sort by time, every sensor's log linearly interpolated onto the encoder times
   (``numpy.interp``; the nearest reading outside a sensor's log), as dbbcal does since it dropped
   the backward as-of join (a hold of half a sensor period biases the time constants);
   ``--asof`` restores the as-of join (backward, then back-filled) of earlier dbbcal versions;
   air = the bar's declared sensor, else the mean of the air sensors;
3. y = counts * resolution_nm / 1000 (µm), minus the declared plate expansion if any, centred on
   each zero segment's median (as dbbcal does; it keeps the finite-difference Jacobian clean); readings
   outside the bar's mounts on plate lengths (or on ``check`` mounts) are dropped from the fit,
   but the thermal lags run over the bar's whole timeline (handling gaps included), as in dbbcal;
4. model  y = -(alpha*I_min*lag(T-T0; tau_R) + beta*I_p*lag(T-T0; tau_S))*1e-3
             + (g_R*I_min*d(tau_R) + g_S*I_p*d(tau_S))*1e-3 + zero[segment]
   (a segment is a mount, split again at ``rezero`` events; d(tau) = exp(-(t - t_ref)/tau) for
   t > t_ref, 1 before, t_ref the first fitted sample: dbbcal's initial-state decay of each base
   path, ``initial_fixed_ppm``/``initial_scale_ppm``, since the bars are not in steady state when
   logging starts), fitted by variable projection: ``scipy.optimize.least_squares`` over
   (ln tau_R, ln tau_S), and for every trial the linear parameters (alpha, beta, g_R, g_S, one
   zero per segment) solved by ``numpy.linalg.lstsq`` on the design matrix [lag and decay
   columns | one-hot segment columns].

The lag is the exact first-order-hold discretisation of a first-order low-pass for irregular
samples (dbbcal's ``signal/lag.rs``)::

    a = exp(-dt/tau),  m = (u_k - u_{k-1}) / dt
    x_k = a x_{k-1} + u_k - a u_{k-1} - m tau (1 - a),   x_0 = u_0

**Implementation choice (honest note).** A plain Python loop over 2.6 M samples per bar and per
trial would take ~2 s per lag and dominate everything, and numba is not allowed. The recursion is
``x_k = a_k x_{k-1} + b_k``: the forcing ``b_k`` is computed vectorised with numpy, and wherever
the sampling step is constant ``a_k`` is constant, so each run of equal integer-nanosecond steps is
one ``scipy.signal.lfilter([1], [1, -a], b, zi=a*x_prev)`` call (C speed, exact same recursion).
A 1 Hz logger gives one run per bar (a few more around gaps); a jittery logger with a different
step at every sample would degrade to a Python-level loop over runs, and a scientist would then
have to resample or reach for numba -- this script would be much slower on such data.

``--project-zeros`` swaps the dense one-hot lstsq for the equivalent Frisch-Waugh-Lovell shortcut
(demean y and the two lag columns within each segment, lstsq on n x 2): same estimates, much
faster. It is NOT the default yardstick (the brief asks for the linear parameters by lstsq); it
is offered to show how much of the Python time is the dense solve. ``--bin-s S`` fits bin means
like ``dbbcal identify --bin-s S``, so a binned dbbcal run is compared with a binned Python run.

    python3 bench/python_equivalent.py CAMPAIGN [--bars B01,B02] [--json OUT] [--compare summary.json]
"""

from __future__ import annotations

import argparse
import calendar
import datetime as _dt
import glob
import json
import os
import sys
import time
import tomllib

import numpy as np
import polars as pl
from scipy.optimize import least_squares
from scipy.signal import lfilter

TAU0_R_S = 1800.0  # dbbcal's initial time constants (model/mod.rs)
TAU0_S_S = 3600.0
LN_TAU_BOUNDS = (np.log(60.0), np.log(30 * 86400.0))  # dbbcal's search interval


# ----------------------------------------------------------------------------- reading


def to_ns(value) -> int:
    """A TOML datetime (or RFC 3339 string) as int ns UTC; naive = UTC."""
    if isinstance(value, str):
        value = _dt.datetime.fromisoformat(value.replace("Z", "+00:00"))
    if value.tzinfo is not None:
        value = value.astimezone(_dt.timezone.utc)
    return calendar.timegm(value.timetuple()) * 1_000_000_000 + value.microsecond * 1_000


def read_manifest(campaign: str) -> dict:
    with open(os.path.join(campaign, "campaign.toml"), "rb") as f:
        return tomllib.load(f)


def scan(campaign: str, folder: str, columns: dict) -> pl.DataFrame | None:
    files = sorted(glob.glob(os.path.join(campaign, folder, "*.parquet")))
    if not files:
        return None
    exprs = []
    for name, kind in columns.items():
        c = pl.col(name)
        if kind == "time":
            exprs.append(c.dt.epoch("ns").alias(name))  # any unit, any zone -> ns UTC
        elif kind == "str":
            exprs.append(c.cast(pl.String).alias(name))
        elif kind == "i64":
            exprs.append(c.cast(pl.Int64).alias(name))
        else:
            exprs.append(c.cast(pl.Float64).alias(name))
    return pl.scan_parquet(files).select(exprs).collect()


# ----------------------------------------------------------------------------- model


def lag(dt_ns: np.ndarray, u: np.ndarray, tau: float, runs: list[tuple[int, int]]) -> np.ndarray:
    """First-order lag of ``u`` (first-order hold), steps ``dt_ns`` (len n-1), x_0 = u_0.

    ``runs``: (start, end) ranges of equal steps in ``dt_ns``; each is one lfilter call.
    """
    n = u.shape[0]
    x = np.empty(n)
    x[0] = u[0]
    if n == 1:
        return x
    r = dt_ns * (1e-9 / tau)
    one_minus_a = -np.expm1(-r)
    a = 1.0 - one_minus_a
    du = np.diff(u)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = u[1:] - a * u[:-1] - (du / r) * one_minus_a
    held = r <= 0.0  # duplicate timestamps: the state is held
    if held.any():
        b[held] = 0.0
        a[held] = 1.0
    for s, e in runs:
        x[s + 1 : e + 1] = lfilter([1.0], [1.0, -a[s]], b[s:e], zi=[a[s] * x[s]])[0]
    return x


def constant_step_runs(dt_ns: np.ndarray) -> list[tuple[int, int]]:
    if dt_ns.size == 0:
        return []
    starts = np.concatenate(([0], np.flatnonzero(np.diff(dt_ns) != 0) + 1))
    ends = np.concatenate((starts[1:], [dt_ns.size]))
    return list(zip(starts.tolist(), ends.tolist()))


class BarProblem:
    """One bar's data, as dbbcal's BarSeries + ThermalProblem (base model)."""

    def __init__(self, t_ns, counts, air_c, man, bar, mounts, rezero_ns, plate_c, t0_ns, bin_s=0.0):
        T0 = man["campaign"]["reference_temperature_c"]
        lengths = {l["id"]: l["mm"] for l in man["plate"]["length"]}
        self.bar = bar["id"]
        self.i_min_mm = bar["fixed_length_mm"]
        t_rel = t_ns - t0_ns

        # mount of each sample ([from, to)), zero segment = (mount, rezeros passed), -1 outside mounts
        mount_of = np.full(t_ns.size, -1)
        for k, m in enumerate(mounts):
            lo, hi = np.searchsorted(t_rel, [m["from_ns"] - t0_ns, m["to_ns"] - t0_ns], side="left")
            mount_of[lo:hi] = k
        self.dropped_outside_mounts = int((mount_of < 0).sum())
        length_mm = np.array([lengths[m["length"]] if "length" in m else np.nan for m in mounts] + [np.nan])
        fitted_mount = np.array([("length" in m) and m.get("purpose", "calibration") != "check" for m in mounts] + [False])
        passed = np.searchsorted(np.sort(np.asarray(rezero_ns, dtype=np.int64)), t_ns, side="right")
        seg_full = np.where(mount_of >= 0, mount_of.astype(np.int64) * (len(rezero_ns) + 1) + passed, -1)

        y = counts.astype(np.float64) * (bar["resolution_nm"] * 1e-3)
        cte = man["plate"].get("cte_ppm_per_k", 0.0)
        if cte != 0.0 and plate_c is not None:
            on_length = np.isfinite(length_mm[mount_of]) & (mount_of >= 0)
            y = y - np.where(on_length, cte * np.nan_to_num(length_mm[mount_of]) * 1e-3 * (plate_c - T0), 0.0)
        u = air_c - T0

        if bin_s > 0:
            # dbbcal's BarSeries::binned: means over bins of bin_s seconds that never cross a mount or
            # zero-segment boundary. Here the bins are aligned on each run's first sample
            # (floor((t - t_run) / bin_s)); dbbcal closes a bin at the first sample >= bin_s after its
            # start -- the same bins for regular sampling, except that dbbcal compares float seconds,
            # so ~0.2 % of its bins take one sample more (t[i] - t[start] = 59.999999 < 60): on the
            # sample campaign with 60-s bins that moves tau_S by up to 4e-3 relative (with dbbcal's
            # exact rule emulated, the two agree to 1e-6).
            n = t_rel.size
            change = np.flatnonzero((np.diff(mount_of) != 0) | (np.diff(seg_full) != 0)) + 1
            run_of = np.zeros(n, dtype=np.int64)
            run_of[change] = 1
            run_of = np.cumsum(run_of)
            run_start = np.concatenate(([0], change))
            k = (t_rel - t_rel[run_start][run_of]) // int(round(bin_s * 1e9))
            new_bin = np.ones(n, dtype=bool)
            new_bin[1:] = (run_of[1:] != run_of[:-1]) | (k[1:] != k[:-1])
            starts = np.flatnonzero(new_bin)
            size = np.diff(np.append(starts, n))
            t_rel = np.add.reduceat(t_rel, starts) // size  # int64 sums: exact mean times (to 1 ns)
            y = np.add.reduceat(y, starts) / size
            u = np.add.reduceat(u, starts) / size
            mount_of, seg_full = mount_of[starts], seg_full[starts]

        self.n_total = t_rel.size
        self.t_s = t_rel * 1e-9
        self.dt_ns = np.diff(t_rel)
        self.runs = constant_step_runs(self.dt_ns)
        self.u = u
        i_p_mm = np.where(mount_of >= 0, length_mm[mount_of] - self.i_min_mm, 0.0)
        self.i_p_mm = np.nan_to_num(i_p_mm, nan=0.0)  # device mounts: 0
        self.fit = np.flatnonzero(fitted_mount[mount_of])
        _, self.segment = np.unique(seg_full[self.fit], return_inverse=True)  # zero segment of each fitted row
        self.n_segments = int(self.segment.max()) + 1 if self.segment.size else 0

        # Centre each segment on its median, as dbbcal does: raw readings are ~1e5 um, and without
        # this the lstsq rounding noise swamps least_squares' finite-difference Jacobian.
        self.y = y[self.fit]
        for k in range(self.n_segments):
            in_k = self.segment == k
            self.y[in_k] -= np.median(self.y[in_k])
        self.evaluations = 0

    def decay(self, tau):
        """The initial-state column's time course: 1 up to the first fitted sample, then
        exp(-(t - t_ref)/tau), exactly 0 once below 1e-13 (as dbbcal's ``model::decay``)."""
        t = self.t_s[self.fit]
        e = np.exp(-np.maximum(t - t[0], 0.0) / tau)
        return np.where(e < 1e-13, 0.0, e)

    def columns(self, theta):
        tau_r, tau_s = np.exp(theta)
        c_r = -self.i_min_mm * 1e-3 * lag(self.dt_ns, self.u, tau_r, self.runs)
        c_s = -self.i_p_mm * 1e-3 * lag(self.dt_ns, self.u, tau_s, self.runs)
        d_r = self.i_min_mm * 1e-3 * self.decay(tau_r)
        d_s = self.i_p_mm[self.fit] * 1e-3 * self.decay(tau_s)
        return c_r[self.fit], c_s[self.fit], d_r, d_s

    def linear(self, theta, project_zeros=False):
        """(alpha, beta, zeros), residual for fixed time constants."""
        self.evaluations += 1
        cols = self.columns(theta)
        n, s, p = self.y.size, self.n_segments, len(cols)
        if not project_zeros:
            design = np.zeros((n, p + s))
            for j, c in enumerate(cols):
                design[:, j] = c
            design[np.arange(n), p + self.segment] = 1.0
            coef = np.linalg.lstsq(design, self.y, rcond=None)[0]
            return coef, self.y - design @ coef
        counts = np.bincount(self.segment, minlength=s)
        demean = lambda v: v - (np.bincount(self.segment, v, minlength=s) / counts)[self.segment]
        x = np.column_stack([demean(c) for c in cols])
        gains = np.linalg.lstsq(x, demean(self.y), rcond=None)[0]
        rest = self.y - np.column_stack(cols) @ gains
        zeros = np.bincount(self.segment, rest, minlength=s) / counts
        return np.concatenate((gains, zeros)), rest - zeros[self.segment]


def fit_bar(problem: BarProblem, project_zeros: bool) -> dict:
    theta0 = np.log([TAU0_R_S, TAU0_S_S])
    res = least_squares(
        lambda th: problem.linear(th, project_zeros)[1],
        theta0,
        bounds=LN_TAU_BOUNDS,
        method="trf",
        ftol=1e-12,
        xtol=1e-12,
        gtol=1e-12,
    )
    coef, resid = problem.linear(res.x, project_zeros)
    return {
        "bar": problem.bar,
        "alpha_ppm_per_k": float(coef[0]),
        "beta_ppm_per_k": float(coef[1]),
        "tau_r_s": float(np.exp(res.x[0])),
        "tau_s_s": float(np.exp(res.x[1])),
        "initial_fixed_ppm": float(coef[2]),
        "initial_scale_ppm": float(coef[3]),
        "zeros_um": coef[4:].tolist(),
        "rms_um": float(np.sqrt(np.mean(resid**2))),
        "n_samples": int(problem.y.size),
        "dropped_outside_mounts": problem.dropped_outside_mounts,
        "evaluations": problem.evaluations,
        "status": int(res.status),
    }


# ----------------------------------------------------------------------------- pipeline


def run(campaign: str, only_bars: list[str] | None, project_zeros: bool, asof: bool = False, bin_s: float = 0.0, log=print) -> dict:
    t_start = time.perf_counter()
    man = read_manifest(campaign)
    enc = scan(campaign, "encoders", {"time": "time", "bar": "str", "counts": "i64"})
    tmp = scan(campaign, "temperatures", {"time": "time", "sensor": "str", "celsius": "f64"})
    ev = scan(campaign, "events", {"time": "time", "bar": "str", "kind": "str"})
    mounts_ns = [dict(m, from_ns=to_ns(m["from"]), to_ns=to_ns(m["to"])) for m in man.get("mount", [])]
    t0_ns = min(m["from_ns"] for m in mounts_ns) if mounts_ns else int(enc["time"].min())
    sensors = {s["id"]: s.get("kind", "other") for s in man.get("sensor", [])}
    air_ids = [s for s, k in sensors.items() if k == "air"]
    plate_ids = [s for s, k in sensors.items() if k == "plate"]
    per_sensor = {
        s: df.sort("time").rename({"celsius": s}).drop("sensor")
        for (s,), df in tmp.partition_by("sensor", as_dict=True).items()
    }
    per_bar = {b: df for (b,), df in enc.partition_by("bar", as_dict=True).items()}
    del enc
    t_read = time.perf_counter() - t_start
    log(f"read {sum(d.height for d in per_bar.values())} encoder rows, {tmp.height} temperature rows in {t_read:.2f} s")

    results, timings = [], {}
    for bar in man["bar"]:
        b = bar["id"]
        if only_bars and b not in only_bars:
            continue
        t_bar = time.perf_counter()
        df = per_bar.pop(b, None)
        if df is None or df.height == 0:
            log(f"{b}: no readings")
            continue
        df = df.sort(["time", "counts"])
        if asof:
            for s, sdf in per_sensor.items():
                df = df.join_asof(sdf, on="time", strategy="backward").with_columns(pl.col(s).fill_null(strategy="backward"))
        else:
            t_rel = (df["time"].to_numpy() - t0_ns).astype(np.float64)
            df = df.with_columns(
                pl.Series(s, np.interp(t_rel, (sdf["time"].to_numpy() - t0_ns).astype(np.float64), sdf[s].to_numpy()))
                for s, sdf in per_sensor.items()
            )
        ids = [bar["sensor"]] if bar.get("sensor") else air_ids
        air = df.select(pl.mean_horizontal(ids)).to_series().to_numpy()
        plate = df[plate_ids[0]].to_numpy() if plate_ids else None
        rezero = []
        if ev is not None:
            rz = ev.filter((pl.col("kind") == "rezero") & (pl.col("bar").is_null() | (pl.col("bar") == b)))
            rezero = rz["time"].to_list()
        mounts = [m for m in mounts_ns if m["bar"] == b]
        mounts.sort(key=lambda m: m["from_ns"])
        problem = BarProblem(df["time"].to_numpy(), df["counts"].to_numpy(), air, man, bar, mounts, rezero, plate, t0_ns, bin_s)
        del df
        r = fit_bar(problem, project_zeros)
        r["seconds"] = time.perf_counter() - t_bar
        timings[b] = r["seconds"]
        results.append(r)
        log(
            f"{b}: alpha {r['alpha_ppm_per_k']:.5f} ppm/K  beta {r['beta_ppm_per_k']:.5f} ppm/K  "
            f"tau_R {r['tau_r_s']:.2f} s  tau_S {r['tau_s_s']:.2f} s  rms {r['rms_um']:.4f} um  "
            f"n {r['n_samples']}  evals {r['evaluations']}  {r['seconds']:.1f} s"
        )
    total = time.perf_counter() - t_start
    return {
        "campaign": man["campaign"]["id"],
        "mode": ("project-zeros" if project_zeros else "dense-lstsq") + (", as-of temperatures" if asof else "")
        + (f", {bin_s:g}-s bins" if bin_s > 0 else ""),
        "read_s": t_read,
        "total_s": total,
        "bars": results,
        "n_bars_in_campaign": len(man["bar"]),
    }


def compare(out: dict, summary_path: str, rtol: float) -> bool:
    """Relative differences against dbbcal's summary.json."""
    with open(summary_path) as f:
        summary = json.load(f)
    theirs = {b["bar"]: b for b in summary["bars"]}
    names = ["alpha_ppm_per_k", "beta_ppm_per_k", "tau_r_s", "tau_s_s"]
    worst, compared = 0.0, 0
    print(f"\ncomparison with {summary_path} (relative difference, python vs dbbcal)")
    print("bar   " + "  ".join(f"{n:>16}" for n in names) + "  rms_um(py/dbbcal)")
    for r in out["bars"]:
        t = theirs.get(r["bar"])
        if t is None:
            print(f"{r['bar']:<5} not in summary.json (skipped)")
            continue
        compared += 1
        rel = [abs(r[n] - t["params"][n]["value"]) / abs(t["params"][n]["value"]) for n in names]
        worst = max(worst, *rel)
        print(f"{r['bar']:<5} " + "  ".join(f"{v:16.2e}" for v in rel) + f"  {r['rms_um']:.5f}/{t['rms_um']:.5f}")
    ok = worst <= rtol and compared > 0
    print(f"worst relative difference {worst:.2e} over {compared} bars ({'OK' if ok else 'ABOVE'} the tolerance {rtol:g})")
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaign")
    ap.add_argument("--bars", help="comma-separated bar ids (default: all); for timing a subset")
    ap.add_argument("--project-zeros", action="store_true", help="FWL shortcut instead of the dense one-hot lstsq")
    ap.add_argument("--asof", action="store_true", help="as-of join of the temperatures (dbbcal before 2026-11-22) instead of interpolation")
    ap.add_argument("--bin-s", type=float, default=0.0, help="fit on bin means of this many seconds, as dbbcal --bin-s (default 0: every sample)")
    ap.add_argument("--json", help="write the estimates and timings here")
    ap.add_argument("--compare", metavar="SUMMARY_JSON", help="dbbcal summary.json to compare the estimates with")
    ap.add_argument("--rtol", type=float, default=1e-3, help="tolerance of --compare (default 1e-3)")
    args = ap.parse_args()
    only = args.bars.split(",") if args.bars else None
    out = run(args.campaign, only, args.project_zeros, args.asof, args.bin_s)
    print(f"total {out['total_s']:.2f} s ({len(out['bars'])} of {out['n_bars_in_campaign']} bars, read {out['read_s']:.2f} s, {out['mode']})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)
    if args.compare and not compare(out, args.compare, args.rtol):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
