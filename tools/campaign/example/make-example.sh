#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The example campaign's surveys: four short simulated surveys of the demo pit (seeds 1-4,
# DURATION seconds each, default 30; the last with a refracting water column and its cast)
# in WORK/surveys/epochN, and the campaign files in WORK/: campaign.yaml, and
# campaign-tiles.yaml with its tiles.yaml (epoch1 by tiles beside epoch2 whole).
#   tools/campaign/example/make-example.sh WORK [DURATION]
# BIN_DIR: the folder of pitmap-sim (default build/bin).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../../.." && pwd)
work=${1:?usage: make-example.sh WORK [DURATION]}
duration=${2:-30}
bin=${BIN_DIR:-$root/build/bin}
mkdir -p "$work/surveys"
for n in 1 2 3 4; do
  dir=$work/surveys/epoch$n
  if [[ -d $dir/log ]]; then continue; fi
  extra=()
  [[ $n == 4 ]] && extra=(--refraction)
  "$bin/pitmap-sim" synth --scenario demo --seed "$n" --duration "$duration" --out "$dir" \
    "${extra[@]}" > "$work/surveys/epoch$n.sim.log" 2>&1
done
cp "$here/campaign.yaml" "$here/campaign-tiles.yaml" "$here/tiles.yaml" "$work/"
echo "make-example: $work/campaign.yaml (4 surveys of $duration s), $work/campaign-tiles.yaml"
