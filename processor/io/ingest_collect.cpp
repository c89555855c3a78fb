// SPDX-License-Identifier: MIT
#include "processor/io/ingest_collect.hpp"

#include <cctype>
#include <cmath>
#include <limits>
#include <type_traits>
#include <variant>

#include "common/frames.hpp"

namespace pitmap::proc::io::detail {

using survey::NavSample;
using survey::NavStdDev;
using survey::PingHeader;

std::string Upper(std::string s) {
    for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

bool StartsWith(std::string_view s, std::string_view prefix) {
    return s.size() >= prefix.size() && s.substr(0, prefix.size()) == prefix;
}

NavSample FromPva(std::int64_t utime_gps,
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
                  int position_type) {
    NavSample s;
    s.utime_gps = utime_gps;
    s.position = {lat, lon, h};
    s.roll_rad = frames::DegToRad(roll_deg);
    s.pitch_rad = frames::DegToRad(pitch_deg);
    s.yaw_rad = frames::WrapPi(frames::DegToRad(azimuth_deg));
    s.velocity_enu_mps = Eigen::Vector3d(ve, vn, vu);
    s.ins_status = status;
    s.position_type = position_type;
    return s;
}

namespace {

bool PlausibleNav(const NavSample& s) {
    return std::isfinite(s.position.latitude_deg) && std::abs(s.position.latitude_deg) <= 90 &&
           std::isfinite(s.position.longitude_deg) && std::abs(s.position.longitude_deg) <= 360 &&
           std::isfinite(s.position.height_m) && std::isfinite(s.roll_rad) &&
           std::isfinite(s.pitch_rad) && std::isfinite(s.yaw_rad);
}

}  // namespace

void Collector::AddNav(const NavSample& s) {
    if (s.utime_gps <= 0) {
        ++r_.counts.nav_without_time;
        return;
    }
    if (!PlausibleNav(s)) {
        ++r_.counts.decode_failures;
        return;
    }
    // The INS status rule is applied to the whole series (ApplyInsStatusRule), which knows
    // the windows.
    r_.nav.samples.push_back(s);
}
void Collector::AddStdDev(const NavStdDev& s) {
    if (s.utime_gps <= 0) return;
    r_.nav.stddevs.push_back(s);
}
void Collector::AddLeapSeconds(double utc_offset_s, int utc_status) {
    if (utc_status == 1 && std::isfinite(utc_offset_s)) {
        r_.nav.leap_seconds = static_cast<int>(std::lround(-utc_offset_s));
    }
}
void Collector::AddPing(const PingHeader& h_in,
                        const std::int32_t* counts,
                        std::size_t n,
                        const std::uint16_t* intensities,
                        const float* angles_deg) {
    if (h_in.utime_gps <= 0) {
        ++r_.counts.pings_without_time;
        return;
    }
    if (n == 0 || n > kMaxPingBeams) {
        ++r_.counts.pings_bad;
        return;
    }
    PingHeader h = h_in;
    h.beam_offset = static_cast<std::uint32_t>(r_.pings.range_counts.size());
    h.num_beams = static_cast<std::uint16_t>(n);
    for (std::size_t i = 0; i < n; ++i) {
        r_.pings.range_counts.push_back(counts[i] > 0 ? static_cast<std::uint32_t>(counts[i]) : 0u);
    }
    // Intensities beside the counts: the first ping with some gives the earlier pings zeros
    // ("none"); a ping without any after that gets zeros too.
    auto& in = r_.pings.intensities;
    if (intensities != nullptr && in.empty()) in.assign(h.beam_offset, 0);
    if (intensities != nullptr) {
        in.insert(in.end(), intensities, intensities + n);
    } else if (!in.empty()) {
        in.resize(in.size() + n, 0);
    }
    // Per-beam angles likewise, NaN ("the header's") for the pings without.
    auto& an = r_.pings.beam_angles_deg;
    if (angles_deg != nullptr && an.empty()) an.assign(h.beam_offset, survey::kNaNf);
    if (angles_deg != nullptr) {
        an.insert(an.end(), angles_deg, angles_deg + n);
    } else if (!an.empty()) {
        an.resize(an.size() + n, survey::kNaNf);
    }
    r_.pings.pings.push_back(h);
}
void Collector::AddPing83P(const dt::Ping83P& p, std::int64_t utime_gps) {
    PingHeader h;
    h.utime_gps = utime_gps;
    h.ping_number = p.ping_number;
    h.sound_speed_mps = p.sound_velocity_mps;
    h.sound_speed_valid = p.sound_velocity_valid;
    h.range_resolution_m = p.range_resolution_mm / 1000.0;
    h.start_angle_deg = p.start_angle_deg();
    h.angle_increment_deg = p.angle_increment_deg();
    h.profile_tilt_deg = p.profile_tilt_deg;
    h.aid_latitude_deg = p.latitude_deg;
    h.aid_longitude_deg = p.longitude_deg;
    // The head's own sensor first; the topside's external fields when it has none.
    const bool v110 = p.is_v110();
    const auto ext = [&](std::uint8_t bit, float v) {
        return v110 && (p.external_sensor_flags & bit) != 0 && std::isfinite(v)
                   ? static_cast<double>(v)
                   : std::numeric_limits<double>::quiet_NaN();
    };
    h.aid_roll_deg = p.internal_roll_valid ? p.internal_roll_deg
                                           : ext(dt::kExternalRollValid, p.external_roll_deg);
    h.aid_pitch_deg = p.internal_pitch_valid ? p.internal_pitch_deg
                                             : ext(dt::kExternalPitchValid, p.external_pitch_deg);
    h.aid_attitude_at_ping = p.internal_roll_valid && p.internal_pitch_valid;
    h.aid_heading_deg = p.internal_heading_valid
                            ? p.internal_heading_deg
                            : ext(dt::kExternalHeadingValid, p.external_heading_deg);
    counts_buf_.assign(p.range_counts.begin(), p.range_counts.end());
    const bool with = p.intensity_included && p.intensities.size() == p.range_counts.size();
    AddPing(h, counts_buf_.data(), counts_buf_.size(), with ? p.intensities.data() : nullptr);
}

void Collector::AddNovatel(const nv::DecodeResult& d) {
    std::visit(
        [&](const auto& m) {
            using T = std::decay_t<decltype(m)>;
            if constexpr (std::is_same_v<T, nv::InsPva>) {
                AddNav(FromPva(m.utime_gps(),
                               m.latitude_deg,
                               m.longitude_deg,
                               m.height_ellipsoid_m,
                               m.velocity_north_mps,
                               m.velocity_east_mps,
                               m.velocity_up_mps,
                               m.roll_deg,
                               m.pitch_deg,
                               m.azimuth_deg,
                               static_cast<int>(m.ins_status),
                               -1));
            } else if constexpr (std::is_same_v<T, nv::InsPvaX>) {
                AddNav(FromPva(m.utime_gps(),
                               m.latitude_deg,
                               m.longitude_deg,
                               m.height_msl_m + m.undulation_m,
                               m.velocity_north_mps,
                               m.velocity_east_mps,
                               m.velocity_up_mps,
                               m.roll_deg,
                               m.pitch_deg,
                               m.azimuth_deg,
                               static_cast<int>(m.ins_status),
                               static_cast<int>(m.position_type)));
                AddStdDev(StdDevOf(m.utime_gps(), m));
            } else if constexpr (std::is_same_v<T, nv::InsStdDev>) {
                AddStdDev(StdDevOf(m.utime_gps(), m));
            } else if constexpr (std::is_same_v<T, nv::Time>) {
                AddLeapSeconds(m.utc_offset_s, static_cast<int>(m.utc_status));
            } else if constexpr (std::is_same_v<T, nv::DecodeError>) {
                ++r_.counts.raw_decode_errors;
            }
        },
        d);
}

void DrainNovatel(RawStream& s, Collector& col, IngestCounts& counts) {
    while (true) {
        auto ev = s.novatel->Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (auto* sk = std::get_if<protocol::Skipped>(&ev)) {
            counts.raw_skipped_bytes += static_cast<std::int64_t>(sk->bytes);
            continue;
        }
        col.AddNovatel(nv::Decode(std::get<nv::Frame>(ev)));
    }
}

void AddRawPing(RawStream& s, Collector& col, const dt::Ping83P& ping) {
    col.AddPing83P(ping, s.stamper->Stamp(ping, clock::ReceiveUtimeGps(s.last_chunk)).utime_gps);
}

void DrainDeltat(RawStream& s, Collector& col, IngestCounts& counts, dt::Ping83P& ping) {
    while (true) {
        auto ev = s.deltat->Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (auto* sk = std::get_if<protocol::Skipped>(&ev)) {
            counts.raw_skipped_bytes += static_cast<std::int64_t>(sk->bytes);
            continue;
        }
        const auto& rec = std::get<dt::Record>(ev);
        auto d = dt::DecodeRecord83PInto(rec.bytes, s.float_order, ping);
        if (std::holds_alternative<dt::DecodeError>(d)) {
            ++counts.pings_bad;
        } else if (std::get<dt::RecordKind>(d) == dt::RecordKind::kPing) {
            AddRawPing(s, col, ping);
        }
    }
}

}  // namespace pitmap::proc::io::detail
