#!/usr/bin/env python3
"""The decode floor in Python polars: the yardstick of `crates/io/examples/decode_floor.rs`.

Decodes a campaign's encoder files (``DIR/encoders/*.parquet``), the same three columns
``dbbcal`` reads (time, bar, counts), with nothing done to the rows, two ways, best of N each:

* ``collect``: ``pl.scan_parquet(files).select(time, bar, counts).collect()`` (polars' default
  engine: every file decoded into one frame in memory, its own thread pool);
* ``stream``: the same scan through polars' streaming engine,
  ``collect_batches(chunk_size=65536, engine="streaming")``, each batch dropped on arrival (as
  the Rust tool's ``stream`` drops its batches).

Polars' thread pool is its default (one thread a core: ``POLARS_MAX_THREADS`` to change it).

    python3 bench/decode_floor.py bench/out/campaign-full-t1-bybar [--repeat 5] [--json FILE]
"""

import argparse
import glob
import json
import os
import sys
import time

import polars as pl

COLUMNS = ("time", "bar", "counts")
BATCH_ROWS = 64 * 1024


def files_of(campaign: str) -> list[str]:
    files = sorted(glob.glob(os.path.join(campaign, "encoders", "*.parquet")))
    if not files:
        raise SystemExit(f"no encoders/*.parquet in {campaign}")
    return files


def collect(files: list[str]) -> int:
    return pl.scan_parquet(files).select(COLUMNS).collect().height


def stream(files: list[str]) -> int:
    rows = 0
    for batch in pl.scan_parquet(files).select(COLUMNS).collect_batches(chunk_size=BATCH_ROWS, engine="streaming"):
        rows += batch.height
        del batch
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaign", help="campaign directory")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each way; the best is reported (default 3)")
    ap.add_argument("--only", choices=["collect", "stream"], help="run one way only")
    ap.add_argument("--json", help="also write {collect,stream}_{best_s,runs_s}, encoder_rows here")
    args = ap.parse_args()
    files = files_of(args.campaign)
    record = {"polars": pl.__version__, "threads": pl.thread_pool_size()}
    for name, decode in (("collect", collect), ("stream", stream)):
        if args.only and name != args.only:
            continue
        runs, rows = [], 0
        for _ in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            rows = decode(files)
            runs.append(time.perf_counter() - t0)
        best = min(runs)
        shown = ", ".join(f"{r:.3f}" for r in runs)
        print(f"{name:8} {rows} rows  best of {len(runs)} {best:.3f} s  (runs: {shown})")
        record.update({f"{name}_best_s": best, f"{name}_runs_s": runs, "encoder_rows": rows})
    print(f"polars {pl.__version__}, threads {pl.thread_pool_size()}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
