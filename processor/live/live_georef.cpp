// SPDX-License-Identifier: MIT
#include "processor/live/live_georef.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::proc::live {

std::vector<std::string> LiveGeorefConfig::Validate() const {
    std::vector<std::string> p = georef.Validate();
    if (!(nav_keep_s >= 1) || !std::isfinite(nav_keep_s))
        p.push_back("live.nav_keep_s must be >= 1");
    if (max_pending < 1) p.push_back("live.max_pending must be >= 1");
    return p;
}

LiveGeoref::LiveGeoref(const LiveGeorefConfig& config, const survey::SonarMount& mount)
    : config_(config), mount_(mount) {
    config_.georef.num_threads = 1;
}

void LiveGeoref::AddNav(const survey::NavSample& s) {
    const bool finite =
        std::isfinite(s.position.latitude_deg) && std::abs(s.position.latitude_deg) <= 90 &&
        std::isfinite(s.position.longitude_deg) && std::abs(s.position.longitude_deg) <= 360 &&
        std::isfinite(s.position.height_m) && std::isfinite(s.roll_rad) &&
        std::isfinite(s.pitch_rad) && std::isfinite(s.yaw_rad);
    // INSPVAS and INSPVAX of one epoch share a time: the first is kept (as SortAndDeduplicate).
    if (s.utime_gps <= 0 || !finite || (!nav_.empty() && s.utime_gps <= nav_.back().utime_gps)) {
        ++counts_.nav_refused;
        return;
    }
    if (!origin_) origin_ = s.position;
    nav_.push_back(s);
    ++counts_.nav_samples;
    const auto keep = static_cast<std::int64_t>(config_.nav_keep_s * 1e6);
    while (nav_.size() > 2 && nav_.front().utime_gps < s.utime_gps - keep) nav_.pop_front();
}

void LiveGeoref::AddPing(const survey::PingHeader& h, const std::int32_t* counts, std::size_t n) {
    ++counts_.pings_in;
    if (h.utime_gps <= 0 || n == 0 || n > 0xFFFF) {
        ++counts_.pings_refused;
        return;
    }
    Pending p;
    p.header = h;
    p.header.num_beams = static_cast<std::uint16_t>(n);
    p.counts.resize(n);
    for (std::size_t i = 0; i < n; ++i)
        p.counts[i] = counts[i] > 0 ? static_cast<std::uint32_t>(counts[i]) : 0u;
    // Pings arrive in time order; a late one is inserted in place.
    auto at = std::upper_bound(
        pending_.begin(), pending_.end(), h.utime_gps, [](std::int64_t t, const Pending& q) {
            return t < q.header.utime_gps;
        });
    pending_.insert(at, std::move(p));
    while (pending_.size() > config_.max_pending) {
        pending_.pop_front();
        ++counts_.pings_dropped_waiting;
    }
}

Expected<std::optional<LiveBatch>> LiveGeoref::Process() {
    if (nav_.empty() || pending_.empty()) return std::optional<LiveBatch>{};
    const std::int64_t newest = nav_.back().utime_gps;
    std::size_t n_ready = 0;
    while (n_ready < pending_.size() && pending_[n_ready].header.utime_gps <= newest) ++n_ready;
    if (n_ready == 0) return std::optional<LiveBatch>{};

    survey::PingSeries pings;
    pings.pings.reserve(n_ready);
    for (std::size_t k = 0; k < n_ready; ++k) {
        survey::PingHeader h = pending_[k].header;
        h.beam_offset = static_cast<std::uint32_t>(pings.range_counts.size());
        pings.range_counts.insert(
            pings.range_counts.end(), pending_[k].counts.begin(), pending_[k].counts.end());
        pings.pings.push_back(h);
    }
    const std::int64_t t0 = pings.pings.front().utime_gps, t1 = pings.pings.back().utime_gps;
    // The INS samples that bracket the batch: the last at or before t0 to the first at or
    // after t1.
    auto lo = std::upper_bound(nav_.begin(), nav_.end(), t0, [](std::int64_t t, const auto& s) {
        return t < s.utime_gps;
    });
    if (lo != nav_.begin()) --lo;
    auto hi = std::lower_bound(nav_.begin(), nav_.end(), t1, [](const auto& s, std::int64_t t) {
        return s.utime_gps < t;
    });
    if (hi != nav_.end()) ++hi;
    survey::NavSeries nav;
    nav.samples.assign(lo, hi);
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n_ready));

    LiveBatch batch;
    batch.result = georef::RunGeoref(nav, pings, mount_, config_.georef, origin_);
    ++counts_.batches;
    const georef::GeorefCounts& c = batch.result.counts;
    georef::GeorefCounts& t = counts_.georef;
    t.pings_in += c.pings_in;
    t.pings_georeferenced += c.pings_georeferenced;
    t.pings_outside_nav += c.pings_outside_nav;
    t.pings_in_nav_gap += c.pings_in_nav_gap;
    t.pings_bad_header += c.pings_bad_header;
    t.soundings_in += c.soundings_in;
    t.no_detection += c.no_detection;
    t.range_gate += c.range_gate;
    t.spikes += c.spikes;
    t.refraction_failed += c.refraction_failed;
    t.points += c.points;
    auto utm = georef::ToUtm(batch.result);
    if (!utm) return utm.error();
    batch.utm = std::move(*utm);
    return std::optional<LiveBatch>(std::move(batch));
}

}  // namespace pitmap::proc::live
