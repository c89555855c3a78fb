// SPDX-License-Identifier: MIT
// The simulated water column: sound speed by depth (WaterColumnConfig) and curved rays through
// it. A flooded pit in summer: a warm mixed layer, a thermocline where the speed falls along a
// half cosine, and cold water below whose speed grows slowly with pressure.
//
// Rays are integrated numerically, independently of the processor's closed-form layer tracer
// (processor/svp/ray_trace.hpp): for a grid of Snell parameters p = sin(phi) / c (phi from the
// downward vertical) the horizontal distance x(z) = int tan(phi) dz and the travel time
// t(z) = int dz / (c cos(phi)) from the surface are tabulated every kNodeM of depth by the
// midpoint rule with 5 mm steps (nodes at the thermocline's ends). A ray from depth z0 is the
// part of its p's table below z0, interpolated linearly in p; its path is cast against the
// terrain as straight chords between the depth nodes (sagitta < 1 mm). Rays leaving the head
// upwards or horizontally stay in the mixed layer (constant speed) and are straight.
//
// Thread safety: immutable after construction; Cast may be called concurrently.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "tools/sim/scenario.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

struct CurvedHit {
    double one_way_time_s = 0;
    Eigen::Vector3d point = Eigen::Vector3d::Zero();  // world
};

class WaterColumn {
public:
    // Tabulates rays down to max_depth_m (the deepest terrain plus a margin).
    WaterColumn(const WaterColumnConfig& config, double max_depth_m);
    double SpeedAt(double depth_m) const { return config_.SpeedAt(depth_m); }
    // First terrain hit of the ray leaving `origin` (world, z up, water surface z = 0) along
    // the unit vector `dir`, within a one-way travel time `max_time_s`; nullopt if none.
    std::optional<CurvedHit> Cast(const PitWorld& world,
                                  const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& dir,
                                  double max_time_s) const;
    // The true profile sampled every `spacing_m` from 0 to `max_depth_m` (depth, speed).
    std::vector<std::pair<double, double>> Sampled(double spacing_m, double max_depth_m) const;

private:
    static constexpr double kNodeM = 0.25;
    static constexpr int kNumP = 2048;
    // x and t at depth node k for parameter index i: [i * nodes + k]; NaN past a turning point.
    double At(const std::vector<double>& table, double p, double z) const;
    WaterColumnConfig config_;
    double max_depth_m_ = 0;
    double dp_ = 0;  // p step
    int nodes_ = 0;
    std::vector<double> x_, t_;
};

}  // namespace pitmap::sim
