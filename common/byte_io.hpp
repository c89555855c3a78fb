// SPDX-License-Identifier: MIT
// Bounds-checked little/big-endian reading and writing of wire formats.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace pitmap {

using ByteSpan = std::span<const std::uint8_t>;

// Reads fixed-width fields from a byte span with an explicit byte order.
//
// Errors are sticky: a read past the end returns 0 (or an empty span), marks the reader as
// failed and leaves the position unchanged, so a decoder reads every field and checks ok()
// once at the end. Never undefined behaviour, whatever the input.
// Not thread safe; cheap to copy (a span and two integers).
class ByteReader {
public:
    ByteReader() = default;
    explicit ByteReader(ByteSpan data) : data_(data) {}
    ByteReader(const std::uint8_t* data, std::size_t size) : data_(data, size) {}

    // True while every read so far stayed inside the data.
    bool ok() const { return ok_; }
    std::size_t position() const { return pos_; }
    std::size_t size() const { return data_.size(); }
    std::size_t remaining() const { return data_.size() - pos_; }
    ByteSpan data() const { return data_; }

    // Moves to an absolute offset; an offset past the end fails the reader.
    bool Seek(std::size_t offset);
    // Skips n bytes; fails the reader if fewer remain.
    bool Skip(std::size_t n);

    std::uint8_t U8();
    std::int8_t I8() { return static_cast<std::int8_t>(U8()); }

    std::uint16_t U16Le() { return ReadInt<std::uint16_t, false>(); }
    std::uint32_t U32Le() { return ReadInt<std::uint32_t, false>(); }
    std::uint64_t U64Le() { return ReadInt<std::uint64_t, false>(); }
    std::int16_t I16Le() { return static_cast<std::int16_t>(U16Le()); }
    std::int32_t I32Le() { return static_cast<std::int32_t>(U32Le()); }
    std::int64_t I64Le() { return static_cast<std::int64_t>(U64Le()); }
    float F32Le() { return BitCast<float>(U32Le()); }
    double F64Le() { return BitCast<double>(U64Le()); }

    std::uint16_t U16Be() { return ReadInt<std::uint16_t, true>(); }
    std::uint32_t U32Be() { return ReadInt<std::uint32_t, true>(); }
    std::uint64_t U64Be() { return ReadInt<std::uint64_t, true>(); }
    std::int16_t I16Be() { return static_cast<std::int16_t>(U16Be()); }
    std::int32_t I32Be() { return static_cast<std::int32_t>(U32Be()); }
    float F32Be() { return BitCast<float>(U32Be()); }
    double F64Be() { return BitCast<double>(U64Be()); }

    // The next n bytes as a view (empty and failed if fewer remain).
    ByteSpan Bytes(std::size_t n);
    // A fixed-width text field of n bytes, cut at the first NUL (bytes after it are ignored,
    // as in NovAtel station ids that are not zero-filled after the terminator).
    std::string FixedString(std::size_t n);

private:
    template <typename T, bool kBigEndian>
    T ReadInt() {
        static_assert(std::is_unsigned_v<T>);
        if (!ok_ || remaining() < sizeof(T)) {
            ok_ = false;
            return 0;
        }
        T value = 0;
        for (std::size_t i = 0; i < sizeof(T); ++i) {
            const std::size_t shift = kBigEndian ? (sizeof(T) - 1 - i) * 8 : i * 8;
            value = static_cast<T>(value | (static_cast<T>(data_[pos_ + i]) << shift));
        }
        pos_ += sizeof(T);
        return value;
    }

    template <typename To, typename From>
    static To BitCast(From from) {
        static_assert(sizeof(To) == sizeof(From));
        To to;
        std::memcpy(&to, &from, sizeof(To));
        return to;
    }

    ByteSpan data_;
    std::size_t pos_ = 0;
    bool ok_ = true;
};

// Appends fixed-width fields to a byte vector with an explicit byte order. Writing into a
// vector cannot overflow; Reserve() up front keeps encoders allocation-free in steady state.
class ByteWriter {
public:
    explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(out) {}

    std::size_t size() const { return out_.size(); }

    void U8(std::uint8_t v) { out_.push_back(v); }
    void I8(std::int8_t v) { U8(static_cast<std::uint8_t>(v)); }

    void U16Le(std::uint16_t v) { WriteInt<std::uint16_t, false>(v); }
    void U32Le(std::uint32_t v) { WriteInt<std::uint32_t, false>(v); }
    void U64Le(std::uint64_t v) { WriteInt<std::uint64_t, false>(v); }
    void I16Le(std::int16_t v) { U16Le(static_cast<std::uint16_t>(v)); }
    void I32Le(std::int32_t v) { U32Le(static_cast<std::uint32_t>(v)); }
    void I64Le(std::int64_t v) { U64Le(static_cast<std::uint64_t>(v)); }
    void F32Le(float v);
    void F64Le(double v);

    void U16Be(std::uint16_t v) { WriteInt<std::uint16_t, true>(v); }
    void U32Be(std::uint32_t v) { WriteInt<std::uint32_t, true>(v); }
    void U64Be(std::uint64_t v) { WriteInt<std::uint64_t, true>(v); }
    void I16Be(std::int16_t v) { U16Be(static_cast<std::uint16_t>(v)); }
    void I32Be(std::int32_t v) { U32Be(static_cast<std::uint32_t>(v)); }
    void F32Be(float v);
    void F64Be(double v);

    void Bytes(ByteSpan bytes) { out_.insert(out_.end(), bytes.begin(), bytes.end()); }
    void Zeros(std::size_t n) { out_.insert(out_.end(), n, std::uint8_t{0}); }
    // Writes text into a fixed-width field of n bytes: truncated to n, NUL-padded.
    void FixedString(std::string_view text, std::size_t n);

    // Overwrites already written bytes (e.g. a length field known only at the end).
    // Returns false, writing nothing, if the range is not inside what was written.
    bool PatchU16Le(std::size_t offset, std::uint16_t v);
    bool PatchU16Be(std::size_t offset, std::uint16_t v);
    bool PatchU32Le(std::size_t offset, std::uint32_t v);

private:
    template <typename T, bool kBigEndian>
    void WriteInt(T value) {
        static_assert(std::is_unsigned_v<T>);
        for (std::size_t i = 0; i < sizeof(T); ++i) {
            const std::size_t shift = kBigEndian ? (sizeof(T) - 1 - i) * 8 : i * 8;
            out_.push_back(static_cast<std::uint8_t>((value >> shift) & 0xFFu));
        }
    }

    std::vector<std::uint8_t>& out_;
};

}  // namespace pitmap
