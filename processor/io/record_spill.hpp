// SPDX-License-Identifier: MIT
// Records of a fixed size appended to a scratch file and read back a block at a time, so that a
// stage's intermediate array (CUBE's input, 48 bytes a sounding: decision 035) waits on disk
// instead of in memory. The file is this process's scratch (native byte order, the records'
// bytes as they were given), removed when the RecordFile is destroyed; its name is the caller's
// (.partial-* in the products folder, so that a killed run's leftover is removed with the other
// partial files: common/formats/replace_file.hpp).
#pragma once

#include <cstddef>
#include <cstdio>
#include <functional>
#include <string>
#include <utility>

#include "common/result.hpp"

namespace pitmap::proc::io {

class RecordFile {
public:
    // An empty file at `path` for records of `record_bytes` bytes (> 0), open for Append. An
    // error (the folder not writable) names the file.
    static Expected<RecordFile> Create(const std::string& path, std::size_t record_bytes);

    RecordFile(RecordFile&& other) noexcept;
    RecordFile& operator=(RecordFile&& other) noexcept;
    RecordFile(const RecordFile&) = delete;
    RecordFile& operator=(const RecordFile&) = delete;
    ~RecordFile();  // closes and removes the file

    // Appends `count` records from `records` (count * record_bytes bytes). An error (the disk
    // full, the file closed) names the file; the records appended before stay.
    Status Append(const void* records, std::size_t count);
    // Ends the appending (the records flushed to the file); reading needs it. Idempotent.
    Status Close();

    // Calls fn(first, count, bytes) on the records a block of `block` (>= 1) at a time, in
    // order, `bytes` the count records' bytes; stops at fn's first error. An error (the file
    // not closed, gone or short) names the file.
    Status ForEachBlock(
        std::size_t block,
        const std::function<Status(std::size_t, std::size_t, const std::byte*)>& fn) const;

    const std::string& path() const { return path_; }
    std::size_t size() const { return size_; }  // records appended
    std::size_t record_bytes() const { return record_bytes_; }

private:
    RecordFile(std::string path, std::size_t record_bytes, std::FILE* out)
        : path_(std::move(path)), record_bytes_(record_bytes), out_(out) {}
    void Release();
    std::string path_;  // empty once moved from
    std::size_t record_bytes_ = 0;
    std::size_t size_ = 0;
    std::FILE* out_ = nullptr;  // open while appending
};

}  // namespace pitmap::proc::io
