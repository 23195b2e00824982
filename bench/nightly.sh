#!/usr/bin/env bash
# The nightly loop at working speed (issue 13): `dbbcal run pipelines/nightly.toml` at its
# defaults (ingest, identify, match, diagnose with forward selection fleet-wide and per bar, beam
# 3, report) — wall time and peak RSS (/usr/bin/time) on
#   - the 10-bar, 15-day, 10-s identification campaign (1.3 M encoder rows), base effects only,
#     and the same with hidden head heating;
#   - the 12-bar, 30-day, 1 Hz benchmark campaign (31 M rows) in the three row orders of
#     bench/layouts.py (run bench/run.sh first, or set LAYOUT_DIR to where they are), no option
#     set (bins chosen automatically);
# beside bench/python_loop.py, the same loop done plainly in polars + scipy (its default, both
# starts, and --starts warm), when python3 has polars, scipy and numpy. Writes bench/results-nightly.md.
#
#   bench/nightly.sh                 # REPEAT=3 by default (best of)
#   PY_BARS=2 bench/nightly.sh       # the Python loop on 2 of the bars (its own timings say so)
#   NO_PY=1 bench/nightly.sh         # dbbcal only
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/dbbcal-target}"
OUT=bench/out/nightly
LAYOUT_DIR="${LAYOUT_DIR:-bench/out}"
REPEAT="${REPEAT:-3}"
PY_BARS="${PY_BARS:-all}"
mkdir -p "$OUT"
cargo build --release --locked --quiet
BIN="$CARGO_TARGET_DIR/release/dbbcal"

if [ ! -d "$OUT/clean-10x15" ]; then
    "$BIN" simulate --config pipelines/sim-identification.toml --out "$OUT/clean-10x15"
fi
if [ ! -d "$OUT/head-10x15" ]; then
    sed 's/campaign_id = "truth-10x15"/campaign_id = "head-10x15"/' pipelines/sim-identification.toml >"$OUT/sim-head.toml"
    printf '\n[effects.head_heating]\nenabled = true\n' >>"$OUT/sim-head.toml"
    "$BIN" simulate --config "$OUT/sim-head.toml" --out "$OUT/head-10x15"
fi

# best of $REPEAT: "wall_s user_s max_rss_kb"
best_of() {
    local name=$1 dir=$2 best="" line
    for _ in $(seq "$REPEAT"); do
        rm -rf "$OUT/run-$name"
        line=$(/usr/bin/time -f "%e %U %M" "$BIN" run pipelines/nightly.toml --campaign "$dir" \
            --out "$OUT/run-$name" 2>&1 >/dev/null | tail -1)
        if [ -z "$best" ] || awk -v a="$line" -v b="$best" 'BEGIN{split(a,x," ");split(b,y," ");exit !(x[1]<y[1])}'; then
            best=$line
        fi
    done
    echo "$best"
}

{
    echo "# Nightly pipeline benchmark ($(date -u +%Y-%m-%dT%H:%MZ))"
    echo
    echo "Machine: $(nproc) cores, $(free -g | awk '/Mem/{print $2}') GB; load before: $(cut -d' ' -f1-3 /proc/loadavg)."
    echo "\`dbbcal run pipelines/nightly.toml\` at its defaults, best of $REPEAT."
    echo
    echo "| campaign | rows | wall s | CPU s | peak RSS MB | fleet ledger |"
    echo "|---|---|---|---|---|---|"
    for spec in "clean-10x15:$OUT/clean-10x15" "head-10x15:$OUT/head-10x15" \
        "1Hz-30d-bybar:$LAYOUT_DIR/campaign-full-bybar" \
        "1Hz-30d-bytime:$LAYOUT_DIR/campaign-full-bytime" \
        "1Hz-30d-shuffled:$LAYOUT_DIR/campaign-full-shuffled"; do
        name=${spec%%:*}
        dir=${spec#*:}
        [ -d "$dir" ] || { echo "| $name | (missing: $dir) | | | | |"; continue; }
        read -r wall user rss <<<"$(best_of "$name" "$dir")"
        rows=$(python3 -c "import json,sys; s=json.load(open(sys.argv[1])); print(sum(b['n_samples'] for b in s['bars']))" "$OUT/run-$name/summary.json")
        ledger=$(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(' → '.join(f\"{s['added']} {s['fleet_rms_um']:.4f}\" for s in d['ledger']))" "$OUT/run-$name/diagnosis.json")
        echo "| $name | $rows | $wall | $user | $((rss / 1024)) | $ledger |"
    done
    echo
    if [ -z "${NO_PY:-}" ] && python3 -c "import polars, scipy, numpy" 2>/dev/null; then
        echo "Python peer (bench/python_loop.py, bars: $PY_BARS):"
        echo
        echo '```'
        for c in clean-10x15 head-10x15; do
            args=()
            [ "$PY_BARS" = all ] || args=(--bars "$PY_BARS")
            /usr/bin/time -f "$c: %e s wall, %U s CPU, %M KB" python3 bench/python_loop.py "$OUT/$c" "${args[@]}" 2>&1 | tail -12
            # One start per refit: the peer's cheapest variant (sometimes wrong, see README).
            /usr/bin/time -f "$c warm: %e s wall, %U s CPU, %M KB" python3 bench/python_loop.py "$OUT/$c" --starts warm "${args[@]}" 2>&1 | tail -6
        done
        echo '```'
    else
        echo "Python peer skipped (NO_PY set, or python3 lacks polars, scipy, numpy)."
    fi
} | tee bench/results-nightly.md
