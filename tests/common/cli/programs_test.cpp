// SPDX-License-Identifier: MIT
// The programs themselves (build/bin): every one answers --version with its name, the project
// version and the commit, and a mistyped option with the usage status (2) and the closest name;
// pitmap's --help lists every command (live among them) and a mistyped command is named; a
// command whose input does not exist creates nothing (no --out folder, no lock, no --json);
// pitmap-live reads the vehicle.yaml beside the replayed log as pitmap run does.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const fs::path kBin = PITMAP_BIN_DIR;

std::string Quote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

std::string ReadText(const fs::path& p) {
    std::ifstream f(p);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

struct Outcome {
    int status = -1;
    std::string out, err;
};

// Runs bin/PROGRAM ARGS... (through the shell, arguments quoted); its exit status and output.
Outcome RunProgram(const std::string& program, const std::vector<std::string>& args) {
    // One folder per test process: ctest -j runs this file's tests at once.
    const fs::path dir =
        fs::path(testing::TempDir()) / ("cli_programs_io_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    std::string cmd = Quote((kBin / program).string());
    for (const auto& a : args) cmd += " " + Quote(a);
    cmd += " > " + Quote((dir / "out").string()) + " 2> " + Quote((dir / "err").string()) +
           " < /dev/null";
    const int rc = std::system(cmd.c_str());
    Outcome r;
    r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    r.out = ReadText(dir / "out");
    r.err = ReadText(dir / "err");
    return r;
}

std::vector<std::string> Programs() {
    std::vector<std::string> out;
    std::stringstream ss(PITMAP_CLI_PROGRAMS);
    for (std::string p; std::getline(ss, p, ',');) {
        if (!p.empty()) out.push_back(p);
    }
    return out;
}

fs::path Fresh(const std::string& name) {
    const fs::path p =
        fs::path(testing::TempDir()) / ("cli_programs_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(p);
    return p;
}

TEST(Programs, EveryOneAnswersVersion) {
    if (Programs().empty()) GTEST_SKIP() << "no program is built in this configuration";
    for (const std::string& p : Programs()) {
        const Outcome r = RunProgram(p, {"--version"});
        EXPECT_EQ(r.status, 0) << p << ": " << r.err;
        const std::regex line(p + " " + PITMAP_PROJECT_VERSION + R"( \(git [^ ()]+\)\n)");
        EXPECT_TRUE(std::regex_match(r.out, line)) << p << ": '" << r.out << "'";
    }
}

TEST(Programs, AMistypedOptionIsUsageWithASuggestion) {
    for (const std::string& p : Programs()) {
        const Outcome r = RunProgram(p, {"--verison"});
        EXPECT_EQ(r.status, 2) << p << ": " << r.err;
        EXPECT_NE(r.err.find("did you mean '--version'?"), std::string::npos) << p << ": " << r.err;
    }
}

class PitmapCommand : public testing::Test {
protected:
    void SetUp() override {
        if (!fs::exists(kBin / "pitmap")) GTEST_SKIP() << "pitmap is not built here";
    }
};

TEST_F(PitmapCommand, HelpListsEveryCommandAndTyposAreNamed) {
    const Outcome help = RunProgram("pitmap", {"--help"});
    EXPECT_EQ(help.status, 0);
    for (const char* c : {"live",
                          "info",
                          "georef",
                          "calibrate",
                          "slam",
                          "clean",
                          "grid",
                          "fuse",
                          "mesh",
                          "report",
                          "rerun",
                          "run",
                          "edit",
                          "config"}) {
        EXPECT_TRUE(std::regex_search(help.out, std::regex(std::string("\\n  ") + c + " ")))
            << c << " missing from pitmap --help:\n"
            << help.out;
    }
    const Outcome lve = RunProgram("pitmap", {"lve"});
    EXPECT_EQ(lve.status, 2);
    EXPECT_NE(lve.err.find("unknown command 'lve'; did you mean 'live'?"), std::string::npos)
        << lve.err;
    const Outcome otu = RunProgram("pitmap", {"run", "x.lcmlog", "--otu", "P"});
    EXPECT_EQ(otu.status, 2);
    EXPECT_NE(otu.err.find("did you mean '--out'?"), std::string::npos) << otu.err;
    // No command at all: the usage status, not CLI11's 106.
    EXPECT_EQ(RunProgram("pitmap", {}).status, 2);
    // `pitmap live` is pitmap-live.
    const Outcome live = RunProgram("pitmap", {"live", "--version"});
    EXPECT_EQ(live.status, 0);
    EXPECT_EQ(live.out.rfind("pitmap-live ", 0), 0u) << live.out;
}

TEST_F(PitmapCommand, AMissingInputCreatesNoOutFolder) {
    const fs::path out = Fresh("out");
    const std::string missing = (Fresh("missing") / "survey.lcmlog").string();
    for (const char* cmd : {"run", "georef"}) {
        const Outcome r = RunProgram("pitmap", {cmd, missing, "--out", out.string()});
        EXPECT_EQ(r.status, 2) << cmd << ": " << r.err;
        EXPECT_NE(r.err.find(missing + " does not exist"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out)) << cmd << " created " << out;
    }
    // An existing log but a missing vehicle file or cast: the same.
    const fs::path logs = Fresh("logs");
    fs::create_directories(logs);
    std::ofstream(logs / "a.lcmlog") << "x";
    const Outcome v = RunProgram(
        "pitmap",
        {"run", (logs / "a.lcmlog").string(), "--out", out.string(), "--vehicle", missing});
    EXPECT_EQ(v.status, 2) << v.err;
    const Outcome svp = RunProgram(
        "pitmap",
        {"georef", (logs / "a.lcmlog").string(), "--out", out.string(), "--svp", missing});
    EXPECT_EQ(svp.status, 2) << svp.err;
    EXPECT_FALSE(fs::exists(out));
    // The stages after georef read P: a P that is not there is not created.
    for (const char* cmd :
         {"calibrate", "slam", "clean", "grid", "fuse", "mesh", "report", "rerun"}) {
        const Outcome r = RunProgram("pitmap", {cmd, "--out", out.string()});
        EXPECT_EQ(r.status, 2) << cmd << ": " << r.err;
        EXPECT_FALSE(fs::exists(out)) << cmd << " created " << out;
    }
    const Outcome edit = RunProgram("pitmap", {"edit", out.string(), "--no-open"});
    EXPECT_EQ(edit.status, 2) << edit.err;
    EXPECT_FALSE(fs::exists(out));
}

TEST(Programs, OtherProgramsCreateNothingForAMissingInput) {
    const fs::path out = Fresh("out2");
    const std::string missing = (Fresh("missing2") / "x").string();
    if (fs::exists(kBin / "pitmap-live")) {
        const Outcome r = RunProgram("pitmap-live",
                                     {"--replay",
                                      missing + ".lcmlog",
                                      "--no-serve",
                                      "--snapshot-on-exit",
                                      "--out",
                                      out.string(),
                                      "--status-json",
                                      (out / "s.json").string()});
        EXPECT_EQ(r.status, 2) << r.err;
        EXPECT_FALSE(fs::exists(out));
    }
    if (fs::exists(kBin / "pitmap-eval")) {
        const fs::path json = Fresh("scores.json");
        const Outcome r = RunProgram(
            "pitmap-eval", {"--truth", missing, "--products", missing, "--json", json.string()});
        EXPECT_EQ(r.status, 2) << r.err;
        EXPECT_FALSE(fs::exists(json));
    }
    if (fs::exists(kBin / "pitmap-sim")) {
        const Outcome r = RunProgram(
            "pitmap-sim", {"hil", "--scenario", "demo", "--acqd", missing, "--out", out.string()});
        EXPECT_EQ(r.status, 2) << r.err;
        EXPECT_FALSE(fs::exists(out));
    }
    if (fs::exists(kBin / "pitmap-acqd")) {
        const Outcome r = RunProgram("pitmap-acqd", {"--config", missing + ".yaml"});
        EXPECT_EQ(r.status, 2) << r.err;
    }
}

// pitmap-live without --vehicle reads vehicle.yaml beside the first replayed log, as pitmap run
// does (processor/io/products.hpp VehicleFilePath); without that file the mount is unknown.
TEST(Programs, LiveReadsTheVehicleFileBesideTheLogs) {
    if (!fs::exists(kBin / "pitmap-live") || !fs::exists(kBin / "pitmap-sim")) {
        GTEST_SKIP() << "pitmap-live or pitmap-sim is not built here";
    }
    const fs::path sim = Fresh("sim");
    const Outcome synth = RunProgram(
        "pitmap-sim", {"synth", "--scenario", "demo", "--duration", "5", "--out", sim.string()});
    ASSERT_EQ(synth.status, 0) << synth.err;
    std::vector<std::string> logs;
    for (const auto& e : fs::directory_iterator(sim / "log")) {
        if (e.path().extension() == ".lcmlog") logs.push_back(e.path().string());
    }
    ASSERT_FALSE(logs.empty());
    ASSERT_TRUE(fs::exists(sim / "log" / "vehicle.yaml"));
    const auto mount_known = [&](const std::string& tag, std::string* err) {
        const fs::path status = sim / (tag + ".json");
        std::vector<std::string> args = {
            "--no-serve", "--status-json", status.string(), "--replay"};
        args.insert(args.end(), logs.begin(), logs.end());
        const Outcome r = RunProgram("pitmap-live", args);
        EXPECT_EQ(r.status, 0) << r.err;
        *err = r.err;
        return std::regex_search(ReadText(status), std::regex("\"mount_known\": true"));
    };
    std::string err;
    EXPECT_TRUE(mount_known("beside", &err)) << err;
    EXPECT_NE(err.find("vehicle.yaml"), std::string::npos) << err;
    fs::rename(sim / "log" / "vehicle.yaml", sim / "vehicle.yaml.away");
    EXPECT_FALSE(mount_known("none", &err)) << err;
    EXPECT_NE(err.find("no --vehicle"), std::string::npos) << err;
}

}  // namespace
