// SPDX-License-Identifier: MIT
// Internal to processor/fusion: a scan prepared for the voxel rasteriser. The sensor model's
// footprint (footprint.cpp, no OpenVDB) turns a ping's ranges into beams with footprint ranges,
// weights and the x range of voxels they can touch; the rasteriser (tsdf.cpp) walks voxels.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion::detail {

// Geometry shared by both sensor models, in voxel index units (voxel centres at integers).
struct Geometry {
    double trunc_vox;
    double tan_half_bw;
    double cos_half_bw;
    double metres_per_voxel;
};

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
    float dr_dx = 0;     // beam-width mode: range change per voxel out of the fan plane (the
                         // footprint's along-track slope, from the neighbouring pings)
    float x_fit_lo = 0;  // the out-of-plane offsets it was fitted over (voxels): beyond, the
    float x_fit_hi = 0;  // range is held at the span's end, not extrapolated
};

// Beam-width mode: what the per-voxel test needs of one sector (beam index k of the scan),
// in voxel units. weight 0 = no footprint range (the sector is not integrated).
struct FanSector {
    double cos_theta = 0, sin_theta = 0;  // beam axis theta_k (as float start + k * increment)
    double far2 = 0;    // (r_max + T)^2: beyond, d <= -T whatever the interpolated range
    double h_out2 = 0;  // square of the out-of-plane half-thickness off the cone (a voxel's
                        // half-extent or half the gap to the neighbouring pings' fans)
    float range = 0;    // footprint range
    float dr_prev = 0;  // range change towards sector k - 1 (0 = no interpolation that side)
    float dr_next = 0;  // range change towards sector k + 1
    float weight = 0;   // f times the footprint's support
    float dr_dx = 0;    // range change per voxel out of the plane (PreparedBeam::dr_dx)
    float x_fit_lo = 0, x_fit_hi = 0;  // applied over this span of offsets (held beyond)
};

// Beam-width mode: a ping rasterised as a whole, in columns of voxels along the world axis that
// lies closest to the fan plane (z for a level, downward-looking head). In the sonar frame a
// column moves along a fixed in-plane direction c (and slowly out of the plane); columns are
// binned by their in-plane offset omega across c, and each bin holds bounds on the position
// tau along c, and on the out-of-plane distance, that contain every voxel a sector of the ping
// can update. The walk then tests each candidate exactly (sector by half-plane tests against
// the sector boundaries, cone, band).
struct FanColumns {
    int axis = 2;                                    // world axis of the columns
    Eigen::Vector3d step = Eigen::Vector3d::Zero();  // sonar-frame change per voxel along axis
    double c_y = 0, c_z = 0;            // in-plane unit direction of the columns (sonar y, z)
    double w_y = 0, w_z = 0;            // in-plane unit normal to it: omega = w . (y, z)
    double g = 0;                       // in-plane length of one step, |(step.y, step.z)|
    double omega0 = 0;                  // omega of bin 0's lower edge (bins are one voxel wide)
    std::vector<float> tau_lo, tau_hi;  // per bin; tau_lo > tau_hi = empty
    std::vector<float> x_max;           // per bin: largest |x| a sector there can update
    std::vector<float> h_max;  // per bin: largest off-cone half-thickness h_out of its sectors
    double tau_min = 0, tau_max = 0, x_max_all = 0;  // over all bins
    std::int32_t lo[3] = {0, 0, 0};  // world voxel bounds of every voxel the ping can update
    std::int32_t hi[3] = {-1, -1, -1};
    // Sector k is [beta_k, beta_{k+1}) of the in-plane angle in index order, beta_k = start +
    // (k - 1/2) increment; a voxel lies at index >= k when side_y[k] y + side_z[k] z >= 0.
    std::vector<double> side_y, side_z;  // num_beams + 1 boundaries
    std::vector<FanSector> sectors;      // num_beams
    double inv_increment = 0;            // 1 / increment (signed)
    double start_angle = 0, increment = 0;
    bool wide = false;  // the fan spans 180 deg or more: sectors from the angle, not tracked
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
    FanColumns fan;              // beam-width mode (empty sectors in ray mode)
};

// The valid ranges of one scan and, in beam-width mode, every beam's footprint across the fan:
// a robust line through the ranges of the beams inside its cone (FitFootprints).
struct ScanFootprints {
    std::vector<float> r;  // valid ranges in voxel units, NaN otherwise
    // sin and cos of each beam's axis angle, start + i * increment in float as every reader of
    // the scan computes it
    std::vector<double> sin_theta, cos_theta;
    std::vector<float> range;             // beam-width mode: footprint range per beam, NaN = none
    std::vector<float> slope;             // range change per beam of the footprint's line
    std::vector<float> gate;              // inlier gate of that line (voxels)
    std::vector<int> support;             // inliers of that line
    std::vector<float> point_y, point_z;  // the footprint point (beam axis at its range) in the
                                          // scan's sonar frame, voxels
    int half = 0;                         // beams on each side of a footprint
    std::int64_t no_detection = 0;
    std::int64_t out_of_range = 0;
    std::int64_t inconsistent = 0;  // valid beams outvoted by their footprint
};
ScanFootprints FitFootprints(const SonarScan& scan, const TsdfConfig& config);

// Beam-width mode: how far the along-track slope can move a footprint's range (|dr_dx| times
// the largest offset of its fitted span).
inline double AlongTrackReach(const PreparedBeam& pb) {
    return std::abs(static_cast<double>(pb.dr_dx)) *
           std::max(std::abs(static_cast<double>(pb.x_fit_lo)),
                    std::abs(static_cast<double>(pb.x_fit_hi)));
}

// The widest gap between pings a beam is widened across (half of it on each side): a bridged
// run of missing beams is at most ping_gap_bridge_pings times ping_gap_fill_m long.
inline double WidestGapM(const TsdfConfig& config) {
    const int runs = config.ping_gap_fill_per_beam ? std::max(1, config.ping_gap_bridge_pings) : 1;
    return config.ping_gap_fill_m * runs;
}

// A scan near the one being prepared, in input order (offset -1: the previous ping).
struct ScanNeighbour {
    const SonarScan* scan = nullptr;
    const ScanFootprints* footprints = nullptr;  // FitFootprints of *scan
    int offset = 0;
};

// The beams of one scan in voxel units, from its footprints. Beam-width mode also measures the
// gap from each footprint to the fan planes of the neighbours at offsets -1 and +1 (-2 and +2
// where those have no footprint at the beam and these have; further, up to
// ping_gap_bridge_pings + 1, where the beam's footprint there agrees with this one), and fits
// each footprint's along-track slope (PreparedBeam::dr_dx) to the footprints of the same beam
// in the neighbours within TsdfConfig::footprint_neighbour_pings.
PreparedScan PrepareScan(const SonarScan& scan,
                         const ScanFootprints& footprints,
                         const TsdfConfig& config,
                         const Geometry& geo,
                         const std::vector<ScanNeighbour>& neighbours);

// The same for scans[index], its neighbours taken from scans (footprints fitted here).
PreparedScan PrepareScan(const std::vector<SonarScan>& scans,
                         std::size_t index,
                         const TsdfConfig& config,
                         const Geometry& geo);

// A scan on its own (no neighbours).
PreparedScan PrepareScan(const SonarScan& scan, const TsdfConfig& config, const Geometry& geo);

// Beam-width mode: fills ps.fan from the prepared beams (ps.beams, ps.R, ps.p_vox) of a scan
// and its footprints (fan_columns.cpp).
void BuildFanColumns(PreparedScan& ps,
                     const SonarScan& scan,
                     const ScanFootprints& footprints,
                     const Geometry& geo);

}  // namespace pitmap::proc::fusion::detail
