// SPDX-License-Identifier: MIT
#include "common/formats/byte_file.hpp"

#include <utility>

namespace pitmap::formats {

namespace {
constexpr std::size_t kBufferBytes = 1 << 20;
}  // namespace

ByteFileWriter::ByteFileWriter(std::string path)
    : path_(std::move(path)), file_(std::fopen(path_.c_str(), "wb")), writer_(buffer_) {
    buffer_.reserve(kBufferBytes + 4096);
}

ByteFileWriter::~ByteFileWriter() {
    if (file_ != nullptr) std::fclose(file_);
}

ByteWriter& ByteFileWriter::out() {
    if (buffer_.size() >= kBufferBytes) Drain();
    return writer_;
}

void ByteFileWriter::Text(std::string_view text) {
    out().Bytes({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
}

void ByteFileWriter::Drain() {
    if (file_ != nullptr && !buffer_.empty() &&
        std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size()) {
        ok_ = false;
    }
    buffer_.clear();
}

Status ByteFileWriter::Close() {
    if (file_ == nullptr) return Error{path_ + ": cannot create"};
    Drain();
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!ok_ || !closed) return Error{path_ + ": write failed (disk full?)"};
    return Ok{};
}

Status WriteFileBytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
    ByteFileWriter f(path);
    f.out().Bytes(bytes);
    return f.Close();
}

}  // namespace pitmap::formats
