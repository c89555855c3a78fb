#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The main job: installs dependencies, builds, then runs the demo survey end to end:
#   1. the simulated sensors (tools/, HIL rig) feed the real daemon (pitmap-acqd) -> LCM log,
#      while pitmap-live shows the coverage and alarms on http://127.0.0.1:8765/ (LIVE_PORT)
#   2. the processor (pitmap run) turns the log into products and a report
#   3. the scorer (pitmap-eval) compares the products with the simulator's ground truth
# Products land in out/demo/. Each step runs when its program exists; a missing one is named.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
out=${OUT_DIR:-$root/out/demo}
bin=$build/bin

"$root/tools/install-deps.sh"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release > "$build.configure.log" 2>&1 || {
  cat "$build.configure.log"; echo "run-demo: configure failed" >&2; exit 1; }
# Only what the demo runs (the tests and benchmarks are built by tools/run-tests.sh).
targets=()
for t in pitmap pitmap-acqd pitmap-sim pitmap-eval pitmap-inspect pitmap-report pitmap-live; do
  ninja -C "$build" -t query "$t" > /dev/null 2>&1 && targets+=(--target "$t")
done
start=$(date +%s)
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" "${targets[@]}"
mkdir -p "$out"

missing=()
step() { echo; echo "=== run-demo: $*"; }

if [[ -x $bin/pitmap-inspect ]]; then
  step "checking the real NovAtel captures with pitmap-inspect"
  for f in "$root"/tests/data/novatel/*; do
    [[ -f $f ]] || continue
    case "$f" in *.md|*.json) continue ;; esac
    "$bin/pitmap-inspect" "$f" | head -n 4
  done
else
  missing+=("pitmap-inspect (wire protocols, issue 3)")
fi

if [[ -x $bin/pitmap-sim && -x $bin/pitmap-acqd ]]; then
  step "simulated survey 'demo' through the real daemon"
  rm -rf "$out/sim" "$out/products" "$out/live"   # the demo's own output of an earlier run
  # The live view beside the daemon: the daemon publishes on a multicast URL of its own (ttl=0:
  # nothing leaves this machine) and pitmap-live serves the page on 127.0.0.1. Without a
  # multicast route (a machine with no network) the daemon keeps memq:// and the demo runs
  # without the live view.
  live_url="udpm://239.255.76.67:7671?ttl=0&recv_buf_size=4194304"
  live_port=${LIVE_PORT:-8765}
  hil_lcm=(--lcm-url "memq://")
  live_pid=
  trap '[[ -n ${live_pid:-} ]] && kill -TERM "$live_pid" 2> /dev/null; true' EXIT
  if [[ -x $bin/pitmap-live ]] && ip route get 239.255.76.67 > /dev/null 2>&1; then
    mkdir -p "$out/live"
    "$bin/pitmap-live" --lcm-url "$live_url" --port "$live_port" --out "$out/live" \
      --cell-size 0.5 --snapshot-on-exit --status-json "$out/live/status.json" \
      > "$out/live/pitmap-live.out" 2>&1 &
    live_pid=$!
    sleep 0.5
    if kill -0 "$live_pid" 2> /dev/null; then
      hil_lcm=(--lcm-url "$live_url")
      echo "run-demo: live view of the survey: open http://127.0.0.1:$live_port/ now"
    else
      echo "run-demo: pitmap-live did not start (see $out/live/pitmap-live.out); no live view"
      live_pid=
    fi
  else
    echo "run-demo: no multicast route here: the survey runs without the live view"
  fi
  "$bin/pitmap-sim" hil --scenario demo --out "$out/sim" --acqd "$bin/pitmap-acqd" "${hil_lcm[@]}"
  if [[ -n $live_pid ]]; then
    kill -TERM "$live_pid"; wait "$live_pid" || true
    live_pid=
    echo "run-demo: live view stopped; its last grid and status are in $out/live"
  fi
else
  [[ -x $bin/pitmap-acqd ]] || missing+=("pitmap-acqd (acquisition daemon, issue 4)")
  [[ -x $bin/pitmap-sim ]] || missing+=("pitmap-sim (simulated sensors and HIL rig, issue 5)")
fi

if [[ -x $bin/pitmap && -d $out/sim/log ]]; then
  step "processing: pitmap run (ingest, georef, calibrate, SLAM, TSDF, mesh, report)"
  "$bin/pitmap" run "$out/sim/log" --out "$out/products"
else
  [[ -x $bin/pitmap ]] || missing+=("pitmap run (processor, issues 6-9)")
fi

if [[ -x $bin/pitmap-eval && -d $out/products ]]; then
  step "scoring against ground truth"
  "$bin/pitmap-eval" --truth "$out/sim/truth" --products "$out/products" \
    --json "$out/products/scores.json"
  if [[ -x $bin/pitmap-report ]]; then
    step "report with the scores"
    "$bin/pitmap" report --out "$out/products"
  fi
else
  [[ -x $bin/pitmap-eval ]] || missing+=("pitmap-eval (scorer, issue 5)")
fi

echo
if [[ ${#missing[@]} -gt 0 ]]; then
  echo "run-demo: the demo is not complete yet; these parts do not exist:"
  printf '  - %s\n' "${missing[@]}"
else
  echo "run-demo: built and ran in $(( $(date +%s) - start )) s."
  echo "  products: $out/products (points.ply/.las, trajectory.csv, tsdf.vdb, mesh.ply/.obj/.glb)"
  echo "  report:   $out/products/report.html"
  echo "  scores:   $out/products/scores.json"
  if [[ -d $out/live ]]; then
    echo "  live:     $out/live (the live view's last coverage grid and status)"
  fi
fi
