// SPDX-License-Identifier: MIT
// Encoded LCM input for LiveSession tests: a level vehicle heading north at 1 m/s from kStart
// over a flat bottom kDepthM down, INS and multibeam pings at the times the test asks for.
#pragma once

#include <cmath>
#include <cstdint>
#include <pitmap/ins_pva_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "lcmtypes/log/channels.hpp"
#include "processor/live/session.hpp"

namespace pitmap::proc::live {
namespace test {

constexpr double kDepthM = 10.0;
constexpr std::int64_t kHost0 = 1'781'500'000'000'000;
constexpr std::int64_t kGps0 = 1'465'000'000'000'000;
constexpr std::int64_t kS = 1'000'000;
const Geodetic kStart{40.0, -7.0, 100.0};

template <class M>
std::vector<std::uint8_t> Encode(const M& m) {
    std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(b.data(), 0, static_cast<int>(b.size()));
    return b;
}

class Feeder {
public:
    explicit Feeder(LiveSession& s) : s_(s), world_(kStart) {}
    // Reported INS height sigma (INSPVAX), m; <= 0 = none (INSPVAS).
    double height_sigma_m = 0;
    void Nav(std::int64_t dt_us) {
        pitmap::ins_pva_t m{};
        m.utime = kHost0 + dt_us;
        m.utime_gps = kGps0 + dt_us;
        const Geodetic p = world_.FromEnu(Eigen::Vector3d(0, 1.0 * dt_us * 1e-6, 0));
        m.latitude_deg = p.latitude_deg;
        m.longitude_deg = p.longitude_deg;
        m.height_ellipsoid_m = p.height_m;
        m.velocity_north_mps = 1.0;
        m.ins_status = 3;
        m.position_type = -1;
        m.has_stddev = height_sigma_m > 0 ? 1 : 0;
        if (m.has_stddev) {
            m.latitude_stddev_m = m.longitude_stddev_m = 0.01f;
            m.height_stddev_m = static_cast<float>(height_sigma_m);
            m.roll_stddev_deg = m.pitch_stddev_deg = 0.015f;
            m.azimuth_stddev_deg = 0.04f;
        }
        Send(std::string(lcmlog::kChannelInsPva) + "NOVATEL_COM1", Encode(m), m.utime);
    }
    void Ping(std::int64_t dt_us) {
        pitmap::multibeam_ping_t m{};
        m.utime = kHost0 + dt_us + 2000;
        m.utime_gps = kGps0 + dt_us;
        m.range_resolution_m = 0.002f;
        m.start_angle_deg = -60;
        m.angle_increment_deg = 1.0f;
        m.sound_speed_mps = 1500;
        m.num_beams = 121;
        for (int i = 0; i < m.num_beams; ++i) {
            const double th = (m.start_angle_deg + i * m.angle_increment_deg) * M_PI / 180.0;
            m.range_counts.push_back(
                static_cast<std::int32_t>(std::lround(kDepthM / std::cos(th) / 0.002)));
        }
        m.num_intensities = 0;
        Send(std::string(lcmlog::kChannelMultibeamPing) + "DELTAT_UDP", Encode(m), m.utime);
    }
    void Send(const std::string& ch, const std::vector<std::uint8_t>& b, std::int64_t utime) {
        s_.OnEvent(ch, b.data(), b.size(), utime);
    }

private:
    LiveSession& s_;
    LocalTangentFrame world_;
};

}  // namespace test
}  // namespace pitmap::proc::live
