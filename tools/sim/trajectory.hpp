// SPDX-License-Identifier: MIT
// The vehicle's true motion: a planned track (concentric laps and tie lines, or star or zigzag
// lines: TrackPattern in scenario.hpp), driven at a
// constant speed, with wave-induced roll, pitch, heave and yaw oscillation. Times are seconds
// since the survey start (t = 0 at the first sample); GPS time = start_gps + t.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "common/result.hpp"
#include "common/se3.hpp"
#include "tools/sim/scenario.hpp"

namespace pitmap::sim {

// A 2-D path in the world frame, resampled uniformly by arc length.
class SurveyTrack {
public:
    // Plans the track; fails if the laps do not fit the pit.
    static Expected<SurveyTrack> Plan(const ScenarioConfig& scenario);

    double length_m() const { return spacing_m_ * static_cast<double>(points_.size() - 1); }
    const std::vector<Eigen::Vector2d>& points() const { return points_; }
    // Position and heading (radians, clockwise from north = y axis) at arc length s (clamped).
    Eigen::Vector2d PositionAt(double s) const;
    double HeadingAt(double s) const;

private:
    double spacing_m_ = 0.1;
    std::vector<Eigen::Vector2d> points_;
};

// One instant of the true vehicle state.
struct TruthState {
    double t_s = 0;                        // seconds since the survey start
    Pose T_world_vehicle;                  // vehicle (FRD) -> world (ENU)
    Eigen::Vector3d velocity_world;        // m/s
    Eigen::Vector3d angular_rate_vehicle;  // rad/s, body rates in the vehicle frame
    Eigen::Vector3d acceleration_world;    // m/s^2, kinematic (gravity not included)
};

// Thread safety: const methods may be called concurrently.
class TruthTrajectory {
public:
    TruthTrajectory(const ScenarioConfig& scenario, SurveyTrack track);

    double duration_s() const { return duration_s_; }
    const SurveyTrack& track() const { return track_; }
    // The pose alone (cheap): position on the track, heave, roll/pitch/yaw with waves.
    Pose PoseAt(double t_s) const;
    // Pose plus rates by central differences (h = 1 ms).
    TruthState StateAt(double t_s) const;

private:
    TrackConfig cfg_;
    SurveyTrack track_;
    double duration_s_;
    double phase_[6];  // wave phases from the seed
};

}  // namespace pitmap::sim
