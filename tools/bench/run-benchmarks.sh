#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Runs benchmarks, stores each result with its context in docs/benchmarks/NAME.json and writes
# docs/benchmarks.md from them (tools/bench/benchmarks_page.py), so the page's figures are the
# last measured ones by construction.
#   tools/bench/run-benchmarks.sh [micro] [e2e] [grid] [compare] [live] [scale] [all]   (default: micro)
#     micro  the Google Benchmark programs (pitmap-bench-deltat, -novatel, -edit_select), 3
#            repetitions each, medians; about a minute
#     e2e    tools/bench/run-e2e-bench.sh bejanca: `pitmap run` stage by stage; minutes
#     grid   tools/bench/run-grid-bench.sh bejanca: the grid stage's parts; minutes
#     compare tools/bench/run-compare-bench.sh bejanca: two epochs through pitmap run, then
#            pitmap compare without and with its report; minutes (SIM1/SIM2, P1/P2 reuse)
#     live   pitmap-bench-live_latency: ping-to-page latency at 1x over 60 s of a demo survey
#     scale  tools/bench/run-scale-bench.sh: bejanca at 1x and 2x its duration (SCALES="1 2 4"
#            for more); tens of minutes
# BUILD_DIR (default build) is the Release build to measure. Measure on an idle machine: the
# page states the load average before and after each run.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=${BUILD_DIR:-$root/build}
export BUILD_DIR=$build
page=$root/tools/bench/benchmarks_page.py
work=${BENCH_WORK:-$root/out/bench}

which=("$@")
[[ ${#which[@]} -eq 0 ]] && which=(micro)
[[ ${which[*]} == all ]] && which=(micro live e2e grid)
for w in "${which[@]}"; do
  case $w in micro|e2e|grid|live|scale) ;; *) echo "run-benchmarks: unknown benchmark '$w' (micro, e2e, grid, live, scale, all)" >&2; exit 2 ;; esac
done

load() { cut -d' ' -f1 /proc/loadavg; }
mkdir -p "$work"

for w in "${which[@]}"; do
  before=$(load)
  case $w in
    micro)
      programs=(deltat novatel edit_select)
      cmake --build "$build" -j 2 --target "${programs[@]/#/pitmap-bench-}" > /dev/null
      for p in "${programs[@]}"; do
        echo "=== run-benchmarks: pitmap-bench-$p"
        "$build/bin/pitmap-bench-$p" --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
          --benchmark_out="$work/micro-$p.json" --benchmark_out_format=json > /dev/null
      done
      python3 - "$work" "${programs[@]}" > "$work/micro.json" <<'PY'
import json, os, sys
work, programs = sys.argv[1], sys.argv[2:]
out = {"programs": {}}
for p in programs:
    r = json.load(open(os.path.join(work, f"micro-{p}.json")))
    out["programs"][f"pitmap-bench-{p}"] = r["benchmarks"]
json.dump(out, sys.stdout, indent=1)
PY
      result=$work/micro.json ;;
    e2e)
      "$root/tools/bench/run-e2e-bench.sh" bejanca "$work/bejanca"
      result=$work/bejanca/bench.json ;;
    grid)
      "$root/tools/bench/run-grid-bench.sh" bejanca "$work/grid-bejanca"
      result=$work/grid-bejanca/grid.json ;;
    compare)
      "$root/tools/bench/run-compare-bench.sh" bejanca "$work/compare-bejanca"
      result=$work/compare-bejanca/compare.json ;;
    scale)
      "$root/tools/bench/run-scale-bench.sh" --scales "${SCALES:-1 2}" --out "$work/scale"
      result=$work/scale/scale.json ;;
    live)
      cmake --build "$build" -j 2 --target pitmap-sim pitmap-bench-live_latency > /dev/null
      rm -rf "$work/live-sim"
      echo "=== run-benchmarks: simulating 'demo' (120 s) for pitmap live"
      "$build/bin/pitmap-sim" synth --scenario demo --duration 120 --out "$work/live-sim" \
        > "$work/live-sim.log" 2>&1 || { tail -20 "$work/live-sim.log"; exit 1; }
      before=$(load)
      "$build/bin/pitmap-bench-live_latency" "$work"/live-sim/log/*.lcmlog \
        --vehicle "$work/live-sim/log/vehicle.yaml" --seconds 60 --json "$work/live.json"
      result=$work/live.json ;;
  esac
  "$page" publish "$w" "$result" --load-before "$before"
done
"$page" render
