// SPDX-License-Identifier: MIT
// Automatic cleaning of soundings in 3D (issue 35): fish schools, bubble sweep-down, the nadir
// smile and multipath ghosts are runs of soundings held over many beams and pings, which a
// per-ping median filter does not see. This stage decides on all of a survey's soundings at
// once, from the evidence of every ping, in a sparse OpenVDB grid of voxels (`voxel_m`):
//
//   1. Voxels and patches. Every sounding is binned; each voxel keeps its count and the
//      moments of its soundings (centroid, covariance: a plane patch where the surface is).
//      Voxels touching (26-neighbours) form components: the terrain is the few large ones
//      (>= `cluster_max_voxels`); anything else is a cluster.
//   2. Free space (kFreeSpace). Every sounding's ray, from the transducer to `margin` before
//      its own end, is marched through the clusters' voxels (OpenVDB's hierarchical DDA skips
//      the empty water). A cluster voxel that other rays passed through, at least
//      `free_min_rays` of them and `free_ratio` times its own soundings, is water other pings
//      observed as free: its soundings are transients (fish seen by some beams and not by the
//      beams beside them, bubbles).
//   3. Clusters off the surface (kCluster). A cluster whose soundings have terrain behind them
//      along their own rays floats in front of the observed surface: persistent mid-water
//      targets and near-field returns (bubble clouds, the smile's arc) are not terrain.
//   4. Multipath (kMultipath). Every sounding's ray is marched through the terrain's voxels
//      from the transducer; where it meets a well-observed plane patch (>= `surface_min_hits`
//      soundings, thin) well before its own end and passes through the patch (not past its
//      edge), a sounding lying behind that plane (by more than `multipath_behind_m` and 4 times
//      the patch's thickness) is a ghost: sound that travelled further than the surface it
//      went through.
// What the cleaning does not see: a sounding within `margin` of the terrain (it is on it), a
// ghost behind a surface no other ping observed, a transient held in the same place long
// enough to be the only evidence there (then it is terrain to this stage; CUBE's hypotheses
// and the surface filter of the grid stage still judge it on floors).
//
// Input: a georeferenced view (candidates: accepted by georef's own filters); output: a status
// per point (georef::SoundingStatus: kAccepted, kFreeSpace, kCluster, kMultipath).
// Deterministic: the decisions do not depend on the thread count (counts are sums).
// Failure model: none beyond memory; an empty view gives empty results.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/progress.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::clean {

struct CleanConfig {
    bool enabled = true;           // `run` cleans the soundings before the grid and the TSDF
    double voxel_m = 0.5;          // the evidence grid's voxel edge
    int cluster_max_voxels = 300;  // components with fewer voxels are clusters, not terrain
    double margin_m = 0.5;         // a ray stops this far before its own end (noise) ...
    double margin_rel = 0.03;      // ... or this share of its range, whichever is larger
    int free_min_rays = 3;         // free space: rays through a cluster voxel, at least ...
    double free_ratio = 0.5;       // ... and this many times its own soundings
    int surface_min_hits = 8;      // a plane patch for the multipath test: soundings in it
    double surface_max_thickness_m = 0.12;  // its 1-sigma across the plane, at most
    double multipath_behind_m = 0.3;        // a ghost lies this far behind the patch's plane
    double solid_ratio = 0.3;               // a patch crossed by fewer rays than this share of
                                            // its own support is solid (a ghost's ray crossed it)
    double scatter_free_ratio = 2.0;        // voxels without a plane: free rays / soundings
    int along_track_pings = 15;             // along track: neighbouring pings each side; 0 = off
    double along_track_sigmas = 5.0;        // off the neighbours' line by this many spreads ...
    double along_track_min_m = 0.3;         // ... and this far (and margin_rel of the range)
    double along_track_max_spread = 0.03;   // where the neighbours agree: spread / range
    int num_threads = 0;                    // 0 = all cores (TBB)

    std::vector<std::string> Validate() const;
};

struct CleanCounts {
    std::int64_t soundings = 0;
    std::int64_t voxels = 0;
    std::int64_t terrain_components = 0;
    std::int64_t clusters = 0;  // components smaller than cluster_max_voxels
    std::int64_t free_space = 0;
    std::int64_t cluster = 0;
    std::int64_t multipath = 0;
    std::int64_t along_track = 0;
    double seconds_voxels = 0, seconds_free_space = 0, seconds_clusters = 0, seconds_multipath = 0;
};

struct CleanResult {
    std::vector<std::uint8_t> status;  // georef::SoundingStatus per point of the view
    CleanCounts counts;
    bool cancelled = false;
};

CleanResult Clean(const georef::GeorefResult& geo,
                  const CleanConfig& config,
                  const ProgressCallback& progress = {});

}  // namespace pitmap::proc::clean
