// SPDX-License-Identifier: MIT
// The INS's slow error stated from the GNSS fixes in the ping headers (docs/decisions/027): a
// survey in laps whose INS sits off by more than it reports, with header fixes that are noisy
// and stale along the track.
#include "processor/calib/ins_slow_error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/frames.hpp"
#include "common/geodesy.hpp"

namespace pitmap::proc::calib {
namespace {

constexpr double kRadius95 = 2.4477;  // Rayleigh: 95 % of a circular error within this x sigma

struct Lap {
    // A 60 m x 40 m rectangle at 1.5 m/s (sharp corners); position and heading at t.
    Eigen::Vector2d p;
    double yaw;  // from north, clockwise (NED)
};

Lap LapAt(double t) {
    const double v = 1.5, a = 60, b = 40, perimeter = 2 * (a + b);
    double s = std::fmod(v * t, perimeter);
    const double legs[4] = {a, b, a, b};
    const double yaws[4] = {frames::kPi / 2, 0.0, -frames::kPi / 2, frames::kPi};  // E N W S
    Eigen::Vector2d p(0, 0);
    for (int k = 0; k < 4; ++k) {
        const Eigen::Vector2d dir(std::sin(yaws[k]), std::cos(yaws[k]));
        if (s <= legs[k]) return {p + s * dir, yaws[k]};
        p += legs[k] * dir;
        s -= legs[k];
    }
    return {p, yaws[0]};
}

struct Survey {
    survey::NavSeries nav;
    survey::PingSeries pings;
    std::vector<double> ins_error_east, ins_error_north;  // per nav sample, GNSS-good only
};

// INS at 20 Hz = truth + a constant offset + a Gauss-Markov error (sigma gm, 60 s) + 5 mm white;
// it reports 1 cm. Outage 300-400 s: 1.5 m of error, a reported sigma of 1 m. Pings at 10 Hz,
// each carrying the last 1 Hz fix of the antenna (2 cm white noise) received 0.2 s after it.
Survey MakeLaps(const Eigen::Vector2d& offset, double gm_sigma_m, std::uint32_t seed) {
    Survey sv;
    const Geodetic origin{-23.5, 133.9, 300.0};
    const LocalTangentFrame world(origin);
    const Eigen::Vector3d lever(-0.5, 0.0, -1.2);
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    // Two draws in a fixed order (north first), not as two arguments of one call, whose order
    // of evaluation is unspecified: one realisation whatever the compiler.
    const auto g2 = [&] {
        const double north = g(rng);
        const double east = g(rng);
        return Eigen::Vector2d(east, north);
    };
    const double duration = 700, dt = 0.05, tau = 60;
    const double phi = std::exp(-dt / tau), q = std::sqrt(1 - phi * phi);
    Eigen::Vector2d gm = gm_sigma_m * g2();
    const std::int64_t t0 = 1'400'000'000'000'000;
    for (int k = 0; k * dt <= duration; ++k) {
        const double t = k * dt;
        gm = phi * gm + gm_sigma_m * q * g2();
        const bool outage = t >= 300 && t < 400;
        const Lap lap = LapAt(t);
        Eigen::Vector2d e = offset + gm + 0.005 * g2();
        if (outage) e += Eigen::Vector2d(1.5, -1.0);
        survey::NavSample s;
        s.utime_gps = t0 + std::llround(t * 1e6);
        s.yaw_rad = lap.yaw;
        s.position = world.FromEnu({lap.p.x() + e.x(), lap.p.y() + e.y(), 0.0});
        sv.nav.samples.push_back(s);
        if (!outage && k % 20 == 0) {
            survey::NavStdDev sd;
            sd.utime_gps = s.utime_gps;
            sd.east_m = sd.north_m = 0.01f;
            sd.up_m = 0.015f;
            sv.nav.stddevs.push_back(sd);
        }
        if (outage && k % 20 == 0) {
            survey::NavStdDev sd;
            sd.utime_gps = s.utime_gps;
            sd.east_m = sd.north_m = 1.0f;
            sd.up_m = 0.4f;
            sv.nav.stddevs.push_back(sd);
        }
        if (!outage && t > 430) {
            sv.ins_error_east.push_back(e.x());
            sv.ins_error_north.push_back(e.y());
        }
    }
    // Pings: the header holds the fix of epoch floor(t - 0.2).
    Eigen::Vector3d fix_enu = Eigen::Vector3d::Zero();
    long last_epoch = -1;
    for (int k = 0; k * 0.1 <= duration; ++k) {
        const double t = k * 0.1;
        const long epoch = std::lround(std::floor(t - 0.2));
        if (epoch < 0) continue;
        if (epoch != last_epoch) {
            const Lap lap = LapAt(static_cast<double>(epoch));
            const Eigen::Matrix3d R = frames::RotationWorldFromRpy(0, 0, lap.yaw);
            fix_enu = Eigen::Vector3d(lap.p.x(), lap.p.y(), 0.0) + R * lever;
            fix_enu.x() += 0.02 * g(rng);
            fix_enu.y() += 0.02 * g(rng);
            last_epoch = epoch;
        }
        survey::PingHeader h;
        h.utime_gps = t0 + std::llround(t * 1e6);
        const Geodetic fix = world.FromEnu(fix_enu);
        h.aid_latitude_deg = fix.latitude_deg;
        h.aid_longitude_deg = fix.longitude_deg;
        sv.pings.pings.push_back(h);
    }
    return sv;
}

// The share of GNSS-good INS outputs within the 95 % radius of a per-axis sigma.
double ShareWithin(const Survey& sv, double sigma) {
    std::size_t in = 0;
    for (std::size_t i = 0; i < sv.ins_error_east.size(); ++i) {
        in += std::hypot(sv.ins_error_east[i], sv.ins_error_north[i]) <= kRadius95 * sigma ? 1 : 0;
    }
    return static_cast<double>(in) / static_cast<double>(sv.ins_error_east.size());
}

InsSlowErrorConfig WithLever() {
    InsSlowErrorConfig c;
    c.antenna_lever_arm_m = Eigen::Vector3d(-0.5, 0.0, -1.2);
    return c;
}

TEST(InsSlowError, AnOffsetTheInsDoesNotReportIsStatedFromTheHeaderFixes) {
    // 2 cm east and north: a 2.8 cm error where the INS reports 1 cm (95 % radius 2.4 cm).
    const Survey sv = MakeLaps({0.02, -0.02}, 0.002, 1);
    ASSERT_LT(ShareWithin(sv, 0.01), 0.2);  // the INS's own report contains almost none
    const InsSlowError e = EstimateInsSlowError(sv.pings, sv.nav, WithLever());
    ASSERT_TRUE(e.estimated) << e.message;
    EXPECT_NEAR(e.reported_sigma_m, 0.01, 1e-6);
    // Per axis the error's RMS is 2.0 cm; the fixes' 0.2 s staleness (30 cm along the track)
    // and their 2 cm noise do not enter.
    EXPECT_NEAR(e.slow_sigma_m, 0.020, 0.004) << e.message;
    EXPECT_NEAR(e.white_sigma_m, std::hypot(0.02, 0.005), 0.005) << e.message;
    // The outage (100 s, 1.5 m off) and the 30 s after it are left out: 570 s of fixes less
    // the turns.
    EXPECT_GT(e.fixes, 400U);
    EXPECT_LT(e.fixes, 571U);
    EXPECT_GE(ShareWithin(sv, std::max(e.reported_sigma_m, e.slow_sigma_m)), 0.93);
}

TEST(InsSlowError, AnInsAsGoodAsItReportsIsNotInflated) {
    // A Gauss-Markov error of 1 cm with no offset: the estimate is its realised RMS, near 1 cm.
    const Survey sv = MakeLaps({0.0, 0.0}, 0.01, 2);
    const InsSlowError e = EstimateInsSlowError(sv.pings, sv.nav, WithLever());
    ASSERT_TRUE(e.estimated) << e.message;
    double ms = 0;
    for (std::size_t i = 0; i < sv.ins_error_east.size(); ++i) {
        ms += 0.5 * (sv.ins_error_east[i] * sv.ins_error_east[i] +
                     sv.ins_error_north[i] * sv.ins_error_north[i]);
    }
    const double realised = std::sqrt(ms / static_cast<double>(sv.ins_error_east.size()));
    EXPECT_NEAR(e.slow_sigma_m, realised, 0.004) << e.message << " realised " << realised;
    EXPECT_LT(e.slow_sigma_m, 0.016) << e.message;
}

TEST(InsSlowError, WithoutFixesOrStddevsItSaysWhy) {
    Survey sv = MakeLaps({0.0, 0.0}, 0.01, 3);
    survey::PingSeries none = sv.pings;
    for (auto& h : none.pings) h.aid_latitude_deg = h.aid_longitude_deg = std::nan("");
    const InsSlowError a = EstimateInsSlowError(none, sv.nav, WithLever());
    EXPECT_FALSE(a.estimated);
    EXPECT_NE(a.message.find("0 usable GNSS fixes"), std::string::npos) << a.message;
    sv.nav.stddevs.clear();
    const InsSlowError b = EstimateInsSlowError(sv.pings, sv.nav, WithLever());
    EXPECT_FALSE(b.estimated);
    EXPECT_NE(b.message.find("standard deviation"), std::string::npos) << b.message;
    InsSlowErrorConfig bad = WithLever();
    bad.good_sigma_ratio = 0.5;
    EXPECT_FALSE(bad.Validate().empty());
    EXPECT_FALSE(EstimateInsSlowError(sv.pings, sv.nav, bad).estimated);
}

TEST(InsSlowError, TheWavesMotionIsNotTakenForTheSlowError) {
    // Innovations at 1 Hz on one heading: a slow sine of 1.5 cm RMS, 2 cm white noise and a
    // wave's 3.5 s motion of 2 cm RMS (the antenna's roll over the fix's staleness): the fast
    // part decorrelates within the 2-10 s lags, the slow one does not.
    std::mt19937 rng(4);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<AcrossInnovation> a;
    double ms = 0;
    for (int i = 0; i < 2000; ++i) {
        const double slow = 0.015 * std::sqrt(2.0) * std::sin(i / 90.0);
        const double wave = 0.02 * std::sqrt(2.0) * std::sin(2 * frames::kPi * i / 3.5 + 0.3);
        ms += slow * slow;
        a.push_back({static_cast<double>(i), slow + wave + 0.02 * g(rng), 0.5});
    }
    const InsSlowError e = SlowErrorFromInnovations(a);
    ASSERT_TRUE(e.estimated) << e.message;
    EXPECT_NEAR(e.slow_sigma_m, std::sqrt(ms / 2000.0), 0.002) << e.message;
    EXPECT_NEAR(e.white_sigma_m, std::hypot(0.02, 0.02), 0.003) << e.message;
    // Opposite headings flip the across-track sign (laps of 5 s each way): products across a
    // turn would be negative; they are not taken.
    std::vector<AcrossInnovation> b = a;
    for (std::size_t i = 0; i < b.size(); ++i) {
        if ((i / 5) % 2 == 1) {
            b[i].across_m = -b[i].across_m;
            b[i].course_rad += frames::kPi;
        }
    }
    const InsSlowError f = SlowErrorFromInnovations(b);
    ASSERT_TRUE(f.estimated) << f.message;
    EXPECT_NEAR(f.slow_sigma_m, std::sqrt(ms / 2000.0), 0.003) << f.message;
}

}  // namespace
}  // namespace pitmap::proc::calib
