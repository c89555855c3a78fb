// SPDX-License-Identifier: MIT
// Scenario test of a real vendor line (issue 35 item 6): `pitmap run` on the R2Sonic 2026 line
// that QINSy recorded as XTF (tests/data/xtf/, 923 pings over 48 s, no truth). It must end with
// exit 0 and products that open; calibration and SLAM must say "no overlap" (one line, no
// crossing lines) and keep the nominal mount; the ingest must say what it assumed; the
// soundings must be plausible for the head's 31.9 m range setting.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/formats/ply.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

const fs::path kData = fs::path(PITMAP_TEST_DATA_DIR) / "xtf";

std::string Head(const fs::path& p, std::size_t n) {
    std::ifstream in(p, std::ios::binary);
    std::string s(n, '\0');
    in.read(s.data(), static_cast<std::streamsize>(n));
    s.resize(static_cast<std::size_t>(in.gcount()));
    return s;
}

bool HasGate(const json& summary, const std::string& stage, const std::string& gate) {
    if (!summary.contains("quality_gates")) return false;
    for (const auto& g : summary["quality_gates"]) {
        if (g.value("stage", "") == stage && g.value("gate", "") == gate) return true;
    }
    return false;
}

TEST(XtfScenario, PitmapRunProcessesTheR2SonicLineEndToEnd) {
    const fs::path dir = FreshDir("pitmap_xtf");
    const fs::path P = dir / "p";
    std::string out;
    // The report too where its program is built (a build without it would fail the run).
    const bool report = fs::exists(kBin + "/pitmap-report");
    const auto t0 = std::chrono::steady_clock::now();
    const int status =
        RunCommand(kBin + "/pitmap run " + Quote(kData / "r2sonic2026_150708_R2Testing_0001.xtf") +
                       " --out " + Quote(P) + " --vehicle " + Quote(kData / "vehicle.yaml") +
                       (report ? "" : " --no-report"),
                   &out);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_EQ(status, 0) << out;
    std::printf("pitmap run on the XTF line: %.1f s%s\n", seconds, report ? "" : " (no report)");
    if (report) {
        EXPECT_TRUE(fs::exists(P / "report.html"));
    }

    const json summary = ReadJson(P / "summary.json");
    const json& ingest = summary["stages"]["ingest"];
    EXPECT_EQ(ingest["pings"].get<int>(), 923) << ingest.dump();
    EXPECT_EQ(ingest["nav_samples"].get<int>(), 1204) << ingest.dump();
    EXPECT_EQ(ingest["events"].get<int>(), 923 + 1203 + 1204);  // XTF packets
    // What had to be assumed is said, in the summary and in the log.
    const auto& assumed = ingest["assumed"];
    ASSERT_TRUE(assumed.is_array());
    const auto says = [&](const std::string& what) {
        return std::any_of(assumed.begin(), assumed.end(), [&](const json& a) {
            return a.get<std::string>().find(what) != std::string::npos;
        });
    };
    EXPECT_TRUE(says("sigmas")) << assumed.dump();
    EXPECT_TRUE(says("sound speed")) << assumed.dump();
    EXPECT_TRUE(says("mount: lever arm 0.000 0.000 0.000 m")) << assumed.dump();
    EXPECT_NE(out.find("assumed: XTF navigation sigmas"), std::string::npos) << out;

    // One line: nothing to calibrate or register, said as gates; the nominal mount is kept.
    EXPECT_TRUE(HasGate(summary, "calibrate", "calibration_no_overlap")) << summary.dump();
    EXPECT_TRUE(HasGate(summary, "slam", "slam_no_overlap")) << summary.dump();
    const json& mount = summary["mount"];
    for (const char* k : {"roll_deg", "pitch_deg", "yaw_deg"}) {
        if (mount.contains(k)) {
            EXPECT_NEAR(mount[k].get<double>(), 0.0, 1e-9) << mount.dump();
        }
    }

    // Products that open.
    for (const char* f : {"points.ply", "points.las", "dem.tif", "mesh.ply"}) {
        ASSERT_TRUE(fs::exists(P / f)) << f;
        EXPECT_GT(fs::file_size(P / f), 1000u) << f;
    }
    EXPECT_EQ(Head(P / "points.las", 4), "LASF");
    const std::string tif = Head(P / "dem.tif", 4);
    EXPECT_TRUE(tif == std::string("II*\0", 4) || tif == std::string("II+\0", 4));
    const auto mesh = pitmap::formats::ply::ReadMesh((P / "mesh.ply").string());
    ASSERT_TRUE(mesh.ok()) << mesh.error().message;
    EXPECT_GT(mesh->triangles.size(), 1000u);

    // Plausible soundings: heights below the first navigation position (the world origin, at
    // the water line within the boat's heave) between a few metres and the 31.9 m range setting;
    // none NaN.
    // The accepted ones (status 0; points.ply also holds the rejected soundings, issue 35).
    const auto points = pitmap::formats::ply::ReadMesh((P / "points.ply").string(), {"status"});
    ASSERT_TRUE(points.ok()) << points.error().message;
    std::vector<double> depth;
    depth.reserve(points->vertices.size());
    for (std::size_t i = 0; i < points->vertices.size(); ++i) {
        const auto& v = points->vertices[i];
        ASSERT_TRUE(std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()));
        if (points->vertex_properties[0][i] == 0) depth.push_back(-v.z());
    }
    ASSERT_GT(depth.size(), 923u * 200u);
    std::sort(depth.begin(), depth.end());
    const double median = depth[depth.size() / 2];
    std::printf("points %zu, depth below the origin: min %.2f median %.2f max %.2f m\n",
                depth.size(),
                depth.front(),
                median,
                depth.back());
    EXPECT_GT(median, 3.0);
    EXPECT_LT(median, 30.0);
    EXPECT_GT(depth.front(), 0.5);
    EXPECT_LT(depth.back(), 31.9 + 1.0);
    EXPECT_LT(seconds, 60.0);
}

}  // namespace
