#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The clean stage's cost (issue 35: <= 10 % of `pitmap run`): runs `pitmap run --no-report` on a
# simulated survey RUNS times and prints, per run, the clean stage's seconds (both passes: the
# first before the calibration, `earlier_pass`, and the final one, with its parts) against the
# whole run's, wall and CPU, from the same summary.json; then the spread over the runs. On a
# shared machine the CPU share is the steadier of the two.
#   tools/bench/run-clean-bench.sh SIM [RUNS] [OUT]   (SIM: a pitmap-sim synth folder;
#   defaults: 3 runs, out/bench/clean)
# e.g. build/bin/pitmap-sim synth --scenario bejanca --vendor-files --echo-artifacts typical --out S
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
sim=${1:?usage: run-clean-bench.sh SIM [RUNS] [OUT]}
runs=${2:-3}
out=${3:-$root/out/bench/clean}
bin=${BUILD_DIR:-$root/build}/bin
[[ -d $sim/log ]] || { echo "run-clean-bench: $sim/log: no such folder (a pitmap-sim synth output)" >&2; exit 1; }
mkdir -p "$out"
for i in $(seq 1 "$runs"); do
  rm -rf "$out/P$i"
  "$bin/pitmap" run "$sim/log" --out "$out/P$i" --no-report > "$out/run$i.log" 2>&1 || {
    tail -5 "$out/run$i.log"; echo "run-clean-bench: pitmap run failed" >&2; exit 1; }
done
python3 - "$out" "$runs" <<'PY'
import json, os, sys
out, runs = sys.argv[1], int(sys.argv[2])
wall, cpu = [], []
for i in range(1, runs + 1):
    st = json.load(open(os.path.join(out, f"P{i}", "summary.json")))["stages"]
    c = st["clean"]
    first = c.get("earlier_pass") or {}
    stages = [v for v in st.values() if isinstance(v, dict)]
    tw = sum(v.get("seconds", 0) for v in stages) + first.get("seconds", 0)
    tc = sum(v.get("cpu_seconds", 0) for v in stages) + first.get("cpu_seconds", 0)
    cw = c["seconds"] + first.get("seconds", 0)
    cc = c["cpu_seconds"] + first.get("cpu_seconds", 0)
    wall.append(100 * cw / tw)
    cpu.append(100 * cc / tc)
    parts = ", ".join(f"{k[8:]} {c[k]:.2f}" for k in sorted(c) if k.startswith("seconds_"))
    print(f"run {i}: clean {cw:.2f} s of {tw:.1f} s wall ({wall[-1]:.1f} %), "
          f"{cc:.2f} s of {tc:.1f} s CPU ({cpu[-1]:.1f} %); first pass {first.get('seconds', 0):.2f} s, "
          f"final {c['seconds']:.2f} s ({parts})")
print(f"clean share of the run over {runs} runs: wall {min(wall):.1f}-{max(wall):.1f} %, "
      f"CPU {min(cpu):.1f}-{max(cpu):.1f} %")
PY
