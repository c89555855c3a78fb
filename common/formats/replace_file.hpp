// SPDX-License-Identifier: MIT
// Products are replaced, never rewritten in place: a writer writes PATH.partial beside PATH and
// renames it over PATH only once every byte is written, so a reader (or a later stage) sees the
// old file or the new one, never half of one, and a killed writer leaves only a *.partial file
// (pitmap georef removes them). rename(2) within one folder is atomic on POSIX file systems.
// Errors name the path and carry the system's reason (strerror).
#pragma once

#include <functional>
#include <string>

#include "common/result.hpp"

namespace pitmap::formats {

inline constexpr const char* kPartialSuffix = ".partial";

// PATH.partial.
std::string PartialPath(const std::string& path);

// "PATH: WHAT: REASON" with REASON the text of errno value `err`.
std::string ErrnoMessage(const std::string& path, const std::string& what, int err);

// Renames `partial` over `path`; on failure removes `partial` and returns an error naming
// `path` and the reason.
Status CommitPartial(const std::string& partial, const std::string& path);

// Calls write(PartialPath(path)); when it succeeds renames the partial file over `path`, when
// it fails removes the partial file and returns its error (`path` is then untouched).
Status WriteReplacing(const std::string& path,
                      const std::function<Status(const std::string& partial)>& write);

}  // namespace pitmap::formats
