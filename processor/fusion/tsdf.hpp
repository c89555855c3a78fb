// SPDX-License-Identifier: MIT
// TSDF fusion of multibeam sonar scans into sparse OpenVDB grids (seed paper section 4.3):
// signed distance d(v) = m - |p - v| (Eq. 4), running weighted average (Eq. 5) with uniform
// weight f and a weight cap w_max (Eq. 6). The multibeam is a polar line sensor with a beam
// width, updated by back-projection after May et al. (2014); a plain per-beam ray mode (as
// point-sensor TSDF libraries do) is kept for comparison.
//
// Beam-width mode: every beam's cone (beam_width_rad, in and out of the fan plane) covers the
// axes of its neighbours within beam_width / 2 (7 beams at 1.5 deg and 0.25 deg spacing). The
// range that footprint sees is a robust line fit over those beams (coarse outliers and
// dropouts are outvoted, and counted in beams_inconsistent); a voxel back-projects into the
// sector of one beam, takes the range interpolated between that footprint and its neighbour's
// (not across a range jump, e.g. a bench crest and the floor behind it), and is updated once
// per ping with weight f times the number of beams in the footprint (so single coverage at
// short range still carries a weight a filter can use). Out of the plane a voxel is in the
// beam when its centre lies within the cone, within half a voxel of the fan plane, or within
// half the gap to the neighbouring pings' fans (TsdfConfig::ping_gap_fill_m): at short range
// the cone is narrower than the ping spacing, and without that every third voxel plane along
// the track would stay unobserved and the iso-surface would break up there.
//
// Frames: sonar x forward, y starboard, z down; beam i points at theta_i = start + i * increment
// from nadir towards starboard, a hit lies at (0, r sin theta, r cos theta) in the sonar frame.
// The world frame is the local ENU frame (z up) of the survey (docs/conventions.md).
//
// OpenVDB stays inside tsdf.cpp and vdb_io.cpp; this header is cheap to include.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/progress.hpp"

namespace pitmap::proc::fusion {

// One multibeam ping, already georeferenced.
struct SonarScan {
    double gps_time_s = 0;  // GPS time of the ping (only for diagnostics)
    Eigen::Isometry3d T_world_sonar = Eigen::Isometry3d::Identity();  // sonar -> world (ENU)
    float start_angle_rad = 0;      // angle of beam 0 from nadir, positive to starboard
    float angle_increment_rad = 0;  // angle between consecutive beams
    std::vector<float> ranges_m;    // slant range per beam; 0 or NaN = no detection
};

enum class SensorModel : std::uint8_t {
    kBeamWidth,  // polar line sensor with a beam width, back-projection (May et al. 2014)
    kRay,        // one ray per beam through the beam centre (vdbfusion-style)
};

// Most pings on each side a footprint's along-track slope is fitted to.
inline constexpr int kMaxFootprintNeighbourPings = 8;

// Longest run of pings a missing beam is bridged across (TsdfConfig::ping_gap_bridge_pings).
inline constexpr int kMaxBridgePings = 8;

// Longest range gate, in voxels (TsdfConfig::max_range_m / voxel_size_m): 2 km at 0.1 m.
inline constexpr double kMaxRangeVoxels = 20000.0;

struct TsdfConfig {
    double voxel_size_m = 0.10;           // edge length of a voxel
    double truncation_m = 1.5;            // |d| band: voxels with d in (-T, T] are updated
    float weight_per_measurement = 1.0f;  // f in Eq. 5-6 (uniform weights)
    // w_max in Eq. 6, in measurements of weight f: a ray through a voxel is one, a beam-width
    // footprint as many as its beams (7 at 1.5 deg and 0.25 deg spacing). Larger averages more
    // passes (about 20 pings at 140), smaller follows change sooner but keeps the last line's
    // navigation error. docs/decisions/006.
    float max_weight = 140.0f;
    // Beam-width keeps the walls and shores that rays leave as holes at the same weight
    // threshold, at the rays' error. docs/decisions/001.
    SensorModel sensor_model = SensorModel::kBeamWidth;
    double beam_width_rad = 1.5 * 3.14159265358979323846 / 180.0;  // full out-of-plane width
    double min_range_m = 0.3;    // ranges below are not detections (counted)
    double max_range_m = 120.0;  // ranges above are not detections (counted); at most
                                 // kMaxRangeVoxels voxels
    // Beam-width mode: the beams of one footprint (those whose axes lie within beam_width / 2
    // of a beam's axis) agree with the footprint's robust range line within
    // footprint_gate_m + footprint_gate_fraction * range; the others are outliers (counted).
    double footprint_gate_m = 0.15;
    double footprint_gate_fraction = 0.01;
    // Beam-width mode: consecutive scans of the input are consecutive pings of one head. Where
    // a beam's footprint lies at most this far from the fan plane of the previous or next
    // scan, the beam is widened out of its plane to half that distance (never narrowed), so
    // the voxels between two pings are updated. At short range the beam is narrower than the
    // ping spacing (2 r tan(bw / 2) = 8 cm at 3 m against 15 cm at 1.5 m/s and 10 Hz), and a
    // 0.1 m voxel grid would keep every third plane across the track unobserved. Wider gaps
    // (missing pings, the turn between lines) stay holes. 0 = off.
    double ping_gap_fill_m = 0.3;
    // Beam-width mode, with ping_gap_fill_m: where the next ping on one side has no footprint at
    // a beam (its echoes there were rejected, or it had none) and the ping after it has, the gap
    // on that side is measured to that ping's fan: a beam missing in one ping leaves the same
    // strip unobserved as a missing ping, and is bridged the same way (within ping_gap_fill_m).
    // false = the gap to the next pings' fans whatever they hold. docs/decisions/026.
    bool ping_gap_fill_per_beam = true;
    // Beam-width mode, with ping_gap_fill_per_beam: a beam missing in a run of up to this many
    // consecutive pings (its echoes rejected: a fish school, the smile, a bubble episode) is
    // bridged across the run when the same beam's footprint in the ping past the run lies on
    // the surface the widened beam writes: within the footprint's gate of its range line, at
    // the range the ping sees out of its plane, within its cone across the fan (each side
    // tests the other, and each widens to half the gap), and the run at most this many times
    // ping_gap_fill_m long. Nothing is bridged where the two sides disagree (an edge, a step,
    // a slope along the track steeper than the gate over the gap). 0 = only the rule above
    // (one ping). At most kMaxBridgePings. docs/decisions/039.
    int ping_gap_bridge_pings = 8;
    // Beam-width mode: the footprint's range varies across the beam's width along the track as
    // well as across the fan. That slope is fitted to the footprints of the same beam in up to
    // this many pings before and after (consecutive scans of the input), so a face or wall the
    // track runs towards is placed where it is across the whole out-of-plane width, not smeared
    // over it as a sphere of one range (2.5 r tan(incidence) tan(bw / 2) off at the cone's edge).
    // 0 = the range is the same across the width.
    int footprint_neighbour_pings = 2;
    int num_threads = 0;  // 0 = all cores (TBB default)

    // Every problem with the configuration (empty when valid).
    std::vector<std::string> Validate() const;
};

// The pings on each side of a scan that its integration reads as neighbouring pings (beam-width
// mode): the gap between pings needs the next two (ping_gap_fill_m), or one more than the
// longest run a missing beam is bridged across (ping_gap_bridge_pings); the along-track slope
// footprint_neighbour_pings. Integrate(scans, begin, end) reads that many scans before begin
// and after end: a survey integrated in blocks gives each call that many of the neighbouring
// blocks' pings around it, and equals one call.
inline int NeighbourPings(const TsdfConfig& config) {
    int gap = 1;
    if (config.ping_gap_fill_m > 0.0) {
        gap = std::max(2, config.ping_gap_fill_per_beam ? config.ping_gap_bridge_pings + 1 : 0);
    }
    return std::max(gap, config.footprint_neighbour_pings);
}

// Statistics of one Integrate call.
// Sonar positions further than this from the world origin on any axis (or non-finite poses)
// are not integrated: no survey spans 100 km, and the volume's index range stays far inside
// OpenVDB's 32-bit coordinates.
inline constexpr double kMaxSonarOffsetM = 100'000.0;

struct IntegrateResult {
    std::int64_t scans = 0;                // scans given
    std::int64_t scans_out_of_bounds = 0;  // pose non-finite or beyond kMaxSonarOffsetM; their
                                           // beams are not integrated (nor counted below)
    std::int64_t beams_used = 0;           // beams with a valid range that were integrated
    std::int64_t beams_no_detection = 0;   // 0 or NaN range
    std::int64_t beams_out_of_range = 0;   // outside [min_range_m, max_range_m] or negative
    std::int64_t beams_inconsistent = 0;   // beam-width mode: valid beams outvoted by their
                                           // footprint (coarse outliers; not integrated)
    std::int64_t voxel_updates = 0;        // (voxel, measurement) updates applied
    std::int64_t active_voxels = 0;        // active voxels of the volume afterwards
    double elapsed_s = 0;                  // wall time of the call
    double prepare_s = 0;                  // of which footprints and beam bounds (wall time)
    double rasterise_s = 0;                // of which the slab tasks' voxel updates (wall time)
    double merge_s = 0;      // of which gathering the slabs' leaves into the volume (wall time)
    double cpu_s = 0;        // CPU time of the whole process during the call (all threads)
    bool cancelled = false;  // the progress callback asked to stop
    std::string message;
};

struct WeightFilterConfig {
    // Voxels with weight below are removed. In beam-width mode a ping adds f per beam of the
    // footprint (7 at 1.5 deg / 0.25 deg), so 3 removes voxels seen by fewer than 3 beams and
    // keeps single coverage; higher trades completeness for fewer stray voxels.
    // docs/decisions/007.
    float min_weight = 3.0f;

    std::vector<std::string> Validate() const;
};

struct WeightFilterResult {
    std::int64_t voxels_before = 0;
    std::int64_t voxels_removed = 0;  // weight < min_weight
    std::int64_t voxels_after = 0;
    std::string message;
};

// A triangle mesh in world coordinates (metres), indexed.
struct TriangleMesh {
    std::vector<Eigen::Vector3f> vertices;
    std::vector<Eigen::Vector3i> triangles;  // counter-clockwise seen from the water side
};

struct IsoSurfaceResult {
    TriangleMesh mesh;
    std::int64_t polygons_raw = 0;         // polygons from volume-to-mesh (quads count once)
    std::int64_t polygons_unobserved = 0;  // dropped: sign change only against unobserved voxels
    std::string message;
};

// Voxel-level summary (for tests and reports).
struct VolumeStats {
    std::int64_t active_voxels = 0;
    std::int64_t leaf_nodes = 0;
    std::size_t memory_bytes = 0;  // both grids
    float min_weight = 0;
    float max_weight = 0;
};

// Histogram of the weights of the active (observed) voxels. Bin k counts weights w with
// edges[k] <= w < edges[k + 1] (the last bin also takes w == edges.back()); counts has
// edges.size() - 1 entries.
struct WeightHistogram {
    std::vector<float> edges;
    std::vector<std::int64_t> counts;
    std::int64_t total = 0;  // active voxels counted (sum of counts)
};

// A region of voxel columns (world voxel indices, voxel centres at integer multiples of the
// voxel size): x in [x_min, x_max], y in [y_min, y_max], every z. A volume restricted to a
// region (a tile and its overlap) updates only its voxels, and each of them exactly as a
// volume without region does (same updates, same order, same rounding): the edges must lie on
// the rasteriser's slabs and bands, x_min and y_min multiples of kRegionAlignVoxels and
// x_max + 1, y_max + 1 too.
inline constexpr int kRegionAlignVoxels = 64;
struct VoxelColumns {
    std::int32_t x_min = 0, x_max = -1, y_min = 0, y_max = -1;
    bool Aligned() const;  // the edges on kRegionAlignVoxels, and not empty
};

// The triangles of `mesh` whose centroid lies in `columns` (world x in [(x_min - 1/2) s,
// (x_max + 1/2) s), y alike, s the voxel size): the seam rule of tiled meshes, each triangle of
// the whole mesh in exactly one tile. Vertices are renumbered in first use order.
TriangleMesh KeepTrianglesIn(const TriangleMesh& mesh,
                             const VoxelColumns& columns,
                             double voxel_size_m);

// The horizontal box (world metres) holding every voxel a scan can update: the hit points of
// its beams within the range gate, grown by T + 0.1 r_max + the widest gap between pings
// bridged (ping_gap_fill_m, times ping_gap_bridge_pings with ping_gap_fill_per_beam) + 2 voxels
// (the beam's cone, r tan(bw / 2) = 0.013 r at 1.5 deg, the footprint's range line and
// along-track slope, the gap fill out of the fan plane). Empty (x_min > x_max) without a valid
// beam; everything for a pose that is not finite (Integrate counts it out of bounds).
struct ScanReach {
    double x_min = 0, x_max = -1, y_min = 0, y_max = -1;
    bool empty() const { return !(x_min <= x_max); }
};
ScanReach ReachOf(const SonarScan& scan, const TsdfConfig& config);

// THREADING: Integrate uses up to num_threads TBB workers internally. Space is cut into slabs
// along world x; the scans are taken in chunks of consecutive scans, and each slab integrates
// a chunk's scans in input order in one task, so the result is identical for any thread count
// (bit for bit). The object itself is not thread safe: do not call methods concurrently.
// MEMORY: besides the grids, Integrate holds one chunk's prepared scans (512 scans: ~36 bytes
// per beam, and in beam-width mode ~40 KB per ping for its column set-up) and, while merging,
// nothing more: slab leaves are moved into the volume.
class TsdfVolume {
public:
    // Precondition: config.Validate() is empty.
    explicit TsdfVolume(const TsdfConfig& config);
    // Restricted to `region` (VoxelColumns): Integrate updates its voxels only, and skips the
    // scans that cannot reach it (ReachOf). Precondition: region.Aligned().
    TsdfVolume(const TsdfConfig& config, const VoxelColumns& region);
    ~TsdfVolume();
    TsdfVolume(TsdfVolume&&) noexcept;
    TsdfVolume& operator=(TsdfVolume&&) noexcept;
    TsdfVolume(const TsdfVolume&) = delete;
    TsdfVolume& operator=(const TsdfVolume&) = delete;

    // Integrates the scans in order. progress (optional) gets the fraction done; returning false
    // cancels (the volume then holds a partial integration). Beam-width mode takes the scans
    // before and after each scan in `scans` as its neighbouring pings (ping_gap_fill_m,
    // footprint_neighbour_pings), so the first and last scans of a call see neighbours on one
    // side only.
    IntegrateResult Integrate(const std::vector<SonarScan>& scans,
                              const ProgressCallback& progress = nullptr);
    // Integrates scans[begin, end) (clamped to the vector); the scans around that range are
    // only its neighbouring pings. A survey integrated part by part this way, each call given
    // the whole sequence, equals one call voxel for voxel.
    IntegrateResult Integrate(const std::vector<SonarScan>& scans,
                              std::size_t begin,
                              std::size_t end,
                              const ProgressCallback& progress = nullptr);

    // Removes voxels observed too rarely (outlier surfaces), from both grids.
    WeightFilterResult FilterByWeight(const WeightFilterConfig& config);

    // Zero level set (OpenVDB volumeToMesh, marching-cubes style, adaptivity 0), keeping only
    // polygons whose cells hold observed voxels on both sides of the iso value (an unobserved
    // neighbour reads as the background +T and would create a false surface at the back of
    // the band).
    IsoSurfaceResult ExtractIsoSurface(double iso_m = 0.0) const;

    // Signed distance and weight at a world point (nearest voxel); weight 0 = unobserved.
    float DistanceAt(const Eigen::Vector3d& p_world) const;
    float WeightAt(const Eigen::Vector3d& p_world) const;

    VolumeStats Stats() const;

    // Every observed voxel: its index (x, y, z), signed distance (m) and weight, in no
    // particular order.
    void ForEachVoxel(
        const std::function<void(const Eigen::Vector3i&, float distance_m, float weight)>& visit)
        const;
    // Copies the voxels of `from` in `columns` into this volume (a tile's core into the whole),
    // replacing what it held there. Preconditions: the same voxel size and truncation,
    // columns.Aligned().
    void CopyColumns(const TsdfVolume& from, const VoxelColumns& columns);

    // Weight histogram over the active voxels (config().max_weight is w_max).
    // num_bins = 0: one bin per unit weight, edges 0, 1, ..., W + 1 with W = ceil(w_max), so a
    // weight of exactly k lands in bin k and the cap w_max in the last bin.
    // num_bins > 0: that many equal bins over [0, w_max]. Precondition: num_bins >= 0.
    WeightHistogram ComputeWeightHistogram(int num_bins = 0) const;
    const TsdfConfig& config() const { return config_; }

    struct Impl;  // defined in detail/tsdf_grids.hpp (OpenVDB)
    const Impl& impl() const { return *impl_; }
    Impl& impl() { return *impl_; }

    const std::optional<VoxelColumns>& region() const { return region_; }

private:
    TsdfConfig config_;
    std::optional<VoxelColumns> region_;
    std::unique_ptr<Impl> impl_;
};

}  // namespace pitmap::proc::fusion
