#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The test command: installs dependencies, configures, builds and runs ctest.
#   tools/run-tests.sh                 # everything
#   tools/run-tests.sh -L unit         # extra arguments go to ctest
# Environment:
#   BUILD_DIR        build folder (default: build)
#   BUILD_TYPE       CMake build type (default: Release)
#   PITMAP_WERROR    ON = warnings are errors (CI sets it)
#   PITMAP_SANITIZE  e.g. address,undefined
#   PITMAP_CMAKE_ARGS extra configure arguments
#   BUILD_TARGETS    build only these targets (default: everything), e.g. "unit-tests" with -L unit
#   CC, CXX          the compilers, read by cmake when it configures a new build folder
#   BUILD_ONLY       1 = configure and build, run no test (CI builds its sanitizer stage so, in
#                    the background, while the Release tests run)
# ctest runs inside a private network namespace (only loopback, multicast routed to it) when
# the machine allows one, so LCM multicast tests never meet other traffic and send nothing out.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
case "$build" in /*) ;; *) build=$root/$build ;; esac

"$root/tools/install-deps.sh"

jobs=$(nproc 2>/dev/null || echo 2)
# shellcheck disable=SC2086
cmake -S "$root" -B "$build" -G Ninja \
  -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-Release}" \
  -DPITMAP_WARNINGS_AS_ERRORS="${PITMAP_WERROR:-OFF}" \
  -DPITMAP_SANITIZE="${PITMAP_SANITIZE:-}" \
  ${PITMAP_CMAKE_ARGS:-} > "$build.configure.log" 2>&1 || {
    cat "$build.configure.log"; echo "run-tests: configure failed" >&2; exit 1; }
echo "run-tests: configured $build (${BUILD_TYPE:-Release}${PITMAP_SANITIZE:+, sanitizers: $PITMAP_SANITIZE})"
# shellcheck disable=SC2086
cmake --build "$build" -j "$jobs" ${BUILD_TARGETS:+--target $BUILD_TARGETS}
if [[ ${BUILD_ONLY:-0} == 1 ]]; then
  echo "run-tests: built $build (BUILD_ONLY=1: no test run)"
  exit 0
fi

ctest_cmd=(ctest --test-dir "$build" --output-on-failure -j "$jobs" "$@")
if unshare -n true 2>/dev/null; then
  echo "run-tests: running ctest in a private network namespace"
  unshare -n bash -c 'ip link set lo up && ip link set lo multicast on &&
                      ip route add 224.0.0.0/4 dev lo && exec "$@"' bash "${ctest_cmd[@]}"
else
  echo "run-tests: no network namespace available; running ctest in the host namespace"
  "${ctest_cmd[@]}"
fi
