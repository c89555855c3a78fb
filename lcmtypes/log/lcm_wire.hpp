// SPDX-License-Identifier: MIT
// Bounds checks for LCM-encoded messages read from outside (log files, the network), before
// lcm-gen's decode() sees them.
//
// lcm-gen's C++ decode() trusts the counts in the bytes: a negative array count throws
// std::length_error out of vector::resize, a count of 0x7fffffff allocates gigabytes before the
// read fails, and a string length of 0 or below assigns (size_t)-1 bytes. LcmWire walks the
// encoding (LCM type specification: big-endian primitives, int32 string length including the
// NUL, arrays sized by an earlier integer member, nested structs without a fingerprint) from the
// project's own .lcm definitions, embedded at build time, so that it cannot drift from the
// generated code. A message passes only when every length lies within the bytes that hold it
// and the walk ends exactly at the end of the buffer; then decode() allocates no more than the
// message's own size.
//
// DecodeChecked() is the one way shore code and tools decode an outside message.
#pragma once

#include <climits>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace pitmap::lcmlog {

struct Dim {
    std::int64_t size = 0;  // fixed size, when `ref` is empty
    std::string ref;        // name of the integer member holding the size
    int ref_index = -1;     // that member's index in Struct::fields (resolved by Parse)
};

struct Field {
    std::string type;  // primitive name, or a struct name without its package
    std::string name;
    std::vector<Dim> dims;
};

struct Struct {
    // More members than any LCM type of the project has; Parse refuses a larger struct.
    static constexpr std::size_t kMaxFields = 128;
    std::string name;
    std::vector<Field> fields;
};

// The structs of a set of .lcm texts, by name (without the package).
class Schema {
public:
    // Parses .lcm texts; throws std::runtime_error naming the text and line on a syntax it
    // does not know (a build-time input, never outside data).
    static Schema Parse(const std::vector<std::string_view>& texts);
    // The project's lcmtypes/pitmap/*.lcm.
    static const Schema& Pitmap();

    const Struct* Find(std::string_view name) const;
    // Empty when `data` is a well-formed encoding of struct `type` (fingerprint first, then
    // exactly the struct's bytes); otherwise why not, e.g. "num_beams = -1".
    std::string Check(std::string_view type, const void* data, std::size_t size) const;

private:
    std::map<std::string, Struct, std::less<>> structs_;
};

// Decodes `msg` from `data` only when it is a well-formed encoding of T that fills `size`
// bytes exactly; false otherwise (never throws, never allocates beyond `size`).
template <class T>
bool DecodeChecked(T& msg, const void* data, std::size_t size, std::string* why = nullptr) {
    if (size > static_cast<std::size_t>(INT32_MAX)) {
        if (why) *why = "message larger than 2 GiB";
        return false;
    }
    if (size < 8) {
        if (why) *why = "shorter than a fingerprint";
        return false;
    }
    const auto* b = static_cast<const std::uint8_t*>(data);
    std::uint64_t hash = 0;
    for (int i = 0; i < 8; ++i) hash = (hash << 8) | b[i];
    if (static_cast<std::int64_t>(hash) != T::getHash()) {
        if (why) *why = std::string("not a ") + T::getTypeName() + " (fingerprint)";
        return false;
    }
    std::string problem = Schema::Pitmap().Check(T::getTypeName(), data, size);
    if (problem.empty()) {
        try {
            const int n = static_cast<int>(size);
            if (msg.decode(data, 0, n) == n) return true;
            problem = "lcm decode failed";
        } catch (const std::exception& e) {
            problem = std::string("lcm decode threw: ") + e.what();
        }
    }
    if (why) *why = std::move(problem);
    return false;
}

}  // namespace pitmap::lcmlog
