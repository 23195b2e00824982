#!/usr/bin/env python3
"""Copy a campaign keeping only some bars (same duration, same rows per bar).

bench/run.sh uses it to time ``dbbcal identify`` on a few bars of the 30-day campaign when
timing all twelve would take too long (``DBBCAL_BARS=N``): per-bar fit cost at full length is
what matters, and the result is extrapolated (and labelled so) in results.md.

The manifest is filtered as text, block by block (a block runs from one ``[header]`` line to the
next): ``[[bar]]`` and ``[[mount]]`` blocks of other bars are dropped, everything else is kept.
Encoders and events are filtered with polars (setup-wide events, bar = null, are kept);
temperatures are copied.

    python3 bench/subset_campaign.py SRC DST --bars B01,B02
"""

import argparse
import os
import re
import shutil
import sys

import polars as pl


def blocks(text: str):
    block = []
    for line in text.splitlines(keepends=True):
        if line.startswith("[") and block:
            yield "".join(block)
            block = []
        block.append(line)
    if block:
        yield "".join(block)


def block_bar(block: str, key: str):
    m = re.search(rf'^{key}\s*=\s*"([^"]*)"', block, flags=re.M)
    return m.group(1) if m else None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--bars", required=True, help="comma-separated bar ids to keep")
    args = ap.parse_args()
    keep = set(args.bars.split(","))
    if os.path.exists(args.dst):
        sys.exit(f"{args.dst} exists")
    tmp = args.dst + ".partial"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)

    out = []
    for b in blocks(open(os.path.join(args.src, "campaign.toml")).read()):
        header = b.split("\n", 1)[0].strip()
        if header == "[[bar]]" and block_bar(b, "id") not in keep:
            continue
        if header == "[[mount]]" and block_bar(b, "bar") not in keep:
            continue
        out.append(b)
    open(os.path.join(tmp, "campaign.toml"), "w").write("".join(out))

    for folder in ["encoders", "temperatures", "events"]:
        src = os.path.join(args.src, folder)
        if not os.path.isdir(src):
            continue
        os.makedirs(os.path.join(tmp, folder))
        for name in sorted(os.listdir(src)):
            if not name.endswith(".parquet"):
                continue
            if folder == "temperatures":
                shutil.copy(os.path.join(src, name), os.path.join(tmp, folder, name))
                continue
            df = pl.scan_parquet(os.path.join(src, name))
            bar = pl.col("bar").cast(pl.String)
            df = df.filter(bar.is_in(list(keep)) | (bar.is_null() if folder == "events" else pl.lit(False)))
            df.collect().write_parquet(os.path.join(tmp, folder, name))
    os.rename(tmp, args.dst)
    print(f"{args.dst}: bars {', '.join(sorted(keep))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
