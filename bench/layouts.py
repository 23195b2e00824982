#!/usr/bin/env python3
"""Rewrite a campaign into the row orders a logger of many bars leaves (issue 13, item 4).

The same rows, in day files (UTC) each holding every bar, in one of three orders:

    bybar     sorted by bar, then time, inside each file
    bytime    sorted by time, then bar: the bars interleaved, as a logger of many bars writes them
    shuffled  shuffled inside each file (seeded: the same bytes on every run)

Encoders and temperatures get the layout (temperatures: by sensor, by time, shuffled); events
and campaign.toml are copied. bench/run.sh times ``dbbcal ingest`` / ``dbbcal identify`` and
bench/bare_scan.py on each, to show that cost and memory do not depend on the row order.

    python3 bench/layouts.py SRC DST --order bybar|bytime|shuffled [--seed 13]
"""

import argparse
import os
import shutil
import sys

import numpy as np
import polars as pl

NS_PER_DAY = 86_400_000_000_000


def day_of(time: pl.Expr) -> pl.Expr:
    return time.dt.epoch("ns") // NS_PER_DAY


def rewrite(src: str, dst: str, table: str, id_col: str, order: str, seed: int) -> int:
    files = sorted(f for f in os.listdir(os.path.join(src, table)) if f.endswith(".parquet"))
    df = pl.concat([pl.read_parquet(os.path.join(src, table, f)) for f in files], how="vertical")
    os.makedirs(os.path.join(dst, table))
    df = df.with_columns(day_of(pl.col("time")).alias("__day"))
    rng = np.random.default_rng(seed)
    days = df.get_column("__day").unique().sort().to_list()
    for day in days:
        part = df.filter(pl.col("__day") == day).drop("__day")
        if order == "bybar":
            part = part.sort([id_col, "time"], maintain_order=True)
        elif order == "bytime":
            part = part.sort(["time", id_col], maintain_order=True)
        else:
            part = part.sort([id_col, "time"], maintain_order=True)
            part = part[rng.permutation(part.height)]
        name = np.datetime64(int(day) * NS_PER_DAY, "ns").astype("datetime64[D]").astype(str)
        part.write_parquet(os.path.join(dst, table, f"{name}.parquet"), compression="zstd", statistics=True)
    return df.height


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--order", required=True, choices=["bybar", "bytime", "shuffled"])
    ap.add_argument("--seed", type=int, default=13)
    args = ap.parse_args()
    if os.path.exists(args.dst):
        sys.exit(f"{args.dst} exists")
    tmp = args.dst + ".partial"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    shutil.copy(os.path.join(args.src, "campaign.toml"), tmp)
    for extra in ("truth.json",):
        if os.path.exists(os.path.join(args.src, extra)):
            shutil.copy(os.path.join(args.src, extra), tmp)
    if os.path.isdir(os.path.join(args.src, "events")):
        shutil.copytree(os.path.join(args.src, "events"), os.path.join(tmp, "events"))
    n_enc = rewrite(args.src, tmp, "encoders", "bar", args.order, args.seed)
    n_tmp = rewrite(args.src, tmp, "temperatures", "sensor", args.order, args.seed + 1)
    os.rename(tmp, args.dst)
    print(f"{args.dst}: {n_enc} encoder rows, {n_tmp} temperature rows, order {args.order}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
