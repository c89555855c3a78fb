// SPDX-License-Identifier: MIT
#include "common/config.hpp"

#include <fstream>
#include <sstream>

namespace pitmap {

Expected<ConfigReader> ConfigReader::FromFile(const std::string& path) {
    std::ifstream in(path);
    if (!in) return Error{path + ": cannot open config file"};
    std::stringstream text;
    text << in.rdbuf();
    return FromString(text.str(), path);
}

Expected<ConfigReader> ConfigReader::FromString(const std::string& text,
                                                const std::string& origin) {
    YAML::Node root;
    try {
        root = YAML::Load(text);
    } catch (const YAML::ParserException& e) {
        return Error{origin + ":" + std::to_string(e.mark.line + 1) + ":" +
                     std::to_string(e.mark.column + 1) + ": YAML syntax error: " + e.msg};
    }
    auto state = std::make_shared<State>();
    state->origin = origin;
    if (root.IsDefined() && !root.IsNull() && !root.IsMap()) {
        return Error{origin + ": the top level must be a map of key: value"};
    }
    return ConfigReader(root, "", std::move(state));
}

YAML::Node ConfigReader::Lookup(std::string_view key) const {
    const std::string k(key);
    state_->consumed.insert(Path(k));
    if (!node_.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    // operator[] on a const node does not insert; for a missing key it returns a "zombie"
    // node on which most calls throw, so hand out a plain undefined node instead.
    const YAML::Node& const_node = node_;
    YAML::Node n = const_node[k];
    if (!n.IsDefined()) return YAML::Node(YAML::NodeType::Undefined);
    return n;
}

bool ConfigReader::Has(std::string_view key) const {
    if (!node_.IsMap()) return false;
    const YAML::Node& const_node = node_;
    const YAML::Node n = const_node[std::string(key)];
    return n.IsDefined() && !n.IsNull();
}

ConfigReader ConfigReader::Child(std::string_view key) {
    const YAML::Node n = Lookup(key);
    const std::string child_path =
        path_.empty() ? std::string(key) : path_ + "." + std::string(key);
    if (n.IsDefined() && !n.IsNull() && !n.IsMap()) {
        AddProblemAt(n, std::string(key), "must be a map of key: value");
        return ConfigReader(YAML::Node(YAML::NodeType::Undefined), child_path, state_);
    }
    return ConfigReader(n, child_path, state_);
}

std::vector<ConfigReader> ConfigReader::Items(std::string_view key) {
    const YAML::Node n = Lookup(key);
    std::vector<ConfigReader> items;
    if (!n.IsDefined() || n.IsNull()) return items;
    if (!n.IsSequence()) {
        AddProblemAt(n, std::string(key), "must be a list");
        return items;
    }
    const std::string base = path_.empty() ? std::string(key) : path_ + "." + std::string(key);
    for (std::size_t i = 0; i < n.size(); ++i) {
        const std::string item_path = base + "[" + std::to_string(i) + "]";
        if (!n[i].IsMap()) {
            AddProblem(state_->origin + ": " + item_path + ": must be a map of key: value");
            continue;
        }
        items.push_back(ConfigReader(n[i], item_path, state_));
    }
    return items;
}

std::vector<std::string> ConfigReader::Keys() const {
    std::vector<std::string> keys;
    if (!node_.IsMap()) return keys;
    // A key may be any node in YAML ("? [a, b]: 1", "{a: 1}: 2"); only scalars name settings.
    for (const auto& kv : node_) {
        keys.push_back(kv.first.IsScalar() ? kv.first.Scalar() : Describe(kv.first));
    }
    return keys;
}

void ConfigReader::RejectUnknownKeys() {
    for (const std::string& key : Keys()) {
        if (state_->consumed.count(Path(key)) == 0) {
            const YAML::Node& const_node = node_;
            AddProblemAt(const_node[key], key, "is not a known setting (misspelt?)");
        }
    }
}

void ConfigReader::AddProblem(const std::string& message) {
    state_->problems.push_back(message);
}

std::string ConfigReader::Path(std::string_view key) const {
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

void ConfigReader::AddProblemAt(const YAML::Node& node,
                                const std::string& key,
                                const std::string& what) {
    std::string where = state_->origin;
    if (node.IsDefined() && node.Mark().line >= 0)
        where += ":" + std::to_string(node.Mark().line + 1);
    AddProblem(where + ": " + Path(key) + " " + what);
}

std::string ConfigReader::Describe(const YAML::Node& node) {
    if (node.IsScalar()) return node.Scalar();
    if (node.IsSequence()) return "<list>";
    if (node.IsMap()) return "<map>";
    return "<null>";
}

std::string FormatProblems(const std::vector<std::string>& problems) {
    std::string out;
    for (const auto& p : problems) out += "  - " + p + "\n";
    return out;
}

}  // namespace pitmap
