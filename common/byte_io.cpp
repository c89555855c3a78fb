// SPDX-License-Identifier: MIT
#include "common/byte_io.hpp"

#include <algorithm>

namespace pitmap {

bool ByteReader::Seek(std::size_t offset) {
    if (!ok_ || offset > data_.size()) {
        ok_ = false;
        return false;
    }
    pos_ = offset;
    return true;
}

bool ByteReader::Skip(std::size_t n) {
    if (!ok_ || n > remaining()) {
        ok_ = false;
        return false;
    }
    pos_ += n;
    return true;
}

std::uint8_t ByteReader::U8() {
    if (!ok_ || remaining() < 1) {
        ok_ = false;
        return 0;
    }
    return data_[pos_++];
}

ByteSpan ByteReader::Bytes(std::size_t n) {
    if (!ok_ || n > remaining()) {
        ok_ = false;
        return {};
    }
    ByteSpan view = data_.subspan(pos_, n);
    pos_ += n;
    return view;
}

std::string ByteReader::FixedString(std::size_t n) {
    const ByteSpan raw = Bytes(n);
    const auto end = std::find(raw.begin(), raw.end(), std::uint8_t{0});
    return std::string(raw.begin(), end);
}

void ByteWriter::F32Le(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    U32Le(bits);
}

void ByteWriter::F64Le(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    U64Le(bits);
}

void ByteWriter::F32Be(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    U32Be(bits);
}

void ByteWriter::F64Be(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    U64Be(bits);
}

void ByteWriter::FixedString(std::string_view text, std::size_t n) {
    const std::size_t len = std::min(text.size(), n);
    out_.insert(out_.end(), text.begin(), text.begin() + static_cast<std::ptrdiff_t>(len));
    Zeros(n - len);
}

bool ByteWriter::PatchU16Le(std::size_t offset, std::uint16_t v) {
    if (offset > out_.size() || out_.size() - offset < 2) return false;
    out_[offset] = static_cast<std::uint8_t>(v & 0xFF);
    out_[offset + 1] = static_cast<std::uint8_t>(v >> 8);
    return true;
}

bool ByteWriter::PatchU16Be(std::size_t offset, std::uint16_t v) {
    if (offset > out_.size() || out_.size() - offset < 2) return false;
    out_[offset] = static_cast<std::uint8_t>(v >> 8);
    out_[offset + 1] = static_cast<std::uint8_t>(v & 0xFF);
    return true;
}

bool ByteWriter::PatchU32Le(std::size_t offset, std::uint32_t v) {
    if (offset > out_.size() || out_.size() - offset < 4) return false;
    for (int i = 0; i < 4; ++i)
        out_[offset + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
    return true;
}

}  // namespace pitmap
