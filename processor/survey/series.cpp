// SPDX-License-Identifier: MIT
#include "processor/survey/series.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::proc::survey {

namespace {

// Same message: INSPVAS and INSPVAX of one epoch agree to float rounding (the latter's height
// is rebuilt from a float undulation), two recordings of different surveys do not.
bool SameNavContent(const NavSample& a, const NavSample& b) {
    constexpr double kDegPerM = 1.0 / 111000.0;
    constexpr double kPosTolM = 0.05, kAngleTolRad = 0.05 * 3.14159265358979323846 / 180.0;
    const double cos_lat = std::cos(a.position.latitude_deg * 3.14159265358979323846 / 180.0);
    const auto wrap = [](double x) { return std::remainder(x, 2 * 3.14159265358979323846); };
    return std::abs(a.position.latitude_deg - b.position.latitude_deg) <= kPosTolM * kDegPerM &&
           std::abs(a.position.longitude_deg - b.position.longitude_deg) * cos_lat <=
               kPosTolM * kDegPerM &&
           std::abs(a.position.height_m - b.position.height_m) <= kPosTolM &&
           std::abs(wrap(a.roll_rad - b.roll_rad)) <= kAngleTolRad &&
           std::abs(wrap(a.pitch_rad - b.pitch_rad)) <= kAngleTolRad &&
           std::abs(wrap(a.yaw_rad - b.yaw_rad)) <= kAngleTolRad;
}

}  // namespace

void SortAndDeduplicate(NavSeries& nav, std::vector<std::int64_t>* conflicts) {
    auto by_time = [](const auto& a, const auto& b) { return a.utime_gps < b.utime_gps; };
    auto same_time = [](const auto& a, const auto& b) { return a.utime_gps == b.utime_gps; };
    std::stable_sort(nav.samples.begin(), nav.samples.end(), by_time);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < nav.samples.size(); ++i) {
        if (kept > 0 && nav.samples[kept - 1].utime_gps == nav.samples[i].utime_gps) {
            if (conflicts && !SameNavContent(nav.samples[kept - 1], nav.samples[i]) &&
                (conflicts->empty() || conflicts->back() != nav.samples[i].utime_gps)) {
                conflicts->push_back(nav.samples[i].utime_gps);
            }
            continue;
        }
        nav.samples[kept++] = nav.samples[i];
    }
    nav.samples.resize(kept);
    std::stable_sort(nav.stddevs.begin(), nav.stddevs.end(), by_time);
    nav.stddevs.erase(std::unique(nav.stddevs.begin(), nav.stddevs.end(), same_time),
                      nav.stddevs.end());
}

void SortAndDeduplicate(PingSeries& s, std::vector<std::int64_t>* conflicts) {
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
    const bool with_angles =
        s.beam_angles_deg.size() == s.range_counts.size() && !s.beam_angles_deg.empty();
    if (with_angles) out.beam_angles_deg.reserve(s.beam_angles_deg.size());
    std::size_t last_kept = 0;  // index into s.pings of out.pings.back()
    for (std::size_t k = 0; k < order.size(); ++k) {
        const PingHeader& h = s.pings[order[k]];
        if (!out.pings.empty() && out.pings.back().utime_gps == h.utime_gps) {
            const PingHeader& a = s.pings[last_kept];
            const bool same = a.ping_number == h.ping_number && a.num_beams == h.num_beams &&
                              std::equal(s.range_counts.begin() + a.beam_offset,
                                         s.range_counts.begin() + a.beam_offset + a.num_beams,
                                         s.range_counts.begin() + h.beam_offset);
            if (conflicts && !same && (conflicts->empty() || conflicts->back() != h.utime_gps))
                conflicts->push_back(h.utime_gps);
            continue;
        }
        last_kept = order[k];
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
        if (with_angles) {
            out.beam_angles_deg.insert(out.beam_angles_deg.end(),
                                       s.beam_angles_deg.begin() + h.beam_offset,
                                       s.beam_angles_deg.begin() + h.beam_offset + h.num_beams);
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

}  // namespace pitmap::proc::survey
