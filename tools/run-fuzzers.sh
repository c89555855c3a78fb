#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Builds the libFuzzer targets (tests/fuzz/*_fuzz.cpp) with clang and runs each for a bounded
# time, seeded with tests/fuzz/seeds/<target>/ (small product and config files), else the real
# captures in tests/data/<target>/. A crash, leak or sanitizer report fails.
#   tools/run-fuzzers.sh [seconds-per-target]     (default 60; CI uses 10)
#   FUZZ_TARGETS="ply_fuzz novatel_fuzz" tools/run-fuzzers.sh 30   (only those targets)
# The product and config targets need the processor and daemon libraries, so both are built
# (with clang, only what the fuzz targets link) in build-fuzz/.
#   BUILD_DIR=build-san tools/run-fuzzers.sh 10   (CI) reuses a build folder that was already
#       configured with clang and PITMAP_BUILD_FUZZERS=ON (e.g. with PITMAP_SANITIZE and the
#       tests too): no second configure, and only fuzz targets not yet built are built.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-60}
build=${BUILD_DIR:-$root/build-fuzz}
case "$build" in /*) ;; *) build=$root/$build ;; esac
"$root/tools/install-deps.sh"

if [[ -f $build/CMakeCache.txt ]] && grep -q '^PITMAP_BUILD_FUZZERS:BOOL=ON$' "$build/CMakeCache.txt"; then
  echo "run-fuzzers: reusing $build (configured with PITMAP_BUILD_FUZZERS=ON)"
elif [[ -f $build/CMakeCache.txt && -n ${BUILD_DIR:-} ]]; then
  # Reconfiguring with another compiler would wipe that build folder's cache.
  echo "run-fuzzers: $build is a build without PITMAP_BUILD_FUZZERS=ON; choose another BUILD_DIR" >&2
  exit 1
else
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DPITMAP_BUILD_FUZZERS=ON -DPITMAP_BUILD_PROCESSOR=ON -DPITMAP_BUILD_TOOLS=OFF \
    -DPITMAP_BUILD_FIRMWARE_HOST=ON -DPITMAP_BUILD_BENCHMARKS=OFF -DPITMAP_BUILD_TESTS=OFF \
    > "$build.configure.log" 2>&1 || {
      cat "$build.configure.log"; echo "run-fuzzers: configure failed" >&2; exit 1; }
fi
shopt -s nullglob
targets=()
if [[ -n ${FUZZ_TARGETS:-} ]]; then
  read -r -a targets <<< "$FUZZ_TARGETS"
else
  for src in "$root"/tests/fuzz/*_fuzz.cpp; do targets+=("$(basename "${src%.cpp}")"); done
fi
if [[ ${#targets[@]} -eq 0 ]]; then
  echo "run-fuzzers: no fuzz targets"; exit 0
fi
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" --target "${targets[@]}"

# One fuzz target per core at a time (FUZZ_JOBS, default nproc): each libFuzzer run is a single
# process on one core, so 14 targets x 20 s take 140 s of wall time on 2 cores instead of 280 s.
jobs=${FUZZ_JOBS:-$(nproc 2>/dev/null || echo 2)}
(( jobs >= 1 )) || jobs=1

run_one() {  # $1 = target; its log is $build/fuzz/$1.log, its verdict the exit status
  local t=$1 corpus seeds label rc=0
  corpus=$(mktemp -d)
  seeds="$root/tests/fuzz/seeds/${t%_fuzz}"
  [[ -d $seeds ]] || seeds="$root/tests/data/fuzz/${t%_fuzz}"
  [[ -d $seeds ]] || seeds="$root/tests/data/${t%_fuzz}"
  [[ -d $seeds ]] || seeds=""
  label=none
  [[ -n $seeds ]] && label=${seeds#"$root"/}
  echo "run-fuzzers: $t for ${seconds} s (seeds: $label)"
  "$build/fuzz/$t" -max_total_time="$seconds" -max_len=65536 -print_final_stats=1 \
      -artifact_prefix="$build/fuzz/$t-" "$corpus" ${seeds:+"$seeds"} > "$build/fuzz/$t.log" 2>&1 ||
    rc=$?
  rm -rf "$corpus"
  return $rc
}

report() {  # $1 = target, $2 = its exit status; prints the verdict in one block
  local t=$1
  if [[ $2 -ne 0 ]]; then
    echo "run-fuzzers: $t FAILED (exit $2); last lines of its log:"
    tail -n 40 "$build/fuzz/$t.log"
  else
    grep -E 'stat::number_of_executed_units|stat::peak_rss_mb' "$build/fuzz/$t.log" | sed "s/^/  $t /"
  fi
}

status=0
declare -A running=()  # pid -> target
wait_one() {
  local pid rc=0
  wait -n -p pid "${!running[@]}" || rc=$?
  report "${running[$pid]}" "$rc"
  [[ $rc -eq 0 ]] || status=1
  unset "running[$pid]"
}
for t in "${targets[@]}"; do
  while (( ${#running[@]} >= jobs )); do wait_one; done
  run_one "$t" &
  running[$!]=$t
done
while (( ${#running[@]} > 0 )); do wait_one; done
exit $status
