// SPDX-License-Identifier: MIT
// Scenario tests of `pitmap georef` and `pitmap calibrate` on the simulator's demo survey,
// scored against its ground truth with pitmap-eval (issue 6 numbers):
//   - georef with the true boresight: points RMS within 1.2x the RMS of the simulated range
//     noise (sigma = 0.002 r + 0.02 per sounding, from the ranges in points.ply);
//   - calibrate from the nominal boresight (0, 0, 0): each axis within 0.05 deg of the truth;
//   - vendor files (the raw NovAtel stream as a .gps file, the 83P datagrams as a .83P file,
//     GPS time from the topside clock plus an offset) give the soundings the log gives.
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/formats/ply.hpp"
#include "common/peak_memory.hpp"
#include "pitmap/raw_bytes_t.hpp"

#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using pitmap::test::EvalScores;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;
using pitmap::test::Scores;
using pitmap::test::SetTrueBoresight;

// RMS of sigma = 0.002 r + 0.02 over the points of a PLY product (the project's PLY reader).
double RangeNoiseRms(const fs::path& ply) {
    // The accepted soundings (status 0): points.ply also holds the rejected ones (issue 35).
    const auto mesh = pitmap::formats::ply::ReadMesh(ply.string(), {"range_m", "status"});
    EXPECT_TRUE(mesh.ok()) << (mesh.ok() ? "" : mesh.error().message);
    if (!mesh.ok()) return 0.0;
    const std::vector<double>& range_m = mesh->vertex_properties.at(0);
    const std::vector<double>& status = mesh->vertex_properties.at(1);
    double ss = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < range_m.size(); ++i) {
        if (status[i] != 0) continue;
        const double s = 0.002 * range_m[i] + 0.02;
        ss += s * s;
        ++n;
    }
    return n == 0 ? 0.0 : std::sqrt(ss / static_cast<double>(n));
}

class DemoScenario : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("pitmap_scenario_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        std::string out;
        ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario demo --vendor-files --out " +
                                 Quote(dir_ / "sim"),
                             &out),
                  0)
            << out;
        truth_ = ReadJson(dir_ / "sim/truth/boresight.json");
    }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(dir_);
    }
    std::map<std::string, double> Eval(const fs::path& products, const std::string& extra = "") {
        return EvalScores(dir_ / "sim/truth", products, extra);
    }
    fs::path dir_;
    json truth_;
};

TEST_F(DemoScenario, GeorefWithTrueBoresightIsWithinTheRangeNoise) {
    ASSERT_TRUE(SetTrueBoresight(dir_ / "sim"));
    const fs::path p = dir_ / "products";
    std::string out;
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim/log") + " --out " + Quote(p), &out),
        0)
        << out;
    const auto s = Eval(p);
    ASSERT_TRUE(s.count("points_rms_m")) << "pitmap-eval printed no points_rms_m";
    const double noise = RangeNoiseRms(p / "points.ply");
    RecordProperty("points_rms_m", std::to_string(s.at("points_rms_m")));
    RecordProperty("range_noise_rms_m", std::to_string(noise));
    EXPECT_GT(noise, 0.02);
    EXPECT_LT(s.at("points_rms_m"), 1.2 * noise) << "range noise RMS " << noise;
    EXPECT_GT(s.at("points_scored"), 400000);
}

// Issue 17: the per-sounding TPU is honest and the CUBE surface lies on the true terrain. The
// demo lasts 120 s, two INS height-error correlation times (60 s), so one draw of the INS
// height error (sigma 1.5 cm) shifts every sounding alike: the share within TVU is checked
// loosely here; the 93-97 % figure is measured on bejanca (docs/benchmarks.md, benchmark command).
TEST_F(DemoScenario, GridTpuIsHonestAndTheDemLiesOnTheTruth) {
    ASSERT_TRUE(SetTrueBoresight(dir_ / "sim"));
    const fs::path p = dir_ / "products";
    std::string out;
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim/log") + " --out " + Quote(p), &out),
        0)
        << out;
    std::ofstream(dir_ / "grid.yaml") << "grid:\n  write_sounding_tpu: true\n";
    ASSERT_EQ(RunCommand(kBin + "/pitmap grid --out " + Quote(p) + " --config " +
                             Quote(dir_ / "grid.yaml"),
                         &out),
              0)
        << out;
    for (const char* f : {"dem.tif", "dem.bag", "soundings_tpu.ply"}) {
        EXPECT_TRUE(fs::exists(p / f)) << f;
    }
    const json grid = ReadJson(p / "summary.json").at("stages").at("grid");
    EXPECT_NE(grid.at("error_model").get<std::string>().find("uncertainty:"), std::string::npos)
        << "the simulator's vehicle.yaml states its error model";
    EXPECT_EQ(grid.at("utm_epsg").get<int>(), 32629);
    const auto s = Eval(p);
    ASSERT_TRUE(s.count("tpu_within_tvu") && s.count("dem_mean_abs_m")) << out;
    for (const char* k :
         {"tpu_within_tvu", "tpu_within_thu", "dem_mean_abs_m", "dem_fill_insonified"}) {
        RecordProperty(k, std::to_string(s.at(k)));
    }
    EXPECT_GT(s.at("tpu_soundings_scored"), 400000);
    EXPECT_GT(s.at("tpu_within_tvu"), 0.85);
    EXPECT_LT(s.at("tpu_within_tvu"), 0.99);
    EXPECT_GT(s.at("tpu_within_thu"), 0.85);
    EXPECT_LT(s.at("tpu_within_thu"), 0.99);
    EXPECT_LT(s.at("dem_mean_abs_m"), 0.04);
    EXPECT_GE(s.at("dem_fill_insonified"), 0.98);
}

TEST_F(DemoScenario, CalibrateRecoversTheBoresightFromTheNominal) {
    const fs::path p = dir_ / "products";
    std::string out;
    ASSERT_EQ(
        RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim/log") + " --out " + Quote(p), &out),
        0)
        << out;
    const double before = Eval(p).at("boresight_error_deg");
    ASSERT_EQ(RunCommand(kBin + "/pitmap calibrate --out " + Quote(p), &out), 0) << out;
    const auto s = Eval(p);
    const json b = ReadJson(p / "boresight.json");
    const json summary = ReadJson(p / "summary.json");
    const json& st = summary.at("stages").at("calibrate");
    // The stated uncertainty covers the error: range noise alone (formal) would not, the INS's
    // attitude error over the window (the simulator's INS reports its 1-sigma) does.
    ASSERT_TRUE(b.contains("sd_deg")) << b.dump();
    int i = 0;
    for (const char* axis : {"roll_deg", "pitch_deg", "yaw_deg"}) {
        const double err = b.at(axis).get<double>() - truth_.at(axis).get<double>();
        const double sd = b.at("sd_deg").at(i).get<double>();
        EXPECT_NEAR(sd, st.at("sd_deg").at(i).get<double>(), 1e-12);
        EXPECT_GT(sd, st.at("formal_sd_deg").at(i).get<double>()) << axis;
        EXPECT_GT(st.at("ins_attitude_sd_deg").at(i).get<double>(), 0.005) << axis;
        EXPECT_LT(std::abs(err), 3 * sd) << axis << " sd " << sd;
        EXPECT_NEAR(b.at(axis).get<double>(), truth_.at(axis).get<double>(), 0.05) << axis;
        ++i;
    }
    EXPECT_GT(before, 1.0);
    EXPECT_LT(s.at("boresight_error_deg"), 0.05);
    EXPECT_LT(st.at("residual_after_rms_m").get<double>(),
              st.at("residual_before_rms_m").get<double>());
}

}  // namespace

TEST_F(DemoScenario, VendorFilesGiveTheSoundingsTheLogGives) {
    ASSERT_TRUE(SetTrueBoresight(dir_ / "sim"));
    // The raw streams of the log, as the receiver and the topside program would have written
    // them to disk: a NovAtel binary file and a .83P file (records concatenated).
    const fs::path vendor = dir_ / "vendor";
    fs::create_directories(vendor);
    std::vector<fs::path> logs;
    for (const auto& e : fs::directory_iterator(dir_ / "sim/log"))
        if (e.path().extension() == ".lcmlog") logs.push_back(e.path());
    std::sort(logs.begin(), logs.end());
    std::ofstream nav(vendor / "nav.gps", std::ios::binary),
        sonar(vendor / "survey.83P", std::ios::binary);
    std::size_t records = 0;
    for (const auto& path : logs) {
        lcm::LogFile log(path.string(), "r");
        ASSERT_TRUE(log.good()) << path;
        while (const lcm::LogEvent* ev = log.readNextEvent()) {
            if (ev->channel != "RAW_NOVATEL_COM1" && ev->channel != "RAW_DELTAT_UDP") continue;
            pitmap::raw_bytes_t raw;
            ASSERT_GT(raw.decode(ev->data, 0, ev->datalen), 0);
            auto& out = ev->channel == "RAW_NOVATEL_COM1" ? nav : sonar;
            out.write(reinterpret_cast<const char*>(raw.data.data()),
                      static_cast<std::streamsize>(raw.data.size()));
            if (ev->channel == "RAW_DELTAT_UDP") ++records;
        }
    }
    nav.close();
    sonar.close();
    ASSERT_EQ(records, 1200u);
    fs::copy_file(dir_ / "sim/log/vehicle.yaml", vendor / "vehicle.yaml");

    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim/log") + " --out " +
                             Quote(dir_ / "from_log"),
                         &out),
              0)
        << out;
    // The demo topside clock runs 3600 + 2.37 s ahead of UTC (tools/sim/scenario.cpp): the
    // offset (sonar clock minus UTC) is +3602.37 s; its 35 ppm drift adds at most 4 ms over the
    // 2-minute survey.
    ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(vendor / "nav.gps") + " " +
                             Quote(vendor / "survey.83P") + " --sonar-clock-offset 3602.37 --out " +
                             Quote(dir_ / "from_files"),
                         &out),
              0)
        << out;
    // The same offset from the vehicle file (sonar.clock_offset_s), no option given.
    {
        std::ifstream in(vendor / "vehicle.yaml");
        std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::string unknown = "  clock_offset_s: null\n";
        const auto at = text.find(unknown);
        ASSERT_NE(at, std::string::npos) << text;
        text.replace(at, unknown.size(), "  clock_offset_s: 3602.37\n");
        std::ofstream(vendor / "vehicle_with_offset.yaml") << text;
    }
    std::string from_vehicle;
    ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(vendor / "nav.gps") + " " +
                             Quote(vendor / "survey.83P") + " --vehicle " +
                             Quote(vendor / "vehicle_with_offset.yaml") + " --out " +
                             Quote(dir_ / "from_vehicle"),
                         &from_vehicle),
              0)
        << from_vehicle;
    // Configured, so checked against the 83P headers rather than searched for.
    const json vehicle_summary = ReadJson(dir_ / "from_vehicle/summary.json");
    EXPECT_EQ(vehicle_summary.at("sonar_clock_offset_s"), 3602.37);
    EXPECT_EQ(vehicle_summary.at("sonar_clock").at("configured"), true) << from_vehicle;
    const auto log_scores = Eval(dir_ / "from_log");
    const auto file_scores = Eval(dir_ / "from_files");
    ASSERT_TRUE(file_scores.count("points_rms_m")) << out;
    EXPECT_NEAR(file_scores.at("points_scored"),
                log_scores.at("points_scored"),
                0.01 * log_scores.at("points_scored"));
    EXPECT_NEAR(file_scores.at("points_rms_m"), log_scores.at("points_rms_m"), 0.003);
    const auto vehicle_scores = Eval(dir_ / "from_vehicle");
    ASSERT_TRUE(vehicle_scores.count("points_rms_m")) << from_vehicle;
    EXPECT_EQ(vehicle_scores.at("points_scored"), file_scores.at("points_scored"));
    EXPECT_EQ(vehicle_scores.at("points_rms_m"), file_scores.at("points_rms_m"));
}

TEST_F(DemoScenario, RawChannelsRedecodeToTheSameSoundings) {
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim/log") + " --out " +
                             Quote(dir_ / "decoded"),
                         &out),
              0)
        << out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim/log") + " --from-raw --out " +
                             Quote(dir_ / "raw"),
                         &out),
              0)
        << out;
    const auto decoded = Eval(dir_ / "decoded");
    const auto raw = Eval(dir_ / "raw");
    ASSERT_TRUE(raw.count("points_scored")) << out;
    EXPECT_EQ(raw.at("points_scored"), decoded.at("points_scored"));
    EXPECT_NEAR(raw.at("points_rms_m"), decoded.at("points_rms_m"), 0.001);
    EXPECT_NEAR(raw.at("trajectory_ate_rmse_m"), decoded.at("trajectory_ate_rmse_m"), 0.001);
}

// `pitmap run` end to end on the demo: every product, every stage in summary.json, and the
// survey no worse than the INS alone; then the stand-alone stages re-make the same products
// from the folder (tsdf.vdb -> mesh, survey.pitmap -> fuse).
TEST_F(DemoScenario, RunMakesEveryProductAndStagesRerunFromTheFolder) {
    const fs::path p = dir_ / "products";
    const bool with_report = fs::exists(kBin + "/pitmap-report");
    std::string out;
    ASSERT_EQ(RunCommand(kBin + "/pitmap run " + Quote(dir_ / "sim/log") + " --out " + Quote(p) +
                             (with_report ? "" : " --no-report"),
                         &out),
              0)
        << out;
    std::vector<std::string> products = {"summary.json",
                                         "survey.pitmap",
                                         "trajectory.csv",
                                         "trajectory_initial.csv",
                                         "trajectory_ins.csv",
                                         "points.ply",
                                         "points_initial.ply",
                                         "points.las",
                                         "boresight.json",
                                         "tsdf.vdb",
                                         "mesh.ply",
                                         "mesh.obj",
                                         "mesh.glb",
                                         "mesh_filled.ply",
                                         "mesh_filled.obj",
                                         "mesh_filled.glb",
                                         "mesh_initial.ply",
                                         "dem.tif",
                                         "dem.bag"};
    if (with_report) {
        products.push_back("report.html");
        products.push_back("report_engineering.html");
    }
    for (const auto& f : products) {
        EXPECT_TRUE(fs::exists(p / f) && fs::file_size(p / f) > 0) << f << " missing or empty";
    }
    const json summary = ReadJson(p / "summary.json");
    std::vector<std::string> order;
    for (const auto& n : summary.at("stage_order")) order.push_back(n.get<std::string>());
    // Georeferenced once; the points, the mount and the survey file exported once, after SLAM
    // and the cleaning (its first pass, before the calibration, is in the record of its last).
    std::vector<std::string> expected = {"ingest",
                                         "georef",
                                         "calibrate",
                                         "fuse_initial",
                                         "mesh_initial",
                                         "slam",
                                         "clean",
                                         "export",
                                         "grid",
                                         "fuse",
                                         "mesh"};
    if (with_report) expected.push_back("report");
    EXPECT_EQ(order, expected);
    for (const auto& n : order) {
        const json& st = summary.at("stages").at(n);
        EXPECT_GE(st.at("seconds").get<double>(), 0.0) << n;
        EXPECT_GT(st.at("peak_rss_mb").get<double>(), 1.0) << n;
    }
    EXPECT_GT(summary.at("total_seconds").get<double>(), 0.0);
    EXPECT_GE(summary.at("process").at("cores").get<int>(), 1);
    {
        // `pitmap` restarted itself with glibc.malloc.hugetlb=1 where the kernel's THP mode is
        // madvise (unless told not to), and says so.
        std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
        const std::string thp((std::istreambuf_iterator<char>(f)),
                              std::istreambuf_iterator<char>());
        const char* env = std::getenv("GLIBC_TUNABLES");
        const auto restart =
            pitmap::HugePageRestartBuiltIn()
                ? pitmap::HugePageTunables(env, std::getenv("PITMAP_HUGEPAGES"), thp)
                : std::nullopt;
        EXPECT_EQ(summary.at("process").at("malloc_huge_pages").get<bool>(),
                  pitmap::MallocOnHugePages(restart ? restart->c_str() : env, thp))
            << thp;
    }
    // The mesh before SLAM is a picture: every 2nd ping at twice the voxel size, yet the whole
    // surface (voxels twice as large: about a quarter of the final mesh's triangles; holes
    // between the kept pings would make it fewer).
    const json& fi = summary.at("stages").at("fuse_initial");
    EXPECT_EQ(fi.at("ping_stride").get<int>(), 2);
    EXPECT_LT(fi.at("voxel_updates").get<double>(),
              0.25 * summary.at("stages").at("fuse").at("voxel_updates").get<double>());
    EXPECT_GT(summary.at("stages").at("mesh_initial").at("triangles").get<double>(),
              0.15 * summary.at("stages").at("mesh").at("triangles").get<double>());
    EXPECT_EQ(summary.at("stages").at("export").at("trajectory"), "slam");
    const json& slam = summary.at("stages").at("slam");
    EXPECT_EQ(slam.at("slices").get<int>(), 1200);
    EXPECT_FALSE(slam.at("iterations").empty());
    // RTK throughout: no section for the coarse search, and the list says so.
    EXPECT_TRUE(slam.at("coarse_search").is_array());
    EXPECT_EQ(slam.at("coarse_search").size(), slam.at("sections_searched").get<std::size_t>());

    const auto s = Eval(p, "--ate-window 30");
    ASSERT_TRUE(s.count("trajectory_ate_rmse_before_m") && s.count("mesh_mean_abs_m")) << out;
    RecordProperty("ate_before_m", std::to_string(s.at("trajectory_ate_rmse_before_m")));
    RecordProperty("ate_after_m", std::to_string(s.at("trajectory_ate_rmse_m")));
    RecordProperty("mesh_mean_abs_m", std::to_string(s.at("mesh_mean_abs_m")));
    EXPECT_LT(s.at("boresight_error_deg"), 0.1);
    // The demo's INS is RTK grade: SLAM must not make it worse overall, nor any 30 s window by
    // more than 5 mm (issue 15; docs/decisions/003-absolute-sigma-scale.md). Overall "not worse"
    // within 1 mm, about 3 % of the demo's ATE: the INS's own error re-estimated from thousands
    // of pairs moves by a few tenths of a millimetre between seeds, either way.
    EXPECT_LE(s.at("trajectory_ate_rmse_m"), s.at("trajectory_ate_rmse_before_m") + 0.001);
    ASSERT_TRUE(s.count("trajectory_ate_worst_window_increase_m"));
    RecordProperty("ate_worst_window_increase_m",
                   std::to_string(s.at("trajectory_ate_worst_window_increase_m")));
    EXPECT_LT(s.at("trajectory_ate_worst_window_increase_m"), 0.005);
    EXPECT_LT(s.at("points_rms_m"), 1.2 * RangeNoiseRms(p / "points.ply"));
    EXPECT_LT(s.at("mesh_mean_abs_m"), 0.05);
    ASSERT_TRUE(s.count("dem_mean_abs_m")) << "pitmap-eval scored no dem.tif";
    EXPECT_LT(s.at("dem_mean_abs_m"), 0.04);
    EXPECT_GE(s.at("dem_fill_insonified"), 0.98);

    const auto triangles = summary.at("stages").at("mesh").at("triangles").get<std::int64_t>();
    const auto voxels = summary.at("stages").at("fuse").at("active_voxels").get<double>();
    ASSERT_EQ(RunCommand(kBin + "/pitmap mesh --out " + Quote(p), &out), 0) << out;
    EXPECT_EQ(
        ReadJson(p / "summary.json").at("stages").at("mesh").at("triangles").get<std::int64_t>(),
        triangles)
        << "meshing tsdf.vdb again gives the mesh of the run";
    ASSERT_EQ(RunCommand(kBin + "/pitmap fuse --out " + Quote(p), &out), 0) << out;
    EXPECT_NEAR(
        ReadJson(p / "summary.json").at("stages").at("fuse").at("active_voxels").get<double>(),
        voxels,
        0.005 * voxels)
        << "fusing on the survey file's SLAM trajectory gives the volume of the run";

    // Issue 14, case 5: damaged products are errors naming the file (exit 1), never crashes.
    // 20 bytes overwritten in tsdf.vdb crashed `pitmap mesh` in 18 of 20 seeds before.
    const fs::path c = dir_ / "corrupt";
    auto damaged = [&](const std::string& file,
                       const std::string& stage,
                       unsigned seed,
                       const std::function<void(std::string&)>& damage) {
        fs::remove_all(c);
        fs::create_directories(c);
        for (const char* f : {"summary.json", "survey.pitmap", "tsdf.vdb"}) {
            fs::copy_file(p / f, c / f);
        }
        std::ifstream in(c / file, std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        in.close();
        damage(bytes);
        std::ofstream(c / file, std::ios::binary | std::ios::trunc) << bytes;
        std::string text;
        const int status = RunCommand(kBin + "/pitmap " + stage + " --out " + Quote(c), &text);
        // summary.json is a report: a damaged one is started again, with a warning.
        const int want = file == "summary.json" ? 0 : 1;
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == want)
            << file << " seed " << seed << " (" << stage << "): " << text;
        EXPECT_NE(text.find((c / file).string()), std::string::npos) << text;
        EXPECT_EQ(text.find("internal error"), std::string::npos) << text;
    };
    auto overwrite = [](unsigned seed) {
        return [seed](std::string& b) {
            std::mt19937 rng(seed);
            for (int k = 0; k < 20; ++k) b[rng() % b.size()] = static_cast<char>(rng() & 0xff);
        };
    };
    for (unsigned seed = 1; seed <= 5; ++seed) {
        damaged("tsdf.vdb", "mesh", seed, overwrite(seed));
        damaged("survey.pitmap", "fuse", seed, overwrite(seed));
    }
    damaged("tsdf.vdb", "mesh", 0, [](std::string& b) { b.resize(b.size() / 2); });
    damaged("survey.pitmap", "fuse", 0, [](std::string& b) { b.resize(b.size() / 2); });
    damaged("survey.pitmap", "mesh", 0, [](std::string& b) { b.resize(10); });
    for (const char* text : {"[1, 2]", "{\"world_origin\": 5, \"mount\": {}}", "{\"trunc"}) {
        damaged("summary.json", "mesh", 0, [text](std::string& b) { b = text; });
    }
}

TEST(PipelineCli, StagesOnAFolderWithoutTheirInputsSayWhatToRunFirst) {
    const fs::path p = fs::temp_directory_path() / ("pitmap_empty_" + std::to_string(::getpid()));
    fs::create_directories(p);
    for (const char* stage : {"slam", "grid", "fuse", "mesh"}) {
        std::string out;
        EXPECT_EQ(RunCommand(kBin + "/pitmap " + stage + " --out " + Quote(p), &out) != 0, true)
            << stage;
        EXPECT_NE(out.find("first"), std::string::npos) << stage << ": " << out;
    }
    fs::remove_all(p);
}

namespace {

// Exit status of a command run by RunCommand (-1 when it did not exit normally).
int ExitCode(int status) {
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The demo's vendor files (NovAtel .gps, topside .83P) with vehicle.yaml beside them.
fs::path VendorDir(const fs::path& sim) {
    fs::copy_file(sim / "log/vehicle.yaml",
                  sim / "vendor/vehicle.yaml",
                  fs::copy_options::overwrite_existing);
    return sim / "vendor";
}

std::vector<std::string> Gates(const json& summary) {
    std::vector<std::string> g;
    if (summary.contains("quality_gates")) {
        for (const auto& e : summary["quality_gates"])
            g.push_back(e.at("stage").get<std::string>() + "/" + e.at("gate").get<std::string>());
    }
    return g;
}

// A faster calibration for the tests: fewer soundings per ping.
fs::path FastCalibrationConfig(const fs::path& dir) {
    const fs::path p = dir / "fast_calibrate.yaml";
    std::ofstream(p) << "calibrate:\n  beam_stride: 8\n";
    return p;
}

}  // namespace

// Issue 15: the topside clock of the demo's .83P file runs 3602.37 s ahead of UTC and nobody
// says so. The 83P headers' NMEA position places the pings (georef), the soundings refine it
// to milliseconds (calibrate), and no quality gate trips.
TEST_F(DemoScenario, VendorFilesWithAnUnknownClockAreTimedFromTheirHeaders) {
    const fs::path vendor = VendorDir(dir_ / "sim");
    const json clock_truth = ReadJson(dir_ / "sim/truth/sonar_clock.json");
    // The correction added to the ping times (ingest used offset 0) is minus the sonar clock
    // offset; the clock drifts: take the survey's mean.
    const double truth = -clock_truth.at("ingest_sonar_clock_offset_s").get<double>() -
                         0.5 * (clock_truth.at("last_ping_offset_s").get<double>() -
                                clock_truth.at("first_ping_offset_s").get<double>());
    const fs::path p = dir_ / "unknown_clock";
    std::string out;
    ASSERT_EQ(ExitCode(RunCommand(
                  kBin + "/pitmap georef " + Quote(vendor) + " --strict --out " + Quote(p), &out)),
              0)
        << out;
    json summary = ReadJson(p / "summary.json");
    const json& coarse = summary.at("sonar_clock").at("coarse");
    EXPECT_EQ(coarse.at("method"), "header position") << out;
    EXPECT_NEAR(coarse.at("correction_s").get<double>(), truth, 1.0) << out;
    // The topside clock runs 35 ppm fast; the head's attitude sensor times its rate, and the
    // correction is minus that.
    const json& rate = summary.at("sonar_clock").at("rate");
    const double drift = clock_truth.at("topside_clock_drift_ppm").get<double>();
    EXPECT_TRUE(rate.at("found").get<bool>()) << rate.dump();
    RecordProperty("clock_rate_error_ppm",
                   std::to_string(rate.at("rate_ppm").get<double>() + drift));
    EXPECT_NEAR(rate.at("rate_ppm").get<double>(),
                -drift,
                std::max(3 * rate.at("rate_sigma_ppm").get<double>(), 5.0))
        << rate.dump();
    EXPECT_LT(rate.at("rate_sigma_ppm").get<double>(), 25.0) << rate.dump();  // 120 s only
    ASSERT_EQ(ExitCode(RunCommand(kBin + "/pitmap calibrate --strict --out " + Quote(p) +
                                      " --config " + Quote(FastCalibrationConfig(dir_)),
                                  &out)),
              0)
        << out;
    summary = ReadJson(p / "summary.json");
    const double found = summary.at("sonar_clock").at("correction_s").get<double>();
    RecordProperty("clock_error_ms", std::to_string(1e3 * (found - truth)));
    EXPECT_NEAR(found, truth, 0.005) << out;
    EXPECT_TRUE(Gates(summary).empty()) << summary["quality_gates"].dump();
    EXPECT_TRUE(ReadJson(p / "boresight.json").contains("sonar_clock"));
    const auto s = Eval(p);
    EXPECT_LT(s.at("boresight_error_deg"), 0.1);
}

// Each gate of the georef stage trips on the data that should trip it; --strict makes it
// exit status 4, and the message names what was found.
TEST_F(DemoScenario, GeorefGatesTripOnAWrongClockAndOnMissingNavigation) {
    const fs::path vendor = VendorDir(dir_ / "sim");
    const json clock_truth = ReadJson(dir_ / "sim/truth/sonar_clock.json");
    const double truth = clock_truth.at("ingest_sonar_clock_offset_s").get<double>();
    std::string out;
    // A configured offset 1.5 s off: the headers disagree.
    char offset[32];
    std::snprintf(offset, sizeof(offset), "%.3f", truth + 1.5);
    const fs::path wrong = dir_ / "wrong_clock";
    EXPECT_EQ(ExitCode(RunCommand(kBin + "/pitmap georef " + Quote(vendor) +
                                      " --strict --sonar-clock-offset " + offset + " --out " +
                                      Quote(wrong),
                                  &out)),
              4)
        << out;
    auto gates = Gates(ReadJson(wrong / "summary.json"));
    EXPECT_NE(std::find(gates.begin(), gates.end(), "georef/sonar_clock_disagrees"), gates.end())
        << out;
    // The calibration cannot absorb 1.5 s either: its residual stays far above the noise.
    EXPECT_EQ(ExitCode(RunCommand(kBin + "/pitmap calibrate --strict --out " + Quote(wrong) +
                                      " --config " + Quote(FastCalibrationConfig(dir_)),
                                  &out)),
              4)
        << out;
    gates = Gates(ReadJson(wrong / "summary.json"));
    EXPECT_TRUE(
        std::find(gates.begin(), gates.end(), "calibrate/calibration_residual") != gates.end() ||
        std::find(gates.begin(), gates.end(), "calibrate/calibration_not_verified") != gates.end())
        << out;
    // SLAM on a trajectory whose pings are 1.5 s off must not bend a good RTK track to fit
    // them: it stays within the INS sigma (or the INS is restored there, slam_beyond_ins_sigma),
    // and the passes' disagreement that is left is a gate, not a quiet success.
    EXPECT_EQ(ExitCode(RunCommand(kBin + "/pitmap slam --strict --out " + Quote(wrong), &out)), 4)
        << out;
    const json wrong_summary = ReadJson(wrong / "summary.json");
    gates = Gates(wrong_summary);
    EXPECT_NE(std::find(gates.begin(), gates.end(), "slam/slam_inconsistent"), gates.end()) << out;
    const json& ins_check = wrong_summary.at("stages").at("slam").at("ins_check");
    EXPECT_TRUE(ins_check.at("reverted").get<bool>() ||
                ins_check.at("moved_beyond_allowance").get<int>() == 0)
        << ins_check.dump();
    // Without --strict the same run finishes (exit 0) and says so.
    out.clear();
    EXPECT_EQ(
        ExitCode(RunCommand(kBin + "/pitmap georef " + Quote(vendor) + " --sonar-clock-offset " +
                                offset + " --out " + Quote(dir_ / "lenient"),
                            &out)),
        0)
        << out;
    EXPECT_NE(out.find("quality gate georef/sonar_clock_disagrees"), std::string::npos) << out;
    EXPECT_NE(out.find("--strict makes this an error"), std::string::npos) << out;

    // Navigation that covers only the first half of the sonar file.
    const fs::path half = dir_ / "half_nav";
    fs::create_directories(half);
    fs::copy_file(vendor / "demo.83P", half / "demo.83P");
    fs::copy_file(vendor / "vehicle.yaml", half / "vehicle.yaml");
    {
        std::ifstream in(vendor / "demo.gps", std::ios::binary);
        std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
        std::ofstream(half / "demo.gps", std::ios::binary)
            .write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
    }
    out.clear();
    char exact[32];
    std::snprintf(exact, sizeof(exact), "%.4f", truth);
    EXPECT_EQ(ExitCode(RunCommand(kBin + "/pitmap georef " + Quote(half) +
                                      " --strict --sonar-clock-offset " + exact + " --out " +
                                      Quote(dir_ / "half_products"),
                                  &out)),
              4)
        << out;
    EXPECT_NE(out.find("pings lie outside the navigation span"), std::string::npos) << out;
    EXPECT_NE(out.find("navigation "), std::string::npos) << out;

    // No overlap at all: a clear error naming both spans, not a product.
    out.clear();
    EXPECT_EQ(
        ExitCode(RunCommand(kBin + "/pitmap georef " + Quote(vendor) +
                                " --sonar-clock-offset 5000 --out " + Quote(dir_ / "no_overlap"),
                            &out)),
        1)
        << out;
    EXPECT_NE(out.find("navigation and sonar do not overlap in time: navigation "),
              std::string::npos)
        << out;
}

namespace {

// The demo simulated with `synth_args` into dir/sim, georeferenced from its logs into
// dir/products; returns the products folder (empty after a failure, which it reports).
fs::path SynthAndGeoref(const fs::path& dir, const std::string& synth_args) {
    std::string out;
    if (RunCommand(kBin + "/pitmap-sim synth --scenario demo " + synth_args + " --out " +
                       Quote(dir / "sim"),
                   &out) != 0) {
        ADD_FAILURE() << out;
        return {};
    }
    const fs::path p = dir / "products";
    if (RunCommand(kBin + "/pitmap georef " + Quote(dir / "sim/log") + " --out " + Quote(p),
                   &out) != 0) {
        ADD_FAILURE() << out;
        return {};
    }
    return p;
}

}  // namespace

// Issue 15, gate calibration_not_verified: the daemon's stamping error steps from +50 ms to
// -50 ms halfway through the survey (its clock re-locked), so no single latency explains both
// halves. The calibration fits its own window; on a window of the other half that mount and
// latency fit worse than the nominal ones. The gate trips, --strict exits 4 and the nominal mount
// is kept.
TEST(DemoLatency, AClockStepMidSurveyIsNotVerifiedAndTheNominalMountIsKept) {
    const fs::path dir =
        fs::temp_directory_path() / ("pitmap_scenario_step_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    const fs::path p =
        SynthAndGeoref(dir, "--sonar-stamp-error-ms 50 --sonar-stamp-error-step 60 -50");
    ASSERT_FALSE(p.empty());
    std::string out;
    const json before = ReadJson(p / "boresight.json");
    // Windows of 40 s: the 120 s survey has other windows to verify on (the default window,
    // 300 s, is the whole survey: nothing independent is left, and the run says so).
    const fs::path config = dir / "windows_40s.yaml";
    std::ofstream(config) << "calibrate:\n  beam_stride: 8\n  segment_duration_s: 40\n";
    EXPECT_EQ(ExitCode(RunCommand(kBin + "/pitmap calibrate --strict --out " + Quote(p) +
                                      " --config " + Quote(config),
                                  &out)),
              4)
        << out;
    const auto gates = Gates(ReadJson(p / "summary.json"));
    EXPECT_NE(std::find(gates.begin(), gates.end(), "calibrate/calibration_not_verified"),
              gates.end())
        << out;
    EXPECT_NE(out.find("the nominal mount and sonar clock are kept"), std::string::npos) << out;
    // What was kept is what georef used.
    const json after = ReadJson(p / "boresight.json");
    for (const char* k : {"roll_deg", "pitch_deg", "yaw_deg"}) {
        EXPECT_DOUBLE_EQ(after.at(k).get<double>(), before.at(k).get<double>()) << k;
    }
    EXPECT_DOUBLE_EQ(ReadJson(p / "summary.json").at("sonar_clock").value("latency_s", 0.0), 0.0);
    if (!HasFailure()) fs::remove_all(dir);
}

// Issue 15: the daemon stamps its pings 35 ms late (a residual latency of its clock model); the
// calibration finds it with the boresight, within 2 ms, and the ping times are corrected.
TEST(DemoLatency, ADaemonStampingLatencyIsFoundWithinTwoMilliseconds) {
    const fs::path dir =
        fs::temp_directory_path() / ("pitmap_scenario_latency_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    const fs::path p = SynthAndGeoref(dir, "--sonar-stamp-error-ms 35");
    ASSERT_FALSE(p.empty());
    std::string out;
    ASSERT_EQ(ExitCode(RunCommand(kBin + "/pitmap calibrate --strict --out " + Quote(p) +
                                      " --config " + Quote(FastCalibrationConfig(dir)),
                                  &out)),
              0)
        << out;
    const json summary = ReadJson(p / "summary.json");
    const json& clk = summary.at("sonar_clock");
    EXPECT_EQ(clk.at("source"), "pitmap-acqd: GPS-disciplined receive stamps");
    const double found = clk.at("correction_s").get<double>();
    RecordProperty("latency_error_ms", std::to_string(1e3 * (found + 0.035)));
    EXPECT_NEAR(found, -0.035, 0.002) << out;
    if (!HasFailure()) fs::remove_all(dir);
}
