// SPDX-License-Identifier: MIT
// For fuzz targets of readers that take a path: the input as an anonymous in-memory file
// (memfd), named by /proc/self/fd/N, closed when the object goes out of scope.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace pitmap::fuzz {

class MemFile {
public:
    MemFile(const std::uint8_t* data, std::size_t size) : fd_(memfd_create("fuzz", 0)) {
        if (fd_ < 0) std::abort();
        std::size_t done = 0;
        while (done < size) {
            const ssize_t n = write(fd_, data + done, size - done);
            if (n <= 0) std::abort();
            done += static_cast<std::size_t>(n);
        }
        path_ = "/proc/self/fd/" + std::to_string(fd_);
    }
    ~MemFile() { close(fd_); }
    MemFile(const MemFile&) = delete;
    MemFile& operator=(const MemFile&) = delete;
    const std::string& path() const { return path_; }

private:
    int fd_;
    std::string path_;
};

// A failed read must name the file it read (every product reader's contract).
inline void CheckNamesFile(const std::string& message, const std::string& path) {
    if (message.find(path) == std::string::npos) std::abort();
}

}  // namespace pitmap::fuzz
