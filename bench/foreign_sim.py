#!/usr/bin/env python3
"""A second, independent simulator of DBB campaigns, written from the two specs alone.

dbbcal is tested mostly on campaigns from its own simulator (crates/sim). This one shares no
code and no habits with it: it reads nothing of dbbcal, and takes its physics and format from
``shared/spec/physics.md`` and ``shared/spec/campaign-format.md`` only. It also writes what
crates/sim does not: microsecond UTC timestamps, int32 counts, dictionary-encoded bar ids, one
encoder file per bar (or per day), rows shuffled, readings that start mid-second.

Truth (physics.md, "First-order thermal model"): a bar on a socket pair of true distance D
reads D - dD, dD = alpha I_min dT_R + beta I_p dT_S [+ head growth], each dT a first-order
lag of (air - T0) started in steady state, I_p = D - I_min. The air a bar feels is:

  smooth  the room's air itself, a continuous process on a 1-s grid (daily swing, an
          air-conditioning triangle, a random walk); the sensors read it every
          --temp-s with noise, so the model sees it only through those readings;
  held    the sensor readings (noise included), each held until the next;
  linear  the sensor readings, linearly interpolated.

Head heating (--head): every head is powered before the campaign starts and switched off once a
day for 1.5-4 h; the bar grows by g * lag(power; tau_h) (g 1-2 um, tau_h 10-25 min), starting
in steady state (powered long enough). Each bar's first head_power event is therefore an "off".
--head-rows off drops the readings while the head is off (power events only tell).

--one-length mounts every bar on the same plate length (beta, tau_S then not identifiable).

--effect adds a hidden effect (repeat it for several at once: --effect settling --effect creep),
each of physics.md's catalogue written here from its one-line description there: second_path (a second thermal path on I_min, gamma 0.8-1.5 ppm/K, its own
tau 5-12 min), air_gradient (the bar's air is its sensor's plus 30-60 % of the difference to the
other sensor, on both paths), settling (each mount's reading relaxes by 0.3-0.6 um with a tau of
20-40 min after the bar is placed), creep (a slow trend of 0.05-0.15 um/day, independent of
temperature), plate_expansion (the plate, declared of zero expansion, expands by 0.5-1.0 ppm/K of
its own temperature, a 3-h lag of the room's mean air, which a plate sensor P1 logs), and one
outside the catalogue:

  heat_source  an electronics cabinet next to the plate, logged by a sensor C1 of kind "other"
          (with the air sensors, every --temp-s). It runs on working days (Mon-Fri, on at about
          08:00 and off at about 18:00 UTC, the times drawn per seed and jittered per day, a
          working day skipped now and then); its temperature is the air at T1 plus an excess
          A lag(on; tau_cab) (A 2-5 K, tau_cab 30-60 min). The excess over the air, C1 - T1,
          warms each bar's parts through a lag of its own:
              dD += a_h I_min lag(C1 - T1; tau_h) + b_h I_p lag(C1 - T1; tau_h)
          a_h, b_h 0.05-0.3 x the bar's alpha, beta; tau_h 20-90 min, shared by the fleet or
          per bar (per seed). Drawn from a random stream of its own, so that adding it changes
          no other draw. Truth: truth.json -> heat_source (cabinet) and bars[].heat_* .

    python3 bench/foreign_sim.py OUT --seed 1 [--air smooth|held|linear] [--head]
        [--effect NAME ...] [--bars 4] [--days 4] [--sample-s 10] [--temp-s 30]
        [--files bar|day] [--shuffle]

Writes OUT/campaign.toml, encoders/, temperatures/, events/ and OUT/truth.json (per bar:
alpha_ppm_per_k, beta_ppm_per_k, tau_r_s, tau_s_s, and head_growth_um, tau_head_s, and each
hidden effect's parameters). With none or one --effect every byte is what the one-effect
version wrote (same draws, same files, truth.json's args.effect a string or null).
"""

import argparse
import json
import os
import shutil
from datetime import datetime, timedelta, timezone

import numpy as np
import polars as pl

T0_C = 20.0
START = datetime(2027, 3, 1, tzinfo=timezone.utc)
LENGTHS_MM = {"min": 250.0006, "mid": 325.0011, "max": 400.0019}
RESOLUTION_NM = 5.0
NOISE_UM = 0.020
SENSOR_NOISE_K = 0.005
# The hidden effects --effect knows, in the order their random draws are made.
EFFECTS = ["second_path", "air_gradient", "settling", "creep", "plate_expansion", "heat_source"]


def lag_held(u, tau_s, h=1.0):
    """First-order lag y' = (u - y) / tau of u held over each step of h s; y(0) = u(0)."""
    a = np.exp(-h / tau_s)
    y = np.empty_like(u)
    y[0] = u[0]
    # y[k+1] = a y[k] + (1 - a) u[k], exact for a held input; unrolled in blocks by numpy.
    return _recurse(y, u[:-1] * (1.0 - a), a)


def lag_linear(u, tau_s, h=1.0):
    """First-order lag of u linearly interpolated between grid points; y(0) = u(0)."""
    a = np.exp(-h / tau_s)
    c = tau_s * (1.0 - a) / h
    y = np.empty_like(u)
    y[0] = u[0]
    # Exact for a ramp over each step: y[k+1] = a y[k] + (1 - c) u[k+1] + (c - a) u[k].
    return _recurse(y, (1.0 - c) * u[1:] + (c - a) * u[:-1], a)


def _recurse(y, drive, a):
    """y[k+1] = a y[k] + drive[k], by a closed form over blocks (no per-step Python loop)."""
    n = len(drive)
    block = 4096
    powers = a ** np.arange(1, block + 1)
    for s in range(0, n, block):
        d = drive[s : s + block]
        m = len(d)
        # y[s+j+1] = a^(j+1) y[s] + sum_{i<=j} a^(j-i) d[i]
        w = a ** -np.arange(m, dtype=float)  # a^-i; block short enough to stay finite
        acc = np.cumsum(d * w) * (a ** np.arange(m, dtype=float))
        y[s + 1 : s + m + 1] = powers[:m] * y[s] + acc
    return y


def room_air(rng, seconds, sensors, sun_k=0.2):
    """The room's air at each sensor on a 1-s grid, K above T0."""
    t = np.arange(seconds, dtype=float)
    base = 0.3 + 0.4 * np.sin(2 * np.pi * (t / 86400.0 - 0.35))
    period = rng.uniform(900, 2100)
    tri = 2.0 * np.abs((t / period) % 1.0 - 0.5) - 0.5  # triangle, +-0.5
    walk = np.cumsum(rng.normal(0, 1, seconds // 60 + 2))[np.minimum(t.astype(int) // 60, seconds // 60)]
    walk = 0.25 * walk / max(1.0, np.abs(walk).max())
    air = {}
    for k, s in enumerate(sensors):
        offset = 0.15 * k
        # The second sensor's place gets the sun in the morning: a daily difference (--sun-k).
        sun = sun_k * k * np.sin(2 * np.pi * (t / 86400.0 - 0.15))
        air[s] = base + offset + sun + rng.uniform(0.08, 0.15) * tri + walk * (1.0 + 0.3 * k)
    return air


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--air", choices=["smooth", "held", "linear"], default="smooth")
    ap.add_argument("--head", action="store_true")
    ap.add_argument("--head-rows", choices=["on", "off"], default="on", help="readings while the head is off")
    ap.add_argument("--one-length", action="store_true")
    ap.add_argument("--effect", choices=EFFECTS, action="append",
                    help="a hidden effect; repeat for several at once")
    ap.add_argument("--sun-k", type=float, default=0.2, help="daily air difference between the sensors, K")
    ap.add_argument("--bars", type=int, default=4)
    ap.add_argument("--days", type=float, default=4.0)
    ap.add_argument("--sample-s", type=float, default=10.0)
    ap.add_argument("--temp-s", type=int, default=30)
    ap.add_argument("--tau-s-range", type=float, nargs=2, default=[900.0, 2400.0],
                    metavar=("LO", "HI"), help="the stems' time constants are drawn from LO..HI s")
    ap.add_argument("--files", choices=["bar", "day"], default="bar")
    ap.add_argument("--shuffle", action="store_true")
    args = ap.parse_args()
    # Several effects: one canonical order (the draws do not depend on the order given), and
    # args.effect as before for none or one (truth.json and the campaign id keep their bytes).
    effects = [e for e in EFFECTS if e in (args.effect or [])]
    args.effect = effects if len(effects) > 1 else (effects[0] if effects else None)

    rng = np.random.default_rng(args.seed)
    seconds = int(args.days * 86400)
    sensors = ["T1", "T2"]
    air = room_air(rng, seconds + 1, sensors, args.sun_k)

    # Sensor readings every temp_s (sensors a few seconds apart), with noise.
    temp_rows = []
    reading = {}
    for k, s in enumerate(sensors):
        times = np.arange(3 * k, seconds + 1, args.temp_s)
        values = air[s][times] + rng.normal(0, SENSOR_NOISE_K, len(times))
        reading[s] = (times, values)
        temp_rows.append(pl.DataFrame({"t": times, "sensor": s, "celsius": values + T0_C}))
    plate_cte, plate_k = 0.0, None
    if "plate_expansion" in effects:
        plate_cte = rng.uniform(0.5, 1.0)
        plate_k = lag_linear(0.5 * (air["T1"] + air["T2"]), 10800.0)
        times = np.arange(7, seconds + 1, args.temp_s)
        values = plate_k[times] + rng.normal(0, 0.002, len(times))
        temp_rows.append(pl.DataFrame({"t": times, "sensor": "P1", "celsius": values + T0_C}))
    cabinet = None
    if "heat_source" in effects:
        # A stream of its own: adding the cabinet changes none of the other draws.
        rng_h = np.random.default_rng([args.seed, 26])
        cabinet = heat_source_cabinet(rng_h, seconds)
        air["C1"] = air["T1"] + cabinet.pop("excess_k")
        times = np.arange(11, seconds + 1, args.temp_s)
        values = air["C1"][times] + rng_h.normal(0, SENSOR_NOISE_K, len(times))
        reading["C1"] = (times, values)
        temp_rows.append(pl.DataFrame({"t": times, "sensor": "C1", "celsius": values + T0_C}))

    def felt(s):
        """The air the bars near sensor s respond to, on the 1-s grid (K above T0)."""
        if args.air == "smooth":
            return air[s], lag_linear
        times, values = reading[s]
        grid = np.arange(seconds + 1)
        if args.air == "held":
            idx = np.clip(np.searchsorted(times, grid, side="right") - 1, 0, None)
            return values[idx], lag_held
        return np.interp(grid, times, values), lag_linear

    bars, truth, enc_frames, events = [], {}, [], []
    for b in range(args.bars):
        bar = f"F{b + 1:02d}"
        sensor = sensors[b % 2]
        p = {
            "alpha_ppm_per_k": rng.uniform(1.5, 2.8),
            "beta_ppm_per_k": rng.uniform(0.3, 0.9),
            "tau_r_s": rng.uniform(1800, 4800),
            "tau_s_s": rng.uniform(*args.tau_s_range),
        }
        fixed_mm = rng.uniform(200, 240)
        u, lag = felt(sensor)
        if "air_gradient" in effects:
            p["gradient_share"] = rng.uniform(0.3, 0.6)
            other, _ = felt(sensors[(b + 1) % 2])
            u = u + p["gradient_share"] * (other - u)
        dT_R = lag(u, p["tau_r_s"])
        dT_S = lag(u, p["tau_s_s"])
        growth_um = np.zeros(seconds + 1)
        powered = np.ones(seconds + 1, dtype=bool)
        if args.head:
            p["head_growth_um"] = rng.uniform(1.0, 2.0)
            p["tau_head_s"] = rng.uniform(600, 1500)
            for day in range(int(np.ceil(args.days))):
                off_from = int(day * 86400 + rng.uniform(2, 20) * 3600)
                off_to = int(off_from + rng.uniform(1.5, 4.0) * 3600)
                if off_from >= seconds:
                    continue
                powered[off_from : min(off_to, seconds + 1)] = False
                events.append((off_from, bar, "head_power", 0.0))
                if off_to <= seconds:
                    events.append((off_to, bar, "head_power", 1.0))
            growth_um = p["head_growth_um"] * lag_held(powered.astype(float), p["tau_head_s"])
        truth[bar] = p

        # Mounts of about a day, 20 min of handling between them.
        lengths = ["mid"] if args.one_length else ["min", "mid", "max"]
        mounts, t = [], 600 + 400 * b
        k = b
        while t < seconds - 3 * 3600:
            end = min(seconds - 60, t + int(rng.uniform(20, 28) * 3600))
            mounts.append((t, end, lengths[k % len(lengths)]))
            k += 1
            t = end + 1200
        # Distance at each second: the mount's length, or a handling wander between mounts.
        dist = np.full(seconds + 1, np.nan)
        for a, e, name in mounts:
            dist[a:e] = LENGTHS_MM[name]
        if plate_k is not None:
            # The true distance of a plate length: mm (1 + cte (T_plate - T0)) (campaign-format.md).
            p["plate_cte_ppm_per_k"] = plate_cte
            for a, e, _ in mounts:
                dist[a:e] *= 1.0 + plate_cte * 1e-6 * plate_k[a:e]
        handling = np.isnan(dist)
        dist[handling] = 300.0 + 30.0 * np.sin(np.arange(handling.sum()) / 50.0)
        dD_um = (p["alpha_ppm_per_k"] * fixed_mm * dT_R + p["beta_ppm_per_k"] * (dist - fixed_mm) * dT_S) * 1e-3
        dD_um += growth_um
        for effect in effects:
            if effect in ("second_path", "settling", "creep"):
                dD_um += hidden_effect_um(effect, rng, p, fixed_mm, u, lag, mounts, seconds)
        if not effects:
            dD_um += hidden_effect_um(None, rng, p, fixed_mm, u, lag, mounts, seconds)
        if cabinet is not None:
            # The cabinet's excess over the air as the bar feels it (true, held or interpolated
            # readings, as --air says), through the bar's own lag, on both lengths.
            excess = felt("C1")[0] - felt("T1")[0]
            if cabinet["tau_shared_s"] is None:
                p["heat_tau_s"] = rng_h.uniform(1200, 5400)
            else:
                p["heat_tau_s"] = cabinet["tau_shared_s"]
            p["heat_fixed_ppm_per_k"] = rng_h.uniform(0.05, 0.3) * p["alpha_ppm_per_k"]
            p["heat_scale_ppm_per_k"] = rng_h.uniform(0.05, 0.3) * p["beta_ppm_per_k"]
            warm = lag(excess, p["heat_tau_s"])
            heat_um = (p["heat_fixed_ppm_per_k"] * fixed_mm + p["heat_scale_ppm_per_k"] * (dist - fixed_mm)) * warm * 1e-3
            mounted_s = ~handling
            p["heat_peak_um"] = float(np.abs(heat_um[mounted_s]).max()) if mounted_s.any() else 0.0
            dD_um += heat_um
        # Readings start mid-second and drift by a few ms against the 1-s grid.
        t_read = np.arange(0.37 * (b + 1), seconds - 1, args.sample_s) + rng.uniform(0, 0.005)
        i0 = np.floor(t_read).astype(int)
        f = t_read - i0
        dD_at = dD_um[i0] * (1 - f) + dD_um[i0 + 1] * f
        keep = np.ones(len(t_read), dtype=bool)
        if args.head and args.head_rows == "off":
            keep = powered[i0] & powered[i0 + 1]
        d_zero_mm = 180.0 + b
        indicated_mm = dist[i0] - dD_at * 1e-3 + rng.normal(0, NOISE_UM, len(t_read)) * 1e-3
        counts = np.round((indicated_mm - d_zero_mm) / (RESOLUTION_NM * 1e-6)).astype(np.int64)
        assert counts.max() < 2**31
        # The noise drawn, rounding included, over the fitted (mounted) readings: what a right
        # model leaves (each mount's mean taken out, as its zero is fitted).
        mounted = keep & ~handling[i0] & ~handling[np.minimum(i0 + 1, seconds)]
        drawn = (counts * RESOLUTION_NM * 1e-3 + d_zero_mm * 1e3) - (dist[i0] * 1e3 - dD_at)
        ss, n = 0.0, 0
        for a, e, _ in mounts:
            sel = mounted & (t_read >= a) & (t_read < e)
            if sel.any():
                ss += float(((drawn[sel] - drawn[sel].mean()) ** 2).sum())
                n += int(sel.sum())
        p["noise_drawn_um"] = (ss / max(n, 1)) ** 0.5
        p["readings_fitted"] = n
        enc_frames.append(pl.DataFrame({"t": t_read[keep], "bar": bar, "counts": counts[keep].astype(np.int32)}))
        bars.append((bar, fixed_mm, sensor, mounts))

    write(args, bars, truth, enc_frames, temp_rows, events, plate_k is not None, cabinet)


def heat_source_cabinet(rng, seconds):
    """The cabinet of --effect heat_source: its schedule and its excess over the air (K, 1-s grid).

    On working days (START is a Monday; Saturday and Sunday off) it is switched on at about
    on_h and off at about off_h (UTC hours drawn per seed, each day jittered by up to 20 min),
    and now and then a working day stays off (skip_p per seed). Its temperature rises above
    the air through its own lag: excess = amplitude lag(on; tau_cab), off and cold at the start.
    """
    c = {
        "sensor": "C1",
        "kind": "other",
        "amplitude_k": rng.uniform(2.0, 5.0),
        "tau_cabinet_s": rng.uniform(1800, 3600),
        "on_h": rng.uniform(7.0, 9.0),
        "off_h": rng.uniform(17.0, 19.0),
        "skip_p": rng.choice([0.0, 0.1, 0.2]),
        "tau_shared_s": rng.uniform(1200, 5400) if rng.random() < 0.5 else None,
    }
    on = np.zeros(seconds + 1)
    switches = []
    for day in range(int(np.ceil(seconds / 86400.0))):
        if (START.weekday() + day) % 7 >= 5 or rng.random() < c["skip_p"]:
            continue
        a = int(day * 86400 + (c["on_h"] + rng.uniform(-1, 1) / 3) * 3600)
        e = int(day * 86400 + (c["off_h"] + rng.uniform(-1, 1) / 3) * 3600)
        if a > seconds:
            continue
        on[a : min(e, seconds + 1)] = 1.0
        switches.append([a, min(e, seconds)])
    c["on_s"] = switches
    c["excess_k"] = c["amplitude_k"] * lag_held(on, c["tau_cabinet_s"])
    return c


def hidden_effect_um(effect, rng, p, fixed_mm, u, lag, mounts, seconds):
    """The growth (um, on the 1-s grid) of the hidden effect `effect`; its truth goes into p."""
    if effect == "second_path":
        p["gamma_ppm_per_k"] = rng.uniform(0.8, 1.5)
        p["tau_2_s"] = rng.uniform(300, 720)
        return p["gamma_ppm_per_k"] * fixed_mm * lag(u, p["tau_2_s"]) * 1e-3
    t = np.arange(seconds + 1, dtype=float)
    if effect == "settling":
        p["settling_um"] = rng.uniform(0.3, 0.6)
        p["tau_settling_s"] = rng.uniform(1200, 2400)
        out = np.zeros(seconds + 1)
        for a, e, _ in mounts:
            out[a:e] = p["settling_um"] * np.exp(-(t[a:e] - a) / p["tau_settling_s"])
        return out
    if effect == "creep":
        p["creep_um_per_day"] = rng.uniform(0.05, 0.15)
        return p["creep_um_per_day"] * t / 86400.0
    return np.zeros(seconds + 1)


def ts(seconds):
    """Seconds since START -> microsecond UTC timestamps."""
    return (pl.lit(START).dt.cast_time_unit("us") + pl.duration(microseconds=(seconds * 1e6).round().cast(pl.Int64))).alias("time")


def write(args, bars, truth, enc_frames, temp_rows, events, plate_sensor, cabinet=None):
    out = args.out
    if os.path.exists(out):
        shutil.rmtree(out)
    for sub in ("encoders", "temperatures", "events"):
        os.makedirs(os.path.join(out, sub))
    iso = lambda s: (START + timedelta(seconds=int(s))).strftime("%Y-%m-%dT%H:%M:%SZ")
    lines = [
        "[campaign]",
        f'id = "foreign-{args.air}{"-head" if args.head else ""}{effect_tag(args.effect)}-{args.seed}"',
        f"reference_temperature_c = {T0_C}",
        "",
        "[plate]",
        'material = "zerodur"',
        "cte_ppm_per_k = 0.0",
        "tilt_deg = 60.0",
    ]
    for name, mm in LENGTHS_MM.items():
        lines += ["", "[[plate.length]]", f'id = "{name}"', f"mm = {mm}", "u_um = 0.15"]
    for s in ("T1", "T2"):
        lines += ["", "[[sensor]]", f'id = "{s}"', 'kind = "air"']
    if plate_sensor:
        lines += ["", "[[sensor]]", 'id = "P1"', 'kind = "plate"']
    if cabinet is not None:
        lines += ["", "[[sensor]]", f'id = "{cabinet["sensor"]}"', 'kind = "other"']
    for bar, fixed_mm, sensor, _ in bars:
        lines += ["", "[[bar]]", f'id = "{bar}"', f"resolution_nm = {RESOLUTION_NM}", f"fixed_length_mm = {fixed_mm:.4f}", f'sensor = "{sensor}"']
    for bar, _, _, mounts in bars:
        for a, e, name in mounts:
            lines += ["", "[[mount]]", f'bar = "{bar}"', f'length = "{name}"', f"from = {iso(a)}", f"to = {iso(e)}"]
    with open(os.path.join(out, "campaign.toml"), "w") as fh:
        fh.write("\n".join(lines) + "\n")

    enc = pl.concat(enc_frames).with_columns(ts(pl.col("t"))).with_columns(pl.col("bar").cast(pl.Categorical))
    enc = enc.select("time", "bar", "counts")
    rng = np.random.default_rng(args.seed + 1000)
    if args.files == "bar":
        parts = enc.partition_by("bar", as_dict=True)
        named = {f"logger-{k[0]}": v for k, v in parts.items()}
    else:
        enc = enc.with_columns(pl.col("time").dt.date().alias("day"))
        named = {f"day-{k[0]}": v.drop("day") for k, v in enc.partition_by("day", as_dict=True).items()}
    for name, df in named.items():
        if args.shuffle:
            df = df.sample(fraction=1.0, shuffle=True, seed=int(rng.integers(1 << 31)))
        df.write_parquet(os.path.join(out, "encoders", f"{name}.parquet"))
    tmp = pl.concat(temp_rows).with_columns(ts(pl.col("t").cast(pl.Float64))).select("time", "sensor", "celsius")
    tmp.sort("time").write_parquet(os.path.join(out, "temperatures", "air.parquet"))
    if events:
        ev = pl.DataFrame(events, schema=["t", "bar", "kind", "value"], orient="row")
        ev = ev.with_columns(ts(pl.col("t").cast(pl.Float64))).select("time", "bar", "kind", "value")
        ev.write_parquet(os.path.join(out, "events", "power.parquet"))
    with open(os.path.join(out, "truth.json"), "w") as fh:
        doc = {"simulator": "bench/foreign_sim.py", "args": vars(args), "noise_um": NOISE_UM, "bars": truth}
        if cabinet is not None:
            doc["heat_source"] = {k: (float(v) if isinstance(v, np.floating) else v) for k, v in cabinet.items()}
        json.dump(doc, fh, indent=1)


def effect_tag(effect):
    """The campaign id's effect part: "-settling", "-settling-creep", or nothing (an id allows
    only letters, digits, '.', '_' and '-')."""
    if not effect:
        return ""
    return "-" + (effect if isinstance(effect, str) else "-".join(effect))


if __name__ == "__main__":
    main()
