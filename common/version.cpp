// SPDX-License-Identifier: MIT
#include "common/version.hpp"

namespace pitmap {

std::string VersionLine(std::string_view program) {
    return std::string(program) + " " + Version() + " (git " + GitCommit() + ")";
}

}  // namespace pitmap
