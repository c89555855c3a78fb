#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The memory benchmark's result from the summary.json of `pitmap run` (issue 38).

Each run is a build (a label such as `before` or `after`), a scale of the scenario (its duration
over the base one) and a products folder; the result holds each stage's peak resident memory
(summary.json stages.*.peak_rss_mb) and CPU seconds (stages.*.cpu_seconds), the grid stage's parts (stages.grid.peak_rss_mb_by_part,
where the build records them), SLAM's own arrays (stages.slam.arrays_mb, where recorded) and the
soundings, for benchmarks_page.py (section `memory`):

  memory_result.py OUT.json --scenario bejanca --run before 1 P1 --run after 1 P2 ...
  benchmarks_page.py publish memory OUT.json
"""

import argparse
import json
import os
import sys


def run_of(label, scale, folder):
    path = os.path.join(folder, "summary.json")
    with open(path) as f:
        s = json.load(f)
    stages = {n: s["stages"][n]["peak_rss_mb"] for n in s["stage_order"] if n in s["stages"]}
    cpu_s = {n: s["stages"][n].get("cpu_seconds") for n in s["stage_order"] if n in s["stages"]}
    grid = s["stages"].get("grid", {})
    # A run stopped before its export has the georef stage's counts only.
    georef = s["stages"].get("georef", {})
    soundings = s["soundings"]["total"] if "soundings" in s else georef["soundings_in"]
    pings = s["soundings"]["pings"]["in"] if "soundings" in s else georef["pings_in"]
    return {
        "build": label,
        "scale": float(scale),
        "soundings": soundings,
        "pings": pings,
        "complete": "soundings" in s,
        "stages": stages,
        "cpu_s": cpu_s,
        "grid_parts": grid.get("peak_rss_mb_by_part", {}),
        "slam_arrays": s["stages"].get("slam", {}).get("arrays_mb", {}),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--run", nargs=3, action="append", required=True,
                    metavar=("BUILD", "SCALE", "PRODUCTS"))
    args = ap.parse_args()
    result = {"scenario": args.scenario, "runs": [run_of(*r) for r in args.run]}
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
