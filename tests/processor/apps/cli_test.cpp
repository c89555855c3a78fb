// SPDX-License-Identifier: MIT
// The `pitmap` CLI's answers to bad input: every config problem listed at once with its file
// and line, a missing input named, a non-zero exit; and `config --defaults` is itself a valid
// config. The vehicle file and the sonar clock offset: --vehicle and --sonar-clock-offset on
// info, georef and run, the sign stated both ways, a foreign vehicle.yaml beside the logs an
// error naming what is missing, `config --vehicle` a vehicle file pitmap reads.
#include <gtest/gtest.h>
#include <unistd.h>

#include <sys/wait.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace {

namespace fs = std::filesystem;

struct CliRun {
    int status = -1;
    std::string output;
};

CliRun Pitmap(const std::string& args) {
    CliRun r;
    FILE* f = popen((std::string(PITMAP_BIN_DIR) + "/pitmap " + args + " 2>&1").c_str(), "r");
    if (f == nullptr) return r;
    char buf[4096];
    while (std::fgets(buf, sizeof buf, f) != nullptr) r.output += buf;
    r.status = pclose(f);
    return r;
}

class Cli : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::path(::testing::TempDir()) / ("pitmap_cli_" + std::to_string(::getpid()));
        fs::remove_all(dir_);
        fs::create_directories(dir_ / "logs");
    }
    void TearDown() override { fs::remove_all(dir_); }
    // A NovAtel capture as the only log: enough for the vehicle file to be read.
    fs::path Log() const {
        const fs::path log = dir_ / "logs" / "nav.gps";
        if (!fs::exists(log)) {
            fs::copy_file(fs::path(PITMAP_TEST_DATA_DIR) / "novatel" / "oem7drv_ins2.gps", log);
        }
        return log;
    }
    std::string Q(const fs::path& p) const { return "'" + p.string() + "'"; }
    fs::path dir_;
};

TEST_F(Cli, InvalidConfigListsEveryProblem) {
    std::ofstream(dir_ / "bad.yaml") << "ingest:\n  source: sideways\ngeoref:\n  max_range_m: -5\n"
                                        "  spike_rel: abc\ncalibrate:\n  part_duration_s: 0\n"
                                        "  colour: blue\nextra_key: 1\n";
    const CliRun r = Pitmap("georef " + Q(dir_ / "logs") + " --out " + Q(dir_ / "P") +
                            " --config " + Q(dir_ / "bad.yaml"));
    EXPECT_NE(r.status, 0);
    for (const char* expected : {"ingest.source",
                                 "bad.yaml:5: georef.spike_rel",
                                 "bad.yaml:8: calibrate.colour",
                                 "bad.yaml:9: extra_key",
                                 "georef.max_range_m",
                                 "calibrate.part_duration_s"}) {
        EXPECT_NE(r.output.find(expected), std::string::npos) << expected << " missing in:\n"
                                                              << r.output;
    }
}

TEST_F(Cli, MissingInputIsNamed) {
    const CliRun r = Pitmap("georef " + Q(dir_ / "nowhere") + " --out " + Q(dir_ / "P"));
    ASSERT_TRUE(WIFEXITED(r.status));
    EXPECT_EQ(WEXITSTATUS(r.status), 2) << "a usage error (docs/cli.md)";
    EXPECT_NE(r.output.find((dir_ / "nowhere").string()), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "P")) << "nothing created for a missing input";
}

TEST_F(Cli, DefaultsAreAValidConfig) {
    const CliRun defaults = Pitmap("config --defaults");
    ASSERT_EQ(defaults.status, 0) << defaults.output;
    std::ofstream(dir_ / "defaults.yaml") << defaults.output;
    // An empty log folder: the run fails on the input, never on the config.
    const CliRun r = Pitmap("georef " + Q(dir_ / "logs") + " --out " + Q(dir_ / "P") +
                            " --config " + Q(dir_ / "defaults.yaml"));
    EXPECT_NE(r.status, 0);
    EXPECT_EQ(r.output.find("invalid config"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("not a known setting"), std::string::npos) << r.output;
}

TEST_F(Cli, ClockOffsetAndVehicleOptionsOnEveryCommandThatReadsLogs) {
    for (const char* command : {"info", "georef", "run"}) {
        const CliRun help = Pitmap(std::string(command) + " --help");
        ASSERT_EQ(help.status, 0) << help.output;
        // CLI11 wraps long help text: compare with the spaces and line breaks squeezed.
        std::string text;
        for (char c : help.output) {
            if (std::isspace(static_cast<unsigned char>(c))) {
                if (!text.empty() && text.back() != ' ') text += ' ';
            } else {
                text += c;
            }
        }
        for (const char* expected : {"--vehicle",
                                     "--sonar-clock-offset",
                                     "minus GPS-disciplined UTC",
                                     "Positive = the sonar clock runs ahead of UTC",
                                     "negative = it runs behind",
                                     "GPS time = header time - S"}) {
            EXPECT_NE(text.find(expected), std::string::npos)
                << command << ": '" << expected << "' not in:\n"
                << help.output;
        }
    }
    // `run` takes the offset into its config (a non-finite one is refused by validation).
    const CliRun r = Pitmap("run " + Q(Log()) + " --out " + Q(dir_ / "P") +
                            " --sonar-clock-offset inf --no-report");
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.output.find("ingest.sonar_clock_offset_s must be finite"), std::string::npos)
        << r.output;
}

TEST_F(Cli, ForeignVehicleFileBesideTheLogsIsAnErrorNamingWhatIsMissing) {
    const fs::path vehicle = dir_ / "logs" / "vehicle.yaml";
    std::ofstream(vehicle) << "# some other tool's vehicle file\nname: boat\nlength_m: 4.2\n";
    for (const char* command : {"georef", "run"}) {
        const CliRun r = Pitmap(std::string(command) + " " + Q(Log()) + " --out " + Q(dir_ / "P"));
        EXPECT_EQ(WEXITSTATUS(r.status), 1) << r.output;
        EXPECT_NE(r.output.find(vehicle.string() + ": not a pitmap vehicle file; missing: "
                                                   "pitmap_vehicle sonar.lever_arm_m"),
                  std::string::npos)
            << command << ": " << r.output;
    }
    // --vehicle names another file; one without the sonar lever arm is an error too.
    const fs::path other = dir_ / "other.yaml";
    std::ofstream(other) << "pitmap_vehicle: 1\nsonar:\n  mount: {orientation: down, "
                            "connector: aft}\n";
    const CliRun r =
        Pitmap("georef " + Q(Log()) + " --vehicle " + Q(other) + " --out " + Q(dir_ / "P"));
    EXPECT_EQ(WEXITSTATUS(r.status), 1) << r.output;
    EXPECT_NE(r.output.find(other.string() + ": sonar.lever_arm_m: required but missing"),
              std::string::npos)
        << r.output;
}

TEST_F(Cli, VehicleTemplateIsAVehicleFilePitmapReads) {
    const CliRun t = Pitmap("config --vehicle");
    ASSERT_EQ(t.status, 0) << t.output;
    EXPECT_NE(t.output.find("pitmap_vehicle: 1"), std::string::npos) << t.output;
    std::ofstream(dir_ / "logs" / "vehicle.yaml") << "name: not this one\n";
    std::ofstream(dir_ / "vehicle.yaml") << t.output;
    // The capture has no sonar: the run stops there, past the vehicle file.
    const CliRun r = Pitmap("georef " + Q(Log()) + " --vehicle " + Q(dir_ / "vehicle.yaml") +
                            " --out " + Q(dir_ / "P"));
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.output.find("no sonar pings"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("vehicle"), std::string::npos) << r.output;
    // docs/reference.md documents the same text.
    std::ifstream readme(fs::path(PITMAP_TEST_DATA_DIR) / ".." / ".." / "docs" / "reference.md");
    const std::string doc((std::istreambuf_iterator<char>(readme)),
                          std::istreambuf_iterator<char>());
    EXPECT_NE(doc.find("```yaml\n" + t.output + "```\n"), std::string::npos)
        << "docs/reference.md's vehicle.yaml block differs from `pitmap config --vehicle`";
    // --defaults carries the same schema, commented out.
    const CliRun d = Pitmap("config --defaults");
    EXPECT_NE(d.output.find("#   pitmap_vehicle: 1"), std::string::npos) << d.output;
    EXPECT_NE(Pitmap("config").status, 0);
}

}  // namespace
