// SPDX-License-Identifier: MIT
// Scenario test of repeat surveys (issue 37): the quarry's first 150 s surveyed twice
// (pitmap-sim synth --epoch 1 and --epoch 2: a slumped wall, a backfill heap, a thin spill, a
// mined cut; the second survey with its own track, noise, mount and clock), both through
// `pitmap run`, then `pitmap compare`, scored by pitmap-eval against the truth of the changes:
//   - every change of >= 4 m3 and >= 0.15 m thick: volume within 5 % or its U95, outline IoU
//     >= 0.8; < 0.3 % of the stable area flagged; the registration's residual on stable terrain;
//     the capacity at B's water level within 0.5 % of the true terrain's;
//   - a deliberately shifted epoch (B's dem.tif moved by 0.5 m and turned by 1 deg) is
//     recovered within 2 cm and 0.02 deg, and the navigation gate trips (exit 4 with --strict);
//   - bad input: a missing product, a damaged survey.pitmap, another vertical datum, another
//     site, another CRS, no overlap, a folder that is not there: an error naming the problem,
//     and no compare.json.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <utility>

#include "common/formats/ply.hpp"
#include "processor/io/grid_io.hpp"
#include "tests/support/process.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

constexpr double kPi = 3.14159265358979323846;

class CompareScenario : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = pitmap::test::FreshDir("pitmap_compare_scenario");
        for (int epoch : {1, 2}) {
            const fs::path sim = dir_ / ("sim" + std::to_string(epoch));
            std::string out;
            ASSERT_EQ(RunCommand(kBin +
                                     "/pitmap-sim synth --scenario quarry --duration 150 "
                                     "--epoch " +
                                     std::to_string(epoch) + " --out " + Quote(sim),
                                 &out),
                      0)
                << out;
            ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(sim / "log") + " --out " +
                                     Quote(dir_ / ("P" + std::to_string(epoch))) + " --no-report",
                                 &out),
                      0)
                << out;
        }
    }
    static fs::path A() { return dir_ / "P1"; }
    static fs::path B() { return dir_ / "P2"; }
    // A copy of the files pitmap compare reads.
    static fs::path CopyEpoch(const fs::path& from, const std::string& name) {
        const fs::path to = dir_ / name;
        fs::remove_all(to);
        fs::create_directories(to);
        for (const char* f : {"summary.json",
                              "dem.tif",
                              "survey.pitmap",
                              "trajectory.csv",
                              "trajectory_sigma.csv",
                              "points_utm.ply"}) {
            fs::copy_file(from / f, to / f);
        }
        return to;
    }
    // pitmap compare's exit status (without the change report: report_compare_test's).
    static int Compare(const fs::path& a,
                       const fs::path& b,
                       const fs::path& out,
                       std::string* text,
                       const std::string& extra = "") {
        const int status = RunCommand(kBin + "/pitmap compare " + Quote(a) + " " + Quote(b) +
                                          " --out " + Quote(out) + " --no-report" + extra,
                                      text);
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    void ChangesMeasuredAgainstTruth();
    void ShiftedEpochIsRecoveredAndTripsTheNavigationGate();
    void BadInputIsAClearErrorAndNoResult();
    void DesignSurfaceVolumes();
    void SeriesOfSurveys();
    static fs::path dir_;
};

fs::path CompareScenario::dir_;

// B's dem.tif rewritten: every band moved by the rigid map S (turn by yaw_deg about the grid's
// centre, then shift), or re-stamped in another UTM zone, or moved far away.
void RewriteDem(const fs::path& dem,
                double yaw_deg,
                const Eigen::Vector2d& shift,
                int zone_override = 0) {
    auto r = pitmap::proc::io::ReadGrid(dem.string());
    ASSERT_TRUE(r.ok()) << r.error().message;
    pitmap::proc::io::GridRaster g = r->grid;
    g.utm_zone = zone_override != 0 ? zone_override : r->horizontal_epsg % 100;
    g.northern = r->horizontal_epsg < 32700;
    const Eigen::Vector2d c(g.x0 + 0.5 * (g.nx - 1) * g.resolution_m,
                            g.y0 + 0.5 * (g.ny - 1) * g.resolution_m);
    const double a = yaw_deg * kPi / 180.0;
    const Eigen::Matrix2d R =
        (Eigen::Matrix2d() << std::cos(a), -std::sin(a), std::sin(a), std::cos(a)).finished();
    if (yaw_deg != 0) {
        for (auto& layer : g.layers) {
            const std::vector<float> src = layer.values;
            for (int j = 0; j < g.ny; ++j) {
                for (int i = 0; i < g.nx; ++i) {
                    // The value at q comes from S^-1(q) = R^T (q - c - shift) + c.
                    const Eigen::Vector2d q(g.x0 + i * g.resolution_m, g.y0 + j * g.resolution_m);
                    const Eigen::Vector2d p = R.transpose() * (q - c - shift) + c;
                    const double gx = (p.x() - g.x0) / g.resolution_m;
                    const double gy = (p.y() - g.y0) / g.resolution_m;
                    float v = std::numeric_limits<float>::quiet_NaN();
                    if (gx >= 0 && gy >= 0 && gx < g.nx - 1 && gy < g.ny - 1) {
                        const int i0 = static_cast<int>(gx), j0 = static_cast<int>(gy);
                        const double u = gx - i0, w = gy - j0;
                        const auto at = [&](int ii, int jj) {
                            return static_cast<double>(
                                src[static_cast<std::size_t>(jj) * g.nx + ii]);
                        };
                        v = static_cast<float>(
                            (at(i0, j0) * (1 - u) + at(i0 + 1, j0) * u) * (1 - w) +
                            (at(i0, j0 + 1) * (1 - u) + at(i0 + 1, j0 + 1) * u) * w);
                    }
                    layer.values[static_cast<std::size_t>(j) * g.nx + i] = v;
                }
            }
        }
    } else {
        g.x0 += shift.x();
        g.y0 += shift.y();
    }
    fs::remove(dem);
    const auto s = pitmap::proc::io::WriteCogGeoTiff(dem.string(), g);
    ASSERT_TRUE(s.ok()) << s.error().message;
}

void CompareScenario::ChangesMeasuredAgainstTruth() {
    std::string out;
    const fs::path C = dir_ / "C";
    ASSERT_EQ(Compare(A(), B(), C, &out, " --strict"), 0) << out;
    for (const char* f : {"dod.tif",
                          "change_regions.geojson",
                          "capacity_a.csv",
                          "capacity_b.csv",
                          "capacity.svg",
                          "change_mesh.ply",
                          "change_mesh.glb",
                          "compare.json"})
        EXPECT_TRUE(fs::exists(C / f)) << f;
    const json j = ReadJson(C / "compare.json");
    EXPECT_TRUE(j["quality_gates"].empty()) << j["quality_gates"].dump();
    EXPECT_TRUE(j["registration"]["navigation_gate"]["evaluated"].get<bool>());
    const auto s = pitmap::test::EvalScores(dir_ / "sim2/truth", C);
    ASSERT_EQ(s.at("change_parts"), 5) << out;
    for (const char* part : {"slump_scar", "slump_toe", "backfill", "spill", "cut"}) {
        const std::string k = std::string("change_") + part + "_";
        EXPECT_EQ(s.at(k + "within"), 1)
            << part << ": " << s.at(k + "volume_detected_m3") << " +- " << s.at(k + "u95_m3")
            << " m3, truth " << s.at(k + "volume_true_m3");
        EXPECT_GE(s.at(k + "iou"), 0.8) << part;
    }
    // The bound (docs/decisions/014: held at 0.012 while the LoD took CUBE's
    // pass-common errors as independent per node; the regions' test as a whole, change.hpp).
    EXPECT_LT(s.at("change_stable_flagged_share"), 0.003);
    // The registration's residual on stable terrain, on the nodes both surveys sounded at least
    // 5 times, walls to 80 deg included: the 2 cm (measured 1.87 cm; both CUBE surfaces'
    // own noise, about 1.6 cm each against the truth: decision 029). Also vertically on the
    // floors and along the normal (1.66 and 1.49 cm; decision 023, section 6). Over every
    // stable node, those of 1-4 soundings too, 2.06 cm: held below 2.5 cm.
    EXPECT_LE(s.at("registration_rms_vertical_after_m"), 0.02);
    EXPECT_LE(s.at("registration_rms_vertical_floor_after_m"), 0.02);
    EXPECT_LE(s.at("registration_rms_normal_after_m"), 0.02);
    EXPECT_LT(s.at("registration_rms_vertical_all_nodes_after_m"), 0.025);
    EXPECT_LT(std::abs(s.at("capacity_b_volume_error_pct")), 0.5);
    // Each survey's own summary.json holds its capacity curve (pitmap run's grid stage), the
    // same as compare finds for it, and capacity.csv the same rows as compare's.
    for (const auto& [side, folder] : {std::pair{"a", A()}, std::pair{"b", B()}}) {
        const json sj = ReadJson(folder / "summary.json");
        ASSERT_TRUE(sj.contains("capacity")) << side;
        const json& own = sj["capacity"];
        const json& cmp = j["capacity"][side];
        ASSERT_TRUE(own.contains("rows_level_area_volume")) << own.dump();
        EXPECT_GT(own["rows_level_area_volume"].size(), 10u);
        for (const char* k :
             {"water_level_m", "deepest_m", "surveyed_area_m2", "volume_at_water_level_m3"}) {
            EXPECT_NEAR(own[k].get<double>(), cmp[k].get<double>(), 1e-6) << side << " " << k;
        }
        std::ifstream own_csv(folder / "capacity.csv"),
            cmp_csv(C / ("capacity_" + std::string(side) + ".csv"));
        const std::string own_text((std::istreambuf_iterator<char>(own_csv)), {});
        const std::string cmp_text((std::istreambuf_iterator<char>(cmp_csv)), {});
        EXPECT_FALSE(own_text.empty()) << side;
        EXPECT_EQ(own_text, cmp_text) << side;
    }
    // The 3D change along the normal: the scar on the 65 deg wall is seen as a loss along the
    // wall's normal (0.42 m at its centre, 0.27 m median where its vertical depth exceeds
    // 0.3 m). Stable cores flagged: the issue's < 0.3 %, on walls too (measured 0 of 15 957
    // stable cores, 0 of 4 566 on walls, with the normal from both surveys, each one's
    // neighbourhood a plane and the surface nearest to the core in the cylinder; 0.85 % and
    // 1.3 % on walls before: docs/compare.md).
    EXPECT_TRUE(fs::exists(C / "change_points.ply"));
    EXPECT_GT(s.at("change3d_scar_detected_share"), 0.9);
    EXPECT_NEAR(s.at("change3d_scar_median_distance_m"), -0.27, 0.08);
    EXPECT_LT(s.at("change3d_stable_flagged_share"), 0.001);
    EXPECT_LT(s.at("change3d_wall_stable_flagged_share"), 0.003);
    // The change mesh: B's TSDF mesh with the distance along the normal per vertex; the scar
    // (1 m vertical on the 65 deg wall, 0.42 m along its normal at the centre) is a loss along
    // the normal, the heap (0.6 m on the floor) a gain.
    const json& cm = j["change_mesh"];
    ASSERT_TRUE(cm["computed"].get<bool>()) << cm.dump();
    EXPECT_GT(cm["measured"].get<double>(), 0.6 * cm["vertices"].get<double>());
    // The five parts as patches of significant vertices, few others (the count measured is in
    // docs/compare.md; the stable vertices flagged are bounded above).
    EXPECT_GE(cm["patches"].get<int>(), 5);
    EXPECT_LE(cm["patches"].get<int>(), 7);
    auto mesh = pitmap::formats::ply::ReadMesh((C / "change_mesh.ply").string(),
                                               {"distance_m", "significance"});
    ASSERT_TRUE(mesh.ok()) << mesh.error().message;
    ASSERT_EQ(mesh->vertices.size(), cm["vertices"].get<std::size_t>());
    const auto median_near = [&](const std::string& kind, int* flagged, int* near) {
        const json* biggest = nullptr;
        for (const json& r : j["change"]["regions"]) {
            if (r["kind"] == kind &&
                (biggest == nullptr || std::abs(r["volume_m3"].get<double>()) >
                                           std::abs((*biggest)["volume_m3"].get<double>())))
                biggest = &r;
        }
        std::vector<double> d;
        *flagged = *near = 0;
        if (biggest == nullptr) return std::nan("");
        const Eigen::Vector2d c((*biggest)["centroid_m"][0], (*biggest)["centroid_m"][1]);
        for (std::size_t i = 0; i < mesh->vertices.size(); ++i) {
            if ((mesh->vertices[i].head<2>() - c).norm() > 0.7) continue;
            const double v = mesh->vertex_properties[0][i];
            if (!std::isfinite(v)) continue;
            d.push_back(v);
            ++*near;
            *flagged += mesh->vertex_properties[1][i] != 0;
        }
        if (d.empty()) return std::nan("");
        std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
        return d[d.size() / 2];
    };
    // The change mesh's regions with their volumes, on the surface (the scar on the 65 deg high
    // wall included, along its mean normal): every part's volume within 5 % or its U95, as the
    // issue asks of the 2.5D regions, and here within 5 % itself (measured: +0.0 % to +2.1 %, the
    // scar +6.1 % before decision 023; IoU 0.79-0.95); the vertices the
    // soundings' change along the normal contradicts set to no change before the patches (measured:
    // 3 144; the 8 regions of 13 on no part the soundings did not confirm before are gone with
    // them), no stable vertex in a region.
    EXPECT_TRUE(fs::exists(C / "change_regions_3d.geojson"));
    ASSERT_TRUE(cm.contains("regions")) << cm.dump();
    EXPECT_EQ(cm["regions"].size(), cm["patches"].get<std::size_t>());
    EXPECT_GE(cm["vetoed_by_soundings"].get<int>(), 1000);
    EXPECT_LE(s.at("change3d_region_false_regions"), 1);
    for (const char* part : {"slump_scar", "slump_toe", "backfill", "spill", "cut"}) {
        const std::string k = std::string("change3d_region_") + part + "_";
        EXPECT_EQ(s.at(k + "within"), 1)
            << part << ": " << s.at(k + "volume_detected_m3") << " +- " << s.at(k + "u95_m3");
        EXPECT_LT(std::abs(s.at(k + "volume_error_pct")), 5.0) << part;
        // The truth inside its U95 (measured: 5 of 5; decision 023).
        EXPECT_LE(std::abs(s.at(k + "volume_detected_m3") -
                           s.at(std::string("change_") + part + "_volume_true_m3")),
                  s.at(k + "u95_m3"))
            << part;
        // The bound on the whole outline: the regions grown by hysteresis into their
        // taper at half the LoD95 (decision 029; measured 0.883-0.970, the scar 0.776 before
        // with 22.7 % of its outline below its LoD95), and against the part's detectable
        // vertices (decision 023, section 5; 0.906-1.000).
        EXPECT_GE(s.at(k + "iou"), 0.8) << part;
        EXPECT_GE(s.at(k + "iou_detectable"), 0.8) << part;
    }
    EXPECT_LT(s.at("change3d_region_stable_flagged_share"), 0.001);
    int flagged = 0, near = 0;
    EXPECT_NEAR(median_near("cut", &flagged, &near), -0.38, 0.08);  // the scar, the largest cut
    EXPECT_GT(flagged, 0.9 * near);
    EXPECT_NEAR(median_near("fill", &flagged, &near), 0.6, 0.1);  // the toe or the heap
    EXPECT_GT(flagged, 0.9 * near);
    // The glTF: a GLB whose primitive carries the change as custom attributes, one per vertex.
    {
        std::ifstream glb(C / "change_mesh.glb", std::ios::binary);
        std::uint32_t head[5] = {};
        glb.read(reinterpret_cast<char*>(head), sizeof head);
        ASSERT_TRUE(glb.good());
        EXPECT_EQ(head[0], 0x46546C67u);  // "glTF"
        EXPECT_EQ(head[2], fs::file_size(C / "change_mesh.glb"));
        std::string text(head[3], ' ');
        glb.read(text.data(), static_cast<std::streamsize>(text.size()));
        const json g = json::parse(text);
        const json& attrs = g["meshes"][0]["primitives"][0]["attributes"];
        for (const char* a :
             {"POSITION", "NORMAL", "COLOR_0", "_DISTANCE", "_LOD95", "_SIGNIFICANCE"}) {
            ASSERT_TRUE(attrs.contains(a)) << a;
            EXPECT_EQ(g["accessors"][attrs[a].get<int>()]["count"].get<std::size_t>(),
                      mesh->vertices.size())
                << a;
        }
    }
    // The outlines: one feature per region, closed rings in the DEM's CRS.
    const json fc = ReadJson(C / "change_regions.geojson");
    EXPECT_EQ(fc["features"].size(), j["change"]["regions"].size());
    EXPECT_EQ(fc["crs"]["properties"]["name"],
              "urn:ogc:def:crs:EPSG::" + std::to_string(j["crs"]["epsg"].get<int>()));
}

void CompareScenario::ShiftedEpochIsRecoveredAndTripsTheNavigationGate() {
    std::string out;
    const fs::path C0 = dir_ / "C_plain";
    ASSERT_EQ(Compare(A(), B(), C0, &out), 0) << out;
    const fs::path Bs = CopyEpoch(B(), "P2_shifted");
    const Eigen::Vector2d shift(0.3, 0.4);  // 0.5 m
    RewriteDem(Bs / "dem.tif", 1.0, shift);
    fs::remove(Bs / "points_utm.ply");  // not moved with the DEM: no 3D change here
    const fs::path C = dir_ / "C_shifted";
    EXPECT_EQ(Compare(A(), Bs, C, &out, " --strict"), 4) << out;
    const json j0 = ReadJson(C0 / "compare.json")["registration"];
    const json j = ReadJson(C / "compare.json");
    const json& r = j["registration"];
    // The shifted epoch's correction is the plain one after undoing S: for every node p of B,
    // T_shifted(S(p)) = T_plain(p), and its yaw 1 deg less.
    auto correction = [](const json& reg) {
        const Eigen::Vector3d pivot(reg["pivot_m"][0], reg["pivot_m"][1], reg["pivot_m"][2]);
        const Eigen::Vector3d t(
            reg["translation_m"][0], reg["translation_m"][1], reg["translation_m"][2]);
        const Eigen::Vector3d w(reg["rotation_deg"]["roll"].get<double>() * kPi / 180,
                                reg["rotation_deg"]["pitch"].get<double>() * kPi / 180,
                                reg["rotation_deg"]["yaw"].get<double>() * kPi / 180);
        return [=](const Eigen::Vector3d& p) {
            const double a = w.norm();
            const Eigen::Matrix3d R = a > 0 ? Eigen::AngleAxisd(a, w / a).toRotationMatrix()
                                            : Eigen::Matrix3d::Identity();
            return Eigen::Vector3d(R * (p - pivot) + pivot + t);
        };
    };
    const auto T0 = correction(j0);
    const auto T1 = correction(r);
    auto dem = pitmap::proc::io::ReadGrid((B() / "dem.tif").string());
    ASSERT_TRUE(dem.ok());
    const auto& g = dem->grid;
    const Eigen::Vector2d c(g.x0 + 0.5 * (g.nx - 1) * g.resolution_m,
                            g.y0 + 0.5 * (g.ny - 1) * g.resolution_m);
    const double a = kPi / 180.0;
    double worst = 0;
    int nodes = 0;
    for (int jj = 0; jj < g.ny; jj += 25) {
        for (int ii = 0; ii < g.nx; ii += 25) {
            const float z = g.layers[0].values[static_cast<std::size_t>(jj) * g.nx + ii];
            if (!std::isfinite(z)) continue;
            const Eigen::Vector3d p(g.x0 + ii * g.resolution_m, g.y0 + jj * g.resolution_m, z);
            const Eigen::Vector2d q2 =
                Eigen::Rotation2Dd(a) * (p.head<2>() - c) + c + shift;  // S(p)
            const Eigen::Vector3d q(q2.x(), q2.y(), z);
            worst = std::max(worst, (T1(q) - T0(p)).norm());
            ++nodes;
        }
    }
    EXPECT_GT(nodes, 100);
    EXPECT_LT(worst, 0.02) << r.dump();
    EXPECT_NEAR(r["rotation_deg"]["yaw"].get<double>(),
                j0["rotation_deg"]["yaw"].get<double>() - 1.0,
                0.02);
    ASSERT_EQ(j["quality_gates"].size(), 1u);
    EXPECT_EQ(j["quality_gates"][0]["gate"], "correction_beyond_navigation");
    // After the correction the change is what it was.
    const auto s = pitmap::test::EvalScores(dir_ / "sim2/truth", C);
    EXPECT_EQ(s.at("change_parts_within"), s.at("change_parts"));
}

void CompareScenario::BadInputIsAClearErrorAndNoResult() {
    struct Case {
        std::string name;
        std::function<void(const fs::path&)> damage;
        std::string message;
    };
    const std::vector<Case> cases = {
        {"missing_dem",
         [](const fs::path& p) { fs::remove(p / "dem.tif"); },
         "missing product dem.tif"},
        {"damaged_survey",
         [](const fs::path& p) {
             std::fstream f(p / "survey.pitmap", std::ios::in | std::ios::out | std::ios::binary);
             f.seekp(static_cast<std::streamoff>(fs::file_size(p / "survey.pitmap") / 2));
             const char junk[8] = {1, 2, 3, 4, 5, 6, 7, 8};
             f.write(junk, sizeof junk);
         },
         "corrupt survey file"},
        {"other_datum",
         [](const fs::path& p) {
             json s = ReadJson(p / "summary.json");
             s["vertical_datum"]["datum"] = "geoid";
             s["vertical_datum"]["vertical_crs"] = "EGM96 height";
             std::ofstream(p / "summary.json") << s.dump();
         },
         "different vertical datums"},
        {"other_site",
         [](const fs::path& p) {
             json s = ReadJson(p / "summary.json");
             s["metadata"]["site"] = "Bejanca";
             std::ofstream(p / "summary.json") << s.dump();
         },
         "different sites"},
        {"other_crs",
         [](const fs::path& p) { RewriteDem(p / "dem.tif", 0, Eigen::Vector2d::Zero(), 30); },
         "different horizontal CRS"},
        {"no_overlap",
         [](const fs::path& p) { RewriteDem(p / "dem.tif", 0, Eigen::Vector2d(5000, 0)); },
         "do not overlap"},
    };
    for (const Case& c : cases) {
        const fs::path bad = CopyEpoch(B(), "P2_" + c.name);
        c.damage(bad);
        if (c.name == "other_site") {
            // Both must name a site for it to count: A names the quarry.
            const fs::path a = CopyEpoch(A(), "P1_site");
            json s = ReadJson(a / "summary.json");
            s["metadata"]["site"] = "Quarry";
            std::ofstream(a / "summary.json") << s.dump();
            std::string out;
            const fs::path C = dir_ / ("C_" + c.name);
            EXPECT_EQ(Compare(a, bad, C, &out), 1) << c.name << ": " << out;
            EXPECT_NE(out.find(c.message), std::string::npos) << c.name << ": " << out;
            EXPECT_FALSE(fs::exists(C / "compare.json")) << c.name;
            continue;
        }
        std::string out;
        const fs::path C = dir_ / ("C_" + c.name);
        EXPECT_EQ(Compare(A(), bad, C, &out), 1) << c.name << ": " << out;
        EXPECT_NE(out.find(c.message), std::string::npos) << c.name << ": " << out;
        EXPECT_FALSE(fs::exists(C / "compare.json")) << c.name;
    }
    // A folder that is not there: a usage error, and C is not even created.
    std::string out;
    const fs::path C = dir_ / "C_missing_folder";
    EXPECT_EQ(Compare(A(), dir_ / "no_such_folder", C, &out), 2) << out;
    EXPECT_NE(out.find("no_such_folder"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(C));
}

// A design surface: A's own DEM with a 0.3 m deep planned cut of 6 m x 6 m about its centre.
// A against it alone: 0.3 m x the cut's surveyed area above the design, within the stated
// uncertainty; A and B against it: both design rasters; a design in another CRS: an error.
void CompareScenario::DesignSurfaceVolumes() {
    auto dem = pitmap::proc::io::ReadGrid((A() / "dem.tif").string());
    ASSERT_TRUE(dem.ok()) << dem.error().message;
    pitmap::proc::io::GridRaster g = dem->grid;
    g.utm_zone = dem->horizontal_epsg % 100;
    g.northern = dem->horizontal_epsg < 32700;
    g.horizontal_only = true;
    std::vector<float> z;
    for (const auto& l : g.layers) {
        if (l.name == "elevation") z = l.values;
    }
    ASSERT_FALSE(z.empty());
    // The centre of A's surveyed nodes.
    double cx = 0, cy = 0;
    int filled = 0;
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            if (!std::isfinite(z[static_cast<std::size_t>(j) * g.nx + i])) continue;
            cx += g.x0 + i * g.resolution_m;
            cy += g.y0 + j * g.resolution_m;
            ++filled;
        }
    }
    cx /= filled;
    cy /= filled;
    double cut_area = 0;
    for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
            float& v = z[static_cast<std::size_t>(j) * g.nx + i];
            if (std::abs(g.x0 + i * g.resolution_m - cx) < 3 &&
                std::abs(g.y0 + j * g.resolution_m - cy) < 3 && std::isfinite(v)) {
                v -= 0.3f;
                cut_area += g.resolution_m * g.resolution_m;
            }
        }
    }
    g.layers = {{"elevation", "metre", z, pitmap::proc::io::GridBandKind::kContinuous}};
    const fs::path design = dir_ / "design.tif";
    fs::remove(design);
    ASSERT_TRUE(pitmap::proc::io::WriteCogGeoTiff(design.string(), g).ok());
    std::string out;
    const fs::path C = dir_ / "C_design";
    ASSERT_EQ(RunCommand(kBin + "/pitmap compare " + Quote(A()) + " --design " + Quote(design) +
                             " --out " + Quote(C),
                         &out),
              0)
        << out;
    ASSERT_TRUE(fs::exists(C / "design_a.tif"));
    const json d = ReadJson(C / "compare.json")["design"]["a"];
    const double truth = 0.3 * cut_area;
    EXPECT_GT(cut_area, 20.0);
    EXPECT_NEAR(d["above_design_m3"].get<double>(),
                truth,
                std::max(0.05 * truth, d["above_design_u95_m3"].get<double>()))
        << d.dump();
    EXPECT_NEAR(d["below_design_m3"].get<double>(), 0.0, 1e-3);  // float rounding
    EXPECT_NEAR(d["significant_above_area_m2"].get<double>(), cut_area, 0.05 * cut_area);
    // Over the significant nodes alone: the cut, with the survey's uncertainty over it only.
    EXPECT_NEAR(d["significant_above_m3"].get<double>(),
                truth,
                std::max(0.05 * truth, d["significant_above_u95_m3"].get<double>()))
        << d.dump();
    EXPECT_LT(d["significant_above_u95_m3"].get<double>(), 0.3 * truth);
    // With both surveys: each against the design, beside the comparison.
    const fs::path C2 = dir_ / "C_design_ab";
    ASSERT_EQ(Compare(A(), B(), C2, &out, " --no-3d --no-mesh --design " + Quote(design)), 0)
        << out;
    EXPECT_TRUE(fs::exists(C2 / "design_a.tif"));
    EXPECT_TRUE(fs::exists(C2 / "design_b.tif"));
    const json j2 = ReadJson(C2 / "compare.json");
    EXPECT_TRUE(j2["design"].contains("b"));
    EXPECT_TRUE(j2["change"].contains("regions"));
    // A design given as a mesh (A's own TSDF mesh, mesh_utm.ply): A's CUBE surface on it to
    // within the two surfaces' difference.
    const fs::path C4 = dir_ / "C_design_mesh";
    ASSERT_EQ(RunCommand(kBin + "/pitmap compare " + Quote(A()) + " --design " +
                             Quote(A() / "mesh_utm.ply") + " --out " + Quote(C4),
                         &out),
              0)
        << out;
    const json dm = ReadJson(C4 / "compare.json")["design"]["a"];
    EXPECT_GT(dm["compared_area_m2"].get<double>(), 0.8 * d["compared_area_m2"].get<double>());
    EXPECT_LT(std::abs(dm["mean_difference_m"].get<double>()), 0.02) << dm.dump();
    // A design in another CRS.
    const fs::path other = dir_ / "design_zone30.tif";
    fs::copy_file(design, other, fs::copy_options::overwrite_existing);
    RewriteDem(other, 0, Eigen::Vector2d::Zero(), 30);
    const fs::path C3 = dir_ / "C_design_crs";
    const int status = RunCommand(kBin + "/pitmap compare " + Quote(A()) + " --design " +
                                      Quote(other) + " --out " + Quote(C3),
                                  &out);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << out;
    EXPECT_NE(out.find("different horizontal CRS"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(C3 / "compare.json"));
}

// More than two surveys: A, B and B again three months later (no change in that interval),
// given as folders and as a list file; out of order or in another CRS: an error naming the
// folder, and no result.
void CompareScenario::SeriesOfSurveys() {
    const fs::path b2 = CopyEpoch(B(), "P3");
    json s = ReadJson(b2 / "summary.json");
    s["metadata"]["survey_start_utc"] = "2026-12-14T09:00:00Z";
    std::ofstream(b2 / "summary.json") << s.dump();
    std::string out;
    const fs::path O = dir_ / "S";
    const std::string fast = " --no-3d --no-mesh";
    ASSERT_EQ(RunCommand(kBin + "/pitmap compare " + Quote(A()) + " " + Quote(B()) + " " +
                             Quote(b2) + " --out " + Quote(O) + fast,
                         &out),
              0)
        << out;
    const json series = ReadJson(O / "series.json");
    ASSERT_EQ(series["intervals"].size(), 2u);
    const json& i1 = series["intervals"][0];
    const json& i2 = series["intervals"][1];
    EXPECT_TRUE(fs::exists(O / i1["folder"].get<std::string>() / "dod.tif"));
    EXPECT_TRUE(fs::exists(O / i2["folder"].get<std::string>() / "compare.json"));
    EXPECT_TRUE(fs::exists(O / "series.csv"));
    // Interval 1 is the plain comparison; interval 2 has no change; the cumulative is the first.
    const json plain = ReadJson(dir_ / "C" / "compare.json")["change"];
    EXPECT_NEAR(i1["fill_m3"].get<double>(), plain["fill"]["volume_m3"].get<double>(), 1e-6);
    EXPECT_NEAR(i1["cut_m3"].get<double>(), plain["cut"]["volume_m3"].get<double>(), 1e-6);
    EXPECT_NEAR(i2["net_m3"].get<double>(), 0.0, 1e-6);
    EXPECT_NEAR(series["cumulative_net_m3"].get<double>(), i1["net_m3"].get<double>(), 1e-9);
    EXPECT_GT(series["cumulative_net_u95_m3"].get<double>(), 0.0);
    // A list file, relative paths.
    std::ofstream(dir_ / "site.txt") << "# the quarry\nP1\n\nP2\nP3\n";
    const fs::path O2 = dir_ / "S_list";
    ASSERT_EQ(RunCommand(kBin + "/pitmap compare " + Quote(dir_ / "site.txt") + " --out " +
                             Quote(O2) + fast,
                         &out),
              0)
        << out;
    EXPECT_EQ(ReadJson(O2 / "series.json")["intervals"].size(), 2u);
    // Out of time order: the folder named.
    const fs::path O3 = dir_ / "S_order";
    int status = RunCommand(kBin + "/pitmap compare " + Quote(B()) + " " + Quote(A()) + " " +
                                Quote(b2) + " --out " + Quote(O3) + fast,
                            &out);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << out;
    EXPECT_NE(out.find(A().string() + " is out of time order"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(O3 / "series.json"));
    // Another CRS: the folder named.
    const fs::path other = CopyEpoch(B(), "P3_zone30");
    s["utm"]["epsg"] = 32630;
    std::ofstream(other / "summary.json") << s.dump();
    const fs::path O4 = dir_ / "S_crs";
    status = RunCommand(kBin + "/pitmap compare " + Quote(A()) + " " + Quote(B()) + " " +
                            Quote(other) + " --out " + Quote(O4) + fast,
                        &out);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << out;
    EXPECT_NE(out.find(other.string() + " is in another CRS"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(O4 / "series.json"));
}

// One test: the two runs of the quarry are made once (about a minute and a half) for all three.
TEST_F(CompareScenario, RepeatSurveysOfTheQuarry) {
    {
        SCOPED_TRACE("changes measured against the truth");
        ChangesMeasuredAgainstTruth();
    }
    {
        SCOPED_TRACE("a shifted epoch");
        ShiftedEpochIsRecoveredAndTripsTheNavigationGate();
    }
    {
        SCOPED_TRACE("bad input");
        BadInputIsAClearErrorAndNoResult();
    }
    {
        SCOPED_TRACE("a design surface");
        DesignSurfaceVolumes();
    }
    {
        SCOPED_TRACE("a series of surveys");
        SeriesOfSurveys();
    }
}

}  // namespace
