// SPDX-License-Identifier: MIT
// Ground truth written beside the simulated sensor data, and read back by the scorer.
//
// <dir>/scenario.json     the ScenarioConfig (every parameter, seed included)
// <dir>/terrain.json      grid header: x0_m, y0_m, resolution_m, nx, ny, origin (lat, lon, h)
// <dir>/terrain.f32       heights, float32 little-endian, row-major (iy * nx + ix), metres, z up
// <dir>/trajectory.csv    true vehicle pose at a fixed rate: gps_time_s (GPS seconds since
//                         1980-01-06), x_m, y_m, z_m (world ENU), roll_deg, pitch_deg, yaw_deg
// <dir>/boresight.json    true R_vehicle_sonar as roll/pitch/yaw degrees, lever arms
// <dir>/coverage.u8       optional: 1 byte per terrain cell (same grid), 1 where a true beam
//                         hit that cell (the insonified area), else 0
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "common/se3.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

struct TruthPose {
    double gps_time_s = 0;  // GPS seconds since 1980-01-06
    Pose T_world_vehicle;
};

struct TruthBoresight {
    double roll_deg = 0, pitch_deg = 0, yaw_deg = 0;  // R_vehicle_sonar error about the nominal
    std::vector<double> lever_arm_sonar_m;            // vehicle frame
};

struct Truth {
    Geodetic origin;  // world frame origin
    TerrainGrid terrain;
    std::vector<TruthPose> trajectory;
    TruthBoresight boresight;
    std::vector<std::uint8_t> coverage;  // empty, or one byte per terrain cell (insonified = 1)
};

Status WriteScenarioJson(const std::string& path, const ScenarioConfig& sc);
Status WriteTruth(const std::string& dir, const ScenarioConfig& sc, const Truth& truth);
// Reads what WriteTruth wrote; every missing or malformed file is an error naming it.
Expected<Truth> ReadTruth(const std::string& dir);

// Interpolated true pose at a GPS time (linear position, slerp attitude); fails outside the
// trajectory's time span.
Expected<Pose> InterpolateTruth(const std::vector<TruthPose>& trajectory, double gps_time_s);

}  // namespace pitmap::sim
