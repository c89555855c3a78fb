// SPDX-License-Identifier: MIT
#include "common/formats/byte_file.hpp"

#include <cerrno>
#include <utility>

#include "common/formats/replace_file.hpp"

namespace pitmap::formats {

namespace {
constexpr std::size_t kBufferBytes = 1 << 20;
}  // namespace

ByteFileWriter::ByteFileWriter(std::string path)
    : path_(std::move(path)),
      partial_(PartialPath(path_)),
      file_(std::fopen(partial_.c_str(), "wb")),
      writer_(buffer_) {
    if (file_ == nullptr) open_errno_ = errno;
    buffer_.reserve(kBufferBytes + 4096);
}

ByteFileWriter::~ByteFileWriter() {
    if (file_ != nullptr) {
        // Not closed: abandoned (an error on the way); the product keeps its previous state.
        std::fclose(file_);
        std::remove(partial_.c_str());
    }
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
        if (ok_) write_errno_ = errno;
        ok_ = false;
    }
    buffer_.clear();
}

Status ByteFileWriter::Close() {
    if (file_ == nullptr) {
        return Error{
            ErrnoMessage(path_, "cannot create (written first as " + partial_ + ")", open_errno_)};
    }
    Drain();
    if (std::fflush(file_) != 0 && ok_) {
        write_errno_ = errno;
        ok_ = false;
    }
    const bool closed = std::fclose(file_) == 0;
    if (!closed && ok_) write_errno_ = errno;
    file_ = nullptr;
    if (!ok_ || !closed) {
        std::remove(partial_.c_str());
        return Error{ErrnoMessage(path_, "write failed", write_errno_)};
    }
    return CommitPartial(partial_, path_);
}

Status WriteFileBytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
    ByteFileWriter f(path);
    f.out().Bytes(bytes);
    return f.Close();
}

}  // namespace pitmap::formats
