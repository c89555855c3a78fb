// SPDX-License-Identifier: MIT
// Synthetic multibeam scans of analytic shapes for the fusion and mesh tests: a sonar flying
// straight lines at the water surface, ray casting a horizontal plane and optional spheres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion::testing {

struct Sphere {
    Eigen::Vector3d centre;
    double radius_m;
};

struct SyntheticWorld {
    double plane_z_m = -10.0;  // horizontal floor (NaN = none)
    std::vector<Sphere> spheres;

    // Range along the unit ray from o, or NaN when nothing is hit within max_m.
    double Cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_m = 100.0) const {
        double best = std::numeric_limits<double>::infinity();
        if (std::isfinite(plane_z_m) && d.z() < -1e-9) {
            const double t = (plane_z_m - o.z()) / d.z();
            if (t > 0) best = t;
        }
        for (const Sphere& s : spheres) {
            const Eigen::Vector3d oc = o - s.centre;
            const double b = oc.dot(d);
            const double c = oc.squaredNorm() - s.radius_m * s.radius_m;
            const double disc = b * b - c;
            if (disc < 0) continue;
            const double t = -b - std::sqrt(disc);
            if (t > 0 && t < best) best = t;
        }
        return best <= max_m ? best : std::numeric_limits<double>::quiet_NaN();
    }
};

// Sonar at the surface heading east (x): forward = +x, starboard = -y, down = -z.
inline Eigen::Isometry3d SonarPose(const Eigen::Vector3d& position, double yaw_rad = 0.0) {
    Eigen::Matrix3d R;
    R.col(0) = Eigen::Vector3d(std::cos(yaw_rad), std::sin(yaw_rad), 0.0);
    R.col(1) = Eigen::Vector3d(std::sin(yaw_rad), -std::cos(yaw_rad), 0.0);
    R.col(2) = Eigen::Vector3d(0.0, 0.0, -1.0);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = position;
    return T;
}

struct LineSurvey {
    double x0_m = -5.0;       // start of each line (east)
    double x1_m = 5.0;        // end
    double spacing_m = 0.05;  // between pings
    std::vector<double> lines_y_m = {0.0};
    int num_beams = 361;
    double start_angle_rad = -45.0 * std::numbers::pi / 180.0;
    double increment_rad = 0.25 * std::numbers::pi / 180.0;
    double noise_sigma_m = 0.0;
    unsigned seed = 7;
};

inline std::vector<SonarScan> MakeScans(const SyntheticWorld& world, const LineSurvey& s) {
    std::vector<SonarScan> scans;
    std::mt19937 rng(s.seed);
    std::normal_distribution<double> noise(0.0, s.noise_sigma_m > 0 ? s.noise_sigma_m : 1.0);
    const int n = static_cast<int>(std::floor((s.x1_m - s.x0_m) / s.spacing_m + 1e-9)) + 1;
    for (double y : s.lines_y_m) {
        for (int k = 0; k < n; ++k) {
            SonarScan scan;
            scan.gps_time_s = static_cast<double>(scans.size()) * 0.1;
            scan.T_world_sonar = SonarPose(Eigen::Vector3d(s.x0_m + k * s.spacing_m, y, 0.0));
            scan.start_angle_rad = static_cast<float>(s.start_angle_rad);
            scan.angle_increment_rad = static_cast<float>(s.increment_rad);
            scan.ranges_m.resize(static_cast<std::size_t>(s.num_beams));
            for (int i = 0; i < s.num_beams; ++i) {
                const double th = s.start_angle_rad + i * s.increment_rad;
                const Eigen::Vector3d d =
                    scan.T_world_sonar.linear() * Eigen::Vector3d(0.0, std::sin(th), std::cos(th));
                double r = world.Cast(scan.T_world_sonar.translation(), d);
                if (std::isfinite(r) && s.noise_sigma_m > 0) r += noise(rng);
                scan.ranges_m[static_cast<std::size_t>(i)] =
                    std::isfinite(r) ? static_cast<float>(r) : 0.0f;
            }
            scans.push_back(std::move(scan));
        }
    }
    return scans;
}

// Turns every scan's head by tilt (world frame) and casts its beams again from the new pose, so
// the ranges stay consistent with the geometry.
inline void Tilt(std::vector<SonarScan>& scans,
                 const SyntheticWorld& world,
                 double increment_rad,
                 const Eigen::Matrix3d& tilt) {
    for (SonarScan& scan : scans) {
        scan.T_world_sonar.linear() = tilt * scan.T_world_sonar.linear();
        for (std::size_t b = 0; b < scan.ranges_m.size(); ++b) {
            const double th = scan.start_angle_rad + static_cast<double>(b) * increment_rad;
            const Eigen::Vector3d dir =
                scan.T_world_sonar.linear() * Eigen::Vector3d(0.0, std::sin(th), std::cos(th));
            const double r = world.Cast(scan.T_world_sonar.translation(), dir);
            scan.ranges_m[b] = std::isfinite(r) ? static_cast<float>(r) : 0.0f;
        }
    }
}

}  // namespace pitmap::proc::fusion::testing
