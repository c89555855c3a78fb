// SPDX-License-Identifier: MIT
#include "processor/io/record_spill.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <utility>
#include <vector>

namespace pitmap::proc::io {

namespace {

struct FileCloser {
    void operator()(std::FILE* f) const {
        if (f != nullptr) std::fclose(f);
    }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

std::string Why() {
    return errno != 0 ? std::string(": ") + std::strerror(errno) : std::string();
}

}  // namespace

Expected<RecordFile> RecordFile::Create(const std::string& path, std::size_t record_bytes) {
    if (record_bytes == 0) return Error{path + ": records of no bytes"};
    errno = 0;
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) return Error{path + ": cannot create the scratch file" + Why()};
    return RecordFile(path, record_bytes, f);
}

RecordFile::RecordFile(RecordFile&& other) noexcept
    : path_(std::move(other.path_)),
      record_bytes_(other.record_bytes_),
      size_(other.size_),
      out_(other.out_) {
    other.path_.clear();
    other.out_ = nullptr;
    other.size_ = 0;
}

RecordFile& RecordFile::operator=(RecordFile&& other) noexcept {
    if (this != &other) {
        Release();
        path_ = std::move(other.path_);
        record_bytes_ = other.record_bytes_;
        size_ = other.size_;
        out_ = other.out_;
        other.path_.clear();
        other.out_ = nullptr;
        other.size_ = 0;
    }
    return *this;
}

RecordFile::~RecordFile() {
    Release();
}

void RecordFile::Release() {
    if (out_ != nullptr) std::fclose(out_);
    out_ = nullptr;
    if (!path_.empty()) {
        std::error_code ec;
        std::filesystem::remove(path_, ec);
    }
    path_.clear();
}

Status RecordFile::Append(const void* records, std::size_t count) {
    if (out_ == nullptr) return Error{path_ + ": the scratch file is closed for appending"};
    errno = 0;
    if (count > 0 && std::fwrite(records, record_bytes_, count, out_) != count)
        return Error{path_ + ": cannot write the scratch file" + Why()};
    size_ += count;
    return Ok{};
}

Status RecordFile::Close() {
    if (out_ == nullptr) return Ok{};
    errno = 0;
    const bool flushed = std::fflush(out_) == 0;
    const bool closed = std::fclose(out_) == 0;
    out_ = nullptr;
    if (!flushed || !closed) return Error{path_ + ": cannot write the scratch file" + Why()};
    return Ok{};
}

Status RecordFile::ForEachBlock(
    std::size_t block,
    const std::function<Status(std::size_t, std::size_t, const std::byte*)>& fn) const {
    if (out_ != nullptr) return Error{path_ + ": the scratch file is still being written"};
    errno = 0;
    File f(std::fopen(path_.c_str(), "rb"));
    if (!f) return Error{path_ + ": cannot read the scratch file" + Why()};
    block = std::max<std::size_t>(block, 1);
    std::vector<std::byte> buffer(std::min(block, size_) * record_bytes_);
    for (std::size_t first = 0; first < size_; first += block) {
        const std::size_t count = std::min(block, size_ - first);
        if (std::fread(buffer.data(), record_bytes_, count, f.get()) != count)
            return Error{path_ + ": the scratch file is shorter than what was written"};
        if (auto st = fn(first, count, buffer.data()); !st) return st;
    }
    return Ok{};
}

}  // namespace pitmap::proc::io
