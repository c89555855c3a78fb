#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Scale benchmark (issue 38): the bejanca pit surveyed for 1x, 2x (4x, 8x on request) its
# 1 278.6 s, each survey through `pitmap run --no-report` under /usr/bin/time -v. Writes
#   OUT/scale.json  per scale: duration, pings, the wall time and peak RSS of the whole run
#                   (time -v), every stage's seconds, CPU seconds and peak RSS (summary.json),
#                   and the simulator's own time and peak RSS
#   OUT/scale.md    the same as a markdown table (the stages that take the time)
#   tools/bench/run-scale-bench.sh [--scales "1 2"] [--out DIR] [--scenario NAME]
#                                  [--keep-products] [--report-only] [--no-eval]
# --report-only: no runs, the tables again from what OUT holds.
# Each run's products are scored by pitmap-eval against the simulator's truth (SLAM's ATE and
# the points' RMS: OUT/eval-<scale>x.json) unless --no-eval; the whole run's CPU seconds (the
# stages' summed, summary.json) and their ratio to the first scale are the cost (on a shared
# machine wall time is the load's). A scale may be fractional (11.259 = 14 400 s of bejanca).
# Peak memory is summary.json's (the largest of the stages' VmHWM): `pitmap` resets the kernel's
# high-water mark at each stage (common/peak_memory.hpp), so time -v's maximum RSS is only the
# last stage's peak; it is kept as time_v_max_rss_mb.
# Defaults: scales "1 2", OUT out/bench/scale, scenario bejanca. BUILD_DIR (default build)
# names the build; BIN_DIR (default BUILD_DIR/bin, not rebuilt when given) the folder of
# pitmap and pitmap-sim, e.g. copies of a baseline build. One run at a time: the figures are only meaningful on an otherwise idle
# machine (docs/benchmarks.md, "Longer surveys of one pit"). The simulations are kept in OUT/sim-<scale>x and
# reused when their log folder is there (delete them to simulate again).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
scales="1 2"
out=$root/out/bench/scale
scenario=bejanca
keep=0
report_only=0
evaluate=1
while [[ $# -gt 0 ]]; do
  case $1 in
    --scales) scales=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scenario) scenario=$2; shift 2 ;;
    --keep-products) keep=1; shift ;;
    --report-only) report_only=1; shift ;;
    --no-eval) evaluate=0; shift ;;
    -h|--help) sed -n '3,19p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "run-scale-bench: unknown argument '$1' (--help)" >&2; exit 2 ;;
  esac
done
for s in $scales; do
  [[ $s =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "run-scale-bench: bad scale '$s'" >&2; exit 2; }
done
[[ -x /usr/bin/time ]] || { echo "run-scale-bench: /usr/bin/time missing (apt-get install time)" >&2; exit 2; }
build=${BUILD_DIR:-$root/build}
if [[ -n ${BIN_DIR:-} ]]; then
  bin=$BIN_DIR
else
  bin=$build/bin
  cmake --build "$build" -j 2 --target pitmap pitmap-sim pitmap-eval > /dev/null
fi
mkdir -p "$out"

# The scenario's own duration, from `pitmap-sim scenarios` ("name: ... N s ...").
base=$("$bin/pitmap-sim" scenarios | python3 -c '
import re, sys
name = sys.argv[1]
for line in sys.stdin:
    m = re.match(r"\s*(\S+)\s.*?([0-9.]+) s\b", line)
    if m and m.group(1).rstrip(":") == name:
        print(m.group(2)); break
else:
    sys.exit("run-scale-bench: scenario %s not in pitmap-sim scenarios" % name)
' "$scenario")

for s in $scales; do
  [[ $report_only == 1 ]] && break
  dur=$(python3 -c "print(round($base * $s, 1))")
  sim=$out/sim-${s}x
  if [[ ! -d $sim/log ]]; then
    rm -rf "$sim"
    echo "=== run-scale-bench: simulating $scenario for $dur s (${s}x)"
    /usr/bin/time -v -o "$out/sim-${s}x.time" \
      "$bin/pitmap-sim" synth --scenario "$scenario" --duration "$dur" --out "$sim" \
      > "$out/sim-${s}x.log" 2>&1 || { tail -20 "$out/sim-${s}x.log"; exit 1; }
  fi
  echo "=== run-scale-bench: pitmap run --no-report on ${s}x ($dur s)"
  rm -rf "$out/products-${s}x"
  /usr/bin/time -v -o "$out/run-${s}x.time" \
    "$bin/pitmap" run "$sim/log" --out "$out/products-${s}x" --no-report \
    > "$out/run-${s}x.log" 2>&1 || { grep -v '%  \[' "$out/run-${s}x.log" | tail -20; exit 1; }
  cp "$out/products-${s}x/summary.json" "$out/summary-${s}x.json"
  if [[ $evaluate == 1 ]]; then
    "$bin/pitmap-eval" --truth "$sim/truth" --products "$out/products-${s}x" \
      --json "$out/eval-${s}x.json" > "$out/eval-${s}x.log" 2>&1 || { tail -20 "$out/eval-${s}x.log"; exit 1; }
  fi
  [[ $keep == 1 ]] || rm -rf "$out/products-${s}x"
done

python3 - "$out" "$scenario" "$base" $scales <<'PY'
import json, os, re, sys
out, scenario, base = sys.argv[1], sys.argv[2], float(sys.argv[3])
scales = sys.argv[4:]

def time_v(path):
    """Wall seconds and peak RSS (MB) from a /usr/bin/time -v file."""
    if not os.path.exists(path):
        return None, None
    text = open(path).read()
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([0-9:.]+)", text)
    seconds = None
    if wall:
        seconds = 0.0
        for part in wall.group(1).split(":"):
            seconds = seconds * 60 + float(part)
    return seconds, (int(rss.group(1)) / 1024.0 if rss else None)

rows = []
for s in scales:
    summary = json.load(open(os.path.join(out, f"summary-{s}x.json")))
    wall, rss = time_v(os.path.join(out, f"run-{s}x.time"))
    sim_wall, sim_rss = time_v(os.path.join(out, f"sim-{s}x.time"))
    stages = {}
    for name, st in summary.get("stages", {}).items():
        if isinstance(st, dict) and "seconds" in st:
            stages[name] = {k: st[k] for k in ("seconds", "cpu_seconds", "peak_rss_mb") if k in st}
    scores = {}
    eval_path = os.path.join(out, f"eval-{s}x.json")
    if os.path.exists(eval_path):
        e = json.load(open(eval_path))
        scores = {k: e.get(k) for k in ("trajectory_ate_rmse_m", "trajectory_ate_rmse_before_m",
                                         "points_rms_m")}
    slam = summary.get("stages", {}).get("slam", {})
    factors = [it.get("factor_nonzeros") for it in slam.get("iterations", [])
               if isinstance(it, dict) and it.get("factor_nonzeros")]
    rows.append({
        "scale": float(s),
        "duration_s": round(base * float(s), 1),
        "pings": summary.get("stages", {}).get("georef", {}).get("pings_in"),
        "soundings": summary.get("soundings", {}).get("total"),
        "total_seconds": summary.get("total_seconds"),
        "wall_seconds": wall,
        "peak_rss_mb": max((st["peak_rss_mb"] for st in stages.values() if "peak_rss_mb" in st),
                           default=None),
        "time_v_max_rss_mb": rss,
        "stages": stages,
        "sim_wall_seconds": sim_wall,
        "sim_peak_rss_mb": sim_rss,
        "cores": summary.get("process", {}).get("cores"),
        "cpu_seconds": sum(st.get("cpu_seconds", 0.0) for st in stages.values()),
        "scores": scores,
        "slam_largest_factor_nonzeros": max(factors) if factors else None,
        "slam_posterior_seconds": (slam.get("posterior") or {}).get("seconds"),
    })
result = {"scenario": scenario, "base_duration_s": base, "runs": rows}
json.dump(result, open(os.path.join(out, "scale.json"), "w"), indent=2)

cols = ["georef", "calibrate", "slam", "clean", "grid", "fuse", "mesh"]
def f(v, fmt="{:.1f}"):
    return "-" if v is None else fmt.format(v)
lines = [f"{scenario}, `pitmap run --no-report`, {rows[0]['cores'] if rows else '?'} cores; "
         "CPU seconds (user + sys) and peak RSS (largest stage VmHWM) from summary.json; "
         "wall: the whole run's",
         "",
         "| scale | duration (s) | soundings | wall (s) | CPU (s) | CPU ratio | " +
         " | ".join(cols) + " | peak RSS (MB) | stage at peak | ATE (m) | points RMS (m) |",
         "|---:|---:|---:|---:|---:|---:|" + "---:|" * len(cols) + "---:|---|---:|---:|"]
c1 = rows[0]["cpu_seconds"] if rows else None
for r in rows:
    st = r["stages"]
    peak_stage = max(st.items(), key=lambda kv: kv[1].get("peak_rss_mb", 0))[0] if st else "-"
    ratio = r["cpu_seconds"] / c1 if c1 else None
    # fuse and mesh run twice (initial, final): summed.
    def cpu(c):
        keys = [c] + ([c + "_initial"] if c in ("fuse", "mesh") else [])
        vals = [st[k]["cpu_seconds"] for k in keys if k in st and "cpu_seconds" in st[k]]
        return sum(vals) if vals else None
    sc = r["scores"]
    lines.append(f"| {r['scale']:g}x | {r['duration_s']:.0f} | {f(r['soundings'], '{:,}')} | "
                 f"{f(r['total_seconds'])} | {f(r['cpu_seconds'])} | {f(ratio, '{:.2f}')} | " +
                 " | ".join(f(cpu(c)) for c in cols) +
                 f" | {f(r['peak_rss_mb'], '{:.0f}')} | {peak_stage} | "
                 f"{f(sc.get('trajectory_ate_rmse_m'), '{:.4f}')} | "
                 f"{f(sc.get('points_rms_m'), '{:.4f}')} |")
if c1:
    lines += ["", "CPU ratio " + " : ".join(f"{r['cpu_seconds'] / c1:.2f}" for r in rows) +
              " at " + " : ".join(f"{r['scale']:g}" for r in rows) +
              "x (linear: the scales; issue 38: 1 : <= 2.2 : <= 4.5 : <= 9 at 1 : 2 : 4 : 8)"]
lines += ["", "| scale | simulator wall (s) | simulator peak RSS (MB) |", "|---:|---:|---:|"]
for r in rows:
    lines.append(f"| {r['scale']:g}x | {f(r['sim_wall_seconds'])} | {f(r['sim_peak_rss_mb'], '{:.0f}')} |")
open(os.path.join(out, "scale.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
