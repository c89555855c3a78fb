// SPDX-License-Identifier: MIT
#include "processor/georef/series.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::proc::georef {

void SortAndDeduplicate(NavSeries& nav) {
    auto by_time = [](const auto& a, const auto& b) { return a.utime_gps < b.utime_gps; };
    auto same_time = [](const auto& a, const auto& b) { return a.utime_gps == b.utime_gps; };
    std::stable_sort(nav.samples.begin(), nav.samples.end(), by_time);
    nav.samples.erase(std::unique(nav.samples.begin(), nav.samples.end(), same_time),
                      nav.samples.end());
    std::stable_sort(nav.stddevs.begin(), nav.stddevs.end(), by_time);
    nav.stddevs.erase(std::unique(nav.stddevs.begin(), nav.stddevs.end(), same_time),
                      nav.stddevs.end());
}

void SortAndDeduplicate(PingSeries& s) {
    std::vector<std::size_t> order(s.pings.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return s.pings[a].utime_gps < s.pings[b].utime_gps;
    });
    PingSeries out;
    out.clock = s.clock;
    out.pings.reserve(s.pings.size());
    out.range_counts.reserve(s.range_counts.size());
    const bool with_intensities =
        s.intensities.size() == s.range_counts.size() && !s.intensities.empty();
    if (with_intensities) out.intensities.reserve(s.intensities.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
        const PingHeader& h = s.pings[order[k]];
        if (!out.pings.empty() && out.pings.back().utime_gps == h.utime_gps) continue;
        PingHeader c = h;
        c.beam_offset = static_cast<std::uint32_t>(out.range_counts.size());
        out.range_counts.insert(out.range_counts.end(),
                                s.range_counts.begin() + h.beam_offset,
                                s.range_counts.begin() + h.beam_offset + h.num_beams);
        if (with_intensities) {
            out.intensities.insert(out.intensities.end(),
                                   s.intensities.begin() + h.beam_offset,
                                   s.intensities.begin() + h.beam_offset + h.num_beams);
        }
        out.pings.push_back(c);
    }
    s = std::move(out);
}

void ShiftPingTimes(PingSeries& pings, double correction_s) {
    const auto d = static_cast<std::int64_t>(std::llround(correction_s * 1e6));
    for (auto& p : pings.pings) p.utime_gps += d;
}

namespace {

std::int64_t LineShiftUs(std::int64_t t, double correction_s, double rate, std::int64_t ref) {
    return static_cast<std::int64_t>(
        std::llround(correction_s * 1e6 + rate * static_cast<double>(t - ref)));
}

}  // namespace

void ShiftPingTimes(PingSeries& pings,
                    double correction_s,
                    double rate,
                    std::int64_t reference_utime) {
    for (auto& p : pings.pings)
        p.utime_gps += LineShiftUs(p.utime_gps, correction_s, rate, reference_utime);
}

}  // namespace pitmap::proc::georef
