#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The vehicle package for 64-bit ARM (docs/packages.md, "arm64"): the daemon-only build
# cross-compiled with Debian's cross compiler, its unit tests run under qemu-user, then
# pitmap-acqd_<v>_arm64.deb. Run by hand (not in CI).
#   tools/build-arm64.sh            -> build-arm64/packages/pitmap-acqd_<v>_arm64.deb
# Environment: BUILD_DIR (default build-arm64), PITMAP_CMAKE_ARGS (e.g. the ccache launcher).
#
# The arm64 libraries come from Debian's arm64 packages, downloaded by a private apt (its own
# lists, cache and an empty status under BUILD_DIR/sysroot-apt) and unpacked into
# BUILD_DIR/sysroot; nothing is installed for arm64 on this machine and dpkg's architectures are
# left alone. Why not `dpkg --add-architecture arm64` and the :arm64 -dev packages: liblcm-dev,
# liblcm1, liblcm-bin, libyaml-cpp-dev and libgeographiclib-dev are not Multi-Arch in Debian 12,
# so installing their arm64 versions removes the amd64 ones this machine builds with.
# Installs on this machine (amd64): g++-aarch64-linux-gnu, qemu-user-static.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build-arm64}
case "$build" in /*) ;; *) build=$root/$build ;; esac
jobs=$(nproc 2> /dev/null || echo 2)
start=$(date +%s)

"$root/tools/install-deps.sh" --minimal
host_pkgs=(g++-aarch64-linux-gnu qemu-user-static)
missing=()
for p in "${host_pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2> /dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [[ ${#missing[@]} -gt 0 ]]; then
  SUDO=
  [[ $(id -u) -eq 0 ]] || SUDO=sudo
  echo "build-arm64: installing ${missing[*]}"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}"
fi

# The daemon's build dependencies (tools/install-deps.sh --minimal, less the tools that run on
# the build machine) and the C/C++ runtime, as arm64 packages.
sysroot_pkgs=(
  libc6-dev libstdc++-12-dev
  libeigen3-dev libgeographiclib-dev liblcm-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev
  libpcap-dev zlib1g-dev libgtest-dev libgmock-dev
)
sysroot=$build/sysroot
aptdir=$build/sysroot-apt
stamp=$sysroot/.pitmap-sysroot
want="${sysroot_pkgs[*]}"
if [[ ! -f $stamp || $(cat "$stamp") != "$want" ]]; then
  echo "build-arm64: sysroot from Debian arm64 packages: $want"
  rm -rf "$sysroot" "$aptdir"
  mkdir -p "$aptdir/lists/partial" "$aptdir/archives/partial" "$sysroot"
  : > "$aptdir/status"
  cat > "$aptdir/apt.conf" << CONF
APT::Architecture "arm64";
APT::Architectures { "arm64"; };
APT::Install-Recommends "false";
Dir::State "$aptdir";
Dir::State::status "$aptdir/status";
Dir::Cache "$aptdir";
Dir::Cache::archives "$aptdir/archives";
CONF
  APT_CONFIG=$aptdir/apt.conf apt-get update -qq
  APT_CONFIG=$aptdir/apt.conf apt-get install --download-only -y -qq "${sysroot_pkgs[@]}"
  for deb in "$aptdir"/archives/*.deb; do dpkg-deb -x "$deb" "$sysroot"; done
  # Absolute links (libfoo.so -> /lib/aarch64-linux-gnu/libfoo.so.1) point into the sysroot.
  find "$sysroot" -type l -lname '/*' -print0 |
    while IFS= read -r -d '' link; do
      target=$sysroot$(readlink "$link")
      ln -sfn "$(realpath -m --relative-to="$(dirname "$link")" "$target")" "$link"
    done
  # Every package's symbols and shlibs files, as if the sysroot were one package being built:
  # dpkg-shlibdeps -S reads them there (it finds nothing in this machine's dpkg database).
  mkdir -p "$sysroot/DEBIAN"
  : > "$sysroot/DEBIAN/symbols"
  : > "$sysroot/DEBIAN/shlibs"
  for deb in "$aptdir"/archives/*.deb; do
    dpkg-deb --info "$deb" symbols >> "$sysroot/DEBIAN/symbols" 2> /dev/null || true
    dpkg-deb --info "$deb" shlibs >> "$sysroot/DEBIAN/shlibs" 2> /dev/null || true
  done
  echo "$want" > "$stamp"
  n=$(find "$aptdir/archives" -name '*.deb' | wc -l)
  echo "build-arm64: sysroot $(du -sh "$sysroot" | cut -f1), $n packages"
fi

# shellcheck disable=SC2086  # PITMAP_CMAKE_ARGS: several words
cmake -S "$root" -B "$build/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_TOOLCHAIN_FILE="$root/cmake/toolchain-aarch64-linux-gnu.cmake" \
  -DCMAKE_SYSROOT="$sysroot" -DCMAKE_INSTALL_PREFIX=/usr \
  -DPITMAP_BUILD_PROCESSOR=OFF -DPITMAP_BUILD_TOOLS=OFF -DPITMAP_BUILD_BENCHMARKS=OFF \
  -DPITMAP_BUILD_TESTS=ON -DPITMAP_WARNINGS_AS_ERRORS=ON ${PITMAP_CMAKE_ARGS:-} \
  > "$build/configure.log" 2>&1 || {
  cat "$build/configure.log"
  echo "build-arm64: configure failed" >&2
  exit 1
}
cmake --build "$build/build" -j "$jobs"
file "$build/build/bin/pitmap-acqd"
# The daemon itself under qemu-user: the example config checks out.
qemu-aarch64-static -L "$sysroot" "$build/build/bin/pitmap-acqd" \
  --config "$root/firmware_host/config/roaz.yaml" --check-config

# The unit tests under qemu-user (CMAKE_CROSSCOMPILING_EMULATOR of the toolchain file).
ctest --test-dir "$build/build" -L unit -j "$jobs" --output-on-failure

# The package's Depends: dpkg-shlibdeps against the sysroot's symbols files (above), for arm64.
mkdir -p "$build/shlibdeps/debian"
: > "$build/shlibdeps/debian/control"
depends=$(cd "$build/shlibdeps" && DEB_HOST_ARCH=arm64 dpkg-shlibdeps -O -S"$sysroot" \
  "$build/build/bin/pitmap-acqd" 2> "$build/shlibdeps/stderr" | sed -n 's/^shlibs:Depends=//p')
if [[ -z $depends ]]; then
  cat "$build/shlibdeps/stderr"
  echo "build-arm64: dpkg-shlibdeps found no dependencies" >&2
  exit 1
fi
cmake -S "$root" -B "$build/build" -DPITMAP_PACKAGE_SHLIBS_DEPENDS="$depends" > /dev/null
(cd "$build/build" && cpack > cpack.log 2>&1) || {
  cat "$build/build/cpack.log"
  echo "build-arm64: cpack failed" >&2
  exit 1
}
for deb in "$build"/build/packages/*.deb; do
  echo "build-arm64: ${deb#"$root"/} ($(dpkg-deb -f "$deb" Architecture)," \
    "$(($(stat -c %s "$deb") / 1024)) KiB)"
  dpkg-deb -f "$deb" Depends | sed 's/^/  Depends: /'
done
echo "build-arm64: done in $(($(date +%s) - start)) s"
