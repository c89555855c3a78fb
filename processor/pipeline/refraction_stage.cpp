// SPDX-License-Identifier: MIT
// Refraction set-up for the stages: casts from the config (new georeference) or from
// summary.json "refraction" (later stages), with the INS height above the water line.
#include <cmath>
#include <filesystem>

#include "common/gps_time.hpp"
#include "processor/io/svp_files.hpp"
#include "processor/pipeline/survey.hpp"

namespace pitmap::proc::pipeline::detail {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

Expected<std::shared_ptr<const svp::Refraction>> Build(const std::vector<std::string>& files,
                                                       svp::CastSelection selection,
                                                       svp::SurfaceSpeedSource surface,
                                                       double ins_height_m) {
    auto casts = io::ReadSoundSpeedFiles(files);
    if (!casts) return casts.error();
    if (auto p = svp::Refraction::Check(*casts, selection, ins_height_m); !p.empty()) {
        std::string text;
        for (const auto& line : p) text += (text.empty() ? "" : "\n") + line;
        return Error{text};
    }
    return std::make_shared<const svp::Refraction>(
        std::move(*casts), selection, surface, ins_height_m);
}

json Record(const svp::Refraction& r, const std::vector<std::string>& files) {
    json j = {{"svp_files", json::array()},
              {"selection", svp::ToString(r.selection())},
              {"surface_speed", svp::ToString(r.surface_speed())},
              {"ins_height_above_waterline_m", r.ins_height_above_waterline_m()},
              {"casts", json::array()}};
    for (const auto& f : files) j["svp_files"].push_back(fs::absolute(f).string());
    for (const auto& pc : r.casts()) {
        const auto& c = pc.cast;
        j["casts"].push_back(
            {{"name", c.name},
             {"time_utc",
              c.has_time() ? json(FormatUnixIso8601(UnixFromGps(c.utime_gps))) : json(nullptr)},
             {"latitude_deg", c.has_position() ? json(c.latitude_deg) : json(nullptr)},
             {"longitude_deg", c.has_position() ? json(c.longitude_deg) : json(nullptr)},
             {"points", c.depth_m.size()},
             {"max_depth_m", c.depth_m.back()},
             {"surface_speed_mps", c.speed_mps.front()}});
    }
    return j;
}

}  // namespace

Status SetUpRefraction(Survey& s,
                       const PipelineConfig& config,
                       std::optional<double> vehicle_ins_height_m,
                       const Log& log) {
    const svp::RefractionConfig& rc = config.refraction;
    s.refraction.reset();
    if (!rc.enabled()) {
        s.summary.erase("refraction");
        return Ok{};
    }
    const double height = !std::isnan(rc.ins_height_above_waterline_m)
                              ? rc.ins_height_above_waterline_m
                              : vehicle_ins_height_m.value_or(std::nan(""));
    auto r = Build(rc.svp_files, rc.selection, rc.surface_speed, height);
    if (!r) return r.error();
    s.refraction = *r;
    s.summary["refraction"] = Record(**r, rc.svp_files);
    log("refraction: " + std::to_string((*r)->casts().size()) + " cast(s), selection " +
        svp::ToString(rc.selection) + ", face speed from the " + svp::ToString(rc.surface_speed));
    return Ok{};
}

Status RestoreRefraction(Survey& s, const Log& log) {
    s.refraction.reset();
    if (!s.summary.contains("refraction")) return Ok{};
    const json& j = s.summary["refraction"];
    const std::string where = s.out_dir + "/summary.json: refraction";
    if (!j.is_object() || !j.contains("svp_files") || !j["svp_files"].is_array() ||
        !j.contains("ins_height_above_waterline_m") ||
        !j["ins_height_above_waterline_m"].is_number()) {
        return Error{where + ": needs svp_files (list) and ins_height_above_waterline_m"};
    }
    std::vector<std::string> files;
    for (const auto& f : j["svp_files"]) {
        if (!f.is_string()) return Error{where + ".svp_files: not a list of file names"};
        files.push_back(f.get<std::string>());
    }
    svp::CastSelection selection = svp::CastSelection::kNearestPreceding;
    svp::SurfaceSpeedSource surface = svp::SurfaceSpeedSource::kProfile;
    const json sel = j.value("selection", json("nearest_preceding"));
    const json sur = j.value("surface_speed", json("profile"));
    if (!sel.is_string() || !svp::ParseCastSelection(sel.get<std::string>(), selection)) {
        return Error{where + ".selection: not a known cast selection"};
    }
    if (!sur.is_string() || !svp::ParseSurfaceSpeedSource(sur.get<std::string>(), surface)) {
        return Error{where + ".surface_speed: not profile or header"};
    }
    auto r = Build(files, selection, surface, j["ins_height_above_waterline_m"].get<double>());
    if (!r) return Error{where + ": " + r.error().message};
    s.refraction = *r;
    log("refraction: " + std::to_string((*r)->casts().size()) + " cast(s) as georef used them");
    return Ok{};
}

}  // namespace pitmap::proc::pipeline::detail
