// SPDX-License-Identifier: MIT
// The Delta T as the simulator sees it: ray casting each beam over its footprint (sub-rays
// spread over the beam width, detection at their median range), then range noise, dropouts, coarse
// outliers and quantisation to the 83P range resolution; intensities from the seabed's
// backscatter, two-way spreading and absorption and an angular response (BackscatterConfig).
// Per-ping random streams depend only on (seed, ping number), so the result is the same for any
// thread count and any order of calls.
#pragma once

#include <cstdint>
#include <vector>

#include "common/se3.hpp"
#include "tools/sim/backscatter.hpp"
#include "tools/sim/echo_artifacts.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/water_column.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

enum class BeamOutcome : std::uint8_t { kValid, kNoHit, kDropout, kOutlier };

struct SimPing {
    std::int64_t ping_number = 0;
    std::vector<std::uint16_t> range_counts;  // 83P counts of range_resolution; 0 = no detection
    std::vector<std::uint16_t> intensities;   // echo amplitude (BackscatterConfig's model)
    std::vector<float> true_range_m;          // noise-free footprint range; NaN = no hit
    std::vector<BeamOutcome> outcome;         // what the model did to each beam
    std::vector<Eigen::Vector3d> true_hit_world;  // where the beam axis's detection lies
    double sound_speed_mps = 0;                   // the speed the sonar assumed (83P header)
    // What EchoArtifactModel made of each beam (empty if it was not applied).
    std::vector<EchoArtifactKind> artifact;
};

// Thread safety: const methods may be called concurrently.
class SonarModel {
public:
    // `water`: with a WaterColumn the beams are ray traced through it, the ranges are the
    // assumed speed (the speed at the transducer) times the one-way travel time, and that speed
    // is the ping's sound_speed_mps; without, rays are straight at config.sound_speed_mps.
    // `backscatter`: the seabed and the echo amplitude model of the intensities
    // (scenario.hpp BackscatterConfig; boulders from `world`).
    SonarModel(const SonarConfig& config,
               const PitWorld& world,
               std::uint64_t seed,
               const WaterColumn* water = nullptr,
               const BackscatterConfig& backscatter = {});
    // Simulates one ping from the sonar head pose (sonar frame: x fwd, y stbd, z down).
    SimPing Ping(const Pose& T_world_sonar, std::int64_t ping_number) const;
    // Beam i's angle from nadir, degrees, positive to starboard (integer 0.01 deg arithmetic,
    // as the 83P header encodes it).
    double BeamAngleDeg(int i) const;
    double RangeSigma(double range_m) const;

private:
    SonarConfig cfg_;
    const PitWorld& world_;
    std::uint64_t seed_;
    const WaterColumn* water_;
    SeabedBackscatter seabed_;
};

}  // namespace pitmap::sim
