// SPDX-License-Identifier: MIT
// The ray tracer against closed forms: constant speed (straight lines), one constant-gradient
// layer (circular arc: tan(phi/2) = tan(phi0/2) exp(g t), x = (cos phi0 - cos phi) / (p g)),
// Snell's invariant across layers, the travel time and horizontal distance against a numerical
// quadrature of dt = dz / (c cos phi), dx = tan phi dz, and the beam refraction of georef.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "processor/svp/ray_trace.hpp"
#include "processor/svp/refraction.hpp"

namespace {

using namespace pitmap::proc::svp;

constexpr double kPi = 3.14159265358979323846;
double Deg(double d) {
    return d * kPi / 180.0;
}

TEST(RayTrace, ConstantSpeedIsAStraightLine) {
    // Several knots at the same speed: the legs must add up to one straight line.
    const LayeredProfile prof({0, 2, 5, 9, 20}, {1480, 1480, 1480, 1480, 1480});
    for (double a : {0.0, 10.0, 30.0, 45.0, 60.0, 75.0, 85.0}) {
        for (double T : {0.001, 0.004, 0.02, 0.05}) {
            const RayEnd e = TraceRay(prof, 0.3, Deg(a), T);
            ASSERT_EQ(e.status, RayStatus::kOk) << a << " " << T;
            EXPECT_NEAR(e.horizontal_m, 1480 * T * std::sin(Deg(a)), 1e-9) << a << " " << T;
            EXPECT_NEAR(e.depth_m, 0.3 + 1480 * T * std::cos(Deg(a)), 1e-9) << a << " " << T;
            EXPECT_NEAR(e.sin_angle, std::sin(Deg(a)), 1e-12);
        }
    }
}

// The circular-arc closed form of one layer c = c0 + g z from z = 0.
void ExpectArc(double c0, double g, double launch_deg, double T) {
    const LayeredProfile prof({0, 500}, {c0, c0 + g * 500});
    const double phi0 = Deg(launch_deg);
    const double p = std::sin(phi0) / c0;
    const double phi = 2 * std::atan(std::tan(phi0 / 2) * std::exp(g * T));
    const double c = std::sin(phi) / p;
    const double z = (c - c0) / g;
    const double x = (std::cos(phi0) - std::cos(phi)) / (p * g);
    const RayEnd e = TraceRay(prof, 0.0, phi0, T);
    ASSERT_EQ(e.status, RayStatus::kOk);
    EXPECT_NEAR(e.depth_m, z, 1e-7) << "g " << g << " launch " << launch_deg << " T " << T;
    EXPECT_NEAR(e.horizontal_m, x, 1e-7) << "g " << g << " launch " << launch_deg << " T " << T;
    // On the circle of radius 1 / (p |g|) centred where c would be 0.
    const double R = 1 / (p * std::abs(g));
    const double zc = -c0 / g;
    const double xc = std::cos(phi0) / (p * g);
    EXPECT_NEAR(std::hypot(e.horizontal_m - xc, e.depth_m - zc), R, 1e-6 * R);
}

TEST(RayTrace, OneGradientLayerIsACircularArc) {
    for (double g : {-2.0, -0.5, -0.017, 0.017, 0.5, 1.5}) {
        for (double a : {5.0, 30.0, 45.0, 60.0, 70.0}) {
            for (double T : {0.002, 0.01, 0.03}) ExpectArc(1490.0, g, a, T);
        }
    }
}

TEST(RayTrace, VerticalRayInAGradient) {
    const double c0 = 1500, g = -1.2, T = 0.02;
    const LayeredProfile prof({0, 100}, {c0, c0 + g * 100});
    const RayEnd e = TraceRay(prof, 0.0, 0.0, T);
    ASSERT_EQ(e.status, RayStatus::kOk);
    // dz/dt = c, dc/dt = g c: z = c0 (exp(g T) - 1) / g.
    EXPECT_NEAR(e.depth_m, c0 * std::expm1(g * T) / g, 1e-8);
    EXPECT_NEAR(e.horizontal_m, 0.0, 1e-12);
}

TEST(RayTrace, TinyGradientIsAStraightSegment) {
    for (double g : {1e-14, 1e-10, -1e-9}) {
        const LayeredProfile prof({0, 100}, {1480, 1480 + g * 100});
        const RayEnd e = TraceRay(prof, 0.0, Deg(60), 0.02);
        ASSERT_EQ(e.status, RayStatus::kOk);
        EXPECT_NEAR(e.horizontal_m, 1480 * 0.02 * std::sin(Deg(60)), 1e-6) << g;
        EXPECT_NEAR(e.depth_m, 1480 * 0.02 * std::cos(Deg(60)), 1e-6) << g;
    }
    // Continuity: 1e-6 1/s against the closed-form arc.
    ExpectArc(1480.0, 1e-6, 60.0, 0.02);
}

// A thermocline profile (warm layer over cold water).
LayeredProfile Thermocline() {
    return LayeredProfile({0, 2, 3, 4, 5, 6, 7, 8, 12, 40},
                          {1496, 1495.5, 1492, 1484, 1472, 1462, 1456, 1453, 1452, 1452.4});
}

TEST(RayTrace, SnellInvariantHoldsAcrossLayers) {
    const LayeredProfile prof = Thermocline();
    for (double a : {15.0, 45.0, 60.0, 65.0}) {
        const double z0 = 0.4;
        const double p = std::sin(Deg(a)) / prof.SpeedAt(z0);
        for (double T : {0.001, 0.003, 0.006, 0.012, 0.02}) {
            const RayEnd e = TraceRay(prof, z0, Deg(a), T);
            ASSERT_EQ(e.status, RayStatus::kOk);
            EXPECT_NEAR(e.sin_angle / prof.SpeedAt(e.depth_m), p, 1e-12 * p) << a << " " << T;
            // Composition: T1 then T - T1 from where the first part ended.
            const double T1 = 0.4 * T;
            const RayEnd a1 = TraceRay(prof, z0, Deg(a), T1);
            const RayEnd a2 = TraceRay(prof, a1.depth_m, std::asin(a1.sin_angle), T - T1);
            EXPECT_NEAR(a1.horizontal_m + a2.horizontal_m, e.horizontal_m, 1e-7);
            EXPECT_NEAR(a2.depth_m, e.depth_m, 1e-7);
        }
    }
}

TEST(RayTrace, TravelTimeAndDistanceMatchAQuadrature) {
    const LayeredProfile prof = Thermocline();
    for (double a : {0.0, 30.0, 60.0}) {
        const double z0 = 0.25;
        const double T = 0.018;  // one way: about 27 m of path
        const RayEnd e = TraceRay(prof, z0, Deg(a), T);
        ASSERT_EQ(e.status, RayStatus::kOk);
        EXPECT_DOUBLE_EQ(e.time_s, T);
        // Midpoint quadrature over depth to the end depth (independent of the closed forms).
        const double p = std::sin(Deg(a)) / prof.SpeedAt(z0);
        const int n = 400000;
        const double dz = (e.depth_m - z0) / n;
        double t = 0, x = 0;
        for (int i = 0; i < n; ++i) {
            const double c = prof.SpeedAt(z0 + (i + 0.5) * dz);
            const double s = p * c, k = std::sqrt(1 - s * s);
            t += dz / (c * k);
            x += dz * s / k;
        }
        EXPECT_NEAR(t, T, 1e-9) << a;  // the legs' times sum to the one-way time
        EXPECT_NEAR(x, e.horizontal_m, 1e-6) << a;
        EXPECT_GT(e.layers, 5);
    }
}

TEST(RayTrace, TurningSurfacingAndHorizontalRaysAreReported) {
    // Speed increasing with depth bends a shallow ray back up.
    const LayeredProfile up({0, 50}, {1450, 1500});
    EXPECT_EQ(TraceRay(up, 0.0, Deg(80), 0.2).status, RayStatus::kTurned);
    EXPECT_EQ(TraceRay(up, 0.0, Deg(80), 0.001).status, RayStatus::kOk);
    // An upward ray reaches the surface.
    const LayeredProfile flat({0, 10}, {1480, 1480});
    const RayEnd s = TraceRay(flat, 0.5, Deg(120), 0.01);
    EXPECT_EQ(s.status, RayStatus::kSurfaced);
    EXPECT_NEAR(s.horizontal_m, 0.5 * std::tan(Deg(60)), 1e-9);
    const RayEnd ok_up = TraceRay(flat, 2.0, Deg(120), 0.0005);
    EXPECT_EQ(ok_up.status, RayStatus::kOk);
    EXPECT_NEAR(ok_up.depth_m, 2.0 - 1480 * 0.0005 * 0.5, 1e-9);
    EXPECT_EQ(TraceRay(flat, 0.5, Deg(90), 0.01).status, RayStatus::kHorizontal);
    EXPECT_EQ(TraceRay(flat, 0.5, Deg(30), -1.0).status, RayStatus::kInvalid);
    EXPECT_EQ(TraceRay(flat, 0.5, Deg(30), NAN).status, RayStatus::kInvalid);
}

TEST(RayTrace, StartSpeedSetsSnellsParameter) {
    // The launch angle refers to 1500 m/s at the face while the water is 1480 m/s: the ray
    // leaves at asin(sin(a) 1480 / 1500).
    const LayeredProfile flat({0, 10}, {1480, 1480});
    const RayEnd e = TraceRay(flat, 0.0, Deg(60), 0.01, 1500.0);
    const double s = std::sin(Deg(60)) * 1480 / 1500;
    EXPECT_NEAR(e.horizontal_m, 14.8 * s, 1e-9);
    EXPECT_NEAR(e.depth_m, 14.8 * std::sqrt(1 - s * s), 1e-9);
}

TEST(Refraction, ConstantProfileAtTheAssumedSpeedGivesTheStraightBeam) {
    SoundSpeedCast c;
    c.name = "flat";
    c.depth_m = {0, 50};
    c.speed_mps = {1480, 1480};
    const Refraction r({c}, CastSelection::kNearestPreceding, SurfaceSpeedSource::kProfile, 0.0);
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(3.1, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    for (double theta : {-1.0, -0.3, 0.0, 0.4, 1.0}) {
        const double tilt = 0.1, range = 23.0;
        const BeamGeometry b = r.Beam(0, R, theta, tilt, range, 1480.0, 0.3, 1480.0);
        ASSERT_EQ(b.status, RayStatus::kOk);
        const Eigen::Vector3d straight = R *
                                         Eigen::Vector3d(std::sin(tilt) * std::cos(theta),
                                                         std::sin(theta),
                                                         std::cos(tilt) * std::cos(theta)) *
                                         range;
        EXPECT_NEAR((b.offset_world - straight).norm(), 0.0, 1e-9) << theta;
    }
}

TEST(Refraction, SteeringIsCorrectedForTheFaceSpeed) {
    // The sonar assumed 1500 m/s; the water at the face is 1470 m/s: sin(theta') scales by
    // 1470/1500 and the range 1500 * T becomes 1470 * T of path.
    SoundSpeedCast c;
    c.name = "flat";
    c.depth_m = {0, 50};
    c.speed_mps = {1470, 1470};
    const Refraction r({c}, CastSelection::kNearestPreceding, SurfaceSpeedSource::kProfile, 0.0);
    // R_world_sonar for a level sonar heading north: sonar x fwd -> north, y stbd -> east,
    // z down -> -up.
    Eigen::Matrix3d R;
    R << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    const double theta = Deg(60), range = 30.0;
    const double face = r.FaceSpeed(0, 0.5, 1500.0);
    EXPECT_DOUBLE_EQ(face, 1470.0);
    const BeamGeometry b = r.Beam(0, R, theta, 0.0, range, 1500.0, 0.5, face);
    ASSERT_EQ(b.status, RayStatus::kOk);
    const double s = std::sin(theta) * 1470 / 1500, path = range * 1470 / 1500;
    EXPECT_NEAR(b.offset_world.x(), path * s, 1e-9);
    EXPECT_NEAR(b.offset_world.y(), 0.0, 1e-9);
    EXPECT_NEAR(b.offset_world.z(), -path * std::sqrt(1 - s * s), 1e-9);
    // With the header as the face speed nothing changes in the steering.
    const Refraction h({c}, CastSelection::kNearestPreceding, SurfaceSpeedSource::kHeader, 0.0);
    EXPECT_DOUBLE_EQ(h.FaceSpeed(0, 0.5, 1500.0), 1500.0);
}

TEST(Refraction, LaunchAngleIsMeasuredAfterAttitude) {
    // A 10 deg roll turns a 50 deg beam into a 60 deg (or 40 deg) launch from the vertical:
    // in a gradient the two refract differently, so the roll must enter before the trace.
    SoundSpeedCast c;
    c.name = "grad";
    c.depth_m = {0, 40};
    c.speed_mps = {1495, 1455};
    const Refraction r({c}, CastSelection::kNearestPreceding, SurfaceSpeedSource::kProfile, 0.0);
    Eigen::Matrix3d R_level;
    R_level << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    const Eigen::Matrix3d roll = Eigen::AngleAxisd(-Deg(10), Eigen::Vector3d::UnitX()).matrix();
    const double range = 30, T = range / 1495;
    const BeamGeometry b = r.Beam(0, R_level * roll, Deg(50), 0.0, range, 1495, 0.0, 1495);
    const RayEnd e = TraceRay(r.casts()[0].profile, 0.0, Deg(60), T);
    ASSERT_EQ(b.status, RayStatus::kOk);
    EXPECT_NEAR(b.offset_world.head<2>().norm(), e.horizontal_m, 1e-9);
    EXPECT_NEAR(-b.offset_world.z(), e.depth_m, 1e-9);
}

TEST(Refraction, CastSelection) {
    auto cast = [](std::int64_t t, double lat, double lon) {
        SoundSpeedCast c;
        c.name = "c" + std::to_string(t);
        c.utime_gps = t;
        c.latitude_deg = lat;
        c.longitude_deg = lon;
        c.depth_m = {0, 10};
        c.speed_mps = {1490, 1480};
        return c;
    };
    const std::vector<SoundSpeedCast> casts = {
        cast(3000, 40.0, -7.0), cast(1000, 40.001, -7.0), cast(2000, 40.0, -7.002)};
    const Refraction pre(casts, CastSelection::kNearestPreceding, SurfaceSpeedSource::kProfile, 0);
    EXPECT_EQ(pre.SelectCast(500, 0, 0), 1);  // before every cast: the first one
    EXPECT_EQ(pre.SelectCast(1999, 0, 0), 1);
    EXPECT_EQ(pre.SelectCast(2000, 0, 0), 2);
    EXPECT_EQ(pre.SelectCast(9000, 0, 0), 0);
    const Refraction near(casts, CastSelection::kNearestInTime, SurfaceSpeedSource::kProfile, 0);
    EXPECT_EQ(near.SelectCast(2600, 0, 0), 0);
    EXPECT_EQ(near.SelectCast(1400, 0, 0), 1);
    const Refraction dist(
        casts, CastSelection::kNearestInDistance, SurfaceSpeedSource::kProfile, 0);
    EXPECT_EQ(dist.SelectCast(0, 40.0009, -7.0), 1);
    EXPECT_EQ(dist.SelectCast(0, 40.0, -7.0019), 2);
    EXPECT_EQ(dist.SelectCast(0, 40.0, -6.9999), 0);
    // Checks: a cast without position for distance selection, no water line height.
    auto nopos = casts;
    nopos[1].latitude_deg = NAN;
    EXPECT_EQ(Refraction::Check(nopos, CastSelection::kNearestInDistance, 0).size(), 1u);
    EXPECT_EQ(Refraction::Check(casts, CastSelection::kNearestPreceding, NAN).size(), 1u);
    EXPECT_EQ(Refraction::Check({}, CastSelection::kNearestPreceding, 0).size(), 1u);
}

}  // namespace
