// SPDX-License-Identifier: MIT
// Internal to processor/io: what the LCM-log and vendor-file readers of ingest.cpp share. The
// Collector turns decoded samples and pings into an IngestResult and counts what it refuses;
// a RawStream re-decodes one raw channel's bytes (NovAtel or 83P), stamping pings with the
// daemon's own rule (common/clock/ping_time.hpp).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/clock/ping_time.hpp"
#include "common/protocol/deltat/stream_framer.hpp"
#include "common/protocol/novatel/decoder.hpp"
#include "processor/io/ingest.hpp"

namespace pitmap::proc::io::detail {

namespace nv = pitmap::protocol::novatel;
namespace dt = pitmap::protocol::deltat;

// Most beams a ping may have (R2Sonic: 1024; the 83P: dt::kMaxBeams).
inline constexpr std::size_t kMaxPingBeams = 1024;

std::string Upper(std::string s);
bool StartsWith(std::string_view s, std::string_view prefix);
survey::NavSample FromPva(std::int64_t utime_gps,
                          double lat,
                          double lon,
                          double h,
                          double vn,
                          double ve,
                          double vu,
                          double roll_deg,
                          double pitch_deg,
                          double azimuth_deg,
                          int status,
                          int position_type);
// The standard deviations of INSPVAX and INSSTDEV (the decoded structs and their LCM types name
// the fields alike), stamped utime_gps.
template <class M>
survey::NavStdDev StdDevOf(std::int64_t utime_gps, const M& m) {
    return {utime_gps,
            m.latitude_stddev_m,
            m.longitude_stddev_m,
            m.height_stddev_m,
            m.roll_stddev_deg,
            m.pitch_stddev_deg,
            m.azimuth_stddev_deg};
}

// Accumulates into an IngestResult, shared by the LCM and vendor-file paths: counts what it
// refuses (no time, implausible, no beams) and keeps the rest (the INS status rule is
// applied to the whole series: ingest_sessions.hpp).
class Collector {
public:
    explicit Collector(IngestResult& r) : r_(r) {}
    void AddNav(const survey::NavSample& s);
    void AddStdDev(const survey::NavStdDev& s);
    void AddLeapSeconds(double utc_offset_s, int utc_status);
    // `intensities`: n per-beam intensities, or null when the ping has none; `angles_deg`: n
    // per-beam angles (survey::PingSeries::beam_angles_deg), or null for the header's.
    void AddPing(const survey::PingHeader& h_in,
                 const std::int32_t* counts,
                 std::size_t n,
                 const std::uint16_t* intensities = nullptr,
                 const float* angles_deg = nullptr);
    void AddPing83P(const dt::Ping83P& p, std::int64_t utime_gps);
    // NovAtel messages decoded from bytes (raw channels and files).
    void AddNovatel(const nv::DecodeResult& d);

private:
    IngestResult& r_;
    std::vector<std::int32_t> counts_buf_;
};

// Re-decoding state per raw source.
struct RawStream {
    std::unique_ptr<nv::Framer> novatel;
    std::unique_ptr<dt::StreamFramer> deltat;
    std::unique_ptr<clock::PingStamper> stamper;  // sonar channels: the daemon's clock model
    dt::FloatOrderMemory float_order;
    clock::ChunkTimes last_chunk;  // receive times of the latest chunk (the flush stamps with it)
};

void DrainNovatel(RawStream& s, Collector& col, IngestCounts& counts);
// A re-decoded ping, stamped as the daemon stamped it (common/clock/ping_time.hpp).
void AddRawPing(RawStream& s, Collector& col, const dt::Ping83P& ping);
void DrainDeltat(RawStream& s, Collector& col, IngestCounts& counts, dt::Ping83P& ping);

}  // namespace pitmap::proc::io::detail
