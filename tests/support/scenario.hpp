// SPDX-License-Identifier: MIT
// What the scenario tests share to run pitmap's programs and read what they write: the
// programs' folder, a shell command with its output, quoting, JSON files,
// the boresight of a simulated survey's vehicle.yaml, and pitmap-eval's "name value" scores.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/support/process.hpp"

namespace pitmap::test {

inline const std::string kBin = PITMAP_BIN_DIR;

// Runs a command, returns its exit status and appends its output (stdout and stderr) to `out`.
inline int RunCommand(const std::string& command, std::string* out = nullptr) {
    FILE* f = popen((command + " 2>&1").c_str(), "r");
    if (f == nullptr) return -1;
    char buf[4096];
    std::string text;
    while (std::fgets(buf, sizeof(buf), f) != nullptr) text += buf;
    const int status = pclose(f);
    if (out != nullptr) *out += text;
    return status;
}

// `b` with every UTC time in it (YYYY-MM-DDTHH:MM:SSZ) zeroed: the products of two runs
// compared byte for byte but for their processing times.
inline void ZeroUtcTimes(std::string& b) {
    constexpr char kShape[] = "dddd-dd-ddTdd:dd:ddZ";
    constexpr std::size_t kLength = sizeof(kShape) - 1;
    for (std::size_t i = 0; i + kLength <= b.size(); ++i) {
        bool time = true;
        for (std::size_t k = 0; k < kLength && time; ++k) {
            const char c = b[i + k];
            time = kShape[k] == 'd' ? (c >= '0' && c <= '9') : c == kShape[k];
        }
        if (!time) continue;
        for (std::size_t k = 0; k < kLength; ++k) {
            if (kShape[k] == 'd') b[i + k] = '0';
        }
    }
}

// A file's bytes with every UTC time in it zeroed (ZeroUtcTimes).
inline std::string BytesWithoutUtcTimes(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::string b{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    ZeroUtcTimes(b);
    return b;
}

inline std::string Quote(const std::filesystem::path& p) {
    return "'" + p.string() + "'";
}

inline nlohmann::json ReadJson(const std::filesystem::path& p) {
    std::ifstream in(p);
    return nlohmann::json::parse(in);
}

// pitmap-eval's "name value" table.
inline std::map<std::string, double> Scores(const std::string& text) {
    std::map<std::string, double> s;
    std::istringstream in(text);
    std::string line, name;
    double value = 0;
    while (std::getline(in, line)) {
        std::istringstream ls(line);
        if (ls >> name >> value) s[name] = value;
    }
    return s;
}

// Sets sonar.boresight_deg (degrees) in a vehicle.yaml as pitmap-sim writes it.
inline ::testing::AssertionResult SetBoresight(const std::filesystem::path& vehicle_yaml,
                                               double roll_deg,
                                               double pitch_deg,
                                               double yaw_deg) {
    std::ifstream in(vehicle_yaml);
    std::ostringstream out;
    bool found = false;
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("  boresight_deg:", 0) == 0) {
            char buf[128];
            std::snprintf(buf,
                          sizeof buf,
                          "  boresight_deg: [%.6f, %.6f, %.6f]",
                          roll_deg,
                          pitch_deg,
                          yaw_deg);
            line = buf;
            found = true;
        }
        out << line << "\n";
    }
    in.close();
    if (!found) {
        return ::testing::AssertionFailure() << vehicle_yaml << ": no sonar.boresight_deg line";
    }
    std::ofstream(vehicle_yaml) << out.str();
    return ::testing::AssertionSuccess();
}

// Puts the simulator's true boresight (SIM/truth/boresight.json) into SIM/log/vehicle.yaml
// (for tests of something other than the calibration).
inline ::testing::AssertionResult SetTrueBoresight(const std::filesystem::path& sim) {
    const nlohmann::json t = ReadJson(sim / "truth/boresight.json");
    return SetBoresight(sim / "log/vehicle.yaml",
                        t["roll_deg"].get<double>(),
                        t["pitch_deg"].get<double>(),
                        t["yaw_deg"].get<double>());
}

// pitmap-eval's scores of a products folder against a simulator's truth folder; a failed run is
// a test failure with its output.
// extra: further pitmap-eval options, e.g. "--ate-window 30".
inline std::map<std::string, double> EvalScores(const std::filesystem::path& truth,
                                                const std::filesystem::path& products,
                                                const std::string& extra = "") {
    std::string out;
    EXPECT_EQ(RunCommand(kBin + "/pitmap-eval --truth " + Quote(truth) + " --products " +
                             Quote(products) + (extra.empty() ? "" : " " + extra),
                         &out),
              0)
        << out;
    return Scores(out);
}

}  // namespace pitmap::test
