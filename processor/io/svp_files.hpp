// SPDX-License-Identifier: MIT
// Sound-velocity files (CARIS .svp, CSV, two-column text; processor/svp/cast.hpp) from disk.
#pragma once

#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/svp/cast.hpp"

namespace pitmap::proc::io {

// Reads every file in order; the casts of all files, in file order. An unreadable, empty,
// over-large (> 64 MiB) or malformed file is an error naming it (and the line).
Expected<std::vector<svp::SoundSpeedCast>> ReadSoundSpeedFiles(
    const std::vector<std::string>& paths);

}  // namespace pitmap::proc::io
