#!/usr/bin/env python3
"""Bare polars scan of a campaign: the floor any ingest is measured against.

Lazily scans ``DIR/encoders/*.parquet`` (time, bar, counts) and ``DIR/temperatures/*.parquet``
(time, sensor, celsius) -- exactly the columns dbbcal reads -- and collects them into memory. No
validation, sorting, joining or type normalisation. Prints the row counts and the best of N wall
times (default 3).

    python3 bench/bare_scan.py bench/out/campaign-30d [--repeat 3] [--json FILE]
"""

import argparse
import json
import os
import sys
import time

import polars as pl


def scan(campaign: str) -> tuple[int, int]:
    enc = pl.scan_parquet(os.path.join(campaign, "encoders", "*.parquet")).select("time", "bar", "counts")
    tmp = pl.scan_parquet(os.path.join(campaign, "temperatures", "*.parquet")).select("time", "sensor", "celsius")
    enc_df, tmp_df = pl.collect_all([enc, tmp])
    return enc_df.height, tmp_df.height


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaign", help="campaign directory")
    ap.add_argument("--repeat", type=int, default=3, help="runs; the best is reported (default 3)")
    ap.add_argument("--json", help="also write {encoder_rows, temperature_rows, best_s, runs_s} here")
    args = ap.parse_args()

    runs = []
    for _ in range(max(1, args.repeat)):
        t0 = time.perf_counter()
        n_enc, n_tmp = scan(args.campaign)
        runs.append(time.perf_counter() - t0)
    best = min(runs)
    print(f"encoder rows      {n_enc}")
    print(f"temperature rows  {n_tmp}")
    print(f"best of {len(runs)}         {best:.3f} s   (runs: {', '.join(f'{r:.3f}' for r in runs)})")
    print(f"polars {pl.__version__}, threads {pl.thread_pool_size()}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"encoder_rows": n_enc, "temperature_rows": n_tmp, "best_s": best, "runs_s": runs,
                       "polars": pl.__version__}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
