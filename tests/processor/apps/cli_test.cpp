// SPDX-License-Identifier: MIT
// The `pitmap` CLI's answers to bad input: every config problem listed at once with its file
// and line, a missing input named, a non-zero exit; and `config --defaults` is itself a valid
// config.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
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
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.output.find((dir_ / "nowhere").string()), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("no such file"), std::string::npos) << r.output;
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

}  // namespace
