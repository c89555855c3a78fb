// SPDX-License-Identifier: MIT
#include "tools/sim/hil/manifest.hpp"

#include <cmath>

namespace pitmap::sim::hil {
namespace {

std::string Quote(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
        if (c == '"' || c == '\\') {
            out += '\\';
            out += c;
        } else if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof(buf), "\\u%04x", static_cast<unsigned>(c));
            out += buf;
        } else {
            out += c;
        }
    }
    return out + "\"";
}

}  // namespace

std::uint64_t Fnv1a64(std::span<const std::uint8_t> bytes) {
    std::uint64_t h = 0xcbf29ce484222325ull;
    for (const std::uint8_t b : bytes) {
        h ^= b;
        h *= 0x100000001b3ull;
    }
    return h;
}

std::string HexU64(std::uint64_t v) {
    char buf[20];
    std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(v));
    return buf;
}

ManifestRecord::ManifestRecord(const std::string& kind, const std::string& source) {
    body_ = "{\"kind\":" + Quote(kind) + ",\"source\":" + Quote(source);
}

ManifestRecord& ManifestRecord::Int(const std::string& key, std::int64_t v) {
    body_ += "," + Quote(key) + ":" + std::to_string(v);
    return *this;
}

ManifestRecord& ManifestRecord::Num(const std::string& key, double v) {
    char buf[40];
    if (std::isfinite(v)) {
        std::snprintf(buf, sizeof(buf), "%.9g", v);
    } else {
        std::snprintf(buf, sizeof(buf), "null");
    }
    body_ += "," + Quote(key) + ":" + buf;
    return *this;
}

ManifestRecord& ManifestRecord::Str(const std::string& key, const std::string& v) {
    body_ += "," + Quote(key) + ":" + Quote(v);
    return *this;
}

ManifestRecord& ManifestRecord::Bytes(std::span<const std::uint8_t> bytes) {
    Int("len", static_cast<std::int64_t>(bytes.size()));
    return Str("fnv64", HexU64(Fnv1a64(bytes)));
}

Manifest::~Manifest() {
    Close();
}

Status Manifest::Open(const std::string& path) {
    std::lock_guard<std::mutex> lock(mu_);
    if (file_ != nullptr) std::fclose(file_);
    file_ = std::fopen(path.c_str(), "w");
    if (file_ == nullptr) return Error{path + ": cannot create the HIL manifest"};
    return Ok{};
}

void Manifest::Write(const ManifestRecord& record) {
    std::lock_guard<std::mutex> lock(mu_);
    if (file_ == nullptr) return;
    std::fputs(record.json().c_str(), file_);
    std::fputs("}\n", file_);
}

void Manifest::Close() {
    std::lock_guard<std::mutex> lock(mu_);
    if (file_ != nullptr) {
        std::fclose(file_);
        file_ = nullptr;
    }
}

}  // namespace pitmap::sim::hil
