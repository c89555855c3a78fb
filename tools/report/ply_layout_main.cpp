// SPDX-License-Identifier: MIT
// pitmap-ply-layout FILE: where the records of a binary PLY lie, as one JSON object on stdout, so
// that pitmap-report memory-maps them with numpy while the PLY itself is parsed and checked only
// by common/formats/ply (DescribeFile). Exit (common/exit_codes.hpp): 0 with the JSON, 1 with
// "FILE: reason" on stderr (not binary_little_endian, truncated, lists of varying length), 2 on
// bad arguments, 3 internal error. `pitmap-ply-layout --version` prints the version (and
// pitmap-report's --version asks it: the Python script has no build stamp of its own).
//
// The JSON: {"comments": [...], "origin": {"latitude_deg", "longitude_deg", "height_m"} | null,
//            "elements": [{"name", "count", "offset", "record_bytes",
//                          "fields": [{"name", "dtype"[, "shape": [n]]}]}]}
// "dtype" is numpy's type string ("<f4", "<u1", ...); a list property is two fields: NAME__count
// (the count's type) and NAME with "shape": [entries per record].
#include <cstdio>
#include <exception>
#include <nlohmann/json.hpp>
#include <string>

#include "common/cli/suggest.hpp"
#include "common/exit_codes.hpp"
#include "common/formats/ply.hpp"
#include "common/version.hpp"

namespace ply = pitmap::formats::ply;
using nlohmann::json;

namespace {

std::string NumpyType(ply::Type t) {
    switch (t) {
        case ply::Type::kInt8:
            return "<i1";
        case ply::Type::kUInt8:
            return "<u1";
        case ply::Type::kInt16:
            return "<i2";
        case ply::Type::kUInt16:
            return "<u2";
        case ply::Type::kInt32:
            return "<i4";
        case ply::Type::kUInt32:
            return "<u4";
        case ply::Type::kFloat32:
            return "<f4";
        case ply::Type::kFloat64:
            return "<f8";
    }
    return "";
}

json LayoutJson(const ply::Layout& layout) {
    json elements = json::array();
    for (std::size_t i = 0; i < layout.elements.size(); ++i) {
        const ply::Element& e = layout.header.elements[i];
        const ply::ElementLayout& el = layout.elements[i];
        json fields = json::array();
        for (std::size_t k = 0; k < e.properties.size(); ++k) {
            const ply::Property& p = e.properties[k];
            if (!p.list_count) {
                fields.push_back({{"name", p.name}, {"dtype", NumpyType(p.type)}});
                continue;
            }
            fields.push_back({{"name", p.name + "__count"}, {"dtype", NumpyType(*p.list_count)}});
            fields.push_back({{"name", p.name},
                              {"dtype", NumpyType(p.type)},
                              {"shape", json::array({el.list_entries[k]})}});
        }
        elements.push_back({{"name", e.name},
                            {"count", e.count},
                            {"offset", el.offset},
                            {"record_bytes", el.record_bytes},
                            {"fields", fields}});
    }
    json origin = nullptr;
    if (layout.origin) {
        origin = {{"latitude_deg", layout.origin->latitude_deg},
                  {"longitude_deg", layout.origin->longitude_deg},
                  {"height_m", layout.origin->height_m}};
    }
    return {{"comments", layout.header.comments}, {"origin", origin}, {"elements", elements}};
}

}  // namespace

namespace codes = pitmap::exit_code;

int main(int argc, char** argv) try {
    constexpr const char* kUsage =
        "usage: pitmap-ply-layout FILE.ply | --version | --help\n"
        "Prints where the records of a binary little-endian PLY lie, as JSON.\n";
    const std::string arg = argc == 2 ? argv[1] : "";
    if (arg == "--version") {
        std::printf("%s\n", pitmap::VersionLine("pitmap-ply-layout").c_str());
        return codes::kOk;
    }
    if (arg == "--help" || arg == "-h") {
        std::fputs(kUsage, stdout);
        return codes::kOk;
    }
    if (argc != 2 || arg.rfind("-", 0) == 0) {
        if (arg.rfind("-", 0) == 0) {
            std::fprintf(stderr,
                         "pitmap-ply-layout: unknown option '%s'%s\n",
                         arg.c_str(),
                         pitmap::cli::DidYouMean(arg, {"--version", "--help"}).c_str());
        }
        std::fputs(kUsage, stderr);
        return codes::kUsage;
    }
    const auto layout = ply::DescribeFile(argv[1]);
    if (!layout) {
        std::fprintf(stderr, "%s\n", layout.error().message.c_str());
        return codes::kFailure;
    }
    // Comments are the file's bytes: not necessarily UTF-8, so invalid bytes are replaced.
    const std::string out =
        LayoutJson(*layout).dump(-1, ' ', false, json::error_handler_t::replace);
    std::printf("%s\n", out.c_str());
    return codes::kOk;
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap-ply-layout: internal error: %s\n", e.what());
    return codes::kInternal;
}
