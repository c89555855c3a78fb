#!/bin/sh
# SPDX-License-Identifier: MIT
# Regenerates tests/data/novatel/golden/<capture>.json: pitmap-inspect's JSON for every capture
# in tests/data/novatel. The only writer of those files; review the diff before committing it.
#   tools/inspect/regen-golden.sh            # uses build/bin/pitmap-inspect --json --dump-first 2
#   PITMAP_BUILD_DIR=build-x tools/inspect/regen-golden.sh
set -eu
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${PITMAP_BUILD_DIR:-build}
case $build in
  /*) ;;
  *) build=$root/$build ;;
esac
inspect=$build/bin/pitmap-inspect
if [ ! -x "$inspect" ]; then
  echo "regen-golden: $inspect not found; build it first (ninja -C $build pitmap-inspect)" >&2
  exit 1
fi
data=$root/tests/data/novatel
mkdir -p "$data/golden"
count=0
for capture in "$data"/*; do
  [ -f "$capture" ] || continue
  name=$(basename "$capture")
  case $name in
    *.md) continue ;;
  esac
  # Run from the data folder so nothing about this machine's paths reaches the output.
  (cd "$data" && "$inspect" --json --dump-first 2 "$name") > "$data/golden/$name.json.tmp"
  mv "$data/golden/$name.json.tmp" "$data/golden/$name.json"
  count=$((count + 1))
done
echo "regen-golden: wrote $count golden files in tests/data/novatel/golden"
cd "$root" && git status --short -- tests/data/novatel/golden || true
