// SPDX-License-Identifier: MIT
// pitmap-eval: scores survey products against the simulator's ground truth.
//   pitmap-eval --truth DIR/truth --products P --json scores.json
// Exit (common/exit_codes.hpp): 0 scored, 1 a product or the truth unreadable (or nothing to
// score, or --json not written), 2 usage (a folder that is not there, bad arguments), 3
// internal error.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>

#include "common/cli/parse.hpp"
#include "common/exit_codes.hpp"
#include "common/formats/ply.hpp"
#include "common/formats/trajectory_csv.hpp"
#include "common/geodesy.hpp"
#include "common/result.hpp"
#include "tools/eval/change_scores.hpp"
#include "tools/eval/scores.hpp"
#ifdef PITMAP_EVAL_GRID
#include "processor/io/grid_io.hpp"
#include "tools/eval/terrain_score.hpp"
#endif

namespace fs = std::filesystem;
using nlohmann::json;
using namespace pitmap;
namespace codes = pitmap::exit_code;

namespace {

constexpr const char* kDefinitions = R"(Scores (only those whose product exists are written):
  trajectory_ate_rmse_m         RMS position error of P/trajectory.csv (after SLAM; without SLAM
                                P/trajectory_ins.csv) against the true trajectory at the same GPS
                                times, in the truth's world frame, no alignment.
  trajectory_ate_rmse_before_m  the same for P/trajectory_initial.csv (before SLAM).
  trajectory_ate_windows        with --ate-window S: both RMS errors per window of S seconds from
                                the first true pose (before_m: trajectory_initial.csv, after_m);
                                trajectory_ate_worst_window_increase_m: the largest after - before.
  trajectory_uncertainty        with P/trajectory_sigma.csv (after SLAM): the share of pings
                                whose true horizontal error lies within the stated 95 % radius
                                2.4477 sqrt((sE^2 + sN^2) / 2) (share_within_h95; vertical:
                                within 1.96 sU), the median error and radius; after: the final
                                positions with the stated sigma (SLAM's posterior where SLAM's
                                trajectory is used), before: the initial ones with the INS's
                                sigma; all pings, and those whose INS horizontal 1-sigma exceeds
                                0.5 m (outage).
  trajectory_z_std_m            standard deviation of the product track height (a surface
                                vehicle's track should be planar).
  points_rms_m, points_p95_m    RMS and 95th percentile of the distance of each point of
                                P/points.ply to the true terrain surface; points_bias_m: mean signed.
                                Every points_*, artifact_* and good_* score counts only the
                                accepted soundings (status 0) of a points.ply with a "status"
                                property (issue 35); points_accepted, points_rejected: how many.
  points_rms_m_angle_A_B        points_rms_m of the beams with A <= |beam angle| < B degrees
                                (bins 0 15 30 45 55 and beyond; beam angles from the points'
                                "beam" property and truth/scenario.json's sonar fan).
  boresight_error_deg           angle between the estimated (P/boresight.json) and the true
                                INS->sonar rotation, R = Rz(yaw) Ry(pitch) Rx(roll).
  mesh_mean_abs_m, mesh_rms_m, mesh_p95_m
                                distance of the vertices and triangle centroids of P/mesh.ply
                                to the true surface.
  mesh_completeness             share of the insonified true surface (truth/coverage.u8) within
                                0.2 m of a mesh vertex or triangle centroid.
  mesh_mean_abs_m_common, mesh_common_share
                                with --mesh-common-with Q: mesh_mean_abs_m over the samples of
                                P/mesh.ply in the 0.2 m cubes that hold samples of both meshes,
                                and their share (two sensor models compared on the surface both
                                hold, each on the same cubes).
  mesh_share_beyond_1m          share of those samples more than 1 m from the true surface.
  mesh_bias_m, mesh_bias_m_common
                                signed mean of the same distances (> 0: the mesh lies in the
                                water, above or in front of the true surface).
  mesh_mean_abs_m_slope_A_B, mesh_bias_m_slope_A_B, mesh_completeness_slope_A_B
                                the same where the true surface's slope is A <= slope < B
                                degrees (classes 0 20 45 91: floors and benches, faces and the
                                ramp, steep walls); mesh_common_mean_abs_m_slope_A_B and
                                mesh_common_bias_m_slope_A_B on the common surface.
  mesh_completeness_depth_A_B   mesh_completeness where the true water depth (below the water
                                line, z = 0 of the truth) is A <= depth < B metres (classes 0 1
                                2 4 8 12 inf: the shore near the water line is seen at the
                                shortest ranges).
  dem_mean_abs_m, dem_rms_m, dem_p95_m, dem_bias_m
                                vertical difference of the filled nodes of P/dem.tif (band 1,
                                UTM; heights in a vertical datum other than the ellipsoid are
                                put back on it with summary.json vertical_datum
                                mean_datum_height_m, exact for the GNSS water level, within
                                millimetres for a geoid over a pit) from the true terrain;
                                dem_mean_abs_insonified_m over the insonified nodes only.
  dem_fill_insonified           share of the nodes on insonified truth cells that are filled.
  mosaic_correlation, mosaic_rms_db, mosaic_patch_mean_abs_db, mosaic_patch_max_abs_db,
  mosaic_level_max_abs_db, mosaic_offset_db, mosaic_nodes, mosaic_patches
                                P/mosaic.tif band "backscatter" against truth/backscatter.f32:
                                Pearson correlation over the nodes whose footprint lies on one
                                truth value; after removing offset_db = median(mosaic - truth)
                                (the sonar's gain is unknown), the RMS error, the mean and
                                largest |mean error| per patch (truth square, >= 20 nodes), the
                                largest |mean error| per truth level. mosaic_uncorrected_*: the
                                same for band "uncorrected" (20 log10 intensity, no correction).
  tpu_within_tvu, tpu_within_thu
                                share of the soundings of P/soundings_tpu.ply whose vertical
                                (horizontal) error from the true beam-axis point (the same beam
                                from the true sonar pose, cast into the true terrain) is within
                                their 95 % TVU (THU); tpu_within_tvu_NN_MM_deg per |beam angle|
                                bin; tpu_truth_rays: curved when truth/scenario.json's water
                                column refracts (the true beam is cast along the curved ray).
  tpu_classes, tpu_within_tvu_{angle,depth,slope}_A_B
                                the same per class (issue 36): |beam angle| 0 20 40 60 90 deg,
                                true water depth at the true point 0 5 10 20 inf m, true slope
                                there 0 20 45 91 deg (floors, faces, walls).
  dem_within_uncertainty, dem_within_uncertainty_{slope,depth}_A_B, dem_uncertainty_classes
                                share of the filled nodes of P/dem.tif whose vertical error from
                                the true terrain is within their stated 95 % uncertainty (band
                                "uncertainty"), all and by the true slope and depth at the node.
  artifact_soundings, artifact_beams_KIND, good_soundings
                                with truth/artifacts.* (pitmap-sim synth): the beams whose
                                range an echo artifact replaced (KIND mid_water, bubble,
                                multipath, smile; dropout: no detection; outlier: the
                                uncorrelated coarse outliers) and the other beams with a
                                detection.
  artifact_in_points[_KIND], artifact_rejected_share[_KIND]
                                those accepted in P/points.ply (status 0; a rejected point is
                                not "in points"), each point matched to its (ping,
                                beam) by its beam and gps_time_s (ping k at truth
                                first_ping_gps_s + k / ping_rate_hz, within a quarter period;
                                points_unmatched: the others), and the share not found.
  good_in_points, good_rejected_share, good_rejected_share_slope_A_B
                                the good soundings accepted in P/points.ply and the share not
                                accepted, also by the true slope (classes 0 20 45 91);
                                points_rms_m_good: points_rms_m over the good points only.
Products are in a local ENU frame whose origin is P/summary.json "world_origin"
(latitude_deg, longitude_deg, height_m) or a PLY comment "pitmap_origin LAT LON H"; without
either, the truth's origin is assumed (and said).
  terrain_slope_mean_abs_deg, terrain_step_mean_abs_m, terrain_class_agreement,
  terrain_blocked_recall, terrain_blocked_false_share
                                P/terrain.tif and P/crawler.tif against the same layers computed
                                from the true heights at the DEM's nodes (tools/eval/
                                terrain_score.hpp): mean abs slope and step errors, the share of
                                nodes whose "can stand" is the truth's, the share of the truly
                                blocked nodes found, the share of the blocked ones that are not.
  change_<part>_volume_true_m3, _volume_detected_m3, _u95_m3, _volume_error_pct, _iou, _within
                                a compare folder (P/compare.json, P/dod.tif of pitmap compare A B
                                --out P) against the truth of B's epoch (pitmap-sim synth --epoch
                                2: truth/changes.json): per true part, the change regions of its
                                sign lying mostly on it, their volume and U95 summed, the error
                                against the exact volume, the IoU of their nodes with the part's,
                                within = |error| <= max(5 %, U95). change_parts_within,
                                change_u95_containment (share of parts with |error| <= U95),
                                change_iou_min, change_volume_error_max_abs_pct,
                                change_stable_flagged_share (region nodes more than 0.5 m from
                                every part, over the compared nodes that far), change_false_regions,
                                change_stable_rms_m, registration_rms_vertical_after_m (the
                                stable nodes both surveys sounded 5 times or more: decision
                                029), registration_rms_normal_after_m (along the normal, the
                                same nodes), registration_rms_vertical_floor_after_m (slope <
                                45 deg, decision 023), registration_rms_vertical_all_nodes_after_m
                                (every stable node, the sparse ones too).
  change3d_scar_detected_share, change3d_scar_median_distance_m, change3d_stable_flagged_share,
  change3d_wall_stable_flagged_share
                                with P/change_points.ply (pitmap compare's 3D change along the
                                normal): the share of the core points on the slump's scar
                                (profile > 0.3) flagged as loss and their median distance; the
                                share of the cores more than 0.5 m from every part flagged (all,
                                and those on walls >= 45 deg).
  change3d_region_<part>_volume_detected_m3, _u95_m3, _volume_error_pct, _iou, _within,
  _iou_detectable, _truth_below_lod_share,
  change3d_region_parts_within, change3d_region_stable_flagged_share,
  change3d_region_false_regions
                                with P/change_mesh.ply and compare.json change_mesh.regions:
                                the change mesh's regions (on the surface, walls included)
                                scored as the change_* scores above, with B's mesh vertices for
                                the nodes; _iou_detectable against the part's vertices
                                whose true change along the normal reaches their lod95_m
                                (the taper below it on neither side), the issue's IoU bound's
                                measure (decision 023).
  capacity_b_volume_error_pct   compare.json's volume of water at B's water level against the
                                true terrain's under B's surveyed nodes (true surface z = 0).
)";

std::optional<Geodetic> ProductOrigin(const fs::path& products,
                                      const std::vector<std::string>& ply_comments) {
    std::ifstream in(products / "summary.json");
    if (in) {
        const json j = json::parse(in, nullptr, false);
        if (!j.is_discarded() && j.contains("world_origin")) {
            const json& o = j["world_origin"];
            return Geodetic{o.value("latitude_deg", 0.0),
                            o.value("longitude_deg", 0.0),
                            o.value("height_m", 0.0)};
        }
    }
    return formats::ply::OriginFromComments(ply_comments);
}

// A mesh sampled at its vertices and triangle centroids.
std::vector<Eigen::Vector3d> MeshSamples(const formats::ply::Mesh& mesh) {
    std::vector<Eigen::Vector3d> samples = mesh.vertices;
    for (const auto& t : mesh.triangles) {
        samples.push_back((mesh.vertices[static_cast<std::size_t>(t[0])] +
                           mesh.vertices[static_cast<std::size_t>(t[1])] +
                           mesh.vertices[static_cast<std::size_t>(t[2])]) /
                          3.0);
    }
    return samples;
}

#ifdef PITMAP_EVAL_GRID
// The datum's mean ellipsoidal height (summary.json vertical_datum), 0 for ellipsoidal heights.
double DatumHeight(const fs::path& products) {
    std::ifstream in(products / "summary.json");
    if (!in) return 0.0;
    const json j = json::parse(in, nullptr, false);
    if (j.is_discarded() || !j.contains("vertical_datum") || !j["vertical_datum"].is_object()) {
        return 0.0;
    }
    const json& v = j["vertical_datum"];
    if (v.value("datum", std::string("ellipsoid")) == "ellipsoid") return 0.0;
    const json& h = v.value("mean_datum_height_m", json());
    return h.is_number() ? h.get<double>() : 0.0;
}
#endif  // PITMAP_EVAL_GRID

// ---- the command line ----

struct EvalOptions {
    std::string truth_dir;
    std::string products_dir;
    std::string json_path;        // empty: no JSON file
    std::string common_with;      // --mesh-common-with: another products folder
    double ate_window_s = 0;      // 0: no per-window ATE
    std::string soundings_csv;    // --soundings-csv: empty, none written
    std::string change_mesh_csv;  // --change-mesh-csv: empty, none written
};

// The command line into `options`; an exit code when the program stops here (help, a usage
// error, a folder that is not there: both must be there before anything is read or written).
std::optional<int> ParseOptions(int argc, char** argv, EvalOptions& options) {
    CLI::App app{"pitmap-eval: score survey products against simulator ground truth"};
    app.add_option(
           "--truth", options.truth_dir, "ground truth folder written by pitmap-sim (DIR/truth)")
        ->required();
    app.add_option("--products", options.products_dir, "products folder (pitmap ... --out P)")
        ->required();
    app.add_option("--json", options.json_path, "write the scores as one JSON object to this file");
    app.add_option("--mesh-common-with",
                   options.common_with,
                   "another products folder: also score P/mesh.ply where that folder's mesh.ply "
                   "lies within 0.2 m (mesh_mean_abs_m_common, mesh_common_share)");
    app.add_option("--ate-window",
                   options.ate_window_s,
                   "also score both trajectories per window of this many seconds "
                   "(trajectory_ate_windows, trajectory_ate_worst_window_increase_m)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--soundings-csv",
                   options.soundings_csv,
                   "with truth/artifacts.*: write every sounding of P/points.ply, accepted or "
                   "not, to this CSV with its truth: ping (the 83P ping number), beam, "
                   "gps_time_s, range_m, status, kind (none for a good sounding), the signed "
                   "distance to the true surface and its slope (where a cleaning's residuals "
                   "come from)");
    app.add_option("--change-mesh-csv",
                   options.change_mesh_csv,
                   "with a compare folder: write every vertex of P/change_mesh.ply to this CSV "
                   "with its truth: x, y (the truth's world frame), z (as in the mesh), the "
                   "normal, distance_m, lod95_m, significance, region, true_dz (B's true height "
                   "change there, vertical), part (the index in changes.json of the part whose "
                   "profile is largest there, -1 on none) and true_height_b_m (B's true terrain "
                   "height, world z): where a change region's volume comes from");
    app.footer(kDefinitions);
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap-eval")) return code;
    for (const std::string& dir : {options.truth_dir, options.products_dir}) {
        if (!fs::is_directory(dir)) {
            std::fprintf(stderr, "pitmap-eval: %s: not a folder\n", dir.c_str());
            return codes::kUsage;
        }
    }
    return std::nullopt;
}

// ---- the products read before scoring ----

// P/points.ply's accepted soundings, read once with the properties that are there: the ping
// times where the truth of the echo artifacts needs them to match the points, the status to
// keep the accepted soundings (issue 35).
struct PointCloud {
    formats::ply::Mesh cloud;  // vertex_properties[0]: gps_time_s when has_times
    bool present = false;      // P/points.ply exists
    bool has_times = false;
    bool has_status = false;
    std::size_t rejected = 0;  // soundings dropped for their status
};

Expected<PointCloud> ReadPointCloud(const fs::path& products, const sim::Truth& truth) {
    PointCloud points;
    if (!fs::exists(products / "points.ply")) return points;
    const std::string path = (products / "points.ply").string();
    auto names = eval::PlyVertexProperties(path);
    if (!names) return names.error();
    const auto has = [&](const char* n) {
        return std::find(names->begin(), names->end(), n) != names->end();
    };
    std::vector<std::string> props;
    points.has_times = truth.artifacts && has("gps_time_s");
    if (points.has_times) props.push_back("gps_time_s");  // vertex_properties[0]
    points.has_status = has("status");
    if (points.has_status) props.push_back("status");
    auto ply = formats::ply::ReadMesh(path, props);
    if (!ply) return ply.error();
    points.cloud = std::move(*ply);
    if (points.has_status) points.rejected = eval::KeepAccepted(points.cloud, props.size() - 1);
    points.present = true;
    return points;
}

// The products' local frame into the truth's, from their origin (summary.json or a PLY comment);
// without one the truth's origin is assumed, and said.
Pose ProductToTruth(const fs::path& products,
                    const std::vector<std::string>& ply_comments,
                    const sim::Truth& truth) {
    auto origin = ProductOrigin(products, ply_comments);
    if (!origin) {
        std::fprintf(stderr,
                     "pitmap-eval: no world origin in the products; assuming the truth's origin\n");
        origin = truth.origin;
    }
    return eval::ProductToTruthFrame(*origin, truth.origin);
}

// What every product family is scored with.
struct Scoring {
    const EvalOptions& options;
    const sim::Truth& truth;
    const sim::PitWorld& world;  // the true terrain
    const fs::path products;
    const PointCloud& points;
    const Pose T_truth_product;
};

// ---- trajectories ----

// The two trajectories' poses, kept for the per-window scores.
struct TrajectoryPoses {
    const char* final_file = "trajectory.csv";
    std::vector<eval::ProductPose> after;   // the final trajectory
    std::vector<eval::ProductPose> before;  // trajectory_initial.csv
};

// RMS position error of the final trajectory and of the initial one at the true trajectory's
// times.
Status ScoreAte(const Scoring& scoring, TrajectoryPoses& poses, json& scores) {
    const fs::path& P = scoring.products;
    // Without SLAM (georef only, or `run --no-slam`) the INS-rate trajectory is the final one.
    poses.final_file = fs::exists(P / "trajectory.csv") || !fs::exists(P / "trajectory_ins.csv")
                           ? "trajectory.csv"
                           : "trajectory_ins.csv";
    for (const auto& [file, key] :
         {std::pair{poses.final_file, "trajectory_ate_rmse_m"},
          std::pair{"trajectory_initial.csv", "trajectory_ate_rmse_before_m"}}) {
        if (!fs::exists(P / file)) continue;
        auto traj = formats::ReadTrajectoryCsv((P / file).string());
        if (!traj) return traj.error();
        const bool is_final = std::string(key) == "trajectory_ate_rmse_m";
        const std::vector<eval::ProductPose> product_poses = eval::ProductPoses(*traj);
        (is_final ? poses.after : poses.before) = product_poses;
        const auto score =
            eval::ScoreTrajectory(product_poses, scoring.T_truth_product, scoring.truth.trajectory);
        if (score.poses == 0) {
            std::fprintf(
                stderr, "pitmap-eval: %s: no pose inside the true trajectory's time span\n", file);
            continue;
        }
        scores[key] = score.ate_rmse_m;
        if (is_final) {
            scores["trajectory_ate_max_m"] = score.ate_max_m;
            scores["trajectory_z_std_m"] = score.z_std_m;
        }
    }
    return Ok{};
}

// P/trajectory_sigma.csv: how often the true error lies within the stated 95 % radius.
Status ScoreStatedUncertainty(const Scoring& scoring, json& scores) {
    if (!fs::exists(scoring.products / "trajectory_sigma.csv")) return Ok{};
    auto stated =
        eval::ReadTrajectorySigmaCsv((scoring.products / "trajectory_sigma.csv").string());
    if (!stated) return stated.error();
    constexpr double kOutageSigmaM = 0.5;  // slam coarse_search_min_sigma_m's default
    const eval::UncertaintyScore u = eval::ScoreUncertainty(
        *stated, scoring.T_truth_product, scoring.truth.trajectory, kOutageSigmaM);
    const auto as_json = [](const eval::ContainmentScore& c) {
        return json{{"poses", c.poses},
                    {"share_within_h95", c.share_within_h95},
                    {"share_within_v95", c.share_within_v95},
                    {"median_error_h_m", c.median_error_h_m},
                    {"median_radius_h95_m", c.median_radius_h95_m}};
    };
    if (u.after_all.poses > 0) {
        scores["trajectory_uncertainty"] = {
            {"outage_sigma_m", kOutageSigmaM},
            {"after", {{"all", as_json(u.after_all)}, {"outage", as_json(u.after_outage)}}},
            {"before", {{"all", as_json(u.before_all)}, {"outage", as_json(u.before_outage)}}}};
    }
    return Ok{};
}

// Both trajectories' RMS error per window of --ate-window seconds; the worst increase is what
// "SLAM never made a segment worse" is judged by.
void ScoreAteWindows(const Scoring& scoring, const TrajectoryPoses& poses, json& scores) {
    json windows = json::array();
    double worst = -std::numeric_limits<double>::infinity();
    for (const eval::AteWindow& w : eval::ScoreTrajectoryWindows(poses.after,
                                                                 poses.before,
                                                                 scoring.T_truth_product,
                                                                 scoring.truth.trajectory,
                                                                 scoring.options.ate_window_s)) {
        windows.push_back({{"t0_s", w.t0_s},
                           {"t1_s", w.t1_s},
                           {"poses", w.poses},
                           {"before_m", w.before_m},
                           {"after_m", w.after_m}});
        worst = std::max(worst, w.after_m - w.before_m);
    }
    if (!windows.empty()) {
        scores["trajectory_ate_windows"] = windows;
        scores["trajectory_ate_worst_window_increase_m"] = worst;
    } else {
        std::fprintf(stderr,
                     "pitmap-eval: --ate-window: no window holds poses of both %s and "
                     "trajectory_initial.csv inside the true trajectory's span; no per-window "
                     "score\n",
                     poses.final_file);
    }
}

// The trajectory family: the ATE of both trajectories, the stated uncertainty, the ATE per
// window.
Status ScoreTrajectories(const Scoring& scoring, json& scores) {
    TrajectoryPoses poses;
    if (auto scored = ScoreAte(scoring, poses, scores); !scored) return scored;
    if (auto scored = ScoreStatedUncertainty(scoring, scores); !scored) return scored;
    if (scoring.options.ate_window_s > 0) ScoreAteWindows(scoring, poses, scores);
    return Ok{};
}

// ---- points ----

// points_rms_m by beam angle, where the points carry their beam number and the truth its fan
// (truth/scenario.json's sonar start angle and increment).
void ScorePointsByBeamAngle(const Scoring& scoring, json& scores) {
    const formats::ply::Mesh& cloud = scoring.points.cloud;
    std::ifstream sin(fs::path(scoring.options.truth_dir) / "scenario.json");
    const json sc = sin ? json::parse(sin, nullptr, false) : json();
    if (!(cloud.vertex_beam.size() == cloud.vertices.size() && sc.is_object() &&
          sc.contains("sonar") && sc["sonar"].is_object() &&
          sc["sonar"].value("angle_increment_deg", json()).is_number() &&
          sc["sonar"].value("start_angle_deg", json()).is_number())) {
        return;
    }
    const double start = sc["sonar"]["start_angle_deg"].get<double>();
    const double inc = sc["sonar"]["angle_increment_deg"].get<double>();
    const double edges[] = {0, 15, 30, 45, 55, 90.01};
    for (int b = 0; b + 1 < 6; ++b) {
        std::vector<Eigen::Vector3d> sel;
        for (std::size_t i = 0; i < cloud.vertices.size(); ++i) {
            const double a = std::abs(start + cloud.vertex_beam[i] * inc);
            if (cloud.vertex_beam[i] >= 0 && a >= edges[b] && a < edges[b + 1])
                sel.push_back(cloud.vertices[i]);
        }
        if (sel.empty()) continue;
        const auto sb = eval::ScorePoints(sel, scoring.T_truth_product, scoring.world);
        char key[64];
        std::snprintf(key,
                      sizeof key,
                      "points_rms_m_angle_%.0f_%.0f",
                      edges[b],
                      b == 4 ? 90.0 : edges[b + 1]);
        scores[key] = sb.rms_m;
    }
}

// P/points.ply's accepted soundings against the true surface.
Status ScorePointsPly(const Scoring& scoring, json& scores) {
    if (!scoring.points.present) return Ok{};
    const formats::ply::Mesh& cloud = scoring.points.cloud;
    const auto score = eval::ScorePoints(cloud.vertices, scoring.T_truth_product, scoring.world);
    scores["points_rms_m"] = score.rms_m;
    scores["points_p95_m"] = score.p95_m;
    scores["points_bias_m"] = score.bias_m;
    scores["points_scored"] = score.count;
    scores["points_accepted"] = cloud.vertices.size();
    if (scoring.points.has_status) scores["points_rejected"] = scoring.points.rejected;
    ScorePointsByBeamAngle(scoring, scores);
    return Ok{};
}

// ---- echo artifacts ----

// What the truth holds: the beams each kind of artifact replaced, and the good soundings.
void PutArtifactTruthCounts(const sim::ArtifactTruth& artifacts, json& scores) {
    scores["artifact_soundings"] = artifacts.artifact_soundings();
    for (int k = 1; k < sim::kNumEchoArtifactKinds; ++k) {
        scores[std::string("artifact_beams_") +
               sim::EchoArtifactName(static_cast<sim::EchoArtifactKind>(k))] =
            artifacts.beams_by_kind[k];
    }
    scores["good_soundings"] = artifacts.good_soundings;
}

// The artifact and good soundings found among the accepted points (matched by ping time and
// beam), and the shares not accepted.
void ScoreArtifactMatches(const Scoring& scoring,
                          const sim::ArtifactTruth& artifacts,
                          json& scores) {
    const formats::ply::Mesh& cloud = scoring.points.cloud;
    const auto total = [&](sim::EchoArtifactKind k) {
        return artifacts.beams_by_kind[static_cast<int>(k)];
    };
    std::vector<Eigen::Vector3d> pts(cloud.vertices.size());
    for (std::size_t i = 0; i < pts.size(); ++i)
        pts[i] = scoring.T_truth_product * cloud.vertices[i];
    const auto found = eval::ScoreArtifacts(
        pts, cloud.vertex_properties[0], cloud.vertex_beam, artifacts, scoring.world);
    std::int64_t artifacts_in = 0;
    for (const auto k : {sim::EchoArtifactKind::kMidWater,
                         sim::EchoArtifactKind::kBubble,
                         sim::EchoArtifactKind::kMultipath,
                         sim::EchoArtifactKind::kSmile,
                         sim::EchoArtifactKind::kOutlier}) {
        const std::string name = sim::EchoArtifactName(k);
        const std::int64_t in = found.in_points[static_cast<int>(k)];
        if (k != sim::EchoArtifactKind::kOutlier) artifacts_in += in;
        scores["artifact_in_points_" + name] = in;
        if (total(k) > 0) {
            scores["artifact_rejected_share_" + name] =
                1.0 - static_cast<double>(in) / static_cast<double>(total(k));
        }
    }
    scores["artifact_in_points"] = artifacts_in;
    if (artifacts.artifact_soundings() > 0) {
        scores["artifact_rejected_share"] =
            1.0 -
            static_cast<double>(artifacts_in) / static_cast<double>(artifacts.artifact_soundings());
    }
    scores["points_unmatched"] = found.unmatched;
    scores["good_in_points"] = found.good_in_points;
    if (artifacts.good_soundings > 0) {
        scores["good_rejected_share"] = 1.0 - static_cast<double>(found.good_in_points) /
                                                  static_cast<double>(artifacts.good_soundings);
    }
    for (int c = 0; c < sim::kNumArtifactSlopeClasses; ++c) {
        if (artifacts.good_by_slope[c] == 0) continue;
        char key[64];
        std::snprintf(key,
                      sizeof key,
                      "good_rejected_share_slope_%.0f_%.0f",
                      sim::kArtifactSlopeEdgesDeg[c],
                      sim::kArtifactSlopeEdgesDeg[c + 1]);
        scores[key] = 1.0 - static_cast<double>(found.good_in_points_by_slope[c]) /
                                static_cast<double>(artifacts.good_by_slope[c]);
    }
    if (found.good.count > 0) scores["points_rms_m_good"] = found.good.rms_m;
}

// With truth/artifacts.*: the echo artifacts pitmap-sim put in, and how many points.ply kept.
Status ScoreArtifactsInPoints(const Scoring& scoring, json& scores) {
    if (!scoring.points.present || !scoring.truth.artifacts) return Ok{};
    PutArtifactTruthCounts(*scoring.truth.artifacts, scores);
    if (!scoring.points.has_times ||
        scoring.points.cloud.vertex_beam.size() != scoring.points.cloud.vertices.size()) {
        std::fprintf(stderr,
                     "pitmap-eval: %s/points.ply has no gps_time_s or beam: the artifact "
                     "soundings are not scored\n",
                     scoring.options.products_dir.c_str());
        return Ok{};
    }
    ScoreArtifactMatches(scoring, *scoring.truth.artifacts, scores);
    return Ok{};
}

// --soundings-csv: every sounding of P/points.ply (accepted or rejected) with its truth, one a
// line, for finding which soundings a product's error comes from.
Status WriteSoundingsCsv(const Scoring& scoring) {
    const fs::path ply_path = scoring.products / "points.ply";
    if (!scoring.truth.artifacts) {
        return Error{"--soundings-csv: " + scoring.options.truth_dir +
                     " holds no artifacts truth (truth/artifacts.bin)"};
    }
    auto ply = formats::ply::ReadMesh(ply_path.string(), {"gps_time_s", "range_m", "status"});
    if (!ply) return Error{"--soundings-csv: " + ply.error().message};
    if (ply->vertex_beam.size() != ply->vertices.size()) {
        return Error{"--soundings-csv: " + ply_path.string() + " has no beam property"};
    }
    std::ofstream out(scoring.options.soundings_csv);
    out << "ping,beam,gps_time_s,range_m,status,kind,distance_m,slope_deg,x,y,z\n";
    const sim::ArtifactTruth& truth = *scoring.truth.artifacts;
    for (std::size_t i = 0; i < ply->vertices.size(); ++i) {
        const double t = ply->vertex_properties[0][i];
        const double k_real = (t - truth.first_ping_gps_s) * truth.ping_rate_hz;
        const double k = std::round(k_real);
        const bool matched = std::abs(k_real - k) <= 0.25 && k >= 0 && ply->vertex_beam[i] >= 0;
        const auto kind = matched ? truth.KindOf(static_cast<std::int64_t>(k), ply->vertex_beam[i])
                                  : sim::EchoArtifactKind::kNone;
        const Eigen::Vector3d p = scoring.T_truth_product * ply->vertices[i];
        char line[256];
        std::snprintf(line,
                      sizeof line,
                      "%lld,%d,%.4f,%.3f,%d,%s,%.4f,%.1f,%.3f,%.3f,%.3f\n",
                      matched ? static_cast<long long>(k) : -1LL,
                      ply->vertex_beam[i],
                      t,
                      ply->vertex_properties[1][i],
                      static_cast<int>(ply->vertex_properties[2][i]),
                      matched ? sim::EchoArtifactName(kind) : "unmatched",
                      scoring.world.SignedDistance(p),
                      eval::SlopeDeg(scoring.world, p.x(), p.y()),
                      p.x(),
                      p.y(),
                      p.z());
        out << line;
    }
    if (!out) return Error{"--soundings-csv: " + scoring.options.soundings_csv + ": cannot write"};
    return Ok{};
}

// --change-mesh-csv: every vertex of a compare folder's change mesh with its truth, one a line,
// for finding where a change region's volume comes from. to_world: A's CRS to the truth's
// world frame (x, y).
template <typename ToWorld>
Status WriteChangeMeshCsv(const Scoring& scoring,
                          const fs::path& ply_path,
                          const ToWorld& to_world) {
    auto cm = formats::ply::ReadMesh(
        ply_path.string(), {"nx", "ny", "nz", "distance_m", "lod95_m", "significance", "region"});
    if (!cm) return Error{"--change-mesh-csv: " + cm.error().message};
    std::ofstream out(scoring.options.change_mesh_csv);
    out << "x,y,z,nx,ny,nz,distance_m,lod95_m,significance,region,true_dz,part,"
           "true_height_b_m\n";
    const auto& parts = scoring.truth.changes;
    const auto& vp = cm->vertex_properties;
    for (std::size_t i = 0; i < cm->vertices.size(); ++i) {
        const auto w = to_world(cm->vertices[i].x(), cm->vertices[i].y());
        if (!w) continue;
        double dz = 0, best = 0;
        int part = -1;
        for (std::size_t p = 0; p < parts.size(); ++p) {
            const double f = parts[p].Profile(w->x(), w->y());
            dz += parts[p].thickness_m * f;
            if (f > best) {
                best = f;
                part = static_cast<int>(p);
            }
        }
        char line[320];
        std::snprintf(line,
                      sizeof line,
                      "%.3f,%.3f,%.3f,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%d,%.4f,%d,%.4f\n",
                      w->x(),
                      w->y(),
                      cm->vertices[i].z(),
                      vp[0][i],
                      vp[1][i],
                      vp[2][i],
                      vp[3][i],
                      vp[4][i],
                      static_cast<int>(vp[5][i]),
                      static_cast<int>(vp[6][i]),
                      dz,
                      part,
                      scoring.world.Height(w->x(), w->y()));
        out << line;
    }
    if (!out) {
        return Error{"--change-mesh-csv: " + scoring.options.change_mesh_csv + ": cannot write"};
    }
    return Ok{};
}

// ---- boresight ----

Status ScoreBoresightJson(const Scoring& scoring, json& scores) {
    if (!fs::exists(scoring.products / "boresight.json")) return Ok{};
    std::ifstream in(scoring.products / "boresight.json");
    const json b = json::parse(in, nullptr, false);
    if (b.is_discarded() || !b.contains("roll_deg") || !b.contains("pitch_deg") ||
        !b.contains("yaw_deg")) {
        return Error{scoring.options.products_dir +
                     "/boresight.json: needs roll_deg, pitch_deg, yaw_deg"};
    }
    const sim::TruthBoresight& truth = scoring.truth.boresight;
    scores["boresight_error_deg"] = eval::BoresightErrorDeg(b["roll_deg"].get<double>(),
                                                            b["pitch_deg"].get<double>(),
                                                            b["yaw_deg"].get<double>(),
                                                            truth.roll_deg,
                                                            truth.pitch_deg,
                                                            truth.yaw_deg);
    return Ok{};
}

// ---- mesh ----

// "_slope_A_B" for slope class c.
std::string SlopeSuffix(std::size_t c) {
    const auto& edges = eval::kSlopeClassEdgesDeg;
    return "_slope_" + std::to_string(static_cast<int>(edges[c])) + "_" +
           std::to_string(static_cast<int>(edges[c + 1]));
}

// Mean absolute and signed distance of the samples (truth frame) by the true slope under each:
// floors, faces, walls; positive where the mesh lies outside the rock.
void ScoreBySlope(const sim::PitWorld& world,
                  const std::vector<Eigen::Vector3d>& samples,
                  const std::string& prefix,
                  json& scores) {
    const auto& edges = eval::kSlopeClassEdgesDeg;
    const std::size_t n_classes = std::size(edges) - 1;
    std::vector<std::vector<double>> by_class(n_classes);
    for (const auto& p : samples) {
        const double slope = eval::SlopeDeg(world, p.x(), p.y());
        for (std::size_t c = 0; c < n_classes; ++c) {
            if (slope >= edges[c] && slope < edges[c + 1]) {
                by_class[c].push_back(world.SignedDistance(p));
                break;
            }
        }
    }
    for (std::size_t c = 0; c < n_classes; ++c) {
        if (by_class[c].empty()) continue;
        const auto sc = eval::SummariseDistances(std::move(by_class[c]));
        scores[prefix + "mean_abs_m" + SlopeSuffix(c)] = sc.mean_abs_m;
        scores[prefix + "bias_m" + SlopeSuffix(c)] = sc.bias_m;
    }
}

// The share of the insonified true surface the mesh holds, by the true slope and by the true
// water depth (the shore near the water line is seen at short range).
void ScoreMeshCompletenessByClass(const sim::Truth& truth,
                                  const std::vector<Eigen::Vector3d>& samples,
                                  json& scores) {
    const auto& edges = eval::kSlopeClassEdgesDeg;
    for (std::size_t c = 0; c + 1 < std::size(edges); ++c) {
        if (auto cc = eval::MeshCompleteness(samples, truth, 0.2, edges[c], edges[c + 1]))
            scores["mesh_completeness" + SlopeSuffix(c)] = *cc;
    }
    const auto& depths = eval::kDepthClassEdgesM;
    for (std::size_t c = 0; c + 1 < std::size(depths); ++c) {
        const std::string hi = std::isfinite(depths[c + 1])
                                   ? std::to_string(static_cast<int>(depths[c + 1]))
                                   : std::string("inf");
        const std::string key =
            "mesh_completeness_depth_" + std::to_string(static_cast<int>(depths[c])) + "_" + hi;
        if (auto cd = eval::MeshCompleteness(samples, truth, 0.2, 0, 91, depths[c], depths[c + 1]))
            scores[key] = *cd;
    }
}

// Error on the part of the surface both meshes hold (--mesh-common-with): a mesh that keeps
// only what was seen often is not more accurate for having dropped the rest.
Status ScoreMeshOnCommonSurface(const Scoring& scoring,
                                const std::vector<Eigen::Vector3d>& samples,
                                json& scores) {
    const fs::path Q(scoring.options.common_with);
    auto other = formats::ply::ReadMesh((Q / "mesh.ply").string());
    if (!other) return other.error();
    const auto other_origin = ProductOrigin(Q, other->comments);
    const Pose T_truth_other = eval::ProductToTruthFrame(
        other_origin ? *other_origin : scoring.truth.origin, scoring.truth.origin);
    std::vector<Eigen::Vector3d> theirs = MeshSamples(*other);
    for (auto& p : theirs) p = T_truth_other * p;
    std::vector<Eigen::Vector3d> common = eval::SamplesInSharedCells(samples, theirs, 0.2);
    scores["mesh_common_share"] =
        samples.empty() ? 0.0
                        : static_cast<double>(common.size()) / static_cast<double>(samples.size());
    std::vector<double> d;
    d.reserve(common.size());
    for (const auto& p : common) d.push_back(scoring.world.SignedDistance(p));
    if (!d.empty()) {
        const auto sc = eval::SummariseDistances(std::move(d));
        scores["mesh_mean_abs_m_common"] = sc.mean_abs_m;
        scores["mesh_bias_m_common"] = sc.bias_m;
    }
    ScoreBySlope(scoring.world, common, "mesh_common_", scores);
    return Ok{};
}

// P/mesh.ply's vertices and triangle centroids against the true surface.
Status ScoreMeshPly(const Scoring& scoring, json& scores) {
    if (!fs::exists(scoring.products / "mesh.ply")) return Ok{};
    auto mesh = formats::ply::ReadMesh((scoring.products / "mesh.ply").string());
    if (!mesh) return mesh.error();
    std::vector<Eigen::Vector3d> samples = MeshSamples(*mesh);
    const auto score = eval::ScorePoints(samples, scoring.T_truth_product, scoring.world);
    for (auto& p : samples) p = scoring.T_truth_product * p;
    if (auto c = eval::MeshCompleteness(samples, scoring.truth)) scores["mesh_completeness"] = *c;
    scores["mesh_mean_abs_m"] = score.mean_abs_m;
    scores["mesh_rms_m"] = score.rms_m;
    scores["mesh_p95_m"] = score.p95_m;
    scores["mesh_bias_m"] = score.bias_m;
    // Issue 35's damage figure: the share of the mesh samples more than 1 m off.
    std::size_t far = 0;
    for (const auto& p : samples) far += std::abs(scoring.world.SignedDistance(p)) > 1.0;
    scores["mesh_share_beyond_1m"] =
        samples.empty() ? 0.0 : static_cast<double>(far) / static_cast<double>(samples.size());
    ScoreBySlope(scoring.world, samples, "mesh_", scores);
    ScoreMeshCompletenessByClass(scoring.truth, samples, scores);
    if (!scoring.options.common_with.empty())
        return ScoreMeshOnCommonSurface(scoring, samples, scores);
    return Ok{};
}

// ---- grids ----
// A class's key: KIND_LO_HI ("slope_20_45"), KIND_LO_inf for the open last class.
std::string ClassKey(const char* kind, double lo, double hi) {
    char key[64];
    if (std::isinf(hi)) {
        std::snprintf(key, sizeof key, "%s_%02.0f_inf", kind, lo);
    } else {
        std::snprintf(key, sizeof key, "%s_%02.0f_%02.0f", kind, lo, hi);
    }
    return key;
}

#ifdef PITMAP_EVAL_GRID

bool IsWgs84Utm(int epsg) {
    return (epsg > 32600 && epsg <= 32660) || (epsg > 32700 && epsg <= 32760);
}

// Node (i, j) of a grid in WGS 84 / UTM (EPSG `epsg`) at `height_m`.
UtmCoordinate GridNodeUtm(const proc::io::GridRaster& g, int epsg, int i, int j, double height_m) {
    UtmCoordinate u;
    u.zone = epsg % 100;
    u.northern = epsg < 32700;
    u.easting_m = g.x0 + i * g.resolution_m;
    u.northing_m = g.y0 + j * g.resolution_m;
    u.height_m = height_m;
    return u;
}

// The DEM nodes whose error from the true terrain is within their stated 95 % uncertainty, all
// and by the true slope and depth at the node (dem_within_uncertainty*).
void ScoreDemUncertainty(const Scoring& scoring,
                         const std::vector<Eigen::Vector3d>& nodes,
                         const std::vector<std::size_t>& node_index,
                         const std::vector<float>& uncertainty,
                         json& scores) {
    std::vector<double> unc(nodes.size(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t k = 0; k < unc.size() && k < node_index.size(); ++k) {
        unc[k] = uncertainty[node_index[k]];
    }
    const eval::DemUncertaintyScore u = eval::ScoreDemUncertainty(nodes, unc, scoring.truth);
    if (u.all.count == 0) return;
    scores["dem_within_uncertainty"] = u.all.within;
    scores["dem_uncertainty_nodes"] = u.all.count;
    json classes = json::object();
    const auto put = [&](const char* kind, const std::vector<eval::DemUncertaintyBin>& bins) {
        for (const auto& c : bins) {
            if (c.count == 0) continue;
            const std::string key = ClassKey(kind, c.lo, c.hi);
            classes[key] = {{"count", c.count},
                            {"within", c.within},
                            {"error_rms_m", c.error_rms_m},
                            {"stated_sigma_rms_m", c.stated_rms_m}};
            scores["dem_within_uncertainty_" + key] = c.within;
        }
    };
    put("slope", u.by_slope);
    put("depth", u.by_depth);
    scores["dem_uncertainty_classes"] = classes;
}

// P/dem.tif's nodes (band 1, heights put back on the ellipsoid with summary.json's datum
// height) against the true terrain; unfilled nodes count towards the fill score.
Status ScoreDemTif(const Scoring& scoring, json& scores) {
    if (!fs::exists(scoring.products / "dem.tif")) return Ok{};
    auto dem = proc::io::ReadGrid((scoring.products / "dem.tif").string());
    if (!dem) return dem.error();
    const int epsg = dem->horizontal_epsg;
    if (!IsWgs84Utm(epsg) || dem->grid.layers.empty()) {
        return Error{scoring.options.products_dir + "/dem.tif: not a WGS 84 / UTM grid (EPSG " +
                     std::to_string(epsg) + ")"};
    }
    const proc::io::GridRaster& g = dem->grid;
    const double datum_height_m = DatumHeight(scoring.products);
    const LocalTangentFrame tf(scoring.truth.origin);
    std::vector<Eigen::Vector3d> nodes;
    std::vector<std::size_t> node_index;  // of each node in the grid's layers
    nodes.reserve(static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny));
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            const float h = g.layers[0].values[static_cast<std::size_t>(j) * g.nx + i];
            auto geo = GeodeticFromUtm(
                GridNodeUtm(g, epsg, i, j, std::isfinite(h) ? h + datum_height_m : 0.0));
            if (!geo) continue;
            Eigen::Vector3d p = tf.ToEnu(*geo);
            if (!std::isfinite(h)) p.z() = std::numeric_limits<double>::quiet_NaN();
            nodes.push_back(p);
            node_index.push_back(static_cast<std::size_t>(j) * g.nx + i);
        }
    }
    if (const std::vector<float>* unc = g.Values("uncertainty")) {
        ScoreDemUncertainty(scoring, nodes, node_index, *unc, scores);
    }
    const auto score = eval::ScoreDem(nodes, scoring.truth);
    scores["dem_mean_abs_m"] = score.all.mean_abs_m;
    scores["dem_rms_m"] = score.all.rms_m;
    scores["dem_p95_m"] = score.all.p95_m;
    scores["dem_bias_m"] = score.all.bias_m;
    scores["dem_nodes_scored"] = score.all.count;
    scores["dem_mean_abs_insonified_m"] = score.insonified.mean_abs_m;
    scores["dem_resolution_m"] = g.resolution_m;
    if (score.fill_insonified) scores["dem_fill_insonified"] = *score.fill_insonified;
    return Ok{};
}

// One mosaic band against truth/backscatter.f32: keys mosaic_* for "backscatter",
// mosaic_uncorrected_* for "uncorrected".
void ScoreMosaicLayer(const Scoring& scoring,
                      const proc::io::GridRaster& g,
                      int epsg,
                      const proc::io::GridLayer& layer,
                      json& scores) {
    const LocalTangentFrame tf(scoring.truth.origin);
    std::vector<Eigen::Vector3d> nodes;
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            const float v = layer.values[static_cast<std::size_t>(j) * g.nx + i];
            if (!std::isfinite(v)) continue;
            auto geo = GeodeticFromUtm(GridNodeUtm(g, epsg, i, j, scoring.truth.origin.height_m));
            if (!geo) continue;
            Eigen::Vector3d p = tf.ToEnu(*geo);
            p.z() = v;
            nodes.push_back(p);
        }
    }
    const auto sc = eval::ScoreMosaic(nodes, g.resolution_m, scoring.truth);
    if (!sc) return;
    const std::string k = layer.name == "backscatter" ? "mosaic_" : "mosaic_uncorrected_";
    scores[k + "nodes"] = sc->nodes;
    scores[k + "correlation"] = sc->correlation;
    scores[k + "offset_db"] = sc->offset_db;
    scores[k + "rms_db"] = sc->rms_db;
    scores[k + "patches"] = sc->patches;
    scores[k + "patch_mean_abs_db"] = sc->patch_mean_abs_db;
    scores[k + "patch_max_abs_db"] = sc->patch_max_abs_db;
    double level_max = 0;
    for (const auto& [level, err, n] : sc->by_level) {
        if (n >= 20) level_max = std::max(level_max, std::abs(err));
    }
    scores[k + "level_max_abs_db"] = level_max;
}

// P/mosaic.tif's bands "backscatter" and "uncorrected" against the true backscatter.
// A compare folder (pitmap compare A B --out P) against the truth of B's epoch: the change
// regions by true part, the stable terrain flagged, the 3D change on the scar and on stable
// ground, the capacity at B's water level.
Status ScoreCompareFolder(const Scoring& scoring, json& scores) {
    const fs::path& P = scoring.products;
    if (!fs::exists(P / "compare.json")) return Ok{};
    const sim::Truth* truth = &scoring.truth;
    const sim::PitWorld& world = scoring.world;
    const std::string& products_dir = scoring.options.products_dir;
    const std::string& truth_dir = scoring.options.truth_dir;
    {
        // A compare folder (pitmap compare A B --out P) against the truth of B's epoch.
        const json cj = json::parse(std::ifstream(P / "compare.json"), nullptr, false);
        auto dod = proc::io::ReadGrid((P / "dod.tif").string());
        if (cj.is_discarded() || !dod || dod->grid.layers.size() < 4) {
            return Error{products_dir + ": compare.json or dod.tif unreadable" +
                         (dod ? std::string() : ": " + dod.error().message)};
        }
        if (truth->changes.empty()) {
            return Error{truth_dir +
                         " has no changes.json: score a compare folder against the truth of a "
                         "repeat survey (pitmap-sim synth --epoch 2)"};
        }
        const int epsg = dod->horizontal_epsg;
        const proc::io::GridRaster& g = dod->grid;
        const LocalTangentFrame tf(truth->origin);
        const auto to_world = [&](double e, double n) -> std::optional<Eigen::Vector2d> {
            UtmCoordinate u;
            u.zone = epsg % 100;
            u.northern = epsg < 32700;
            u.easting_m = e;
            u.northing_m = n;
            auto geo = GeodeticFromUtm(u);
            if (!geo) return std::nullopt;
            return tf.ToEnu(*geo).head<2>();
        };
        std::vector<eval::DodNode> nodes;
        for (int j = 0; j < g.ny; ++j) {
            for (int i = 0; i < g.nx; ++i) {
                const std::size_t k = static_cast<std::size_t>(j) * g.nx + i;
                const float d = g.layers[0].values[k];
                if (!std::isfinite(d)) continue;
                auto w = to_world(g.x0 + i * g.resolution_m, g.y0 + j * g.resolution_m);
                if (!w) continue;
                const float reg = g.layers[3].values[k];
                nodes.push_back({*w, std::isfinite(reg) ? static_cast<int>(reg) : 0});
            }
        }
        std::vector<eval::RegionInfo> regions;
        for (const json& r : cj["change"]["regions"]) {
            regions.push_back({r.value("id", 0),
                               r.value("kind", std::string()) == "fill" ? 1 : -1,
                               r.value("volume_m3", 0.0),
                               r.value("u95_m3", 0.0)});
        }
        const auto cs = eval::ScoreChange(nodes, regions, truth->changes);
        int within = 0, contained = 0;
        double iou_min = 1.0, worst_pct = 0;
        for (const auto& ps : cs.parts) {
            const std::string k = "change_" + ps.name + "_";
            scores[k + "volume_true_m3"] = ps.volume_true_m3;
            scores[k + "volume_detected_m3"] = ps.volume_detected_m3;
            scores[k + "u95_m3"] = ps.u95_m3;
            scores[k + "volume_error_pct"] = ps.error_pct;
            scores[k + "iou"] = ps.iou;
            scores[k + "within"] = ps.within ? 1 : 0;
            within += ps.within;
            contained += ps.contained;
            iou_min = std::min(iou_min, ps.iou);
            worst_pct = std::max(worst_pct, std::abs(ps.error_pct));
        }
        const double n_parts = static_cast<double>(cs.parts.size());
        scores["change_parts"] = cs.parts.size();
        scores["change_parts_within"] = within;
        scores["change_u95_containment"] = n_parts > 0 ? contained / n_parts : 0.0;
        scores["change_iou_min"] = iou_min;
        scores["change_volume_error_max_abs_pct"] = worst_pct;
        scores["change_stable_flagged_share"] = cs.stable_flagged_share;
        scores["change_false_regions"] = cs.false_regions;
        const json& rj = cj["registration"];
        scores["registration_rms_vertical_after_m"] = rj.value("rms_vertical_after_m", 0.0);
        scores["registration_rms_normal_after_m"] = rj.value("rms_normal_after_m", 0.0);
        scores["registration_rms_vertical_floor_after_m"] =
            rj.value("rms_vertical_floor_after_m", 0.0);
        scores["registration_rms_vertical_all_nodes_after_m"] =
            rj.value("rms_vertical_all_nodes_after_m", 0.0);
        scores["change_stable_rms_m"] = cj["change"].value("stable_rms_m", 0.0);
        // The 3D change along the normal (change_points.ply): on the slump's scar (a wall) and
        // on stable terrain, walls apart.
        if (fs::exists(P / "change_points.ply")) {
            auto cp = formats::ply::ReadMesh((P / "change_points.ply").string(),
                                             {"distance_m", "significance", "slope_deg"});
            if (!cp) {
                return cp.error();
            }
            std::size_t scar = 0, scar_loss = 0, stable = 0, stable_flagged = 0, wall = 0,
                        wall_flagged = 0;
            std::vector<double> scar_distance;
            for (std::size_t i = 0; i < cp->vertices.size(); ++i) {
                if (!std::isfinite(cp->vertex_properties[0][i])) continue;
                auto w = to_world(cp->vertices[i].x(), cp->vertices[i].y());
                if (!w) continue;
                const int sig = static_cast<int>(cp->vertex_properties[1][i]);
                bool near = false;
                double scar_profile = 0;
                for (const auto& part : truth->changes) {
                    for (double dx : {-0.5, 0.0, 0.5}) {
                        for (double dy : {-0.5, 0.0, 0.5}) {
                            if (part.Profile(w->x() + dx, w->y() + dy) > 0) near = true;
                        }
                    }
                    if (part.name == "slump_scar") scar_profile = part.Profile(w->x(), w->y());
                }
                if (scar_profile > 0.3) {
                    ++scar;
                    scar_loss += sig < 0;
                    scar_distance.push_back(cp->vertex_properties[0][i]);
                }
                if (!near) {
                    ++stable;
                    stable_flagged += sig != 0;
                    if (cp->vertex_properties[2][i] >= 45) {
                        ++wall;
                        wall_flagged += sig != 0;
                    }
                }
            }
            const auto share = [](std::size_t a, std::size_t b) {
                return b > 0 ? static_cast<double>(a) / static_cast<double>(b) : 0.0;
            };
            scores["change3d_scar_cores"] = scar;
            scores["change3d_scar_detected_share"] = share(scar_loss, scar);
            if (!scar_distance.empty()) {
                std::sort(scar_distance.begin(), scar_distance.end());
                scores["change3d_scar_median_distance_m"] = scar_distance[scar_distance.size() / 2];
            }
            scores["change3d_stable_flagged_share"] = share(stable_flagged, stable);
            scores["change3d_wall_stable_flagged_share"] = share(wall_flagged, wall);
        }
        // The change mesh's regions (on the surface, walls included), scored as the 2.5D
        // regions with B's mesh vertices for the nodes.
        const json& mr = cj["change_mesh"];
        if (fs::exists(P / "change_mesh.ply") && mr.contains("regions")) {
            auto cm = formats::ply::ReadMesh((P / "change_mesh.ply").string(),
                                             {"distance_m", "region", "nz", "lod95_m"});
            if (!cm) {
                return cm.error();
            }
            std::vector<eval::DodNode> vnodes;
            for (std::size_t i = 0; i < cm->vertices.size(); ++i) {
                if (!std::isfinite(cm->vertex_properties[0][i])) continue;
                auto w = to_world(cm->vertices[i].x(), cm->vertices[i].y());
                if (!w) continue;
                const double lod = cm->vertex_properties[3][i];
                vnodes.push_back({*w,
                                  static_cast<int>(cm->vertex_properties[1][i]),
                                  std::abs(static_cast<double>(cm->vertex_properties[2][i])),
                                  std::isfinite(lod) ? lod : 0.0});
            }
            std::vector<eval::RegionInfo> vregions;
            for (const json& r : mr["regions"]) {
                vregions.push_back({r.value("id", 0),
                                    r.value("kind", std::string()) == "fill" ? 1 : -1,
                                    r.value("volume_m3", 0.0),
                                    r.value("u95_m3", 0.0)});
            }
            const auto ms = eval::ScoreChange(vnodes, vregions, truth->changes);
            int mesh_within = 0;
            for (const auto& ps : ms.parts) {
                const std::string k = "change3d_region_" + ps.name + "_";
                scores[k + "volume_detected_m3"] = ps.volume_detected_m3;
                scores[k + "u95_m3"] = ps.u95_m3;
                scores[k + "volume_error_pct"] = ps.error_pct;
                scores[k + "iou"] = ps.iou;
                scores[k + "iou_detectable"] = ps.iou_detectable;
                scores[k + "truth_below_lod_share"] = ps.truth_below_lod_share;
                scores[k + "within"] = ps.within ? 1 : 0;
                mesh_within += ps.within;
            }
            scores["change3d_region_parts_within"] = mesh_within;
            scores["change3d_region_stable_flagged_share"] = ms.stable_flagged_share;
            scores["change3d_region_false_regions"] = ms.false_regions;
            if (!scoring.options.change_mesh_csv.empty()) {
                if (auto w = WriteChangeMeshCsv(scoring, P / "change_mesh.ply", to_world); !w)
                    return w;
            }
        }
        // B's capacity at its water level against the true terrain under B's surveyed nodes.
        const std::string b_dir = cj["inputs"]["b"].value("folder", std::string());
        if (!b_dir.empty() && fs::exists(fs::path(b_dir) / "dem.tif")) {
            auto dem = proc::io::ReadGrid((fs::path(b_dir) / "dem.tif").string());
            if (dem && !dem->grid.layers.empty()) {
                const proc::io::GridRaster& d = dem->grid;
                // The true water surface is the world's z = 0 (the truth origin's height).
                double volume = 0;
                for (int j = 0; j < d.ny; ++j) {
                    for (int i = 0; i < d.nx; ++i) {
                        const float h = d.layers[0].values[static_cast<std::size_t>(j) * d.nx + i];
                        if (!std::isfinite(h)) continue;
                        auto w = to_world(d.x0 + i * d.resolution_m, d.y0 + j * d.resolution_m);
                        if (!w) continue;
                        volume += std::max(0.0, -world.Height(w->x(), w->y()));
                    }
                }
                volume *= d.resolution_m * d.resolution_m;
                const double product = cj["capacity"]["b"].value("volume_at_water_level_m3", 0.0);
                scores["capacity_b_volume_true_m3"] = volume;
                scores["capacity_b_volume_m3"] = product;
                scores["capacity_b_volume_error_pct"] =
                    volume > 0 ? 100.0 * (product - volume) / volume : 0.0;
            }
        }
    }
    return Ok{};
}

// P/terrain.tif and P/crawler.tif against the same layers from the true heights.
Status ScoreTerrainTifs(const Scoring& scoring, json& scores) {
    auto terrain = eval::ScoreTerrainProducts(
        scoring.options.products_dir, scoring.world, scoring.truth.origin);
    if (!terrain) return terrain.error();
    if (!*terrain) return Ok{};
    const eval::TerrainScore& t = **terrain;
    scores["terrain_nodes_scored"] = t.nodes;
    scores["terrain_slope_mean_abs_deg"] = t.slope_mean_abs_deg;
    scores["terrain_step_mean_abs_m"] = t.step_mean_abs_m;
    scores["terrain_class_agreement"] = t.class_agreement;
    scores["terrain_blocked_recall"] = t.blocked_recall;
    scores["terrain_blocked_false_share"] = t.blocked_false_share;
    return Ok{};
}

Status ScoreMosaicTif(const Scoring& scoring, json& scores) {
    if (!fs::exists(scoring.products / "mosaic.tif") || scoring.truth.backscatter_db.empty())
        return Ok{};
    auto mosaic = proc::io::ReadGrid((scoring.products / "mosaic.tif").string());
    if (!mosaic) return mosaic.error();
    const int epsg = mosaic->horizontal_epsg;
    if (!IsWgs84Utm(epsg)) {
        return Error{scoring.options.products_dir + "/mosaic.tif: not a WGS 84 / UTM grid (EPSG " +
                     std::to_string(epsg) + ")"};
    }
    for (const auto& layer : mosaic->grid.layers) {
        if (layer.name != "backscatter" && layer.name != "uncorrected") continue;
        ScoreMosaicLayer(scoring, mosaic->grid, epsg, layer, scores);
    }
    return Ok{};
}

#endif  // PITMAP_EVAL_GRID

// ---- TPU ----

// P/soundings_tpu.ply: how often the true error lies within each sounding's 95 % TVU and THU,
// overall and by beam angle.
Status ScoreSoundingsTpuPly(const Scoring& scoring, json& scores) {
    if (!fs::exists(scoring.products / "soundings_tpu.ply")) return Ok{};
    auto ply = formats::ply::ReadMesh((scoring.products / "soundings_tpu.ply").string(),
                                      {"gps_time_s", "angle_deg", "thu_95_m", "tvu_95_m"});
    if (!ply) return ply.error();
    std::vector<eval::TpuSounding> snd(ply->vertices.size());
    for (std::size_t i = 0; i < snd.size(); ++i) {
        snd[i].position = scoring.T_truth_product * ply->vertices[i];
        snd[i].gps_time_s = ply->vertex_properties[0][i];
        snd[i].angle_deg = ply->vertex_properties[1][i];
        snd[i].thu_95_m = ply->vertex_properties[2][i];
        snd[i].tvu_95_m = ply->vertex_properties[3][i];
    }
    // A refracting survey's true beams are curved (the simulator's water column).
    std::optional<sim::WaterColumn> water;
    if (scoring.truth.water) {
        const auto& heights = scoring.truth.terrain.height_m;
        const auto deepest = std::min_element(heights.begin(), heights.end());
        water.emplace(*scoring.truth.water, std::max(0.0, -static_cast<double>(*deepest)) + 10.0);
    }
    const auto score =
        eval::ScoreTpu(snd, scoring.truth, scoring.world, 1'000'000, water ? &*water : nullptr);
    if (score.all.count == 0) return Ok{};
    scores["tpu_within_tvu"] = score.all.within_tvu;
    scores["tpu_within_thu"] = score.all.within_thu;
    scores["tpu_vertical_rms_m"] = score.all.vertical_rms_m;
    scores["tpu_tvu_sigma_rms_m"] = score.all.tvu_rms_m;
    scores["tpu_vertical_bias_m"] = score.all.vertical_bias_m;
    scores["tpu_soundings_scored"] = score.all.count;
    scores["tpu_truth_rays"] = water ? "curved" : "straight";
    for (const auto& b : score.by_angle) {
        if (b.count == 0) continue;
        auto put = [&](const char* name, const json& value) {
            char key[64];
            std::snprintf(key, sizeof key, "%s_%02.0f_%02.0f_deg", name, b.lo, b.hi);
            scores[key] = value;
        };
        put("tpu_within_tvu", b.within_tvu);
        put("tpu_within_thu", b.within_thu);
        put("tpu_vertical_rms", b.vertical_rms_m);
        put("tpu_tvu_sigma_rms", b.tvu_rms_m);
        put("tpu_vertical_bias", b.vertical_bias_m);
        put("tpu_count", b.count);
    }
    // The classes of issue 36: tpu_classes.angle_00_20 {count, within_tvu, ...}.
    json classes = json::object();
    const auto put_classes = [&](const char* kind, const std::vector<eval::TpuBin>& bins) {
        for (const auto& b : bins) {
            if (b.count == 0) continue;
            const std::string key = ClassKey(kind, b.lo, b.hi);
            classes[key] = {{"count", b.count},
                            {"within_tvu", b.within_tvu},
                            {"within_thu", b.within_thu},
                            {"vertical_rms_m", b.vertical_rms_m},
                            {"tvu_sigma_rms_m", b.tvu_rms_m},
                            {"vertical_bias_m", b.vertical_bias_m}};
            scores["tpu_within_tvu_" + key] = b.within_tvu;
        }
    };
    put_classes("angle", score.by_angle_class);
    put_classes("depth", score.by_depth);
    put_classes("slope", score.by_slope);
    scores["tpu_classes"] = classes;
    return Ok{};
}

// ---- output ----

// The numeric scores as a table on stdout, the ATE windows beneath, and all of them as JSON to
// --json.
int WriteScores(const json& scores, const EvalOptions& options) {
    std::printf("%-32s %12s\n", "score", "value");
    for (const auto& [k, v] : scores.items()) {
        if (v.is_number()) std::printf("%-32s %12.4f\n", k.c_str(), v.get<double>());
    }
    if (scores.contains("trajectory_ate_windows")) {
        std::printf("\n%-16s %8s %12s %12s\n", "window (s)", "poses", "before (m)", "after (m)");
        for (const json& w : scores.at("trajectory_ate_windows")) {
            char span[32];
            std::snprintf(
                span, sizeof span, "%.0f-%.0f", w["t0_s"].get<double>(), w["t1_s"].get<double>());
            std::printf("%-16s %8zu %12.4f %12.4f\n",
                        span,
                        w["poses"].get<std::size_t>(),
                        w["before_m"].get<double>(),
                        w["after_m"].get<double>());
        }
    }
    if (!options.json_path.empty()) {
        std::ofstream out(options.json_path);
        out << scores.dump(2) << "\n";
        if (!out) {
            std::fprintf(stderr, "pitmap-eval: %s: cannot write\n", options.json_path.c_str());
            return codes::kFailure;
        }
    }
    return codes::kOk;
}

// One family of products: adds its scores, or an error for a product that is there but cannot
// be read.
using ProductScorer = Status (*)(const Scoring&, json&);

}  // namespace

int main(int argc, char** argv) try {
    EvalOptions options;
    if (auto code = ParseOptions(argc, argv, options)) return *code;
    auto truth = sim::ReadTruth(options.truth_dir);
    if (!truth) {
        std::fprintf(stderr, "pitmap-eval: %s\n", truth.error().message.c_str());
        return codes::kFailure;
    }
    const sim::PitWorld world(truth->terrain);
    const fs::path products(options.products_dir);
    auto points = ReadPointCloud(products, *truth);
    if (!points) {
        std::fprintf(stderr, "pitmap-eval: %s\n", points.error().message.c_str());
        return codes::kFailure;
    }
    const Scoring scoring{
        .options = options,
        .truth = *truth,
        .world = world,
        .products = products,
        .points = *points,
        .T_truth_product = ProductToTruth(products, points->cloud.comments, *truth)};
    json scores;
    for (const ProductScorer score : {ScoreTrajectories,
                                      ScorePointsPly,
                                      ScoreArtifactsInPoints,
                                      ScoreBoresightJson,
                                      ScoreMeshPly,
#ifdef PITMAP_EVAL_GRID
                                      ScoreDemTif,
                                      ScoreTerrainTifs,
                                      ScoreMosaicTif,
                                      ScoreCompareFolder,
#endif
                                      ScoreSoundingsTpuPly}) {
        if (auto scored = score(scoring, scores); !scored) {
            std::fprintf(stderr, "pitmap-eval: %s\n", scored.error().message.c_str());
            return codes::kFailure;
        }
    }
    if (!options.soundings_csv.empty()) {
        if (auto written = WriteSoundingsCsv(scoring); !written) {
            std::fprintf(stderr, "pitmap-eval: %s\n", written.error().message.c_str());
            return codes::kFailure;
        }
    }
    if (scores.empty()) {
        std::fprintf(
            stderr, "pitmap-eval: %s holds no product to score\n", options.products_dir.c_str());
        return codes::kFailure;
    }
    return WriteScores(scores, options);
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap-eval: internal error: %s\n", e.what());
    return codes::kInternal;
}
