#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Repeat-survey benchmark (issue 37): two epochs of a simulated pit (default bejanca:
# `pitmap-sim synth --epoch 1` and `--epoch 2`), each through `pitmap run --no-report`, then
# `pitmap compare` of the two without and with its change report: the user and system CPU
# seconds, wall seconds and peak resident memory of each compare (getrusage of the child), the
# parts compare.json records (cost.timings_wall_cpu_s), and pitmap-eval's change scores.
#   tools/bench/run-compare-bench.sh [SCENARIO] [OUT]   (defaults: bejanca, out/bench/compare-SCENARIO)
# Writes OUT/compare.json; `tools/bench/run-benchmarks.sh compare` stores it for
# docs/benchmarks.md. SIM1=DIR SIM2=DIR reuse simulations made before (DIR/log, DIR/truth);
# P1=DIR P2=DIR reuse products folders of them (pitmap run on SIM1 and SIM2).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
scenario=${1:-bejanca}
out=${2:-$root/out/bench/compare-$scenario}
build=${BUILD_DIR:-$root/build}
bin=$build/bin
cmake --build "$build" -j 2 --target pitmap pitmap-sim pitmap-eval pitmap-report > /dev/null

mkdir -p "$out"
for k in 1 2; do
  sim_var=SIM$k
  sim=${!sim_var:-$out/sim$k}
  if [[ -z ${!sim_var:-} ]]; then
    rm -rf "$sim"
    echo "=== run-compare-bench: simulating '$scenario' epoch $k"
    "$bin/pitmap-sim" synth --scenario "$scenario" --epoch "$k" --out "$sim" > "$out/sim$k.log" 2>&1 || {
      tail -20 "$out/sim$k.log"; exit 1; }
  fi
  eval "sim$k=\$sim"
  p_var=P$k
  if [[ -z ${!p_var:-} ]]; then
    rm -rf "$out/p$k"
    echo "=== run-compare-bench: pitmap run epoch $k"
    "$bin/pitmap" run "$sim/log" --out "$out/p$k" --no-report > "$out/run$k.log" 2>&1 || {
      grep -v '%  \[' "$out/run$k.log" | tail -20; exit 1; }
    eval "p$k=\$out/p$k"
  else
    eval "p$k=\${!p_var}"
  fi
done

echo "=== run-compare-bench: pitmap compare (without and with the report), pitmap-eval"
python3 - "$bin" "$p1" "$p2" "$out" "$sim2" "$scenario" <<'PY'
import json, os, resource, shutil, subprocess, sys, time
bin_dir, p1, p2, out, sim2, scenario = sys.argv[1:7]

def timed(args, log):
    """Run a command; its user and system CPU s, wall s and peak RSS (MB) from getrusage."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    with open(log, "w") as f:
        rc = subprocess.run(args, stdout=f, stderr=subprocess.STDOUT).returncode
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if rc not in (0,):
        print(open(log).read()[-3000:])
        sys.exit(f"run-compare-bench: {' '.join(args)} exited {rc}")
    return {"user_s": after.ru_utime - before.ru_utime, "system_s": after.ru_stime - before.ru_stime,
            "cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "wall_s": wall, "peak_rss_mb": after.ru_maxrss / 1024.0}

runs = {}
for name, extra in (("no_report", ["--no-report"]), ("with_report", [])):
    c = os.path.join(out, "c-" + name)
    shutil.rmtree(c, ignore_errors=True)
    runs[name] = timed([os.path.join(bin_dir, "pitmap"), "compare", p1, p2, "--out", c] + extra,
                       os.path.join(out, f"compare-{name}.log"))
    runs[name]["parts"] = json.load(open(os.path.join(c, "compare.json"))).get("cost", {})
c = os.path.join(out, "c-no_report")
subprocess.run([os.path.join(bin_dir, "pitmap-eval"), "--truth", os.path.join(sim2, "truth"),
                "--products", c, "--json", os.path.join(c, "eval.json")], check=True,
               stdout=subprocess.DEVNULL)
sc = json.load(open(os.path.join(c, "eval.json")))
cj = json.load(open(os.path.join(c, "compare.json")))
keep = ("change_", "change3d_region_", "change3d_stable", "change3d_wall", "registration_",
        "capacity_b_volume_error_pct")
bench = {"scenario": scenario,
         "resolution_match": cj.get("resolution_match", {}),
         "soundings": {k: json.load(open(os.path.join(p, "summary.json")))["stages"]["grid"]["soundings"]
                       for k, p in (("a", p1), ("b", p2))},
         "runs": runs,
         "scores": {k: v for k, v in sc.items() if k.startswith(keep) and isinstance(v, (int, float))}}
json.dump(bench, open(os.path.join(out, "compare.json"), "w"), indent=1)
PY
"$root/tools/bench/benchmarks_page.py" show compare "$out/compare.json"
