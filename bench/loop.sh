#!/usr/bin/env bash
# The loop at its limits, speed (issue 26, item 3): wall time and peak RSS (/usr/bin/time, best of
# REPEAT) of `dbbcal run pipelines/nightly.toml` at its defaults on
#   - 10-bar x 15-day x 10-s campaigns with 0, 1, 2, 3 hidden effects, from both simulators:
#       ours     `dbbcal simulate --config pipelines/sim-identification.toml` with
#                `[effects.X] enabled = true` appended (X in head_heating, second_path,
#                sensor_gradient, settling, plate_expansion, creep, hidden_channel);
#       foreign  bench/foreign_sim.py --bars 10 --days 15 --sample-s 10 --seed 1 with --head /
#                --effect X (second_path, air_gradient, settling, creep, plate_expansion, heat_source);
#     target: <= 15 s and <= 1 GB each;
#   - the machine-tool log (bench/machine_tool_campaign.py, as tests/e2e/machine_tool.rs): <= 10 s;
#   - 12 bars x 30 days at 1 Hz (bench/sim-bench.toml) with temperatures at 30 s (as bench/run.sh)
#     and at 1 s (the same TOML with [room] temperature_sample_s = 1.0), each in the three row
#     orders of bench/layouts.py: nightly <= 20 s and <= 1.5 GB, `dbbcal identify` <= 3 s;
#   - beside bench/python_loop.py (the Python loop peer) on the campaigns of PY_CASES: >= 20x.
# Writes bench/results-loop-speed.md (and bench/out/loop/measurements.tsv).
#
#   bench/loop.sh                                   # the default set (below), REPEAT=1
#   DBBCAL=/tmp/dbbcal-bench-base REPEAT=3 bench/loop.sh
#   COMBOS=all bench/loop.sh                        # every combination of 1-3 effects (2 x 63 campaigns)
#   SIMS=foreign BIG="" PY=0 bench/loop.sh          # only the second simulator's campaigns, no Python
#
# Knobs (environment):
#   DBBCAL        the binary (default $CARGO_TARGET_DIR/release/dbbcal, CARGO_TARGET_DIR default
#                 ~/.cache/dbbcal-target); copied to bench/out/loop/dbbcal first, so a rebuild during
#                 the run cannot mix two versions. Nothing is built here.
#   REPEAT=1      runs per measurement, the fastest reported (peak RSS: the largest)
#   SIMS="ours foreign"
#   COMBOS=sample every single effect, plus NPAIRS pairs and NTRIPLES triples drawn (seed 26) from
#                 each simulator's seven; "all": every combination; or an explicit list for both
#                 simulators in the foreign names, "head+heat_source settling+creep" (ours maps
#                 head -> head_heating, air_gradient -> sensor_gradient, heat_source -> hidden_channel)
#   NPAIRS=4 NTRIPLES=4
#   MACHINE=1     the machine-tool log (0: skip)
#   BIG="t30 t1"  the 1 Hz layouts: temperatures every 30 s / every 1 s ("" to skip)
#   LAYOUTS="bybar bytime shuffled"
#   PY=1          the Python peer (bench/python_loop.py, its default: both starts) on PY_CASES
#   PY_CASES="ours-clean ours-head_heating foreign-clean foreign-heat_source machine-tool"
#                 (names as in the table; "all10x15" for every 10 x 15 campaign)
#   PY_STARTS=both  (warm: the peer's cheaper, sometimes wrong, variant)
#   RESUME=0      1: keep the rows of bench/out/loop/measurements.tsv (and python.tsv) that hold a
#                 ledger and time only the campaigns missing there; the table covers them all
#   PY_TIMEOUT=600  seconds a peer run may take; one that is stopped is reported as "> PY_TIMEOUT"
#                 (its ratio a lower bound)
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/dbbcal-target}"
SRC_BIN="${DBBCAL:-$CARGO_TARGET_DIR/release/dbbcal}"
REPEAT="${REPEAT:-1}"
SIMS="${SIMS-ours foreign}"
COMBOS="${COMBOS:-sample}"
NPAIRS="${NPAIRS:-4}"
NTRIPLES="${NTRIPLES:-4}"
MACHINE="${MACHINE:-1}"
BIG="${BIG-t30 t1}"
LAYOUTS="${LAYOUTS-bybar bytime shuffled}"
PY="${PY:-1}"
PY_CASES="${PY_CASES:-ours-clean ours-head_heating foreign-clean foreign-heat_source machine-tool}"
PY_STARTS="${PY_STARTS:-both}"
PY_TIMEOUT="${PY_TIMEOUT:-600}"
RESUME="${RESUME:-0}"
OUT=bench/out/loop
CAMP=bench/out/loop-campaigns
BIGDIR=bench/out
TSV=$OUT/measurements.tsv
RESULTS=bench/results-loop-speed.md
mkdir -p "$OUT" "$CAMP"
[ -x "$SRC_BIN" ] || { echo "no dbbcal binary at $SRC_BIN (set DBBCAL)" >&2; exit 2; }
BIN=$OUT/dbbcal
cp "$SRC_BIN" "$BIN"
say() { printf '== %s\n' "$*" >&2; }

# ------------------------------------------------------------------ which campaigns
FOREIGN_POOL="head second_path air_gradient settling creep plate_expansion heat_source"
combos() {
    python3 - "$COMBOS" "$NPAIRS" "$NTRIPLES" $FOREIGN_POOL <<'PY'
import itertools, sys, random
mode, npairs, ntriples, pool = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:]
if mode == "all":
    out = [c for k in (1, 2, 3) for c in itertools.combinations(pool, k)]
elif mode == "sample":
    rnd = random.Random(26)
    out = [(e,) for e in pool]
    out += rnd.sample(list(itertools.combinations(pool, 2)), npairs)
    out += rnd.sample(list(itertools.combinations(pool, 3)), ntriples)
else:
    out = [tuple(e for e in pool if e in c.split("+")) for c in mode.split()]
print("clean")
for c in out:
    print("+".join(c))
PY
}
ours_name() {  # foreign effect name -> ours
    case $1 in
        head) echo head_heating ;;
        air_gradient) echo sensor_gradient ;;
        heat_source) echo hidden_channel ;;
        *) echo "$1" ;;
    esac
}

# name dir pairs of every campaign to time, in order
CASES=()
for sim in $SIMS; do
    for combo in $(combos); do
        if [ "$sim" = ours ]; then
            name="ours-clean"
            if [ "$combo" != clean ]; then
                mapped=""
                for e in ${combo//+/ }; do mapped="$mapped+$(ours_name "$e")"; done
                name="ours-${mapped#+}"
            fi
            dir=$CAMP/$name
            if [ ! -f "$dir/campaign.toml" ]; then
                rm -rf "$dir"
                # A campaign id allows letters, digits, '.', '_' and '-' only.
                sed "s/campaign_id = \"truth-10x15\"/campaign_id = \"loop-${name//+/.}\"/" pipelines/sim-identification.toml >"$CAMP/$name.toml"
                if [ "$combo" != clean ]; then
                    for e in ${combo//+/ }; do
                        printf '\n[effects.%s]\nenabled = true\n' "$(ours_name "$e")" >>"$CAMP/$name.toml"
                    done
                fi
                say "simulating $name"
                "$BIN" simulate --config "$CAMP/$name.toml" --out "$dir" >/dev/null
            fi
        else
            name="foreign-$combo"
            dir=$CAMP/$name
            if [ ! -f "$dir/campaign.toml" ]; then
                flags=()
                if [ "$combo" != clean ]; then
                    for e in ${combo//+/ }; do
                        if [ "$e" = head ]; then flags+=(--head); else flags+=(--effect "$e"); fi
                    done
                fi
                say "simulating $name"
                python3 bench/foreign_sim.py "$dir" --seed 1 --bars 10 --days 15 --sample-s 10 "${flags[@]}"
            fi
        fi
        CASES+=("$name:$dir:10x15")
    done
done
if [ "$MACHINE" = 1 ]; then
    dir=$CAMP/machine-tool
    [ -f "$dir/campaign.toml" ] || python3 bench/machine_tool_campaign.py "$dir" >&2
    CASES+=("machine-tool:$dir:machine")
fi
for t in $BIG; do
    src=$BIGDIR/campaign-full
    if [ "$t" = t1 ]; then
        src=$BIGDIR/campaign-full-t1
        if [ ! -f "$src/campaign.toml" ]; then
            rm -rf "$src"
            sed -e 's/campaign_id = "bench-30d"/campaign_id = "bench-30d-t1"/' \
                -e 's/^temperature_sample_s = 30.0/temperature_sample_s = 1.0/' bench/sim-bench.toml >"$BIGDIR/sim-bench-t1.toml"
            grep -q '^temperature_sample_s = 1.0' "$BIGDIR/sim-bench-t1.toml"
            say "simulating $src (30 days, 1 Hz, temperatures at 1 Hz)"
            "$BIN" simulate --config "$BIGDIR/sim-bench-t1.toml" --out "$src" >/dev/null
        fi
    elif [ ! -f "$src/campaign.toml" ]; then
        rm -rf "$src"
        say "simulating $src (bench/sim-bench.toml)"
        "$BIN" simulate --config bench/sim-bench.toml --out "$src" >/dev/null
    fi
    for layout in $LAYOUTS; do
        dir=$src-$layout
        [ -f "$dir/campaign.toml" ] || { rm -rf "$dir"; python3 bench/layouts.py "$src" "$dir" --order "$layout" >&2; }
        CASES+=("1Hz-30d-$t-$layout:$dir:big")
    done
done

# ------------------------------------------------------------------ measuring
# best of $REPEAT: "wall_s cpu_s max_rss_kb" (CPU = user + system; RSS the largest of the runs)
best_of() {
    local label=$1 best="" rss=0 line w u s m
    shift
    for _ in $(seq "$REPEAT"); do
        rm -rf "$OUT/run-$label"
        /usr/bin/time -f "TIME %e %U %S %M" "$@" --out "$OUT/run-$label" -v >/dev/null 2>"$OUT/run-$label.stderr" || true
        line=$(grep '^TIME' "$OUT/run-$label.stderr" | tail -1)
        read -r _ w u s m <<<"$line"
        [ "$m" -gt "$rss" ] && rss=$m
        if [ -z "$best" ] || awk -v a="$w" -v b="${best%% *}" 'BEGIN{exit !(a<b)}'; then
            best="$w $(awk -v u="$u" -v s="$s" 'BEGIN{printf "%.2f", u+s}')"
        fi
    done
    echo "$best $rss"
}
ledger_of() {
    python3 - "$1" <<'PY'
import json, sys
try:
    d = json.load(open(sys.argv[1]))
    print(" → ".join(f"{s['added']} {s['fleet_rms_um'] * 1e3:.1f}" for s in d["ledger"]))
except Exception as e:
    print(f"(no ledger: {e.__class__.__name__})")
PY
}
samples_of() {
    python3 -c "import json,sys; s=json.load(open(sys.argv[1])); print(sum(b['n_samples'] for b in s['bars']))" "$1" 2>/dev/null || echo "?"
}
meets() {  # value limit -> yes/**no**
    awk -v v="$1" -v l="$2" 'BEGIN{print (v <= l) ? "yes" : "**no**"}'
}

if [ "$RESUME" = 1 ] && [ -f "$TSV" ]; then
    # keep the rows with a ledger (a finished run), drop the others
    awk -F'\t' '$10 !~ /^\(no ledger/' "$TSV" >"$TSV.keep" && mv "$TSV.keep" "$TSV"
else
    : >"$TSV"
fi
BEFORE_LOAD=$(cut -d' ' -f1-3 /proc/loadavg)
START_UTC=$(date -u +%Y-%m-%dT%H:%MZ)
ROWS=()
for spec in "${CASES[@]}"; do
    IFS=: read -r name dir kind <<<"$spec"
    if cut -f1 "$TSV" | grep -qxF "$name"; then
        say "nightly: $name (kept from the last run)"
        continue
    fi
    say "nightly: $name"
    load=$(cut -d' ' -f1 /proc/loadavg)
    read -r wall cpu rss <<<"$(best_of "$name" "$BIN" run pipelines/nightly.toml --campaign "$dir")"
    samples=$(samples_of "$OUT/run-$name/summary.json")
    ledger=$(ledger_of "$OUT/run-$name/diagnosis.json")
    id_wall="" id_rss=""
    if [ "$kind" = big ]; then
        say "identify: $name"
        read -r id_wall _ id_rss <<<"$(best_of "$name-identify" "$BIN" identify --campaign "$dir")"
    fi
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$kind" "$samples" "$wall" "$cpu" "$rss" "$id_wall" "$id_rss" "$load" "$ledger" >>"$TSV"
done

# The Python peer, where it is feasible (minutes a campaign; hours on the 1 Hz layouts: not run).
PYTSV=$OUT/python.tsv
[ "$RESUME" = 1 ] && [ -f "$PYTSV" ] || : >"$PYTSV"
if [ "$PY" = 1 ]; then
    python3 -c "import polars, scipy, numpy" || { echo "python3 lacks polars/scipy/numpy" >&2; exit 2; }
    for spec in "${CASES[@]}"; do
        IFS=: read -r name dir kind <<<"$spec"
        case " $PY_CASES " in
            *" $name "*) ;;
            *) { [ "$kind" = 10x15 ] && [[ " $PY_CASES " == *" all10x15 "* ]]; } || continue ;;
        esac
        if cut -f1 "$PYTSV" | grep -qxF "$name"; then continue; fi
        say "python_loop.py --starts $PY_STARTS: $name"
        rm -f "$OUT/py-$name.json"
        line=$(/usr/bin/time -f "TIME %e %M %x" timeout "$PY_TIMEOUT" python3 bench/python_loop.py "$dir" --starts "$PY_STARTS" \
            --quiet --json "$OUT/py-$name.json" 2>&1 >"$OUT/py-$name.log" | grep '^TIME' | tail -1) || true
        read -r _ w m x <<<"$line"
        [ "$x" != 124 ] || w=">$w"
        pyledger=$(python3 - "$OUT/py-$name.json" <<'PY'
import json, sys
try:
    d = json.load(open(sys.argv[1]))
    steps = d.get("ledger", [])
    print(" → ".join(f"{s.get('added', s.get('effect', '?'))} {s.get('fleet_rms_um', float('nan')) * 1e3:.1f}" for s in steps))
except Exception as e:
    print(f"(no ledger: {e.__class__.__name__})")
PY
)
        printf '%s\t%s\t%s\t%s\n' "$name" "$w" "$m" "$pyledger" >>"$PYTSV"
    done
fi

# ------------------------------------------------------------------ the table
python3 - "$TSV" "$PYTSV" "$BIN" "$REPEAT" "$BEFORE_LOAD" "$START_UTC" "$SRC_BIN" "$RESUME" >"$RESULTS" <<'PY'
import hashlib, subprocess, sys, os, datetime
tsv, pytsv, binary, repeat, load, start, src, resume = sys.argv[1:9]
rows = [l.rstrip("\n").split("\t") for l in open(tsv) if l.strip()]
py = {l.split("\t")[0]: l.rstrip("\n").split("\t")[1:] for l in open(pytsv) if l.strip()}
version = subprocess.run([binary, "--version"], capture_output=True, text=True).stdout.strip()
digest = hashlib.sha256(open(binary, "rb").read()).hexdigest()[:12]
mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
end = datetime.datetime.now(datetime.timezone.utc).strftime("%H:%MZ")
print(f"# The nightly loop at its limits: speed (issue 26)\n")
print(f"`bench/loop.sh`, {start} to {end}; {version} (`{src}`, sha256 {digest}); {os.cpu_count()} cores, {mem:.0f} GB; "
      f"load before {load}. `dbbcal run pipelines/nightly.toml` at its defaults, best of {repeat} (CPU = user + system of that run; "
      "peak RSS the largest). Samples: fitted samples in `summary.json` (nodes when binned). Ledger: `diagnosis.json` → "
      "`ledger`, fleet RMS in nm after each step. "
      + ("RESUME=1: rows kept from earlier runs of the same binary were measured then (load1 column). " if resume == "1" else "")
      + "Targets: 10 × 15 campaigns ≤ 15 s and ≤ 1 GB; machine-tool log ≤ 10 s; "
      "12 × 30-day 1 Hz layouts ≤ 20 s and ≤ 1.5 GB, `dbbcal identify` ≤ 3 s; ≥ 20× the Python loop peer.\n")
print("| campaign | samples | wall s | CPU s | peak MB | identify s (MB) | target | met | Python peer s | × | load1 | ledger |")
print("|---|---:|---:|---:|---:|---|---|---|---:|---:|---:|---|")
limits = {"10x15": (15, 1024, None), "machine": (10, None, None), "big": (20, 1536, 3)}
met_all = []
for name, kind, samples, wall, cpu, rss, id_wall, id_rss, load1, ledger in rows:
    lw, lm, li = limits[kind]
    wall_f, rss_mb = float(wall), int(rss) / 1024
    ok = wall_f <= lw and (lm is None or rss_mb <= lm)
    target = f"≤ {lw} s" + (f", ≤ {lm / 1024:g} GB" if lm else "")
    idcell = ""
    if id_wall:
        idcell = f"{float(id_wall):.2f} ({int(id_rss) / 1024:.0f})"
        ok = ok and float(id_wall) <= li
        target += f"; identify ≤ {li} s"
    pycell = ratio = ""
    if name in py and py[name][0]:
        cut = py[name][0].startswith(">")  # stopped at PY_TIMEOUT: a lower bound
        pw = float(py[name][0].lstrip(">"))
        pycell = f"{'> ' if cut else ''}{pw:.1f}"
        r = pw / wall_f
        ratio = ("> " if cut else "") + (f"{r:.0f}×" if r >= 20 else f"**{r:.1f}×**")
        ok = ok and r >= 20
    met_all.append(ok)
    print(f"| {name} | {samples} | {wall_f:.2f} | {cpu} | {rss_mb:.0f} | {idcell} | {target}{', ≥ 20×' if pycell else ''} | "
          f"{'yes' if ok else '**no**'} | {pycell} | {ratio} | {load1} | {ledger} |")
print(f"\n{sum(met_all)} of {len(met_all)} rows meet their targets.")
if py:
    print("\nThe Python peer's ledgers (bench/python_loop.py --starts as set; wall s, peak MB):\n")
    for name, (w, m, led) in py.items():
        print(f"- {name}: {w} s, {int(m or 0) / 1024:.0f} MB: {led}")
PY
cat "$RESULTS"
