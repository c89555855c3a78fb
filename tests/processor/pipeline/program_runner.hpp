// SPDX-License-Identifier: MIT
// What the scenario tests share to run pitmap's programs and read what they write: the
// programs' folder, a shell command with its output, quoting, JSON files and pitmap-eval's
// "name value" score table.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

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

}  // namespace pitmap::test
