// SPDX-License-Identifier: MIT
// Products are replaced, never rewritten in place: a writer writes DIR/.partial-NAME beside
// DIR/NAME (the extension kept: GDAL's BAG driver wants its own) and
// renames it over PATH only once every byte is written, so a reader (or a later stage) sees the
// old file or the new one, never half of one, and a killed writer leaves only a *.partial file
// (pitmap georef removes them; IsPartialName). rename(2) within one folder is atomic on POSIX file
// systems. Errors name the path and carry the system's reason (strerror).
#pragma once

#include <functional>
#include <string>

#include "common/result.hpp"

namespace pitmap::formats {

inline constexpr const char* kPartialPrefix = ".partial-";

// DIR/.partial-NAME for DIR/NAME.
std::string PartialPath(const std::string& path);
// Whether a file name is a partial file's: .partial-NAME, or NAME.partial (survey.pitmap's).
bool IsPartialName(const std::string& name);

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
