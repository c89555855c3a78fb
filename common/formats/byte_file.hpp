// SPDX-License-Identifier: MIT
// Binary file output through common's ByteWriter: fields are appended to an in-memory buffer
// with an explicit byte order, and the buffer goes to the file whenever it passes 1 MiB and at
// Close(), so a multi-gigabyte product needs only the buffer's memory. The bytes go to
// a partial file beside PATH, renamed over PATH by a successful Close() (replace_file.hpp): a
// writer that fails or is destroyed without Close() leaves PATH as it was and removes the partial
// file.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "common/byte_io.hpp"
#include "common/result.hpp"

namespace pitmap::formats {

class ByteFileWriter {
public:
    // Opens (truncates) the partial file of `path`; a failure to open is reported by Close().
    explicit ByteFileWriter(std::string path);
    ~ByteFileWriter();
    ByteFileWriter(const ByteFileWriter&) = delete;
    ByteFileWriter& operator=(const ByteFileWriter&) = delete;

    // Where the next fields go. Drains the buffer to the file first when it is full, so call it
    // once per record rather than keeping the reference across many records.
    ByteWriter& out();
    void Text(std::string_view text);
    // Writes what is buffered, closes the file and renames it to `path`; an error names the
    // path and the system's reason.
    Status Close();

private:
    void Drain();
    std::string path_;
    std::string partial_;
    std::FILE* file_;
    int open_errno_ = 0;
    int write_errno_ = 0;
    bool ok_ = true;
    std::vector<std::uint8_t> buffer_;
    ByteWriter writer_;
};

// Writes `bytes` to `path` (replacing it whole); an error names the path.
Status WriteFileBytes(const std::string& path, const std::vector<std::uint8_t>& bytes);

}  // namespace pitmap::formats
