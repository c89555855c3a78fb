// SPDX-License-Identifier: MIT
// Issue 34 part 5: a products folder is consistent or it says it is not. One command at a time
// (P/.pitmap.lock names its holder), an unwritable --out refused before any work with the
// reason, a run id in survey.pitmap, summary.json and the products: a survey.pitmap of another
// survey copied into P gives a new summary.json (with a warning), `pitmap mesh` refuses a
// tsdf.vdb of the other run and the report leaves the other run's points out with a line; a
// georef that fails half-way has removed every product of the earlier survey first.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

bool Contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

std::string ReadText(const fs::path& p) {
    std::ifstream in(p);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A NovAtel capture of the test data: enough input for `pitmap georef` to start ingesting.
fs::path NavLog(const fs::path& dir) {
    fs::create_directories(dir / "logs");
    const fs::path log = dir / "logs" / "nav.gps";
    fs::copy_file(fs::path(PITMAP_TEST_DATA_DIR) / "novatel" / "oem7drv_ins2.gps",
                  log,
                  fs::copy_options::overwrite_existing);
    return log;
}

TEST(ProductsFolder, SecondCommandOnALockedFolderFailsNamingTheHolder) {
    const fs::path dir = FreshDir("pitmap_products_lock");
    const fs::path P = dir / "P";
    fs::create_directories(P);
    // The holder: this test, as a pitmap command would hold it.
    const int fd = ::open((P / ".pitmap.lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
    const std::string holder = "pid 4242\ncommand pitmap run logs --out P\nstarted 2026-01-01\n";
    ASSERT_EQ(::write(fd, holder.data(), holder.size()), static_cast<ssize_t>(holder.size()));
    for (const char* command : {"grid", "mesh", "report", "calibrate"}) {
        std::string out;
        EXPECT_NE(RunCommand(kBin + "/pitmap " + command + " --out " + Quote(P), &out), 0) << out;
        EXPECT_TRUE(Contains(out, "is in use by another pitmap command")) << command << ": " << out;
        EXPECT_TRUE(Contains(out, "pid 4242")) << out;
        EXPECT_TRUE(Contains(out, "pitmap run logs --out P")) << out;
    }
    {
        std::string out;
        EXPECT_NE(
            RunCommand(kBin + "/pitmap georef " + Quote(NavLog(dir)) + " --out " + Quote(P), &out),
            0);
        EXPECT_TRUE(Contains(out, "pid 4242")) << out;
        EXPECT_FALSE(Contains(out, "ingest:")) << "worked on a locked folder: " << out;
    }
    ::close(fd);  // released: the next command gets past the lock (and fails on what it finds)
    std::string out;
    EXPECT_NE(RunCommand(kBin + "/pitmap grid --out " + Quote(P), &out), 0);
    EXPECT_FALSE(Contains(out, "in use")) << out;
    EXPECT_TRUE(Contains(out, "survey.pitmap")) << out;
}

TEST(ProductsFolder, TileCommandsShareTheLockAndExcludeTheOthers) {
    const fs::path dir = FreshDir("pitmap_products_shared_lock");
    const fs::path P = dir / "P";
    fs::create_directories(P);
    std::ofstream(dir / "tiles.yaml") << "tiles:\n  enabled: true\n  tile_size_m: 40\n"
                                         "  overlap_m: 12\n";
    const std::string config = " --config " + Quote(dir / "tiles.yaml");
    const std::vector<std::string> tile_commands = {
        "grid --tile=0,0", "fuse --tile=-1,2", "grid --list-tiles", "fuse --list-tiles"};
    // A tile command holding it (shared, no name written): other tile commands get past the
    // lock (and fail on the missing survey), every other command is refused.
    int fd = ::open((P / ".pitmap.lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_SH | LOCK_NB), 0);
    for (const std::string& command : tile_commands) {
        std::string out;
        EXPECT_NE(RunCommand(kBin + "/pitmap " + command + " --out " + Quote(P) + config, &out), 0);
        EXPECT_FALSE(Contains(out, "in use")) << command << ": " << out;
        EXPECT_TRUE(Contains(out, "survey.pitmap")) << command << ": " << out;
    }
    for (const std::string command : {"grid", "fuse --merge-tiles", "grid --merge-tiles"}) {
        std::string out;
        EXPECT_NE(RunCommand(kBin + "/pitmap " + command + " --out " + Quote(P) + config, &out), 0);
        EXPECT_TRUE(Contains(out, "is in use by another pitmap command (per-tile commands"))
            << command << ": " << out;
    }
    ::close(fd);
    // Any other command holding it: the tile commands are refused too.
    fd = ::open((P / ".pitmap.lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
    for (const std::string& command : tile_commands) {
        std::string out;
        EXPECT_NE(RunCommand(kBin + "/pitmap " + command + " --out " + Quote(P) + config, &out), 0);
        EXPECT_TRUE(Contains(out, "is in use by another pitmap command")) << command << ": " << out;
    }
    ::close(fd);
}

TEST(ProductsFolder, UnwritableOutFailsBeforeIngestWithTheReason) {
    const fs::path dir = FreshDir("pitmap_products_readonly");
    const fs::path log = NavLog(dir);
    // Tests run as root, where permissions do not bite: a folder under a regular file cannot
    // be made by anyone.
    std::ofstream(dir / "regular_file") << "x";
    const fs::path P = dir / "regular_file" / "sub";
    std::string out;
    EXPECT_NE(RunCommand(kBin + "/pitmap georef " + Quote(log) + " --out " + Quote(P), &out), 0);
    EXPECT_TRUE(Contains(out, P.string())) << out;
    EXPECT_TRUE(Contains(out, "Not a directory")) << out;
    EXPECT_FALSE(Contains(out, "ingest")) << "the inputs were read first: " << out;
}

// One short simulated survey georeferenced into two folders: two runs of the same data.
class ProductsOfTwoRuns : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = new fs::path(FreshDir("pitmap_products_runs"));
        std::string out;
        ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario demo --duration 20 --out " +
                                 Quote(*dir_ / "sim"),
                             &out),
                  0)
            << out;
    }
    static void TearDownTestSuite() {
        delete dir_;
        dir_ = nullptr;
    }
    static fs::path Georef(const std::string& name) {
        const fs::path P = *dir_ / name;
        std::string out;
        EXPECT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(*dir_ / "sim" / "log") + " --out " +
                                 Quote(P),
                             &out),
                  0)
            << out;
        return P;
    }
    static std::string RunId(const fs::path& P) {
        return ReadJson(P / "summary.json").value("run_id", std::string());
    }
    static fs::path* dir_;
};
fs::path* ProductsOfTwoRuns::dir_ = nullptr;

TEST_F(ProductsOfTwoRuns, EachRunHasItsIdInTheSurveyTheSummaryAndTheProducts) {
    const fs::path a = Georef("a");
    const std::string id = RunId(a);
    ASSERT_EQ(id.size(), 32u) << id;
    EXPECT_TRUE(Contains(ReadText(a / "points.ply"), "comment pitmap_run_id " + id));
    EXPECT_EQ(ReadJson(a / "boresight.json").value("run_id", std::string()), id);
    EXPECT_TRUE(Contains(ReadText(a / "survey.pitmap"), "\"run_id\":\"" + id + "\""));
    // LAS: the id's bytes as the project GUID (header bytes 8..23).
    std::ifstream las(a / "points.las", std::ios::binary);
    char guid[16];
    las.seekg(8);
    ASSERT_TRUE(las.read(guid, 16));
    char hex[33];
    for (int i = 0; i < 16; ++i) {
        std::snprintf(hex + 2 * i, 3, "%02x", static_cast<unsigned char>(guid[i]));
    }
    EXPECT_EQ(std::string(hex, 32), id);
    // No temporary file is left beside the products.
    for (const auto& e : fs::directory_iterator(a)) {
        EXPECT_FALSE(Contains(e.path().filename().string(), "partial")) << e.path();
    }
    // A second georef is a new run.
    const fs::path b = Georef("b");
    EXPECT_NE(RunId(b), id);
}

TEST_F(ProductsOfTwoRuns, SurveyOfAnotherRunCopiedInIsNoticedByEveryLaterStage) {
    const fs::path p = Georef("p");
    const fs::path q = Georef("q");
    const std::string p_id = RunId(p), q_id = RunId(q);
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(p), &out), 0) << out;
    fs::copy_file(p / "points.ply", *dir_ / "p_points.ply", fs::copy_options::overwrite_existing);
    // The other survey's state copied over P's (what the tester did).
    fs::copy_file(q / "survey.pitmap", p / "survey.pitmap", fs::copy_options::overwrite_existing);

    out.clear();
    EXPECT_NE(RunCommand(kBin + "/pitmap mesh --out " + Quote(p), &out), 0) << out;
    EXPECT_TRUE(Contains(out, "tsdf.vdb is from another run (run id " + p_id)) << out;
    EXPECT_FALSE(fs::exists(p / "mesh.ply"));

    out.clear();
    EXPECT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(p), &out), 0) << out;
    EXPECT_TRUE(Contains(out, "summary.json is of another run (run id " + p_id)) << out;
    const nlohmann::json summary = ReadJson(p / "summary.json");
    EXPECT_EQ(summary.value("run_id", std::string()), q_id);
    // The new summary is this run's alone: no georef stage of the other one.
    EXPECT_FALSE(summary["stages"].contains("georef")) << summary.dump();
    EXPECT_FALSE(summary["stages"].contains("fuse")) << summary.dump();

    if (::access((kBin + "/pitmap-report").c_str(), X_OK) != 0) {
        GTEST_SKIP() << "pitmap-report not built";
    }
    // The grid stage wrote points.ply again with this run's id; P's own earlier points, now of
    // another run than the survey (as a killed re-run would leave them), are left out of the
    // report with a line.
    fs::copy_file(
        *dir_ / "p_points.ply", p / "points_initial.ply", fs::copy_options::overwrite_existing);
    out.clear();
    EXPECT_EQ(RunCommand(kBin + "/pitmap report --out " + Quote(p), &out), 0) << out;
    const std::string page = ReadText(p / "report.html");
    EXPECT_TRUE(Contains(page, "points_initial.ply is from another run (id " + p_id)) << out;
    EXPECT_TRUE(Contains(page, "not drawn")) << out;
    EXPECT_FALSE(Contains(page, "points.ply is from another run")) << out;
}

TEST_F(ProductsOfTwoRuns, AGeorefThatFailsHalfWayLeavesNothingOfTheEarlierSurvey) {
    // What a kill -9 during a re-run leaves: the earlier products are removed before the new
    // georef starts work, so what remains cannot be mistaken for the new survey's.
    const fs::path p = Georef("r");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(p), &out), 0) << out;
    ASSERT_TRUE(fs::exists(p / "tsdf.vdb"));
    std::ofstream(p / "mesh.ply") << "an earlier mesh";
    std::ofstream(p / ".partial-points.ply") << "a killed writer's file";
    std::ofstream(*dir_ / "broken_vehicle.yaml") << "pitmap_vehicle: 1\n";
    out.clear();
    EXPECT_NE(RunCommand(kBin + "/pitmap georef " + Quote(*dir_ / "sim" / "log") + " --out " +
                             Quote(p) + " --vehicle " + Quote(*dir_ / "broken_vehicle.yaml"),
                         &out),
              0)
        << out;
    for (const char* stale : {"survey.pitmap",
                              "summary.json",
                              "points.ply",
                              "points.las",
                              "boresight.json",
                              "trajectory_ins.csv",
                              "tsdf.vdb",
                              "mesh.ply",
                              ".partial-points.ply"}) {
        EXPECT_FALSE(fs::exists(p / stale)) << stale << " of the earlier survey is still there";
    }
    // ... and the report says the folder is unusable rather than drawing anything.
    out.clear();
    EXPECT_NE(RunCommand(kBin + "/pitmap report --out " + Quote(p), &out), 0) << out;
}

TEST_F(ProductsOfTwoRuns, AStageThatMakesItsViewFileCannotLoadTheSurveyKeepsItsProducts) {
    // The stage commands make the view's scratch file while they load the survey (decisions
    // 041, 047): what a killed writer left goes before the load, the products they replace only
    // once the survey is loaded. A survey that cannot be loaded (here a damaged edit log) keeps
    // them.
    const fs::path p = Georef("k");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(p), &out), 0) << out;
    ASSERT_TRUE(fs::exists(p / "tsdf.vdb"));
    std::ofstream(p / "edits.json") << "{\"pitmap_edits\": ";
    for (const char* stage : {"calibrate", "slam", "clean", "grid", "fuse", "rerun"}) {
        std::ofstream(p / ".partial-points.ply") << "a killed writer's file";
        out.clear();
        EXPECT_NE(RunCommand(kBin + "/pitmap " + std::string(stage) + " --out " + Quote(p), &out),
                  0)
            << stage << ": " << out;
        EXPECT_TRUE(Contains(out, "edits.json")) << stage << ": " << out;
        EXPECT_TRUE(fs::exists(p / "tsdf.vdb")) << stage << " removed a product before the load";
        EXPECT_TRUE(fs::exists(p / "points.ply")) << stage;
        EXPECT_FALSE(fs::exists(p / ".partial-points.ply"))
            << stage << " left a killed writer's file";
    }
    // Once the survey loads, the stage replaces them as before.
    fs::remove(p / "edits.json");
    out.clear();
    ASSERT_EQ(RunCommand(kBin + "/pitmap slam --out " + Quote(p), &out), 0) << out;
    EXPECT_FALSE(fs::exists(p / "tsdf.vdb"))
        << "slam kept the volume of the trajectory it replaced";
    EXPECT_TRUE(fs::exists(p / "trajectory.csv"));
}

}  // namespace
