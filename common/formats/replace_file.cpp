// SPDX-License-Identifier: MIT
#include "common/formats/replace_file.hpp"

#include <cstdio>
#include <cstring>
#include <filesystem>

namespace pitmap::formats {

std::string PartialPath(const std::string& path) {
    const std::filesystem::path p(path);
    return (p.parent_path() / (kPartialPrefix + p.filename().string())).string();
}

bool IsPartialName(const std::string& name) {
    const std::string suffix = ".partial";
    return name.rfind(kPartialPrefix, 0) == 0 ||
           (name.size() > suffix.size() &&
            name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0);
}

std::string ErrnoMessage(const std::string& path, const std::string& what, int err) {
    return path + ": " + what + ": " + std::strerror(err);
}

Status CommitPartial(const std::string& partial, const std::string& path) {
    if (std::rename(partial.c_str(), path.c_str()) != 0) {
        const int err = errno;
        std::remove(partial.c_str());
        return Error{ErrnoMessage(path, "cannot replace", err)};
    }
    return Ok{};
}

Status WriteReplacing(const std::string& path,
                      const std::function<Status(const std::string& partial)>& write) {
    const std::string partial = PartialPath(path);
    Status written = write(partial);
    if (!written) {
        std::error_code ec;
        std::filesystem::remove(partial, ec);
        // The writer names the file it wrote; the reader knows the product by its own name.
        std::string message = written.error().message;
        for (std::size_t at = message.find(partial); at != std::string::npos;
             at = message.find(partial, at + path.size())) {
            message.replace(at, partial.size(), path);
        }
        return Error{message};
    }
    return CommitPartial(partial, path);
}

}  // namespace pitmap::formats
