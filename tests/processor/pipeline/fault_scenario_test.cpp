// SPDX-License-Identifier: MIT
// Issue 34's fault cases, each made by the simulator or by editing what it wrote (never a copied
// file), each ending in one of: a clear error naming the problem (exit status != 0), a named
// quality gate with its cause, or products within the normal accuracy. None may end with exit
// status 0, wrong products and no word.
//   - the vehicle file: a lever arm with its sign flipped, in cm, in mm; the head turned 180 or
//     90 degrees from the connector the file gives; an x lever arm of the wrong sign, which only
//     the calibration sees;
//   - the clocks and the navigation: a topside clock step, a .83P of another survey (with and
//     without a given offset), INS status windows (aligning, high variance), an INS drift the
//     INS does not report;
//   - the inputs: two recordings with the same time stamps, a day apart, 5.5 km apart.
// The demo scenario (120 s, 1 200 pings) keeps each case under a few seconds of processing.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using pitmap::test::EvalScores;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;
using pitmap::test::SetTrueBoresight;

bool Contains(const std::string& text, const std::string& what) {
    return text.find(what) != std::string::npos;
}

// The gates of a products folder's summary, as "stage/gate: message" lines.
std::string Gates(const fs::path& products) {
    std::string s;
    if (!fs::exists(products / "summary.json")) return s;
    const json j = ReadJson(products / "summary.json");
    for (const auto& g : j.value("quality_gates", json::array())) {
        s +=
            g.value("stage", "") + "/" + g.value("gate", "") + ": " + g.value("message", "") + "\n";
    }
    return s;
}

class FaultScenario : public ::testing::Test {
protected:
    static fs::path Root() {
        static const fs::path root =
            fs::temp_directory_path() / ("pitmap_fault_" + std::to_string(::getpid()));
        return root;
    }
    // A simulated demo survey with extra pitmap-sim options, made once per name.
    static fs::path Sim(const std::string& name, const std::string& options = "") {
        const fs::path dir = Root() / name;
        if (fs::exists(dir / "log/vehicle.yaml")) return dir;
        fs::create_directories(dir);
        std::string out;
        const int rc = RunCommand(
            kBin + "/pitmap-sim synth --scenario demo --out " + Quote(dir) + " " + options, &out);
        EXPECT_EQ(rc, 0) << out;
        return dir;
    }
    static void TearDownTestSuite() {
        if (!::testing::UnitTest::GetInstance()->Failed()) fs::remove_all(Root());
    }
    fs::path Fresh(const std::string& name) {
        const fs::path p = Root() / "work" / name;
        fs::remove_all(p);
        fs::create_directories(p);
        return p;
    }
    // Replaces the line starting with `key` (after its indentation) in a vehicle.yaml.
    static void SetVehicleLine(const fs::path& yaml,
                               const std::string& key,
                               const std::string& value) {
        std::ifstream in(yaml);
        std::ostringstream out;
        bool found = false;
        for (std::string line; std::getline(in, line);) {
            const auto at = line.find_first_not_of(' ');
            if (at != std::string::npos && line.compare(at, key.size() + 1, key + ":") == 0) {
                line = line.substr(0, at) + key + ": " + value;
                found = true;
            }
            out << line << "\n";
        }
        in.close();
        ASSERT_TRUE(found) << key << " not in " << yaml;
        std::ofstream(yaml) << out.str();
    }
    // A copy of a simulated log folder with the vehicle file edited.
    fs::path EditedLog(const std::string& name,
                       const std::string& key,
                       const std::string& value,
                       const fs::path& sim) {
        const fs::path log = Fresh(name) / "log";
        fs::copy(sim / "log", log, fs::copy_options::recursive);
        SetVehicleLine(log / "vehicle.yaml", key, value);
        return log;
    }
    // One input folder holding the logs of two simulated surveys (a_*.lcmlog from `a`,
    // b_*.lcmlog from `b`) and the vehicle file of `a`.
    fs::path TwoRecordings(const std::string& name, const fs::path& a, const fs::path& b) {
        const fs::path in = Fresh(name) / "in";
        fs::create_directories(in);
        for (const auto& [sim, prefix] : {std::pair{a, "a_"}, {b, "b_"}}) {
            for (const auto& e : fs::directory_iterator(sim / "log")) {
                if (e.path().extension() == ".lcmlog")
                    fs::copy_file(e.path(), in / (prefix + e.path().filename().string()));
            }
        }
        fs::copy_file(a / "log/vehicle.yaml", in / "vehicle.yaml");
        return in;
    }
    int Pitmap(const std::string& args, std::string* out) {
        return RunCommand(kBin + "/pitmap " + args, out);
    }
};

// ---- The vehicle file ----

TEST_F(FaultScenario, LeverArmWithItsSignFlippedStopsAtStartNamingTheSign) {
    const fs::path log = EditedLog("flipped", "lever_arm_m", "[-0.8, 0, -0.25]", Sim("base"));
    std::string out;
    EXPECT_NE(Pitmap("run " + Quote(log) + " --out " + Quote(log.parent_path() / "P"), &out), 0);
    EXPECT_TRUE(Contains(out,
                         "sonar.lever_arm_m: [-0.8, 0, -0.25] puts the transducer 0.25 m "
                         "above the water line"))
        << out;
    EXPECT_TRUE(Contains(out, "is its sign flipped?")) << out;
    // Found before any work: no survey model was written.
    EXPECT_FALSE(fs::exists(log.parent_path() / "P/survey.pitmap"));
}

TEST_F(FaultScenario, LeverArmInCentimetresOrMillimetresIsNamedWithTheUnit) {
    std::string out;
    const fs::path cm = EditedLog("cm", "lever_arm_m", "[0.8, 0, 25]", Sim("base"));
    EXPECT_NE(Pitmap("georef " + Quote(cm) + " --out " + Quote(cm.parent_path() / "P"), &out), 0);
    EXPECT_TRUE(Contains(out, "25 m below the water line")) << out;
    EXPECT_TRUE(Contains(out, "z in centimetres? 25 cm is 0.25 m")) << out;
    out.clear();
    const fs::path mm = EditedLog("mm", "lever_arm_m", "[800, 0, 250]", Sim("base"));
    EXPECT_NE(Pitmap("georef " + Quote(mm) + " --out " + Quote(mm.parent_path() / "P"), &out), 0);
    EXPECT_TRUE(Contains(out, "or in millimetres ([0.8, 0, 0.25] m)?")) << out;
}

TEST_F(FaultScenario, HeadTurnedFromTheGivenConnectorIsFoundInTheSoundings) {
    for (const auto& [connector, words] :
         {std::pair<std::string, std::string>{"forward", "the fan is mirrored"},
          {"port", "the fan is placed along the track"}}) {
        SCOPED_TRACE(connector);
        const fs::path log =
            EditedLog("connector_" + connector, "connector", connector, Sim("base"));
        std::string out;
        EXPECT_NE(Pitmap("georef " + Quote(log) + " --out " + Quote(log.parent_path() / "P"), &out),
                  0);
        EXPECT_TRUE(Contains(out, words)) << out;
        EXPECT_TRUE(Contains(out, "sonar.mount.connector")) << out;
        EXPECT_TRUE(Contains(Gates(log.parent_path() / "P"), "georef/mount_inconsistent")) << out;
    }
    // The right connector passes the same check (it is not a check that always fails).
    std::string out;
    const fs::path p = Fresh("connector_aft") / "P";
    ASSERT_EQ(Pitmap("georef " + Quote(Sim("base") / "log") + " --out " + Quote(p), &out), 0)
        << out;
    const json mc = ReadJson(p / "summary.json").at("mount_check");
    EXPECT_TRUE(mc.at("checked").get<bool>()) << mc.dump();
    EXPECT_TRUE(mc.at("consistent").get<bool>()) << mc.dump();
    EXPECT_LT(std::abs(mc.at("roll_gain").get<double>()), 0.2) << mc.dump();
}

TEST_F(FaultScenario, LeverArmXOfTheWrongSignIsACalibrationErrorNamingTheLeverArm) {
    const fs::path log = EditedLog("x_flipped", "lever_arm_m", "[-0.8, 0, 0.25]", Sim("base"));
    std::string out;
    EXPECT_NE(Pitmap("run " + Quote(log) + " --out " + Quote(log.parent_path() / "P") +
                         " --no-slam --no-report",
                     &out),
              0);
    EXPECT_TRUE(Contains(out, "beyond the 5.0 deg a mount can be off")) << out;
    EXPECT_TRUE(Contains(out, "the lever arm's x")) << out;
    EXPECT_TRUE(Contains(Gates(log.parent_path() / "P"), "calibrate/boresight_implausible")) << out;
}

// ---- Clocks and navigation ----

TEST_F(FaultScenario, TopsideClockStepIsFoundAtItsPingAndEachSideGetsItsOffset) {
    const fs::path sim = Sim("clock_step", "--vendor-files --topside-clock-step 30 1.0");
    ASSERT_TRUE(SetTrueBoresight(sim));
    const fs::path p = Fresh("clock_step") / "P";
    std::string out;
    ASSERT_EQ(Pitmap("georef " + Quote(sim / "vendor") + " --vehicle " +
                         Quote(sim / "log/vehicle.yaml") + " --out " + Quote(p),
                     &out),
              0)
        << out;
    const json steps = ReadJson(p / "summary.json").at("sonar_clock").at("steps");
    ASSERT_EQ(steps.at("steps").size(), 1u) << steps.dump(1);
    const json& st = steps.at("steps").at(0);
    EXPECT_TRUE(st.at("resolved").get<bool>()) << st.dump();
    EXPECT_NEAR(st.at("step_s").get<double>(), 1.0, 0.05) << st.dump();
    // The step is at 30 s: ping 300 of the survey (10 Hz), within a ping.
    EXPECT_NEAR(static_cast<double>(st.at("ping_index").get<std::int64_t>()), 300.0, 2.0);
    EXPECT_TRUE(Contains(out, "the topside clock steps +1.0")) << out;
    // The soundings on both sides are where the truth is.
    const auto s = EvalScores(sim / "truth", p);
    EXPECT_LT(s.at("points_rms_m"), 0.08) << out;
}

TEST_F(FaultScenario, SonarFileOfAnotherSurveyMatchesNowhereWithOrWithoutAnOffset) {
    const fs::path ours = Sim("vendor_a", "--vendor-files");
    const fs::path other = Sim("vendor_b", "--vendor-files --origin 40.4445 -7.7820");
    const fs::path in = Fresh("mixed_vendor") / "in";
    fs::create_directories(in);
    fs::copy_file(ours / "vendor/demo.gps", in / "demo.gps");
    fs::copy_file(other / "vendor/demo.83P", in / "demo.83P");
    std::string out;
    EXPECT_NE(Pitmap("georef " + Quote(in) + " --vehicle " + Quote(ours / "log/vehicle.yaml") +
                         " --out " + Quote(in.parent_path() / "P"),
                     &out),
              0);
    EXPECT_TRUE(Contains(out, "match this navigation nowhere")) << out;
    out.clear();
    const json truth = ReadJson(other / "truth/sonar_clock.json");
    const double offset = truth.at("ingest_sonar_clock_offset_s").get<double>();
    EXPECT_NE(Pitmap("georef " + Quote(in) + " --vehicle " + Quote(ours / "log/vehicle.yaml") +
                         " --sonar-clock-offset " + std::to_string(offset) + " --out " +
                         Quote(in.parent_path() / "P2"),
                     &out),
              0);
    EXPECT_TRUE(Contains(out, "with the configured offset")) << out;
    EXPECT_TRUE(Contains(out, "is this .83P of this survey?")) << out;
}

TEST_F(FaultScenario, InsStatusWindowsAreCountedSaidAndAGate) {
    {
        const fs::path sim = Sim("aligning", "--ins-status-window 40 70 aligning");
        ASSERT_TRUE(SetTrueBoresight(sim));
        const fs::path p = Fresh("aligning") / "P";
        std::string out;
        ASSERT_EQ(Pitmap("georef " + Quote(sim / "log") + " --out " + Quote(p), &out), 0) << out;
        const json j = ReadJson(p / "summary.json");
        const json& ing = j.at("stages").at("ingest");
        EXPECT_GT(ing.at("nav_not_navigating").get<std::int64_t>(), 1000) << ing.dump();
        EXPECT_TRUE(Contains(out, "INS status INS_ALIGNING")) << out;
        EXPECT_TRUE(Contains(Gates(p), "georef/ins_not_good")) << out;
        EXPECT_TRUE(Contains(Gates(p), "not georeferenced")) << Gates(p);
        // The 30 s without a solution are not georeferenced on a guess.
        EXPECT_GT(j.at("stages").at("georef").at("pings_in_nav_gap").get<std::int64_t>(), 250);
    }
    {
        const fs::path sim = Sim("high_variance", "--ins-status-window 40 70 high_variance");
        const fs::path p = Fresh("high_variance") / "P";
        std::string out;
        ASSERT_EQ(Pitmap("georef " + Quote(sim / "log") + " --out " + Quote(p), &out), 0) << out;
        const json ing = ReadJson(p / "summary.json").at("stages").at("ingest");
        EXPECT_GT(ing.at("nav_degraded").get<std::int64_t>(), 1000) << ing.dump();
        EXPECT_EQ(ing.at("nav_not_navigating").get<std::int64_t>(), 0);
        EXPECT_TRUE(Contains(Gates(p), "INS_HIGH_VARIANCE")) << out;
        EXPECT_TRUE(Contains(Gates(p), "kept, down-weighted")) << Gates(p);
    }
}

TEST_F(FaultScenario, InsDriftTheInsDoesNotReportIsANavigationDriftGate) {
    const fs::path sim = Sim("drift", "--ins-drift 50 80 0 1.0");
    ASSERT_TRUE(SetTrueBoresight(sim));
    const fs::path p = Fresh("drift") / "P";
    std::string out;
    ASSERT_EQ(
        Pitmap("run " + Quote(sim / "log") + " --out " + Quote(p) + " --no-calibrate --no-report",
               &out),
        0)
        << out;
    // SLAM holds the trajectory to the INS's 1 cm sigma: it sees the drift as passes that
    // disagree, worst in the window of the drift (50..88 s with the INS's recovery).
    const std::string gates = Gates(p);
    EXPECT_TRUE(Contains(gates, "slam/slam_inconsistent")) << out;
    EXPECT_TRUE(Contains(gates, "navigation drift")) << gates;
    EXPECT_TRUE(Contains(gates, "worst windows (from the first ping): +60..+90 s")) << gates;
    const json windows =
        ReadJson(p / "summary.json").at("stages").at("slam").at("consistency_windows");
    EXPECT_EQ(windows.size(), 4u) << windows.dump();
    // The same survey without the drift: its passes agree (no gate).
    const fs::path copy = Fresh("no_drift") / "sim";
    fs::copy(Sim("base"), copy, fs::copy_options::recursive);
    ASSERT_TRUE(SetTrueBoresight(copy));
    const fs::path clean = copy.parent_path() / "P";
    out.clear();
    ASSERT_EQ(Pitmap("run " + Quote(copy / "log") + " --out " + Quote(clean) +
                         " --no-calibrate --no-report",
                     &out),
              0)
        << out;
    EXPECT_FALSE(Contains(Gates(clean), "slam/")) << Gates(clean);
}

// ---- Two recordings in one set of inputs ----

TEST_F(FaultScenario, TwoRecordingsWithTheSameTimeStampsAreAnErrorNamingBoth) {
    const fs::path a = Sim("base");
    const fs::path b = Sim("other_seed", "--seed 77");
    const fs::path in = TwoRecordings("same_times", a, b);
    std::string out;
    EXPECT_NE(Pitmap("georef " + Quote(in) + " --out " + Quote(in.parent_path() / "P"), &out), 0);
    EXPECT_TRUE(Contains(out, "held twice with different content")) << out;
    EXPECT_TRUE(Contains(out, "a_")) << out;
    EXPECT_TRUE(Contains(out, "b_")) << out;
}

TEST_F(FaultScenario, TwoSurveysADayOrKilometresApartAreSessionsNotOneSurvey) {
    const fs::path a = Sim("base");
    const fs::path day = Sim("next_day", "--start-utc 2026-06-16T09:00:00Z");
    // 5.5 km north, a minute after the first ends: no vehicle makes that jump.
    const fs::path away = Sim("away", "--start-utc 2026-06-15T09:03:00Z --origin 40.4930 -7.7806");
    for (const auto& [other, words] :
         {std::pair<fs::path, std::string>{day, "1.0 days later"}, {away, "km away"}}) {
        SCOPED_TRACE(words);
        const fs::path in = TwoRecordings("sessions_" + other.filename().string(), a, other);
        std::string out;
        EXPECT_NE(Pitmap("georef " + Quote(in) + " --out " + Quote(in.parent_path() / "P"), &out),
                  0);
        EXPECT_TRUE(Contains(out, "the inputs hold 2 recordings")) << out;
        EXPECT_TRUE(Contains(out, words)) << out;
        EXPECT_TRUE(Contains(out, "a_")) << out;
        EXPECT_TRUE(Contains(out, "b_")) << out;
        // Asked for one of them, it is processed as its own survey.
        std::ofstream(in.parent_path() / "session.yaml") << "ingest:\n  session: 2\n";
        out.clear();
        ASSERT_EQ(
            Pitmap("georef " + Quote(in) + " --config " + Quote(in.parent_path() / "session.yaml") +
                       " --out " + Quote(in.parent_path() / "P2"),
                   &out),
            0)
            << out;
        const json ing = ReadJson(in.parent_path() / "P2/summary.json").at("stages").at("ingest");
        EXPECT_EQ(ing.at("sessions").get<std::int64_t>(), 2);
        EXPECT_NEAR(static_cast<double>(ing.at("pings").get<std::int64_t>()), 1200.0, 5.0);
    }
}

}  // namespace
