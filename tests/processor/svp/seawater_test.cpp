// SPDX-License-Identifier: MIT
// The seawater equations (processor/svp/seawater.hpp) against the check values printed in
// UNESCO Technical Papers in Marine Science 44 (Fofonoff & Millard 1983), whose tables give
// temperatures on IPTS-68: the functions take ITS-90, so the tests convert (T90 = T68 / 1.00024).
#include <gtest/gtest.h>

#include <cmath>

#include "processor/svp/seawater.hpp"

namespace {

using namespace pitmap::proc::svp;

double T90(double t68) {
    return t68 / 1.00024;
}

TEST(Seawater, ChenMilleroCheckValue) {
    // UNESCO 1983, SVEL: 1731.995 m/s at S = 40, T = 40 degC, P = 10000 dbar (printed to 1 mm/s).
    EXPECT_NEAR(SoundSpeedChenMillero(40.0, T90(40.0), 10000.0), 1731.995, 0.0005);
}

TEST(Seawater, ChenMilleroFreshWaterAtTheSurface) {
    // S = 0, P = 0 leaves the pure-water polynomial Cw(T, 0) of Chen & Millero (1977):
    // 1402.388 m/s at 0 degC; about 1482.3 m/s at 20 degC (Del Grosso & Mader 1972: 1482.34).
    EXPECT_NEAR(SoundSpeedChenMillero(0.0, 0.0, 0.0), 1402.388, 1e-9);
    EXPECT_NEAR(SoundSpeedChenMillero(0.0, T90(20.0), 0.0), 1482.34, 0.01);
    // Speed grows with temperature, salinity and pressure in the range of a pit.
    const double v = SoundSpeedChenMillero(0.5, 10.0, 10.0);
    EXPECT_GT(SoundSpeedChenMillero(0.5, 11.0, 10.0), v);
    EXPECT_GT(SoundSpeedChenMillero(1.5, 10.0, 10.0), v);
    EXPECT_GT(SoundSpeedChenMillero(0.5, 10.0, 50.0), v);
}

TEST(Seawater, DepthCheckValue) {
    // UNESCO 1983, DEPTH: 9712.653 m at 10000 dbar and latitude 30 deg.
    EXPECT_NEAR(DepthFromPressureUnesco(10000.0, 30.0), 9712.653, 0.0005);
    EXPECT_EQ(DepthFromPressureUnesco(0.0, 45.0), 0.0);
    // Near the surface: about 0.993 m per dbar (9.72659 / g).
    EXPECT_NEAR(DepthFromPressureUnesco(10.0, 45.0), 10.0 * 9.72659 / 9.806, 0.002);
}

TEST(Seawater, SalinityCheckValues) {
    // UNESCO 1983, SAL78: conductivity ratios R = C / C(35,15,0).
    const double c0 = kStandardConductivity_mS_cm;
    EXPECT_NEAR(SalinityFromConductivity(1.0 * c0, T90(15.0), 0.0), 35.0, 1e-6);
    EXPECT_NEAR(SalinityFromConductivity(1.2 * c0, T90(20.0), 2000.0), 37.245628, 1e-6);
    EXPECT_NEAR(SalinityFromConductivity(0.65 * c0, T90(5.0), 1500.0), 27.995347, 1e-6);
}

TEST(Seawater, SalinityOfFreshWater) {
    // Below S = 2 the Hill et al. (1986) extension: continuous at 2, positive, 0 at C = 0.
    const double t = 12.0;
    double c_at_2 = 0;
    for (double c = 1.0; c < 10.0; c += 1e-4) {
        if (SalinityFromConductivity(c, t, 0.0) >= 2.0) {
            c_at_2 = c;
            break;
        }
    }
    ASSERT_GT(c_at_2, 0.0);
    EXPECT_NEAR(SalinityFromConductivity(c_at_2 - 2e-4, t, 0.0), 2.0, 1e-3);
    EXPECT_GT(SalinityFromConductivity(0.05, t, 0.0), 0.0);  // 50 uS/cm: a very fresh pit
    EXPECT_LT(SalinityFromConductivity(0.05, t, 0.0), 0.05);
    EXPECT_EQ(SalinityFromConductivity(0.0, t, 0.0), 0.0);
    EXPECT_EQ(SalinityFromConductivity(-1.0, t, 0.0), 0.0);
}

}  // namespace
