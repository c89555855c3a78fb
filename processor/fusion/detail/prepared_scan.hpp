// SPDX-License-Identifier: MIT
// Internal to processor/fusion: a scan prepared for the voxel rasteriser. The sensor model's
// footprint (footprint.cpp, no OpenVDB) turns a ping's ranges into beams with footprint ranges,
// weights and the x range of voxels they can touch; the rasteriser (tsdf.cpp) walks voxels.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <vector>

#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion::detail {

// A beam (beam-width mode: a sector) of a scan, prepared once for all slabs. Ranges are in
// voxel units.
struct PreparedBeam {
    float range_vox;       // ray mode: the measured range; beam-width mode: the footprint range
    float range_prev_vox;  // beam-width mode: footprint range of beam - 1 (NaN = none)
    float range_next_vox;  // beam-width mode: footprint range of beam + 1 (NaN = none)
    float weight;          // f of one update (beam-width mode: f times the footprint support)
    float half_gap_vox;    // beam-width mode: half the gap to the neighbouring pings' fans at
                           // the footprint (TsdfConfig::ping_gap_fill_m), 0 = none
    std::int32_t x_lo;     // voxel x index range the beam can touch
    std::int32_t x_hi;
    std::int32_t y_lo;  // voxel y index range the beam can touch
    std::int32_t y_hi;
    std::uint16_t beam;  // beam index
};

struct PreparedScan {
    Eigen::Matrix3d R;      // R_world_sonar
    Eigen::Vector3d p_vox;  // sonar position in voxel index units
    std::vector<PreparedBeam> beams;
    std::int32_t x_lo = std::numeric_limits<std::int32_t>::max();
    std::int32_t x_hi = std::numeric_limits<std::int32_t>::min();
    std::int32_t y_lo = std::numeric_limits<std::int32_t>::max();
    std::int32_t y_hi = std::numeric_limits<std::int32_t>::min();
    // Counters of this scan (summed into IntegrateResult).
    std::int64_t beams_used = 0;
    std::int64_t beams_no_detection = 0;
    std::int64_t beams_out_of_range = 0;
    std::int64_t beams_inconsistent = 0;
    bool out_of_bounds = false;  // pose non-finite or beyond kMaxSonarOffsetM: no beams
};

// Geometry shared by both sensor models, in voxel index units (voxel centres at integers).
struct Geometry {
    double trunc_vox;
    double tan_half_bw;
    double cos_half_bw;
    double metres_per_voxel;
};

// The beams of one scan in voxel units; beam-width mode fits each beam's footprint (a robust
// line through the ranges of the beams inside its cone) first, and measures the gap from each
// footprint to the fan planes of the previous and next scans (nullptr = none).
PreparedScan PrepareScan(const SonarScan& scan,
                         const TsdfConfig& config,
                         const Geometry& geo,
                         const SonarScan* prev = nullptr,
                         const SonarScan* next = nullptr);

}  // namespace pitmap::proc::fusion::detail
