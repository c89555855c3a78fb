// SPDX-License-Identifier: MIT
// Automatic cleaning of soundings in 3D (issue 35): fish schools, bubble sweep-down, the nadir
// smile and multipath ghosts are runs of soundings held over many beams and pings, which a
// per-ping median filter does not see. This stage decides on all of a survey's soundings at
// once, from the evidence of every ping, in a sparse OpenVDB grid of voxels (`voxel_m`):
//
//   1. Voxels and patches. Every sounding is binned. A voxel with `surface_min_hits` soundings
//      gets a plane patch: a robust (Cauchy-weighted) PCA fit, kept when its soundings lie
//      within `surface_max_thickness_m` (1 sigma) of it. Voxels touching (26-neighbours) form
//      components: the terrain is the large ones (>= `cluster_max_voxels`), the rest clusters.
//   2. Rays. Every sounding's ray, from the transducer to `margin` before its own end, is
//      marched through the voxels (OpenVDB's hierarchical DDA skips the empty water): each voxel
//      counts the rays through it, and a ray that goes through a plane patch (into the plane at
//      more than 15 deg, the crossing inside the voxel) crosses it. A patch's support is its
//      soundings whose rays crossed nothing. A crossing is evidence of water only when the
//      crossing ray ends on a supported patch (a floor sounding seen through a fish school is;
//      a ghost, whose ray went through the floor, is not).
//   3. Free space (kFreeSpace): a patch crossed by at least `free_min_rays` such rays and
//      `free_ratio` times its support is a "surface" of echoes in water other pings saw
//      through: fish, bubbles, the smile. A cluster voxel other rays passed through likewise.
//   4. Multipath (kMultipath): a sounding whose ray first crossed a solid patch (supported,
//      crossed by fewer than `solid_ratio` times its support) lies behind a surface observed
//      from elsewhere: sound that travelled further than the surface it went through. Not
//      when the patch's voxel is a cluster voxel whose own soundings are free space (below): a
//      ray through a fish school's voxel went through water (docs/decisions/026).
//   5. Clusters: a cluster sounding whose ray went through the terrain before its end (into a
//      solid patch's plane at more than the crossing angle, within a voxel of its centre) lies
//      behind the observed surface (kMultipath; all of the cluster when most of its soundings
//      do): a long ghost behind a wall its own pings observed only sparsely, whose rays pass
//      between the patches' extents. A cluster whose soundings mostly have terrain behind them
//      along their rays floats in front of the observed surface (kCluster: persistent
//      mid-water targets, near-field returns).
//   6. Range profiles (kProfile): what is left is judged on its range against a robust line
//      through the same beam over `profile_pings` pings each side and through the same ping
//      over `profile_beams` beams each side (where the neighbours disagree, the line of the
//      side that agrees, for a sounding far in front of it: an echo run's edge); only runs (a
//      neighbouring beam or ping also off) are rejected: the per-ping median filter's idea,
//      over runs longer than its window. With them, near-field echoes (bubble sweep-down):
//      runs of soundings within `near_field_max_range_m` far in front (`near_field_ratio`,
//      `near_field_min_m`) of the median range of the same beam on both sides along track,
//      where a bent side's line does not judge (docs/decisions/024-near-field-echoes.md); and
//      the nadir smile: runs across the fan at the ping's nadir range (`smile_nadir_deg`), more
//      than a break in front of their beam's median range on both sides (decision 025).
//   7. Holes: an accepted sounding between two of one rejection status (along track or across
//      the fan) and on the line between their ranges (`hole_tolerance`) takes their status;
//      so does a small piece of continuous range enclosed by rejected soundings and breaks in
//      the range (`fill_max_soundings`, `fill_min_contacts`, `fill_break_m`).
//   8. Terrain after all: a rejected sounding continuous in range (the pieces' measure) with a
//      piece of `terrain_piece_soundings` accepted soundings, or with one released so, is
//      accepted again: a bench crest or a ledge a beam grazes for a few pings is off its range
//      profile and its rays cross the crest's patch, but its ranges go on into the terrain
//      beside it; the echoes of the water are parted from the terrain by breaks in the range.
// What it does not see: a sounding within `margin` of the surface (it is on it), an echo whose
// range goes on into the terrain's without a break (step 8 keeps it), a ghost behind
// a surface no other ping observed, an echo held in one place so long that it is the only
// evidence there (then it is terrain here; on floors the grid stage's surface filter against
// CUBE's chosen hypothesis still judges it).
//
// Input: a georeferenced view (the candidates: what georef's own filters accept); output: a
// status per point (survey::SoundingStatus: kAccepted, kFreeSpace, kMultipath, kCluster,
// kProfile; CleanCounts::terrain counts the rejections step 8 undid). Deterministic: the
// verdicts do not depend on the thread count.
// Failure model: none beyond memory (the grid holds one voxel per occupied `voxel_m` cube, a
// few tens of bytes each); an empty view gives empty results.
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
    double margin_m = 0.3;         // a ray stops this far before its own end (noise) ...
    double margin_rel = 0.03;      // ... or this share of its range, whichever is larger
    int free_min_rays = 3;         // free space: rays through a cluster voxel, at least ...
    double free_ratio = 0.5;       // ... and this many times its own soundings
    int surface_min_hits = 8;      // a plane patch for the multipath test: soundings in it
    double surface_max_thickness_m = 0.12;  // its 1-sigma across the plane, at most
    double min_crossing_deg = 15.0;         // a ray crosses a patch at more than this to its plane
    double solid_ratio = 0.3;               // a patch crossed by fewer rays than this share of
                                            // its own support is solid (a ghost's ray crossed it)
    int profile_pings = 10;       // range profiles: neighbouring pings each side (along track) ...
    int profile_beams = 0;        // ... and beams each side (across the fan); 0 = off
    double profile_sigmas = 5.0;  // off the neighbours' line by this many spreads ...
    double profile_min_m = 0.3;   // ... and this far (and margin_rel of the range)
    double profile_max_spread = 0.03;     // where the neighbours agree: spread / range
    double near_field_max_range_m = 5.0;  // near-field echoes: at most this range (0 = off) ...
    double near_field_ratio = 0.8;        // ... under this share of both sides' median range
    double near_field_min_m = 0.5;        // ... and this far in front of both, m
    double smile_nadir_deg = 2.0;         // the nadir smile: a ping's nadir is its sounding nearest
                                          // to 0 deg, within this (0 = off)
    double hole_tolerance = 0.01;       // a hole in a run: on its neighbours' line, share of range
    int fill_max_soundings = 500;       // an enclosed piece of continuous range: at most this many
                                        // soundings (0 = off) ...
    int fill_min_contacts = 2;          // ... touching rejected soundings this often ...
    double fill_break_m = 0.15;         // ... its other edges breaks in the range of this, m
                                        // (or margin_rel of the range)
    bool fill_across_fan = true;        // ... grown across the fan too over steps short of a break
    int terrain_piece_soundings = 500;  // a rejection continuous in range with a piece of this
                                        // many accepted soundings is terrain (0 = off)
    int num_threads = 0;                // 0 = all cores (TBB)

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
    std::int64_t profile = 0;
    std::int64_t near_field = 0;  // of `profile`: near-field echoes the lines did not reject
    std::int64_t smile = 0;       // of `profile`: the nadir smile, the other tests did not reject
    std::int64_t terrain = 0;     // rejected by a test, then released: continuous with the terrain
    // Wall time of the parts: voxels and patches, the rays, the clusters, the verdicts of the
    // voxels and rays, the range profiles (with the holes and the enclosed pieces), the
    // terrain's continuity.
    double seconds_voxels = 0, seconds_rays = 0, seconds_clusters = 0, seconds_verdicts = 0,
           seconds_profiles = 0, seconds_terrain = 0;
};

struct CleanResult {
    std::vector<std::uint8_t> status;  // survey::SoundingStatus per point of the view
    CleanCounts counts;
    bool cancelled = false;
};

CleanResult Clean(const georef::GeorefResult& geo,
                  const CleanConfig& config,
                  const ProgressCallback& progress = {});

}  // namespace pitmap::proc::clean
