#!/usr/bin/env python3
"""Identification over many seeds of one simulated campaign design, against its truth.

For each seed: `dbbcal simulate --config CONFIG --seed S`, `dbbcal identify`, then the worst
relative error of alpha, beta, tau_R and tau_S over the bars, the largest |error| / u, and
whether every bar met the limits (default: the identification limits of the README, 0.5 % for
alpha and beta, 3 % for the taus). Not a test: a campaign-design study (~3 s a seed).

    cargo build --release
    python3 bench/identification_seeds.py pipelines/sim-identification.toml --seeds 1-10
"""

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

LIMITS = {"alpha_ppm_per_k": 0.005, "beta_ppm_per_k": 0.005, "tau_r_s": 0.03, "tau_s_s": 0.03}
LABEL = {"alpha_ppm_per_k": "alpha", "beta_ppm_per_k": "beta", "tau_r_s": "tau_R", "tau_s_s": "tau_S"}


def run_seed(binary: str, config: str, seed: int, work: Path, setpoint_off: bool) -> tuple[dict, tuple[float, str]]:
    campaign, out = work / f"c{seed}", work / f"o{seed}"
    cfg = config
    if setpoint_off:
        text = Path(config).read_text()
        text = "\n".join("setpoint_step_k = 0.0" if l.startswith("setpoint_step_k") else l for l in text.splitlines())
        cfg = str(work / "passive.toml")
        Path(cfg).write_text(text + "\n")
    for cmd in (
        [binary, "simulate", "--config", cfg, "--out", str(campaign), "--seed", str(seed)],
        [binary, "identify", "--campaign", str(campaign), "--out", str(out)],
    ):
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            last = (done.stderr.strip().splitlines() or ["(no message)"])[-1]
            sys.exit(f"seed {seed}: `{' '.join(cmd)}` failed (exit {done.returncode}): {last}")
    truth = {b["id"]: b for b in json.loads((campaign / "truth.json").read_text())["bars"]}
    summary = json.loads((out / "summary.json").read_text())
    worst = {k: 0.0 for k in LIMITS}
    worst_z = (0.0, "")
    for bar in summary["bars"]:
        t = truth[bar["bar"]]
        for k in LIMITS:
            p = bar["params"][k]
            worst[k] = max(worst[k], abs(p["value"] / t[k] - 1.0))
            worst_z = max(worst_z, (abs(p["value"] - t[k]) / p["u"], f"{bar['bar']} {LABEL[k]}"))
    shutil.rmtree(campaign)
    shutil.rmtree(out)
    return worst, worst_z


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("config", help="simulation TOML")
    ap.add_argument("--seeds", default="1-10", help="range A-B (inclusive)")
    ap.add_argument("--binary", default="target/release/dbbcal")
    ap.add_argument("--no-setpoint", action="store_true", help="the same campaign with setpoint_step_k = 0")
    args = ap.parse_args()
    first, last = (int(v) for v in args.seeds.split("-"))
    passed = 0
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(first, last + 1):
            worst, worst_z = run_seed(args.binary, args.config, seed, Path(tmp), args.no_setpoint)
            ok = all(worst[k] < LIMITS[k] for k in LIMITS)
            passed += ok
            cells = ", ".join(f"{LABEL[k]} {100 * worst[k]:.3f} %" for k in LIMITS)
            print(f"seed {seed}: worst {cells}; max |error|/u {worst_z[0]:.1f} ({worst_z[1]}); {'all bars within the limits' if ok else 'MISSED'}", flush=True)
    print(f"{passed} of {last - first + 1} campaigns had every bar within the limits")
    return 0


if __name__ == "__main__":
    sys.exit(main())
