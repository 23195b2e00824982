#!/usr/bin/env bash
# The dbbcal benchmark (not a test; not run in CI). From the repository root:
#
#     bench/run.sh
#
# 1. builds the release binary and crates/io/examples/decode_floor.rs (feature bench-tools);
# 2. generates the benchmark campaigns into bench/out/ if missing (sim-bench*.toml: 12 bars at
#    1 Hz for 7.5, 15 and 30 days = 7.8 / 15.6 / 31.1 M encoder rows) and the small sample one;
# 3. checks on the sample campaign that bench/python_equivalent.py and dbbcal agree (1e-3 relative);
# 4. measures wall time and peak RSS (/usr/bin/time -v) of, per campaign size:
#      dbbcal ingest, dbbcal identify (= ingest + identify), bench/bare_scan.py (best of 3),
#    crates/io/examples/decode_floor.rs (dbbcal's parquet reader decoding the encoder files and nothing
#    else: the floor under ingest, best of 3) and bench/decode_floor.py (the same in Python polars), and on the 30-day campaign bench/python_equivalent.py (dense lstsq, the yardstick) on
#    PY_BARS bars, extrapolated to all 12 -- plus the --project-zeros variant on all bars;
# 5. rewrites the 30-day campaign into the row orders a logger of many bars leaves (bench/layouts.py:
#    day files holding all bars, sorted by bar / by time with the bars interleaved / shuffled) and
#    measures the bare scan, dbbcal ingest and dbbcal identify with no option on each (issue 13:
#    cost and memory must not depend on row order);
# 6. writes bench/results.md (bench/report.py); with BIN_S=N, bench/results-binNs.md.
#
# The binary is copied to bench/out/dbbcal first, so a rebuild by someone else during the run
# cannot mix two versions; results.md records a hash of src/ and Cargo.lock.
#
# Knobs (environment):
#   SIZES="quarter half full"  campaign sizes to time (full = sim-bench.toml)
#   REPEAT=1                   dbbcal runs per measurement (the fastest is reported)
#   DBBCAL_BARS=all            bars of the 30-day campaign for `dbbcal identify`; a number N times a copy
#                              with the first N bars (bench/subset_campaign.py) and extrapolates:
#                              ingest(all 12) + (identify - ingest)(N bars) x 12/N  (labelled in results.md)
#   PY_BARS=2                  bars of the dense Python run ("all" for every bar; ~4 min a bar on 2 cores)
#   PY_FAST=1                  also run python_equivalent.py --project-zeros on all bars (0 to skip)
#   BIN_S=0                    compress into BIN_S-second bins: `dbbcal ingest/identify --bin-s BIN_S` (exact), and
#                              `python_equivalent.py --bin-s BIN_S` (bin means: close, not exact; 0: every sample);
#                              BIN_S=auto: no --bin-s (dbbcal chooses: 60 s for these 1 Hz campaigns; Python: 0)
#   LAYOUTS="bybar bytime shuffled"  row orders of the 30-day campaign to time (identify with no option); "" to skip
#   SKIP_PYTHON=1              skip the Python equivalent
#   WAIT_IDLE=1                before each measurement wait (up to 15 min) for the 1-min load < IDLE_LOAD
#   IDLE_LOAD=0.7
#   CARGO_TARGET_DIR           default $HOME/.cache/dbbcal-target
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/dbbcal-target}
SIZES=${SIZES-quarter half full}
REPEAT=${REPEAT:-1}
DBBCAL_BARS=${DBBCAL_BARS:-all}
BIN_S=${BIN_S:-0}
LAYOUTS=${LAYOUTS-bybar bytime shuffled}
PY_BARS=${PY_BARS:-2}
PY_FAST=${PY_FAST:-1}
SKIP_PYTHON=${SKIP_PYTHON:-0}
WAIT_IDLE=${WAIT_IDLE:-0}
IDLE_LOAD=${IDLE_LOAD:-0.7}
OUT=bench/out
BIN=$OUT/dbbcal
TSV=$OUT/measurements.tsv

say() { printf '\n== %s\n' "$*" >&2; }

# ------------------------------------------------------------------ tools
if [ ! -x /usr/bin/time ]; then
    say "installing GNU time"
    SUDO=$([ "$(id -u)" = 0 ] && echo "" || echo sudo)
    $SUDO apt-get install -y time >/dev/null || { $SUDO apt-get update >/dev/null && $SUDO apt-get install -y time >/dev/null; }
fi
if ! python3 -c 'import polars, scipy, numpy' 2>/dev/null; then
    say "installing polars scipy numpy"
    python3 -m pip install --quiet polars scipy numpy
fi

say "cargo build --release, and the decode floor (CARGO_TARGET_DIR=$CARGO_TARGET_DIR)"
cargo build --release --bin dbbcal
cargo build --release -p dbbcal-io --features bench-tools --example decode_floor
mkdir -p "$OUT"
cp "$CARGO_TARGET_DIR/release/dbbcal" "$BIN"
cp "$CARGO_TARGET_DIR/release/examples/decode_floor" "$OUT/decode_floor"

# ------------------------------------------------------------------ campaigns
config_of() {
    case $1 in
        full) echo bench/sim-bench.toml ;;
        half) echo bench/sim-bench-half.toml ;;
        quarter) echo bench/sim-bench-quarter.toml ;;
        sample) echo pipelines/sim-sample.toml ;;
        *) echo "unknown size $1" >&2; exit 2 ;;
    esac
}
for size in sample $SIZES ${LAYOUTS:+full}; do
    dir=$OUT/campaign-$size
    if [ ! -f "$dir/campaign.toml" ]; then
        rm -rf "$dir"
        say "generating $dir from $(config_of "$size")"
        /usr/bin/time -f "simulate $size: %e s, peak %M KB" "$BIN" simulate --config "$(config_of "$size")" --out "$dir"
    fi
done

for layout in $LAYOUTS; do
    dir=$OUT/campaign-full-$layout
    if [ ! -f "$dir/campaign.toml" ]; then
        rm -rf "$dir"
        say "rewriting $OUT/campaign-full as $dir (bench/layouts.py --order $layout)"
        python3 bench/layouts.py "$OUT/campaign-full" "$dir" --order "$layout"
    fi
done

# `--bin-s N`, or nothing for BIN_S=auto (dbbcal then chooses).
bin_flag() { [ "$1" = auto ] || printf -- '--bin-s\n%s\n' "$1"; }
mapfile -t BIN_FLAG < <(bin_flag "$BIN_S")
# The Python equivalent fits bin means (not exact); with BIN_S=auto it takes dbbcal's 60 s.
PY_BIN_S=$BIN_S
[ "$BIN_S" != auto ] || PY_BIN_S=60

# ------------------------------------------------------------------ measuring
wait_idle() {
    [ "$WAIT_IDLE" = 1 ] || return 0
    local waited=0
    while awk -v lim="$IDLE_LOAD" '{exit !($1 >= lim)}' /proc/loadavg && [ $waited -lt 900 ]; do
        [ $waited = 0 ] && echo "   waiting for the load to fall below $IDLE_LOAD ($(cut -d' ' -f1-3 /proc/loadavg))" >&2
        sleep 15
        waited=$((waited + 15))
    done
}

# measure LABEL SIZE CMD... : /usr/bin/time -v into $OUT/LABEL.time, output into $OUT/LABEL.log,
# one line into $TSV (label, size, time file, load before, load after, exit code).
measure() {
    local label=$1 size=$2
    shift 2
    wait_idle
    local before after status=0
    before=$(cut -d' ' -f1 /proc/loadavg)
    echo "   $label: $*" >&2
    /usr/bin/time -v -o "$OUT/$label.time" "$@" >"$OUT/$label.log" 2>&1 || status=$?
    after=$(cut -d' ' -f1 /proc/loadavg)
    printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$label" "$size" "$OUT/$label.time" "$before" "$after" "$status" >>"$TSV"
    echo "   -> exit $status, $(grep -E 'Elapsed|Maximum resident' "$OUT/$label.time" | sed 's/^\s*//' | tr '\n' ' ')" >&2
}

: >"$TSV"
{
    echo "nproc	$(nproc)"
    echo "cpu	$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //')"
    echo "mem	$(awk '/MemTotal/ {printf "%.1f GB", $2/1048576}' /proc/meminfo)"
    echo "kernel	$(uname -r)"
    echo "rustc	$(rustc --version)"
    echo "python	$(python3 -c 'import sys, polars, numpy, scipy; print(sys.version.split()[0], "polars", polars.__version__, "numpy", numpy.__version__, "scipy", scipy.__version__)')"
    echo "dbbcal	$("$BIN" --version), built $(date -u -r "$CARGO_TARGET_DIR/release/dbbcal" +%Y-%m-%dT%H:%M:%SZ), sha256(src/ + Cargo.lock) $(find src Cargo.lock -type f | LC_ALL=C sort | xargs cat | sha256sum | cut -c1-12)"
    echo "date	$(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "bin_s	$BIN_S"
    echo "layouts	$LAYOUTS"
} >"$OUT/machine.tsv"

say "correctness: python_equivalent.py vs dbbcal identify on the sample campaign"
"$BIN" identify --campaign "$OUT/campaign-sample" --out "$OUT/res-sample-identify" || [ $? = 2 ]
python3 bench/python_equivalent.py "$OUT/campaign-sample" --json "$OUT/py-sample.json" \
    --compare "$OUT/res-sample-identify/summary.json" | tee "$OUT/check-sample.txt" || echo "   (estimates differ: see $OUT/check-sample.txt)" >&2

for size in $SIZES; do
    camp=$OUT/campaign-$size
    say "timing $size ($camp)"
    # The bare scan first: it also warms the page cache for everyone after it.
    measure "bare-scan-$size" "$size" python3 bench/bare_scan.py "$camp" --repeat 3 --json "$OUT/bare-scan-$size.json"
    # The floor under ingest: dbbcal's own parquet reader decoding the encoder files, nothing
    # else; then Python polars decoding the same columns the same two ways.
    measure "decode-floor-$size" "$size" "$OUT/decode_floor" "$camp" --repeat 3 --json "$OUT/decode-floor-$size.json"
    measure "decode-floor-py-$size" "$size" python3 bench/decode_floor.py "$camp" --repeat 3 --json "$OUT/decode-floor-py-$size.json"
    for r in $(seq 1 "$REPEAT"); do
        measure "dbbcal-ingest-$size-$r" "$size" "$BIN" ingest --campaign "$camp" --out "$OUT/res-$size-ingest" "${BIN_FLAG[@]}"
        if [ "$size" = full ] && [ "$DBBCAL_BARS" != all ]; then
            sub=$OUT/campaign-full-${DBBCAL_BARS}bars
            if [ ! -f "$sub/campaign.toml" ]; then
                bars=$(python3 -c "import tomllib,sys; m=tomllib.load(open('$camp/campaign.toml','rb')); print(','.join(b['id'] for b in m['bar'][:int(sys.argv[1])]))" "$DBBCAL_BARS")
                python3 bench/subset_campaign.py "$camp" "$sub" --bars "$bars"
            fi
            measure "dbbcal-ingest-full-sub-$r" full-sub "$BIN" ingest --campaign "$sub" --out "$OUT/res-full-sub-ingest" "${BIN_FLAG[@]}"
            measure "dbbcal-identify-full-sub-$r" full-sub "$BIN" identify --campaign "$sub" --out "$OUT/res-full-sub-identify" "${BIN_FLAG[@]}"
        else
            measure "dbbcal-identify-$size-$r" "$size" "$BIN" identify --campaign "$camp" --out "$OUT/res-$size-identify" "${BIN_FLAG[@]}"
        fi
    done
done
# The row orders: each timed like a size (bare scan, decode floor, ingest, identify), dbbcal with no
# option (the bins it chooses), so that the three can be read against each other and their scan.
for layout in $LAYOUTS; do
    camp=$OUT/campaign-full-$layout
    size=full-$layout
    say "timing row order $layout ($camp)"
    measure "bare-scan-$size" "$size" python3 bench/bare_scan.py "$camp" --repeat 3 --json "$OUT/bare-scan-$size.json"
    measure "decode-floor-$size" "$size" "$OUT/decode_floor" "$camp" --repeat 3 --json "$OUT/decode-floor-$size.json"
    measure "decode-floor-py-$size" "$size" python3 bench/decode_floor.py "$camp" --repeat 3 --json "$OUT/decode-floor-py-$size.json"
    for r in $(seq 1 "$REPEAT"); do
        measure "dbbcal-ingest-$size-$r" "$size" "$BIN" ingest --campaign "$camp" --out "$OUT/res-$size-ingest"
        measure "dbbcal-identify-$size-$r" "$size" "$BIN" identify --campaign "$camp" --out "$OUT/res-$size-identify"
    done
done
# Same results whatever the order: summary.json but for its inputs record (file names, hashes).
if [ -n "$LAYOUTS" ]; then
    python3 - "$OUT" $LAYOUTS >"$OUT/layouts-same.txt" <<'PY'
import json, sys
out, layouts = sys.argv[1], sys.argv[2:]
def load(layout):
    s = json.load(open(f"{out}/res-full-{layout}-identify/summary.json"))
    s.pop("inputs")
    return json.dumps(s, sort_keys=True)
first = load(layouts[0])
same = [l for l in layouts[1:] if load(l) == first]
print(f"summary.json (without inputs) identical across {', '.join(layouts)}: {len(same) == len(layouts) - 1}")
PY
    cat "$OUT/layouts-same.txt" >&2
fi

FULL_SUMMARY=$OUT/res-full-identify/summary.json
[ "$DBBCAL_BARS" = all ] || FULL_SUMMARY=$OUT/res-full-sub-identify/summary.json

if [ "$SKIP_PYTHON" != 1 ]; then
    camp=$OUT/campaign-full
    bars=""
    if [ "$PY_BARS" != all ]; then
        bars=$(python3 -c "import tomllib,sys; m=tomllib.load(open('$camp/campaign.toml','rb')); print(','.join(b['id'] for b in m['bar'][:int(sys.argv[1])]))" "$PY_BARS")
    fi
    say "timing the Python equivalent (dense lstsq) on ${bars:-all bars}"
    measure "python-dense-full" full python3 bench/python_equivalent.py "$camp" ${bars:+--bars "$bars"} \
        --bin-s "$PY_BIN_S" --json "$OUT/py-dense-full.json" --compare "$FULL_SUMMARY"
    if [ "$PY_FAST" = 1 ]; then
        say "timing the Python equivalent (--project-zeros) on all bars"
        measure "python-fwl-full" full python3 bench/python_equivalent.py "$camp" --project-zeros \
            --bin-s "$PY_BIN_S" --json "$OUT/py-fwl-full.json" --compare "$FULL_SUMMARY"
    fi
fi

RESULTS=bench/results.md
[ "$BIN_S" = 0 ] || RESULTS=bench/results-bin${BIN_S}s.md
[ "$BIN_S" != auto ] || RESULTS=bench/results-auto.md
say "writing $RESULTS"
python3 bench/report.py --out-dir "$OUT" --results "$RESULTS" --dbbcal-bars "$DBBCAL_BARS"
cat "$RESULTS"
