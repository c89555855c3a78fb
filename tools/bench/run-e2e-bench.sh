#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# End-to-end benchmark: a simulated survey (default bejanca) through `pitmap run`, with the time
# and peak memory of every stage, the scores against ground truth, and a ray-mode TSDF run of
# the same trajectory for comparison with the beam-width sensor model.
#   tools/bench/run-e2e-bench.sh [SCENARIO] [OUT]      (defaults: bejanca, out/bench/SCENARIO)
# Writes OUT/bench.json and prints its tables; `tools/bench/run-benchmarks.sh e2e` runs this and
# stores the result for docs/benchmarks.md.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
scenario=${1:-bejanca}
out=${2:-$root/out/bench/$scenario}
build=${BUILD_DIR:-$root/build}
bin=$build/bin

"$root/tools/install-deps.sh"
if [[ ! -f $build/CMakeCache.txt ]]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release > "$build.configure.log" 2>&1 || {
    cat "$build.configure.log"; echo "run-e2e-bench: configure failed" >&2; exit 1; }
fi
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" \
  --target pitmap pitmap-sim pitmap-eval pitmap-report

rm -rf "$out"
mkdir -p "$out"
echo "=== run-e2e-bench: simulating '$scenario'"
sim_start=$(date +%s.%N)
"$bin/pitmap-sim" synth --scenario "$scenario" --out "$out/sim" > "$out/sim.log" 2>&1 || {
  tail -20 "$out/sim.log"; exit 1; }
sim_s=$(awk -v a="$sim_start" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')

echo "=== run-e2e-bench: pitmap run"
"$bin/pitmap" run "$out/sim/log" --out "$out/products" --no-report 2>&1 | tee "$out/run.log" |
  grep -v '%  \[' || true
[[ -f $out/products/mesh.ply ]] || { echo "run-e2e-bench: pitmap run failed" >&2; exit 1; }
"$bin/pitmap-eval" --truth "$out/sim/truth" --products "$out/products" \
  --json "$out/products/scores.json" > "$out/eval.txt"
report_start=$(date +%s.%N)
"$bin/pitmap" report --out "$out/products" > "$out/report.log" 2>&1 || tail -5 "$out/report.log"
report_s=$(awk -v a="$report_start" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')

echo "=== run-e2e-bench: ray-mode TSDF on the same trajectory"
mkdir -p "$out/ray"
cp "$out/products"/{summary.json,survey.pitmap} "$out/ray/"
printf 'fuse:\n  sensor_model: ray\n' > "$out/ray.yaml"
"$bin/pitmap" fuse --out "$out/ray" --config "$out/ray.yaml" 2>&1 | grep -v '%  \[' || true
"$bin/pitmap" mesh --out "$out/ray" 2>&1 | grep -v '%  \[' || true
"$bin/pitmap-eval" --truth "$out/sim/truth" --products "$out/ray" --json "$out/ray/scores.json" \
  --mesh-common-with "$out/products" > "$out/eval_ray.txt" || true
# Both meshes also on the surface both hold (a mesh with holes is not more accurate for them).
"$bin/pitmap-eval" --truth "$out/sim/truth" --products "$out/products" \
  --json "$out/products/scores.json" --mesh-common-with "$out/ray" > "$out/eval.txt"

python3 - "$out" "$scenario" "$sim_s" "$report_s" <<'PY'
import json, os, sys
out, scenario, sim_s, report_s = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
s = json.load(open(os.path.join(out, "products", "summary.json")))
scores = json.load(open(os.path.join(out, "products", "scores.json")))
ray_s = json.load(open(os.path.join(out, "ray", "summary.json")))
ray_scores = {}
if os.path.exists(os.path.join(out, "ray", "scores.json")):
    ray_scores = json.load(open(os.path.join(out, "ray", "scores.json")))
stages = {n: {"seconds": s["stages"][n]["seconds"],
              "cpu_seconds": s["stages"][n].get("cpu_seconds"),
              "peak_rss_mb": s["stages"][n]["peak_rss_mb"]}
          for n in s["stage_order"]}
# The report stage as `pitmap report` recorded it (its child's CPU and peak), else timed here.
rep = s["stages"].get("report") or {}
stages["report"] = {"seconds": rep.get("seconds", report_s), "cpu_seconds": rep.get("cpu_seconds"),
                    "peak_rss_mb": rep.get("peak_rss_mb")}
fuse = s["stages"]["fuse"]
bench = {
    "scenario": scenario,
    "cores": os.cpu_count(),
    "simulate_seconds": sim_s,
    "run_total_seconds": s["total_seconds"],
    "peak_rss_mb": max(v["peak_rss_mb"] for v in stages.values() if v["peak_rss_mb"]),
    "stages": stages,
    "counts": {"pings": s["stages"]["georef"]["pings_georeferenced"],
               "points": s["stages"]["georef"]["points"],
               "slam_poses": s["stages"].get("slam", {}).get("poses"),
               "active_voxels": fuse["active_voxels"],
               "mesh_triangles": s["stages"]["mesh"]["triangles"]},
    "scores": scores,
    "tsdf_modes": {
        fuse["sensor_model"]: {"integrate_seconds": fuse["integrate_seconds"],
                               "peak_rss_mb": fuse["peak_rss_mb"],
                               "active_voxels": fuse["active_voxels"],
                               **{k: v for k, v in scores.items() if k.startswith("mesh_")}},
        ray_s["stages"]["fuse"]["sensor_model"]: {
            "integrate_seconds": ray_s["stages"]["fuse"]["integrate_seconds"],
            "peak_rss_mb": ray_s["stages"]["fuse"]["peak_rss_mb"],
            "active_voxels": ray_s["stages"]["fuse"]["active_voxels"],
            **{k: v for k, v in ray_scores.items() if k.startswith("mesh_")}}},
}
bench["run_with_report_seconds"] = s["total_seconds"] + stages["report"]["seconds"]
proc = s.get("process") or {}
bench["malloc_huge_pages"] = proc.get("malloc_huge_pages")
json.dump(bench, open(os.path.join(out, "bench.json"), "w"), indent=2)
PY
"$root/tools/bench/benchmarks_page.py" show e2e "$out/bench.json"
echo "bench.json: $out/bench.json"
