#!/usr/bin/env python3
"""Convert the machine-tool thermal-drift log (../shared/external/fl-thermal-machine-tool/data.csv)
into a campaign directory, as tests/e2e/machine_tool.rs does for the suite (issue 26's "the
machine-tool log <= 10 s" is timed on it by bench/loop.sh):

  - the five displacement channels ch1..ch5 (um) are bars (1 nm counts, fixed_length_mm 200,
    air sensor t1), each mounted on one plate length "spindle" (300 mm) for the whole log;
  - t1 is the air sensor, t2..t16 sensors of kind "other";
  - each change of spindle speed is a setup-wide event of kind "spindle" (value = rpm);
  - the log starts at 1 700 000 000 s after the epoch; reference temperature 26 C.

    python3 bench/machine_tool_campaign.py OUT [--csv PATH]
"""

import argparse
import os
import shutil
from datetime import datetime, timezone

import polars as pl

HERE = os.path.dirname(os.path.abspath(__file__))
START_S = 1_700_000_000
RESOLUTION_NM = 1.0


def iso(seconds):
    return datetime.fromtimestamp(int(seconds), tz=timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--csv", default=os.path.join(HERE, "..", "..", "shared", "external", "fl-thermal-machine-tool", "data.csv"))
    args = ap.parse_args()
    df = pl.read_csv(args.csv)
    time = (pl.lit(START_S * 1_000_000_000, dtype=pl.Int64) + (pl.col("time_s") * 1e9).cast(pl.Int64)).cast(pl.Datetime("ns", "UTC")).alias("time")
    bars = [f"ch{k}" for k in range(1, 6)]
    sensors = [f"t{k}" for k in range(1, 17)]
    if os.path.exists(args.out):
        shutil.rmtree(args.out)
    for sub in ("encoders", "temperatures", "events"):
        os.makedirs(os.path.join(args.out, sub))
    enc = pl.concat([
        df.select(time, pl.lit(b).alias("bar"), (pl.col(f"{b}_um") * 1000.0 / RESOLUTION_NM).round().cast(pl.Int64).alias("counts"))
        for b in bars
    ])
    enc.write_parquet(os.path.join(args.out, "encoders", "encoders.parquet"))
    tmp = pl.concat([df.select(time, pl.lit(s).alias("sensor"), pl.col(f"{s}_C").alias("celsius")) for s in sensors])
    tmp.write_parquet(os.path.join(args.out, "temperatures", "temperatures.parquet"))
    rpm = df.select(time, pl.col("spindle_rpm").cast(pl.Float64).alias("value"))
    changes = rpm.filter(pl.col("value") != pl.col("value").shift(1).fill_null(float("nan")))
    ev = changes.select("time", pl.lit(None, dtype=pl.String).alias("bar"), pl.lit("spindle").alias("kind"), "value")
    ev.write_parquet(os.path.join(args.out, "events", "events.parquet"))
    end = START_S + float(df["time_s"].max()) + 1.0
    lines = [
        "[campaign]", 'id = "fl-thermal-machine-tool"', "reference_temperature_c = 26.0", "",
        "[plate]", 'material = "machine"', "cte_ppm_per_k = 0.0", "tilt_deg = 0.0", "",
        "[[plate.length]]", 'id = "spindle"', "mm = 300.0", "u_um = 1.0",
    ]
    for s in sensors:
        lines += ["", "[[sensor]]", f'id = "{s}"', f'kind = "{"air" if s == "t1" else "other"}"']
    for b in bars:
        lines += ["", "[[bar]]", f'id = "{b}"', f"resolution_nm = {RESOLUTION_NM}", "fixed_length_mm = 200.0", 'sensor = "t1"']
    for b in bars:
        lines += ["", "[[mount]]", f'bar = "{b}"', 'length = "spindle"', f"from = {iso(START_S)}", f"to = {iso(end)}"]
    with open(os.path.join(args.out, "campaign.toml"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"{args.out}: {enc.height} encoder rows, {tmp.height} temperature rows, {ev.height} spindle events")


if __name__ == "__main__":
    main()
