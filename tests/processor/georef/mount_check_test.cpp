// SPDX-License-Identifier: MIT
// The mount check against the data (processor/georef/mount_check.hpp) on a synthetic survey: a
// vehicle rolling and pitching with the waves over a flat floor with a gentle slope, its head
// mounted as the truth says, the soundings georeferenced with a mount that is right, turned by
// 180 deg (mirrored fan) or by 90 deg (fan along the track), or without motion to resolve it.
#include "processor/georef/mount_check.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "common/frames.hpp"

namespace pitmap::proc::georef {
namespace {

struct Motion {
    double roll_deg = 2.0, pitch_deg = 1.0;
};

// 2 000 pings at 10 Hz along a lawnmower of 40 s lines over a floor 20 m deep that slopes 3 deg
// across; the head's true mount is the identity (connector aft); `configured` is the mount the
// soundings are computed with.
GeorefResult Survey(const survey::SonarMount& configured, const Motion& m = {}) {
    GeorefResult g;
    g.mount = configured;
    const survey::SonarMount truth;
    const double floor_slope = std::tan(frames::DegToRad(3.0));
    for (int k = 0; k < 2000; ++k) {
        const double t = k * 0.1;
        const bool back = (k / 400) % 2 == 1;
        const double yaw = back ? M_PI : 0.0;  // north, then south (ENU yaw from RPY: NED)
        const double roll = frames::DegToRad(m.roll_deg) * std::sin(2 * M_PI * t / 3.5);
        const double pitch = frames::DegToRad(m.pitch_deg) * std::sin(2 * M_PI * t / 5.3 + 0.7);
        GeorefPing p;
        p.utime_gps = 1'000'000'000'000 + static_cast<std::int64_t>(k) * 100'000;
        const double along = (k % 400) * 0.15;
        const Eigen::Vector3d pos(back ? 10.0 : 0.0, back ? 60.0 - along : along, 0.0);
        p.T_world_vehicle = MakePose(frames::RotationWorldFromRpy(roll, pitch, yaw), pos);
        p.sensor_world = pos;
        g.pings.push_back(p);
        const Eigen::Matrix3d R_true = p.T_world_vehicle.rotation() * truth.R_vehicle_sonar();
        const Eigen::Matrix3d R_conf = p.T_world_vehicle.rotation() * configured.R_vehicle_sonar();
        for (int b = 0; b < 121; ++b) {
            const double a = frames::DegToRad(-60.0 + b);
            const Eigen::Vector3d dir_sonar(0.0, std::sin(a), std::cos(a));
            const Eigen::Vector3d d = R_true * dir_sonar;  // world, where the beam went
            // Floor: z = -20 + slope * x.
            const double r =
                (-20.0 + floor_slope * pos.x() - pos.z()) / (d.z() - floor_slope * d.x());
            if (!(r > 0)) continue;
            g.points.position_world.push_back(pos + R_conf * (r * dir_sonar));
            g.points.ping.push_back(static_cast<std::uint32_t>(k));
            g.points.beam.push_back(static_cast<std::uint16_t>(b));
            g.points.range_m.push_back(static_cast<float>(r));
            g.points.angle_rad.push_back(static_cast<float>(a));
        }
    }
    return g;
}

TEST(MountCheck, TheRightMountExplainsTheSoundings) {
    const MountCheck c = CheckMountAgainstAttitude(Survey(survey::SonarMount{}));
    ASSERT_TRUE(c.checked) << c.message;
    EXPECT_TRUE(c.consistent) << c.message;
    EXPECT_LT(std::abs(c.roll_gain), 0.05) << c.message;
    EXPECT_LT(std::abs(c.pitch_gain), 0.05) << c.message;
}

TEST(MountCheck, AHeadTurned180DegreesTiltsTheFloorByTwiceTheRoll) {
    survey::SonarMount forward;
    forward.boresight_yaw_deg = 180;
    const MountCheck c = CheckMountAgainstAttitude(Survey(forward));
    ASSERT_TRUE(c.checked) << c.message;
    EXPECT_FALSE(c.consistent) << c.message;
    EXPECT_NEAR(std::abs(c.roll_gain), 2.0, 0.2) << c.message;
    EXPECT_NE(c.likely_cause.find("mirrored"), std::string::npos) << c.likely_cause;
    EXPECT_NE(c.likely_cause.find("sonar.mount.connector"), std::string::npos) << c.likely_cause;
}

TEST(MountCheck, AHeadTurned90DegreesKeepsTheRollAndGainsThePitch) {
    survey::SonarMount port;
    port.boresight_yaw_deg = 90;
    const MountCheck c = CheckMountAgainstAttitude(Survey(port));
    ASSERT_TRUE(c.checked) << c.message;
    EXPECT_FALSE(c.consistent) << c.message;
    EXPECT_NEAR(std::abs(c.roll_gain), 1.0, 0.2) << c.message;
    EXPECT_NEAR(std::abs(c.pitch_gain), 1.0, 0.2) << c.message;
    EXPECT_NE(c.likely_cause.find("along the track"), std::string::npos) << c.likely_cause;
}

TEST(MountCheck, WithoutMotionItCannotTellAndSaysSo) {
    survey::SonarMount forward;
    forward.boresight_yaw_deg = 180;
    const MountCheck c = CheckMountAgainstAttitude(Survey(forward, Motion{0.0, 0.0}));
    EXPECT_FALSE(c.checked) << c.message;
    EXPECT_TRUE(c.consistent);
    EXPECT_NE(c.message.find("hardly moved"), std::string::npos) << c.message;
}

}  // namespace
}  // namespace pitmap::proc::georef

// Decision 033: the mount check on blocks of whole pings (MountCheckByBlocks, as georef sees
// the view it writes to its file) is the check of the whole view, to the bit.
namespace pitmap::proc::georef {
namespace {

TEST(MountCheck, BlocksOfWholePingsGiveTheWholeViewsCheck) {
    for (const bool turned : {false, true}) {
        survey::SonarMount configured;
        if (turned) configured.boresight_yaw_deg = 180.0;
        const GeorefResult g = Survey(configured);
        const MountCheck whole = CheckMountAgainstAttitude(g);
        ASSERT_TRUE(whole.checked) << whole.message;
        for (const std::uint32_t pings_a_block : {1u, 7u, 333u, 5000u}) {
            MountCheckByBlocks check;
            GeorefPoints block;
            const auto flush = [&] {
                check.Add(g, block);
                block = GeorefPoints{};
            };
            for (std::size_t j = 0; j < g.points.size(); ++j) {
                if (block.size() > 0 &&
                    g.points.ping[j] / pings_a_block != block.ping.front() / pings_a_block) {
                    flush();
                }
                block.position_world.push_back(g.points.position_world[j]);
                block.ping.push_back(g.points.ping[j]);
                block.beam.push_back(g.points.beam[j]);
                block.range_m.push_back(g.points.range_m[j]);
                block.angle_rad.push_back(g.points.angle_rad[j]);
            }
            flush();
            const MountCheck by = check.Check(g);
            SCOPED_TRACE(pings_a_block);
            EXPECT_EQ(by.checked, whole.checked);
            EXPECT_EQ(by.consistent, whole.consistent);
            EXPECT_EQ(by.pings, whole.pings);
            EXPECT_EQ(by.roll_gain, whole.roll_gain);
            EXPECT_EQ(by.pitch_gain, whole.pitch_gain);
            EXPECT_EQ(by.roll_gain_sd, whole.roll_gain_sd);
            EXPECT_EQ(by.message, whole.message);
        }
    }
}

}  // namespace
}  // namespace pitmap::proc::georef
