// SPDX-License-Identifier: MIT
// Binary file output through common's ByteWriter: fields are appended to an in-memory buffer
// with an explicit byte order, and the buffer goes to the file whenever it passes 1 MiB and at
// Close(), so a multi-gigabyte product needs only the buffer's memory.
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
    // Opens (truncates) `path`; a failure to open is reported by Close().
    explicit ByteFileWriter(std::string path);
    ~ByteFileWriter();
    ByteFileWriter(const ByteFileWriter&) = delete;
    ByteFileWriter& operator=(const ByteFileWriter&) = delete;

    // Where the next fields go. Drains the buffer to the file first when it is full, so call it
    // once per record rather than keeping the reference across many records.
    ByteWriter& out();
    void Text(std::string_view text);
    // Writes what is buffered and closes the file; an error names the path.
    Status Close();

private:
    void Drain();
    std::string path_;
    std::FILE* file_;
    bool ok_ = true;
    std::vector<std::uint8_t> buffer_;
    ByteWriter writer_;
};

// Writes `bytes` to `path` (truncating); an error names the path.
Status WriteFileBytes(const std::string& path, const std::vector<std::uint8_t>& bytes);

}  // namespace pitmap::formats
