// SPDX-License-Identifier: MIT
// Incremental georeferencing for the live view: INS samples and pings arrive as they are
// published; each ping is georeferenced, through processor/georef's RunGeoref (the one
// georeferencer), as soon as an INS sample at or after its time has arrived, i.e. as soon as
// navigation brackets it. The world origin is the first INS position and stays fixed.
//
// Bounded memory: INS samples older than nav_keep_s behind the newest are dropped; pings that
// wait for navigation beyond max_pending are dropped oldest first and counted.
// Pings older than the oldest kept INS sample, or in a gap wider than max_nav_gap_s, are refused
// by RunGeoref and counted there (counts().georef).
// Thread safety: none.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "processor/georef/georef.hpp"

namespace pitmap::proc::live {

struct LiveGeorefConfig {
    georef::GeorefConfig georef;     // num_threads is forced to 1
    double nav_keep_s = 30.0;        // INS history kept behind the newest sample
    std::size_t max_pending = 2000;  // pings waiting for navigation
    std::vector<std::string> Validate() const;
};

struct LiveGeorefCounts {
    std::int64_t nav_samples = 0;
    std::int64_t nav_refused = 0;  // no time, not finite, or older than the newest sample
    std::int64_t pings_in = 0;
    std::int64_t pings_refused = 0;          // no time, no beams
    std::int64_t pings_dropped_waiting = 0;  // beyond max_pending
    std::int64_t batches = 0;
    georef::GeorefCounts georef;  // summed over the batches
};

// One batch of georeferenced pings, with the soundings' UTM coordinates.
struct LiveBatch {
    georef::GeorefResult result;
    georef::UtmPoints utm;
};

class LiveGeoref {
public:
    LiveGeoref(const LiveGeorefConfig& config, const survey::SonarMount& mount);

    void AddNav(const survey::NavSample& s);
    void AddPing(const survey::PingHeader& h, const std::int32_t* counts, std::size_t n);
    // Georeferences every waiting ping that navigation now brackets; nullopt when there is none.
    // A UTM failure (the origin cannot be projected) is an error.
    Expected<std::optional<LiveBatch>> Process();

    const LiveGeorefCounts& counts() const { return counts_; }
    std::size_t pending() const { return pending_.size(); }
    std::size_t nav_kept() const { return nav_.size(); }
    bool has_origin() const { return origin_.has_value(); }
    const Geodetic& origin() const { return *origin_; }

private:
    struct Pending {
        survey::PingHeader header;
        std::vector<std::uint32_t> counts;
    };
    LiveGeorefConfig config_;
    survey::SonarMount mount_;
    std::optional<Geodetic> origin_;
    std::deque<survey::NavSample> nav_;
    std::deque<Pending> pending_;  // time-sorted
    LiveGeorefCounts counts_;
};

}  // namespace pitmap::proc::live
