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
#include "tools/eval/scores.hpp"
#ifdef PITMAP_EVAL_GRID
#include "processor/io/grid_io.hpp"
#endif

namespace fs = std::filesystem;
using nlohmann::json;
using namespace pitmap;

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
either, the truth's origin is assumed (and said).)";

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

}  // namespace

namespace codes = pitmap::exit_code;

int main(int argc, char** argv) try {
    CLI::App app{"pitmap-eval: score survey products against simulator ground truth"};
    std::string truth_dir, products_dir, json_path;
    app.add_option("--truth", truth_dir, "ground truth folder written by pitmap-sim (DIR/truth)")
        ->required();
    app.add_option("--products", products_dir, "products folder (pitmap ... --out P)")->required();
    app.add_option("--json", json_path, "write the scores as one JSON object to this file");
    std::string common_with;
    app.add_option("--mesh-common-with",
                   common_with,
                   "another products folder: also score P/mesh.ply where that folder's mesh.ply "
                   "lies within 0.2 m (mesh_mean_abs_m_common, mesh_common_share)");
    double ate_window_s = 0;
    app.add_option("--ate-window",
                   ate_window_s,
                   "also score both trajectories per window of this many seconds "
                   "(trajectory_ate_windows, trajectory_ate_worst_window_increase_m)")
        ->check(CLI::NonNegativeNumber);
    app.footer(kDefinitions);
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap-eval")) return *code;
    // Both folders must be there before anything is read or --json written.
    for (const std::string& dir : {truth_dir, products_dir}) {
        if (!fs::is_directory(dir)) {
            std::fprintf(stderr, "pitmap-eval: %s: not a folder\n", dir.c_str());
            return codes::kUsage;
        }
    }
    auto truth = sim::ReadTruth(truth_dir);
    if (!truth) {
        std::fprintf(stderr, "pitmap-eval: %s\n", truth.error().message.c_str());
        return codes::kFailure;
    }
    const fs::path P(products_dir);
    const sim::PitWorld world(truth->terrain);
    json scores;
    std::vector<std::string> comments;
    formats::ply::Mesh cloud;
    bool have_cloud = false;
    // With the truth of the echo artifacts, the points' ping times are needed to match them.
    bool have_times = false;
    std::size_t points_rejected = 0;
    bool have_status = false;
    if (fs::exists(P / "points.ply")) {
        // One read with the properties that are there: the ping times where the artifacts need
        // them, the status to keep the accepted soundings (issue 35).
        const std::string path = (P / "points.ply").string();
        auto names = eval::PlyVertexProperties(path);
        if (!names) {
            std::fprintf(stderr, "pitmap-eval: %s\n", names.error().message.c_str());
            return codes::kFailure;
        }
        const auto has = [&](const char* n) {
            return std::find(names->begin(), names->end(), n) != names->end();
        };
        std::vector<std::string> props;
        have_times = truth->artifacts && has("gps_time_s");
        if (have_times) props.push_back("gps_time_s");  // vertex_properties[0]
        have_status = has("status");
        if (have_status) props.push_back("status");
        auto ply = formats::ply::ReadMesh(path, props);
        if (!ply) {
            std::fprintf(stderr, "pitmap-eval: %s\n", ply.error().message.c_str());
            return codes::kFailure;
        }
        cloud = std::move(*ply);
        if (have_status) points_rejected = eval::KeepAccepted(cloud, props.size() - 1);
        comments = cloud.comments;
        have_cloud = true;
    }
    auto origin = ProductOrigin(P, comments);
    if (!origin) {
        std::fprintf(stderr,
                     "pitmap-eval: no world origin in the products; assuming the truth's origin\n");
        origin = truth->origin;
    }
    const Pose T = eval::ProductToTruthFrame(*origin, truth->origin);

    // Without SLAM (georef only, or `run --no-slam`) the INS-rate trajectory is the final one.
    const char* final_trajectory =
        fs::exists(P / "trajectory.csv") || !fs::exists(P / "trajectory_ins.csv")
            ? "trajectory.csv"
            : "trajectory_ins.csv";
    std::vector<eval::ProductPose> windowed[2];  // after, before
    for (const auto& [file, key] :
         {std::pair{final_trajectory, "trajectory_ate_rmse_m"},
          std::pair{"trajectory_initial.csv", "trajectory_ate_rmse_before_m"}}) {
        if (!fs::exists(P / file)) continue;
        auto traj = formats::ReadTrajectoryCsv((P / file).string());
        if (!traj) {
            std::fprintf(stderr, "pitmap-eval: %s\n", traj.error().message.c_str());
            return codes::kFailure;
        }
        const std::vector<eval::ProductPose> poses = eval::ProductPoses(*traj);
        windowed[std::string(key) == "trajectory_ate_rmse_m" ? 0 : 1] = poses;
        const auto s = eval::ScoreTrajectory(poses, T, truth->trajectory);
        if (s.poses == 0) {
            std::fprintf(
                stderr, "pitmap-eval: %s: no pose inside the true trajectory's time span\n", file);
            continue;
        }
        scores[key] = s.ate_rmse_m;
        if (std::string(key) == "trajectory_ate_rmse_m") {
            scores["trajectory_ate_max_m"] = s.ate_max_m;
            scores["trajectory_z_std_m"] = s.z_std_m;
        }
    }
    if (fs::exists(P / "trajectory_sigma.csv")) {
        auto stated = eval::ReadTrajectorySigmaCsv((P / "trajectory_sigma.csv").string());
        if (!stated) {
            std::fprintf(stderr, "pitmap-eval: %s\n", stated.error().message.c_str());
            return codes::kFailure;
        }
        constexpr double kOutageSigmaM = 0.5;  // slam coarse_search_min_sigma_m's default
        const eval::UncertaintyScore u =
            eval::ScoreUncertainty(*stated, T, truth->trajectory, kOutageSigmaM);
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
    }
    if (ate_window_s > 0) {
        json windows = json::array();
        // The worst increase is what "SLAM never made a segment worse" is judged by.
        double worst = -std::numeric_limits<double>::infinity();
        for (const eval::AteWindow& w : eval::ScoreTrajectoryWindows(
                 windowed[0], windowed[1], T, truth->trajectory, ate_window_s)) {
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
                         final_trajectory);
        }
    }
    if (have_cloud) {
        const auto s = eval::ScorePoints(cloud.vertices, T, world);
        scores["points_rms_m"] = s.rms_m;
        scores["points_p95_m"] = s.p95_m;
        scores["points_bias_m"] = s.bias_m;
        scores["points_scored"] = s.count;
        scores["points_accepted"] = cloud.vertices.size();
        if (have_status) scores["points_rejected"] = points_rejected;
        // By beam angle, where the points carry their beam number and the truth its fan.
        std::ifstream sin(fs::path(truth_dir) / "scenario.json");
        const json sc = sin ? json::parse(sin, nullptr, false) : json();
        if (cloud.vertex_beam.size() == cloud.vertices.size() && sc.is_object() &&
            sc.contains("sonar") && sc["sonar"].is_object() &&
            sc["sonar"].value("angle_increment_deg", json()).is_number() &&
            sc["sonar"].value("start_angle_deg", json()).is_number()) {
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
                const auto sb = eval::ScorePoints(sel, T, world);
                char key[64];
                std::snprintf(key,
                              sizeof key,
                              "points_rms_m_angle_%.0f_%.0f",
                              edges[b],
                              b == 4 ? 90.0 : edges[b + 1]);
                scores[key] = sb.rms_m;
            }
        }
    }
    if (have_cloud && truth->artifacts) {
        const sim::ArtifactTruth& a = *truth->artifacts;
        const auto total = [&](sim::EchoArtifactKind k) {
            return a.beams_by_kind[static_cast<int>(k)];
        };
        scores["artifact_soundings"] = a.artifact_soundings();
        for (int k = 1; k < sim::kNumEchoArtifactKinds; ++k) {
            scores[std::string("artifact_beams_") +
                   sim::EchoArtifactName(static_cast<sim::EchoArtifactKind>(k))] =
                a.beams_by_kind[k];
        }
        scores["good_soundings"] = a.good_soundings;
        if (!have_times || cloud.vertex_beam.size() != cloud.vertices.size()) {
            std::fprintf(stderr,
                         "pitmap-eval: %s/points.ply has no gps_time_s or beam: the artifact "
                         "soundings are not scored\n",
                         products_dir.c_str());
        } else {
            std::vector<Eigen::Vector3d> pts(cloud.vertices.size());
            for (std::size_t i = 0; i < pts.size(); ++i) pts[i] = T * cloud.vertices[i];
            const auto s =
                eval::ScoreArtifacts(pts, cloud.vertex_properties[0], cloud.vertex_beam, a, world);
            std::int64_t artifacts_in = 0;
            for (const auto k : {sim::EchoArtifactKind::kMidWater,
                                 sim::EchoArtifactKind::kBubble,
                                 sim::EchoArtifactKind::kMultipath,
                                 sim::EchoArtifactKind::kSmile,
                                 sim::EchoArtifactKind::kOutlier}) {
                const std::string name = sim::EchoArtifactName(k);
                const std::int64_t in = s.in_points[static_cast<int>(k)];
                if (k != sim::EchoArtifactKind::kOutlier) artifacts_in += in;
                scores["artifact_in_points_" + name] = in;
                if (total(k) > 0) {
                    scores["artifact_rejected_share_" + name] =
                        1.0 - static_cast<double>(in) / static_cast<double>(total(k));
                }
            }
            scores["artifact_in_points"] = artifacts_in;
            if (a.artifact_soundings() > 0) {
                scores["artifact_rejected_share"] =
                    1.0 -
                    static_cast<double>(artifacts_in) / static_cast<double>(a.artifact_soundings());
            }
            scores["points_unmatched"] = s.unmatched;
            scores["good_in_points"] = s.good_in_points;
            if (a.good_soundings > 0) {
                scores["good_rejected_share"] = 1.0 - static_cast<double>(s.good_in_points) /
                                                          static_cast<double>(a.good_soundings);
            }
            for (int c = 0; c < sim::kNumArtifactSlopeClasses; ++c) {
                if (a.good_by_slope[c] == 0) continue;
                char key[64];
                std::snprintf(key,
                              sizeof key,
                              "good_rejected_share_slope_%.0f_%.0f",
                              sim::kArtifactSlopeEdgesDeg[c],
                              sim::kArtifactSlopeEdgesDeg[c + 1]);
                scores[key] = 1.0 - static_cast<double>(s.good_in_points_by_slope[c]) /
                                        static_cast<double>(a.good_by_slope[c]);
            }
            if (s.good.count > 0) scores["points_rms_m_good"] = s.good.rms_m;
        }
    }
    if (fs::exists(P / "boresight.json")) {
        std::ifstream in(P / "boresight.json");
        const json b = json::parse(in, nullptr, false);
        if (b.is_discarded() || !b.contains("roll_deg") || !b.contains("pitch_deg") ||
            !b.contains("yaw_deg")) {
            std::fprintf(stderr,
                         "pitmap-eval: %s/boresight.json: needs roll_deg, pitch_deg, yaw_deg\n",
                         products_dir.c_str());
            return codes::kFailure;
        }
        scores["boresight_error_deg"] = eval::BoresightErrorDeg(b["roll_deg"].get<double>(),
                                                                b["pitch_deg"].get<double>(),
                                                                b["yaw_deg"].get<double>(),
                                                                truth->boresight.roll_deg,
                                                                truth->boresight.pitch_deg,
                                                                truth->boresight.yaw_deg);
    }
    if (fs::exists(P / "mesh.ply")) {
        auto mesh = formats::ply::ReadMesh((P / "mesh.ply").string());
        if (!mesh) {
            std::fprintf(stderr, "pitmap-eval: %s\n", mesh.error().message.c_str());
            return codes::kFailure;
        }
        std::vector<Eigen::Vector3d> samples = MeshSamples(*mesh);
        const auto s = eval::ScorePoints(samples, T, world);
        for (auto& p : samples) p = T * p;
        if (auto c = eval::MeshCompleteness(samples, *truth)) scores["mesh_completeness"] = *c;
        scores["mesh_mean_abs_m"] = s.mean_abs_m;
        scores["mesh_rms_m"] = s.rms_m;
        scores["mesh_p95_m"] = s.p95_m;
        scores["mesh_bias_m"] = s.bias_m;
        {
            // Issue 35's damage figure: the share of the mesh samples more than 1 m off.
            std::size_t far = 0;
            for (const auto& p : samples) far += std::abs(world.SignedDistance(p)) > 1.0;
            scores["mesh_share_beyond_1m"] =
                samples.empty() ? 0.0
                                : static_cast<double>(far) / static_cast<double>(samples.size());
        }
        // The same by the true slope under the sample: floors, faces, walls (mean abs error
        // and signed mean, truth to mesh positive when the mesh lies outside the rock).
        const auto& edges = eval::kSlopeClassEdgesDeg;
        const std::size_t n_classes = std::size(edges) - 1;
        auto slope_suffix = [&](std::size_t c) {
            return "_slope_" + std::to_string(static_cast<int>(edges[c])) + "_" +
                   std::to_string(static_cast<int>(edges[c + 1]));
        };
        auto score_by_slope = [&](const std::vector<Eigen::Vector3d>& pts,
                                  const std::string& prefix) {
            std::vector<std::vector<double>> by_class(n_classes);
            for (const auto& p : pts) {
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
                scores[prefix + "mean_abs_m" + slope_suffix(c)] = sc.mean_abs_m;
                scores[prefix + "bias_m" + slope_suffix(c)] = sc.bias_m;
            }
        };
        score_by_slope(samples, "mesh_");
        for (std::size_t c = 0; c < n_classes; ++c) {
            if (auto cc = eval::MeshCompleteness(samples, *truth, 0.2, edges[c], edges[c + 1]))
                scores["mesh_completeness" + slope_suffix(c)] = *cc;
        }
        // By the true water depth: the shore near the water line is seen at short range.
        const auto& depths = eval::kDepthClassEdgesM;
        for (std::size_t c = 0; c + 1 < std::size(depths); ++c) {
            const std::string hi = std::isfinite(depths[c + 1])
                                       ? std::to_string(static_cast<int>(depths[c + 1]))
                                       : std::string("inf");
            const std::string key =
                "mesh_completeness_depth_" + std::to_string(static_cast<int>(depths[c])) + "_" + hi;
            if (auto cd =
                    eval::MeshCompleteness(samples, *truth, 0.2, 0, 91, depths[c], depths[c + 1]))
                scores[key] = *cd;
        }
        if (!common_with.empty()) {
            // Error on the part of the surface both meshes hold: a mesh that keeps only what
            // was seen often is not more accurate for having dropped the rest.
            const fs::path Q(common_with);
            auto other = formats::ply::ReadMesh((Q / "mesh.ply").string());
            if (!other) {
                std::fprintf(stderr, "pitmap-eval: %s\n", other.error().message.c_str());
                return codes::kFailure;
            }
            const auto other_origin = ProductOrigin(Q, other->comments);
            const Pose T_other = eval::ProductToTruthFrame(
                other_origin ? *other_origin : truth->origin, truth->origin);
            std::vector<Eigen::Vector3d> theirs = MeshSamples(*other);
            for (auto& p : theirs) p = T_other * p;
            std::vector<Eigen::Vector3d> common = eval::SamplesInSharedCells(samples, theirs, 0.2);
            scores["mesh_common_share"] = samples.empty() ? 0.0
                                                          : static_cast<double>(common.size()) /
                                                                static_cast<double>(samples.size());
            std::vector<double> d;
            d.reserve(common.size());
            for (const auto& p : common) d.push_back(world.SignedDistance(p));
            if (!d.empty()) {
                const auto sc = eval::SummariseDistances(std::move(d));
                scores["mesh_mean_abs_m_common"] = sc.mean_abs_m;
                scores["mesh_bias_m_common"] = sc.bias_m;
            }
            score_by_slope(common, "mesh_common_");
        }
    }
#ifdef PITMAP_EVAL_GRID
    if (fs::exists(P / "dem.tif")) {
        auto dem = proc::io::ReadGrid((P / "dem.tif").string());
        if (!dem) {
            std::fprintf(stderr, "pitmap-eval: %s\n", dem.error().message.c_str());
            return codes::kFailure;
        }
        const int epsg = dem->horizontal_epsg;
        if (!((epsg > 32600 && epsg <= 32660) || (epsg > 32700 && epsg <= 32760)) ||
            dem->grid.layers.empty()) {
            std::fprintf(stderr,
                         "pitmap-eval: %s/dem.tif: not a WGS 84 / UTM grid (EPSG %d)\n",
                         products_dir.c_str(),
                         epsg);
            return codes::kFailure;
        }
        const proc::io::GridRaster& g = dem->grid;
        const double datum_height_m = DatumHeight(P);
        const LocalTangentFrame tf(truth->origin);
        std::vector<Eigen::Vector3d> nodes;
        std::vector<std::size_t> node_index;  // of each node in the grid's layers
        nodes.reserve(static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny));
        for (int j = 0; j < g.ny; ++j) {
            for (int i = 0; i < g.nx; ++i) {
                const float h = g.layers[0].values[static_cast<std::size_t>(j) * g.nx + i];
                UtmCoordinate u;
                u.zone = epsg % 100;
                u.northern = epsg < 32700;
                u.easting_m = g.x0 + i * g.resolution_m;
                u.northing_m = g.y0 + j * g.resolution_m;
                u.height_m = std::isfinite(h) ? h + datum_height_m : 0.0;
                auto geo = GeodeticFromUtm(u);
                if (!geo) continue;
                Eigen::Vector3d p = tf.ToEnu(*geo);
                if (!std::isfinite(h)) p.z() = std::numeric_limits<double>::quiet_NaN();
                nodes.push_back(p);
                node_index.push_back(static_cast<std::size_t>(j) * g.nx + i);
            }
        }
        const auto s = eval::ScoreDem(nodes, *truth);
        for (const auto& layer : g.layers) {
            if (layer.name != "uncertainty") continue;
            std::vector<double> unc(nodes.size(), std::numeric_limits<double>::quiet_NaN());
            for (std::size_t k = 0; k < unc.size() && k < node_index.size(); ++k) {
                unc[k] = layer.values[node_index[k]];
            }
            const eval::DemUncertaintyScore u = eval::ScoreDemUncertainty(nodes, unc, *truth);
            if (u.all.count == 0) break;
            scores["dem_within_uncertainty"] = u.all.within;
            scores["dem_uncertainty_nodes"] = u.all.count;
            json classes = json::object();
            const auto put = [&](const char* kind, const std::vector<eval::DemUncertaintyBin>& b) {
                for (const auto& c : b) {
                    if (c.count == 0) continue;
                    char key[64];
                    if (std::isinf(c.hi)) {
                        std::snprintf(key, sizeof key, "%s_%02.0f_inf", kind, c.lo);
                    } else {
                        std::snprintf(key, sizeof key, "%s_%02.0f_%02.0f", kind, c.lo, c.hi);
                    }
                    classes[key] = {{"count", c.count},
                                    {"within", c.within},
                                    {"error_rms_m", c.error_rms_m},
                                    {"stated_sigma_rms_m", c.stated_rms_m}};
                    scores[std::string("dem_within_uncertainty_") + key] = c.within;
                }
            };
            put("slope", u.by_slope);
            put("depth", u.by_depth);
            scores["dem_uncertainty_classes"] = classes;
        }
        scores["dem_mean_abs_m"] = s.all.mean_abs_m;
        scores["dem_rms_m"] = s.all.rms_m;
        scores["dem_p95_m"] = s.all.p95_m;
        scores["dem_bias_m"] = s.all.bias_m;
        scores["dem_nodes_scored"] = s.all.count;
        scores["dem_mean_abs_insonified_m"] = s.insonified.mean_abs_m;
        scores["dem_resolution_m"] = g.resolution_m;
        if (s.fill_insonified) scores["dem_fill_insonified"] = *s.fill_insonified;
    }
    if (fs::exists(P / "mosaic.tif") && !truth->backscatter_db.empty()) {
        auto mosaic = proc::io::ReadGrid((P / "mosaic.tif").string());
        if (!mosaic) {
            std::fprintf(stderr, "pitmap-eval: %s\n", mosaic.error().message.c_str());
            return codes::kFailure;
        }
        const int epsg = mosaic->horizontal_epsg;
        if (!((epsg > 32600 && epsg <= 32660) || (epsg > 32700 && epsg <= 32760))) {
            std::fprintf(stderr,
                         "pitmap-eval: %s/mosaic.tif: not a WGS 84 / UTM grid (EPSG %d)\n",
                         products_dir.c_str(),
                         epsg);
            return codes::kFailure;
        }
        const proc::io::GridRaster& g = mosaic->grid;
        const LocalTangentFrame tf(truth->origin);
        for (const auto& layer : g.layers) {
            if (layer.name != "backscatter" && layer.name != "uncorrected") continue;
            std::vector<Eigen::Vector3d> nodes;
            for (int j = 0; j < g.ny; ++j) {
                for (int i = 0; i < g.nx; ++i) {
                    const float v = layer.values[static_cast<std::size_t>(j) * g.nx + i];
                    if (!std::isfinite(v)) continue;
                    UtmCoordinate u;
                    u.zone = epsg % 100;
                    u.northern = epsg < 32700;
                    u.easting_m = g.x0 + i * g.resolution_m;
                    u.northing_m = g.y0 + j * g.resolution_m;
                    u.height_m = truth->origin.height_m;
                    auto geo = GeodeticFromUtm(u);
                    if (!geo) continue;
                    Eigen::Vector3d p = tf.ToEnu(*geo);
                    p.z() = v;
                    nodes.push_back(p);
                }
            }
            const auto sc = eval::ScoreMosaic(nodes, g.resolution_m, *truth);
            if (!sc) continue;
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
    }
#endif
    if (fs::exists(P / "soundings_tpu.ply")) {
        auto ply = formats::ply::ReadMesh((P / "soundings_tpu.ply").string(),
                                          {"gps_time_s", "angle_deg", "thu_95_m", "tvu_95_m"});
        if (!ply) {
            std::fprintf(stderr, "pitmap-eval: %s\n", ply.error().message.c_str());
            return codes::kFailure;
        }
        std::vector<eval::TpuSounding> snd(ply->vertices.size());
        for (std::size_t i = 0; i < snd.size(); ++i) {
            snd[i].position = T * ply->vertices[i];
            snd[i].gps_time_s = ply->vertex_properties[0][i];
            snd[i].angle_deg = ply->vertex_properties[1][i];
            snd[i].thu_95_m = ply->vertex_properties[2][i];
            snd[i].tvu_95_m = ply->vertex_properties[3][i];
        }
        // A refracting survey's true beams are curved (the simulator's water column).
        std::optional<sim::WaterColumn> water;
        if (truth->water) {
            const auto deepest =
                std::min_element(truth->terrain.height_m.begin(), truth->terrain.height_m.end());
            water.emplace(*truth->water, std::max(0.0, -static_cast<double>(*deepest)) + 10.0);
        }
        const auto s = eval::ScoreTpu(snd, *truth, world, 1'000'000, water ? &*water : nullptr);
        if (s.all.count > 0) {
            scores["tpu_within_tvu"] = s.all.within_tvu;
            scores["tpu_within_thu"] = s.all.within_thu;
            scores["tpu_vertical_rms_m"] = s.all.vertical_rms_m;
            scores["tpu_tvu_sigma_rms_m"] = s.all.tvu_rms_m;
            scores["tpu_vertical_bias_m"] = s.all.vertical_bias_m;
            scores["tpu_soundings_scored"] = s.all.count;
            scores["tpu_truth_rays"] = water ? "curved" : "straight";
            for (const auto& b : s.by_angle) {
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
                    char key[64];
                    if (std::isinf(b.hi)) {
                        std::snprintf(key, sizeof key, "%s_%02.0f_inf", kind, b.lo);
                    } else {
                        std::snprintf(key, sizeof key, "%s_%02.0f_%02.0f", kind, b.lo, b.hi);
                    }
                    classes[key] = {{"count", b.count},
                                    {"within_tvu", b.within_tvu},
                                    {"within_thu", b.within_thu},
                                    {"vertical_rms_m", b.vertical_rms_m},
                                    {"tvu_sigma_rms_m", b.tvu_rms_m},
                                    {"vertical_bias_m", b.vertical_bias_m}};
                    scores[std::string("tpu_within_tvu_") + key] = b.within_tvu;
                }
            };
            put_classes("angle", s.by_angle_class);
            put_classes("depth", s.by_depth);
            put_classes("slope", s.by_slope);
            scores["tpu_classes"] = classes;
        }
    }

    if (scores.empty()) {
        std::fprintf(stderr, "pitmap-eval: %s holds no product to score\n", products_dir.c_str());
        return codes::kFailure;
    }
    std::printf("%-32s %12s\n", "score", "value");
    for (const auto& [k, v] : scores.items()) {
        if (v.is_number()) std::printf("%-32s %12.4f\n", k.c_str(), v.get<double>());
    }
    if (scores.contains("trajectory_ate_windows")) {
        std::printf("\n%-16s %8s %12s %12s\n", "window (s)", "poses", "before (m)", "after (m)");
        for (const json& w : scores["trajectory_ate_windows"]) {
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
    if (!json_path.empty()) {
        std::ofstream out(json_path);
        out << scores.dump(2) << "\n";
        if (!out) {
            std::fprintf(stderr, "pitmap-eval: %s: cannot write\n", json_path.c_str());
            return codes::kFailure;
        }
    }
    return codes::kOk;
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap-eval: internal error: %s\n", e.what());
    return codes::kInternal;
}
