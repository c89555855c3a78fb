# SPDX-License-Identifier: MIT
# Cross build for 64-bit ARM Linux (Debian arm64) with Debian's cross compiler
# (g++-aarch64-linux-gnu) against a sysroot of Debian arm64 packages (tools/build-arm64.sh makes
# one: -DCMAKE_SYSROOT=...). Programs found at configure time (lcm-gen) are the build machine's;
# libraries, headers and CMake package files come from the sysroot only. Tests and the
# programs run at build time go through qemu-user (qemu-aarch64-static, the sysroot as its
# library root). The packages are arm64 (cmake/Packaging.cmake).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
if(CMAKE_SYSROOT)
  set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64-static -L ${CMAKE_SYSROOT})
endif()
set(PITMAP_DEBIAN_ARCHITECTURE arm64)
