#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Hydrographic products benchmark (issue 17): a simulated survey (default bejanca) through
# `pitmap run` with the per-sounding TPU written (grid.write_sounding_tpu), the water-level
# datum from the GNSS heights and IHO S-44 order 1a QC, then pitmap-eval: the grid stage's
# time, the CUBE surface against the true terrain (dem_*) and the share of soundings within
# their 95 % TVU / THU (tpu_*), overall and by |beam angle|; the S-44 figures (share within
# TVU/THU per order, holidays, crosslines); and the time the datum, the THU/TVU point files
# and S-44 add: `pitmap grid` again on the same products without them (ellipsoidal heights,
# s44.enabled false, grid.write_point_tpu false) and with them.
#   tools/bench/run-grid-bench.sh [SCENARIO] [OUT]   (defaults: bejanca, out/bench/grid-SCENARIO)
# Writes OUT/grid.json; `tools/bench/run-benchmarks.sh grid` stores it for docs/benchmarks.md.
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
printf 'grid:\n  write_sounding_tpu: true\nvertical:\n  datum: water_level\ns44:\n  order: 1a\n' \
  > "$out/grid.yaml"
printf 'grid:\n  write_point_tpu: false\ns44:\n  enabled: false\n' > "$out/grid-base.yaml"
printf 'vertical:\n  datum: water_level\ns44:\n  order: 1a\n' > "$out/grid-full.yaml"
echo "=== run-grid-bench: pitmap run"
"$bin/pitmap" run "$sim/log" --out "$out/products" --config "$out/grid.yaml" --no-report \
  > "$out/run.log" 2>&1 || { grep -v '%  \[' "$out/run.log" | tail -20; exit 1; }
"$bin/pitmap-eval" --truth "$sim/truth" --products "$out/products" \
  --json "$out/products/scores.json" > "$out/eval.txt"
cp "$out/products/summary.json" "$out/summary-run.json"
echo "=== run-grid-bench: pitmap grid without and with datum, point THU/TVU and S-44"
for k in base full; do
  "$bin/pitmap" grid --out "$out/products" --config "$out/grid-$k.yaml" > "$out/grid-$k.log" 2>&1
  cp "$out/products/summary.json" "$out/summary-grid-$k.json"
done
cp "$out/summary-run.json" "$out/products/summary.json"

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
q = g.get("s44")
if q:
    vd = s.get("vertical_datum", {})
    print(f"\nvertical datum: {vd.get('description', '?')}")
    print(f"\nIHO S-44 (order {q['order']} chosen; strictest met by 95 %: "
          f"{q['strictest_order_met_95']})\n| order | soundings within TVU | within THU | "
          "nodes within TVU |\n|---|---:|---:|---:|")
    for o in ("exclusive", "special", "1a", "1b", "2"):
        print(f"| {o} | {100 * q['soundings_within_tvu'][o]:.2f} % | "
              f"{100 * q['soundings_within_thu'][o]:.2f} % | {100 * q['nodes_within_tvu'][o]:.2f} % |")
    print(f"holidays (order {q['order']}, feature {q['feature_size_m']:.2f} m): "
          f"{q['holiday_count']}; gaps {q['gaps']}, coverage {100 * q['coverage_share']:.2f} %")
    cl = q["crossline"]
    print(f"crossline: {cl['compared']} soundings, mean {cl['mean_m']:.4f} m, sd {cl['sd_m']:.4f} m, "
          f"RMS {cl['rms_m']:.4f} m, within TVU {100 * cl['within_tvu']:.2f} %\n"
          "| abs beam angle | soundings | mean (m) | sd (m) | RMS (m) | within TVU |\n|---|---:|---:|---:|---:|---:|")
    for b in cl["by_angle"]:
        print(f"| {b['angle_lo_deg']:.0f}-{b['angle_hi_deg']:.0f} | {b['count']} | {b['mean_m']:.4f} | "
              f"{b['sd_m']:.4f} | {b['rms_m']:.4f} | {100 * b['within_tvu']:.1f} % |")
print("\n| pitmap grid | seconds | CPU s | parts (wall, CPU s) |\n|---|---:|---:|---|")
for k in ("base", "full"):
    gs = json.load(open(os.path.join(out, f"summary-grid-{k}.json")))["stages"]["grid"]
    t = gs["timings_wall_cpu_s"]
    cpu = sum(v[1] for v in t.values())
    print(f"| {k} | {gs['seconds']:.1f} | {cpu:.1f} | " +
          ", ".join(f"{n} {v[0]:.1f}/{v[1]:.1f}" for n, v in t.items()) + " |")
print(f"\nrun total {s['total_seconds']:.1f} s; scores: {os.path.join(out, 'products', 'scores.json')}")
runs = {}
for k in ("base", "full"):
    gs = json.load(open(os.path.join(out, f"summary-grid-{k}.json")))["stages"]["grid"]
    runs[k] = {n: gs[n] for n in ("seconds", "peak_rss_mb", "timings_wall_cpu_s") if n in gs}
bench = {"scenario": scenario, "soundings": g["soundings"], "nodes": g["nx"] * g["ny"],
         "resolution_m": g["resolution_m"], "run_total_seconds": s["total_seconds"],
         "grid_runs": runs,
         "scores": {k: v for k, v in sc.items() if k.startswith(("dem_", "tpu_within"))}}
json.dump(bench, open(os.path.join(out, "grid.json"), "w"), indent=2)
PY
"$root/tools/bench/benchmarks_page.py" show grid "$out/grid.json"
