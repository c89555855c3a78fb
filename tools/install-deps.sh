#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs every Debian package pitmap needs to build, test and run the demo.
# Idempotent: when everything is present it only checks and returns (< 1 s).
# Usage: tools/install-deps.sh [--minimal]   (--minimal: the vehicle side only, no OpenVDB)
set -euo pipefail

# dpkg-dev, file: the Debian packages' shared-library dependencies (cpack; tools/build-packages.sh).
common_pkgs=(
  cmake ninja-build g++ pkg-config git ca-certificates
  libeigen3-dev libgeographiclib-dev
  liblcm-dev liblcm-bin
  libyaml-cpp-dev libcli11-dev nlohmann-json3-dev
  libpcap-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  iproute2 socat util-linux pps-tools
  dpkg-dev file
)
# snakemake, python3-yaml: pitmap-campaign, a campaign of surveys as a Snakemake workflow on one
# machine or a Slurm cluster (tools/campaign, docs/campaigns.md).
# libopenblas0-pthread: an optimised BLAS/LAPACK that Debian's alternatives put in place of the
# reference libblas.so.3 and liblapack.so.3 that CHOLMOD loads; SLAM's supernodal
# factorisation runs its dense blocks there (the reference BLAS was ~20 % of SLAM's CPU).
processor_pkgs=(
  libsuitesparse-dev libblas-dev liblapack-dev libopenblas0-pthread
  libopenvdb-dev libtbb-dev libboost-iostreams-dev
  libnanoflann-dev libassimp-dev
  libgdal-dev libproj-dev proj-data libcpp-httplib-dev
  python3-numpy python3-matplotlib python3-gdal python3-yaml
  snakemake
)
# The browser tests (headless Chromium loads the live page and report.html), report.pdf
# (pitmap-report --pdf prints through Chromium) and the report's 3D viewer (three.js, inlined
# into report.html). The report's maps read the GeoTIFFs through python3-gdal (above).
browser_pkgs=(
  chromium libjs-three
)
# lintian: Debian policy checks of the packages (tools/build-packages.sh). lld: the sanitizer
# build's linker (.ci/sanitize.cmake).
tool_pkgs=(
  clang libclang-rt-14-dev clang-format llvm-14 lld ccache lintian
)

pkgs=("${common_pkgs[@]}")
if [[ "${1:-}" != "--minimal" ]]; then
  pkgs+=("${processor_pkgs[@]}" "${browser_pkgs[@]}" "${tool_pkgs[@]}")
fi

missing=()
for p in "${pkgs[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all ${#pkgs[@]} packages present"
  exit 0
fi

if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo >/dev/null 2>&1; then SUDO=sudo; else
    echo "install-deps: missing packages and not root (no sudo): ${missing[*]}" >&2
    exit 1
  fi
else
  SUDO=
fi

echo "install-deps: installing ${#missing[@]} package(s): ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: done"
