// SPDX-License-Identifier: MIT
// Scores of survey products against the simulator's ground truth (pitmap-eval). Definitions:
//   trajectory_ate_rmse_m   RMS of |p_est(t) - p_true(t)| over the product trajectory's poses
//                           inside the true trajectory's span, positions in the truth's world
//                           frame, no alignment (products are georeferenced, so an offset is an
//                           error). ..._before_m: the same for trajectory_initial.csv.
//   points_rms_m, points_p95_m  RMS and 95th percentile of the unsigned distance of each point
//                           to the true terrain surface (points_bias_m: mean signed distance).
//                           Only the accepted soundings count: points.ply also holds the
//                           rejected ones (issue 35), told by its "status" property (0 =
//                           accepted); every points_*, artifact_* and good_* score is of the
//                           status-0 points (KeepAccepted).
//   boresight_error_deg     angle of R_true^T R_est, R = Rz(yaw) Ry(pitch) Rx(roll).
//   mesh_mean_abs_m, mesh_rms_m, mesh_p95_m  distance of mesh vertices and triangle centroids to
//                           the true surface.
//   mesh_completeness       share of the insonified true surface (truth/coverage.u8: terrain
//                           cells hit by a true beam) lying within 0.2 m of the mesh, the mesh
//                           being sampled at its vertices and triangle centroids (for a 0.1 m
//                           voxel mesh this overstates the distance by at most a few cm).
//   dem_mean_abs_m, dem_rms_m, dem_p95_m, dem_bias_m  vertical difference of every filled node
//                           of the gridded surface (P/dem.tif band 1) from the true terrain
//                           height at the node; dem_mean_abs_insonified_m: the same over the
//                           insonified nodes only.
//   dem_fill_insonified     share of the nodes whose centre lies on an insonified truth cell
//                           (truth/coverage.u8) that hold a value.
//   mosaic_*                P/mosaic.tif against truth/backscatter.f32 (ScoreMosaic).
//   tpu_within_tvu, tpu_within_thu  share of the soundings (P/soundings_tpu.ply) whose vertical
//                           (horizontal) error lies within their 95 % TVU (THU); the error is
//                           the sounding minus the true beam-axis point: the ray of the same
//                           beam angle from the true sonar pose at the ping time, cast into the
//                           true terrain. Also per 10-degree bin of |beam angle|.
#pragma once

#include <limits>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "common/formats/ply.hpp"
#include "common/formats/trajectory_csv.hpp"
#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "tools/sim/truth_io.hpp"
#include "tools/sim/water_column.hpp"

namespace pitmap::eval {

struct ProductPose {
    double gps_time_s = 0;
    Eigen::Vector3d position = Eigen::Vector3d::Zero();  // product world frame
};

// The positions of a product trajectory (common/formats/trajectory_csv reads the file).
std::vector<ProductPose> ProductPoses(const formats::TrajectoryCsv& trajectory);

// Maps product world coordinates (ENU at product_origin) to the truth's world frame. Two local
// ENU frames are both rigid transforms of ECEF, so one rigid transform relates them exactly.
Pose ProductToTruthFrame(const Geodetic& product_origin, const Geodetic& truth_origin);

struct DistanceStats {
    std::size_t count = 0;
    double rms_m = 0, p95_m = 0, mean_abs_m = 0, bias_m = 0, max_abs_m = 0;
};
// Statistics of signed distances (|d| for rms/p95/mean_abs, d for bias).
DistanceStats SummariseDistances(std::vector<double> d);

struct TrajectoryScore {
    std::size_t poses = 0;
    double ate_rmse_m = 0, ate_max_m = 0, z_std_m = 0;
};
TrajectoryScore ScoreTrajectory(const std::vector<ProductPose>& est,
                                const Pose& T_truth_product,
                                const std::vector<sim::TruthPose>& truth);

// Both trajectories scored per window of window_s seconds from the first true pose; a window
// where either has no pose inside the truth's span is left out.
struct AteWindow {
    double t0_s = 0, t1_s = 0;  // from the first true pose
    std::size_t poses = 0;      // of `after` in the window
    double before_m = 0, after_m = 0;
};
std::vector<AteWindow> ScoreTrajectoryWindows(const std::vector<ProductPose>& after,
                                              const std::vector<ProductPose>& before,
                                              const Pose& T_truth_product,
                                              const std::vector<sim::TruthPose>& truth,
                                              double window_s);

// P/trajectory_sigma.csv (processor/pipeline/posterior.hpp): per ping the final and initial
// positions (product world frame), the stated 1-sigma (SLAM's posterior or the INS's) and the
// INS's own.
struct StatedPose {
    double gps_time_s = 0;
    Eigen::Vector3d position = Eigen::Vector3d::Zero(), initial = Eigen::Vector3d::Zero();
    Eigen::Vector3d sigma_enu_m = Eigen::Vector3d::Zero(),
                    ins_sigma_enu_m = Eigen::Vector3d::Zero();
    bool slam_posterior = false;
};
Expected<std::vector<StatedPose>> ReadTrajectorySigmaCsv(const std::string& path);

// Whether the stated uncertainty contains the true error: the share of poses whose true
// horizontal error lies within the stated 95 % radius 2.4477 sqrt((s_E^2 + s_N^2) / 2) (IHO
// S-44's circular factor, the TPU's THU) and whose vertical error within 1.96 s_U.
struct ContainmentScore {
    std::size_t poses = 0;
    double share_within_h95 = 0, share_within_v95 = 0;
    double median_error_h_m = 0, median_radius_h95_m = 0;
};
struct UncertaintyScore {
    // after: the final positions with the stated sigma; before: the initial positions with the
    // INS's own sigma. all: every pose in the truth's span; outage: those whose INS horizontal
    // 1-sigma exceeds outage_sigma_m.
    ContainmentScore after_all, after_outage, before_all, before_outage;
};
UncertaintyScore ScoreUncertainty(const std::vector<StatedPose>& poses,
                                  const Pose& T_truth_product,
                                  const std::vector<sim::TruthPose>& truth,
                                  double outage_sigma_m);

DistanceStats ScorePoints(const std::vector<Eigen::Vector3d>& points_product,
                          const Pose& T_truth_product,
                          const sim::PitWorld& world,
                          std::size_t max_points = 3'000'000);

// Share of the covered true-surface cells whose surface point has a mesh sample within
// radius_m (mesh samples already in the truth frame). nullopt without a coverage mask, or when
// no covered cell has a true slope in [min_slope_deg, max_slope_deg) and a true water depth
// (PitWorld::Depth, below the water line z = 0) in [min_depth_m, max_depth_m).
std::optional<double> MeshCompleteness(
    const std::vector<Eigen::Vector3d>& mesh_samples_truth,
    const sim::Truth& truth,
    double radius_m = 0.2,
    double min_slope_deg = 0,
    double max_slope_deg = 91,
    double min_depth_m = 0,
    double max_depth_m = std::numeric_limits<double>::infinity());

// The samples that lie in a cube of cell_m (a grid from the origin) holding one of `others`:
// two meshes' common surface. Both meshes keep their samples in the same set of cells, so
// both are scored on the same surface in the same mix of floors and walls. (A radius test
// around the other mesh's samples is not symmetric: around a patchy mesh it keeps a rim of the
// fuller one, and the rims of small patches on walls are mostly wall.)
std::vector<Eigen::Vector3d> SamplesInSharedCells(const std::vector<Eigen::Vector3d>& samples,
                                                  const std::vector<Eigen::Vector3d>& others,
                                                  double cell_m);

// The true surface's slope under (x, y), degrees from horizontal.
double SlopeDeg(const sim::PitWorld& world, double x, double y);
// Slope classes [edge i, edge i + 1) that the mesh is also scored in: floors and benches, the
// ramp and bench faces, steep walls (a sensor model that smears a footprint shows it there).
inline constexpr double kSlopeClassEdgesDeg[] = {0, 20, 45, 91};
// True water depth classes [edge i, edge i + 1), m, that the mesh completeness is also scored
// in: the shore near the water line is seen at the shortest ranges, where the beam is
// narrowest and the pings' footprints do not overlap along the track.
inline constexpr double kDepthClassEdgesM[] = {
    0, 1, 2, 4, 8, 12, std::numeric_limits<double>::infinity()};

// A gridded surface's nodes in the truth frame: position (x, y, z = the node's elevation), or
// z NaN for an empty node.
struct DemScore {
    DistanceStats all;         // every filled node over the true terrain grid
    DistanceStats insonified;  // filled nodes on insonified cells
    std::size_t insonified_nodes = 0;
    std::optional<double> fill_insonified;  // nullopt without a coverage mask
};
DemScore ScoreDem(const std::vector<Eigen::Vector3d>& nodes_truth, const sim::Truth& truth);

// A backscatter mosaic's nodes in the truth frame: (x, y, z = the node's dB, NaN = empty).
// Only nodes whose footprint (the node +- 0.75 resolution) lies on one truth value are scored,
// so that a patch edge inside a node does not count as an error. The mosaic is relative (the
// sonar's gain is unknown): offset_db = median(mosaic - truth) is removed before the errors.
// A patch is one square of the truth (BackscatterConfig patch_size_m) or the boulders in it.
struct MosaicScore {
    std::size_t nodes = 0;         // scored
    double correlation = 0;        // Pearson, mosaic vs truth dB
    double offset_db = 0;          // median(mosaic - truth)
    double rms_db = 0;             // RMS of mosaic - truth - offset
    std::size_t patches = 0;       // patches with at least min_patch_nodes nodes
    double patch_mean_abs_db = 0;  // mean over them of |mean(mosaic - truth - offset)|
    double patch_max_abs_db = 0;   // the largest of those
    // Per truth level (material): (truth dB, mean error dB after the offset, nodes).
    std::vector<std::tuple<double, double, std::size_t>> by_level;
};
// nullopt when the truth has no backscatter. Precondition: resolution_m > 0.
std::optional<MosaicScore> ScoreMosaic(const std::vector<Eigen::Vector3d>& nodes_truth,
                                       double resolution_m,
                                       const sim::Truth& truth,
                                       std::size_t min_patch_nodes = 20);

// One sounding of soundings_tpu.ply, position in the truth frame.
struct TpuSounding {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    double gps_time_s = 0;
    double angle_deg = 0;
    double thu_95_m = 0, tvu_95_m = 0;
};
struct TpuBin {
    double lo = 0, hi = 0;  // the class: |beam angle| (deg), true depth (m) or slope (deg)
    std::size_t count = 0;
    double within_tvu = 0, within_thu = 0;
    double vertical_rms_m = 0, tvu_rms_m = 0;  // RMS of the error and of TVU / 1.96
    double vertical_bias_m = 0;                // mean vertical error
};
// The classes the TPU and the DEM uncertainty are checked in (issue 36): |beam angle| (the
// last class holds the beams beyond 60 deg), the true water depth at the true beam-axis point
// (below the water line z = 0 of the truth) and the true slope there (kSlopeClassEdgesDeg:
// floors, faces, walls).
inline constexpr double kTpuAngleClassEdgesDeg[] = {0, 20, 40, 60, 90};
inline constexpr double kTpuDepthClassEdgesM[] = {
    0, 5, 10, 20, std::numeric_limits<double>::infinity()};
struct TpuScore {
    TpuBin all;
    std::vector<TpuBin> by_angle;        // 10-degree bins
    std::vector<TpuBin> by_angle_class;  // kTpuAngleClassEdgesDeg
    std::vector<TpuBin> by_depth;        // kTpuDepthClassEdgesM
    std::vector<TpuBin> by_slope;        // kSlopeClassEdgesDeg
    std::size_t no_truth = 0;            // outside the true trajectory or no terrain on the ray
};
// At most max_soundings (evenly strided) are scored. The true beam-axis point is the beam of
// the same angle from the true sonar pose cast into the true terrain: straight, or with
// `water` (the truth's refracting water column) along the curved ray, as the simulator cast it.
TpuScore ScoreTpu(const std::vector<TpuSounding>& soundings,
                  const sim::Truth& truth,
                  const sim::PitWorld& world,
                  std::size_t max_soundings = 1'000'000,
                  const sim::WaterColumn* water = nullptr);

// Whether the DEM's stated 95 % uncertainty (P/dem.tif band "uncertainty") contains its true
// vertical error: per filled node with a finite uncertainty, |z - true height| <= uncertainty;
// all nodes, and by the true slope (kSlopeClassEdgesDeg) and true depth (kTpuDepthClassEdgesM)
// at the node.
struct DemUncertaintyBin {
    double lo = 0, hi = 0;
    std::size_t count = 0;
    double within = 0;                         // share
    double error_rms_m = 0, stated_rms_m = 0;  // RMS of the error and of uncertainty / 1.96
};
struct DemUncertaintyScore {
    DemUncertaintyBin all;
    std::vector<DemUncertaintyBin> by_slope, by_depth;
};
// `nodes_truth` as ScoreDem's, `uncertainty_95_m` one per node (NaN = none).
DemUncertaintyScore ScoreDemUncertainty(const std::vector<Eigen::Vector3d>& nodes_truth,
                                        const std::vector<double>& uncertainty_95_m,
                                        const sim::Truth& truth);

// The echo artifacts (truth/artifacts.*, tools/sim/echo_artifacts.hpp) found in a point cloud:
// each point is matched to its (ping, beam) by its beam number and its ping time (ping k
// transmits at first_ping_gps_s + k / ping_rate_hz; a point further than a quarter of a ping
// period from every ping is unmatched), then looked up in the truth's runs.
struct ArtifactScore {
    std::size_t points = 0;
    std::size_t unmatched = 0;
    std::int64_t in_points[sim::kNumEchoArtifactKinds] = {};  // [kind]: points of that kind
    std::int64_t good_in_points = 0;                          // points not listed
    // Good points per slope class (sim::kArtifactSlopeEdgesDeg) of the true surface under the
    // point (the truth counts them under the beam's true hit: the same for a good sounding).
    std::int64_t good_in_points_by_slope[sim::kNumArtifactSlopeClasses] = {};
    DistanceStats good;  // distances of the good points to the true surface
};
// Preconditions: gps_time_s and beam hold one value per point; points in the truth frame.
ArtifactScore ScoreArtifacts(const std::vector<Eigen::Vector3d>& points_truth,
                             const std::vector<double>& gps_time_s,
                             const std::vector<int>& beam,
                             const sim::ArtifactTruth& truth,
                             const sim::PitWorld& world);

// The accepted soundings of points.ply read with its "status" vertex property (issue 35; the
// writer is processor/io/products.hpp: 0 = accepted, else the reason of the rejection) at
// `status_index` of cloud.vertex_properties: keeps the vertices (with their beams and every
// other vertex property) of status 0, removes the status property itself (the properties
// after it move down by one) and returns how many vertices it dropped. A status that is not a
// finite 0 is a rejection.
std::size_t KeepAccepted(formats::ply::Mesh& cloud, std::size_t status_index);

// The names of the vertex properties in a PLY file's header ({} for a file without a vertex
// element); an unreadable file or header is an error naming the path.
Expected<std::vector<std::string>> PlyVertexProperties(const std::string& path);

// Angle in degrees between two roll/pitch/yaw (degrees) rotations.
double BoresightErrorDeg(double roll_est,
                         double pitch_est,
                         double yaw_est,
                         double roll_true,
                         double pitch_true,
                         double yaw_true);

}  // namespace pitmap::eval
