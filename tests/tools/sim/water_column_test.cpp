// SPDX-License-Identifier: MIT
// The simulator's water column: the thermocline profile, and its numerically tabulated curved
// rays against straight rays (homogeneous water) and against Snell's law (the end angle).
#include "tools/sim/water_column.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace pitmap::sim {
namespace {

TEST(WaterColumn, ProfileIsContinuousWithAThermocline) {
    WaterColumnConfig w;
    EXPECT_DOUBLE_EQ(w.SpeedAt(0.0), w.surface_speed_mps);
    EXPECT_DOUBLE_EQ(w.SpeedAt(w.mixed_layer_depth_m), w.surface_speed_mps);
    EXPECT_NEAR(w.SpeedAt(w.thermocline_depth_m - 1e-9), w.deep_speed_mps, 1e-6);
    EXPECT_NEAR(w.SpeedAt(w.thermocline_depth_m + 10), w.deep_speed_mps + 0.17, 1e-9);
    const double mid = 0.5 * (w.mixed_layer_depth_m + w.thermocline_depth_m);
    EXPECT_NEAR(w.SpeedAt(mid), 0.5 * (w.surface_speed_mps + w.deep_speed_mps), 1e-9);
}

PitConfig SmallPit() {
    PitConfig p;
    p.half_length_m = 20;
    p.half_width_m = 15;
    p.max_depth_m = 12;
    p.floor_depth_m = 10;
    p.num_benches = 1;
    p.bench_width_m = 3;
    p.backfill_amplitude_m = 1.2;
    p.backfill_wavelength_m = 12;
    return p;
}

TEST(WaterColumn, HomogeneousWaterGivesStraightRays) {
    WaterColumnConfig w;
    w.surface_speed_mps = w.deep_speed_mps = 1480;
    w.deep_gradient_per_s = 0;
    const WaterColumn col(w, 22.0);
    const PitWorld world(SmallPit(), 3);
    const Eigen::Vector3d origin(1.0, -2.0, -0.3);
    for (double a : {0.0, 20.0, 45.0, 60.0}) {
        const double t = a * 3.14159265358979 / 180;
        const Eigen::Vector3d dir(std::sin(t) * 0.6, std::sin(t) * 0.8, -std::cos(t));
        const auto curved = col.Cast(world, origin, dir, 0.1);
        const auto straight = world.RayCast(origin, dir, 100.0);
        ASSERT_TRUE(curved && straight) << a;
        EXPECT_NEAR(curved->one_way_time_s * 1480, *straight, 2e-4) << a;
        EXPECT_NEAR((curved->point - (origin + *straight * dir)).norm(), 0.0, 2e-4) << a;
    }
}

TEST(WaterColumn, RaysBendTowardsTheVerticalInColderWater) {
    const WaterColumnConfig w;  // 1496 m/s over a thermocline down to 1452 m/s
    const WaterColumn col(w, 22.0);
    const PitWorld world(SmallPit(), 3);
    const Eigen::Vector3d origin(0.0, 0.0, -0.25);
    const double t = 45 * 3.14159265358979 / 180;
    const Eigen::Vector3d dir(std::sin(t), 0.0, -std::cos(t));
    const auto hit = col.Cast(world, origin, dir, 0.1);
    ASSERT_TRUE(hit);
    const double depth = -hit->point.z();
    ASSERT_GT(depth, w.thermocline_depth_m);
    // Snell's law by a quadrature of dx = tan(phi) dz, sin(phi) = p c(z), to the hit's depth:
    // the ray is steeper than 45 deg below the thermocline, so it lands short of the straight
    // line (about 0.2 m here).
    const double p = std::sin(t) / w.SpeedAt(0.25);
    const int n = 100000;
    const double dz = (depth - 0.25) / n;
    double x = 0;
    for (int i = 0; i < n; ++i) {
        const double sn = p * w.SpeedAt(0.25 + (i + 0.5) * dz);
        x += dz * sn / std::sqrt(1 - sn * sn);
    }
    EXPECT_NEAR(hit->point.x(), x, 2e-3);
    const double straight_x = (depth - 0.25) * std::tan(t);
    EXPECT_LT(hit->point.x(), straight_x - 0.1);
    // The path is longer in time than the straight chord at the surface speed.
    EXPECT_GT(hit->one_way_time_s, (hit->point - origin).norm() / w.surface_speed_mps);
}

}  // namespace
}  // namespace pitmap::sim
