// SPDX-License-Identifier: MIT
// YAML configuration reading that collects every problem instead of stopping at the first.
//
// Usage (in an app or io layer; stages never read files):
//   auto reader = ConfigReader::FromFile(path);          // parse errors name the file and line
//   if (!reader) { print reader.error().message; exit 2; }
//   reader->Read("voxel_size_m", cfg.voxel_size_m);       // optional: keeps the default if absent
//   reader->Require("port", cfg.port);                    // missing -> a problem
//   reader->RejectUnknownKeys();                          // typos -> a problem each
//   problems = reader->problems() + cfg.Validate();       // print all, exit non-zero if any
#pragma once

#include <yaml-cpp/yaml.h>

#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"

namespace pitmap {

class ConfigReader {
public:
    // Parses a YAML file. Fails (with file name and line) on a missing file or a syntax error.
    static Expected<ConfigReader> FromFile(const std::string& path);
    // Parses YAML text; `origin` names it in messages.
    static Expected<ConfigReader> FromString(const std::string& text,
                                             const std::string& origin = "<string>");

    // Reads an optional scalar or sequence. Absent or null: `value` is untouched, returns false.
    // Present but of the wrong type: a problem is recorded, `value` untouched, returns false.
    template <typename T>
    bool Read(std::string_view key, T& value) {
        const YAML::Node node = Lookup(key);
        if (!node.IsDefined() || node.IsNull()) return false;
        try {
            value = node.as<T>();
            return true;
        } catch (const YAML::Exception&) {
            AddProblemAt(
                node, std::string(key), "has the wrong type or value '" + Describe(node) + "'");
            return false;
        }
    }

    // As Read, and records a problem when the key is absent.
    template <typename T>
    bool Require(std::string_view key, T& value) {
        if (!Has(key)) {
            AddProblem(Path(key) + ": required but missing");
            return false;
        }
        return Read(key, value);
    }

    bool Has(std::string_view key) const;
    // A nested map. Absent: a reader over nothing (every Read keeps its default).
    // Present but not a map: a problem, and the same empty reader.
    ConfigReader Child(std::string_view key);
    // A sequence of maps (e.g. a list of channels). Absent: empty. Not a sequence: a problem.
    std::vector<ConfigReader> Items(std::string_view key);
    // The keys of this map, in file order.
    std::vector<std::string> Keys() const;

    // Records a problem for every key of this map that no Read/Require/Child/Items asked for.
    void RejectUnknownKeys();

    void AddProblem(const std::string& message);
    // All problems found so far, across this reader and every child.
    const std::vector<std::string>& problems() const { return state_->problems; }
    // "file.yaml: channels[1].port" style path of a key of this map.
    std::string Path(std::string_view key) const;

private:
    struct State {
        std::string origin;
        std::vector<std::string> problems;
        std::set<std::string> consumed;
    };
    ConfigReader(YAML::Node node, std::string path, std::shared_ptr<State> state)
        : node_(std::move(node)), path_(std::move(path)), state_(std::move(state)) {}

    YAML::Node Lookup(std::string_view key) const;
    void AddProblemAt(const YAML::Node& node, const std::string& key, const std::string& what);
    static std::string Describe(const YAML::Node& node);

    YAML::Node node_;
    std::string path_;  // "" for the root, "a.b", "channels[2]"
    std::shared_ptr<State> state_;
};

// Joins problems into one message, one per line, prefixed with "  - ".
std::string FormatProblems(const std::vector<std::string>& problems);

}  // namespace pitmap
