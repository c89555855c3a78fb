// SPDX-License-Identifier: MIT
// The synthetic seabed's backscatter strength BS(x, y), dB (scenario.hpp BackscatterConfig):
// square patches of materials drawn from the seed, boulders harder. Deterministic in
// (config, seed, boulders).
// Thread safety: const methods may be called concurrently.
#pragma once

#include <cstdint>
#include <vector>

#include "tools/sim/scenario.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

class SeabedBackscatter {
public:
    SeabedBackscatter(const BackscatterConfig& config,
                      std::uint64_t seed,
                      std::vector<Boulder> boulders = {});
    // BS at world (x, y), dB.
    double At(double x, double y) const;
    // The patch level index at (x, y) (which of patch_levels_db), ignoring boulders.
    int PatchIndex(double x, double y) const;
    // BS sampled at the nodes of a terrain grid (row-major iy * nx + ix).
    std::vector<float> Sample(const TerrainGrid& g) const;
    // The angular response AR(theta), dB (theta in degrees, 0 = normal incidence).
    double AngularResponseDb(double incidence_deg) const;
    // The echo level without speckle, dB re one intensity count.
    double LevelDb(double range_m, double incidence_deg, double bs_db) const;
    const BackscatterConfig& config() const { return cfg_; }

private:
    BackscatterConfig cfg_;
    std::uint64_t seed_;
    std::vector<Boulder> boulders_;
};

}  // namespace pitmap::sim
