// SPDX-License-Identifier: MIT
// The beam-width rasteriser (tsdf.cpp: per-ping columns, leaf cache, slabs and bands) against a
// straightforward evaluation of the same model: every voxel of a box, for every scan in order,
// is back-projected into the sonar frame, given the sector of its in-plane angle (atan2), tested
// against the beam's width and the truncation band, and updated with the running average
// (Eq. 4-6). The footprint ranges come from the same PrepareScan (footprint.cpp); what is
// checked here is which voxels a ping updates and with which distance and weight.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "processor/fusion/detail/prepared_scan.hpp"
#include "processor/fusion/tsdf.hpp"
#include "tests/processor/fusion/synthetic_scans.hpp"

namespace pitmap::proc::fusion {
namespace {

using testing::LineSurvey;
using testing::MakeScans;
using testing::Sphere;
using testing::SyntheticWorld;
using testing::Tilt;

struct RefVoxel {
    float distance_m = 0;
    float weight = 0;
};
using Key = std::tuple<int, int, int>;

// The rasteriser's geometry for a configuration (as TsdfVolume::Integrate builds it).
detail::Geometry GeometryOf(const TsdfConfig& c) {
    const double s = c.voxel_size_m;
    return {
        c.truncation_m / s, std::tan(0.5 * c.beam_width_rad), std::cos(0.5 * c.beam_width_rad), s};
}

// The model as stated in tsdf.hpp, voxel by voxel.
std::map<Key, RefVoxel> ReferenceIntegrate(const std::vector<SonarScan>& scans,
                                           const TsdfConfig& c) {
    const double s = c.voxel_size_m;
    const detail::Geometry geo = GeometryOf(c);
    const double T = geo.trunc_vox;
    std::map<Key, RefVoxel> grid;
    for (std::size_t si = 0; si < scans.size(); ++si) {
        const SonarScan& scan = scans[si];
        const detail::PreparedScan ps = detail::PrepareScan(scans, si, c, geo);
        if (ps.beams.empty()) continue;
        std::vector<const detail::PreparedBeam*> by_index(scan.ranges_m.size(), nullptr);
        double r_max = 0;
        for (const detail::PreparedBeam& pb : ps.beams) {
            by_index[pb.beam] = &pb;
            for (double rr : {pb.range_vox, pb.range_prev_vox, pb.range_next_vox}) {
                if (std::isfinite(rr)) r_max = std::max(r_max, rr + detail::AlongTrackReach(pb));
            }
        }
        const double reach = r_max + T + 1.0;
        const Eigen::Vector3d& p = ps.p_vox;
        const Eigen::Vector3d n = ps.R.col(0);
        const double h_cube = 0.5 * (std::abs(n.x()) + std::abs(n.y()) + std::abs(n.z()));
        const double inc = scan.angle_increment_rad;
        for (int x = static_cast<int>(std::floor(p.x() - reach));
             x <= static_cast<int>(std::ceil(p.x() + reach));
             ++x) {
            for (int y = static_cast<int>(std::floor(p.y() - reach));
                 y <= static_cast<int>(std::ceil(p.y() + reach));
                 ++y) {
                for (int z = static_cast<int>(std::floor(p.z() - reach));
                     z <= static_cast<int>(std::ceil(p.z() + reach));
                     ++z) {
                    const Eigen::Vector3d xs = ps.R.transpose() * (Eigen::Vector3d(x, y, z) - p);
                    const double rho = std::hypot(xs.y(), xs.z());
                    // Sector [theta_i - inc/2, theta_i + inc/2) of the in-plane angle.
                    const double phi = std::atan2(xs.y(), xs.z());
                    const double k = std::floor((phi - scan.start_angle_rad) / inc + 0.5);
                    if (k < 0 || k >= static_cast<double>(by_index.size())) continue;
                    const detail::PreparedBeam* pb = by_index[static_cast<std::size_t>(k)];
                    if (pb == nullptr) continue;
                    // Out of the plane: within the cone, half a voxel's extent or half the gap
                    // to the neighbouring pings' fans.
                    const double h_out = std::max(h_cube, static_cast<double>(pb->half_gap_vox));
                    if (std::abs(xs.x()) > std::max(geo.tan_half_bw * rho, h_out)) continue;
                    const double theta = static_cast<double>(
                        scan.start_angle_rad + static_cast<float>(k) * scan.angle_increment_rad);
                    const double frac = (phi - theta) / inc;  // > 0 towards beam k + 1
                    const double rn = frac >= 0 ? pb->range_next_vox : pb->range_prev_vox;
                    // Along the track: the footprint's slope over its fitted span, held beyond.
                    const double r_at =
                        pb->range_vox +
                        (std::isfinite(rn) ? std::abs(frac) * (rn - pb->range_vox) : 0.0) +
                        pb->dr_dx * std::clamp(xs.x(),
                                               static_cast<double>(pb->x_fit_lo),
                                               static_cast<double>(pb->x_fit_hi));
                    const double d = r_at - xs.norm();
                    if (!(d > -T && d <= T)) continue;
                    RefVoxel& v = grid[{x, y, z}];
                    const float f = pb->weight;
                    const float dm = static_cast<float>(std::min(d, T) * s);
                    v.distance_m = (v.weight * v.distance_m + f * dm) / (v.weight + f);
                    v.weight = std::min(v.weight + f, c.max_weight);
                }
            }
        }
    }
    return grid;
}

// Voxel-by-voxel comparison of the volume with the reference: the same voxels (every reference
// voxel observed, no others), distances and weights within 1e-5 (the rasteriser takes the
// in-plane angle as tan(angle), |angle| <= inc / 2, relative error < 2e-6, and accumulates in
// float like the reference: 1e-5 m on 0.4 m). Returns the reference.
std::map<Key, RefVoxel> ExpectMatchesReference(const std::vector<SonarScan>& scans,
                                               const TsdfConfig& c,
                                               const std::string& what) {
    TsdfVolume volume(c);
    const IntegrateResult ir = volume.Integrate(scans);
    std::map<Key, RefVoxel> ref = ReferenceIntegrate(scans, c);
    EXPECT_EQ(ir.active_voxels, static_cast<std::int64_t>(ref.size())) << what;
    std::size_t missing = 0;
    double worst_d = 0, worst_w = 0;
    for (const auto& [key, rv] : ref) {
        const auto [x, y, z] = key;
        const Eigen::Vector3d p_world = Eigen::Vector3d(x, y, z) * c.voxel_size_m;
        const float w = volume.WeightAt(p_world);
        if (w == 0.0f) {
            ++missing;
            continue;
        }
        worst_w = std::max(worst_w, static_cast<double>(std::abs(w - rv.weight)));
        worst_d = std::max(
            worst_d, static_cast<double>(std::abs(volume.DistanceAt(p_world) - rv.distance_m)));
    }
    EXPECT_EQ(missing, 0u) << what;
    EXPECT_LT(worst_d, 1e-5) << what;
    EXPECT_LT(worst_w, 1e-5) << what;
    return ref;
}

// A tilted sonar (yaw, roll and pitch, so no voxel sits exactly on a sector or cone boundary)
// over a floor with a boulder: range jumps, one-sided footprints at the swath edge, and noise
// with a few coarse outliers for the footprint to outvote. Pings 0.07 m apart are closer than the
// beam is wide at the floor (13 cm); 0.2 m apart the beams are widened towards the neighbouring
// pings (ping_gap_fill_m).
std::vector<SonarScan> Scene(double ping_spacing_m) {
    SyntheticWorld world;
    world.plane_z_m = -5.0;
    world.spheres.push_back({Eigen::Vector3d(0.3, -0.8, -4.6), 0.7});
    LineSurvey survey;
    survey.x0_m = -0.6;
    survey.x1_m = 0.6;
    survey.spacing_m = ping_spacing_m;
    survey.lines_y_m = {0.0};
    survey.num_beams = 161;
    survey.start_angle_rad = -20.0 * std::numbers::pi / 180.0;
    survey.noise_sigma_m = 0.02;
    std::vector<SonarScan> scans = MakeScans(world, survey);
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.31, Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(0.04, Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitY()))
                                     .toRotationMatrix();
    Tilt(scans, world, survey.increment_rad, tilt);
    for (std::size_t i = 0; i < scans.size(); ++i) {
        SonarScan& scan = scans[i];
        if (i % 3 == 1) scan.ranges_m[40 + i] *= 0.7f;  // a coarse outlier
        if (i % 4 == 2) scan.ranges_m[90] = 0.0f;       // a dropout
    }
    return scans;
}

TEST(BeamWidthRasteriser, MatchesVoxelByVoxelReference) {
    TsdfConfig c;
    c.truncation_m = 0.4;
    c.sensor_model = SensorModel::kBeamWidth;
    for (auto [spacing_m, threads] : {std::pair{0.07, 1}, std::pair{0.07, 2}, std::pair{0.2, 1}}) {
        c.num_threads = threads;
        const std::vector<SonarScan> scans = Scene(spacing_m);
        const std::size_t n =
            ExpectMatchesReference(scans, c, std::to_string(threads) + " threads").size();
        ASSERT_GT(n, 1500u);
        // The scene's footprints slope along the track (the tilt, the boulder): the model's
        // along-track term is exercised.
        std::size_t sloped = 0, beams = 0;
        for (std::size_t si = 0; si < scans.size(); ++si) {
            for (const detail::PreparedBeam& pb :
                 detail::PrepareScan(scans, si, c, GeometryOf(c)).beams) {
                sloped += pb.dr_dx != 0.0f ? 1 : 0;
                ++beams;
            }
        }
        EXPECT_GT(sloped, beams / 3);
    }
}

// The footprint's along-track slope (PreparedBeam::dr_dx) against the plane it sees: a head
// pitched and turned over a level floor, the range's derivative out of the fan plane cast from
// the ping's own pose. Noise-free ranges, so the fit to the neighbouring pings' footprints
// must find the plane's slope; without neighbours there is none.
TEST(BeamWidthFootprint, AlongTrackSlopeIsThePlanesSlope) {
    SyntheticWorld world;
    world.plane_z_m = -5.0;
    LineSurvey survey;
    survey.x0_m = -0.3;
    survey.x1_m = 0.3;
    survey.spacing_m = 0.1;
    survey.num_beams = 161;
    survey.start_angle_rad = -20.0 * std::numbers::pi / 180.0;
    std::vector<SonarScan> scans = MakeScans(world, survey);
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    Tilt(scans, world, survey.increment_rad, tilt);
    TsdfConfig c;
    const detail::Geometry geo = GeometryOf(c);
    const std::size_t mid = scans.size() / 2;
    const detail::PreparedScan ps = detail::PrepareScan(scans, mid, c, geo);
    ASSERT_EQ(ps.beams.size(), 161u);
    const SonarScan& scan = scans[mid];
    std::size_t fitted = 0;
    double worst = 0;
    for (const detail::PreparedBeam& pb : ps.beams) {
        const double th = scan.start_angle_rad + pb.beam * scan.angle_increment_rad;
        // Range and out-of-plane offset along the beam turned by +-phi out of the plane.
        auto cast = [&](double phi) {
            const Eigen::Vector3d u(
                std::sin(phi) * std::cos(th), std::sin(th), std::cos(phi) * std::cos(th));
            const double r =
                world.Cast(scan.T_world_sonar.translation(), scan.T_world_sonar.linear() * u);
            return std::pair{r, r * u.x()};
        };
        const auto [r_plus, x_plus] = cast(1e-4);
        const auto [r_minus, x_minus] = cast(-1e-4);
        const double expected = (r_plus - r_minus) / (x_plus - x_minus);
        ASSERT_GT(std::abs(expected), 0.3);  // the pitch: ~tan(0.4) along the track
        if (pb.dr_dx == 0.0f) continue;
        ++fitted;
        worst = std::max(worst, std::abs(pb.dr_dx - expected) / std::abs(expected));
        // Fitted over the neighbours on both sides, two pings (~2 voxels) each way.
        EXPECT_LT(pb.x_fit_lo, -1.0f);
        EXPECT_GT(pb.x_fit_hi, 1.0f);
        EXPECT_LT(pb.x_fit_hi - pb.x_fit_lo, 6.0f);
    }
    EXPECT_EQ(fitted, ps.beams.size());
    EXPECT_LT(worst, 0.01);
    c.footprint_neighbour_pings = 0;
    for (const detail::PreparedBeam& pb : detail::PrepareScan(scans, mid, c, geo).beams) {
        EXPECT_EQ(pb.dr_dx, 0.0f);
    }
    // A scan on its own has no neighbours to fit to.
    for (const detail::PreparedBeam& pb : detail::PrepareScan(scan, c, geo).beams) {
        EXPECT_EQ(pb.dr_dx, 0.0f);
    }
}

// A fan wider than a half turn (161 beams 1.25 deg apart, 200 deg), its outer beams looking up
// at boulders beside the head: a voxel's sector then comes from its angle, since the boundary
// tests of such a fan are not monotone from one sector to the next. Ranges beyond 4 m are out
// of range so the reference's box stays small.
std::vector<SonarScan> WideFanScene() {
    SyntheticWorld world;
    world.plane_z_m = -2.5;
    world.spheres.push_back({Eigen::Vector3d(0.1, -1.9, 0.3), 0.8});
    world.spheres.push_back({Eigen::Vector3d(-0.2, 2.0, 0.4), 0.8});
    LineSurvey survey;
    survey.x0_m = -0.5;
    survey.x1_m = 0.5;
    survey.spacing_m = 0.07;
    survey.lines_y_m = {0.0};
    survey.num_beams = 161;
    survey.start_angle_rad = -100.0 * std::numbers::pi / 180.0;
    survey.increment_rad = 1.25 * std::numbers::pi / 180.0;
    std::vector<SonarScan> scans = MakeScans(world, survey);
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.23, Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(-0.05, Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()))
                                     .toRotationMatrix();
    Tilt(scans, world, survey.increment_rad, tilt);
    return scans;
}

// A head pitched most of the way up (a forward-looking mount: the fan nearly horizontal), so the
// rasteriser's columns run along a horizontal world axis and leave the fan plane as they go,
// over boulders in front of it and the floor.
std::vector<SonarScan> ForwardLookingScene(double yaw_rad) {
    SyntheticWorld world;
    world.plane_z_m = -0.9;
    // Before the yaw the head looks towards -x; the boulders turn with it.
    const Eigen::AngleAxisd turn(yaw_rad, Eigen::Vector3d::UnitZ());
    world.spheres.push_back({turn * Eigen::Vector3d(-2.2, 0.4, -0.5), 0.8});
    world.spheres.push_back({turn * Eigen::Vector3d(-1.5, -1.8, -0.4), 0.6});
    world.spheres.push_back({turn * Eigen::Vector3d(-1.6, 1.7, -0.7), 0.7});
    LineSurvey survey;
    survey.x0_m = -0.4;
    survey.x1_m = 0.4;
    survey.spacing_m = 0.1;
    survey.lines_y_m = {0.0};
    survey.num_beams = 241;
    survey.start_angle_rad = -60.0 * std::numbers::pi / 180.0;
    survey.increment_rad = 0.5 * std::numbers::pi / 180.0;
    std::vector<SonarScan> scans = MakeScans(world, survey);
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(1.25, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(0.07, Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    Tilt(scans, world, survey.increment_rad, tilt);
    return scans;
}

TEST(BeamWidthRasteriser, ForwardLookingHeadMatchesTheReference) {
    TsdfConfig c;
    c.truncation_m = 0.4;
    c.max_range_m = 3.5;
    c.sensor_model = SensorModel::kBeamWidth;
    // The fan normal is mostly vertical: columns along y (yaw 0.2) and along x (yaw 1.3).
    const detail::Geometry geo = GeometryOf(c);
    for (auto [yaw, axis] : {std::pair{0.2, 1}, std::pair{1.3, 0}}) {
        const std::vector<SonarScan> scans = ForwardLookingScene(yaw);
        EXPECT_EQ(detail::PrepareScan(scans[0], c, geo).fan.axis, axis) << yaw;
        const std::size_t n = ExpectMatchesReference(scans, c, "yaw " + std::to_string(yaw)).size();
        EXPECT_GT(n, 500u) << yaw;
    }
}

// Single pings in random orientations (any world axis can be the column axis, columns cross
// the fan plane at any angle), with increments of either sign, wavy ranges with range jumps and
// dropouts: every voxel the model updates must lie inside the column bounds.
TEST(BeamWidthRasteriser, PingsInRandomOrientationsMatchTheReference) {
    TsdfConfig c;
    c.truncation_m = 0.3;
    c.sensor_model = SensorModel::kBeamWidth;
    std::mt19937 rng(20261129);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int axis_seen[3] = {0, 0, 0};
    for (int trial = 0; trial < 40; ++trial) {
        SonarScan scan;
        const Eigen::Quaterniond q =
            Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
        scan.T_world_sonar.linear() = q.toRotationMatrix();
        scan.T_world_sonar.translation() = Eigen::Vector3d(3.0 * u(rng), 3.0 * u(rng), u(rng));
        const int n = 96;
        const double inc =
            (trial % 2 == 0 ? 1.0 : -1.0) * (0.4 + 0.3 * (u(rng) + 1.0)) * std::numbers::pi / 180.0;
        scan.angle_increment_rad = static_cast<float>(inc);
        scan.start_angle_rad = static_cast<float>(-0.5 * (n - 1) * inc + 0.2 * u(rng));
        const double a = 1.2 + 0.4 * u(rng), b = 0.3 * u(rng), ph = 3.0 * u(rng);
        scan.ranges_m.resize(n);
        for (int i = 0; i < n; ++i) {
            double r = a + b * std::sin(0.15 * i + ph);
            if (i > 60 && i < 70) r += 0.5;      // a range jump (a ledge)
            if ((i + trial) % 17 == 0) r = 0.0;  // a dropout
            scan.ranges_m[static_cast<std::size_t>(i)] = static_cast<float>(r);
        }
        ++axis_seen[detail::PrepareScan(scan, c, GeometryOf(c)).fan.axis];
        const std::size_t voxels =
            ExpectMatchesReference({scan}, c, "trial " + std::to_string(trial)).size();
        EXPECT_GT(voxels, 50u) << trial;
    }
    for (int k = 0; k < 3; ++k) EXPECT_GT(axis_seen[k], 0) << "axis " << k;
}

TEST(BeamWidthRasteriser, FanWiderThanAHalfTurnMatchesTheReference) {
    TsdfConfig c;
    c.truncation_m = 0.3;
    c.max_range_m = 4.0;
    c.sensor_model = SensorModel::kBeamWidth;
    const std::map<Key, RefVoxel> ref = ExpectMatchesReference(WideFanScene(), c, "wide fan");
    ASSERT_GT(ref.size(), 1000u);
    // Beams beyond +-90 deg (upwards) reach the boulders beside the head.
    std::size_t above_head = 0;
    for (const auto& [key, rv] : ref) {
        if (std::get<2>(key) >= 0) ++above_head;
    }
    EXPECT_GT(above_head, 100u);
}

}  // namespace
}  // namespace pitmap::proc::fusion
