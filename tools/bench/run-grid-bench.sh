#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Hydrographic products benchmark (issue 17): a simulated survey (default bejanca) through
# `pitmap run` with the per-sounding TPU written (grid.write_sounding_tpu), then pitmap-eval:
# the grid stage's time, the CUBE surface against the true terrain (dem_*) and the share of
# soundings within their 95 % TVU / THU (tpu_*), overall and by |beam angle|.
#   tools/bench/run-grid-bench.sh [SCENARIO] [OUT]   (defaults: bejanca, out/bench/grid-SCENARIO)
# SIM=DIR reuses a simulation made before (DIR/log, DIR/truth) instead of simulating again.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
scenario=${1:-bejanca}
out=${2:-$root/out/bench/grid-$scenario}
build=${BUILD_DIR:-$root/build}
bin=$build/bin
cmake --build "$build" -j 2 --target pitmap pitmap-sim pitmap-eval > /dev/null

mkdir -p "$out"
sim=${SIM:-$out/sim}
if [[ -z ${SIM:-} ]]; then
  rm -rf "$sim"
  echo "=== run-grid-bench: simulating '$scenario'"
  "$bin/pitmap-sim" synth --scenario "$scenario" --out "$sim" > "$out/sim.log" 2>&1 || {
    tail -20 "$out/sim.log"; exit 1; }
fi
rm -rf "$out/products"
printf 'grid:\n  write_sounding_tpu: true\n' > "$out/grid.yaml"
echo "=== run-grid-bench: pitmap run"
"$bin/pitmap" run "$sim/log" --out "$out/products" --config "$out/grid.yaml" --no-report \
  > "$out/run.log" 2>&1 || { grep -v '%  \[' "$out/run.log" | tail -20; exit 1; }
"$bin/pitmap-eval" --truth "$sim/truth" --products "$out/products" \
  --json "$out/products/scores.json" > "$out/eval.txt"

python3 - "$out" "$scenario" <<'PY'
import json, os, sys
out, scenario = sys.argv[1], sys.argv[2]
s = json.load(open(os.path.join(out, "products", "summary.json")))
sc = json.load(open(os.path.join(out, "products", "scores.json")))
g = s["stages"]["grid"]
print(f"\n{scenario}: {g['soundings']} soundings; grid stage {g['seconds']:.1f} s, "
      f"peak RSS {g['peak_rss_mb']:.0f} MB; error model: {g['error_model']}")
print(f"CUBE {g['disambiguation']}: {g['nx']} x {g['ny']} nodes at {g['resolution_m']} m "
      f"(median depth {g['median_depth_m']:.1f} m), {g['nodes_filled']} filled, "
      f"{g['nodes_multiple_hypotheses']} with several hypotheses")
print(f"median TVU {g['median_tvu_95_m']:.3f} m, THU {g['median_thu_95_m']:.3f} m (95 %); "
      "TVU variance shares: " +
      ", ".join(f"{k} {v:.2f}" for k, v in g["tvu_variance_share"].items() if v >= 0.005))
print("\n| DEM against the true terrain | value |\n|---|---:|")
for k in ["dem_mean_abs_m", "dem_mean_abs_insonified_m", "dem_rms_m", "dem_p95_m", "dem_bias_m",
          "dem_fill_insonified"]:
    if k in sc:
        print(f"| {k} | {sc[k]:.4f} |")
print("\n| abs beam angle | soundings | within 95 % TVU | within 95 % THU | vertical RMS (m) "
      "| TVU/1.96 RMS (m) |\n|---|---:|---:|---:|---:|---:|")
for lo in range(0, 70, 10):
    b = f"{lo:02d}_{lo + 10:02d}_deg"
    if f"tpu_count_{b}" not in sc:
        continue
    print(f"| {lo}-{lo + 10} | {sc['tpu_count_' + b]:.0f} | {100 * sc['tpu_within_tvu_' + b]:.1f} % | "
          f"{100 * sc['tpu_within_thu_' + b]:.1f} % | {sc['tpu_vertical_rms_' + b]:.4f} | "
          f"{sc['tpu_tvu_sigma_rms_' + b]:.4f} |")
if "tpu_within_tvu" in sc:
    print(f"| all | {sc['tpu_soundings_scored']:.0f} | {100 * sc['tpu_within_tvu']:.1f} % | "
          f"{100 * sc['tpu_within_thu']:.1f} % | {sc['tpu_vertical_rms_m']:.4f} | "
          f"{sc['tpu_tvu_sigma_rms_m']:.4f} |")
print(f"\nrun total {s['total_seconds']:.1f} s; scores: {os.path.join(out, 'products', 'scores.json')}")
PY
