#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Builds the Debian packages with CMake and CPack (docs/packages.md):
#   pitmap-acqd  from the daemon-only build (the vehicle's: PITMAP_BUILD_PROCESSOR=OFF,
#                PITMAP_BUILD_TESTS=OFF)  -> $VEHICLE_BUILD_DIR/packages/pitmap-acqd_<v>_<arch>.deb
#   pitmap       from the full build      -> $BUILD_DIR/packages/pitmap_<v>_<arch>.deb
# Usage: tools/build-packages.sh [both|acqd|shore]     (default: both)
# Environment:
#   BUILD_DIR          the full build (default: build)
#   VEHICLE_BUILD_DIR  the daemon-only build (default: build-vehicle)
#   PITMAP_CMAKE_ARGS  extra configure arguments for a new build folder (e.g. the ccache launcher)
# A build folder that exists is reused as it is configured (CI: stage 1's build/ and stage 2's
# build-vehicle/), with only its install prefix set to /usr, so nothing is compiled again; a new
# one is configured Release, without tests and benchmarks. Installs the Debian packages it needs
# first (tools/install-deps.sh; --minimal for acqd alone).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
which=${1:-both}
case "$which" in both | acqd | shore) ;; *)
  echo "usage: tools/build-packages.sh [both|acqd|shore]" >&2
  exit 2
  ;;
esac
abs() { case "$1" in /*) echo "$1" ;; *) echo "$root/$1" ;; esac }
build=$(abs "${BUILD_DIR:-build}")
vehicle=$(abs "${VEHICLE_BUILD_DIR:-build-vehicle}")
jobs=$(nproc 2> /dev/null || echo 2)

if [[ $which == acqd ]]; then
  "$root/tools/install-deps.sh" --minimal
else
  "$root/tools/install-deps.sh"
fi

# configure_and_package DIR LABEL ARGS...: configure with ARGS, build, cpack.
configure_and_package() {
  local dir=$1 label=$2
  shift 2
  # ARGS define the build (the vehicle's PITMAP_BUILD_PROCESSOR=OFF): always given.
  local args=(-DCMAKE_INSTALL_PREFIX=/usr "$@")
  if [[ -f $dir/CMakeCache.txt ]]; then
    if grep -Eq '^PITMAP_SANITIZE:[A-Z]+=.+' "$dir/CMakeCache.txt"; then
      echo "build-packages: $dir is a sanitizer build; not packaging it" >&2
      exit 1
    fi
  else
    # shellcheck disable=SC2206  # PITMAP_CMAKE_ARGS: several words
    args+=(-G Ninja -DCMAKE_BUILD_TYPE=Release -DPITMAP_BUILD_TESTS=OFF
      -DPITMAP_BUILD_BENCHMARKS=OFF ${PITMAP_CMAKE_ARGS:-})
  fi
  cmake -S "$root" -B "$dir" "${args[@]}" > "$dir.configure.log" 2>&1 || {
    cat "$dir.configure.log"
    echo "build-packages: configure of $dir failed" >&2
    exit 1
  }
  cmake --build "$dir" -j "$jobs"
  rm -f "$dir"/packages/*.deb
  (cd "$dir" && cpack > cpack.log 2>&1) || {
    cat "$dir/cpack.log"
    echo "build-packages: cpack in $dir failed" >&2
    exit 1
  }
  local deb
  for deb in "$dir"/packages/*.deb; do
    echo "build-packages: $label: ${deb#"$root"/} ($(($(stat -c %s "$deb") / 1024)) KiB)"
    dpkg-deb -f "$deb" Depends | sed 's/^/  Depends: /'
    debs+=("$deb")
  done
}
debs=()

if [[ $which != shore ]]; then
  configure_and_package "$vehicle" "vehicle" -DPITMAP_BUILD_PROCESSOR=OFF
fi
if [[ $which != acqd ]]; then
  configure_and_package "$build" "shore"
fi

# Debian policy checks (lintian, from tools/install-deps.sh; not in --minimal): an error fails.
# Left: no-manual-page (the programs' --help is their manual).
if command -v lintian > /dev/null 2>&1; then
  log=$(mktemp)
  trap 'rm -f "$log"' EXIT
  if ! lintian --fail-on error --suppress-tags no-manual-page "${debs[@]}" > "$log" 2>&1; then
    grep -v "root privileges" "$log" >&2
    echo "build-packages: lintian found errors" >&2
    exit 1
  fi
  grep -v "root privileges" "$log" || true
  echo "build-packages: lintian: no errors in ${#debs[@]} package(s)"
else
  echo "build-packages: lintian not installed: the packages are not checked against Debian policy"
fi
