// SPDX-License-Identifier: MIT
// What every program prints for --version: the CMake project version (the top CMakeLists.txt's
// project(pitmap VERSION ...)) and the git commit the build came from, stamped at build time
// into one generated source (common/version_info.cpp.in, cmake/GitVersion.cmake) so that a new
// commit recompiles that file only and relinks the programs.
#pragma once

#include <string>
#include <string_view>

namespace pitmap {

// "0.1.0".
const char* Version();
// The commit's 12-digit abbreviation, "-dirty" appended when tracked files differ from it;
// "unknown" outside a git checkout (a source tarball), or what -DPITMAP_GIT_COMMIT= gave.
const char* GitCommit();
// "PROGRAM 0.1.0 (git 1a2b3c4d5e6f)": the line --version prints.
std::string VersionLine(std::string_view program);

}  // namespace pitmap
