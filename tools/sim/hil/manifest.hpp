// SPDX-License-Identifier: MIT
// The HIL rig's ground-truth manifest: one JSON object per line (DIR/truth/hil_manifest.jsonl)
// for every byte item an emulator put on a wire, every datagram, every injected fault and every
// command or EC frame it received, so a test can hold the daemon's log against it.
//
// Common keys: "kind", "source" (emulator id), "utime" (host Unix microseconds when the item
// was complete on the wire), "t_s" (seconds since the survey start). Byte items add "len" and
// "fnv64" (FNV-1a 64 of the bytes, 16 hex digits):
//   kind "frame"          a NovAtel log, "id" = message id
//   kind "corrupt_frame"  a NovAtel log with one byte flipped (CRC fault), "id"
//   kind "garbage"        a burst of bytes that frame nothing
//   kind "response"       "<OK\r\n[PORT]" or "<ERROR:...\r\n[PORT]", "command" = the line
//   kind "datagram"       one 83P record; "ping", "utime_gps_transmit", "jitter_us" (the
//                         designed jitter), "late_us" (how much later than its schedule,
//                         jitter included, the emulator's thread got it out: this machine's
//                         scheduling, not a designed fault)
// Other kinds: "fault" ("fault": garbage | crc | unplug | replug | tcp_drop | outage,
// "lost_frames" for frames due while a port was away), "command" (a line received), "ec" (an
// EC frame received, "range_m", "start_gain_db"), "start" and "end" (run bounds).
// Byte items of one source appear in wire order.
//
// THREADING: Write() may be called from any thread (one mutex around the file).
#pragma once

#include <cstdint>
#include <cstdio>
#include <mutex>
#include <span>
#include <string>

#include "common/result.hpp"

namespace pitmap::sim::hil {

// FNV-1a, 64 bits: the manifest's byte hash.
std::uint64_t Fnv1a64(std::span<const std::uint8_t> bytes);
std::string HexU64(std::uint64_t v);

// One manifest line under construction: keys in insertion order, values already JSON.
class ManifestRecord {
public:
    ManifestRecord(const std::string& kind, const std::string& source);
    ManifestRecord& Int(const std::string& key, std::int64_t v);
    ManifestRecord& Num(const std::string& key, double v);
    ManifestRecord& Str(const std::string& key, const std::string& v);
    // "len" and "fnv64" of `bytes`.
    ManifestRecord& Bytes(std::span<const std::uint8_t> bytes);
    const std::string& json() const { return body_; }

private:
    std::string body_;
};

class Manifest {
public:
    Manifest() = default;
    ~Manifest();
    Manifest(const Manifest&) = delete;
    Manifest& operator=(const Manifest&) = delete;

    Status Open(const std::string& path);
    void Write(const ManifestRecord& record);
    void Close();

private:
    std::mutex mu_;
    std::FILE* file_ = nullptr;
};

}  // namespace pitmap::sim::hil
