// SPDX-License-Identifier: MIT
#include "common/geodesy.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace pitmap {
namespace {

TEST(LocalTangentFrame, RoundTripAroundTheSurvey) {
    // Bejanca mine, Portugal (approximate).
    const LocalTangentFrame frame({40.44, -7.78, 350.0});
    EXPECT_TRUE(frame.ToEnu(frame.origin()).isZero(1e-9));
    for (const Eigen::Vector3d& enu :
         {Eigen::Vector3d(62.5, 45.0, -27.0), Eigen::Vector3d(-300, 10, 2)}) {
        const Geodetic g = frame.FromEnu(enu);
        EXPECT_TRUE(frame.ToEnu(g).isApprox(enu, 1e-9));
    }
    // 1 arc-second of latitude is about 30.87 m north at 40 deg N.
    const Geodetic north{40.44 + 1.0 / 3600.0, -7.78, 350.0};
    const Eigen::Vector3d enu = frame.ToEnu(north);
    EXPECT_NEAR(enu.x(), 0.0, 1e-6);
    EXPECT_NEAR(enu.y(), 30.85, 0.05);
}

TEST(LocalTangentFrame, CopiesAreIndependent) {
    LocalTangentFrame a({10, 20, 0});
    LocalTangentFrame b = a;
    a = LocalTangentFrame({-10, 20, 0});
    EXPECT_DOUBLE_EQ(b.origin().latitude_deg, 10);
    EXPECT_TRUE(b.ToEnu({10, 20, 0}).isZero(1e-9));
}

TEST(Utm, ReferenceValue) {
    // Central meridian of zone 31 (3 deg E) on the equator: easting 500 000 m, northing 0.
    const auto u = UtmFromGeodetic({0.0, 3.0, 0.0});
    ASSERT_TRUE(u.ok());
    EXPECT_EQ(u->zone, 31);
    EXPECT_TRUE(u->northern);
    EXPECT_NEAR(u->easting_m, 500000.0, 1e-6);
    EXPECT_NEAR(u->northing_m, 0.0, 1e-6);
    EXPECT_EQ(UtmEpsgCode(u->zone, u->northern), 32631);
}

TEST(Utm, RoundTripBothHemispheresAndForcedZone) {
    for (const Geodetic& g : {Geodetic{40.44, -7.78, 350}, Geodetic{-33.9, 151.2, 10}}) {
        const auto u = UtmFromGeodetic(g);
        ASSERT_TRUE(u.ok());
        const auto back = GeodeticFromUtm(*u);
        ASSERT_TRUE(back.ok());
        EXPECT_NEAR(back->latitude_deg, g.latitude_deg, 1e-9);
        EXPECT_NEAR(back->longitude_deg, g.longitude_deg, 1e-9);
    }
    const auto u = UtmFromGeodetic({40.44, -7.78, 0}, 30);  // neighbour zone, still valid
    ASSERT_TRUE(u.ok());
    EXPECT_EQ(u->zone, 30);
    EXPECT_EQ(UtmEpsgCode(29, false), 32729);
}

TEST(Utm, PolesUseUps) {
    const auto u = UtmFromGeodetic({89.9, 0.0, 0.0});
    ASSERT_TRUE(u.ok());
    EXPECT_EQ(u->zone, 0);
    const auto back = GeodeticFromUtm(*u);
    ASSERT_TRUE(back.ok());
    EXPECT_NEAR(back->latitude_deg, 89.9, 1e-9);
    EXPECT_EQ(UtmEpsgCode(0, true), 32661);
}

TEST(Utm, BadInputIsAnErrorNotACrash) {
    EXPECT_FALSE(UtmFromGeodetic({91.0, 0.0, 0.0}).ok());
    EXPECT_FALSE(UtmFromGeodetic({NAN, 0.0, 0.0}).ok());
    EXPECT_FALSE(UtmFromGeodetic({10.0, 0.0, 0.0}, 61).ok());
    EXPECT_FALSE(UtmFromGeodetic({89.0, 0.0, 0.0}, 31).ok());  // zone 31 does not reach 89 N
}

}  // namespace
}  // namespace pitmap
